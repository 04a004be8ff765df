/* Noise-free readings of the ColorChecker (Ohta 1997) by the Nikon D5100 (NPL) under
 * CIE D65, all from ../shared/reference, against a direct long-double integration
 * that reads the CSV files itself (no kogei reader involved): through the C API and
 * through `kogei sim patches`. Also: the white level, the recorded keywords, and
 * seeds with noise. Argument: the path of the kogei program. */
#include <math.h>
#include <string.h>

#include "kg_sim.h"
#include "kg_test.h"
#include "sim_test_util.h"

#define NP 24

static char camera_csv[4200], chart_csv[4200], d65_csv[4200];

/* Rows of a CSV whose first column is a wavelength: value of column col at wl nm. */
static int csv_column_at(const char *path, int col, double wl, double *out)
{
	FILE *fp = fopen(path, "r");
	if (!fp)
		return -1;
	char line[65536];
	int found = -1;
	if (!fgets(line, sizeof(line), fp)) {
		fclose(fp);
		return -1;
	}
	while (fgets(line, sizeof(line), fp)) {
		if (strtod(line, NULL) != wl)
			continue;
		char *p = line;
		for (int c = 0; c < col && p; c++) {
			p = strchr(p, ',');
			if (p)
				p++;
		}
		if (p) {
			*out = strtod(p, NULL);
			found = 0;
		}
		break;
	}
	fclose(fp);
	return found;
}

/* Patch i's reflectance at wl nm from `patch,name,380,385,...`. */
static int chart_at(int patch, double wl, double *out)
{
	FILE *fp = fopen(chart_csv, "r");
	if (!fp)
		return -1;
	char line[65536];
	int ok = -1, row = -1;
	while (fgets(line, sizeof(line), fp)) {
		if (row++ != patch)
			continue;
		char *p = line;
		int col = 2 + (int)((wl - 380.0) / 5.0);
		for (int c = 0; c < col && p; c++) {
			p = strchr(p, ',');
			if (p)
				p++;
		}
		if (p) {
			*out = strtod(p, NULL);
			ok = 0;
		}
		break;
	}
	fclose(fp);
	return ok;
}

/* The textbook formula: rho_c = k sum E R S_c 5 nm, k = wl / max_c sum E S_c 5 nm. */
static void direct(double white_level, double rho[NP][3])
{
	long double e[KG_NBANDS], s[3][KG_NBANDS], white[3] = {0, 0, 0};
	for (int i = 0; i < KG_NBANDS; i++) {
		double wl = 400.0 + 5.0 * i, v;
		CHECK(csv_column_at(d65_csv, 1, wl, &v) == 0, "D65 at %g", wl);
		e[i] = v;
		for (int c = 0; c < 3; c++) {
			CHECK(csv_column_at(camera_csv, 1 + c, wl, &v) == 0, "camera at %g", wl);
			s[c][i] = v;
			white[c] += e[i] * s[c][i] * 5.0L;
		}
	}
	long double top = fmaxl(white[0], fmaxl(white[1], white[2]));
	for (int p = 0; p < NP; p++) {
		long double acc[3] = {0, 0, 0};
		for (int i = 0; i < KG_NBANDS; i++) {
			double r;
			CHECK(chart_at(p, 400.0 + 5.0 * i, &r) == 0, "chart patch %d", p);
			for (int c = 0; c < 3; c++)
				acc[c] += e[i] * r * s[c][i] * 5.0L;
		}
		for (int c = 0; c < 3; c++)
			rho[p][c] = (double)(acc[c] * white_level / top);
	}
}

static double max_rel_diff(const double *a, const double *b, int n)
{
	double worst = 0.0;
	for (int i = 0; i < n; i++)
		worst = fmax(worst, fabs(a[i] - b[i]) / fmax(fabs(b[i]), 1e-12));
	return worst;
}

static void test_api(double rho[NP][3])
{
	kg_err err = {{0}};
	kg_sim_capture c;
	CHECK(kg_sim_capture_load(&c, camera_csv, d65_csv, 0.9, NULL, 0, &err) == 0, "%s",
	      err.msg);
	kg_patchset *chart = NULL;
	CHECK(kg_sim_read_spectra(chart_csv, 0, &chart, &err) == 0, "%s", err.msg);
	if (!chart)
		return;
	CHECK(chart->n == NP, "%d patches", chart->n);
	double got[NP][3];
	kg_sim_patches(&c, chart->spectra, NP, 1, &got[0][0]);
	double d = max_rel_diff(&got[0][0], &rho[0][0], 3 * NP);
	printf("API vs direct integration: max relative difference %.3g\n", d);
	CHECK(d < 1e-12, "API differs from direct integration by %g (relative)", d);

	/* The white level is hit exactly by the perfect diffuser. */
	kg_spectrum one = kg_spectrum_const(1.0);
	double w[3];
	kg_sim_capture_mean(&c, &one, w);
	CHECK_NEAR(fmax(w[0], fmax(w[1], w[2])), 0.9, 1e-15, "white level");
	/* patch 19 (white 9.5) just below the white level, black 2 near the floor */
	CHECK(rho[18][1] > 0.75 && rho[18][1] < 0.9, "white patch G %g", rho[18][1]);
	CHECK(rho[23][1] < 0.04, "black patch G %g", rho[23][1]);

	/* D65 by name (CIE table in core) agrees with the reference file. */
	kg_sim_capture byname;
	CHECK(kg_sim_capture_load(&byname, camera_csv, "D65", 0.9, NULL, 0, &err) == 0, "%s",
	      err.msg);
	kg_sim_patches(&byname, chart->spectra, NP, 1, &got[0][0]);
	d = max_rel_diff(&got[0][0], &rho[0][0], 3 * NP);
	printf("illuminant D65 by name vs reference file: max relative difference %.3g\n", d);
	CHECK(d < 1e-6, "D65 by name differs by %g (relative)", d);
	kg_patchset_free(&chart);
}

static void test_cli(const char *kogei, double rho[NP][3])
{
	char errbuf[4096];
	const char *out = kg_test_path("ohta.cgats");
	char *argv[] = {(char *)kogei, "sim", "patches", "--spectra", chart_csv, "--camera",
	                camera_csv, "--illuminant", d65_csv, "-o", (char *)out, NULL};
	int rc = sim_run(argv, errbuf, sizeof(errbuf));
	CHECK(rc == 0, "kogei sim patches exit %d: %s", rc, errbuf);
	kg_err err = {{0}};
	kg_patchset *ps = NULL;
	CHECK(kg_patchset_read(out, 0, &ps, &err) == 0, "%s", err.msg);
	if (ps) {
		CHECK(ps->n == NP && ps->rgb && !ps->spectra, "patch file content");
		if (ps->rgb && ps->n == NP) {
			double d = max_rel_diff(&ps->rgb[0][0], &rho[0][0], 3 * NP);
			printf("CLI (CGATS, 10 digits) vs direct integration: %.3g\n", d);
			CHECK(d < 1e-9, "CLI output differs by %g (relative)", d);
			CHECK(strcmp(ps->ids[0], "1") == 0 && strcmp(ps->ids[23], "24") == 0,
			      "ids %s..%s", ps->ids[0], ps->ids[23]);
		}
	}
	kg_patchset_free(&ps);
	kg_cgats *cg = NULL;
	CHECK(kg_cgats_read(out, &cg, &err) == 0, "%s", err.msg);
	if (cg) {
		const kg_cgats_table *t = cg->tables[0];
		const char *cam = kg_cgats_keyword(t, "CAMERA");
		const char *ill = kg_cgats_keyword(t, "ILLUMINANT");
		const char *noise = kg_cgats_keyword(t, "NOISE");
		const char *seed = kg_cgats_keyword(t, "SEED");
		const char *white = kg_cgats_keyword(t, "WHITE_LEVEL");
		CHECK(cam && strstr(cam, "Nikon_D5100"), "CAMERA keyword %s", cam ? cam : "missing");
		CHECK(ill && strstr(ill, "cie_D65"), "ILLUMINANT keyword %s", ill ? ill : "missing");
		CHECK(noise && strcmp(noise, "none") == 0, "NOISE keyword %s",
		      noise ? noise : "missing");
		CHECK(seed && strcmp(seed, "1") == 0, "SEED keyword %s", seed ? seed : "missing");
		CHECK(white && strtod(white, NULL) == 0.9, "WHITE_LEVEL keyword %s",
		      white ? white : "missing");
		static const char *const fields[] = {"SAMPLE_ID", "RGB_R", "RGB_G", "RGB_B"};
		CHECK(t->nfields == 4, "%d fields, expected SAMPLE_ID RGB_R RGB_G RGB_B", t->nfields);
		for (int f = 0; f < 4 && f < t->nfields; f++)
			CHECK(strcmp(t->fields[f], fields[f]) == 0, "field %d is %s", f, t->fields[f]);
	}
	kg_cgats_free(&cg);

	/* Noise: same seed, same bytes; another seed, other values. */
	const char *outs[3] = {kg_test_path("n1.cgats"), kg_test_path("n2.cgats"), kg_test_path("n3.cgats")};
	const char *seeds[3] = {"17", "17", "18"};
	for (int k = 0; k < 3; k++) {
		char *nargv[] = {(char *)kogei, "sim", "patches", "--spectra", chart_csv,
		                 "--camera", camera_csv, "--illuminant", "D65", "--noise",
		                 "20000:4:12", "--seed", (char *)seeds[k], "-o", (char *)outs[k],
		                 NULL};
		rc = sim_run(nargv, errbuf, sizeof(errbuf));
		CHECK(rc == 0, "noisy run %d: exit %d: %s", k, rc, errbuf);
	}
	char *a = NULL, *b = NULL, *c = NULL;
	size_t la = 0, lb = 0, lc = 0;
	if (kg_read_file(outs[0], &a, &la, NULL) == 0 && kg_read_file(outs[1], &b, &lb, NULL) == 0 &&
	    kg_read_file(outs[2], &c, &lc, NULL) == 0) {
		CHECK(la == lb && memcmp(a, b, la) == 0, "seed 17 twice: files differ");
		CHECK(!(la == lc && memcmp(a, c, la) == 0), "seeds 17 and 18: files identical");
		CHECK(strstr(a, "20000:4:12") != NULL, "NOISE keyword not recorded");
	} else {
		CHECK(0, "noisy outputs missing");
	}
	free(a);
	free(b);
	free(c);
}

int main(int argc, char **argv)
{
	const char *ref = kg_test_reference_dir();
	snprintf(camera_csv, sizeof(camera_csv), "%s/cameras/Nikon_D5100.csv", ref);
	snprintf(chart_csv, sizeof(chart_csv), "%s/charts/colorchecker24_ohta1997.csv", ref);
	snprintf(d65_csv, sizeof(d65_csv), "%s/illuminants/cie_D65.csv", ref);
	if (!kg_test_file_exists(camera_csv) || !kg_test_file_exists(chart_csv) ||
	    !kg_test_file_exists(d65_csv))
		kg_test_skip("Nikon_D5100.csv, colorchecker24_ohta1997.csv or cie_D65.csv missing");
	static double rho[NP][3];
	direct(0.9, rho);
	test_api(rho);
	if (argc > 1) {
		kg_test_scratch_dir("simref");
		test_cli(argv[1], rho);
		kg_test_scratch_remove();
	}
	return kg_test_done("sim/reference");
}
