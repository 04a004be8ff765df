/* Reflection lobes: Beckmann normalisation, the Torrance-Sparrow geometric term,
 * and directional albedos that never exceed 1. */
#include <math.h>
#include <stdio.h>

#include "hemisphere.h"
#include "kg_optics.h"
#include "kg_test.h"

static const double N[3] = {0, 0, 1};

static void beckmann(void)
{
	/* int D(h) (N.H) dw_h = 2 pi int_0^{pi/2} D cos sin dtheta = 1 */
	const double ms[] = {0.02, 0.05, 0.1, 0.3, 0.6, 1.0};
	for (size_t i = 0; i < sizeof(ms) / sizeof(ms[0]); i++) {
		const int steps = 200000;
		double h = M_PI_2 / steps, sum = 0.0;
		for (int s = 0; s <= steps; s++) {
			double t = s * h, w = (s == 0 || s == steps) ? 1 : (s % 2 ? 4 : 2);
			sum += w * kg_beckmann(cos(t), ms[i]) * cos(t) * sin(t);
		}
		sum *= 2.0 * M_PI * h / 3.0;
		CHECK_NEAR(sum, 1.0, 1e-6, "Beckmann normalisation");
	}
	/* closed form at alpha: tan = 0.5, m = 0.3 */
	double c = 1 / sqrt(1.25), m = 0.3;
	CHECK_NEAR(kg_beckmann(c, m), exp(-0.25 / (m * m)) / (M_PI * m * m * pow(c, 4)), 1e-12,
	           "Beckmann closed form");
	CHECK(kg_beckmann(0.0, 0.3) == 0.0, "D at 90 deg");
	CHECK(kg_beckmann(1e-200, 0.3) == 0.0, "D near 90 deg: no 0/0");
	CHECK(isnan(kg_beckmann(0.5, 0.0)), "m = 0");
	CHECK(isnan(kg_beckmann(1.5, 0.3)), "cos > 1");
}

static void geometry_term(void)
{
	/* normal viewing and lighting: no shadowing */
	CHECK_NEAR(kg_ts_geometry(N, N, N), 1.0, 0, "G at normal incidence");
	/* V at 80 deg, L at 80 deg on opposite sides (mirror configuration): H = N,
	 * G = min(1, 2 (N.V) / (V.H)) = min(1, 2) = 1 */
	double V[3], L[3];
	direction(80 * M_PI / 180, 0, V);
	direction(80 * M_PI / 180, M_PI, L);
	CHECK_NEAR(kg_ts_geometry(N, V, L), 1.0, 1e-15, "G, mirror configuration");
	/* V at 80 deg, L at 80 deg on the same side: H = V = L, V.H = 1, N.H = cos 80,
	 * G = min(1, 2 cos^2 80) */
	direction(80 * M_PI / 180, 0, L);
	double c80 = cos(80 * M_PI / 180);
	CHECK_NEAR(kg_ts_geometry(N, V, L), 2 * c80 * c80, 1e-15, "G, retro-reflection");
	/* a general geometry against the formula written out */
	direction(70 * M_PI / 180, 0.3, V);
	direction(50 * M_PI / 180, 2.0, L);
	double H[3] = {V[0] + L[0], V[1] + L[1], V[2] + L[2]};
	double hl = sqrt(H[0] * H[0] + H[1] * H[1] + H[2] * H[2]);
	double nh = H[2] / hl, vh = (V[0] * H[0] + V[1] * H[1] + V[2] * H[2]) / hl;
	double g = fmin(1, fmin(2 * nh * V[2] / vh, 2 * nh * L[2] / vh));
	CHECK_NEAR(kg_ts_geometry(N, V, L), g, 1e-14, "G, general geometry");
	CHECK_NEAR(kg_ts_geometry(N, V, L), kg_ts_geometry(N, L, V), 1e-15, "G symmetric");
	/* below the horizon */
	double below[3];
	direction(95 * M_PI / 180, 0, below);
	CHECK(kg_ts_geometry(N, below, L) == 0.0, "V below the surface");
	CHECK(kg_lobe_gloss(N, V, below, 0.1, NULL) == 0.0, "L below the surface");
	CHECK(kg_lobe_mirror(N, below, L, 0.02, NULL) == 0.0, "mirror, V below the surface");
	/* not unit vectors */
	double longer[3] = {0, 0, 1.01};
	CHECK(isnan(kg_ts_geometry(N, longer, L)), "non-unit V");
	CHECK(isnan(kg_lobe_gloss(longer, V, L, 0.1, NULL)), "non-unit N");
	CHECK(isnan(kg_lobe_mirror(N, V, L, 0.0, NULL)), "mirror width 0");
}

typedef struct lobe_ctx {
	const double *L;
	double param;
	int mirror;
} lobe_ctx;

static void lobe_times_cos(const double V[3], double w, double *acc, void *p)
{
	lobe_ctx *c = p;
	if (V[2] <= 0)
		return;
	double f = c->mirror ? kg_lobe_mirror(N, V, c->L, c->param, NULL)
	                     : kg_lobe_gloss(N, V, c->L, c->param, NULL);
	acc[0] += w * f * V[2];
}

static void albedo(void)
{
	const double incid[] = {0, 15, 30, 45, 60, 75, 85, 89, 89.9};
	const double ms[] = {0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 0.8, 1.0};
	const double ws[] = {0.005, 0.02, 0.05, 0.1};
	double worst_gloss = 0, worst_mirror = 0;
	for (size_t i = 0; i < sizeof(incid) / sizeof(incid[0]); i++) {
		double L[3], R[3];
		direction(incid[i] * M_PI / 180, 0, L);
		R[0] = -L[0];
		R[1] = -L[1];
		R[2] = L[2];
		for (size_t j = 0; j < sizeof(ms) / sizeof(ms[0]); j++) {
			lobe_ctx c = {L, ms[j], 0};
			double a;
			integrate_around(R, 600, 360, 1, lobe_times_cos, &c, &a);
			worst_gloss = fmax(worst_gloss, a);
			CHECK(a <= 1.0 + 1e-3, "gloss lobe m %g at %g deg: albedo %.6f > 1", ms[j],
			      incid[i], a);
			/* shadowing removes little at normal incidence for smooth surfaces */
			if (incid[i] == 0 && ms[j] <= 0.2)
				CHECK(a > 0.97, "gloss lobe m %g at normal incidence: albedo %.6f, "
				      "expected about 1", ms[j], a);
		}
		for (size_t j = 0; j < sizeof(ws) / sizeof(ws[0]); j++) {
			lobe_ctx c = {L, ws[j], 1};
			double a;
			integrate_around(R, 600, 360, 1, lobe_times_cos, &c, &a);
			worst_mirror = fmax(worst_mirror, a);
			CHECK(a <= 1.0 + 1e-3, "mirror lobe w %g at %g deg: albedo %.6f > 1", ws[j],
			      incid[i], a);
			if (incid[i] <= 60)
				CHECK(a > 0.99, "mirror lobe w %g at %g deg: albedo %.6f, expected "
				      "about 1", ws[j], incid[i], a);
		}
	}
	printf("largest directional albedo: gloss lobe %.8f, mirror lobe %.8f\n", worst_gloss,
	       worst_mirror);
}

static void sweep(void)
{
	/* many geometries: values finite, >= 0, gloss lobe reciprocal, V.H in [0, 1] */
	unsigned long long s = 12345;
	int bad = 0;
	for (int i = 0; i < 200000; i++) {
		double u[4];
		for (int k = 0; k < 4; k++) {
			s = s * 6364136223846793005ULL + 1442695040888963407ULL;
			u[k] = (double)(s >> 11) / 9007199254740992.0;
		}
		double V[3], L[3], cvh, cvh2;
		direction(acos(u[0]), 2 * M_PI * u[1], V);
		direction(acos(u[2]), 2 * M_PI * u[3], L);
		double m = 0.01 + 0.99 * u[1 + i % 3];
		double g = kg_lobe_gloss(N, V, L, m, &cvh);
		double g2 = kg_lobe_gloss(N, L, V, m, &cvh2);
		double r = kg_lobe_mirror(N, V, L, 0.01 + 0.1 * u[0], NULL);
		if (!(g >= 0 && isfinite(g) && r >= 0 && isfinite(r) && cvh >= 0 && cvh <= 1 &&
		      fabs(g - g2) <= 1e-12 * fmax(1, g))) {
			if (bad++ < 5)
				fprintf(stderr, "geometry %d: gloss %g (reversed %g) mirror %g V.H %g\n",
				        i, g, g2, r, cvh);
		}
	}
	CHECK(bad == 0, "%d geometries gave negative, non-finite or non-reciprocal values",
	      bad);
}

int main(void)
{
	beckmann();
	geometry_term();
	albedo();
	sweep();
	return kg_test_done("test_lobes");
}
