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
 *     (Finlayson, Mackiewicz & Hurlbert 2015, IEEE TIP 24(5)). The paper's
 *     A = B M M2, direct linear regression and Wiener estimation are all KG_EST_LINEAR;
 *     the fitting is done in calib/, which hands the matrices over.
 *   - LUT kernels: a grid of N^3 nodes over [lo, hi]^3 holding the output of any
 *     matrix kernel, read with trilinear interpolation.
 * A kernel made with a K-dimensional basis B (61 x K, orthonormal columns, and an
 * optional mean for centred PCA) produces either the spectrum s = mean + B w or the
 * K weights w themselves, and can feed the material classifier (DESIGN.md section 1,
 * step 4, eq. 11), which works on w alone.
 *
 * Every kernel has a plain C reference implementation and, on x86-64 CPUs with AVX2
 * and F16C, an optimised one. Both produce bit-identical output: they perform the same
 * IEEE operations in the same order (no FMA contraction; estimate/ is built with
 * -ffp-contract=off), and the F16C conversion rounds exactly like kg_f16_from_f32.
 * Output is also bit-identical for every block size and thread count: each pixel is
 * computed independently of its neighbours.
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
#define KG_EST_MAX_MATERIALS 254 /* labels 1..254 fit in a byte beside KG_EST_LABEL_NONE */
#define KG_EST_LUT_MAX_N 65

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

/* Which implementation runs. AUTO picks the best the CPU supports. */
typedef enum kg_est_isa {
	KG_EST_ISA_AUTO,
	KG_EST_ISA_C,    /* the reference kernels */
	KG_EST_ISA_AVX2, /* AVX2 + F16C; KG_ENOTSUP when the CPU lacks them */
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

/* Material classification in the K-dim subspace (DESIGN.md section 1, step 4). */
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

#endif
