/* calib/: the reference calibration (once, in the lab) and the site calibration
 * (every session) of docs/architecture.md, "The method", steps 1-2, and the JSON files
 * that carry them.
 *
 * Reference calibration. A chart of m patches gives spectra S (m x 61) and the
 * reference camera's linear RGB rho (m x 3), matched by SAMPLE_ID. Five ways of
 * turning camera RGB into a spectrum are fitted on it, all of the form
 *
 *     s = offset + A x(rho)          A: 61 x T, x: the method's T regression terms
 *
 *   pca        the paper: B = the K leading right singular vectors of S (the
 *              eigenvectors of S^T S), weights W = S B, M = W^T rho (rho^T rho +
 *              ridge I)^-1, so A = B M. Centred (an option): B from the covariance,
 *              w = M (rho - mean rho) and s = mean s + B w, an affine map.
 *   linear     direct regression A = S^T rho (rho^T rho + ridge I)^-1.
 *   wiener     Wiener estimation with a noise prior, in its data-driven form:
 *              A = E[s rho^T] (E[rho rho^T] + sigma^2 I)^-1 with the expectations
 *              taken over the chart, i.e. A = S^T rho (rho^T rho + m sigma^2 I)^-1.
 *              (The model-based form K_s C^T (C K_s C^T + sigma^2 I)^-1 needs the
 *              camera's sensitivities C and the illuminant, which a chart alone
 *              does not give.) sigma is the camera noise on the 0..1 scale.
 *   rootpoly2  root-polynomial regression (Finlayson, Mackiewicz & Hurlbert 2015),
 *              terms r, g, b, sqrt(rg), sqrt(gb), sqrt(rb);
 *   rootpoly3  the same with the degree-3 terms as well (13 terms, see
 *              kg_method_terms). Both scale with exposure like the linear methods.
 *
 * Validation is leave-one-out (remove one patch, refit, predict it), by the mean
 * spectral RMSE on the chart: K for `--basis auto` and the method for `--method
 * auto` are the simplest within 1 % (+1e-6) of the best. The regression methods
 * are solved through the SVD of their m x T design matrix X (the degree-3 root
 * terms are nearly collinear, and X^T X would square that), and their leave-one-out
 * predictions follow in closed form from the leverages, s_i - r_i / (1 - h_ii),
 * with lambda held fixed. PCA refits on the chart's moments without the patch (a
 * 61 x 61 eigen-decomposition and a 3 x 3 solve per patch and every K).
 *
 * Site calibration. Another camera photographs the field chart (k patches): rho_r.
 * M2 = rho0 pinv(rho_r) (3 x 3) maps its RGB into the reference camera's, so a site
 * pixel gives s = offset + A x(M2 rho). Charts that cannot determine M2 are refused
 * with the cause (kg_camera_fit).
 *
 * Matrices are row-major doubles. */
#ifndef KG_CALIB_H
#define KG_CALIB_H

#include "kg_estimate.h"

#define KG_CALIB_MAX_BASIS 8  /* largest K */
#define KG_CALIB_MAX_TERMS 13 /* regression terms of rootpoly3 */

typedef enum kg_method {
	KG_METHOD_AUTO = -1, /* only in options: the lowest leave-one-out error */
	KG_METHOD_PCA = 0,
	KG_METHOD_LINEAR,
	KG_METHOD_WIENER,
	KG_METHOD_ROOTPOLY2,
	KG_METHOD_ROOTPOLY3,
	KG_METHOD_COUNT
} kg_method;

/* "pca", "linear", "wiener", "rootpoly2", "rootpoly3" ("auto" for KG_METHOD_AUTO). */
const char *kg_method_name(kg_method m);
/* Parse a name above (auto allowed). KG_EINVAL with the list of names otherwise. */
int kg_method_parse(const char *name, kg_method *out, kg_err *err);
/* Number of regression terms T of a method (3, 6 or 13). */
int kg_method_nterms(kg_method m);
/* The kernel family of estimate/ that evaluates a method's terms. */
kg_est_method kg_method_est(kg_method m);
/* The regression terms x(rgb) of a method, T of them, exactly as estimate/'s kernels
 * form them (kg_est_terms): r, g, b, sqrt(rg), sqrt(gb), sqrt(rb), then for degree
 * 3: cbrt(r g^2), cbrt(g b^2), cbrt(r b^2), cbrt(g r^2), cbrt(b g^2), cbrt(b r^2),
 * cbrt(rgb). Negative channels count as 0 in the root terms. */
void kg_method_terms(kg_method m, const double rgb[3], double *x);
/* Names of the terms ("r", "sqrt(rg)", ...). */
const char *kg_method_term_name(kg_method m, int i);

/* One fitted method: s = offset + A x(rho). */
typedef struct kg_spectral_map {
	kg_method method;
	int available;      /* 0: the chart could not support it (see note) */
	char note[160];     /* why it is unavailable, else "" */
	int nterms;         /* T */
	double A[KG_NBANDS * KG_CALIB_MAX_TERMS]; /* 61 x T, row-major */
	double offset[KG_NBANDS];                 /* zero except centred pca */
	double lambda;      /* ridge added to X^T X (wiener: m sigma^2) */
	double cond;        /* condition number of X (m x T; pca: of rho, centred
	                     * when centred) */
	double fit_rmse;    /* mean spectral RMSE over the chart, in sample */
	double loo_rmse;    /* mean leave-one-out spectral RMSE (NAN if not run) */
	double loo_de00;    /* mean leave-one-out CIEDE2000 under D65 (NAN if not run) */
	double loo_band[KG_NBANDS]; /* per band, the RMS over the chart of the held-out
	                             * estimate's error: the method's spectral uncertainty
	                             * (NAN if not run) */
	double neutral_tilt; /* the spectral shape the map gives a flat neutral: the largest
	                      * relative departure from its own mean of the estimate of a
	                      * flat 0.2 and a flat 0.8 reflectance, whose readings come from
	                      * the reference camera's response (NAN if not known) */
} kg_spectral_map;

/* Above this neutral tilt, estimated spectra carry shape the chart cannot support
 * (kogei process warns). */
#define KG_CALIB_MAX_NEUTRAL_TILT 0.05
/* The flat greys of the neutral prior: reflectances 0.05, 0.2, 0.5 and 0.9. */
#define KG_CALIB_NEUTRAL_LEVELS 4

/* Spectrum of one RGB through a map (no clamping). */
void kg_spectral_map_apply(const kg_spectral_map *map, const double rgb[3],
                           kg_spectrum *out);

/* ---- the reference camera's spectral response (response.c) --------------------- */

/* The reading of a reflectance s under the chart's light, rho_c = sum_l F[c][l] s(l):
 * sensitivity times light per channel, learned from the training chart as the
 * smoothest response that fits it (a second-difference penalty whose weight per
 * channel minimises the leave-one-out error). It predicts, in the reference camera's
 * space, the reading of materials the chart does not hold. */
typedef struct kg_response {
	int available;          /* 0: none (a file from before it existed) */
	char source[16];        /* "chart" (learned) or "camera" (sensitivities) */
	double F[3][KG_NBANDS];
	double lambda[3];       /* the penalty weight chosen per channel */
	double loo_rmse[3];     /* leave-one-out RMSE of the chart's readings, per channel */
	double loo_relative;    /* the same over all channels, relative to the readings */
	int patches;            /* of the chart it was learned from */
} kg_response;

/* Learn the response from a chart's spectra and readings (3 or more patches). */
int kg_response_fit(const kg_patchset *train, kg_response *out, kg_err *err);
/* The response from the camera's spectral sensitivities times the chart's light
 * (weight, any scale): each channel's scale (the exposure) fitted to the chart's
 * readings by least squares; loo_rmse the leave-one-out error of that fit, lambda 0,
 * source "camera". */
int kg_response_from_camera(const kg_spectrum weight[3], const kg_patchset *train,
                            kg_response *out, kg_err *err);
/* A reflectance's reading (61 values in, 3 out). */
void kg_response_apply(const kg_response *r, const double *spectrum, double rgb[3]);
/* The neutral tilt of a map (kg_spectral_map): white is the camera's value of the
 * perfect diffuser (a flat grey t reads t white); NAN when a channel of white is not
 * above 0. */
double kg_spectral_map_neutral_tilt(const kg_spectral_map *map, const double white[3]);

/* ---- pairing two patch files by SAMPLE_ID (pairing.c) ---------------------------- */

/* How the patches of two files of one chart are paired: a file of known colours (the
 * spectra, or the reference's rho0: "first") and a camera's values of the same chart
 * ("second"). NAMES pairs by SAMPLE_ID as written, else through kg_patch_ids_match's
 * aliases (A1 = A01; chartread's 1..24 = A1..D6). The others re-pair on purpose, for a
 * file whose ids follow another convention; letter + number ids (A01, a1, A0) are
 * read as a grid, plain numbers as one line:
 *   FILE_ORDER    the n-th patch of one file with the n-th of the other
 *   GRID_ORDER    both files' ids sorted by letter, then number, and paired in that
 *                 order (A00..D05 with A01..D06; 1..24 with A01..D06)
 *   FIRST_BY_NUMBER, SECOND_BY_NUMBER  that file's ids sorted by number, then letter
 *                 (A1, B1, C1, .., A2, ..: column letters, or a chart numbered down
 *                 its columns), the other's by letter, then number
 *   NUMBER_UP, NUMBER_DOWN  the first file's X<n> with the second's X<n+1> (X<n-1>)
 *   LETTER_UP, LETTER_DOWN  the first file's A<n> with the second's B<n> (the
 *                 letter before) */
typedef enum kg_id_pairing {
	KG_ID_PAIRING_NAMES = 0,
	KG_ID_PAIRING_FILE_ORDER,
	KG_ID_PAIRING_GRID_ORDER,
	KG_ID_PAIRING_FIRST_BY_NUMBER,
	KG_ID_PAIRING_SECOND_BY_NUMBER,
	KG_ID_PAIRING_NUMBER_UP,
	KG_ID_PAIRING_NUMBER_DOWN,
	KG_ID_PAIRING_LETTER_UP,
	KG_ID_PAIRING_LETTER_DOWN,
	KG_ID_PAIRING_COUNT
} kg_id_pairing;

/* The name of a pairing as a command states it: "names", "file-order", "grid-order",
 * "<first>-by-number", "<second>-by-number", "number+1", "number-1", "letter+1",
 * "letter-1", where first and second are the files' roles in that command ("spectra"
 * and "rgb" for calib reference, "reference" and "rgb" for calib camera). */
void kg_id_pairing_name(kg_id_pairing p, const char *first, const char *second, char *buf,
                        size_t size);
/* Parse such a name; KG_EINVAL listing the names otherwise. */
int kg_id_pairing_parse(const char *name, const char *first, const char *second,
                        kg_id_pairing *out, kg_err *err);

/* The check that paired patches are the same patches (kg_calib_pair_checked,
 * kg_camera_fit). The known colours (the spectra's XYZ under D65, or the reference
 * camera's rho0) are fitted to the camera's values through the 3 x 3 matrix that fits
 * them best, each patch's error taken relative to its own colour (plus a floor of 5 %
 * of the brightest patch, for dark patches' noise and flare): the misfit is the RMS of
 * these errors over the n pairs, sqrt(sum e^2 / (n - 3)). Measured (ColorChecker 24,
 * babelcolor spectra unless said): correct pairings leave 1.7 % (kogei sim patches of
 * the demo's reference camera), at most 10.5 % over 1200 simulated charts (52 + 28
 * published cameras under D65, D50 and A; ColorChecker babelcolor and Ohta, PMC 30,
 * CIE test colours, CIE 2017 CES 99; noise 20000:5:12), 7-12 % on four real raw
 * photographs, 26 % on a camera JPEG linearised as sRGB; wrong pairings 48 % and more
 * (zero-based ids, column letters, column-major, rows shifted, the chart turned, and
 * 200 random re-pairings of each of those photographs). Above the limit the pairing is
 * refused, with the other pairings of kg_id_pairing that fit, if any. */
#define KG_CALIB_PAIR_MAX_MISFIT 0.35
/* Fewer patches than this in common are not checked by colour (M has 9 unknowns). */
#define KG_CALIB_PAIR_MIN_CHECK 6
/* Single patches: under the matrix fitted robustly (least median of squares over
 * triples of patches, then least squares on the patches it fits, whose RMS error is
 * sigma), the one-to-one re-pairing of camera values with known colours that fits
 * best (Hungarian assignment). A cycle of patches it moves (two swapped, a row read
 * one patch late) whose errors fall in sum by more than this and by more than
 * 3 sigma sqrt(its length) is refused, naming the patches whose error falls, unless
 * such cycles move half the patches or more (then the whole pairing is wrong, and
 * KG_CALIB_PAIR_MAX_MISFIT judges it). Correct
 * pairings: 0 on every simulated chart above and on the raw photographs, 0.07 on the
 * linearised JPEG; any two ColorChecker patches swapped: 0.18 and more in simulation,
 * 271-276 of the 276 swaps above it on the real photographs. */
#define KG_CALIB_PAIR_MIN_GAIN 0.15

/* What a pairing was, for the calibration file: the rule, the patches paired and
 * checked, the misfit, and the patches of each file that found no partner. */
typedef struct kg_pairing_record {
	kg_id_pairing rule;
	int pairs;            /* patches paired */
	int checked;          /* of them, judged by colour (not flagged, excluded, clipped) */
	double misfit;        /* NAN when fewer than KG_CALIB_PAIR_MIN_CHECK were judged */
	int nunpaired[2];     /* first file, second file */
	char **unpaired[2];
} kg_pairing_record;

void kg_pairing_record_free(kg_pairing_record *rec);

typedef struct kg_pair_options {
	kg_id_pairing pairing;       /* default NAMES */
	const char *const *exclude;  /* ids (of either file) left out of the colour check */
	int nexclude;
	const char *option;          /* the command's option that states a pairing
	                              * ("--id-pairing"), named in refusals; NULL: none */
} kg_pair_options;

/* ---- reference calibration --------------------------------------------------- */

typedef struct kg_reference_options {
	int basis;          /* K in 1..8, or 0: chosen by leave-one-out (1..min(m-1, 8)) */
	int centred;        /* mean-centred PCA with an affine M */
	double ridge;       /* lambda >= 0 for pca, linear and root-polynomial */
	double noise_sigma; /* wiener's camera noise (0..1 scale), > 0 */
	kg_method method;   /* the default method of the file; AUTO: lowest LOO error */
	double max_cond;    /* collinearity limit for both charts (see kg_camera_fit) */
	const char *const *exclude; /* ids left out of both charts, or NULL */
	int nexclude;
	/* The reference camera's sensitivities times the chart's light (3 spectra), or
	 * NULL: the response is then learned from the chart (kg_response_fit). */
	const kg_spectrum *camera_weights;
	kg_id_pairing id_pairing; /* how the spectra's and RGB's patches pair (NAMES) */
	const char *id_pairing_option; /* the option stating it ("--id-pairing"), named
	                                * in refusals; NULL: the caller has none */
	double max_flare; /* the largest flare (fraction of white, any channel) a chart may
	                   * carry; above it the fit is refused (calib/flare.c); 0: the
	                   * default KG_CALIB_MAX_FLARE; INFINITY: no limit */
	int no_flare;     /* 1: never remove flare (it is still measured and reported) */
	int no_neutral_prior; /* 1: never add flat greys to the fit (kg_reference's
	                       * neutral_prior) */
} kg_reference_options;

/* The default flare limit: 8 % of white. Daylight and booth frames of real charts
 * carry 1.4-3.7 % (their neutral rows meet zero there); a chart facing the sky 10 %,
 * where the best fit still misses by 5 dE00 held out. */
#define KG_CALIB_MAX_FLARE 0.08

/* Flare (veiling glare) of a chart's frame, from its neutral patches (chroma C*ab < 5
 * under D65 of their spectra): per channel, the straight line camera value = offset +
 * slope Y through them (Y the luminance factor, 0..1). found: at least three neutrals
 * from dark to light (the lightest at least 4x the darkest) with a rising line. */
#define KG_FLARE_MAX_NEUTRALS 32
typedef struct kg_flare {
	int found;
	int n;                                  /* neutrals used */
	char ids[KG_FLARE_MAX_NEUTRALS][64];
	double offset[3];                       /* camera values at Y = 0 */
	double slope[3];                        /* camera value of the perfect diffuser */
	double white_fraction[3];               /* offset / slope */
	double residual[3];                     /* rms scatter about the line, / slope */
} kg_flare;

/* The flare of the camera values of `field` (NULL: train's own) at train's neutral
 * patches (train holds the spectra; field is paired to it by id), but the excluded ids
 * and the patches chart detection flagged (a FLAGS column != 0: a clipped white would
 * bend the line). Not found (f->found
 * 0, no error) without spectra or enough neutrals. */
int kg_flare_estimate(const kg_patchset *train, const kg_patchset *field,
                      const char *const *exclude, int nexclude, kg_flare *f, kg_err *err);
/* The largest white_fraction of the three channels (0 when not found). */
double kg_flare_max_fraction(const kg_flare *f);
/* A copy of ps with the flare's offset subtracted from its camera values (at least 0). */
int kg_flare_remove(const kg_patchset *ps, const kg_flare *f, kg_patchset **out, kg_err *err);

/* K = 3, uncentred, ridge 0, noise_sigma 0.01, method pca, max_cond
 * KG_CALIB_MAX_COND. */
void kg_reference_options_default(kg_reference_options *o);

/* Where an input came from: path, sha256 and the CGATS keywords (devices,
 * illuminant, dates ...) as name/value pairs. */
typedef struct kg_calib_source {
	char *role;   /* "spectra", "rgb", "field_rgb", "site_rgb", "reference" */
	char *path;
	char sha256[65]; /* "" when not computed */
	int nkeywords;
	char **keyword_names;
	char **keyword_values;
} kg_calib_source;

/* --basis auto and --method auto take the simplest candidate whose mean LOO RMSE is
 * within this fraction (+1e-6) of the best. */
#define KG_CALIB_K_TOLERANCE 0.01

typedef struct kg_reference {
	/* the PCA model */
	int K;
	int centred;
	int basis_auto;                             /* K was chosen by LOO */
	double B[KG_NBANDS * KG_CALIB_MAX_BASIS];   /* 61 x K, row-major (stride K) */
	double mean[KG_NBANDS];                     /* mean spectrum (centred), else 0 */
	double M[KG_CALIB_MAX_BASIS * 3];           /* K x 3 */
	double rgb_mean[3];                         /* mean rho (centred), else 0 */
	double weight_offset[KG_CALIB_MAX_BASIS];   /* -M rgb_mean: w = M rho + this */
	double singular_values[KG_CALIB_MAX_BASIS]; /* leading singular values of S
	                                             * (or of centred S) */
	double energy[KG_CALIB_MAX_BASIS];          /* cumulative fraction of sum s^2 */
	double loo_by_K[KG_CALIB_MAX_BASIS];        /* mean LOO RMSE for K = 1.. (NAN
	                                             * beyond what was evaluated) */
	int nK;                                     /* entries of loo_by_K evaluated */

	/* every method, fitted on the same chart */
	kg_spectral_map maps[KG_METHOD_COUNT];
	kg_method method;     /* the default one */
	int method_auto;      /* it was chosen by LOO */
	double ridge, noise_sigma;

	/* training chart */
	int m;
	char **ids;
	double (*train_rgb)[3];
	double *rmse;              /* per patch, the default method, in sample */
	double *gfc;
	double *de00;              /* CIEDE2000 under D65, CIE 1931 2 degree */
	double *projection_rmse;   /* ||s - B B^T s|| / sqrt(61) (centred: about mean) */
	double *weight_residual;   /* ||W_i - M rho_i|| (pca) */
	double cond_rho;           /* condition number of rho (m x 3) */

	/* field chart: the reference camera's rho0 */
	int k;
	char **field_ids;
	double (*rho0)[3];         /* k x 3 (written 3 x k in JSON) */
	double cond_rho0;

	kg_response response;      /* the reference camera's, from the training chart */

	int nsources;
	kg_calib_source *sources;
	char id_rule[256];         /* how the spectra's and RGB's ids were paired when not
	                            * as written (kg_patch_ids_match), else "" */
	int nflagged;              /* field patches left out because chart detection
	                            * flagged them (FLAGS column != 0) */
	char **flagged_ids;
	unsigned *flagged_flags;   /* their FLAGS (KG_CHART_FLAG_*) */
	kg_pairing_record pairing; /* first: the spectra, second: the RGB file */
	kg_flare flare;            /* the training chart's flare, measured */
	kg_flare field_flare;      /* the field chart's (== flare when it is the same) */
	int flare_removed;         /* subtracted from the training RGB and rho0 before the
	                            * fit, because that validated better */
	double flare_loo_kept;     /* the chosen method's mean LOO dE00 with flare kept */
	double flare_loo_removed;  /* ... with it removed (NAN when not tried) */
	/* Flat greys added to the fit when the chosen method gave a flat grey more shape
	 * than KG_CALIB_MAX_NEUTRAL_TILT (the chart holds too few neutrals to say a grey
	 * is flat): each of KG_CALIB_NEUTRAL_LEVELS levels, its reading through the
	 * response, counted `neutral_weight` times; validation stays on the chart's own
	 * patches. */
	double neutral_white[3];   /* the camera's value of the perfect diffuser, for the
	                            * neutral tilt: the line through the chart's neutral
	                            * patches at Y = 1 when it has three or more from dark
	                            * to light, else the response's reading of a flat 1 */
	char neutral_white_source[16]; /* "neutrals" or "response" */
	int neutral_prior;         /* 1: added (only without neutral patches) */
	int neutral_weight;        /* times each level counts (0: not added) */
	double neutral_tilt_before; /* the chosen method's tilt without them (NAN: none) */
	double neutral_loo_before; /* its mean LOO dE00 without them (NAN: not tried) */
	kg_method neutral_method_before; /* the method chosen without them */
} kg_reference;

/* Pair spectra and RGB by SAMPLE_ID into one patch set (spectra + rgb), in the order
 * of `spectra`, with the RGB file's ids. Ids pair as opt->pairing says (NULL options:
 * by name, kg_id_pairing). Refused (KG_EINVAL, naming both files): duplicate ids, no
 * patch in common, fewer than half of the smaller file's patches paired, and a pairing
 * whose colours do not fit (the spectra's XYZ under D65 against the camera values,
 * KG_CALIB_PAIR_MAX_MISFIT and KG_CALIB_PAIR_MIN_GAIN; patches the RGB file flags in a
 * FLAGS column, clipped ones and opt->exclude are left out of that check): the message
 * says how each file names its patches and which other pairing fits, if one does.
 * Patches without a partner are left out and listed in *rec (may be NULL; free with
 * kg_pairing_record_free); *rule (may be NULL) gets the alias rule used (NULL: ids
 * as written or another pairing). */
int kg_calib_pair_checked(const kg_patchset *spectra, const kg_patchset *rgb,
                          const kg_pair_options *opt, kg_patchset **out,
                          kg_pairing_record *rec, const char **rule, kg_err *err);
/* kg_calib_pair_checked by name, no record. */
int kg_calib_pair(const kg_patchset *spectra, const kg_patchset *rgb, kg_patchset **out,
                  kg_err *err);

/* Fit everything on a training chart (spectra + rgb) for a field chart (rgb; may be
 * the training set itself). Patches the field chart's FLAGS column flags (chart
 * detection: clipped, glare, a colour that is not the layout's, ...) are left out of
 * both, as opt->exclude's are, and listed in flagged_ids. Refused (KG_EINVAL, naming
 * the patches): non-finite or clipped values, near-black field patches, nearly
 * collinear RGB (the site test of kg_camera_fit, on both charts), too few patches,
 * options out of range. */
int kg_reference_fit(const kg_patchset *train, const kg_patchset *field,
                     const kg_reference_options *opt, kg_reference **out, kg_err *err);
/* Read the inputs and fit: spectra from CGATS (SPEC_*) or a `patch,name,<nm>...` CSV,
 * RGB from CGATS (RGB_R RGB_G RGB_B); field_rgb_path NULL means rgb_path. Records the
 * sources (path, sha256, keywords). */
int kg_reference_fit_files(const char *spectra_path, const char *rgb_path,
                           const char *field_rgb_path, const kg_reference_options *opt,
                           kg_reference **out, kg_err *err);
void kg_reference_free(kg_reference **ref);
/* Record where a reference fitted in memory (kg_reference_fit) came from: role
 * ("spectra", "rgb", ...), path, its sha256 and, for CGATS, its keywords. */
int kg_reference_add_source(kg_reference *ref, const char *role, const char *path,
                            kg_err *err);

/* "format": "kogei-reference/1"; the keys are listed at the top of calib/json.c. */
int kg_reference_save(const kg_reference *ref, const char *path, kg_err *err);
int kg_reference_load(const char *path, kg_reference **out, kg_err *err);

/* ---- site calibration -------------------------------------------------------- */

/* Defaults of kg_camera_options. The condition number tested is that of rho_r
 * with each channel (row) scaled to unit RMS, so a channel's gain (white balance,
 * exposure) does not count as collinearity. Measured (noise-free simulation): the
 * ColorChecker 24 gives 10 (Nikon D5100 under D65, Canon 5D Mark II under A), its
 * six neutral patches alone 1900. */
#define KG_CALIB_MAX_COND 100.0
#define KG_CALIB_CLIP_LEVEL 0.98  /* a channel at or above this is clipped */
#define KG_CALIB_BLACK_LEVEL 0.01 /* a patch whose brightest channel is below is black */
#define KG_CALIB_PINV_RTOL 1e-10  /* singular values <= rtol * smax count as zero */

/* Default limit of the relative residual ||rho0 - M2 rho_r||_F / ||rho0||_F. M2 (3 x 3)
 * cannot absorb the difference between two cameras' spectral responses, so a good
 * chart leaves a few per cent: measured (ColorChecker 24, babelcolor spectra,
 * reference Nikon D5100 under D65, noise 20000:5:12) 1.5-2.0 % for eight other
 * cameras under D65 and 2.2-3.4 % under A; kogei demo 3.3 %. Patches read in the wrong
 * order give 55-80 % (the ColorChecker turned 180 degrees: 62 %, rows shifted: 79 %;
 * the CIE test colours reversed: 55 %), an object photograph's material tiles taken
 * for a ColorChecker 69 %. 10 % is three times the worst good chart and far below
 * those (docs/calib-camera.md). */
#define KG_CALIB_MAX_RESIDUAL 0.10

typedef struct kg_camera_options {
	double max_cond;
	double clip_level;
	double black_level;
	double pinv_rtol;
	double max_residual; /* relative residual above which the fit is refused */
	int force;           /* accept a chart of exactly 3 usable patches, whose residual
	                      * is 0 whatever the chart: M2 cannot be checked */
	const char *const *exclude; /* ids to leave out of the fit (both files), or NULL */
	int nexclude;
	kg_id_pairing id_pairing;   /* how the site file's patches pair with rho0's (NAMES) */
	const char *id_pairing_option; /* as in kg_reference_options */
	double max_flare; /* as in kg_reference_options (0: KG_CALIB_MAX_FLARE) */
} kg_camera_options;

void kg_camera_options_default(kg_camera_options *o);

/* The per-pixel map of a site camera for one method: s = offset + A x(P rho_site).
 * For the linear methods (pca, linear, wiener) M2 is folded in: A = A_ref M2
 * (pca: B M M2) and P = identity. For the root-polynomial ones A = A_ref, P = M2. */
typedef struct kg_site_map {
	kg_method method;
	int available;
	int nterms;
	double A[KG_NBANDS * KG_CALIB_MAX_TERMS]; /* 61 x T */
	double offset[KG_NBANDS];
	double pre[9];                            /* P, 3 x 3 */
	double lambda;                            /* the reference fit's ridge */
	double loo_rmse;                          /* the reference fit's LOO error */
} kg_site_map;

/* The camera a site calibration belongs to, as the session that photographed the
 * chart recorded it (kogei chart detect writes it into the patch file as the keywords
 * CAMERA_BACKEND, CAMERA_MODEL, CAMERA_SERIAL, CAMERA_PIXFMT, CAMERA_WHITE_LEVEL,
 * CAMERA_DEMOSAIC and CAPTURE). Backend, model and serial say which camera it is;
 * pixel format, white level and demosaicing how it was read. */
typedef struct kg_camera_identity {
	int known;          /* 0: not recorded (a chart from outside a session, older files) */
	char backend[32];   /* URI scheme: "sim", "aravis", "v4l2", ... */
	char model[128];
	char serial[128];
	char pixfmt[32];    /* "bayer16", "rgb16", ... */
	long white_level;   /* full scale in DN, 2^bits - 1 (4095 for 12 bits); 0 unknown */
	char demosaic[160]; /* the algorithm, "none" when the camera delivered RGB */
	char capture[64];   /* the session capture the chart was photographed in */
} kg_camera_identity;

/* The identity in CGATS keywords (names[i] = values[i]; the names above). known is set
 * when CAMERA_BACKEND, CAMERA_MODEL and CAMERA_SERIAL are all present; KG_EINVAL when
 * CAMERA_WHITE_LEVEL is not a whole number >= 1. `what` names the file in messages. */
int kg_camera_identity_from_keywords(const char *what, char *const *names,
                                     char *const *values, int n, kg_camera_identity *out,
                                     kg_err *err);
/* "sim camera \"simulated sensor\" serial A (bayer16, white level 4095, demosaic X)". */
void kg_camera_identity_describe(const kg_camera_identity *id, char *buf, size_t size);
/* Whether an image's camera is the calibration's. 0: the same camera (backend, model
 * and serial); *note (note_size > 0) then says which reading settings differ (pixel
 * format, white level, demosaicing), "" when none. KG_ENOENT when either identity is
 * unknown (the message says which, so nothing was checked); KG_EINVAL when they are
 * different cameras, the message naming both (calib_what, image_what: file names). */
int kg_camera_identity_check(const kg_camera_identity *calib, const char *calib_what,
                             const kg_camera_identity *image, const char *image_what,
                             char *note, size_t note_size, kg_err *err);

typedef struct kg_camera_calib {
	/* from the reference */
	int K, centred;
	double B[KG_NBANDS * KG_CALIB_MAX_BASIS]; /* 61 x K (stride K) */
	double mean[KG_NBANDS];
	double M[KG_CALIB_MAX_BASIS * 3];         /* K x 3 */
	double rgb_mean[3];
	double weight_matrix[KG_CALIB_MAX_BASIS * 3]; /* M M2 (K x 3) */
	double weight_offset[KG_CALIB_MAX_BASIS];     /* -M rgb_mean: w = M M2 rho + this */
	kg_method method;                         /* default for estimate */
	kg_site_map maps[KG_METHOD_COUNT];

	/* the site fit */
	double M2[9];             /* 3 x 3: rho_reference = M2 rho_site */
	double cond;              /* of rho_r (3 x k) */
	double cond_equilibrated; /* of rho_r with unit-RMS rows: the refusal test */
	double singular_values[3];
	int rank;                 /* of rho_r under pinv_rtol */
	int k;                    /* patches used */
	char **ids;
	double (*rho_r)[3];       /* k x 3 site values */
	double (*rho0)[3];        /* k x 3 reference values of the same patches */
	double (*residual)[3];    /* rho0 - M2 rho_r, k x 3 */
	double residual_rms;      /* over all patches and channels */
	double residual_relative; /* ||rho0 - M2 rho_r||_F / ||rho0||_F */
	int nflagged;             /* patches left out because detection flagged them */
	char **flagged_ids;
	unsigned *flagged_flags;  /* their FLAGS (KG_CHART_FLAG_*) */

	kg_camera_identity identity; /* the site camera */
	char id_rule[256];    /* how the site file's ids were matched with the reference's
	                       * when not as written (kg_patch_ids_match), else "" */
	kg_pairing_record pairing;   /* first: the reference's rho0, second: the site file */
	kg_response response;        /* the reference camera's (from the reference) */

	/* The site chart's flare, when the reference's values are flare-free (the reference
	 * removed its own): the straight line site value = offset + a rho0 through the
	 * neutral patches, per channel; slope = a times the reference's value of the
	 * perfect diffuser. Removed: the offset was subtracted from rho_r before M2 was
	 * fitted (kogei process then subtracts it from the objects' values too). */
	kg_flare flare;
	int flare_removed;

	int nsources;
	kg_calib_source *sources; /* "reference", "site_rgb" */
} kg_camera_calib;

/* The site fit's residual as a relative covariance (3 x 3): the patches' sum of r r^T
 * (r = rho0 - M2 rho_r) over their sum of l^2 = |rho0|^2 / 3, times k / (k - 3) (each
 * channel's row of M2 fits 3 values). A reading of mean square level l^2 carries
 * about l^2 R of calibration error. Zeros for a fit of 3 patches. */
void kg_camera_residual_cov(const kg_camera_calib *cam, double R[9]);

/* The sha256 of the reference calibration the site calibration was fitted against, or
 * "" when it was not recorded. */
const char *kg_camera_reference_sha256(const kg_camera_calib *cam);

/* M2 from the reference's rho0 and a site patch set (rgb), matched by SAMPLE_ID.
 * Patches the detector flagged (a FLAGS column: clipped, glare, too few pixels, out of
 * frame, non-uniform) are left out and listed in flagged_ids. Refused (KG_EINVAL, the
 * message names the cause and the patches): site ids the reference does not know,
 * fewer than 3 patches in common (which are missing) or left after the flagged ones
 * (which were flagged and why), non-finite values, clipped patches (a channel >=
 * clip_level, or a clipped-fraction column > 0 when the file has one), near-black
 * patches (brightest channel < black_level), nearly collinear charts (equilibrated
 * condition number > max_cond; the message lists the patches and how close to grey
 * they are), a relative residual above max_residual (the residual and the worst
 * patches: the patches do not read as the reference's chart), and, unless force, a
 * chart of exactly 3 patches (its residual is 0 whatever was photographed). */
int kg_camera_fit(const kg_reference *ref, const kg_patchset *site,
                  const kg_camera_options *opt, kg_camera_calib **out, kg_err *err);
/* Read the reference JSON and the site patch file and fit (sources recorded). */
int kg_camera_fit_files(const char *reference_path, const char *site_rgb_path,
                        const kg_camera_options *opt, kg_camera_calib **out, kg_err *err);
int kg_camera_set_method(kg_camera_calib *cam, kg_method m, kg_err *err);
void kg_camera_calib_free(kg_camera_calib **cam);

/* The map of a method (KG_METHOD_AUTO: the default one); KG_EINVAL if the method
 * was not available on the reference chart. */
int kg_camera_site_map(const kg_camera_calib *cam, kg_method m, const kg_site_map **out,
                       kg_err *err);
/* Reference evaluation of a site map at one pixel (tests, demo). */
void kg_site_map_apply(const kg_site_map *map, const double rgb[3], kg_spectrum *out);
/* The pca weights of a site pixel: w = M (M2 rho - rgb_mean); s = mean + B w. */
void kg_camera_weights(const kg_camera_calib *cam, const double rgb[3], double *w);

/* ---- kernels for estimate/ ------------------------------------------------------ */

/* The estimate/ kernel description of a method (KG_METHOD_AUTO: the default one) for
 * reference-camera RGB. It points into ref and is valid while ref lives. pca comes
 * with its basis (k = K: matrix M, offset -M rgb_mean, basis B, mean when centred),
 * so the kernel can also give weights and feed the classifier; the other methods
 * give spectra (k = 0, matrix 61 x T). */
int kg_reference_kernel_desc(const kg_reference *ref, kg_method m, kg_est_desc *desc,
                             kg_err *err);
/* The same for a site camera's RGB. M2 is folded into the linear methods (pca: matrix
 * M M2). The root-polynomial terms are not linear, so for rootpoly2/3 the kernel is
 * the reference's and the pixels must first be multiplied by pre (= M2); for every
 * other method pre is the identity. pre may be NULL only for the linear methods. */
int kg_camera_kernel_desc(const kg_camera_calib *cam, kg_method m, kg_est_desc *desc,
                          double pre[9], kg_err *err);

/* "format": "kogei-camera/1"; the keys are listed at the top of calib/json.c. */
int kg_camera_save(const kg_camera_calib *cam, const char *path, kg_err *err);
int kg_camera_load(const char *path, kg_camera_calib **out, kg_err *err);

/* sha256 of a file as 64 hex digits. */
int kg_calib_sha256_file(const char *path, char hex[65], kg_err *err);

/* ==== A camera's kernel, ready to apply (apply_kernel.c) ========================== */

/* Build the estimate/ kernel of a site camera for method m (KG_METHOD_AUTO: the
 * camera file's default), and, when lut_size > 0, a lookup table of lut_size^3 nodes
 * (2..KG_EST_LUT_MAX_N; 17, 33 or 65 reproduce the kernel at the nodes) over the
 * values the kernel can receive from pixels in [0, 1]. pre receives the 3 x 3 matrix
 * to apply to each pixel first (M2 for rootpoly2/3, else the identity); *pre_needed
 * (may be NULL) is set to 0 when it is the identity. The kernel is independent of cam
 * once built. Free with kg_est_kernel_free. */
int kg_camera_kernel(const kg_camera_calib *cam, kg_method m, int lut_size, kg_est_kernel **out,
                     double pre[9], int *pre_needed, kg_err *err);

/* ==== end of apply_kernel.c ======================================================= */

/* ==== Chart layouts (chart_layout.c, chart_print.c) ============================== */

/* A chart layout says where a colour chart's patches are and where the fiducial tags
 * around it are, in millimetres on the printed frame: origin at the frame's top-left
 * corner, x to the right, y down. Files: JSON with "format": "kogei-chart/1" (see
 * docs/charts.md and fixtures/charts/), or an ArgyllCMS .cht recognition template
 * (patch geometry only, no tags; see kg_chart_layout_load_cht). */
#define KG_CHART_FORMAT "kogei-chart/1"

/* One AprilTag of the frame. The tag is printed upright: its bit grid's rows run
 * along +x and its columns along +y (down the page), as apriltag_to_image() draws it.
 * size_mm is the edge of the square apriltag detects: width_at_border cells (8 of the
 * 10 of tag36h11, i.e. the outer edge of the black border; 5 of the 9 of
 * tagStandard41h12, the outer edge of its white ring). The printed pattern is
 * total_width / width_at_border times larger (kg_chart_tag_footprint).
 * corners_mm are that square's corners in apriltag_detection_t.p order, which wraps
 * counter-clockwise as seen on the page: p[0] bottom-left, p[1] bottom-right,
 * p[2] top-right, p[3] top-left (tag coordinates (-1,+1), (+1,+1), (+1,-1), (-1,-1)
 * with y down). */
typedef struct kg_chart_tag {
	int id;
	double center_mm[2];
	double size_mm;
	double corners_mm[4][2];
} kg_chart_tag;

typedef struct kg_chart_patch {
	char id[32];        /* SAMPLE_ID in the measurement files (Argyll style, "A01") */
	char alias[32];     /* another id of the same patch ("1".."24" for the ColorChecker
	                     * in ../shared/reference/charts), "" if none */
	char name[48];      /* human name ("dark skin"), "" if none */
	double center_mm[2];
	double size_mm[2];  /* full patch, w x h */
} kg_chart_patch;

typedef struct kg_chart_layout {
	char name[64];
	char family[32];          /* "tag36h11" or "tagStandard41h12"; "" without tags */
	int template_units;       /* 1: coordinates are a .cht template's scan pixels, not
	                           * mm (a .cht read without a physical width) */
	double width_mm, height_mm;  /* the printed frame (page) */
	double chart_area_mm[4];  /* x, y, w, h: where the physical chart goes */
	double sample_fraction;   /* inner fraction of each patch's w and h to sample */
	int ntags;
	kg_chart_tag *tags;
	int npatches;
	kg_chart_patch *patches;
} kg_chart_layout;

/* The file a --layout argument names: an existing file (or any argument with a '/') as
 * it is, else a bundled layout by name: colorchecker24-frame, colorchecker-passport-frame,
 * colorchecker-sg-frame and the demo's cie-tcs-frame. An unknown name fails with
 * KG_ENOENT listing them. *path is newly allocated. Every command that takes a layout
 * goes through this (kg_chart_layout_load calls it). */
int kg_chart_layout_resolve(const char *arg, char **path, kg_err *err);
/* 1 when name is a bundled layout's name (no '/', a ".json" suffix allowed). */
int kg_chart_layout_is_bundled(const char *name);
/* The layout a session's manifest names (value at key, e.g. "captures[2].chart_layout"):
 * a bundled layout's name, or a regular file captures/<capture>/<file> of the session
 * reached with no symbolic link on the way (acquire copies a --layout FILE there).
 * Anything else (an absolute path, "..", a file elsewhere) fails with KG_EINVAL naming
 * the manifest, the key and what was expected. *path is newly allocated. */
int kg_chart_layout_resolve_session(const char *session_dir, const char *manifest,
                                    const char *key, const char *value, char **path,
                                    kg_err *err);
/* Load a layout (a file or a bundled name, kg_chart_layout_resolve): "kogei-chart/1"
 * JSON, or (by the .cht extension, any case) an ArgyllCMS template in its own units. The
 * geometry is checked (kg_chart_layout_check). Errors name the file, the key or line,
 * and what was expected. */
int kg_chart_layout_load(const char *path, kg_chart_layout **out, kg_err *err);
/* Read an ArgyllCMS .cht recognition template as patch geometry: every sample box
 * of its X/Y BOXES lines at full size (ids as the template writes them, e.g. "A1");
 * BOX_SHRINK (template units off each side) becomes sample_fraction = 1 - 2 shrink /
 * the smallest box side. The chart area is the bounding box of the fiducial (F)
 * marks and the boxes; width_mm > 0 scales the template so the chart area is that
 * wide, 0 keeps template units (template_units = 1). The frame runs from the
 * template's origin to the chart area's far corner. No tags. */
int kg_chart_layout_load_cht(const char *path, double width_mm, kg_chart_layout **out,
                             kg_err *err);
/* Geometry checks: sizes positive and finite, ids unique, patches inside the chart
 * area and not overlapping, tags (their printed footprint) inside the frame, outside
 * the chart area and not overlapping; a known tag family and ids within it. */
int kg_chart_layout_check(const kg_chart_layout *l, kg_err *err);
void kg_chart_layout_free(kg_chart_layout **l);
/* Index of the patch whose id is id, else whose alias is id, else whose id differs
 * only in the zeros padding its trailing number ("A1" finds "A01"); -1 if none. */
int kg_chart_layout_find_patch(const kg_chart_layout *l, const char *id);
/* Index of the tag with this id; -1 if none. */
int kg_chart_layout_find_tag(const kg_chart_layout *l, int id);
/* The region to sample of patch i: the centred sample_fraction of its w and h, as
 * four corners in mm (top-left, top-right, bottom-right, bottom-left). */
void kg_chart_patch_sample_corners(const kg_chart_layout *l, int i, double corners[4][2]);
/* The printed square of tag i (total_width cells, with its own white/data ring)
 * as x, y, w, h in mm. */
void kg_chart_tag_footprint(const kg_chart_layout *l, int i, double rect[4]);

/* A tag's cells from libapriltag's code table: *cells (caller frees) holds
 * total_width^2 bytes, row-major from the top-left, y down, 1 = white, 0 = black;
 * the detected square is the centred border_width x border_width block. KG_ENOTSUP
 * without libapriltag, KG_EINVAL for an unknown family or an id out of range. */
int kg_chart_tag_cells(const char *family, int id, unsigned char **cells,
                       int *total_width, int *border_width, kg_err *err);

/* The printed page is the frame plus this margin on every side, which carries the cut
 * marks: frame point (x, y) mm is at (x + margin, y + margin) mm on the page. */
#define KG_CHART_PRINT_MARGIN_MM 10.0

/* Draw the printable frame at true size: tags, cut marks at the frame corners, the
 * outline of the chart area, patch outlines and ids (light grey), a 50 mm scale bar
 * and the layout's name. The format comes from the extension: .svg, .pdf or .png
 * (dpi applies to PNG only, 10..2400; a PNG pixel (i, j) covers [i, i+1) x [j, j+1)
 * in units of 25.4 / dpi mm). Written atomically. KG_ENOTSUP without libapriltag;
 * layouts in template units are refused. */
int kg_chart_print(const kg_chart_layout *l, const char *path, double dpi, kg_err *err);

/* ==== end of chart layouts ======================================================== */

/* ==== Chart detection (chart_detect.c) ============================================ */

/* Homographies are 3 x 3, row-major, mapping (x, y, 1) to (u w, v w, w). */
void kg_homography_map(const double H[9], double x, double y, double out[2]);
/* 0, or KG_EINVAL when H is singular. */
int kg_homography_invert(const double H[9], double inv[9]);
/* The homography taking src[i] to dst[i] (n >= 4 pairs): normalised DLT (Hartley),
 * then, when refine is set and n > 4, Levenberg-Marquardt on the reprojection error
 * in dst. H[8] = 1. rms (may be NULL): RMS distance |H src - dst| over the points. */
int kg_homography_fit(const double (*src)[2], const double (*dst)[2], int n, int refine,
                      double H[9], double *rms, kg_err *err);

typedef enum kg_chart_statistic {
	KG_CHART_MEDIAN = 0,      /* per-channel median */
	KG_CHART_TRIMMED_MEAN,    /* mean after dropping `trim` of the pixels at each end */
} kg_chart_statistic;

const char *kg_chart_statistic_name(kg_chart_statistic s);
int kg_chart_statistic_parse(const char *name, kg_chart_statistic *out, kg_err *err);

typedef struct kg_chart_detect_options {
	int decimate;            /* apriltag quad_decimate; 0: 2 below 4 Mpix, else 4 */
	int threads;             /* threads for the grey picture, libapriltag, mcc and the
	                          * sampling (default 2); results do not depend on it */
	double sample_fraction;  /* inner fraction of each patch side to sample; 0: the
	                          * layout's (default 0) */
	kg_chart_statistic statistic;
	double trim;             /* trimmed mean: fraction cut at each end (0.1) */
	const char *family;      /* tag family; NULL: the layout's */
	int tagless;             /* 1: the tagless detector only (ColorChecker 24 layouts) */
	int tagless_decimate;    /* the tagless detector looks at an N x N box-averaged copy
	                          * (the patch-grid finder, then mcc) and its box is refined
	                          * on the patch edges at full resolution; 1: mcc on the
	                          * full image, no refinement; 0 (default): the longer
	                          * side / 1000, at least 1 */
	int min_tags;            /* fewest tags that place the chart; 0 (the default): 2,
	                          * and a ColorChecker 24 layout with no tag in view falls
	                          * back to the tagless detector; N > 0: N, no fallback */
	int min_pixels;          /* fewer sampled pixels flag a patch (30) */
	double clip_level;       /* a channel at or above is clipped; 0: the source's full
	                          * scale (1 - 0.5 / (2^bits - 1) for integer images, 1.0
	                          * for float) */
	double nonuniformity_limit; /* quadrant spread above this flags a patch (0.05) */
	double glare_fraction;   /* more bright outliers than this flag glare (0.01) */
	int light_field;         /* 1 (default): estimate the light over the chart from the
	                          * patches' own gradients and divide the patch values by it
	                          * (calib/light_field.c); 0: patch values as sampled */
	double max_light_variation; /* a fitted light field varying more than this (peak to
	                          * peak over the patches, relative to its mean) is refused
	                          * (KG_EINVAL); 0: KG_CHART_MAX_LIGHT_VARIATION */
	int keep_refused;        /* 1: when the chart is not found (KG_ENOENT), *out still
	                          * gets a result with refused = 1: the refusal, the region
	                          * searched, tags and candidates seen, for the overlay */
} kg_chart_detect_options;

/* The largest light variation across a chart that the light-field correction is
 * trusted to remove (docs/chart-detect.md, "Uneven light"). */
#define KG_CHART_MAX_LIGHT_VARIATION 1.0

void kg_chart_detect_options_default(kg_chart_detect_options *o);

/* A tag found in the image. */
typedef struct kg_chart_tag_found {
	int id;
	double corners[4][2]; /* px, apriltag order (as kg_chart_tag.corners_mm) */
	double margin;        /* apriltag decision margin */
	int hamming;          /* bits corrected */
	int used;             /* 1: its corners determined the homography */
	double error;         /* largest corner distance from the fitted chart, px
	                       * (tags of the layout only) */
} kg_chart_tag_found;

/* Flags of a sampled patch. Rejected patches have no value (NaN) and are left out
 * of the patch file; the others are kept with their flags. */
enum {
	KG_CHART_FLAG_CLIPPED = 1 << 0,      /* some pixel has a channel >= clip level */
	KG_CHART_FLAG_GLARE = 1 << 1,        /* more than glare_fraction bright outliers */
	KG_CHART_FLAG_FEW_PIXELS = 1 << 2,   /* fewer than min_pixels */
	KG_CHART_FLAG_OUT_OF_FRAME = 1 << 3, /* some of the region is outside the image */
	KG_CHART_FLAG_NONUNIFORM = 1 << 4,   /* quadrants differ (occlusion, shadow, glare) */
	KG_CHART_FLAG_REJECTED = 1 << 5,     /* no usable pixel */
	KG_CHART_FLAG_MISFIT = 1 << 6,       /* its colour does not fit the layout's expected
	                                      * colour there (covered, painted, shadowed) */
};

/* One sampled patch, in the layout's order. */
typedef struct kg_chart_sample {
	char *id;
	double rgb[3];           /* linear 0..1 as the image; grey images give r = g = b */
	double sd[3];            /* pixel spread: 1.4826 x MAD per channel */
	double clipped_fraction; /* of the sampled pixels */
	double nonuniformity;    /* (max - min) / mean of the four quadrant means of r+g+b */
	long pixels;
	unsigned flags;          /* KG_CHART_FLAG_* */
	char warning[256];       /* the reasons, "" when not flagged */
	double quad[4][2];       /* the sampled region in px (tl, tr, br, bl of the layout) */
	double quadrant[4];      /* mean r+g+b of each quadrant of the sampled region (chart
	                          * u < 0 / >= 0, v < 0 / >= 0: index (u >= 0) + 2 (v >= 0)),
	                          * as sampled (before any light-field correction) */
	double centre_mm[2], half_mm[2]; /* the sampled region on the chart */
	double light;            /* the light field at the patch centre the values were
	                          * divided by (1: none) */
	double misfit;           /* against the layout's expected colour: the larger of its
	                          * hue and level misfits over their thresholds (> 1:
	                          * flagged KG_CHART_FLAG_MISFIT); NaN when not judged */
} kg_chart_sample;

/* The patches against the layout's expected colours (calib/chart_colours.c). */
typedef struct kg_chart_colour_check {
	int checked;             /* 0: the layout has no expected colours, or too few
	                          * unflagged patches have one */
	int used;                /* patches judged */
	int flagged;             /* of them, flagged KG_CHART_FLAG_MISFIT */
	double threshold_level, threshold_hue; /* in units of each patch's tolerance */
	double worst;            /* the largest misfit of a patch not flagged (< 1) */
	char worst_id[32];
	char note[160];          /* why not checked, when the layout has colours: "" */
} kg_chart_colour_check;

/* The light over the chart as estimated from the patches (calib/light_field.c):
 * ln L(u, v) = c0 + c1 u + c2 v + c3 u^2 + c4 u v + c5 v^2 + c6 u^3 + c7 u^2 v +
 * c8 u v^2 + c9 v^3 + c10 u^4 + c11 u^3 v + c12 u^2 v^2 + c13 u v^3 + c14 v^4 (terms
 * up to `degree`, the others 0), u = (x - origin_mm[0]) / scale_mm, v = (y -
 * origin_mm[1]) / scale_mm in chart millimetres, normalised so that L averages 1
 * over the patch centres. */
typedef struct kg_chart_light {
	int fitted;              /* 0: not estimated (turned off or too few patches) */
	int degree;              /* of the polynomial in ln L, 1..4 */
	double origin_mm[2], scale_mm;
	double coef[15];
	int used;                /* patches whose gradients entered the fit */
	double min, max;         /* of L over the patches' area (mean 1 over the centres) */
	double variation;        /* max - min */
	double rms;              /* weighted RMS residual of the gradients, in units of
	                          * their noise */
} kg_chart_light;

/* ln L at chart position (x, y) mm (0 when not fitted). */
double kg_chart_light_log(const kg_chart_light *f, double x_mm, double y_mm);
/* Something the detector tried and did not take (kept on a refusal). */
typedef struct kg_chart_candidate {
	double quad[4][2]; /* px */
	char why[256];     /* what it was and why it failed */
} kg_chart_candidate;

typedef struct kg_chart_result {
	char layout[64];
	int tagless;              /* found by the tagless detector, not by tags */
	int tagless_grid;         /* tagless: placed by its patch-grid finder, not OpenCV mcc */
	int ntags;                /* every tag found, of the layout or not */
	kg_chart_tag_found *tags;
	int ntags_used;
	double H[9];              /* mm -> px */
	double rms_px;            /* RMS reprojection error of the points used */
	double outline[4][2];     /* the layout's chart area in px (tl, tr, br, bl) */
	int decimate;             /* the quad_decimate used */
	int tagless_decimate;     /* tagless: the reduction the box was found on (1: full image) */
	int npatches;
	kg_chart_sample *patches;
	int nwarnings;            /* what an operator should know, one sentence each */
	char **warnings;
	double prepare_seconds;   /* the detectors' images: white level, 8-bit grey for the
	                           * tags, the decimated copy for the tagless detector */
	double tag_seconds;       /* tag detection (libapriltag), or the tagless detector
	                           * (OpenCV mcc and the refinement of its box) */
	double sample_seconds;    /* patch sampling (all four turns when tagless) */
	double total_seconds;
	kg_chart_light light;     /* the light field removed from the patch values */
	kg_chart_colour_check colours; /* the patches against the layout's colours */
	double clip[3];           /* per colour (R, G, B; grey: all three alike): the level
	                           * at or above which a value of the image detected is
	                           * clipped, as KG_CHART_FLAG_CLIPPED judges the patches
	                           * (clip_level, or the saturation found below it); 0 when
	                           * not known (a refusal before the image was read) */
	/* a refusal (options.keep_refused): patches, when present, are the regions of the
	 * best reading tried, not a chart found */
	int refused;
	char refusal[1024];       /* the error message */
	int has_searched;
	double searched[4][2];    /* the region searched, px */
	int ncandidates;
	kg_chart_candidate *candidates;
} kg_chart_result;

/* Find the chart of layout l in img and sample its patches. img: 1 channel (grey,
 * or raw with a CFA pattern, demosaiced first) or 3 (RGB), linear 0..1. Errors:
 * KG_ENOENT when the chart is not found (the message says what was seen: no tags,
 * tags of other ids, too few tags; for the tagless detector, a box whose patches do
 * not read as the layout's in any of its four turns); KG_ENOTSUP when a needed
 * library is missing.
 * Warnings (tags ignored, missing, few tags, flagged patches) are in the result. */
int kg_chart_detect(const kg_chart_layout *l, const kg_image *img,
                    const kg_chart_detect_options *opt, kg_chart_result **out, kg_err *err);
void kg_chart_result_free(kg_chart_result **r);
/* When a detection of layout l with options opt may use OpenCV mcc (a ColorChecker 24
 * layout), start building what it needs once per process (OpenCV's colour tables,
 * about 0.13 s of one core) on a thread of its own; otherwise nothing. For a
 * long-lived caller (the console) that will detect many times. kg_chart_detect itself
 * starts it only when mcc would be tried first (an image too small for the patch-grid
 * finder's reduced copy), and joins the thread before it returns; a caller that ends
 * without detecting calls kg_chart_warm_wait (a no-op when nothing runs). */
void kg_chart_warm_up(const kg_chart_layout *l, const kg_chart_detect_options *opt);
void kg_chart_warm_wait(void);

/* The patch values as a patch set: ids, rgb and the extra columns RGB_R_SD RGB_G_SD
 * RGB_B_SD CLIPPED_FRACTION NONUNIFORMITY PIXELS FLAGS; rejected patches left out. */
int kg_chart_result_patchset(const kg_chart_result *r, kg_patchset **out, kg_err *err);

/* The overlay an operator checks: the image (gamma-encoded, scaled so its longer
 * side is at most max_side px; 0: 1600), tags outlined with their ids (green: used,
 * orange: ignored), the chart outline, each sampled region with its id, flagged
 * patches in red with a cross when rejected. PNG, written atomically. */
int kg_chart_overlay_write(const kg_chart_result *r, const kg_image *img, const char *path,
                           int max_side, kg_err *err);

/* ==== end of chart detection ====================================================== */

#endif
