/* Private to calib/: shared between its files, never included from outside. */
#ifndef KG_CALIB_PRIVATE_H
#define KG_CALIB_PRIVATE_H

#include "kg_calib.h"

/* Free an array of n strings (and the array). */
void calib_strv_free(char **v, int n);
/* Copy an array of n strings; NULL on allocation failure. */
char **calib_strv_dup(char *const *v, int n);

/* Append ids to buf as "A1, A2, ..." (at most `max` of them, then "and N more"). */
void calib_list_ids(char *buf, size_t len, char *const *ids, const int *which, int n,
                    int max);

/* Condition numbers of rgb (n x 3 taken as 3 x n), raw and with each channel scaled
 * to unit RMS (+inf when rank deficient), and the singular values of both. */
int calib_rgb_conditioning(const double (*rgb)[3], int n, double *cond,
                           double *cond_equilibrated, double sv[3], double sv_eq[3],
                           kg_err *err);

/* Value checks on the patches of a chart (what: e.g. "site.cgats"): non-finite,
 * clipped (any channel >= clip_level, or clipped_fraction[i] > 0 when that array is
 * given) and near-black (brightest channel < black_level; black_level <= 0 skips
 * it). The message names every offending patch. */
int calib_check_patch_values(const char *what, char *const *ids, const double (*rgb)[3],
                             const double *clipped_fraction, int n, double clip_level,
                             double black_level, kg_err *err);

/* Refuse a chart whose equilibrated condition number exceeds max_cond, naming the
 * patches and how close their chromaticities are. */
int calib_check_collinear(const char *what, char *const *ids, const double (*rgb)[3],
                          int n, double max_cond, double *cond, double *cond_eq,
                          double sv[3], kg_err *err);

/* The clipped-fraction column of a patch set (an extra column whose name contains
 * "CLIP", case-insensitive), or NULL. */
const double *calib_clipped_column(const kg_patchset *ps, int *stride);

int calib_source_add(kg_calib_source **sources, int *n, const char *role,
                     const char *path, kg_err *err);
void calib_sources_free(kg_calib_source **sources, int *n);
int calib_sources_copy(const kg_calib_source *src, int n, kg_calib_source **out,
                       kg_err *err);

/* CIEDE2000 between reflectances under D65 (CIE 1931 2 degree observer). */
typedef struct calib_d65 {
	kg_xyz_weights w;
	kg_xyz white;
} calib_d65;

int calib_d65_init(calib_d65 *d, kg_err *err);
double calib_de00(const calib_d65 *d, const kg_spectrum *a, const kg_spectrum *b);

/* A copy of ps without the patches whose ids are listed (all columns kept). */
int calib_patchset_without(const kg_patchset *ps, const char *const *ids, int nids,
                           kg_patchset **out, kg_err *err);

/* Quantities that follow from the stored ones (after a fit or a load): the pca
 * kernel's weight offset, and for a camera the weight matrix M M2. */
void calib_reference_derive(kg_reference *ref);
void calib_camera_derive(kg_camera_calib *cam);

/* The patches of layout l sampled in img through H (mm -> px), as kg_chart_detect
 * samples them, by the optimised sampler (reference 0: scanline spans, radix
 * selection, opt->threads threads) or the reference (1: every pixel of each region's
 * bounding box through the inverse homography, quickselect): both must give the same
 * result. The result holds H, the patches and their outline, nothing else. */
int calib_chart_sample(const kg_chart_layout *l, const kg_image *img, const double H[9],
                       const kg_chart_detect_options *opt, int reference,
                       kg_chart_result **out, kg_err *err);

/* The median of v[0..n) (v sorted in place: for a few dozen values); NaN when n is 0. */
double calib_median(double *v, int n);

/* Solve the m x m system N c = b (N row-major with row stride `stride`, b: both
 * overwritten) by Gaussian elimination with partial pivoting; 1 when singular. */
int calib_solve_normal(double *N, int stride, double *b, int m, double *c);

/* Estimate the light over the chart from the patches' quadrant means (each patch's
 * own gradient), divide every patch's values by it, judge the "non-uniform" flag on
 * what the field does not explain, and fill r->light (calib/light_field.c). A field
 * varying more than opt->max_light_variation is refused (KG_EINVAL). */
int calib_light_field_apply(kg_chart_result *r, const kg_chart_detect_options *opt,
                            kg_err *err);
/* Refuse a patch file (CGATS) whose IMAGE_ENCODING is "jpeg-unstated": patches of a
 * JPEG read without a stated encoding (kogei chart detect --encoding). */
int calib_check_encoding(const char *path, kg_err *err);

#endif
