/* Figures of the report, drawn with core/plot into PNGs held in memory: measured
 * against estimated chart spectra, and each material's mean estimate against its
 * library model (the paper's Figs. 11-12). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "report_private.h"

static const double solid_colour[3] = {0.1, 0.1, 0.1};
static const double dashed_colour[3] = {0.85, 0.33, 0.10};
static const double note_colour[3] = {0.45, 0.45, 0.45};

enum {
	margin = 20,   /* left and right of the panels */
	header = 84,   /* title and legend above them */
	cell_w = 250,
	cell_h = 228,
	axes_dx = 64,  /* room for the tick labels and the y label */
	axes_dy = 30,  /* room for the panel's title */
	axes_w = 170,
	axes_h = 140,
};

/* A scale that shows the shape of dark spectra too: 0 (or below, for negative
 * estimates) to the next tenth above the largest value. */
static void panel_range(const report_panel *p, double *ymin, double *ymax)
{
	double lo = 0, hi = 0;
	for (int b = 0; b < KG_NBANDS; b++) {
		if (p->solid && isfinite(p->solid[b])) {
			lo = fmin(lo, p->solid[b]);
			hi = fmax(hi, p->solid[b]);
		}
		if (p->dashed && isfinite(p->dashed[b])) {
			double u = p->band && isfinite(p->band[b]) ? p->band[b] : 0;
			lo = fmin(lo, p->dashed[b] - u);
			hi = fmax(hi, p->dashed[b] + u);
		}
	}
	*ymin = lo < 0 ? floor(lo * 1.05 * 10) / 10 : 0;
	*ymax = fmax(0.1, ceil(hi * 1.05 * 10) / 10);
}

int report_figure_spectra(const report_panel *panels, int n, int cols, const char *title,
                          const char *solid_label, const char *dashed_label,
                          unsigned char **png, size_t *len, kg_err *err)
{
	kg_check_arg(panels && n > 0 && cols > 0 && png && len, err);
	if (cols > n)
		cols = n;
	int rows = (n + cols - 1) / cols;
	int width = 2 * margin + cols * cell_w;
	if (width < 560)
		width = 560;
	kg_plot *p = NULL;
	int ret = kg_plot_new(width, header + rows * cell_h, &p, err);
	if (ret)
		return ret;
	double wl[KG_NBANDS];
	for (int b = 0; b < KG_NBANDS; b++)
		wl[b] = kg_band_nm(b);
	kg_plot_text(p, width / 2.0, 30, 17, KG_ALIGN_CENTER, NULL, "%s", title);
	/* Legend entries: a 24 px line, a gap and the label (about 7 px a character). */
	double solid_w = 30 + 7.0 * strlen(solid_label), dashed_w = 30 + 7.0 * strlen(dashed_label);
	double lx = (width - solid_w - 40 - dashed_w) / 2;
	kg_plot_legend(p, lx, 62, solid_colour, 0, solid_label);
	kg_plot_legend(p, lx + solid_w + 40, 62, dashed_colour, 1, dashed_label);
	for (int i = 0; i < n; i++) {
		const report_panel *q = &panels[i];
		double x = margin + (i % cols) * cell_w + axes_dx;
		double y = header + (i / cols) * cell_h + axes_dy;
		double ymin, ymax;
		panel_range(q, &ymin, &ymax);
		/* Axis labels on the outer panels: x where no panel lies below, y at the left. */
		kg_axes ax = kg_plot_axes(p, x, y, axes_w, axes_h, 400, 700, ymin, ymax,
		                          i + cols >= n ? "wavelength (nm)" : NULL,
		                          i % cols == 0 ? "reflectance" : NULL, NULL);
		kg_plot_text(p, x, y - 10, 13, KG_ALIGN_LEFT, NULL, "%s", q->title ? q->title : "");
		if (q->dashed && q->band) {
			double blo[KG_NBANDS], bhi[KG_NBANDS];
			for (int b = 0; b < KG_NBANDS; b++) {
				blo[b] = q->dashed[b] - q->band[b];
				bhi[b] = q->dashed[b] + q->band[b];
			}
			kg_plot_band(p, &ax, wl, blo, bhi, KG_NBANDS, dashed_colour, 0.18);
		}
		if (q->solid)
			kg_plot_line(p, &ax, wl, q->solid, KG_NBANDS, solid_colour, 1.8, 0);
		if (q->dashed)
			kg_plot_line(p, &ax, wl, q->dashed, KG_NBANDS, dashed_colour, 1.8, 1);
		if (q->note)
			kg_plot_text(p, x + axes_w - 6, y + 16, 11, KG_ALIGN_RIGHT, note_colour, "%s",
			             q->note);
	}
	ret = kg_plot_encode_png(p, png, len, err);
	kg_plot_free(&p);
	return ret;
}
