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

/* One side of a pairing (pairing.c): a file's patch ids and colours, as the first file
 * (known colours: the spectra's XYZ, the reference's rho0) or the second (a camera's
 * values of the same chart). */
typedef struct calib_pair_side {
	const char *file;           /* named in messages */
	const char *role;           /* its name in --id-pairing values ("spectra", "rgb") */
	const char *what;           /* what its colours are ("the spectra's XYZ under D65") */
	char *const *ids;
	int n;
	double (*colour)[3];        /* n, owned */
	unsigned char *skip;        /* n, owned: 1 left out of the colour check */
} calib_pair_side;

/* A side with a copy of n colours (file, role, what and ids are borrowed) and nothing
 * skipped; free with calib_pair_side_free. */
int calib_pair_side_new(const char *file, const char *role, const char *what,
                        char *const *ids, int n, const double (*colour)[3],
                        calib_pair_side *s, kg_err *err);
/* Skip the patches whose ids are listed and, when `camera` (the side's own patch set)
 * is given, those it flags (a FLAGS column != 0) or has clipped (a channel >= clip, or
 * at or below 0: no signal). */
void calib_pair_side_skip(calib_pair_side *s, const char *const *exclude, int nexclude,
                          const kg_patchset *camera, double clip);
void calib_pair_side_free(calib_pair_side *s);
/* The pairing's map alone: map[i] the second side's patch paired with the first's i-th
 * (-1 none); the number paired, -1 out of memory. */
int calib_pair_map(const calib_pair_side *a, const calib_pair_side *b, kg_id_pairing how,
                   int *map, const char **alias);

typedef struct calib_pair_result {
	int *match;        /* a->n entries: the second file's patch, or -1 */
	int npairs;
	const char *alias; /* kg_patch_ids_match's rule when NAMES paired through it */
	int nchecked;      /* pairs judged by colour */
	double misfit;     /* NAN when fewer than KG_CALIB_PAIR_MIN_CHECK */
} calib_pair_result;

/* Pair a's patches with b's as `how` says and check the pairs by colour
 * (KG_CALIB_PAIR_MAX_MISFIT, KG_CALIB_PAIR_MIN_GAIN); KG_EINVAL naming both files,
 * their ids' conventions and the pairing that fits (stated with `option`, or NULL
 * when the caller has none). With `whole`, a misfit above the limit is refused
 * whatever its cause, and single patches are checked; without, only a misfit that
 * another pairing read from the ids explains is refused (the caller judges the whole
 * chart itself, as calib camera's relative residual does, and then its single patches
 * with calib_pair_check_patches). Pairs whose camera values do not span three
 * colours, or fewer than KG_CALIB_PAIR_MIN_CHECK, are not judged (misfit NAN). *r is
 * filled on success; free with calib_pair_result_free. */
int calib_pair_check(const calib_pair_side *a, const calib_pair_side *b, kg_id_pairing how,
                     int whole, const char *option, calib_pair_result *r, kg_err *err);
/* The single-patch check of a pairing calib_pair_check made (KG_CALIB_PAIR_MIN_GAIN). */
int calib_pair_check_patches(const calib_pair_side *a, const calib_pair_side *b,
                             const calib_pair_result *r, const char *option, kg_err *err);
/* The same as words for another refusal ("N patches fit other patches' colours ...");
 * the number of patches (0: buf ""), -1 out of memory. */
int calib_pair_moved(const calib_pair_side *a, const calib_pair_side *b,
                     const calib_pair_result *r, const char *option, char *buf, size_t size);
void calib_pair_result_free(calib_pair_result *r);
/* Fill rec's unpaired lists (the patches of a and of b that r left without a partner)
 * and its counts. */
int calib_pair_record(const calib_pair_side *a, const calib_pair_side *b,
                      const calib_pair_result *r, kg_id_pairing how, kg_pairing_record *rec,
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
