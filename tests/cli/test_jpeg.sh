#!/bin/sh
# JPEG photographs: read (libjpeg-turbo) for chart detection and previews; refused for
# calibration and estimation unless the user states the encoding (--encoding), because
# a JPEG is gamma-encoded and white-balanced by the camera. The JPEG is made here from
# a simulated linear chart (make_jpeg: sRGB-encoded like a camera's), so the linear
# truth is known. Without libjpeg a JPEG is refused with the reason.
# usage: test_jpeg.sh KOGEI SOURCE_ROOT HAVE_APRILTAG MAKE_JPEG|none
set -u
. "$(dirname "$0")/../lib.sh"
. "$(dirname "$0")/demo_reference.sh"
KOGEI=$1
SRC=$2
HAVE_APRILTAG=${3:-1}
MAKE_JPEG=${4:-none}
kg_temp

if [ "$MAKE_JPEG" = none ]; then
	# A JPEG's first bytes (SOI, APP0 JFIF): recognised, and refused with the reason.
	printf '\377\330\377\340\000\020JFIF\000\001\001\000\000\001\000\001\000\000\377\331' \
		> "$T/photo.jpg"
	expect_exit 1 "$KOGEI" chart detect --layout colorchecker24-frame "$T/photo.jpg" \
		-o "$T/p.cgats"
	check "no libjpeg: the message names the file" grep -q "photo.jpg" "$T/err"
	check "no libjpeg: says why" grep -q "built without libjpeg" "$T/err"
	check "no libjpeg: nothing written" test ! -e "$T/p.cgats"
	echo "built without libjpeg: JPEG refused with the reason (the rest needs libjpeg)"
	exit $fail
fi
demo_reference "$HAVE_APRILTAG"
expect_exit 0 "$KOGEI" sim chart --layout "$LAYOUT" --spectra "$TCS" --camera "$D/site_camera.csv" \
	--illuminant A --tilt 15 --rotate 5 --width 800 --height 600 --noise 20000:5:12 \
	--depth 16 -o "$T/chart.tif"
expect_exit 0 "$KOGEI" chart detect --layout "$LAYOUT" "$T/chart.tif" -o "$T/tif.cgats"
check "a TIFF's patches say linear" grep -q 'IMAGE_ENCODING "*linear' "$T/tif.cgats"
expect_exit 0 "$MAKE_JPEG" "$T/chart.tif" "$T/chart.jpg" 95
check "the helper wrote a JPEG" test -s "$T/chart.jpg"

# 1. Detection on the JPEG works, and the patch file says the encoding was not stated.
expect_exit 0 "$KOGEI" chart detect --layout "$LAYOUT" "$T/chart.jpg" -o "$T/unstated.cgats" \
	--overlay "$T/overlay.png"
check "JPEG: patches written" test -s "$T/unstated.cgats"
check "JPEG: overlay written" test -s "$T/overlay.png"
check "JPEG: IMAGE_ENCODING jpeg-unstated" grep -q 'IMAGE_ENCODING "*jpeg-unstated' "$T/unstated.cgats"
check "JPEG: a note on standard error" grep -q "not for calibration" "$T/err"

# A truncated JPEG is refused (libjpeg's warning about the missing end is an error),
# naming the file; nothing written.
size=$(wc -c < "$T/chart.jpg")
head -c $((size / 2)) "$T/chart.jpg" > "$T/cut.jpg"
expect_exit 1 "$KOGEI" chart detect --layout "$LAYOUT" "$T/cut.jpg" -o "$T/cut.cgats"
check "truncated JPEG: refused naming the file" grep -q "cut.jpg: not a readable JPEG file" "$T/err"
check "truncated JPEG: nothing written" test ! -e "$T/cut.cgats"

# 2. ... and calibration refuses it, naming the file and the reason; nothing written.
expect_exit 1 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/unstated.cgats" \
	-o "$T/cam_unstated.json"
check "calib camera: the message names the file" grep -q "unstated.cgats" "$T/err"
check "calib camera: says why" grep -q "gamma-encoded and white-balanced" "$T/err"
check "calib camera: says how to state it" grep -q "\-\-encoding" "$T/err"
check "calib camera: nothing written" test ! -e "$T/cam_unstated.json"
expect_exit 1 "$KOGEI" calib reference --spectra "$TCS" --rgb "$T/unstated.cgats" -o "$T/ref2.json"
check "calib reference: refused" grep -q "IMAGE_ENCODING" "$T/err"
check "calib reference: nothing written" test ! -e "$T/ref2.json"

# 3. With the encoding stated, the patches are the TIFF's linear values within JPEG's
# loss, and calibration takes them. Stated wrongly (linear), they are far off.
expect_exit 0 "$KOGEI" chart detect --layout "$LAYOUT" --encoding srgb "$T/chart.jpg" \
	-o "$T/srgb.cgats"
check "--encoding srgb: IMAGE_ENCODING jpeg-srgb" grep -q 'IMAGE_ENCODING "*jpeg-srgb' "$T/srgb.cgats"
expect_exit 0 "$KOGEI" chart detect --layout "$LAYOUT" --encoding linear "$T/chart.jpg" \
	-o "$T/lin.cgats"
# the largest relative difference of RGB over the patches, against the TIFF's
maxdiff() {
	awk 'FNR == 1 { f++ } /^BEGIN_DATA_FORMAT/ { fmt = 1; next } /^END_DATA_FORMAT/ { fmt = 0; next }
	     fmt { for (i = 1; i <= NF; i++) { if ($i == "RGB_R") c = i } next }
	     /^BEGIN_DATA[ \t\r]*$/ { d = 1; next } /^END_DATA/ { d = 0; next }
	     d && f == 1 { for (k = 0; k < 3; k++) v[$1, k] = $(c + k); next }
	     d && f == 2 { for (k = 0; k < 3; k++) { r = $(c + k) / v[$1, k] - 1; if (r < 0) r = -r;
	                   if (r > m) m = r } n++ }
	     END { printf "%.4f %d\n", m, n }' "$1" "$2"
}
set -- $(maxdiff "$T/tif.cgats" "$T/srgb.cgats")
srgb_diff=$1 npatch=$2
set -- $(maxdiff "$T/tif.cgats" "$T/lin.cgats")
lin_diff=$1
echo "JPEG patches against the TIFF's: sRGB stated: max relative difference $srgb_diff over $npatch patches; linear stated: $lin_diff"
check "sRGB stated: 15 patches compared" test "$npatch" = 15
check "sRGB stated: within 6 % of the linear truth" awk "BEGIN { exit !($srgb_diff < 0.06) }"
check "linear stated wrongly: far off (> 30 %)" awk "BEGIN { exit !($lin_diff > 0.30) }"
expect_exit 0 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/srgb.cgats" -o "$T/cam.json"
check "calib camera takes the stated JPEG" test -s "$T/cam.json"
expect_exit 2 "$KOGEI" chart detect --layout "$LAYOUT" --encoding gamma:9 "$T/chart.jpg" -o "$T/g.cgats"
check "--encoding gamma:9: usage error" grep -q "gamma:G" "$T/err"

# 4. estimate and classify: a JPEG is refused unless its encoding is stated.
expect_exit 1 "$KOGEI" estimate --calib "$T/cam.json" "$T/chart.jpg" -o "$T/cube.hdr" --quiet
check "estimate: the message names the file" grep -q "chart.jpg" "$T/err"
check "estimate: says why" grep -q "gamma-encoded and white-balanced" "$T/err"
check "estimate: nothing written" test ! -e "$T/cube.hdr"
expect_exit 1 "$KOGEI" classify --calib "$T/cam.json" --materials default "$T/chart.jpg" \
	-o "$T/labels.hdr" --quiet
check "classify: refused" grep -q "a JPEG" "$T/err"
check "classify: nothing written" test ! -e "$T/labels.hdr"
expect_exit 0 "$KOGEI" estimate --calib "$T/cam.json" --encoding srgb "$T/chart.jpg" \
	-o "$T/cube.hdr" --quiet
check "estimate --encoding srgb: cube written" test -s "$T/cube.img"
exit $fail
