#!/bin/sh
# kogei process on small sim sessions (chart 400x300, objects 160x120): exposure and
# darks, and the states it must not pass over in silence.
#  - --assume-same-exposure fills in only what is missing: with the gain unrecorded and
#    both exposure times recorded, the object is still scaled by the times' ratio (its
#    cube equals the run with everything recorded);
#  - a dark of another camera (serial) is neither subtracted by acquire nor by process
#    (one acquire subtracted in an older session is warned),
#    and "no matching dark" is warned on stdout, in process.json and in report.html;
#  - --skip NAME leaves a foreign capture out without --force, listed in process.json;
#  - warnings: a flat applied by process that acquire recorded as none, an object
#    under-exposed by more than 50 %, one with over 1 % of its pixels clipped, an all
#    black one, one lit by another light (a green LED: over 1 % of its lit pixels
#    clamped, counted inside the --mask), and not a normal one on black ground (its
#    ground clamped, its lit pixels not).
# usage: test_process_exposure.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
FIX=$2/fixtures
. "$(dirname "$0")/sim_session.sh"
sim_session_needs "${3:-1}" numpy
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
OBJ=$T/object.tif
S=$T/S
sim_acquire "$S" dark "$OBJ" 10000 '&light=0' || fail=1
sim_acquire "$S" dark "$OBJ" 5000 '&light=0' || fail=1
sim_acquire "$S" chart "$T/chart.tif" 10000 '' --layout cie-tcs-frame || fail=1
sim_acquire "$S" object "$OBJ" 10000 '' --name object-full || fail=1
sim_acquire "$S" object "$OBJ" 5000 '&seed=7' --name object-half || fail=1
sim_measure "$T/chart.cgats" || { echo "FAIL: kogei measure"; fail=1; }
[ $fail = 0 ] || exit 1

# ---- everything recorded ----------------------------------------------------------
A=$T/A
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$A" --no-render
cp "$T/out" "$T/out-A"
check "recorded: object-half scaled by 2, dark-matched; under-exposure warned" \
	"$PY" - "$A/process.json" "$T/out-A" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
o = {x["capture"]: x for x in d["objects"]}
assert abs(o["object-half"]["exposure_scale"] - 2) < 1e-9, o["object-half"]["exposure_scale"]
assert o["object-half"]["dark"] == "dark-0002", o["object-half"]["dark"]
w = d["warnings"] + [x for ob in d["objects"] for x in ob["warnings"]]  # each once, in its scope
out = open(sys.argv[2]).read()
assert not [x for x in w if "no matching dark" in x or "applied by kogei process" in x], w
# object-half reaches about 43 % of full scale, object-full about 85 %
assert [x for x in o["object-half"]["warnings"] if "under-exposed by more than 50 %" in x], w
# (the master's gamut clipping, "master.tif: N pixels outside", is another matter)
assert not [x for x in w if "object-full" in x and "master.tif" not in x and
            ("under-exposed" in x or "clipped" in x)], w
assert 0.3 < o["object-half"]["level"] < 0.5 < o["object-full"]["level"] < 0.95, \
    (o["object-half"]["level"], o["object-full"]["level"])
assert "capture object-half: under-exposed by more than 50 %" in out, out
# on its black ground most pixels' estimates are noise about 0, clamped; the lit ones
# (the patches' inner pixels) are not: no clamp warning
for c in ("object-full", "object-half"):
    e = o[c]["estimate"]
    assert e["clamped"] > 0.5 * e["pixels"], (c, e)
    assert 0.05 * e["pixels"] < e["lit"] < 0.3 * e["pixels"], (c, e)
    assert e["clamped_lit"] <= 0.01 * e["lit"], (c, e)
    assert not [x for x in o[c]["warnings"] if "clamped" in x], (c, o[c]["warnings"])
assert "clamped" not in out, out
PY

# ---- the gain not recorded: --assume-same-exposure fills in only the gain ---------
U=$T/U
cp -r "$S" "$U"
"$PY" - "$U/session.json" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
for c in m["captures"]:
    c["settings"]["gain"] = None  # not recorded; both exposure times are
json.dump(m, open(sys.argv[1], "w"), indent=1)
PY
expect_exit 1 "$KOGEI" process "$U" --reference "$A/reference.json" -o "$T/B" --no-render
check "gain unknown: refused, naming the gain" grep -q "gain (dB or ISO) not recorded" "$T/err"
expect_exit 0 "$KOGEI" process "$U" --reference "$A/reference.json" -o "$T/B" --no-render \
	--assume-same-exposure
check "assumed gain: the recorded times still scale; cube equal to the recorded run's" \
	"$PY" - "$A" "$T/B" <<'PY'
import json, sys, numpy as np
def cube(d):
    h = open(f"{d}/cube.hdr").read()
    def key(k): return int(h.split(k)[1].split("=")[1].split("\n")[0])
    s, l, b = key("samples"), key("lines"), key("bands")
    return np.fromfile(f"{d}/cube.img", dtype="<f4").reshape(b, l, s)
b = json.load(open(sys.argv[2] + "/process.json"))
o = {x["capture"]: x for x in b["objects"]}
assert abs(o["object-half"]["exposure_scale"] - 2) < 1e-9, o["object-half"]["exposure_scale"]
assert [x for x in o["object-half"]["warnings"] if "gain unknown" in x], o["object-half"]["warnings"]
assert not [x for x in b["warnings"] if "exposure time unknown" in x or "exposure unknown" in x], b["warnings"]
ref, got = cube(sys.argv[1] + "/object-half"), cube(sys.argv[2] + "/object-half")
ok = np.isfinite(ref) & np.isfinite(got)
assert ok.sum() > 0.9 * ref.size, ok.sum()
diff = np.abs(got[ok] - ref[ok]).max()
print("object-half, gain assumed against recorded: max |difference| %.3g" % diff)
assert diff <= 1e-5 * max(1.0, np.abs(ref[ok]).max()), diff
PY

# ---- darks of another camera, a flat, a foreign capture, bad levels -----------------
S2=$T/S2
cp -r "$S" "$S2"
sim_acquire "$S2" dark "$OBJ" 7000 '&light=0&serial=site-2' || fail=1
sim_acquire "$S2" object "$OBJ" 7000 '' --name object-nodark || fail=1
sim_acquire "$S2" flat "$OBJ" 10000 '&uniform=0.6' || fail=1
# recorded without a flat (--flat none), so that process applies the session's
sim_acquire "$S2" object "$OBJ" 40000 '' --name object-over --flat none || fail=1
sim_acquire "$S2" object "$OBJ" 10000 '&light=0' --name object-black --flat none || fail=1
sim_acquire "$S2" object "$OBJ" 10000 '&serial=site-2' --name object-foreign || fail=1
[ $fail = 0 ] || exit 1
check "acquire: another camera's dark not subtracted" "$PY" - "$S2/session.json" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
c = {x["name"]: x for x in m["captures"]}
assert c["object-nodark"]["corrections"]["dark"] is None, c["object-nodark"]["corrections"]
PY
C=$T/C
expect_exit 1 "$KOGEI" process "$S2" --reference "$A/reference.json" -o "$C" --no-render
check "a foreign capture refuses the run" grep -q "site-2" "$T/err"
expect_exit 1 "$KOGEI" process "$S2" --reference "$A/reference.json" -o "$C" --no-render \
	--skip object-foreign,no-such-capture
check "--skip of an unknown capture: named" grep -q "no-such-capture" "$T/err"
expect_exit 0 "$KOGEI" process "$S2" --reference "$A/reference.json" -o "$C" --no-render \
	--skip object-foreign
cp "$T/out" "$T/out-C"
check "--skip, darks, flat and levels" "$PY" - "$C/process.json" "$T/out-C" "$C/report.html" <<'PY'
import html, json, sys
d = json.load(open(sys.argv[1]))
out = open(sys.argv[2]).read()
page = html.unescape(open(sys.argv[3]).read())
o = {x["capture"]: x for x in d["objects"]}
assert "object-foreign" not in o, list(o)
assert [x["capture"] for x in d["skipped_captures"]] == ["object-foreign"], d["skipped_captures"]
assert d["parameters"]["skip"] == ["object-foreign"], d["parameters"]["skip"]
w = d["warnings"] + [x for ob in d["objects"] for x in ob["warnings"]]  # each once, in its scope
def warned(capture, text):
    hits = [x for x in w if x.startswith("capture %s:" % capture) and text in x]
    assert hits, (capture, text, w)
    for h in hits:
        assert h in o[capture]["warnings"], (h, o[capture]["warnings"])
        assert "kogei process: warning: " + h in out, (h, out)
        assert h in page, h
# another camera's dark at the same exposure is not applied: no matching dark
assert o["object-nodark"]["dark"] is None, o["object-nodark"]["dark"]
warned("object-nodark", "no matching dark")
for c in ("object-full", "object-half", "object-black"):
    assert not [x for x in w if x.startswith("capture %s:" % c) and "no matching dark" in x], c
# the flat: applied by process, where acquire recorded none
for c in ("object-full", "object-nodark", "object-over"):
    assert o[c]["flat"] == "flat-0001", (c, o[c]["flat"])
    warned(c, "flat flat-0001 applied by kogei process")
# levels
warned("object-over", "of its pixels clipped")
assert o["object-over"]["estimate"]["clipped"] > 0.01 * o["object-over"]["estimate"]["pixels"]
warned("object-black", "all black")
assert not [x for x in w if x.startswith("capture object-black:") and "under-exposed" in x], w
assert not [x for x in w if x.startswith("capture object-full:") and
            ("clipped" in x or "all black" in x or "under-exposed" in x)], w
assert "%d warning(s)" % len(w) in out, out
PY

# A session recorded before acquire checked the camera: its dark of another camera is
# named, not passed over.
S3=$T/S3
cp -r "$S2" "$S3"
"$PY" - "$S3/session.json" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
for c in m["captures"]:
    if c["name"] == "object-nodark":
        c["corrections"]["dark"] = "dark-0003"  # site-2's, as acquire once chose it
json.dump(m, open(sys.argv[1], "w"), indent=1)
PY
expect_exit 0 "$KOGEI" process "$S3" --reference "$A/reference.json" -o "$T/D" --no-render \
	--skip object-foreign
check "acquire's dark of another camera: warned" \
	grep -q "warning: capture object-nodark: acquire subtracted dark dark-0003, of another camera" \
	"$T/out"

# ---- another light: the object under a green LED, the chart under A -----------------
# Its lit pixels read pure green, a colour the calibration under A cannot give without
# negative reflectance: clamped, warned. The --mask counts only what it keeps: half of
# the lit pixels (left of the middle column), or none (only ground rows kept).
"$PY" - "$T/green.csv" "$T/mask-left.png" "$T/mask-ground.png" <<'PY'
import struct, sys, zlib
import numpy as np
with open(sys.argv[1], "w") as f:
    f.write("wavelength_nm,power\n")
    for nm in range(380, 781, 5):
        f.write("%d,%g\n" % (nm, 1.0 if 510 <= nm <= 550 else 0.0))
def png(path, a):
    raw = b"".join(b"\0" + bytes(r) for r in a.astype(np.uint8))
    def chunk(t, x):
        return struct.pack(">I", len(x)) + t + x + struct.pack(">I", zlib.crc32(t + x))
    ihdr = struct.pack(">IIBBBBB", a.shape[1], a.shape[0], 8, 0, 0, 0, 0)  # 8-bit grey
    open(path, "wb").write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) +
                           chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))
m = np.zeros((120, 160))
m[:, :80] = 255
png(sys.argv[2], m)
m = np.zeros((120, 160))
m[:20, :] = 255
png(sys.argv[3], m)
PY
"$KOGEI" sim image --materials default --camera "$FIX/demo/site_camera.csv" \
	--illuminant "$T/green.csv" --angle 30 --patch-size 16 --gap 4 --columns 5 \
	--background 0 --white-level 0.9 --size 160x120 --noise none --depth float \
	-o "$T/object-green.tif" >/dev/null || { echo "FAIL: simulated green-lit scene"; exit 1; }
S4=$T/S4
cp -r "$S" "$S4"
sim_acquire "$S4" object "$T/object-green.tif" 10000 '' --name object-green || exit 1
for m in none left ground; do
	mopt=; [ $m = none ] || mopt="--mask $T/mask-$m.png"
	# shellcheck disable=SC2086
	expect_exit 0 "$KOGEI" process "$S4" --reference "$A/reference.json" -o "$T/G-$m" \
		--no-render $mopt
	cp "$T/out" "$T/out-G-$m"
done
check "another light: lit pixels clamped, warned; counted inside the mask only" \
	"$PY" - "$T" <<'PY'
import json, sys
t = sys.argv[1]
def run(m):
    d = json.load(open("%s/G-%s/process.json" % (t, m)))
    return {x["capture"]: x for x in d["objects"]}, d["warnings"] + [x for ob in d["objects"] for x in ob["warnings"]], open("%s/out-G-%s" % (t, m)).read()
o, w, out = run("none")
g, f = o["object-green"]["estimate"], o["object-full"]["estimate"]
print("object-green: %d lit, %d of them clamped; object-full: %d lit, %d clamped"
      % (g["lit"], g["clamped_lit"], f["lit"], f["clamped_lit"]))
assert g["lit"] > 0.05 * g["pixels"], g
assert g["clamped_lit"] > 0.5 * g["lit"], g
hits = [x for x in w if x.startswith("capture object-green: ") and "of its lit pixels clamped" in x]
assert len(hits) == 1 and hits[0] in o["object-green"]["warnings"], w
assert "(%d of %d lit pixels with a negative reflectance" % (g["clamped_lit"], g["lit"]) in hits[0], hits
assert "8 neighbours" in hits[0] and "sigma" in hits[0], hits
assert "kogei process: warning: " + hits[0] in out, out
assert not [x for x in w if "clamped" in x and not x.startswith("capture object-green:")], w
# the left half of the image: about half of the lit pixels, still warned, "inside the mask"
o, w, out = run("left")
h = o["object-green"]["estimate"]
assert 0.3 * g["lit"] < h["lit"] < 0.7 * g["lit"], (h, g)
assert h["clamped_lit"] <= h["lit"], h
assert [x for x in w if x.startswith("capture object-green: ") and
        "lit pixels inside the mask with a negative" in x], w
# only ground kept: nothing lit, no clamp warning (the clamped count stays over all pixels)
o, w, out = run("ground")
z = o["object-green"]["estimate"]
assert z["lit"] == 0 and z["clamped_lit"] == 0 and z["clamped"] == g["clamped"], (z, g)
assert not [x for x in w if "clamped" in x], w
PY

exit $fail
