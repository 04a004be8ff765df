/* Spatial frequency response by the slanted-edge method (ISO 12233) and colour
 * channel misregistration, on one straight edge in a region of interest; and the
 * edges of a detected chart's AprilTags that suit it (calib/sfr.c, docs/report.md
 * "Sharpness: slanted-edge SFR").
 *
 * Coordinates: image pixels, pixel (i, j) covers [i, i+1) x [j, j+1), its centre is
 * (i + 0.5, j + 0.5). Frequencies are in cycles per pixel (Nyquist is 0.5).
 *
 * Typical use (the conformance analysis):
 *
 *   kg_sfr_edge *edges; int n;
 *   kg_sfr_find_edges(layout, chart_result, img, 0, &edges, &n, &err);
 *   for (int i = 0; i < n; i++) {
 *       kg_sfr_result r;
 *       if (kg_sfr_measure(img, &edges[i].roi, &r, &err) == 0)
 *           ... r.mtf50, r.mtf10, r.efficiency, r.misregistration ...
 *           // (unless r.peak[c] reaches the image's clip level: a clipped edge)
 *       // else err.msg says why this edge is not usable (skip it, report it);
 *       // r.too_blurred: the band is too narrow for its blur (r.rise, r.band)
 *   }
 *   free(edges);
 */
#ifndef KG_SFR_H
#define KG_SFR_H

#include "image.h"
#include "kg_calib.h"

/* Bins per pixel of the edge spread function (ISO 12233: 4). */
#define KG_SFR_OVERSAMPLE 4
/* Accepted slant of the edge from the nearest image axis, degrees. Below the minimum
 * the edge does not sweep the pixel phases; above the maximum the projection's
 * aperture is no longer the axis's. */
#define KG_SFR_MIN_ANGLE 1.0
#define KG_SFR_MAX_ANGLE 20.0
/* The band must hold the edge's blur: its half-width across the edge at least
 * KG_SFR_BAND_RISE times the edge spread function's 10-90 % rise. A narrower band cuts
 * off the line spread function's tails and reads the MTF too high (a Gaussian blur of
 * sigma has a rise of 2.563 sigma: the band then reaches 4.1 sigma, where the tails
 * left out are 4e-5 of the line spread function). */
#define KG_SFR_BAND_RISE 1.6
/* On a chart's tag side: how close (in 10-90 % rises) a band may come to the next
 * printed edge (one tag cell away: the tag's data bits inside, beyond its white ring
 * outside), which bounds any band on a tag at a cell less this many rises. Half a rise
 * is what the 0.8-cell band leaves at the largest blur it holds (a rise of 0.5 cell),
 * where simulated tags measure within 1 % of their analytic MTF50. */
#define KG_SFR_NEIGHBOUR_RISE 0.5
/* The MTF curve kept in the result: at k / (KG_SFR_CURVE - 1) cycles/px, k = 0 ..
 * KG_SFR_CURVE - 1 (0 .. 1 cycle/px, twice Nyquist). */
#define KG_SFR_CURVE 65

/* A region with one straight edge crossing it from side to side. */
typedef struct kg_sfr_roi {
	int x, y, w, h;     /* pixels [x, x + w) x [y, y + h), inside the image */
	int has_line;       /* 1: the edge is known roughly: the segment p0 -> p1 (px),
	                     * e.g. from a homography; only pixels within half_width
	                     * (px, measured along the image axis across the edge) of the
	                     * line fitted near it are used, so other structure in the
	                     * box is ignored. 0: the whole box, one edge in it. */
	double p0[2], p1[2];
	double half_width;
} kg_sfr_roi;

typedef struct kg_sfr_channel {
	double mtf50;        /* cycles/px where the MTF first falls to 0.5 */
	double mtf10;        /* cycles/px where it first falls to 0.1; 1.0 with
	                      * mtf10_reached = 0 when it stays above 0.1 up to 1 cy/px */
	int mtf10_reached;
	double efficiency;   /* sampling efficiency: min(mtf10 / 0.5, 1) */
	double position;     /* the edge (centroid of the line spread function within
	                      * 3 times the edge's 10-90 % rise of its peak), px
	                      * across the edge from the reference line (the line fitted
	                      * to the mean of the channels), signed along +x (vertical
	                      * edge) or +y (horizontal edge) */
	double contrast;     /* |bright side - dark side| of the edge spread function */
	double noise;        /* RMS of the pixels about the edge spread function on the
	                      * flat parts either side */
	double mtf[KG_SFR_CURVE];
} kg_sfr_channel;

typedef struct kg_sfr_result {
	int channels;          /* 1 or 3, as the image */
	int vertical;          /* 1: near-vertical edge (profile along x), 0: near-
	                        * horizontal (profile along y) */
	double angle_deg;      /* slant from the nearest image axis (signed) */
	double centre[2];      /* px: the reference line at the middle of the region */
	double length;         /* px along the edge that was used */
	double fit_rms;        /* px: RMS of the per-line edge positions about the line */
	int lines;             /* image rows (vertical) or columns used */
	long pixels;           /* pixels projected into the bins */
	kg_sfr_channel ch[3];
	/* the figures graded: the mean of the channels' values for a colour image, the
	 * channel itself for a grey one */
	double mtf50, mtf10, efficiency;
	int mtf10_reached;     /* 0 when some channel's MTF stays above 0.1 to 1 cy/px */
	/* colour channel misregistration: the largest difference between the R, G and B
	 * edge positions, px (0 for one channel) */
	double misregistration;
	/* the blur against the band: the 10-90 % rise of the mean channel's edge spread
	 * function and the band's half-width, both px perpendicular to the edge; set
	 * when the edge was found (also on a refusal after that, 0 before);
	 * too_blurred = 1 when band < KG_SFR_BAND_RISE x rise (the edge is refused) */
	double rise, band;
	int too_blurred;
	/* per channel, the largest value among the pixels projected (the band): the
	 * caller compares it with the image's clip level (an edge whose band reaches it
	 * is shaped by the clipping, not the optics); set with pixels, also on a refusal
	 * after the projection */
	double peak[3];
} kg_sfr_result;

/* Measure the edge in roi of img (1 or 3 channels, linear): per line across the
 * edge, the centroid of the derivative; a straight line fitted to those (twice, the
 * second time with a Hamming window around the first fit); every pixel projected by
 * its distance to the line perpendicular to the edge into 1/4 px bins (empty bins
 * interpolated); the binned edge spread function differentiated to the line spread
 * function, Hamming-windowed about its centroid, Fourier-transformed, normalised at
 * 0 cycles/px and divided by the two-point derivative's sinc. Per channel: MTF50,
 * MTF10, sampling efficiency and edge position; for three channels, the
 * misregistration.
 * KG_EINVAL (err says which) for a region outside the image or too small, and for a
 * region that holds no usable edge: no step above the noise, positions that do not
 * lie on a straight line, a slant outside [KG_SFR_MIN_ANGLE, KG_SFR_MAX_ANGLE], an
 * edge too close to the region's sides, an edge too blurred for the band (its 10-90 %
 * rise more than 1 / KG_SFR_BAND_RISE of the band's half-width: too_blurred, rise and
 * band say by how much). */
int kg_sfr_measure(const kg_image *img, const kg_sfr_roi *roi, kg_sfr_result *out,
                   kg_err *err);

/* An edge of a detected chart suited to the slanted-edge method. */
typedef struct kg_sfr_edge {
	kg_sfr_roi roi;      /* with has_line = 1: the edge's middle part, half_width 0.8
	                      * of a tag cell either side (inside: the tag's black border,
	                      * outside: its white ring, for tag36h11) */
	int tag_id;          /* the AprilTag whose square side it is */
	int side;            /* 0..3: from corner side to corner side + 1 (apriltag order:
	                      * 0 bottom, 1 right, 2 top, 3 left on the page) */
	double angle_deg;    /* slant from the nearest image axis, unsigned */
	double length_px;    /* of the part used */
	double cell_px;      /* the tag's cell (its side / 8 for tag36h11, / 5 for
	                      * tagStandard41h12): the next printed edge is one cell away
	                      * either side, which bounds the band */
} kg_sfr_edge;

/* The region of edge e with a band of half_width px (along the image axis across the
 * edge) either side of the edge's line (e->roi.p0, p1), into *roi; the region holds
 * the whole band. -1 when that region leaves img or half_width is under 4 px. On a
 * tag no band reaches further than cell_px - KG_SFR_NEIGHBOUR_RISE x the edge's rise. */
int kg_sfr_edge_band(const kg_sfr_edge *e, double half_width, const kg_image *img,
                     kg_sfr_roi *roi);

/* The sides of the detected tags of layout l in r (tags of the layout only) that are
 * slanted 2 to 10 degrees from the image axes and whose middle part (the side less
 * half a tag cell at each end) is at least min_length_px long (0: 20 px), with a
 * band of at least 4 px either side and inside img. Tag families: tag36h11 and
 * tagStandard41h12 (their cell sizes). *edges is newly allocated (free()), *n may be
 * 0 (no side suits: the chart sits square to the sensor or too small). The frame's
 * other printed lines (chart outline, cut marks) are light grey or thin and are not
 * used. KG_EINVAL for a layout without tags or of another family. */
int kg_sfr_find_edges(const kg_chart_layout *l, const kg_chart_result *r,
                      const kg_image *img, double min_length_px, kg_sfr_edge **edges,
                      int *n, kg_err *err);

#endif
