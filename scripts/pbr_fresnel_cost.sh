#!/bin/sh
# What the glTF (PBR metallic-roughness) approximation of a Fresnel conductor costs,
# per library metal and alloy: glTF and Blender's Principled BSDF reflect a metal by
# Schlick's approximation from the base colour, F = F0 + (1 - F0)(1 - cos theta)^5,
# F0 the normal-incidence reflectance; kogei by the exact Fresnel equations of the
# metal's n, k (an alloy: the composition-weighted sum of its metals'). Schlick's
# formula is linear in F0, so applying it to the RGB base colour equals applying it per
# wavelength: the CIEDE2000 between the exact and the Schlick reflectance spectra under
# D65 (CIE 1931, the 61 bands, kogei spectra xyz --range paper) is the colour cost at
# each incidence angle, before any lobe shape or sampling difference.
# usage: scripts/pbr_fresnel_cost.sh [BUILD_DIR]   (prints a Markdown table)
set -eu
ROOT=$(cd "$(dirname "$0")/.." && pwd)
KOGEI=${1:-$ROOT/build}/cli/kogei
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
names=$(python3 -c '
import json, sys
for m in json.load(open(sys.argv[1]))["materials"]:
    if m["kind"] in ("metal", "alloy"):
        print(m["name"])' "$ROOT/fixtures/materials/default.json")
for m in $names; do
	"$KOGEI" model --material "$m" --angles 0:85:5 -o "$T/$m.csv"
done
python3 - "$T" $names <<'PY'
import math, sys
d, names = sys.argv[1], sys.argv[2:]
angles = [0, 30, 45, 60, 75, 85]
wl = [400 + 5 * i for i in range(61)]
with open(d + "/all.cgats", "w") as f:
    f.write("CGATS.17\nORIGINATOR \"pbr_fresnel_cost.sh\"\nNUMBER_OF_FIELDS 62\n"
            "BEGIN_DATA_FORMAT\nSAMPLE_ID %s\nEND_DATA_FORMAT\nNUMBER_OF_SETS %d\nBEGIN_DATA\n"
            % (" ".join("SPEC_%d" % w for w in wl), 2 * len(names) * len(angles)))
    for n in names:
        rows = [list(map(float, ln.split(","))) for ln in open("%s/%s.csv" % (d, n)).read().split("\n")[1:] if ln]
        head = open("%s/%s.csv" % (d, n)).readline().strip().split(",")[1:]
        col = {int(float(a)): i + 1 for i, a in enumerate(head)}
        for a in angles:
            exact = [r[col[a]] for r in rows]
            w = (1 - math.cos(math.radians(a))) ** 5
            schlick = [r[col[0]] + (1 - r[col[0]]) * w for r in rows]
            f.write("%s@%d:exact %s\n" % (n, a, " ".join("%.6f" % v for v in exact)))
            f.write("%s@%d:schlick %s\n" % (n, a, " ".join("%.6f" % v for v in schlick)))
    f.write("END_DATA\n")
PY
"$KOGEI" spectra xyz "$T/all.cgats" --range paper -o "$T/lab.cgats"
python3 - "$T/lab.cgats" "$ROOT/tests/render" $names <<'PY'
import sys
sys.path.insert(0, sys.argv[2])
from blender_compare import de2000
lines = open(sys.argv[1]).read().split("BEGIN_DATA\n")[1].split("END_DATA")[0].split("\n")
lab = {}
for ln in lines:
    if ln.strip():
        w = ln.split()
        lab[w[0]] = tuple(map(float, w[4:7]))
angles = [0, 30, 45, 60, 75, 85]
print("| material | " + " | ".join("%d°" % a for a in angles) + " |")
print("|---|" + "---:|" * len(angles))
for n in sys.argv[3:]:
    de = [de2000(lab["%s@%d:exact" % (n, a)], lab["%s@%d:schlick" % (n, a)]) for a in angles]
    print("| %s | %s |" % (n, " | ".join("%.2f" % v for v in de)))
PY
