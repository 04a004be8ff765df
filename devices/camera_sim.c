/* sim: a simulated sensor looking at a linear image (docs/cameras.md).
 *
 * URI sim:[IMAGE][?key=value&...]. IMAGE (TIFF or PNG, 1 or 3 channels) is the scene
 * in units of the full well at the reference exposure and 0 dB; without it, a built-in
 * test scene. Per pixel and frame:
 *
 *   electrons = Poisson(fullwell * scene * exposure / ref_exposure) + Normal(0, read)
 *   DN        = round(electrons * (2^bits - 1) / fullwell * 10^(gain_dB / 20) * wb)
 *               clipped to 0 .. 2^bits - 1 (or to saturation=N: a sensor that stops
 *               short of full scale, as a 12-bit one at 4092)
 *
 * where scene is the CFA colour's channel for Bayer formats, each channel for RGB,
 * the Rec. 709 luminance of an RGB scene for mono, and wb the white-balance gain of red
 * and blue samples (1 for green and mono). The random generator of a frame is seeded
 * from (seed, sequence), so a frame depends only on the settings it was taken with.
 * The camera's identity is the sensor's: model "simulated sensor (fullwell F e-, read R
 * e-)" and serial from serial= (default "sim"), whatever the scene and the seed.
 *
 * light=F scales the scene (light=0: the lens capped, for dark captures); uniform=V
 * makes every scene value V (a flat field; an image given then sets only the size).
 *
 * The sensor counts frames from 1 for the life of the camera (across stop/start);
 * drop=N loses every frame whose number is a multiple of N, stall=N stops delivering
 * after N frames. Timestamps are the sensor's own clock (seconds from open: each frame
 * takes max(1/fps, exposure)); realtime=1 also waits for that clock. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "camera_driver.h"

#define SIM_MAX_BUFFERS 64
#define SIM_DEFAULT_BUFFERS 4

typedef struct sim_cam {
	kg_image *scene; /* sensor-sized, 1 or 3 channels */
	kg_frame_format fmt;
	/* model */
	double fullwell, read_e, ref_exposure_us;
	uint64_t seed;
	char serial[64];
	long drop, stall;
	int realtime;
	double light;   /* scale of the scene (0: the lens capped, for darks) */
	double uniform; /* >= 0: every scene value this (flats); the image sets the size */
	double saturation; /* > 0: the DN the sensor's output stops at, below 2^bits - 1 */
	/* features */
	double exposure_us, gain_db, fps, wb_red, wb_blue;
	int auto_exposure, auto_wb;
	/* sensor and stream */
	uint64_t sensor_frame; /* number of the last frame the sensor produced */
	uint64_t delivered;    /* frames delivered since open */
	double clock;          /* sensor clock at the next frame, seconds */
	struct timespec t0;    /* CLOCK_MONOTONIC at open (realtime) */
	int streaming, nbuf;
	uint8_t *buf[SIM_MAX_BUFFERS];
	int held[SIM_MAX_BUFFERS];
	/* preview: the expected DN and its noise's standard deviation per sample, for the
	 * settings in pv_key (recomputed when they change), a table of normal deviates,
	 * the frame buffer, its count and the time the next preview is due */
	float *pv_mean, *pv_sigma, *pv_noise;
	double pv_key[6];
	kg_frame_format pv_fmt;
	uint8_t *pv_buf;
	uint64_t pv_seq;
	double pv_next;
} sim_cam;

/* ---- scene ---------------------------------------------------------------------- */

/* A grey ramp 0..1 across the top two thirds; below it six patches: black, 18 % grey,
 * 90 % white, red, green and blue. */
static int builtin_scene(int w, int h, kg_image **out, kg_err *err)
{
	static const float patch[6][3] = {{0, 0, 0},         {0.18f, 0.18f, 0.18f},
	                                  {0.9f, 0.9f, 0.9f}, {0.7f, 0.1f, 0.1f},
	                                  {0.1f, 0.6f, 0.1f}, {0.1f, 0.1f, 0.7f}};
	int ret = kg_image_new(w, h, 3, out, err);
	if (ret)
		return ret;
	int ramp_rows = h * 2 / 3;
	for (int y = 0; y < h; y++)
		for (int x = 0; x < w; x++) {
			float *p = (*out)->data + ((size_t)y * (size_t)w + (size_t)x) * 3;
			if (y < ramp_rows) {
				float v = w > 1 ? (float)x / (float)(w - 1) : 0.5f;
				p[0] = p[1] = p[2] = v;
			} else {
				memcpy(p, patch[x * 6 / w], sizeof(patch[0]));
			}
		}
	return 0;
}

/* Mean of each channel (a mono scene repeats its one channel). */
static void scene_means(const kg_image *s, double m[3])
{
	double sum[3] = {0, 0, 0};
	size_t n = (size_t)s->width * (size_t)s->height;
	for (size_t i = 0; i < n; i++)
		for (int c = 0; c < 3; c++) {
			float v = s->data[i * (size_t)s->channels + (size_t)(s->channels == 3 ? c : 0)];
			sum[c] += isfinite(v) && v > 0 ? v : 0;
		}
	for (int c = 0; c < 3; c++)
		m[c] = n ? sum[c] / (double)n : 0;
}

static double luminance(const double rgb[3])
{
	return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

/* ---- features ------------------------------------------------------------------- */

static double gain_linear(const sim_cam *s) { return pow(10.0, s->gain_db / 20.0); }

/* Auto exposure puts the mean luminance at 18 % of full scale; auto white balance
 * makes the scene's mean grey (grey world). */
static double exposure_in_force(const sim_cam *s)
{
	if (!s->auto_exposure)
		return s->exposure_us;
	double m[3];
	scene_means(s->scene, m);
	double y = luminance(m);
	double t = y > 0 ? 0.18 * s->ref_exposure_us / (y * gain_linear(s)) : 1e7;
	return t < 10 ? 10 : t > 1e7 ? 1e7 : t;
}

static double wb_in_force(const sim_cam *s, int blue)
{
	if (!s->auto_wb)
		return blue ? s->wb_blue : s->wb_red;
	double m[3];
	scene_means(s->scene, m);
	double c = m[blue ? 2 : 0];
	double g = c > 0 ? m[1] / c : 1;
	return g < 0.25 ? 0.25 : g > 4 ? 4 : g;
}

static int sim_feature_info(void *state, kg_feature f, kg_feature_info *o, kg_err *err)
{
	static const struct {
		double min, max, step;
		const char *unit, *native;
	} tab[KG_FEAT_COUNT] = {
		[KG_FEAT_EXPOSURE_US] = {10, 1e7, 0, "us", "ExposureTime"},
		[KG_FEAT_GAIN] = {0, 24, 0, "dB", "Gain"},
		[KG_FEAT_FRAME_RATE] = {0.1, 1000, 0, "fps", "AcquisitionFrameRate"},
		[KG_FEAT_AUTO_EXPOSURE] = {0, 1, 1, "bool", "ExposureAuto"},
		[KG_FEAT_AUTO_WHITE_BALANCE] = {0, 1, 1, "bool", "BalanceWhiteAuto"},
		[KG_FEAT_WB_RED] = {0.25, 4, 0, "x", "BalanceRatio[Red]"},
		[KG_FEAT_WB_BLUE] = {0.25, 4, 0, "x", "BalanceRatio[Blue]"},
	};
	(void)state;
	(void)err;
	if (!tab[f].unit)
		return 0; /* a photographic setting the simulated sensor does not have */
	o->available = o->writable = 1;
	o->min = tab[f].min;
	o->max = tab[f].max;
	o->step = tab[f].step;
	snprintf(o->unit, sizeof(o->unit), "%s", tab[f].unit);
	snprintf(o->native, sizeof(o->native), "%s", tab[f].native);
	return 0;
}

static int sim_get(void *state, kg_feature f, double *v, kg_err *err)
{
	sim_cam *s = state;
	switch (f) {
	case KG_FEAT_EXPOSURE_US: *v = exposure_in_force(s); break;
	case KG_FEAT_GAIN: *v = s->gain_db; break;
	case KG_FEAT_FRAME_RATE: *v = s->fps; break;
	case KG_FEAT_AUTO_EXPOSURE: *v = s->auto_exposure; break;
	case KG_FEAT_AUTO_WHITE_BALANCE: *v = s->auto_wb; break;
	case KG_FEAT_WB_RED: *v = wb_in_force(s, 0); break;
	case KG_FEAT_WB_BLUE: *v = wb_in_force(s, 1); break;
	default: return kg_fail(err, KG_EINVAL, "feature %d: unknown", (int)f);
	}
	return 0;
}

static int sim_set(void *state, kg_feature f, double v, kg_err *err)
{
	sim_cam *s = state;
	if ((f == KG_FEAT_EXPOSURE_US && s->auto_exposure) ||
	    ((f == KG_FEAT_WB_RED || f == KG_FEAT_WB_BLUE) && s->auto_wb))
		return kg_fail(err, KG_EINVAL,
		               "%s: cannot be set while %s is on (turn it off first, e.g. with "
		               "kg_camera_manual)",
		               kg_feature_name(f),
		               f == KG_FEAT_EXPOSURE_US ? "auto_exposure" : "auto_white_balance");
	switch (f) {
	case KG_FEAT_EXPOSURE_US: s->exposure_us = v; break;
	case KG_FEAT_GAIN: s->gain_db = v; break;
	case KG_FEAT_FRAME_RATE: s->fps = v; break;
	/* Turning auto off keeps the value auto had settled at, as cameras do. */
	case KG_FEAT_AUTO_EXPOSURE:
		if (s->auto_exposure && v == 0)
			s->exposure_us = exposure_in_force(s);
		s->auto_exposure = v != 0;
		break;
	case KG_FEAT_AUTO_WHITE_BALANCE:
		if (s->auto_wb && v == 0) {
			s->wb_red = wb_in_force(s, 0);
			s->wb_blue = wb_in_force(s, 1);
		}
		s->auto_wb = v != 0;
		break;
	case KG_FEAT_WB_RED: s->wb_red = v; break;
	case KG_FEAT_WB_BLUE: s->wb_blue = v; break;
	default: return kg_fail(err, KG_EINVAL, "feature %d: unknown", (int)f);
	}
	return 0;
}

/* ---- format --------------------------------------------------------------------- */

static int check_format(const sim_cam *s, const kg_frame_format *f, kg_err *err)
{
	if (f->pixfmt == KG_PIX_YUYV || f->pixfmt == KG_PIX_MJPEG || f->pixfmt == KG_PIX_NONE)
		return kg_fail(err, KG_ENOTSUP,
		               "format %s: the simulated sensor delivers mono8/16, bayer8/16 and "
		               "rgb8/16 only",
		               kg_pixfmt_name(f->pixfmt));
	int wide = kg_pixfmt_bytes_per_pixel(f->pixfmt) / kg_pixfmt_channels(f->pixfmt) == 2;
	if (wide ? (f->bits < 8 || f->bits > 16) : f->bits != 8)
		return kg_fail(err, KG_EINVAL, "bits %d: expected %s for %s", f->bits,
		               wide ? "8..16" : "8", kg_pixfmt_name(f->pixfmt));
	int sw = s->scene->width, sh = s->scene->height;
	if (f->width < 1 || f->height < 1 || f->offset_x < 0 || f->offset_y < 0 ||
	    f->offset_x + f->width > sw || f->offset_y + f->height > sh)
		return kg_fail(err, KG_EINVAL,
		               "ROI %dx%d at (%d, %d): expected a region inside the %dx%d sensor",
		               f->width, f->height, f->offset_x, f->offset_y, sw, sh);
	int bayer = f->pixfmt == KG_PIX_BAYER8 || f->pixfmt == KG_PIX_BAYER16;
	if (bayer && ((f->offset_x | f->offset_y) & 1))
		return kg_fail(err, KG_EINVAL,
		               "ROI offset (%d, %d): a Bayer ROI starts on even coordinates so the "
		               "CFA keeps its pattern",
		               f->offset_x, f->offset_y);
	return 0;
}

static int sim_set_format(void *state, const kg_frame_format *want, kg_frame_format *got,
                          kg_err *err)
{
	sim_cam *s = state;
	kg_frame_format f = s->fmt;
	if (want->pixfmt != KG_PIX_NONE && want->pixfmt != f.pixfmt) {
		f.pixfmt = want->pixfmt;
		f.bits = 0; /* the new format's default unless asked */
		f.cfa[0] = 0;
	}
	if (want->bits)
		f.bits = want->bits;
	if (!f.bits)
		f.bits = kg_pixfmt_bytes_per_pixel(f.pixfmt) / kg_pixfmt_channels(f.pixfmt) == 2
		             ? 16
		             : 8;
	int bayer = f.pixfmt == KG_PIX_BAYER8 || f.pixfmt == KG_PIX_BAYER16;
	if (!bayer)
		f.cfa[0] = 0;
	else if (want->cfa[0])
		memcpy(f.cfa, want->cfa, 5);
	else if (!f.cfa[0])
		memcpy(f.cfa, "RGGB", 5);
	if (want->width)
		f.width = want->width;
	if (want->height)
		f.height = want->height;
	if (want->offset_x)
		f.offset_x = want->offset_x;
	if (want->offset_y)
		f.offset_y = want->offset_y;
	kg_frame_format_fill(&f);
	int ret = check_format(s, &f, err);
	if (ret)
		return ret;
	s->fmt = f;
	*got = f;
	return 0;
}

static int sim_get_format(void *state, kg_frame_format *out, kg_err *err)
{
	(void)err;
	*out = ((sim_cam *)state)->fmt;
	return 0;
}

/* ---- open ----------------------------------------------------------------------- */

static void sim_close(void *state)
{
	sim_cam *s = state;
	if (!s)
		return;
	for (int i = 0; i < SIM_MAX_BUFFERS; i++)
		free(s->buf[i]);
	free(s->pv_mean);
	free(s->pv_sigma);
	free(s->pv_noise);
	free(s->pv_buf);
	kg_image_free(&s->scene);
	free(s);
}

static const char sim_keys[] = "width, height, format, bits, fullwell, read, seed, "
                               "serial, ref_exposure_us, fps, drop, stall, realtime, light, uniform, "
                               "saturation";

/* A number filling all of text within [min, max]; integral when asked. */
static int parse_value(const char *key, const char *text, double min, double max,
                       int integral, double *out, kg_err *err)
{
	char *end;
	double v = strtod(text, &end);
	if (end == text || *end || !isfinite(v) || v < min || v > max ||
	    (integral && v != floor(v)))
		return kg_fail(err, KG_EINVAL, "%s=%s: expected %s %g..%g", key, text,
		               integral ? "a whole number" : "a number", min, max);
	*out = v;
	return 0;
}

/* Apply the ?key=value&... part. */
static int parse_keys(sim_cam *s, char *q, int have_image, int *w, int *h, kg_err *err)
{
	for (char *kv = q, *next; kv && *kv; kv = next) {
		next = strchr(kv, '&');
		if (next)
			*next++ = 0;
		char *val = strchr(kv, '=');
		if (!val)
			return kg_fail(err, KG_EINVAL, "'%s': expected key=value (keys: %s)", kv,
			               sim_keys);
		*val++ = 0;
		double v = 0;
		int ret = 0;
		if (!strcmp(kv, "width") || !strcmp(kv, "height")) {
			if (have_image)
				return kg_fail(err, KG_EINVAL,
				               "%s: only for the built-in scene; an image sets the sensor "
				               "size",
				               kv);
			if (!(ret = parse_value(kv, val, 2, 16384, 1, &v, err)))
				*(kv[0] == 'w' ? w : h) = (int)v;
		} else if (!strcmp(kv, "format")) {
			kg_pixfmt pf;
			int bits;
			char cfa[5];
			if (!(ret = kg_pixfmt_parse(val, &pf, &bits, cfa, err))) {
				s->fmt.pixfmt = pf;
				s->fmt.bits = bits;
				memcpy(s->fmt.cfa, cfa, 5);
			}
		} else if (!strcmp(kv, "bits")) {
			if (!(ret = parse_value(kv, val, 8, 16, 1, &v, err)))
				s->fmt.bits = (int)v;
		} else if (!strcmp(kv, "fullwell")) {
			ret = parse_value(kv, val, 1, 1e9, 0, &s->fullwell, err);
		} else if (!strcmp(kv, "read")) {
			ret = parse_value(kv, val, 0, 1e6, 0, &s->read_e, err);
		} else if (!strcmp(kv, "seed")) {
			char *end;
			s->seed = strtoull(val, &end, 10);
			if (end == val || *end)
				ret = kg_fail(err, KG_EINVAL, "seed=%s: expected a whole number", val);
		} else if (!strcmp(kv, "serial")) {
			size_t n = strlen(val);
			int ok = n > 0 && n < sizeof(s->serial);
			for (size_t i = 0; ok && i < n; i++)
				ok = val[i] > ' ' && val[i] < 127;
			if (!ok)
				return kg_fail(err, KG_EINVAL, "serial=%s: expected 1..%zu printable "
				               "characters without spaces", val, sizeof(s->serial) - 1);
			memcpy(s->serial, val, n + 1);
		} else if (!strcmp(kv, "ref_exposure_us")) {
			ret = parse_value(kv, val, 10, 1e7, 0, &s->ref_exposure_us, err);
		} else if (!strcmp(kv, "fps")) {
			ret = parse_value(kv, val, 0.1, 1000, 0, &s->fps, err);
		} else if (!strcmp(kv, "drop") || !strcmp(kv, "stall")) {
			if (!(ret = parse_value(kv, val, 0, 1e12, 1, &v, err)))
				*(kv[0] == 'd' ? &s->drop : &s->stall) = (long)v;
			if (!ret && kv[0] == 'd' && v == 1)
				ret = kg_fail(err, KG_EINVAL, "drop=1: would lose every frame; expected 0 "
				                              "(none) or 2 and more");
		} else if (!strcmp(kv, "light")) {
			ret = parse_value(kv, val, 0, 1e6, 0, &s->light, err);
		} else if (!strcmp(kv, "saturation")) {
			ret = parse_value(kv, val, 1, 65535, 1, &s->saturation, err);
		} else if (!strcmp(kv, "uniform")) {
			ret = parse_value(kv, val, 0, 1e6, 0, &s->uniform, err);
		} else if (!strcmp(kv, "realtime")) {
			if (!(ret = parse_value(kv, val, 0, 1, 1, &v, err)))
				s->realtime = (int)v;
		} else {
			return kg_fail(err, KG_EINVAL, "unknown key '%s' (keys: %s)", kv, sim_keys);
		}
		if (ret)
			return ret;
	}
	return 0;
}

static int sim_open(const char *target, void **state, kg_camera_info *info, kg_err *err)
{
	sim_cam *s = calloc(1, sizeof(*s));
	char *t = strdup(target);
	if (!s || !t) {
		free(s);
		free(t);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	s->fullwell = 20000;
	s->read_e = 5;
	s->seed = 1;
	snprintf(s->serial, sizeof(s->serial), "sim");
	s->ref_exposure_us = 10000;
	s->fps = 30;
	s->light = 1;
	s->uniform = -1;
	s->gain_db = 0;
	s->wb_red = s->wb_blue = 1;
	s->auto_exposure = s->auto_wb = 1;
	s->fmt.pixfmt = KG_PIX_MONO16;
	s->fmt.bits = 12;
	int w = 640, h = 480;
	char *q = strrchr(t, '?');
	if (q)
		*q++ = 0;
	int ret = parse_keys(s, q, t[0] != 0, &w, &h, err);
	if (!ret && t[0]) {
		ret = kg_image_read(t, &s->scene, err);
		if (!ret && s->scene->channels != 1 && s->scene->channels != 3)
			ret = kg_fail(err, KG_EINVAL, "%s: %d channels: expected 1 or 3", t,
			              s->scene->channels);
	} else if (!ret) {
		ret = builtin_scene(w, h, &s->scene, err);
	}
	s->exposure_us = s->ref_exposure_us;
	if (!ret && (s->light != 1 || s->uniform >= 0)) {
		size_t n = (size_t)s->scene->width * (size_t)s->scene->height * (size_t)s->scene->channels;
		for (size_t i = 0; i < n; i++)
			s->scene->data[i] = (float)((s->uniform >= 0 ? s->uniform : s->scene->data[i]) *
			                            s->light);
	}
	if (!ret) {
		int bayer = s->fmt.pixfmt == KG_PIX_BAYER8 || s->fmt.pixfmt == KG_PIX_BAYER16;
		if (bayer && !s->fmt.cfa[0])
			memcpy(s->fmt.cfa, "RGGB", 5);
		s->fmt.width = s->scene->width;
		s->fmt.height = s->scene->height;
		kg_frame_format_fill(&s->fmt);
		ret = check_format(s, &s->fmt, err);
	}
	if (ret) {
		free(t);
		sim_close(s);
		return ret;
	}
	clock_gettime(CLOCK_MONOTONIC, &s->t0);
	snprintf(info->vendor, sizeof(info->vendor), "kogei");
	/* The sensor, not what it looks at: one simulated camera photographing a chart and
	 * then an object is one camera. */
	char params[96];
	snprintf(params, sizeof(params), "fullwell %.6g e-, read %.4g e-", s->fullwell, s->read_e);
	snprintf(info->model, sizeof(info->model), "simulated sensor (%.40s)", params);
	snprintf(info->serial, sizeof(info->serial), "%s", s->serial);
	snprintf(info->transport, sizeof(info->transport), "sim");
	info->sensor_width = s->scene->width;
	info->sensor_height = s->scene->height;
	free(t);
	*state = s;
	return 0;
}

/* ---- stream --------------------------------------------------------------------- */

static int sim_start(void *state, int nbuffers, kg_err *err)
{
	sim_cam *s = state;
	int n;
	int ret = kg_buffers_count(nbuffers, SIM_DEFAULT_BUFFERS, SIM_MAX_BUFFERS, &n, err);
	if (ret)
		return ret;
	for (int i = 0; i < n; i++) {
		uint8_t *b = realloc(s->buf[i], s->fmt.size);
		if (!b)
			return kg_fail(err, KG_ENOMEM, "out of memory for %d buffers of %zu bytes", n,
			               s->fmt.size);
		s->buf[i] = b;
		s->held[i] = 0;
	}
	s->nbuf = n;
	s->streaming = 1;
	return 0;
}

static int sim_stop(void *state, kg_err *err)
{
	(void)err;
	((sim_cam *)state)->streaming = 0;
	return 0;
}

static void sleep_until(const struct timespec *t0, double t)
{
	struct timespec ts = *t0;
	double whole = floor(t);
	ts.tv_sec += (time_t)whole;
	ts.tv_nsec += (long)((t - whole) * 1e9);
	if (ts.tv_nsec >= 1000000000L) {
		ts.tv_sec++;
		ts.tv_nsec -= 1000000000L;
	}
	while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL))
		;
}

static double since_open(const sim_cam *s)
{
	struct timespec now;
	clock_gettime(CLOCK_MONOTONIC, &now);
	return (double)(now.tv_sec - s->t0.tv_sec) + 1e-9 * (double)(now.tv_nsec - s->t0.tv_nsec);
}

/* Render the frame numbered seq into buf with the settings in force. */
static void render(const sim_cam *s, uint64_t seq, double exposure_us, uint8_t *buf)
{
	const kg_frame_format *f = &s->fmt;
	const kg_image *sc = s->scene;
	kg_rng rng;
	kg_rng_seed(&rng, s->seed * 0x9e3779b97f4a7c15ULL + seq);
	double maxdn = (double)((1u << f->bits) - 1u);
	double k = maxdn / s->fullwell * gain_linear(s);
	double top = s->saturation > 0 && s->saturation < maxdn ? s->saturation : maxdn;
	double wb[3] = {wb_in_force(s, 0), 1, wb_in_force(s, 1)};
	double scale = s->fullwell * exposure_us / s->ref_exposure_us;
	int ch = kg_pixfmt_channels(f->pixfmt);
	int wide = kg_pixfmt_bytes_per_pixel(f->pixfmt) / ch == 2;
	int bayer = f->pixfmt == KG_PIX_BAYER8 || f->pixfmt == KG_PIX_BAYER16;
	for (int y = 0; y < f->height; y++) {
		uint8_t *row = buf + f->stride * (size_t)y;
		int sy = f->offset_y + y;
		for (int x = 0; x < f->width; x++) {
			int sx = f->offset_x + x;
			const float *p =
				sc->data + ((size_t)sy * (size_t)sc->width + (size_t)sx) * (size_t)sc->channels;
			for (int c = 0; c < ch; c++) {
				int colour = c; /* 0 R, 1 G, 2 B; -1 mono */
				double v;
				if (bayer) {
					char l = f->cfa[(sy & 1) * 2 + (sx & 1)];
					colour = l == 'R' ? 0 : l == 'G' ? 1 : 2;
				} else if (ch == 1) {
					colour = -1;
				}
				if (sc->channels == 1)
					v = p[0];
				else if (colour >= 0)
					v = p[colour];
				else
					v = 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
				double e = kg_rng_poisson(&rng, isfinite(v) && v > 0 ? scale * v : 0);
				if (s->read_e > 0)
					e += s->read_e * kg_rng_normal(&rng);
				double dn = floor(e * k * (colour >= 0 ? wb[colour] : 1) + 0.5);
				dn = dn < 0 ? 0 : dn > top ? top : dn;
				size_t i = (size_t)x * (size_t)ch + (size_t)c;
				if (wide) {
					uint16_t u = (uint16_t)dn;
					row[2 * i] = (uint8_t)(u & 0xff);
					row[2 * i + 1] = (uint8_t)(u >> 8);
				} else {
					row[i] = (uint8_t)dn;
				}
			}
		}
	}
}

static int sim_pop(void *state, int timeout_ms, kg_frame *frame, kg_err *err)
{
	sim_cam *s = state;
	if (s->stall && s->delivered >= (uint64_t)s->stall) {
		if (timeout_ms > 0)
			sleep_until(&s->t0, since_open(s) + timeout_ms / 1000.0);
		return kg_fail(err, KG_ETIMEDOUT,
		               "no frame within %d ms (the sensor stalls after %ld frames: stall=%ld)",
		               timeout_ms, s->stall, s->stall);
	}
	int slot = kg_buffers_free_slot(s->held, s->nbuf, err);
	if (slot < 0)
		return KG_EINVAL;
	double exposure = exposure_in_force(s);
	double period = fmax(1.0 / s->fps, exposure * 1e-6);
	/* Frames the sensor loses (drop=N) still take their time. */
	uint64_t seq = s->sensor_frame + 1;
	double clock = s->clock;
	while (s->drop && seq % (uint64_t)s->drop == 0) {
		clock += period;
		seq++;
	}
	if (s->realtime) {
		if ((clock + period - since_open(s)) * 1000.0 > timeout_ms) {
			if (timeout_ms > 0)
				sleep_until(&s->t0, since_open(s) + timeout_ms / 1000.0);
			return kg_fail(err, KG_ETIMEDOUT, "no frame within %d ms (frame period %.3f s)",
			               timeout_ms, period);
		}
		sleep_until(&s->t0, clock + period);
	}
	s->sensor_frame = seq;
	s->clock = clock + period;
	render(s, seq, exposure, s->buf[slot]);
	s->held[slot] = 1;
	s->delivered++;
	frame->fmt = s->fmt;
	frame->data = s->buf[slot];
	frame->size = s->fmt.size;
	frame->sequence = seq;
	frame->timestamp = s->clock;
	frame->status = KG_FRAME_OK;
	frame->exposure_us = exposure;
	frame->gain = s->gain_db;
	frame->slot = slot;
	return 0;
}

/* ---- preview --------------------------------------------------------------------- */

#define SIM_NOISE_N 65536 /* normal deviates in the preview's table (a power of 2) */

/* The preview's expected DN and noise per sample for the settings in force (the model
 * of render with the Poisson count replaced by a normal of the same variance). */
static int preview_model(sim_cam *s, double exposure, kg_err *err)
{
	const kg_frame_format *f = &s->fmt;
	double key[6] = {exposure, s->gain_db, wb_in_force(s, 0), wb_in_force(s, 1),
	                 (double)f->pixfmt, (double)f->bits};
	if (s->pv_mean && !memcmp(key, s->pv_key, sizeof(key)) &&
	    !memcmp(&s->pv_fmt, f, sizeof(*f)))
		return 0;
	int ch = kg_pixfmt_channels(f->pixfmt);
	size_t n = (size_t)f->width * (size_t)f->height * (size_t)ch;
	free(s->pv_mean);
	free(s->pv_sigma);
	free(s->pv_buf);
	s->pv_mean = malloc(n * sizeof(float));
	s->pv_sigma = malloc(n * sizeof(float));
	s->pv_buf = malloc(f->size);
	if (!s->pv_noise && (s->pv_noise = malloc(SIM_NOISE_N * sizeof(float)))) {
		kg_rng rng;
		kg_rng_seed(&rng, s->seed * 0x9e3779b97f4a7c15ULL + 0x5eedULL);
		for (int i = 0; i < SIM_NOISE_N; i++)
			s->pv_noise[i] = (float)kg_rng_normal(&rng);
	}
	if (!s->pv_mean || !s->pv_sigma || !s->pv_buf || !s->pv_noise) {
		free(s->pv_mean);
		s->pv_mean = NULL;
		return kg_fail(err, KG_ENOMEM, "out of memory for the %dx%d preview", f->width,
		               f->height);
	}
	const kg_image *sc = s->scene;
	double maxdn = (double)((1u << f->bits) - 1u);
	double k = maxdn / s->fullwell * gain_linear(s);
	double wb[3] = {key[2], 1, key[3]};
	double scale = s->fullwell * exposure / s->ref_exposure_us;
	int bayer = f->pixfmt == KG_PIX_BAYER8 || f->pixfmt == KG_PIX_BAYER16;
	size_t i = 0;
	for (int y = 0; y < f->height; y++) {
		int sy = f->offset_y + y;
		for (int x = 0; x < f->width; x++) {
			int sx = f->offset_x + x;
			const float *p =
				sc->data + ((size_t)sy * (size_t)sc->width + (size_t)sx) * (size_t)sc->channels;
			for (int c = 0; c < ch; c++, i++) {
				int colour = c;
				if (bayer) {
					char l = f->cfa[(sy & 1) * 2 + (sx & 1)];
					colour = l == 'R' ? 0 : l == 'G' ? 1 : 2;
				} else if (ch == 1) {
					colour = -1;
				}
				double v = sc->channels == 1 ? p[0]
				           : colour >= 0     ? p[colour]
				                             : 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
				double e = isfinite(v) && v > 0 ? scale * v : 0;
				double kc = k * (colour >= 0 ? wb[colour] : 1);
				s->pv_mean[i] = (float)(e * kc);
				s->pv_sigma[i] = (float)(kc * sqrt(e + s->read_e * s->read_e));
			}
		}
	}
	memcpy(s->pv_key, key, sizeof(key));
	s->pv_fmt = *f;
	return 0;
}

/* A live-view frame: the expected DN plus normal noise from a table (each row starts
 * at a random place in it), paced at max(1/fps, exposure) in real time whatever
 * realtime= says (a live view is), numbered on its own (the stream's sequence and
 * clock are untouched). */
static int sim_preview(void *state, int timeout_ms, kg_frame *frame, kg_err *err)
{
	sim_cam *s = state;
	double exposure = exposure_in_force(s);
	int ret = preview_model(s, exposure, err);
	if (ret)
		return ret;
	double period = fmax(1.0 / s->fps, exposure * 1e-6);
	double now = since_open(s), due = fmax(s->pv_next, now);
	if ((due - now) * 1000.0 > timeout_ms) {
		if (timeout_ms > 0)
			sleep_until(&s->t0, now + timeout_ms / 1000.0);
		return kg_fail(err, KG_ETIMEDOUT, "no preview within %d ms (frame period %.3f s)",
		               timeout_ms, period);
	}
	if (due > now)
		sleep_until(&s->t0, due);
	s->pv_next = due + period;
	s->pv_seq++;
	const kg_frame_format *f = &s->fmt;
	int ch = kg_pixfmt_channels(f->pixfmt);
	int wide = kg_pixfmt_bytes_per_pixel(f->pixfmt) / ch == 2;
	float maxdn = (float)((1u << f->bits) - 1u);
	if (s->saturation > 0 && s->saturation < maxdn)
		maxdn = (float)s->saturation;
	size_t rowlen = (size_t)f->width * (size_t)ch;
	kg_rng rng;
	kg_rng_seed(&rng, s->seed * 0x9e3779b97f4a7c15ULL + 0xbeefULL + s->pv_seq);
	for (int y = 0; y < f->height; y++) {
		const float *m = s->pv_mean + (size_t)y * rowlen, *sd = s->pv_sigma + (size_t)y * rowlen;
		uint8_t *row = s->pv_buf + f->stride * (size_t)y;
		unsigned o = (unsigned)kg_rng_next(&rng);
		for (size_t i = 0; i < rowlen; i++) {
			float dn = m[i] + sd[i] * s->pv_noise[(o + i) & (SIM_NOISE_N - 1)] + 0.5f;
			dn = dn < 0 ? 0 : dn > maxdn ? maxdn : dn;
			unsigned u = (unsigned)dn;
			if (wide) {
				row[2 * i] = (uint8_t)(u & 0xff);
				row[2 * i + 1] = (uint8_t)(u >> 8);
			} else {
				row[i] = (uint8_t)u;
			}
		}
	}
	frame->fmt = *f;
	frame->data = s->pv_buf;
	frame->size = f->size;
	frame->sequence = s->pv_seq;
	frame->timestamp = due;
	frame->status = KG_FRAME_OK;
	frame->exposure_us = exposure;
	frame->gain = s->gain_db;
	frame->slot = -1;
	return 0;
}

static int sim_push(void *state, kg_frame *frame, kg_err *err)
{
	sim_cam *s = state;
	return kg_buffers_release(s->held, NULL, s->nbuf, frame, err);
}

const kg_camera_driver kg_camera_sim_driver = {
	.scheme = "sim",
	.description = "simulated sensor: sim:[IMAGE][?key=value&...] (Poisson and read noise; "
	               "serial=S names the camera)",
	.open = sim_open,
	.close = sim_close,
	.feature_info = sim_feature_info,
	.get = sim_get,
	.set = sim_set,
	.set_format = sim_set_format,
	.get_format = sim_get_format,
	.start = sim_start,
	.stop = sim_stop,
	.pop = sim_pop,
	.push = sim_push,
	.preview = sim_preview,
};
