#!/bin/sh
# kogei process end to end on a session recorded with the sim devices (dark, flat,
# chart, three objects, the chart measured), then every refusal: no chart, wrong
# layout, too few usable patches, an uncheckable 3-patch chart, an M2 residual above
# the limit, unknown exposure, another camera, the session as output; re-runs that
# skip unchanged objects; the scenes render; exposure normalisation within 1 %.
# usage: test_process.sh KOGEI SOURCE_ROOT HAVE_EMBREE HAVE_TAGS_AND_DEMOSAIC
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
FIX=$2/fixtures
HAVE_EMBREE=${3:-0}
. "$(dirname "$0")/sim_session.sh"
sim_session_needs "${4:-1}" numpy
kg_temp
# A refusal: exit 1, the message names $2, and OUTDIR holds nothing.
expect_refusal() { # outdir pattern command...
	out=$1 pat=$2; shift 2
	expect_exit 1 "$@"
	check "refusal names '$pat'" grep -q -- "$pat" "$T/err"
	if [ -e "$out" ] && [ -n "$(ls -A "$out")" ]; then
		echo "FAIL: a refused run left files in $out:"; ls -A "$out"; fail=1
	fi
}

sim_scenes "$T" || { echo "FAIL: simulated scenes"; exit 1; }
S=$T/S
sim_acquire "$S" dark "$T/chart.tif" 10000 '&light=0' || fail=1
sim_acquire "$S" dark "$T/chart.tif" 5000 '&light=0' || fail=1
sim_acquire "$S" flat "$T/chart.tif" 10000 '&uniform=0.6' || fail=1
sim_acquire "$S" chart "$T/chart.tif" 10000 '' --layout cie-tcs-frame || fail=1
sim_acquire "$S" object "$T/object.tif" 10000 '' --name object-full || fail=1
sim_acquire "$S" object "$T/object.tif" 5000 '&seed=7' --name object-half || fail=1
sim_acquire "$S" object "$T/object.tif" 10000 '&seed=9' --name object-again || fail=1
sim_measure "$T/chart.cgats" || { echo "FAIL: kogei measure"; fail=1; }
[ $fail = 0 ] || exit 1

# ---- the lab session: its chart gives the reference; then every object ------------
O=$T/lab
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$O"
for f in camera.json reference.json process.json report.html chart_overlay.png; do
	check "process writes $f" test -s "$O/$f"
done
for c in object-full object-half object-again; do
	for f in cube.hdr cube.img labels.hdr labels.json labels.png photo.png confidence.png scene.json; do
		check "process writes $c/$f" test -s "$O/$c/$f"
	done
done
check "progress on stderr" grep -q "kogei process: object-half: estimating" "$T/err"
check "summary: 3 processed" grep -q "3 object(s), 3 processed, 0 unchanged" "$T/out"
check "dark and flat applied" "$PY" - "$O/process.json" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
c = d["calibration"]
assert c["dark"] and c["flat"], (c["dark"], c["flat"])
# the flat is a uniform target: its illuminance non-uniformity is noise; the chart's
# vignetting (0.1) stays after it and is estimated from the patches and removed
nu = c["flat_illuminance_nonuniformity"]
lf = c["light_field"]
print("flat non-uniformity %.4f, light field over the chart %s" % (nu, lf))
assert isinstance(nu, float) and 0 <= nu < 0.01, nu
assert lf["fitted"] and 0.005 < lf["variation"] < 0.15, lf
assert lf["min"] < 1 < lf["max"] and lf["patches"] >= 10, lf
assert len(lf["coefficients"]) == 15, lf
o = {x["capture"]: x for x in d["objects"]}
assert o["object-half"]["dark"] == "dark-0002", o["object-half"]["dark"]
assert abs(o["object-half"]["exposure_scale"] - 2) < 1e-9
PY
check "report: the light over the chart" grep -q "Light over the chart</th><td>varies by" "$O/report.html"
check "report: the flat's non-uniformity" grep -q "Flat: illuminance non-uniformity</th><td>0.0" "$O/report.html"
# The half-exposure object gives the same reflectance within 1 %.
check "exposure normalised: half exposure within 1 %" "$PY" - "$O" <<'PY'
import sys, numpy as np
def cube(d):
    h = open(f"{d}/cube.hdr").read()
    def key(k): return int(h.split(k)[1].split("=")[1].split("\n")[0])
    s, l, b = key("samples"), key("lines"), key("bands")
    return np.fromfile(f"{d}/cube.img", dtype="<f4").reshape(b, l, s)
full, half = cube(sys.argv[1] + "/object-full"), cube(sys.argv[1] + "/object-half")
ok = np.isfinite(full).all(0) & np.isfinite(half).all(0) & (full.mean(0) > 0.05)
assert ok.sum() > 10000, ok.sum()
r = half[:, ok].mean(1) / full[:, ok].mean(1)
print("half/full reflectance ratio per band: %.4f .. %.4f" % (r.min(), r.max()))
assert np.all(np.abs(r - 1) < 0.01), r
PY

# The report as a person sees it: headless Chromium loads it with nothing failing,
# every section present and every image decoded (skipped without chromium).
sh "$(dirname "$0")/report_browser.sh" "$O/report.html" "$T/report.png" >"$T/out" 2>"$T/err"
rc=$?
if [ $rc = 77 ]; then echo "note: report in Chromium skipped: $(cat "$T/err")"
elif [ $rc != 0 ]; then echo "FAIL: the report in Chromium"; cat "$T/out" "$T/err"; fail=1; fi

# Scenes render as written.
if [ "$HAVE_EMBREE" = 1 ]; then
	check "process rendered object-full" test -s "$O/object-full/render.png"
	expect_exit 0 "$KOGEI" render --scene "$O/object-full/scene.json" -o "$T/r.png" --spp 2
	check "kogei render --scene renders process's scene" test -s "$T/r.png"
	# the Mitsuba 3 scene beside it: the chart's pose, the label map's regions as PLYs
	check "process wrote object_mitsuba.xml" "$PY" "$2/tests/render/mitsuba_check.py" \
		"$O/object-full/object_mitsuba.xml" --scene "$O/object-full/scene.json"
fi

# Re-runs skip what did not change; a later object is the only one processed.
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$O" --quiet
check "re-run: all unchanged" grep -q "3 object(s), 0 processed, 3 unchanged" "$T/out"
sim_acquire "$S" object "$T/object.tif" 10000 '&seed=11' --name object-later || fail=1
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$O" --quiet
check "later object: only it processed" grep -q "4 object(s), 1 processed, 3 unchanged" "$T/out"
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$O" --quiet --angle 40
check "changed parameters: all processed" grep -q "4 object(s), 4 processed, 0 unchanged" "$T/out"

# --mask: pixels at 0 in the mask are background, whatever they show; a mask of
# another size is refused, naming it.
W=$(sed -n 's/^samples *= *//p' "$O/object-full/labels.hdr")
H=$(sed -n 's/^lines *= *//p' "$O/object-full/labels.hdr")
# The mask takes out the left part of what the last run (--angle 40) labelled as
# materials: every column left of the material pixels' median column.
"$PY" - "$O/object-full" "$W" "$H" "$T/mask.png" "$T/mask-small.png" "$T/cut" <<'PY'
import json, struct, sys, zlib
import numpy as np
d, w, h = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
def png(path, a):
    raw = b"".join(b"\0" + bytes(r) for r in a.astype(np.uint8))
    def chunk(t, x):
        return struct.pack(">I", len(x)) + t + x + struct.pack(">I", zlib.crc32(t + x))
    ihdr = struct.pack(">IIBBBBB", a.shape[1], a.shape[0], 8, 0, 0, 0, 0)  # 8-bit grey
    open(path, "wb").write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) +
                           chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))
cls = {c["name"]: c["label"] for c in json.load(open(d + "/labels.json"))["classes"]}
lab = np.fromfile(d + "/labels.img", dtype=np.uint8).reshape(h, w)
material = (lab > 0) & (lab != cls["unknown"]) & (lab != cls["background"])
cut = int(np.median(np.nonzero(material)[1]))
assert material[:, :cut].sum() > 1000, material[:, :cut].sum()
m = np.full((h, w), 255)
m[:, :cut] = 0
png(sys.argv[4], m)
png(sys.argv[5], np.full((h, w // 2), 255))
open(sys.argv[6], "w").write("%d %d\n" % (cut, material[:, :cut].sum()))
PY
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/masked" --angle 40 \
	--mask "$T/mask.png" --no-render --quiet
check "--mask: background where it is 0, the labels elsewhere as without it" "$PY" - \
	"$T/masked" "$O" "$W" "$H" "$T/cut" <<'PY'
import json, sys, numpy as np
masked, plain, w, h = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
cut, had = map(int, open(sys.argv[5]).read().split())
def labels(d):
    return np.fromfile(f"{d}/object-full/labels.img", dtype=np.uint8).reshape(h, w)
cls = {c["name"]: c["label"] for c in json.load(open(masked + "/object-full/labels.json"))["classes"]}
m, p = labels(masked), labels(plain)
assert np.all(m[:, :cut] == cls["background"]), np.unique(m[:, :cut])
same = np.mean(m[:, cut:] == p[:, cut:])
print("mask: %d material pixels taken out; the rest %.4f as without the mask" % (had, same))
assert same > 0.99, same
obj = {o["capture"]: o for o in json.load(open(masked + "/process.json"))["objects"]}["object-full"]
assert obj["background_fraction"] >= cut / w - 1e-9, obj["background_fraction"]
assert json.load(open(masked + "/process.json"))["parameters"]["mask"].endswith("mask.png")
PY
expect_refusal "$T/masked2" "mask-small.png" "$KOGEI" process "$S" --spectra "$T/chart.cgats" \
	-o "$T/masked2" --mask "$T/mask-small.png" --no-render
# --cube: weights (K bands and their basis, the same labels), none (labels only; the
# report says so and still loads); a changed cube format reprocesses.
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/weights" --angle 40 \
	--cube weights --no-render --quiet
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/nocube" --angle 40 \
	--cube none --no-render --quiet
check "--cube weights and none: bands, files, labels as with f32" "$PY" - "$T/weights" \
	"$T/nocube" "$O" <<'PY'
import json, os, sys, numpy as np
weights, nocube, plain = sys.argv[1:4]
hdr = open(weights + "/object-full/cube.hdr").read()
bands = int([l for l in hdr.splitlines() if l.replace(" ", "").startswith("bands=")][0].split("=")[1])
assert 2 <= bands <= 10 and "kogei basis" in hdr, bands
assert os.path.getsize(weights + "/object-full/cube.img") % (4 * bands) == 0
assert not os.path.exists(nocube + "/object-full/cube.hdr")
obj = {o["capture"]: o for o in json.load(open(nocube + "/process.json"))["objects"]}
assert obj["object-full"]["cube"] is None and obj["object-full"]["estimate"]["pixels"] > 0
assert json.load(open(nocube + "/process.json"))["parameters"]["cube"] == "none"
for d in (weights, nocube):
    a = np.fromfile(d + "/object-full/labels.img", dtype=np.uint8)
    b = np.fromfile(plain + "/object-full/labels.img", dtype=np.uint8)
    assert np.array_equal(a, b), (d, np.mean(a != b))
print("cube: weights with %d bands; none: labels only; labels identical to f32's" % bands)
PY
check "--cube none: the report says there is no cube" grep -q "no reflectance cube" \
	"$T/nocube/report.html"
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/nocube" --angle 40 \
	--cube f16 --no-render --quiet
check "changed cube format: all processed" grep -q "4 processed, 0 unchanged" "$T/out"
expect_exit 2 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/bad" --cube f64
check "--cube f64 refused" grep -q "expected f32, f16, weights or none" "$T/err"
# --method: camera-space labels by default (separability, regions, composition in
# labels.json and process.json), the paper's eq. 11 on request; a changed method
# reprocesses.
expect_exit 0 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/nocube" --angle 40 \
	--cube f16 --no-render --quiet --method eq11
check "changed method: all processed" grep -q "4 processed, 0 unchanged" "$T/out"
check "--method: camera by default, eq11 on request" "$PY" - "$O" "$T/nocube" <<'PY'
import json, sys
cam, eq = sys.argv[1:3]
lc = json.load(open(cam + "/object-full/labels.json"))
le = json.load(open(eq + "/object-full/labels.json"))
assert lc["method"] == "camera" and "separability" in lc and "regions" in lc, lc["method"]
assert le["method"] == "pca" and "separability" not in le, le["method"]
obj = {o["capture"]: o for o in json.load(open(cam + "/process.json"))["objects"]}["object-full"]
assert obj["labels_method"]["method"] == "camera" and "separability" in obj
assert json.load(open(eq + "/process.json"))["parameters"]["method"] == "eq11"
print("camera: %d classes of %d materials; eq11: %d classes" % (
    obj["labels_method"]["classes"], obj["labels_method"]["materials"],
    len([c for c in le["classes"] if c["name"] not in ("unclassified", "unknown", "background")])))
PY
expect_exit 2 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$T/bad" --method svm
check "--method svm refused" grep -q "expected camera or eq11" "$T/err"
# A reference from before the camera response existed: labels by eq. 11, and a
# warning that says so (in process.json and the report).
"$PY" - "$O/reference.json" "$T/old-reference.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
r.pop("response", None)
json.dump(r, open(sys.argv[2], "w"))
PY
expect_exit 0 "$KOGEI" process "$S" --reference "$T/old-reference.json" -o "$T/oldref" \
	--cube none --no-render --quiet
check "old reference: eq. 11 labels with a warning" "$PY" - "$T/oldref" <<'PY'
import json, sys
out = sys.argv[1]
obj = {o["capture"]: o for o in json.load(open(out + "/process.json"))["objects"]}["object-full"]
assert obj["labels_method"]["method"] == "eq11", obj["labels_method"]
assert any("no camera response" in w for w in obj["warnings"]), obj["warnings"]
assert "no camera response" in open(out + "/report.html").read()
print("old reference: eq. 11 labels, warned")
PY

# One run at a time into an OUTDIR: a second kogei process is refused while it is locked.
exec 9<"$O"
flock -n 9 || { echo "FAIL: cannot lock $O for the test"; fail=1; }
expect_exit 1 "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$O" --quiet
check "a locked OUTDIR is refused" grep -q "in use by another kogei process" "$T/err"
exec 9<&-

# ---- the site session against the lab's reference ----------------------------------
expect_exit 0 "$KOGEI" process "$S" --reference "$O/reference.json" --spectra "$T/chart.cgats" \
	-o "$T/site" --no-render --quiet
check "site: colour accuracy per patch" "$PY" - "$T/site/process.json" <<'PY'
import json, sys
p = json.load(open(sys.argv[1]))["calibration"]["patches"]
assert len(p) == 15 and all(x["de00_d65"] is not None for x in p), p[0]
PY

# ---- refusals: exit 1, the cause named, nothing written ----------------------------
# No chart: the chart capture shows only the material tiles.
N=$T/nochart
sim_acquire "$N" chart "$T/object.tif" 10000 '' --layout cie-tcs-frame || fail=1
expect_refusal "$T/r1" "chart-0001" "$KOGEI" process "$N" --spectra "$T/chart.cgats" -o "$T/r1"
# The wrong layout: not this chart.
expect_refusal "$T/r2" "chart-0001" "$KOGEI" process "$S" --spectra "$T/chart.cgats" \
	--layout colorchecker24-frame -o "$T/r2"
# The M2 residual above the limit: another photograph of the chart (its own noise)
# against the lab's reference.
R=$T/resid
cp -r "$S" "$R"
# (--layout a file: copied into captures/chart-again/, which process reads)
sim_acquire "$R" chart "$T/chart.tif" 10000 '&seed=5' --layout "$FIX/demo/cie-tcs-frame.json" \
	--name chart-again || fail=1
check "the layout file copied into the session" \
	cmp -s "$R/captures/chart-again/layout.json" "$FIX/demo/cie-tcs-frame.json"
check "the manifest names the copy" \
	grep -q '"chart_layout": *"captures/chart-again/layout.json"' "$R/session.json"
expect_refusal "$T/r3" "residual" "$KOGEI" process "$R" --reference "$O/reference.json" \
	--chart chart-again -o "$T/r3" --max-residual 0.00001
# A 3-patch chart cannot be checked: refused unless --force.
"$PY" - "$FIX/demo/cie-tcs-frame.json" "$T/three.json" <<'PY'
import json, sys
l = json.load(open(sys.argv[1]))
l["name"] = "cie-tcs-three"
l["patches"] = [p for p in l["patches"] if p["id"] in ("TCS02", "TCS05", "TCS09")]
json.dump(l, open(sys.argv[2], "w"))
PY
expect_refusal "$T/r4" "cannot be checked" "$KOGEI" process "$S" --reference "$O/reference.json" \
	--layout "$T/three.json" -o "$T/r4"
expect_exit 0 "$KOGEI" process "$S" --reference "$O/reference.json" --layout "$T/three.json" \
	-o "$T/r4" --force --no-render --quiet
# Unknown exposure: refused unless --assume-same-exposure.
U=$T/unknown
cp -r "$S" "$U"
"$PY" - "$U/session.json" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
for c in m["captures"]:
    if c["name"] == "object-half":
        c["settings"]["exposure_us"] = None  # not recorded
json.dump(m, open(sys.argv[1], "w"), indent=1)
PY
expect_refusal "$T/r5" "object-half" "$KOGEI" process "$U" --reference "$O/reference.json" -o "$T/r5"
check "unknown exposure: the cause" grep -q "exposure" "$T/err"
expect_exit 0 "$KOGEI" process "$U" --reference "$O/reference.json" -o "$T/r5" \
	--assume-same-exposure --no-render --quiet
# Another camera: an object from serial site-2 against the chart of site-1.
C=$T/camera
cp -r "$S" "$C"
sim_acquire "$C" object "$T/object.tif" 10000 '&serial=site-2' --name object-other || fail=1
expect_refusal "$T/r6" "site-2" "$KOGEI" process "$C" --reference "$O/reference.json" -o "$T/r6"
check "another camera: both named" grep -q "site-1" "$T/err"
expect_exit 0 "$KOGEI" process "$C" --reference "$O/reference.json" -o "$T/r6" --force \
	--no-render --quiet
# camera.json records the chart's camera: estimate refuses another camera's image.
expect_exit 0 "$KOGEI" estimate --calib "$O/camera.json" "$S/captures/object-full/rgb.tif" \
	-o "$T/same.hdr"
expect_exit 1 "$KOGEI" estimate --calib "$O/camera.json" "$C/captures/object-other/rgb.tif" \
	-o "$T/other.hdr"
check "estimate: another camera named" grep -q "site-2" "$T/err"
# The session itself as the output.
expect_exit 1 "$KOGEI" process "$S" --reference "$O/reference.json" -o "$S"
check "session as output refused" grep -q "session directory" "$T/err"
# A folder that is not a previous run's is not written into.
mkdir -p "$T/other" && echo x >"$T/other/process.json"
expect_exit 1 "$KOGEI" process "$S" --reference "$O/reference.json" -o "$T/other"
check "foreign process.json refused" grep -q "not a kogei-process/1 file" "$T/err"
# Usage.
expect_exit 2 "$KOGEI" process "$S" -o "$T/x"
expect_exit 2 "$KOGEI" process --reference r.json "$S"

exit $fail
