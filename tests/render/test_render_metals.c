/* A sphere of each metal and alloy of the library (gold, silver, copper, shakudo and the
 * five shibuichi of the paper's Table 1) under a
 * uniform environment (equal energy, and D65 with all bands), seen head-on through a narrow field of view, so
 * the pixels see the sphere within about 6 degrees of normal incidence. A convex
 * object in a uniform environment reflects the environment's radiance times its
 * directional albedo; near normal incidence the metal lobes reflect at V.H close to 1,
 * so the colour is that of the normal-incidence Fresnel reflectance F(0) of optics/.
 *
 * Checked, with all 61 bands per path and with 4 hero wavelengths per path:
 *  - chromaticity: CIEDE2000 between the rendered colour (scaled to the luminance of
 *    F(0)) and F(0) under the environment's illuminant. Tolerance 0.1 for all bands
 *    (what remains is F at V.H slightly below 1 inside the lobes and the tabulation
 *    of F: measured below 0.001); 0.5 for 4 hero wavelengths, whose random bands add
 *    colour noise (measured 0.03-0.09 at 256 samples per pixel on 256 pixels).
 *  - luminance: Y against the Y of the directional albedo at normal incidence, the
 *    integral of kg_material_eval over the hemisphere (a quadrature here), within
 *    0.5 % (all bands) or 1 % (hero wavelengths); measured within 0.02 %. */
#include "render_test.h"

#define DE_ALL 0.1
#define DE_HERO 0.5
#define Y_ALL 0.005
#define Y_HERO 0.01

/* The directional albedo at V = N: the model is symmetric about N there, so a 1-D
 * integral over the angle theta of L from N, finest near 0 where the lobes peak. */
static void albedo_normal(const kg_material *mat, kg_spectrum *out)
{
	const int n = 20000;
	double N[3] = {0, 0, 1};
	memset(out, 0, sizeof(*out));
	for (int i = 0; i < n; i++) {
		double x = (i + 0.5) / n;
		double th = M_PI_2 * x * x, dth = M_PI * x / n;
		double L[3] = {sin(th), 0, cos(th)};
		kg_spectrum f;
		kg_err err;
		if (kg_material_eval(mat, N, N, L, &f, &err) != 0) {
			fprintf(stderr, "%s\n", err.msg);
			exit(1);
		}
		for (int k = 0; k < KG_NBANDS; k++)
			out->v[k] += 2.0 * M_PI * sin(th) * dth * f.v[k];
	}
}

static kg_xyz scaled(kg_xyz c, double s)
{
	return (kg_xyz){c.X * s, c.Y * s, c.Z * s};
}

/* Every metal under a uniform environment of illuminant `env`; hero wavelengths too
 * when `hero` is set. */
static void check_environment(const kg_material_library *lib, const char *env, int hero)
{
	static const char *const metals[] = {
		"gold", "silver", "copper", "shakudo", "shibuichi-nami", "shibuichi-shiro",
		"shibuichi-jo", "shibuichi-nami-uchisanbu", "shibuichi-nami-sotosanbu"};
	const int nmetals = (int)(sizeof(metals) / sizeof(metals[0]));
	kg_err err;
	kg_illuminant *ill = NULL;
	if (kg_illuminant_by_name(env, &ill, &err)) {
		CHECK(0, "%s", err.msg);
		return;
	}
	char scene[512];
	render_test_write(scene, sizeof(scene), "sphere.json",
		"{\"format\": \"kogei-scene/1\",\n"
		" \"mesh\": {\"generator\": \"icosphere\", \"level\": 5},\n"
		" \"materials\": {\"material\": \"gold\"},\n"
		" \"environment\": {\"illuminant\": \"%s\", \"intensity\": 1},\n"
		" \"camera\": {\"position\": [0, -4, 0], \"look_at\": [0, 0, 0], \"fov_deg\": 3,\n"
		"            \"width\": 16, \"height\": 16},\n"
		" \"sampling\": {\"spp\": 256, \"wavelengths\": 4, \"bounces\": 4, \"seed\": 11}}\n",
		env);
	for (int i = 0; i < nmetals; i++) {
		const kg_material *mat = kg_material_library_find(lib, metals[i]);
		kg_spectrum f0, albedo;
		if (!mat || kg_material_reflectance(mat, 0.0, &f0, &err)) {
			CHECK(0, "%s: %s", metals[i], mat ? err.msg : "not in the library");
			continue;
		}
		albedo_normal(mat, &albedo);
		kg_xyz want = scaled(kg_reflectance_to_xyz(&f0, ill), 0.01);
		kg_xyz want_y = scaled(kg_reflectance_to_xyz(&albedo, ill), 0.01);
		for (int mode = 0; mode < 1 + hero; mode++) {
			kg_render_options opt = {.wavelengths = mode ? 4 : KG_RENDER_ALL_BANDS,
			                         .spp = mode ? 256 : 64};
			kg_xyz white;
			kg_image *img = render_test_render(scene, metals[i], &opt, &white);
			kg_xyz got = render_test_mean(img, 0, 0, img->width, img->height);
			kg_image_free(&img);
			kg_lab lab_want = kg_xyz_to_lab(want, white);
			kg_lab lab_got = kg_xyz_to_lab(scaled(got, want.Y / got.Y), white);
			double de = kg_ciede2000(lab_want, lab_got);
			double dy = got.Y / want_y.Y - 1.0;
			printf("%-3s %-15s %-6s rendered xy %.4f %.4f  F(0) xy %.4f %.4f  dE00 %.3f  "
			       "Y %.4f vs albedo %.4f (%+.2f %%)\n", env, metals[i],
			       mode ? "hero 4" : "all", got.X / (got.X + got.Y + got.Z),
			       got.Y / (got.X + got.Y + got.Z), want.X / (want.X + want.Y + want.Z),
			       want.Y / (want.X + want.Y + want.Z), de, got.Y, want_y.Y, 100.0 * dy);
			CHECK(de <= (mode ? DE_HERO : DE_ALL), "%s under %s (%s): dE00 %.3f from F(0)",
			      metals[i], env, mode ? "hero" : "all bands", de);
			CHECK(fabs(dy) <= (mode ? Y_HERO : Y_ALL), "%s under %s (%s): Y %.5f, albedo "
			      "%.5f", metals[i], env, mode ? "hero" : "all bands", got.Y, want_y.Y);
		}
	}
	kg_illuminant_free(&ill);
}

int main(void)
{
	render_test_init();
	kg_err err;
	kg_material_library *lib = NULL;
	char *path = kg_data_path("materials/default.json");
	if (!path || kg_material_library_load(path, &lib, &err)) {
		fprintf(stderr, "%s\n", path ? err.msg : "materials/default.json not found");
		return 1;
	}
	free(path);
	check_environment(lib, "E", 1);
	check_environment(lib, "D65", 0);
	kg_material_library_free(&lib);
	render_test_cleanup();
	return kg_test_done("render-metals");
}
