#!/bin/sh
# Saturation found from the data (core/saturation.h) through acquire, chart detect,
# estimate and classify, on DNG files of a simulated ColorChecker (Ohta's spectra, a
# Canon EOS 5D Mark IV's sensitivities, D65; ../shared/reference) with shot noise:
#   - a 12-bit sensor (black 256, white 4095) that saturates at 4092: kogei acquire
#     (files:) reports the fraction of samples make_dng held at 4092 (to the printed
#     precision; "clipped 0.0000 %" before), chart detect flags the white patch
#     clipped and says where saturation was found;
#   - one that saturates at 3900 (an ADC whose top is unreachable at that gain):
#     estimate and classify flag the pixels at it clipped (none before: 0.949 of full
#     scale is below their 0.999 default);
#   - the same chart exposed below saturation: no saturation reported, nothing clipped
#     (no false positive on a natural histogram).
# usage: test_raw_saturation.sh KOGEI SOURCE_ROOT MAKE_DNG HAVE_TAGS_AND_DEMOSAIC HAVE_LIBRAW
set -u
. "$(dirname "$0")/../lib.sh"
. "$(dirname "$0")/raw_chart.sh"
raw_chart_setup "$@"
# the value of FIELD for SAMPLE_ID ID in a CGATS file
field() {
	awk -v id="$2" -v f="$3" '
		/^BEGIN_DATA_FORMAT/ {fmt = 1; next}
		fmt && !/^END_DATA_FORMAT/ {for (i = 1; i <= NF; i++) col[$i] = i; fmt = 0; next}
		/^BEGIN_DATA$/ {d = 1; next}
		/^END_DATA$/ {d = 0}
		d && $1 == id {print $col[f]}' "$1"
}

run_or_exit "$KOGEI" sim chart --layout colorchecker24-frame --spectra "$CHART" --camera "$CSS" \
	--illuminant D65 --tilt 10 --width 900 --height 600 --noise none --depth float \
	--white-level 0.9 -o "$T/cc.tif"
mkdir "$T/s4092" "$T/s3900" "$T/fine"
dng() { # OUT SCALE [--saturate DN]
	out=$1 scale=$2
	shift 2
	"$MAKE_DNG" "$T/cc.tif" "$out" --cfa RGGB --black 256 --white 4095 --scale "$scale" \
		--noise 20000:7 --make Kogei --model "Sat-12" --exposure 0.01 --iso 100 "$@"
}
dng "$T/s4092/a.dng" 1.6 --saturate 4092 >"$T/n4092" || exit 1
dng "$T/s3900/a.dng" 1.6 --saturate 3900 >"$T/n3900" || exit 1
dng "$T/fine/a.dng" 0.95 >/dev/null || exit 1
want=$(awk '{printf "%.4f", 100 * $2 / $4}' "$T/n4092")
echo "  make_dng: $(cat "$T/n4092") = $want %"

# acquire
run_or_exit "$KOGEI" acquire --camera "files:$T/s4092" --out "$T/S" --kind chart --name sat
got=$(sed -n 's/^  clipped \([0-9.]*\) %.*/\1/p' "$T/out")
echo "  acquire: clipped $got %"
check "acquire: clipped fraction at the sensor's 4092 ($got % = make_dng's $want %)" \
	sh -c "[ '$got' = '$want' ] && [ '$want' != 0.0000 ]"
check "acquire: says where saturation was found" \
	grep -q "saturation found from the data below full scale: [RGB] at 0.99922" "$T/out"
run_or_exit "$KOGEI" acquire --camera "files:$T/fine" --out "$T/S" --kind chart --name fine
check "acquire: nothing clipped below saturation" grep -q "^  clipped 0.0000 %" "$T/out"
check "acquire: no saturation reported below saturation" \
	sh -c "! grep -q 'saturation found' '$T/out' '$T/err'"

# chart detect
for s in s4092 s3900 fine; do
	run_or_exit "$KOGEI" chart detect --layout colorchecker24-frame "$T/$s/a.dng" -o "$T/$s.cgats"
	cp "$T/err" "$T/$s.err"
done
cf=$(field "$T/s4092.cgats" D01 CLIPPED_FRACTION)
echo "  chart detect, white patch D01 of the 4092 DNG: clipped fraction $cf"
check "chart detect: white patch clipped at 4092 ($cf)" awk -v v="$cf" 'BEGIN {exit !(v > 0.5)}'
check "chart detect: warns where saturation was found" \
	grep -q "saturation found from the data below full scale" "$T/s4092.err"
cf=$(field "$T/s3900.cgats" D01 CLIPPED_FRACTION)
check "chart detect: white patch clipped at 3900 ($cf)" awk -v v="$cf" 'BEGIN {exit !(v > 0.5)}'
nclip=$(awk '/^BEGIN_DATA$/ {d = 1; next} /^END_DATA$/ {d = 0} d' "$T/fine.cgats" | wc -l)
check "chart detect below saturation: 24 patches, no saturation warning" \
	sh -c "[ $nclip = 24 ] && ! grep -q 'saturation found' '$T/fine.err'"
cf=$(field "$T/fine.cgats" D01 CLIPPED_FRACTION)
check "chart detect below saturation: white patch not clipped ($cf)" \
	awk -v v="$cf" 'BEGIN {exit !(v == 0)}'

# estimate and classify with a calibration from the unsaturated DNG
run_or_exit "$KOGEI" chart detect --layout colorchecker24-frame "$T/cc.tif" -o "$T/tif.cgats"
# the reference spectra number the patches 1..24: the layout's aliases
kg_python
"$PY" "$(dirname "$0")/alias_ids.py" "$SRC/fixtures/charts/colorchecker24-frame.json" "$T" \
	tif fine || exit 1
run_or_exit "$KOGEI" calib reference --spectra "$CHART" --rgb "$T/tif_n.cgats" --camera "$CSS" \
	--illuminant D65 -o "$T/ref.json"
run_or_exit "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/fine_n.cgats" -o "$T/cam.json"
run_or_exit "$KOGEI" estimate --calib "$T/cam.json" "$T/s3900/a.dng" -o "$T/cube.hdr"
clipped=$(sed -n 's/.*clipped \([0-9]*\) (.*/\1/p' "$T/err" | head -1)
echo "  estimate on the 3900 DNG: $(grep 'pixels' "$T/err")"
check "estimate: pixels at 3900 flagged clipped ($clipped)" sh -c "[ '${clipped:-0}' -gt 1000 ]"
check "estimate: says where saturation was found" grep -q "saturation found from the data" "$T/err"
run_or_exit "$KOGEI" estimate --calib "$T/cam.json" "$T/fine/a.dng" -o "$T/cube2.hdr"
clipped=$(sed -n 's/.*clipped \([0-9]*\) (.*/\1/p' "$T/err" | head -1)
check "estimate below saturation: nothing clipped ($clipped)" sh -c "[ '${clipped:-1}' = 0 ]"
run_or_exit "$KOGEI" classify --calib "$T/cam.json" --materials "$SRC/fixtures/materials/default.json" \
	"$T/s3900/a.dng" -o "$T/labels.hdr"
check "classify: says where saturation was found" grep -q "saturation found from the data" "$T/err"
check "classify: pixels at 3900 flagged clipped" \
	sh -c "grep -o '\"clipped\": *[0-9]*' '$T/labels.json' | head -1 | awk '{exit !(\$2 > 1000)}'"
check "classify: labels.json records the per-channel clip levels (below 0.95)" \
	"${PY:-python3}" -c "import json, sys; c = json.load(open(sys.argv[1]))['clip_levels']; sys.exit(not (len(c) == 3 and min(c) < 0.95 and max(c) < 0.9991))" "$T/labels.json"
[ $fail = 0 ] || exit 1
echo "test_raw_saturation: ok"
