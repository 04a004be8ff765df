#!/bin/sh
# Clipping is a fact of the sensor's codes, judged before any correction (issue 47,
# item 2). A ColorChecker frame under strong vignetting (0.8: the white patch D01 sits
# where the light is 0.58 of the centre's) photographed by a simulated 12-bit sensor
# that saturates at 4092 of 4095 (sim camera saturation=4092), at two exposures:
#   - not clipped: no code of D01 reaches 4092, but the light field chart detection
#     removes divides D01 by less than 1, so its corrected green reads above 1.0. It
#     must not be flagged, and calib reference and calib camera must use it (they
#     used to refuse the whole chart: "a channel at or above 0.98 of full scale");
#   - clipped: some of D01's pixels sit at 4092 (no code anywhere reaches 4095, so the
#     level must be found from the data): D01 flagged clipped with its share of
#     pixels, left out of the fit and named.
# Reads ../shared/reference (skipped without it).
# usage: test_clip_sensor.sh KOGEI SOURCE_ROOT HAVE_APRILTAG
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
SRC=$2
HAVE_APRILTAG=${3:-1}
kg_need_reference "$SRC" charts/colorchecker24_babelcolor_avg.csv cameras/Nikon_D5100.csv \
	cameras/Canon_EOS_5D.csv
SPECTRA=$REF/charts/colorchecker24_babelcolor_avg.csv
kg_need "$HAVE_APRILTAG" "built without libapriltag"
kg_temp
LAYOUT=$SRC/fixtures/charts/colorchecker24-frame.json
# awk: is a < b (numbers)
lt() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a + 0 < b + 0) }'; }
# column COL of patch ID in a patch file
field() { # file id column-name
	awk -v id="$2" -v name="$3" '/^BEGIN_DATA_FORMAT/ { f = 1; next } /^END_DATA_FORMAT/ { f = 0; next }
	f { for (i = 1; i <= NF; i++) if ($i == name) c = ++k; else ++k; next }
	/^BEGIN_DATA$/ { d = 1; next } /^END_DATA$/ { d = 0 } d && $1 == id { print $c }' "$1"
}
# patch ids as the spectra's numbers (1..24, reading order), for calib camera
renumber() {
	awk '/^BEGIN_DATA$/ { d = 1; print; next } /^END_DATA$/ { d = 0 }
	d { $1 = (index("ABCD", substr($1, 1, 1)) - 1) * 6 + substr($1, 2) } { print }' "$1" > "$2"
}

# The scene: the chart's noise-free camera values (Canon EOS 5D, D65), vignetted.
run_or_exit "$KOGEI" sim chart --layout "$LAYOUT" --spectra "$SPECTRA" \
	--camera "$REF/cameras/Canon_EOS_5D.csv" --illuminant D65 --tilt 15 --rotate 4 \
	--fill 0.95 --width 900 --height 660 --vignetting 0.8 --depth float --white-level 1.0 \
	-o "$T/scene.tif" --truth "$T/scene.truth.cgats"
# A reference camera for calib camera (Nikon D5100 on the same spectra).
run_or_exit "$KOGEI" sim patches --spectra "$SPECTRA" --camera "$REF/cameras/Nikon_D5100.csv" \
	--illuminant D65 --noise 50000:3:16 -o "$T/ref_rgb.cgats"
run_or_exit "$KOGEI" calib reference --spectra "$SPECTRA" --rgb "$T/ref_rgb.cgats" \
	-o "$T/ref.json"

shoot() { # name light
	run_or_exit "$KOGEI" acquire --camera "sim:$T/scene.tif?format=rgb16&bits=12&saturation=4092&light=$2" \
		--out "$T/$1" --kind chart --frames 2 --exposure 10000 --no-record
	run_or_exit "$KOGEI" chart detect --layout "$LAYOUT" "$T/$1/captures/chart-0001/mean.tif" \
		-o "$T/$1.cgats"
	cp "$T/err" "$T/$1.detect.err"
}

# --- not clipped: D01's codes below 4092, its corrected value above 1 ------------------
shoot bright 1.6
g=$(field "$T/bright.cgats" D01 RGB_G)
echo "not clipped: D01 corrected green $g, flags $(field "$T/bright.cgats" D01 FLAGS)," \
	"clipped fraction $(field "$T/bright.cgats" D01 CLIPPED_FRACTION)"
check "the light field lifts D01 above 1.0 ($g)" lt 1.0 "$g"
check "D01 is not flagged" test "$(field "$T/bright.cgats" D01 FLAGS)" = 0
check "D01 has no clipped pixel" test "$(field "$T/bright.cgats" D01 CLIPPED_FRACTION)" = 0
expect_exit 0 "$KOGEI" calib reference --spectra "$SPECTRA" --rgb "$T/bright.cgats" \
	-o "$T/bright.ref.json"
check "calib reference trains on all 24 patches, D01 with its value above 1" \
	grep -q "^reference calibration: 24 training patches" "$T/out"
check "calib reference calls nothing clipped" sh -c "! grep -qi clipped '$T/out' '$T/err'"
renumber "$T/bright.cgats" "$T/bright.ids.cgats"
expect_exit 0 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/bright.ids.cgats" \
	--max-residual 5 -o "$T/bright.cam.json"
check "calib camera does not refuse D01 (19) for its corrected value" \
	sh -c "! grep -qi clipped '$T/out' '$T/err'"

# --- clipped: some of D01's pixels at the sensor's 4092 -------------------------------
shoot clipped 1.75
frac=$(field "$T/clipped.cgats" D01 CLIPPED_FRACTION)
flags=$(field "$T/clipped.cgats" D01 FLAGS)
echo "clipped: D01 flags $flags, clipped fraction $frac"
cat "$T/clipped.detect.err"
check "the saturation is found from the data at 4092 of 4095 (0.99927)" \
	grep -q "saturation found from the data below full scale: .*0\.99927" "$T/clipped.detect.err"
check "D01 is flagged clipped (flag 1)" test "$((flags & 1))" = 1
check "D01's clipped share is above 0 ($frac)" lt 0 "$frac"
check "and a part of the patch ($frac)" lt "$frac" 1
check "the warning gives the share" grep -q "D01: clipped ([0-9.]* % of pixels)" \
	"$T/clipped.detect.err"
# no other patch is clipped: only the white one reaches the ceiling
others=$(awk '/^BEGIN_DATA_FORMAT/ { f = 1; next } /^END_DATA_FORMAT/ { f = 0; next }
	f { for (i = 1; i <= NF; i++) if ($i == "CLIPPED_FRACTION") c = ++k; else ++k; next }
	/^BEGIN_DATA$/ { d = 1; next } /^END_DATA$/ { d = 0 }
	d && $1 != "D01" && $c + 0 > 0 { n++ } END { print n + 0 }' "$T/clipped.cgats")
check "no other patch has a clipped pixel ($others)" test "$others" = 0
expect_exit 0 "$KOGEI" calib reference --spectra "$SPECTRA" --rgb "$T/clipped.cgats" \
	-o "$T/clipped.ref.json"
check "calib reference leaves D01 out (23 training patches)" \
	grep -q "^reference calibration: 23 training patches" "$T/out"
check "and names it" grep -q "left out of the fit: D01 (flags 1)" "$T/err"

# --- a patch file without a clipped-fraction column is still judged by its values -----
awk '/^BEGIN_DATA_FORMAT/ { f = 1; print; next } /^END_DATA_FORMAT/ { f = 0 }
	f { print "SAMPLE_ID\tRGB_R\tRGB_G\tRGB_B"; next }
	/^BEGIN_DATA$/ { d = 1; print; next } /^END_DATA$/ { d = 0 }
	d { print $1 "\t" $2 "\t" $3 "\t" $4; next } { print }' "$T/bright.cgats" > "$T/bare.cgats"
expect_exit 1 "$KOGEI" calib reference --spectra "$SPECTRA" --rgb "$T/bare.cgats" \
	-o "$T/bare.ref.json"
check "without the sensor's verdict, a value at or above 0.98 is refused naming D01" \
	grep -q "clipped patch (a channel at or above 0.98 of full scale): D01" "$T/err"
exit $fail
