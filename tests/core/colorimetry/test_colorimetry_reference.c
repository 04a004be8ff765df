/* The project's CIE tables against the copies in ../shared/reference/illuminants
 * (colour-science's datasets; see its SOURCES.md). Skipped when that directory is
 * absent. */
#include <math.h>
#include <string.h>

#include "kg_test.h"
#include "spectra_io.h"

#define MAX_ROWS 1024

static double wl[MAX_ROWS], v[MAX_ROWS];

static int read_column(const char *dir, const char *file, int col)
{
	char path[4096];
	snprintf(path, sizeof(path), "%s/illuminants/%s", dir, file);
	return test_csv_column(path, col, wl, v, MAX_ROWS);
}

static void test_cmf(const char *dir)
{
	double max_5nm = 0.0, max_1nm = 0.0;
	for (int c = 0; c < 3; c++) {
		int n = read_column(dir, "cie1931_2deg_xyz_cmf_1nm.csv", c + 1);
		CHECK(n == KG_CMF_COUNT, "expected %d rows, got %d", KG_CMF_COUNT, n);
		for (int i = 0; i < n && i < KG_CMF_COUNT; i++) {
			CHECK(wl[i] == KG_CMF_FIRST_NM + i, "row %d: %g nm", i, wl[i]);
			double d = fabs(kg_cie1931_cmf[i][c] - v[i]);
			if (d > max_1nm)
				max_1nm = d;
			if (i % 5 == 0 && d > max_5nm)
				max_5nm = d;
		}
	}
	printf("CMF vs reference cie1931_2deg_xyz_cmf_1nm.csv: max |diff| at 5 nm %.3g, "
	       "at 1 nm %.3g\n",
	       max_5nm, max_1nm);
	CHECK(max_5nm < 1e-6, "5 nm CMF differs by %g", max_5nm);
	CHECK(max_1nm < 1e-6, "1 nm CMF differs by %g", max_1nm);
}

/* Largest |ours - reference| at the reference's wavelengths. */
static double compare(const kg_illuminant *ill, int n, double *rel)
{
	double max_diff = 0.0;
	*rel = 0.0;
	for (int i = 0; i < n; i++) {
		int found = 0;
		for (int j = 0; j < ill->nsamples; j++)
			if (fabs(ill->wl[j] - wl[i]) < 1e-6) {
				double d = fabs(ill->v[j] - v[i]);
				if (d > max_diff)
					max_diff = d;
				if (v[i] > 0 && d / v[i] > *rel)
					*rel = d / v[i];
				found = 1;
			}
		CHECK(found, "%g nm is not among %s's samples", wl[i], ill->name);
	}
	return max_diff;
}

static void test_illuminant(const char *dir, const char *name, const char *file,
                            double tol, int relative)
{
	kg_illuminant *ill = NULL;
	kg_err err = {{0}};
	if (kg_illuminant_by_name(name, &ill, &err) != 0) {
		fprintf(stderr, "%s\n", err.msg);
		kg_test_failures++;
		return;
	}
	int n = read_column(dir, file, 1);
	double rel, d = compare(ill, n, &rel);
	printf("%s vs reference %s (%d rows): max |diff| %.3g, relative %.3g\n", name, file,
	       n, d, rel);
	CHECK((relative ? rel : d) <= tol, "%s differs from %s by %g", name, file,
	      relative ? rel : d);
	kg_illuminant_free(&ill);
}

static void test_daylight_basis(const char *dir)
{
	double max_diff = 0.0;
	for (int c = 0; c < 3; c++) {
		int n = read_column(dir, "cie_daylight_basis_S0S1S2.csv", c + 1);
		CHECK(n == KG_DAYLIGHT_COUNT, "expected %d rows, got %d", KG_DAYLIGHT_COUNT, n);
		for (int i = 0; i < n && i < KG_DAYLIGHT_COUNT; i++) {
			double d = fabs(kg_cie_daylight_s[i][c] - v[i]);
			if (d > max_diff)
				max_diff = d;
		}
	}
	printf("S0 S1 S2 vs reference cie_daylight_basis_S0S1S2.csv: max |diff| %.3g\n",
	       max_diff);
	CHECK(max_diff < 1e-12, "daylight basis differs by %g", max_diff);
}

int main(void)
{
	const char *dir = kg_test_reference_dir();
	test_cmf(dir);
	/* The reference D65 has 4 decimals, D50 3 (CIE 015:2018); A 6 significant digits. */
	test_illuminant(dir, "D65", "cie_D65.csv", 1e-9, 0);
	test_illuminant(dir, "D50", "cie_D50.csv", 5e-4 + 1e-9, 0);
	test_illuminant(dir, "A", "cie_A.csv", 1e-5, 1);
	test_daylight_basis(dir);
	return kg_test_done("colorimetry_reference");
}
