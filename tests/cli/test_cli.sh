#!/bin/sh
# End-to-end checks of the kogei command line: exit codes, output formats, error
# messages that name the file, and no half-written output on failure.
# usage: test_cli.sh KOGEI HAVE_APRILTAG
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
HAVE_APRILTAG=${2:-1}
kg_temp

expect_exit 0 "$KOGEI" --help
check "--help lists commands" grep -q "spectra xyz" "$T/out"
expect_exit 0 "$KOGEI" --version
check "--version prints the version" grep -q "^kogei [0-9]" "$T/out"
expect_exit 2 "$KOGEI"
expect_exit 2 "$KOGEI" no-such-command
expect_exit 2 "$KOGEI" spectra
expect_exit 2 "$KOGEI" model --bogus
expect_exit 0 "$KOGEI" model --help
# `kogei bench` runs the kogei-bench program with its arguments.
expect_exit 0 "$KOGEI" bench --help
check "bench --help is the benchmark's" grep -q "Speed against error" "$T/out"
expect_exit 2 "$KOGEI" bench --reps 0
check "bench usage error names the option" grep -q -- "--reps 0" "$T/err"

# spectra xyz: the perfect diffuser has Y = 100 and L* = 100.
cat >"$T/white.cgats" <<'CG'
CGATS.17
SPECTRAL_START_NM 380
SPECTRAL_END_NM 780
SPECTRAL_BANDS 5
NUMBER_OF_FIELDS 6
BEGIN_DATA_FORMAT
SAMPLE_ID SPEC_380 SPEC_480 SPEC_580 SPEC_680 SPEC_780
END_DATA_FORMAT
NUMBER_OF_SETS 2
BEGIN_DATA
white 1 1 1 1 1
grey 0.18 0.18 0.18 0.18 0.18
END_DATA
CG
for ill in D65 D50 A; do
	expect_exit 0 "$KOGEI" spectra xyz "$T/white.cgats" --illuminant $ill -o "$T/xyz.cgats"
	check "spectra xyz writes the fields" grep -q "SAMPLE_ID.*XYZ_X.*XYZ_Y.*XYZ_Z.*LAB_L.*LAB_A.*LAB_B" "$T/xyz.cgats"
	check "perfect diffuser Y = 100 under $ill" awk '$1=="white"{ if ($3 < 99.999 || $3 > 100.001 || $5 < 99.999) exit 1; found=1 } END { exit !found }' "$T/xyz.cgats"
	check "18% grey L* = 49.5 under $ill" awk '$1=="grey"{ if ($5 < 49.4 || $5 > 49.6 || $6*$6 > 1e-8 || $7*$7 > 1e-8) exit 1; found=1 } END { exit !found }' "$T/xyz.cgats"
done

# Bad input: the message names the file, the line and the field; exit 1; nothing written.
sed 's/^grey 0.18 0.18/grey 0.18 zero/' "$T/white.cgats" >"$T/bad.cgats"
expect_exit 1 "$KOGEI" spectra xyz "$T/bad.cgats" -o "$T/bad_out.cgats"
check "error names the file" grep -q "bad.cgats" "$T/err"
check "error names the field" grep -q "SPEC_480" "$T/err"
check "no output on failure" test ! -e "$T/bad_out.cgats"
check "no temporary left" sh -c "! ls '$T' | grep -q tmp"
expect_exit 1 "$KOGEI" spectra xyz "$T/missing.cgats"
check "missing file named" grep -q "missing.cgats" "$T/err"
expect_exit 1 "$KOGEI" spectra xyz "$T/white.cgats" --illuminant Z99
check "unknown illuminant explained" grep -qi "illuminant" "$T/err"
# Spectra not covering 400-700 nm are refused.
sed 's/SPECTRAL_START_NM 380/SPECTRAL_START_NM 480/; s/SPEC_380 //; s/^white 1 /white /; s/^grey 0.18 /grey /; s/NUMBER_OF_FIELDS 6/NUMBER_OF_FIELDS 5/; s/SPECTRAL_BANDS 5/SPECTRAL_BANDS 4/' "$T/white.cgats" >"$T/short.cgats"
expect_exit 1 "$KOGEI" spectra xyz "$T/short.cgats"
check "short range refused with the range" grep -q "480" "$T/err"
# The integration range: the file's own by default, the paper's grid on request.
expect_exit 0 "$KOGEI" spectra xyz "$T/white.cgats" -o "$T/xyz.cgats"
check "default range is the file's" grep -q 'INTEGRATION_RANGE_NM "380-780"' "$T/xyz.cgats"
check "default step 1 nm" grep -q 'INTEGRATION_STEP_NM "1"' "$T/xyz.cgats"
expect_exit 0 "$KOGEI" spectra xyz "$T/white.cgats" --range paper -o "$T/xyz.cgats"
check "paper range named" grep -q 'INTEGRATION_RANGE_NM "400-700"' "$T/xyz.cgats"
check "paper step 5 nm" grep -q 'INTEGRATION_STEP_NM "5"' "$T/xyz.cgats"
expect_exit 1 "$KOGEI" spectra xyz "$T/white.cgats" --range 300-700 -o "$T/xyz2.cgats"
check "range beyond the data refused with the data's range" grep -q "380-780" "$T/err"
expect_exit 2 "$KOGEI" spectra xyz "$T/white.cgats" --range 700-400
# A SPEC_ field without a wavelength is refused, not skipped and interpolated across.
for name in SPEC_abc SPEC_Inf SPEC_; do
	sed "s/SPEC_580 /$name /" "$T/white.cgats" >"$T/badname.cgats"
	expect_exit 1 "$KOGEI" spectra xyz "$T/badname.cgats" -o "$T/badname_out.cgats"
	check "$name refused naming file and field" grep -q "badname.cgats: field $name: expected SPEC_<nm> .*with a finite wavelength" "$T/err"
	check "$name: no output" test ! -e "$T/badname_out.cgats"
done

# model: the Fig. 7 table.
expect_exit 0 "$KOGEI" model --material gold --angles 0:90:10 -o "$T/gold.csv" --plot "$T/gold.png"
check "model CSV header" sh -c "head -1 '$T/gold.csv' | grep -qx 'wavelength_nm,0,10,20,30,40,50,60,70,80,90'"
check "model CSV has 61 bands" test "$(tail -n +2 "$T/gold.csv" | wc -l)" = 61
check "model CSV rows 400..700" sh -c "sed -n '2p;62p' '$T/gold.csv' | cut -d, -f1 | tr '\n' ' ' | grep -qx '400 700 '"
check "reflectance within [0,1], 1 at grazing" awk -F, 'NR>1 { for (i=2;i<=NF;i++) if ($i<0 || $i>1) exit 1; if ($11 < 0.999) exit 1 }' "$T/gold.csv"
check "gold is yellow: R(650) > R(450)" awk -F, '$1==450{a=$2} $1==650{b=$2} END{exit !(b > a + 0.3)}' "$T/gold.csv"
check "model plot is a PNG" sh -c "head -c 8 '$T/gold.png' | od -An -c | grep -q 'P   N   G'"
expect_exit 1 "$KOGEI" model --material unobtainium -o "$T/x.csv"
check "unknown material lists the library" grep -q "shibuichi-nami" "$T/err"
check "no output for an unknown material" test ! -e "$T/x.csv"
expect_exit 1 "$KOGEI" model --material gold --angles 0:95:5 -o "$T/x.csv"

# demo (it photographs and detects its charts, so it needs libapriltag)
if [ "$HAVE_APRILTAG" = 1 ]; then
	expect_exit 0 "$KOGEI" demo -o "$T/demo"
	for f in fig7_shibuichi-nami.csv fig7_shibuichi-nami.png materials_d65.png; do
		check "demo wrote $f" test -s "$T/demo/$f"
	done
else
	expect_exit 1 "$KOGEI" demo -o "$T/demo"
	check "demo explains what is missing" grep -q "libapriltag" "$T/err"
fi

[ $fail = 0 ] && echo "cli: ok"
exit $fail
