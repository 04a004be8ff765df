#!/bin/sh
# CGATS input through the real command line (calib reference, spectra xyz): what is
# wrong is refused (exit 1, a message naming the file and the line or field, no output
# left behind), never taken in silently; text in Windows-1252 (Latin-1), as Windows
# tools write it, is converted, so that whatever reaches JSON is UTF-8. The files are
# written here from colord's CIE test colours (docs/formats.md, "CGATS input").
# usage: test_cgats_input.sh KOGEI
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
kg_temp
kg_need_tcs
run_or_exit "$KOGEI" sim patches --spectra "$TCS" --camera demo-reference --illuminant D65 \
	-o "$T/rgb.cgats"
# The spectra as a file of our own: the identifier, then the keywords and data of TCS.
{ echo SPECT; sed 1d "$TCS"; } >"$T/good.cgats"

files_now() { ls -A "$T" | wc -l; }

# accepted FILE [RGB]: both commands read FILE as spectra (RGB: the camera's file) and
# write their output ($T/ref.json, $T/xyz.cgats).
accepted() {
	rm -f "$T/ref.json" "$T/xyz.cgats"
	expect_exit 0 "$KOGEI" calib reference --spectra "$1" --rgb "${2:-$T/rgb.cgats}" \
		-o "$T/ref.json"
	expect_exit 0 "$KOGEI" spectra xyz "$1" -o "$T/xyz.cgats"
}

# refused DESC FILE PATTERN...: both commands refuse FILE as spectra with exit 1, a
# message naming the file and matching each PATTERN, and leave no file behind.
refused() {
	what=$1 file=$2
	shift 2
	rm -f "$T/ref.json" "$T/xyz.cgats"
	before=$(files_now)
	expect_exit 1 "$KOGEI" calib reference --spectra "$file" --rgb "$T/rgb.cgats" -o "$T/ref.json"
	refusal_named "$what: calib reference" "$file" "$@"
	expect_exit 1 "$KOGEI" spectra xyz "$file" -o "$T/xyz.cgats"
	refusal_named "$what: spectra xyz" "$file" "$@"
	check "$what: nothing left behind" test "$(files_now)" = "$before"
}

refusal_named() { # DESC FILE PATTERN...
	d=$1 f=$2
	shift 2
	check "$d: the message names $(basename "$f")" grep -qF "$(basename "$f"):" "$T/err"
	for p in "$@"; do
		check "$d: the message says '$p'" grep -qF -- "$p" "$T/err"
	done
	check "$d: no wrong cause" sh -c "! grep -q 'out of memory\|eigen' '$T/err'"
}

# line_of PATTERN FILE: the line number of the first line matching PATTERN.
line_of() { grep -n -- "$1" "$2" | head -1 | cut -d: -f1; }

# ---- text encodings ------------------------------------------------------------------

# Windows-1252 (Latin-1) in the keywords, a comment and an undeclared keyword, as
# Windows tools write them: converted; the JSON holds the text in UTF-8.
{
	echo SPECT
	printf 'ORIGINATOR "Caf\351 25\260C"\n'
	printf 'MANUFACTURER "Probe \226 Muster \200"\n'
	printf '# Kalibrierung f\374r die Werkstatt\n'
	printf 'KEYWORD "NOTIZ"\nNOTIZ "Gr\366\337e \253A\273"\n'
	sed 1d "$TCS"
} >"$T/latin1.cgats"
accepted "$T/latin1.cgats"
check "Latin-1 ORIGINATOR in the reference as UTF-8" grep -qF '"ORIGINATOR": "Café 25°C"' "$T/ref.json"
check "Windows-1252 en dash and euro as UTF-8" grep -qF '"MANUFACTURER": "Probe – Muster €"' "$T/ref.json"
check "undeclared keyword as UTF-8" grep -qF '"NOTIZ": "Größe «A»"' "$T/ref.json"
check "the reference is UTF-8 throughout" sh -c "iconv -f UTF-8 -t UTF-8 '$T/ref.json' >/dev/null"
check "spectra xyz read all 15" test "$(grep -c '^TCS' "$T/xyz.cgats")" = 15

# A patch id in Latin-1 in the spectra and in UTF-8 in the camera's file: one id.
sed "s/^TCS01/$(printf 'Caf\351')/" "$T/good.cgats" >"$T/latin1_id.cgats"
sed 's/^TCS01/Café/' "$T/rgb.cgats" >"$T/rgb_utf8_id.cgats"
accepted "$T/latin1_id.cgats" "$T/rgb_utf8_id.cgats"
check "Latin-1 id paired with its UTF-8 spelling" grep -q '"patches": 15' "$T/ref.json"
check "the id in the reference as UTF-8" grep -qF '"Café"' "$T/ref.json"
check "the id in spectra xyz's output as UTF-8" grep -q '^Café[[:space:]]' "$T/xyz.cgats"

# A byte Windows-1252 leaves undefined (0x81) in a file that is not UTF-8: refused
# with the line and the byte.
{ echo SPECT; printf 'ORIGINATOR "Caf\351"\nDESCRIPTOR "x\201y"\n'; sed 1d "$TCS"; } >"$T/undefined.cgats"
refused "undefined byte" "$T/undefined.cgats" "line 3: byte 0x81 (offset 37 in the file)" \
	"neither UTF-8 nor Windows-1252"
# UTF-8 on one line, Latin-1 on another: no single conversion reads it right.
{ echo SPECT; echo 'ORIGINATOR "Café"'; printf 'DESCRIPTOR "Caf\351"\n'; sed 1d "$TCS"; } >"$T/mixed.cgats"
refused "mixed encodings" "$T/mixed.cgats" "line 3: byte 0xE9" "line 2 holds UTF-8" \
	"one encoding throughout"

# A file name that is not UTF-8 cannot stand in the reference's JSON: the cause named.
latin1_name=$T/$(printf 'caf\351').cgats
cp "$T/good.cgats" "$latin1_name"
expect_exit 1 "$KOGEI" calib reference --spectra "$latin1_name" --rgb "$T/rgb.cgats" -o "$T/ref.json"
check "non-UTF-8 file name: the cause named" grep -q "the path of the spectra file is not UTF-8 text (byte 0xE9" "$T/err"
check "non-UTF-8 file name: not 'out of memory'" sh -c "! grep -q 'out of memory' '$T/err'"
check "non-UTF-8 file name: no reference" test ! -e "$T/ref.json"
rm -f "$latin1_name"

# ---- values --------------------------------------------------------------------------

# set_cell ID FIELD VALUE OUT: good.cgats with the cell of sample ID under FIELD set.
set_cell() {
	awk -v id="$1" -v field="$2" -v val="$3" 'BEGIN { FS = OFS = "\t" }
		$1 == "SAMPLE_ID" { for (i = 1; i <= NF; i++) if ($i == field) col = i }
		$1 == id { $col = val } { print }' "$T/good.cgats" >"$4"
}
TCS05_LINE=$(line_of '^TCS05' "$T/good.cgats")
for v in 1e308 -1e308 1e30 -5 -1.5; do
	set_cell TCS05 SPEC_550 "$v" "$T/value.cgats"
	refused "spectral value $v" "$T/value.cgats" "line $TCS05_LINE: field SPEC_550: '$v'" \
		"expected a reflectance between -1 and 10"
done
set_cell TCS05 SPEC_550 1e309 "$T/value.cgats"
refused "spectral value 1e309" "$T/value.cgats" "line $TCS05_LINE: field SPEC_550" \
	"beyond the largest number a double holds"
# Slightly above 1 and slightly below 0, as real measurements give: taken.
set_cell TCS05 SPEC_550 1.07 "$T/value.cgats"
accepted "$T/value.cgats"
set_cell TCS05 SPEC_550 -0.02 "$T/value.cgats"
accepted "$T/value.cgats"
# Camera RGB far beyond any encoding.
awk 'BEGIN { OFS = "\t" } $1 == "TCS07" { $3 = "1e308" } { print }' "$T/rgb.cgats" >"$T/rgb_huge.cgats"
rm -f "$T/ref.json"
expect_exit 1 "$KOGEI" calib reference --spectra "$T/good.cgats" --rgb "$T/rgb_huge.cgats" -o "$T/ref.json"
refusal_named "RGB 1e308" "$T/rgb_huge.cgats" \
	"line $(line_of '^TCS07' "$T/rgb_huge.cgats"): field RGB_G: '1e308': expected a value of magnitude at most"
check "RGB 1e308: no reference" test ! -e "$T/ref.json"

# ---- spectral field names ------------------------------------------------------------

# X-Rite's nm<nm> and SPECTRAL_NM<nm>, and SPEC_ in lower case, read as SPEC_<nm>.
expect_exit 0 "$KOGEI" spectra xyz "$T/good.cgats" -o "$T/xyz_spec.cgats"
for form in nm NM SPECTRAL_NM SPECTRAL_NM_ spec_; do
	sed "/^SAMPLE_ID/s/SPEC_/$form/g" "$T/good.cgats" >"$T/form.cgats"
	accepted "$T/form.cgats"
	check "$form<nm>: the same XYZ as SPEC_<nm>" cmp -s "$T/xyz.cgats" "$T/xyz_spec.cgats"
done

# rename FROM TO OUT: the nm<nm> file with field FROM renamed TO.
sed '/^SAMPLE_ID/s/SPEC_/nm/g' "$T/good.cgats" >"$T/nm.cgats"
TAB=$(printf '\t')
rename() { sed "/^SAMPLE_ID/s/$TAB$1$TAB/$TAB$2$TAB/" "$T/nm.cgats" >"$3"; }
for name in nmInf nmnan nm-x nm400x '"nm 400"' nm NMinf spec_Inf SPECTRAL_NM_abc; do
	rename nm580 "$name" "$T/name.cgats"
	shown=$(echo "$name" | tr -d '"')
	refused "field $name" "$T/name.cgats" "field $shown: expected SPEC_<nm>" \
		"with a finite wavelength in nm as a plain number"
done
for name in nm-5 nm0 nm50 nm9999 SPEC_50000; do
	rename nm580 "$name" "$T/name.cgats"
	refused "field $name" "$T/name.cgats" "field $name:" \
		"expected a wavelength between 100 and 5000 nm"
done
# The same wavelength twice, in one form or two.
for name in nm575 SPEC_575 SPECTRAL_NM575 SPEC_575000; do
	rename nm580 "$name" "$T/name.cgats"
	refused "field $name after nm575" "$T/name.cgats" "both hold 575 nm" "each wavelength once"
done

exit $fail
