/* Noise-free recovery. Spectra lie exactly in a 3-dim span and the camera responds
 * exactly linearly, so every method must give the chart's spectra back:
 *  - pca (K = 3, uncentred and centred) and linear to 1e-9, root-polynomial to 1e-7;
 *  - M agrees with a direct computation of the paper's formula M = W^T rho
 *    (rho^T rho)^-1, W = S B, done here by Gauss-Jordan, to 1e-10;
 *  - a site camera responding T rho gives M2 = T^-1 (1e-10), and through M2 every
 *    method again recovers the spectra (1e-9, root-polynomial 1e-7), as do the pca
 *    weights (mean + B w);
 *  - the kernels estimate/ builds from kg_camera_kernel_desc agree in float
 *    precision (2e-6). */
#include "calib_fixture.h"
#include "kg_test.h"

/* out = inverse of the 3 x 3 a (Gauss-Jordan with partial pivoting). */
static void inv3(const double a[9], double out[9])
{
	double m[3][6];
	for (int r = 0; r < 3; r++)
		for (int c = 0; c < 6; c++)
			m[r][c] = c < 3 ? a[3 * r + c] : (c - 3 == r);
	for (int p = 0; p < 3; p++) {
		int best = p;
		for (int r = p + 1; r < 3; r++)
			if (fabs(m[r][p]) > fabs(m[best][p]))
				best = r;
		for (int c = 0; c < 6; c++) {
			double t = m[p][c];
			m[p][c] = m[best][c];
			m[best][c] = t;
		}
		double d = m[p][p];
		for (int c = 0; c < 6; c++)
			m[p][c] /= d;
		for (int r = 0; r < 3; r++)
			if (r != p) {
				double f = m[r][p];
				for (int c = 0; c < 6; c++)
					m[r][c] -= f * m[p][c];
			}
	}
	for (int r = 0; r < 3; r++)
		for (int c = 0; c < 3; c++)
			out[3 * r + c] = m[r][c + 3];
}

/* M = W^T rho (rho^T rho)^-1 with W = S B, straight from the definition. */
static void direct_m(const kg_reference *ref, const kg_patchset *chart, double *M)
{
	double G[9] = {0}, Gi[9];
	for (int i = 0; i < chart->n; i++)
		for (int a = 0; a < 3; a++)
			for (int b = 0; b < 3; b++)
				G[3 * a + b] += chart->rgb[i][a] * chart->rgb[i][b];
	inv3(G, Gi);
	for (int k = 0; k < ref->K; k++) {
		double wr[3] = {0};
		for (int i = 0; i < chart->n; i++) {
			double w = 0;
			for (int l = 0; l < KG_NBANDS; l++)
				w += chart->spectra[i].v[l] * ref->B[l * ref->K + k];
			for (int c = 0; c < 3; c++)
				wr[c] += w * chart->rgb[i][c];
		}
		for (int c = 0; c < 3; c++)
			M[3 * k + c] = wr[0] * Gi[c] + wr[1] * Gi[3 + c] + wr[2] * Gi[6 + c];
	}
}

static double tolerance(kg_method m)
{
	return m == KG_METHOD_ROOTPOLY2 || m == KG_METHOD_ROOTPOLY3 ? 1e-7 : 1e-9;
}

static void check_reference(const kg_patchset *chart, int centred)
{
	kg_reference_options opt;
	kg_reference_options_default(&opt);
	opt.centred = centred;
	kg_reference *ref = NULL;
	kg_err err = {{0}};
	int ret = kg_reference_fit(chart, chart, &opt, &ref, &err);
	CHECK(ret == 0, "fit (centred %d): %s", centred, err.msg);
	if (ret)
		return;
	CHECK(ref->K == 3, "K = %d", ref->K);
	for (int j = 0; j < KG_METHOD_COUNT; j++) {
		const kg_spectral_map *map = &ref->maps[j];
		CHECK(map->available, "method %s unavailable: %s", kg_method_name((kg_method)j),
		      map->note);
		if (j == KG_METHOD_WIENER || !map->available)
			continue; /* wiener's noise prior biases it on purpose */
		double worst = 0;
		for (int i = 0; i < chart->n; i++) {
			kg_spectrum est;
			kg_spectral_map_apply(map, chart->rgb[i], &est);
			worst = fmax(worst, fx_max_diff(&est, &chart->spectra[i]));
		}
		printf("centred %d, %-9s: largest error %.3g\n", centred, kg_method_name((kg_method)j),
		       worst);
		CHECK(worst < tolerance((kg_method)j), "%s (centred %d): recovery error %.3g",
		      kg_method_name((kg_method)j), centred, worst);
	}
	/* The basis spans the data: projection error and weight residual vanish. */
	for (int i = 0; i < ref->m; i++) {
		CHECK(ref->projection_rmse[i] < 1e-12, "patch %s: projection %.3g", ref->ids[i],
		      ref->projection_rmse[i]);
		CHECK(ref->weight_residual[i] < 1e-9, "patch %s: weight residual %.3g", ref->ids[i],
		      ref->weight_residual[i]);
		CHECK(ref->de00[i] < 1e-6, "patch %s: dE00 %.3g", ref->ids[i], ref->de00[i]);
	}
	/* B has orthonormal columns. */
	for (int a = 0; a < ref->K; a++)
		for (int b = 0; b < ref->K; b++) {
			double d = 0;
			for (int l = 0; l < KG_NBANDS; l++)
				d += ref->B[l * ref->K + a] * ref->B[l * ref->K + b];
			CHECK_NEAR(d, a == b, 1e-12, "B^T B");
		}
	if (!centred) {
		double M[3 * 3];
		direct_m(ref, chart, M);
		for (int i = 0; i < 9; i++)
			CHECK_NEAR(ref->M[i], M[i], 1e-10 * (1 + fabs(M[i])), "M against its definition");
	}

	/* Site camera: responses T rho. */
	kg_patchset *site = fx_site(chart);
	kg_camera_calib *cam = NULL;
	ret = kg_camera_fit(ref, site, NULL, &cam, &err);
	CHECK(ret == 0, "camera fit: %s", err.msg);
	if (ret == 0) {
		double Ti[9];
		inv3(fx_T, Ti);
		for (int i = 0; i < 9; i++)
			CHECK_NEAR(cam->M2[i], Ti[i], 1e-10, "M2 = T^-1");
		CHECK(cam->residual_relative < 1e-12, "M2 residual %.3g", cam->residual_relative);
		printf("site: cond %.4g, equilibrated %.4g, residual %.3g\n", cam->cond,
		       cam->cond_equilibrated, cam->residual_relative);
		for (int j = 0; j < KG_METHOD_COUNT; j++) {
			if (j == KG_METHOD_WIENER)
				continue;
			const kg_site_map *map = NULL;
			CHECK(kg_camera_site_map(cam, (kg_method)j, &map, &err) == 0, "%s", err.msg);
			if (!map)
				continue;
			kg_est_desc desc;
			double pre[9];
			kg_est_kernel *kern = NULL;
			ret = kg_camera_kernel_desc(cam, (kg_method)j, &desc, pre, &err);
			if (ret == 0)
				ret = kg_est_kernel_new(&desc, &kern, &err);
			CHECK(ret == 0, "kernel %s: %s", kg_method_name((kg_method)j), err.msg);
			double worst = 0, worst_f = 0;
			for (int i = 0; i < chart->n; i++) {
				kg_spectrum est;
				kg_site_map_apply(map, site->rgb[i], &est);
				worst = fmax(worst, fx_max_diff(&est, &chart->spectra[i]));
				if (!kern)
					continue;
				float in[3], out[KG_NBANDS];
				for (int c = 0; c < 3; c++)
					in[c] = (float)(pre[3 * c] * site->rgb[i][0] + pre[3 * c + 1] * site->rgb[i][1] +
					                pre[3 * c + 2] * site->rgb[i][2]);
				kg_est_kernel_eval(kern, in, INFINITY, 0, out);
				for (int l = 0; l < KG_NBANDS; l++)
					worst_f = fmax(worst_f, fabs(out[l] - chart->spectra[i].v[l]));
			}
			kg_est_kernel_free(&kern);
			printf("site %-9s: largest error %.3g (double), %.3g (estimate kernel, float)\n",
			       kg_method_name((kg_method)j), worst, worst_f);
			CHECK(worst < tolerance((kg_method)j), "site %s: recovery error %.3g",
			      kg_method_name((kg_method)j), worst);
			CHECK(worst_f < 2e-6, "site %s: kernel error %.3g", kg_method_name((kg_method)j),
			      worst_f);
		}
		/* Weights: mean + B w. */
		double worst = 0;
		for (int i = 0; i < chart->n; i++) {
			double w[KG_CALIB_MAX_BASIS];
			kg_spectrum est;
			kg_camera_weights(cam, site->rgb[i], w);
			for (int l = 0; l < KG_NBANDS; l++) {
				est.v[l] = cam->mean[l];
				for (int k = 0; k < cam->K; k++)
					est.v[l] += cam->B[l * cam->K + k] * w[k];
			}
			worst = fmax(worst, fx_max_diff(&est, &chart->spectra[i]));
		}
		CHECK(worst < 1e-9, "weights: recovery error %.3g", worst);
	}
	kg_camera_calib_free(&cam);
	kg_patchset_free(&site);
	kg_reference_free(&ref);
}

int main(void)
{
	kg_patchset *chart = fx_chart(24, 0.0, 1);
	CHECK(chart != NULL, "chart");
	if (!chart)
		return kg_test_done("calib-recovery");
	check_reference(chart, 0);
	check_reference(chart, 1);
	kg_patchset_free(&chart);
	return kg_test_done("calib-recovery");
}
