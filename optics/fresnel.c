/* Fresnel reflectance of a plane interface, ambient medium n0 (real) to n + ik.
 *
 * With the relative index eta = (n + ik) / n0, c = cos(theta), s^2 = 1 - c^2 and
 * w = a + ib = sqrt(eta^2 - s^2) (principal root: a, b >= 0 for k >= 0):
 *   r_s = (c - w) / (c + w),  r_p = (eta^2 c - w) / (eta^2 c + w).
 * Three things keep this accurate from normal incidence to grazing and for large k:
 *   - eta^2 - s^2 = (n^2 - k^2 - n0^2 + (n0 c)^2) / n0^2 is summed from exact
 *     products (fma) with compensated addition, so it is right to about one rounding
 *     even when its terms nearly cancel (small |eta| at normal incidence, eta near 1
 *     at grazing, the critical angle of total internal reflection);
 *   - each reflectance is |p - q|^2 / |p + q|^2 with the denominator written as the
 *     numerator plus 4 Re(p conj(q)), a sum of non-negative terms: for s,
 *     4 c a; for p, 4 c a (|w|^2 + s^2) (because eta^2 = w^2 + s^2). So 0 <= R <= 1
 *     holds in floating point too, and R -> 1 at grazing without cancellation;
 *   - no tan(theta) or sin/cos of angles: the caller's cos(theta) is used as given. */
#include <math.h>

#include "kg_optics.h"

/* a + b = s + *e exactly (Knuth's TwoSum). */
static double two_sum(double a, double b, double *e)
{
	double s = a + b, bb = s - a;
	*e = (a - (s - bb)) + (b - bb);
	return s;
}

/* n^2 - k^2 - n0^2 + (n0 c)^2 = n0^2 (eta^2 - sin^2) from exact products, summed with
 * error compensation (Ogita, Rump & Oishi's Sum2): the error is about one rounding of
 * the result plus eps^2 times the largest term. n0 c is split exactly too, so that
 * n0 != 1 costs no accuracy. */
static double eta2_minus_sin2_scaled(double n, double k, double n0, double c)
{
	double m = n0 * c, me = fma(n0, c, -m); /* n0 c = m + me exactly */
	double t[9];
	t[0] = n * n;
	t[1] = fma(n, n, -t[0]);
	t[2] = -k * k;
	t[3] = fma(-k, k, -t[2]);
	t[4] = -n0 * n0;
	t[5] = fma(-n0, n0, -t[4]);
	t[6] = m * m;
	t[7] = fma(m, m, -t[6]);
	t[8] = me * (2.0 * m + me);
	double s = t[0], comp = 0.0, e;
	for (int i = 1; i < 9; i++) {
		s = two_sum(s, t[i], &e);
		comp += e;
	}
	return s + comp;
}

/* Principal square root of x + iy (y >= 0) into a + ib without cancellation. The
 * modulus skips hypot's scaling (a third of the time of a reflectance) unless the
 * squares could overflow. */
static void sqrt_complex(double x, double y, double *a, double *b)
{
	double r = fabs(x) < 1e150 && y < 1e150 ? sqrt(x * x + y * y) : hypot(x, y);
	if (x >= 0.0) {
		*a = sqrt(0.5 * (r + x));
		*b = *a > 0.0 ? y / (2.0 * *a) : 0.0;
	} else {
		*b = sqrt(0.5 * (r - x));
		*a = y / (2.0 * *b);
	}
}

void kg_fresnel_conductor_sp(double n, double k, double n0, double cos_i, double *rs,
                             double *rp)
{
	double s = NAN, p = NAN;
	if (n >= 0.0 && k >= 0.0 && (n > 0.0 || k > 0.0) && n0 > 0.0 && cos_i >= 0.0 &&
	    cos_i <= 1.0 && isfinite(n) && isfinite(k) && isfinite(n0)) {
		double c = cos_i, n02 = n0 * n0;
		if (n == n0 && k == 0.0) {
			s = p = 0.0; /* no interface */
		} else {
			/* w = a + ib = sqrt(x + iy), x + iy = eta^2 - sin^2 */
			double x = eta2_minus_sin2_scaled(n, k, n0, c) / n02, y = 2.0 * n * k / n02;
			double a, b;
			sqrt_complex(x, y, &a, &b);
			/* s: |c - w|^2 / (|c - w|^2 + 4 c a) */
			double num = (c - a) * (c - a) + b * b;
			s = num / (num + 4.0 * c * a);
			if (c == 1.0) {
				p = s; /* normal incidence: no plane of incidence, r_p = r_s */
			} else {
				/* p: u = eta^2 c; |u - w|^2 / (|u - w|^2 + 4 c a (|w|^2 + s^2)) */
				double ur = fma(n, n, -k * k) / n02 * c, ui = y * c;
				double sin2 = (1.0 - c) * (1.0 + c);
				num = (ur - a) * (ur - a) + (ui - b) * (ui - b);
				p = num / (num + 4.0 * c * a * (a * a + b * b + sin2));
			}
		}
	}
	if (rs)
		*rs = s;
	if (rp)
		*rp = p;
}

double kg_fresnel_conductor(double n, double k, double n0, double cos_i)
{
	double rs, rp;
	kg_fresnel_conductor_sp(n, k, n0, cos_i, &rs, &rp);
	return 0.5 * (rs + rp);
}

/* With k = 0 the conductor formula is the dielectric one: below the critical angle w
 * is real; beyond it w is imaginary (a = 0) and both reflectances are exactly 1. */
void kg_fresnel_dielectric_sp(double n, double n0, double cos_i, double *rs, double *rp)
{
	kg_fresnel_conductor_sp(n, 0.0, n0, cos_i, rs, rp);
}

double kg_fresnel_dielectric(double n, double n0, double cos_i)
{
	return kg_fresnel_conductor(n, 0.0, n0, cos_i);
}

void kg_nk_reflectance(const kg_nk *nk, double cos_i, kg_spectrum *out)
{
	for (int i = 0; i < KG_NBANDS; i++)
		out->v[i] = kg_fresnel_conductor(nk->n.v[i], nk->k.v[i], 1.0, cos_i);
}
