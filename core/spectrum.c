#include <math.h>

#include "spectrum.h"

/* Index of the first sample with wl[i] > at (n when none). */
static int upper_bound(const double *wl, int n, double at)
{
	int lo = 0, hi = n;
	while (lo < hi) {
		int mid = lo + (hi - lo) / 2;
		if (wl[mid] > at)
			hi = mid;
		else
			lo = mid + 1;
	}
	return lo;
}

double kg_samples_interp(const double *wl, const double *val, int n, double at)
{
	if (n <= 0)
		return NAN;
	if (at <= wl[0])
		return val[0];
	if (at >= wl[n - 1])
		return val[n - 1];
	int i = upper_bound(wl, n, at); /* wl[i-1] <= at < wl[i], 1 <= i <= n-1 */
	double t = (at - wl[i - 1]) / (wl[i] - wl[i - 1]);
	return val[i - 1] + t * (val[i] - val[i - 1]);
}

/* Weighted mean of the piecewise-linear interpolant of the samples under a triangle of
 * half-width KG_LAMBDA_STEP centred on c: the band seen through a triangular slit as wide
 * as the grid step. Between breakpoints (the samples, the triangle's corners) the
 * integrand is a product of two linear functions, so Simpson's rule is exact there. */
static double band_average(const double *wl, const double *val, int n, double c)
{
	const double h = KG_LAMBDA_STEP;
	double a = c - h, b = c + h, sum = 0.0;
	int i = upper_bound(wl, n, a);
	double p = a;
	while (p < b) {
		double q = b;
		if (p < c && c < q)
			q = c;
		if (i < n && wl[i] < q)
			q = wl[i];
		if (i < n && wl[i] <= q)
			i++;
		double m = 0.5 * (p + q);
		double gp = kg_samples_interp(wl, val, n, p) * (1.0 - fabs(p - c) / h);
		double gm = kg_samples_interp(wl, val, n, m) * (1.0 - fabs(m - c) / h);
		double gq = kg_samples_interp(wl, val, n, q) * (1.0 - fabs(q - c) / h);
		sum += (q - p) / 6.0 * (gp + 4.0 * gm + gq);
		p = q;
	}
	return sum / h;
}

int kg_spectrum_resample(const double *wl, const double *val, int n, unsigned flags,
                         const char *what, kg_spectrum *out, kg_err *err)
{
	kg_check_arg(wl && val && out, err);
	if (!what)
		what = "spectrum";
	if (n < 1)
		return kg_fail(err, KG_EINVAL, "%s: no samples: expected wavelengths covering "
		               "400-700 nm", what);
	for (int i = 0; i < n; i++) {
		if (!isfinite(wl[i]))
			return kg_fail(err, KG_EINVAL, "%s: sample %d: wavelength is not a finite "
			               "number", what, i + 1);
		if (!isfinite(val[i]))
			return kg_fail(err, KG_EINVAL, "%s: value at %g nm: expected a finite "
			               "number, found %g", what, wl[i], val[i]);
		if (i > 0 && !(wl[i] > wl[i - 1]))
			return kg_fail(err, KG_EINVAL, "%s: wavelengths must increase strictly, "
			               "found %g nm after %g nm", what, wl[i], wl[i - 1]);
	}
	const double tol = 1e-6;
	if ((wl[0] > KG_LAMBDA_MIN + tol || wl[n - 1] < KG_LAMBDA_MAX - tol) &&
	    !(flags & KG_RESAMPLE_EXTRAPOLATE))
		return kg_fail(err, KG_ERANGE, "%s: data cover %g-%g nm, expected at least "
		               "%g-%g nm (extrapolation was not requested)", what, wl[0],
		               wl[n - 1], KG_LAMBDA_MIN, KG_LAMBDA_MAX);

	/* Mean spacing of the samples that matter for the grid decides the method: data
	 * finer than the grid step are averaged per band, others interpolated. */
	int first = upper_bound(wl, n, KG_LAMBDA_MIN - KG_LAMBDA_STEP - tol);
	int last = upper_bound(wl, n, KG_LAMBDA_MAX + KG_LAMBDA_STEP + tol) - 1;
	int finer = 0;
	if (last > first)
		finer = (wl[last] - wl[first]) / (last - first) < KG_LAMBDA_STEP * (1.0 - 1e-6);

	for (int b = 0; b < KG_NBANDS; b++) {
		double c = kg_band_nm(b);
		out->v[b] = finer ? band_average(wl, val, n, c) : kg_samples_interp(wl, val, n, c);
	}
	return 0;
}

kg_spectrum kg_spectrum_const(double c)
{
	kg_spectrum s;
	for (int i = 0; i < KG_NBANDS; i++)
		s.v[i] = c;
	return s;
}

kg_spectrum kg_spectrum_add(const kg_spectrum *a, const kg_spectrum *b)
{
	kg_spectrum s;
	for (int i = 0; i < KG_NBANDS; i++)
		s.v[i] = a->v[i] + b->v[i];
	return s;
}

kg_spectrum kg_spectrum_sub(const kg_spectrum *a, const kg_spectrum *b)
{
	kg_spectrum s;
	for (int i = 0; i < KG_NBANDS; i++)
		s.v[i] = a->v[i] - b->v[i];
	return s;
}

kg_spectrum kg_spectrum_mul(const kg_spectrum *a, const kg_spectrum *b)
{
	kg_spectrum s;
	for (int i = 0; i < KG_NBANDS; i++)
		s.v[i] = a->v[i] * b->v[i];
	return s;
}

kg_spectrum kg_spectrum_scale(const kg_spectrum *a, double f)
{
	kg_spectrum s;
	for (int i = 0; i < KG_NBANDS; i++)
		s.v[i] = a->v[i] * f;
	return s;
}

kg_spectrum kg_spectrum_axpy(const kg_spectrum *a, double f, const kg_spectrum *b)
{
	kg_spectrum s;
	for (int i = 0; i < KG_NBANDS; i++)
		s.v[i] = a->v[i] + f * b->v[i];
	return s;
}

double kg_spectrum_dot(const kg_spectrum *a, const kg_spectrum *b)
{
	double d = 0.0;
	for (int i = 0; i < KG_NBANDS; i++)
		d += a->v[i] * b->v[i];
	return d;
}

double kg_spectrum_max(const kg_spectrum *a)
{
	double m = a->v[0];
	for (int i = 1; i < KG_NBANDS; i++)
		if (a->v[i] > m)
			m = a->v[i];
	return m;
}

double kg_spectrum_rmse(const kg_spectrum *a, const kg_spectrum *b)
{
	double s = 0.0;
	for (int i = 0; i < KG_NBANDS; i++) {
		double d = a->v[i] - b->v[i];
		s += d * d;
	}
	return sqrt(s / KG_NBANDS);
}

double kg_spectrum_gfc(const kg_spectrum *a, const kg_spectrum *b)
{
	double na = sqrt(kg_spectrum_dot(a, a)), nb = sqrt(kg_spectrum_dot(b, b));
	if (na == 0.0 || nb == 0.0)
		return 0.0;
	return fabs(kg_spectrum_dot(a, b)) / (na * nb);
}

int kg_spectrum_isfinite(const kg_spectrum *a)
{
	for (int i = 0; i < KG_NBANDS; i++)
		if (!isfinite(a->v[i]))
			return 0;
	return 1;
}
