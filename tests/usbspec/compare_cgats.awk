# Compare the data rows of two CGATS files by SAMPLE_ID: every field of the expected
# file within tol of the measured one. Spectral fields (SPEC_<nm>) are compared as
# fractions: each file's values divided by its SPECTRAL_NORM (1 when absent), so a
# percent file and a fraction file compare equal.
# usage: awk -v tol=T -f compare_cgats.awk EXPECTED MEASURED
FNR == 1 { file++; norm[file] = 1; nfmt = 0 }
$1 == "SPECTRAL_NORM" { v = $2; gsub(/"/, "", v); norm[file] = v + 0 }
/^BEGIN_DATA_FORMAT$/ { informat = 1; next }
/^END_DATA_FORMAT$/ { informat = 0; next }
informat { for (i = 1; i <= NF; i++) spec[file, ++nfmt] = ($i ~ /^SPEC_/) }
/^BEGIN_DATA$/ { indata = 1; next }
/^END_DATA$/ { indata = 0; next }
indata && NF > 1 {
	for (i = 2; i <= NF; i++) if (spec[file, i]) $i = $i / norm[file]
	if (file == 1) { for (i = 2; i <= NF; i++) want[$1, i] = $i; nf[$1] = NF; n++ }
	else { seen[$1] = 1; if (NF != nf[$1]) { print "field count differs for " $1; bad++ }
		for (i = 2; i <= NF; i++) { d = $i - want[$1, i]; if (d < 0) d = -d; if (d > max) { max = d; at = $1 " field " i } } }
}
END { for (k in nf) if (!(k in seen)) { print "missing sample " k; bad++ }
	printf "max difference %.5f at %s\n", max, at; if (bad || max > tol) exit 1 }
