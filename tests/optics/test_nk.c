/* Optical constants: the published dispersion models (the Rakic 1998 Lorentz-Drude
 * model, Vial & Laroche's and Vial's Drude-critical-points fits, Le Ru & Etchegoin's gold
 * model: transcription, and distance from Johnson & Christy's measurements), the
 * models the default library uses, and the CSV / refractiveindex.info YAML readers on
 * real files and on malformed input. */
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

/* The published models by name: the evaluation against an independent evaluation of
 * the same formulas and parameters (a Python script written separately from nk.c, complex
 * arithmetic in double precision; printed to 10 digits), the element/model checks, and
 * n, k >= 0 on the grid. */
static void models_by_name(void)
{
	static const struct {
		const char *model, *el;
		double nm, n, k; /* k of the principal root of eps (may be < 0, see below) */
	} pts[] = {
		{"vial-laroche2008-dcp", "Au", 450, 1.415665357, 1.950640882},
		{"vial-laroche2008-dcp", "Au", 650, 0.1846719218, 3.585421436},
		{"vial-laroche2008-dcp", "Ag", 450, 0.02047256519, -2.628404116},
		{"vial-laroche2008-dcp", "Ag", 650, 0.01073680698, 4.41187001},
		{"vial2008ch-dcp", "Au", 550, 0.394688651, 2.453152711},
		{"vial2008ch-dcp", "Ag", 550, 0.1255494797, 3.332784316},
		{"vial2008ch-dcp", "Cu", 450, 1.241704932, 2.400338179},
		{"vial2008ch-dcp", "Cu", 600, 0.4106521178, 2.935121806},
		{"leru-etchegoin2009", "Au", 500, 0.9252943446, 1.961734851},
		{"leru-etchegoin2009", "Au", 700, 0.1365227852, 4.046903691},
	};
	double worst = 0;
	for (size_t i = 0; i < sizeof(pts) / sizeof(pts[0]); i++) {
		double n, k;
		kg_err e = {""};
		CHECK(kg_nk_model_at(pts[i].model, pts[i].el, pts[i].nm, &n, &k, &e) == 0, "%s",
		      e.msg);
		/* Im eps < 0 (here Vial & Laroche's silver at 450 nm) is returned as |k| */
		CHECK_NEAR(n, pts[i].n, 1e-8, pts[i].model);
		CHECK_NEAR(k, fabs(pts[i].k), 1e-8, pts[i].model);
		worst = fmax(worst, fmax(fabs(n - pts[i].n), fabs(k - fabs(pts[i].k))));
	}
	printf("published models vs an independent evaluation: max |d(n,k)| = %.2g\n", worst);

	/* rakic1998-ld by name is kg_nk_rakic1998_ld */
	static const char *const els[] = {"Ag", "Au", "Cu"};
	for (int i = 0; i < 3; i++) {
		kg_nk a, b;
		CHECK(kg_nk_model("rakic1998-ld", els[i], &a, NULL) == 0 &&
		      kg_nk_rakic1998_ld(els[i], &b, NULL) == 0 &&
		      memcmp(&a, &b, sizeof(a)) == 0, "rakic1998-ld by name, %s", els[i]);
	}

	/* every model and element: n, k finite and >= 0 on the grid; where Im eps < 0 the
	 * reflectance from (n, |k|) equals that of the principal root (it depends on k^2) */
	static const struct {
		const char *model, *el;
	} all[] = {
		{"rakic1998-ld", "Ag"}, {"rakic1998-ld", "Au"}, {"rakic1998-ld", "Cu"},
		{"vial-laroche2008-dcp", "Ag"}, {"vial-laroche2008-dcp", "Au"},
		{"vial2008ch-dcp", "Ag"}, {"vial2008ch-dcp", "Au"}, {"vial2008ch-dcp", "Cu"},
		{"leru-etchegoin2009", "Au"},
	};
	for (size_t i = 0; i < sizeof(all) / sizeof(all[0]); i++) {
		kg_nk nk;
		kg_err e = {""};
		CHECK(kg_nk_model(all[i].model, all[i].el, &nk, &e) == 0, "%s", e.msg);
		for (int b = 0; b < KG_NBANDS; b++)
			CHECK(isfinite(nk.n.v[b]) && isfinite(nk.k.v[b]) && nk.n.v[b] >= 0 &&
			      nk.k.v[b] >= 0, "%s %s at %g nm: n %g, k %g", all[i].model, all[i].el,
			      kg_band_nm(b), nk.n.v[b], nk.k.v[b]);
	}

	kg_err e = {""};
	kg_nk nk;
	double n, k;
	CHECK(kg_nk_model("vial-laroche2008-dcp", "Cu", &nk, &e) == KG_ENOTSUP &&
	      strstr(e.msg, "Cu") && strstr(e.msg, "Ag or Au"), "element not in model: %s",
	      e.msg);
	CHECK(kg_nk_model("drude", "Au", &nk, &e) == KG_ENOTSUP && strstr(e.msg, "drude") &&
	      strstr(e.msg, "vial-laroche2008-dcp"), "unknown model: %s", e.msg);
	CHECK(kg_nk_model(NULL, "Au", &nk, &e) == KG_ENOTSUP, "no model");
	CHECK(kg_nk_model_at("leru-etchegoin2009", "Au", 0, &n, &k, &e) == KG_EINVAL,
	      "zero wavelength");
	CHECK(kg_nk_model("vial2008ch-dcp", "cu", &nk, NULL) == 0, "element names ignore case");
}

/* Max |R(model) - R(ref)| at normal incidence over the bands from `from` nm to 700 nm;
 * the reference's n, k are interpolated linearly to the band centres. */
static double max_dev(const kg_spectrum *rm, const kg_spectrum *rref, double from,
                      double *at)
{
	double worst = 0;
	for (int b = 0; b < KG_NBANDS; b++) {
		double nm = kg_band_nm(b), d = fabs(rm->v[b] - rref->v[b]);
		if (nm >= from && d > worst) {
			worst = d;
			if (at)
				*at = nm;
		}
	}
	return worst;
}

/* Normal-incidence reflectance of every model against Johnson & Christy (1972) (and,
 * for context only, McPeak et al. 2015), over 450-700 and 400-700 nm.
 *
 * The bounds are the measured deviations plus a small margin (printed): they pin each
 * model, so that a change in a model or in the resampling shows up. For the model the
 * default library uses for each metal (checked below against fixtures/materials/
 * default.json) the 450-700 nm bound is the 0.03:
 *   Au: vial-laroche2008-dcp 0.016; Ag: vial-laroche2008-dcp 0.014 (0.034 at 400-405
 *   nm, so 400-700 nm is NOT within 0.03 for silver); Cu: vial2008ch-dcp 0.0298 (also
 *   over 400-700 nm; a fit to Palik's data published in a book chapter -- no journal
 *   fit of copper to J&C with verifiable parameters was found).
 * The Rakic LD model does NOT meet 0.03 (Rakic et al. fitted a compilation of data sets
 * over a wide energy range): Ag 0.02-0.06 low (worst at 450 nm), Au 0.04-0.06 low in
 * the red with the interband edge ~10 nm off, Cu up to 0.16 high at 520-590 nm (smeared
 * edge). Its parameters are transcribed correctly (rakic_transcription above), so these
 * are properties of the model; the 0.03 agreement is checked where it has it. */
static void against_johnson_christy(const char *ref)
{
	static const struct {
		const char *model, *el;
		double bound450, bound400; /* max |dR| vs J&C, measured + margin */
		double good_from;          /* |dR| <= 0.03 from there to 700 nm (0: nowhere) */
	} cases[] = {
		{"vial-laroche2008-dcp", "Au", 0.03, 0.03, 400},
		{"vial2008ch-dcp", "Au", 0.03, 0.03, 400},
		{"leru-etchegoin2009", "Au", 0.046, 0.046, 0},
		{"rakic1998-ld", "Au", 0.070, 0.070, 0}, /* curves only cross (~470, 520 nm) */
		{"vial-laroche2008-dcp", "Ag", 0.03, 0.036, 410},
		{"vial2008ch-dcp", "Ag", 0.062, 0.101, 0},
		{"rakic1998-ld", "Ag", 0.065, 0.101, 585},
		{"vial2008ch-dcp", "Cu", 0.03, 0.03, 400},
		{"rakic1998-ld", "Cu", 0.165, 0.165, 610},
	};
	printf("max |R(model) - R(ref)| at normal incidence:\n"
	       "  %-22s %-2s  J&C 450-700  J&C 400-700  McPeak 450-700  McPeak 400-700\n",
	       "model", "");
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		char path[4096];
		kg_nk jc, mp, md;
		kg_err e = {""};
		snprintf(path, sizeof(path), "%s/nk/%s_JohnsonChristy1972.csv", ref, cases[i].el);
		CHECK(kg_nk_load(path, 0, &jc, &e) == 0, "%s", e.msg);
		snprintf(path, sizeof(path), "%s/nk/%s_McPeak2015.csv", ref, cases[i].el);
		CHECK(kg_nk_load(path, 0, &mp, &e) == 0, "%s", e.msg);
		CHECK(kg_nk_model(cases[i].model, cases[i].el, &md, &e) == 0, "%s", e.msg);
		if (e.msg[0])
			continue;
		kg_spectrum rjc, rmp, rmd;
		kg_nk_reflectance(&jc, 1.0, &rjc);
		kg_nk_reflectance(&mp, 1.0, &rmp);
		kg_nk_reflectance(&md, 1.0, &rmd);
		double at450 = 0, at400 = 0;
		double d450 = max_dev(&rmd, &rjc, 450, &at450), d400 = max_dev(&rmd, &rjc, 400, &at400);
		printf("  %-22s %-2s  %.3f (%3g)  %.3f (%3g)  %.3f           %.3f\n", cases[i].model,
		       cases[i].el, d450, at450, d400, at400, max_dev(&rmd, &rmp, 450, NULL),
		       max_dev(&rmd, &rmp, 400, NULL));
		CHECK(d450 <= cases[i].bound450, "%s %s: max |dR| over 450-700 nm %.4f at %g nm "
		      "exceeds %.3f", cases[i].model, cases[i].el, d450, at450, cases[i].bound450);
		CHECK(d400 <= cases[i].bound400, "%s %s: max |dR| over 400-700 nm %.4f at %g nm "
		      "exceeds %.3f", cases[i].model, cases[i].el, d400, at400, cases[i].bound400);
		if (cases[i].good_from) {
			double good = max_dev(&rmd, &rjc, cases[i].good_from, NULL);
			CHECK(good <= 0.03, "%s %s: |dR| %.4f > 0.03 in %g-700 nm", cases[i].model,
			      cases[i].el, good, cases[i].good_from);
		}
	}

	/* the default library uses the models asserted to 0.03 above */
	static const struct {
		const char *name, *model, *el;
	} lib_metals[] = {
		{"gold", "vial-laroche2008-dcp", "Au"},
		{"silver", "vial-laroche2008-dcp", "Ag"},
		{"copper", "vial2008ch-dcp", "Cu"},
	};
	char path[4096];
	snprintf(path, sizeof(path), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	kg_material_library *lib = NULL;
	kg_err e = {""};
	CHECK(kg_material_library_load(path, &lib, &e) == 0, "%s", e.msg);
	for (int i = 0; lib && i < 3; i++) {
		const kg_material *m = kg_material_library_find(lib, lib_metals[i].name);
		kg_nk nk;
		kg_nk_model(lib_metals[i].model, lib_metals[i].el, &nk, NULL);
		CHECK(m && memcmp(&m->nk, &nk, sizeof(nk)) == 0, "default library: %s is not %s",
		      lib_metals[i].name, lib_metals[i].model);
	}
	kg_material_library_free(&lib);

	/* the brief's sanity points, with the Rakic model's own values */
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
	models_by_name();
	malformed();
	if (kg_test_failures) /* report them even when the reference data are absent */
		return kg_test_done("test_nk");
	const char *ref = kg_test_reference_dir();
	against_johnson_christy(ref);
	real_csv(ref);
	yaml_roundtrip(ref);
	return kg_test_done("test_nk");
}
