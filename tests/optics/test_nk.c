/* Optical constants: the Rakic 1998 Lorentz-Drude model (transcription and its
 * distance from Johnson & Christy's measurements), and the CSV / refractiveindex.info
 * YAML readers on real files and on malformed input. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "kg_optics.h"
#include "kg_test.h"
#include "tmpfiles.h"

/* The model evaluated by refractiveindex.info from the paper's parameters
 * (database/data/main/{Ag,Au,Cu}/nk/Rakic-LD.yml, CC0; wavelengths in um rounded
 * to 5 digits, n and k to 5): a check of the transcription of the table. */
static void rakic_transcription(void)
{
	static const struct {
		const char *el;
		double um, n, k;
	} pts[] = {
		{"Ag", 0.45610, 0.13507, 2.3840}, {"Ag", 0.55518, 0.13465, 3.2132},
		{"Ag", 0.64973, 0.14619, 3.9347}, {"Ag", 0.30783, 1.1300, 0.58101},
		{"Au", 0.45114, 1.2439, 1.6777},  {"Au", 0.55672, 0.47290, 2.4364},
		{"Au", 0.65446, 0.28922, 3.3350}, {"Au", 0.40285, 1.4112, 1.7490},
		{"Cu", 0.45161, 1.2279, 2.1883},  {"Cu", 0.55477, 0.53052, 2.8106},
		{"Cu", 0.65403, 0.31507, 3.7266}, {"Cu", 1.0075, 0.25557, 6.5372},
	};
	double worst = 0;
	for (size_t i = 0; i < sizeof(pts) / sizeof(pts[0]); i++) {
		double n, k;
		kg_err e = {""};
		int r = kg_nk_rakic1998_ld_at(pts[i].el, 1000 * pts[i].um, &n, &k, &e);
		CHECK(r == 0, "%s", e.msg);
		/* 5 significant digits, plus the rounding of the wavelength */
		double tol = 2e-4 * fmax(1, fabs(pts[i].k));
		CHECK_NEAR(n, pts[i].n, tol, pts[i].el);
		CHECK_NEAR(k, pts[i].k, tol, pts[i].el);
		worst = fmax(worst, fmax(fabs(n - pts[i].n), fabs(k - pts[i].k)));
	}
	printf("Rakic LD vs refractiveindex.info's evaluation: max |d(n,k)| = %.2g\n", worst);

	kg_err e = {""};
	kg_nk nk;
	CHECK(kg_nk_rakic1998_ld("Sn", &nk, &e) == KG_ENOTSUP && strstr(e.msg, "Sn"),
	      "unknown element: %s", e.msg);
	double n, k;
	CHECK(kg_nk_rakic1998_ld_at("Au", -5, &n, &k, &e) == KG_EINVAL, "negative wavelength");
	CHECK(kg_nk_rakic1998_ld("au", &nk, NULL) == 0, "element names ignore case");
}

/* Normal-incidence reflectance of the model against Johnson & Christy (1972), whose
 * n, k are interpolated linearly to the band centres, over 450-700 nm.
 *
 * The model does NOT meet 0.03 everywhere (measured, see the printout): Rakic et al.
 * fitted their oscillators to a compilation of several data sets over a wide energy
 * range, and the visible part comes out differently from J&C --
 *   Ag: R is 0.02-0.06 low (too much damping in the visible; worst at 450 nm);
 *   Au: R is 0.04-0.06 low in the red and the interband edge sits ~10 nm off;
 *   Cu: the interband edge is smeared: R is up to 0.16 high at 520-590 nm.
 * The parameters are transcribed correctly (rakic_transcription above agrees with
 * refractiveindex.info's evaluation to 1e-4), so these are properties of the model.
 * The test pins the measured deviations (bounds a little above them) so that a
 * change in the model or the resampling shows up, and checks the 0.03 agreement where
 * the model has it. */
static void against_johnson_christy(const char *ref)
{
	static const struct {
		const char *el, *file;
		double bound;                  /* max |dR| over 450-700 nm, measured + margin */
		double good_from, good_to;     /* a range where |dR| <= 0.03 holds (0: none) */
	} metals[] = {
		{"Ag", "Ag_JohnsonChristy1972.csv", 0.065, 585, 700},
		/* Au: the curves only cross (near 470 and 520 nm); no range of agreement */
		{"Au", "Au_JohnsonChristy1972.csv", 0.070, 0, 0},
		{"Cu", "Cu_JohnsonChristy1972.csv", 0.165, 610, 700},
	};
	for (int m = 0; m < 3; m++) {
		char path[4096];
		snprintf(path, sizeof(path), "%s/nk/%s", ref, metals[m].file);
		kg_nk jc, ld;
		kg_err e = {""};
		int r = kg_nk_load(path, 0, &jc, &e);
		CHECK(r == 0, "%s", e.msg);
		r = kg_nk_rakic1998_ld(metals[m].el, &ld, &e);
		CHECK(r == 0, "%s", e.msg);
		kg_spectrum rjc, rld;
		kg_nk_reflectance(&jc, 1.0, &rjc);
		kg_nk_reflectance(&ld, 1.0, &rld);
		double worst = 0, at = 0, worst_good = 0;
		char over[256] = ""; /* the ranges where |dR| > 0.03 */
		double run_from = 0, prev = 0;
		printf("%s  R(LD) - R(J&C):", metals[m].el);
		for (int b = 0; b < KG_NBANDS; b++) {
			double nm = kg_band_nm(b), d = rld.v[b] - rjc.v[b];
			if (nm < 450)
				continue;
			if ((int)nm % 50 == 0)
				printf(" %g:%+.3f", nm, d);
			if (fabs(d) > worst) {
				worst = fabs(d);
				at = nm;
			}
			if (fabs(d) > 0.03 && !run_from)
				run_from = nm;
			if (run_from && (fabs(d) <= 0.03 || nm == KG_LAMBDA_MAX)) {
				snprintf(over + strlen(over), sizeof(over) - strlen(over), " %g-%g",
				         run_from, fabs(d) > 0.03 ? nm : prev);
				run_from = 0;
			}
			prev = nm;
			if (metals[m].good_from && nm >= metals[m].good_from && nm <= metals[m].good_to)
				worst_good = fmax(worst_good, fabs(d));
		}
		printf("\n%s  max |dR| over 450-700 nm = %.3f at %g nm; target 0.03 %s "
		       "(|dR| > 0.03 in nm:%s)\n", metals[m].el, worst, at,
		       worst <= 0.03 ? "met" : "NOT met", over[0] ? over : " none");
		CHECK(worst <= metals[m].bound, "%s: max |dR| %.3f at %g nm exceeds the measured "
		      "deviation of the model (%.3f)", metals[m].el, worst, at, metals[m].bound);
		CHECK(worst_good <= 0.03, "%s: |dR| %.3f > 0.03 in %g-%g nm", metals[m].el,
		      worst_good, metals[m].good_from, metals[m].good_to);
	}
	/* the brief's sanity points, with the model's own values */
	kg_nk ld;
	kg_spectrum r;
	kg_nk_rakic1998_ld("Au", &ld, NULL);
	kg_nk_reflectance(&ld, 1.0, &r);
	CHECK(r.v[10] < 0.45 && r.v[60] > 0.9, "Au: R450 %.3f, R700 %.3f", r.v[10], r.v[60]);
	kg_nk_rakic1998_ld("Ag", &ld, NULL);
	kg_nk_reflectance(&ld, 1.0, &r);
	CHECK(r.v[30] > 0.94, "Ag: R550 %.3f", r.v[30]);
}

/* Every CSV in reference/nk loads; R at 450, 550, 650, 700 nm matches the
 * plausibility table of reference/SOURCES.md (computed there independently by linear
 * interpolation, printed to 3 decimals). */
static void real_csv(const char *ref)
{
	static const struct {
		const char *file;
		double r[4];
	} table[] = {
		{"Ag_JohnsonChristy1972", {0.980, 0.983, 0.990, 0.993}},
		{"Cu_JohnsonChristy1972", {0.538, 0.624, 0.935, 0.955}},
		{"Au_JohnsonChristy1972", {0.408, 0.792, 0.957, 0.971}},
		{"Ag_McPeak2015", {0.980, 0.988, 0.990, 0.991}},
		{"Cu_McPeak2015", {0.582, 0.675, 0.973, 0.979}},
		{"Au_McPeak2015", {0.390, 0.848, 0.968, 0.980}},
		{"Au_BabarWeaver2015", {0.363, 0.842, 0.967, 0.980}},
		{"Cu_BabarWeaver2015", {0.541, 0.656, 0.977, 0.985}},
		{"Al_McPeak2015", {0.922, 0.916, 0.904, 0.895}},
		{"Zn_Werner2009", {0.857, 0.869, 0.875, 0.877}},
		{"Zn_Querry1987", {0.768, 0.767, 0.738, 0.725}},
		{"Pb_MathewsonMyers1971", {0.690, 0.661, 0.658, 0.672}},
		{"CuZn_Cu70Zn30_Querry1985", {0.434, 0.789, 0.887, 0.906}},
		{"AuAg_Au50Ag50_Rioux2014", {0.648, 0.891, 0.933, 0.941}},
		{"Cu2O_SOPRA", {0.273, 0.264, 0.238, 0.229}},
		{"CuO_SOPRA", {0.216, 0.216, 0.223, 0.239}},
	};
	const int bands[4] = {10, 30, 50, 60};
	double worst = 0;
	for (size_t i = 0; i < sizeof(table) / sizeof(table[0]); i++) {
		char path[4096];
		snprintf(path, sizeof(path), "%s/nk/%s.csv", ref, table[i].file);
		kg_nk nk;
		kg_err e = {""};
		if (kg_nk_load(path, 0, &nk, &e) != 0) {
			CHECK(0, "%s", e.msg);
			continue;
		}
		kg_spectrum r;
		kg_nk_reflectance(&nk, 1.0, &r);
		for (int j = 0; j < 4; j++) {
			/* the 1 nm Rioux data are averaged over each band, not interpolated */
			CHECK_NEAR(r.v[bands[j]], table[i].r[j], 0.0015, table[i].file);
			worst = fmax(worst, fabs(r.v[bands[j]] - table[i].r[j]));
		}
	}
	printf("reference/nk CSVs: R vs SOURCES.md table, max |d| = %.4f\n", worst);
}

/* Write a reference CSV out as refractiveindex.info YAML (um), both as one
 * `tabulated nk` item and as `tabulated n` + `tabulated k` items, and read it back. */
static void yaml_roundtrip(const char *ref)
{
	char path[4096];
	snprintf(path, sizeof(path), "%s/nk/Au_JohnsonChristy1972.csv", ref);
	kg_nk csv, yml;
	kg_err e = {""};
	CHECK(kg_nk_load(path, 0, &csv, &e) == 0, "%s", e.msg);
	FILE *in = fopen(path, "r");
	CHECK(in != NULL, "open %s", path);
	if (!in)
		return;
	char nkbuf[8192] = "", nbuf[8192] = "", kbuf[8192] = "", line[256];
	double w, n, k;
	fgets(line, sizeof(line), in);
	while (fgets(line, sizeof(line), in) && sscanf(line, "%lf,%lf,%lf", &w, &n, &k) == 3) {
		snprintf(nkbuf + strlen(nkbuf), sizeof(nkbuf) - strlen(nkbuf),
		         "        %.10g %.10g %.10g\n", w / 1000, n, k);
		snprintf(nbuf + strlen(nbuf), sizeof(nbuf) - strlen(nbuf), "        %.10g %.10g\n",
		         w / 1000, n);
		snprintf(kbuf + strlen(kbuf), sizeof(kbuf) - strlen(kbuf), "      %.10g %.10g\n",
		         w / 1000, k);
	}
	fclose(in);
	char doc[40000];
	snprintf(doc, sizeof(doc),
	         "# this file is part of refractiveindex.info database\n"
	         "REFERENCES: \"P. B. Johnson and R. W. Christy. Phys. Rev. B 6, 4370 (1972)\"\n"
	         "COMMENTS: |\n    Room temperature.\n    DATA: not a key here\n"
	         "DATA:\n  - type: tabulated nk\n    data: |\n%s"
	         "SPECS:\n    thin_film: true\n", nkbuf);
	e.msg[0] = 0;
	CHECK(kg_nk_load(kg_tmpfile("au.yml", doc), 0, &yml, &e) == 0, "%s", e.msg);
	double d = fmax(kg_spectrum_rmse(&csv.n, &yml.n), kg_spectrum_rmse(&csv.k, &yml.k));
	CHECK(d < 1e-12, "tabulated nk YAML vs CSV: rms %g", d);

	/* n and k as separate items; k given at every other wavelength only, with a
	 * comment and a key the reader skips */
	char khalf[8192] = "";
	int row = 0;
	for (char *p = kbuf; *p; row++) {
		char *nl = strchr(p, '\n');
		if (row % 2 == 0 || !nl[1])
			snprintf(khalf + strlen(khalf), sizeof(khalf) - strlen(khalf), "%.*s",
			         (int)(nl - p + 1), p);
		p = nl + 1;
	}
	snprintf(doc, sizeof(doc),
	         "REFERENCES: x\nDATA:\n  - type: tabulated n\n    data: |\n%s"
	         "  -\n    type: 'tabulated k'\n    wavelength_range: 0.2 1.0\n    data: |\n"
	         "      # comment\n%s", nbuf, khalf);
	e.msg[0] = 0;
	CHECK(kg_nk_load(kg_tmpfile("au_n_k.yaml", doc), 0, &yml, &e) == 0, "%s", e.msg);
	CHECK(kg_spectrum_rmse(&csv.n, &yml.n) < 1e-12, "tabulated n vs CSV");
	CHECK(kg_spectrum_rmse(&csv.k, &yml.k) < 0.05, "tabulated k (half the points) vs CSV");

	/* n only: k = 0 */
	snprintf(doc, sizeof(doc), "DATA:\n  - type: tabulated n\n    data: |\n"
	         "        0.3 1.5\n        0.8 1.48\n");
	CHECK(kg_nk_parse_yaml(doc, "glass", 0, &yml, &e) == 0 && yml.k.v[20] == 0.0 &&
	      fabs(yml.n.v[0] - (1.5 - 0.02 * 100 / 500)) < 1e-12, "tabulated n only: %s", e.msg);
}

/* An input that must fail with `code`, the message containing `needle`. */
static void expect_fail(int got, int code, const kg_err *e, const char *needle,
                        const char *what)
{
	CHECK(got == code, "%s: returned %d, expected %d (%s)", what, got, code, e->msg);
	CHECK(strstr(e->msg, needle) != NULL, "%s: message '%s' lacks '%s'", what, e->msg,
	      needle);
}

static void malformed(void)
{
	kg_nk nk;
	kg_err e;
	const char *head = "wavelength_nm,n,k\n";
	char doc[1024];
#define CSV(body, code, needle)                                                       \
	do {                                                                              \
		snprintf(doc, sizeof(doc), "%s%s", head, body);                               \
		e.msg[0] = 0;                                                                 \
		expect_fail(kg_nk_parse_csv(doc, "t.csv", 0, &nk, &e), code, &e, needle, body); \
	} while (0)
	CSV("", KG_EINVAL, "no data rows");
	CSV("390,1,2\n500,x,2\n710,1,2\n", KG_EINVAL, "line 3");
	CSV("390,1,2\n500,1,-0.5\n710,1,2\n", KG_EINVAL, "k = -0.5");
	CSV("390,-1,2\n710,1,2\n", KG_EINVAL, "n = -1");
	CSV("390,1,2\n500,1,2\n450,1,2\n710,1,2\n", KG_EINVAL, "line 4");
	CSV("390,1,2\n500,1,2\n", KG_ERANGE, "400-700");
	CSV("390,1,2\n500,1\n", KG_EINVAL, "line 3");
	e.msg[0] = 0;
	expect_fail(kg_nk_parse_csv("wavelength_nm,n,kappa\n400,1,1\n", "t.csv", 0, &nk, &e),
	            KG_EINVAL, &e, "'k'", "missing column");
	/* short data are accepted when extrapolation is asked for */
	snprintf(doc, sizeof(doc), "%s390,1,2\n500,1.5,3\n", head);
	CHECK(kg_nk_parse_csv(doc, "t.csv", KG_RESAMPLE_EXTRAPOLATE, &nk, &e) == 0 &&
	      nk.k.v[60] == 3.0, "extrapolate: %s", e.msg);
	/* a decreasing table is turned round */
	snprintf(doc, sizeof(doc), "%s800,1,4\n600,2,3\n390,3,2\n", head);
	CHECK(kg_nk_parse_csv(doc, "t.csv", 0, &nk, &e) == 0 && nk.n.v[40] == 2.0 &&
	      nk.k.v[0] < nk.k.v[60], "decreasing table: %s", e.msg);

	const char *good_item = "  - type: tabulated nk\n    data: |\n        0.3 1 2\n"
	                        "        0.8 1 2\n";
#define YAML(text, code, needle)                                                      \
	do {                                                                              \
		e.msg[0] = 0;                                                                 \
		expect_fail(kg_nk_parse_yaml(text, "t.yml", 0, &nk, &e), code, &e, needle, text); \
	} while (0)
	YAML("REFERENCES: x\n", KG_EINVAL, "no top-level DATA");
	YAML("DATA:\n  - type: formula 2\n    coefficients: 0 1 2\n", KG_ENOTSUP,
	     "formula 2");
	YAML("DATA:\n  - type: tabulated nk\n    data: |\n        0.3 1\n", KG_EINVAL,
	     "line 4");
	YAML("DATA:\n  - type: tabulated nk\n    data: |\n        0.3 1 2 4\n", KG_EINVAL,
	     "line 4");
	YAML("DATA:\n  - type: tabulated nk\n    data: |\n        0.3 1 zz\n", KG_EINVAL,
	     "'zz'");
	YAML("DATA:\n  - type: tabulated nk\n    data: 0.3 1 2\n", KG_EINVAL, "literal block");
	YAML("DATA:\n  - type: tabulated nk\n", KG_EINVAL, "no 'data: |'");
	YAML("DATA:\n\t- type: tabulated nk\n", KG_EINVAL, "tab");
	YAML("DATA:\n  - data: |\n        0.3 1 2\n", KG_EINVAL, "before 'type'");
	YAML("DATA:\n  - type: tabulated k\n    data: |\n        0.3 1\n", KG_EINVAL,
	     "no 'tabulated nk' or 'tabulated n'");
	snprintf(doc, sizeof(doc), "DATA:\n%s%s", good_item, good_item);
	YAML(doc, KG_EINVAL, "second");
	YAML("DATA:\n  - type: tabulated nk\n    data: |\n        0.3 1 2\n        0.5 1 2\n",
	     KG_ERANGE, "400-700");
	YAML("just text\n", KG_EINVAL, "line 1");
	YAML("DATA:\n  - type: tabulated nk\n    data: |\n        0.3 1 -2\n        0.8 1 2\n",
	     KG_EINVAL, "k = -2");
	snprintf(doc, sizeof(doc), "DATA:\n%s", good_item);
	CHECK(kg_nk_parse_yaml(doc, "t.yml", 0, &nk, &e) == 0 && nk.n.v[3] == 1.0, "%s",
	      e.msg);

	e.msg[0] = 0;
	expect_fail(kg_nk_load("table.txt", 0, &nk, &e), KG_ENOTSUP, &e, ".csv", "extension");
	e.msg[0] = 0;
	CHECK(kg_nk_load("/nonexistent/x.csv", 0, &nk, &e) < 0 && strstr(e.msg, "x.csv"),
	      "missing file: %s", e.msg);
#undef CSV
#undef YAML
}

int main(void)
{
	kg_tmpdir_create("kg_test_nk");
	rakic_transcription();
	malformed();
	if (kg_test_failures) /* report them even when the reference data are absent */
		return kg_test_done("test_nk");
	const char *ref = kg_test_reference_dir();
	against_johnson_christy(ref);
	real_csv(ref);
	yaml_roundtrip(ref);
	return kg_test_done("test_nk");
}
