#include <cairo.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fsutil.h"
#include "plot.h"

struct kg_plot {
	cairo_surface_t *surface;
	cairo_t *cr;
	int width, height;
};

static const double black[3] = {0, 0, 0};
static const double grey[3] = {0.55, 0.55, 0.55};

int kg_plot_new(int width, int height, kg_plot **out, kg_err *err)
{
	if (width <= 0 || height <= 0 || width > 20000 || height > 20000)
		return kg_fail(err, KG_EINVAL, "plot: size %dx%d: expected 1..20000 pixels", width,
		               height);
	kg_plot *p = calloc(1, sizeof(*p));
	if (!p)
		return kg_fail(err, KG_ENOMEM, "plot: out of memory");
	p->surface = cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height);
	p->cr = cairo_create(p->surface);
	if (cairo_status(p->cr) != CAIRO_STATUS_SUCCESS) {
		kg_plot_free(&p);
		return kg_fail(err, KG_ENOMEM, "plot: cannot create a %dx%d image", width, height);
	}
	p->width = width;
	p->height = height;
	cairo_set_source_rgb(p->cr, 1, 1, 1);
	cairo_paint(p->cr);
	cairo_select_font_face(p->cr, "DejaVu Sans", CAIRO_FONT_SLANT_NORMAL,
	                       CAIRO_FONT_WEIGHT_NORMAL);
	*out = p;
	return 0;
}

void kg_plot_free(kg_plot **pp)
{
	kg_plot *p = *pp;
	if (!p)
		return;
	if (p->cr)
		cairo_destroy(p->cr);
	if (p->surface)
		cairo_surface_destroy(p->surface);
	free(p);
	*pp = NULL;
}

static cairo_status_t write_cb(void *closure, const unsigned char *data, unsigned int len)
{
	return fwrite(data, 1, len, closure) == len ? CAIRO_STATUS_SUCCESS
	                                            : CAIRO_STATUS_WRITE_ERROR;
}

int kg_plot_save_png(kg_plot *p, const char *path, kg_err *err)
{
	kg_outfile o;
	int ret = kg_outfile_open(&o, path, 0, err);
	if (ret)
		return ret;
	cairo_surface_flush(p->surface);
	if (cairo_surface_write_to_png_stream(p->surface, write_cb, o.fp) != CAIRO_STATUS_SUCCESS) {
		kg_outfile_abort(&o);
		return kg_fail(err, KG_EIO, "%s: cannot write PNG", path);
	}
	return kg_outfile_commit(&o, err);
}

typedef struct png_buffer {
	unsigned char *data;
	size_t len, cap;
} png_buffer;

static cairo_status_t append_cb(void *closure, const unsigned char *data, unsigned int len)
{
	png_buffer *b = closure;
	if (b->len + len > b->cap) {
		size_t cap = b->cap ? b->cap : 65536;
		while (cap < b->len + len)
			cap *= 2;
		unsigned char *grown = realloc(b->data, cap);
		if (!grown)
			return CAIRO_STATUS_NO_MEMORY;
		b->data = grown;
		b->cap = cap;
	}
	memcpy(b->data + b->len, data, len);
	b->len += len;
	return CAIRO_STATUS_SUCCESS;
}

int kg_plot_encode_png(kg_plot *p, unsigned char **png, size_t *len, kg_err *err)
{
	png_buffer b = {0};
	cairo_surface_flush(p->surface);
	if (cairo_surface_write_to_png_stream(p->surface, append_cb, &b) != CAIRO_STATUS_SUCCESS) {
		free(b.data);
		return kg_fail(err, KG_ENOMEM, "plot: cannot encode a %dx%d PNG", p->width, p->height);
	}
	*png = b.data;
	*len = b.len;
	return 0;
}

static void set_rgb(kg_plot *p, const double rgb[3])
{
	cairo_set_source_rgb(p->cr, rgb[0], rgb[1], rgb[2]);
}

void kg_plot_fill_rect(kg_plot *p, double x, double y, double w, double h, const double rgb[3])
{
	set_rgb(p, rgb);
	cairo_rectangle(p->cr, x, y, w, h);
	cairo_fill(p->cr);
}

void kg_plot_stroke_rect(kg_plot *p, double x, double y, double w, double h,
                         const double rgb[3], double line_width)
{
	set_rgb(p, rgb);
	cairo_set_line_width(p->cr, line_width);
	cairo_rectangle(p->cr, x, y, w, h);
	cairo_stroke(p->cr);
}

void kg_plot_image(kg_plot *p, double x, double y, const unsigned char *rgb, int w, int h)
{
	if (!rgb || w <= 0 || h <= 0)
		return;
	cairo_surface_t *img = cairo_image_surface_create(CAIRO_FORMAT_RGB24, w, h);
	if (cairo_surface_status(img) != CAIRO_STATUS_SUCCESS) {
		cairo_surface_destroy(img);
		return;
	}
	cairo_surface_flush(img);
	unsigned char *data = cairo_image_surface_get_data(img);
	int stride = cairo_image_surface_get_stride(img);
	for (int j = 0; j < h; j++)
		for (int i = 0; i < w; i++) {
			/* RGB24: one native-endian 32-bit word per pixel, 0x00RRGGBB */
			const unsigned char *q = rgb + 3 * ((size_t)j * (size_t)w + (size_t)i);
			uint32_t v = (uint32_t)q[0] << 16 | (uint32_t)q[1] << 8 | q[2];
			memcpy(data + (size_t)j * (size_t)stride + 4 * (size_t)i, &v, sizeof(v));
		}
	cairo_surface_mark_dirty(img);
	cairo_save(p->cr);
	cairo_set_source_surface(p->cr, img, x, y);
	cairo_pattern_set_filter(cairo_get_source(p->cr), CAIRO_FILTER_NEAREST);
	cairo_rectangle(p->cr, x, y, w, h);
	cairo_fill(p->cr);
	cairo_restore(p->cr);
	cairo_surface_destroy(img);
}

static void text_at(kg_plot *p, double x, double y, double size, enum kg_align align,
                    const double rgb[3], const char *s)
{
	cairo_text_extents_t ext;
	cairo_set_font_size(p->cr, size);
	cairo_text_extents(p->cr, s, &ext);
	double dx = align == KG_ALIGN_LEFT ? 0 : align == KG_ALIGN_CENTER ? -ext.x_advance / 2
	                                                                   : -ext.x_advance;
	set_rgb(p, rgb);
	cairo_move_to(p->cr, x + dx, y);
	cairo_show_text(p->cr, s);
}

void kg_plot_text(kg_plot *p, double x, double y, double size, enum kg_align align,
                  const double rgb[3], const char *fmt, ...)
{
	char buf[512];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(buf, sizeof(buf), fmt, ap);
	va_end(ap);
	text_at(p, x, y, size, align, rgb ? rgb : black, buf);
}

void kg_plot_text_vertical(kg_plot *p, double x, double y, double size, const char *text)
{
	cairo_save(p->cr);
	cairo_translate(p->cr, x, y);
	cairo_rotate(p->cr, -M_PI / 2);
	text_at(p, 0, 0, size, KG_ALIGN_CENTER, black, text);
	cairo_restore(p->cr);
}

/* A "nice" tick step giving about n ticks over span. */
static double nice_step(double span, int n)
{
	double raw = span / n, mag = pow(10, floor(log10(raw))), f = raw / mag;
	double nice = f < 1.5 ? 1 : f < 3 ? 2 : f < 7 ? 5 : 10;
	return nice * mag;
}

static double map_x(const kg_axes *ax, double v)
{
	return ax->x + (v - ax->xmin) / (ax->xmax - ax->xmin) * ax->w;
}

static double map_y(const kg_axes *ax, double v)
{
	return ax->y + ax->h - (v - ax->ymin) / (ax->ymax - ax->ymin) * ax->h;
}

static void format_tick(char *buf, size_t n, double v, double step)
{
	int decimals = step >= 1 ? 0 : (int)ceil(-log10(step) - 1e-9);
	if (decimals > 6)
		decimals = 6;
	snprintf(buf, n, "%.*f", decimals, fabs(v) < step * 1e-6 ? 0.0 : v);
}

kg_axes kg_plot_axes(kg_plot *p, double x, double y, double w, double h, double xmin,
                     double xmax, double ymin, double ymax, const char *xlabel,
                     const char *ylabel, const char *title)
{
	if (!(xmax > xmin))
		xmax = xmin + 1;
	if (!(ymax > ymin))
		ymax = ymin + 1;
	kg_axes ax = {x, y, w, h, xmin, xmax, ymin, ymax};
	char buf[64];
	cairo_set_line_width(p->cr, 1);
	double sx = nice_step(xmax - xmin, 6), sy = nice_step(ymax - ymin, 5);
	for (double t = ceil(xmin / sx - 1e-9) * sx; t <= xmax + sx * 1e-9; t += sx) {
		double px = map_x(&ax, t);
		set_rgb(p, grey);
		cairo_move_to(p->cr, px, y + h);
		cairo_line_to(p->cr, px, y + h + 5);
		cairo_stroke(p->cr);
		format_tick(buf, sizeof(buf), t, sx);
		text_at(p, px, y + h + 18, 11, KG_ALIGN_CENTER, black, buf);
	}
	for (double t = ceil(ymin / sy - 1e-9) * sy; t <= ymax + sy * 1e-9; t += sy) {
		double py = map_y(&ax, t);
		set_rgb(p, grey);
		cairo_move_to(p->cr, x - 5, py);
		cairo_line_to(p->cr, x, py);
		cairo_stroke(p->cr);
		format_tick(buf, sizeof(buf), t, sy);
		text_at(p, x - 8, py + 4, 11, KG_ALIGN_RIGHT, black, buf);
	}
	kg_plot_stroke_rect(p, x, y, w, h, black, 1);
	if (xlabel)
		text_at(p, x + w / 2, y + h + 38, 13, KG_ALIGN_CENTER, black, xlabel);
	if (ylabel)
		kg_plot_text_vertical(p, x - 48, y + h / 2, 13, ylabel);
	if (title)
		text_at(p, x + w / 2, y - 12, 15, KG_ALIGN_CENTER, black, title);
	return ax;
}

static void begin_clip(kg_plot *p, const kg_axes *ax)
{
	cairo_save(p->cr);
	cairo_rectangle(p->cr, ax->x, ax->y, ax->w, ax->h);
	cairo_clip(p->cr);
}

void kg_plot_band(kg_plot *p, const kg_axes *ax, const double *xs, const double *lo,
                  const double *hi, int n, const double rgb[3], double alpha)
{
	begin_clip(p, ax);
	cairo_set_source_rgba(p->cr, rgb[0], rgb[1], rgb[2], alpha);
	for (int i = 0; i < n;) {
		while (i < n && !(isfinite(xs[i]) && isfinite(lo[i]) && isfinite(hi[i])))
			i++;
		int a = i;
		while (i < n && isfinite(xs[i]) && isfinite(lo[i]) && isfinite(hi[i]))
			i++;
		if (i - a < 2)
			continue;
		cairo_move_to(p->cr, map_x(ax, xs[a]), map_y(ax, hi[a]));
		for (int k = a + 1; k < i; k++)
			cairo_line_to(p->cr, map_x(ax, xs[k]), map_y(ax, hi[k]));
		for (int k = i - 1; k >= a; k--)
			cairo_line_to(p->cr, map_x(ax, xs[k]), map_y(ax, lo[k]));
		cairo_close_path(p->cr);
		cairo_fill(p->cr);
	}
	cairo_restore(p->cr);
}

void kg_plot_line(kg_plot *p, const kg_axes *ax, const double *xs, const double *ys, int n,
                  const double rgb[3], double width, int dashed)
{
	begin_clip(p, ax);
	set_rgb(p, rgb);
	cairo_set_line_width(p->cr, width);
	if (dashed) {
		double d[2] = {6, 4};
		cairo_set_dash(p->cr, d, 2, 0);
	}
	int pen = 0;
	for (int i = 0; i < n; i++) {
		if (!isfinite(xs[i]) || !isfinite(ys[i])) {
			pen = 0;
			continue;
		}
		if (pen)
			cairo_line_to(p->cr, map_x(ax, xs[i]), map_y(ax, ys[i]));
		else
			cairo_move_to(p->cr, map_x(ax, xs[i]), map_y(ax, ys[i]));
		pen = 1;
	}
	cairo_stroke(p->cr);
	cairo_restore(p->cr);
}

void kg_plot_points(kg_plot *p, const kg_axes *ax, const double *xs, const double *ys, int n,
                    const double rgb[3], double radius)
{
	begin_clip(p, ax);
	set_rgb(p, rgb);
	for (int i = 0; i < n; i++) {
		if (!isfinite(xs[i]) || !isfinite(ys[i]))
			continue;
		cairo_new_sub_path(p->cr);
		cairo_arc(p->cr, map_x(ax, xs[i]), map_y(ax, ys[i]), radius, 0, 2 * M_PI);
	}
	cairo_fill(p->cr);
	cairo_restore(p->cr);
}

void kg_plot_legend(kg_plot *p, double x, double y, const double rgb[3], int dashed,
                    const char *label)
{
	cairo_save(p->cr);
	set_rgb(p, rgb);
	cairo_set_line_width(p->cr, 2);
	if (dashed) {
		double d[2] = {6, 4};
		cairo_set_dash(p->cr, d, 2, 0);
	}
	cairo_move_to(p->cr, x, y - 4);
	cairo_line_to(p->cr, x + 24, y - 4);
	cairo_stroke(p->cr);
	cairo_restore(p->cr);
	text_at(p, x + 30, y, 11, KG_ALIGN_LEFT, black, label);
}

void kg_plot_heatmap(kg_plot *p, const kg_axes *ax, const double *values, int rows, int cols,
                     double vmin, double vmax)
{
	double cw = ax->w / cols, ch = ax->h / rows, rgb[3];
	for (int r = 0; r < rows; r++)
		for (int c = 0; c < cols; c++) {
			double t = (values[(size_t)r * cols + c] - vmin) / (vmax - vmin);
			kg_colormap(t, rgb);
			/* Overlap by half a pixel so no seams show between cells. */
			kg_plot_fill_rect(p, ax->x + c * cw, ax->y + ax->h - (r + 1) * ch, cw + 0.5,
			                  ch + 0.5, rgb);
		}
	kg_plot_stroke_rect(p, ax->x, ax->y, ax->w, ax->h, black, 1);
}

void kg_plot_colorbar(kg_plot *p, double x, double y, double w, double h, double vmin,
                      double vmax, const char *label)
{
	double rgb[3];
	int steps = (int)h;
	for (int i = 0; i < steps; i++) {
		kg_colormap((double)i / (steps - 1), rgb);
		kg_plot_fill_rect(p, x, y + h - i - 1, w, 1.5, rgb);
	}
	kg_axes ax = {x, y, w, h, 0, 1, vmin, vmax};
	char buf[64];
	double s = nice_step(vmax - vmin, 5);
	for (double t = ceil(vmin / s - 1e-9) * s; t <= vmax + s * 1e-9; t += s) {
		format_tick(buf, sizeof(buf), t, s);
		text_at(p, x + w + 6, map_y(&ax, t) + 4, 11, KG_ALIGN_LEFT, black, buf);
	}
	kg_plot_stroke_rect(p, x, y, w, h, black, 1);
	if (label)
		text_at(p, x + w / 2, y - 8, 12, KG_ALIGN_CENTER, black, label);
}

void kg_colormap(double t, double rgb[3])
{
	/* Anchors chosen for monotonically increasing lightness: dark blue-violet,
	 * blue, teal, green, yellow. */
	static const double anchors[5][3] = {
		{0.19, 0.07, 0.33}, {0.18, 0.33, 0.56}, {0.12, 0.57, 0.55},
		{0.42, 0.78, 0.33}, {0.99, 0.91, 0.15},
	};
	if (!isfinite(t))
		t = 0;
	t = t < 0 ? 0 : t > 1 ? 1 : t;
	double s = t * 4;
	int i = (int)s;
	if (i > 3)
		i = 3;
	double f = s - i;
	for (int c = 0; c < 3; c++)
		rgb[c] = anchors[i][c] * (1 - f) + anchors[i + 1][c] * f;
}

void kg_series_colour(int i, double rgb[3])
{
	static const double pal[10][3] = {
		{0.12, 0.47, 0.71}, {0.85, 0.37, 0.01}, {0.17, 0.63, 0.17}, {0.84, 0.15, 0.16},
		{0.58, 0.40, 0.74}, {0.55, 0.34, 0.29}, {0.89, 0.47, 0.76}, {0.35, 0.35, 0.35},
		{0.74, 0.74, 0.13}, {0.09, 0.75, 0.81},
	};
	memcpy(rgb, pal[((i % 10) + 10) % 10], sizeof(pal[0]));
}
