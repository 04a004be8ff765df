/* Kernel objects: matrix kernels from a description, LUTs built from them, and
 * one-pixel evaluation with the reference path. */
#include <stdlib.h>
#include <string.h>

#include "est_private.h"

int kg_est_method_terms(kg_est_method m)
{
	switch (m) {
	case KG_EST_LINEAR:
		return 3;
	case KG_EST_ROOTPOLY2:
		return 6;
	case KG_EST_ROOTPOLY3:
		return 13;
	default:
		return KG_EINVAL;
	}
}

int kg_est_terms(kg_est_method m, const double rgb[3], double *t)
{
	int nt = kg_est_method_terms(m);
	if (nt < 0 || !rgb || !t)
		return KG_EINVAL;
	double r = rgb[0], g = rgb[1], b = rgb[2];
	t[0] = r;
	t[1] = g;
	t[2] = b;
	if (nt == 3)
		return nt;
	double rp = r > 0 ? r : 0, gp = g > 0 ? g : 0, bp = b > 0 ? b : 0;
	t[3] = sqrt(rp * gp);
	t[4] = sqrt(gp * bp);
	t[5] = sqrt(rp * bp);
	if (nt == 6)
		return nt;
	t[6] = cbrt(rp * gp * gp);
	t[7] = cbrt(gp * bp * bp);
	t[8] = cbrt(rp * bp * bp);
	t[9] = cbrt(gp * rp * rp);
	t[10] = cbrt(bp * gp * gp);
	t[11] = cbrt(bp * rp * rp);
	t[12] = cbrt(rp * gp * bp);
	return nt;
}

static void map_fini(est_map *m)
{
	free(m->a);
	free(m->off);
	free(m->a8);
	free(m->off8);
	free(m->bip_coef);
	free(m->bip_off);
	free(m->bip_pix);
	free(m->lut);
	memset(m, 0, sizeof(*m));
}

void kg_est_kernel_free(kg_est_kernel **pk)
{
	kg_est_kernel *k = pk ? *pk : NULL;
	if (!k)
		return;
	map_fini(&k->spec);
	map_fini(&k->wts);
	free(k->basis);
	free(k->mean);
	free(k);
	*pk = NULL;
}

/* Matrix and offset (rounded to float) plus the BIP tables. */
static int map_init_matrix(est_map *m, int nb, int nt, int clamp, const double *a,
                           const double *off)
{
	m->nb = nb;
	m->clamp = clamp;
	m->a = est_alloc_zeroed(sizeof(float) * nb * nt);
	m->off = est_alloc_zeroed(sizeof(float) * nb);
	m->a8 = est_alloc_zeroed(sizeof(float) * nb * nt * 8);
	m->off8 = est_alloc_zeroed(sizeof(float) * nb * 8);
	m->bip_coef = est_alloc_zeroed(sizeof(float) * nb * nt * 8);
	m->bip_off = est_alloc_zeroed(sizeof(float) * nb * 8);
	m->bip_pix = est_alloc_zeroed(sizeof(int32_t) * nb * 8);
	if (!m->a || !m->off || !m->a8 || !m->off8 || !m->bip_coef || !m->bip_off || !m->bip_pix)
		return KG_ENOMEM;
	for (int i = 0; i < nb * nt; i++)
		m->a[i] = (float)a[i];
	for (int o = 0; o < nb; o++)
		m->off[o] = off ? (float)off[o] : 0.0f;
	for (int o = 0; o < nb; o++)
		for (int l = 0; l < 8; l++) {
			m->off8[o * 8 + l] = m->off[o];
			for (int t = 0; t < nt; t++)
				m->a8[(o * nt + t) * 8 + l] = m->a[o * nt + t];
		}
	for (int v = 0; v < nb; v++) {
		for (int l = 0; l < 8; l++) {
			int j = 8 * v + l, p = j / nb, o = j % nb;
			m->bip_pix[v * 8 + l] = p;
			m->bip_off[v * 8 + l] = m->off[o];
			for (int t = 0; t < nt; t++)
				m->bip_coef[(v * nt + t) * 8 + l] = m->a[o * nt + t];
		}
	}
	return 0;
}

static int all_finite(const double *v, size_t n)
{
	for (size_t i = 0; i < n; i++)
		if (!isfinite(v[i]))
			return 0;
	return 1;
}

static int copy_basis(kg_est_kernel *k, int kk, const double *basis, const double *mean)
{
	k->k = kk;
	if (!kk)
		return 0;
	k->basis = malloc(sizeof(double) * KG_NBANDS * kk);
	if (!k->basis)
		return KG_ENOMEM;
	memcpy(k->basis, basis, sizeof(double) * KG_NBANDS * kk);
	if (mean) {
		k->mean = malloc(sizeof(double) * KG_NBANDS);
		if (!k->mean)
			return KG_ENOMEM;
		memcpy(k->mean, mean, sizeof(double) * KG_NBANDS);
	}
	return 0;
}

int kg_est_kernel_new(const kg_est_desc *d, kg_est_kernel **out, kg_err *err)
{
	kg_check_arg(d && out, err);
	*out = NULL;
	int nt = kg_est_method_terms(d->method);
	if (nt < 0)
		return kg_fail(err, KG_EINVAL,
		               "estimation kernel: method %d: expected linear, root-polynomial 2 "
		               "or 3 (a LUT is made with kg_est_kernel_new_lut)",
		               (int)d->method);
	if (d->k < 0 || d->k > KG_EST_MAX_K)
		return kg_fail(err, KG_EINVAL, "estimation kernel: basis size %d: expected 0..%d",
		               d->k, KG_EST_MAX_K);
	if (!d->matrix || (d->k && !d->basis))
		return kg_fail(err, KG_EINVAL, "estimation kernel: %s missing",
		               d->matrix ? "basis" : "matrix");
	int rows = d->k ? d->k : KG_NBANDS;
	if (!all_finite(d->matrix, (size_t)rows * nt) ||
	    (d->offset && !all_finite(d->offset, rows)) ||
	    (d->basis && !all_finite(d->basis, (size_t)KG_NBANDS * d->k)) ||
	    (d->mean && !all_finite(d->mean, KG_NBANDS)))
		return kg_fail(err, KG_EINVAL,
		               "estimation kernel: matrix, offset, basis or mean: expected finite "
		               "numbers");

	kg_est_kernel *k = calloc(1, sizeof(*k));
	double *spec_a = NULL, *spec_off = NULL;
	int rc = KG_ENOMEM;
	if (!k)
		goto error;
	k->method = d->method;
	k->nterms = nt;
	if ((rc = copy_basis(k, d->k, d->basis, d->mean)) < 0)
		goto error;
	if (d->k) {
		/* Spectrum = B (W phi + w0) + mean = (B W) phi + (B w0 + mean), in double. */
		rc = KG_ENOMEM;
		spec_a = calloc((size_t)KG_NBANDS * nt, sizeof(double));
		spec_off = calloc(KG_NBANDS, sizeof(double));
		if (!spec_a || !spec_off)
			goto error;
		for (int o = 0; o < KG_NBANDS; o++) {
			for (int i = 0; i < d->k; i++) {
				double bo = d->basis[o * d->k + i];
				for (int t = 0; t < nt; t++)
					spec_a[o * nt + t] += bo * d->matrix[i * nt + t];
				if (d->offset)
					spec_off[o] += bo * d->offset[i];
			}
			if (d->mean)
				spec_off[o] += d->mean[o];
		}
		if ((rc = map_init_matrix(&k->spec, KG_NBANDS, nt, 1, spec_a, spec_off)) < 0 ||
		    (rc = map_init_matrix(&k->wts, d->k, nt, 0, d->matrix, d->offset)) < 0)
			goto error;
	} else if ((rc = map_init_matrix(&k->spec, KG_NBANDS, nt, 1, d->matrix, d->offset)) < 0) {
		goto error;
	}
	free(spec_a);
	free(spec_off);
	*out = k;
	return 0;
error:
	free(spec_a);
	free(spec_off);
	kg_est_kernel_free(&k);
	return kg_fail(err, rc, "estimation kernel: out of memory");
}

/* Unclamped output of the reference matrix kernel at one input. */
static void eval_matrix(const kg_est_kernel *k, const est_map *m, const float *rgb, float *out)
{
	float t[KG_EST_MAX_TERMS];
	est_pixel_terms(k->method, rgb, 0, t);
	for (int o = 0; o < m->nb; o++)
		out[o] = est_matrix_band(m, k->nterms, o, t);
}

static int map_init_lut(const kg_est_kernel *src, const est_map *sm, est_map *m, int n,
                        const kg_est_kernel *lut)
{
	m->nb = sm->nb;
	m->clamp = sm->clamp;
	m->stride = EST_PAD(sm->nb);
	m->lut = est_alloc_zeroed(sizeof(float) * m->stride * n * n * n);
	if (!m->lut)
		return KG_ENOMEM;
	for (int z = 0; z < n; z++)
		for (int y = 0; y < n; y++)
			for (int x = 0; x < n; x++) {
				float rgb[3] = {kg_est_lut_node(lut, x), kg_est_lut_node(lut, y),
				                kg_est_lut_node(lut, z)};
				eval_matrix(src, sm, rgb, m->lut + (size_t)((z * n + y) * n + x) * m->stride);
			}
	return 0;
}

int kg_est_kernel_new_lut(const kg_est_kernel *src, int n, float lo, float hi,
                          kg_est_kernel **out, kg_err *err)
{
	kg_check_arg(src && out, err);
	*out = NULL;
	if (src->method == KG_EST_LUT)
		return kg_fail(err, KG_EINVAL, "LUT: source kernel: expected a matrix kernel, not a LUT");
	if (n < 2 || n > KG_EST_LUT_MAX_N)
		return kg_fail(err, KG_EINVAL, "LUT: %d nodes per axis: expected 2..%d", n,
		               KG_EST_LUT_MAX_N);
	if (!isfinite(lo) || !isfinite(hi) || !(hi > lo))
		return kg_fail(err, KG_EINVAL, "LUT: range [%g, %g]: expected finite lo < hi",
		               (double)lo, (double)hi);
	kg_est_kernel *k = calloc(1, sizeof(*k));
	int rc = KG_ENOMEM;
	if (!k)
		goto error;
	k->method = KG_EST_LUT;
	k->lut_n = n;
	k->lut_lo = lo;
	k->lut_scale = (float)(n - 1) / (hi - lo);
	if ((rc = copy_basis(k, src->k, src->basis, src->mean)) < 0 ||
	    (rc = map_init_lut(src, &src->spec, &k->spec, n, k)) < 0 ||
	    (src->k && (rc = map_init_lut(src, &src->wts, &k->wts, n, k)) < 0))
		goto error;
	*out = k;
	return 0;
error:
	kg_est_kernel_free(&k);
	return kg_fail(err, rc, "LUT: out of memory for %d^3 nodes", n);
}

float kg_est_lut_node(const kg_est_kernel *k, int i)
{
	if (k->lut_n < 2)
		return NAN;
	return k->lut_lo + (float)i / k->lut_scale;
}

kg_est_method kg_est_kernel_method(const kg_est_kernel *k) { return k->method; }

int kg_est_kernel_k(const kg_est_kernel *k) { return k->k; }

unsigned kg_est_kernel_eval(const kg_est_kernel *k, const float rgb[3], float clip_level,
                            int weights, float *out)
{
	const est_map *m = weights ? &k->wts : &k->spec;
	unsigned flags = est_pixel_flags(rgb, clip_level);
	if (k->method == KG_EST_LUT) {
		float w[8];
		int32_t cell = est_lut_cell(k, rgb, flags, w);
		for (int o = 0; o < m->nb; o++)
			out[o] = est_lut_band(m, k->lut_n, cell, w, o);
	} else {
		float t[KG_EST_MAX_TERMS];
		est_pixel_terms(k->method, rgb, flags, t);
		for (int o = 0; o < m->nb; o++)
			out[o] = est_matrix_band(m, k->nterms, o, t);
	}
	if (m->clamp)
		for (int o = 0; o < m->nb; o++)
			if (out[o] < 0.0f) {
				out[o] = 0.0f;
				flags |= KG_EST_MASK_CLAMPED;
			}
	return flags;
}

int kg_est_format_bands(const kg_est_kernel *k, kg_est_format f)
{
	switch (f) {
	case KG_EST_WEIGHTS:
		return k->k;
	case KG_EST_LABELS:
		return 1;
	default:
		return KG_NBANDS;
	}
}

size_t kg_est_format_elem_size(kg_est_format f)
{
	switch (f) {
	case KG_EST_F16_BSQ:
	case KG_EST_F16_BIP:
		return 2;
	case KG_EST_LABELS:
		return 1;
	default:
		return 4;
	}
}

uint16_t kg_f16_from_f32(float f)
{
	uint32_t x;
	memcpy(&x, &f, sizeof(x));
	uint16_t sign = (uint16_t)((x >> 16) & 0x8000);
	uint32_t ax = x & 0x7fffffff;
	if (ax > 0x7f800000) /* NaN: quiet, upper payload bits kept (as F16C does) */
		return (uint16_t)(sign | 0x7e00 | ((ax >> 13) & 0x3ff));
	if (ax >= 0x477ff000) /* >= 65520 rounds to Inf (65520 is a tie, Inf is even) */
		return (uint16_t)(sign | 0x7c00);
	if (ax >= 0x38800000) { /* normal: rebias, round the 13 dropped bits to even */
		uint32_t r = ax - 0x38000000;
		r += 0xfff + ((r >> 13) & 1);
		return (uint16_t)(sign | (r >> 13));
	}
	uint32_t e = ax >> 23;
	if (e < 102) /* below 2^-25: rounds to zero */
		return sign;
	/* subnormal half: value / 2^-24 = mantissa * 2^(e - 126) */
	uint32_t m = (ax & 0x7fffff) | 0x800000;
	uint32_t shift = 126 - e; /* 14..24 */
	uint32_t h = m >> shift, rem = m & ((1u << shift) - 1), half = 1u << (shift - 1);
	if (rem > half || (rem == half && (h & 1)))
		h++;
	return (uint16_t)(sign | h);
}

float kg_f32_from_f16(uint16_t h)
{
	uint32_t sign = (uint32_t)(h & 0x8000) << 16, e = (h >> 10) & 0x1f, m = h & 0x3ff, x;
	if (e == 0x1f)
		x = sign | 0x7f800000 | (m << 13);
	else if (e)
		x = sign | ((e + 112) << 23) | (m << 13);
	else {
		float v = (float)m * 0x1p-24f; /* exact: m < 2^10 */
		return sign ? -v : v;
	}
	float f;
	memcpy(&f, &x, sizeof(f));
	return f;
}
