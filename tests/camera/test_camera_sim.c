/* The sim camera against its own noise model (docs/cameras.md): the mean signal is
 * linear in exposure and in linear gain, the variance is Poisson plus read noise
 * (scaled by the conversion gain, plus 1/12 DN^2 of rounding), full scale clips,
 * the Bayer mosaic samples the colour its CFA names, auto white balance and auto
 * exposure act until kg_camera_manual turns them off, and a frame depends only on
 * (seed, sequence, settings); the live view (kg_camera_preview) has the frames' mean
 * and variance. Tolerances are 5 standard errors of the statistic. */
#include <math.h>
#include <string.h>

#include "camera_test.h"

#define FULLWELL 10000.0
#define REF_US 10000.0
#define NSTRIP 3
static const double strip_level[NSTRIP] = {0.1, 0.3, 0.6};

/* A 96x64 float scene: three vertical strips of 32 columns. */
static void write_strips(const char *path)
{
	kg_image *img;
	kg_err e = {{0}};
	cam_must(kg_image_new(96, 64, 1, &img, &e), &e, "kg_image_new");
	for (int y = 0; y < 64; y++)
		for (int x = 0; x < 96; x++)
			img->data[y * 96 + x] = (float)strip_level[x / 32];
	cam_must(kg_image_write(img, path, 32, &e), &e, path);
	kg_image_free(&img);
}

static void write_rgb(const char *path, float r, float g, float b)
{
	kg_image *img;
	kg_err e = {{0}};
	cam_must(kg_image_new(8, 6, 3, &img, &e), &e, "kg_image_new");
	for (int i = 0; i < 8 * 6; i++) {
		img->data[3 * i] = r;
		img->data[3 * i + 1] = g;
		img->data[3 * i + 2] = b;
	}
	cam_must(kg_image_write(img, path, 32, &e), &e, path);
	kg_image_free(&img);
}

static void set(kg_camera *c, kg_feature f, double v)
{
	kg_err e = {{0}};
	double got = NAN;
	int ret = kg_camera_set(c, f, v, &got, &e);
	CHECK(ret == 0 && got == v, "set %s %g: %d got %g: %s", kg_feature_name(f), v, ret, got,
	      e.msg);
}

static double get(kg_camera *c, kg_feature f)
{
	kg_err e = {{0}};
	double v = NAN;
	CHECK(kg_camera_get(c, f, &v, &e) == 0, "get %s: %s", kg_feature_name(f), e.msg);
	return v;
}

/* Pop nframes and accumulate, per strip, the sum and sum of squares of DN. */
static void strip_stats(kg_camera *c, int nframes, double mean[NSTRIP], double var[NSTRIP],
                        unsigned *maxdn_seen)
{
	double s[NSTRIP] = {0}, s2[NSTRIP] = {0};
	long n[NSTRIP] = {0};
	*maxdn_seen = 0;
	for (int k = 0; k < nframes; k++) {
		kg_frame f;
		kg_err e = {{0}};
		cam_must(kg_camera_pop(c, 1000, &f, &e), &e, "pop");
		for (int y = 0; y < f.fmt.height; y++)
			for (int x = 0; x < f.fmt.width; x++) {
				unsigned v = cam_sample(&f, x, y, 0);
				int i = x / 32;
				s[i] += v;
				s2[i] += (double)v * v;
				n[i]++;
				if (v > *maxdn_seen)
					*maxdn_seen = v;
			}
		cam_must(kg_camera_push(c, &f, &e), &e, "push");
	}
	for (int i = 0; i < NSTRIP; i++) {
		mean[i] = s[i] / (double)n[i];
		var[i] = (s2[i] - s[i] * mean[i]) / (double)(n[i] - 1);
	}
}

/* The live view (kg_camera_preview): the same mean and variance as the frames (shot
 * and read noise, here Gaussian from a table), the settings in force (exposure
 * doubled: twice the mean), counted on its own: the stream is not started, and its
 * first frame afterwards is still number 1. */
static void test_preview(void)
{
	const double read_e = 8;
	const char *scene = kg_test_path("strips.tif");
	kg_inputs_reset();
	write_strips(scene);
	char uri[4600];
	snprintf(uri, sizeof(uri), "sim:%s?format=mono12&fullwell=%g&read=%g&seed=7&"
	         "ref_exposure_us=%g&fps=200", scene, FULLWELL, read_e, REF_US);
	kg_camera *c = cam_open(uri);
	kg_err e = {{0}};
	cam_must(kg_camera_manual(c, &e), &e, "kg_camera_manual");
	CHECK(kg_camera_has_preview(c), "the sim camera has its own preview");
	const int nframes = 4;
	for (int k = 0; k < 2; k++) {
		double f = k ? 0.5 : 0.25;
		set(c, KG_FEAT_EXPOSURE_US, f * REF_US);
		double mean[NSTRIP], var[NSTRIP];
		/* the preview count goes on across settings: number from it */
		kg_frame fr;
		int own = 0;
		cam_must(kg_camera_preview(c, 1000, &fr, &own, &e), &e, "preview");
		CHECK(fr.fmt.pixfmt == KG_PIX_MONO16 && fr.fmt.width == 96 && fr.fmt.height == 64 &&
		          fr.exposure_us == f * REF_US,
		      "preview format %s %dx%d, exposure %g", kg_pixfmt_name(fr.fmt.pixfmt),
		      fr.fmt.width, fr.fmt.height, fr.exposure_us);
		uint64_t base = fr.sequence;
		double s[NSTRIP] = {0}, s2[NSTRIP] = {0};
		long n = 0;
		for (int j = 0; j < nframes; j++) {
			cam_must(kg_camera_preview(c, 1000, &fr, &own, &e), &e, "preview");
			CHECK(own == 1 && fr.sequence == base + (uint64_t)j + 1, "preview sequence %llu",
			      (unsigned long long)fr.sequence);
			for (int y = 0; y < 64; y++)
				for (int x = 0; x < 96; x++) {
					unsigned v = cam_sample(&fr, x, y, 0);
					s[x / 32] += v;
					s2[x / 32] += (double)v * v;
				}
			n += 32 * 64;
		}
		double g = 4095 / FULLWELL;
		for (int i = 0; i < NSTRIP; i++) {
			mean[i] = s[i] / (double)n;
			var[i] = (s2[i] - s[i] * mean[i]) / (double)(n - 1);
			double mu_e = FULLWELL * strip_level[i] * f;
			double want_mean = mu_e * g, want_var = (mu_e + read_e * read_e) * g * g + 1.0 / 12.0;
			char what[96];
			snprintf(what, sizeof(what), "preview mean, level %.1f, exposure x%.2f",
			         strip_level[i], f);
			CHECK_NEAR(mean[i], want_mean, 5 * sqrt(want_var / n), what);
			snprintf(what, sizeof(what), "preview variance, level %.1f, exposure x%.2f",
			         strip_level[i], f);
			CHECK_NEAR(var[i], want_var, 5 * want_var * sqrt(2.0 / (n - 1)), what);
		}
	}
	kg_stream_stats st;
	kg_camera_stats(c, &st);
	CHECK(st.completed == 0, "previews are no stream frames (%llu completed)",
	      (unsigned long long)st.completed);
	cam_must(kg_camera_start(c, 0, &e), &e, "start");
	kg_frame fr;
	cam_must(kg_camera_pop(c, 1000, &fr, &e), &e, "pop");
	CHECK(fr.sequence == 1, "the stream's first frame after previews: sequence %llu",
	      (unsigned long long)fr.sequence);
	cam_must(kg_camera_push(c, &fr, &e), &e, "push");
	kg_camera_free(&c);
}

/* read_e: read noise in electrons; ncfg: how many of the settings below to take. */
static void test_physics(double read_e, int ncfg)
{
	const char *scene = kg_test_path("strips.tif");
	kg_inputs_reset(); /* the last round's camera read this scene */
	write_strips(scene);
	char uri[4600];
	snprintf(uri, sizeof(uri), "sim:%s?format=mono12&fullwell=%g&read=%g&seed=7&"
	         "ref_exposure_us=%g", scene, FULLWELL, read_e, REF_US);
	kg_camera *c = cam_open(uri);
	kg_err e = {{0}};
	const kg_camera_info *info = kg_camera_get_info(c);
	CHECK(!strcmp(info->transport, "sim") && info->sensor_width == 96 &&
	          info->sensor_height == 64 && !strcmp(info->backend, "sim"),
	      "info: %s %dx%d", info->transport, info->sensor_width, info->sensor_height);
	kg_frame_format fmt;
	cam_must(kg_camera_get_format(c, &fmt, &e), &e, "get_format");
	CHECK(fmt.pixfmt == KG_PIX_MONO16 && fmt.bits == 12 && fmt.width == 96 &&
	          fmt.stride == 192 && fmt.size == 192 * 64,
	      "format %s/%d %dx%d", kg_pixfmt_name(fmt.pixfmt), fmt.bits, fmt.width, fmt.height);

	/* Auto exposure is on at open: exposure cannot be set, and it sits where the mean
	 * luminance is 18 % of full scale (the strips' mean is 1/3). */
	CHECK(get(c, KG_FEAT_AUTO_EXPOSURE) == 1 && get(c, KG_FEAT_AUTO_WHITE_BALANCE) == 1,
	      "auto exposure and auto white balance start on");
	CHECK_NEAR(get(c, KG_FEAT_EXPOSURE_US), 0.18 * REF_US / (1.0 / 3.0), 1e-6 * REF_US,
	           "auto exposure");
	CHECK(kg_camera_set(c, KG_FEAT_EXPOSURE_US, 5000, NULL, &e) == KG_EINVAL &&
	          strstr(e.msg, "auto_exposure"),
	      "set exposure under auto exposure refused: %s", e.msg);
	cam_must(kg_camera_manual(c, &e), &e, "kg_camera_manual");
	CHECK(get(c, KG_FEAT_AUTO_EXPOSURE) == 0 && get(c, KG_FEAT_AUTO_WHITE_BALANCE) == 0 &&
	          get(c, KG_FEAT_WB_RED) == 1 && get(c, KG_FEAT_WB_BLUE) == 1,
	      "kg_camera_manual: auto off, white balance 1");
	CHECK(kg_camera_set(c, KG_FEAT_GAIN, 30, NULL, &e) == KG_ERANGE && strstr(e.msg, "0..24"),
	      "gain out of range refused: %s", e.msg);

	cam_must(kg_camera_start(c, 0, &e), &e, "start");
	const double maxdn = 4095;
	static const struct {
		double f, gain_db;
	} cfg[] = {{0.25, 0}, {0.5, 0}, {1.0, 0}, {0.5, 6}, {0.25, 12}};
	const int nframes = 4;
	for (int k = 0; k < ncfg; k++) {
		set(c, KG_FEAT_EXPOSURE_US, cfg[k].f * REF_US);
		set(c, KG_FEAT_GAIN, cfg[k].gain_db);
		double mean[NSTRIP], var[NSTRIP];
		unsigned seen;
		strip_stats(c, nframes, mean, var, &seen);
		double g = pow(10, cfg[k].gain_db / 20) * maxdn / FULLWELL; /* DN per electron */
		for (int i = 0; i < NSTRIP; i++) {
			double mu_e = FULLWELL * strip_level[i] * cfg[k].f;
			double want_mean = mu_e * g;
			double want_var = (mu_e + read_e * read_e) * g * g + 1.0 / 12.0;
			double n = 32.0 * 64.0 * nframes;
			char what[96];
			snprintf(what, sizeof(what), "mean, level %.1f, exposure x%.2f, %g dB, read %g",
			         strip_level[i], cfg[k].f, cfg[k].gain_db, read_e);
			CHECK_NEAR(mean[i], want_mean, 5 * sqrt(want_var / n), what);
			snprintf(what, sizeof(what), "variance, level %.1f, exposure x%.2f, %g dB, read %g",
			         strip_level[i], cfg[k].f, cfg[k].gain_db, read_e);
			CHECK_NEAR(var[i], want_var, 5 * want_var * sqrt(2.0 / (n - 1)), what);
		}
	}
	/* Clipping: the 0.6 strip at 2x the reference exposure and 6 dB is 2.4x full
	 * scale; every sample sits at 4095 and none above. */
	set(c, KG_FEAT_EXPOSURE_US, 2 * REF_US);
	set(c, KG_FEAT_GAIN, 6);
	double mean[NSTRIP], var[NSTRIP];
	unsigned seen;
	strip_stats(c, 1, mean, var, &seen);
	CHECK(mean[2] == maxdn && var[2] == 0 && seen == maxdn,
	      "clipped strip: mean %g var %g max %u", mean[2], var[2], seen);
	kg_stream_stats st;
	kg_camera_stats(c, &st);
	CHECK(st.completed == (uint64_t)(ncfg * nframes + 1) && st.dropped == 0, "completed %llu dropped %llu",
	      (unsigned long long)st.completed, (unsigned long long)st.dropped);
	kg_camera_free(&c);
	CHECK(c == NULL, "kg_camera_free nulls the pointer");
}

/* Bayer: each site samples the colour its CFA letter names; auto white balance (on at
 * open) scales red and blue to the green mean (grey world) until turned off. */
static void test_bayer(void)
{
	const char *scene = kg_test_path("rgb.tif");
	write_rgb(scene, 0.8f, 0.4f, 0.1f);
	char uri[4600];
	snprintf(uri, sizeof(uri), "sim:%s?format=bayer_grbg12&read=0&fullwell=1e9", scene);
	kg_camera *c = cam_open(uri);
	kg_err e = {{0}};
	const double lv[3] = {0.8, 0.4, 0.1};
	for (int pass = 0; pass < 2; pass++) {
		if (pass == 1) {
			cam_must(kg_camera_manual(c, &e), &e, "manual");
			set(c, KG_FEAT_EXPOSURE_US, REF_US);
		}
		double t = get(c, KG_FEAT_EXPOSURE_US) / REF_US;
		double wb[3] = {get(c, KG_FEAT_WB_RED), 1, get(c, KG_FEAT_WB_BLUE)};
		if (pass == 0)
			CHECK_NEAR(wb[0] * 0.8, 0.4, 1e-9, "auto white balance red");
		cam_must(kg_camera_start(c, 0, &e), &e, "start");
		kg_frame f;
		cam_must(kg_camera_pop(c, 1000, &f, &e), &e, "pop");
		CHECK(f.fmt.pixfmt == KG_PIX_BAYER16 && !strcmp(f.fmt.cfa, "GRBG"), "bayer format");
		const char *cfa = "GRBG";
		for (int y = 0; y < f.fmt.height; y++)
			for (int x = 0; x < f.fmt.width; x++) {
				char l = cfa[(y & 1) * 2 + (x & 1)];
				int col = l == 'R' ? 0 : l == 'G' ? 1 : 2;
				double want = fmin(4095, lv[col] * t * wb[col] * 4095);
				CHECK_NEAR(cam_sample(&f, x, y, 0), want, 2, "bayer site");
			}
		kg_image *img = NULL;
		cam_must(kg_frame_to_image(&f, 0, &img, &e), &e, "kg_frame_to_image");
		CHECK(img->cfa && !strcmp(img->cfa, "GRBG"), "image carries the CFA");
		kg_image_free(&img);
		cam_must(kg_camera_push(c, &f, &e), &e, "push");
		cam_must(kg_camera_stop(c, &e), &e, "stop");
	}
	/* RGB and mono from the same scene: each channel, and Rec. 709 luminance. */
	kg_frame_format want;
	memset(&want, 0, sizeof(want));
	want.pixfmt = KG_PIX_RGB8;
	kg_frame_format got;
	cam_must(kg_camera_set_format(c, &want, &got, &e), &e, "set_format rgb8");
	CHECK(got.bits == 8 && got.cfa[0] == 0 && got.stride == 24, "rgb8 format");
	cam_must(kg_camera_start(c, 0, &e), &e, "start");
	kg_frame f;
	cam_must(kg_camera_pop(c, 1000, &f, &e), &e, "pop");
	for (int ch = 0; ch < 3; ch++)
		CHECK_NEAR(cam_sample(&f, 3, 2, ch), lv[ch] * 255, 1, "rgb8 channel");
	cam_must(kg_camera_push(c, &f, &e), &e, "push");
	kg_camera_stop(c, &e);
	want.pixfmt = KG_PIX_MONO8;
	want.width = 4;
	want.height = 2;
	want.offset_x = 2;
	want.offset_y = 3;
	cam_must(kg_camera_set_format(c, &want, &got, &e), &e, "set_format mono8 ROI");
	CHECK(got.width == 4 && got.height == 2 && got.offset_x == 2 && got.size == 8, "ROI");
	cam_must(kg_camera_start(c, 0, &e), &e, "start");
	cam_must(kg_camera_pop(c, 1000, &f, &e), &e, "pop");
	CHECK(f.size == 8, "ROI frame size %zu", f.size);
	CHECK_NEAR(cam_sample(&f, 1, 1, 0), (0.2126 * 0.8 + 0.7152 * 0.4 + 0.0722 * 0.1) * 255,
	           1, "mono luminance");
	cam_must(kg_camera_push(c, &f, &e), &e, "push");
	kg_camera_stop(c, &e);
	want.width = 8;
	want.offset_x = 1;
	CHECK(kg_camera_set_format(c, &want, &got, &e) == KG_EINVAL && strstr(e.msg, "8x6"),
	      "ROI outside the sensor refused: %s", e.msg);
	want.pixfmt = KG_PIX_YUYV;
	CHECK(kg_camera_set_format(c, &want, &got, &e) == KG_ENOTSUP, "yuyv refused: %s", e.msg);
	kg_camera_free(&c);
}

/* The same seed and sequence give the same bytes in another camera; another seed,
 * or the next frame, does not. */
static void test_reproducible(void)
{
	unsigned char *first[3] = {NULL, NULL, NULL};
	size_t size = 0;
	const char *uris[3] = {"sim:?width=40&height=30&seed=5", "sim:?width=40&height=30&seed=5",
	                       "sim:?width=40&height=30&seed=6"};
	unsigned char *second = NULL;
	for (int k = 0; k < 3; k++) {
		kg_camera *c = cam_open(uris[k]);
		kg_err e = {{0}};
		cam_must(kg_camera_manual(c, &e), &e, "manual");
		cam_must(kg_camera_start(c, 0, &e), &e, "start");
		for (int n = 0; n < 2; n++) {
			kg_frame f;
			cam_must(kg_camera_pop(c, 1000, &f, &e), &e, "pop");
			size = f.size;
			unsigned char *copy = malloc(size);
			memcpy(copy, f.data, size);
			if (n == 0)
				first[k] = copy;
			else if (k == 0)
				second = copy;
			else
				free(copy);
			kg_camera_push(c, &f, &e);
		}
		kg_camera_free(&c);
	}
	CHECK(!memcmp(first[0], first[1], size), "same seed and sequence: identical frame");
	CHECK(memcmp(first[0], first[2], size), "another seed: another frame");
	CHECK(memcmp(first[0], second, size), "next sequence: another frame");
	for (int k = 0; k < 3; k++)
		free(first[k]);
	free(second);
}

static void test_uri_errors(void)
{
	static const struct {
		const char *uri, *needle;
		int code;
	} bad[] = {
		{"sim:?bogus=1", "unknown key 'bogus'", KG_EINVAL},
		{"sim:?fullwell=abc", "fullwell=abc", KG_EINVAL},
		{"sim:?format=yuyv", "mono8/16", KG_ENOTSUP},
		{"sim:?format=mono8&bits=12", "bits 12", KG_EINVAL},
		{"sim:/nonexistent/scene.tif", "/nonexistent/scene.tif", KG_ENOENT},
		{"sim:?drop=1", "drop=1", KG_EINVAL},
		{"nosuch:x", "unknown scheme", KG_EINVAL},
		{"sim", "SCHEME:TARGET", KG_EINVAL},
	};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		kg_camera *c = NULL;
		kg_err e = {{0}};
		int ret = kg_camera_open(bad[i].uri, &c, &e);
		CHECK(ret == bad[i].code && !c && strstr(e.msg, bad[i].needle) &&
		          strstr(e.msg, bad[i].uri),
		      "%s: %d '%s'", bad[i].uri, ret, e.msg);
	}
}

int main(void)
{
	kg_test_scratch_dir("camsim");
	test_physics(8, 5); /* shot noise dominates */
	test_physics(60, 3); /* read noise dominates */
	test_bayer();
	test_reproducible();
	test_preview();
	test_uri_errors();
	kg_test_scratch_remove();
	return kg_test_done("test_camera_sim");
}
