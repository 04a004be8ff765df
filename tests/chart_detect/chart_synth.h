/* Synthetic chart photographs for the detection tests: a layout built in memory
 * (tags in the frame's corners, a grid of patches), drawn through a known
 * homography with 4 x 4 supersampling. Tags are drawn from libapriltag's code
 * tables: outer ring white, next ring black, data bits inside (MSB first). */
#ifndef CHART_SYNTH_H
#define CHART_SYNTH_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>

#include "kg_calib.h"

#define SYN_ROWS 4
#define SYN_COLS 6
#define SYN_TAG_MM 20.0

/* A 210 x 160 mm frame: tags (ids first_id..first_id+3) in the corners, 24 patches
 * of 20 mm on a 25 mm pitch. */
static kg_chart_layout *syn_layout(const char *name, int first_id)
{
	kg_chart_layout *l = calloc(1, sizeof(*l));
	snprintf(l->name, sizeof(l->name), "%s", name);
	snprintf(l->family, sizeof(l->family), "tag36h11");
	l->width_mm = 210;
	l->height_mm = 160;
	l->chart_area_mm[0] = 30;
	l->chart_area_mm[1] = 30;
	l->chart_area_mm[2] = 150;
	l->chart_area_mm[3] = 100;
	l->sample_fraction = 0.6;
	l->ntags = 4;
	l->tags = calloc(4, sizeof(*l->tags));
	double centres[4][2] = {{17, 17}, {193, 17}, {193, 143}, {17, 143}};
	for (int i = 0; i < 4; i++) {
		kg_chart_tag *t = &l->tags[i];
		t->id = first_id + i;
		t->center_mm[0] = centres[i][0];
		t->center_mm[1] = centres[i][1];
		t->size_mm = SYN_TAG_MM;
		double h = SYN_TAG_MM / 2, cx = centres[i][0], cy = centres[i][1];
		double c[4][2] = {{cx - h, cy + h}, {cx + h, cy + h}, {cx + h, cy - h}, {cx - h, cy - h}};
		memcpy(t->corners_mm, c, sizeof(c));
	}
	l->npatches = SYN_ROWS * SYN_COLS;
	l->patches = calloc((size_t)l->npatches, sizeof(*l->patches));
	for (int r = 0; r < SYN_ROWS; r++)
		for (int c = 0; c < SYN_COLS; c++) {
			kg_chart_patch *p = &l->patches[r * SYN_COLS + c];
			snprintf(p->id, sizeof(p->id), "%c%d", 'A' + r, c + 1);
			p->center_mm[0] = 30 + 12.5 + 25 * c;
			p->center_mm[1] = 30 + 12.5 + 25 * r;
			p->size_mm[0] = p->size_mm[1] = 20;
		}
	return l;
}

static void syn_layout_free(kg_chart_layout *l)
{
	free(l->tags);
	free(l->patches);
	free(l);
}

/* The true value of patch i, channel c (linear). */
static double syn_value(int i, int c)
{
	return 0.04 + 0.85 * fmod(0.37 * i + 0.23 * c * (i % 5 + 1) + 0.11 * c, 1.0);
}

/* Colour of a point of the chart in mm: 1 if found, else 0 (leave as is). */
static int syn_colour(const kg_chart_layout *l, apriltag_family_t *tf, double x, double y,
                      int channels, float *out)
{
	for (int i = 0; i < l->ntags; i++) {
		const kg_chart_tag *t = &l->tags[i];
		double cell = t->size_mm / tf->width_at_border;
		double x0 = t->center_mm[0] - cell * tf->total_width / 2.0;
		double y0 = t->center_mm[1] - cell * tf->total_width / 2.0;
		int cx = (int)floor((x - x0) / cell), cy = (int)floor((y - y0) / cell);
		if (cx < 0 || cy < 0 || cx >= tf->total_width || cy >= tf->total_width)
			continue;
		int b = (tf->total_width - tf->width_at_border) / 2;
		double v;
		if (cx < b || cy < b || cx >= tf->total_width - b || cy >= tf->total_width - b)
			v = 0.9;
		else if (cx == b || cy == b || cx == tf->total_width - b - 1 ||
		         cy == tf->total_width - b - 1)
			v = 0.02;
		else {
			v = 0.02;
			uint64_t code = tf->codes[t->id];
			for (uint32_t k = 0; k < tf->nbits; k++)
				if ((int)tf->bit_x[k] + b == cx && (int)tf->bit_y[k] + b == cy &&
				    ((code >> (tf->nbits - 1 - k)) & 1))
					v = 0.9;
		}
		for (int c = 0; c < channels; c++)
			out[c] = (float)v;
		return 1;
	}
	for (int i = 0; i < l->npatches; i++) {
		const kg_chart_patch *p = &l->patches[i];
		if (fabs(x - p->center_mm[0]) <= p->size_mm[0] / 2 &&
		    fabs(y - p->center_mm[1]) <= p->size_mm[1] / 2) {
			for (int c = 0; c < channels; c++)
				out[c] = (float)syn_value(i, channels == 1 ? 1 : c);
			return 1;
		}
	}
	const double *a = l->chart_area_mm;
	if (x >= a[0] && y >= a[1] && x <= a[0] + a[2] && y <= a[1] + a[3]) {
		for (int c = 0; c < channels; c++)
			out[c] = 0.03f;
		return 1;
	}
	if (x >= 0 && y >= 0 && x <= l->width_mm && y <= l->height_mm) {
		for (int c = 0; c < channels; c++)
			out[c] = 0.8f;
		return 1;
	}
	return 0;
}

/* Draw layout l into img (which keeps its background elsewhere) through H (mm -> px). */
static void syn_draw(kg_image *img, const kg_chart_layout *l, const double H[9])
{
	apriltag_family_t *tf = tag36h11_create();
	double Hi[9];
	kg_homography_invert(H, Hi);
	enum { SS = 4 };
	int C = img->channels;
	for (int y = 0; y < img->height; y++)
		for (int x = 0; x < img->width; x++) {
			double acc[3] = {0, 0, 0};
			int hit = 0;
			float *px = img->data + ((size_t)y * img->width + x) * C;
			for (int sy = 0; sy < SS; sy++)
				for (int sx = 0; sx < SS; sx++) {
					double m[2];
					kg_homography_map(Hi, x + (sx + 0.5) / SS, y + (sy + 0.5) / SS, m);
					float v[3];
					if (syn_colour(l, tf, m[0], m[1], C, v))
						hit++;
					else
						memcpy(v, px, (size_t)C * sizeof(float));
					for (int c = 0; c < C; c++)
						acc[c] += v[c];
				}
			if (hit)
				for (int c = 0; c < C; c++)
					px[c] = (float)(acc[c] / (SS * SS));
		}
	tag36h11_destroy(tf);
}

/* H taking the frame of l to the quadrilateral q (tl, tr, br, bl) in px. */
static void syn_homography(const kg_chart_layout *l, const double q[4][2], double H[9])
{
	double src[4][2] = {{0, 0}, {l->width_mm, 0}, {l->width_mm, l->height_mm},
	                    {0, l->height_mm}};
	kg_homography_fit((const double (*)[2])src, (const double (*)[2])q, 4, 0, H, NULL, NULL);
}

/* An image of width x height filled with v. */
static kg_image *syn_image(int width, int height, int channels, float v)
{
	kg_image *img = NULL;
	kg_image_new(width, height, channels, &img, NULL);
	for (size_t i = 0; i < (size_t)width * height * channels; i++)
		img->data[i] = v;
	return img;
}

/* The mosaic a camera with 2 x 2 CFA pattern pat ("RGGB", ...) records of an RGB image. */
static kg_image *syn_mosaic(const kg_image *rgb, const char *pat)
{
	kg_image *raw = syn_image(rgb->width, rgb->height, 1, 0);
	for (int y = 0; y < rgb->height; y++)
		for (int x = 0; x < rgb->width; x++) {
			int c = (int)(strchr("RGB", pat[(y % 2) * 2 + x % 2]) - "RGB");
			raw->data[(size_t)y * rgb->width + x] = rgb->data[((size_t)y * rgb->width + x) * 3 + c];
		}
	kg_image_set_cfa(raw, pat, 2, 2, NULL);
	return raw;
}

/* Add Gaussian-like noise (sum of uniforms) of sigma and quantise to bits. */
static void syn_finish(kg_image *img, double sigma, int bits, unsigned seed)
{
	uint64_t s = seed * 6364136223846793005ULL + 1442695040888963407ULL;
	double full = bits < 32 ? (double)((1L << bits) - 1) : 0;
	for (size_t i = 0; i < (size_t)img->width * img->height * img->channels; i++) {
		double n = 0;
		for (int k = 0; k < 4; k++) {
			s = s * 6364136223846793005ULL + 1442695040888963407ULL;
			n += (double)(s >> 11) / 9007199254740992.0 - 0.5;
		}
		double v = img->data[i] + sigma * n * sqrt(3.0);
		if (full > 0)
			v = fmin(fmax(round(v * full) / full, 0), 1);
		img->data[i] = (float)v;
	}
	img->bits = bits;
	img->is_float = bits == 32;
}

#endif
