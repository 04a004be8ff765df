# Compare `kogei spectra xyz` output (first file) with spec2cie output (second file)
# row by row: max |difference| of XYZ_X/Y/Z, and the CIE 1976 colour difference of
# kogei's LAB_L/A/B against L*a*b* computed from spec2cie's XYZ and its
# ILLUMINANT_WHITE_POINT_XYZ (Y = 1). spec2cie reads every reflective value as percent:
# -v scale=100 brings its XYZ of a file of fractions to kogei's Y = 100 scale.
# usage: awk -v tol=T -v scale=S -v what=TEXT -f compare_spec2cie.awk KOGEI SPEC2CIE
function f(t) { return t > 216 / 24389 ? exp(log(t) / 3) : t * 841 / 108 + 4 / 29 }
FNR == 1 { file++; nfmt = 0; row = 0 }
$1 == "ILLUMINANT_WHITE_POINT_XYZ" { v = $0; sub(/^[^"]*"/, "", v); sub(/".*$/, "", v)
	split(v, w, " "); wx = 100 * w[1]; wy = 100 * w[2]; wz = 100 * w[3] }
/^BEGIN_DATA_FORMAT$/ { informat = 1; next }
/^END_DATA_FORMAT$/ { informat = 0; next }
informat { for (i = 1; i <= NF; i++) col[file, $i] = ++nfmt }
/^BEGIN_DATA$/ { indata = 1; next }
/^END_DATA$/ { indata = 0; next }
indata && NF > 1 {
	row++
	if (file == 1) {
		for (k = 1; k <= 3; k++) {
			x[row, k] = $(col[1, "XYZ_" substr("XYZ", k, 1)])
			lab[row, k] = $(col[1, "LAB_" substr("LAB", k, 1)])
		}
		n = row
		next
	}
	for (k = 1; k <= 3; k++) {
		y[k] = scale * $(col[2, "XYZ_" substr("XYZ", k, 1)])
		d = y[k] - x[row, k]; if (d < 0) d = -d
		if (d > dxyz) { dxyz = d; at = row }
	}
	L = 116 * f(y[2] / wy) - 16; A = 500 * (f(y[1] / wx) - f(y[2] / wy))
	B = 200 * (f(y[2] / wy) - f(y[3] / wz))
	de = sqrt((L - lab[row, 1]) ^ 2 + (A - lab[row, 2]) ^ 2 + (B - lab[row, 3]) ^ 2)
	if (de > dmax) dmax = de
	m = row
}
END {
	printf "%s: %d samples, max |dXYZ| %.2g, max dE76 %.2g (tolerance %g)\n", what, m,
	       dxyz, dmax, tol
	if (m == 0 || m != n || !(wy > 0)) { print "FAIL: " what ": rows or white point missing"; exit 1 }
	if (dxyz > tol || dmax > tol) { print "FAIL: " what ": beyond the tolerance"; exit 1 }
}
