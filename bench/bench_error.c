/* The error part: simulate a camera on a training chart and a test set, fit every
 * method on the chart and score its kernel's estimates on the test set. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_bench.h"

static const char *const method_names[KG_BENCH_NMETHODS] = {
	"pca3", "pca-auto", "linear", "wiener", "rootpoly2", "rootpoly3", "lut33-pca3",
};

const char *kg_bench_method_name(kg_bench_method m)
{
	return m >= 0 && m < KG_BENCH_NMETHODS ? method_names[m] : "unknown";
}

int kg_bench_colour_init(kg_bench_colour *c, kg_err *err)
{
	kg_check_arg(c, err);
	kg_illuminant *d65 = NULL, *a = NULL;
	int ret = kg_illuminant_by_name("D65", &d65, err);
	if (!ret)
		ret = kg_illuminant_by_name("A", &a, err);
	if (!ret) {
		kg_xyz_weights_reflectance(d65, &c->d65);
		kg_xyz_weights_reflectance(a, &c->a);
		c->white_d65 = kg_illuminant_white(d65);
		c->white_a = kg_illuminant_white(a);
	}
	kg_illuminant_free(&d65);
	kg_illuminant_free(&a);
	return ret;
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return (x > y) - (x < y);
}

double kg_bench_percentile(double *v, int n, double p)
{
	if (n < 1)
		return NAN;
	qsort(v, (size_t)n, sizeof(*v), cmp_double);
	double pos = p * (n - 1);
	int i = (int)floor(pos);
	if (i >= n - 1)
		return v[n - 1];
	double f = pos - i;
	return v[i] + f * (v[i + 1] - v[i]);
}

static double colour_difference(const kg_xyz_weights *w, kg_xyz white, const kg_spectrum *a,
                                const kg_spectrum *b)
{
	kg_lab la = kg_xyz_to_lab(kg_xyz_from_weights(w, a), white);
	kg_lab lb = kg_xyz_to_lab(kg_xyz_from_weights(w, b), white);
	return kg_ciede2000(la, lb);
}

int kg_bench_metrics_compute(const kg_bench_colour *c, const kg_spectrum *truth,
                             const kg_spectrum *est, int n, kg_bench_metrics *out,
                             kg_err *err)
{
	kg_check_arg(c && truth && est && out && n > 0, err);
	double *de65 = malloc(sizeof(double) * (size_t)n);
	double *dea = malloc(sizeof(double) * (size_t)n);
	if (!de65 || !dea) {
		free(de65);
		free(dea);
		return kg_fail(err, KG_ENOMEM, "bench: out of memory");
	}
	double rmse = 0, gfc = 0, s65 = 0, sa = 0;
	for (int i = 0; i < n; i++) {
		rmse += kg_spectrum_rmse(&truth[i], &est[i]);
		gfc += kg_spectrum_gfc(&truth[i], &est[i]);
		de65[i] = colour_difference(&c->d65, c->white_d65, &truth[i], &est[i]);
		dea[i] = colour_difference(&c->a, c->white_a, &truth[i], &est[i]);
		s65 += de65[i];
		sa += dea[i];
	}
	out->n = n;
	out->rmse = rmse / n;
	out->gfc = gfc / n;
	out->de_d65_mean = s65 / n;
	out->de_a_mean = sa / n;
	out->de_d65_p95 = kg_bench_percentile(de65, n, 0.95);
	out->de_a_p95 = kg_bench_percentile(dea, n, 0.95);
	free(de65);
	free(dea);
	return 0;
}

int kg_bench_fit(const kg_patchset *spectra, const double *rgb, int basis,
                 double wiener_sigma, kg_reference **out, kg_err *err)
{
	kg_check_arg(spectra && spectra->spectra && rgb && out, err);
	kg_patchset *train = NULL;
	int ret = kg_patchset_new(spectra->n, KG_PATCH_SPECTRA | KG_PATCH_RGB, &train, err);
	for (int i = 0; i < spectra->n && !ret; i++) {
		ret = kg_patchset_set_id(train, i, spectra->ids[i], err);
		train->spectra[i] = spectra->spectra[i];
		memcpy(train->rgb[i], rgb + 3 * i, sizeof(train->rgb[i]));
	}
	if (!ret) {
		kg_reference_options opt;
		kg_reference_options_default(&opt);
		opt.basis = basis;
		opt.noise_sigma = wiener_sigma;
		ret = kg_reference_fit(train, train, &opt, out, err);
	}
	kg_patchset_free(&train);
	return ret;
}

static const kg_method calib_method[KG_BENCH_NMETHODS] = {
	[KG_BENCH_PCA3] = KG_METHOD_PCA,         [KG_BENCH_PCA_AUTO] = KG_METHOD_PCA,
	[KG_BENCH_LINEAR] = KG_METHOD_LINEAR,    [KG_BENCH_WIENER] = KG_METHOD_WIENER,
	[KG_BENCH_ROOTPOLY2] = KG_METHOD_ROOTPOLY2, [KG_BENCH_ROOTPOLY3] = KG_METHOD_ROOTPOLY3,
	[KG_BENCH_LUT33] = KG_METHOD_PCA,
};

int kg_bench_kernels_new(const kg_reference *ref3, const kg_reference *ref_auto,
                         kg_est_kernel *k[KG_BENCH_NMETHODS], char (*note)[160],
                         kg_err *err)
{
	kg_check_arg(ref3 && ref_auto && k, err);
	memset(k, 0, sizeof(*k) * KG_BENCH_NMETHODS);
	int ret = 0;
	for (int m = 0; m < KG_BENCH_NMETHODS && !ret; m++) {
		if (note)
			note[m][0] = '\0';
		const kg_reference *ref = m == KG_BENCH_PCA_AUTO ? ref_auto : ref3;
		const kg_spectral_map *map = &ref->maps[calib_method[m]];
		if (!map->available) {
			if (note)
				snprintf(note[m], sizeof(note[m]), "%s", map->note);
			continue;
		}
		if (m == KG_BENCH_LUT33) {
			if (k[KG_BENCH_PCA3])
				ret = kg_est_kernel_new_lut(k[KG_BENCH_PCA3], KG_BENCH_LUT_N, 0.0f, 1.0f,
				                            &k[m], err);
			continue;
		}
		kg_est_desc desc;
		ret = kg_reference_kernel_desc(ref, calib_method[m], &desc, err);
		if (!ret)
			ret = kg_est_kernel_new(&desc, &k[m], err);
	}
	if (ret)
		kg_bench_kernels_free(k);
	return ret;
}

void kg_bench_kernels_free(kg_est_kernel *k[KG_BENCH_NMETHODS])
{
	for (int m = 0; m < KG_BENCH_NMETHODS; m++)
		kg_est_kernel_free(&k[m]);
}

int kg_bench_error_case(const kg_bench_colour *c, const kg_bench_case *bc,
                        kg_bench_error_row *row, kg_err *err)
{
	kg_check_arg(c && bc && bc->camera && bc->illuminant && bc->train && bc->test && row,
	             err);
	kg_check_arg(bc->train->spectra && bc->test->spectra && bc->wiener_sigma > 0, err);
	kg_sim_capture cap;
	int ret = kg_sim_capture_init(&cap, bc->camera, bc->illuminant, KG_BENCH_WHITE_LEVEL,
	                              bc->noise, err);
	if (ret)
		return ret;
	row->noisy = kg_sim_noise_enabled(bc->noise);
	int ntr = bc->train->n, nte = bc->test->n;
	double *rgb_train = malloc(sizeof(double) * 3 * (size_t)ntr);
	double *rgb_test = malloc(sizeof(double) * 3 * (size_t)nte);
	kg_spectrum *est = malloc(sizeof(kg_spectrum) * (size_t)nte);
	kg_reference *ref3 = NULL, *ref_auto = NULL;
	kg_est_kernel *k[KG_BENCH_NMETHODS] = {0};
	if (!rgb_train || !rgb_test || !est) {
		ret = kg_fail(err, KG_ENOMEM, "bench: out of memory");
		goto done;
	}
	kg_sim_patches(&cap, bc->train->spectra, ntr, bc->seed, rgb_train);
	kg_sim_patches(&cap, bc->test->spectra, nte, bc->seed + 1, rgb_test);
	ret = kg_bench_fit(bc->train, rgb_train, 3, bc->wiener_sigma, &ref3, err);
	if (!ret)
		ret = kg_bench_fit(bc->train, rgb_train, 0, bc->wiener_sigma, &ref_auto, err);
	if (ret)
		goto done;
	row->K_auto = ref_auto->K;
	ret = kg_bench_kernels_new(ref3, ref_auto, k, row->note, err);
	for (int m = 0; m < KG_BENCH_NMETHODS && !ret; m++) {
		row->available[m] = k[m] != NULL;
		memset(&row->m[m], 0, sizeof(row->m[m]));
		if (!k[m])
			continue;
		for (int i = 0; i < nte; i++) {
			float in[3] = {(float)rgb_test[3 * i], (float)rgb_test[3 * i + 1],
			               (float)rgb_test[3 * i + 2]};
			float s[KG_NBANDS];
			kg_est_kernel_eval(k[m], in, INFINITY, 0, s);
			for (int b = 0; b < KG_NBANDS; b++)
				est[i].v[b] = s[b];
		}
		ret = kg_bench_metrics_compute(c, bc->test->spectra, est, nte, &row->m[m], err);
	}
done:
	kg_bench_kernels_free(k);
	kg_reference_free(&ref3);
	kg_reference_free(&ref_auto);
	free(rgb_train);
	free(rgb_test);
	free(est);
	return ret;
}
