/* calib/: the reference calibration (once, in the lab) and the site calibration
 * (every session) of DESIGN.md §1 steps 1-2, and the JSON files that carry them.
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
} kg_spectral_map;

/* Spectrum of one RGB through a map (no clamping). */
void kg_spectral_map_apply(const kg_spectral_map *map, const double rgb[3],
                           kg_spectrum *out);

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
} kg_reference_options;

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

	int nsources;
	kg_calib_source *sources;
} kg_reference;

/* Pair spectra and RGB by SAMPLE_ID into one patch set (spectra + rgb), in the order
 * of `spectra`. Patches missing from either are left out; no id in common and
 * duplicate ids are errors naming the files and ids. */
int kg_calib_pair(const kg_patchset *spectra, const kg_patchset *rgb, kg_patchset **out,
                  kg_err *err);

/* Fit everything on a training chart (spectra + rgb) for a field chart (rgb; may be
 * the training set itself). Refused (KG_EINVAL, naming the patches): non-finite or
 * clipped values, near-black field patches, nearly collinear RGB (the site test of
 * kg_camera_fit, on both charts), too few patches, options out of range. */
int kg_reference_fit(const kg_patchset *train, const kg_patchset *field,
                     const kg_reference_options *opt, kg_reference **out, kg_err *err);
/* Read the inputs and fit: spectra from CGATS (SPEC_*) or a `patch,name,<nm>...` CSV,
 * RGB from CGATS (RGB_R RGB_G RGB_B); field_rgb_path NULL means rgb_path. Records the
 * sources (path, sha256, keywords). */
int kg_reference_fit_files(const char *spectra_path, const char *rgb_path,
                           const char *field_rgb_path, const kg_reference_options *opt,
                           kg_reference **out, kg_err *err);
void kg_reference_free(kg_reference **ref);

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

typedef struct kg_camera_options {
	double max_cond;
	double clip_level;
	double black_level;
	double pinv_rtol;
	const char *const *exclude; /* ids to leave out of the fit (both files), or NULL */
	int nexclude;
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

typedef struct kg_camera {
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

	int nsources;
	kg_calib_source *sources; /* "reference", "site_rgb" */
} kg_camera;

/* M2 from the reference's rho0 and a site patch set (rgb), matched by SAMPLE_ID.
 * Refused (KG_EINVAL, the message names the cause and the patches): site ids the
 * reference does not know, fewer than 3 patches in common (which are missing),
 * non-finite values, clipped patches (a channel >= clip_level, or a clipped-fraction
 * column > 0 when the file has one), near-black patches (brightest channel <
 * black_level) and nearly collinear charts (equilibrated condition number >
 * max_cond; the message lists the patches and how close to grey they are). */
int kg_camera_fit(const kg_reference *ref, const kg_patchset *site,
                  const kg_camera_options *opt, kg_camera **out, kg_err *err);
/* Read the reference JSON and the site patch file and fit (sources recorded). */
int kg_camera_fit_files(const char *reference_path, const char *site_rgb_path,
                        const kg_camera_options *opt, kg_camera **out, kg_err *err);
int kg_camera_set_method(kg_camera *cam, kg_method m, kg_err *err);
void kg_camera_free(kg_camera **cam);

/* The map of a method (KG_METHOD_AUTO: the default one); KG_EINVAL if the method
 * was not available on the reference chart. */
int kg_camera_site_map(const kg_camera *cam, kg_method m, const kg_site_map **out,
                       kg_err *err);
/* Reference evaluation of a site map at one pixel (tests, demo). */
void kg_site_map_apply(const kg_site_map *map, const double rgb[3], kg_spectrum *out);
/* The pca weights of a site pixel: w = M (M2 rho - rgb_mean); s = mean + B w. */
void kg_camera_weights(const kg_camera *cam, const double rgb[3], double *w);

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
int kg_camera_kernel_desc(const kg_camera *cam, kg_method m, kg_est_desc *desc,
                          double pre[9], kg_err *err);

/* "format": "kogei-camera/1"; the keys are listed at the top of calib/json.c. */
int kg_camera_save(const kg_camera *cam, const char *path, kg_err *err);
int kg_camera_load(const char *path, kg_camera **out, kg_err *err);

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
int kg_camera_kernel(const kg_camera *cam, kg_method m, int lut_size, kg_est_kernel **out,
                     double pre[9], int *pre_needed, kg_err *err);

/* ==== end of apply_kernel.c ======================================================= */

#endif
