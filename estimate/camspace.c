/* Camera-space material matching with a noise model.
 *
 * Each declared material's reading is predicted in the reference camera's space,
 * mu(m, theta) = F R_m(theta), F the reference camera's spectral response (3 x 61,
 * calib's kg_response) and R_m the material's reflectance at incidence theta (optics:
 * the Fresnel colour shift of the paper's Fig. 7), on a grid of angles. A pixel x (the
 * site reading mapped through M2) with covariance C is matched over the materials,
 * the angles and an intensity a in [lo, hi] (the unknown geometry scales the whole
 * reading): with C = L L^T, y = L^-1 x and v = L^-1 mu, the noise-weighted
 * (Mahalanobis) distance is
 *   d2(m) = min over theta, a of |y - a v|^2,  a = clamp(v.y / v.v, lo, hi)
 * (a quadratic in a, so the clamped minimiser is exact). The material of least d2 is
 * the label; with equal priors and the profile likelihood exp(-d2 / 2), its posterior
 * is 1 / sum_m exp(-(d2(m) - d2(best)) / 2). */
#include <stdatomic.h>
#include <stdlib.h>

#include "est_private.h"

void kg_cs_model_free(kg_cs_model **pm)
{
	if (!pm || !*pm)
		return;
	free((*pm)->names);
	free((*pm)->angle_deg);
	free((*pm)->mu);
	free((*pm)->muf);
	free((*pm)->ppf);
	free((*pm)->anglef);
	free((*pm)->templated);
	free(*pm);
	*pm = NULL;
}

int kg_cs_model_new(const double *F, const kg_material *const *mats, int n, double a0,
                    double a1, double step, double lo, double hi, kg_cs_model **out,
                    kg_err *err)
{
	kg_check_arg(F && mats && out, err);
	*out = NULL;
	if (n < 1 || n > KG_EST_MAX_MATERIALS)
		return kg_fail(err, KG_EINVAL, "camera-space model: %d materials: expected 1 to %d",
		               n, KG_EST_MAX_MATERIALS);
	if (!(a0 >= 0 && a1 >= a0 && a1 < 90 && step > 0))
		return kg_fail(err, KG_EINVAL, "camera-space model: angles %g to %g every %g degrees: "
		               "expected 0 <= from <= to < 90 and a positive step", a0, a1, step);
	if (!(lo > 0 && hi >= lo && isfinite(hi)))
		return kg_fail(err, KG_EINVAL, "camera-space model: intensity %g to %g: expected "
		               "0 < low <= high", lo, hi);
	int na = (int)floor((a1 - a0) / step + 1e-9) + 1;
	kg_cs_model *m = calloc(1, sizeof(*m));
	if (m) {
		m->names = calloc((size_t)n, sizeof(*m->names));
		m->angle_deg = malloc(sizeof(double) * (size_t)na);
		m->mu = malloc(sizeof(double) * 3 * (size_t)n * (size_t)na);
		m->muf = malloc(sizeof(float) * 3 * (size_t)n * (size_t)na);
		m->anglef = malloc(sizeof(float) * (size_t)na);
		m->templated = calloc((size_t)n, 1);
	}
	if (!m || !m->names || !m->angle_deg || !m->mu || !m->muf || !m->anglef ||
	    !m->templated) {
		kg_cs_model_free(&m);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	m->n = n;
	m->nangles = na;
	m->lo = lo;
	m->hi = hi;
	int ret = 0;
	for (int k = 0; k < na; k++)
		m->angle_deg[k] = a0 + step * k;
	for (int j = 0; j < n && !ret; j++) {
		snprintf(m->names[j], sizeof(m->names[j]), "%s", mats[j]->name);
		const kg_material_template *t = &mats[j]->tmpl;
		if (t->n > 0) {
			/* the coupon's readings, linear between its views' angles, held beyond */
			m->templated[j] = 1;
			for (int k = 0; k < na; k++) {
				double th = m->angle_deg[k], *mu = m->mu + 3 * ((size_t)j * na + k);
				int v = 0;
				while (v + 1 < t->n && t->angle_deg[v + 1] <= th)
					v++;
				double f = 0;
				if (v + 1 < t->n && th > t->angle_deg[v])
					f = (th - t->angle_deg[v]) / (t->angle_deg[v + 1] - t->angle_deg[v]);
				for (int c = 0; c < 3; c++)
					mu[c] = (1 - f) * t->mean[v][c] + (f > 0 ? f * t->mean[v + 1][c] : 0);
			}
			continue;
		}
		for (int k = 0; k < na && !ret; k++) {
			kg_spectrum r;
			if ((ret = kg_material_reflectance(mats[j], m->angle_deg[k] * M_PI / 180.0, &r,
			                                   err)))
				break;
			double *mu = m->mu + 3 * ((size_t)j * na + k);
			for (int c = 0; c < 3; c++) {
				double s = 0;
				for (int l = 0; l < KG_NBANDS; l++)
					s += F[c * KG_NBANDS + l] * r.v[l];
				mu[c] = s;
			}
		}
	}
	if (ret) {
		kg_cs_model_free(&m);
		return ret;
	}
	for (size_t i = 0; i < 3 * (size_t)n * (size_t)na; i++)
		m->muf[i] = (float)m->mu[i];
	for (int k = 0; k < na; k++)
		m->anglef[k] = (float)m->angle_deg[k];
	if (kg_cs_model_products(m)) {
		kg_cs_model_free(&m);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	*out = m;
	return 0;
}

static int black(const float *p)
{
	return p[0] == 0.0f && p[1] == 0.0f && p[2] == 0.0f;
}

/* The component a model's predictions are scaled by for KG_CS_QUADRATIC: the one whose
 * least magnitude over the predictions other than black (0, 0, 0) is the largest; -1
 * where every component is 0 or not finite in one of them. */
static int products_component(const kg_cs_model *m, size_t nc)
{
	int c = -1;
	double best = 0;
	for (int a = 0; a < 3; a++) {
		double least = INFINITY;
		for (size_t k = 0; k < nc; k++) {
			double v = fabs((double)m->muf[3 * k + (size_t)a]);
			if (!black(m->muf + 3 * k))
				least = !isfinite(v) ? 0 : v < least ? v : least;
		}
		if (least > best)
			best = least, c = a;
	}
	return c;
}

int kg_cs_model_products(kg_cs_model *m)
{
	size_t nc = (size_t)m->n * (size_t)m->nangles;
	free(m->ppf);
	m->ppf = NULL;
	int c = products_component(m, nc);
	if (c < 0)
		return 0; /* the quadratic method is refused */
	float *pp = calloc(KG_CS_PP * (nc ? nc : 1), sizeof(float));
	if (!pp)
		return KG_ENOMEM;
	const int i = c == 0 ? 1 : 0, j = c == 2 ? 1 : 2;
	m->ppf = pp;
	m->ppc = c;
	for (size_t k = 0; k < nc; k++, pp += KG_CS_PP) {
		/* black: all zero, so vv = Q_cc, vy = b_c and alpha is clamped to 0, s = 0 as
		 * for any intensity of a zero prediction */
		if (black(m->muf + 3 * k))
			continue;
		const double w = m->muf[3 * k + (size_t)c];
		const double u = m->muf[3 * k + (size_t)i] / w, v = m->muf[3 * k + (size_t)j] / w;
		const double lo = m->lo * w, hi = m->hi * w;
		pp[0] = (float)(u * u);
		pp[1] = (float)(v * v);
		pp[2] = (float)(2 * u * v);
		pp[3] = (float)(2 * u);
		pp[4] = (float)(2 * v);
		pp[5] = (float)u;
		pp[6] = (float)v;
		pp[7] = (float)(w > 0 ? lo : hi);
		pp[8] = (float)(w > 0 ? hi : lo);
	}
	return 0;
}

int kg_cs_match(const kg_cs_model *m, const double x[3], const double cov[9],
                kg_cs_result *out)
{
	double L[9];
	if (!est_chol3(cov, L) || !isfinite(x[0] + x[1] + x[2]))
		return KG_EINVAL;
	double y[3];
	est_forward3(L, x, y);
	double best = INFINITY, second = INFINITY, sum = 0;
	out->best = -1;
	for (int j = 0; j < m->n; j++) {
		double dj = INFINITY, aj = NAN, thj = NAN;
		for (int k = 0; k < m->nangles; k++) {
			double v[3];
			est_forward3(L, m->mu + 3 * ((size_t)j * m->nangles + k), v);
			double vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
			double a = vv > 0 ? (v[0] * y[0] + v[1] * y[1] + v[2] * y[2]) / vv : m->lo;
			a = a < m->lo ? m->lo : a > m->hi ? m->hi : a;
			double e0 = y[0] - a * v[0], e1 = y[1] - a * v[1], e2 = y[2] - a * v[2];
			double d = e0 * e0 + e1 * e1 + e2 * e2;
			if (d < dj) {
				dj = d;
				aj = a;
				thj = m->angle_deg[k];
			}
		}
		if (dj < best) {
			second = best;
			best = dj;
			out->best = j;
			out->scale = aj;
			out->angle_deg = thj;
		} else if (dj < second) {
			second = dj;
		}
		out->d2_each[j] = dj;
	}
	for (int j = 0; j < m->n; j++)
		sum += exp(-0.5 * (out->d2_each[j] - best));
	out->d2_best = best;
	out->d2_second = second;
	out->posterior = 1.0 / sum;
	return 0;
}

/* ---- blocks of pixels in float -------------------------------------------------------
 *
 * Two methods, each a plain C reference here and vector kernels that repeat exactly
 * its operations in its order, lane by lane (camspace_avx2.c, camspace_avx512.c):
 *
 * KG_CS_EXACT: every candidate (material, angle) through the pixel's Cholesky factor
 * L, d = |y - a v|^2 with v = L^-1 mu, y = L^-1 x, a = clamp(v.y / v.v, lo, hi).
 * About 40 operations per candidate, none fused.
 *
 * KG_CS_QUADRATIC: the same distance is |y|^2 + a (a p^T Q p - 2 p^T b), Q = C^-1 =
 * L^-T L^-1 (6 numbers per pixel), b = Q x, p the candidate's prediction. Each
 * prediction is stored scaled by one of its components, p = w (u, v, 1) (the
 * component nonzero in every prediction, kg_cs_model_products), with the products
 * u^2, v^2, 2uv, 2u, 2v and the intensity bounds times w: p^T Q p / w^2 is then five
 * multiply-adds from Q's constant term, p.b / w two, and the whole candidate 9
 * multiplies and multiply-adds, a division and 6 other operations. That form cancels: its
 * rounding is some eps |y|^2 (|y|^2 the whitened reading's length squared, 10^4 and
 * more at a camera's noise) where the exact form's is some eps |y| sqrt(d). So it only
 * chooses each material's angle, and that one candidate is then computed by
 * KG_CS_EXACT's operations: every output a material gets is bit for bit the exact
 * method's value for that material at that angle. The two differ only where another
 * of the material's angles is within the form's rounding of the best (the exact
 * method's minimum over the angles is then a hair lower); the label differs only where
 * two materials are that close too. */

/* A pixel's Cholesky factor (of cov: c00 c01 c02 c11 c12 c22), reciprocals of its
 * diagonal and whitened reading; ok is 0 where the reference refuses the pixel. */
typedef struct cs_px {
	float l3, l6, l7, i0, i4, i8, y0, y1, y2;
	int ok;
} cs_px;

static cs_px px_factor(const float *x, const float *c)
{
	cs_px p;
	float l0 = sqrtf(c[0]);
	p.l3 = c[1] / l0;
	p.l6 = c[2] / l0;
	float l4 = sqrtf(c[3] - p.l3 * p.l3);
	p.l7 = (c[4] - p.l6 * p.l3) / l4;
	float l8 = sqrtf(c[5] - p.l6 * p.l6 - p.l7 * p.l7);
	p.ok = l0 > 0.0f && l4 > 0.0f && l8 > 0.0f && isfinite(x[0] + x[1] + x[2]);
	p.i0 = 1.0f / l0;
	p.i4 = 1.0f / l4;
	p.i8 = 1.0f / l8;
	p.y0 = x[0] * p.i0;
	p.y1 = (x[1] - p.l3 * p.y0) * p.i4;
	p.y2 = (x[2] - p.l6 * p.y0 - p.l7 * p.y1) * p.i8;
	return p;
}

/* KG_CS_EXACT's candidate: the squared distance, the intensity in *a. */
static float exact_candidate(const cs_px *p, const float *mu, float lo, float hi, float *a)
{
	float v0 = mu[0] * p->i0;
	float v1 = (mu[1] - p->l3 * v0) * p->i4;
	float v2 = (mu[2] - p->l6 * v0 - p->l7 * v1) * p->i8;
	float vv = v0 * v0 + v1 * v1 + v2 * v2;
	float vy = v0 * p->y0 + v1 * p->y1 + v2 * p->y2;
	float s = vy / vv;
	s = s > lo ? s : lo;
	s = s < hi ? s : hi;
	float e0 = p->y0 - s * v0, e1 = p->y1 - s * v1, e2 = p->y2 - s * v2;
	*a = s;
	return e0 * e0 + e1 * e1 + e2 * e2;
}

/* The running results of one pixel over the materials. */
typedef struct cs_fold {
	float best, second, a, t;
	int j;
} cs_fold;

static void fold_material(cs_fold *f, int j, float dj, float aj, float tj)
{
	if (dj < f->best) {
		f->second = f->best;
		f->best = dj;
		f->j = j;
		f->a = aj;
		f->t = tj;
	} else if (dj < f->second) {
		f->second = dj;
	}
}

static void store_pixel(const kg_cs_model *m, const cs_px *p, const cs_fold *f,
                        const kg_cs_block *out, size_t i)
{
	out->best[i] = p->ok ? (uint8_t)f->j : KG_CS_NO_MATCH;
	if (out->d2best)
		out->d2best[i] = p->ok ? f->best : NAN;
	if (out->d2second)
		out->d2second[i] = p->ok ? f->second : NAN;
	if (out->angle_deg)
		out->angle_deg[i] = p->ok ? f->t : NAN;
	if (out->scale)
		out->scale[i] = p->ok ? f->a : NAN;
	if (out->d2 && !p->ok)
		for (int j = 0; j < m->n; j++)
			out->d2[i * (size_t)m->n + j] = NAN;
}

/* KG_CS_EXACT on one pixel: the vector kernels repeat these operations in this order. */
static void match_one(const kg_cs_model *m, const float *x, const float *c, size_t i,
                      const kg_cs_block *out)
{
	const cs_px p = px_factor(x, c);
	cs_fold f = {INFINITY, INFINITY, NAN, NAN, 0};
	const float lo = (float)m->lo, hi = (float)m->hi;
	const float *mu = m->muf;
	for (int j = 0; j < m->n && p.ok; j++) {
		float dj = INFINITY, aj = NAN, tj = NAN;
		for (int k = 0; k < m->nangles; k++, mu += 3) {
			float a, d = exact_candidate(&p, mu, lo, hi, &a);
			if (d < dj) {
				dj = d;
				aj = a;
				tj = m->anglef[k];
			}
		}
		if (out->d2)
			out->d2[i * (size_t)m->n + j] = dj;
		fold_material(&f, j, dj, aj, tj);
	}
	store_pixel(m, &p, &f, out, i);
}

/* KG_CS_QUADRATIC's per-pixel terms for a model scaled by component c (ppc): with the
 * other two i < j, t[0 .. 5] = Q_cc, Q_ii, Q_jj, Q_ij, Q_ci, Q_cj and t[6 .. 8] = b_c,
 * b_i, b_j, so that for p = w (u, v, 1) (in the order i, j, c)
 *   p^T Q p / w^2 = Q_cc + Q_ii u^2 + Q_jj v^2 + Q_ij 2uv + Q_ci 2u + Q_cj 2v,
 *   p.b / w = b_c + b_i u + b_j v. */
int est_cs_quad_index(int c, int k)
{
	/* q: q00 q11 q22 q01 q02 q12; sym[a][b] its index of Q_ab */
	static const int sym[3][3] = {{0, 3, 4}, {3, 1, 5}, {4, 5, 2}};
	const int i = c == 0 ? 1 : 0, j = c == 2 ? 1 : 2;
	const int ra[6] = {c, i, j, i, c, c}, rb[6] = {c, i, j, j, i, j}, rv[3] = {c, i, j};
	return k < 6 ? sym[ra[k]][rb[k]] : rv[k - 6];
}

void est_cs_quad_terms(int c, const float q[6], const float b[3], float t[9])
{
	for (int k = 0; k < 9; k++)
		t[k] = (k < 6 ? q : b)[est_cs_quad_index(c, k)];
}

/* KG_CS_QUADRATIC on one pixel, multiply-adds fused (fmaf) where the vector kernels
 * fuse them. Q = W^T W with W = L^-1 (lower triangular, by forward substitution),
 * b = W^T y = Q x. Per candidate p = w (u, v, 1) (kg_cs_model.ppf; est_cs_quad_terms
 * orders Q and b to match): vv = p^T Q p / w^2 by five multiply-adds, vy = p.b / w by
 * two, and for alpha = a w, clamped to the bounds of [lo, hi] w, the distance less
 * |y|^2, s = a^2 p^T Q p - 2 a p.b = alpha ((alpha vv - vy) - vy), whose least value
 * picks the angle (the first of equals; NaN never). */
EST_REF_CLONES static void match_one_quad(const kg_cs_model *m, const float *x, const float *c,
                                          size_t i, const kg_cs_block *out)
{
	const cs_px p = px_factor(x, c);
	cs_fold f = {INFINITY, INFINITY, NAN, NAN, 0};
	const float lo = (float)m->lo, hi = (float)m->hi;
	const float w00 = p.i0, w11 = p.i4, w22 = p.i8;
	const float w10 = -p.l3 * w00 * p.i4;
	const float w21 = -p.l7 * w11 * p.i8;
	const float w20 = (-p.l6 * w00 - p.l7 * w10) * p.i8;
	const float q[6] = {fmaf(w20, w20, fmaf(w10, w10, w00 * w00)), fmaf(w21, w21, w11 * w11),
	                    w22 * w22, fmaf(w20, w21, w10 * w11), w20 * w22, w21 * w22};
	const float b[3] = {fmaf(w20, p.y2, fmaf(w10, p.y1, w00 * p.y0)),
	                    fmaf(w21, p.y2, w11 * p.y1), w22 * p.y2};
	float t[9];
	est_cs_quad_terms(m->ppc, q, b, t);
	const int na = m->nangles;
	for (int j = 0; j < m->n && p.ok; j++) {
		const float *pp = m->ppf + KG_CS_PP * (size_t)j * na;
		float sj = INFINITY;
		int kj = 0;
		for (int k = 0; k < na; k++, pp += KG_CS_PP) {
			float vv = fmaf(t[1], pp[0], t[0]);
			vv = fmaf(t[2], pp[1], vv);
			vv = fmaf(t[3], pp[2], vv);
			vv = fmaf(t[4], pp[3], vv);
			vv = fmaf(t[5], pp[4], vv);
			float vy = fmaf(t[7], pp[5], t[6]);
			vy = fmaf(t[8], pp[6], vy);
			float a = vy / vv;
			a = a > pp[7] ? a : pp[7];
			a = a < pp[8] ? a : pp[8];
			float s = a * (fmaf(a, vv, -vy) - vy);
			if (s < sj) {
				sj = s;
				kj = k;
			}
		}
		float a, d = exact_candidate(&p, m->muf + 3 * ((size_t)j * na + kj), lo, hi, &a);
		/* the exact method's update from its start (INFINITY, NaN, NaN) */
		float dj = d < INFINITY ? d : INFINITY;
		float aj = d < INFINITY ? a : NAN, tj = d < INFINITY ? m->anglef[kj] : NAN;
		if (out->d2)
			out->d2[i * (size_t)m->n + j] = dj;
		fold_material(&f, j, dj, aj, tj);
	}
	store_pixel(m, &p, &f, out, i);
}

/* CPUID once: a virtual machine may trap it. */
static int have_isa(kg_est_isa isa)
{
	static atomic_int known[2] = {-1, -1};
	int w = isa == KG_EST_ISA_AVX512;
	int v = atomic_load_explicit(&known[w], memory_order_relaxed);
	if (v < 0) {
		v = w ? est_have_avx512() : est_have_avx2();
		atomic_store_explicit(&known[w], v, memory_order_relaxed);
	}
	return v;
}

int kg_cs_match_block_method(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                             const kg_cs_block *out, kg_cs_method method, kg_est_isa isa)
{
	const int quad = method == KG_CS_QUADRATIC;
	if ((method != KG_CS_EXACT && !quad) || isa < KG_EST_ISA_AUTO || isa > KG_EST_ISA_AVX512 ||
	    (quad && !m->ppf))
		return KG_EINVAL;
	if (isa == KG_EST_ISA_AUTO)
		isa = have_isa(KG_EST_ISA_AVX512) ? KG_EST_ISA_AVX512
		      : have_isa(KG_EST_ISA_AVX2) ? KG_EST_ISA_AVX2
		                                  : KG_EST_ISA_C;
	else if (isa != KG_EST_ISA_C && !have_isa(isa))
		return KG_ENOTSUP;
	/* The vector kernels take whole vectors, the reference the rest. Past the 254
	 * materials a label can name, their labels would saturate where the reference's
	 * wrap: the reference takes such a model whole. */
	size_t done = 0;
	if (isa != KG_EST_ISA_C && m->n < KG_CS_NO_MATCH)
		done = isa == KG_EST_ISA_AVX512 ? (quad ? est_cs_quad_avx512 : est_cs_match_avx512)(
		                                      m, x, cov, n, out)
		       : quad ? est_cs_quad_avx2(m, x, cov, n, out)
		              : est_cs_match_avx2(m, x, cov, n, out);
	for (size_t i = done; i < n; i++)
		(quad ? match_one_quad : match_one)(m, x + 3 * i, cov + 6 * i, i, out);
	return 0;
}

int kg_cs_match_block_isa(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                          const kg_cs_block *out, kg_est_isa isa)
{
	return kg_cs_match_block_method(m, x, cov, n, out, KG_CS_EXACT, isa);
}

void kg_cs_match_block(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                       const kg_cs_block *out)
{
	/* with 8 lanes the quadratic method is no faster: its per-pixel terms and the
	 * gathers of the chosen candidates cost what it saves */
	int quad = m->ppf && have_isa(KG_EST_ISA_AVX512);
	kg_cs_match_block_method(m, x, cov, n, out, quad ? KG_CS_QUADRATIC : KG_CS_EXACT,
	                         KG_EST_ISA_AUTO);
}

/* ---- separability ------------------------------------------------------------------ */

/* The least |a u - b v| over b in [lo, hi] for a fixed a u (whitened vectors). */
static double ray_distance(const double au[3], const double v[3], double lo, double hi)
{
	double vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
	double b = vv > 0 ? (au[0] * v[0] + au[1] * v[1] + au[2] * v[2]) / vv : lo;
	b = b < lo ? lo : b > hi ? hi : b;
	double e0 = au[0] - b * v[0], e1 = au[1] - b * v[1], e2 = au[2] - b * v[2];
	return sqrt(e0 * e0 + e1 * e1 + e2 * e2);
}

/* The pixels a region must pool for a decision between two materials at whitened
 * distance d to err 1 % of the time: the pooled mean's distance grows as sqrt(N) d,
 * and two Gaussians at distance D are mistaken with probability Phi(-D / 2), so
 * N = (2 z / d)^2, z = 2.3263 the 99 % point of the standard normal. */
#define Z99 2.3263478740408408

double kg_cs_pixels_for(double d)
{
	return d > 0 ? ceil((2 * Z99 / d) * (2 * Z99 / d)) : INFINITY;
}

int kg_cs_separability_each(const kg_cs_model *m, const double *covs, double level, double *d,
                            kg_err *err)
{
	kg_check_arg(m && covs && d, err);
	if (!(level >= m->lo && level <= m->hi))
		return kg_fail(err, KG_EINVAL, "separability: level %g outside the intensity range "
		               "%g to %g", level, m->lo, m->hi);
	const int n = m->n, na = m->nangles;
	double *v = malloc(sizeof(double) * 3 * (size_t)n * (size_t)na);
	if (!v)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (int i = 0; i < n * n; i++)
		d[i] = i % (n + 1) == 0 ? 0.0 : INFINITY;
	/* d(i, j): over i's angles at the given level, whitened by that reading's own
	 * covariance, the nearest reading of j (any angle, any intensity); the pair's
	 * separability is the smaller of d(i, j) and d(j, i). */
	int ret = 0;
	for (int i = 0; i < n && !ret; i++)
		for (int k = 0; k < na && !ret; k++) {
			double L[9], u[3];
			if (!est_chol3(covs + 9 * ((size_t)i * na + k), L)) {
				ret = kg_fail(err, KG_EINVAL, "separability: the covariance of %s at %g degrees "
				              "is not positive definite", m->names[i], m->angle_deg[k]);
				break;
			}
			for (int q = 0; q < n * na; q++)
				est_forward3(L, m->mu + 3 * (size_t)q, v + 3 * (size_t)q);
			const double *w = v + 3 * ((size_t)i * na + k);
			for (int c = 0; c < 3; c++)
				u[c] = level * w[c];
			for (int j = 0; j < n; j++) {
				if (j == i)
					continue;
				double best = d[(size_t)i * n + j];
				for (int q = 0; q < na; q++)
					best = fmin(best, ray_distance(u, v + 3 * ((size_t)j * na + q), m->lo, m->hi));
				d[(size_t)i * n + j] = best;
			}
		}
	free(v);
	if (ret)
		return ret;
	for (int i = 0; i < n; i++)
		for (int j = i + 1; j < n; j++) {
			double s = fmin(d[(size_t)i * n + j], d[(size_t)j * n + i]);
			d[(size_t)i * n + j] = d[(size_t)j * n + i] = s;
		}
	return 0;
}

int kg_cs_separability(const kg_cs_model *m, const double cov[9], double level, double *d,
                       kg_err *err)
{
	kg_check_arg(m && cov && d, err);
	double L[9];
	if (!est_chol3(cov, L))
		return kg_fail(err, KG_EINVAL, "separability: the covariance is not positive definite");
	size_t nr = (size_t)m->n * (size_t)m->nangles;
	double *covs = malloc(sizeof(double) * 9 * nr);
	if (!covs)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (size_t r = 0; r < nr; r++)
		memcpy(covs + 9 * r, cov, 9 * sizeof(double));
	int ret = kg_cs_separability_each(m, covs, level, d, err);
	free(covs);
	return ret;
}

int kg_cs_merge_groups(const double *d, int n, double dmin, int *group)
{
	/* complete linkage: join the two classes whose farthest pair is the closest, while
	 * that pair is closer than dmin (a chain of close pairs does not join far ends) */
	for (int i = 0; i < n; i++)
		group[i] = i;
	for (;;) {
		double best = dmin;
		int ga = -1, gb = -1;
		for (int a = 0; a < n; a++) {
			if (group[a] != a)
				continue;
			for (int b = a + 1; b < n; b++) {
				if (group[b] != b)
					continue;
				double far = 0;
				for (int i = 0; i < n; i++)
					for (int j = 0; j < n; j++)
						if (group[i] == a && group[j] == b && d[(size_t)i * n + j] > far)
							far = d[(size_t)i * n + j];
				if (far < best) {
					best = far;
					ga = a;
					gb = b;
				}
			}
		}
		if (ga < 0)
			break;
		for (int i = 0; i < n; i++)
			if (group[i] == gb)
				group[i] = ga;
	}
	int ngroups = 0;
	for (int i = 0; i < n; i++)
		ngroups += group[i] == i;
	return ngroups;
}
