/* The reference fit's options and files:
 *  - a ridge shrinks: ||M||, ||A|| (linear, root-polynomial) fall and the in-sample
 *    error rises as lambda grows; wiener equals linear with lambda = m sigma^2;
 *  - --basis auto picks K = 3 on spectra built to have 3 dimensions (exactly, and
 *    with a small perturbation outside the span), and K = 2 on 2-dim data;
 *  - --method auto picks the first method within 1 % of the lowest LOO error, and
 *    the LOO errors of the regression methods (closed form) agree with refits that
 *    leave each patch out (1e-9);
 *  - JSON round trip: kogei-reference/1 and kogei-camera/1 load back to the same
 *    values (exactly) and write the same bytes again; inputs read from CGATS files
 *    record their sha256 and keywords (devices, illuminant);
 *  - option errors (K too large, bad ridge, too few patches for auto). */
#include <stdlib.h>
#include <unistd.h>

#include "calib_fixture.h"
#include "kg_test.h"

static double frob(const double *a, int n)
{
	double s = 0;
	for (int i = 0; i < n; i++)
		s += a[i] * a[i];
	return sqrt(s);
}

static kg_reference *fit(const kg_patchset *chart, const kg_reference_options *opt)
{
	kg_reference *ref = NULL;
	kg_err err = {{0}};
	if (kg_reference_fit(chart, chart, opt, &ref, &err)) {
		fprintf(stderr, "fit: %s\n", err.msg);
		kg_test_failures++;
	}
	return ref;
}

static void test_ridge(const kg_patchset *chart)
{
	static const double lambdas[] = {0, 1e-3, 1e-2, 1e-1, 1};
	double prev_m = INFINITY, prev_a = INFINITY, prev_rp = INFINITY, prev_fit = -1;
	for (int i = 0; i < 5; i++) {
		kg_reference_options opt;
		kg_reference_options_default(&opt);
		opt.ridge = lambdas[i];
		kg_reference *ref = fit(chart, &opt);
		if (!ref)
			return;
		double nm = frob(ref->M, ref->K * 3);
		double na = frob(ref->maps[KG_METHOD_LINEAR].A, KG_NBANDS * 3);
		double nrp = frob(ref->maps[KG_METHOD_ROOTPOLY2].A, KG_NBANDS * 6);
		double f = ref->maps[KG_METHOD_PCA].fit_rmse;
		printf("ridge %-6g |M| %.6f |A| %.6f |A_rp2| %.6f fit RMSE %.3g\n", lambdas[i], nm, na,
		       nrp, f);
		CHECK(nm < prev_m && na < prev_a && nrp < prev_rp, "ridge %g does not shrink",
		      lambdas[i]);
		CHECK(f >= prev_fit, "ridge %g: fit error fell", lambdas[i]);
		prev_m = nm;
		prev_a = na;
		prev_rp = nrp;
		prev_fit = f;
		kg_reference_free(&ref);
	}
	/* Wiener is the ridge lambda = m sigma^2. */
	kg_reference_options opt;
	kg_reference_options_default(&opt);
	opt.noise_sigma = 0.02;
	kg_reference *w = fit(chart, &opt);
	opt.ridge = chart->n * 0.02 * 0.02;
	kg_reference *l = fit(chart, &opt);
	if (w && l)
		for (int i = 0; i < KG_NBANDS * 3; i++)
			CHECK_NEAR(w->maps[KG_METHOD_WIENER].A[i], l->maps[KG_METHOD_LINEAR].A[i], 1e-12,
			           "wiener = ridge m sigma^2");
	kg_reference_free(&w);
	kg_reference_free(&l);
}

static void test_basis_auto(void)
{
	static const double outside[] = {0.0, 0.002};
	for (int t = 0; t < 2; t++) {
		kg_patchset *chart = fx_chart(30, outside[t], 11);
		kg_reference_options opt;
		kg_reference_options_default(&opt);
		opt.basis = 0;
		kg_reference *ref = chart ? fit(chart, &opt) : NULL;
		if (ref) {
			printf("3-dim data (+%g outside): K = %d; LOO:", outside[t], ref->K);
			for (int K = 0; K < ref->nK; K++)
				printf(" %.3g", ref->loo_by_K[K]);
			printf("\n");
			CHECK(ref->K == 3 && ref->basis_auto, "K = %d chosen for 3-dim data", ref->K);
			CHECK(ref->nK == KG_CALIB_MAX_BASIS, "LOO evaluated for %d values of K", ref->nK);
		}
		kg_reference_free(&ref);
		kg_patchset_free(&chart);
	}
	/* 2-dim data: drop the bump from every spectrum. A 2-dim chart has rank-2 RGB,
	 * which the collinearity check refuses, so the RGB comes from a third,
	 * independent direction that no spectrum shows: K = 2 reproduces the spectra. */
	kg_patchset *chart = fx_chart(30, 0.0, 5);
	uint64_t st = 99;
	for (int i = 0; chart && i < chart->n; i++) {
		double a0 = 0.3 + 0.3 * fx_rand(&st), a1 = (fx_rand(&st) - 0.5) * 0.3;
		for (int l = 0; l < KG_NBANDS; l++)
			chart->spectra[i].v[l] = a0 * fx_basis(0, l) + a1 * fx_basis(1, l);
		chart->rgb[i][0] = 0.5 * a0 + 0.4 * a1;
		chart->rgb[i][1] = 0.6 * a0 - 0.2 * a1;
		chart->rgb[i][2] = 0.2 + 0.2 * fx_rand(&st);
	}
	kg_reference_options opt;
	kg_reference_options_default(&opt);
	opt.basis = 0;
	kg_reference *ref = chart ? fit(chart, &opt) : NULL;
	if (ref) {
		printf("2-dim data: K = %d\n", ref->K);
		CHECK(ref->K == 2, "K = %d chosen for 2-dim data", ref->K);
	}
	kg_reference_free(&ref);
	kg_patchset_free(&chart);
}

/* LOO of the regression methods against explicit refits without each patch. */
static void test_loo_closed_form(const kg_patchset *chart)
{
	kg_reference_options opt;
	kg_reference_options_default(&opt);
	opt.method = KG_METHOD_AUTO;
	opt.ridge = 1e-4;
	kg_reference *ref = fit(chart, &opt);
	if (!ref)
		return;
	kg_err err = {{0}};
	for (int j = KG_METHOD_LINEAR; j < KG_METHOD_COUNT; j++) {
		double sum = 0;
		for (int i = 0; i < chart->n; i++) {
			const char *ex[1] = {chart->ids[i]};
			kg_reference_options o = opt;
			o.method = (kg_method)j;
			o.exclude = ex;
			o.nexclude = 1;
			/* Wiener's lambda is m sigma^2 on the full chart; keep it for the refit. */
			if (j == KG_METHOD_WIENER)
				o.noise_sigma = opt.noise_sigma * sqrt((double)chart->n / (chart->n - 1));
			kg_reference *r = NULL;
			if (kg_reference_fit(chart, chart, &o, &r, &err)) {
				CHECK(0, "refit without %s: %s", chart->ids[i], err.msg);
				break;
			}
			kg_spectrum est;
			kg_spectral_map_apply(&r->maps[j], chart->rgb[i], &est);
			sum += kg_spectrum_rmse(&est, &chart->spectra[i]);
			kg_reference_free(&r);
		}
		printf("%-9s LOO RMSE %.9g (closed form) %.9g (refits)\n", kg_method_name((kg_method)j),
		       ref->maps[j].loo_rmse, sum / chart->n);
		CHECK_NEAR(ref->maps[j].loo_rmse, sum / chart->n, 1e-9, kg_method_name((kg_method)j));
	}
	/* The method chosen is the first within 1 % (+1e-6) of the lowest. */
	double best = INFINITY;
	for (int j = 0; j < KG_METHOD_COUNT; j++)
		if (ref->maps[j].available && ref->maps[j].loo_rmse < best)
			best = ref->maps[j].loo_rmse;
	CHECK(ref->method_auto, "method not chosen by LOO");
	CHECK(ref->maps[ref->method].loo_rmse <= best * 1.01 + 1e-6, "method %s",
	      kg_method_name(ref->method));
	for (int j = 0; j < (int)ref->method; j++)
		CHECK(!(ref->maps[j].loo_rmse <= best * 1.01 + 1e-6),
		      "simpler method %s was within tolerance", kg_method_name((kg_method)j));
	printf("method auto: %s\n", kg_method_name(ref->method));
	kg_reference_free(&ref);
}

static int same_double(double a, double b)
{
	return a == b || (isnan(a) && isnan(b));
}

static void compare_maps(const kg_spectral_map *a, const kg_spectral_map *b)
{
	CHECK(a->available == b->available, "%s: available", kg_method_name(a->method));
	if (!a->available) {
		CHECK(strcmp(a->note, b->note) == 0, "note '%s' vs '%s'", a->note, b->note);
		return;
	}
	for (int i = 0; i < KG_NBANDS * a->nterms; i++)
		CHECK(a->A[i] == b->A[i], "%s: A[%d]", kg_method_name(a->method), i);
	for (int i = 0; i < KG_NBANDS; i++)
		CHECK(a->offset[i] == b->offset[i], "%s: offset[%d]", kg_method_name(a->method), i);
	CHECK(same_double(a->lambda, b->lambda) && same_double(a->loo_rmse, b->loo_rmse) &&
	          same_double(a->loo_de00, b->loo_de00) && same_double(a->fit_rmse, b->fit_rmse) &&
	          same_double(a->cond, b->cond),
	      "%s: numbers", kg_method_name(a->method));
}

static void compare_references(const kg_reference *a, const kg_reference *b)
{
	CHECK(a->K == b->K && a->centred == b->centred && a->method == b->method &&
	          a->basis_auto == b->basis_auto && a->method_auto == b->method_auto,
	      "header fields");
	CHECK(memcmp(a->B, b->B, sizeof(double) * KG_NBANDS * a->K) == 0, "B");
	CHECK(memcmp(a->M, b->M, sizeof(double) * 3 * a->K) == 0, "M");
	CHECK(memcmp(a->mean, b->mean, sizeof(a->mean)) == 0, "mean");
	CHECK(memcmp(a->rgb_mean, b->rgb_mean, sizeof(a->rgb_mean)) == 0, "rgb_mean");
	CHECK(a->nK == b->nK, "nK");
	for (int K = 0; K < a->nK; K++)
		CHECK(same_double(a->loo_by_K[K], b->loo_by_K[K]), "loo_by_K[%d]", K);
	for (int j = 0; j < KG_METHOD_COUNT; j++)
		compare_maps(&a->maps[j], &b->maps[j]);
	CHECK(a->m == b->m && a->k == b->k, "sizes");
	if (a->m != b->m || a->k != b->k)
		return;
	for (int i = 0; i < a->m; i++)
		CHECK(strcmp(a->ids[i], b->ids[i]) == 0 && a->rmse[i] == b->rmse[i] &&
		          a->de00[i] == b->de00[i] && a->gfc[i] == b->gfc[i] &&
		          a->projection_rmse[i] == b->projection_rmse[i] &&
		          a->weight_residual[i] == b->weight_residual[i] &&
		          memcmp(a->train_rgb[i], b->train_rgb[i], sizeof(a->train_rgb[i])) == 0,
		      "training patch %d", i);
	for (int i = 0; i < a->k; i++)
		CHECK(strcmp(a->field_ids[i], b->field_ids[i]) == 0 &&
		          memcmp(a->rho0[i], b->rho0[i], sizeof(a->rho0[i])) == 0,
		      "field patch %d", i);
	CHECK(a->nsources == b->nsources, "sources");
}

static int same_file(const char *a, const char *b)
{
	char *x = NULL, *y = NULL;
	size_t nx = 0, ny = 0;
	int same = kg_read_file(a, &x, &nx, NULL) == 0 && kg_read_file(b, &y, &ny, NULL) == 0 &&
	           nx == ny && memcmp(x, y, nx) == 0;
	free(x);
	free(y);
	return same;
}

static void test_round_trip(const kg_patchset *chart, const char *dir)
{
	char spectra[512], rgb[512], site[512], r1[512], r2[512], c1[512], c2[512];
	snprintf(spectra, sizeof(spectra), "%s/spectra.cgats", dir);
	snprintf(rgb, sizeof(rgb), "%s/rgb.cgats", dir);
	snprintf(site, sizeof(site), "%s/site.cgats", dir);
	snprintf(r1, sizeof(r1), "%s/ref1.json", dir);
	snprintf(r2, sizeof(r2), "%s/ref2.json", dir);
	snprintf(c1, sizeof(c1), "%s/cam1.json", dir);
	snprintf(c2, sizeof(c2), "%s/cam2.json", dir);
	kg_err err = {{0}};
	const char *kw_s[] = {"INSTRUMENTATION", "test spectrophotometer", NULL};
	const char *kw_r[] = {"CAMERA", "synthetic Gaussian camera", "ILLUMINANT", "D65", NULL};
	kg_patchset *sp = fx_site(chart);
	int ret = kg_patchset_write(spectra, chart, KG_PATCH_SPECTRA, kw_s, &err);
	if (!ret)
		ret = kg_patchset_write(rgb, chart, KG_PATCH_RGB, kw_r, &err);
	if (!ret)
		ret = kg_patchset_write(site, sp, KG_PATCH_RGB, NULL, &err);
	CHECK(ret == 0, "writing inputs: %s", err.msg);
	kg_patchset_free(&sp);

	kg_reference_options opt;
	kg_reference_options_default(&opt);
	opt.basis = 0;
	opt.centred = 1;
	opt.method = KG_METHOD_AUTO;
	kg_reference *ref = NULL, *back = NULL;
	ret = kg_reference_fit_files(spectra, rgb, NULL, &opt, &ref, &err);
	CHECK(ret == 0, "fit from files: %s", err.msg);
	if (ret)
		return;
	CHECK(ref->nsources == 2 && strlen(ref->sources[0].sha256) == 64, "sources recorded");
	ret = kg_reference_save(ref, r1, &err);
	CHECK(ret == 0, "save: %s", err.msg);
	ret = kg_reference_load(r1, &back, &err);
	CHECK(ret == 0, "load: %s", err.msg);
	if (back) {
		compare_references(ref, back);
		ret = kg_reference_save(back, r2, &err);
		CHECK(ret == 0 && same_file(r1, r2), "reference JSON differs after a round trip");
	}
	char *text = NULL;
	size_t len = 0;
	if (kg_read_file(r1, &text, &len, NULL) == 0) {
		CHECK(strstr(text, "\"format\": \"kogei-reference/1\"") != NULL, "format key");
		CHECK(strstr(text, "\"illuminant\": \"D65\"") != NULL, "illuminant from keywords");
		CHECK(strstr(text, "\"rgb\": \"synthetic Gaussian camera\"") != NULL, "devices");
		CHECK(strstr(text, "\"spectra\": \"test spectrophotometer\"") != NULL, "devices");
	}
	free(text);

	kg_camera_calib *cam = NULL, *cback = NULL;
	ret = kg_camera_fit_files(r1, site, NULL, &cam, &err);
	CHECK(ret == 0, "camera from files: %s", err.msg);
	if (cam) {
		ret = kg_camera_save(cam, c1, &err);
		CHECK(ret == 0, "camera save: %s", err.msg);
		ret = kg_camera_load(c1, &cback, &err);
		CHECK(ret == 0, "camera load: %s", err.msg);
	}
	if (cback) {
		CHECK(memcmp(cam->M2, cback->M2, sizeof(cam->M2)) == 0, "M2");
		CHECK(memcmp(cam->weight_matrix, cback->weight_matrix, sizeof(cam->weight_matrix)) == 0,
		      "M M2");
		CHECK(cam->method == cback->method && cam->K == cback->K && cam->k == cback->k, "sizes");
		for (int j = 0; j < KG_METHOD_COUNT; j++) {
			CHECK(cam->maps[j].available == cback->maps[j].available, "available %d", j);
			if (cam->maps[j].available)
				CHECK(memcmp(cam->maps[j].A, cback->maps[j].A,
				             sizeof(double) * KG_NBANDS * cam->maps[j].nterms) == 0 &&
				          memcmp(cam->maps[j].pre, cback->maps[j].pre, sizeof(double) * 9) == 0 &&
				          memcmp(cam->maps[j].offset, cback->maps[j].offset,
				                 sizeof(cam->maps[j].offset)) == 0,
				      "site map %s", kg_method_name((kg_method)j));
		}
		ret = kg_camera_save(cback, c2, &err);
		CHECK(ret == 0 && same_file(c1, c2), "camera JSON differs after a round trip");
		char hex[65];
		CHECK(kg_calib_sha256_file(r1, hex, &err) == 0 && cback->nsources == 2 &&
		          strcmp(cback->sources[0].sha256, hex) == 0,
		      "reference sha256 recorded");
	}
	/* A wrong format is refused with the key and the expectation. */
	kg_reference_free(&back);
	ret = kg_reference_load(c1, &back, &err);
	CHECK(ret == KG_EINVAL && strstr(err.msg, "expected \"kogei-reference/1\""), "%s", err.msg);
	kg_camera_calib_free(&cam);
	kg_camera_calib_free(&cback);
	kg_reference_free(&ref);
	kg_reference_free(&back);
	const char *files[] = {spectra, rgb, site, r1, r2, c1, c2};
	for (size_t i = 0; i < sizeof(files) / sizeof(files[0]); i++)
		unlink(files[i]);
}

static void test_option_errors(const kg_patchset *chart)
{
	kg_reference_options opt;
	kg_reference *ref = NULL;
	kg_err err = {{0}};
	kg_reference_options_default(&opt);
	opt.basis = 9;
	CHECK(kg_reference_fit(chart, chart, &opt, &ref, &err) == KG_EINVAL &&
	          strstr(err.msg, "expected 1 to 8"),
	      "K = 9: %s", err.msg);
	kg_reference_options_default(&opt);
	opt.ridge = -1;
	CHECK(kg_reference_fit(chart, chart, &opt, &ref, &err) == KG_EINVAL &&
	          strstr(err.msg, "ridge"),
	      "ridge -1: %s", err.msg);
	/* Three patches of a chart that span RGB well (P3, P5, P15 of seed 7). */
	kg_patchset *big = fx_chart(24, 0.0, 7), *small = NULL;
	if (big && kg_patchset_new(3, KG_PATCH_SPECTRA | KG_PATCH_RGB, &small, &err) == 0) {
		static const int pick[3] = {2, 4, 14};
		for (int i = 0; i < 3; i++) {
			small->spectra[i] = big->spectra[pick[i]];
			memcpy(small->rgb[i], big->rgb[pick[i]], sizeof(small->rgb[i]));
			kg_patchset_set_id(small, i, big->ids[pick[i]], &err);
		}
	}
	kg_patchset_free(&big);
	kg_reference_options_default(&opt);
	opt.basis = 0;
	CHECK(small && kg_reference_fit(small, small, &opt, &ref, &err) == KG_EINVAL &&
	          strstr(err.msg, "at least 4"),
	      "3 patches with auto: %s", err.msg);
	/* Three patches with everything fixed: rootpoly is unavailable, pca works. */
	kg_reference_options_default(&opt);
	int ret = small ? kg_reference_fit(small, small, &opt, &ref, &err) : -1;
	CHECK(ret == 0, "3 patches: %s", err.msg);
	if (ref) {
		CHECK(!ref->maps[KG_METHOD_ROOTPOLY2].available &&
		          strstr(ref->maps[KG_METHOD_ROOTPOLY2].note, "at least 6 patches"),
		      "rootpoly2 note: %s", ref->maps[KG_METHOD_ROOTPOLY2].note);
		CHECK(isnan(ref->maps[KG_METHOD_PCA].loo_rmse), "no LOO with 3 patches");
	}
	kg_reference_free(&ref);
	opt.method = KG_METHOD_ROOTPOLY3;
	CHECK(small && kg_reference_fit(small, small, &opt, &ref, &err) == KG_EINVAL &&
	          strstr(err.msg, "rootpoly3"),
	      "rootpoly3 on 3 patches: %s", err.msg);
	kg_patchset_free(&small);
}

int main(void)
{
	kg_patchset *chart = fx_chart(24, 0.003, 2);
	if (!chart)
		return kg_test_done("calib-fit");
	test_ridge(chart);
	test_basis_auto();
	test_loo_closed_form(chart);
	char dir[] = "/tmp/kogei-calib-XXXXXX";
	if (mkdtemp(dir)) {
		test_round_trip(chart, dir);
		rmdir(dir);
	} else {
		CHECK(0, "mkdtemp failed");
	}
	test_option_errors(chart);
	kg_patchset_free(&chart);
	return kg_test_done("calib-fit");
}
