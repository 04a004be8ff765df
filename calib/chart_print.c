/* The printable AprilTag frame of a chart layout, drawn with cairo at true size into
 * SVG, PDF or PNG. Tag cells come from libapriltag's code tables; everything else is
 * drawn from the layout. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include <cairo.h>
#include <cairo-pdf.h>
#include <cairo-svg.h>

#include "kg_calib.h"
#include "kg_config.h"

#if HAVE_APRILTAG
#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagStandard41h12.h>

int kg_chart_tag_cells(const char *family, int id, unsigned char **cells,
                       int *total_width, int *border_width, kg_err *err)
{
	kg_check_arg(family && cells && total_width && border_width, err);
	apriltag_family_t *fam = NULL;
	void (*destroy)(apriltag_family_t *) = NULL;
	if (strcmp(family, "tag36h11") == 0)
		fam = tag36h11_create(), destroy = tag36h11_destroy;
	else if (strcmp(family, "tagStandard41h12") == 0)
		fam = tagStandard41h12_create(), destroy = tagStandard41h12_destroy;
	else
		return kg_fail(err, KG_EINVAL,
		               "tag family \"%s\": expected tag36h11 or tagStandard41h12", family);
	if (!fam)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	int ret = 0;
	if (id < 0 || (uint32_t)id >= fam->ncodes) {
		ret = kg_fail(err, KG_EINVAL, "tag id %d: expected 0..%u for %s", id,
		              fam->ncodes - 1, family);
		goto done;
	}
	int n = fam->total_width, b = fam->width_at_border;
	unsigned char *c = calloc((size_t)n * n, 1); /* all black */
	if (!c) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto done;
	}
	/* The white ring: just outside the black border for classic families, the ring
	 * of the detected square itself for reversed-border families (whose black border
	 * lies one cell further out). */
	int ring = fam->reversed_border ? b : b + 2;
	int r0 = (n - ring) / 2, r1 = r0 + ring - 1;
	for (int k = r0; k <= r1; k++) {
		c[r0 * n + k] = c[r1 * n + k] = 1;
		c[k * n + r0] = c[k * n + r1] = 1;
	}
	/* Data bits, most significant first, at (bit_x, bit_y) from the border square's
	 * top-left cell; bit_x/bit_y are negative (as unsigned) for cells outside it. */
	int off = (n - b) / 2;
	uint64_t code = fam->codes[id];
	for (uint32_t i = 0; i < fam->nbits; i++) {
		int x = (int)fam->bit_x[i] + off, y = (int)fam->bit_y[i] + off;
		if (x < 0 || y < 0 || x >= n || y >= n) {
			free(c);
			ret = kg_fail(err, KG_EINVAL, "%s: bit %u at (%d, %d) lies outside the %d x %d "
			              "tag", family, i, x, y, n, n);
			goto done;
		}
		c[y * n + x] = (unsigned char)((code >> (fam->nbits - 1 - i)) & 1);
	}
	*cells = c;
	*total_width = n;
	*border_width = b;
done:
	destroy(fam);
	return ret;
}

#else

int kg_chart_tag_cells(const char *family, int id, unsigned char **cells,
                       int *total_width, int *border_width, kg_err *err)
{
	return kg_fail(err, KG_ENOTSUP, "AprilTag tags need libapriltag, which this kogei was "
	               "built without (install libapriltag-dev and rebuild)");
}

#endif

/* ---- drawing --------------------------------------------------------------------- */

static const double ink = 0.0, mark_grey = 0.35, patch_grey = 0.7;

static void draw_text(cairo_t *cr, double x, double y, double size, int centred,
                      const char *text)
{
	cairo_text_extents_t te;
	cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL,
	                       CAIRO_FONT_WEIGHT_NORMAL);
	cairo_set_font_size(cr, size);
	cairo_text_extents(cr, text, &te);
	cairo_move_to(cr, centred ? x - te.width / 2 - te.x_bearing : x, y);
	cairo_show_text(cr, text);
}

/* All black cells of a tag as one path filled once, so neighbouring cells leave no
 * antialiasing seams between them. */
static int draw_tag(cairo_t *cr, const kg_chart_layout *l, int i, kg_err *err)
{
	const kg_chart_tag *t = &l->tags[i];
	unsigned char *cells = NULL;
	int n, b;
	int ret = kg_chart_tag_cells(l->family, t->id, &cells, &n, &b, err);
	if (ret)
		return ret;
	double cell = t->size_mm / b;
	double x0 = t->center_mm[0] - 0.5 * n * cell, y0 = t->center_mm[1] - 0.5 * n * cell;
	cairo_new_path(cr);
	for (int y = 0; y < n; y++)
		for (int x = 0; x < n; x++)
			if (!cells[y * n + x])
				cairo_rectangle(cr, x0 + x * cell, y0 + y * cell, cell, cell);
	cairo_set_fill_rule(cr, CAIRO_FILL_RULE_WINDING);
	cairo_set_source_rgb(cr, ink, ink, ink);
	cairo_fill(cr);
	free(cells);

	char label[64];
	snprintf(label, sizeof(label), "%s #%d", l->family, t->id);
	cairo_set_source_rgb(cr, mark_grey, mark_grey, mark_grey);
	draw_text(cr, t->center_mm[0], y0 + n * cell + cell + 2.5, 2.5, 1, label);
	return 0;
}

/* Crop marks in the margin, in line with the frame's edges, 2 mm clear of them. */
static void draw_cut_marks(cairo_t *cr, const kg_chart_layout *l)
{
	const double gap = 2.0, len = KG_CHART_PRINT_MARGIN_MM - 3.0;
	double xs[2] = {0, l->width_mm}, ys[2] = {0, l->height_mm};
	cairo_set_source_rgb(cr, ink, ink, ink);
	cairo_set_line_width(cr, 0.2);
	for (int a = 0; a < 2; a++)
		for (int c = 0; c < 2; c++) {
			double x = xs[a], y = ys[c];
			double dx = a ? 1 : -1, dy = c ? 1 : -1;
			cairo_move_to(cr, x + dx * gap, y);
			cairo_line_to(cr, x + dx * (gap + len), y);
			cairo_move_to(cr, x, y + dy * gap);
			cairo_line_to(cr, x, y + dy * (gap + len));
		}
	cairo_stroke(cr);
}

static void draw_chart_area(cairo_t *cr, const kg_chart_layout *l)
{
	const double *a = l->chart_area_mm;
	double dash[2] = {3.0, 1.5};
	cairo_set_source_rgb(cr, mark_grey, mark_grey, mark_grey);
	cairo_set_line_width(cr, 0.3);
	cairo_set_dash(cr, dash, 2, 0);
	cairo_rectangle(cr, a[0], a[1], a[2], a[3]);
	cairo_stroke(cr);
	cairo_set_dash(cr, NULL, 0, 0);

	cairo_set_source_rgb(cr, patch_grey, patch_grey, patch_grey);
	cairo_set_line_width(cr, 0.15);
	for (int i = 0; i < l->npatches; i++) {
		const kg_chart_patch *p = &l->patches[i];
		cairo_rectangle(cr, p->center_mm[0] - 0.5 * p->size_mm[0],
		                p->center_mm[1] - 0.5 * p->size_mm[1], p->size_mm[0], p->size_mm[1]);
	}
	cairo_stroke(cr);
	for (int i = 0; i < l->npatches; i++) {
		const kg_chart_patch *p = &l->patches[i];
		double size = fmin(3.0, 0.22 * fmin(p->size_mm[0], p->size_mm[1]));
		draw_text(cr, p->center_mm[0], p->center_mm[1] + 0.35 * size, size, 1, p->id);
	}
	cairo_set_source_rgb(cr, mark_grey, mark_grey, mark_grey);
	draw_text(cr, a[0] + 1.0, a[1] - 1.5, 2.5, 0, "chart area: align the chart's edges with "
	          "this outline, its patches over their ids");
}

/* A 50 mm bar with 10 mm ticks, centred under the chart area. */
static void draw_scale_bar(cairo_t *cr, const kg_chart_layout *l)
{
	const double len = 50.0;
	const double *a = l->chart_area_mm;
	double x0 = a[0] + 0.5 * a[2] - 0.5 * len;
	double y = fmin(l->height_mm - 6.0, a[1] + a[3] + 0.5 * (l->height_mm - a[1] - a[3]));
	cairo_set_source_rgb(cr, ink, ink, ink);
	cairo_set_line_width(cr, 0.3);
	cairo_move_to(cr, x0, y);
	cairo_line_to(cr, x0 + len, y);
	for (int k = 0; k <= 5; k++) {
		cairo_move_to(cr, x0 + 10.0 * k, y);
		cairo_line_to(cr, x0 + 10.0 * k, y - (k % 5 ? 1.5 : 3.0));
	}
	cairo_stroke(cr);
	draw_text(cr, x0 + 0.5 * len, y + 3.5, 2.5, 1,
	          "50 mm: print at 100 % (no fit-to-page) and check");
}

static void draw_frame(cairo_t *cr, const kg_chart_layout *l, int *ret, kg_err *err)
{
	cairo_translate(cr, KG_CHART_PRINT_MARGIN_MM, KG_CHART_PRINT_MARGIN_MM);
	draw_cut_marks(cr, l);
	draw_chart_area(cr, l);
	draw_scale_bar(cr, l);
	char title[160];
	snprintf(title, sizeof(title), "kogei chart frame: %s (%g x %g mm)", l->name,
	         l->width_mm, l->height_mm);
	cairo_set_source_rgb(cr, ink, ink, ink);
	draw_text(cr, 0.5 * l->width_mm, 6.0, 3.5, 1, title);
	for (int i = 0; i < l->ntags && !*ret; i++)
		*ret = draw_tag(cr, l, i, err);
}

static cairo_status_t write_stream(void *closure, const unsigned char *data,
                                   unsigned int length)
{
	FILE *fp = closure;
	return fwrite(data, 1, length, fp) == length ? CAIRO_STATUS_SUCCESS
	                                              : CAIRO_STATUS_WRITE_ERROR;
}

static int has_suffix(const char *s, const char *suffix)
{
	size_t n = strlen(s), m = strlen(suffix);
	return n >= m && strcasecmp(s + n - m, suffix) == 0;
}

int kg_chart_print(const kg_chart_layout *l, const char *path, double dpi, kg_err *err)
{
	kg_check_arg(l && path, err);
	enum { SVG, PDF, PNG } kind;
	if (has_suffix(path, ".svg"))
		kind = SVG;
	else if (has_suffix(path, ".pdf"))
		kind = PDF;
	else if (has_suffix(path, ".png"))
		kind = PNG;
	else
		return kg_fail(err, KG_EINVAL, "%s: unknown output format: expected a name ending "
		               "in .svg, .pdf or .png", path);
	if (kind == PNG && !(dpi >= 10 && dpi <= 2400))
		return kg_fail(err, KG_EINVAL, "resolution %g dpi: expected 10..2400", dpi);
	if (l->template_units)
		return kg_fail(err, KG_EINVAL, "%s: the layout is in template units, not mm: give "
		               "the chart's physical width", l->name);
	if (!HAVE_APRILTAG && l->ntags > 0)
		return kg_fail(err, KG_ENOTSUP, "kogei was built without libapriltag: it cannot "
		               "draw the frame's AprilTags (install libapriltag-dev and rebuild)");
	int ret = kg_chart_layout_check(l, err);
	if (ret)
		return ret;

	double page_w = l->width_mm + 2 * KG_CHART_PRINT_MARGIN_MM;
	double page_h = l->height_mm + 2 * KG_CHART_PRINT_MARGIN_MM;
	kg_outfile o;
	if ((ret = kg_outfile_open(&o, path, 0, err)))
		return ret;
	cairo_surface_t *s = NULL;
	double scale = 1.0;
	if (kind == SVG) {
		s = cairo_svg_surface_create_for_stream(write_stream, o.fp, page_w, page_h);
		cairo_svg_surface_set_document_unit(s, CAIRO_SVG_UNIT_MM);
	} else if (kind == PDF) {
		scale = 72.0 / 25.4;
		s = cairo_pdf_surface_create_for_stream(write_stream, o.fp, page_w * scale,
		                                        page_h * scale);
		cairo_pdf_surface_set_metadata(s, CAIRO_PDF_METADATA_TITLE, l->name);
	} else {
		scale = dpi / 25.4;
		double w = ceil(page_w * scale), h = ceil(page_h * scale);
		if (w * h > 4e8) {
			kg_outfile_abort(&o);
			return kg_fail(err, KG_EINVAL, "%s: %.0f x %.0f pixels at %g dpi is too large",
			               path, w, h, dpi);
		}
		s = cairo_image_surface_create(CAIRO_FORMAT_RGB24, (int)w, (int)h);
	}
	cairo_t *cr = cairo_create(s);
	cairo_scale(cr, scale, scale);
	cairo_set_source_rgb(cr, 1, 1, 1);
	cairo_paint(cr);
	draw_frame(cr, l, &ret, err);
	cairo_status_t st = cairo_status(cr);
	cairo_destroy(cr);
	if (!ret && kind == PNG)
		st = cairo_surface_write_to_png_stream(s, write_stream, o.fp);
	cairo_surface_finish(s);
	if (st == CAIRO_STATUS_SUCCESS)
		st = cairo_surface_status(s);
	cairo_surface_destroy(s);
	if (!ret && st != CAIRO_STATUS_SUCCESS)
		ret = kg_fail(err, KG_EIO, "%s: cairo: %s", path, cairo_status_to_string(st));
	if (ret) {
		kg_outfile_abort(&o);
		return ret;
	}
	return kg_outfile_commit(&o, err);
}
