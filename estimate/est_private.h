/* Inside estimate/: kernel data, the per-pixel steps shared by the reference and the
 * optimised kernels, and the table of block functions. Not included from outside. */
#ifndef KG_EST_PRIVATE_H
#define KG_EST_PRIVATE_H

#include <math.h>
#include <string.h>

#include "kg_estimate.h"

/* Pixels per chunk in the optimised kernels: their scratch (terms, values) stays in
 * L1/L2. A multiple of 16. */
#define EST_CHUNK 256
#define EST_PAD(n) (((n) + 7) & ~7)

/* One output of a kernel: the spectrum (nb = 61) or the weights (nb = K). */
typedef struct est_map {
	int nb;
	int clamp;   /* negative values are set to 0 (spectra) */
	float *a;    /* nb x T, row-major (matrix kernels) */
	float *off;  /* nb */
	float *a8;   /* nb x T x 8: each coefficient repeated for 8 lanes */
	float *off8; /* nb x 8 */
	/* Tables for writing 8 pixels of BIP output at once: output vector v covers
	 * elements 8v..8v+7 of the 8*nb values, element j being band j % nb of pixel
	 * j / nb. */
	float *bip_coef;  /* nb x T x 8 */
	float *bip_off;   /* nb x 8 */
	int32_t *bip_pix; /* nb x 8 */
	float *lut;       /* LUT kernels: n^3 nodes of `stride` values */
	int stride;
} est_map;

struct kg_est_kernel {
	kg_est_method method; /* KG_EST_LUT for LUTs */
	int nterms;           /* matrix kernels */
	int k;
	double *basis; /* 61 x k */
	double *mean;  /* 61, NULL when none */
	est_map spec, wts;
	int lut_n;
	float lut_lo, lut_scale;
};

struct kg_est_classifier {
	int k, n;
	kg_est_distance distance;
	double *basis; /* copy, to check it matches the kernel at run time */
	double *mean;
	double mpar[KG_EST_MAX_K]; /* B^T mean */
	double h;                  /* ||(I - B B^T) mean||^2 */
	double *c;                 /* n x k: B^T C_j */
	double *e;                 /* plain: ||r_j - m_perp||^2 */
	double *g;                 /* r_j . m_perp */
	double *q;                 /* ||r_j||^2 */
	double *inv_norm;          /* 1 / ||C_j||^2, 0 for a black material */
	char **names;
};

typedef struct est_counts {
	uint64_t nonfinite, clipped, clamped_pixels, clamped_values;
} est_counts;

/* What a run computes, resolved once. */
typedef struct est_plan {
	const kg_est_kernel *k;
	const est_map *map; /* spec or wts */
	kg_est_format format;
	const kg_est_classifier *cls;
	float clip;
	int stream; /* non-temporal stores */
} est_plan;

/* Where one run of n consecutive pixels goes. BSQ: plane p starts at
 * data + p * plane_stride elements. */
typedef struct est_dst {
	void *data;
	size_t plane_stride;
	float *conf;
	uint8_t *mask;
} est_dst;

/* Per-thread scratch of the optimised kernels. */
typedef struct est_scratch {
	float *terms;      /* KG_EST_MAX_TERMS x (EST_CHUNK + 16) */
	float *vals;       /* 64 x EST_CHUNK, band-major */
	float *rows;       /* EST_CHUNK x 64, pixel-major (LUT) */
	int32_t *cell;     /* EST_CHUNK: LUT node offsets */
	float *cw;         /* EST_CHUNK x 8: LUT corner weights */
	uint8_t *flags;    /* EST_CHUNK */
	uint8_t *clampbits; /* EST_CHUNK / 8: bit i % 8 of byte i / 8 set when pixel i
	                       had a band clamped */
	float *terms2;     /* as terms and flags: the next chunk's, staged while the AVX-512 */
	uint8_t *flags2;   /* BSQ kernel writes the current one (avx512.c) */
} est_scratch;

typedef void (*est_block_fn)(const est_plan *p, est_scratch *s, const float *rgb, size_t n,
                             const est_dst *d, est_counts *c);

enum { EST_KIND_MATRIX, EST_KIND_LUT, EST_NKINDS };

typedef struct est_dsp {
	est_block_fn block[EST_NKINDS][KG_EST_NFORMATS];
} est_dsp;

/* Fill the table for isa: the reference everywhere, then the optimised kernels the
 * CPU supports. KG_ENOTSUP when isa names an extension the CPU lacks. */
int est_dsp_init(est_dsp *dsp, kg_est_isa isa);
void est_dsp_init_c(est_dsp *dsp);
/* AVX2 + FMA + F16C (+ POPCNT), and the OS saves the YMM registers. */
int est_have_avx2(void);
void est_dsp_init_avx2(est_dsp *dsp);
/* AVX-512F on top of est_have_avx2's set, and the OS saves the ZMM and mask registers. */
int est_have_avx512(void);
void est_dsp_init_avx512(est_dsp *dsp);

/* Pieces of the AVX2 path the AVX-512 path reuses (avx2.c; the CPU must have AVX2):
 * stage 1 of matrix kernels (flags and terms of m <= EST_CHUNK pixels into s), the
 * mask bytes and clamped-pixel count of a chunk, and the whole AVX2 matrix block. */
void est_avx2_stage_terms(const est_plan *p, est_scratch *s, const float *rgb, size_t m,
                          est_counts *c);
void est_avx2_stage_terms_part(const est_plan *p, est_scratch *s, const float *rgb, size_t m,
                               size_t i0, size_t i1, est_counts *c);
void est_finish_mask(const est_scratch *s, size_t m, uint8_t *mask, est_counts *c);
void est_avx2_matrix_block(const est_plan *p, est_scratch *s, const float *rgb, size_t n,
                           const est_dst *d, est_counts *c);

/* kg_cs_match_block's optimised kernel (camspace_avx2.c; the CPU must have AVX2):
 * pixels 0 to n - n % 8 - 1, 8 at a time, bit-identical to the reference. Returns the
 * number of pixels matched (0 where it is not built in); the caller matches the rest. */
size_t est_cs_match_avx2(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                         const kg_cs_block *out);
/* The other kernels of camspace_simd.h (in camspace_avx2.c and camspace_avx512.c; the
 * CPU must have the extension), likewise: KG_CS_EXACT on 16 pixels per vector,
 * KG_CS_QUADRATIC on 8 and 16. */
size_t est_cs_match_avx512(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                           const kg_cs_block *out);
size_t est_cs_quad_avx2(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                        const kg_cs_block *out);
size_t est_cs_quad_avx512(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                          const kg_cs_block *out);
/* KG_CS_QUADRATIC's nine per-pixel terms in the order of the model's scaled
 * predictions (camspace.c), from Q (q00 q11 q22 q01 q02 q12) and b: for ppc = c, the
 * vector kernels take their lanes' terms in the same order. */
void est_cs_quad_terms(int c, const float q[6], const float b[3], float t[9]);
/* Its index map: t[k] = (k < 6 ? q : b)[est_cs_quad_index(c, k)]. */
int est_cs_quad_index(int c, int k);

/* The Ag, Cu, Au composition of one pixel (labels_cam.c): x (3) with covariance cf (6:
 * c00 c01 c02 c11 c12 c22) as a non-negative mix of the model `metals`' three
 * materials (silver, copper, gold) at angle index k. out: the 3 fractions and their
 * Cramer-Rao standard deviations; NaN when nothing fits. */
void est_composition_pixel(const kg_cs_model *metals, int k, const float *x, const float *cf,
                           float out[6]);

/* On x86-64 a reference that uses fmaf is also built for CPUs with FMA and the better
 * build is chosen when the program loads (an ifunc): there fmaf is one instruction
 * instead of a library call. fmaf is exact either way (one rounding), so both builds
 * give the same bytes; what changes is only the reference's speed. */
#if defined(__x86_64__) && defined(__has_attribute)
#if __has_attribute(target_clones)
#define EST_REF_CLONES __attribute__((target_clones("fma", "default")))
#endif
#endif
#ifndef EST_REF_CLONES
#define EST_REF_CLONES
#endif

/* Zeroed memory aligned to 64 bytes (free with free()). */
void *est_alloc_zeroed(size_t bytes);

int est_scratch_init(est_scratch *s);
void est_scratch_fini(est_scratch *s);

#define EST_TSTRIDE (EST_CHUNK + 16)

static inline int est_kind(const kg_est_kernel *k)
{
	return k->method == KG_EST_LUT ? EST_KIND_LUT : EST_KIND_MATRIX;
}

/* Mask bits of a pixel before estimation. */
static inline unsigned est_pixel_flags(const float *rgb, float clip)
{
	if (!isfinite(rgb[0]) || !isfinite(rgb[1]) || !isfinite(rgb[2]))
		return KG_EST_MASK_NONFINITE;
	if (rgb[0] >= clip || rgb[1] >= clip || rgb[2] >= clip)
		return KG_EST_MASK_CLIPPED;
	return 0;
}

/* Cube root of x >= 0 (0 below 2^-120), within about 1 ulp: a first guess from the
 * bits of x, then three Newton steps in double. Written out step by step because
 * the optimised kernels repeat exactly these operations on 8 lanes, which keeps the
 * two bit-identical (libm's cbrtf has no vector twin and is slower). */
#define EST_CBRT_MAGIC 709958130 /* (127 - 127/3 - 0.0330624) * 2^23 */
static inline float est_cbrtf(float x)
{
	if (!(x >= 0x1p-120f))
		return 0.0f;
	int32_t i;
	memcpy(&i, &x, sizeof(i));
	float third = (float)i * (1.0f / 3.0f);
	int32_t j = (int32_t)third + EST_CBRT_MAGIC;
	float guess;
	memcpy(&guess, &j, sizeof(guess));
	double y = guess, xd = x;
	for (int k = 0; k < 3; k++) {
		double y2 = y * y;
		double num = y2 * y - xd;
		double den = 3.0 * y2;
		y = y - num / den;
	}
	return (float)y;
}

/* Terms of a matrix method; a flagged pixel gets NaN terms so that every output
 * computed from them is NaN. Root terms use max(0, channel); the cube roots are
 * formed from the channels' cube roots. */
static inline void est_pixel_terms(kg_est_method m, const float *rgb, unsigned flags,
                                   float *t)
{
	if (flags) {
		for (int i = 0; i < KG_EST_MAX_TERMS; i++)
			t[i] = NAN;
		return;
	}
	float r = rgb[0], g = rgb[1], b = rgb[2];
	t[0] = r;
	t[1] = g;
	t[2] = b;
	if (m == KG_EST_LINEAR)
		return;
	float rp = r > 0.0f ? r : 0.0f, gp = g > 0.0f ? g : 0.0f, bp = b > 0.0f ? b : 0.0f;
	t[3] = sqrtf(rp * gp);
	t[4] = sqrtf(gp * bp);
	t[5] = sqrtf(rp * bp);
	if (m == KG_EST_ROOTPOLY2)
		return;
	float cr = est_cbrtf(rp), cg = est_cbrtf(gp), cb = est_cbrtf(bp);
	t[6] = cr * (cg * cg);
	t[7] = cg * (cb * cb);
	t[8] = cr * (cb * cb);
	t[9] = cg * (cr * cr);
	t[10] = cb * (cg * cg);
	t[11] = cb * (cr * cr);
	t[12] = cr * (cg * cb);
}

/* Value of band o of a matrix kernel: offset first, then the terms in order, each
 * added with one fused multiply-add (fmaf: a single rounding), as the vector paths'
 * FMA instructions do. */
static inline float est_matrix_band(const est_map *m, int nterms, int o, const float *t)
{
	const float *a = m->a + (size_t)o * nterms;
	float acc = m->off[o];
	for (int i = 0; i < nterms; i++)
		acc = fmaf(a[i], t[i], acc);
	return acc;
}

/* LUT cell of a pixel: offset of its lower corner (in nodes) and the 8 corner
 * weights, corner c = dx + 2 dy + 4 dz. A flagged pixel gets cell 0 and NaN weights. */
static inline int32_t est_lut_cell(const kg_est_kernel *k, const float *rgb, unsigned flags,
                                   float *w)
{
	if (flags) {
		for (int c = 0; c < 8; c++)
			w[c] = NAN;
		return 0;
	}
	int n = k->lut_n, idx[3];
	float f[3];
	for (int a = 0; a < 3; a++) {
		float x = (rgb[a] - k->lut_lo) * k->lut_scale;
		if (!(x > 0.0f))
			x = 0.0f;
		if (x > (float)(n - 1))
			x = (float)(n - 1);
		int i = (int)x;
		if (i > n - 2)
			i = n - 2;
		idx[a] = i;
		f[a] = x - (float)i;
	}
	float gx[2] = {1.0f - f[0], f[0]}, gy[2] = {1.0f - f[1], f[1]},
	      gz[2] = {1.0f - f[2], f[2]};
	for (int c = 0; c < 8; c++)
		w[c] = (gz[c >> 2] * gy[(c >> 1) & 1]) * gx[c & 1];
	return (idx[2] * n + idx[1]) * n + idx[0];
}

/* Node offsets (in nodes) of the 8 corners relative to the lower one. */
static inline int32_t est_lut_corner(int n, int c)
{
	return ((c >> 2) * n + ((c >> 1) & 1)) * n + (c & 1);
}

/* Band o of a LUT output: corners summed in order, starting from corner 0 (a plain
 * product), each further corner added with one fused multiply-add. */
static inline float est_lut_band(const est_map *m, int n, int32_t cell, const float *w,
                                 int o)
{
	float acc = w[0] * m->lut[(size_t)cell * m->stride + o];
	for (int c = 1; c < 8; c++)
		acc = fmaf(w[c], m->lut[(size_t)(cell + est_lut_corner(n, c)) * m->stride + o], acc);
	return acc;
}

/* Distances of weights v (K, already offset by the mean's projection) to material
 * j, in double. Shared by the reference and by kg_est_classifier_distances; the
 * optimised kernel repeats the same operations lane by lane. */
static inline double est_material_distance(const kg_est_classifier *c, int j, const double *v)
{
	const double *cj = c->c + (size_t)j * c->k;
	if (c->distance == KG_EST_DIST_PLAIN) {
		double d = c->e[j];
		for (int i = 0; i < c->k; i++) {
			double t = cj[i] - v[i];
			d = d + t * t;
		}
		return d;
	}
	double p = c->g[j];
	for (int i = 0; i < c->k; i++)
		p = p + cj[i] * v[i];
	double a = p > 0.0 ? p * c->inv_norm[j] : 0.0;
	double d = c->h + a * (a * c->q[j] - 2.0 * c->g[j]);
	for (int i = 0; i < c->k; i++) {
		double t = v[i] - a * cj[i];
		d = d + t * t;
	}
	return d;
}

static inline void est_weights_to_v(const kg_est_classifier *c, const float *w, double *v)
{
	for (int i = 0; i < c->k; i++)
		v[i] = (double)w[i] + c->mpar[i];
}

/* Label and margin of one pixel. */
static inline void est_classify_pixel(const kg_est_classifier *c, const double *v,
                                      uint8_t *label, float *margin)
{
	double best = INFINITY, second = INFINITY;
	int lab = 0;
	for (int j = 0; j < c->n; j++) {
		double d = est_material_distance(c, j, v);
		if (d < best) {
			second = best;
			best = d;
			lab = j;
		} else if (d < second) {
			second = d;
		}
	}
	*label = (uint8_t)(lab + 1);
	*margin = (float)(second - best);
}

/* C = L L^T for a 3 x 3 covariance (row-major), L lower triangular; 0 when C is not
 * positive definite. */
static inline int est_chol3(const double cov[9], double L[9])
{
	memset(L, 0, 9 * sizeof(double));
	L[0] = sqrt(cov[0]);
	L[3] = cov[3] / L[0];
	L[6] = cov[6] / L[0];
	L[4] = sqrt(cov[4] - L[3] * L[3]);
	L[7] = (cov[7] - L[6] * L[3]) / L[4];
	L[8] = sqrt(cov[8] - L[6] * L[6] - L[7] * L[7]);
	return L[0] > 0 && L[4] > 0 && L[8] > 0;
}

/* y = L^-1 x for the lower Cholesky factor L of est_chol3. */
static inline void est_forward3(const double L[9], const double x[3], double y[3])
{
	y[0] = x[0] / L[0];
	y[1] = (x[1] - L[3] * y[0]) / L[4];
	y[2] = (x[2] - L[6] * y[0] - L[7] * y[1]) / L[8];
}

#endif
