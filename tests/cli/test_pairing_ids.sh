#!/bin/sh
# Patch ids that name other patches: the ColorChecker's measured spectra (BabelColor's
# average, ../shared/reference; skipped without it) and a camera's values of the same
# chart simulated by kogei sim patches are paired by SAMPLE_ID, and the pairing is
# checked by colour. Spectra files named as other programs and people name a chart
# (zero-based, column letters, numbered down the columns, one row read a patch late,
# two patches swapped) are refused with exit 1, naming both files, how each names its
# patches and, when one fits, the pairing to state; --id-pairing states it. The
# correctly named file passes; patches without a partner are listed in a note and in
# the calibration's record; calib camera and --field-rgb are checked the same way.
# usage: test_pairing_ids.sh KOGEI SOURCE_ROOT
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
SRC=$2
kg_need_reference "$SRC" charts/colorchecker24_babelcolor_avg.csv
CSV=$REF/charts/colorchecker24_babelcolor_avg.csv
kg_python
kg_temp
D=$SRC/fixtures/demo

# spectra STYLE OUT: the 24 spectra (CSV rows in chart order, row-major from dark skin)
# as CGATS whose SAMPLE_IDs follow STYLE, for patch k at row r = k / 6, column c = k % 6:
#   kogei     A01..D06 (letter = row, number = column from 1)
#   zero      A00..D05 (numbers from 0)
#   letters   A1..F4 (letter = column, number = row)
#   colmajor  A1..D6 given to the patches read down the columns (p = 4 c + r)
#   rowshift  kogei's, but row B read one patch late (B02 names B01's spectrum, ...)
#   swap      kogei's with A02 (light skin) and B04 (purple) swapped
#   extra     kogei's and two more patches, E01 and E02
#   few       kogei's for row A, the rest renamed X01..X18
spectra() {
	awk -F, -v style="$1" '
	function id(k,    r, c, p) {
		r = int(k / 6); c = k % 6
		if (style == "zero") return sprintf("%c%02d", 65 + r, c)
		if (style == "letters") return sprintf("%c%d", 65 + c, r + 1)
		if (style == "colmajor") { p = 4 * c + r; return sprintf("%c%d", 65 + int(p / 6), p % 6 + 1) }
		if (style == "rowshift" && r == 1) return sprintf("B%02d", (c + 1) % 6 + 1)
		if (style == "swap" && k == 1) return "B04"
		if (style == "swap" && k == 9) return "A02"
		if (style == "few" && r > 0) return sprintf("X%02d", k - 5)
		return sprintf("%c%02d", 65 + r, c + 1)
	}
	NR == 1 { nb = NF - 2; for (i = 3; i <= NF; i++) wl[i] = $i; next }
	{ n++; for (i = 1; i <= NF; i++) v[n, i] = $i }
	END {
		extra = style == "extra" ? 2 : 0
		printf "CGATS.17\nORIGINATOR \"test\"\nNUMBER_OF_FIELDS %d\nBEGIN_DATA_FORMAT\nSAMPLE_ID", nb + 1
		for (i = 3; i <= nb + 2; i++) printf " SPEC_%s", wl[i]
		printf "\nEND_DATA_FORMAT\nNUMBER_OF_SETS %d\nBEGIN_DATA\n", n + extra
		for (k = 1; k <= n + extra; k++) {
			printf "%s", k <= n ? id(k - 1) : sprintf("E%02d", k - n)
			for (i = 3; i <= nb + 2; i++) printf " %.6f", v[k <= n ? k : k - n, i] * (k <= n ? 1 : 0.5)
			printf "\n"
		}
		print "END_DATA"
	}' "$CSV" > "$2"
}
for s in kogei zero letters colmajor rowshift swap extra few; do
	spectra $s "$T/$s.cgats"
done
check "zero-based ids written" grep -q "^A00 " "$T/zero.cgats"
check "column-major: C1 names the patch of row 1, column 3" sh -c \
	"awk '\$1 == \"C1\"' '$T/colmajor.cgats' | grep -q ."

# The camera's values of the chart (ids 1..24 from the CSV), named as kogei's layouts
# name the ColorChecker: A01..D06.
run_or_exit "$KOGEI" sim patches --spectra "$CSV" --camera "$D/reference_camera.csv" \
	--illuminant D65 --noise 20000:5:12 --seed 4 -o "$T/sim.cgats"
# rgb_as STYLE IN OUT: the sim's ids 1..24 renamed (kogei A01..D06, zero A00..D05)
rgb_as() {
	awk -v style="$1" '/^BEGIN_DATA[ \t\r]*$/ { d = 1; print; next } /^END_DATA/ { d = 0 }
	d { k = $1 - 1; $1 = sprintf("%c%02d", 65 + int(k / 6), k % 6 + (style == "zero" ? 0 : 1)) }
	{ print }' "$2" > "$3"
}
rgb_as kogei "$T/sim.cgats" "$T/rgb.cgats"
rgb_as zero "$T/sim.cgats" "$T/rgb_zero.cgats"

# 1. The correctly named file passes, with its misfit on the report.
expect_exit 0 "$KOGEI" calib reference --spectra "$T/kogei.cgats" --rgb "$T/rgb.cgats" \
	-o "$T/ok.json"
check "correct ids: the pairing's misfit reported" \
	grep -q "patch pairing: 24 pairs by names; colour misfit [0-9.]* % over 24" "$T/out"
grep "patch pairing" "$T/out"
check "correct ids: no note" test ! -s "$T/err"
check_eval "correct ids: misfit under 5 % in the record" \
	"'$PY' -c 'import json,sys; p = json.load(open(sys.argv[1]))[\"pairing\"]; \
sys.exit(not (p[\"rule\"] == \"names\" and p[\"pairs\"] == 24 and p[\"misfit\"] < 0.05 and \
p[\"unpaired\"] == {\"spectra\": [], \"rgb\": []}))' '$T/ok.json'"

# refused NAME STYLE FRAGMENT...: calib reference on STYLE's spectra exits 1, writes
# nothing, names both files and says each FRAGMENT.
refused() {
	name=$1
	style=$2
	shift 2
	expect_exit 1 "$KOGEI" calib reference --spectra "$T/$style.cgats" --rgb "$T/rgb.cgats" \
		-o "$T/$style.json"
	check "$name: nothing written" test ! -e "$T/$style.json"
	check "$name: names the spectra file" grep -q "$style.cgats" "$T/err"
	check "$name: names the RGB file" grep -q "rgb.cgats" "$T/err"
	for f in "$@"; do
		check "$name: says '$f'" grep -qF -- "$f" "$T/err"
	done
	echo "$name: $(cat "$T/err")"
}
refused "zero-based" zero "A00..D05" "counted from 0" "A01..D06" "are not the same patches" \
	"--id-pairing grid-order"
refused "column letters" letters \
	"A1..F4 (6 letters A-F x 4 numbers 1-4: the other file's grid turned" \
	"A01..D06 (4 letters A-D x 6 numbers 1-6)" "--id-pairing spectra-by-number"
refused "numbered down the columns" colmajor "A1..D6" "--id-pairing rgb-by-number"
refused "one row read a patch late" rowshift "6 patches fit other patches' colours" \
	"B02 -> B03" "B05 -> B06" "--exclude B02,B03,B04,B05,B06,B01"
refused "two swapped patches" swap "2 patches fit other patches' colours" "A02 -> B04" \
	"B04 -> A02"
refused "few patches pair" few "only 6 of their 24 and 24 patches pair"

# 2. A stated pairing is taken, and checked.
expect_exit 0 "$KOGEI" calib reference --spectra "$T/zero.cgats" --rgb "$T/rgb.cgats" \
	--id-pairing grid-order -o "$T/zero.json"
check "zero-based with --id-pairing grid-order: 24 pairs" \
	grep -q "patch pairing: 24 pairs by grid-order" "$T/out"
expect_exit 0 "$KOGEI" calib reference --spectra "$T/letters.cgats" --rgb "$T/rgb.cgats" \
	--id-pairing spectra-by-number -o "$T/letters.json"
expect_exit 1 "$KOGEI" calib reference --spectra "$T/kogei.cgats" --rgb "$T/rgb.cgats" \
	--id-pairing number+1 -o "$T/stated.json"
check "number+1 stated for correct ids: refused, naming the pairing that fits" \
	grep -q "Paired by names instead" "$T/err"
expect_exit 2 "$KOGEI" calib reference --spectra "$T/kogei.cgats" --rgb "$T/rgb.cgats" \
	--id-pairing sideways -o "$T/stated.json"
check "an unknown pairing: the names listed" grep -q "grid-order, spectra-by-number" "$T/err"
# Excluding the swapped patches leaves a pairing that fits.
expect_exit 0 "$KOGEI" calib reference --spectra "$T/swap.cgats" --rgb "$T/rgb.cgats" \
	--exclude A02,B04 -o "$T/swap.json"

# 3. Patches without a partner: listed in a note and in the record.
expect_exit 0 "$KOGEI" calib reference --spectra "$T/extra.cgats" --rgb "$T/rgb.cgats" \
	-o "$T/extra.json"
check "unpaired spectra listed in a note" \
	grep -q "extra.cgats: 2 patches paired with nothing in .*rgb.cgats, left out: E01, E02" \
	"$T/err"
check_eval "unpaired spectra in the record" \
	"'$PY' -c 'import json,sys; p = json.load(open(sys.argv[1]))[\"pairing\"]; \
sys.exit(p[\"unpaired\"] != {\"spectra\": [\"E01\", \"E02\"], \"rgb\": []})' '$T/extra.json'"
grep -v "^A03\|^C05" "$T/rgb.cgats" | sed 's/^NUMBER_OF_SETS.*/NUMBER_OF_SETS 22/' \
	> "$T/rgb22.cgats"
expect_exit 0 "$KOGEI" calib reference --spectra "$T/kogei.cgats" --rgb "$T/rgb22.cgats" \
	-o "$T/rgb22.json"
check "spectra the camera file lacks listed" \
	grep -q "kogei.cgats: 2 patches paired with nothing in .*rgb22.cgats, left out: A03, C05" \
	"$T/err"

# 4. calib camera: the site file against the reference's rho0, by the same check.
expect_exit 0 "$KOGEI" calib camera --reference "$T/ok.json" --rgb "$T/rgb.cgats" \
	-o "$T/cam.json"
check "calib camera: the pairing reported" grep -q "patch pairing: 24 pairs by names" "$T/out"
expect_exit 1 "$KOGEI" calib camera --reference "$T/ok.json" --rgb "$T/rgb_zero.cgats" \
	-o "$T/cam_zero.json"
check "calib camera, zero-based site file: refused by colour, naming the ids" \
	grep -q "A00..D05 (4 letters A-D x 6 numbers 0-5, counted from 0) in .*rgb_zero.cgats" \
	"$T/err"
check "calib camera, zero-based site file: the pairing to state" \
	grep -q -- "--id-pairing grid-order" "$T/err"
echo "calib camera, zero-based: $(cat "$T/err")"
expect_exit 0 "$KOGEI" calib camera --reference "$T/ok.json" --rgb "$T/rgb_zero.cgats" \
	--id-pairing grid-order -o "$T/cam_zero.json"
check_eval "calib camera, stated pairing: the reference's ids kept" \
	"'$PY' -c 'import json,sys; c = json.load(open(sys.argv[1]))[\"site\"]; \
sys.exit(not (c[\"ids\"][0] == \"A01\" and c[\"pairing\"][\"rule\"] == \"grid-order\"))' \
'$T/cam_zero.json'"
expect_exit 0 "$KOGEI" calib camera --reference "$T/ok.json" --rgb "$T/rgb22.cgats" \
	-o "$T/cam22.json"
check "calib camera: reference patches the site file lacks listed" \
	grep -q "ok.json: 2 patches paired with nothing in .*rgb22.cgats, left out: A03, C05" \
	"$T/err"
check_eval "calib camera: unpaired in the record" \
	"'$PY' -c 'import json,sys; p = json.load(open(sys.argv[1]))[\"site\"][\"pairing\"]; \
sys.exit(p[\"unpaired\"] != {\"reference\": [\"A03\", \"C05\"], \"rgb\": []})' '$T/cam22.json'"
# two patches swapped in the site file
awk '$1 == "A02" { $1 = "B04"; print; next } $1 == "B04" { $1 = "A02" } { print }' \
	"$T/rgb.cgats" > "$T/rgb_swap.cgats"
expect_exit 1 "$KOGEI" calib camera --reference "$T/ok.json" --rgb "$T/rgb_swap.cgats" \
	-o "$T/cam_swap.json"
check "calib camera, two swapped patches: named" grep -q "A02 -> B04" "$T/err"

# 5. --field-rgb: a field file naming the spectra's very patches is checked too.
expect_exit 0 "$KOGEI" calib reference --spectra "$T/kogei.cgats" --rgb "$T/rgb.cgats" \
	--field-rgb "$T/rgb.cgats" -o "$T/field.json"
expect_exit 1 "$KOGEI" calib reference --spectra "$T/kogei.cgats" --rgb "$T/rgb.cgats" \
	--field-rgb "$T/rgb_swap.cgats" -o "$T/field_swap.json"
check "--field-rgb with two swapped patches: refused, naming the field file" \
	grep -q "rgb_swap.cgats.*A02 -> B04" "$T/err"
exit $fail
