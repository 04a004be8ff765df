/* Camera responses and scene layout with a synthetic camera and illuminant (no
 * files): the exposure puts the perfect diffuser's brightest channel exactly at the
 * white level, responses equal a direct long-double integration, seeds fix the
 * output, and scenes are laid out as documented in kg_sim.h. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "kg_sim.h"
#include "kg_test.h"

static kg_sim_camera synthetic_camera(void)
{
	kg_sim_camera cam;
	memset(&cam, 0, sizeof(cam));
	snprintf(cam.name, sizeof(cam.name), "gaussian");
	static const double peak[3] = {600.0, 540.0, 460.0}, height[3] = {0.8, 1.0, 0.6};
	for (int ch = 0; ch < 3; ch++)
		for (int i = 0; i < KG_NBANDS; i++) {
			double d = (kg_band_nm(i) - peak[ch]) / 30.0;
			cam.sens[ch].v[i] = height[ch] * exp(-0.5 * d * d);
		}
	return cam;
}

static kg_spectrum sloped_illuminant(void)
{
	kg_spectrum e;
	for (int i = 0; i < KG_NBANDS; i++)
		e.v[i] = 50.0 + 0.2 * (kg_band_nm(i) - 400.0);
	return e;
}

/* A smooth step between 0.05 and 0.95 at a random place. */
static kg_spectrum random_reflectance(kg_rng *r)
{
	kg_spectrum s;
	double a = kg_rng_uniform(r), b = kg_rng_uniform(r), c = 400 + 300 * kg_rng_uniform(r);
	for (int i = 0; i < KG_NBANDS; i++)
		s.v[i] = 0.05 + 0.45 * (a + b * (0.5 + 0.5 * tanh((kg_band_nm(i) - c) / 40.0)));
	return s;
}

/* The textbook sum, in long double, with the exposure worked out separately. */
static void direct(const kg_sim_camera *cam, const kg_spectrum *e, const kg_spectrum *r,
                   double white_level, double rgb[3])
{
	long double white[3] = {0}, resp[3] = {0};
	for (int ch = 0; ch < 3; ch++)
		for (int i = 0; i < KG_NBANDS; i++) {
			long double es = (long double)e->v[i] * cam->sens[ch].v[i] * 5.0L;
			white[ch] += es;
			resp[ch] += es * r->v[i];
		}
	long double top = fmaxl(white[0], fmaxl(white[1], white[2]));
	for (int ch = 0; ch < 3; ch++)
		rgb[ch] = (double)(resp[ch] * white_level / top);
}

static void test_exposure_and_integration(void)
{
	kg_sim_camera cam = synthetic_camera();
	kg_spectrum e = sloped_illuminant();
	kg_spectrum one = kg_spectrum_const(1.0);
	static const double levels[] = {0.9, 0.5, 1.0, 0.37, 0.999};
	for (size_t k = 0; k < sizeof(levels) / sizeof(levels[0]); k++) {
		kg_sim_capture c;
		kg_err err = {{0}};
		CHECK(kg_sim_capture_init(&c, &cam, &e, levels[k], NULL, &err) == 0, "%s", err.msg);
		double w[3];
		kg_sim_capture_mean(&c, &one, w);
		double top = fmax(w[0], fmax(w[1], w[2]));
		CHECK_NEAR(top, levels[k], 4 * DBL_EPSILON, "white level");
		/* green peaks highest in this camera */
		CHECK(w[1] == top, "brightest channel is not green: %g %g %g", w[0], w[1], w[2]);
		kg_rng r;
		kg_rng_seed(&r, k);
		double worst = 0.0;
		for (int n = 0; n < 200; n++) {
			kg_spectrum s = random_reflectance(&r);
			double a[3], b[3];
			kg_sim_capture_mean(&c, &s, a);
			direct(&cam, &e, &s, levels[k], b);
			/* the colour signal E R through the same exposure reads the same */
			kg_spectrum signal = kg_spectrum_mul(&e, &s);
			double sig[3];
			kg_sim_capture_signal_mean(&c, &signal, sig);
			for (int ch = 0; ch < 3; ch++)
				worst = fmax(worst, fmax(fabs(a[ch] - b[ch]), fabs(sig[ch] - b[ch])));
		}
		CHECK(worst < 1e-14, "white level %g: differs from direct integration by %g",
		      levels[k], worst);
	}
}

static void test_capture_errors(void)
{
	kg_sim_camera cam = synthetic_camera();
	kg_spectrum dark = kg_spectrum_const(0.0), e = sloped_illuminant();
	kg_sim_capture c;
	kg_err err = {{0}};
	CHECK(kg_sim_capture_init(&c, &cam, &dark, 0.9, NULL, &err) == KG_EINVAL,
	      "a dark illuminant was accepted");
	CHECK(strstr(err.msg, "gaussian") && strstr(err.msg, "no response"), "message: %s",
	      err.msg);
	CHECK(kg_sim_capture_init(&c, &cam, &e, 0.0, NULL, &err) == KG_EINVAL,
	      "white level 0 accepted");
	CHECK(kg_sim_capture_init(&c, &cam, &e, NAN, NULL, &err) == KG_EINVAL,
	      "white level NaN accepted");
}

static void test_patches_seed(void)
{
	kg_sim_camera cam = synthetic_camera();
	kg_spectrum e = sloped_illuminant();
	kg_spectrum s[24];
	kg_rng r;
	kg_rng_seed(&r, 99);
	for (int i = 0; i < 24; i++)
		s[i] = random_reflectance(&r);
	kg_sim_noise noise;
	CHECK(kg_sim_noise_parse("20000:5:12", &noise, NULL) == 0, "noise");
	kg_sim_capture clean, noisy;
	CHECK(kg_sim_capture_init(&clean, &cam, &e, 0.9, NULL, NULL) == 0, "init");
	CHECK(kg_sim_capture_init(&noisy, &cam, &e, 0.9, &noise, NULL) == 0, "init");
	double a[72], b[72], c[72], m[72];
	kg_sim_patches(&clean, s, 24, 1, a);
	for (int i = 0; i < 24; i++)
		kg_sim_capture_mean(&clean, &s[i], m + 3 * i);
	CHECK(memcmp(a, m, sizeof(a)) == 0, "noise-free patches differ from the mean");
	kg_sim_patches(&noisy, s, 24, 1, a);
	kg_sim_patches(&noisy, s, 24, 1, b);
	kg_sim_patches(&noisy, s, 24, 2, c);
	CHECK(memcmp(a, b, sizeof(a)) == 0, "same seed, different output");
	int differ = 0;
	double worst = 0.0;
	for (int i = 0; i < 72; i++) {
		differ += a[i] != c[i];
		worst = fmax(worst, fabs(a[i] - m[i]));
	}
	CHECK(differ > 36, "seeds 1 and 2 agree in %d of 72 values", 72 - differ);
	CHECK(worst > 0.0 && worst < 0.05, "noise amplitude %g implausible", worst);
}

static void test_scene(void)
{
	kg_sim_camera cam = synthetic_camera();
	kg_spectrum e = sloped_illuminant();
	kg_spectrum patches[5], materials[3];
	kg_rng r;
	kg_rng_seed(&r, 3);
	for (int i = 0; i < 5; i++)
		patches[i] = random_reflectance(&r);
	for (int i = 0; i < 3; i++)
		materials[i] = random_reflectance(&r);
	const char *pn[5] = {"A1", "A2", "A3", "A4", "A5"};
	const char *mn[3] = {"gold", "silver", "urushi"};
	kg_sim_scene_desc d = {
	    .patches = patches, .patch_names = pn, .npatches = 5,
	    .materials = materials, .material_names = mn, .nmaterials = 3,
	    .tile = 4, .gap = 2, .columns = 3, .background = 0.05,
	};
	kg_sim_capture clean;
	CHECK(kg_sim_capture_init(&clean, &cam, &e, 0.9, NULL, NULL) == 0, "init");
	kg_sim_scene *s = NULL;
	kg_err err = {{0}};
	CHECK(kg_sim_scene_new(&d, &clean, 1, &s, &err) == 0, "%s", err.msg);
	if (!s)
		return;
	/* 3 columns of (4 + 2) + 2; 2 patch rows + 1 material row */
	CHECK(s->width == 20 && s->height == 20, "size %d x %d, expected 20 x 20", s->width,
	      s->height);
	CHECK(s->nsamples == 8 && s->nclasses == 5, "%d samples, %d classes", s->nsamples,
	      s->nclasses);
	static const char *const classes[5] = {"unclassified", "gold", "silver", "urushi",
	                                       "chart"};
	for (int k = 0; k < 5 && k < s->nclasses; k++)
		CHECK(strcmp(s->class_names[k], classes[k]) == 0, "class %d is %s, expected %s", k,
		      s->class_names[k], classes[k]);
	/* tile (row, col) -> sample: patches 0-4 in rows 0-1, materials 5-7 in row 2 */
	static const int expect[3][3] = {{0, 1, 2}, {3, 4, -1}, {5, 6, 7}};
	for (int row = 0; row < 3; row++)
		for (int col = 0; col < 3; col++) {
			int x = 2 + col * 6 + 1, y = 2 + row * 6 + 2;
			size_t p = (size_t)y * 20 + (size_t)x;
			int want = expect[row][col];
			int cls = want < 0 ? 0 : want < 5 ? 4 : want - 4;
			CHECK(s->sample[p] == want, "tile %d,%d holds sample %d, expected %d", row, col,
			      s->sample[p], want);
			CHECK(s->label[p] == cls, "tile %d,%d has class %d, expected %d", row, col,
			      s->label[p], cls);
		}
	CHECK(s->sample[0] == -1 && s->label[0] == 0, "corner is not background");
	CHECK(s->sample[2 * 20 + 2] == 0 && s->sample[2 * 20 + 5] == 0 &&
	          s->sample[2 * 20 + 6] == -1,
	      "tile 0 does not span x 2..5");
	/* Noise-free pixels are the rounded means; background too. */
	int bad = 0;
	for (int p = 0; p < 400; p++) {
		double m[3];
		kg_sim_capture_mean(&clean, s->sample[p] < 0 ? &s->background : &s->truth[s->sample[p]],
		                    m);
		for (int ch = 0; ch < 3; ch++)
			bad += s->rgb[3 * p + ch] != (float)m[ch];
	}
	CHECK(bad == 0, "%d noise-free pixel values differ from the mean", bad);
	CHECK(s->truth[6].v[10] == materials[1].v[10], "truth of silver");
	CHECK(strcmp(s->sample_names[2], "A3") == 0 && strcmp(s->sample_names[7], "urushi") == 0,
	      "sample names");

	/* Noisy scenes: same seed, same pixels; another seed, other pixels. */
	kg_sim_noise noise;
	CHECK(kg_sim_noise_parse("20000:5:12", &noise, NULL) == 0, "noise");
	kg_sim_capture noisy;
	CHECK(kg_sim_capture_init(&noisy, &cam, &e, 0.9, &noise, NULL) == 0, "init");
	kg_sim_scene *a = NULL, *b = NULL, *c = NULL;
	CHECK(kg_sim_scene_new(&d, &noisy, 7, &a, NULL) == 0, "scene a");
	CHECK(kg_sim_scene_new(&d, &noisy, 7, &b, NULL) == 0, "scene b");
	CHECK(kg_sim_scene_new(&d, &noisy, 8, &c, NULL) == 0, "scene c");
	if (a && b && c) {
		CHECK(memcmp(a->rgb, b->rgb, 400 * 3 * sizeof(float)) == 0, "same seed differs");
		CHECK(memcmp(a->rgb, c->rgb, 400 * 3 * sizeof(float)) != 0, "seeds 7 and 8 agree");
	}
	kg_sim_scene_free(&a);
	kg_sim_scene_free(&b);
	kg_sim_scene_free(&c);
	CHECK(a == NULL, "free does not null the pointer");
	kg_sim_scene_free(&s);

	/* Bad descriptions are refused with a message. */
	kg_sim_scene_desc bad_desc = d;
	bad_desc.tile = 0;
	CHECK(kg_sim_scene_new(&bad_desc, &clean, 1, &s, &err) == KG_EINVAL && !s,
	      "tile 0 accepted");
	CHECK(strstr(err.msg, "tile") != NULL, "message: %s", err.msg);
	bad_desc = d;
	bad_desc.npatches = 0;
	bad_desc.nmaterials = 0;
	CHECK(kg_sim_scene_new(&bad_desc, &clean, 1, &s, &err) == KG_EINVAL && !s,
	      "empty scene accepted");
	bad_desc = d;
	patches[2].v[3] = NAN;
	CHECK(kg_sim_scene_new(&bad_desc, &clean, 1, &s, &err) == KG_EINVAL && !s,
	      "NaN spectrum accepted");
	CHECK(strstr(err.msg, "A3") != NULL, "message does not name the patch: %s", err.msg);
}

int main(void)
{
	test_exposure_and_integration();
	test_capture_errors();
	test_patches_seed();
	test_scene();
	return kg_test_done("sim/capture");
}
