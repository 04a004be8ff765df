/* Shared by the estimate/ tests: a seeded generator, a smooth orthonormal basis and
 * synthetic images with the hard cases (negative, NaN, Inf, clipped) sprinkled in. */
#ifndef EST_FIXTURE_H
#define EST_FIXTURE_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_config.h"
#include "kg_estimate.h"

typedef struct fx_rng {
	uint64_t s;
} fx_rng;

static inline uint64_t fx_next(fx_rng *r)
{
	/* splitmix64 */
	uint64_t z = (r->s += 0x9e3779b97f4a7c15ull);
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	return z ^ (z >> 31);
}

/* Uniform in [lo, hi). */
static inline double fx_uniform(fx_rng *r, double lo, double hi)
{
	return lo + (hi - lo) * (double)(fx_next(r) >> 11) * 0x1p-53;
}

/* K smooth spectra (a constant and slow cosines) made orthonormal by Gram-Schmidt:
 * basis is 61 x k, row-major. */
static inline void fx_basis(int k, double *basis)
{
	for (int i = 0; i < k; i++)
		for (int o = 0; o < KG_NBANDS; o++)
			basis[o * k + i] = cos(M_PI * i * (o + 0.5) / KG_NBANDS) + 0.1 * i * o / 60.0;
	for (int i = 0; i < k; i++) {
		for (int j = 0; j < i; j++) {
			double d = 0;
			for (int o = 0; o < KG_NBANDS; o++)
				d += basis[o * k + i] * basis[o * k + j];
			for (int o = 0; o < KG_NBANDS; o++)
				basis[o * k + i] -= d * basis[o * k + j];
		}
		double n = 0;
		for (int o = 0; o < KG_NBANDS; o++)
			n += basis[o * k + i] * basis[o * k + i];
		for (int o = 0; o < KG_NBANDS; o++)
			basis[o * k + i] /= sqrt(n);
	}
}

/* A random rows x cols matrix with entries in [-scale, scale]. */
static inline void fx_matrix(fx_rng *r, int rows, int cols, double scale, double *m)
{
	for (int i = 0; i < rows * cols; i++)
		m[i] = fx_uniform(r, -scale, scale);
}

/* An image of n pixels in [lo, hi) with hard cases mixed in when `hard` is set:
 * every 37th pixel gets a NaN, Inf or -Inf channel, every 41st a clipped channel
 * (1.0), every 13th a negative channel. */
static inline float *fx_image(fx_rng *r, size_t n, double lo, double hi, int hard)
{
	float *rgb = malloc(n * 3 * sizeof(float));
	for (size_t i = 0; i < n * 3; i++)
		rgb[i] = (float)fx_uniform(r, lo, hi);
	if (hard) {
		const float odd[3] = {NAN, INFINITY, -INFINITY};
		for (size_t i = 0; i < n; i++) {
			if (i % 37 == 5)
				rgb[3 * i + i % 3] = odd[(i / 37) % 3];
			else if (i % 41 == 7)
				rgb[3 * i + (i + 1) % 3] = 1.0f;
			else if (i % 13 == 3)
				rgb[3 * i + (i + 2) % 3] = -0.02f;
		}
	}
	return rgb;
}

/* Kernels used across the tests, all with a random but reasonable model. */
typedef struct fx_kernels {
	kg_est_kernel *linear;    /* 61x3, no basis */
	kg_est_kernel *pca;       /* K = 3 basis, uncentred (the paper's A = B M M2) */
	kg_est_kernel *centred;   /* K = 4 basis with a mean and an affine offset */
	kg_est_kernel *rootpoly2; /* with K = 3 basis */
	kg_est_kernel *rootpoly3; /* 61x13, no basis */
	kg_est_kernel *lut;       /* 17^3 from rootpoly2 (has the basis) */
	double basis3[KG_NBANDS * 3], basis4[KG_NBANDS * 4], mean[KG_NBANDS];
} fx_kernels;

static inline int fx_kernels_make(fx_kernels *k, uint64_t seed)
{
	memset(k, 0, sizeof(*k));
	fx_rng r = {seed};
	double a[KG_NBANDS * 13], off[KG_NBANDS], m[4 * 13];
	fx_basis(3, k->basis3);
	fx_basis(4, k->basis4);
	for (int o = 0; o < KG_NBANDS; o++)
		k->mean[o] = 0.3 + 0.2 * sin(o / 9.0);
	int rc = 0;
	fx_matrix(&r, KG_NBANDS, 3, 1.0, a);
	fx_matrix(&r, KG_NBANDS, 1, 0.05, off);
	rc |= kg_est_kernel_new(&(kg_est_desc){KG_EST_LINEAR, 0, a, off, NULL, NULL}, &k->linear,
	                        NULL);
	fx_matrix(&r, 3, 3, 3.0, m);
	rc |= kg_est_kernel_new(&(kg_est_desc){KG_EST_LINEAR, 3, m, NULL, k->basis3, NULL}, &k->pca,
	                        NULL);
	fx_matrix(&r, 4, 3, 2.0, m);
	fx_matrix(&r, 4, 1, 0.2, off);
	rc |= kg_est_kernel_new(&(kg_est_desc){KG_EST_LINEAR, 4, m, off, k->basis4, k->mean},
	                        &k->centred, NULL);
	fx_matrix(&r, 3, 6, 2.0, m);
	rc |= kg_est_kernel_new(&(kg_est_desc){KG_EST_ROOTPOLY2, 3, m, NULL, k->basis3, NULL},
	                        &k->rootpoly2, NULL);
	fx_matrix(&r, KG_NBANDS, 13, 0.5, a);
	rc |= kg_est_kernel_new(&(kg_est_desc){KG_EST_ROOTPOLY3, 0, a, NULL, NULL, NULL},
	                        &k->rootpoly3, NULL);
	if (k->rootpoly2)
		rc |= kg_est_kernel_new_lut(k->rootpoly2, 17, 0.0f, 1.0f, &k->lut, NULL);
	return rc;
}

static inline void fx_kernels_free(fx_kernels *k)
{
	kg_est_kernel_free(&k->linear);
	kg_est_kernel_free(&k->pca);
	kg_est_kernel_free(&k->centred);
	kg_est_kernel_free(&k->rootpoly2);
	kg_est_kernel_free(&k->rootpoly3);
	kg_est_kernel_free(&k->lut);
}

/* A standard normal draw (Box-Muller). */
static inline double fx_gauss(fx_rng *r)
{
	double u = fx_uniform(r, 0x1p-53, 1), v = fx_uniform(r, 0, 1);
	return sqrt(-2 * log(u)) * cos(2 * M_PI * v);
}

/* A smooth synthetic camera F (3 x KG_NBANDS, row-major): Gaussian sensitivities at 600,
 * 540 and 450 nm weighting a flat light, the perfect diffuser's brightest channel at
 * 0.9. */
static inline void fx_gaussian_camera(double *F)
{
	static const double peak[3] = {600, 540, 450}, width[3] = {30, 35, 25};
	double white = 0;
	for (int c = 0; c < 3; c++) {
		double s = 0;
		for (int b = 0; b < KG_NBANDS; b++) {
			double z = (kg_band_nm(b) - peak[c]) / width[c];
			s += F[c * KG_NBANDS + b] = exp(-0.5 * z * z);
		}
		white = fmax(white, s);
	}
	for (int i = 0; i < 3 * KG_NBANDS; i++)
		F[i] *= 0.9 / white;
}

/* The bundled material library (fixtures/materials/default.json) and the camera of
 * fx_gaussian_camera. 0, or the library's error. */
static inline int fx_library_camera(kg_material_library **lib, double *F, kg_err *err)
{
	char path[4096];
	snprintf(path, sizeof(path), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	int rc = kg_material_library_load(path, lib, err);
	if (!rc)
		fx_gaussian_camera(F);
	return rc;
}

/* n material spectra: smooth curves in and out of the basis' span. */
static inline void fx_materials(fx_rng *r, int n, double *spectra)
{
	for (int j = 0; j < n; j++) {
		double a = fx_uniform(r, 0.1, 0.8), b = fx_uniform(r, -0.3, 0.3),
		       c = fx_uniform(r, 0.5, 4.0), ph = fx_uniform(r, 0, 6.3);
		for (int o = 0; o < KG_NBANDS; o++)
			spectra[j * KG_NBANDS + o] = a + b * (o / 60.0) + 0.1 * sin(c * o / 10.0 + ph);
	}
}

#endif
