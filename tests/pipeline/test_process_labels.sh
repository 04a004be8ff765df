#!/bin/sh
# The README's session (the library's ten metals at 30 deg, processed as its lab session)
# through two cameras and lights: the demo's site camera under CIE A, and a Nikon D5100
# (SOURCE_ROOT/../shared/reference/cameras/Nikon_D5100.csv, skipped when absent) under
# D50. Every tile region (the sim's truth gives its material) is labelled with a class
# that holds its material: the region test carries each material's own model error
# (the library's model_rsd), not only the calibration's. Then the warnings: process.json
# lists the unknown regions and a large share of unknown pixels, when the library lacks
# two of the metals (--only without copper and shakudo).
# usage: test_process_labels.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
ROOT=$2
FIX=$ROOT/fixtures
. "$(dirname "$0")/sim_session.sh"
sim_session_needs "${3:-1}" json
kg_temp
CAM='format=bayer_rggb12&fullwell=20000&read=5&serial=site-1'

# session DIR CAMERA.csv ILLUMINANT [process options...]: the README's commands
session() {
	d=$1 cam=$2 ill=$3
	shift 3
	mkdir -p "$d" &&
	"$KOGEI" sim chart --layout cie-tcs-frame --spectra /usr/share/colord/ref/CIE-TCS.sp \
		--camera "$cam" --illuminant "$ill" --tilt 25 --width 800 --height 600 \
		-o "$d/chart.tif" >/dev/null &&
	"$KOGEI" sim image --materials default --camera "$cam" --illuminant "$ill" --angle 30 \
		--patch-size 40 --size 800x600 -o "$d/object.tif" \
		--truth-labels "$d/truth.hdr" >/dev/null &&
	"$KOGEI" acquire --camera "sim:$d/chart.tif?$CAM&light=0" --out "$d/S" --kind dark \
		--exposure 10000 --gain 0 >/dev/null &&
	"$KOGEI" acquire --camera "sim:$d/chart.tif?$CAM&uniform=0.6" --out "$d/S" --kind flat \
		--exposure 10000 --gain 0 >/dev/null &&
	"$KOGEI" acquire --camera "sim:$d/chart.tif?$CAM" --out "$d/S" --kind chart \
		--exposure 10000 --gain 0 --layout cie-tcs-frame ${ACQUIRE_FLAT:-} >/dev/null &&
	"$KOGEI" acquire --camera "sim:$d/object.tif?$CAM" --out "$d/S" --kind object \
		--exposure 10000 --gain 0 ${ACQUIRE_FLAT:-} >/dev/null &&
	"$KOGEI" measure --spectro sim:/usr/share/colord/ref/CIE-TCS.sp --chart cie-tcs-frame \
		--illuminant "$ill" --yes -o "$d/chart.cgats" >/dev/null 2>&1 ||
	"$KOGEI" measure --spectro sim:/usr/share/colord/ref/CIE-TCS.sp --chart cie-tcs-frame \
		--yes -o "$d/chart.cgats" >/dev/null 2>&1 || return 1
	"$KOGEI" process "$d/S" --spectra "$d/chart.cgats" -o "$d/out" "$@" >"$d/process.log" 2>&1 ||
		{ cat "$d/process.log"; return 1; }
}

# check_regions DIR WHAT: every region of >= 500 pixels (a tile is 1600) mostly of one
# library material in the truth has a decided label that holds that material.
check_regions() {
	"$PY" - "$1" "$2" <<'PYEOF' || fail=1
import array, glob, json, os, sys
d, what = sys.argv[1], sys.argv[2]
def hdr(p):
    h, key, val = {}, None, ""
    for line in open(p):
        if key is None and "=" in line:
            key, val = [x.strip() for x in line.split("=", 1)]
        elif key is not None:
            val += " " + line.strip()
        if key is not None and (not val.startswith("{") or "}" in val):
            h[key] = val.strip("{} ")
            key = None
    return h
def load(p):
    h = hdr(p)
    base = os.path.splitext(p)[0]
    data = base if os.path.exists(base) else base + ".img"
    dt = int(h["data type"])
    typ = {1: "B", 13: "I", 12: "H", 4: "f", 3: "i"}[dt]
    a = array.array(typ)
    with open(data, "rb") as f:
        a.frombytes(f.read())
    if h.get("byte order", "0") == "1" and a.itemsize > 1:
        a.byteswap()
    names = [s.strip() for s in h.get("class names", "").split(",")]
    return a, names
truth, tnames = load(os.path.join(d, "truth.hdr"))
objs = sorted(glob.glob(os.path.join(d, "out", "*", "labels_regions.hdr")))
if not objs:
    print("FAIL: %s: no labels_regions.hdr" % what); sys.exit(1)
reg, _ = load(objs[0])
import csv, collections
rows = {}
with open(objs[0].replace(".hdr", ".csv")) as f:
    for r in csv.DictReader(f):
        rows[int(r["region"])] = r
votes = collections.defaultdict(collections.Counter)
for t, g in zip(truth, reg):
    if g:
        votes[g][t] += 1
bad = ok = 0
for g, c in votes.items():
    n = sum(c.values())
    t, k = c.most_common(1)[0]
    if n < 500 or k < 0.9 * n or t == 0 or t >= len(tnames):
        continue
    mat = tnames[t]
    r = rows.get(g)
    lab = r["label"] if r else "?"
    holds = mat in lab.split("|")
    print("%s: region %d (%d px) of %s: %s (class %s, mean d2 %s)%s" %
          (what, g, n, mat, lab, r["class"] if r else "?", r.get("mean_d2", "?") if r else "?",
           "" if holds else "  <- FAIL"))
    ok += holds
    bad += not holds
print("%s: %d of %d tile regions labelled with a class that holds their material" % (what, ok, ok + bad))
if bad or ok < 10:
    print("FAIL: %s: %d regions wrong, %d right (10 expected)" % (what, bad, ok)); sys.exit(1)
PYEOF
}

session "$T/site" "$FIX/demo/site_camera.csv" A || { echo "FAIL: the README's session"; exit 1; }
check_regions "$T/site" "site camera, A"
# warnings WHAT OUTDIR PATTERN WANT: process.json (object and session lists) and
# report.html hold a warning matching PATTERN (WANT 1) or none (WANT 0)
warnings() {
	"$PY" - "$@" <<'PYEOF' || fail=1
import json, re, sys
what, out, pat, want = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4] == "1"
pj = json.load(open(out + "/process.json"))
obj = [w for o in pj["objects"] for w in o.get("warnings", [])]
top = pj.get("warnings", [])
html = open(out + "/report.html").read()
hit = [w for w in obj if re.search(pat, w)]
for w in hit:
    print("%s: warning: %s" % (what, w))
# each warning once, in its scope: an object's is not repeated in the session's list
ok = bool(hit) == want and not [w for w in top if re.search(pat, w)]
if want and hit:
    # the report escapes the text; its first words are enough
    ok = ok and hit[0][:40] in html
if not ok:
    print("FAIL: %s: a warning /%s/ %s in process.json and the report" %
          (what, pat, "expected" if want else "not expected")); sys.exit(1)
PYEOF
}
S=$T/site
warnings "site camera, A" "$S/out" "decided unknown|region.*decided otherwise" 0
# the pooled test without the model's error (model_rsd removed).
# On captures flat-corrected by kogei process (acquired with --flat none), whose
# demosaicing leaves the colour errors the model's error has to cover.
ACQUIRE_FLAT="--flat none" session "$T/pflat" "$FIX/demo/site_camera.csv" A ||
	{ echo "FAIL: the session flat-corrected by process"; exit 1; }
S=$T/pflat
# the flat divided by process (low-passed, as acquire does): every region still right
check_regions "$T/pflat" "flat by process"
"$PY" -c 'import json, sys
d = json.load(open(sys.argv[1]))
for m in d["materials"]: m.pop("model_rsd", None)
json.dump(d, open(sys.argv[2], "w"))' "$FIX/materials/default.json" "$T/norsd.json"
"$KOGEI" process "$S/S" --spectra "$S/chart.cgats" -o "$T/norsd" --materials "$T/norsd.json" \
	>"$T/norsd.log" 2>&1 || { cat "$T/norsd.log"; fail=1; }
n=$(grep -c ',unknown,' "$T"/norsd/*/labels_regions.csv)
echo "without model_rsd: $n of the 10 tile regions unknown"
# Before the flat was low-passed (issue 47 item 9b) some regions came out unknown
# here: the raw flat's pixel noise, which the variance does not carry, pushed their
# pooled test over the threshold; with it low-passed none does on this data, so the
# unknown-region warning is checked when there are any (its wording is checked by
# tests/pipeline label-warnings).
if [ "$n" -ge 1 ]; then
	warnings "without model_rsd" "$T/norsd" "$n regions? of 100 pixels or more decided unknown" 1
	grep -q "warning: .*decided unknown" "$T/norsd.log" ||
		{ echo "FAIL: the summary does not print the unknown regions"; fail=1; }
fi
S=$T/site
# copper and shakudo not declared: their pixels unknown, a large share of the object's
"$KOGEI" process "$S/S" --spectra "$S/chart.cgats" -o "$T/only" \
	--only gold,silver,shibuichi-nami,shibuichi-shiro,shibuichi-jo,shibuichi-nami-uchisanbu,shibuichi-nami-sotosanbu,urushi \
	>"$T/only.log" 2>&1 || { cat "$T/only.log"; fail=1; }
warnings "copper and shakudo undeclared" "$T/only" "% of the object's pixels are unknown" 1
warnings "site camera, A (all declared)" "$S/out" "% of the object's pixels are unknown" 0

D5100=$ROOT/../shared/reference/cameras/Nikon_D5100.csv
if [ -r "$D5100" ]; then
	session "$T/nikon" "$D5100" D50 || { echo "FAIL: the session through a D5100"; exit 1; }
	check_regions "$T/nikon" "Nikon D5100, D50"
else
	echo "note: $D5100 absent; the D5100 session is not run"
fi
exit $fail
