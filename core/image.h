/* Images from cameras and for people: TIFF (libtiff) and PNG (libpng).
 *
 * Samples are floats, interleaved, row-major, on a linear 0..1 scale: integer files
 * are divided by their full scale (255, 65535), float files are taken as they are.
 * A PNG that declares sRGB or a gamma other than 1 is linearised on read (and says so
 * in the note); linear PNGs are written with gAMA 1.0. Writes are atomic. */
#ifndef KG_IMAGE_H
#define KG_IMAGE_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"

/* How a display-encoded file (JPEG) maps to linear values. A JPEG is gamma-encoded
 * and white-balanced by the camera: read without a stated encoding it is linearised as
 * sRGB for chart detection and previews, and calibration and estimation refuse it. */
typedef enum kg_encoding_curve {
	KG_ENCODING_UNSTATED = 0, /* read as sRGB, not for measurement */
	KG_ENCODING_SRGB,         /* stated: IEC 61966-2-1 */
	KG_ENCODING_LINEAR,       /* stated: code / 255 */
	KG_ENCODING_GAMMA,        /* stated: (code / 255)^gamma */
} kg_encoding_curve;

typedef struct kg_image_encoding {
	kg_encoding_curve curve;
	double gamma;
} kg_image_encoding;

typedef struct kg_image {
	int width, height;
	int channels;    /* 1 (grey or raw Bayer) or 3 (RGB) */
	float *data;     /* width * height * channels samples, points past this header */
	int bits;        /* sample depth of the source file: 1..16 integer, or 32 float */
	int is_float;    /* the source samples were floating point */
	char *cfa;       /* raw Bayer frames: colours of the CFA repeat, row by row, from
	                    "RGBCMYW" (e.g. "RGGB"); NULL when the file has none */
	int cfa_rows, cfa_cols; /* size of the CFA repeat (2 x 2 for Bayer) */
	char note[256];  /* what the reader changed (alpha dropped, ...), "" if nothing */
	int jpeg;        /* read from a JPEG: display-encoded by the camera */
	kg_image_encoding encoding; /* a JPEG's encoding as read (UNSTATED: not stated) */
	/* kg_image_map: the file's 16-bit samples where they lie in it (interleaved,
	 * width * channels a row; sample k is the float kg_image_u16_lut()[k]), and data
	 * NULL. Only the consumers that say so take such an image. */
	const uint16_t *u16;
	struct kg_mapfile *map;
} kg_image;

/* Largest image accepted: 2^28 pixels per image and 2^20 per side. */
#define KG_IMAGE_MAX_PIXELS (1L << 28)

/* A zeroed image (bits 32, float). */
int kg_image_new(int width, int height, int channels, kg_image **out, kg_err *err);
void kg_image_free(kg_image **img);
/* Attach a CFA pattern of rows x cols letters from "RGBCMYW" (copied). */
int kg_image_set_cfa(kg_image *img, const char *pattern, int rows, int cols, kg_err *err);

/* Read a TIFF, PNG, JPEG or camera raw, recognised by its first bytes. */
int kg_image_read(const char *path, kg_image **out, kg_err *err);
/* The same, with a JPEG decoded through a stated encoding (NULL: not stated). JPEG
 * needs a build with libjpeg (KG_ENOTSUP without). */
/* An uncompressed 16-bit grey or RGB TIFF (strips in order, the machine's byte order,
 * no extra samples) mapped rather than decoded: no copy of its pixels is made (u16
 * above). A compressed one (LZW, Deflate, ...; strips or tiles) of the same layout is
 * decoded into its 16-bit codes (u16, in memory; half the bytes of the floats), on
 * several threads as kg_image_read decodes it; its errors are kg_image_read's.
 * KG_ENOTSUP for any other file, which kg_image_read then reads. For a
 * one-pass reader of a large file (chart detection): a 12 Mpix RGB image otherwise
 * costs 144 MB of floats that the kernel must first zero. The pages are the file's
 * (mapfile.h): a file cut short by another program while it is mapped reads as zeros
 * from there on instead of ending the process, and kg_image_map_check then fails, so
 * a reader checks it after its last read of the pixels and before it writes anything
 * from them. */
int kg_image_map(const char *path, kg_image **out, kg_err *err);
/* 0 for an image that is not mapped, or whose file is still as it was mapped; KG_EIO
 * naming the file when it was cut short or changed in place while mapped. */
int kg_image_map_check(const kg_image *img, kg_err *err);
/* The float of every 16-bit code k, k / 65535 as the readers compute it. */
const float *kg_image_u16_lut(void);
int kg_image_read_as(const char *path, const kg_image_encoding *enc, kg_image **out,
                     kg_err *err);
/* "srgb", "linear" or "gamma:G" (0.2 <= G <= 5). */
int kg_image_encoding_parse(const char *text, kg_image_encoding *enc, kg_err *err);
/* "linear" (not a JPEG), "jpeg-unstated", "jpeg-srgb", "jpeg-linear", "jpeg-gamma-G":
 * the IMAGE_ENCODING keyword chart detect writes. */
void kg_image_encoding_name(const kg_image *img, char *buf, size_t size);
/* 1 when the file is a JPEG (by its first bytes). */
int kg_image_is_jpeg(const char *path);
/* TIFF: 8/16-bit unsigned or 32-bit float, 1 or 3 colour samples (further samples such
 * as alpha are dropped with a note), strips or tiles, contiguous or separate planes.
 * The first image of a multi-page file. CFA pattern tags (33421/33422) are read. */
int kg_image_read_tiff(const char *path, kg_image **out, kg_err *err);
/* How many threads kg_image_read decodes a TIFF of many strips or tiles with, each on
 * its own handle of the file: 0 (the default) as many as the CPUs this process may use,
 * up to 8; 1 one; at most 16. The samples are the same whatever the number. Returns
 * the previous setting (for benches and tests). */
int kg_image_set_read_threads(int n);
/* PNG: 1..16-bit grey or RGB, palettes expanded, alpha dropped with a note. */
int kg_image_read_png(const char *path, kg_image **out, kg_err *err);

/* Reading an image a band of rows at a time, top to bottom, for images too large to
 * hold whole: besides the caller's rows the reader holds one TIFF strip or row of
 * tiles, or one PNG row (an interlaced PNG is decoded whole when opened). Values are
 * those kg_image_read gives. */
typedef struct kg_image_rows kg_image_rows;
int kg_image_rows_open(const char *path, kg_image_rows **out, kg_err *err);
/* The same with a JPEG's stated encoding (kg_image_read_as); a JPEG is decoded whole. */
int kg_image_rows_open_as(const char *path, const kg_image_encoding *enc,
                          kg_image_rows **out, kg_err *err);
/* What the file holds: size, channels, bits, CFA and note; data is NULL. */
const kg_image *kg_image_rows_header(const kg_image_rows *r);
/* The next `rows` rows (width * channels floats each) into out. */
int kg_image_rows_read(kg_image_rows *r, int rows, float *out, kg_err *err);
void kg_image_rows_free(kg_image_rows **r);

/* Rows of an image from anywhere (a file, memory, a correction chain), for consumers
 * that go through an image once, top to bottom: read() is called with y0 increasing,
 * each row once, and fills rows * width * channels floats. */
typedef struct kg_row_source {
	int width, height, channels;
	int (*read)(void *user, int y0, int rows, float *out, kg_err *err);
	void *user;
} kg_row_source;
/* A source over an image in memory, or over an open row reader (which it does not
 * own). */
void kg_row_source_of_image(const kg_image *img, kg_row_source *s);
void kg_row_source_of_rows(kg_image_rows *r, kg_row_source *s);

/* Write with a sample depth of 8, 16 (integer, values clamped to 0..1 and rounded;
 * NaN becomes 0) or 32 (TIFF only, float, values as they are). kg_image_write picks
 * the format from the extension (.tif, .tiff, .png). */
int kg_image_write(const kg_image *img, const char *path, int bits, kg_err *err);
int kg_image_write_tiff(const kg_image *img, const char *path, int bits, kg_err *err);
int kg_image_write_png(const kg_image *img, const char *path, int bits, kg_err *err);

/* An 8-bit RGB buffer (width * height * 3, display-encoded sRGB) to a PNG, for plots
 * and previews. */
int kg_png_write_rgb8(const char *path, const unsigned char *rgb, int width, int height,
                      kg_err *err);

#endif
