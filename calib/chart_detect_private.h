/* Private to calib/chart_*.c: the chart detector's stages share these types and
 * functions (chart_detect.c lists which file holds which stage). The public API is
 * kg_calib.h. */
#ifndef KG_CHART_DETECT_PRIVATE_H
#define KG_CHART_DETECT_PRIVATE_H

#include <pthread.h>
#include <stddef.h>
#include <stdint.h>

#include "calib_private.h"
#include "kg_calib.h"
#include "kg_config.h"
#include "saturation.h"

#if KG_HAVE_MCC
#include "chart_mcc.h"
#define MCC_MIN_SIDE 100L
/* The tagless detector's orientation (orientation_score): the best of the 4 turns
 * must fit the layout's colours with an RMS sine below KG_ORIENT_SCORE_MAX, be
 * KG_ORIENT_MARGIN times better than the next, and its patches must spread by more
 * than KG_ORIENT_SPREAD_MIN (RMS sine from their mean direction). */
#define KG_ORIENT_SCORE_MAX 0.15
#define KG_ORIENT_MARGIN 1.5
#define KG_ORIENT_SPREAD_MIN 0.05
/* mcc's candidate boxes tried, its best first */
#define MCC_CANDIDATES 3
#endif
#if HAVE_APRILTAG
/* The largest side libapriltag's segmentation takes after decimation. */
#define APRILTAG_MAX_SIDE 32767L
#endif

/* ---- chart_detect.c: results, timing, image sides ------------------------------- */

int chart_add_warning(kg_chart_result *r, const char *fmt, ...) KG_PRINTF(2, 3);
double chart_now_seconds(void);
/* Every stage states the image sides it supports, and an image outside them is refused
 * before the stage runs. */
int chart_check_sides(int width, int height, long min_side, long max_side, const char *stage,
                      const char *hint, kg_err *err);

/* ---- chart_image.c: threads ---------------------------------------------------- */

/* fn(arg, t, n) for t = 0..n-1, t = 0 on the caller's thread. Every caller splits its
 * work by t into pieces whose results do not depend on n, so any thread count gives
 * the same numbers. A thread that cannot be started has its share run here. */
typedef void (*par_fn)(void *arg, int t, int n);

enum { MAX_THREADS = 64 };

int chart_clamp_threads(int threads);
void chart_run_parallel(par_fn fn, void *arg, int threads);

/* ---- chart_image.c: the image as the sampler sees it ----------------------------- */

/* The patch sampler's scratch (chart_sample.c, chart_count.c): one set per thread. */
typedef struct sample_buffers {
	float *ch[3];
	float *sum;
	float *work;
	uint32_t *keys;
	long cap;
	float *row; /* one row of the region, demosaiced or gathered */
	long row_cap;
	/* counting (count_values): keys lo .. lo + nb - 1 and their counts; a key is its
	 * value (bin_value), inv the 1 / scale it was made with. seen has a bit per bin,
	 * set where the count is not 0, so the walks over the counts step from one
	 * occupied bin to the next; both arrays are all zero again (the bins that were
	 * counted cleared) before the next values are counted. */
	int32_t *cnt;
	uint64_t *seen;
	float inv;
	long lo, nb, bins_cap;
} sample_buffers;

/* Interleaved linear floats with 1 or 3 channels. A raw CFA frame is not demosaiced
 * as a whole: the stages read it through image_span, which demosaics the pixels they
 * ask for (the patch regions, every 4th pixel for the white level, the rows of the
 * grey picture), so only what is looked at is converted. */
typedef struct work_image {
	int width, height, channels;
	const float *data; /* NULL for a raw CFA frame until demosaic_all, and for a mapped
	                    * 16-bit image (u16) */
	const uint16_t *u16; /* a mapped image's codes (kg_image_map), read through lut */
	const float *lut;
	/* the tag search's 8-bit grey picture (sRGB-encoded, every grey_zoom-th pixel of
	 * every grey_zoom-th row), kept for the tagless detector's patch-grid finder; NULL
	 * when there is none */
	unsigned char *grey;
	int grey_w, grey_h, grey_zoom;
	double white; /* chart_white_level's, once found (0: not yet) */
	float *owned;
	const kg_image *raw; /* the CFA frame, or NULL */
	int cfa_rows, cfa_cols;
	int colour[64];      /* the CFA repeat's filters: 0 R, 1 G, 2 B */
	/* Per CFA phase, each colour's neighbours in the 3 x 3 window, in raster order, as
	 * offsets in the frame (dy W + dx): the interior pixels' sums without the edge
	 * clamping. */
	ptrdiff_t nb[64][3][9];
	int nbn[64][3];
	double clip_level;
	double clip_ch[3];   /* per colour: the clip level, or the saturation found from the
	                      * data below it (core/saturation.h) */
	char sat_note[200];  /* where saturation was found below full scale, else ""
	                      * (after chart_image_levels) */
	/* the saturation scan of sat_src (NULL: none), on its own thread when sat_running */
	const kg_image *sat_src;
	pthread_t sat_tid;
	int sat_running, sat_done, sat_applied, sat_ret;
	kg_saturation sat;
	kg_err sat_err;
	double quantum; /* step between the source's integer codes (0: float or demosaiced) */
	/* Values times count_scale land near integers, distinct values on distinct ones
	 * (integer codes, and the halves and quarters of raw codes that demosaicing
	 * averages), so the sampler can count them; 0 for float images. */
	float count_scale;
	int threads;
	/* The patch sampler's scratch, one set per thread, kept from one sampling of the
	 * image to the next (the tagless detector samples it up to 8 times), so its pages
	 * are faulted in once; freed by chart_image_free. */
	sample_buffers sample_bufs[MAX_THREADS];
} work_image;

/* Pixels x0, x0 + step, ... (n of them) of row y, interleaved: a pointer into the
 * image, or into scratch (n * 3 floats) where they had to be gathered or demosaiced. */
const float *chart_image_span(const work_image *wi, int y, int x0, int n, int step,
                              float *scratch);
/* The whole frame demosaiced, for the stages that need every pixel. */
int chart_demosaic_all(work_image *wi, kg_err *err);
/* wi for img: its clip level, its CFA's demosaicing; the saturation scan started (on
 * a thread of its own when opt->threads > 1). */
int chart_prepare_image(const kg_image *img, const kg_chart_detect_options *opt,
                        work_image *wi, kg_err *err);
/* The saturation scan finished (waited for) and its clip levels (clip_ch, sat_note)
 * applied: before anything is sampled. */
int chart_image_levels(work_image *wi, kg_err *err);
/* The scan waited for, the demosaiced copy freed. */
void chart_image_free(work_image *wi);

/* ---- chart_grey.c -------------------------------------------------------------- */

double chart_white_level(const work_image *wi);
unsigned char *chart_grey8(const work_image *wi, int step, int *gw, int *gh,
                           double *scale_out);
#if HAVE_APRILTAG
int chart_block_weights(const work_image *wi, float w[4]);
unsigned char *chart_grey8_binned(const work_image *wi, const float w[4], int *bw, int *bh);
#endif

/* ---- the layout ---------------------------------------------------------------- */

typedef struct layout_view {
	const char *name;
	const char *family;
	int ntags;
	const int *tag_ids;
	const double (*tag_corners)[4][2]; /* mm, apriltag order */
	int npatches;
	char *const *patch_ids;
	const double (*patch_center)[2];
	const double (*patch_size)[2];
	double outline[4][2]; /* mm, the bounding box of tags and patches */
} layout_view;

/* ---- chart_tags.c -------------------------------------------------------------- */

int chart_detect_with_tags(const layout_view *L, work_image *wi,
                           const kg_chart_detect_options *opt, kg_chart_result *r,
                           kg_err *err);

/* ---- chart_sample.c, chart_select.c, chart_count.c ------------------------------ */


int chart_buffers_reserve(sample_buffers *b, long n, long row);
void chart_buffers_free(sample_buffers *b);
void chart_robust_stats(float *v, float *work, uint32_t *scratch, long n,
                        const kg_chart_detect_options *opt, double quantum, int fast,
                        double *loc, double *sigma);
int chart_count_values(const float *v, long n, float scale, sample_buffers *b);
void chart_counted_stats(const sample_buffers *b, long n, const kg_chart_detect_options *opt,
                         double quantum, double *loc, double *sigma);
long chart_counted_above(const sample_buffers *b, double t);
int chart_sample_all_with(const layout_view *L, work_image *wi,
                          const kg_chart_detect_options *opt, int fast, int stride,
                          kg_chart_result *r, kg_err *err);
int chart_sample_all(const layout_view *L, work_image *wi,
                     const kg_chart_detect_options *opt, kg_chart_result *r, kg_err *err);

/* ---- chart_tagless.c, chart_orient.c, chart_refine.c ------------------------------ */

int chart_detect_tagless(const kg_chart_layout *l, const layout_view *L, work_image *wi,
                         const kg_chart_detect_options *opt, kg_chart_result *r, kg_err *err);
int chart_tagless_fallback(const kg_chart_layout *l, const kg_chart_result *r, int ret);
/* kg_chart_warm_up when the tagless detector would start with mcc on an image of
 * width x height (one too small for the patch-grid finder's reduced copy). */
void chart_tagless_warm_up(const kg_chart_layout *l, const kg_chart_detect_options *opt,
                           int width, int height);
/* chart_orient.c: the ColorChecker 24's patches in a layout (idx[k]: the layout's index
 * of A01..D06 row by row; 0 when the layout does not have exactly these 24) and
 * X-Rite's published colour of its k-th patch, linear sRGB. */
int chart_colorchecker24_patches(const kg_chart_layout *l, int idx[24]);
void chart_cc24_linear(int k, double lin[3]);
void chart_unit3(const double v[3], double u[3]);
/* sin^2 of the angle between u (unit) and M e, 1 when M e points away from u. */
double chart_colour_sin2(const double M[9], const double e[3], const double u[3]);
/* M (3 x 3) and per-patch scales s_i (s: n of scratch) minimising sum |u_i - s_i M e_i|^2
 * over the patches i < n with use[i], by alternating least squares from the plain
 * regression of u on e (u, e unit vectors): the colours up to any camera primaries,
 * white balance and light level per patch. The mean sin^2 of the angles left (1 when
 * no fit). */
double chart_colour_fit(int n, const double (*u)[3], const double (*e)[3], const int *use,
                        double *s, double M[9]);
/* How much colour the directions u_i (unit, i < n with use[i]) have: the RMS sine of
 * their angles from their mean direction (0 for a grey picture). */
double chart_direction_spread(int n, const double (*u)[3], const int *use);
/* chart_colours.c: every patch against its layout's expected colour (a patch that does
 * not fit is flagged KG_CHART_FLAG_MISFIT) and the chart's light against a step
 * between its patches (refused, KG_EINVAL). */
int chart_check_colours(const kg_chart_layout *l, kg_chart_result *r, kg_err *err);

#if KG_HAVE_MCC
void chart_mcc24_box_mm(const layout_view *L, const int idx[24], double box[4][2]);
double chart_quad_signed_area(const double q[4][2]);
void chart_samples_free(kg_chart_sample *p, int n);
double chart_orientation_score(const kg_chart_sample *p, const int idx[24], int *used);
double chart_colour_spread(const kg_chart_sample *p, const int idx[24]);
float *chart_decimate_image(const work_image *wi, int f, int *w, int *h);
/* chart_grid.c: up to max boxes (as chart_mcc24_box_mm's, in px of img) of 6 x 4 grids
 * of uniform patches in img (w x h x C floats, white its white level), the most
 * patches first; costs: the patch centres' RMS off the grid in pitches; counts: the
 * patches found of 24. The number found. */
int chart_grid_find(const float *img, int w, int h, int C, double white, int max,
                    double (*boxes)[4][2], double *costs, int *counts);
/* The same on an 8-bit perceptually encoded grey picture (w x h) averaged over q x q
 * blocks (its size in *rw x *rh; the boxes in its px). */
int chart_grid_find_grey8(const unsigned char *grey, int w, int h, int q, int max,
                          double (*boxes)[4][2], double *costs, int *counts, int *rw, int *rh);
/* The same on a luminance already perceptually encoded on 0..1 (w x h). */
int chart_grid_find_encoded(const float *g, int w, int h, int max, double (*boxes)[4][2],
                            double *costs, int *counts);
int chart_refine_on_edges(const work_image *wi, const layout_view *L, const int idx[24],
                          double white, double H[9], double *rms);
#endif

#endif
