#!/bin/sh
# `kogei render --mitsuba`: the Mitsuba 3 scene of a kogei scene, checked structurally
# against Mitsuba 3's plugin reference by mitsuba_check.py (no Mitsuba is installable
# here, so nothing renders it): the demo object (per-face ids, all ten library
# materials, an image environment), a label-map scene (the map projected onto the
# mesh as the renderer does it), the alloys as blends of their metals' n, k, the
# metals' n, k against kogei model, and refusals that leave nothing behind.
# usage: test_mitsuba.sh KOGEI SOURCE_ROOT HAVE_EMBREE
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
SRC=$2
kg_need "${3:-0}" "the renderer was built without Embree 3 (libembree-dev): label maps cannot be projected"
PY=$(command -v python3) || { echo "SKIP: python3 not found"; exit 77; }
CHECK=$SRC/tests/render/mitsuba_check.py
kg_temp
run() { # what, command...
	what=$1; shift
	if "$@" >"$T/out" 2>&1; then
		cat "$T/out"
	else
		echo "FAIL: $what"; cat "$T/out"; fail=1
	fi
}

# 1. The demo object: ten materials, each its own PLY; n, k of three metals against
# kogei model's normal-incidence reflectance.
demo=$SRC/fixtures/demo/tsuba_scene.json
run "export the demo object" "$KOGEI" render --scene "$demo" --mitsuba "$T/demo.xml"
for m in gold silver copper; do
	run "kogei model $m" "$KOGEI" model --material $m --angles 0:5:5 -o "$T/$m.csv"
done
run "demo.xml structure" "$PY" "$CHECK" "$T/demo.xml" --scene "$demo" \
	--model-csv gold="$T/gold.csv" --model-csv silver="$T/silver.csv" \
	--model-csv copper="$T/copper.csv"
n=$(ls "$T/demo" | grep -c '\.ply$')
[ "$n" = 10 ] || { echo "FAIL: $n PLY files for the demo's ten materials"; fail=1; }

# 2. Alloys by their mixture: each blend's weight is the component's fraction of the
# components so far, and every component carries its metal's own n, k.
run "alloys as blends" "$PY" - "$T/demo.xml" "$SRC/fixtures/materials/default.json" <<'PY'
import json, sys
import xml.etree.ElementTree as ET
root = ET.parse(sys.argv[1]).getroot()
lib = {m["name"]: m for m in json.load(open(sys.argv[2]))["materials"]}
top = {b.get("id"): b for b in root.findall("bsdf")}
def nk(el):
    c = next(x for x in el.iter("bsdf") if x.get("type") == "roughconductor")
    return tuple(c.find("spectrum[@name='%s']" % k).get("value") for k in ("eta", "k"))
checked = 0
for name, m in lib.items():
    if m["kind"] != "alloy":
        continue
    comps = m["components"]
    el = top[name].find("bsdf")
    # walk the nested blends from the last component back to the first
    for i in range(len(comps) - 1, -1, -1):
        if i == 0:
            part = el
        else:
            assert el.get("type") == "blendbsdf", (name, i)
            w = float(el.find("float[@name='weight']").get("value"))
            want = comps[i]["fraction"] / sum(c["fraction"] for c in comps[:i + 1])
            assert abs(w - want) < 1e-5, (name, i, w, want)
            a, part = el.findall("bsdf")
            assert a.get("id") < part.get("id"), "blendbsdf takes its BSDFs in id order"
        metal = comps[i]["material"]
        assert nk(part) == nk(top[metal]), (name, metal, "n, k differ from the metal's")
        checked += 1
        if i:
            el = a
print("alloys: %d components of %d alloys carry their metal's n, k with the library's "
      "weights" % (checked, sum(1 for m in lib.values() if m["kind"] == "alloy")))
assert checked >= 10
PY

# 3. A label map: the truth of the inlay scene rendered small, projected back from the
# same camera; every region gets its own PLY and together they hold every triangle.
inlay=$SRC/fixtures/scenes/tsuba_inlay.json
run "truth labels" "$KOGEI" render --scene "$inlay" --width 160 --height 120 --spp 1 \
	--wavelengths 1 --quiet -o "$T/inlay.png" --truth-labels "$T/inlay_labels.hdr"
"$PY" - "$inlay" "$T/label_scene.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
cam = dict(s["camera"]); cam.pop("width"); cam.pop("height")
s["materials"] = {"library": "default", "label_map": {"file": "inlay_labels.hdr", "camera": cam,
                  "fallback": "neutral-grey"}}
s["light"] = {"illuminant": "D65", "direction": [0.3, -1, 1.2], "intensity": 1.2}
s["camera"]["width"], s["camera"]["height"] = 160, 120
json.dump(s, open(sys.argv[2], "w"))
PY
run "export the label-map scene" "$KOGEI" render --scene "$T/label_scene.json" --mitsuba "$T/lm.xml"
run "lm.xml structure" "$PY" "$CHECK" "$T/lm.xml" --scene "$T/label_scene.json"
run "export the face-id scene" "$KOGEI" render --scene "$inlay" --mitsuba "$T/ids.xml"
for m in shakudo copper gold silver neutral-grey; do
	[ -s "$T/lm/$m.ply" ] || { echo "FAIL: no lm/$m.ply"; fail=1; }
done
faces() { # the face counts of the PLYs of a folder, summed
	for f in "$1"/*.ply; do sed -n 's/^element face //p' "$f" | head -n 1; done |
		awk '{s += $1} END {print s}'
}
a=$(faces "$T/lm"); b=$(faces "$T/ids")
echo "label map: $a triangles over $(ls "$T/lm" | wc -l) PLYs; face ids: $b"
[ "$a" = "$b" ] && [ "$a" -gt 1000 ] || { echo "FAIL: the label map's PLYs hold $a triangles, the mesh $b"; fail=1; }

# kogei export -o X.xml writes the same files as kogei render --mitsuba.
mkdir "$T/exp"
run "kogei export -o .xml" "$KOGEI" export --scene "$demo" -o "$T/exp/demo.xml"
cmp -s "$T/demo.xml" "$T/exp/demo.xml" && cmp -s "$T/demo/gold.ply" "$T/exp/demo/gold.ply" ||
	{ echo "FAIL: kogei export -o demo.xml differs from kogei render --mitsuba"; fail=1; }
"$KOGEI" export --scene "$demo" -o "$T/nowhere/x.xml" >"$T/out" 2>&1 &&
	{ echo "FAIL: export into a missing folder succeeded"; fail=1; }
[ -e "$T/nowhere" ] && { echo "FAIL: export made the missing folder"; fail=1; }

# 4. Refusals leave nothing: a missing folder, a bad scene, options that do not apply.
"$KOGEI" render --scene "$demo" --mitsuba "$T/nowhere/x.xml" >"$T/out" 2>&1 &&
	{ echo "FAIL: --mitsuba into a missing folder succeeded"; fail=1; }
grep -q "nowhere" "$T/out" || { echo "FAIL: the message does not name the folder"; cat "$T/out"; fail=1; }
printf '{"format": "kogei-scene/1", "mesh": {"generator": "plane"}, "materials": {"material": "unobtainium"}, "light": {"illuminant": "D65", "direction": [0, 0, 1]}, "camera": {"position": [0, -1, 2], "look_at": [0, 0, 0], "fov_deg": 40, "width": 8, "height": 8}}\n' >"$T/bad.json"
"$KOGEI" render --scene "$T/bad.json" --mitsuba "$T/bad.xml" >"$T/out" 2>&1
rc=$?
[ "$rc" = 1 ] || { echo "FAIL: a bad scene exited $rc (expected 1)"; cat "$T/out"; fail=1; }
grep -q "unobtainium" "$T/out" || { echo "FAIL: the message does not name the material"; cat "$T/out"; fail=1; }
[ -e "$T/bad.xml" ] && { echo "FAIL: a refused export left bad.xml"; fail=1; }
"$KOGEI" render --scene "$demo" --mitsuba "$T/x.xml" --spp 4 >"$T/out" 2>&1
rc=$?
[ "$rc" = 2 ] || { echo "FAIL: --mitsuba with --spp exited $rc (expected 2)"; fail=1; }

# 5. The checker itself fails on what Mitsuba would refuse (a test that could fail).
sed 's/name="alpha"/name="roughness"/' "$T/demo.xml" >"$T/wrong.xml"
ln -s "$T/demo" "$T/wrong"
if "$PY" "$CHECK" "$T/wrong.xml" >"$T/out" 2>&1; then
	echo "FAIL: the checker passed a roughconductor with a 'roughness' parameter"; fail=1
else
	grep -q "roughness" "$T/out" || { echo "FAIL: checker message"; cat "$T/out"; fail=1; }
fi
[ $fail = 0 ] && echo "PASS: Mitsuba 3 export"
exit $fail
