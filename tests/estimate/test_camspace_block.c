/* The camera-space block matcher (kg_cs_match_block_method, estimate/camspace.c,
 * camspace_simd.h in camspace_avx2.c and camspace_avx512.c), both methods.
 *  - Bit identity: over random models (1 to 16 materials, 1 to 20 angles, materials
 *    that are black, negative, duplicated, the same at every angle or near FLT_MAX at
 *    one angle (infinite and NaN distances among finite ones), intensity ranges
 *    with lo = hi) at ordinary, tiny and huge scales, and random pixels with the hard
 *    cases sprinkled in (x NaN or infinite or summing past FLT_MAX; covariances zero,
 *    negative, indefinite, singular, NaN, infinite or subnormal; readings that clamp at
 *    lo and at hi; x = 0 and x = -mu), each method's reference (KG_EST_ISA_C) and its
 *    AVX2 and AVX-512 kernels write the same bytes into every output, for block sizes
 *    that are and are not a multiple of 8, 16 and 32, with every output and with only
 *    some of them. All are run into buffers prefilled with different bytes, so every
 *    value is written. On a CPU without an extension that part is skipped with a
 *    message and KG_ENOTSUP is checked.
 *  - The quadratic method against the exact one, on every pixel: the same pixels
 *    refused; no material's distance below the exact method's (it is the exact
 *    distance at one of the material's angles); and on the ordinary pixels no
 *    distance above it by more than the quadratic form's rounding, 32 eps M summed
 *    over the two candidates compared (M = a^2 p^T|Q|p + 2 a |p|.|b|, the form's
 *    terms' magnitudes, in double) plus the exact method's own rounding of both; where
 *    the labels differ, the two best materials are that close.
 *  - The exact method against the double kg_cs_match, on the ordinary pixels (none of
 *    the hard cases, scales 1e-15 to 1e15): every material's distance within 1e-4
 *    relative (plus the float rounding of whitening a reading of length |y|,
 *    16 eps |y| (2 sqrt(d) + 16 eps |y|), which only matters for near-perfect fits),
 *    and the same best material whenever the double best and second distances are
 *    more than 1e-3 relative (and twice the distance tolerance) apart.
 *  - The library's ten materials under a smooth synthetic response, realistic noise.
 */
#include <float.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "est_fixture.h"
#include "kg_estimate.h"
#include "kg_test.h"

/* A model built field by field (kg_cs_model_free frees it): mu is muf in double, so
 * the double matcher sees exactly the float model. */
static kg_cs_model *model_alloc(int n, int na, double lo, double hi)
{
	kg_cs_model *m = calloc(1, sizeof(*m));
	if (!m)
		return NULL;
	m->n = n;
	m->nangles = na;
	m->lo = lo;
	m->hi = hi;
	m->names = calloc((size_t)n, sizeof(*m->names));
	m->angle_deg = malloc(sizeof(double) * (size_t)na);
	m->anglef = malloc(sizeof(float) * (size_t)na);
	m->mu = malloc(sizeof(double) * 3 * (size_t)n * (size_t)na);
	m->muf = malloc(sizeof(float) * 3 * (size_t)n * (size_t)na);
	if (!m->names || !m->angle_deg || !m->anglef || !m->mu || !m->muf) {
		kg_cs_model_free(&m);
		return NULL;
	}
	for (int k = 0; k < na; k++) {
		m->anglef[k] = (float)(5.0 * k);
		m->angle_deg[k] = m->anglef[k];
	}
	return m;
}

static kg_cs_model *random_model(fx_rng *r, double scale)
{
	int n = 1 + (int)(fx_next(r) % 16), na = 1 + (int)(fx_next(r) % 20);
	double lo = fx_uniform(r, 0.05, 0.6);
	double hi = fx_next(r) % 8 ? lo * fx_uniform(r, 1.0, 4.0) : lo;
	kg_cs_model *m = model_alloc(n, na, lo, hi);
	if (!m)
		return NULL;
	for (int j = 0; j < n; j++) {
		snprintf(m->names[j], sizeof(m->names[j]), "m%d", j);
		double base[3], tilt[3];
		for (int c = 0; c < 3; c++) {
			base[c] = fx_uniform(r, 0.02, 1.0);
			tilt[c] = fx_uniform(r, -0.3, 0.3);
		}
		int special = (int)(fx_next(r) % 10);
		if (special == 3)
			base[fx_next(r) % 3] *= -1; /* a negative channel */
		for (int k = 0; k < na; k++) {
			float *mu = m->muf + 3 * ((size_t)j * na + k);
			for (int c = 0; c < 3; c++) {
				double v = special == 0 ? 0                /* black: vv = 0, a = NaN */
				           : special == 1 ? base[c]         /* the same at every angle */
				                          : base[c] * (1 + tilt[c] * k / 20.0);
				mu[c] = (float)(scale * v);
			}
			if (special == 2 && j > 0) /* the previous material again: ties */
				memcpy(mu, mu - 3 * (size_t)na, 3 * sizeof(float));
			if (special == 4 && k == na / 2 && na > 1) /* whitened: Inf and NaN distances */
				mu[0] = mu[1] = mu[2] = 3e38f;
		}
	}
	for (size_t i = 0; i < 3 * (size_t)n * (size_t)na; i++)
		m->mu[i] = m->muf[i];
	if (kg_cs_model_products(m))
		kg_cs_model_free(&m);
	return m;
}

/* Covariance (6 floats) of a reading at scale s: channel noise of 0.3 % to 3 % of s,
 * mixed by a matrix near identity (a camera's values mapped through M2). */
static void random_cov(fx_rng *r, double s, double cov[9])
{
	double M[9], sd[3];
	for (int i = 0; i < 9; i++)
		M[i] = (i % 4 == 0 ? 1 : 0) + fx_uniform(r, -0.3, 0.3);
	for (int c = 0; c < 3; c++)
		sd[c] = s * fx_uniform(r, 0.003, 0.03);
	for (int a = 0; a < 3; a++)
		for (int b = 0; b < 3; b++) {
			double v = 0;
			for (int c = 0; c < 3; c++)
				v += M[a * 3 + c] * sd[c] * sd[c] * M[b * 3 + c];
			cov[a * 3 + b] = v;
		}
}

/* |L^-1 x| in double (the whitened reading's length), for the rounding allowance. */
static double whitened_length(const double x[3], const double C[9])
{
	double l0 = sqrt(C[0]), l3 = C[3] / l0, l6 = C[6] / l0;
	double l4 = sqrt(C[4] - l3 * l3), l7 = (C[7] - l6 * l3) / l4;
	double l8 = sqrt(C[8] - l6 * l6 - l7 * l7);
	double y0 = x[0] / l0, y1 = (x[1] - l3 * y0) / l4, y2 = (x[2] - l6 * y0 - l7 * y1) / l8;
	return sqrt(y0 * y0 + y1 * y1 + y2 * y2);
}

typedef struct pixels {
	size_t n;
	float *x, *cov;
	double *xd, *covd; /* the same values, cov as 3 x 3 */
	uint8_t *clean;    /* ordinary: compared with the double matcher */
} pixels;

static void pixels_free(pixels *p)
{
	free(p->x);
	free(p->cov);
	free(p->xd);
	free(p->covd);
	free(p->clean);
	memset(p, 0, sizeof(*p));
}

/* n readings of the model's materials at random angles and intensities (half again
 * beyond [lo, hi] on either side) with their covariances' noise; with `hard`, one in
 * two gets one of the hard cases. */
static int make_pixels(fx_rng *r, const kg_cs_model *m, double scale, size_t n, int hard,
                       pixels *p)
{
	p->n = n;
	p->x = malloc(sizeof(float) * 3 * (n ? n : 1));
	p->cov = malloc(sizeof(float) * 6 * (n ? n : 1));
	p->xd = malloc(sizeof(double) * 3 * (n ? n : 1));
	p->covd = malloc(sizeof(double) * 9 * (n ? n : 1));
	p->clean = malloc(n ? n : 1);
	if (!p->x || !p->cov || !p->xd || !p->covd || !p->clean)
		return -1;
	static const int tri[6] = {0, 1, 2, 4, 5, 8};
	for (size_t i = 0; i < n; i++) {
		int j = (int)(fx_next(r) % (uint64_t)m->n);
		int k = (int)(fx_next(r) % (uint64_t)m->nangles);
		double a = fx_uniform(r, 0.5 * m->lo, 1.5 * m->hi);
		const double *mu = m->mu + 3 * ((size_t)j * m->nangles + k);
		double C[9], z[3] = {fx_gauss(r), fx_gauss(r), fx_gauss(r)};
		random_cov(r, scale, C);
		double l0 = sqrt(C[0]), l3 = C[3] / l0, l6 = C[6] / l0;
		double l4 = sqrt(C[4] - l3 * l3), l7 = (C[7] - l6 * l3) / l4;
		double l8 = sqrt(C[8] - l6 * l6 - l7 * l7);
		double x[3] = {a * mu[0] + l0 * z[0], a * mu[1] + l3 * z[0] + l4 * z[1],
		               a * mu[2] + l6 * z[0] + l7 * z[1] + l8 * z[2]};
		float *xf = p->x + 3 * i, *cf = p->cov + 6 * i;
		for (int c = 0; c < 3; c++)
			xf[c] = (float)x[c];
		for (int q = 0; q < 6; q++)
			cf[q] = (float)C[tri[q]];
		int kind = hard && fx_next(r) % 2 ? 1 + (int)(fx_next(r) % 16) : 0;
		switch (kind) {
		case 1: xf[fx_next(r) % 3] = NAN; break;
		case 2: xf[fx_next(r) % 3] = INFINITY; break;
		case 3: xf[fx_next(r) % 3] = -INFINITY; break;
		case 4: xf[0] = xf[1] = xf[2] = 3e38f; break; /* finite, but the sum is not */
		case 5: memset(cf, 0, 6 * sizeof(float)); break;
		case 6: cf[0] = -cf[0]; break;
		case 7: cf[3] = 0.5f * cf[1] * cf[1] / cf[0]; break; /* indefinite */
		case 8: { /* rank 1: v v^T */
			float v[3] = {xf[0], xf[1], xf[2]};
			for (int q = 0; q < 6; q++)
				cf[q] = v[tri[q] / 3] * v[tri[q] % 3];
			break;
		}
		case 9: cf[4] = NAN; break;
		case 10: cf[0] = INFINITY; break;
		case 11: cf[3] = INFINITY; break;
		case 12: /* subnormal */
			for (int q = 0; q < 6; q++)
				cf[q] *= 1e-38f;
			break;
		case 13: xf[0] = xf[1] = xf[2] = 0; break;
		case 14:
			for (int c = 0; c < 3; c++)
				xf[c] = (float)-mu[c];
			break;
		case 15: /* clamps at hi */
			for (int c = 0; c < 3; c++)
				xf[c] = (float)(1e3 * mu[c]);
			break;
		case 16: cf[1] = cf[2] = cf[4] = -0.0f; break;
		}
		p->clean[i] = kind == 0 && scale >= 1e-15 && scale <= 1e15 &&
		              fmax(fabs(mu[0]), fmax(fabs(mu[1]), fabs(mu[2]))) < 1e3 * scale;
		for (int c = 0; c < 3; c++)
			p->xd[3 * i + c] = xf[c];
		for (int q = 0; q < 6; q++)
			p->covd[9 * i + tri[q]] = p->covd[9 * i + (tri[q] % 3) * 3 + tri[q] / 3] = cf[q];
	}
	return 0;
}

typedef struct outputs {
	uint8_t *best;
	float *d2best, *d2second, *angle, *scale, *d2;
} outputs;

static int outputs_alloc(outputs *o, size_t n, int nm, int fill)
{
	size_t k = n ? n : 1;
	o->best = malloc(k);
	o->d2best = malloc(sizeof(float) * k);
	o->d2second = malloc(sizeof(float) * k);
	o->angle = malloc(sizeof(float) * k);
	o->scale = malloc(sizeof(float) * k);
	o->d2 = malloc(sizeof(float) * k * (size_t)nm);
	if (!o->best || !o->d2best || !o->d2second || !o->angle || !o->scale || !o->d2)
		return -1;
	memset(o->best, fill, k);
	memset(o->d2best, fill, sizeof(float) * k);
	memset(o->d2second, fill, sizeof(float) * k);
	memset(o->angle, fill, sizeof(float) * k);
	memset(o->scale, fill, sizeof(float) * k);
	memset(o->d2, fill, sizeof(float) * k * (size_t)nm);
	return 0;
}

static void outputs_free(outputs *o)
{
	free(o->best);
	free(o->d2best);
	free(o->d2second);
	free(o->angle);
	free(o->scale);
	free(o->d2);
	memset(o, 0, sizeof(*o));
}

static kg_cs_block block_of(const outputs *o, int all)
{
	kg_cs_block b = {o->best, NULL, NULL, NULL, NULL, NULL};
	if (all) {
		b.d2best = o->d2best;
		b.d2second = o->d2second;
		b.angle_deg = o->angle;
		b.scale = o->scale;
		b.d2 = o->d2;
	} else {
		b.scale = o->scale; /* one optional output, and never d2 */
	}
	return b;
}

/* Index of the first differing output, or -1 when all bytes agree. */
static long first_difference(const outputs *a, const outputs *b, size_t n, int nm,
                             const char **what)
{
	const struct {
		const char *name;
		const void *p, *q;
		size_t elem, count;
	} arr[6] = {
		{"best", a->best, b->best, 1, n},
		{"d2best", a->d2best, b->d2best, 4, n},
		{"d2second", a->d2second, b->d2second, 4, n},
		{"angle", a->angle, b->angle, 4, n},
		{"scale", a->scale, b->scale, 4, n},
		{"d2", a->d2, b->d2, 4, n * (size_t)nm},
	};
	for (int t = 0; t < 6; t++)
		for (size_t i = 0; i < arr[t].count; i++)
			if (memcmp((const char *)arr[t].p + i * arr[t].elem,
			           (const char *)arr[t].q + i * arr[t].elem, arr[t].elem)) {
				*what = arr[t].name;
				return (long)i;
			}
	return -1;
}

typedef struct tally {
	long blocks[2], identical_blocks[2], pixels, nomatch, nan_valid, at_lo, at_hi;
	long compared, best_checked, best_wrong, dist_wrong;
	long quad_compared, quad_labels_same, quad_all_same, quad_below, quad_above, quad_tie_wrong;
	double max_rel, max_rel_fit, worst, quad_worst;
} tally;

/* Bytes of the outputs a partial block did not ask for: still the fill. */
static int untouched(const outputs *o, size_t n, int nm, int fill)
{
	const float *arr[4] = {o->d2best, o->d2second, o->angle, o->d2};
	const size_t cnt[4] = {n, n, n, n * (size_t)nm};
	for (int t = 0; t < 4; t++)
		for (size_t i = 0; i < 4 * cnt[t]; i++)
			if (((const uint8_t *)arr[t])[i] != (uint8_t)fill)
				return 0;
	return 1;
}

static const char *method_name[2] = {"exact", "quadratic"};
static const char *isa_label[4] = {"auto", "C", "AVX2", "AVX-512"};

/* One method's implementation against its reference ref (all: every output; else only
 * best and scale, the rest untouched). */
static void compare_impl(const kg_cs_model *m, const pixels *p, const outputs *ref,
                         kg_cs_method method, kg_est_isa isa, int all, tally *t,
                         const char *label)
{
	outputs vec = {0};
	int nm = m->n;
	if (outputs_alloc(&vec, p->n, nm, 0x5a)) {
		CHECK(0, "out of memory");
		return;
	}
	kg_cs_block bv = block_of(&vec, all);
	CHECK(kg_cs_match_block_method(m, p->x, p->cov, p->n, &bv, method, isa) == 0, "%s %s",
	      method_name[method], isa_label[isa]);
	const char *what = "";
	long at;
	t->blocks[method]++;
	if (all) {
		at = first_difference(ref, &vec, p->n, nm, &what);
	} else {
		CHECK(untouched(&vec, p->n, nm, 0x5a), "%s: %s %s writes outputs not asked for", label,
		      method_name[method], isa_label[isa]);
		outputs some = vec;
		some.d2best = ref->d2best;
		some.d2second = ref->d2second;
		some.angle = ref->angle;
		some.d2 = ref->d2;
		at = first_difference(ref, &some, p->n, nm, &what);
	}
	t->identical_blocks[method] += at < 0;
	if (at >= 0) {
		size_t i = strcmp(what, "d2") ? (size_t)at : (size_t)at / (size_t)nm;
		const float *x = p->x + 3 * i, *c = p->cov + 6 * i;
		CHECK(0, "%s (%s outputs): %s C and %s differ at %s[%ld]; pixel %zu x %a %a %a "
		      "cov %a %a %a %a %a %a", label, all ? "all" : "some", method_name[method],
		      isa_label[isa], what, at, i, x[0], x[1], x[2], c[0], c[1], c[2], c[3], c[4],
		      c[5]);
	}
	outputs_free(&vec);
}

/* The bound on how far the quadratic form's s = d - |y|^2 of a candidate is from its
 * value in exact arithmetic: 32 eps M, M the magnitudes of the form's terms. */
static double quad_rounding(const double Q[9], const double b[3], const double *mu, double lo,
                            double hi)
{
	const double eps = FLT_EPSILON;
	double pqp = 0, aqp = 0, pb = 0, apb = 0;
	for (int r = 0; r < 3; r++) {
		pb += mu[r] * b[r];
		apb += fabs(mu[r] * b[r]);
		for (int c = 0; c < 3; c++) {
			pqp += mu[r] * Q[3 * r + c] * mu[c];
			aqp += fabs(mu[r] * Q[3 * r + c] * mu[c]);
		}
	}
	double a = pqp > 0 ? pb / pqp : lo;
	a = a < lo ? lo : a > hi ? hi : a;
	return 32 * eps * (a * a * aqp + 2 * a * apb);
}

/* The quadratic method's reference q against the exact one e (every output). */
static void compare_methods(const kg_cs_model *m, const pixels *p, const outputs *e,
                            const outputs *q, tally *t, const char *label)
{
	const double eps = FLT_EPSILON;
	const int nm = m->n;
	for (size_t i = 0; i < p->n; i++) {
		int refused = e->best[i] == KG_CS_NO_MATCH;
		CHECK(refused == (q->best[i] == KG_CS_NO_MATCH), "%s: pixel %zu refused by one method "
		      "only", label, i);
		if (refused)
			continue;
		const float *de = e->d2 + i * (size_t)nm, *dq = q->d2 + i * (size_t)nm;
		for (int j = 0; j < nm; j++)
			if (dq[j] < de[j] || isnan(dq[j]) != isnan(de[j])) {
				if (t->quad_below++ < 3)
					fprintf(stderr, "%s: pixel %zu material %d: quadratic %g, exact %g\n", label, i,
					        j, dq[j], de[j]);
			}
		if (!p->clean[i])
			continue;
		/* Q = C^-1 and b = Q x in double, |y|^2 = x.b */
		const double *C = p->covd + 9 * i, *x = p->xd + 3 * i;
		double Q[9], b[3], det = C[0] * (C[4] * C[8] - C[5] * C[7]) -
		                         C[1] * (C[3] * C[8] - C[5] * C[6]) +
		                         C[2] * (C[3] * C[7] - C[4] * C[6]);
		Q[0] = (C[4] * C[8] - C[5] * C[7]) / det;
		Q[1] = Q[3] = (C[2] * C[7] - C[1] * C[8]) / det;
		Q[2] = Q[6] = (C[1] * C[5] - C[2] * C[4]) / det;
		Q[4] = (C[0] * C[8] - C[2] * C[6]) / det;
		Q[5] = Q[7] = (C[2] * C[3] - C[0] * C[5]) / det;
		Q[8] = (C[0] * C[4] - C[1] * C[3]) / det;
		for (int r = 0; r < 3; r++)
			b[r] = Q[3 * r] * x[0] + Q[3 * r + 1] * x[1] + Q[3 * r + 2] * x[2];
		double ylen = whitened_length(x, C), u = 16 * eps * ylen;
		double tol[KG_EST_MAX_MATERIALS];
		for (int j = 0; j < nm; j++) {
			double worst = 0;
			for (int k = 0; k < m->nangles; k++)
				worst = fmax(worst, quad_rounding(Q, b, m->mu + 3 * ((size_t)j * m->nangles + k),
				                                  m->lo, m->hi));
			double d = de[j];
			tol[j] = 2 * worst + 2 * (1e-4 * d + u * (2 * sqrt(d) + u));
		}
		t->quad_compared++;
		t->quad_labels_same += q->best[i] == e->best[i];
		int same = q->best[i] == e->best[i] && !memcmp(dq, de, sizeof(float) * (size_t)nm);
		t->quad_all_same += same;
		for (int j = 0; j < nm; j++) {
			if (!isfinite(de[j]))
				continue;
			double over = (double)dq[j] - de[j];
			if (!(over <= tol[j])) {
				if (t->quad_above++ < 3)
					fprintf(stderr, "%s: pixel %zu material %d: quadratic %.9g, exact %.9g (tolerance "
					        "%g)\n", label, i, j, dq[j], de[j], tol[j]);
			} else if (tol[j] > 0) {
				t->quad_worst = fmax(t->quad_worst, over / tol[j]);
			}
		}
		int qb = q->best[i], eb = e->best[i];
		if (qb != eb && !((double)de[qb] - de[eb] <= tol[eb]) && t->quad_tie_wrong++ < 3)
			fprintf(stderr, "%s: pixel %zu: quadratic best %d (exact %g), exact best %d (%g)\n",
			        label, i, qb, de[qb], eb, de[eb]);
	}
}

/* Run every implementation of both methods over p and compare: only best and scale,
 * then all outputs, each time into fresh buffers filled with different bytes. */
static void check_block(const kg_cs_model *m, const pixels *p, const int have[4], tally *t,
                        const char *label)
{
	outputs ref[2] = {{0}}, ref2 = {0}, aut = {0};
	int nm = m->n;
	for (int all = 0; all <= 1; all++) {
		for (int me = 0; me < 2; me++) {
			outputs_free(&ref[me]);
			outputs_free(&ref2);
			if (outputs_alloc(&ref[me], p->n, nm, 0xa5) || outputs_alloc(&ref2, p->n, nm, 0x5a)) {
				CHECK(0, "out of memory");
				return;
			}
			kg_cs_block b = block_of(&ref[me], all), b2 = block_of(&ref2, all);
			CHECK(kg_cs_match_block_method(m, p->x, p->cov, p->n, &b, (kg_cs_method)me,
			                               KG_EST_ISA_C) == 0, "C");
			CHECK(kg_cs_match_block_method(m, p->x, p->cov, p->n, &b2, (kg_cs_method)me,
			                               KG_EST_ISA_C) == 0, "C");
			const char *what = "";
			if (all) {
				long at = first_difference(&ref[me], &ref2, p->n, nm, &what);
				CHECK(at < 0, "%s: the %s reference leaves %s[%ld] unwritten", label,
				      method_name[me], what, at);
			} else {
				CHECK(untouched(&ref[me], p->n, nm, 0xa5), "%s: the %s reference writes outputs "
				      "not asked for", label, method_name[me]);
			}
			for (int isa = KG_EST_ISA_AVX2; isa <= KG_EST_ISA_AVX512; isa++)
				if (have[isa])
					compare_impl(m, p, &ref[me], (kg_cs_method)me, (kg_est_isa)isa, all, t, label);
		}
		if (all) {
			/* kg_cs_match_block: the quadratic method where the CPU has AVX-512 */
			outputs_free(&aut);
			if (outputs_alloc(&aut, p->n, nm, 0x3c)) {
				CHECK(0, "out of memory");
				return;
			}
			kg_cs_block ba = block_of(&aut, all);
			kg_cs_match_block(m, p->x, p->cov, p->n, &ba);
			const char *what = "";
			long at = first_difference(&ref[have[KG_EST_ISA_AVX512]], &aut, p->n, nm, &what);
			CHECK(at < 0, "%s: kg_cs_match_block differs from the %s reference at %s[%ld]", label,
			      method_name[have[KG_EST_ISA_AVX512]], what, at);
		}
	}
	compare_methods(m, p, &ref[0], &ref[1], t, label);
	/* coverage and the double matcher */
	const double eps = FLT_EPSILON;
	const outputs *e = &ref[0];
	for (size_t i = 0; i < p->n; i++) {
		t->pixels++;
		if (e->best[i] == KG_CS_NO_MATCH) {
			t->nomatch++;
			continue;
		}
		t->nan_valid += isnan(e->d2best[i]) || isnan(e->scale[i]);
		t->at_lo += e->scale[i] == (float)m->lo;
		t->at_hi += e->scale[i] == (float)m->hi && m->hi > m->lo;
		if (!p->clean[i])
			continue;
		kg_cs_result r;
		if (kg_cs_match(m, p->xd + 3 * i, p->covd + 9 * i, &r)) {
			CHECK(0, "%s: pixel %zu matched in float, refused in double", label, i);
			continue;
		}
		t->compared++;
		double ylen = whitened_length(p->xd + 3 * i, p->covd + 9 * i);
		double u = 16 * eps * ylen;
#define TOL(d) (1e-4 * (d) + u * (2 * sqrt(d) + u))
		int bad = 0;
		for (int j = 0; j < nm; j++) {
			double df = e->d2[i * (size_t)nm + j], dd = r.d2_each[j];
			if (!(fabs(df - dd) <= TOL(dd)))
				bad = 1;
			else
				t->worst = fmax(t->worst, fabs(df - dd) / TOL(dd));
			if (dd > 0)
				t->max_rel = fmax(t->max_rel, fabs(df - dd) / dd);
			if (dd > 1e-4 * ylen * ylen) /* not a near-perfect fit */
				t->max_rel_fit = fmax(t->max_rel_fit, fabs(df - dd) / dd);
		}
		bad |= !(fabs(e->d2best[i] - r.d2_best) <= TOL(r.d2_best));
		bad |= !(fabs(e->d2second[i] - r.d2_second) <= TOL(r.d2_second)) &&
		       !(isinf(r.d2_second) && isinf(e->d2second[i]));
		if (bad && t->dist_wrong++ < 3)
			fprintf(stderr, "%s: pixel %zu: float distances %g %g, double %g %g (|y| %g)\n",
			        label, i, e->d2best[i], e->d2second[i], r.d2_best, r.d2_second, ylen);
		if (r.d2_second - r.d2_best > 1e-3 * r.d2_best + 2 * TOL(r.d2_second)) {
			t->best_checked++;
			if (e->best[i] != r.best && t->best_wrong++ < 3)
				fprintf(stderr, "%s: pixel %zu: float best %d, double best %d (%g vs %g)\n",
				        label, i, e->best[i], r.best, r.d2_best, r.d2_second);
		}
#undef TOL
	}
	outputs_free(&ref[0]);
	outputs_free(&ref[1]);
	outputs_free(&ref2);
	outputs_free(&aut);
}

/* Near FLT_MAX: readings whose channels are finite but whose sum overflows (refused
 * by the reference) and readings just below, with a covariance large enough that the
 * whitened reading and the distances stay finite, so that only the refusal itself
 * (not a NaN the arithmetic makes anyway) tells the two apart. */
static void check_overflow(const int have[4], tally *t)
{
	kg_cs_model *m = model_alloc(2, 3, 0.3, 1.0);
	if (!m) {
		CHECK(0, "out of memory");
		return;
	}
	for (int j = 0; j < 2; j++)
		for (int k = 0; k < 3; k++) {
			float *mu = m->muf + 3 * (size_t)(j * 3 + k);
			mu[0] = 2e38f;
			mu[1] = (j ? 1.6e38f : 2e38f) * (1 - 0.05f * (float)k);
			mu[2] = 2e35f;
		}
	for (int i = 0; i < 18; i++)
		m->mu[i] = m->muf[i];
	CHECK(kg_cs_model_products(m) == 0, "out of memory");
	pixels p = {0};
	fx_rng r = {7};
	if (make_pixels(&r, m, 1, 24, 0, &p) == 0) {
		for (size_t i = 0; i < p.n; i++) {
			/* two in three sum past FLT_MAX (3.4e38), the rest to about half of it */
			float a = (0.9f + 0.004f * (float)i) * (i % 3 ? 1.0f : 0.5f);
			float *x = p.x + 3 * i, *c = p.cov + 6 * i;
			x[0] = 2e38f * a;
			x[1] = 1.9e38f * a;
			x[2] = 2e35f * a;
			c[0] = c[3] = c[5] = 3e38f;
			c[1] = c[2] = c[4] = 1e37f;
			p.clean[i] = 0;
		}
		check_block(m, &p, have, t, "sums past FLT_MAX");
	}
	pixels_free(&p);
	kg_cs_model_free(&m);
}

/* The library's materials under Gaussian sensitivities (600, 540, 450 nm) weighting a
 * flat light, the perfect diffuser's brightest channel at 0.9. */
static kg_cs_model *library_model(kg_material_library **lib, kg_err *err)
{
	double F[3 * KG_NBANDS];
	if (fx_library_camera(lib, F, err))
		return NULL;
	int n = kg_material_library_count(*lib);
	const kg_material *mats[KG_EST_MAX_MATERIALS];
	for (int j = 0; j < n; j++)
		mats[j] = kg_material_library_get(*lib, j);
	kg_cs_model *m = NULL;
	kg_cs_model_new(F, mats, n, 0, 70, 5, 0.3, 1.0, &m, err);
	return m;
}

int main(void)
{
	outputs none = {0};
	kg_cs_block empty = {none.best, NULL, NULL, NULL, NULL, NULL};
	kg_cs_model *m1 = model_alloc(1, 1, 0.5, 1);
	CHECK(m1 != NULL, "out of memory");
	if (!m1)
		return kg_test_done("estimate-camspace-block");
	CHECK(kg_cs_model_products(m1) == 0, "out of memory");
	int have[4] = {0, 1, 0, 0};
	for (int isa = KG_EST_ISA_AVX2; isa <= KG_EST_ISA_AVX512; isa++) {
		int probe = kg_cs_match_block_method(m1, NULL, NULL, 0, &empty, KG_CS_EXACT,
		                                     (kg_est_isa)isa);
		have[isa] = probe == 0;
		CHECK(probe == 0 || probe == KG_ENOTSUP, "%s asked for: %d", isa_label[isa], probe);
		CHECK(kg_cs_match_block_method(m1, NULL, NULL, 0, &empty, KG_CS_QUADRATIC,
		                               (kg_est_isa)isa) == probe, "%s: both methods alike",
		      isa_label[isa]);
		if (!have[isa])
			printf("SKIP (part): this CPU has no %s; its kernels are not compared\n",
			       isa_label[isa]);
	}
	CHECK(kg_cs_match_block_isa(m1, NULL, NULL, 0, &empty, (kg_est_isa)7) == KG_EINVAL,
	      "an isa out of range is refused");
	CHECK(kg_cs_match_block_method(m1, NULL, NULL, 0, &empty, (kg_cs_method)2, KG_EST_ISA_C) ==
	      KG_EINVAL, "a method out of range is refused");
	free(m1->ppf);
	m1->ppf = NULL;
	CHECK(kg_cs_match_block_method(m1, NULL, NULL, 0, &empty, KG_CS_QUADRATIC, KG_EST_ISA_C) ==
	      KG_EINVAL, "the quadratic method without the products is refused");
	kg_cs_model_free(&m1);
	/* every component 0 in one prediction: nothing to scale the predictions by */
	m1 = model_alloc(1, 3, 0.5, 1.0);
	CHECK(m1 != NULL, "out of memory");
	if (m1) {
		static const float unscalable[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
		memcpy(m1->muf, unscalable, sizeof(unscalable));
		CHECK(kg_cs_model_products(m1) == 0 && m1->ppf == NULL,
		      "a model with each component 0 in one prediction has no products");
		CHECK(kg_cs_match_block_method(m1, NULL, NULL, 0, &empty, KG_CS_QUADRATIC,
		                               KG_EST_ISA_C) == KG_EINVAL,
		      "and the quadratic method is refused for it");
	}
	kg_cs_model_free(&m1);

	fx_rng r = {20261202};
	int ppc_seen[3] = {0};
	static const double scales[] = {1, 1, 1, 1e-15, 1e15, 1e-19, 1e19, 1e25};
	static const size_t sizes[] = {0, 1, 7, 8, 9, 15, 16, 17, 31, 32, 33, 100, 1027};
	tally t = {0};
	for (int trial = 0; trial < 156; trial++) {
		double scale = scales[trial % 8];
		kg_cs_model *m = random_model(&r, scale);
		CHECK(m != NULL, "out of memory");
		if (!m)
			break;
		CHECK(m->ppf && m->ppc >= 0 && m->ppc < 3, "trial %d: the model has products", trial);
		if (m->ppf && m->ppc >= 0 && m->ppc < 3)
			ppc_seen[m->ppc]++;
		size_t n = sizes[(size_t)trial % 13];
		pixels p = {0};
		char label[64];
		snprintf(label, sizeof(label), "trial %d (scale %g, %d x %d, %zu pixels)", trial, scale,
		         m->n, m->nangles, n);
		if (make_pixels(&r, m, scale, n, trial % 3 != 0, &p) == 0)
			check_block(m, &p, have, &t, label);
		else
			CHECK(0, "out of memory");
		pixels_free(&p);
		kg_cs_model_free(&m);
	}

	/* the kernels order the per-pixel terms for each component the predictions are
	 * scaled by: each order is compared */
	printf("models scaled by component 0, 1, 2: %d, %d, %d\n", ppc_seen[0], ppc_seen[1],
	       ppc_seen[2]);
	CHECK(ppc_seen[0] > 0 && ppc_seen[1] > 0 && ppc_seen[2] > 0,
	      "models scaled by each component: %d, %d, %d", ppc_seen[0], ppc_seen[1], ppc_seen[2]);

	check_overflow(have, &t);

	/* the library at realistic noise */
	kg_err err = {{0}};
	kg_material_library *lib = NULL;
	kg_cs_model *m = library_model(&lib, &err);
	CHECK(m != NULL, "library model: %s", err.msg);
	if (m) {
		CHECK(m->n == 10 && m->nangles == 15, "10 materials at 15 angles, got %d x %d", m->n,
		      m->nangles);
		pixels p = {0};
		if (make_pixels(&r, m, 1, 20003, 0, &p) == 0)
			check_block(m, &p, have, &t, "library");
		pixels_free(&p);
	}
	kg_cs_model_free(&m);
	kg_material_library_free(&lib);

	printf("%ld pixels: %ld not matched, %ld matched with NaN outputs, %ld at the low and %ld "
	       "at the high intensity bound\n", t.pixels, t.nomatch, t.nan_valid, t.at_lo, t.at_hi);
	for (int me = 0; me < 2; me++)
		printf("%s: C and the vector kernels bit-identical in %ld of %ld blocks\n",
		       method_name[me], t.identical_blocks[me], t.blocks[me]);
	printf("quadratic against exact: %ld pixels, labels the same in %ld, every distance the "
	       "same in %ld; %ld distances below the exact, %ld above by more than the rounding "
	       "(at most %.3f of it), %ld labels different without a tie\n", t.quad_compared,
	       t.quad_labels_same, t.quad_all_same, t.quad_below, t.quad_above, t.quad_worst,
	       t.quad_tie_wrong);
	printf("against the double matcher: %ld pixels; largest relative distance error %.2g "
	       "(%.2g where d > 1e-4 |y|^2), at most %.2f of the tolerance; best material "
	       "checked on %ld, %ld wrong; %ld with distances out of tolerance\n",
	       t.compared, t.max_rel, t.max_rel_fit, t.worst, t.best_checked, t.best_wrong,
	       t.dist_wrong);
	CHECK(t.nomatch > 0 && t.nan_valid > 0 && t.at_lo > 0 && t.at_hi > 0,
	      "the hard cases are covered");
	CHECK(t.best_wrong == 0, "%ld pixels with a different best material", t.best_wrong);
	CHECK(t.dist_wrong == 0, "%ld pixels with distances out of tolerance", t.dist_wrong);
	CHECK(t.compared > 10000, "%ld pixels compared with the double matcher", t.compared);
	CHECK(t.quad_below == 0, "%ld quadratic distances below the exact method's", t.quad_below);
	CHECK(t.quad_above == 0, "%ld quadratic distances above the exact method's by more than "
	      "the rounding", t.quad_above);
	CHECK(t.quad_tie_wrong == 0, "%ld labels different where the exact method has no tie",
	      t.quad_tie_wrong);
	for (int me = 0; me < 2; me++)
		CHECK(t.identical_blocks[me] == t.blocks[me], "%s: %ld of %ld blocks differ",
		      method_name[me], t.blocks[me] - t.identical_blocks[me], t.blocks[me]);
	return kg_test_done("estimate-camspace-block");
}
