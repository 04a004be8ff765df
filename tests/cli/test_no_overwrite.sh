#!/bin/sh
# No command overwrites what it reads: -o (or --plot, --overlay) naming an input, a
# hard link to it, a symbolic link to it or its ENVI sidecar exits 1 with a message
# naming both files, and the input keeps its bytes; a command with several outputs
# writes none of them.
# usage: test_no_overwrite.sh KOGEI HAVE_APRILTAG
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
case $KOGEI in /*) ;; *) KOGEI=$(pwd)/$KOGEI ;; esac
HAVE_APRILTAG=${2:-1}
DEMO=${KOGEI_SOURCE_ROOT:?}/fixtures/demo
kg_need_tcs
kg_temp
cd "$T" || exit 1
run() { # command...: must succeed (setting up the inputs)
	if ! "$@" >out 2>err; then
		echo "FAIL: setup '$*' exited non-zero"; cat err; exit 1
	fi
}
# refused INPUT command...: exit 1, a message naming INPUT, INPUT's bytes unchanged.
refused() {
	input=$1; shift
	before=$(sha256sum <"$input")
	"$@" >out 2>err
	got=$?
	if [ "$got" != 1 ]; then
		echo "FAIL: '$*' exited $got, expected 1"; cat err; fail=1
	elif ! grep -q "is an input of this command" err; then
		echo "FAIL: '$*': message does not say the output is an input:"; cat err; fail=1
	fi
	if [ "$(sha256sum <"$input")" != "$before" ]; then
		echo "FAIL: '$*' changed $input"; fail=1
	fi
	if ls ./*.tmp.* >/dev/null 2>&1; then
		echo "FAIL: '$*' left a temporary file:"; ls ./*.tmp.*; fail=1
	fi
}
absent() { # file, what
	if [ -e "$1" ]; then echo "FAIL: $2 wrote $1"; fail=1; rm -f "$1"; fi
}

cp "$TCS" s.cgats
ln s.cgats hard.cgats
ln -s s.cgats sym.cgats
cp "$DEMO/site_camera.csv" site.csv
run "$KOGEI" sim patches --spectra s.cgats --camera "$DEMO/reference_camera.csv" \
	--illuminant D65 -o ref.cgats
run "$KOGEI" sim patches --spectra s.cgats --camera site.csv --illuminant A -o site.cgats
run "$KOGEI" calib reference --spectra s.cgats --rgb ref.cgats -o ref.json
run "$KOGEI" calib camera --reference ref.json --rgb site.cgats -o cam.json
ln -s cam.json cam-link.json
cp "$KOGEI_SOURCE_ROOT/fixtures/materials/default.json" lib.json
run "$KOGEI" sim image --materials lib.json --camera site.csv --illuminant A \
	--patch-size 8 -o img.tif
ln img.tif img-hard.tif

# spectra xyz: the input itself, a hard link, a symbolic link; and the input named
# through a link with -o naming the file.
refused s.cgats "$KOGEI" spectra xyz s.cgats -o s.cgats
refused s.cgats "$KOGEI" spectra xyz s.cgats -o hard.cgats
refused s.cgats "$KOGEI" spectra xyz s.cgats -o sym.cgats
refused s.cgats "$KOGEI" spectra xyz sym.cgats -o s.cgats

# estimate: the cube's data file would be the calibration (-o cam.json writes
# cam.json + cam.json.hdr), the image, or a link to either.
refused cam.json "$KOGEI" estimate --calib cam.json img.tif -o cam.json
refused cam.json "$KOGEI" estimate --calib cam.json img.tif -o cam-link.json
refused img.tif "$KOGEI" estimate --calib cam.json img.tif -o img-hard.tif
absent img-hard.tif.hdr "a refused estimate"
absent cam.json.hdr "a refused estimate"

# classify: the label map over the image, or its .png preview over the image, or the
# library; nothing of the label set is left.
refused img.tif "$KOGEI" classify --calib cam.json --materials lib.json img.tif -o img.tif
refused lib.json "$KOGEI" classify --calib cam.json --materials lib.json img.tif -o lib.json
cp img.tif labels.png
refused labels.png "$KOGEI" classify --calib cam.json --materials lib.json labels.png \
	-o labels.hdr
for f in labels.hdr labels.img labels.json labels_confidence.hdr labels_mask.hdr; do
	absent $f "a refused classify"
done

# calib camera and calib reference over their inputs.
refused ref.json "$KOGEI" calib camera --reference ref.json --rgb site.cgats -o ref.json
refused site.cgats "$KOGEI" calib camera --reference ref.json --rgb site.cgats -o site.cgats
refused ref.cgats "$KOGEI" calib reference --spectra s.cgats --rgb ref.cgats -o ref.cgats

# sim: over its spectra, its camera, its library.
refused s.cgats "$KOGEI" sim patches --spectra s.cgats --camera site.csv --illuminant A \
	-o hard.cgats
refused site.csv "$KOGEI" sim patches --spectra s.cgats --camera site.csv --illuminant A \
	-o site.csv
refused lib.json "$KOGEI" sim image --materials lib.json --camera site.csv --illuminant A \
	--patch-size 8 -o img2.tif --truth-labels lib.json
absent img2.tif "a refused sim image"

# model: the plot over the library writes no table either.
refused lib.json "$KOGEI" model --material gold --materials lib.json -o gold.csv --plot lib.json
absent gold.csv "a refused model"

# chart detect: -o or --overlay over the photograph.
if [ "$HAVE_APRILTAG" = 1 ]; then
	run "$KOGEI" sim chart --layout "$DEMO/cie-tcs-frame.json" --camera site.csv \
		--illuminant D65 --width 640 --height 480 -o chart.tif
	ln -s chart.tif chart-link.tif
	refused chart.tif "$KOGEI" chart detect --layout "$DEMO/cie-tcs-frame.json" chart.tif \
		-o chart.tif
	refused chart.tif "$KOGEI" chart detect --layout "$DEMO/cie-tcs-frame.json" chart.tif \
		-o p.cgats --overlay chart-link.tif
	absent p.cgats "a refused chart detect"
fi

# The same commands with new output names still work.
run "$KOGEI" spectra xyz s.cgats -o xyz.cgats
run "$KOGEI" estimate --calib cam.json img.tif -o cube.hdr
run "$KOGEI" model --material gold --materials lib.json -o gold.csv --plot gold.png

[ $fail = 0 ] && echo "no-overwrite: ok"
exit $fail
