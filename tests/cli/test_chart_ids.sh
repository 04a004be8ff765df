#!/bin/sh
# Chart files people have: the ColorChecker's spectra and camera values pair up
# whatever convention names their patches (ArgyllCMS chartread's 1..24, a .cht's
# A1..D6, kogei's A01..D06), both ways, and X-Rite's spectral field names (i1Profiler
# SPECTRAL_NM380.., MeasureTool nm380..) read as spectra. Each pairing must give the
# very calibration the same files with matching ids give. Spectra: BabelColor's
# ColorChecker average in ../shared/reference (skipped without it).
# usage: test_chart_ids.sh KOGEI SOURCE_ROOT
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
SRC=$2
kg_need_reference "$SRC" charts/colorchecker24_babelcolor_avg.csv
CSV=$REF/charts/colorchecker24_babelcolor_avg.csv
kg_temp
D=$SRC/fixtures/demo

# The spectra as three programs write them (from the CSV: patch,name,380..730).
# conv: 1 chartread (.ti3: SAMPLE_ID 1..24, SAMPLE_LOC, SPEC_ in percent),
# 2 i1Profiler (SAMPLE_ID A1..D6, SPECTRAL_NM, fractions), 3 MeasureTool (A01..D06, nm).
spectra() { # conv out
	awk -F, -v conv="$1" '
	NR == 1 { nb = NF - 2; for (i = 3; i <= NF; i++) wl[i] = $i; next }
	{ n++; for (i = 1; i <= NF; i++) v[n, i] = $i }
	END {
		pre = conv == 1 ? "SPEC_" : conv == 2 ? "SPECTRAL_NM" : "nm"
		print (conv == 1 ? "CTI3" : "CGATS.17")
		print "ORIGINATOR \"test\""
		if (conv == 1) print "KEYWORD \"SAMPLE_LOC\""
		printf "NUMBER_OF_FIELDS %d\nBEGIN_DATA_FORMAT\nSAMPLE_ID %s", nb + 2,
		       conv == 1 ? "SAMPLE_LOC" : "SAMPLE_NAME"
		for (i = 3; i <= nb + 2; i++) printf " %s%s", pre, wl[i]
		printf "\nEND_DATA_FORMAT\nNUMBER_OF_SETS %d\nBEGIN_DATA\n", n
		for (k = 1; k <= n; k++) {
			row = sprintf("%c", 65 + int((k - 1) / 6)); col = (k - 1) % 6 + 1
			if (conv == 1) printf "%d \"%s%d\"", k, row, col
			else if (conv == 2) printf "%s%d \"%s\"", row, col, v[k, 2]
			else printf "%s%02d \"%s\"", row, col, v[k, 2]
			for (i = 3; i <= nb + 2; i++) printf " %.6f", (conv == 1 ? 100 : 1) * v[k, i]
			printf "\n"
		}
		print "END_DATA"
	}' "$CSV" > "$2"
}
# A patch file with its SAMPLE_IDs (1..24) renamed: style 1 A01..D06, 2 A1..D6.
rename() { # style in out
	awk -v style="$1" '/^BEGIN_DATA[ \t\r]*$/ { d = 1; print; next } /^END_DATA/ { d = 0 }
	d { k = $1; row = sprintf("%c", 65 + int((k - 1) / 6)); col = (k - 1) % 6 + 1
	    $1 = style == 1 ? sprintf("%s%02d", row, col) : sprintf("%s%d", row, col) } { print }' \
		"$2" > "$3"
}
spectra 1 "$T/chartread.ti3"
spectra 2 "$T/i1profiler.txt"
spectra 3 "$T/measuretool.txt"
expect_exit 0 "$KOGEI" sim patches --spectra "$CSV" --camera "$D/reference_camera.csv" \
	--illuminant D65 --noise 50000:3:16 --seed 3 -o "$T/rgb_num.cgats"
rename 1 "$T/rgb_num.cgats" "$T/rgb_kogei.cgats"
rename 2 "$T/rgb_num.cgats" "$T/rgb_cht.cgats"
check "RGB ids renamed to A01" grep -q "^A01 " "$T/rgb_kogei.cgats"

on_chart() { grep "on the chart" "$T/out"; }
# 0. Ids as written: the baseline.
expect_exit 0 "$KOGEI" calib reference --spectra "$CSV" --rgb "$T/rgb_num.cgats" -o "$T/base.json"
base=$(on_chart)
echo "ids as written: $base"
check "baseline: no alias note" sh -c "! grep -q 'paired as' '$T/err'"
pair() { # description spectra rgb
	expect_exit 0 "$KOGEI" calib reference --spectra "$2" --rgb "$3" -o "$T/pair.json"
	got=$(on_chart)
	echo "$1: $got"
	check "$1: the same calibration as with matching ids" test "$got" = "$base"
	check "$1: a note says how ids were paired" grep -q "patch ids paired as" "$T/err"
	rm -f "$T/pair.json"
}
pair "chartread 1..24 + kogei A01..D06" "$T/chartread.ti3" "$T/rgb_kogei.cgats"
pair "chartread 1..24 + .cht A1..D6" "$T/chartread.ti3" "$T/rgb_cht.cgats"
pair "i1Profiler A1..D6 (SPECTRAL_NM) + kogei A01..D06" "$T/i1profiler.txt" "$T/rgb_kogei.cgats"
pair "i1Profiler A1..D6 (SPECTRAL_NM) + chartread 1..24" "$T/i1profiler.txt" "$T/rgb_num.cgats"
pair "MeasureTool A01..D06 (nm) + chartread 1..24" "$T/measuretool.txt" "$T/rgb_num.cgats"
pair "MeasureTool A01..D06 (nm) + .cht A1..D6" "$T/measuretool.txt" "$T/rgb_cht.cgats"

# Site calibration: the reference's field ids are kogei's (A01..D06); the site file
# names its patches as chartread, as a .cht, or as kogei: the same M2 each time.
expect_exit 0 "$KOGEI" calib reference --spectra "$T/chartread.ti3" --rgb "$T/rgb_kogei.cgats" \
	-o "$T/ref.json"
expect_exit 0 "$KOGEI" sim patches --spectra "$CSV" --camera "$D/site_camera.csv" \
	--illuminant A --noise 50000:3:16 --seed 5 -o "$T/site_num.cgats"
rename 1 "$T/site_num.cgats" "$T/site_kogei.cgats"
rename 2 "$T/site_num.cgats" "$T/site_cht.cgats"
expect_exit 0 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/site_kogei.cgats" -o "$T/cam0.json"
m2=$(grep "^M2 = " "$T/out")
check "site ids as written: no alias note" sh -c "! grep -q 'matched with the reference' '$T/err'"
for s in num cht; do
	expect_exit 0 "$KOGEI" calib camera --reference "$T/ref.json" --rgb "$T/site_$s.cgats" \
		-o "$T/cam_$s.json"
	got=$(grep "^M2 = " "$T/out")
	check "site ids ($s): the same M2" test "$got" = "$m2"
	check "site ids ($s): a note says how ids were matched" grep -q "matched with the reference" "$T/err"
	check "site ids ($s): the patches keep the reference's ids" grep -q '"A01"' "$T/cam_$s.json"
done
echo "site M2 with kogei, chartread and .cht ids: $m2"
# Ids of another chart still refuse, naming both sides.
awk '/^BEGIN_DATA[ \t\r]*$/ { d = 1; print; next } /^END_DATA/ { d = 0 }
	d { $1 = "X" $1 } { print }' "$T/rgb_num.cgats" > "$T/rgb_other.cgats"
expect_exit 1 "$KOGEI" calib reference --spectra "$T/chartread.ti3" --rgb "$T/rgb_other.cgats" \
	-o "$T/other.json"
check "unrelated ids: refused naming the files" grep -q "rgb_other.cgats" "$T/err"
exit $fail
