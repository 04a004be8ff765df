#!/bin/sh
# What correct and wrong patch pairings give in calib reference's colour check (the
# misfit of the spectra's XYZ under D65 against the camera values through the best
# 3 x 3 matrix; calib/pairing.c): the measurements behind KG_CALIB_PAIR_MAX_MISFIT
# and KG_CALIB_PAIR_MIN_GAIN (calib/kg_calib.h, docs/calib-reference.md).
#   sim   every published camera of the reference data (52, and Jiang et al.'s 28)
#         under D65, D50 and A, on five spectral sets (ColorChecker BabelColor and Ohta,
#         PMC 30, the CIE test colours, CIE 2017 CES 99), kogei sim patches with noise
#         20000:5:12: one line per chart, "misfit %" or the refusal
#   real  real photographs of a ColorChecker (the three raw frames of the reference
#         data's real/ folder, sampled at their hand-placed centres; this checkout's
#         fixtures/real: the Flea3 narrowband composites and the Passport JPEG, found by
#         kogei chart detect) against the BabelColor spectra, paired correctly, under
#         five ways of misnaming a chart and under 200 random renamings each
# usage: scripts/pairing_survey.sh sim|real [BUILD_DIR]   (reference data beside the
#        checkout, or $KOGEI_REFERENCE)
set -eu
MODE=$1
ROOT=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${2:-$ROOT/build}
KOGEI=$BUILD/cli/kogei
REF=${KOGEI_REFERENCE:-$ROOT/../shared/reference}
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT

# misfit SPECTRA RGB [OPTION...]: the misfit in per cent, "refused X" or "failed"
misfit() {
	s=$1
	r=$2
	shift 2
	if "$KOGEI" calib reference --spectra "$s" --rgb "$r" "$@" -o "$T/ref.json" \
		>"$T/out" 2>"$T/err"; then
		sed -n 's/^patch pairing: .*colour misfit \([0-9.]*\) %.*/\1/p' "$T/out"
	elif grep -q "miss the camera values by" "$T/err"; then
		echo "refused $(sed -n 's/.*miss the camera values by \([0-9.]*\) %.*/\1/p' "$T/err")"
	elif grep -q "fit other patches' colours" "$T/err"; then
		echo "refused-patches"
	else
		echo "failed: $(head -c 200 "$T/err")"
	fi
	rm -f "$T/ref.json"
}

if [ "$MODE" = sim ]; then
	for chart in "$REF/charts/colorchecker24_babelcolor_avg.csv" \
		"$REF/charts/colorchecker24_ohta1997.csv" "$REF/charts/pmc30_luo2024_10nm.csv" \
		/usr/share/colord/ref/CIE-TCS.sp "$REF/reflectance/cie2017_cfi_ces99_5nm.csv"; do
		[ -r "$chart" ] || { echo "missing $chart" >&2; continue; }
		for cam in "$REF"/cameras/*.csv "$REF"/cameras/jiang2013_camspec_CC-BY-NC-SA/*.csv; do
			for ill in D65 D50 A; do
				"$KOGEI" sim patches --spectra "$chart" --camera "$cam" --illuminant "$ill" \
					--noise 20000:5:12 --extrapolate -o "$T/sim.cgats" 2>/dev/null
				echo "$(basename "$chart") $(basename "$cam" .csv) $ill" \
					"$(misfit "$chart" "$T/sim.cgats")"
			done
		done
	done
	exit 0
fi

CSV=$REF/charts/colorchecker24_babelcolor_avg.csv
# The spectra with kogei's ids, A01..D06, renamed by STYLE (as tests/cli/
# test_pairing_ids.sh names them; random:SEED a random renaming).
spectra() { # STYLE OUT
	awk -F, -v style="$1" '
	function id(k,    r, c, p) {
		r = int(k / 6); c = k % 6
		if (style == "zero") return sprintf("%c%02d", 65 + r, c)
		if (style == "letters") return sprintf("%c%d", 65 + c, r + 1)
		if (style == "colmajor") { p = 4 * c + r; return sprintf("%c%d", 65 + int(p / 6), p % 6 + 1) }
		if (style == "rowsdown") return sprintf("%c%02d", 65 + (r + 1) % 4, c + 1)
		if (style == "turned") return sprintf("%c%02d", 65 + 3 - r, 6 - c)
		return sprintf("%c%02d", 65 + r, c + 1)
	}
	NR == 1 { nb = NF - 2; for (i = 3; i <= NF; i++) wl[i] = $i; next }
	{ n++; for (i = 1; i <= NF; i++) v[n, i] = $i }
	END {
		for (k = 0; k < n; k++) perm[k] = k
		if (style ~ /^random:/) {
			srand(substr(style, 8) + 0)
			for (k = n - 1; k > 0; k--) { j = int(rand() * (k + 1)); t = perm[k]; perm[k] = perm[j]; perm[j] = t }
		}
		printf "CGATS.17\nNUMBER_OF_FIELDS %d\nBEGIN_DATA_FORMAT\nSAMPLE_ID", nb + 1
		for (i = 3; i <= nb + 2; i++) printf " SPEC_%s", wl[i]
		printf "\nEND_DATA_FORMAT\nNUMBER_OF_SETS %d\nBEGIN_DATA\n", n
		for (k = 1; k <= n; k++) {
			printf "%s", id(perm[k - 1])
			for (i = 3; i <= nb + 2; i++) printf " %.6f", v[k, i]
			printf "\n"
		}
		print "END_DATA"
	}' "$CSV" > "$2"
}

# The raw frames: each patch's mean of the GRBG mosaic's channels in a box of half its
# pitch around the hand-placed centre, black 12.5 and white 255 removed.
for i in 1 3 4; do
	python3 - "$REF/real/iisp_outdoor${i}_2592x1536_8bit_grbg.raw" \
		"$REF/real/iisp_outdoor$i.hand.json" > "$T/iisp$i.cgats" <<'PY'
import json, sys
raw = open(sys.argv[1], "rb").read()
W = 2592
cent = json.load(open(sys.argv[2]))
pitch = ((cent[5][0] - cent[0][0]) ** 2 + (cent[5][1] - cent[0][1]) ** 2) ** 0.5 / 5
h = int(pitch / 4)
print("CGATS.17\nNUMBER_OF_FIELDS 4\nBEGIN_DATA_FORMAT\nSAMPLE_ID RGB_R RGB_G RGB_B\n"
      "END_DATA_FORMAT\nNUMBER_OF_SETS 24\nBEGIN_DATA")
for k, (cx, cy) in enumerate(cent):
    s = {"R": [0, 0], "G": [0, 0], "B": [0, 0]}
    for y in range(int(cy) - h, int(cy) + h + 1):
        for x in range(int(cx) - h, int(cx) + h + 1):
            c = ("G" if x % 2 == 0 else "R") if y % 2 == 0 else ("B" if x % 2 == 0 else "G")
            s[c][0] += raw[y * W + x] - 12.5
            s[c][1] += 1
    v = [s[c][0] / s[c][1] / (255 - 12.5) for c in "RGB"]
    print("%c%02d %.6f %.6f %.6f" % (65 + k // 6, k % 6 + 1, *v))
print("END_DATA")
PY
done
# The Flea3 composites (reference and site exposures of tests/real) and the Passport
# PNG linearised as sRGB.
NB=$ROOT/fixtures/real/flea3-narrowband/d2_colorChecker30cm_
frame() { ls "$NB$1nm_$2ms_"*.tif; }
"$BUILD/tests/real/real_tool" compose "$T/f_ref.tif" "$(frame 650 100)" "$(frame 550 25)" \
	"$(frame 450 25)"
"$BUILD/tests/real/real_tool" compose "$T/f_site.tif" "$(frame 650 250)" "$(frame 550 50)" \
	"$(frame 450 100)"
for f in f_ref f_site; do
	"$KOGEI" chart detect --layout colorchecker24-frame --tagless "$T/$f.tif" \
		-o "$T/flea3_$f.cgats" 2>/dev/null
done
"$KOGEI" chart detect --layout colorchecker24-frame --tagless \
	"$ROOT/fixtures/real/passport-jpeg/below_fishbox_crop.png" -o "$T/pp.cgats" 2>/dev/null
# (scaled so that the white, D01, reads 0.9, as tests/real does)
awk -F'\t' 'BEGIN { OFS = "\t" }
	function lin(v) { return v <= 0.04045 ? v / 12.92 : ((v + 0.055) / 1.055) ^ 2.4 }
	{ line[NR] = $0 } /^END_DATA/ { d = 0 }
	d && $1 == "D01" { for (c = 2; c <= 4; c++) if (lin($c) > w) w = lin($c) }
	/^BEGIN_DATA$/ { d = 1 }
	END {
		for (i = 1; i <= NR; i++) {
			$0 = line[i]
			if ($0 ~ /^END_DATA/) d = 0
			if (d) for (c = 2; c <= 4; c++) $c = sprintf("%.6f", lin($c) * 0.9 / w)
			if ($0 ~ /^BEGIN_DATA$/) d = 1
			print
		}
	}' "$T/pp.cgats" > "$T/passport_lin.cgats"

for s in kogei zero letters colmajor rowsdown turned; do
	spectra $s "$T/s_$s.cgats"
done
# The site composite clips C04, D01 and D02 (tests/real uses it only for calib camera).
for r in ${ONLY:-iisp1 iisp3 iisp4 flea3_f_ref flea3_f_site passport_lin}; do
	x=
	[ $r = flea3_f_site ] && x="--exclude C04,D01,D02"
	line="$r: correct $(misfit "$T/s_kogei.cgats" "$T/$r.cgats" $x)"
	for s in zero letters colmajor rowsdown turned; do
		line="$line; $s $(misfit "$T/s_$s.cgats" "$T/$r.cgats" $x)"
	done
	lowest=1000
	accepted=0
	seed=1
	while [ $seed -le 200 ]; do
		spectra "random:$seed" "$T/s_rand.cgats"
		m=$(misfit "$T/s_rand.cgats" "$T/$r.cgats" $x)
		case $m in
		refused\ *) lowest=$(echo "$m $lowest" | awk '{ v = $2; print (v < $3 ? v : $3) }') ;;
		refused-patches) ;;
		*) accepted=$((accepted + 1)) ;;
		esac
		seed=$((seed + 1))
	done
	echo "$line; 200 random renamings: lowest misfit $lowest %, accepted $accepted"
done
