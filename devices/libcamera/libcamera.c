/* libcamera: cameras libcamera lists (Raspberry Pi and other ISP pipelines, UVC
 * through its uvcvideo pipeline, ...), through the C++ shim lc_shim.h.
 *
 * URI libcamera:<id> (an id as libcamera lists it, see `kogei devices`) or
 * libcamera:<index>. The pixel format chooses the stream: Bayer comes from a raw
 * stream (StreamRole::Raw, the sensor's own samples, unpacked 8 or 16-bit words only),
 * mono, RGB, YUYV and MJPEG from a processed one (StillCapture, or Viewfinder), mono
 * falling back to the raw stream of a mono sensor. Features map onto libcamera
 * controls set on every request: ExposureTime, AnalogueGain, AeEnable, AwbEnable,
 * ColourGains, FrameDurationLimits; a frame's exposure and gain are those its
 * request's metadata reports. libcamera's RGB888 (B, G, R in memory) is delivered as
 * kogei's rgb8 through a per-buffer copy with red and blue swapped. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera_driver.h"
#include "lc_formats.h"
#include "lc_shim.h"

typedef struct lc_state {
	kg_lc_camera *cam;
	const kg_lc_format *fmt; /* NULL until a format kogei can take is configured */
	kg_frame_format ff;
	uint8_t **swapped;       /* per slot, for formats stored B, G, R */
	int nswapped;
	uint64_t failed, incomplete;
} lc_state;

/* ---- formats ------------------------------------------------------------------- */

/* Streams to try for a format: Bayer only raw; mono processed, then a mono sensor's
 * raw stream; everything else processed. */
static int roles_for(kg_pixfmt p, int roles[2])
{
	if (p == KG_PIX_BAYER8 || p == KG_PIX_BAYER16) {
		roles[0] = 1;
		return 1;
	}
	roles[0] = 0;
	if (p == KG_PIX_MONO8 || p == KG_PIX_MONO16) {
		roles[1] = 1;
		return 2;
	}
	return 1;
}

static void request_name(kg_pixfmt p, int bits, const char *cfa, char *buf, size_t len)
{
	const char *base = kg_pixfmt_name(p);
	if (bits && bits != 8 && bits != 16)
		snprintf(buf, len, "%.*s%d%s%s", (int)strlen(base) - 2, base, bits, cfa[0] ? " " : "",
		         cfa);
	else
		snprintf(buf, len, "%s%s%s", base, cfa[0] ? " " : "", cfa);
}

/* Append to a message, "; "-separated, truncating when full. */
static void append(char *buf, size_t len, const char *fmt, ...) KG_PRINTF(3, 4);
static void append(char *buf, size_t len, const char *fmt, ...)
{
	size_t used = strlen(buf);
	if (used && used + 2 < len)
		memcpy(buf + used, "; ", 3), used += 2;
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(buf + used, len - used, fmt, ap);
	va_end(ap);
}

/* Configure the first stream that delivers pixfmt/bits/cfa at about width x height
 * (0: the stream's default). */
static int configure(lc_state *s, kg_pixfmt pixfmt, int bits, const char *cfa, int width,
                     int height, kg_err *err)
{
	uint32_t cand[32];
	char want[48];
	request_name(pixfmt, bits, cfa, want, sizeof(want));
	int n = kg_lc_formats_for(pixfmt, bits, cfa, cand, 32);
	if (!n)
		return kg_fail(err, KG_ENOTSUP,
		               "pixel format %s: libcamera has no unpacked format for it (expected "
		               "mono8, mono10/12/16, bayer8, bayer10/12/16, rgb8, yuyv or mjpeg)",
		               want);
	int roles[2], nroles = roles_for(pixfmt, roles);
	char tried[640] = "";
	for (int r = 0; r < nroles; r++) {
		kg_lc_stream got;
		char note[160];
		kg_err e = {{0}};
		int ret = kg_lc_try(s->cam, roles[r], cand, n, width, height, &got, note, sizeof(note),
		                    &e);
		const char *role = roles[r] ? "raw stream" : "processed stream";
		if (ret == KG_ENOMEM)
			return kg_fail(err, ret, "%s", e.msg);
		if (ret) {
			append(tried, sizeof(tried), "%s: %s", role, e.msg);
			continue;
		}
		const kg_lc_format *f = kg_lc_format_find(got.fourcc, got.modifier);
		if (!f || !kg_lc_format_matches(f, pixfmt, bits, cfa)) {
			char offered[256], name[48];
			kg_lc_offered(s->cam, roles[r], offered, sizeof(offered));
			kg_lc_format_name(got.fourcc, got.modifier, name, sizeof(name));
			append(tried, sizeof(tried), "%s settles on %s (%s; offers %s)", role, name,
			       note[0] ? note : "unchanged", offered);
			continue;
		}
		if ((ret = kg_lc_configure(s->cam, err)))
			return ret;
		s->fmt = f;
		kg_lc_frame_format(f, got.width, got.height, got.stride, got.frame_size, &s->ff);
		return 0;
	}
	return kg_fail(err, KG_ENOTSUP, "pixel format %s: not delivered: %s", want, tried);
}

/* ---- open and close ------------------------------------------------------------- */

static void lc_free_swapped(lc_state *s)
{
	for (int i = 0; i < s->nswapped; i++)
		free(s->swapped[i]);
	free(s->swapped);
	s->swapped = NULL;
	s->nswapped = 0;
}

static void lc_close(void *state)
{
	lc_state *s = state;
	if (!s)
		return;
	kg_lc_close(&s->cam);
	lc_free_swapped(s);
	free(s);
}

static int lc_open(const char *target, void **state, kg_camera_info *info, kg_err *err)
{
	lc_state *s = calloc(1, sizeof(*s));
	if (!s)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	kg_lc_identity who;
	int ret = kg_lc_open(target, &s->cam, &who, err);
	if (ret) {
		free(s);
		return ret;
	}
	snprintf(info->model, sizeof(info->model), "%.63s", who.model[0] ? who.model : who.id);
	snprintf(info->transport, sizeof(info->transport), "libcamera");
	info->sensor_width = who.sensor_width;
	info->sensor_height = who.sensor_height;
	/* A first format kogei can measure with: raw Bayer, then mono, then processed RGB,
	 * then the non-linear ones. A camera offering none still opens; start says why. */
	static const kg_pixfmt order[] = {KG_PIX_BAYER16, KG_PIX_BAYER8, KG_PIX_MONO16,
	                                  KG_PIX_MONO8,   KG_PIX_RGB8,   KG_PIX_YUYV,
	                                  KG_PIX_MJPEG};
	for (size_t i = 0; i < sizeof(order) / sizeof(order[0]) && !s->fmt; i++) {
		ret = configure(s, order[i], 0, "", 0, 0, NULL);
		if (ret == KG_ENOMEM || ret == KG_EIO) {
			lc_close(s);
			return kg_fail(err, ret, "configuring a first pixel format failed");
		}
	}
	*state = s;
	return 0;
}

/* ---- features ------------------------------------------------------------------- */

static const struct {
	kg_lc_control control;
	const char *unit;
} feature_map[KG_FEAT_COUNT] = {
	[KG_FEAT_EXPOSURE_US] = {KG_LC_EXPOSURE_TIME, "us"},
	[KG_FEAT_GAIN] = {KG_LC_ANALOGUE_GAIN, "x"},
	[KG_FEAT_FRAME_RATE] = {KG_LC_FRAME_DURATION, "fps"},
	[KG_FEAT_AUTO_EXPOSURE] = {KG_LC_AE_ENABLE, "bool"},
	[KG_FEAT_AUTO_WHITE_BALANCE] = {KG_LC_AWB_ENABLE, "bool"},
	[KG_FEAT_WB_RED] = {KG_LC_COLOUR_GAIN_RED, "x"},
	[KG_FEAT_WB_BLUE] = {KG_LC_COLOUR_GAIN_BLUE, "x"},
};

static int lc_feature_info(void *state, kg_feature f, kg_feature_info *out, kg_err *err)
{
	lc_state *s = state;
	if (!feature_map[f].unit)
		return 0; /* no libcamera control behind it */
	kg_lc_control k = feature_map[f].control;
	double lo, hi;
	out->available = kg_lc_control_range(s->cam, k, &lo, &hi);
	out->writable = out->available;
	if (f == KG_FEAT_FRAME_RATE) { /* durations in us, longest first */
		out->min = hi > 0 ? 1e6 / hi : 0;
		out->max = lo > 0 ? 1e6 / lo : 0;
	} else {
		out->min = lo;
		out->max = hi;
	}
	/* continuous: sensors round exposure to line times, gain to register steps */
	out->step = f == KG_FEAT_AUTO_EXPOSURE || f == KG_FEAT_AUTO_WHITE_BALANCE ? 1 : 0;
	snprintf(out->unit, sizeof(out->unit), "%s", feature_map[f].unit);
	snprintf(out->native, sizeof(out->native), "%s", kg_lc_control_name(k));
	return 0;
}

static int lc_get(void *state, kg_feature f, double *value, kg_err *err)
{
	lc_state *s = state;
	double v;
	int ret = kg_lc_control_get(s->cam, feature_map[f].control, &v, err);
	if (ret)
		return ret;
	*value = f == KG_FEAT_FRAME_RATE ? (v > 0 ? 1e6 / v : 0) : v;
	return 0;
}

static int lc_set(void *state, kg_feature f, double value, kg_err *err)
{
	lc_state *s = state;
	if (f == KG_FEAT_FRAME_RATE) {
		if (!(value > 0))
			return kg_fail(err, KG_EINVAL, "frame_rate %g: expected > 0 fps", value);
		value = 1e6 / value;
	}
	return kg_lc_control_set(s->cam, feature_map[f].control, value, err);
}

/* ---- format --------------------------------------------------------------------- */

static int lc_get_format(void *state, kg_frame_format *out, kg_err *err)
{
	lc_state *s = state;
	if (!s->fmt) {
		char raw[256], processed[256];
		kg_lc_offered(s->cam, 1, raw, sizeof(raw));
		kg_lc_offered(s->cam, 0, processed, sizeof(processed));
		return kg_fail(err, KG_ENOTSUP,
		               "no pixel format kogei can take (raw stream offers %s; processed "
		               "stream offers %s)",
		               raw, processed);
	}
	*out = s->ff;
	return 0;
}

static int lc_set_format(void *state, const kg_frame_format *want, kg_frame_format *got,
                         kg_err *err)
{
	lc_state *s = state;
	if (want->offset_x || want->offset_y)
		return kg_fail(err, KG_ENOTSUP,
		               "ROI offset %d,%d: the libcamera backend sets only the output size",
		               want->offset_x, want->offset_y);
	kg_pixfmt p = want->pixfmt ? want->pixfmt : s->ff.pixfmt;
	if (!p)
		return lc_get_format(s, got, err);
	int same = p == s->ff.pixfmt;
	int bits = want->bits ? want->bits : same ? s->ff.bits : 0;
	const char *cfa = want->cfa[0] ? want->cfa : same ? s->ff.cfa : "";
	int w = want->width > 0 ? want->width : s->ff.width;
	int h = want->height > 0 ? want->height : s->ff.height;
	int ret = configure(s, p, bits, cfa, w, h, err);
	if (ret)
		return ret;
	*got = s->ff;
	return 0;
}

/* ---- stream --------------------------------------------------------------------- */

static int lc_start(void *state, int nbuffers, kg_err *err)
{
	lc_state *s = state;
	kg_frame_format ff;
	int ret = lc_get_format(s, &ff, err);
	if (ret)
		return ret;
	if ((ret = kg_lc_start(s->cam, nbuffers, err)))
		return ret;
	s->failed = s->incomplete = 0;
	if (s->fmt->swap_rb) {
		s->nswapped = kg_lc_slots(s->cam);
		s->swapped = calloc((size_t)s->nswapped, sizeof(*s->swapped));
		if (!s->swapped) {
			s->nswapped = 0;
			kg_lc_stop(s->cam, NULL);
			return kg_fail(err, KG_ENOMEM, "out of memory");
		}
	}
	return 0;
}

static int lc_stop(void *state, kg_err *err)
{
	lc_state *s = state;
	int ret = kg_lc_stop(s->cam, err);
	lc_free_swapped(s);
	return ret;
}

/* The slot's own copy with red and blue swapped (libcamera's RGB888 to rgb8). */
static const void *swapped_copy(lc_state *s, int slot, const uint8_t *src)
{
	if (slot < 0 || slot >= s->nswapped)
		return NULL;
	if (!s->swapped[slot] && !(s->swapped[slot] = calloc(1, s->ff.size)))
		return NULL;
	kg_lc_swap_rb(src, s->swapped[slot], s->ff.width, s->ff.height, s->ff.stride);
	return s->swapped[slot];
}

static int lc_pop(void *state, int timeout_ms, kg_frame *frame, kg_err *err)
{
	lc_state *s = state;
	kg_lc_buffer b;
	int ret = kg_lc_pop(s->cam, timeout_ms, &b, err);
	if (ret)
		return ret;
	frame->fmt = s->ff;
	frame->slot = b.slot;
	frame->sequence = b.sequence;
	frame->timestamp = (double)b.timestamp_ns * 1e-9;
	frame->exposure_us = b.exposure_us;
	frame->gain = b.gain;
	frame->size = b.bytesused ? b.bytesused : b.length;
	if (frame->size > b.length)
		frame->size = b.length;
	frame->data = b.data;
	if (b.status) {
		frame->status = KG_FRAME_CORRUPT;
		s->failed++;
	} else if (s->ff.pixfmt != KG_PIX_MJPEG && frame->size < s->ff.size) {
		frame->status = KG_FRAME_INCOMPLETE;
		s->incomplete++;
	} else {
		frame->status = KG_FRAME_OK;
		if (s->ff.pixfmt != KG_PIX_MJPEG)
			frame->size = s->ff.size;
	}
	/* complete frames only: a short buffer is not read past its end */
	if (s->fmt->swap_rb && frame->status == KG_FRAME_OK &&
	    !(frame->data = swapped_copy(s, b.slot, b.data))) {
		kg_lc_push(s->cam, b.slot, NULL);
		return kg_fail(err, KG_ENOMEM, "out of memory converting RGB888 to rgb8");
	}
	return 0;
}

static int lc_push(void *state, kg_frame *frame, kg_err *err)
{
	lc_state *s = state;
	return kg_lc_push(s->cam, frame->slot, err);
}

static void lc_stats(void *state, kg_stream_stats *out)
{
	lc_state *s = state;
	out->failed = s->failed;
	out->incomplete = s->incomplete;
}

/* ---- enumeration ---------------------------------------------------------------- */

typedef struct lc_found {
	kg_camera_found_fn found;
	void *user;
} lc_found;

static void lc_found_one(void *user, int index, const char *id, const char *model)
{
	lc_found *f = user;
	char uri[300];
	snprintf(uri, sizeof(uri), "libcamera:%s", id);
	f->found(f->user, uri, model[0] ? model : id, "", "libcamera");
}

static int lc_enumerate(kg_camera_found_fn found, void *user, kg_err *err)
{
	lc_found f = {found, user};
	int n = kg_lc_list(found ? lc_found_one : NULL, &f, err);
	return n < 0 ? n : 0;
}

const kg_camera_driver kg_camera_libcamera_driver = {
	.scheme = "libcamera",
	.description = "libcamera cameras: raw Bayer and ISP-processed streams (C++ shim)",
	.enumerate = lc_enumerate,
	.open = lc_open,
	.close = lc_close,
	.feature_info = lc_feature_info,
	.get = lc_get,
	.set = lc_set,
	.set_format = lc_set_format,
	.get_format = lc_get_format,
	.start = lc_start,
	.stop = lc_stop,
	.pop = lc_pop,
	.push = lc_push,
	.stats = lc_stats,
};
