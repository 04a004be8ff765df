/* Frames injected into an Aravis fake camera (in-process, or served over loopback by
 * the fake GigE Vision camera) through its fill callback, and the check that kogei
 * delivers them byte for byte.
 *
 * Frame k of a run is 16 bytes of header (the frame number, then the exposure and gain
 * the fake camera reported to the callback) followed by xoshiro256** bytes seeded with
 * k, so a reordered, repeated, truncated or shifted frame cannot match. The callback is
 * called only for frames that have a buffer to go to, so the k-th frame kogei delivers
 * must be the k-th one filled. */
#ifndef KG_ARAVIS_INJECT_H
#define KG_ARAVIS_INJECT_H

#include <arv.h>
#include <stdint.h>
#include <string.h>

#include "kg_camera.h"
#include "kg_core.h"

typedef struct inject {
	ArvFakeCamera *fake;
	GMutex lock;
	uint64_t filled;       /* frames filled so far */
	uint32_t exposure_us;  /* as the fake camera passed them to the last fill */
	uint32_t gain;
	size_t last_size;      /* bytes written into the last frame */
} inject;

static inline void inject_frame_bytes(uint64_t k, uint8_t *out, size_t size)
{
	kg_rng r;
	kg_rng_seed(&r, 0x6b6f676569ull ^ (k * 0x9e3779b97f4a7c15ull));
	for (size_t i = 0; i < size; i += 8) {
		uint64_t v = kg_rng_next(&r);
		memcpy(out + i, &v, size - i < 8 ? size - i : 8);
	}
	memcpy(out, &k, size < 8 ? size : 8);
}

/* The bytes of the frame a fill callback is asked for. The buffer's own size is stale
 * in Aravis 0.8.26 (often 0): the frame size comes from the registers and the pixel
 * format. */
static inline size_t inject_frame_size(ArvFakeCamera *fake, ArvPixelFormat pf)
{
	guint32 w = 0, h = 0;
	arv_fake_camera_read_register(fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, &w);
	arv_fake_camera_read_register(fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT, &h);
	return (size_t)w * h * ARV_PIXEL_FORMAT_BIT_PER_PIXEL(pf) / 8;
}

/* ArvFakeCameraFillPattern. */
static inline void inject_fill(ArvBuffer *b, void *user, guint32 exposure_us, guint32 gain,
                               ArvPixelFormat pf)
{
	inject *in = user;
	size_t size = inject_frame_size(in->fake, pf);
	uint8_t *data = (uint8_t *)arv_buffer_get_data(b, NULL);
	g_mutex_lock(&in->lock);
	uint64_t k = in->filled++;
	in->exposure_us = exposure_us;
	in->gain = gain;
	in->last_size = size;
	g_mutex_unlock(&in->lock);
	inject_frame_bytes(k, data, size);
	if (size >= 16) {
		memcpy(data + 8, &exposure_us, 4);
		memcpy(data + 12, &gain, 4);
	}
}

static inline void inject_attach(inject *in, ArvFakeCamera *fake)
{
	memset(in, 0, sizeof(*in));
	g_mutex_init(&in->lock);
	in->fake = fake;
	arv_fake_camera_set_fill_pattern(fake, inject_fill, in);
}

/* Keep only the bits of `mask` in every little-endian 16-bit sample (a 12-bit camera's
 * samples). */
static inline void inject_mask_samples(uint8_t *data, size_t size, guint32 mask)
{
	for (size_t i = 0; i + 1 < size; i += 2) {
		guint32 v = (guint32)(data[i] | data[i + 1] << 8) & mask;
		data[i] = (uint8_t)v;
		data[i + 1] = (uint8_t)(v >> 8);
	}
}

/* 1 when frame f is injected frame k byte for byte, its 16-bit samples cut to mask
 * (0: as injected); else prints where they differ. */
static inline int inject_matches_masked(const kg_frame *f, uint64_t k, guint32 mask)
{
	size_t n = f->fmt.size;
	uint8_t *want = malloc(n ? n : 1);
	if (!want)
		return 0;
	inject_frame_bytes(k, want, n);
	if (n >= 16)
		memcpy(want + 8, (const uint8_t *)f->data + 8, 8); /* settings: checked apart */
	if (mask)
		inject_mask_samples(want, n, mask);
	size_t at = n;
	for (size_t i = 0; i < n && at == n; i++)
		if (want[i] != ((const uint8_t *)f->data)[i])
			at = i;
	if (at < n)
		fprintf(stderr, "frame %llu (sequence %llu): byte %zu of %zu is 0x%02x, injected 0x%02x\n",
		        (unsigned long long)k, (unsigned long long)f->sequence, at, n,
		        ((const uint8_t *)f->data)[at], want[at]);
	free(want);
	return at == n && f->size == n;
}

static inline int inject_matches(const kg_frame *f, uint64_t k)
{
	return inject_matches_masked(f, k, 0);
}

#endif
