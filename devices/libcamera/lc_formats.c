/* libcamera pixel formats against kg_pixfmt (lc_formats.h). The codes are DRM fourccs
 * as libcamera's formats.h defines them; the order within a family is the order of
 * preference (deepest first; for RGB the one that needs no byte swap). */
#include <stdio.h>
#include <string.h>

#include "lc_formats.h"

#define FOURCC(a, b, c, d)                                                             \
	((uint32_t)(a) | (uint32_t)(b) << 8 | (uint32_t)(c) << 16 | (uint32_t)(d) << 24)

static const kg_lc_format table[] = {
	/* mono sensors (raw) or the luma of an ISP's output; R10..R16 are 16-bit words */
	{"R8", FOURCC('R', '8', ' ', ' '), KG_PIX_MONO8, 8, "", 0, 0},
	{"R16", FOURCC('R', '1', '6', ' '), KG_PIX_MONO16, 16, "", 0, 0},
	{"R12", FOURCC('R', '1', '2', ' '), KG_PIX_MONO16, 12, "", 0, 0},
	{"R10", FOURCC('R', '1', '0', ' '), KG_PIX_MONO16, 10, "", 0, 0},
	/* Bayer, 8 bit */
	{"SRGGB8", FOURCC('R', 'G', 'G', 'B'), KG_PIX_BAYER8, 8, "RGGB", 0, 1},
	{"SGRBG8", FOURCC('G', 'R', 'B', 'G'), KG_PIX_BAYER8, 8, "GRBG", 0, 1},
	{"SGBRG8", FOURCC('G', 'B', 'R', 'G'), KG_PIX_BAYER8, 8, "GBRG", 0, 1},
	{"SBGGR8", FOURCC('B', 'A', '8', '1'), KG_PIX_BAYER8, 8, "BGGR", 0, 1},
	/* Bayer, unpacked into 16-bit little-endian words */
	{"SRGGB16", FOURCC('R', 'G', 'B', '6'), KG_PIX_BAYER16, 16, "RGGB", 0, 1},
	{"SGRBG16", FOURCC('G', 'R', '1', '6'), KG_PIX_BAYER16, 16, "GRBG", 0, 1},
	{"SGBRG16", FOURCC('G', 'B', '1', '6'), KG_PIX_BAYER16, 16, "GBRG", 0, 1},
	{"SBGGR16", FOURCC('B', 'Y', 'R', '2'), KG_PIX_BAYER16, 16, "BGGR", 0, 1},
	{"SRGGB12", FOURCC('R', 'G', '1', '2'), KG_PIX_BAYER16, 12, "RGGB", 0, 1},
	{"SGRBG12", FOURCC('B', 'A', '1', '2'), KG_PIX_BAYER16, 12, "GRBG", 0, 1},
	{"SGBRG12", FOURCC('G', 'B', '1', '2'), KG_PIX_BAYER16, 12, "GBRG", 0, 1},
	{"SBGGR12", FOURCC('B', 'G', '1', '2'), KG_PIX_BAYER16, 12, "BGGR", 0, 1},
	{"SRGGB10", FOURCC('R', 'G', '1', '0'), KG_PIX_BAYER16, 10, "RGGB", 0, 1},
	{"SGRBG10", FOURCC('B', 'A', '1', '0'), KG_PIX_BAYER16, 10, "GRBG", 0, 1},
	{"SGBRG10", FOURCC('G', 'B', '1', '0'), KG_PIX_BAYER16, 10, "GBRG", 0, 1},
	{"SBGGR10", FOURCC('B', 'G', '1', '0'), KG_PIX_BAYER16, 10, "BGGR", 0, 1},
	/* processed RGB: BGR888 is R, G, B in memory; RGB888 is B, G, R */
	{"BGR888", FOURCC('B', 'G', '2', '4'), KG_PIX_RGB8, 8, "", 0, 0},
	{"RGB888", FOURCC('R', 'G', '2', '4'), KG_PIX_RGB8, 8, "", 1, 0},
	/* UVC cameras through libcamera's uvcvideo pipeline */
	{"YUYV", FOURCC('Y', 'U', 'Y', 'V'), KG_PIX_YUYV, 8, "", 0, 0},
	{"MJPEG", FOURCC('M', 'J', 'P', 'G'), KG_PIX_MJPEG, 8, "", 0, 0},
};
#define NTABLE ((int)(sizeof(table) / sizeof(table[0])))

const kg_lc_format *kg_lc_format_table(int *n)
{
	*n = NTABLE;
	return table;
}

const kg_lc_format *kg_lc_format_find(uint32_t fourcc, uint64_t modifier)
{
	if (modifier)
		return NULL;
	for (int i = 0; i < NTABLE; i++)
		if (table[i].fourcc == fourcc)
			return &table[i];
	return NULL;
}

int kg_lc_format_matches(const kg_lc_format *f, kg_pixfmt pixfmt, int bits, const char *cfa)
{
	return f->pixfmt == pixfmt && (!bits || f->bits == bits) &&
	       (!cfa || !cfa[0] || !f->cfa[0] || !strcmp(f->cfa, cfa));
}

int kg_lc_formats_for(kg_pixfmt pixfmt, int bits, const char *cfa, uint32_t *out, int max)
{
	int n = 0;
	for (int i = 0; i < NTABLE && n < max; i++)
		if (kg_lc_format_matches(&table[i], pixfmt, bits, cfa))
			out[n++] = table[i].fourcc;
	return n;
}

void kg_lc_fourcc_text(uint32_t fourcc, char out[5])
{
	for (int i = 0; i < 4; i++) {
		char ch = (char)(fourcc >> (8 * i) & 0xff);
		out[i] = ch >= 0x20 && ch < 0x7f ? ch : '.';
	}
	out[4] = 0;
}

void kg_lc_swap_rb(const uint8_t *src, uint8_t *dst, int width, int height, size_t stride)
{
	for (int y = 0; y < height; y++) {
		const uint8_t *in = src + stride * (size_t)y;
		uint8_t *o = dst + stride * (size_t)y;
		for (int x = 0; x < width; x++) {
			o[3 * x] = in[3 * x + 2];
			o[3 * x + 1] = in[3 * x + 1];
			o[3 * x + 2] = in[3 * x];
		}
	}
}

void kg_lc_frame_format(const kg_lc_format *f, int width, int height, unsigned stride,
                        unsigned frame_size, kg_frame_format *out)
{
	memset(out, 0, sizeof(*out));
	out->pixfmt = f->pixfmt;
	out->width = width;
	out->height = height;
	out->bits = f->bits;
	snprintf(out->cfa, sizeof(out->cfa), "%s", f->cfa);
	kg_frame_format_fill(out);
	/* libcamera's stride may pad rows; MJPEG's frame size is the buffer's bound */
	if (f->pixfmt != KG_PIX_MJPEG && stride >= out->stride) {
		out->stride = stride;
		out->size = (size_t)stride * (size_t)height;
	}
	if (f->pixfmt == KG_PIX_MJPEG && frame_size)
		out->size = frame_size;
}
