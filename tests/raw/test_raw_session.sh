#!/bin/sh
# A museum's raw shoot through kogei: folders of DNG files of a simulated chart and
# object (make_dng: the scenes of tests/pipeline/sim_session.sh mosaicked RGGB, 12-bit
# above a black of 256, two identical frames each, EXIF 1/100 s, ISO 100, f/8) become a
# session through `kogei acquire --camera files:...`, and `kogei process` turns it into
# maps and a report. The same scenes through the sim camera (noise-free, 12 bits, the
# machine-vision path) give the reference: the raw path must agree with it (cube values
# within 0.2 %, labels on 99.5 % of the pixels), so decoding kept the values linear. Then
# an object shot at half the exposure time and twice the ISO (the same signal) and one
# at half the light and half the time at f/8 normalise to the same reflectance within
# 1 %; a dark DNG set is subtracted from the captures at its exposure and ISO only; the
# manifest names the source files with their sha256 and the decoding; the
# report shows the demosaicing and the raw decoding; a folder mixing exposures and an
# object from another camera body are refused.
# usage: test_raw_session.sh KOGEI SOURCE_ROOT MAKE_DNG HAVE_TAGS_AND_DEMOSAIC HAVE_LIBRAW
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
FIX=$2/fixtures
MAKE_DNG=$3
. "$2/tests/pipeline/sim_session.sh"
sim_session_needs "${4:-1}" numpy
kg_need "${5:-1}" "built without LibRaw"
kg_temp
KG_CHECK_OK=1

sim_scenes "$T" || { echo "FAIL: simulated scenes"; exit 1; }
sim_measure "$T/chart.cgats" || { echo "FAIL: kogei measure"; exit 1; }

# ---- the DSLR's files -------------------------------------------------------------
mkdir -p "$T/shoot" "$T/mixed" "$T/other"
dng() { # scene out [make_dng options]
	in=$1 out=$2; shift 2
	"$MAKE_DNG" "$in" "$out" --cfa RGGB --black 256 --white 4351 --iso 100 --fnumber 8 \
		--focal 90 --make Kogei --model "Studio DSLR" --serial 7001 --lens "Macro 90mm" "$@"
}
for k in 1 2; do
	dng "$T/chart.tif" "$T/shoot/chart_$k.dng" --exposure 0.01 || fail=1
	dng "$T/object.tif" "$T/shoot/object_$k.dng" --exposure 0.01 || fail=1
	# half the time at twice the ISO: the same signal
	dng "$T/object.tif" "$T/shoot/fast_$k.dng" --exposure 0.005 --iso 200 || fail=1
	# the lens capped: a dark at the chart's and object's settings
	dng "$T/chart.tif" "$T/shoot/dark_$k.dng" --exposure 0.01 --scale 0 || fail=1
	# half the light (values halved) in half the time
	dng "$T/object.tif" "$T/shoot/dim_$k.dng" --exposure 0.005 --scale 0.5 || fail=1
done
cp "$T/shoot/object_1.dng" "$T/mixed/a.dng"
cp "$T/shoot/fast_1.dng" "$T/mixed/b.dng"
dng "$T/object.tif" "$T/other/object.dng" --exposure 0.01 --serial 7002 || fail=1
[ $fail = 0 ] || exit 1

S=$T/S
acq() { # kind pattern name [options]
	kind=$1 pat=$2 name=$3; shift 3
	"$KOGEI" acquire --camera "files:$T/$pat" --out "$S" --kind "$kind" --name "$name" "$@" \
		>"$T/acq.out" 2>"$T/acq.err"
}
check "acquire the dark's DNG files" acq dark 'shoot/dark_*.dng' dark
check "acquire the chart's DNG files" acq chart 'shoot/chart_*.dng' chart --layout cie-tcs-frame
check "acquire took every file (2 frames)" grep -q "chart: 2 frames, bayer16 RGGB 16 bits" "$T/acq.out"
check "acquire the object's DNG files" acq object 'shoot/object_*.dng' object
check "acquire the fast object" acq object 'shoot/fast_*.dng' object-fast
check "acquire the dim object" acq object 'shoot/dim_*.dng' object-dim
acq object 'mixed' object-mixed
rc=$?
check "a folder mixing exposures is refused (exit 1, naming both files)" \
	sh -c "[ $rc = 1 ] && grep -q 'a.dng' '$T/acq.err' && grep -q 'b.dng' '$T/acq.err' && grep -q 'exposure time' '$T/acq.err'"
check "manifest: settings, sources with sha256, decoding" "$PY" - "$S/session.json" "$T/shoot" <<'PY'
import json, sys, hashlib, os
d = json.load(open(sys.argv[1]))
caps = {c["name"]: c for c in d["captures"]}
assert "object-mixed" not in caps
c = caps["chart"]
s = c["settings"]
assert s["iso"] == 100 and s["aperture"] == 8 and s["focal_length_mm"] == 90, s
assert abs(s["exposure_us"] - 10000) < 1e-6 and s["lens"] == "Macro 90mm", s
src = c["sources"]["files"]
assert [os.path.basename(f["file"]) for f in src] == ["chart_1.dng", "chart_2.dng"], src
for f in src:
    assert f["sha256"] == hashlib.sha256(open(f["file"], "rb").read()).hexdigest()
dec = c["sources"]["decoding"]
assert "DNG" in dec and "LibRaw" in dec and "256" in dec and "4351" in dec, dec
assert "OpenCV" in c["demosaic"]["algorithm"], c["demosaic"]
cam = [x for x in d["devices"]["cameras"] if x["id"] == c["camera"]][0]
assert cam["backend"] == "files" and cam["model"] == "Studio DSLR" and cam["serial"] == "7001", cam
assert caps["object-fast"]["settings"]["iso"] == 200
# the dark (ISO 100, 1/100 s) is subtracted from the captures at its settings only
assert c["corrections"]["dark"] == "dark" and caps["object"]["corrections"]["dark"] == "dark"
assert caps["object-fast"]["corrections"]["dark"] is None, caps["object-fast"]["corrections"]
PY

# ---- the same scenes through the sim camera -------------------------------------------
R=$T/R
SIM_CAMERA='format=bayer_rggb12&fullwell=1e9&read=0&serial=sim-1'
sim_acquire "$R" chart "$T/chart.tif" 10000 '' --layout cie-tcs-frame --name chart --frames 1 || fail=1
sim_acquire "$R" object "$T/object.tif" 10000 '' --name object --frames 1 || fail=1

# ---- process both ----------------------------------------------------------------------
"$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/out" >"$T/p.out" 2>"$T/p.err"
rc=$?
check "kogei process of the raw session (exit $rc)" [ $rc = 0 ]
[ $rc = 0 ] || cat "$T/p.err"
"$KOGEI" process "$R" --spectra "$T/chart.cgats" -o "$T/ref" >/dev/null 2>"$T/r.err"
rc=$?
check "kogei process of the sim-camera session (exit $rc)" [ $rc = 0 ]
[ $rc = 0 ] || cat "$T/r.err"
for f in camera.json process.json report.html object/cube.hdr object/labels.hdr object/labels.png object/scene.json; do
	check "process wrote $f" test -s "$T/out/$f"
done
check "raw path = machine-vision path; exposure, ISO and light normalised" "$PY" - "$T" <<'PY'
import sys, json, numpy as np
T = sys.argv[1]
def envi(stem):
    h = open(stem + ".hdr").read()
    def key(k): return h.split("\n" + k)[1].split("=")[1].split("\n")[0].strip()
    s, l, b = int(key("samples")), int(key("lines")), int(key("bands"))
    dt = {"4": np.float32, "12": np.uint16, "1": np.uint8, "2": np.int16, "13": np.uint32}[key("data type")]
    a = np.fromfile(stem + ".img", dtype=dt)
    il = key("interleave").lower()
    return a.reshape((b, l, s)) if il == "bsq" else a.reshape((l, b, s)).transpose(1, 0, 2) if il == "bil" else a.reshape((l, s, b)).transpose(2, 0, 1)
raw, ref = envi(f"{T}/out/object/cube"), envi(f"{T}/ref/object/cube")
lab, lref = envi(f"{T}/out/object/labels"), envi(f"{T}/ref/object/labels")
m = np.isfinite(raw).all(0) & np.isfinite(ref).all(0) & (ref.mean(0) > 0.05)
rel = np.abs(raw[:, m] - ref[:, m]).mean() / ref[:, m].mean()
agree = (lab == lref).mean()
print(f"  raw vs sim camera: cube mean |diff| {100*rel:.3f} %, labels agree on {100*agree:.2f} % of pixels")
assert rel < 0.002, rel
assert agree > 0.995, agree
for o in ("object-fast", "object-dim"):
    c = envi(f"{T}/out/{o}/cube")
    r = np.abs(c[:, m] - raw[:, m]).mean() / raw[:, m].mean()
    print(f"  {o}: mean |diff| {100*r:.3f} % from the full exposure")
    assert r < 0.01, (o, r)
d = json.load(open(f"{T}/out/process.json"))
ob = {o["capture"]: o for o in d["objects"]}
assert abs(ob["object-fast"]["exposure_scale"] - 1) < 1e-9, ob["object-fast"]["exposure_scale"]
assert abs(ob["object-dim"]["exposure_scale"] - 2) < 1e-9, ob["object-dim"]["exposure_scale"]
assert ob["object"]["gain_unit"] == "ISO" and ob["object-fast"]["gain"] == 200
c = d["calibration"]
assert c["aperture"] == 8 and "OpenCV" in c["demosaic"] and "LibRaw" in c["raw_decoding"], c
PY
check "the report shows the demosaicing and the raw decoding" \
	sh -c "grep -q 'demosaicing' '$T/out/report.html' && grep -q 'LibRaw' '$T/out/report.html' && grep -q 'OpenCV' '$T/out/report.html'"

# ---- another camera body --------------------------------------------------------------
acq object 'other/object.dng' object-other
"$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/out2" >/dev/null 2>"$T/o.err"
rc=$?
check "an object from another camera body is refused (exit $rc)" \
	sh -c "[ $rc = 1 ] && grep -q 'another camera' '$T/o.err'"
[ $fail = 0 ] || { echo "test_raw_session: failed (files in $T kept)"; trap - EXIT; exit 1; }
echo "test_raw_session: ok"
