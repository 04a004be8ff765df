/* The error computation of bench/ on synthetic data: the metrics on cases with known
 * answers, then one train -> test experiment with every method (no reference data
 * needed, no timing asserted); and the camera-space rows on a small image. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "kg_bench.h"
#include "kg_test.h"

static void test_percentile(void)
{
	double v[5] = {5, 1, 4, 2, 3};
	CHECK_NEAR(kg_bench_percentile(v, 5, 0.5), 3.0, 0, "median of 1..5");
	double w[21];
	for (int i = 0; i < 21; i++)
		w[i] = 20 - i;
	CHECK_NEAR(kg_bench_percentile(w, 21, 0.95), 19.0, 1e-12, "p95 of 0..20");
	double two[2] = {1, 3};
	CHECK_NEAR(kg_bench_percentile(two, 2, 0.95), 2.9, 1e-12, "p95 between two values");
	double one = 7;
	CHECK_NEAR(kg_bench_percentile(&one, 1, 0.95), 7.0, 0, "p95 of one value");
}

static void test_metrics(const kg_bench_colour *col)
{
	kg_spectrum truth[2], est[2];
	truth[0] = kg_spectrum_const(0.5);
	truth[1] = kg_spectrum_const(0.2);
	/* Identical spectra: no error at all. */
	kg_bench_metrics m;
	CHECK(kg_bench_metrics_compute(col, truth, truth, 2, &m, NULL) == 0, "metrics");
	CHECK_NEAR(m.rmse, 0, 0, "rmse of identical spectra");
	CHECK_NEAR(m.gfc, 1, 1e-12, "gfc of identical spectra");
	CHECK_NEAR(m.de_d65_mean, 0, 1e-9, "dE00 D65 of identical spectra");
	CHECK_NEAR(m.de_a_p95, 0, 1e-9, "dE00 A of identical spectra");
	CHECK(m.n == 2, "n = %d", m.n);
	/* A flat spectrum scaled: RMSE is the offset, the shape (GFC) is unchanged, and a
	 * grey stays grey, so D65 and A give the same lightness difference. */
	est[0] = kg_spectrum_const(0.6);
	est[1] = kg_spectrum_const(0.2);
	CHECK(kg_bench_metrics_compute(col, truth, est, 2, &m, NULL) == 0, "metrics");
	CHECK_NEAR(m.rmse, 0.05, 1e-12, "mean rmse (0.1 and 0)");
	CHECK_NEAR(m.gfc, 1, 1e-12, "gfc of proportional spectra");
	CHECK(m.de_d65_mean > 1, "dE00 of 0.5 vs 0.6 grey: %g", m.de_d65_mean);
	CHECK_NEAR(m.de_d65_mean, m.de_a_mean, 1e-6, "greys: D65 and A agree");
	/* p95 of {0, d} is 0.95 d; the mean is d / 2. */
	CHECK_NEAR(m.de_d65_p95, 1.9 * m.de_d65_mean, 1e-9, "p95 of two values");
}

static void run_case(const kg_bench_colour *col, const kg_sim_camera *cam,
                     const kg_illuminant *d65, const kg_patchset *train,
                     const kg_patchset *test, const kg_sim_noise *noise,
                     kg_bench_error_row *row)
{
	kg_bench_case bc = {
	    .camera = cam,
	    .illuminant = &d65->spd,
	    .train = train,
	    .test = test,
	    .noise = noise,
	    .seed = 7,
	    .wiener_sigma = 0.01,
	};
	kg_err err = {{0}};
	memset(row, 0, sizeof(*row));
	int ret = kg_bench_error_case(col, &bc, row, &err);
	CHECK(ret == 0, "error case: %s", err.msg);
}

static void test_case(const kg_bench_colour *col)
{
	kg_patchset *train = NULL, *test = NULL;
	kg_illuminant *d65 = NULL;
	kg_sim_camera cam;
	kg_bench_synthetic_camera(&cam);
	CHECK(kg_bench_synthetic_spectra(60, 1, &train, NULL) == 0, "training spectra");
	CHECK(kg_bench_synthetic_spectra(150, 2, &test, NULL) == 0, "test spectra");
	CHECK(kg_illuminant_by_name("D65", &d65, NULL) == 0, "D65");
	if (!train || !test || !d65)
		goto done;

	kg_bench_error_row clean, noisy, again;
	run_case(col, &cam, d65, train, test, NULL, &clean);
	CHECK(!clean.noisy, "noise-free row marked noisy");
	CHECK(clean.K_auto >= 1 && clean.K_auto <= KG_CALIB_MAX_BASIS, "K auto %d", clean.K_auto);
	for (int m = 0; m < KG_BENCH_NMETHODS; m++) {
		const kg_bench_metrics *e = &clean.m[m];
		const char *name = kg_bench_method_name((kg_bench_method)m);
		CHECK(clean.available[m], "%s unavailable: %s", name, clean.note[m]);
		CHECK(e->n == test->n, "%s: %d samples", name, e->n);
		CHECK(isfinite(e->rmse) && e->rmse > 0 && e->rmse < 0.1, "%s: rmse %g", name, e->rmse);
		CHECK(e->gfc > 0.9 && e->gfc <= 1 + 1e-12, "%s: gfc %g", name, e->gfc);
		CHECK(e->de_d65_mean >= 0 && e->de_d65_mean < 10, "%s: dE00 D65 %g", name,
		      e->de_d65_mean);
		CHECK(e->de_a_mean >= 0 && e->de_a_mean < 10, "%s: dE00 A %g", name, e->de_a_mean);
		CHECK(e->de_d65_p95 >= 0 && e->de_a_p95 >= 0, "%s: p95", name);
		printf("  %-10s rmse %.4f gfc %.4f dE00 D65 %.2f (p95 %.2f) A %.2f (p95 %.2f)\n", name,
		       e->rmse, e->gfc, e->de_d65_mean, e->de_d65_p95, e->de_a_mean, e->de_a_p95);
	}
	/* A trilinear LUT reproduces a linear map exactly but for float rounding. */
	CHECK_NEAR(clean.m[KG_BENCH_LUT33].rmse, clean.m[KG_BENCH_PCA3].rmse, 1e-4,
	           "lut33 against pca3 rmse");

	kg_sim_noise noise = {.full_well = 20000, .read_noise = 10, .bits = 12};
	run_case(col, &cam, d65, train, test, &noise, &noisy);
	CHECK(noisy.noisy, "noisy row not marked");
	CHECK(noisy.m[KG_BENCH_PCA3].de_d65_mean != clean.m[KG_BENCH_PCA3].de_d65_mean,
	      "noise changed nothing");
	/* The same seed gives the same numbers. */
	run_case(col, &cam, d65, train, test, &noise, &again);
	CHECK(memcmp(noisy.m, again.m, sizeof(noisy.m)) == 0, "not deterministic");
done:
	kg_patchset_free(&train);
	kg_patchset_free(&test);
	kg_illuminant_free(&d65);
}

/* The camera-space rows on a few thousand pixels: every path the CPU has measured,
 * each bit-identical to its method's C reference, the exact paths to the exact one,
 * the quadratic labels nearly all the exact ones, the labels far better than chance,
 * and the report carrying them. */
static void test_camspace_rows(void)
{
	static const int threads[2] = {1, 2};
	char lib[4096], dir[] = "/tmp/kogei-bench-test-XXXXXX";
	snprintf(lib, sizeof(lib), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	kg_bench_config cfg;
	kg_bench_config_default(&cfg, 1);
	cfg.run_error = cfg.run_speed = 0;
	cfg.camspace_mpix = 0.004;
	cfg.reps = 1;
	cfg.threads = threads;
	cfg.nthreads = 2;
	cfg.materials = lib;
	kg_err err = {{0}};
	kg_bench_results *r = NULL;
	CHECK(kg_bench_run(&cfg, &r, &err) == 0, "%s", err.msg);
	if (!r)
		return;
	const kg_bench_camspace *cs = &r->camspace;
	CHECK(cs->pixels == 4000 && cs->materials == 10 && cs->angles == 15,
	      "%ld pixels, %d materials, %d angles", cs->pixels, cs->materials, cs->angles);
	int supported = 0;
	for (int q = 0; q < KG_BENCH_CS_PATHS; q++) {
		const kg_bench_camspace_path *pa = &cs->paths[q];
		supported += pa->supported;
		CHECK(pa->supported || pa->isa != KG_EST_ISA_C, "path %d: the C reference measured", q);
		if (!pa->supported)
			continue;
		CHECK(pa->identical, "path %d differs from its method's C reference", q);
		if (pa->method == KG_CS_EXACT)
			CHECK(pa->labels_agree == 1 && pa->all_agree == 1, "exact path %d: %g %g", q,
			      pa->labels_agree, pa->all_agree);
		else
			CHECK(pa->labels_agree > 0.99 && pa->all_agree > 0, "quadratic path %d: labels %g",
			      q, pa->labels_agree);
	}
	CHECK(cs->nrows == 2 * supported, "%d rows for %d paths", cs->nrows, supported);
	for (int i = 0; i < cs->nrows; i++)
		CHECK(cs->rows[i].mpix_s > 0 && cs->rows[i].threads == threads[i % 2] &&
		          cs->paths[cs->rows[i].path].supported,
		      "row %d: %d threads, %g Mpix/s", i, cs->rows[i].threads, cs->rows[i].mpix_s);
	CHECK(cs->accuracy > 0.5 && cs->refused == 0, "accuracy %.3f, %ld refused",
	      cs->accuracy, cs->refused);
	CHECK(r->nspeed == 0 && r->nerror == 0, "only the camera-space rows were run");
	if (mkdtemp(dir)) {
		CHECK(kg_bench_write_report(r, dir, &err) == 0, "%s", err.msg);
		char md[4200], js[4200], png[4200], text[65536] = {0};
		snprintf(md, sizeof(md), "%s/bench.md", dir);
		snprintf(js, sizeof(js), "%s/bench.json", dir);
		snprintf(png, sizeof(png), "%s/pareto.png", dir);
		FILE *fp = fopen(md, "r");
		if (fp) {
			size_t got = fread(text, 1, sizeof(text) - 1, fp);
			text[got] = '\0';
			fclose(fp);
		}
		CHECK(strstr(text, "## Camera-space matching") && strstr(text, "| exact, c |") &&
		          strstr(text, "| quadratic, c |") &&
		          (strstr(text, "| exact, avx2 | not supported") != NULL) != cs->paths[1].supported,
		      "bench.md has the camera-space table");
		fp = fopen(js, "r");
		memset(text, 0, sizeof(text));
		if (fp) {
			size_t got = fread(text, 1, sizeof(text) - 1, fp);
			text[got] = '\0';
			fclose(fp);
		}
		CHECK(strstr(text, "\"camspace\"") && strstr(text, "\"bit_identical_to_its_c\""),
		      "bench.json has the camera-space rows");
		unlink(md);
		unlink(js);
		unlink(png);
		rmdir(dir);
	}
	kg_bench_results_free(&r);
}

int main(void)
{
	kg_bench_colour col;
	CHECK(kg_bench_colour_init(&col, NULL) == 0, "colour init");
	test_percentile();
	test_metrics(&col);
	test_case(&col);
	test_camspace_rows();
	return kg_test_done("bench-error");
}
