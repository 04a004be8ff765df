/* Camera-space matching (estimate/camspace.c) with a real camera's response: Nikon
 * D5100 sensitivities (../shared/reference; skipped without it) under CIE D65, white
 * at 0.9, and the library's ten materials.
 *  - Noise-free readings of every material at grid angles and several intensities are
 *    matched to their material, angle and intensity exactly.
 *  - With noise of known covariance (the readings of a 40 dB white SNR: sigma 0.009 per
 *    channel), over random materials, grid angles 0-60 degrees and intensities
 *    0.3-1.0: the posterior is checked against the outcome (labels given with a
 *    posterior above 0.99 are right at least 99 % of the time, and the mean posterior
 *    matches the accuracy), and gold, silver and urushi, far apart, are never
 *    confused with one another. The accuracy is printed. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "kg_estimate.h"
#include "kg_test.h"
#include "kg_test_camera.h"

/* F (3 x 61, row-major): the camera's weights. */
static int response(const char *dir, double F[3 * KG_NBANDS], kg_err *err)
{
	kg_spectrum w[3];
	int ret = kg_test_camera_weights(dir, "cameras/Nikon_D5100.csv", "D65", w, err);
	for (int c = 0; !ret && c < 3; c++)
		memcpy(F + c * KG_NBANDS, w[c].v, sizeof(w[c].v));
	return ret;
}

static int index_of(const kg_cs_model *m, const char *name)
{
	for (int j = 0; j < m->n; j++)
		if (!strcmp(m->names[j], name))
			return j;
	return -1;
}

int main(void)
{
	const char *dir = kg_test_reference_dir();
	double F[3 * KG_NBANDS];
	kg_err err = {{0}};
	char lib_path[4096];
	snprintf(lib_path, sizeof(lib_path), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	kg_material_library *lib = NULL;
	CHECK(response(dir, F, &err) == 0 && kg_material_library_load(lib_path, &lib, &err) == 0,
	      "%s", err.msg);
	if (!lib)
		return kg_test_done("estimate-camspace");
	int n = kg_material_library_count(lib);
	const kg_material *mats[KG_EST_MAX_MATERIALS];
	for (int j = 0; j < n; j++)
		mats[j] = kg_material_library_get(lib, j);
	kg_cs_model *m = NULL, *refused = NULL;
	CHECK(kg_cs_model_new(F, mats, n, 0, 95, 5, 0.3, 1.0, &refused, &err) == KG_EINVAL &&
	      !refused && strstr(err.msg, "angles"), "an angle beyond 90 refused: %s", err.msg);
	CHECK(kg_cs_model_new(F, mats, n, 0, 60, 5, 0.3, 1.0, &m, &err) == 0, "%s", err.msg);
	if (!m) {
		kg_material_library_free(&lib);
		return kg_test_done("estimate-camspace");
	}
	CHECK(m->nangles == 13, "13 angles, got %d", m->nangles);

	/* noise-free: exact */
	const double tiny[9] = {1e-8, 0, 0, 0, 1e-8, 0, 0, 0, 1e-8};
	int wrong = 0;
	for (int j = 0; j < n; j++)
		for (int k = 0; k < m->nangles; k += 3)
			for (double a = 0.35; a <= 1.0; a += 0.3) {
				const double *mu = m->mu + 3 * ((size_t)j * m->nangles + k);
				double x[3] = {a * mu[0], a * mu[1], a * mu[2]};
				kg_cs_result r;
				if (kg_cs_match(m, x, tiny, &r) || r.best != j ||
				    r.angle_deg != m->angle_deg[k] || fabs(r.scale - a) > 1e-9 ||
				    r.d2_best > 1e-12)
					wrong++;
			}
	CHECK(wrong == 0, "%d noise-free readings not matched exactly", wrong);
	const double bad_cov[9] = {1, 0, 0, 0, -1, 0, 0, 0, 1};
	kg_cs_result r;
	double x0[3] = {0.3, 0.3, 0.3};
	CHECK(kg_cs_match(m, x0, bad_cov, &r) == KG_EINVAL, "a covariance that is not positive "
	      "definite gives no match");

	/* noise of known covariance */
	const double sigma = 0.009;
	const double cov[9] = {sigma * sigma, 0, 0, 0, sigma * sigma, 0, 0, 0, sigma * sigma};
	/* Separability at that noise, for readings at intensity 0.65. */
	double *d = malloc(sizeof(double) * n * n);
	int group[KG_EST_MAX_MATERIALS];
	CHECK(kg_cs_separability(m, cov, 0.65, d, &err) == 0, "%s", err.msg);
	int ngroups = kg_cs_merge_groups(d, n, KG_CS_MERGE_DISTANCE, group), asym = 0;
	printf("separability at sigma %.3f, intensity 0.65 (pairs a pixel cannot tell apart "
	       "with 1 %% error):\n", sigma);
	for (int i = 0; i < n; i++)
		for (int j = 0; j < n; j++) {
			asym += d[i * n + j] != d[j * n + i];
			if (i < j && kg_cs_pixels_for(d[i * n + j]) > 1)
				printf("  %-26s %-26s d %.3f, %.0f pixels for 1 %% error\n", m->names[i],
				       m->names[j], d[i * n + j], kg_cs_pixels_for(d[i * n + j]));
		}
	printf("  %d classes of %d materials joined below d = %g:", ngroups, n, KG_CS_MERGE_DISTANCE);
	for (int i = 0; i < n; i++)
		if (group[i] == i) {
			printf(" ");
			for (int j = i, first = 1; j < n; j++)
				if (group[j] == i) {
					printf("%s%s", first ? "" : "|", m->names[j]);
					first = 0;
				}
		}
	printf("\n");
	CHECK(asym == 0, "the distance table is symmetric");
	int copper = index_of(m, "copper"), shakudo = index_of(m, "shakudo");
	CHECK(copper >= 0 && shakudo >= 0 && group[copper] == group[shakudo],
	      "copper and shakudo are one class at 40 dB");
	uint64_t st = 12345;
	enum { N = 20000 };
	long right = 0, class_right = 0, confident = 0, confident_right = 0, far_confused = 0;
	double post_sum = 0;
	int gold = index_of(m, "gold"), silver = index_of(m, "silver"), urushi = index_of(m, "urushi");
	CHECK(gold >= 0 && silver >= 0 && urushi >= 0, "the library names gold, silver, urushi");
	for (int i = 0; i < N; i++) {
		int j = (int)(kg_test_uniform(&st) * n), k = (int)(kg_test_uniform(&st) * m->nangles);
		double a = 0.3 + 0.7 * kg_test_uniform(&st);
		const double *mu = m->mu + 3 * ((size_t)j * m->nangles + k);
		double x[3];
		for (int c = 0; c < 3; c++)
			x[c] = a * mu[c] + sigma * kg_test_gauss(&st);
		if (kg_cs_match(m, x, cov, &r))
			continue;
		right += r.best == j;
		class_right += group[r.best] == group[j];
		post_sum += r.posterior;
		if (r.posterior > 0.99) {
			confident++;
			confident_right += r.best == j;
		}
		int far[3] = {gold, silver, urushi};
		for (int p = 0; p < 3; p++)
			for (int q = 0; q < 3; q++)
				far_confused += p != q && j == far[p] && r.best == far[q];
	}
	double acc = (double)right / N, mean_post = post_sum / N;
	double conf_acc = confident ? (double)confident_right / confident : 1;
	printf("camera-space, %d materials, angles 0-60 deg and intensity 0.3-1.0 unknown, "
	       "sigma %.3f: accuracy %.4f, mean posterior %.4f; %ld labels with posterior > "
	       "0.99, %.4f of them right\n", n, sigma, acc, mean_post, confident, conf_acc);
	CHECK(conf_acc >= 0.99, "posterior > 0.99 but right only %.4f of the time", conf_acc);
	CHECK(fabs(mean_post - acc) < 0.03, "mean posterior %.4f against accuracy %.4f", mean_post,
	      acc);
	CHECK(far_confused == 0, "gold, silver or urushi confused with one another %ld times",
	      far_confused);
	CHECK(gold >= 0 && silver >= 0 && urushi >= 0 && group[gold] == gold &&
	      group[silver] == silver && group[urushi] == urushi,
	      "gold, silver and urushi stay classes of their own");

	/* the pooling rule: at d = 0.59, 63 pixels (2 z / d)^2 = 62.2 */
	CHECK(kg_cs_pixels_for(0.59) == 63 && kg_cs_pixels_for(10) == 1 &&
	      isinf(kg_cs_pixels_for(0)), "pixels for a 1 %% error");
	double class_acc = (double)class_right / N;
	printf("  accuracy over the %d classes: %.4f (materials: %.4f)\n", ngroups, class_acc, acc);
	CHECK(class_acc > acc, "merging makes the labels more often right");
	free(d);
	kg_cs_model_free(&m);
	kg_material_library_free(&lib);
	return kg_test_done("estimate-camspace");
}
