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
