/* Plots for people: heat maps, spectra, scatter plots and swatch sheets drawn
 * with cairo into PNG files. Coordinates are in pixels from the top left; an
 * axes object maps data coordinates into a rectangle of the figure. */
#ifndef KG_PLOT_H
#define KG_PLOT_H

#include "error.h"

typedef struct kg_plot kg_plot;

typedef struct kg_axes {
	double x, y, w, h;         /* pixel rectangle of the plotting area */
	double xmin, xmax, ymin, ymax;
} kg_axes;

enum kg_align { KG_ALIGN_LEFT, KG_ALIGN_CENTER, KG_ALIGN_RIGHT };

int kg_plot_new(int width, int height, kg_plot **out, kg_err *err);
void kg_plot_free(kg_plot **p);
/* Write the figure as an 8-bit RGB PNG, atomically. */
int kg_plot_save_png(kg_plot *p, const char *path, kg_err *err);
/* The same PNG in memory (for pages that inline their figures); the caller frees *png. */
int kg_plot_encode_png(kg_plot *p, unsigned char **png, size_t *len, kg_err *err);

/* Colours are linear 0..1 display values already encoded for the screen (sRGB). */
void kg_plot_fill_rect(kg_plot *p, double x, double y, double w, double h, const double rgb[3]);
void kg_plot_stroke_rect(kg_plot *p, double x, double y, double w, double h,
                         const double rgb[3], double line_width);
void kg_plot_text(kg_plot *p, double x, double y, double size, enum kg_align align,
                  const double rgb[3], const char *fmt, ...) KG_PRINTF(7, 8);
/* An image: w x h pixels of 8-bit display-encoded sRGB (3 bytes each, row by row),
 * drawn 1:1 with its top left corner at (x, y). */
void kg_plot_image(kg_plot *p, double x, double y, const unsigned char *rgb, int w, int h);
/* Text rotated 90 degrees counter-clockwise (for y axis labels), centred at x, y. */
void kg_plot_text_vertical(kg_plot *p, double x, double y, double size, const char *text);

/* Draw the frame, ticks and labels of an axes and return the mapping. */
kg_axes kg_plot_axes(kg_plot *p, double x, double y, double w, double h, double xmin,
                     double xmax, double ymin, double ymax, const char *xlabel,
                     const char *ylabel, const char *title);
/* The area between lo and hi (n points at xs, non-finite ones end a segment), in rgb at
 * opacity alpha. */
void kg_plot_band(kg_plot *p, const kg_axes *ax, const double *xs, const double *lo,
                  const double *hi, int n, const double rgb[3], double alpha);
void kg_plot_line(kg_plot *p, const kg_axes *ax, const double *xs, const double *ys, int n,
                  const double rgb[3], double width, int dashed);
void kg_plot_points(kg_plot *p, const kg_axes *ax, const double *xs, const double *ys, int n,
                    const double rgb[3], double radius);
/* A legend entry at pixel position (x, y): a short line in the colour and a label. */
void kg_plot_legend(kg_plot *p, double x, double y, const double rgb[3], int dashed,
                    const char *label);
/* values[r * cols + c]: row r spans y from ymin (r = 0) upward, column c spans x. */
void kg_plot_heatmap(kg_plot *p, const kg_axes *ax, const double *values, int rows, int cols,
                     double vmin, double vmax);
void kg_plot_colorbar(kg_plot *p, double x, double y, double w, double h, double vmin,
                      double vmax, const char *label);

/* A perceptually ordered colour map (dark blue - teal - yellow) for t in [0, 1]. */
void kg_colormap(double t, double rgb[3]);
/* A qualitative colour for series i (distinct for the first ten). */
void kg_series_colour(int i, double rgb[3]);

#endif
