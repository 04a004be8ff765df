/* The material classifier: per-material constants of eq. 11 in the K-dim subspace.
 *
 * With an orthonormal basis B, write a material's signal C_j = B c_j + r_j (r_j
 * orthogonal to span B) and the estimate s = mean + B w = B v + m_perp, where
 * v = w + B^T mean and m_perp = (I - B B^T) mean (zero for uncentred PCA). Then
 *   plain:      ||C_j - s||^2 = ||c_j - v||^2 + ||r_j - m_perp||^2
 *   scale-free: ||a C_j - s||^2 = a^2 ||C_j||^2 - 2a (c_j.v + r_j.m_perp) + ||s||^2
 *               is smallest over a >= 0 at a = max(0, (c_j.v + g_j) / ||C_j||^2),
 *               g_j = r_j.m_perp, where it equals
 *               ||v - a c_j||^2 + ||m_perp||^2 - 2a g_j + a^2 ||r_j||^2.
 * Both are sums of squares of small differences, which avoids the cancellation of
 * the expanded form when a pixel is close to a material. */
#include <stdlib.h>
#include <string.h>

#include "est_private.h"

void kg_est_classifier_free(kg_est_classifier **pc)
{
	kg_est_classifier *c = pc ? *pc : NULL;
	if (!c)
		return;
	if (c->names)
		for (int j = 0; j < c->n; j++)
			free(c->names[j]);
	free(c->names);
	free(c->basis);
	free(c->mean);
	free(c->c);
	free(c->e);
	free(c->g);
	free(c->q);
	free(c->inv_norm);
	free(c);
	*pc = NULL;
}

/* B^T x (k values) and the residual x - B B^T x. */
static void project(const double *basis, int k, const double *x, double *coef, double *resid)
{
	for (int i = 0; i < k; i++) {
		double s = 0;
		for (int o = 0; o < KG_NBANDS; o++)
			s += basis[o * k + i] * x[o];
		coef[i] = s;
	}
	for (int o = 0; o < KG_NBANDS; o++) {
		double s = x[o];
		for (int i = 0; i < k; i++)
			s -= basis[o * k + i] * coef[i];
		resid[o] = s;
	}
}

static int all_finite_spectrum(const double *v)
{
	for (int o = 0; o < KG_NBANDS; o++)
		if (!isfinite(v[o]))
			return 0;
	return 1;
}

int kg_est_classifier_new(const kg_est_kernel *kern, const kg_est_material *mats, int n,
                          kg_est_distance distance, kg_est_classifier **out, kg_err *err)
{
	kg_check_arg(kern && mats && out, err);
	*out = NULL;
	int k = kern->k;
	if (k <= 0)
		return kg_fail(err, KG_EINVAL,
		               "classifier: the kernel has no basis: expected one with K weights");
	if (n < 1 || n > KG_EST_MAX_MATERIALS)
		return kg_fail(err, KG_EINVAL, "classifier: %d materials: expected 1..%d", n,
		               KG_EST_MAX_MATERIALS);
	if (distance != KG_EST_DIST_PLAIN && distance != KG_EST_DIST_SCALE_FREE)
		return kg_fail(err, KG_EINVAL, "classifier: distance %d: expected plain or scale-free",
		               (int)distance);
	for (int i = 0; i < k; i++)
		for (int l = 0; l < k; l++) {
			double s = 0;
			for (int o = 0; o < KG_NBANDS; o++)
				s += kern->basis[o * k + i] * kern->basis[o * k + l];
			if (fabs(s - (i == l)) > 1e-6)
				return kg_fail(err, KG_EINVAL,
				               "classifier: basis columns %d and %d: B^T B = %g: expected "
				               "orthonormal columns",
				               i + 1, l + 1, s);
		}
	for (int j = 0; j < n; j++)
		if (!mats[j].name || !mats[j].spectrum || !all_finite_spectrum(mats[j].spectrum))
			return kg_fail(err, KG_EINVAL,
			               "classifier: material %d (%s): expected a name and 61 finite values",
			               j + 1, mats[j].name ? mats[j].name : "unnamed");

	kg_est_classifier *c = calloc(1, sizeof(*c));
	if (!c)
		goto nomem;
	c->k = k;
	c->n = n;
	c->distance = distance;
	c->basis = malloc(sizeof(double) * KG_NBANDS * k);
	c->c = malloc(sizeof(double) * n * k);
	c->e = malloc(sizeof(double) * n);
	c->g = malloc(sizeof(double) * n);
	c->q = malloc(sizeof(double) * n);
	c->inv_norm = malloc(sizeof(double) * n);
	c->names = calloc(n, sizeof(char *));
	if (!c->basis || !c->c || !c->e || !c->g || !c->q || !c->inv_norm || !c->names)
		goto nomem;
	memcpy(c->basis, kern->basis, sizeof(double) * KG_NBANDS * k);
	double mperp[KG_NBANDS] = {0};
	if (kern->mean) {
		if (!(c->mean = malloc(sizeof(double) * KG_NBANDS)))
			goto nomem;
		memcpy(c->mean, kern->mean, sizeof(double) * KG_NBANDS);
		project(c->basis, k, c->mean, c->mpar, mperp);
	}
	c->h = 0;
	for (int o = 0; o < KG_NBANDS; o++)
		c->h += mperp[o] * mperp[o];
	for (int j = 0; j < n; j++) {
		double r[KG_NBANDS], norm = 0;
		project(c->basis, k, mats[j].spectrum, c->c + (size_t)j * k, r);
		c->e[j] = c->g[j] = c->q[j] = 0;
		for (int o = 0; o < KG_NBANDS; o++) {
			double dr = r[o] - mperp[o];
			c->e[j] += dr * dr;
			c->g[j] += r[o] * mperp[o];
			c->q[j] += r[o] * r[o];
			norm += mats[j].spectrum[o] * mats[j].spectrum[o];
		}
		c->inv_norm[j] = norm > 0 ? 1.0 / norm : 0.0;
		if (!(c->names[j] = strdup(mats[j].name)))
			goto nomem;
	}
	*out = c;
	return 0;
nomem:
	kg_est_classifier_free(&c);
	return kg_fail(err, KG_ENOMEM, "classifier: out of memory");
}

int kg_est_classifier_count(const kg_est_classifier *c) { return c->n; }

const char *kg_est_classifier_name(const kg_est_classifier *c, int j)
{
	return j >= 0 && j < c->n ? c->names[j] : NULL;
}

void kg_est_classifier_distances(const kg_est_classifier *c, const float *w, double *d)
{
	double v[KG_EST_MAX_K];
	est_weights_to_v(c, w, v);
	for (int j = 0; j < c->n; j++)
		d[j] = est_material_distance(c, j, v);
}

int kg_est_classifier_dof(const kg_est_classifier *c)
{
	if (c->distance == KG_EST_DIST_PLAIN)
		return c->k;
	return c->k > 1 ? c->k - 1 : 1;
}

/* The residual inside span B and the distance's part outside it, for material j. */
static double split_residual(const kg_est_classifier *c, int j, const double *v, double *r)
{
	const double *cj = c->c + (size_t)j * c->k;
	if (c->distance == KG_EST_DIST_PLAIN) {
		for (int i = 0; i < c->k; i++)
			r[i] = v[i] - cj[i];
		return c->e[j];
	}
	double p = c->g[j];
	for (int i = 0; i < c->k; i++)
		p += cj[i] * v[i];
	double a = p > 0.0 ? p * c->inv_norm[j] : 0.0;
	for (int i = 0; i < c->k; i++)
		r[i] = v[i] - a * cj[i];
	double outside = c->h + a * (a * c->q[j] - 2.0 * c->g[j]);
	return outside > 0.0 ? outside : 0.0;
}

double kg_est_classifier_chi2(const kg_est_classifier *c, int j, const float *w,
                              const double *sigma_w)
{
	const int k = c->k;
	double v[KG_EST_MAX_K], r[KG_EST_MAX_K], l[KG_EST_MAX_K * KG_EST_MAX_K];
	est_weights_to_v(c, w, v);
	double floor = split_residual(c, j, v, r) / k;
	/* Cholesky factor L of sigma_w + floor I (lower, row-major), then ||L^-1 r||^2. */
	for (int a = 0; a < k; a++)
		for (int b = 0; b <= a; b++) {
			double s = sigma_w[a * k + b] + (a == b ? floor : 0.0);
			for (int m = 0; m < b; m++)
				s -= l[a * k + m] * l[b * k + m];
			if (a == b) {
				if (!(s > 0.0)) {
					for (int i = 0; i < k; i++)
						if (r[i] != 0.0)
							return INFINITY;
					return 0.0;
				}
				l[a * k + a] = sqrt(s);
			} else {
				l[a * k + b] = s / l[b * k + b];
			}
		}
	double chi2 = 0.0, y[KG_EST_MAX_K];
	for (int a = 0; a < k; a++) {
		double s = r[a];
		for (int m = 0; m < a; m++)
			s -= l[a * k + m] * y[m];
		y[a] = s / l[a * k + a];
		chi2 += y[a] * y[a];
	}
	return chi2;
}

/* Regularised lower incomplete gamma P(s, x) by its series, which converges for every
 * x; enough terms for the x of a chi-square quantile (below a few thousand). */
static double gamma_p(double s, double x)
{
	if (x <= 0.0)
		return 0.0;
	double term = 1.0 / s, sum = term;
	for (int n = 1; n < 100000; n++) {
		term *= x / (s + n);
		sum += term;
		if (term < sum * 1e-17)
			break;
	}
	double p = exp(s * log(x) - x - lgamma(s)) * sum;
	return p < 1.0 ? p : 1.0;
}

double kg_chi2_quantile(double p, int dof)
{
	if (!(p > 0.0 && p < 1.0) || dof < 1 || dof > 1000)
		return NAN;
	double lo = 0.0, hi = dof + 10.0;
	while (gamma_p(0.5 * dof, 0.5 * hi) < p)
		hi *= 2.0;
	while (hi - lo > 1e-10 * hi) {
		double mid = 0.5 * (lo + hi);
		if (gamma_p(0.5 * dof, 0.5 * mid) < p)
			lo = mid;
		else
			hi = mid;
	}
	return 0.5 * (lo + hi);
}
