/* bench/: speed against error for every estimation method (issue 3, item 5).
 *
 * Error. A camera (spectral sensitivities) under an illuminant photographs a training
 * chart and a different test set (sim/, optionally with sensor noise); every method is
 * fitted on the training chart (calib/) and evaluated through its estimate/ kernel on
 * the test set's camera values. Metrics compare the estimated with the true
 * reflectance of each test sample: spectral RMSE over the 61 bands, GFC, and CIEDE2000
 * between the CIE 1931 2 degree XYZ of the two under D65 and under A (mean and 95th
 * percentile).
 *
 * Speed. Each method's kernel runs over a synthetic camera image through kg_est_run
 * (the path `kogei estimate` takes) for each output format and thread count; the
 * median of repeated runs into one reused output buffer gives Mpix/s and GB/s of
 * output. In the same run the machine's limit is measured: writing the same number of
 * output bytes into the same buffer with non-temporal stores on as many threads.
 *
 * Methods compared (kg_bench_method): the paper's PCA with K = 3 and with K chosen by
 * leave-one-out, direct linear regression, Wiener estimation, root-polynomial
 * regression of degree 2 and 3, and a 33^3 LUT built from the K = 3 PCA kernel. */
#ifndef KG_BENCH_H
#define KG_BENCH_H

#include <stddef.h>
#include <stdint.h>

#include "kg_calib.h"
#include "kg_sim.h"

typedef enum kg_bench_method {
	KG_BENCH_PCA3,
	KG_BENCH_PCA_AUTO,
	KG_BENCH_LINEAR,
	KG_BENCH_WIENER,
	KG_BENCH_ROOTPOLY2,
	KG_BENCH_ROOTPOLY3,
	KG_BENCH_LUT33,
	KG_BENCH_NMETHODS
} kg_bench_method;

#define KG_BENCH_LUT_N 33
/* Exposure of the simulated captures: the perfect diffuser's brightest channel. */
#define KG_BENCH_WHITE_LEVEL 0.9

/* "pca3", "pca-auto", "linear", "wiener", "rootpoly2", "rootpoly3", "lut33-pca3". */
const char *kg_bench_method_name(kg_bench_method m);

/* ---- error ---------------------------------------------------------------------- */

/* CIE XYZ weights and whites of the two illuminants the colour differences use. */
typedef struct kg_bench_colour {
	kg_xyz_weights d65, a;
	kg_xyz white_d65, white_a;
} kg_bench_colour;

int kg_bench_colour_init(kg_bench_colour *c, kg_err *err);

typedef struct kg_bench_metrics {
	int n;               /* test samples */
	double rmse;         /* mean spectral RMSE */
	double gfc;          /* mean GFC */
	double de_d65_mean, de_d65_p95;
	double de_a_mean, de_a_p95;
} kg_bench_metrics;

/* The 95th (or any) percentile of v[0..n-1] by linear interpolation between order
 * statistics (position p (n - 1)); v is sorted in place. p = 0.5 is the median. */
double kg_bench_percentile(double *v, int n, double p);

/* Metrics of est against truth over n samples. */
int kg_bench_metrics_compute(const kg_bench_colour *c, const kg_spectrum *truth,
                             const kg_spectrum *est, int n, kg_bench_metrics *out,
                             kg_err *err);

/* One train -> test experiment. noise NULL or disabled: noise-free readings. The
 * training readings are drawn with `seed`, the test readings with seed + 1. */
typedef struct kg_bench_case {
	const kg_sim_camera *camera;
	const kg_spectrum *illuminant; /* relative SPD on the grid */
	const kg_patchset *train;      /* spectra */
	const kg_patchset *test;       /* spectra */
	const kg_sim_noise *noise;
	uint64_t seed;
	double wiener_sigma;           /* wiener's noise prior (0..1 scale), > 0 */
} kg_bench_case;

typedef struct kg_bench_error_row {
	char camera[128];
	char train[32], test[32];
	int noisy;
	int K_auto;                      /* K chosen by leave-one-out */
	int available[KG_BENCH_NMETHODS];
	char note[KG_BENCH_NMETHODS][160]; /* why a method is unavailable */
	kg_bench_metrics m[KG_BENCH_NMETHODS];
} kg_bench_error_row;

/* Simulate, fit every method and evaluate it on the test set. row->camera, train and
 * test are left for the caller to name. */
int kg_bench_error_case(const kg_bench_colour *c, const kg_bench_case *bc,
                        kg_bench_error_row *row, kg_err *err);

/* Fit the reference calibration on spectra and camera values (rgb[3 * i + c]) with
 * K = basis (0: chosen by leave-one-out). The training chart is its own field chart. */
int kg_bench_fit(const kg_patchset *spectra, const double *rgb, int basis,
                 double wiener_sigma, kg_reference **out, kg_err *err);

/* The estimate/ kernel of every method from a K = 3 fit and a K = auto fit; an
 * unavailable method gives NULL (with its reason in note[m] when note is not NULL). */
int kg_bench_kernels_new(const kg_reference *ref3, const kg_reference *ref_auto,
                         kg_est_kernel *k[KG_BENCH_NMETHODS],
                         char (*note)[160], kg_err *err);
void kg_bench_kernels_free(kg_est_kernel *k[KG_BENCH_NMETHODS]);

/* ---- synthetic inputs (tests; the speed part when ../shared/reference is absent) -- */

/* n smooth reflectance spectra (sums of Gaussian bumps over a base level, within
 * 0.02..0.95), ids "S1".."Sn", deterministic for a seed. */
int kg_bench_synthetic_spectra(int n, uint64_t seed, kg_patchset **out, kg_err *err);
/* A camera with Gaussian sensitivities peaking at 600, 540 and 450 nm. */
void kg_bench_synthetic_camera(kg_sim_camera *cam);

/* ---- speed ---------------------------------------------------------------------- */

typedef struct kg_bench_speed_row {
	kg_bench_method method;
	kg_est_format format;
	kg_est_isa isa; /* the path measured: KG_EST_ISA_C, _AVX2 or _AVX512 */
	int threads;
	double bytes_per_pixel; /* output bytes (labels: label + confidence) */
	double seconds;         /* median */
	double mpix_s, gb_s;
	double limit_gb_s;      /* non-temporal writes of the same bytes on as many threads,
	                         * runs alternating with the kernel's: median */
	double fraction;        /* gb_s / limit_gb_s */
} kg_bench_speed_row;

/* The limit of one (bytes per pixel, threads) pair over the speed rows that share it. */
typedef struct kg_bench_limit_row {
	double bytes_per_pixel;
	int threads;
	int measurements; /* speed rows it was measured beside */
	double gb_s;      /* median of their limits */
} kg_bench_limit_row;

/* ---- timing (also used by kogei-bench-kernels) ----------------------------------- */

/* Seconds on CLOCK_MONOTONIC. */
double kg_bench_now(void);
/* Run argv (argv[0] a path) and wait: its exit status, -1 when it could not run or
 * did not exit; quiet sends its output to /dev/null. */
int kg_bench_run_program(char *const *argv, int quiet);
/* Seconds to write `bytes` into buf with non-temporal stores on `threads` threads
 * (at most 64), one contiguous share each; the threads are created for the call, as
 * kg_est_run creates its pool for each run. The bytes are those of float 0.5. */
double kg_bench_stream_seconds(void *buf, size_t bytes, int threads);
/* How: SSE2 non-temporal stores, or memset where they are not built in. */
const char *kg_bench_stream_kind(void);

/* "f32-bsq", "f32-bip", "f16-bsq", "f16-bip", "weights", "labels". */
const char *kg_bench_format_name(kg_est_format f);
/* "c", "avx2+fma", "avx512" ("auto" for KG_EST_ISA_AUTO). */
const char *kg_bench_isa_name(kg_est_isa isa);
/* Whether the CPU runs path isa (a one-pixel kg_est_run; C always). */
int kg_bench_isa_available(kg_est_isa isa);

/* ---- camera-space matching --------------------------------------------------------- */

/* kg_cs_match_block_method over camspace_mpix Mpix of noisy readings of the library's
 * materials (bench_camspace.c says how they are made). A path is one method in one
 * implementation; a row, one path on one thread count, timed with best, both
 * distances, angle and intensity written. */
typedef struct kg_bench_camspace_path {
	kg_cs_method method;
	kg_est_isa isa;      /* KG_EST_ISA_C, _AVX2 or _AVX512 */
	int supported;       /* the CPU has the extension: measured */
	int identical;       /* the same bytes as its method's C reference, every output */
	double labels_agree; /* share of pixels with the exact C reference's label */
	double all_agree;    /* share of pixels whose every output (each material's distance
	                        included) is the exact C reference's, bit for bit */
} kg_bench_camspace_path;

typedef struct kg_bench_camspace_row {
	int path; /* index into kg_bench_camspace.paths */
	int threads;
	double seconds; /* median */
	double mpix_s;
} kg_bench_camspace_row;

#define KG_BENCH_CS_PATHS 6
typedef struct kg_bench_camspace {
	long pixels;
	int materials, angles;
	double angle_to, lo, hi; /* angles 0 to angle_to degrees, intensities lo to hi */
	kg_bench_camspace_path paths[KG_BENCH_CS_PATHS];
	double accuracy;         /* exact C labels equal to the material a reading was drawn from */
	double accuracy_quad;    /* the same for the quadratic C reference */
	long refused;            /* KG_CS_NO_MATCH */
	int nrows;
	kg_bench_camspace_row *rows;
} kg_bench_camspace;

/* ---- the whole benchmark --------------------------------------------------------- */

typedef void (*kg_bench_progress_fn)(void *user, const char *line);

typedef struct kg_bench_config {
	const char *reference_dir; /* ../shared/reference; missing: error part skipped */
	const char *materials;     /* material library for the label output (NULL: the
	                            * classifier uses test spectra as materials) */
	int quick;
	double mpix;               /* image size in Mpix */
	int reps;                  /* timed repetitions per measurement */
	const int *threads;        /* thread counts */
	int nthreads;
	int nmaterials;            /* classifier size */
	int run_error, run_speed, run_camspace;
	double camspace_mpix;      /* pixels of the camera-space rows, in Mpix */
	double camspace_step;      /* their model's angle step, degrees (5) */
	const char *command;       /* the command line, for the report */
	kg_bench_progress_fn progress;
	void *progress_user;
} kg_bench_config;

/* Full bench: 12 Mpix, 5 repetitions, threads 1 and 2, 16 materials, camera-space
 * rows on 1 Mpix. quick: 2 Mpix and 3 repetitions. */
void kg_bench_config_default(kg_bench_config *c, int quick);

typedef struct kg_bench_results {
	char command[1024];
	char machine[256];
	char date[64];
	int quick;
	int width, height, reps, nmaterials;
	char speed_calibration[256]; /* what the speed kernels were fitted on */
	char stream_kind[64];

	int error_skipped;
	char error_note[512];
	int nerror;
	kg_bench_error_row *error;
	kg_sim_noise noise;
	uint64_t seed;
	double wiener_sigma;

	int nspeed;
	kg_bench_speed_row *speed;
	int nlimit;
	kg_bench_limit_row *limit;
	kg_bench_camspace camspace; /* nrows 0: not run */
	double seconds_error, seconds_speed, seconds_camspace;
} kg_bench_results;

int kg_bench_run(const kg_bench_config *cfg, kg_bench_results **out, kg_err *err);
void kg_bench_results_free(kg_bench_results **r);

/* bench.md, bench.json and pareto.png into dir (created if needed). */
int kg_bench_write_report(const kg_bench_results *r, const char *dir, kg_err *err);

#endif
