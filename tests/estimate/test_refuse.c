/* The refusal of estimate/: the chi-square quantile, the statistic of the unknown test
 * and kg_classify_image_opts on synthetic data.
 *
 *  - kg_chi2_quantile: exact for 2 degrees of freedom (-2 ln(1 - p)), and the
 *    published 99.9 % points for 1 and 3 (10.828, 16.266); NaN out of range.
 *  - kg_est_classifier_chi2: for a material inside the basis' span and weights drawn
 *    from N(c_j, sigma_w), the mean is K and about 1 in 1000 exceeds the 99.9 %
 *    point; the part outside the span enters as (o_j / K) I; without covariance and
 *    outside part any residual is decisive.
 *  - kg_classify_image_opts with a variance image, a mask and a background level:
 *    identical files for the reference and the optimised kernels and for any block
 *    size; masked pixels are background even when flagged, flagged ones stay
 *    unclassified, dark ones are background, and confidence is NaN for all of them;
 *    a LUT kernel is refused for the unknown test, and so are mismatched sizes. */
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "est_fixture.h"
#include "kg_test.h"

static double gauss(fx_rng *r)
{
	double u = fx_uniform(r, 1e-300, 1.0), v = fx_uniform(r, 0.0, 1.0);
	return sqrt(-2.0 * log(u)) * cos(6.283185307179586 * v);
}

static void check_quantile(void)
{
	const double p[3] = {0.5, 0.9, 0.999};
	for (int i = 0; i < 3; i++) {
		double want = -2.0 * log(1.0 - p[i]), got = kg_chi2_quantile(p[i], 2);
		CHECK(fabs(got - want) <= 1e-8 * want, "chi2 quantile p %g dof 2: %.10g, want %.10g",
		      p[i], got, want);
	}
	CHECK(fabs(kg_chi2_quantile(0.999, 1) - 10.828) < 1e-3, "chi2 0.999 dof 1: %.5f",
	      kg_chi2_quantile(0.999, 1));
	CHECK(fabs(kg_chi2_quantile(0.999, 3) - 16.266) < 1e-3, "chi2 0.999 dof 3: %.5f",
	      kg_chi2_quantile(0.999, 3));
	CHECK(isnan(kg_chi2_quantile(1.0, 3)) && isnan(kg_chi2_quantile(0.5, 0)),
	      "chi2 quantile out of range is NaN");
}

static void check_statistic(const fx_kernels *ks)
{
	/* Material 0 inside span B (c = B^T C exactly), material 1 with a part outside. */
	double spectra[2 * KG_NBANDS], c[3] = {1.2, -0.3, 0.4}, outside = 0;
	for (int o = 0; o < KG_NBANDS; o++) {
		double s = 0;
		for (int i = 0; i < 3; i++)
			s += ks->basis3[o * 3 + i] * c[i];
		spectra[o] = s;
		spectra[KG_NBANDS + o] = s + 0.01 * ((o % 2) ? 1 : -1);
	}
	kg_est_material mats[2] = {{"inside", spectra}, {"outside", spectra + KG_NBANDS}};
	kg_est_classifier *cls = NULL;
	kg_err err = {{0}};
	CHECK(kg_est_classifier_new(ks->pca, mats, 2, KG_EST_DIST_PLAIN, &cls, &err) == 0, "%s",
	      err.msg);
	if (!cls)
		return;
	CHECK(kg_est_classifier_dof(cls) == 3, "dof %d", kg_est_classifier_dof(cls));
	const double g[9] = {0.02, 0.01, 0.0, -0.01, 0.03, 0.005, 0.0, 0.004, 0.015};
	double sigma[9];
	for (int a = 0; a < 3; a++)
		for (int b = 0; b < 3; b++)
			sigma[a * 3 + b] = g[a * 3] * g[b * 3] + g[a * 3 + 1] * g[b * 3 + 1] +
			                   g[a * 3 + 2] * g[b * 3 + 2];
	/* sigma = G G^T, so G z has covariance sigma */
	fx_rng r = {42};
	const int n = 200000;
	double sum = 0, q = kg_chi2_quantile(0.999, 3);
	long above = 0;
	for (int t = 0; t < n; t++) {
		double z[3] = {gauss(&r), gauss(&r), gauss(&r)};
		float w[3];
		for (int a = 0; a < 3; a++)
			w[a] = (float)(c[a] + g[a * 3] * z[0] + g[a * 3 + 1] * z[1] + g[a * 3 + 2] * z[2]);
		double x = kg_est_classifier_chi2(cls, 0, w, sigma);
		sum += x;
		above += x > q;
	}
	printf("chi2 of %d draws: mean %.4f (expected 3), above the 99.9 %% point %ld (expected "
	       "%d)\n",
	       n, sum / n, above, n / 1000);
	CHECK(fabs(sum / n - 3.0) < 0.05, "chi2 mean %.4f, expected 3", sum / n);
	CHECK(above > 120 && above < 290, "%ld of %d above the 99.9 %% point", above, n);

	/* The outside part: zero covariance leaves (o_j / 3) I. */
	for (int o = 0; o < KG_NBANDS; o++) {
		double s = spectra[KG_NBANDS + o];
		for (int i = 0; i < 3; i++) {
			double ci = 0;
			for (int m = 0; m < KG_NBANDS; m++)
				ci += ks->basis3[m * 3 + i] * spectra[KG_NBANDS + m];
			s -= ks->basis3[o * 3 + i] * ci;
		}
		outside += s * s;
	}
	double d[2];
	float w[3] = {1.3f, -0.3f, 0.4f};
	kg_est_classifier_distances(cls, w, d);
	double zero[9] = {0}, r2 = d[1] - outside;
	double x = kg_est_classifier_chi2(cls, 1, w, zero);
	CHECK(fabs(x - r2 / (outside / 3.0)) < 1e-9 * x, "chi2 with the outside part only: %.10g, "
	      "want %.10g", x, r2 / (outside / 3.0));
	/* inside the span o_0 is 0 up to rounding: nothing but the residual is left */
	x = kg_est_classifier_chi2(cls, 0, w, zero);
	CHECK(x > 1e12, "no covariance, no outside part, r != 0: %g", x);
	kg_est_classifier_free(&cls);
}

static char dir[] = "/tmp/kogei-refuse-XXXXXX";

static const char *path(const char *name)
{
	static char pool[64][256];
	static int next;
	char *p = pool[next++ % 64];
	snprintf(p, sizeof(pool[0]), "%s/%s", dir, name);
	return p;
}

static int cmp_float(const void *a, const void *b)
{
	float x = *(const float *)a, y = *(const float *)b;
	return (x > y) - (x < y);
}

static uint8_t *read_bytes(const char *p, size_t n)
{
	uint8_t *b = malloc(n);
	FILE *f = fopen(p, "rb");
	if (!b || !f || fread(b, 1, n, f) != n) {
		free(b);
		b = NULL;
	}
	if (f)
		fclose(f);
	return b;
}

/* The margins' median and 5th percentile of each class, from all of them sorted,
 * equal the summary's (kept in bounded memory by a two-pass histogram). Returns the
 * number of classes with pixels. */
static int check_margins(const kg_classify_result *res, const uint8_t *lab, const float *conf,
                         int npix)
{
	int nonempty = 0;
	for (int j = 0; lab && conf && j < res->nclasses; j++) {
		float *v = malloc(sizeof(float) * npix);
		size_t m = 0;
		for (int i = 0; i < npix; i++)
			if (lab[i] == j + 1)
				v[m++] = conf[i];
		CHECK(m == res->classes[j].pixels, "class %d: %zu pixels in the map, %llu counted", j,
		      m, (unsigned long long)res->classes[j].pixels);
		if (m) {
			nonempty++;
			qsort(v, m, sizeof(float), cmp_float);
			double median = m % 2 ? v[m / 2] : 0.5 * ((double)v[m / 2 - 1] + v[m / 2]);
			size_t rank = (size_t)ceil(0.05 * (double)m);
			double p5 = v[rank ? rank - 1 : 0];
			CHECK(res->classes[j].margin_median == median && res->classes[j].margin_p5 == p5,
			      "class %d (%zu pixels): median %.9g p5 %.9g, sorted %.9g %.9g", j, m,
			      res->classes[j].margin_median, res->classes[j].margin_p5, median, p5);
		}
		free(v);
	}
	return nonempty;
}

static void remove_outputs(const char *stem)
{
	const char *suffix[] = {".hdr", ".img", "_confidence.hdr", "_confidence.img", "_mask.hdr",
	                        "_mask.img", ".json", ".png"};
	for (int i = 0; i < 8; i++) {
		char p[300];
		snprintf(p, sizeof(p), "%s/%s%s", dir, stem, suffix[i]);
		unlink(p);
	}
}

static void check_image(const fx_kernels *ks)
{
	enum { W = 61, H = 37, NMAT = 3 };
	fx_rng r = {7};
	double spectra[NMAT * KG_NBANDS];
	fx_materials(&r, NMAT, spectra);
	kg_est_material mats[NMAT];
	kg_spectrum spec[NMAT];
	char names[NMAT][KG_EST_CLASS_NAME_MAX] = {"a", "b", "c"};
	for (int j = 0; j < NMAT; j++) {
		mats[j].name = names[j];
		mats[j].spectrum = spectra + j * KG_NBANDS;
		memcpy(spec[j].v, spectra + j * KG_NBANDS, sizeof(spec[j].v));
	}
	kg_est_material_set set = {NMAT, mats, spec, names, 0.0, NULL};
	const char *stems[4] = {"c", "avx2", "rows7", "threads1"};
	kg_image *img = NULL, *var = NULL, *mask = NULL, *small = NULL;
	kg_err err = {{0}};
	int rc = kg_image_new(W, H, 3, &img, &err) || kg_image_new(W, H, 3, &var, &err) ||
	         kg_image_new(W, H, 1, &mask, &err) || kg_image_new(W - 1, H, 1, &small, &err);
	CHECK(rc == 0, "images: %s", err.msg);
	if (rc)
		goto out;
	float *px = fx_image(&r, (size_t)W * H, 0.0, 0.9, 1);
	memcpy(img->data, px, sizeof(float) * 3 * W * H);
	free(px);
	for (int i = 0; i < W * H; i++) {
		for (int ch = 0; ch < 3; ch++)
			var->data[3 * i + ch] = (float)fx_uniform(&r, 1e-6, 4e-3);
		mask->data[i] = i % 11 == 3 ? 0.0f : 1.0f;
		if (i % 17 == 5)
			for (int ch = 0; ch < 3; ch++)
				img->data[3 * i + ch] = 0.004f;
	}
	kg_apply_options opt;
	kg_apply_options_init(&opt);
	kg_classify_options copt;
	kg_classify_options_init(&copt);
	kg_row_source var_src, mask_src, small_src;
	kg_row_source_of_image(var, &var_src);
	kg_row_source_of_image(mask, &mask_src);
	kg_row_source_of_image(small, &small_src);
	copt.variance = &var_src;
	copt.frames = 4;
	copt.residual_relative = 0.01;
	copt.mask = &mask_src;
	kg_classify_result res = {0}, first = {0};
	uint64_t unknown_total = 0;
	int have_avx2 = 1;
	for (int s = 0; s < 4; s++) {
		opt.isa = s == 1 ? KG_EST_ISA_AVX2 : KG_EST_ISA_C;
		opt.block_rows = s == 2 ? 7 : 0;
		opt.threads = s == 3 ? 1 : 0;
		char hdr[300];
		snprintf(hdr, sizeof(hdr), "%s.hdr", path(stems[s]));
		rc = kg_classify_image_opts(ks->pca, &set, img, &opt, &copt, NULL, hdr, &res, &err);
		if (s == 1 && rc == KG_ENOTSUP) {
			printf("no AVX2 on this CPU: the optimised kernel is not compared\n");
			have_avx2 = 0;
			continue;
		}
		CHECK(rc == 0, "%s: %s", stems[s], err.msg);
		if (s == 0) {
			unknown_total = res.unknown;
			printf("synthetic: %llu unknown, %llu background, %llu unclassified of %d\n",
			       (unsigned long long)res.unknown, (unsigned long long)res.background,
			       (unsigned long long)res.unclassified, W * H);
			first = res;
			memset(&res, 0, sizeof(res));
		}
		kg_classify_result_free(&res);
	}
	for (int s = 1; s < 4; s++) {
		if (s == 1 && !have_avx2)
			continue;
		const char *sfx[2] = {".img", "_confidence.img"};
		for (int f = 0; f < 2; f++) {
			char a[300], b[300];
			snprintf(a, sizeof(a), "%s%s", path("c"), sfx[f]);
			snprintf(b, sizeof(b), "%s%s", path(stems[s]), sfx[f]);
			CHECK(kg_test_same_file(a, b), "%s%s differs from the reference's", stems[s], sfx[f]);
		}
	}
	char p[300];
	snprintf(p, sizeof(p), "%s.img", path("c"));
	uint8_t *lab = read_bytes(p, (size_t)W * H);
	snprintf(p, sizeof(p), "%s_confidence.img", path("c"));
	float *conf = (float *)read_bytes(p, sizeof(float) * W * H);
	CHECK(lab && conf, "read back");
	long wrong = 0, unknown = 0;
	for (int i = 0; lab && conf && i < W * H; i++) {
		const float *q = img->data + 3 * i;
		int finite = isfinite(q[0]) && isfinite(q[1]) && isfinite(q[2]);
		int flagged = !finite || q[0] >= 0.999f || q[1] >= 0.999f || q[2] >= 0.999f;
		int dark = finite && fmaxf(q[0], fmaxf(q[1], q[2])) < 0.01f;
		int want = i % 11 == 3 ? NMAT + 2 : flagged ? 0 : dark ? NMAT + 2 : -1;
		if (want >= 0)
			wrong += lab[i] != want || !isnan(conf[i]);
		else if (lab[i] == NMAT + 1) {
			unknown++;
			wrong += !isnan(conf[i]);
		} else {
			wrong += lab[i] < 1 || lab[i] > NMAT || isnan(conf[i]);
		}
	}
	CHECK((uint64_t)unknown == unknown_total, "%ld unknown in the map, %llu in the result",
	      unknown, (unsigned long long)unknown_total);
	check_margins(&first, lab, conf, W * H);
	kg_classify_result_free(&first);
	CHECK(wrong == 0, "%ld pixels with the wrong label or confidence", wrong);
	free(lab);
	free(conf);
	/* Without refusals every unflagged pixel gets a material: the margins' order
	 * statistics over thousands of pixels per class. */
	rc = kg_classify_image(ks->pca, &set, KG_EST_DIST_PLAIN, img, &opt, NULL, path("plain.hdr"),
	                       &res, &err);
	CHECK(rc == 0, "plain: %s", err.msg);
	snprintf(p, sizeof(p), "%s.img", path("plain"));
	lab = read_bytes(p, (size_t)W * H);
	snprintf(p, sizeof(p), "%s_confidence.img", path("plain"));
	conf = (float *)read_bytes(p, sizeof(float) * W * H);
	int nonempty = lab && conf ? check_margins(&res, lab, conf, W * H) : -1;
	CHECK(nonempty >= 2, "plain: %d materials with pixels, expected 2 or more", nonempty);
	kg_classify_result_free(&res);
	free(lab);
	free(conf);
	remove_outputs("plain");

	/* Refusals. */
	kg_classify_options bad = copt;
	bad.mask = &small_src;
	rc = kg_classify_image_opts(ks->pca, &set, img, &opt, &bad, NULL, path("bad.hdr"), NULL,
	                            &err);
	CHECK(rc == KG_EINVAL && strstr(err.msg, "60 x 37") && strstr(err.msg, "61 x 37"),
	      "wrong-size mask: %d %s", rc, err.msg);
	bad = copt;
	bad.variance = &mask_src;
	rc = kg_classify_image_opts(ks->pca, &set, img, &opt, &bad, NULL, path("bad.hdr"), NULL,
	                            &err);
	CHECK(rc == KG_EINVAL && strstr(err.msg, "channel"), "1-channel variance: %d %s", rc,
	      err.msg);
	bad = copt;
	var->data[5] = -1.0f;
	rc = kg_classify_image_opts(ks->pca, &set, img, &opt, &bad, NULL, path("bad.hdr"), NULL,
	                            &err);
	CHECK(rc == KG_EINVAL && strstr(err.msg, "pixel (1, 0)"), "negative variance: %d %s", rc,
	      err.msg);
	var->data[5] = 1e-4f;
	rc = kg_classify_image_opts(ks->lut, &set, img, &opt, &copt, NULL, path("bad.hdr"), NULL,
	                            &err);
	CHECK(rc == KG_EINVAL && strstr(err.msg, "lookup-table"), "LUT kernel: %d %s", rc,
	      err.msg);
	snprintf(p, sizeof(p), "%s.hdr", path("bad"));
	CHECK(!kg_test_file_exists(p), "refusals leave no file");
out:
	for (int s = 0; s < 4; s++)
		remove_outputs(stems[s]);
	kg_image_free(&img);
	kg_image_free(&var);
	kg_image_free(&mask);
	kg_image_free(&small);
}

int main(void)
{
	if (!mkdtemp(dir)) {
		perror("mkdtemp");
		return 1;
	}
	fx_kernels ks;
	CHECK(fx_kernels_make(&ks, 1) == 0, "kernels");
	check_quantile();
	check_statistic(&ks);
	check_image(&ks);
	fx_kernels_free(&ks);
	rmdir(dir);
	return kg_test_done("estimate-refuse");
}
