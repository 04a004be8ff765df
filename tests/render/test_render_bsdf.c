/* The renderer's materials against optics/: its tabulated evaluation against
 * kg_material_eval, and its importance sampling (the directional albedo it estimates)
 * against a quadrature of kg_material_eval over the hemisphere. */
#include <math.h>
#include <string.h>

#include "kg_render.h"
#include "kg_test.h"

/* Tabulating F against cos(theta) in 1024 steps: measured largest relative error
 * 2.5e-6 for the metals and alloys, 5e-4 for urushi (n = 1.5, steep near grazing). */
#define EVAL_REL_TOL 1e-3

static void random_dir(kg_rng *r, double v[3])
{
	double z = kg_rng_uniform(r), phi = 2.0 * M_PI * kg_rng_uniform(r);
	double s = sqrt(1.0 - z * z);
	v[0] = s * cos(phi), v[1] = s * sin(phi), v[2] = z;
}

static void normalize(double v[3])
{
	double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
	for (int i = 0; i < 3; i++)
		v[i] /= n;
}

static void check_eval(const kg_material *mat, kg_rng *r)
{
	kg_err err;
	kg_render_material *rm = NULL;
	int ret = kg_render_material_new(mat, &rm, &err);
	CHECK(ret == 0, "%s: %s", mat->name, err.msg);
	if (ret)
		return;
	double worst = 0.0;
	for (int k = 0; k < 1500; k++) {
		double N[3] = {0, 0, 1}, V[3], L[3];
		random_dir(r, V);
		if (k % 2) {
			/* near the mirror direction, where the lobes peak */
			double d[3], e = 0.05 * kg_rng_uniform(r);
			random_dir(r, d);
			L[0] = -V[0] + e * d[0], L[1] = -V[1] + e * d[1], L[2] = V[2] + e * d[2];
			normalize(L);
			if (!(L[2] > 0.0))
				continue;
		} else {
			random_dir(r, L);
		}
		kg_spectrum got, want;
		kg_render_material_eval(rm, N, V, L, &got);
		ret = kg_material_eval(mat, N, V, L, &want, &err);
		CHECK(ret == 0, "%s", err.msg);
		for (int i = 0; i < KG_NBANDS; i++) {
			double d = fabs(got.v[i] - want.v[i]);
			double rel = want.v[i] > 1e-6 ? d / want.v[i] : d / 1e-6;
			worst = fmax(worst, rel);
		}
	}
	printf("eval %-26s largest relative difference %.2e\n", mat->name, worst);
	CHECK(worst <= EVAL_REL_TOL, "%s: the renderer's evaluation differs from "
	      "kg_material_eval by %.3g (relative) > %g", mat->name, worst, EVAL_REL_TOL);
	kg_render_material_free(&rm);
}

/* int f_r (N.L) dL by the midpoint rule in polar coordinates (delta, phi) around the
 * mirror direction of V, delta = pi x^2 so the steps are finest at the lobes' peak. */
static void quadrature_albedo(const kg_material *mat, const double N[3], const double V[3],
                              kg_spectrum *out)
{
	const int nd = 500, np = 120;
	double R[3], t[3], b[3];
	double nv = N[0] * V[0] + N[1] * V[1] + N[2] * V[2];
	for (int i = 0; i < 3; i++)
		R[i] = 2.0 * nv * N[i] - V[i];
	/* a basis t, b around R */
	double a[3] = {fabs(R[0]) < 0.9 ? 1.0 : 0.0, fabs(R[0]) < 0.9 ? 0.0 : 1.0, 0.0};
	t[0] = a[1] * R[2] - a[2] * R[1], t[1] = a[2] * R[0] - a[0] * R[2];
	t[2] = a[0] * R[1] - a[1] * R[0];
	normalize(t);
	b[0] = R[1] * t[2] - R[2] * t[1], b[1] = R[2] * t[0] - R[0] * t[2];
	b[2] = R[0] * t[1] - R[1] * t[0];
	memset(out, 0, sizeof(*out));
	for (int i = 0; i < nd; i++) {
		double x = (i + 0.5) / nd;
		double delta = M_PI * x * x, dd = 2.0 * M_PI * x / nd;
		for (int j = 0; j < np; j++) {
			double phi = 2.0 * M_PI * (j + 0.5) / np;
			double L[3];
			for (int k = 0; k < 3; k++)
				L[k] = cos(delta) * R[k] + sin(delta) * (cos(phi) * t[k] + sin(phi) * b[k]);
			normalize(L);
			if (N[0] * L[0] + N[1] * L[1] + N[2] * L[2] <= 0.0)
				continue;
			kg_spectrum f;
			kg_err err;
			if (kg_material_eval(mat, N, V, L, &f, &err) != 0)
				continue;
			double w = sin(delta) * dd * 2.0 * M_PI / np;
			for (int k = 0; k < KG_NBANDS; k++)
				out->v[k] += w * f.v[k];
		}
	}
}

/* The sampled albedo in batches (different seeds) against the quadrature: within four
 * standard errors of the batch mean plus 0.5 % for the quadrature itself. */
static void check_albedo(const kg_material *mat, double theta_deg)
{
	kg_err err;
	kg_render_material *rm = NULL;
	if (kg_render_material_new(mat, &rm, &err) != 0) {
		CHECK(0, "%s", err.msg);
		return;
	}
	double th = theta_deg * M_PI / 180.0;
	double N[3] = {0, 0, 1}, V[3] = {sin(th), 0, cos(th)};
	kg_spectrum quad;
	quadrature_albedo(mat, N, V, &quad);
	enum { BATCHES = 8, PER_BATCH = 20000 };
	static const int bands[3] = {10, 30, 50}; /* 450, 550, 650 nm */
	double sum[3] = {0}, sum2[3] = {0};
	for (int s = 0; s < BATCHES; s++) {
		kg_spectrum a;
		kg_render_material_albedo(rm, N, V, PER_BATCH, 1000 + (uint64_t)s, &a);
		for (int k = 0; k < 3; k++) {
			sum[k] += a.v[bands[k]];
			sum2[k] += a.v[bands[k]] * a.v[bands[k]];
		}
	}
	for (int k = 0; k < 3; k++) {
		double mean = sum[k] / BATCHES;
		double var = fmax(0.0, (sum2[k] / BATCHES - mean * mean) * BATCHES / (BATCHES - 1));
		double se = sqrt(var / BATCHES);
		double want = quad.v[bands[k]];
		double tol = 4.0 * se + 0.005 * want + 1e-6;
		printf("albedo %-26s %2.0f deg %3.0f nm: sampled %.5f +- %.5f, quadrature %.5f\n",
		       mat->name, theta_deg, kg_band_nm(bands[k]), mean, se, want);
		CHECK(fabs(mean - want) <= tol, "%s at %g deg, %g nm: sampled albedo %.5f, "
		      "quadrature of kg_material_eval %.5f, tolerance %.5f", mat->name, theta_deg,
		      kg_band_nm(bands[k]), mean, want, tol);
	}
	kg_render_material_free(&rm);
}

int main(void)
{
	kg_err err;
	kg_material_library *lib = NULL;
	char *path = kg_data_path("materials/default.json");
	int ret = path ? kg_material_library_load(path, &lib, &err) : KG_ENOENT;
	free(path);
	if (ret) {
		fprintf(stderr, "default library: %s\n", err.msg);
		return 1;
	}
	kg_rng r;
	kg_rng_seed(&r, 7);
	for (int i = 0; i < kg_material_library_count(lib); i++)
		check_eval(kg_material_library_get(lib, i), &r);

	check_albedo(kg_material_library_find(lib, "gold"), 0.0);
	check_albedo(kg_material_library_find(lib, "gold"), 50.0);
	check_albedo(kg_material_library_find(lib, "shibuichi-nami"), 25.0);
	check_albedo(kg_material_library_find(lib, "urushi"), 0.0);
	check_albedo(kg_material_library_find(lib, "urushi"), 65.0);

	/* a white Lambertian body (n = 1: no surface reflection): albedo exactly 1 */
	kg_material white = {.kind = KG_MATERIAL_DIELECTRIC, .roughness = 0.1,
	                     .mirror_width = 0.02};
	snprintf(white.name, sizeof(white.name), "white");
	white.nk.n = kg_spectrum_const(1.0);
	white.body = kg_spectrum_const(1.0);
	check_albedo(&white, 30.0);
	kg_render_material *rm = NULL;
	if (kg_render_material_new(&white, &rm, &err) == 0) {
		double N[3] = {0, 0, 1}, V[3] = {0.6, 0, 0.8};
		kg_spectrum a;
		kg_render_material_albedo(rm, N, V, 1000, 3, &a);
		CHECK_NEAR(a.v[20], 1.0, 1e-6, "white Lambertian: every sample weighs 1");
		kg_render_material_free(&rm);
	}
	kg_material_library_free(&lib);
	return kg_test_done("render-bsdf");
}
