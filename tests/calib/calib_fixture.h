/* Synthetic charts for the calib tests, built so the answer is known:
 *  - spectra that lie exactly in a 3-dimensional span (three smooth basis curves
 *    with deterministic pseudo-random positive weights), optionally plus a small
 *    deterministic perturbation outside it;
 *  - a camera of three Gaussian sensitivities whose responses are exactly linear in
 *    the spectra (white at 0.9 in the brightest channel);
 *  - a site camera whose sensitivities are T times the reference camera's, so its
 *    responses are T rho and M2 must come out as T^-1. */
#ifndef CALIB_FIXTURE_H
#define CALIB_FIXTURE_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "kg_calib.h"
#include "kg_test_camera.h"

/* xorshift64*: deterministic values in [0, 1). */
static inline double fx_rand(uint64_t *s)
{
	*s ^= *s >> 12;
	*s ^= *s << 25;
	*s ^= *s >> 27;
	return (double)((*s * 2685821657736338717ULL) >> 11) / 9007199254740992.0;
}

/* The generating curves: a flat level, a slope and a bump. */
static inline double fx_basis(int k, int band)
{
	double x = (kg_band_nm(band) - 550.0) / 150.0; /* -1 .. 1 */
	switch (k) {
	case 0: return 1.0;
	case 1: return x;
	default: return exp(-0.5 * pow((kg_band_nm(band) - 520.0) / 40.0, 2));
	}
}

/* A camera: three Gaussian sensitivities on the grid. */
static inline void fx_camera(kg_spectrum sens[3])
{
	static const double centre[3] = {605, 540, 460}, width[3] = {35, 40, 28};
	for (int c = 0; c < 3; c++)
		for (int l = 0; l < KG_NBANDS; l++)
			sens[c].v[l] = exp(-0.5 * pow((kg_band_nm(l) - centre[c]) / width[c], 2));
	/* Exposure: the perfect diffuser gives 0.9 in the brightest channel. */
	kg_test_expose(sens);
}

static inline void fx_response(const kg_spectrum sens[3], const kg_spectrum *s, double rgb[3])
{
	for (int c = 0; c < 3; c++)
		rgb[c] = kg_spectrum_dot(&sens[c], s);
}

/* The site camera's mixing: rho_site = T rho_reference. */
static const double fx_T[9] = {1.10, 0.10, 0.00, 0.05, 0.90, 0.05, 0.00, 0.20, 0.80};

static inline void fx_site_response(const double rgb[3], double out[3])
{
	for (int r = 0; r < 3; r++)
		out[r] = fx_T[3 * r] * rgb[0] + fx_T[3 * r + 1] * rgb[1] + fx_T[3 * r + 2] * rgb[2];
}

/* m patches "P1".."Pm": spectra (in the 3-dim span, plus `outside` times a fixed
 * wiggle per patch) and the reference camera's RGB. */
static inline kg_patchset *fx_chart(int m, double outside, uint64_t seed)
{
	kg_patchset *ps = NULL;
	kg_err err = {{0}};
	if (kg_patchset_new(m, KG_PATCH_SPECTRA | KG_PATCH_RGB, &ps, &err)) {
		fprintf(stderr, "fx_chart: %s\n", err.msg);
		return NULL;
	}
	kg_spectrum sens[3];
	fx_camera(sens);
	uint64_t st = seed * 0x9E3779B97F4A7C15ULL + 1;
	for (int i = 0; i < m; i++) {
		double a0 = 0.3 + 0.35 * fx_rand(&st);
		double a1 = (fx_rand(&st) - 0.5) * 0.25;
		double a2 = (fx_rand(&st) - 0.3) * 0.4;
		double ph = 6.28 * fx_rand(&st);
		for (int l = 0; l < KG_NBANDS; l++)
			ps->spectra[i].v[l] = a0 * fx_basis(0, l) + a1 * fx_basis(1, l) +
			                      a2 * fx_basis(2, l) +
			                      outside * sin(kg_band_nm(l) / 9.0 + ph);
		fx_response(sens, &ps->spectra[i], ps->rgb[i]);
		char id[16];
		snprintf(id, sizeof(id), "P%d", i + 1);
		kg_patchset_set_id(ps, i, id, &err);
	}
	return ps;
}

/* The site camera's view of a chart (rgb only), patches in the same order. */
static inline kg_patchset *fx_site(const kg_patchset *chart)
{
	kg_patchset *ps = NULL;
	kg_err err = {{0}};
	if (kg_patchset_new(chart->n, KG_PATCH_RGB, &ps, &err))
		return NULL;
	for (int i = 0; i < chart->n; i++) {
		fx_site_response(chart->rgb[i], ps->rgb[i]);
		kg_patchset_set_id(ps, i, chart->ids[i], &err);
	}
	return ps;
}

static inline double fx_max_diff(const kg_spectrum *a, const kg_spectrum *b)
{
	double d = 0;
	for (int l = 0; l < KG_NBANDS; l++)
		d = fmax(d, fabs(a->v[l] - b->v[l]));
	return d;
}

#endif
