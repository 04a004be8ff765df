/* The exposure shown as white (the 99.5th percentile of the luminance) and the 8-bit
 * grey picture the tag detector and the overlay see, from a demosaiced frame or straight
 * from a Bayer mosaic's 2 x 2 blocks. */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"

static double luminance(const float *p, int channels)
{
	if (channels == 1)
		return p[0];
	return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
}

enum { GREY_BINS = 4096, WHITE_STEP = 4 };

typedef struct white_job {
	const work_image *wi;
	long (*hist)[GREY_BINS];
	int failed;
} white_job;

static const double WHITE_TOP = 4.0; /* the white level's histogram spans 0..4 */

static int white_bin(double y)
{
	return y <= 0 || !isfinite(y) ? 0 : y >= WHITE_TOP ? GREY_BINS - 1
	                                                   : (int)(y / WHITE_TOP * GREY_BINS);
}

/* The 99.5th percentile of the n threads' histograms (summed into hist[0]); 1 if it
 * is 0. */
static double white_of(long (*hist)[GREY_BINS], int n)
{
	long total = 0, acc = 0;
	for (int t = 1; t < n; t++)
		for (int b = 0; b < GREY_BINS; b++)
			hist[0][b] += hist[t][b];
	for (int b = 0; b < GREY_BINS; b++)
		total += hist[0][b];
	double white = 1.0;
	for (int b = 0; b < GREY_BINS; b++) {
		acc += hist[0][b];
		if (acc >= 0.995 * total) {
			white = (b + 1) * WHITE_TOP / GREY_BINS;
			break;
		}
	}
	return white > 1e-6 ? white : 1.0;
}

static void white_rows(void *arg, int t, int n)
{
	white_job *j = arg;
	const work_image *wi = j->wi;
	int cols = (wi->width + WHITE_STEP - 1) / WHITE_STEP;
	int rows = (wi->height + WHITE_STEP - 1) / WHITE_STEP;
	float *scratch = malloc((size_t)cols * 3 * sizeof(float));
	long *hist = j->hist[t];
	if (!scratch) {
		j->failed = 1;
		return;
	}
	for (int r = (int)((long)rows * t / n); r < (int)((long)rows * (t + 1) / n); r++) {
		const float *p = chart_image_span(wi, r * WHITE_STEP, 0, cols, WHITE_STEP, scratch);
		for (int i = 0; i < cols; i++) {
			hist[white_bin(luminance(p + (size_t)i * wi->channels, wi->channels))]++;
		}
	}
	free(scratch);
}

/* The exposure shown as white to the detectors: the 99.5th percentile of the
 * luminance (a histogram over 0..4 of full scale of every 4th pixel of every 4th row,
 * 1/16 of the image); 1 if that is 0, or if memory ran out. */
double chart_white_level(const work_image *wi)
{
	/* found once per detection (the tag search's grey picture, then the tagless
	 * detector); only the detection's own thread asks, and every work_image is the
	 * detection's own, never a const object */
	if (wi->white > 0)
		return wi->white;
	int n = wi->threads;
	white_job j = {wi, calloc((size_t)n, sizeof(*j.hist)), 0};
	if (!j.hist)
		return 1.0;
	chart_run_parallel(white_rows, &j, n);
	double white = j.failed ? 1.0 : white_of(j.hist, n);
	free(j.hist);
	if (!j.failed)
		((work_image *)wi)->white = white;
	return white;
}

/* value / white through the sRGB curve, as 8 bits, in GREY_BINS steps over 0..1 */
static void srgb_lut(unsigned char lut[GREY_BINS])
{
	for (int b = 0; b < GREY_BINS; b++) {
		double v = (b + 0.5) / GREY_BINS;
		double e = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
		lut[b] = (unsigned char)lrint(fmin(fmax(e, 0), 1) * 255);
	}
}

/* The 8-bit code of a luminance already scaled to the table's GREY_BINS steps. */
static unsigned char grey_code(const unsigned char lut[GREY_BINS], float v)
{
	return lut[!(v > 0) ? 0 : v >= GREY_BINS - 1 ? GREY_BINS - 1 : (int)v];
}

typedef struct grey_job {
	const work_image *wi;
	int step, gw, gh; /* every step-th pixel of every step-th row: gw x gh */
	unsigned char *g, lut[GREY_BINS];
	float k;
	int failed;
} grey_job;

static void grey_rows(void *arg, int t, int n)
{
	grey_job *j = arg;
	const work_image *wi = j->wi;
	int gw = j->gw, C = wi->channels;
	int direct = wi->data && j->step == 1;
	float *scratch = direct ? NULL : malloc((size_t)gw * 3 * sizeof(float));
	if (!direct && !scratch) {
		j->failed = 1;
		return;
	}
	const float k = j->k;
	for (int y = (int)((long)j->gh * t / n); y < (int)((long)j->gh * (t + 1) / n); y++) {
		if (!wi->data && wi->u16) {
			/* a mapped image: the same sums of the same floats, from its codes */
			const uint16_t *row = wi->u16 + (size_t)y * j->step * wi->width * C;
			const float *lut = wi->lut;
			unsigned char *o = j->g + (size_t)y * gw;
			size_t stride = (size_t)j->step * C;
			for (int x = 0; x < gw; x++) {
				const uint16_t *q = row + (size_t)x * stride;
				float v = (C == 1 ? lut[q[0]]
				                  : 0.2126f * lut[q[0]] + 0.7152f * lut[q[1]] + 0.0722f * lut[q[2]]) *
				          k;
				o[x] = grey_code(j->lut, v);
			}
			continue;
		}
		const float *p = chart_image_span(wi, y * j->step, 0, gw, j->step, scratch);
		unsigned char *o = j->g + (size_t)y * gw;
		for (int x = 0; x < gw; x++) {
			const float *q = p + (size_t)x * C;
			float v = (C == 1 ? q[0] : 0.2126f * q[0] + 0.7152f * q[1] + 0.0722f * q[2]) * k;
			o[x] = grey_code(j->lut, v);
		}
	}
	free(scratch);
}

/* An 8-bit grey picture for tag detection and the overlay: luminance scaled so its
 * 99.5th percentile is white, then sRGB-encoded (a lookup table of 4096 steps), in
 * bands of rows over the threads. step 2: every 2nd pixel of every 2nd row only
 * (*gw x *gh), whose every 2nd pixel and row are the ones chart_white_level reads. */
unsigned char *chart_grey8(const work_image *wi, int step, int *gw, int *gh,
                            double *scale_out)
{
	grey_job j = {.wi = wi, .step = step, .gw = (wi->width + step - 1) / step,
	              .gh = (wi->height + step - 1) / step};
	size_t n = (size_t)j.gw * j.gh;
	if (!(j.g = malloc(n ? n : 1)))
		return NULL;
	double white = chart_white_level(wi);
	srgb_lut(j.lut);
	j.k = (float)(GREY_BINS / white);
	chart_run_parallel(grey_rows, &j, wi->threads);
	if (j.failed) {
		free(j.g);
		return NULL;
	}
	*gw = j.gw;
	*gh = j.gh;
	*scale_out = 1.0 / white;
	return j.g;
}

#if HAVE_APRILTAG /* the tags' grey picture of a mosaic */
/* A 2 x 2 CFA holding R, G and B: each 2 x 2 block's luminance is a weighted sum of
 * its four pixels (each filter's coefficient shared among the pixels behind it), so
 * the tags can be looked for on a half-resolution grey picture built straight from the
 * mosaic, without demosaicing. Returns 0 and the weights, or -1 for other CFAs. */
int chart_block_weights(const work_image *wi, float w[4])
{
	static const float coef[3] = {0.2126f, 0.7152f, 0.0722f};
	int count[3] = {0, 0, 0};
	if (!wi->raw || wi->cfa_rows != 2 || wi->cfa_cols != 2)
		return -1;
	for (int k = 0; k < 4; k++)
		count[wi->colour[k]]++;
	if (!count[0] || !count[1] || !count[2])
		return -1;
	for (int k = 0; k < 4; k++)
		w[k] = coef[wi->colour[k]] / (float)count[wi->colour[k]];
	return 0;
}

typedef struct binned_job {
	const work_image *wi;
	float w[4];
	int bw, bh; /* the blocks: bw x bh */
	long (*hist)[GREY_BINS];
	unsigned char *g, lut[GREY_BINS];
	float k;
} binned_job;

static float block_luminance(const binned_job *j, const float *r0, const float *r1, int bx)
{
	return j->w[0] * r0[2 * bx] + j->w[1] * r0[2 * bx + 1] + j->w[2] * r1[2 * bx] +
	       j->w[3] * r1[2 * bx + 1];
}

/* The white level's histogram over every 2nd block of every 2nd block row (1/16 of the
 * pixels, as chart_white_level takes of a demosaiced frame). */
static void binned_white_rows(void *arg, int t, int n)
{
	binned_job *j = arg;
	const float *d = j->wi->raw->data;
	int W = j->wi->width, rows = (j->bh + 1) / 2;
	long *hist = j->hist[t];
	for (int r = (int)((long)rows * t / n); r < (int)((long)rows * (t + 1) / n); r++) {
		const float *r0 = d + (size_t)(4 * r) * W, *r1 = r0 + W;
		for (int bx = 0; bx < j->bw; bx += 2)
			hist[white_bin(block_luminance(j, r0, r1, bx))]++;
	}
}

static void binned_grey_rows(void *arg, int t, int n)
{
	binned_job *j = arg;
	const float *d = j->wi->raw->data;
	int W = j->wi->width;
	const float k = j->k;
	for (int by = (int)((long)j->bh * t / n); by < (int)((long)j->bh * (t + 1) / n); by++) {
		const float *r0 = d + (size_t)(2 * by) * W, *r1 = r0 + W;
		unsigned char *o = j->g + (size_t)by * j->bw;
		for (int bx = 0; bx < j->bw; bx++)
			o[bx] = grey_code(j->lut, block_luminance(j, r0, r1, bx) * k);
	}
}

/* The tag detector's grey picture of a Bayer frame at half resolution (the blocks of
 * chart_block_weights; an odd last row or column is left out), white level included. */
unsigned char *chart_grey8_binned(const work_image *wi, const float w[4], int *bw, int *bh)
{
	int n = wi->threads;
	binned_job j = {.wi = wi, .bw = wi->width / 2, .bh = wi->height / 2};
	memcpy(j.w, w, sizeof(j.w));
	j.hist = calloc((size_t)n, sizeof(*j.hist));
	j.g = malloc((size_t)j.bw * j.bh);
	if (!j.hist || !j.g) {
		free(j.hist);
		free(j.g);
		return NULL;
	}
	chart_run_parallel(binned_white_rows, &j, n);
	double white = white_of(j.hist, n);
	free(j.hist);
	srgb_lut(j.lut);
	j.k = (float)(GREY_BINS / white);
	chart_run_parallel(binned_grey_rows, &j, n);
	*bw = j.bw;
	*bh = j.bh;
	return j.g;
}
#endif /* HAVE_APRILTAG */
