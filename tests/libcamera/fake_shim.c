/* A scripted stand-in for devices/libcamera/lc_shim.cpp, linked into test_driver in
 * place of the real shim (the test's own definitions win over the archive's), so the
 * C driver (devices/libcamera/libcamera.c) is driven through kogei's public camera API
 * without a camera. It behaves as libcamera documents:
 * - one camera, id "fake/sensor@10", model "fakesensor", pixel array 4056x3040;
 * - the raw stream lists SBGGR10_CSI2P (packed) then SBGGR12, default 64x48, stride
 *   width * 2 + 32; the processed stream lists RGB888 (B, G, R in memory) and YUYV,
 *   default 32x24, stride width * 3 + 16; validate() turns a format the stream does not
 *   list into its first one and rounds sizes down to even (Adjusted);
 * - controls ExposureTime 10..100000 us (metadata reports it rounded down to the 30 us
 *   line time), AnalogueGain 1..16, AeEnable, AwbEnable, ColourGains 0..32,
 *   FrameDurationLimits 33333..1000000 us;
 * - requests complete in queue order; the sensor skips sequence number 3 (a dropped
 *   frame) and the request with sequence 5 comes back half filled; a pop with nothing
 *   queued times out at once.
 * Samples: raw pixel (x, y) of sequence s is (x + 2 y + s) & 0xfff; processed pixels are
 * the bytes 10, 20, 30 (B, G, R). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lc_formats.h"
#include "lc_shim.h"

#define FOURCC(a, b, c, d)                                                             \
	((uint32_t)(a) | (uint32_t)(b) << 8 | (uint32_t)(c) << 16 | (uint32_t)(d) << 24)
#define PACKED_MOD ((uint64_t)11 << 56 | 1)

static const struct fake_format {
	const char *name;
	uint32_t fourcc;
	uint64_t modifier;
	int raw;
} fake_formats[] = {
	{"SBGGR10_CSI2P", FOURCC('B', 'G', '1', '0'), PACKED_MOD, 1},
	{"SBGGR12", FOURCC('B', 'G', '1', '2'), 0, 1},
	{"RGB888", FOURCC('R', 'G', '2', '4'), 0, 0},
	{"YUYV", FOURCC('Y', 'U', 'Y', 'V'), 0, 0},
};
enum { NFAKE = 4, MAXSLOTS = 8 };

struct kg_lc_camera {
	kg_lc_stream tried, config;
	int have_tried, have_config, streaming;
	int nslots;
	uint8_t *buf[MAXSLOTS];
	int queue[MAXSLOTS], queued; /* FIFO of queued slots */
	double carried[MAXSLOTS][KG_LC_NCONTROLS]; /* settings each queued request carried */
	double want[KG_LC_NCONTROLS];
	int want_set[KG_LC_NCONTROLS];
	double seen[KG_LC_NCONTROLS];
	int seen_valid[KG_LC_NCONTROLS];
	uint64_t next_seq;
};

static int open_cameras;

int kg_lc_test_open_cameras(void);
int kg_lc_test_open_cameras(void) { return open_cameras; }

const char *kg_lc_version(void) { return "fake"; }

int kg_lc_list(kg_lc_camera_fn fn, void *user, kg_err *err)
{
	if (fn)
		fn(user, 0, "fake/sensor@10", "fakesensor");
	return 1;
}

void kg_lc_format_name(uint32_t fourcc, uint64_t modifier, char *buf, size_t len)
{
	for (int i = 0; i < NFAKE; i++)
		if (fake_formats[i].fourcc == fourcc && fake_formats[i].modifier == modifier) {
			snprintf(buf, len, "%s", fake_formats[i].name);
			return;
		}
	const kg_lc_format *f = kg_lc_format_find(fourcc, modifier);
	snprintf(buf, len, "%s", f ? f->name : "?");
}

int kg_lc_open(const char *target, kg_lc_camera **out, kg_lc_identity *who, kg_err *err)
{
	if (strcmp(target, "0") && strcmp(target, "fake/sensor@10"))
		return kg_fail(err, KG_ENODEV, "no libcamera camera with id or index '%s': libcamera "
		               "fake sees 1 camera: fake/sensor@10", target);
	kg_lc_camera *c = calloc(1, sizeof(*c));
	if (!c)
		return KG_ENOMEM;
	memset(who, 0, sizeof(*who));
	snprintf(who->id, sizeof(who->id), "fake/sensor@10");
	snprintf(who->model, sizeof(who->model), "fakesensor");
	who->sensor_width = 4056;
	who->sensor_height = 3040;
	c->next_seq = 1;
	open_cameras++;
	*out = c;
	return 0;
}

void kg_lc_close(kg_lc_camera **pc)
{
	if (!pc || !*pc)
		return;
	kg_lc_stop(*pc, NULL);
	free(*pc);
	*pc = NULL;
	open_cameras--;
}

static const char *const names[KG_LC_NCONTROLS] = {
	"AeEnable",       "AwbEnable",      "ExposureTime",        "AnalogueGain",
	"ColourGains[0]", "ColourGains[1]", "FrameDurationLimits",
};
static const double lo[KG_LC_NCONTROLS] = {0, 0, 10, 1, 0, 0, 33333};
static const double hi[KG_LC_NCONTROLS] = {1, 1, 100000, 16, 32, 32, 1000000};

const char *kg_lc_control_name(kg_lc_control k) { return names[k]; }

int kg_lc_control_range(kg_lc_camera *c, kg_lc_control k, double *min, double *max)
{
	*min = lo[k];
	*max = hi[k];
	return 1;
}

int kg_lc_control_set(kg_lc_camera *c, kg_lc_control k, double v, kg_err *err)
{
	c->want[k] = v;
	c->want_set[k] = 1;
	for (int i = 0; i < KG_LC_NCONTROLS; i++)
		c->seen_valid[i] = 0; /* only frames carrying the new settings count */
	return 0;
}

int kg_lc_control_get(kg_lc_camera *c, kg_lc_control k, double *v, kg_err *err)
{
	if (c->seen_valid[k])
		*v = c->seen[k];
	else if (c->want_set[k])
		*v = c->want[k];
	else
		return kg_fail(err, KG_ENOENT, "%s: no value known", names[k]);
	return 0;
}

int kg_lc_try(kg_lc_camera *c, int raw, const uint32_t *fourccs, int n, int width,
              int height, kg_lc_stream *got, char *note, size_t note_len, kg_err *err)
{
	const struct fake_format *pick = NULL, *first = NULL;
	for (int i = 0; i < NFAKE; i++)
		if (fake_formats[i].raw == raw && !first)
			first = &fake_formats[i];
	for (int j = 0; j < n && !pick; j++)
		for (int i = 0; i < NFAKE; i++)
			if (fake_formats[i].raw == raw && fake_formats[i].fourcc == fourccs[j] &&
			    !fake_formats[i].modifier)
				pick = &fake_formats[i];
	if (note && note_len)
		snprintf(note, note_len, "%s", pick ? "" : "libcamera adjusted the format");
	if (!pick)
		pick = first;
	memset(got, 0, sizeof(*got));
	got->fourcc = pick->fourcc;
	got->modifier = pick->modifier;
	got->width = width > 0 ? width & ~1 : raw ? 64 : 32;
	got->height = height > 0 ? height & ~1 : raw ? 48 : 24;
	got->stride = (unsigned)(raw ? got->width * 2 + 32 : got->width * 3 + 16);
	got->frame_size = got->stride * (unsigned)got->height;
	got->buffer_count = 4;
	got->raw = raw;
	c->tried = *got;
	c->have_tried = 1;
	return 0;
}

int kg_lc_configure(kg_lc_camera *c, kg_err *err)
{
	if (!c->have_tried)
		return kg_fail(err, KG_EINVAL, "configure: nothing validated");
	c->config = c->tried;
	c->have_config = 1;
	return 0;
}

void kg_lc_offered(kg_lc_camera *c, int raw, char *buf, size_t len)
{
	snprintf(buf, len, raw ? "SBGGR10_CSI2P, SBGGR12" : "RGB888, YUYV");
}

static void queue_slot(kg_lc_camera *c, int slot)
{
	c->queue[c->queued++] = slot;
	for (int k = 0; k < KG_LC_NCONTROLS; k++)
		c->carried[slot][k] = c->want_set[k] ? c->want[k] : NAN;
}

int kg_lc_start(kg_lc_camera *c, int nbuffers, kg_err *err)
{
	if (!c->have_config)
		return kg_fail(err, KG_EINVAL, "start: nothing configured");
	c->nslots = nbuffers > 0 ? nbuffers : (int)c->config.buffer_count;
	if (c->nslots > MAXSLOTS)
		c->nslots = MAXSLOTS;
	for (int i = 0; i < c->nslots; i++) {
		c->buf[i] = calloc(1, c->config.frame_size);
		if (!c->buf[i])
			return KG_ENOMEM;
		queue_slot(c, i);
	}
	c->streaming = 1;
	return 0;
}

int kg_lc_stop(kg_lc_camera *c, kg_err *err)
{
	for (int i = 0; i < c->nslots; i++) {
		free(c->buf[i]);
		c->buf[i] = NULL;
	}
	c->nslots = c->queued = 0;
	c->streaming = 0;
	return 0;
}

int kg_lc_slots(const kg_lc_camera *c) { return c->nslots; }

int kg_lc_pop(kg_lc_camera *c, int timeout_ms, kg_lc_buffer *out, kg_err *err)
{
	if (!c->queued)
		return kg_fail(err, KG_ETIMEDOUT, "no request completed within %d ms", timeout_ms);
	int slot = c->queue[0];
	memmove(c->queue, c->queue + 1, (size_t)--c->queued * sizeof(int));
	if (c->next_seq == 3)
		c->next_seq++; /* the sensor skipped a frame */
	uint64_t seq = c->next_seq++;
	const kg_lc_stream *s = &c->config;
	uint8_t *b = c->buf[slot];
	for (int y = 0; y < s->height; y++)
		for (int x = 0; x < s->width; x++) {
			uint8_t *p = b + (size_t)s->stride * (size_t)y;
			if (s->raw) {
				unsigned v = ((unsigned)x + 2u * (unsigned)y + (unsigned)seq) & 0xfff;
				p[2 * x] = (uint8_t)(v & 0xff);
				p[2 * x + 1] = (uint8_t)(v >> 8);
			} else {
				p[3 * x] = 10;
				p[3 * x + 1] = 20;
				p[3 * x + 2] = 30;
			}
		}
	memset(out, 0, sizeof(*out));
	out->slot = slot;
	out->data = b;
	out->length = s->frame_size;
	out->bytesused = seq == 5 ? s->frame_size / 2 : s->frame_size;
	out->sequence = seq;
	out->timestamp_ns = seq * 33333333ull;
	double e = c->carried[slot][KG_LC_EXPOSURE_TIME];
	out->exposure_us = isnan(e) ? 1000 : floor(e / 30) * 30; /* whole line times */
	double g = c->carried[slot][KG_LC_ANALOGUE_GAIN];
	out->gain = isnan(g) ? 1 : g;
	/* metadata of a request that carried the current settings is the read-back */
	int current = 1;
	for (int k = 0; k < KG_LC_NCONTROLS; k++)
		current &= !c->want_set[k] || c->carried[slot][k] == c->want[k];
	if (current) {
		c->seen[KG_LC_EXPOSURE_TIME] = out->exposure_us;
		c->seen[KG_LC_ANALOGUE_GAIN] = out->gain;
		c->seen_valid[KG_LC_EXPOSURE_TIME] = c->seen_valid[KG_LC_ANALOGUE_GAIN] = 1;
	}
	return 0;
}

int kg_lc_push(kg_lc_camera *c, int slot, kg_err *err)
{
	if (!c->streaming)
		return 0;
	if (slot < 0 || slot >= c->nslots)
		return kg_fail(err, KG_EINVAL, "push: buffer %d is not one of the stream's %d", slot,
		               c->nslots);
	queue_slot(c, slot);
	return 0;
}
