#!/bin/sh
# A DSLR's raw file of a ColorChecker through chart detect and calib camera: a
# simulated ColorChecker Classic (Ohta's measured spectra, the measured sensitivities
# of a Canon EOS 5D Mark IV, D65, tilted 20 degrees; ../shared/reference) photographed
# as a 14-bit DNG (GRBG, per-site black 2048/2049/2047/2050, white 16383). The patches
# chart detect reads from the DNG (decoded by LibRaw, demosaiced) must equal those it
# reads from the linear float image the DNG was made from within one raw step (the
# DNG's rounding is half a step per pixel; a wrong black or white would be thousands
# of steps off on the bright patches), and calib
# camera, with a reference calibrated on that float image, must find M2 = identity
# (within 0.002): nothing between the file and kogei's values broke linearity. The
# calibration records the camera named by the DNG, and `kogei estimate` takes the DNG
# itself.
# usage: test_raw_colorchecker.sh KOGEI SOURCE_ROOT MAKE_DNG HAVE_TAGS_AND_DEMOSAIC HAVE_LIBRAW
set -u
. "$(dirname "$0")/../lib.sh"
. "$(dirname "$0")/raw_chart.sh"
raw_chart_setup "$@"
kg_python

run_or_exit "$KOGEI" sim chart --layout colorchecker24-frame --spectra "$CHART" --camera "$CSS" \
	--illuminant D65 --tilt 20 --rotate 5 --width 1200 --height 800 --noise none \
	--depth float --white-level 0.9 -o "$T/cc.tif"
run_or_exit "$MAKE_DNG" "$T/cc.tif" "$T/cc.dng" --cfa GRBG --black 2048,2049,2047,2050 \
	--white 16383 --exposure 0.02 --iso 100 --fnumber 8 --make Canon \
	--model "Canon EOS 5D Mark IV" --serial 031021000123
run_or_exit "$KOGEI" chart detect --layout colorchecker24-frame "$T/cc.dng" -o "$T/dng.cgats"
run_or_exit "$KOGEI" chart detect --layout colorchecker24-frame "$T/cc.tif" -o "$T/tif.cgats"
check "chart detect names the DNG's camera" \
	sh -c "grep -q 'CAMERA_MODEL \"EOS 5D Mark IV\"' '$T/dng.cgats' && grep -q 'CAMERA_SERIAL \"031021000123\"' '$T/dng.cgats'"
# The reference charts number the patches 1..24 (the layout's aliases).
"$PY" "$(dirname "$0")/alias_ids.py" "$SRC/fixtures/charts/colorchecker24-frame.json" "$T" \
	tif dng || fail=1
check "DNG patches = the linear image's within one raw step" "$PY" - "$T" <<'PY'
import sys
def read(p):
    rows, data, fields = {}, False, None
    for line in open(p):
        line = line.rstrip("\n")
        if line == "BEGIN_DATA_FORMAT": fields = []
        elif fields == [] and line and line != "END_DATA_FORMAT": fields = line.split("\t")
        elif line == "BEGIN_DATA": data = True
        elif line == "END_DATA": data = False
        elif data and line:
            v = line.split("\t"); rows[v[0]] = [float(v[fields.index(k)]) for k in ("RGB_R", "RGB_G", "RGB_B")]
    return rows
a, b = read(sys.argv[1] + "/dng.cgats"), read(sys.argv[1] + "/tif.cgats")
assert len(a) == 24 and a.keys() == b.keys()
step = 1 / (16383 - 2050)
worst = max(abs(x - y) / step for k in a for x, y in zip(a[k], b[k]))
print(f"  worst patch difference DNG vs linear image: {worst:.2f} raw steps")
assert worst < 1, worst
PY
run_or_exit "$KOGEI" calib reference --spectra "$CHART" --rgb "$T/tif_n.cgats" --camera "$CSS" \
	--illuminant D65 -o "$T/ref.json"
run_or_exit "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/dng_n.cgats" -o "$T/cam.json"
check "calib camera from the DNG: M2 = identity, the DNG's camera recorded" "$PY" - "$T/cam.json" <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))
M2 = c["M2"]
dev = max(abs(M2[i][j] - (i == j)) for i in range(3) for j in range(3))
print(f"  M2 largest deviation from identity: {dev:.2e}")
assert dev < 0.002, M2
cam = c["camera"]
assert cam["model"] == "EOS 5D Mark IV" and cam["serial"] == "031021000123", cam
assert cam["backend"] == "files", cam
PY
"$KOGEI" estimate --calib "$T/cam.json" "$T/cc.dng" -o "$T/cube.hdr" >"$T/out" 2>"$T/err"
rc=$?
check "estimate takes the DNG (exit $rc)" sh -c "[ $rc = 0 ] && [ -s '$T/cube.hdr' ]"
[ $rc = 0 ] || cat "$T/err"
[ $fail = 0 ] || exit 1
echo "test_raw_colorchecker: ok"
