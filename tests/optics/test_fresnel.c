/* Fresnel reflectance: closed forms, limits, and a sweep against a straightforward
 * long-double complex evaluation of the same equations. */
#include <complex.h>
#include <math.h>
#include <stdio.h>

#include "kg_optics.h"
#include "kg_test.h"

/* The textbook formulas in long double complex arithmetic, from the same (double)
 * inputs: eta = (n + ik)/n0, w = sqrt(eta^2 - sin^2), r_s = (c - w)/(c + w),
 * r_p = (eta^2 c - w)/(eta^2 c + w). */
static void reference(double n, double k, double n0, double c, long double *rs,
                      long double *rp)
{
	long double complex eta = ((long double)n + (long double)k * I) / (long double)n0;
	long double cl = c, s2 = 1.0L - cl * cl;
	long double complex w = csqrtl(eta * eta - s2);
	long double complex e2c = eta * eta * cl;
	long double complex a = (cl - w) / (cl + w), b = (e2c - w) / (e2c + w);
	*rs = creall(a) * creall(a) + cimagl(a) * cimagl(a);
	*rp = creall(b) * creall(b) + cimagl(b) * cimagl(b);
}

static void closed_forms(void)
{
	/* normal incidence: ((n-1)^2 + k^2) / ((n+1)^2 + k^2), s = p */
	const double ns[] = {0.05, 0.2, 0.5, 1.0, 1.5, 2.4, 5.0};
	const double ks[] = {0.0, 1e-3, 0.3, 2.0, 3.5, 10.0, 50.0};
	for (size_t i = 0; i < sizeof(ns) / sizeof(ns[0]); i++)
		for (size_t j = 0; j < sizeof(ks) / sizeof(ks[0]); j++) {
			double n = ns[i], k = ks[j], rs, rp;
			double r0 = ((n - 1) * (n - 1) + k * k) / ((n + 1) * (n + 1) + k * k);
			kg_fresnel_conductor_sp(n, k, 1.0, 1.0, &rs, &rp);
			/* the closed form in double carries a few roundings of its own */
			CHECK_NEAR(rs, r0, 4e-16, "R_s(0) closed form");
			CHECK_NEAR(rp, r0, 4e-16, "R_p(0) closed form");
			CHECK(rs == rp, "s and p differ at normal incidence: %.17g %.17g", rs, rp);
			/* grazing: exactly 1 (unless the media are identical) */
			if (!(n == 1.0 && k == 0.0)) {
				kg_fresnel_conductor_sp(n, k, 1.0, 0.0, &rs, &rp);
				CHECK(rs == 1.0 && rp == 1.0, "n %g k %g: R(90 deg) = %.17g, %.17g", n, k,
				      rs, rp);
				/* cos(M_PI_2) is 6e-17, not 0: R falls short of 1 by O(1e-15) */
				double r = kg_fresnel_conductor(n, k, 1.0, cos(M_PI_2));
				CHECK(r <= 1.0 && r > 1.0 - 1e-14, "R(cos(pi/2)) = %.17g", r);
			}
		}
	/* the ambient medium scales the index: n0 = 2 with 2n + 2ik is n + ik in air */
	CHECK_NEAR(kg_fresnel_conductor(0.6, 3.1, 2.0, 0.37), kg_fresnel_conductor(0.3, 1.55,
	                                                                             1.0, 0.37),
	           1e-15, "n0 scaling");
	/* identical media reflect nothing at any angle */
	CHECK(kg_fresnel_conductor(1.0, 0.0, 1.0, 0.0) == 0.0, "matched media at grazing");
	CHECK(kg_fresnel_dielectric(1.33, 1.33, 0.5) == 0.0, "matched media");
	/* n = 0: a perfect reflector at every angle */
	for (double c = 0; c <= 1.0; c += 0.125)
		CHECK_NEAR(kg_fresnel_conductor(0.0, 4.0, 1.0, c), 1.0, 1e-15, "n = 0 conductor");

	/* dielectric against the Snell's-law form of the Fresnel equations */
	const double n1s[] = {1.0, 1.0, 1.5, 1.33};
	const double n2s[] = {1.5, 1.33, 1.0, 2.4};
	for (int m = 0; m < 4; m++) {
		double n1 = n1s[m], n2 = n2s[m], worst = 0;
		for (int d = 0; d <= 9000; d++) {
			double th = d * 0.01 * M_PI / 180, ci = cos(th), si = sin(th);
			double st = n1 / n2 * si, rs, rp;
			kg_fresnel_dielectric_sp(n2, n1, ci, &rs, &rp);
			if (st >= 1.0) {
				CHECK(rs == 1.0 && rp == 1.0, "n0 %g n %g at %g deg: total internal "
				      "reflection expected, got %.17g %.17g", n1, n2, d * 0.01, rs, rp);
				continue;
			}
			double ct = sqrt(1 - st * st);
			double as = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
			double ap = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
			worst = fmax(worst, fmax(fabs(rs - as * as), fabs(rp - ap * ap)));
		}
		/* the Snell form itself loses digits near the critical angle (ct -> 0) */
		CHECK(worst < 1e-9, "dielectric %g -> %g: max difference to Snell form %.3g", n1,
		      n2, worst);
		printf("dielectric %g -> %g: max |R - Snell form| = %.3g\n", n1, n2, worst);
	}
	/* Brewster's angle: tan(theta_B) = n / n0, R_p = 0 */
	double tb = atan(1.5), rs, rp;
	kg_fresnel_dielectric_sp(1.5, 1.0, cos(tb), &rs, &rp);
	CHECK(rp < 1e-15, "R_p at Brewster's angle = %.3g", rp);
	CHECK_NEAR(rs, 0.1479289940828402, 1e-12, "R_s at Brewster's angle (n 1.5)");
	/* critical angle from glass: exactly 1 beyond */
	CHECK(kg_fresnel_dielectric(1.0, 1.5, cos(asin(1 / 1.5) + 1e-9)) == 1.0, "TIR");

	/* invalid arguments give NaN */
	CHECK(isnan(kg_fresnel_conductor(-0.1, 1, 1, 0.5)), "n < 0");
	CHECK(isnan(kg_fresnel_conductor(0.1, -1, 1, 0.5)), "k < 0");
	CHECK(isnan(kg_fresnel_conductor(0.1, 1, 0, 0.5)), "n0 = 0");
	CHECK(isnan(kg_fresnel_conductor(0.1, 1, 1, 1.0000001)), "cos > 1");
	CHECK(isnan(kg_fresnel_conductor(0.1, 1, 1, -1e-300)), "cos < 0");
	CHECK(isnan(kg_fresnel_conductor(NAN, 1, 1, 0.5)), "NaN n");
	CHECK(isnan(kg_fresnel_conductor(0.0, 0.0, 1, 0.5)), "n = k = 0");
}

/* The sweep: theta 0..90 deg in 0.05 deg steps plus points crowding 90 deg, k 0..50,
 * n 0.05..5 (n = 1, k = 0 left out: identical media, 0/0 in the textbook form). */
static void sweep(void)
{
	double thetas[1900];
	int nt = 0;
	for (int d = 0; d <= 1800; d++)
		thetas[nt++] = d * 0.05;
	const double near90[] = {89.9, 89.99, 89.999, 89.9999, 89.99999, 89.999999};
	for (size_t i = 0; i < sizeof(near90) / sizeof(near90[0]); i++)
		thetas[nt++] = near90[i];
	double ks[48];
	int nk = 0;
	const double small_k[] = {0.0, 1e-9, 1e-6, 1e-3, 0.01, 0.05, 0.1, 0.2, 0.5};
	for (size_t i = 0; i < sizeof(small_k) / sizeof(small_k[0]); i++)
		ks[nk++] = small_k[i];
	for (int i = 0; i < 38; i++)
		ks[nk++] = 1.0 * pow(50.0, i / 37.0);
	double worst = 0, at_n = 0, at_k = 0, at_t = 0;
	long count = 0;
	for (int in = 0; in < 60; in++) {
		double n = 0.05 * pow(100.0, in / 59.0);
		for (int ik = 0; ik < nk; ik++) {
			double k = ks[ik];
			for (int it = 0; it < nt + 1; it++) {
				/* the last point is cos = 0 exactly, the rest cos(theta) in double */
				double c = it < nt ? cos(thetas[it] * M_PI / 180) : 0.0;
				if (c < 0)
					c = 0;
				double rs, rp;
				long double ls, lp;
				kg_fresnel_conductor_sp(n, k, 1.0, c, &rs, &rp);
				reference(n, k, 1.0, c, &ls, &lp);
				double r = kg_fresnel_conductor(n, k, 1.0, c);
				double e = fmax(fabsl(rs - ls), fmaxl(fabsl(rp - lp),
				                                      fabsl(r - 0.5L * (ls + lp))));
				count++;
				if (!(e <= worst)) {
					worst = e;
					at_n = n;
					at_k = k;
					at_t = it < nt ? thetas[it] : 90.0;
				}
				CHECK(rs >= 0 && rs <= 1 && rp >= 0 && rp <= 1,
				      "n %g k %g theta %g: R_s %.17g R_p %.17g outside [0, 1]", n, k,
				      it < nt ? thetas[it] : 90.0, rs, rp);
			}
		}
	}
	printf("Fresnel vs long-double reference: %ld points, largest |error| %.3g "
	       "(n %.4g, k %.4g, theta %.6g deg)\n", count, worst, at_n, at_k, at_t);
	CHECK(worst < 1e-12, "largest error %.3g at n %g k %g theta %g", worst, at_n, at_k,
	      at_t);

	/* with an ambient medium other than air, including n0 > n (k = 0: TIR) */
	worst = 0;
	const double n0s[] = {1.33, 1.5, 2.0};
	for (int i0 = 0; i0 < 3; i0++)
		for (int in = 0; in < 30; in++) {
			double n = 0.05 * pow(100.0, in / 29.0);
			for (int ik = 0; ik < nk; ik += 4)
				for (int d = 0; d <= 900; d++) {
					double c = cos(d * 0.1 * M_PI / 180), rs, rp;
					long double ls, lp;
					if (n == n0s[i0] && ks[ik] == 0.0)
						continue;
					kg_fresnel_conductor_sp(n, ks[ik], n0s[i0], c, &rs, &rp);
					reference(n, ks[ik], n0s[i0], c, &ls, &lp);
					worst = fmax(worst, fmax(fabsl(rs - ls), fabsl(rp - lp)));
				}
		}
	printf("Fresnel with n0 in {1.33, 1.5, 2}: largest |error| %.3g\n", worst);
	CHECK(worst < 1e-12, "n0 != 1: largest error %.3g", worst);
}

int main(void)
{
	closed_forms();
	sweep();
	return kg_test_done("test_fresnel");
}
