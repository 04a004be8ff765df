/* Private to devices/libcamera/ (and its tests): libcamera pixel formats (DRM fourcc
 * plus modifier) against kogei's kg_pixfmt. Plain C, no libcamera headers, so the
 * table can be tested on its own; tests/libcamera checks its names and codes against
 * libcamera's own PixelFormat::fromString.
 *
 * Only formats kogei can measure without unpacking are listed: 8-bit and unpacked
 * 16-bit-word mono and Bayer, 24-bit RGB, plus YUYV and MJPEG (non-linear, refused for
 * measurement unless forced). MIPI CSI-2 packed and IPU3 packed Bayer (non-zero
 * modifier) are not. Byte order: libcamera names formats as DRM does, from the most
 * significant byte of a little-endian word, so RGB888 is B, G, R in memory and BGR888
 * is R, G, B; kogei's rgb8 is R, G, B. */
#ifndef KG_LC_FORMATS_H
#define KG_LC_FORMATS_H

#include <stddef.h>
#include <stdint.h>

#include "kg_camera.h"

typedef struct kg_lc_format {
	const char *name; /* libcamera's name ("SRGGB12", "BGR888") */
	uint32_t fourcc;  /* DRM fourcc; the modifier is 0 for every entry */
	kg_pixfmt pixfmt;
	int bits;         /* significant bits per sample */
	char cfa[5];      /* Bayer pattern, "" otherwise */
	int swap_rb;      /* 1: memory order is B, G, R; the driver swaps to R, G, B */
	int raw;          /* 1: a sensor format, delivered on a StreamRole::Raw stream */
} kg_lc_format;

/* The whole table (for tests): *n entries. */
const kg_lc_format *kg_lc_format_table(int *n);

/* The entry for a libcamera format; NULL when kogei cannot take it (packed, planar
 * YUV, a non-zero modifier, ...). */
const kg_lc_format *kg_lc_format_find(uint32_t fourcc, uint64_t modifier);

/* The libcamera formats that deliver a request, best first, into out (at most max);
 * returns how many. bits 0 accepts any depth of the family (deepest first), cfa NULL
 * or "" any Bayer order. 0 when libcamera has no unpacked format for it (rgb16,
 * 14-bit). */
int kg_lc_formats_for(kg_pixfmt pixfmt, int bits, const char *cfa, uint32_t *out, int max);

/* 1 when entry f satisfies the request (same rules as kg_lc_formats_for). */
int kg_lc_format_matches(const kg_lc_format *f, kg_pixfmt pixfmt, int bits, const char *cfa);

/* A fourcc as text ("RG12"; unprintable bytes as '.'). */
void kg_lc_fourcc_text(uint32_t fourcc, char out[5]);

/* kogei's rgb8 (R, G, B) from rows stored B, G, R (libcamera's RGB888): width x
 * height pixels, rows stride bytes apart in both src and dst. */
void kg_lc_swap_rb(const uint8_t *src, uint8_t *dst, int width, int height, size_t stride);

/* kogei's frame format for a configured stream of format f. */
void kg_lc_frame_format(const kg_lc_format *f, int width, int height, unsigned stride,
                        unsigned frame_size, kg_frame_format *out);

#endif
