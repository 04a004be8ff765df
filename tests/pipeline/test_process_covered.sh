#!/bin/sh
# kogei process of a lab session whose ColorChecker has a dark card over two patches
# (the simulator's --occlude patches): the two are flagged for not fitting the layout's
# colours, listed in process.json's patches_flagged with their reason and left out of
# the reference and site fits, so the calibration's error on the patches it used stays
# that of a clean chart; a session whose chart has its left half in shadow is refused
# with the cause and writes nothing. Reads the reference data
# set (kg_need_reference; skipped without it).
# usage: test_process_covered.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
ROOT=$2
kg_need "${3:-1}" "built without libapriltag or OpenCV (chart tags, demosaicing)"
kg_need_reference "$ROOT" charts/colorchecker24_babelcolor_avg.csv cameras/Nikon_D5100.csv
kg_python json
kg_temp
SPECTRA=$REF/charts/colorchecker24_babelcolor_avg.csv
CAMERA=$REF/cameras/Nikon_D5100.csv
CAM='format=bayer_rggb12&fullwell=20000&read=5&serial=site-1'
LAYOUT=$ROOT/fixtures/charts/colorchecker24-frame.json

scene() { # NAME [sim options]
	n=$1
	shift
	"$KOGEI" sim chart --layout colorchecker24-frame --spectra "$SPECTRA" --camera "$CAMERA" \
		--illuminant D65 --tilt 20 --width 800 --height 600 --white-level 0.9 --noise none \
		--depth 16 "$@" -o "$T/$n.tif" --truth "$T/$n.truth" >/dev/null
}
session() { # SESSION CHART_SCENE
	"$KOGEI" acquire --camera "sim:$2?$CAM&light=0" --out "$1" --kind dark --exposure 10000 \
		--frames 3 --gain 0 >/dev/null 2>&1 &&
	"$KOGEI" acquire --camera "sim:$2?$CAM" --out "$1" --kind chart --exposure 10000 \
		--frames 3 --gain 0 --layout colorchecker24-frame >/dev/null 2>&1 &&
	"$KOGEI" acquire --camera "sim:$T/object.tif?$CAM" --out "$1" --kind object \
		--exposure 10000 --gain 0 >/dev/null 2>&1
}
scene covered --occlude patches &&
scene even &&
"$PY" "$ROOT/tests/chart_detect/paint_chart.py" "$T/even.tif" "$T/even.truth" "$LAYOUT" \
	"$T/shade.tif" light:60:30:200:250:0.05 &&
"$KOGEI" sim image --materials default --camera "$CAMERA" --illuminant D65 --angle 30 \
	--patch-size 40 --size 800x600 --depth 16 -o "$T/object.tif" >/dev/null &&
session "$T/S" "$T/covered.tif" && session "$T/S2" "$T/shade.tif" ||
	{ echo "FAIL: setting up the sessions"; exit 1; }

expect_exit 0 "$KOGEI" process "$T/S" --spectra "$SPECTRA" -o "$T/O"
check "the two covered patches left out, named in the progress" \
	grep -q "left out: A01 (colour does not fit the layout's" "$T/err"
check "process.json: flagged, not used, and the fit on the others" "$PY" - "$T/O/process.json" <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))["calibration"]
assert c["patches_flagged"] == ["A01", "A02"], c["patches_flagged"]
by = {p["id"]: p for p in c["patches"]}
for i in ("A01", "A02"):
    p = by[i]
    assert not p["used"] and p["flags"] & 64, p
    assert "colour does not fit the layout's" in p["warning"], p["warning"]
used = [p["de00_d50"] for p in c["patches"] if p["used"]]
mean, worst = sum(used) / len(used), max(used)
print("%d patches used: dE00 (D50) mean %.2f, max %.2f" % (len(used), mean, worst))
# a clean chart's errors (2.5 and 5: about twice what the patches used give)
assert len(used) == 22 and mean < 2.5 and worst < 5, (mean, worst)
PY

expect_exit 1 "$KOGEI" process "$T/S2" --spectra "$SPECTRA" -o "$T/O2"
check "the shadowed chart refused with its cause" grep -q \
	"refused the chart colorchecker24-frame: the light over chart colorchecker24-frame falls by 95 % from its right to its left half" \
	"$T/err"
check "the refused run wrote nothing" test ! -e "$T/O2/process.json"
exit $fail
