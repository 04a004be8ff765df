/* Reflection lobes: the Torrance-Sparrow gloss lobe (Beckmann facets, V-groove
 * shadowing) and a narrow mirror lobe. Each returns the geometric part of a BRDF;
 * the caller multiplies by the Fresnel reflectance at the facet angle V.H. */
#include <math.h>

#include "kg_optics.h"

static double dot3(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static int is_unit(const double v[3])
{
	return fabs(dot3(v, v) - 1.0) <= 1e-6;
}

/* Dot product of unit vectors, kept within [-1, 1] despite rounding. */
static double cosine(const double a[3], const double b[3])
{
	return fmax(-1.0, fmin(1.0, dot3(a, b)));
}

typedef struct geometry {
	double nv, nl, nh, vh;
} geometry;

/* -1: invalid input, 0: V or L at or below the horizon, 1: both above. */
static int geometry_of(const double N[3], const double V[3], const double L[3], geometry *g)
{
	if (!N || !V || !L || !is_unit(N) || !is_unit(V) || !is_unit(L))
		return -1;
	g->nv = cosine(N, V);
	g->nl = cosine(N, L);
	if (!(g->nv > 0.0) || !(g->nl > 0.0))
		return 0;
	double h[3] = {V[0] + L[0], V[1] + L[1], V[2] + L[2]};
	double len = sqrt(dot3(h, h));
	/* V and L both above the surface: V + L cannot vanish, |V + L| > 0 */
	for (int i = 0; i < 3; i++)
		h[i] /= len;
	g->nh = cosine(N, h);
	g->vh = cosine(V, h);
	return 1;
}

double kg_beckmann(double cos_alpha, double m)
{
	if (!(m > 0.0) || !(cos_alpha >= -1.0 && cos_alpha <= 1.0) || !isfinite(m))
		return NAN;
	if (cos_alpha <= 0.0)
		return 0.0;
	double c2 = cos_alpha * cos_alpha;
	double e = (1.0 - c2) / (c2 * m * m); /* tan^2(alpha) / m^2 */
	if (e > 740.0)
		return 0.0; /* exp(-e) is below the smallest double; avoids 0 / 0 */
	return exp(-e) / (M_PI * m * m * c2 * c2);
}

static double ts_geometry(const geometry *g)
{
	return fmin(1.0, fmin(2.0 * g->nh * g->nv / g->vh, 2.0 * g->nh * g->nl / g->vh));
}

double kg_ts_geometry(const double N[3], const double V[3], const double L[3])
{
	geometry g;
	int s = geometry_of(N, V, L, &g);
	return s < 0 ? NAN : s == 0 ? 0.0 : ts_geometry(&g);
}

double kg_lobe_gloss(const double N[3], const double V[3], const double L[3], double m,
                     double *cos_vh)
{
	geometry g;
	int s = geometry_of(N, V, L, &g);
	if (cos_vh)
		*cos_vh = s > 0 ? g.vh : s == 0 ? 1.0 : NAN;
	if (s <= 0)
		return s < 0 ? NAN : 0.0;
	return kg_beckmann(g.nh, m) * ts_geometry(&g) / (4.0 * g.nl * g.nv);
}

double kg_lobe_mirror(const double N[3], const double V[3], const double L[3], double w,
                      double *cos_vh)
{
	geometry g;
	int s = geometry_of(N, V, L, &g);
	if (s > 0 && !(w > 0.0 && isfinite(w)))
		s = -1;
	if (cos_vh)
		*cos_vh = s > 0 ? g.vh : s == 0 ? 1.0 : NAN;
	if (s <= 0)
		return s < 0 ? NAN : 0.0;
	/* mirror direction R = 2 (N.L) N - L; the angle to V by atan2, which keeps its
	 * accuracy for small angles where acos(V.R) would lose half the digits */
	double r[3], x[3];
	for (int i = 0; i < 3; i++)
		r[i] = 2.0 * g.nl * N[i] - L[i];
	x[0] = V[1] * r[2] - V[2] * r[1];
	x[1] = V[2] * r[0] - V[0] * r[2];
	x[2] = V[0] * r[1] - V[1] * r[0];
	double delta = atan2(sqrt(dot3(x, x)), dot3(V, r)) / w;
	return exp(-delta * delta) / (M_PI * w * w * g.nv);
}
