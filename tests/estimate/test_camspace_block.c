/* The camera-space block matcher (kg_cs_match_block, estimate/camspace.c and
 * camspace_avx2.c).
 *  - Bit identity: over random models (1 to 16 materials, 1 to 20 angles, materials
 *    that are black, negative, duplicated, the same at every angle or near FLT_MAX at
 *    one angle (infinite and NaN distances among finite ones), intensity ranges
 *    with lo = hi) at ordinary, tiny and huge scales, and random pixels with the hard
 *    cases sprinkled in (x NaN or infinite or summing past FLT_MAX; covariances zero,
 *    negative, indefinite, singular, NaN, infinite or subnormal; readings that clamp at
 *    lo and at hi; x = 0 and x = -mu), the reference (KG_EST_ISA_C) and the AVX2 kernel
 *    write the same bytes into every output, for block sizes that are and are not a
 *    multiple of 8, with every output and with only some of them. Both are run into
 *    buffers prefilled with different bytes, so every value is written. On a CPU
 *    without AVX2 that part is skipped with a message and KG_ENOTSUP is checked.
 *  - Against the double kg_cs_match, on the ordinary pixels (none of the hard cases,
 *    scales 1e-15 to 1e15): every material's distance within 1e-4 relative (plus
 *    the float rounding of whitening a reading of length |y|, 16 eps |y| (2 sqrt(d) +
 *    16 eps |y|), which only matters for near-perfect fits), and the same best material
 *    whenever the double best and second distances are more than 1e-3 relative (and
 *    twice the distance tolerance) apart.
 *  - The library's ten materials under a smooth synthetic response, realistic noise.
 */
#include <float.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "est_fixture.h"
#include "kg_estimate.h"
#include "kg_test.h"

static double gauss(fx_rng *r)
{
	double u = fx_uniform(r, 0x1p-53, 1), v = fx_uniform(r, 0, 1);
	return sqrt(-2 * log(u)) * cos(2 * M_PI * v);
}

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
		double C[9], z[3] = {gauss(r), gauss(r), gauss(r)};
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
	long blocks, identical_blocks, pixels, nomatch, nan_valid, at_lo, at_hi;
	long compared, best_checked, best_wrong, dist_wrong;
	double max_rel, max_rel_fit, worst;
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

/* Run every implementation over p and compare: only best and scale, then all outputs,
 * each time into fresh buffers filled with different bytes. */
static void check_block(const kg_cs_model *m, const pixels *p, int have_avx2, tally *t,
                        const char *label)
{
	outputs ref = {0}, ref2 = {0}, vec = {0}, aut = {0};
	int nm = m->n;
	for (int all = 0; all <= 1; all++) {
		outputs_free(&ref);
		outputs_free(&ref2);
		outputs_free(&vec);
		outputs_free(&aut);
		if (outputs_alloc(&ref, p->n, nm, 0xa5) || outputs_alloc(&ref2, p->n, nm, 0x5a) ||
		    outputs_alloc(&vec, p->n, nm, 0x5a) || outputs_alloc(&aut, p->n, nm, 0x3c)) {
			CHECK(0, "out of memory");
			break;
		}
		kg_cs_block b = block_of(&ref, all), b2 = block_of(&ref2, all);
		CHECK(kg_cs_match_block_isa(m, p->x, p->cov, p->n, &b, KG_EST_ISA_C) == 0, "C");
		CHECK(kg_cs_match_block_isa(m, p->x, p->cov, p->n, &b2, KG_EST_ISA_C) == 0, "C");
		const char *what = "";
		long at;
		if (all) {
			at = first_difference(&ref, &ref2, p->n, nm, &what);
			CHECK(at < 0, "%s: the reference leaves %s[%ld] unwritten", label, what, at);
		} else {
			CHECK(untouched(&ref, p->n, nm, 0xa5), "%s: the reference writes outputs not asked "
			      "for", label);
		}
		kg_cs_block ba = block_of(&aut, all);
		kg_cs_match_block(m, p->x, p->cov, p->n, &ba);
		if (have_avx2) {
			kg_cs_block bv = block_of(&vec, all);
			CHECK(kg_cs_match_block_isa(m, p->x, p->cov, p->n, &bv, KG_EST_ISA_AVX2) == 0,
			      "AVX2");
			t->blocks++;
			if (all) {
				at = first_difference(&ref, &vec, p->n, nm, &what);
			} else {
				CHECK(untouched(&vec, p->n, nm, 0x5a), "%s: AVX2 writes outputs not asked for",
				      label);
				outputs some = vec;
				some.d2best = ref.d2best;
				some.d2second = ref.d2second;
				some.angle = ref.angle;
				some.d2 = ref.d2;
				at = first_difference(&ref, &some, p->n, nm, &what);
			}
			t->identical_blocks += at < 0;
			if (at >= 0) {
				size_t i = strcmp(what, "d2") ? (size_t)at : (size_t)at / (size_t)nm;
				const float *x = p->x + 3 * i, *c = p->cov + 6 * i;
				CHECK(0, "%s (%s outputs): C and AVX2 differ at %s[%ld]; pixel %zu x %a %a %a "
				      "cov %a %a %a %a %a %a", label, all ? "all" : "some", what, at, i, x[0],
				      x[1], x[2], c[0], c[1], c[2], c[3], c[4], c[5]);
			}
		}
		if (all) {
			/* kg_cs_match_block is one of the two, which agree */
			at = first_difference(&ref, &aut, p->n, nm, &what);
			CHECK(at < 0, "%s: kg_cs_match_block differs from the reference at %s[%ld]", label,
			      what, at);
		}
	}
	/* coverage and the double matcher */
	const double eps = FLT_EPSILON;
	for (size_t i = 0; i < p->n; i++) {
		t->pixels++;
		if (ref.best[i] == KG_CS_NO_MATCH) {
			t->nomatch++;
			continue;
		}
		t->nan_valid += isnan(ref.d2best[i]) || isnan(ref.scale[i]);
		t->at_lo += ref.scale[i] == (float)m->lo;
		t->at_hi += ref.scale[i] == (float)m->hi && m->hi > m->lo;
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
			double df = ref.d2[i * (size_t)nm + j], dd = r.d2_each[j];
			if (!(fabs(df - dd) <= TOL(dd)))
				bad = 1;
			else
				t->worst = fmax(t->worst, fabs(df - dd) / TOL(dd));
			if (dd > 0)
				t->max_rel = fmax(t->max_rel, fabs(df - dd) / dd);
			if (dd > 1e-4 * ylen * ylen) /* not a near-perfect fit */
				t->max_rel_fit = fmax(t->max_rel_fit, fabs(df - dd) / dd);
		}
		bad |= !(fabs(ref.d2best[i] - r.d2_best) <= TOL(r.d2_best));
		bad |= !(fabs(ref.d2second[i] - r.d2_second) <= TOL(r.d2_second)) &&
		       !(isinf(r.d2_second) && isinf(ref.d2second[i]));
		if (bad && t->dist_wrong++ < 3)
			fprintf(stderr, "%s: pixel %zu: float distances %g %g, double %g %g (|y| %g)\n",
			        label, i, ref.d2best[i], ref.d2second[i], r.d2_best, r.d2_second, ylen);
		if (r.d2_second - r.d2_best > 1e-3 * r.d2_best + 2 * TOL(r.d2_second)) {
			t->best_checked++;
			if (ref.best[i] != r.best && t->best_wrong++ < 3)
				fprintf(stderr, "%s: pixel %zu: float best %d, double best %d (%g vs %g)\n",
				        label, i, ref.best[i], r.best, r.d2_best, r.d2_second);
		}
#undef TOL
	}
	outputs_free(&ref);
	outputs_free(&ref2);
	outputs_free(&vec);
	outputs_free(&aut);
}

/* Near FLT_MAX: readings whose channels are finite but whose sum overflows (refused
 * by the reference) and readings just below, with a covariance large enough that the
 * whitened reading and the distances stay finite, so that only the refusal itself
 * (not a NaN the arithmetic makes anyway) tells the two apart. */
static void check_overflow(int have_avx2, tally *t)
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
		check_block(m, &p, have_avx2, t, "sums past FLT_MAX");
	}
	pixels_free(&p);
	kg_cs_model_free(&m);
}

/* The library's materials under Gaussian sensitivities (600, 540, 450 nm) weighting a
 * flat light, the perfect diffuser's brightest channel at 0.9. */
static kg_cs_model *library_model(kg_material_library **lib, kg_err *err)
{
	char path[4096];
	snprintf(path, sizeof(path), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	if (kg_material_library_load(path, lib, err))
		return NULL;
	static const double peak[3] = {600, 540, 450}, width[3] = {30, 35, 25};
	double F[3 * KG_NBANDS], white = 0;
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
	int probe = kg_cs_match_block_isa(m1, NULL, NULL, 0, &empty, KG_EST_ISA_AVX2);
	int have_avx2 = probe == 0;
	CHECK(probe == 0 || probe == KG_ENOTSUP, "AVX2 asked for: %d", probe);
	CHECK(kg_cs_match_block_isa(m1, NULL, NULL, 0, &empty, (kg_est_isa)7) == KG_EINVAL,
	      "an isa out of range is refused");
	kg_cs_model_free(&m1);
	if (!have_avx2)
		printf("SKIP (part): this CPU has no AVX2; the AVX2 kernel is not compared, "
		       "only the reference against the double matcher\n");

	fx_rng r = {20261202};
	static const double scales[] = {1, 1, 1, 1e-15, 1e15, 1e-19, 1e19, 1e25};
	static const size_t sizes[] = {0, 1, 7, 8, 9, 15, 16, 17, 100, 1027};
	tally t = {0};
	for (int trial = 0; trial < 120; trial++) {
		double scale = scales[trial % 8];
		kg_cs_model *m = random_model(&r, scale);
		CHECK(m != NULL, "out of memory");
		if (!m)
			break;
		size_t n = sizes[(size_t)trial % 10];
		pixels p = {0};
		char label[64];
		snprintf(label, sizeof(label), "trial %d (scale %g, %d x %d, %zu pixels)", trial, scale,
		         m->n, m->nangles, n);
		if (make_pixels(&r, m, scale, n, trial % 3 != 0, &p) == 0)
			check_block(m, &p, have_avx2, &t, label);
		else
			CHECK(0, "out of memory");
		pixels_free(&p);
		kg_cs_model_free(&m);
	}

	check_overflow(have_avx2, &t);

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
			check_block(m, &p, have_avx2, &t, "library");
		pixels_free(&p);
	}
	kg_cs_model_free(&m);
	kg_material_library_free(&lib);

	printf("%ld pixels: %ld not matched, %ld matched with NaN outputs, %ld at the low and %ld "
	       "at the high intensity bound\n", t.pixels, t.nomatch, t.nan_valid, t.at_lo, t.at_hi);
	if (have_avx2)
		printf("C and AVX2 bit-identical in %ld of %ld blocks\n", t.identical_blocks, t.blocks);
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
	return kg_test_done("estimate-camspace-block");
}
