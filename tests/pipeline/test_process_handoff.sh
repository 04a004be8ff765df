#!/bin/sh
# The renderer handoff carries what the regions resolved. The README's session (the
# library's ten metals at 30 deg through the demo's site camera under CIE A): the
# pixels of two tiles read the compound class copper|shakudo and three read the
# shibuichi-nami class of three members, while the regions' pooled likelihood
# resolves them (copper, shakudo, and the three shibuichi-nami variants). Checked:
#   - labels.hdr stays the pixels' classes (the compound ones included);
#   - labels_materials.hdr holds, on every pixel of every region of
#     labels_regions.hdr, the label labels_regions.csv gives that region, and the
#     pixel's class elsewhere; at least one region differs from its pixels' class;
#   - scene.json projects labels_materials.hdr; object.glb has a material named after
#     every label the regions table decided (shakudo among them) and no compound one
#     that no region left compound; the Mitsuba XML a shape per decided material;
#   - captures flat-corrected by kogei process and the library's model error removed
#     (model_rsd), as in test process-labels: regions decided unknown are "unknown" in
#     the material map and the glb, not their pixels' metal.
# Then a compound class left unresolved: `kogei export` of a scene whose label map
# holds "copper|shakudo" mapped to copper writes a glb material named
# "copper|shakudo" (extras: kogei_material copper, compound true) apart from copper,
# and the Mitsuba XML names the class beside copper's shape. The glbs pass the Khronos
# glTF-Validator (when scripts/setup.sh installed it).
# usage: test_process_handoff.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
ROOT=$2
FIX=$ROOT/fixtures
. "$(dirname "$0")/sim_session.sh"
sim_session_needs "${3:-1}" json
kg_temp
fail=0
d=$T/site
mkdir -p "$d"
cam=$FIX/demo/site_camera.csv
"$KOGEI" sim chart --layout cie-tcs-frame --spectra "$TCS" --camera "$cam" --illuminant A \
	--tilt 25 --width 800 --height 600 -o "$d/chart.tif" >/dev/null &&
"$KOGEI" sim image --materials default --camera "$cam" --illuminant A --angle 30 \
	--patch-size 40 --size 800x600 -o "$d/object.tif" >/dev/null &&
sim_acquire "$d/S" dark "$d/chart.tif" 10000 "&light=0" &&
sim_acquire "$d/S" flat "$d/chart.tif" 10000 "&uniform=0.6" &&
sim_acquire "$d/S" chart "$d/chart.tif" 10000 "" --layout cie-tcs-frame &&
sim_acquire "$d/S" object "$d/object.tif" 10000 &&
sim_measure "$d/chart.cgats" || { echo "FAIL: the session could not be recorded"; exit 1; }
"$KOGEI" process "$d/S" --spectra "$d/chart.cgats" -o "$d/out" >"$d/process.log" 2>&1 ||
	{ cat "$d/process.log"; exit 1; }
# the same captures acquired without a flat (kogei process flat-corrects them; the
# demosaicing's colour errors are what the model error covers), processed without
# model_rsd: regions decided unknown (test process-labels)
sim_acquire "$d/P" dark "$d/chart.tif" 10000 "&light=0" &&
sim_acquire "$d/P" flat "$d/chart.tif" 10000 "&uniform=0.6" &&
sim_acquire "$d/P" chart "$d/chart.tif" 10000 "" --layout cie-tcs-frame --flat none &&
sim_acquire "$d/P" object "$d/object.tif" 10000 "" --flat none ||
	{ echo "FAIL: the second session could not be recorded"; exit 1; }
"$PY" -c 'import json, sys
d = json.load(open(sys.argv[1]))
for m in d["materials"]: m.pop("model_rsd", None)
json.dump(d, open(sys.argv[2], "w"))' "$FIX/materials/default.json" "$T/norsd.json"
"$KOGEI" process "$d/P" --spectra "$d/chart.cgats" -o "$d/norsd" --materials "$T/norsd.json" \
	>"$d/norsd.log" 2>&1 || { cat "$d/norsd.log"; exit 1; }

cat >"$T/check.py" <<'PYEOF'
import array, csv, glob, json, os, re, struct, sys
out, what, want = sys.argv[1], sys.argv[2], sys.argv[3]

def hdr(p):
    h, key, val = {}, None, ""
    for line in open(p):
        if key is None and "=" in line:
            key, val = [x.strip() for x in line.split("=", 1)]
        elif key is not None:
            val += " " + line.strip()
        if key is not None and (not val.startswith("{") or "}" in val):
            h[key] = val.strip().strip("{}").strip()
            key = None
    return h

def load(p):
    h = hdr(p)
    base = os.path.splitext(p)[0]
    data = base if os.path.exists(base) else base + ".img"
    typ = {1: "B", 13: "I", 12: "H", 4: "f"}[int(h["data type"])]
    a = array.array(typ)
    a.frombytes(open(data, "rb").read())
    if h.get("byte order", "0") == "1" and a.itemsize > 1:
        a.byteswap()
    names = [s.strip() for s in h.get("class names", "").split(",")] if "class names" in h else None
    return a, names

def glb_json(p):
    d = open(p, "rb").read()
    n = struct.unpack("<I", d[12:16])[0]
    return json.loads(d[20:20 + n])

objs = sorted(glob.glob(os.path.join(out, "*", "labels.json")))
if len(objs) != 1:
    print("FAIL: %s: %d objects in %s" % (what, len(objs), out)); sys.exit(1)
o = os.path.dirname(objs[0])
bad = []
lj = json.load(open(objs[0]))
labels, lnames = load(os.path.join(o, "labels.hdr"))
regions, _ = load(os.path.join(o, "labels_regions.hdr"))
mats, mnames = load(os.path.join(o, "labels_materials.hdr"))
# labels.hdr: the pixels' classes, as labels.json lists them
jnames = [c["name"] for c in lj["classes"]]
if sorted(set(lnames) - {"unclassified"}) != sorted(set(jnames) - {"unclassified"}):
    bad.append("labels.hdr's classes %s are not labels.json's %s" % (lnames, jnames))
rows = {int(r["region"]): r for r in csv.DictReader(open(os.path.join(o, "labels_regions.csv")))}
wrong = 0
for i, g in enumerate(regions):
    want_name = rows[g]["label"] if g else lnames[labels[i]]
    if mnames[mats[i]] != want_name:
        wrong += 1
if wrong:
    bad.append("%d pixels of labels_materials.hdr are not their region's label (or their class)" % wrong)
table = lj["regions"]["table"]
differ = [r for r in table if r.get("differs")]
for r in table:
    print("%s: region %d (%d px): pixels %s, decided %s" % (what, r["region"], r["pixels"],
                                                          r["pixel_class"], r["label"]))
if not differ:
    bad.append("no region decided otherwise than its pixels' class: nothing tested")
if want not in {r["label"] for r in differ}:
    bad.append("no region decided %s apart from its pixels' class" % want)
if lj["files"].get("materials") is None:
    bad.append("labels.json: files.materials is null")
sc = json.load(open(os.path.join(o, "scene.json")))
if sc["materials"]["label_map"]["file"] != "labels_materials.hdr":
    bad.append("scene.json projects %s" % sc["materials"]["label_map"]["file"])
g = glb_json(os.path.join(o, "object.glb"))
gnames = {m["name"]: m for m in g["materials"]}
decided = {r["label"] for r in table}
for lab in sorted(decided):
    if lab not in gnames:
        bad.append("object.glb has no material %s (a region's decision)" % lab)
for name, m in gnames.items():
    if "|" in name and name not in decided:
        # a compound class no region left compound may only cover stray pixels
        px = sum(1 for v in mats if mnames[v] == name)
        if px > 0.01 * len(mats):
            bad.append("object.glb's compound material %s covers %d pixels that no region left compound" % (name, px))
print("%s: object.glb materials: %s" % (what, ", ".join(sorted(gnames))))
xml = os.path.join(o, "object_mitsuba.xml")
if os.path.exists(xml):
    ids = set(re.findall(r'<shape type="ply" id="shape_([^"]+)"', open(xml).read()))
    for lab in decided - {"unknown"}:
        if re.sub(r"[^A-Za-z0-9._-]", "_", lab) not in ids:
            bad.append("object_mitsuba.xml has no shape for %s" % lab)
    print("%s: Mitsuba shapes: %s" % (what, ", ".join(sorted(ids))))
for b in bad:
    print("FAIL: %s: %s" % (what, b))
sys.exit(1 if bad else 0)
PYEOF
"$PY" "$T/check.py" "$d/out" "all declared" shakudo || fail=1
"$PY" "$T/check.py" "$d/norsd" "without model_rsd" unknown || fail=1

# a compound class left unresolved keeps its name in the glb
"$PY" - "$T" <<'PYEOF' || fail=1
import json, os, sys
t = sys.argv[1]
w, h = 64, 48
with open(os.path.join(t, "cmap.img"), "wb") as f:
    f.write(bytes((1 if x < w // 2 else 2) for y in range(h) for x in range(w)))
with open(os.path.join(t, "cmap.hdr"), "w") as f:
    f.write("ENVI\nsamples = %d\nlines = %d\nbands = 1\nheader offset = 0\n"
            "file type = ENVI Classification\ndata type = 1\ninterleave = bsq\n"
            "byte order = 0\nclasses = 3\nclass names = {unclassified, copper|shakudo, gold}\n"
            % (w, h))
cam = {"position": [0, 0, 2], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov_deg": 40}
scene = {"format": "kogei-scene/1",
         "mesh": [{"generator": "plane", "half_size": 1.0, "segments": 16}],
         "materials": {"library": "default",
                       "label_map": {"file": "cmap.hdr", "camera": cam,
                                     "classes": {"copper|shakudo": "copper"},
                                     "fallback": "neutral-grey"}},
         "light": {"illuminant": "D65", "direction": [0, 0, 1], "intensity": 1},
         "camera": dict(cam, width=64, height=48)}
json.dump(scene, open(os.path.join(t, "cscene.json"), "w"))
PYEOF
if "$KOGEI" export --scene "$T/cscene.json" -o "$T/c.glb" >"$T/out" 2>&1; then
	"$PY" - "$T/c.glb" <<'PYEOF' || fail=1
import json, struct, sys
d = open(sys.argv[1], "rb").read()
g = json.loads(d[20:20 + struct.unpack("<I", d[12:16])[0]])
m = {x["name"]: x for x in g["materials"]}
print("compound scene: glb materials %s" % sorted(m))
c = m.get("copper|shakudo")
ok = (c is not None and c["extras"]["kogei_material"] == "copper" and c["extras"]["compound"]
      and c["extras"]["kogei_class"] == "copper|shakudo" and "gold" in m and "copper" not in m
      and c["pbrMetallicRoughness"]["baseColorFactor"] != m["gold"]["pbrMetallicRoughness"]["baseColorFactor"])
if not ok:
    print("FAIL: the compound class copper|shakudo is not its own glb material rendered as copper")
sys.exit(0 if ok else 1)
PYEOF
else
	echo "FAIL: kogei export of the compound scene"
	cat "$T/out"
	fail=1
fi
# the glbs against the Khronos glTF-Validator, where scripts/setup.sh installed it
if command -v node >/dev/null 2>&1 && [ -d "$ROOT/.tools/gltf-validator" ]; then
	node "$ROOT/tests/gltf_validate.mjs" "$ROOT/.tools/gltf-validator" "$d"/out/*/object.glb \
		"$T/c.glb"
	rc=$?
	[ "$rc" = 0 ] || [ "$rc" = 77 ] || { echo "FAIL: glTF-Validator (exit $rc)"; fail=1; }
else
	echo "note: no node or gltf-validator (scripts/setup.sh): the glbs are not validated"
fi
# and the Mitsuba XML names it beside the material it renders as (needs Embree)
if "$KOGEI" export --scene "$T/cscene.json" -o "$T/c.xml" >"$T/out" 2>&1; then
	grep -q 'label-map class copper|shakudo (compound.*renders as copper' "$T/c.xml" ||
		{ echo "FAIL: the Mitsuba XML does not name the compound class copper|shakudo"; fail=1; }
elif grep -q "needs Embree" "$T/out"; then
	echo "note: built without Embree: no Mitsuba XML of a label map"
else
	echo "FAIL: kogei export of the compound scene's Mitsuba XML"
	cat "$T/out"
	fail=1
fi
exit $fail
