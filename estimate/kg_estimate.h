/* The public header of estimate/: per-pixel estimation kernels (camera RGB to
 * 61-band reflectance, basis weights or material labels) and the framework that runs
 * them over an image in row blocks on a small thread pool.
 *
 * A kernel maps linear camera RGB (float, 0..1 scale) to an output vector:
 *   - matrix kernels: out = A phi(rho) + offset, where phi(rho) are the kernel's terms:
 *       KG_EST_LINEAR     r, g, b                                   (T = 3)
 *       KG_EST_ROOTPOLY2  r, g, b, sqrt(rg), sqrt(gb), sqrt(rb)       (T = 6)
 *       KG_EST_ROOTPOLY3  the above, then cbrt(r g^2), cbrt(g b^2), cbrt(r b^2),
 *                         cbrt(g r^2), cbrt(b g^2), cbrt(b r^2), cbrt(rgb)   (T = 13)
 *     (Finlayson, Mackiewicz & Hurlbert 2015, IEEE TIP 24(5)); negative channels
 *     count as 0 inside the roots, and in float the cube-root terms are products of
 *     the channels' own cube roots (within 2 ulp of the double terms). The paper's
 *     A = B M M2, direct linear regression and Wiener estimation are all KG_EST_LINEAR;
 *     the fitting is done in calib/, which hands the matrices over.
 *   - LUT kernels: a grid of N^3 nodes over [lo, hi]^3 holding the output of any
 *     matrix kernel, read with trilinear interpolation.
 * A kernel made with a K-dimensional basis B (61 x K, orthonormal columns, and an
 * optional mean for centred PCA) produces either the spectrum s = mean + B w or the
 * K weights w themselves, and can feed the material classifier (the paper's eq. 11),
 * which works on w alone.
 *
 * Every kernel has a plain C reference implementation and, on x86-64, optimised ones
 * chosen at run time: AVX2 + FMA + F16C, and AVX-512F (kg_est_isa). All produce
 * bit-identical output: they perform the same IEEE operations in the same order. Each
 * multiply-add of a band's sum (offset, then the terms in order; a LUT's corners 1 to
 * 7 after corner 0's product) is one fused operation with a single rounding: fmaf in
 * the reference, an FMA instruction in the vector paths. Nothing else is fused (the
 * compiler may not contract: estimate/ is built with -ffp-contract=off; the cube root
 * and the classifier's double distances stay unfused in every path), and the F16C
 * conversion rounds exactly like kg_f16_from_f32. Output is also bit-identical for
 * every block size and thread count: each pixel is computed independently of its
 * neighbours.
 *
 * Pixel flags (the optional uint8 mask, one byte per pixel):
 *   KG_EST_MASK_NONFINITE  an input channel is NaN or +-Inf.
 *   KG_EST_MASK_CLIPPED    the pixel is finite and a channel is >= job.clip_level.
 *   KG_EST_MASK_CLAMPED    one or more output bands were negative and were set to 0.
 * A NONFINITE or CLIPPED pixel is never estimated: every float output band of it is
 * NaN (f32 and f16, spectra and weights), its label is KG_EST_LABEL_NONE (0) and its
 * confidence NaN. Negative reflectance (spectral outputs only; weights keep their
 * sign) is clamped to 0 and counted in kg_est_stats. */
#ifndef KG_ESTIMATE_H
#define KG_ESTIMATE_H

#include <stddef.h>
#include <stdint.h>

#include "kg_optics.h"

#define KG_EST_MAX_K 16          /* largest basis */
#define KG_EST_MAX_TERMS 13      /* terms of KG_EST_ROOTPOLY3 */
/* Labels 1..253 for the materials, then "unknown" and "background" (label map classes,
 * kg_classify_image_opts) fit in a byte beside KG_EST_LABEL_NONE. */
#define KG_EST_MAX_MATERIALS 253
#define KG_EST_LUT_MAX_N 65
/* A class name: a material's, or a compound of several joined by '|'. */
#define KG_EST_CLASS_NAME_MAX 256

typedef enum kg_est_method {
	KG_EST_LINEAR,
	KG_EST_ROOTPOLY2,
	KG_EST_ROOTPOLY3,
	KG_EST_LUT, /* only made by kg_est_kernel_new_lut */
} kg_est_method;

typedef enum kg_est_format {
	KG_EST_F32_BSQ, /* 61 planes of width*height floats */
	KG_EST_F32_BIP, /* 61 floats per pixel */
	KG_EST_F16_BSQ, /* as F32_BSQ in IEEE binary16 (uint16_t) */
	KG_EST_F16_BIP,
	KG_EST_WEIGHTS, /* K floats per pixel (BIP); needs a kernel with a basis */
	KG_EST_LABELS,  /* one uint8 label per pixel, plus a float confidence */
	KG_EST_NFORMATS
} kg_est_format;

enum {
	KG_EST_MASK_NONFINITE = 1 << 0,
	KG_EST_MASK_CLIPPED = 1 << 1,
	KG_EST_MASK_CLAMPED = 1 << 2,
};

/* Label of a pixel that was not classified (flagged); material j of the classifier
 * has label j + 1, as class 0 is "Unclassified" in an ENVI classification file. */
#define KG_EST_LABEL_NONE 0

/* Which implementation runs. AUTO picks the best the CPU supports (AVX-512, then
 * AVX2, then C), asked once per run (CPUID). A path the CPU lacks gives KG_ENOTSUP. */
typedef enum kg_est_isa {
	KG_EST_ISA_AUTO,
	KG_EST_ISA_C,      /* the reference kernels (fmaf for every multiply-add) */
	KG_EST_ISA_AVX2,   /* AVX2 + FMA + F16C */
	KG_EST_ISA_AVX512, /* AVX-512F on top of those: 16 lanes for the BSQ outputs */
	KG_EST_NISAS
} kg_est_isa;

/* Non-temporal (streaming) stores bypass the cache: they pay when the output is far
 * larger than the cache and is not read again soon. */
typedef enum kg_est_stores {
	KG_EST_STORES_AUTO, /* streaming for in-memory outputs above 64 MiB, never for sinks */
	KG_EST_STORES_CACHED,
	KG_EST_STORES_STREAMING,
} kg_est_stores;

/* A matrix kernel. Without a basis (k == 0) matrix is 61 x T and offset has 61
 * values. With a basis (k > 0) matrix is K x T and offset K values: they give the
 * weights w, and the spectrum is mean + basis w (basis 61 x K row-major, mean 61
 * values or NULL). T is the method's number of terms. All values must be finite. */
typedef struct kg_est_desc {
	kg_est_method method;
	int k;
	const double *matrix;
	const double *offset;
	const double *basis;
	const double *mean;
} kg_est_desc;

typedef struct kg_est_kernel kg_est_kernel;

int kg_est_kernel_new(const kg_est_desc *desc, kg_est_kernel **out, kg_err *err);
/* A LUT of n^3 nodes (2 <= n <= KG_EST_LUT_MAX_N) over [lo, hi]^3 holding src's
 * unclamped output (spectra, and weights when src has a basis). Inputs outside the
 * range are clamped to it; negative spectral values are clamped after interpolation.
 * At a node the LUT returns exactly src's output when the node's coordinate maps back
 * exactly to its index, e.g. over [0, 1] with n - 1 a power of two (17, 33, 65). */
int kg_est_kernel_new_lut(const kg_est_kernel *src, int n, float lo, float hi,
                          kg_est_kernel **out, kg_err *err);
void kg_est_kernel_free(kg_est_kernel **k);

kg_est_method kg_est_kernel_method(const kg_est_kernel *k);
/* Basis size K, 0 when the kernel has no basis. */
int kg_est_kernel_k(const kg_est_kernel *k);
/* Input value of LUT node i along each axis (for tests and reports). */
float kg_est_lut_node(const kg_est_kernel *k, int i);

/* Evaluate one pixel with the reference kernel: 61 clamped reflectances, or with
 * weights set, K weights. Returns the pixel's mask bits (flagged pixels give NaN). */
unsigned kg_est_kernel_eval(const kg_est_kernel *k, const float rgb[3], float clip_level,
                            int weights, float *out);

/* Number of terms of a matrix method (3, 6 or 13), or KG_EINVAL. */
int kg_est_method_terms(kg_est_method m);
/* The root-polynomial (or linear) terms of rgb in the order listed above, in double
 * precision, for fitting in calib/. Negative channels count as 0 inside the roots.
 * Returns the number of terms or KG_EINVAL. */
int kg_est_terms(kg_est_method m, const double rgb[3], double *terms);

/* Material classification in the K-dim subspace (the paper's eq. 11). */
typedef enum kg_est_distance {
	KG_EST_DIST_PLAIN,      /* ||C_j - s||^2 */
	KG_EST_DIST_SCALE_FREE, /* min over a >= 0 of ||a C_j - s||^2 */
} kg_est_distance;

typedef struct kg_est_material {
	const char *name;
	const double *spectrum; /* 61 values: reflectance or colour signal C_j */
} kg_est_material;

typedef struct kg_est_classifier kg_est_classifier;

/* Classify among exactly the n materials given (the scene's declared set), with the
 * basis and mean of kernel k (which must have one, with orthonormal columns). */
int kg_est_classifier_new(const kg_est_kernel *k, const kg_est_material *materials, int n,
                          kg_est_distance distance, kg_est_classifier **out, kg_err *err);
void kg_est_classifier_free(kg_est_classifier **c);
int kg_est_classifier_count(const kg_est_classifier *c);
const char *kg_est_classifier_name(const kg_est_classifier *c, int j);
/* Distances of weights w (K values) to every material, as the reference kernel
 * computes them (double). */
void kg_est_classifier_distances(const kg_est_classifier *c, const float *w, double *d);

/* Is material j an explanation of weights w at all? The distance splits into a part
 * inside span B and one outside it: plain d_j = ||v - c_j||^2 + o_j with v = w +
 * B^T mean, c_j = B^T C_j and o_j = ||(I - B B^T)(C_j - mean)||^2; scale-free the same
 * with a C_j at the best a. Noise moves only the inside part; the outside part o_j is
 * what the K-dimensional model cannot represent of the material, so it is taken as
 * model error of that size spread evenly over the K weights. The statistic is
 *   chi2_j = r^T (sigma_w + (o_j / K) I)^-1 r,   r = v - c_j (plain) or v - a c_j,
 * where sigma_w (K x K, row-major, symmetric) is the covariance of the pixel's
 * weights (noise and calibration error propagated through the kernel's weight
 * matrix: sigma_w = A_w sigma_rgb A_w^T). For a pixel of material j whose errors are
 * Gaussian with that covariance it follows a chi-square distribution with
 * kg_est_classifier_dof degrees of freedom. A singular covariance gives 0 when r is
 * 0 and +Inf otherwise. Computed in double by Cholesky factorisation. */
double kg_est_classifier_chi2(const kg_est_classifier *c, int j, const float *w,
                              const double *sigma_w);
/* Degrees of freedom of kg_est_classifier_chi2: K for the plain distance, K - 1 (at
 * least 1) for the scale-free one, whose scale a is fitted. */
int kg_est_classifier_dof(const kg_est_classifier *c);
/* The point x with P(X <= x) = p for X chi-square with dof degrees of freedom
 * (1 <= dof <= 1000, 0 < p < 1), from the regularised incomplete gamma function by
 * bisection, to 1e-9 relative; NaN for arguments out of range. E.g. p = 0.999:
 * 10.828 (dof 1), 13.816 (2), 16.266 (3). */
double kg_chi2_quantile(double p, int dof);

/* What to compute and how. Set with kg_est_job_init, then adjust. */
typedef struct kg_est_job {
	const kg_est_kernel *kernel;
	kg_est_format format;
	const kg_est_classifier *classifier; /* KG_EST_LABELS only */
	float clip_level; /* flag pixels with a channel >= this; INFINITY disables */
	int threads;      /* 0: online CPUs */
	int block_rows;   /* rows per block; 0: about 4 MiB of output per block */
	kg_est_isa isa;
	kg_est_stores stores;
	/* Stream mode only: each block's input is pulled from fill instead of read from
	 * rgb (which may then be NULL). fill is called for one block at a time, in row
	 * order, so a file can be read top to bottom once; it fills `in` (in_bytes per
	 * pixel times the block's pixels) and leaves the kernel's RGB, 3 floats per pixel,
	 * at its start. The rest is the caller's: the sink gets the whole of it as
	 * block->input. A fill error stops the run and is returned. */
	int (*fill)(void *user, int y0, int rows, void *in, kg_err *err);
	void *fill_user;
	size_t in_bytes; /* per pixel, >= 12; 0: 12 */
	/* Labels format in stream mode only: instead of the kernel and classifier (kernel
	 * may then be NULL), the caller's per-block function runs in the worker threads on
	 * what fill wrote (`in`, n pixels), writing each pixel's label, confidence and mask
	 * byte and counting the pixels it flagged; anything else it computes it may leave in
	 * `in`, which the sink gets as block->input. */
	void (*compute)(void *user, void *in, size_t n, uint8_t *labels, float *conf,
	                uint8_t *mask, uint64_t *nonfinite, uint64_t *clipped);
	void *compute_user;
} kg_est_job;

/* Defaults: clip_level 0.999 (of the 0..1 full scale; callers set the level their
 * camera saturates at), threads 0, block_rows 0, isa AUTO, stores AUTO. */
void kg_est_job_init(kg_est_job *job, const kg_est_kernel *k, kg_est_format format);

/* Bands per pixel of a format for a kernel (61, K, or 1 for labels) and bytes per
 * band value (4, 2 or 1). */
int kg_est_format_bands(const kg_est_kernel *k, kg_est_format format);
size_t kg_est_format_elem_size(kg_est_format format);

typedef struct kg_est_stats {
	uint64_t pixels;
	uint64_t nonfinite;      /* pixels with a NaN or Inf channel */
	uint64_t clipped;        /* finite pixels with a channel >= clip_level */
	uint64_t clamped_pixels; /* pixels with a negative band set to 0 */
	uint64_t clamped_values; /* band values set to 0 */
} kg_est_stats;

/* Whole-image destination: data holds width*height pixels in the format's layout
 * (labels: uint8). confidence (labels only: margin, second-best distance minus best,
 * +Inf with a single material) and mask are optional. */
typedef struct kg_est_dest {
	void *data;
	float *confidence;
	uint8_t *mask;
} kg_est_dest;

/* rgb: width*height interleaved pixels, rows contiguous. stats may be NULL. */
int kg_est_run(const kg_est_job *job, const float *rgb, int width, int height,
               const kg_est_dest *dest, kg_est_stats *stats, kg_err *err);

/* One finished row block, handed to a sink in row order. In BSQ formats data holds
 * `bands` planes of rows*width values. */
typedef struct kg_est_block {
	int y0, rows, width, bands;
	kg_est_format format;
	const void *data;
	const float *confidence; /* labels only */
	const uint8_t *mask;
	const void *input; /* what the job's fill wrote for this block, or NULL */
} kg_est_block;

typedef int (*kg_est_sink_fn)(void *user, const kg_est_block *block, kg_err *err);

/* As kg_est_run, but each block goes to sink (called from the calling thread, in row
 * order) so memory stays bounded: at most 2 x threads blocks are alive. A sink's
 * error stops the run and is returned. */
int kg_est_run_stream(const kg_est_job *job, const float *rgb, int width, int height,
                      kg_est_sink_fn sink, void *user, kg_est_stats *stats, kg_err *err);

/* IEEE binary16 conversion, round to nearest even; NaN stays a quiet NaN with the
 * upper payload bits kept, overflow gives Inf, subnormals are exact. */
uint16_t kg_f16_from_f32(float f);
float kg_f32_from_f16(uint16_t h);

/* ==== Camera-space matching (camspace.c) ==========================================
 *
 * Materials matched where the camera measures, not in the 61-band estimate: each
 * declared material's reading is predicted in the reference camera's space from its
 * spectral response F (3 x 61; calib's kg_response, learned from the chart) and the
 * material's reflectance over a grid of incidence angles; a pixel in that space (the
 * site reading through M2) with its covariance takes the material, angle and intensity
 * of the least noise-weighted distance (camspace.c says how). */
#define KG_CS_PP 9 /* floats per prediction in kg_cs_model.ppf */
typedef struct kg_cs_model {
	int n, nangles;
	char (*names)[KG_MATERIAL_NAME_MAX];
	double *angle_deg; /* nangles, increasing */
	double *mu;        /* n x nangles x 3: the predicted readings at intensity 1 */
	float *muf;        /* the same in float, for the block kernels */
	float *ppf;        /* n x nangles x KG_CS_PP (KG_CS_QUADRATIC): each prediction
	                      muf = w (..), w its component ppc and u, v its other two
	                      (in order) over w: u^2, v^2, 2 u v, 2 u, 2 v, u, v, and the
	                      bounds of a w for a in [lo, hi] (the lesser first); NULL:
	                      that method refused (no component nonzero in every
	                      prediction) */
	int ppc;
	float *anglef;
	uint8_t *templated; /* n: the material's readings come from its coupon template */
	double lo, hi;     /* the intensity range searched */
} kg_cs_model;

/* F row-major (3 x 61); angles a0 to a1 degrees every step; intensities lo to hi. A
 * material with a template (kg_material.tmpl, learned from coupons) takes its readings
 * from it instead of F times its reflectance: linear between the views' angles, the
 * nearest view's beyond them. */
int kg_cs_model_new(const double *F, const kg_material *const *mats, int n, double a0,
                    double a1, double step, double lo, double hi, kg_cs_model **out,
                    kg_err *err);
void kg_cs_model_free(kg_cs_model **m);
/* (Re)computes ppf and ppc from muf, lo and hi (kg_cs_model_new does; for a model built
 * field by field, or after changing them). 0 or KG_ENOMEM. */
int kg_cs_model_products(kg_cs_model *m);

typedef struct kg_cs_result {
	int best;                  /* material index */
	double d2_best, d2_second; /* noise-weighted squared distances */
	double angle_deg, scale;   /* the best material's fitted angle and intensity */
	double posterior;          /* of the best, equal priors */
	double d2_each[KG_EST_MAX_MATERIALS];
} kg_cs_result;

/* Match one pixel x (reference camera's space) with covariance cov (3 x 3, row-major,
 * positive definite). KG_EINVAL (no result) for a covariance that is not positive
 * definite or a non-finite pixel. */
int kg_cs_match(const kg_cs_model *m, const double x[3], const double cov[9],
                kg_cs_result *out);

/* What kg_cs_match_block writes per pixel; all but best may be NULL. */
#define KG_CS_NO_MATCH 255
typedef struct kg_cs_block {
	uint8_t *best;     /* material index, KG_CS_NO_MATCH: non-finite x or covariance not
	                      positive definite */
	float *d2best, *d2second;
	float *angle_deg, *scale; /* the best material's */
	float *d2;         /* n x model->n: every material's distance */
} kg_cs_block;

/* kg_cs_match for n pixels in float: x 3 values per pixel, cov 6 per pixel (c00 c01 c02
 * c11 c12 c22). Up to 254 materials. Two methods (camspace.c says how each computes):
 * KG_CS_EXACT, every candidate (material, angle) through the pixel's Cholesky factor;
 * KG_CS_QUADRATIC, each material's angle chosen by quadratic forms (9 multiplies and
 * multiply-adds, a division and 6 other operations per candidate instead of about
 * 40), then that candidate through KG_CS_EXACT's
 * operations, so every value it writes is the exact method's for that material at that
 * angle. They differ only where another angle of a material is within float rounding
 * (some eps |y|^2, y the whitened reading) of the best one: the quadratic method may
 * take it, its distance a hair above the exact method's, and where two materials are
 * that close the label may differ (kogei bench counts the pixels). Each method's
 * implementations write bit-identical outputs. */
typedef enum kg_cs_method {
	KG_CS_EXACT,
	KG_CS_QUADRATIC,
} kg_cs_method;
/* On a CPU with AVX-512, KG_CS_QUADRATIC in AVX-512 (when the model has ppf); elsewhere
 * KG_CS_EXACT in AVX2 or C (with 8 lanes the quadratic method is no faster). */
void kg_cs_match_block(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                       const kg_cs_block *out);
/* The same with the method and the implementation chosen. KG_EST_ISA_C: the method's
 * reference in plain C float (KG_CS_QUADRATIC: multiply-adds fused by fmaf).
 * KG_EST_ISA_AVX2: 8 pixels per vector, KG_EST_ISA_AVX512: 16, the same IEEE
 * operations in the same order lane by lane, the last pixels that fill no vector
 * through the reference; KG_ENOTSUP (nothing written) on a CPU without the extension.
 * AUTO: the widest the CPU has, else C. Returns 0, or KG_EINVAL for a method or isa
 * out of range or KG_CS_QUADRATIC without ppf. Pixels the reference refuses
 * (KG_CS_NO_MATCH, NaNs) are refused alike by both methods. */
int kg_cs_match_block_method(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                             const kg_cs_block *out, kg_cs_method method, kg_est_isa isa);
/* kg_cs_match_block_method with KG_CS_EXACT. */
int kg_cs_match_block_isa(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                          const kg_cs_block *out, kg_est_isa isa);

/* Separability of the model's materials at noise cov, for a reading at intensity
 * level: d[i * n + j] (n x n, symmetric, 0 on the diagonal) is the least
 * noise-weighted distance between i and j over every angle and intensity, i.e. the
 * smaller over the two of: over the one's angles at `level`, the nearest reading of the
 * other. A single pixel tells them apart with error Phi(-d / 2). */
int kg_cs_separability(const kg_cs_model *m, const double cov[9], double level, double *d,
                       kg_err *err);
/* The same with each reading's own covariance: covs holds 9 values for each reading
 * of material i at angle k at intensity level (index i * nangles + k), e.g. from a
 * noise model that grows with the signal. */
int kg_cs_separability_each(const kg_cs_model *m, const double *covs, double level,
                            double *d, kg_err *err);
/* Pixels a region must pool to tell two materials at distance d apart with 1 % error:
 * ceil((2 z / d)^2), z the standard normal's 99 % point; +Inf for d = 0. */
double kg_cs_pixels_for(double d);
/* The classes a single pixel can support: materials joined by complete linkage (the
 * two classes whose farthest pair is the closest join, while that pair is closer than
 * dmin), so every pair inside a class is closer than dmin, and a chain of close pairs
 * does not join materials far apart (such a pair across two classes stays in the
 * separability table); group[i] is the smallest index of i's class. Returns the number
 * of classes. KG_CS_MERGE_DISTANCE, two noise sigmas, joins pairs a single pixel
 * confuses more than one time in six (Phi(-1) = 16 %: its reading lies past the
 * midpoint, one sigma away); pairs up to 2 z_99 = 4.65 apart still need pooled pixels
 * (kg_cs_pixels_for) for a 1 % error. */
#define KG_CS_MERGE_DISTANCE 2.0
int kg_cs_merge_groups(const double *d, int n, double dmin, int *group);

/* ==== Images to files: cubes, masks and label maps (apply.c) =====================
 *
 * The glue between a kernel and the station's file formats. It knows nothing
 * of calibrations: the caller builds the kernel (calib/: kg_camera_kernel) and, for
 * site maps of the root-polynomial methods, passes the 3 x 3 matrix applied to each
 * pixel before the kernel. Rows go through kg_est_run_stream into the streaming ENVI
 * writer, so the output cube is never held in memory; nothing appears under the
 * output names unless every file of the call is complete.
 *
 * Files written for an output name OUT (e.g. "cube.hdr", data "cube.img"; side files
 * are named from OUT without its extension, kg_apply_side_path):
 *   estimate:  OUT                 the cube (f32: data type 4; f16: data type 12 with
 *                                  "kogei sample format = ieee-half": the samples are
 *                                  IEEE binary16 bit patterns, which only kogei reads
 *                                  as such; weights: K bands plus "kogei basis" (61 x K,
 *                                  row-major), "kogei mean" (61) and "kogei basis
 *                                  wavelength" (61), so s = mean + basis w)
 *              <stem>_mask.hdr     uint8, one band, the KG_EST_MASK_* bits per pixel
 *   classify:  OUT                 ENVI Classification, uint8: 0 "unclassified"
 *                                  (flagged pixels), j + 1 the j-th material, n + 1
 *                                  "unknown", n + 2 "background" (n materials)
 *              <stem>_confidence.hdr  float32, the margin to the runner-up (NaN when
 *                                  flagged, unknown or background, +Inf with a
 *                                  single material)
 *              <stem>_mask.hdr     as for estimate
 *              <stem>.json         classes, counts, mean spectra, confidence, and how
 *                                  unknown and background were decided
 *              <stem>.png          preview: class colours, flagged pixels grey,
 *                                  unknown magenta, background near-black, legend */

#include <stdio.h>

#include "kg_core.h"

/* Images with at least this many pixels report progress (when asked to). */
#define KG_APPLY_PROGRESS_PIXELS 4000000L

typedef struct kg_apply_options {
	/* 3 x 3 row-major matrix applied to every pixel's RGB before the kernel (the M2
	 * of a root-polynomial site map), or NULL for none. */
	const double *pre;
	/* A pixel with a channel >= clip_level, tested on the image's values before pre,
	 * is flagged KG_EST_MASK_CLIPPED; INFINITY disables the test. */
	float clip_level;
	/* Per channel (R, G, B): a lower clip level where the image's own values say the
	 * sensor saturates below full scale (core/saturation.h); 0 (the default): none.
	 * Tested on the image's values like clip_level; the lower of the two applies. */
	float clip_rgb[3];
	int threads;    /* 0: online CPUs */
	int block_rows; /* 0: automatic (kg_est_job) */
	kg_est_isa isa;
	/* Rows done / total and throughput for images of KG_APPLY_PROGRESS_PIXELS or
	 * more; NULL: silent. */
	FILE *progress;
	/* Written as the cube's ENVI "description" (no braces), or NULL. */
	const char *description;
	/* kg_estimate_rows only: called with each finished block, in row order from the
	 * calling thread, before it is written: its pixel flags (block->mask) and the
	 * image's own values of its pixels (raw: 3 per pixel, before pre). NULL: none. An
	 * error it returns stops the run, with nothing written. */
	int (*observe)(void *user, const kg_est_block *block, const float *raw, kg_err *err);
	void *observe_user;
} kg_apply_options;

/* pre NULL, clip_level 0.999, threads 0, block_rows 0, isa AUTO, progress NULL,
 * description NULL, observe NULL. */
void kg_apply_options_init(kg_apply_options *o);

/* A side file of an output: the output name without its extension (".hdr", ".img"
 * or whatever follows the last '.' of the last path component) followed by suffix,
 * e.g. ("labels.hdr", ".json") -> "labels.json". Caller frees *out. */
int kg_apply_side_path(const char *out_path, const char *suffix, char **out, kg_err *err);

/* Estimate a 3-channel image (kg_image_read, 0..1 scale) into the cube out_hdr in
 * format (F32_BSQ, F32_BIP, F16_BSQ, F16_BIP or WEIGHTS; weights need a kernel with
 * a basis) plus its mask file. Refused (KG_EINVAL): an image that is not 3-channel
 * (a raw Bayer frame needs demosaicing first; the message says so), and an image of
 * which every pixel is flagged (clipped or non-finite: the message gives the counts),
 * before anything is written. stats may be NULL. */
int kg_estimate_image(const kg_est_kernel *k, const kg_image *img, kg_est_format format,
                      const kg_apply_options *opt, const char *out_hdr,
                      kg_est_stats *stats, kg_err *err);
/* The same from rows (a file read top to bottom, a correction chain): memory stays
 * bounded whatever the image's size. The all-flagged refusal comes after the run,
 * with the outputs dropped before they get their names. */
int kg_estimate_rows(const kg_est_kernel *k, const kg_row_source *src, kg_est_format format,
                     const kg_apply_options *opt, const char *out_hdr,
                     kg_est_stats *stats, kg_err *err);

/* The basis of a kernel (61 x K, row-major) and its mean (61 values, zeros when it
 * has none), i.e. what a consumer of a weights cube needs for s = mean + B w.
 * KG_EINVAL when the kernel has no basis. */
int kg_est_kernel_basis(const kg_est_kernel *k, double *basis, double *mean, kg_err *err);

/* "pixels N, clipped N (p %), non-finite N (p %), clamped N (p %), flagged N (p %)"
 * into buf; flagged (clipped or non-finite) pixels are NaN in a cube and unclassified
 * in a label map. */
void kg_est_stats_format(const kg_est_stats *s, char *buf, size_t size);

/* The materials a scene declares, with their spectra. */
typedef struct kg_est_material_set {
	int n;
	kg_est_material *materials; /* n entries; name and spectrum point into the set */
	kg_spectrum *spectra;       /* reflectance at the set's angle */
	char (*names)[KG_EST_CLASS_NAME_MAX];
	double angle_deg;
	const kg_material **mats; /* the library's entries (the library must outlive the set),
	                             NULL in a set built by hand */
} kg_est_material_set;

/* The reflectance of library materials at incidence angle_deg (0..90, 0 = normal)
 * (kg_material_reflectance): all of the library in file order when nonly == 0, else
 * exactly the ones named in only, in that order. Unknown or repeated names, and more
 * than KG_EST_MAX_MATERIALS, are refused naming them and the library's materials.
 * `library` names the library in messages (may be NULL). */
int kg_est_material_set_new(const kg_material_library *lib, const char *library,
                            const char *const *only, int nonly, double angle_deg,
                            kg_est_material_set **out, kg_err *err);
void kg_est_material_set_free(kg_est_material_set **set);

/* Per class of a label map. */
typedef struct kg_class_summary {
	char name[KG_EST_CLASS_NAME_MAX];
	uint64_t pixels;
	double fraction; /* of all pixels of the image */
	/* The spectrum of the class's mean RGB: for the (linear) pca kernel the mean of
	 * the pixels' unclamped spectra, then negative bands set to 0. NaN if empty. */
	double mean_spectrum[KG_NBANDS];
	/* The margin to the runner-up (confidence band) over the class's pixels: mean,
	 * median and 5th percentile (nearest rank). NaN if empty; +Inf with one material. */
	double margin_mean, margin_median, margin_p5;
} kg_class_summary;

typedef struct kg_classify_result {
	int nclasses;              /* materials; class j + 1 of the label map */
	kg_class_summary *classes; /* nclasses entries */
	uint64_t unclassified;     /* flagged pixels, label 0 */
	uint64_t unknown;          /* label nclasses + 1: no declared material explains them */
	uint64_t background;       /* label nclasses + 2: masked out or below the level */
	double unknown_threshold;  /* the bound used (+Inf when the test was off) */
	int dof;                   /* its degrees of freedom */
	int nregions;              /* camera space: regions decided (0: none formed) */
	kg_est_stats stats;
} kg_classify_result;

void kg_classify_result_free(kg_classify_result *r);

/* What LABELS.json records about where the labels came from (each may be NULL). */
typedef struct kg_classify_info {
	const char *calib;     /* the camera file */
	const char *materials; /* the material library */
	const char *method;    /* e.g. "pca" */
	const char *image;     /* the input image */
	const char *variance;  /* the variance image, if one was given */
	const char *mask;      /* the mask, if one was given */
	const json_t *identity; /* the object's identity (kogei process), copied into
	                         * LABELS.json as "identity", or NULL */
	const json_t *spectral_uncertainty; /* the calibration's per-band uncertainty of an
	                                     * estimate (kogei process), copied into
	                                     * LABELS.json as "spectral_uncertainty", or NULL */
} kg_classify_info;

/* How a label map refuses pixels instead of naming a wrong material.
 *
 * Background: a pixel the mask marks 0, or whose largest channel (on the image's
 * 0..1 full scale, before pre) is below background_level, is labelled background.
 *
 * Unknown: the pixel's best material j (by the distance) must explain it:
 * kg_est_classifier_chi2 <= unknown_threshold, with sigma_w = G sigma_rgb G^T, G =
 * A_w P the kernel's K x 3 weight matrix (pca: M M2) times pre, and sigma_rgb
 * diagonal, per channel c of the pixel's values rho_c:
 *   variance_c / frames + (residual_relative rho_c)^2                 with variance,
 *   noise_floor^2 + (noise_relative rho_c)^2 + (residual_relative rho_c)^2  without.
 * variance is what acquire records: the per-pixel variance of the single frames
 * (3 channels, the image's size and 0..1 scale, squared), of which the mean of
 * `frames` frames has 1 / frames. residual_relative is the calibration's relative
 * model error (kg_camera_calib residual_relative: ||rho0 - M2 rho_r||_F / ||rho0||_F),
 * a floor proportional to the pixel's level. The statistic of a correctly explained
 * pixel is chi-square with the classifier's dof, so unknown_threshold 0 means the
 * 99.9 % point (1 in 1000 explained pixels called unknown when the noise model
 * holds). The 61-band form of the test is the same number: the estimate's noise
 * lies in span B (sigma_s = B sigma_w B^T), and the part outside is o_j.
 *
 * Precedence: masked-out pixels are background whatever else they are; then flagged
 * pixels (non-finite, clipped) are unclassified; then low signal is background; then
 * the unknown test. The labels of the remaining pixels, and their confidences, are
 * exactly those of the label kernel (reference or optimised: the refusal stage is
 * the same code after either). */
typedef struct kg_classify_options {
	kg_est_distance distance;
	const kg_row_source *variance; /* 3 channels, or NULL: the noise model below */
	int frames;               /* frames averaged into the image, >= 1 */
	double noise_relative;    /* noise model without a variance image */
	double noise_floor;
	double residual_relative; /* calibration model error, >= 0 */
	double unknown_threshold; /* > 0; 0: the 99.9 % point; INFINITY: no unknown test */
	double background_level;  /* 0..1; 0: no low-signal test */
	const kg_row_source *mask; /* 1 channel, the image's size; 0 = background, or NULL */
	int preview_no_legend;    /* 1: the preview PNG is the map alone (a page that shows
	                             it carries the legend itself, e.g. kogei process's
	                             report) */
	const char *record_dir;   /* the labels .json records its files relative to this
	                             folder when they lie below it (kogei process: its staging
	                             folder, so the paths name the files in the final OUTDIR);
	                             NULL: as written */
} kg_classify_options;

/* Defaults: distance plain, no variance (the noise model: noise_relative 0.01 and
 * noise_floor 0.002, i.e. 1 % of the level plus half a step of an 8-bit scale),
 * frames 1, residual_relative 0 (callers pass their calibration's), unknown_threshold
 * 0 (the 99.9 % point), background_level 0.01 (1 % of full scale), no mask. */
void kg_classify_options_init(kg_classify_options *o);

/* Classify every pixel of a 3-channel image among the materials of set (eq. 11 in
 * the K-dim subspace of kernel k, which must have a basis) with the refusals of
 * copt (NULL: kg_classify_options_init), and write the label map out_hdr with its
 * side files (see above). The unknown test needs a linear kernel (pca), not a LUT.
 * Refused (KG_EINVAL, naming both sizes or the bad value): a variance image or mask
 * that does not match the image, a variance that is negative or not finite, bad
 * option values, an image of which every pixel is flagged. res (may be NULL) receives
 * the summary; free it with kg_classify_result_free. Memory does not grow with the
 * image: the margins' exact median and 5th percentile come from a histogram of their
 * high 16 bits kept while classifying and a second pass over the written confidence
 * file for the low bits. */
int kg_classify_image_opts(const kg_est_kernel *k, const kg_est_material_set *set,
                           const kg_image *img, const kg_apply_options *opt,
                           const kg_classify_options *copt, const kg_classify_info *info,
                           const char *out_hdr, kg_classify_result *res, kg_err *err);
/* The same from rows (see kg_estimate_rows); the variance and mask of copt are row
 * sources read alongside. */
int kg_classify_rows(const kg_est_kernel *k, const kg_est_material_set *set,
                     const kg_row_source *src, const kg_apply_options *opt,
                     const kg_classify_options *copt, const kg_classify_info *info,
                     const char *out_hdr, kg_classify_result *res, kg_err *err);

/* kg_classify_image_opts with the distance given and nothing refused: no unknown
 * test, no background level, no mask (the classes unknown and background exist in
 * the label map but stay empty). */
int kg_classify_image(const kg_est_kernel *k, const kg_est_material_set *set,
                      kg_est_distance distance, const kg_image *img,
                      const kg_apply_options *opt, const kg_classify_info *info,
                      const char *out_hdr, kg_classify_result *res, kg_err *err);

/* ==== Camera-space label maps (labels_cam.c) =====================================
 *
 * The default method of kogei classify and kogei process: each pixel matched in the
 * reference camera's space (kg_cs_*) with its own noise, over the declared materials,
 * incidence angles and intensities; materials the capture's noise cannot tell apart
 * per pixel merged into compound classes "a|b"; regions decided on their pooled
 * likelihood. Files (OUT = LABELS.hdr, stem = OUT without its extension):
 *   OUT                    ENVI Classification, uint8: 0 unclassified (flagged), then
 *                          the classes (a material, or a compound "a|b"), "unknown",
 *                          "background"
 *   <stem>_confidence.hdr  float32, 4 bands BIP: margin (noise-weighted d2 of the
 *                          runner-up class minus the chosen class's), posterior of the
 *                          chosen class, the best material's fitted angle (degrees) and
 *                          intensity; NaN where no class was given
 *   <stem>_mask.hdr        pixel flags, as for estimate
 *   <stem>_regions.hdr     uint32 region number per pixel (0: none), connected
 *                          components of the classes (not written with a user map)
 *   <stem>_regions.csv     region,pixels,class,label,posterior,mean_d2: every region
 *   <stem>_materials.hdr   ENVI Classification, uint8: per pixel the label its region
 *                          was decided (the table's: a material, a compound class left
 *                          unresolved, or "unknown"); pixels in no region keep their
 *                          class. Classes: OUT's, then the materials regions resolved
 *                          to within a compound class (not written with a user map)
 *   <stem>.json            as for classify, plus camera_space (the model, the noise
 *                          survey, the unknown bound), separability (the pairs' table),
 *                          merges, each class's members, regions (those of 100 pixels
 *                          or more)
 *   <stem>.png             preview
 *   COMP.hdr               (composition_hdr) float32, 6 bands BIP: ag, cu, au
 *                          fractions, sd_ag, sd_cu, sd_au; NaN where not fitted; au is
 *                          NaN where its sd is not below the declared materials' range
 *                          of gold fractions (gold is not reported where the data
 *                          cannot place it) */
typedef struct kg_classify_camera {
	const double *response;   /* F, 3 x 61 row-major: the reference camera's response */
	char response_source[32]; /* where it came from, for LABELS.json */
	double site_to_ref[9];    /* M2: reference reading = M2 site reading */
	/* The calibration residual's relative covariance: a reading of mean square level
	 * l^2 = |x|^2 / 3 carries l^2 calib_cov of model error (kg_camera_residual_cov). */
	double calib_cov[9];
	double angle_from, angle_to, angle_step; /* degrees, 0 <= from <= to < 90 */
	double intensity_lo, intensity_hi;       /* the unknown scale of the geometry */
	double merge_distance; /* 0: KG_CS_MERGE_DISTANCE; negative: no merges */
	int regions;           /* connected components decided on the pooled likelihood */
	/* The noise survey before the run: a second reader of the image and of its
	 * variance (NULL: the noise model at mid intensity). */
	const kg_row_source *survey, *survey_variance;
	/* User regions: 1 channel of whole numbers (0: none, up to 65535), the image's
	 * size; replaces the connected components. */
	const kg_row_source *region_map;
	const char *region_map_name;
	double region_scale; /* the map's values times this are the region numbers: 2^bits - 1
	                        for an integer image read on the 0..1 scale, 1 for a float
	                        one; 0 means 1 */
	/* Composition: the library's pure silver, copper and gold (in that order; NULL: no
	 * composition), and where to write its cube (NULL: LABELS.json and the regions'
	 * table only). Pixels whose best material is made of these metals get their Ag,
	 * Cu and Au fractions (non-negative, summing to 1; the alloy model is linear in
	 * them) fitted at the fitted angle, with Cramer-Rao standard deviations. */
	const kg_material *metals[3];
	const char *composition_hdr;
	/* sha256 of the reference calibration the site calibration was fitted against
	 * (kg_camera_reference_sha256), or NULL: a declared material's coupon template
	 * learned through another reference is refused */
	const char *reference_sha256;
	/* 1: no neutral-diffuse alternative. By default a pixel that a flat reflectance
	 * (at any level: F times a constant spectrum) fits better than every declared
	 * material is `background` (a grey card, paper, cloth), not the nearest material. */
	int no_neutral;
} kg_classify_camera;

/* 1 when class name cls ("a", or a compound "a|b|c") holds material m. */
int kg_class_holds(const char *cls, const char *m);

/* M2 identity, angles 0-70 every 5 degrees, intensity 0.3-1.0, merge distance 0
 * (the default), regions on, no survey, no region map. */
void kg_classify_camera_init(kg_classify_camera *c);

/* Camera-space label map of src among the materials of set (from
 * kg_est_material_set_new: it needs the library's entries). copt gives the noise
 * (variance and frames, or the noise model), the mask, the background level and the
 * unknown bound (0: the 99.9 % point of chi-square for the best material's d2, with 2
 * degrees of freedom when the intensity is searched (the 3 channels less the fitted
 * intensity; the angle, weakly determined, is not counted), 3 when it is fixed); its
 * distance is not used. k, the site's pca kernel, gives the classes'
 * mean spectra (may be NULL: no spectra). Memory stays bounded (regions: at most
 * 2^20 runs of a class, above which no regions are formed and LABELS.json says so). */
int kg_classify_camera_rows(const kg_est_kernel *k, const kg_est_material_set *set,
                            const kg_classify_camera *cam, const kg_row_source *src,
                            const kg_apply_options *opt, const kg_classify_options *copt,
                            const kg_classify_info *info, const char *out_hdr,
                            kg_classify_result *res, kg_err *err);

/* ==== end of apply.c ============================================================ */

#endif
