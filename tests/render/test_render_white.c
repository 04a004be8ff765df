/* White, diffuse surfaces:
 *  - neutral: a white Lambertian sphere (body 0.8, no surface reflection) under a D65
 *    light and a D65 environment, 4 hero wavelengths per path, renders neutral: the
 *    lit face's a*, b* relative to the D65 white within 0.5 (the colour noise of the
 *    random bands averaged over the region; measured below 0.15).
 *  - furnace: a white, non-absorbing Lambertian sphere resting on a white plane in a
 *    uniform equal-energy environment of radiance 1, 64 bounces: every pixel returns
 *    the environment's radiance, Y = 1, whatever the interreflections. With all 61
 *    bands every path carries exactly 1 (or 0 if still bouncing after 64 bounces), so
 *    the image mean is within 1e-3 below 1 and no pixel exceeds 1 + 1e-5. With 4 hero
 *    wavelengths each path's Y depends on its random bands; the image mean must lie
 *    within 4 standard errors of 1, the standard error computed here from the spread
 *    of that estimate over the 61 possible hero bands (CIE weights of core/). */
#include <unistd.h>

#include "render_test.h"

#define NEUTRAL_TOL 0.5

static const char library[] =
	"{\"format\": \"kogei-materials/1\", \"materials\": [\n"
	" {\"name\": \"white\", \"kind\": \"dielectric\", \"n\": 1.0, \"body\": 1.0,\n"
	"  \"gloss\": 0, \"mirror\": 0},\n"
	" {\"name\": \"matte-white\", \"kind\": \"dielectric\", \"n\": 1.0, \"body\": 0.8,\n"
	"  \"gloss\": 0, \"mirror\": 0}]}\n";

static void check_neutral(void)
{
	char scene[512];
	render_test_write(scene, sizeof(scene), "neutral.json",
		"{\"format\": \"kogei-scene/1\",\n"
		" \"mesh\": {\"generator\": \"icosphere\", \"level\": 4},\n"
		" \"materials\": {\"library\": \"lib.json\", \"material\": \"matte-white\"},\n"
		" \"light\": {\"illuminant\": \"D65\", \"direction\": [0.3, -1, 0.4],\n"
		"           \"intensity\": 1},\n"
		" \"environment\": {\"illuminant\": \"D65\", \"intensity\": 0.3},\n"
		" \"camera\": {\"position\": [0, -4, 0], \"look_at\": [0, 0, 0], \"fov_deg\": 10,\n"
		"            \"width\": 32, \"height\": 32},\n"
		" \"sampling\": {\"spp\": 64, \"wavelengths\": 4, \"bounces\": 4, \"seed\": 3}}\n");
	kg_xyz white;
	kg_image *img = render_test_render(scene, NULL, NULL, &white);
	kg_xyz got = render_test_mean(img, 8, 8, 24, 24);
	kg_image_free(&img);
	kg_illuminant *d65 = NULL;
	kg_err err;
	if (kg_illuminant_by_name("D65", &d65, &err) == 0) {
		kg_xyz w = kg_illuminant_white(d65);
		w = (kg_xyz){w.X / 100.0, w.Y / 100.0, w.Z / 100.0};
		CHECK_NEAR(white.X, w.X, 1e-9, "the image's white is D65's");
		CHECK_NEAR(white.Z, w.Z, 1e-9, "the image's white is D65's");
		kg_lab lab = kg_xyz_to_lab(got, w);
		printf("neutral: white Lambertian sphere under D65: L* %.2f a* %+.3f b* %+.3f\n",
		       lab.L, lab.a, lab.b);
		CHECK(fabs(lab.a) <= NEUTRAL_TOL && fabs(lab.b) <= NEUTRAL_TOL,
		      "white sphere under D65: a* %.3f b* %.3f, expected within %g of 0", lab.a,
		      lab.b, NEUTRAL_TOL);
		CHECK(lab.L > 50.0, "the lit face is bright (L* %.1f)", lab.L);
	}
	kg_illuminant_free(&d65);
}

/* The standard deviation of one path's Y estimate with n hero wavelengths in a
 * uniform environment of Y = 1: over the 61 equally likely hero bands. */
static double hero_sd(int n)
{
	kg_illuminant *e = NULL;
	kg_err err;
	if (kg_illuminant_by_name("E", &e, &err))
		return NAN;
	kg_xyz_weights w;
	kg_xyz_weights_signal(e, &w);
	double y = 0.0;
	for (int i = 0; i < KG_NBANDS; i++)
		y += w.w[1][i] * e->spd.v[i];
	double sum2 = 0.0;
	for (int h = 0; h < KG_NBANDS; h++) {
		double est = 0.0;
		for (int j = 0; j < n; j++) {
			int b = (h + j * KG_NBANDS / n) % KG_NBANDS;
			est += (double)KG_NBANDS / n * w.w[1][b] * e->spd.v[b] / y;
		}
		sum2 += (est - 1.0) * (est - 1.0);
	}
	kg_illuminant_free(&e);
	return sqrt(sum2 / KG_NBANDS);
}

static void check_furnace(void)
{
	char scene[512];
	render_test_write(scene, sizeof(scene), "furnace.json",
		"{\"format\": \"kogei-scene/1\",\n"
		" \"mesh\": [{\"generator\": \"icosphere\", \"level\": 4, \"translate\": [0, 0, 1]},\n"
		"          {\"generator\": \"plane\", \"half_size\": 3}],\n"
		" \"materials\": {\"library\": \"lib.json\", \"material\": \"white\"},\n"
		" \"environment\": {\"illuminant\": \"E\", \"intensity\": 1},\n"
		" \"camera\": {\"position\": [0, -5, 2.5], \"look_at\": [0, 0, 0.7], \"fov_deg\": 40,\n"
		"            \"width\": 48, \"height\": 36},\n"
		" \"sampling\": {\"spp\": 16, \"wavelengths\": \"all\", \"bounces\": 64, \"seed\": 5}}\n");
	kg_xyz white;
	kg_image *img = render_test_render(scene, NULL, NULL, &white);
	kg_xyz mean = render_test_mean(img, 0, 0, img->width, img->height);
	double ymax = 0.0, ymin = 2.0;
	for (size_t i = 0; i < (size_t)img->width * img->height; i++) {
		ymax = fmax(ymax, img->data[3 * i + 1]);
		ymin = fmin(ymin, img->data[3 * i + 1]);
	}
	kg_image_free(&img);
	printf("furnace, all bands: mean XYZ %.6f %.6f %.6f, pixel Y from %.6f to %.6f\n",
	       mean.X, mean.Y, mean.Z, ymin, ymax);
	CHECK(mean.Y >= 1.0 - 1e-3 && mean.Y <= 1.0 + 1e-5, "furnace: mean Y %.6f, expected 1",
	      mean.Y);
	CHECK(ymax <= 1.0 + 1e-5, "furnace: a pixel has Y %.6f > 1: energy created", ymax);
	CHECK(ymin >= 1.0 - 1e-3, "furnace: a pixel has Y %.6f < 1: energy lost", ymin);
	CHECK(fabs(mean.X / mean.Y - white.X) <= 1e-4 && fabs(mean.Z / mean.Y - white.Z) <= 1e-4,
	      "furnace: the colour of the environment (its white %.6f %.6f %.6f), got %.6f "
	      "%.6f %.6f", white.X, white.Y, white.Z, mean.X, mean.Y, mean.Z);

	/* the same scene absorbing 20 % per bounce: the object is there and is seen */
	img = render_test_render(scene, "matte-white", NULL, NULL);
	kg_xyz absorbing = render_test_mean(img, 0, 0, img->width, img->height);
	kg_image_free(&img);
	printf("furnace with body 0.8: mean Y %.4f\n", absorbing.Y);
	CHECK(absorbing.Y < 0.95, "the furnace scene's object is not seen (mean Y %.4f with "
	      "an absorbing body)", absorbing.Y);

	kg_render_options opt = {.wavelengths = 4, .spp = 32};
	img = render_test_render(scene, NULL, &opt, NULL);
	mean = render_test_mean(img, 0, 0, img->width, img->height);
	double paths = (double)img->width * img->height * opt.spp;
	kg_image_free(&img);
	double se = hero_sd(4) / sqrt(paths);
	printf("furnace, 4 hero wavelengths: mean Y %.6f, standard error %.6f\n", mean.Y, se);
	CHECK(isfinite(se) && fabs(mean.Y - 1.0) <= 4.0 * se + 1e-3, "furnace (hero): mean Y "
	      "%.6f, expected 1 within %.6f", mean.Y, 4.0 * se + 1e-3);
}

/* Shadows: a matte sphere over a matte plane, lit by a light alone from 45 degrees on
 * one side, seen from straight above. The plane at 1.9 units on the light's side is
 * lit; at 1.9 on the other side it lies in the sphere's shadow (the shadow of a unit
 * sphere at height 1 spans -2.41 .. 0.41 along the light's azimuth) and gets only
 * what the sphere reflects. Neither point is hidden from the camera by the sphere.
 * With the light moved to the other side, the dark side must follow. The light is
 * also given as a CGATS spectrum (colord's CIE D65): the lit plane must match the
 * named D65 within 0.5 %. */
static void check_shadow(void)
{
	double side[2][2]; /* [light from -x / +x][patch at image left / right] */
	for (int k = 0; k < 2; k++) {
		char scene[512];
		render_test_write(scene, sizeof(scene), "shadow.json",
			"{\"format\": \"kogei-scene/1\",\n"
			" \"mesh\": [{\"generator\": \"icosphere\", \"level\": 4, \"translate\": [0, 0, 1]},\n"
			"          {\"generator\": \"plane\", \"half_size\": 6}],\n"
			" \"materials\": {\"library\": \"lib.json\", \"material\": \"matte-white\"},\n"
			" \"light\": {\"illuminant\": \"D65\", \"direction\": [%d, 0, 1], \"intensity\": 1},\n"
			" \"camera\": {\"position\": [0, 0, 10], \"look_at\": [0, 0, 0], \"up\": [0, 1, 0],\n"
			"            \"fov_deg\": 40, \"width\": 64, \"height\": 64},\n"
			" \"sampling\": {\"spp\": 16, \"wavelengths\": 4, \"bounces\": 4, \"seed\": 7}}\n",
			k ? 1 : -1);
		kg_image *img = render_test_render(scene, NULL, NULL, NULL);
		/* x = -1.9 and +1.9 on the plane: columns 32 -/+ 1.9 / (10 tan 20 deg) * 32 */
		int dx = (int)lround(1.9 / (10 * tan(20 * M_PI / 180)) * 32);
		side[k][0] = render_test_mean(img, 32 - dx - 2, 30, 32 - dx + 2, 34).Y;
		side[k][1] = render_test_mean(img, 32 + dx - 2, 30, 32 + dx + 2, 34).Y;
		kg_image_free(&img);
	}
	printf("shadow: light from -x: plane Y left %.4f right %.4f; from +x: left %.4f right "
	       "%.4f\n",
	       side[0][0], side[0][1], side[1][0], side[1][1]);
	/* the side away from the light is in shadow, whichever way the image is oriented */
	int lit0 = side[0][0] > side[0][1], lit1 = side[1][0] > side[1][1];
	double r0 = fmin(side[0][0], side[0][1]) / fmax(side[0][0], side[0][1]);
	double r1 = fmin(side[1][0], side[1][1]) / fmax(side[1][0], side[1][1]);
	CHECK(lit0 != lit1, "shadow: moving the light to the other side did not move the shadow");
	CHECK(r0 < 0.2 && r1 < 0.2, "shadow: shadowed/lit plane %.3f and %.3f, expected < 0.2",
	      r0, r1);
	CHECK(fabs(side[0][lit0 ? 0 : 1] / side[1][lit1 ? 0 : 1] - 1) < 0.02,
	      "shadow: the lit plane differs between the two sides: %.4f vs %.4f",
	      side[0][lit0 ? 0 : 1], side[1][lit1 ? 0 : 1]);

	const char *cgats = "/usr/share/colord/illuminant/CIE-D65.sp";
	if (access(cgats, R_OK) != 0) {
		printf("%s absent (colord-data): the CGATS light is not checked\n", cgats);
		return;
	}
	double lit[2];
	for (int k = 0; k < 2; k++) {
		char scene[512];
		render_test_write(scene, sizeof(scene), "lit.json",
			"{\"format\": \"kogei-scene/1\",\n"
			" \"mesh\": {\"generator\": \"plane\", \"half_size\": 6},\n"
			" \"materials\": {\"library\": \"lib.json\", \"material\": \"matte-white\"},\n"
			" \"light\": {\"illuminant\": \"%s\", \"direction\": [1, 0, 1], \"intensity\": 1},\n"
			" \"camera\": {\"position\": [0, 0, 10], \"look_at\": [0, 0, 0], \"up\": [0, 1, 0],\n"
			"            \"fov_deg\": 20, \"width\": 16, \"height\": 16},\n"
			" \"sampling\": {\"spp\": 4, \"wavelengths\": \"all\", \"bounces\": 1, \"seed\": 7}}\n",
			k ? cgats : "D65");
		kg_image *img = render_test_render(scene, NULL, NULL, NULL);
		lit[k] = render_test_mean(img, 0, 0, img->width, img->height).Y;
		kg_image_free(&img);
	}
	printf("light D65 by name: plane Y %.5f; from %s: %.5f\n", lit[0], cgats, lit[1]);
	CHECK(lit[0] > 0 && fabs(lit[1] / lit[0] - 1) < 0.005,
	      "a CGATS D65 light gives Y %.5f, the named D65 %.5f", lit[1], lit[0]);
}

int main(void)
{
	render_test_init();
	char lib[512];
	render_test_write(lib, sizeof(lib), "lib.json", "%s", library);
	check_neutral();
	check_furnace();
	check_shadow();
	render_test_cleanup();
	return kg_test_done("render-white");
}
