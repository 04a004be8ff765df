#!/bin/sh
# Regions too small for the noise (issue 47 item 6), with the sim devices' session:
#  - A uniform 20 % grey card alone (its truth: no material anywhere). Per pixel some of
#    its pixels read a material (urushi, the near-neutral dielectric), in regions of a
#    few pixels; in the material map (labels_materials.hdr, what the handoff renders)
#    no connected region of a material is smaller than the pixels LABELS.json says a
#    pooled decision against its surroundings needs, no pixel of the card holds a
#    material, the merged pixels recorded (labels.json, process.json) are those the
#    maps show changed, and the report says so.
#  - Two materials on the card (gold and urushi, tiles of 12 x 12 pixels, more than the
#    55 or so urushi needs against the card but few): every pixel of each tile that
#    reads its material keeps it in the material map (no over-merging).
# usage: test_process_speckle.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
FIX=$2/fixtures
. "$(dirname "$0")/sim_session.sh"
sim_session_needs "${3:-1}" numpy
kg_temp

sim_scenes "$T" || { echo "FAIL: simulated scenes"; exit 1; }
cat >"$T/card.json" <<'EOJ'
{"format": "kogei-materials/1", "materials": [
 {"name": "card", "kind": "dielectric", "n": 1.0, "body": 0.2, "gloss": 0, "mirror": 0}]}
EOJ
"$KOGEI" sim image --materials "$T/card.json" --camera "$FIX/demo/site_camera.csv" \
	--illuminant A --patch-size 40 --background 0.2 --white-level 0.9 --size 800x600 \
	--noise none --depth float -o "$T/card.tif" >/dev/null ||
	{ echo "FAIL: sim image of the card"; exit 1; }
"$KOGEI" sim image --materials default --only gold,urushi --camera "$FIX/demo/site_camera.csv" \
	--illuminant A --angle 30 --patch-size 12 --gap 12 --background 0.2 --white-level 0.9 \
	--size 800x600 --noise none --depth float -o "$T/pair.tif" \
	--truth-labels "$T/pair_truth.hdr" >/dev/null ||
	{ echo "FAIL: sim image of gold and urushi on the card"; exit 1; }
S=$T/S
sim_acquire "$S" dark "$T/chart.tif" 10000 '&light=0' || fail=1
sim_acquire "$S" flat "$T/chart.tif" 10000 '&uniform=0.6' || fail=1
sim_acquire "$S" chart "$T/chart.tif" 10000 '' --layout cie-tcs-frame || fail=1
sim_acquire "$S" object "$T/card.tif" 10000 '&seed=3' --name card || fail=1
sim_acquire "$S" object "$T/pair.tif" 10000 '&seed=4' --name pair || fail=1
sim_measure "$T/chart.cgats" || { echo "FAIL: kogei measure"; fail=1; }
[ $fail = 0 ] || exit 1
O=$T/res
run_or_exit "$KOGEI" process "$S" --spectra "$T/chart.cgats" -o "$O" --quiet

"$PY" - "$O" "$T/pair_truth.hdr" <<'PY' || fail=1
import csv, json, sys
import numpy as np
out, pair_truth = sys.argv[1:3]

def envi(hdr):
    h = open(hdr).read()
    key = lambda k: h.split(k)[1].split("=")[1].split("\n")[0].strip()
    s, l = int(key("samples")), int(key("lines"))
    dt = {"1": "u1", "13": "<u4", "4": "<f4"}[key("data type")]
    names = None
    if "class names" in h:
        names = [n.strip() for n in h.split("class names")[1].split("{")[1].split("}")[0].split(",")]
    return np.fromfile(hdr[:-4] + ".img", dtype=dt).reshape(l, s), names

def components(mask):
    """4-connected components of mask: (label image, sizes)"""
    lab = np.zeros(mask.shape, dtype=np.int64)
    H, W = mask.shape
    n = 0
    sizes = [0]
    for y0, x0 in zip(*np.nonzero(mask)):
        if lab[y0, x0]:
            continue
        n += 1
        lab[y0, x0] = n
        stack, k = [(y0, x0)], 0
        while stack:
            y, x = stack.pop()
            k += 1
            for yy, xx in ((y - 1, x), (y + 1, x), (y, x - 1), (y, x + 1)):
                if 0 <= yy < H and 0 <= xx < W and mask[yy, xx] and not lab[yy, xx]:
                    lab[yy, xx] = n
                    stack.append((yy, xx))
        sizes.append(k)
    return lab, sizes

bad = 0
def check(ok, what):
    global bad
    print(("ok: " if ok else "FAIL: ") + what)
    bad += not ok

def material_regions(d, obj):
    """every connected region of one material label in the material map at least the
    pixels LABELS.json says its class needs against the label around it"""
    pix, pnames = envi(d + "/labels.hdr")
    mat, mnames = envi(d + "/labels_materials.hdr")
    need = json.load(open(d + "/labels.json"))["regions"].get("small", {}).get("min_pixels")
    check(need is not None, "%s: labels.json gives the pixels a region needs" % obj)
    need = need or {}
    classes = [n for n in pnames[1:] if n not in ("unknown", "background")]
    nonmat = {0, mnames.index("unknown"), mnames.index("background")}
    H, W = mat.shape
    worst = None
    for l in range(len(mnames)):
        if l in nonmat:
            continue
        lab, sizes = components(mat == l)
        for c in range(1, len(sizes)):
            m = lab == c
            # its pixels' class, and the label most of its border holds
            pc = pnames[np.bincount(pix[m]).argmax()]
            grow = np.zeros_like(m)
            grow[1:] |= m[:-1]; grow[:-1] |= m[1:]; grow[:, 1:] |= m[:, :-1]; grow[:, :-1] |= m[:, 1:]
            border = mat[grow & ~m]
            border = border[border != 0]
            host = mnames[np.bincount(border).argmax()] if border.size else "unknown"
            # without the table: a region of one pixel is too small
            n = need[pc].get("isolated" if host == "unknown" else host, 0) if pc in need else 2
            if sizes[c] < n:
                worst = (mnames[l], sizes[c], host, n)
    check(worst is None, "%s: no region of a material in the material map smaller than "
          "its class needs against its surroundings%s" % (obj, "" if worst is None else
          " (%s: %d pixels amid %s, %s needed)" % worst))
    return pix, pnames, mat, mnames

# ---- the card alone --------------------------------------------------------------------
d = out + "/card"
lj = json.load(open(d + "/labels.json"))
small = lj["regions"].get("small", {})
for k in ("one_pixel_regions", "one_pixel_regions_kept", "merged_regions", "merged_pixels",
          "unknown_pixels"):
    small.setdefault(k, -1)
pix, pnames, mat, mnames = material_regions(d, "card")
nonmat_p = [pnames.index(n) for n in ("unclassified", "unknown", "background")]
speckle = ~np.isin(pix, nonmat_p)
print("card: %d pixels read a material (%s); %d regions of one pixel; merged %d regions, "
      "%d pixels (%d unknown)" % (speckle.sum(), ", ".join(sorted({pnames[v] for v in
      pix[speckle]})), small["one_pixel_regions"], small["merged_regions"],
      small["merged_pixels"], small["unknown_pixels"]))
ones = sum(1 for l in set(np.unique(mat)) - {mnames.index(n) for n in ("unclassified",
           "unknown", "background")} for k in components(mat == l)[1][1:] if k == 1)
print("card: the material map holds %d regions of one pixel" % ones)
check(speckle.sum() >= 100,
      "card: per pixel, the card shows speckle (the case the rule is for)")
held = np.isin(mat, [mnames.index(n) for n in ("unclassified", "unknown", "background")])
check(held.all(), "card: no pixel of the material map holds a material (%d do)" % (~held).sum())
check(small["one_pixel_regions_kept"] == 0, "card: no region of one pixel is kept")
scene = json.load(open(d + "/scene.json"))
check(scene["materials"]["label_map"]["file"] == "labels_materials.hdr",
      "card: the handoff (scene.json, and the render) uses the material map")
# the merged pixels recorded are those the maps show changed, region by region
reg, _ = envi(d + "/labels_regions.hdr")
rows = list(csv.DictReader(open(d + "/labels_regions.csv")))
merged_ids = [int(r["region"]) for r in rows if r["merged"] == "1"]
pooled_unknown = [int(r["region"]) for r in rows if r["merged"] == "0" and r["label"] == "unknown"]
changed = speckle & (np.array(mnames)[mat] != np.array(pnames)[pix]) & ~np.isin(reg, pooled_unknown)
check(changed.sum() == small["merged_pixels"] == np.isin(reg, merged_ids).sum() and
      len(merged_ids) == small["merged_regions"],
      "card: merged pixels recorded %d, shown changed in the maps %d, in merged regions %d; "
      "regions %d, %d" % (small["merged_pixels"], changed.sum(), np.isin(reg, merged_ids).sum(),
                          small["merged_regions"], len(merged_ids)))
for r in rows:
    if r["merged"] == "1" and not int(r["pixels"]) < float(r["min_pixels"]):
        check(False, "card: region %s merged with %s pixels, %s needed" %
              (r["region"], r["pixels"], r["min_pixels"]))
        break
pj = json.load(open(out + "/process.json"))
pc = [o["regions"]["small"]["merged_pixels"] for o in pj["objects"]
      if o.get("capture") == "card" and "small" in o.get("regions", {})]
check(small["merged_pixels"] in pc, "process.json records the merged pixels (%s)" % pc)
html = open(out + "/report.html").read()
check("Too small for the noise: %d regions" % small["merged_regions"] in html,
      "the report's regions note gives the merged regions")

# ---- gold and urushi on the card: both kept --------------------------------------------
d = out + "/pair"
pix, pnames, mat, mnames = material_regions(d, "pair")
truth, tnames = envi(pair_truth)
for name in ("gold", "urushi"):
    t = truth == tnames.index(name)
    holds = lambda names, img: np.array([name in n.split("|") for n in names])[img[t]].mean()
    hp, hm = holds(pnames, pix), holds(mnames, mat)
    print("pair: %s tile: %d pixels; hold %s: %.3f per pixel, %.3f in the material map "
          "(its rim of mixed pixels reads unknown)" % (name, t.sum(), name, hp, hm))
    check(hp >= 0.5 and hm >= hp, "pair: the %s tile keeps its material" % name)
sys.exit(1 if bad else 0)
PY
exit $fail
