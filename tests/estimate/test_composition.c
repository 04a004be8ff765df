/* The per-pixel Ag, Cu, Au composition of camera-space classification
 * (est_composition_pixel, estimate/labels_cam.c), against what the statistics say and
 * not against its own arithmetic:
 *  - Interior mixes (every metal present): over 20000 noisy readings drawn with a full
 *    covariance, the fractions' mean is the truth and their scatter is the reported
 *    Cramer-Rao standard deviation (ratio within 4 %: the sampling error of a standard
 *    deviation over 20000 draws is 0.5 %, the delta method's is below 1 % at this noise).
 *  - Mixes on the simplex's edge (no gold, and pure silver): every fraction in [0, 1],
 *    summing to 1, and the fit optimal under w >= 0: the Karush-Kuhn-Tucker conditions
 *    of the whitened least squares hold at w = s c (s the best intensity along the
 *    fractions), checked with the test's own Cholesky factor.
 *  - Refusals: a covariance that is not positive definite gives NaN everywhere.
 */
#include <float.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "est_fixture.h"
#include "est_private.h"
#include "kg_estimate.h"
#include "kg_test.h"

/* silver, copper and gold of the bundled library under Gaussian sensitivities (600,
 * 540, 450 nm), angles 0-70 every 5 degrees */
static kg_cs_model *metals_model(kg_material_library **lib, kg_err *err)
{
	double F[3 * KG_NBANDS];
	if (fx_library_camera(lib, F, err))
		return NULL;
	static const char *names[3] = {"silver", "copper", "gold"};
	const kg_material *mats[3];
	for (int j = 0; j < 3; j++)
		if (!(mats[j] = kg_material_library_find(*lib, names[j])))
			return NULL;
	kg_cs_model *m = NULL;
	kg_cs_model_new(F, mats, 3, 0, 70, 5, 0.3, 1.0, &m, err);
	return m;
}

/* lower Cholesky factor of a 3 x 3 (row-major), the test's own */
static void chol(const double C[9], double L[9])
{
	memset(L, 0, 9 * sizeof(double));
	for (int i = 0; i < 3; i++)
		for (int j = 0; j <= i; j++) {
			double s = C[3 * i + j];
			for (int k = 0; k < j; k++)
				s -= L[3 * i + k] * L[3 * j + k];
			L[3 * i + j] = i == j ? sqrt(s) : s / L[3 * j + j];
		}
}

static void solve_lower(const double L[9], const double x[3], double y[3])
{
	for (int i = 0; i < 3; i++) {
		double s = x[i];
		for (int k = 0; k < i; k++)
			s -= L[3 * i + k] * y[k];
		y[i] = s / L[3 * i + i];
	}
}

/* The reading of the mix w (3 weights) at angle index k, and a covariance for it:
 * photon-like noise of relative size rel on each channel, mixed by a matrix near
 * identity (a camera's values mapped through M2), so it is full. */
static void mix_reading(const kg_cs_model *m, int k, const double w[3], double rel,
                        double x[3], double C[9])
{
	for (int a = 0; a < 3; a++) {
		x[a] = 0;
		for (int j = 0; j < 3; j++)
			x[a] += w[j] * m->mu[3 * ((size_t)j * m->nangles + k) + a];
	}
	static const double M[9] = {1.0, 0.2, -0.1, 0.15, 1.0, 0.1, -0.05, 0.25, 1.0};
	double v[3];
	for (int c = 0; c < 3; c++)
		v[c] = (rel * x[c]) * (rel * x[c]) + 1e-8;
	for (int a = 0; a < 3; a++)
		for (int b = 0; b < 3; b++) {
			double s = 0;
			for (int c = 0; c < 3; c++)
				s += M[3 * a + c] * M[3 * b + c] * v[c];
			C[3 * a + b] = s;
		}
}

static void cov6(const double C[9], float c[6])
{
	c[0] = (float)C[0], c[1] = (float)C[1], c[2] = (float)C[2];
	c[3] = (float)C[4], c[4] = (float)C[5], c[5] = (float)C[8];
}

/* Interior: mean and scatter against the truth and the reported sds. */
static void interior(const kg_cs_model *m, fx_rng *r, const double frac[3], double s, int k,
                     double rel)
{
	double w[3] = {s * frac[0], s * frac[1], s * frac[2]}, x0[3], C[9], L[9];
	mix_reading(m, k, w, rel, x0, C);
	chol(C, L);
	float cf[6];
	cov6(C, cf);
	enum { N = 20000 };
	double sum[3] = {0}, sq[3] = {0}, sdsum[3] = {0};
	long ok = 0, simplex = 0;
	for (int it = 0; it < N; it++) {
		double z[3] = {fx_gauss(r), fx_gauss(r), fx_gauss(r)};
		float x[3], out[6];
		for (int a = 0; a < 3; a++)
			x[a] = (float)(x0[a] + L[3 * a] * z[0] + L[3 * a + 1] * z[1] + L[3 * a + 2] * z[2]);
		est_composition_pixel(m, k, x, cf, out);
		if (!isfinite(out[0]) || !isfinite(out[3]))
			continue;
		ok++;
		double t = out[0] + out[1] + out[2];
		simplex += out[0] >= 0 && out[1] >= 0 && out[2] >= 0 && fabs(t - 1) < 1e-5;
		for (int i = 0; i < 3; i++) {
			sum[i] += out[i];
			sq[i] += (double)out[i] * out[i];
			sdsum[i] += out[3 + i];
		}
	}
	CHECK(ok == N, "%.2f/%.2f/%.2f: %ld of %d readings fitted", frac[0], frac[1], frac[2], ok,
	      N);
	CHECK(simplex == ok, "%.2f/%.2f/%.2f: %ld of %ld fits on the simplex", frac[0], frac[1],
	      frac[2], simplex, ok);
	if (ok < 2)
		return;
	static const char *name[3] = {"Ag", "Cu", "Au"};
	for (int i = 0; i < 3; i++) {
		double mean = sum[i] / ok, sd = sqrt((sq[i] - ok * mean * mean) / (ok - 1));
		double rep = sdsum[i] / ok;
		printf("  %.2f/%.2f/%.2f %s: mean %.5f (truth %.5f), scatter %.5f, reported sd "
		       "%.5f (ratio %.3f)\n",
		       frac[0], frac[1], frac[2], name[i], mean, frac[i], sd, rep, sd / rep);
		CHECK(fabs(mean - frac[i]) < 0.05 * sd + 4 * sd / sqrt((double)ok),
		      "%s mean %.5f, truth %.5f (scatter %.5f)", name[i], mean, frac[i], sd);
		CHECK(fabs(sd / rep - 1) < 0.04, "%s: scatter %.5f against the reported sd %.5f",
		      name[i], sd, rep);
	}
}

/* On the edge: the fit is the constrained least squares' optimum. */
static void edge(const kg_cs_model *m, fx_rng *r, const double frac[3], double s, int k,
                 double rel)
{
	double w0[3] = {s * frac[0], s * frac[1], s * frac[2]}, x0[3], C[9], L[9], A[9];
	mix_reading(m, k, w0, rel, x0, C);
	chol(C, L);
	float cf[6];
	cov6(C, cf);
	for (int j = 0; j < 3; j++) { /* whitened metals, column j */
		double v[3];
		solve_lower(L, m->mu + 3 * ((size_t)j * m->nangles + k), v);
		for (int a = 0; a < 3; a++)
			A[3 * a + j] = v[a];
	}
	long fitted = 0, simplex = 0, kkt = 0, zeros = 0;
	double worst = 0;
	for (int it = 0; it < 4000; it++) {
		double z[3] = {fx_gauss(r), fx_gauss(r), fx_gauss(r)}, xd[3], y[3];
		float x[3], out[6];
		for (int a = 0; a < 3; a++) {
			x[a] = (float)(x0[a] + L[3 * a] * z[0] + L[3 * a + 1] * z[1] + L[3 * a + 2] * z[2]);
			xd[a] = x[a];
		}
		est_composition_pixel(m, k, x, cf, out);
		if (!isfinite(out[0]))
			continue;
		fitted++;
		double t = out[0] + out[1] + out[2];
		simplex += out[0] >= 0 && out[1] >= 0 && out[2] >= 0 && fabs(t - 1) < 1e-5;
		solve_lower(L, xd, y);
		/* w = s c, s the least squares intensity along c */
		double Ac[3], num = 0, den = 0;
		for (int a = 0; a < 3; a++) {
			Ac[a] = A[3 * a] * out[0] + A[3 * a + 1] * out[1] + A[3 * a + 2] * out[2];
			num += Ac[a] * y[a];
			den += Ac[a] * Ac[a];
		}
		double sc = num / den, g[3], scale = 0, e[3];
		for (int a = 0; a < 3; a++)
			e[a] = sc * Ac[a] - y[a];
		for (int j = 0; j < 3; j++) {
			g[j] = A[j] * e[0] + A[3 + j] * e[1] + A[6 + j] * e[2];
			scale = fmax(scale, sqrt(A[j] * A[j] + A[3 + j] * A[3 + j] + A[6 + j] * A[6 + j]) *
			                        sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]));
		}
		/* the fractions are floats: their rounding moves the gradient by about
		 * 1e-7 of its scale */
		double tol = 2e-6 * scale, bad = 0;
		for (int j = 0; j < 3; j++) {
			if (out[j] > 0)
				bad = fmax(bad, fabs(g[j]) - tol); /* free: stationary */
			else
				bad = fmax(bad, -g[j] - tol), zeros++; /* at 0: no descent inward */
		}
		kkt += bad <= 0;
		worst = fmax(worst, bad / scale);
	}
	printf("  %.2f/%.2f/%.2f: %ld fitted, %ld weights at 0, KKT worst excess %.2g of scale\n",
	       frac[0], frac[1], frac[2], fitted, zeros, worst);
	CHECK(fitted == 4000, "%.2f/%.2f/%.2f: %ld of 4000 fitted", frac[0], frac[1], frac[2],
	      fitted);
	CHECK(simplex == fitted, "%ld of %ld fits on the simplex", simplex, fitted);
	CHECK(kkt == fitted, "%.2f/%.2f/%.2f: %ld of %ld fits optimal under w >= 0", frac[0],
	      frac[1], frac[2], kkt, fitted);
	CHECK(zeros > 400, "%.2f/%.2f/%.2f: %ld weights at 0: the edge is reached", frac[0],
	      frac[1], frac[2], zeros);
}

int main(void)
{
	kg_err err = {0};
	kg_material_library *lib = NULL;
	kg_cs_model *m = metals_model(&lib, &err);
	CHECK(m != NULL, "the metals' model: %s", err.msg);
	if (!m) {
		kg_material_library_free(&lib);
		return kg_test_done("estimate-composition");
	}
	fx_rng r = {20261204};
	static const double mixes[3][3] = {{0.5, 0.3, 0.2}, {0.25, 0.5, 0.25}, {0.1, 0.2, 0.7}};
	for (int i = 0; i < 3; i++)
		interior(m, &r, mixes[i], 0.7, 2 + 3 * i, 0.004);
	static const double edges[2][3] = {{0.594, 0.406, 0.0}, {1.0, 0.0, 0.0}};
	for (int i = 0; i < 2; i++)
		edge(m, &r, edges[i], 0.8, 6, 0.01);

	/* refused: not positive definite */
	float x[3] = {0.3f, 0.3f, 0.3f}, out[6];
	float bad[6] = {1e-4f, 2e-4f, 0, 1e-4f, 0, 1e-4f};
	est_composition_pixel(m, 6, x, bad, out);
	int nan = 0;
	for (int i = 0; i < 6; i++)
		nan += isnan(out[i]);
	CHECK(nan == 6, "an indefinite covariance: %d of 6 outputs NaN", nan);

	kg_cs_model_free(&m);
	kg_material_library_free(&lib);
	return kg_test_done("estimate-composition");
}
