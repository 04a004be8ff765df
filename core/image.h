/* Images from cameras and for people: TIFF (libtiff) and PNG (libpng).
 *
 * Samples are floats, interleaved, row-major, on a linear 0..1 scale: integer files
 * are divided by their full scale (255, 65535), float files are taken as they are.
 * A PNG that declares sRGB or a gamma other than 1 is linearised on read (and says so
 * in the note); linear PNGs are written with gAMA 1.0. Writes are atomic. */
#ifndef KG_IMAGE_H
#define KG_IMAGE_H

#include "error.h"

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
} kg_image;

/* Largest image accepted: 2^28 pixels per image and 2^20 per side. */
#define KG_IMAGE_MAX_PIXELS (1L << 28)

/* A zeroed image (bits 32, float). */
int kg_image_new(int width, int height, int channels, kg_image **out, kg_err *err);
void kg_image_free(kg_image **img);
/* Attach a CFA pattern of rows x cols letters from "RGBCMYW" (copied). */
int kg_image_set_cfa(kg_image *img, const char *pattern, int rows, int cols, kg_err *err);

/* Read a TIFF or PNG, recognised by its first bytes. */
int kg_image_read(const char *path, kg_image **out, kg_err *err);
/* TIFF: 8/16-bit unsigned or 32-bit float, 1 or 3 colour samples (further samples such
 * as alpha are dropped with a note), strips or tiles, contiguous or separate planes.
 * The first image of a multi-page file. CFA pattern tags (33421/33422) are read. */
int kg_image_read_tiff(const char *path, kg_image **out, kg_err *err);
/* PNG: 1..16-bit grey or RGB, palettes expanded, alpha dropped with a note. */
int kg_image_read_png(const char *path, kg_image **out, kg_err *err);

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
