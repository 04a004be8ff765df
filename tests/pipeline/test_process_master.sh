#!/bin/sh
# kogei process, the master (a small sim session: chart 400x300, object 160x120):
#  - OUTDIR/<object>/master.tif: 16-bit RGB with the eciRGB v2 profile embedded,
#    recorded in process.json (path, space, illuminant);
#  - decoded through its embedded profile with LittleCMS (icc_decode) it matches the
#    object's cube rendered under D50: CIEDE2000 max under 0.1 for the default ICC v2
#    profile (which holds eciRGB v2's L* curve as a table and ProPhoto's gamma as an
#    8.8 number: measured 0.06-0.07) and under 0.05 for --icc-version 4 (16-bit
#    quantisation and the profile's fixed-point matrix), for each space, and under
#    --master-illuminant D65 against the cube under D65 adapted to D50;
#    and from an f16 cube;
#  - ImageMagick's identify shows the embedded profile (skipped when absent);
#  - OUTDIR/camera.icc opens with LittleCMS as an RGB input profile and maps the
#    chart's camera values (camera.ti3) to the reference within what the matrix fit
#    recorded in process.json (0.01) and within mean 3, max 6 dE00 (measured 1.94 and
#    4.43 on the 9 CIE-TCS patches: a 3x3 matrix from a camera that is not colorimetric,
#    lit by A, to D50); colprof (ArgyllCMS) builds a profile from camera.ti3 (skipped
#    when absent);
#  - ArgyllCMS reads the profiles (ICC v2 by default): iccdump of camera.icc and of the
#    master's embedded profile says version 2, and profcheck checks camera.icc against
#    camera.ti3; with --icc-version 4 both are v4 (which Argyll 2.3 refuses);
#  - --master-space none writes none (master null); an unknown space or illuminant
#    refuses the run naming the option, and writes nothing.
# usage: test_process_master.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC HAVE_LCMS ICC_DECODE
#        ICC_CAMERA_CHECK
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
FIX=$2/fixtures
DECODE=$5
CAMCHECK=$6
. "$(dirname "$0")/sim_session.sh"
sim_session_needs "${3:-1}"
kg_need "$4" "built without LittleCMS (-Dlcms): no master"
kg_temp

"$KOGEI" sim chart --layout cie-tcs-frame --spectra "$TCS" \
	--camera "$FIX/demo/site_camera.csv" --illuminant A --tilt 25 --tilt-axis 120 \
	--rotate 5 --blur 1 --vignetting 0.1 --seed 2 --width 400 --height 300 --fov 40 \
	--fill 0.85 --paper 0.85 --ink 0.03 --background 0.2 --white-level 0.9 \
	--noise none --depth float -o "$T/chart.tif" >/dev/null &&
"$KOGEI" sim image --materials default --camera "$FIX/demo/site_camera.csv" \
	--illuminant A --angle 30 --patch-size 16 --gap 4 --columns 5 --background 0 \
	--white-level 0.9 --size 160x120 --noise none --depth float -o "$T/object.tif" \
	>/dev/null || { echo "FAIL: simulated scenes"; exit 1; }
S=$T/S
sim_acquire "$S" chart "$T/chart.tif" 10000 '' --layout cie-tcs-frame || fail=1
sim_acquire "$S" object "$T/object.tif" 10000 '' --name obj || fail=1
sim_measure "$T/chart.cgats" || { echo "FAIL: kogei measure"; fail=1; }
[ $fail = 0 ] || exit 1

A=$T/A
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$A" --no-render
[ -s "$A/obj/master.tif" ] || { echo "FAIL: no master.tif"; cat "$T/err"; exit 1; }
"$PY" - "$A/process.json" <<'PY' || fail=1
import json, sys
j = json.load(open(sys.argv[1]))
o = [x for x in j["objects"] if x["capture"] == "obj"][0]
m = o["master"]
assert m["path"] == "obj/master.tif", m
assert m["space"] == "ecirgb-v2" and m["illuminant"] == "D50", m
assert "eciRGB v2" in m["profile"], m
# the gamut clipping is counted over the lit pixels only (the unlit ground of the
# object image is not), as the clamp warning's
e = o["estimate"]
print("master: %d lit pixels of %d clipped to the gamut; %d lit of %d estimated"
      % (m["clipped_pixels"], e["lit"], e["lit"], e["pixels"]))
assert m["clipped_counted"] == "lit pixels", m
assert 0 < e["lit"] < e["pixels"], e
assert m["clipped_pixels"] <= e["lit"], (m, e)
w = [x for x in o["warnings"] if "master.tif" in x]
assert bool(w) == (m["clipped_pixels"] > 0), w
# each clipped pixel is warned once, by its cause: brighter than the diffuse white, a
# channel above the space's white, or outside its primaries (highlights: their counts)
h = o["highlights"]
assert h["clipped_in_master"] + h["outside_primaries"] == m["clipped_pixels"], (h, m)
assert all("lit pixels" in x for x in w), w
assert bool([x for x in w if "lit pixels outside" in x]) == (h["outside_primaries"] > 0), w
assert bool([x for x in w if "highlights above" in x]) == (h["above_white"] > 0), w
PY
# decoded through its own profile: within 0.05 of the cube under D50
check_decode() { # master cube illuminant label [limit]
	r=$("$DECODE" "$1" "$2" "$3") || { echo "FAIL: icc_decode $1: $r"; fail=1; return; }
	echo "$4: $r"
	max=$(echo "$r" | sed 's/.* max //')
	n=$(echo "$r" | sed 's/^pixels \([0-9]*\) .*/\1/')
	lim=${5:-0.1}
	"$PY" -c "import sys; sys.exit(0 if float('$max') < $lim and int('$n') > 1000 else 1)" ||
		{ echo "FAIL: $4: decoded master against the cube: $r (max dE00 < $lim over > 1000 pixels expected)"; fail=1; }
}
# the profile embedded in a TIFF (tag 34675), written out for Argyll
embedded_icc() { # TIFF OUT.icc
	"$PY" - "$1" "$2" <<'PY'
import struct, sys
d = open(sys.argv[1], "rb").read()
e = "<" if d[:2] == b"II" else ">"
off = struct.unpack(e + "I", d[4:8])[0]
n = struct.unpack(e + "H", d[off:off + 2])[0]
for i in range(n):
    tag, typ, cnt, val = struct.unpack(e + "HHII", d[off + 2 + 12 * i: off + 14 + 12 * i])
    if tag == 34675:
        open(sys.argv[2], "wb").write(d[val:val + cnt])
        sys.exit(0)
sys.exit(1)
PY
}
argyll_reads() { # PROFILE VERSION LABEL
	if ! command -v iccdump >/dev/null 2>&1; then
		echo "iccdump (ArgyllCMS) not installed: that check skipped"; return
	fi
	iccdump "$1" >"$T/iccdump" 2>&1
	if [ "$2" = 2 ]; then
		grep -q "Version *= 2\." "$T/iccdump" ||
			{ echo "FAIL: $3: iccdump does not read a v2 profile:"; head -5 "$T/iccdump"; fail=1; }
	else
		grep -q "V4 not supported" "$T/iccdump" ||
			{ echo "FAIL: $3: expected a v4 profile, which Argyll 2.3 refuses"; head -5 "$T/iccdump"; fail=1; }
	fi
}
check_decode "$A/obj/master.tif" "$A/obj/cube.hdr" D50 ecirgb-v2
if command -v identify >/dev/null 2>&1; then
	identify -verbose "$A/obj/master.tif" >"$T/id" 2>&1
	grep -qi "icc" "$T/id" && grep -q "eciRGB v2" "$T/id" && grep -qi "16-bit" "$T/id" ||
		{ echo "FAIL: identify does not show a 16-bit image with the eciRGB v2 profile"; head -40 "$T/id"; fail=1; }
else
	echo "identify (ImageMagick) not installed: that check skipped"
fi
if command -v tificc >/dev/null 2>&1; then
	tificc -t1 "$A/obj/master.tif" "$T/lab.tif" >"$T/tificc" 2>&1 ||
		{ echo "FAIL: tificc cannot transform master.tif"; cat "$T/tificc"; fail=1; }
fi
# the camera input profile
r=$("$CAMCHECK" "$A/camera.icc" "$A/camera.ti3") || { echo "FAIL: camera.icc: $r"; fail=1; }
echo "camera.icc: $r"
"$PY" - "$A/process.json" "$r" <<'PY' || fail=1
import json, sys
c = json.load(open(sys.argv[1]))["calibration"]["camera_icc"]
f = sys.argv[2].split()
n, mean, mx = int(f[1]), float(f[3]), float(f[5])
assert c["path"] == "camera.icc" and c["ti3"] == "camera.ti3", c
assert n == c["patches"] and n >= 9, (n, c)
assert abs(mean - c["fit_de00_mean"]) < 0.01 and abs(mx - c["fit_de00_max"]) < 0.01, (f, c)
assert mean < 3 and mx < 6, ("camera.icc against the reference", mean, mx)
PY
# camera.icc held out: process.json's leave-one-out recomputed from camera.ti3, and
# ArgyllCMS's shaper/matrix profile held out the same way beside it
if command -v colprof >/dev/null 2>&1 && command -v xicclu >/dev/null 2>&1; then
	mkdir -p "$T/loo"
	"$PY" "$(dirname "$0")/icc_loo.py" "$A/process.json" "$A/camera.ti3" --argyll "$T/loo" || fail=1
else
	"$PY" "$(dirname "$0")/icc_loo.py" "$A/process.json" "$A/camera.ti3" || fail=1
fi
if command -v colprof >/dev/null 2>&1; then
	cp "$A/camera.ti3" "$T/argyll.ti3"
	(cd "$T" && timeout 60 colprof -v -am -O argyll.icc argyll) >"$T/colprof" 2>&1 && [ -s "$T/argyll.icc" ] ||
		{ echo "FAIL: colprof cannot build a profile from camera.ti3"; tail -5 "$T/colprof"; fail=1; }
else
	echo "colprof (ArgyllCMS) not installed: that check skipped"
fi
# ICC v2 by default: ArgyllCMS reads camera.icc and the master's profile, and checks
# camera.icc against the chart's patches
argyll_reads "$A/camera.icc" 2 "camera.icc"
embedded_icc "$A/obj/master.tif" "$T/master.icc" || { echo "FAIL: no profile in master.tif"; fail=1; }
argyll_reads "$T/master.icc" 2 "master.tif's profile"
if command -v profcheck >/dev/null 2>&1; then
	cp "$A/camera.ti3" "$T/pc.ti3"
	(cd "$T" && profcheck -v pc.ti3 "$A/camera.icc") >"$T/profcheck" 2>&1 ||
		{ echo "FAIL: profcheck cannot check camera.icc"; tail -5 "$T/profcheck"; fail=1; }
	echo "profcheck: $(grep -i "average" "$T/profcheck" | head -1)"
fi
# --icc-version 4: v4 profiles, the master within 0.05
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/v4" --no-render \
	--icc-version 4
argyll_reads "$T/v4/camera.icc" 4 "camera.icc v4"
[ -s "$T/v4/obj/master.tif" ] && check_decode "$T/v4/obj/master.tif" "$T/v4/obj/cube.hdr" D50 "ecirgb-v2 v4" 0.05
expect_exit 2 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/v3" --icc-version 3
for sp in adobe-rgb prophoto; do
	expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/$sp" --no-render \
		--master-space "$sp"
	[ -s "$T/$sp/obj/master.tif" ] && check_decode "$T/$sp/obj/master.tif" "$T/$sp/obj/cube.hdr" D50 "$sp"
done
# an f16 cube (IEEE half in the ENVI file) renders the same master
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/f16" --no-render --cube f16
[ -s "$T/f16/obj/master.tif" ] && check_decode "$T/f16/obj/master.tif" "$T/f16/obj/cube.hdr" D50 "ecirgb-v2 f16" ||
	{ echo "FAIL: no master from an f16 cube"; fail=1; }
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/d65" --no-render \
	--master-illuminant D65
[ -s "$T/d65/obj/master.tif" ] && check_decode "$T/d65/obj/master.tif" "$T/d65/obj/cube.hdr" D65 "ecirgb-v2 D65"
grep -q '"illuminant": "D65"' "$T/d65/process.json" || { echo "FAIL: D65 not recorded"; fail=1; }
# an illuminant from a spectrum file: used, and recorded as an input with its sha256
printf 'CGATS.17\nNUMBER_OF_FIELDS 3\nBEGIN_DATA_FORMAT\nSAMPLE_ID SPEC_400 SPEC_700\nEND_DATA_FORMAT\nNUMBER_OF_SETS 1\nBEGIN_DATA\n1 50 100\nEND_DATA\n' >"$T/ill.sp"
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/ill" --no-render \
	--master-illuminant "$T/ill.sp"
[ -s "$T/ill/obj/master.tif" ] && check_decode "$T/ill/obj/master.tif" "$T/ill/obj/cube.hdr" "$T/ill.sp" "ecirgb-v2 ill.sp" ||
	{ echo "FAIL: no master under a spectrum file"; fail=1; }
grep -q '"master_illuminant"' "$T/ill/process.json" || { echo "FAIL: the illuminant file is not an input"; fail=1; }
# none: not written
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/none" --no-render \
	--master-space none
[ ! -e "$T/none/obj/master.tif" ] || { echo "FAIL: --master-space none wrote master.tif"; fail=1; }
"$PY" -c "import json,sys; o=json.load(open('$T/none/process.json'))['objects'][0]; sys.exit(0 if o['master'] is None else 1)" ||
	{ echo "FAIL: --master-space none: master not null"; fail=1; }
# refusals
expect_exit 2 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/bad" --master-space srgb
grep -q "master-space srgb: expected ecirgb-v2" "$T/err" || { echo "FAIL: bad space message"; cat "$T/err"; fail=1; }
expect_exit 1 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/bad" --master-illuminant D9x
grep -q "master-illuminant" "$T/err" || { echo "FAIL: bad illuminant message"; cat "$T/err"; fail=1; }
[ ! -e "$T/bad/process.json" ] || { echo "FAIL: a refused run wrote process.json"; fail=1; }
[ $fail = 0 ] && echo "process-master: ok"
exit $fail
