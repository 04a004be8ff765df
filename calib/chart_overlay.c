/* The overlay PNG: the image as the tag detector sees it, reduced, with the chart's
 * outline, the tags, each patch's sampled region and flags, or for a refusal what was
 * searched and why each candidate failed. */
#include <cairo.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"

/* ---- overlay ----------------------------------------------------------------- */

static void path_quad(cairo_t *cr, const double q[4][2], double s)
{
	cairo_move_to(cr, q[0][0] * s, q[0][1] * s);
	for (int k = 1; k < 4; k++)
		cairo_line_to(cr, q[k][0] * s, q[k][1] * s);
	cairo_close_path(cr);
}

/* One line of text from (x, y) (its baseline) at the current font size, outlined in
 * black so it reads on any background. */
static void outlined_line(cairo_t *cr, double x, double y, double size, const char *text,
                          double r, double g, double b)
{
	cairo_move_to(cr, x, y);
	cairo_text_path(cr, text);
	cairo_set_source_rgb(cr, 0, 0, 0);
	cairo_set_line_width(cr, fmax(1.5, size / 6));
	cairo_stroke(cr);
	cairo_move_to(cr, x, y);
	cairo_set_source_rgb(cr, r, g, b);
	cairo_show_text(cr, text);
}

/* text centred on (x, y), outlined */
static void label(cairo_t *cr, double x, double y, double size, const char *text,
                  double r, double g, double b)
{
	cairo_text_extents_t ext;
	cairo_set_font_size(cr, size);
	cairo_text_extents(cr, text, &ext);
	outlined_line(cr, x - ext.width / 2 - ext.x_bearing, y - ext.height / 2 - ext.y_bearing,
	              size, text, r, g, b);
}

/* text from (x, y) (the first line's baseline) in lines no wider than maxw, broken
 * at spaces, outlined in black; the baseline below the last line. */
static double wrapped_text(cairo_t *cr, double x, double y, double maxw, double size,
                           const char *text, double r, double g, double b)
{
	char line[1100];
	size_t n = 0;
	cairo_set_font_size(cr, size);
	const char *p = text;
	while (*p) {
		/* the next word, with the spaces before it */
		const char *w = p;
		while (*w == ' ')
			w++;
		const char *end = w;
		while (*end && *end != ' ')
			end++;
		char trial[1100];
		int len = snprintf(trial, sizeof(trial), "%.*s%.*s", (int)n, line,
		                   (int)(n ? end - p : end - w), n ? p : w);
		cairo_text_extents_t ext;
		cairo_text_extents(cr, trial, &ext);
		if (n && (ext.x_advance > maxw || len >= (int)sizeof(line) - 1)) {
			line[n] = '\0';
			outlined_line(cr, x, y, size, line, r, g, b);
			y += size * 1.2;
			n = (size_t)snprintf(line, sizeof(line), "%.*s", (int)(end - w), w);
		} else {
			n = (size_t)snprintf(line, sizeof(line), "%s", trial);
		}
		p = end;
	}
	if (n) {
		outlined_line(cr, x, y, size, line, r, g, b);
		y += size * 1.2;
	}
	return y;
}

int kg_chart_overlay_write(const kg_chart_result *r, const kg_image *img, const char *path,
                           int max_side, kg_err *err)
{
	kg_check_arg(r && img && img->data && path, err);
	if (max_side <= 0)
		max_side = 1600;
	kg_chart_detect_options opt;
	kg_chart_detect_options_default(&opt);
	opt.clip_level = 1; /* nothing is sampled: no saturation scan */
	work_image wi;
	int ret = chart_prepare_image(img, &opt, &wi, err);
	if (!ret)
		ret = chart_demosaic_all(&wi, err);
	if (ret) {
		chart_image_free(&wi);
		return ret;
	}
	double scale_px;
	unsigned char *g = NULL;
	int big = img->width > img->height ? img->width : img->height;
	int step = (big + max_side - 1) / max_side;
	if (step < 1)
		step = 1;
	int W = (img->width + step - 1) / step, Hh = (img->height + step - 1) / step;
	double s = 1.0 / step;
	cairo_surface_t *surf = cairo_image_surface_create(CAIRO_FORMAT_RGB24, W, Hh);
	cairo_t *cr = cairo_create(surf);
	unsigned char *rgb = malloc((size_t)W * Hh * 3);
	if (cairo_status(cr) != CAIRO_STATUS_SUCCESS || !rgb) {
		ret = kg_fail(err, KG_ENOMEM, "overlay: out of memory");
		goto done;
	}
	/* Background: each output pixel is the mean of its step x step block, with the
	 * exposure normalisation of the tag detector, sRGB-encoded. */
	int gw, gh;
	g = chart_grey8(&wi, 1, &gw, &gh, &scale_px);
	if (!g) {
		ret = kg_fail(err, KG_ENOMEM, "overlay: out of memory");
		goto done;
	}
	cairo_surface_flush(surf);
	unsigned char *dst = cairo_image_surface_get_data(surf);
	int stride = cairo_image_surface_get_stride(surf);
	for (int y = 0; y < Hh; y++) {
		for (int x = 0; x < W; x++) {
			double acc[3] = {0, 0, 0};
			int cnt = 0;
			for (int yy = y * step; yy < (y + 1) * step && yy < img->height; yy++)
				for (int xx = x * step; xx < (x + 1) * step && xx < img->width; xx++) {
					const float *p = wi.data + ((size_t)yy * wi.width + xx) * wi.channels;
					for (int c = 0; c < 3; c++)
						acc[c] += p[wi.channels == 3 ? c : 0];
					cnt++;
				}
			uint32_t pix = 0;
			for (int c = 0; c < 3; c++) {
				double v = fmin(fmax(acc[c] / cnt * scale_px, 0), 1);
				v = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
				pix = (pix << 8) | (uint32_t)lrint(v * 255);
			}
			memcpy(dst + (size_t)y * stride + 4 * x, &pix, 4);
		}
	}
	cairo_surface_mark_dirty(surf);
	cairo_select_font_face(cr, "DejaVu Sans", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_BOLD);
	double lw = fmax(1.5, W / 800.0);
	double font = fmax(10, W / 90.0);
	/* a refusal: the region searched (dashed yellow) and each candidate tried
	 * (magenta) with why it failed */
	if (r->refused && r->has_searched) {
		double dash[2] = {4 * lw, 3 * lw};
		cairo_set_dash(cr, dash, 2, 0);
		cairo_set_source_rgb(cr, 1, 0.9, 0.2);
		cairo_set_line_width(cr, 2 * lw);
		double q[4][2];
		for (int k = 0; k < 4; k++) {
			/* inset by a line width so the frame of the whole image shows */
			q[k][0] = r->searched[k][0] + (k == 0 || k == 3 ? 1 : -1) * 1.5 * lw / s;
			q[k][1] = r->searched[k][1] + (k < 2 ? 1 : -1) * 1.5 * lw / s;
		}
		path_quad(cr, q, s);
		cairo_stroke(cr);
		cairo_set_dash(cr, NULL, 0, 0);
	}
	double box_text = 0; /* below the last box's reason: mcc's boxes often overlap */
	for (int i = 0; r->refused && i < r->ncandidates; i++) {
		const kg_chart_candidate *c = &r->candidates[i];
		int box = strncmp(c->why, "mcc's box", 9) == 0, turn = !strncmp(c->why, "A01 if", 6);
		cairo_set_source_rgb(cr, 1, 0.2, 1);
		cairo_set_line_width(cr, (box ? 2.5 : 1.5) * lw);
		path_quad(cr, c->quad, s);
		cairo_stroke(cr);
		double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
		for (int k = 0; k < 4; k++) {
			x0 = fmin(x0, c->quad[k][0] * s);
			x1 = fmax(x1, c->quad[k][0] * s);
			y0 = fmin(y0, c->quad[k][1] * s);
			y1 = fmax(y1, c->quad[k][1] * s);
		}
		double size = turn ? font * 0.8 : font;
		double maxw = fmax(x1 - x0, 12 * size);
		if (x0 + maxw > W)
			x0 = fmax(0, W - maxw);
		/* a box's reason below it, each turn's at its A01 region, a tag's below it */
		double y = box ? fmax(fmin(y1 + size * 1.3, Hh - 3 * size), box_text) : y1 + size;
		y = wrapped_text(cr, x0, y, maxw, size, c->why, 1, 0.5, 1);
		if (box)
			box_text = y + 0.3 * size;
	}
	/* chart outline */
	if (r->npatches > 0 && !r->refused) {
		cairo_set_source_rgb(cr, 0.2, 0.6, 1.0);
		cairo_set_line_width(cr, lw);
		path_quad(cr, r->outline, s);
		cairo_stroke(cr);
	}
	for (int i = 0; i < r->ntags; i++) {
		const kg_chart_tag_found *t = &r->tags[i];
		if (t->used)
			cairo_set_source_rgb(cr, 0.1, 0.9, 0.2);
		else
			cairo_set_source_rgb(cr, 1.0, 0.55, 0.0);
		cairo_set_line_width(cr, 1.5 * lw);
		path_quad(cr, t->corners, s);
		cairo_stroke(cr);
		double cx = 0, cy = 0;
		for (int k = 0; k < 4; k++) {
			cx += t->corners[k][0] * s / 4;
			cy += t->corners[k][1] * s / 4;
		}
		char txt[32];
		snprintf(txt, sizeof(txt), "%d%s", t->id, t->used ? "" : "?");
		label(cr, cx, cy, font * 1.2, txt, t->used ? 0.1 : 1.0, t->used ? 0.9 : 0.55,
		      t->used ? 0.2 : 0.0);
	}
	for (int i = 0; i < r->npatches; i++) {
		const kg_chart_sample *p = &r->patches[i];
		int bad = p->flags != 0;
		if (bad)
			cairo_set_source_rgb(cr, 1, 0.1, 0.1);
		else
			cairo_set_source_rgb(cr, 1, 1, 1);
		cairo_set_line_width(cr, bad ? 2 * lw : lw);
		path_quad(cr, p->quad, s);
		cairo_stroke(cr);
		if (p->flags & (KG_CHART_FLAG_REJECTED | KG_CHART_FLAG_CLIPPED |
		                KG_CHART_FLAG_GLARE | KG_CHART_FLAG_MISFIT)) {
			cairo_move_to(cr, p->quad[0][0] * s, p->quad[0][1] * s);
			cairo_line_to(cr, p->quad[2][0] * s, p->quad[2][1] * s);
			cairo_move_to(cr, p->quad[1][0] * s, p->quad[1][1] * s);
			cairo_line_to(cr, p->quad[3][0] * s, p->quad[3][1] * s);
			cairo_stroke(cr);
		}
		double cx = 0, cy = 0;
		for (int k = 0; k < 4; k++) {
			cx += p->quad[k][0] * s / 4;
			cy += p->quad[k][1] * s / 4;
		}
		label(cr, cx, cy, font, p->id, bad ? 1 : 1, bad ? 0.3 : 1, bad ? 0.3 : 1);
		if (bad) {
			char why[32];
			snprintf(why, sizeof(why), "%s",
			         p->flags & KG_CHART_FLAG_REJECTED ? "rejected"
			         : p->flags & KG_CHART_FLAG_CLIPPED ? "clipped"
			         : p->flags & KG_CHART_FLAG_GLARE ? "glare"
			         : p->flags & KG_CHART_FLAG_OUT_OF_FRAME ? "out of frame"
			         : p->flags & KG_CHART_FLAG_NONUNIFORM ? "non-uniform"
			         : p->flags & KG_CHART_FLAG_MISFIT ? "not its colour" : "few pixels");
			label(cr, cx, cy + font * 1.1, font * 0.8, why, 1, 0.3, 0.3);
		}
	}
	char title[160];
	snprintf(title, sizeof(title), "%s: %d tags used, RMS %.2f px%s", r->layout, r->ntags_used,
	         r->rms_px, r->tagless ? " (tagless)" : "");
	if (r->refused) {
		snprintf(title, sizeof(title), "%s NOT FOUND (%d tag%s seen, %d candidate%s)",
		         r->layout, r->ntags, r->ntags == 1 ? "" : "s", r->ncandidates,
		         r->ncandidates == 1 ? "" : "s");
		wrapped_text(cr, font * 0.5, font * 2.9, W - font, font * 0.9, r->refusal, 1, 0.6,
		             0.3);
	}
	cairo_set_font_size(cr, font);
	cairo_move_to(cr, font * 0.5 + 1, font * 1.5 + 1);
	cairo_set_source_rgb(cr, 0, 0, 0);
	cairo_show_text(cr, title);
	cairo_move_to(cr, font * 0.5, font * 1.5);
	cairo_set_source_rgb(cr, 1, 1, 0.3);
	cairo_show_text(cr, title);
	cairo_surface_flush(surf);
	for (int y = 0; y < Hh; y++)
		for (int x = 0; x < W; x++) {
			uint32_t pix;
			memcpy(&pix, dst + (size_t)y * stride + 4 * x, 4);
			unsigned char *o = rgb + ((size_t)y * W + x) * 3;
			o[0] = (pix >> 16) & 255;
			o[1] = (pix >> 8) & 255;
			o[2] = pix & 255;
		}
	ret = kg_png_write_rgb8(path, rgb, W, Hh, err);
done:
	free(g);
	free(rgb);
	cairo_destroy(cr);
	cairo_surface_destroy(surf);
	chart_image_free(&wi);
	return ret;
}
