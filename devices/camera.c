/* Cameras: the registry of drivers by URI scheme and the bookkeeping every backend
 * shares (feature read-back, dropped frames from sequence gaps, timeouts, recording,
 * conversion of frames to float images). Drivers: camera_driver.h. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera_driver.h"
#include "device_uri.h"
#include "mjpeg.h"

static const kg_camera_driver *const drivers[] = {
#if HAVE_V4L2
	&kg_camera_v4l2_driver,
#endif
#if HAVE_ARAVIS
	&kg_camera_aravis_driver,
#endif
#if HAVE_LIBCAMERA
	&kg_camera_libcamera_driver,
#endif
#if HAVE_GPHOTO2
	&kg_camera_gphoto2_driver,
#endif
	&kg_camera_replay_driver,
	&kg_camera_files_driver,
	&kg_camera_sim_driver,
};
#define NDRIVERS ((int)(sizeof(drivers) / sizeof(drivers[0])))

struct kg_camera {
	const kg_camera_driver *drv;
	void *state;
	kg_camera_info info;
	int streaming;
	int have_seq;
	uint64_t last_seq;
	kg_stream_stats counts; /* completed, dropped, timeouts kept here */
	double exposure_us, gain; /* last values read back (NAN: unknown) */
	kg_frame_recorder *rec;
};

int kg_camera_backend_count(void) { return NDRIVERS; }

const char *kg_camera_backend_scheme(int i)
{
	return i >= 0 && i < NDRIVERS ? drivers[i]->scheme : NULL;
}

const char *kg_camera_backend_description(int i)
{
	return i >= 0 && i < NDRIVERS ? drivers[i]->description : NULL;
}

/* ---- pixel formats and features ---------------------------------------------- */

static const char *const pixfmt_names[] = {
	[KG_PIX_NONE] = "none",     [KG_PIX_MONO8] = "mono8",   [KG_PIX_MONO16] = "mono16",
	[KG_PIX_BAYER8] = "bayer8", [KG_PIX_BAYER16] = "bayer16", [KG_PIX_RGB8] = "rgb8",
	[KG_PIX_RGB16] = "rgb16",   [KG_PIX_YUYV] = "yuyv",     [KG_PIX_MJPEG] = "mjpeg",
};

const char *kg_pixfmt_name(kg_pixfmt f)
{
	return (unsigned)f < sizeof(pixfmt_names) / sizeof(pixfmt_names[0]) ? pixfmt_names[f]
	                                                                    : "unknown";
}

int kg_pixfmt_parse(const char *text, kg_pixfmt *f, int *bits, char cfa[5], kg_err *err)
{
	static const struct {
		const char *prefix;
		kg_pixfmt f8, f16;
	} fam[] = {{"mono", KG_PIX_MONO8, KG_PIX_MONO16},
	           {"bayer", KG_PIX_BAYER8, KG_PIX_BAYER16},
	           {"rgb", KG_PIX_RGB8, KG_PIX_RGB16}};
	const char *expected = "expected mono8|mono10|mono12|mono14|mono16, bayer8..16 "
	                       "(optionally bayer_rggb12 etc.), rgb8, rgb16, yuyv or mjpeg";
	if (!text)
		return kg_fail(err, KG_EINVAL, "pixel format: missing; %s", expected);
	if (cfa)
		cfa[0] = 0;
	if (!strcmp(text, "yuyv") || !strcmp(text, "mjpeg")) {
		*f = text[0] == 'y' ? KG_PIX_YUYV : KG_PIX_MJPEG;
		if (bits)
			*bits = 8;
		return 0;
	}
	for (size_t i = 0; i < sizeof(fam) / sizeof(fam[0]); i++) {
		size_t n = strlen(fam[i].prefix);
		if (strncmp(text, fam[i].prefix, n))
			continue;
		const char *p = text + n;
		char pat[5] = "";
		if (fam[i].f8 == KG_PIX_BAYER8 && *p == '_') {
			if (strlen(p) < 6)
				break;
			for (int k = 0; k < 4; k++)
				pat[k] = (char)(p[1 + k] & ~0x20); /* upper case */
			pat[4] = 0;
			if (strcmp(pat, "RGGB") && strcmp(pat, "GRBG") && strcmp(pat, "GBRG") &&
			    strcmp(pat, "BGGR"))
				break;
			p += 5;
		}
		char *end;
		long b = strtol(p, &end, 10);
		if (end == p || *end || (b != 8 && b != 10 && b != 12 && b != 14 && b != 16) ||
		    (fam[i].f8 == KG_PIX_RGB8 && b != 8 && b != 16))
			break;
		*f = b == 8 ? fam[i].f8 : fam[i].f16;
		if (bits)
			*bits = (int)b;
		if (cfa)
			memcpy(cfa, pat, 5);
		return 0;
	}
	return kg_fail(err, KG_EINVAL, "pixel format '%s': %s", text, expected);
}

int kg_pixfmt_bytes_per_pixel(kg_pixfmt f)
{
	switch (f) {
	case KG_PIX_MONO8:
	case KG_PIX_BAYER8:
		return 1;
	case KG_PIX_MONO16:
	case KG_PIX_BAYER16:
	case KG_PIX_YUYV:
		return 2;
	case KG_PIX_RGB8:
		return 3;
	case KG_PIX_RGB16:
		return 6;
	default:
		return 0;
	}
}

int kg_pixfmt_channels(kg_pixfmt f)
{
	return f == KG_PIX_RGB8 || f == KG_PIX_RGB16 || f == KG_PIX_YUYV || f == KG_PIX_MJPEG
	           ? 3
	           : 1;
}

int kg_pixfmt_is_linear(kg_pixfmt f)
{
	return f != KG_PIX_YUYV && f != KG_PIX_MJPEG && f != KG_PIX_NONE;
}

void kg_frame_format_fill(kg_frame_format *f)
{
	f->stride = (size_t)f->width * (size_t)kg_pixfmt_bytes_per_pixel(f->pixfmt);
	f->size = f->stride * (size_t)f->height;
	if (f->pixfmt == KG_PIX_MJPEG) /* an upper bound for one compressed frame */
		f->size = (size_t)f->width * (size_t)f->height * 3 + 4096;
	if (!f->bits)
		f->bits = f->pixfmt == KG_PIX_MONO16 || f->pixfmt == KG_PIX_BAYER16 ||
		                  f->pixfmt == KG_PIX_RGB16
		              ? 16
		              : 8;
}

static const char *const feature_names[KG_FEAT_COUNT] = {
	"exposure_us", "gain", "frame_rate", "auto_exposure", "auto_white_balance",
	"wb_red", "wb_blue", "iso", "aperture", "focal_length_mm",
};

const char *kg_feature_name(kg_feature f)
{
	return (unsigned)f < KG_FEAT_COUNT ? feature_names[f] : "unknown";
}

int kg_feature_parse(const char *text, kg_feature *f, kg_err *err)
{
	for (int i = 0; i < KG_FEAT_COUNT; i++)
		if (text && !strcmp(text, feature_names[i])) {
			*f = (kg_feature)i;
			return 0;
		}
	return kg_fail(err, KG_EINVAL,
	               "feature '%s': expected exposure_us, gain, frame_rate, auto_exposure, "
	               "auto_white_balance, wb_red, wb_blue, iso, aperture or focal_length_mm",
	               text ? text : "(null)");
}

/* ---- open and close ----------------------------------------------------------- */

int kg_camera_open(const char *uri, kg_camera **out, kg_err *err)
{
	kg_check_arg(uri && out, err);
	*out = NULL;
	const char *colon = strchr(uri, ':');
	if (!colon || colon == uri)
		return kg_fail(err, KG_EINVAL,
		               "camera '%s': expected SCHEME:TARGET (v4l2:/dev/video0, "
		               "aravis:ADDRESS, libcamera:ID, gphoto2:MODEL, files:DIR/PATTERN, "
		               "replay:SESSION, sim:[IMAGE])",
		               uri);
	size_t n = (size_t)(colon - uri);
	const kg_camera_driver *drv = NULL;
	for (int i = 0; i < NDRIVERS; i++)
		if (kg_uri_scheme_is(uri, n, drivers[i]->scheme))
			drv = drivers[i];
	if (!drv) {
		static const char *const known[] = {"v4l2", "aravis", "libcamera", "gphoto2", NULL};
		return kg_uri_scheme_unknown("camera", uri, n, known,
		                             "see `kogei devices` for the backends built in", err);
	}
	kg_camera *c = calloc(1, sizeof(*c));
	if (!c)
		return kg_fail(err, KG_ENOMEM, "camera '%s': out of memory", uri);
	c->drv = drv;
	c->exposure_us = c->gain = NAN;
	int ret = drv->open(colon + 1, &c->state, &c->info, err);
	if (ret) {
		kg_err_prefix(err, "camera '%s'", uri);
		free(c);
		return ret;
	}
	snprintf(c->info.backend, sizeof(c->info.backend), "%s", drv->scheme);
	snprintf(c->info.uri, sizeof(c->info.uri), "%s", uri);
	*out = c;
	return 0;
}

void kg_camera_free(kg_camera **pc)
{
	if (!pc || !*pc)
		return;
	kg_camera *c = *pc;
	if (c->streaming)
		c->drv->stop(c->state, NULL);
	if (c->rec)
		kg_frame_recorder_close(&c->rec, NULL);
	c->drv->close(c->state);
	free(c);
	*pc = NULL;
}

const kg_camera_info *kg_camera_get_info(const kg_camera *c) { return &c->info; }

void *kg_camera_driver_state(kg_camera *c, const kg_camera_driver *drv)
{
	return c && c->drv == drv ? c->state : NULL;
}

int kg_camera_target_split(const char *target, char *name, size_t n, const char *usage,
                           kg_camera_option_fn option, void *user, kg_err *err)
{
	const char *q = strchr(target, '?');
	size_t len = q ? (size_t)(q - target) : strlen(target);
	if (!len || len >= n)
		return kg_fail(err, KG_EINVAL, "expected %s, got '%s'", usage, target);
	memcpy(name, target, len);
	name[len] = 0;
	for (const char *p = q ? q + 1 : NULL; p && *p;) {
		const char *amp = strchr(p, '&');
		size_t plen = amp ? (size_t)(amp - p) : strlen(p);
		char kv[1024];
		if (plen >= sizeof(kv))
			return kg_fail(err, KG_EINVAL, "option '%.*s...': too long", 32, p);
		memcpy(kv, p, plen);
		kv[plen] = 0;
		char *eq = strchr(kv, '=');
		if (eq)
			*eq = 0;
		int ret = option(user, kv, eq ? eq + 1 : NULL, err);
		if (ret)
			return ret;
		p = amp ? amp + 1 : NULL;
	}
	return 0;
}

int kg_buffers_count(int nbuffers, int def, int max, int *n, kg_err *err)
{
	*n = nbuffers ? nbuffers : def;
	if (*n > max)
		return kg_fail(err, KG_EINVAL, "%d buffers: expected at most %d", *n, max);
	return 0;
}

int kg_buffers_free_slot(const int *held, int n, kg_err *err)
{
	for (int i = 0; i < n; i++)
		if (!held[i])
			return i;
	kg_fail(err, KG_EINVAL,
	        "all %d buffers are held by the caller; give frames back with kg_camera_push", n);
	return -1;
}

int kg_buffers_release(int *held, void *const *data, int n, const kg_frame *frame,
                       kg_err *err)
{
	if (frame->slot < 0 || frame->slot >= n || !held[frame->slot] ||
	    (data && data[frame->slot] != frame->data))
		return kg_fail(err, KG_EINVAL, "frame %llu: buffer %d was not handed out",
		               (unsigned long long)frame->sequence, frame->slot);
	held[frame->slot] = 0;
	return 0;
}

long kg_camera_frames_available(kg_camera *c)
{
	return c && c->drv->frames_available ? c->drv->frames_available(c->state) : -1;
}

/* ---- features ----------------------------------------------------------------- */

static int prefixed(kg_camera *c, kg_err *err, int ret)
{
	if (ret && err && strncmp(err->msg, "camera '", 8))
		kg_err_prefix(err, "camera '%s'", c->info.uri);
	return ret;
}

int kg_camera_feature_info(kg_camera *c, kg_feature f, kg_feature_info *out, kg_err *err)
{
	kg_check_arg(c && out && (unsigned)f < KG_FEAT_COUNT, err);
	memset(out, 0, sizeof(*out));
	return prefixed(c, err, c->drv->feature_info(c->state, f, out, err));
}

int kg_camera_get(kg_camera *c, kg_feature f, double *value, kg_err *err)
{
	kg_check_arg(c && value && (unsigned)f < KG_FEAT_COUNT, err);
	int ret = c->drv->get(c->state, f, value, err);
	if (!ret && f == KG_FEAT_EXPOSURE_US)
		c->exposure_us = *value;
	if (!ret && f == KG_FEAT_GAIN)
		c->gain = *value;
	return prefixed(c, err, ret);
}

int kg_camera_set(kg_camera *c, kg_feature f, double value, double *got, kg_err *err)
{
	kg_check_arg(c && (unsigned)f < KG_FEAT_COUNT && isfinite(value), err);
	kg_feature_info fi;
	memset(&fi, 0, sizeof(fi));
	int ret = c->drv->feature_info(c->state, f, &fi, err);
	if (ret)
		return prefixed(c, err, ret);
	if (!fi.available)
		return kg_fail(err, KG_ENOTSUP, "camera '%s': has no %s control", c->info.uri,
		               kg_feature_name(f));
	if (!fi.writable)
		return kg_fail(err, KG_ENOTSUP, "camera '%s': %s (%s) is read-only", c->info.uri,
		               kg_feature_name(f), fi.native);
	if (fi.max > fi.min && (value < fi.min || value > fi.max))
		return kg_fail(err, KG_ERANGE, "camera '%s': %s %g %s is outside %g..%g",
		               c->info.uri, kg_feature_name(f), value, fi.unit, fi.min, fi.max);
	ret = c->drv->set(c->state, f, value, err);
	double back = NAN;
	if (!ret)
		ret = kg_camera_get(c, f, &back, err);
	if (ret)
		return prefixed(c, err, ret);
	if (got)
		*got = back;
	/* On/off features exactly; others within one step (or 0.5 % for continuous
	 * controls: cameras round to line times and register units). */
	int onoff = f == KG_FEAT_AUTO_EXPOSURE || f == KG_FEAT_AUTO_WHITE_BALANCE;
	double tol = onoff ? 0 : fi.step > 0 ? fi.step : 0.005 * fabs(value) + 1e-9;
	if (!(fabs(back - value) <= tol))
		return kg_fail(err, KG_ERANGE,
		               "camera '%s': %s set to %g %s but reads back %g (%s)", c->info.uri,
		               kg_feature_name(f), value, fi.unit, back, fi.native);
	return 0;
}

int kg_camera_manual(kg_camera *c, kg_err *err)
{
	static const struct {
		kg_feature f;
		double v;
	} manual[] = {
		{KG_FEAT_AUTO_EXPOSURE, 0},
		{KG_FEAT_AUTO_WHITE_BALANCE, 0},
		{KG_FEAT_WB_RED, 1},
		{KG_FEAT_WB_BLUE, 1},
	};
	for (size_t i = 0; i < sizeof(manual) / sizeof(manual[0]); i++) {
		kg_feature_info fi;
		memset(&fi, 0, sizeof(fi));
		int ret = c->drv->feature_info(c->state, manual[i].f, &fi, err);
		if (ret)
			return prefixed(c, err, ret);
		if (!fi.available)
			continue;
		if (!fi.writable) {
			double v;
			if ((ret = kg_camera_get(c, manual[i].f, &v, err)))
				return ret;
			if (v != manual[i].v)
				return kg_fail(err, KG_ENOTSUP,
				               "camera '%s': %s is %g and read-only; measurement needs %g",
				               c->info.uri, kg_feature_name(manual[i].f), v, manual[i].v);
			continue;
		}
		if ((ret = kg_camera_set(c, manual[i].f, manual[i].v, NULL, err)))
			return ret;
	}
	return 0;
}

/* ---- format and stream -------------------------------------------------------- */

int kg_camera_set_format(kg_camera *c, const kg_frame_format *want, kg_frame_format *got,
                         kg_err *err)
{
	kg_check_arg(c && want, err);
	if (c->streaming)
		return kg_fail(err, KG_EINVAL, "camera '%s': stop the stream before changing format",
		               c->info.uri);
	kg_frame_format tmp;
	memset(&tmp, 0, sizeof(tmp));
	return prefixed(c, err, c->drv->set_format(c->state, want, got ? got : &tmp, err));
}

int kg_camera_get_format(kg_camera *c, kg_frame_format *out, kg_err *err)
{
	kg_check_arg(c && out, err);
	memset(out, 0, sizeof(*out));
	return prefixed(c, err, c->drv->get_format(c->state, out, err));
}

int kg_camera_start(kg_camera *c, int nbuffers, kg_err *err)
{
	kg_check_arg(c && nbuffers >= 0, err);
	if (c->streaming)
		return 0;
	/* The settings in force, for frames whose driver does not report them. */
	double v;
	kg_feature_info fi;
	for (int k = 0; k < 2; k++) {
		kg_feature f = k ? KG_FEAT_GAIN : KG_FEAT_EXPOSURE_US;
		memset(&fi, 0, sizeof(fi));
		if (!c->drv->feature_info(c->state, f, &fi, NULL) && fi.available)
			kg_camera_get(c, f, &v, NULL);
	}
	memset(&c->counts, 0, sizeof(c->counts));
	c->have_seq = 0;
	int ret = c->drv->start(c->state, nbuffers, err);
	if (ret)
		return prefixed(c, err, ret);
	c->streaming = 1;
	return 0;
}

int kg_camera_stop(kg_camera *c, kg_err *err)
{
	kg_check_arg(c, err);
	if (!c->streaming)
		return 0;
	c->streaming = 0;
	return prefixed(c, err, c->drv->stop(c->state, err));
}

/* Before the driver fills a frame: nothing, and exposure and gain not known. */
static void frame_reset(kg_frame *frame)
{
	memset(frame, 0, sizeof(*frame));
	frame->exposure_us = NAN;
	frame->gain = NAN;
}

/* A frame without its own exposure and gain has the last values read back. */
static void settings_of(const kg_camera *c, kg_frame *frame)
{
	if (isnan(frame->exposure_us))
		frame->exposure_us = c->exposure_us;
	if (isnan(frame->gain))
		frame->gain = c->gain;
}

int kg_camera_pop(kg_camera *c, int timeout_ms, kg_frame *frame, kg_err *err)
{
	kg_check_arg(c && frame, err);
	if (!c->streaming)
		return kg_fail(err, KG_EINVAL, "camera '%s': not streaming (kg_camera_start first)",
		               c->info.uri);
	frame_reset(frame);
	int ret = c->drv->pop(c->state, timeout_ms, frame, err);
	if (ret == KG_ETIMEDOUT) {
		c->counts.timeouts++;
		if (err) { /* the counts say whether the camera stopped or never started */
			kg_stream_stats st;
			kg_camera_stats(c, &st);
			size_t n = strlen(err->msg);
			snprintf(err->msg + n, sizeof(err->msg) - n,
			         " (since start: %llu complete, %llu dropped, %llu incomplete, "
			         "%llu failed, %llu timeouts)",
			         (unsigned long long)st.completed, (unsigned long long)st.dropped,
			         (unsigned long long)st.incomplete, (unsigned long long)st.failed,
			         (unsigned long long)st.timeouts);
		}
	}
	if (ret)
		return prefixed(c, err, ret);
	settings_of(c, frame);
	if (c->have_seq && frame->sequence > c->last_seq + 1)
		c->counts.dropped += frame->sequence - c->last_seq - 1;
	c->have_seq = 1;
	c->last_seq = frame->sequence;
	if (frame->status == KG_FRAME_OK)
		c->counts.completed++;
	if (c->rec && (ret = kg_frame_recorder_write(c->rec, frame, err))) {
		/* the recording's disk failed, not the camera: its message stands alone */
		c->drv->push(c->state, frame, NULL);
		return ret;
	}
	return 0;
}

int kg_camera_has_preview(const kg_camera *c) { return c && c->drv->preview != NULL; }

int kg_camera_preview(kg_camera *c, int timeout_ms, kg_frame *frame, int *own, kg_err *err)
{
	kg_check_arg(c && frame && own, err);
	*own = 0;
	if (!c->drv->preview) {
		int ret = kg_camera_start(c, 0, err);
		return ret ? ret : kg_camera_pop(c, timeout_ms, frame, err);
	}
	frame_reset(frame);
	int ret = c->drv->preview(c->state, timeout_ms, frame, err);
	if (ret)
		return prefixed(c, err, ret);
	settings_of(c, frame);
	*own = 1;
	return 0;
}

int kg_camera_push(kg_camera *c, kg_frame *frame, kg_err *err)
{
	kg_check_arg(c && frame, err);
	return prefixed(c, err, c->drv->push(c->state, frame, err));
}

void kg_camera_stats(kg_camera *c, kg_stream_stats *out)
{
	memset(out, 0, sizeof(*out));
	if (c->drv->stats)
		c->drv->stats(c->state, out);
	out->completed = c->counts.completed;
	out->dropped = c->counts.dropped;
	out->timeouts = c->counts.timeouts;
}

/* ---- recording ---------------------------------------------------------------- */

int kg_camera_record_start(kg_camera *c, const char *session_dir, kg_err *err)
{
	kg_check_arg(c && session_dir, err);
	if (c->rec)
		return kg_fail(err, KG_EINVAL, "camera '%s': already recording (record_stop first)",
		               c->info.uri);
	kg_frame_format fmt;
	int ret = kg_camera_get_format(c, &fmt, err);
	if (!ret)
		ret = kg_frame_recorder_open(session_dir, &c->info, &fmt, &c->rec, err);
	return ret;
}

int kg_camera_record_capture(kg_camera *c, const char *capture, kg_err *err)
{
	kg_check_arg(c && capture, err);
	if (!c->rec)
		return kg_fail(err, KG_EINVAL, "camera '%s': not recording", c->info.uri);
	return kg_frame_recorder_capture(c->rec, capture, err);
}

int kg_camera_record_last(kg_camera *c, char *file, size_t file_len, char sha256[65])
{
	if (!c || !c->rec)
		return KG_EINVAL;
	kg_frame_recorder_last(c->rec, file, file_len, sha256);
	return 0;
}

int kg_camera_record_sync(kg_camera *c, kg_err *err)
{
	kg_check_arg(c, err);
	return c->rec ? kg_frame_recorder_sync(c->rec, err) : 0;
}

int kg_camera_record_stop(kg_camera *c, kg_err *err)
{
	kg_check_arg(c, err);
	return c->rec ? kg_frame_recorder_close(&c->rec, err) : 0;
}

/* ---- enumeration -------------------------------------------------------------- */

/* Backends whose enumeration broadcasts on the network (GigE Vision discovery). */
static int discovers_over_network(const kg_camera_driver *d)
{
	return !strcmp(d->scheme, "aravis");
}

void kg_camera_enumerate(kg_camera_found_fn found, kg_camera_note_fn note, void *user)
{
	const char *disc = getenv("KOGEI_CAMERA_DISCOVERY");
	int no_network = disc && !strcmp(disc, "none");
	for (int i = 0; i < NDRIVERS; i++) {
		if (!drivers[i]->enumerate)
			continue;
		if (no_network && discovers_over_network(drivers[i])) {
			if (note)
				note(user, drivers[i]->scheme,
				     "not scanned: network discovery is off (KOGEI_CAMERA_DISCOVERY=none)");
			continue;
		}
		kg_err e = {{0}};
		if (drivers[i]->enumerate(found, user, &e) && note)
			note(user, drivers[i]->scheme, e.msg);
	}
}

/* ---- frames to float images --------------------------------------------------- */

static float clamp01(float v) { return v < 0 ? 0 : v > 1 ? 1 : v; }

/* A forced MJPEG frame: decoded to R'G'B' (display-encoded, like YUYV) on 0..1. */
static int mjpeg_to_image(const kg_frame *f, kg_image **out, kg_err *err)
{
	const kg_frame_format *fmt = &f->fmt;
	kg_image *img = NULL;
	int ret = kg_image_new(fmt->width, fmt->height, 3, &img, err); /* checks the size */
	size_t n = img ? (size_t)fmt->width * (size_t)fmt->height * 3 : 0;
	uint8_t *rgb = img ? malloc(n) : NULL;
	if (!ret && !rgb)
		ret = kg_fail(err, KG_ENOMEM, "out of memory for a %dx%d MJPEG frame", fmt->width,
		              fmt->height);
	if (!ret)
		ret = kg_mjpeg_decode(f->data, f->size, fmt->width, fmt->height, rgb, err);
	if (ret) {
		free(rgb);
		kg_image_free(&img);
		if (err)
			kg_err_prefix(err, "frame %llu", (unsigned long long)f->sequence);
		return ret;
	}
	for (size_t i = 0; i < n; i++)
		img->data[i] = (float)rgb[i] / 255.0f;
	free(rgb);
	img->bits = 8;
	img->is_float = 0;
	*out = img;
	return 0;
}

int kg_frame_to_image(const kg_frame *f, int allow_nonlinear, kg_image **out, kg_err *err)
{
	kg_check_arg(f && f->data && out, err);
	*out = NULL;
	const kg_frame_format *fmt = &f->fmt;
	if (!kg_pixfmt_is_linear(fmt->pixfmt) && !allow_nonlinear)
		return kg_fail(err, KG_EINVAL,
		               "frame %llu: %s is not linear sensor data%s; refused for measurement "
		               "unless forced",
		               (unsigned long long)f->sequence, kg_pixfmt_name(fmt->pixfmt),
		               fmt->pixfmt == KG_PIX_MJPEG ? " (MJPEG: compressed, lossy and "
		                                             "display-encoded)"
		                                           : "");
	if (fmt->pixfmt == KG_PIX_MJPEG)
		return mjpeg_to_image(f, out, err);
	int bpp = kg_pixfmt_bytes_per_pixel(fmt->pixfmt);
	if (!bpp || fmt->width <= 0 || fmt->height <= 0 ||
	    fmt->stride < (size_t)fmt->width * (size_t)bpp ||
	    f->size < fmt->stride * (size_t)(fmt->height - 1) + (size_t)fmt->width * (size_t)bpp)
		return kg_fail(err, KG_EINVAL,
		               "frame %llu: %zu bytes do not hold %dx%d %s (stride %zu)",
		               (unsigned long long)f->sequence, f->size, fmt->width, fmt->height,
		               kg_pixfmt_name(fmt->pixfmt), fmt->stride);
	if (fmt->pixfmt == KG_PIX_YUYV && (fmt->width & 1))
		return kg_fail(err, KG_EINVAL,
		               "frame %llu: YUYV width %d: expected an even width (pixels come in "
		               "pairs sharing Cb and Cr)",
		               (unsigned long long)f->sequence, fmt->width);
	int ch = kg_pixfmt_channels(fmt->pixfmt);
	kg_image *img;
	int ret = kg_image_new(fmt->width, fmt->height, ch, &img, err);
	if (ret)
		return ret;
	int bits = fmt->bits > 0 ? fmt->bits : 8;
	float scale = 1.0f / (float)((1u << bits) - 1u);
	for (int y = 0; y < fmt->height; y++) {
		const uint8_t *row = (const uint8_t *)f->data + fmt->stride * (size_t)y;
		float *o = img->data + (size_t)y * (size_t)fmt->width * (size_t)ch;
		switch (fmt->pixfmt) {
		case KG_PIX_MONO8:
		case KG_PIX_BAYER8:
		case KG_PIX_RGB8:
			for (int x = 0; x < fmt->width * ch; x++)
				o[x] = row[x] * scale;
			break;
		case KG_PIX_MONO16:
		case KG_PIX_BAYER16:
		case KG_PIX_RGB16:
			for (int x = 0; x < fmt->width * ch; x++)
				o[x] = (float)(row[2 * x] | row[2 * x + 1] << 8) * scale;
			break;
		case KG_PIX_YUYV: /* BT.601 limited range to R'G'B', display-encoded */
			for (int x = 0; x < fmt->width; x++) {
				float Y = ((float)row[2 * x] - 16.0f) / 219.0f;
				int pair = x & ~1;
				float cb = ((float)row[2 * pair + 1] - 128.0f) / 224.0f;
				float cr = ((float)row[2 * pair + 3] - 128.0f) / 224.0f;
				o[3 * x] = clamp01(Y + 1.402f * cr);
				o[3 * x + 1] = clamp01(Y - 0.344136f * cb - 0.714136f * cr);
				o[3 * x + 2] = clamp01(Y + 1.772f * cb);
			}
			break;
		default:
			break;
		}
	}
	img->bits = bits;
	img->is_float = 0;
	if ((fmt->pixfmt == KG_PIX_BAYER8 || fmt->pixfmt == KG_PIX_BAYER16) && fmt->cfa[0] &&
	    (ret = kg_image_set_cfa(img, fmt->cfa, 2, 2, err))) {
		kg_image_free(&img);
		return ret;
	}
	*out = img;
	return 0;
}
