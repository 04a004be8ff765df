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
	*out = m;
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

/* One pixel in float: the Cholesky factor of its covariance, the whitened reading, then
 * every material at every angle with the clamped intensity. The optimised kernel must
 * repeat exactly these operations in this order. */
static void match_one(const kg_cs_model *m, const float *x, const float *c, size_t i,
                      const kg_cs_block *out)
{
	float l0 = sqrtf(c[0]);
	float l3 = c[1] / l0, l6 = c[2] / l0;
	float l4 = sqrtf(c[3] - l3 * l3);
	float l7 = (c[4] - l6 * l3) / l4;
	float l8 = sqrtf(c[5] - l6 * l6 - l7 * l7);
	if (!(l0 > 0.0f && l4 > 0.0f && l8 > 0.0f) || !isfinite(x[0] + x[1] + x[2])) {
		out->best[i] = KG_CS_NO_MATCH;
		if (out->d2best)
			out->d2best[i] = NAN;
		if (out->d2second)
			out->d2second[i] = NAN;
		if (out->angle_deg)
			out->angle_deg[i] = NAN;
		if (out->scale)
			out->scale[i] = NAN;
		if (out->d2)
			for (int j = 0; j < m->n; j++)
				out->d2[i * (size_t)m->n + j] = NAN;
		return;
	}
	float i0 = 1.0f / l0, i4 = 1.0f / l4, i8 = 1.0f / l8;
	float y0 = x[0] * i0;
	float y1 = (x[1] - l3 * y0) * i4;
	float y2 = (x[2] - l6 * y0 - l7 * y1) * i8;
	const float lo = (float)m->lo, hi = (float)m->hi;
	float best = INFINITY, second = INFINITY, best_a = NAN, best_t = NAN;
	int bj = 0;
	const float *mu = m->muf;
	for (int j = 0; j < m->n; j++) {
		float dj = INFINITY, aj = NAN, tj = NAN;
		for (int k = 0; k < m->nangles; k++, mu += 3) {
			float v0 = mu[0] * i0;
			float v1 = (mu[1] - l3 * v0) * i4;
			float v2 = (mu[2] - l6 * v0 - l7 * v1) * i8;
			float vv = v0 * v0 + v1 * v1 + v2 * v2;
			float vy = v0 * y0 + v1 * y1 + v2 * y2;
			float a = vy / vv;
			a = a > lo ? a : lo;
			a = a < hi ? a : hi;
			float e0 = y0 - a * v0, e1 = y1 - a * v1, e2 = y2 - a * v2;
			float d = e0 * e0 + e1 * e1 + e2 * e2;
			if (d < dj) {
				dj = d;
				aj = a;
				tj = m->anglef[k];
			}
		}
		if (out->d2)
			out->d2[i * (size_t)m->n + j] = dj;
		if (dj < best) {
			second = best;
			best = dj;
			bj = j;
			best_a = aj;
			best_t = tj;
		} else if (dj < second) {
			second = dj;
		}
	}
	out->best[i] = (uint8_t)bj;
	if (out->d2best)
		out->d2best[i] = best;
	if (out->d2second)
		out->d2second[i] = second;
	if (out->angle_deg)
		out->angle_deg[i] = best_t;
	if (out->scale)
		out->scale[i] = best_a;
}

/* est_have_avx2 once: it asks CPUID, which a virtual machine may trap. */
static int have_avx2(void)
{
	static atomic_int known = -1;
	int v = atomic_load_explicit(&known, memory_order_relaxed);
	if (v < 0) {
		v = est_have_avx2();
		atomic_store_explicit(&known, v, memory_order_relaxed);
	}
	return v;
}

int kg_cs_match_block_isa(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                          const kg_cs_block *out, kg_est_isa isa)
{
	if (isa != KG_EST_ISA_AUTO && isa != KG_EST_ISA_C && isa != KG_EST_ISA_AVX2)
		return KG_EINVAL;
	int avx2 = isa != KG_EST_ISA_C && have_avx2();
	if (isa == KG_EST_ISA_AVX2 && !avx2)
		return KG_ENOTSUP;
	/* The optimised kernel takes whole vectors of 8 pixels, the reference the rest. Past
	 * the 254 materials a label can name, its labels would saturate where the
	 * reference's wrap: the reference takes such a model whole. */
	size_t done = avx2 && m->n < KG_CS_NO_MATCH ? est_cs_match_avx2(m, x, cov, n, out) : 0;
	for (size_t i = done; i < n; i++)
		match_one(m, x + 3 * i, cov + 6 * i, i, out);
	return 0;
}

void kg_cs_match_block(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                       const kg_cs_block *out)
{
	kg_cs_match_block_isa(m, x, cov, n, out, KG_EST_ISA_AUTO);
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
