/* Integration over viewing directions for the optics tests: directional albedos
 * int f(V) (N.V) dw_V of lobes that may be very narrow around the mirror direction. */
#ifndef KG_TEST_HEMISPHERE_H
#define KG_TEST_HEMISPHERE_H

#include <math.h>

/* Unit vector at angle theta from +z, azimuth phi. */
static inline void direction(double theta, double phi, double v[3])
{
	v[0] = sin(theta) * cos(phi);
	v[1] = sin(theta) * sin(phi);
	v[2] = cos(theta);
}

/* int g(V) dw over the whole sphere of V for a g with `dim` components (g adds
 * weight * g(V) into acc[0..dim-1]; dim <= 64), in polar coordinates (delta, phi)
 * around the unit vector R with delta = pi t^2, so that samples crowd near R (midpoint
 * rule in t and phi). g adds nothing where it has no support. Results in out. */
static inline void integrate_around(const double R[3], int nt, int nphi, int dim,
                                    void (*g)(const double V[3], double weight,
                                              double *acc, void *ctx),
                                    void *ctx, double *out)
{
	/* an orthonormal frame T1, T2 perpendicular to R */
	double a[3] = {fabs(R[0]) < 0.9 ? 1.0 : 0.0, fabs(R[0]) < 0.9 ? 0.0 : 1.0, 0.0};
	double t1[3] = {a[1] * R[2] - a[2] * R[1], a[2] * R[0] - a[0] * R[2],
	                a[0] * R[1] - a[1] * R[0]};
	double l = sqrt(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]);
	for (int i = 0; i < 3; i++)
		t1[i] /= l;
	double t2[3] = {R[1] * t1[2] - R[2] * t1[1], R[2] * t1[0] - R[0] * t1[2],
	                R[0] * t1[1] - R[1] * t1[0]};
	for (int c = 0; c < dim; c++)
		out[c] = 0.0;
	for (int i = 0; i < nt; i++) {
		double t = (i + 0.5) / nt, delta = M_PI * t * t, ddelta = 2.0 * M_PI * t / nt;
		double cd = cos(delta), sd = sin(delta), w = sd * ddelta * 2.0 * M_PI / nphi;
		for (int j = 0; j < nphi; j++) {
			double phi = (j + 0.5) * 2.0 * M_PI / nphi, cp = cos(phi), sp = sin(phi), v[3];
			for (int c = 0; c < 3; c++)
				v[c] = cd * R[c] + sd * (cp * t1[c] + sp * t2[c]);
			double q = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
			for (int c = 0; c < 3; c++)
				v[c] /= q;
			g(v, w, out, ctx);
		}
	}
}

#endif
