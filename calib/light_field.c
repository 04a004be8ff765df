/* The light over a chart, estimated from the chart itself, and removed from its
 * patch values (docs/chart-detect.md, "Uneven light").
 *
 * A patch is printed uniform, so what varies inside it is the light (lens
 * vignetting, a lamp's falloff). The sampler keeps the mean of r+g+b in each
 * quadrant of every sampled region; the log ratio of the right half to the left
 * half is the light's log gradient along u times the half-side, and the same for v.
 * Those 2 N gradients are fitted, by weighted least squares with Tukey's biweight
 * (glare, dirt and occlusion are outliers, not light), by the gradient of a smooth
 * field ln L = c1 u + c2 v + c3 u^2 + c4 u v + c5 v^2 (a plane with fewer than six
 * usable patches). For a quadratic the difference of the half-region means is
 * exactly the half-side times the gradient at the centre, so the integration is
 * exact for the model. L is normalised to average 1 over the patch centres, each
 * patch's values are divided by L at its centre, and the "non-uniform" flag is
 * judged on the quadrants after the field is removed. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib_private.h"

#define MAX_DEGREE 4
#define NT 14 /* terms of a degree-4 log field without the constant */

/* Gradient noise floor: print texture, light structure finer than the model. */
#define GRAD_FLOOR 0.002

/* Term k is u^ex[k][0] v^ex[k][1], by total degree 1, 2, 3, 4. */
static const int ex[NT][2] = {{1, 0}, {0, 1}, {2, 0}, {1, 1}, {0, 2}, {3, 0}, {2, 1},
                              {1, 2}, {0, 3}, {4, 0}, {3, 1}, {2, 2}, {1, 3}, {0, 4}};

static int terms_of_degree(int d)
{
	return (d + 1) * (d + 2) / 2 - 1;
}

static void basis(double u, double v, double phi[NT])
{
	for (int k = 0; k < NT; k++)
		phi[k] = pow(u, ex[k][0]) * pow(v, ex[k][1]);
}

/* The mean of x^i over [a, b]. */
static double mean_pow(int i, double a, double b)
{
	return (pow(b, i + 1) - pow(a, i + 1)) / ((i + 1) * (b - a));
}

double kg_chart_light_log(const kg_chart_light *f, double x_mm, double y_mm)
{
	if (!f || !f->fitted)
		return 0;
	double u = (x_mm - f->origin_mm[0]) / f->scale_mm, v = (y_mm - f->origin_mm[1]) / f->scale_mm;
	double phi[NT], s = f->coef[0];
	basis(u, v, phi);
	for (int k = 0; k < NT; k++)
		s += f->coef[k + 1] * phi[k];
	return s;
}

int calib_solve_normal(double *N, int stride, double *b, int m, double *c)
{
#define AT(i, j) N[(i) * stride + (j)]
	double scale = 0;
	for (int i = 0; i < m; i++)
		scale = fmax(scale, fabs(AT(i, i)));
	if (!(scale > 0))
		return 1;
	for (int k = 0; k < m; k++) {
		int piv = k;
		for (int i = k + 1; i < m; i++)
			if (fabs(AT(i, k)) > fabs(AT(piv, k)))
				piv = i;
		if (!(fabs(AT(piv, k)) > 1e-10 * scale))
			return 1;
		if (piv != k) {
			for (int j = 0; j < m; j++) {
				double t = AT(k, j);
				AT(k, j) = AT(piv, j);
				AT(piv, j) = t;
			}
			double t = b[k];
			b[k] = b[piv];
			b[piv] = t;
		}
		for (int i = k + 1; i < m; i++) {
			double f = AT(i, k) / AT(k, k);
			for (int j = k; j < m; j++)
				AT(i, j) -= f * AT(k, j);
			b[i] -= f * b[k];
		}
	}
	for (int i = m - 1; i >= 0; i--) {
		double s = b[i];
		for (int j = i + 1; j < m; j++)
			s -= AT(i, j) * c[j];
		c[i] = s / AT(i, i);
	}
	return 0;
#undef AT
}

typedef struct obs {
	double a[NT]; /* d(observation)/d(coef) */
	double y, sigma, w;
} obs;

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

/* Weighted fit of the first m terms with Tukey's biweight; 1 when singular. */
static int robust_fit(obs *o, int n, int m, double c[NT], double *rms)
{
	double *z = malloc((size_t)(n ? n : 1) * sizeof(*z));
	if (!z)
		return 1;
	for (int i = 0; i < n; i++)
		o[i].w = 1;
	int ret = 0;
	for (int iter = 0; iter < 8 && !ret; iter++) {
		double N[NT][NT] = {{0}}, b[NT] = {0};
		for (int i = 0; i < n; i++) {
			double w = o[i].w / (o[i].sigma * o[i].sigma);
			for (int j = 0; j < m; j++) {
				b[j] += w * o[i].a[j] * o[i].y;
				for (int k = 0; k < m; k++)
					N[j][k] += w * o[i].a[j] * o[i].a[k];
			}
		}
		for (int j = 0; j < NT; j++)
			c[j] = 0;
		if ((ret = calib_solve_normal(&N[0][0], NT, b, m, c)))
			break;
		for (int i = 0; i < n; i++) {
			double r = o[i].y;
			for (int j = 0; j < m; j++)
				r -= o[i].a[j] * c[j];
			z[i] = fabs(r) / o[i].sigma;
		}
		double *sorted = malloc((size_t)(n ? n : 1) * sizeof(*sorted));
		if (!sorted) {
			ret = 1;
			break;
		}
		memcpy(sorted, z, (size_t)n * sizeof(*z));
		qsort(sorted, (size_t)n, sizeof(*sorted), cmp_double);
		double s = fmax(1.0, 1.4826 * sorted[n / 2]);
		free(sorted);
		double sw = 0, swr = 0;
		for (int i = 0; i < n; i++) {
			double t = z[i] / (4.685 * s);
			o[i].w = t < 1 ? (1 - t * t) * (1 - t * t) : 0;
			sw += o[i].w;
			swr += o[i].w * z[i] * z[i];
		}
		*rms = sw > 0 ? sqrt(swr / sw) : NAN;
	}
	/* most gradients must agree with the field, or it is not the light */
	int kept = 0;
	for (int i = 0; i < n; i++)
		kept += o[i].w > 0;
	if (!ret && 2 * kept < n)
		ret = 1;
	free(z);
	return ret;
}

/* Remove "non-uniform (...)" from a patch's reasons. */
static void strip_nonuniform(char *w)
{
	char *at = strstr(w, "non-uniform (");
	if (!at)
		return;
	char *end = strstr(at, "; ");
	if (end) {
		memmove(at, end + 2, strlen(end + 2) + 1);
	} else {
		if (at >= w + 2 && at[-2] == ';')
			at -= 2;
		*at = '\0';
	}
}

enum { UNUSABLE = KG_CHART_FLAG_REJECTED | KG_CHART_FLAG_CLIPPED | KG_CHART_FLAG_OUT_OF_FRAME |
                  KG_CHART_FLAG_FEW_PIXELS | KG_CHART_FLAG_GLARE };

/* Quadrants differing by more than this are not light: a region across two patches
 * or an occluder (a field varying by the largest trusted amount changes by a few
 * per cent across a sampled region). */
#define MAX_GRADIENT_SPREAD 0.25

static int usable(const kg_chart_sample *p)
{
	if ((p->flags & UNUSABLE) || !(p->nonuniformity <= MAX_GRADIENT_SPREAD))
		return 0;
	for (int q = 0; q < 4; q++)
		if (!(isfinite(p->quadrant[q]) && p->quadrant[q] > 0))
			return 0;
	return p->pixels >= 8;
}

int calib_light_field_apply(kg_chart_result *r, const kg_chart_detect_options *opt,
                            kg_err *err)
{
	kg_chart_light *f = &r->light;
	memset(f, 0, sizeof(*f));
	int n = r->npatches;
	double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY, hmax = 0;
	int nused = 0;
	for (int i = 0; i < n; i++) {
		const kg_chart_sample *p = &r->patches[i];
		if (p->flags & KG_CHART_FLAG_REJECTED)
			continue;
		x0 = fmin(x0, p->centre_mm[0]);
		x1 = fmax(x1, p->centre_mm[0]);
		y0 = fmin(y0, p->centre_mm[1]);
		y1 = fmax(y1, p->centre_mm[1]);
		hmax = fmax(hmax, fmax(p->half_mm[0], p->half_mm[1]));
		nused += usable(p);
	}
	if (nused < 3)
		return 0; /* not estimated: the values stay as sampled */
	f->origin_mm[0] = 0.5 * (x0 + x1);
	f->origin_mm[1] = 0.5 * (y0 + y1);
	f->scale_mm = fmax(1.0, 0.5 * fmax(x1 - x0, y1 - y0) + hmax);
	obs *o = calloc((size_t)(2 * nused), sizeof(*o));
	if (!o)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	int k = 0;
	for (int i = 0; i < n; i++) {
		const kg_chart_sample *p = &r->patches[i];
		if ((p->flags & KG_CHART_FLAG_REJECTED) || !usable(p))
			continue;
		const double *Q = p->quadrant;
		double u = (p->centre_mm[0] - f->origin_mm[0]) / f->scale_mm;
		double v = (p->centre_mm[1] - f->origin_mm[1]) / f->scale_mm;
		double hu = p->half_mm[0] / f->scale_mm, hv = p->half_mm[1] / f->scale_mm;
		double S = 0.25 * (Q[0] + Q[1] + Q[2] + Q[3]);
		double s2 = p->sd[0] * p->sd[0] + p->sd[1] * p->sd[1] + p->sd[2] * p->sd[2];
		double var = 4 * s2 / ((double)p->pixels * S * S) + GRAD_FLOOR * GRAD_FLOOR;
		obs *ox = &o[k++], *oy = &o[k++];
		ox->y = log((Q[1] + Q[3]) / (Q[0] + Q[2]));
		oy->y = log((Q[2] + Q[3]) / (Q[0] + Q[1]));
		ox->sigma = oy->sigma = sqrt(var);
		/* each term's mean over the right (lower) half minus the left (upper) */
		for (int j = 0; j < NT; j++) {
			int i0 = ex[j][0], i1 = ex[j][1];
			ox->a[j] = (mean_pow(i0, u, u + hu) - mean_pow(i0, u - hu, u)) *
			           mean_pow(i1, v - hv, v + hv);
			oy->a[j] = (mean_pow(i1, v, v + hv) - mean_pow(i1, v - hv, v)) *
			           mean_pow(i0, u - hu, u + hu);
		}
	}
	double c[NT] = {0}, rms = NAN;
	/* the highest degree with three gradients or more per coefficient */
	int degree = MAX_DEGREE;
	while (degree > 1 && 3 * terms_of_degree(degree) > k)
		degree--;
	while (degree >= 1 && robust_fit(o, k, terms_of_degree(degree), c, &rms))
		degree--;
	free(o);
	if (degree < 1)
		return 0;
	f->fitted = 1;
	f->degree = degree;
	f->used = nused;
	f->rms = rms;
	for (int j = 0; j < NT; j++)
		f->coef[j + 1] = c[j];
	/* normalise: L averages 1 over the patch centres */
	double sum = 0;
	int cnt = 0;
	for (int i = 0; i < n; i++) {
		const kg_chart_sample *p = &r->patches[i];
		if (p->flags & KG_CHART_FLAG_REJECTED)
			continue;
		sum += exp(kg_chart_light_log(f, p->centre_mm[0], p->centre_mm[1]));
		cnt++;
	}
	f->coef[0] = -log(sum / cnt);
	/* its range over the patches' area */
	f->min = INFINITY;
	f->max = -INFINITY;
	for (int a = 0; a <= 20; a++)
		for (int b = 0; b <= 20; b++) {
			double x = x0 - hmax + (x1 - x0 + 2 * hmax) * a / 20.0;
			double y = y0 - hmax + (y1 - y0 + 2 * hmax) * b / 20.0;
			double L = exp(kg_chart_light_log(f, x, y));
			f->min = fmin(f->min, L);
			f->max = fmax(f->max, L);
		}
	f->variation = f->max - f->min;
	double limit = opt->max_light_variation > 0 ? opt->max_light_variation
	                                            : KG_CHART_MAX_LIGHT_VARIATION;
	if (!(f->variation <= limit))
		return kg_fail(err, KG_EINVAL,
		               "the light across chart %s varies by %.0f %% (from %.2f to %.2f of "
		               "its mean, estimated from %d patches' own gradients): more than the "
		               "%.0f %% the light-field correction is trusted to remove; light the "
		               "chart more evenly, place it nearer the middle of the frame or "
		               "apply a flat", r->layout, 100 * f->variation, f->min, f->max,
		               f->used, 100 * limit);
	/* divide the values by the field; judge non-uniformity on what is left */
	for (int i = 0; i < n; i++) {
		kg_chart_sample *p = &r->patches[i];
		if (p->flags & KG_CHART_FLAG_REJECTED)
			continue;
		double L = exp(kg_chart_light_log(f, p->centre_mm[0], p->centre_mm[1]));
		p->light = L;
		for (int ch = 0; ch < 3; ch++) {
			p->rgb[ch] /= L;
			p->sd[ch] /= L;
		}
		double qmin = INFINITY, qmax = -INFINITY, qs = 0;
		int qn = 0;
		for (int q = 0; q < 4; q++) {
			if (!isfinite(p->quadrant[q]))
				continue;
			double x = p->centre_mm[0] + (q & 1 ? 0.5 : -0.5) * p->half_mm[0];
			double y = p->centre_mm[1] + (q & 2 ? 0.5 : -0.5) * p->half_mm[1];
			double v = p->quadrant[q] / exp(kg_chart_light_log(f, x, y));
			qmin = fmin(qmin, v);
			qmax = fmax(qmax, v);
			qs += v;
			qn++;
		}
		if (!qn || !(fabs(qs) > 1e-12))
			continue;
		p->nonuniformity = (qmax - qmin) / fabs(qs / qn);
		if (p->flags & KG_CHART_FLAG_NONUNIFORM) {
			p->flags &= ~(unsigned)KG_CHART_FLAG_NONUNIFORM;
			strip_nonuniform(p->warning);
		}
		if (p->nonuniformity > opt->nonuniformity_limit) {
			p->flags |= KG_CHART_FLAG_NONUNIFORM;
			size_t at = strlen(p->warning);
			snprintf(p->warning + at, sizeof(p->warning) - at,
			         "%snon-uniform (quadrants differ by %.1f %% after the light field is "
			         "removed: occluded, shadowed or glare?)",
			         at ? "; " : "", 100 * p->nonuniformity);
		}
	}
	return 0;
}
