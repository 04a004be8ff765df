/* kogei-bench-kernels: throughput of the per-pixel estimation kernels against the
 * machine's limit for writing the same bytes.
 *
 * A synthetic image (default 12 Mpix, 4000 pixels wide, smooth gradients with noise)
 * goes through every method
 * and output format at 1 and 2 threads into one reused, pre-faulted buffer (a fresh
 * 3 GB buffer would cost more in page faults than the kernels do). In the same run
 * the limit is measured: the same number of output bytes written with non-temporal
 * stores by 1 and 2 threads. Each figure is the median of several repetitions
 * (CLOCK_MONOTONIC). Markdown goes to stdout, JSON to --json.
 *
 * Each repetition times the limit and then the kernel, back to back, so that a ratio
 * compares runs under the same conditions (the machine drifts between sessions and
 * within one); the figures are the medians of each.
 *
 *   kogei-bench-kernels [--mpix N] [--reps N] [--quick] [--isa auto|c|avx2|avx512]
 *                       [--methods N] [--output NAME] [--json PATH]
 * --methods N keeps the first N methods (1: the linear kernel only); --output NAME
 * only the output of that name (e.g. "f16 BSQ"). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_bench.h"
#include "kg_estimate.h"

#define WIDTH 4000
#define MAX_REPS 31

/* ---- the model ------------------------------------------------------------- */

static uint64_t rng_state = 0x2545f4914f6cdd1dull;
static double uniform(double lo, double hi)
{
	rng_state ^= rng_state << 13;
	rng_state ^= rng_state >> 7;
	rng_state ^= rng_state << 17;
	return lo + (hi - lo) * (double)(rng_state >> 11) * 0x1p-53;
}

/* Three smooth orthonormal spectra (Gram-Schmidt on slow cosines). */
static void make_basis(double *b)
{
	for (int i = 0; i < 3; i++)
		for (int o = 0; o < KG_NBANDS; o++)
			b[o * 3 + i] = cos(3.14159265358979 * i * (o + 0.5) / KG_NBANDS);
	for (int i = 0; i < 3; i++) {
		for (int j = 0; j < i; j++) {
			double d = 0;
			for (int o = 0; o < KG_NBANDS; o++)
				d += b[o * 3 + i] * b[o * 3 + j];
			for (int o = 0; o < KG_NBANDS; o++)
				b[o * 3 + i] -= d * b[o * 3 + j];
		}
		double n = 0;
		for (int o = 0; o < KG_NBANDS; o++)
			n += b[o * 3 + i] * b[o * 3 + i];
		for (int o = 0; o < KG_NBANDS; o++)
			b[o * 3 + i] /= sqrt(n);
	}
}

typedef struct method {
	const char *name;
	kg_est_kernel *k;
} method;

typedef struct output {
	const char *name;
	kg_est_format format;
	size_t bytes_per_pixel; /* what is written, confidence included */
} output;

static void usage(FILE *f)
{
	fprintf(f, "usage: kogei-bench-kernels [--mpix N] [--reps N] [--quick] "
	           "[--isa auto|c|avx2|avx512] [--methods N] [--output NAME] [--json PATH]\n"
	           "  --output: f32 BSQ, f32 BIP, f16 BSQ, f16 BIP, weights (K=3) or\n"
	           "  labels (16 materials); default every one\n");
}

int main(int argc, char **argv)
{
	double mpix = 12;
	int reps = 5, nmethods = 5;
	const char *only = NULL;
	const char *json_path = NULL;
	kg_est_isa isa = KG_EST_ISA_AUTO;
	kg_outfile json = {0};
	json_t *doc = NULL, *results = NULL;
	for (int i = 1; i < argc; i++) {
		if (!strcmp(argv[i], "--mpix") && i + 1 < argc)
			mpix = atof(argv[++i]);
		else if (!strcmp(argv[i], "--reps") && i + 1 < argc)
			reps = atoi(argv[++i]);
		else if (!strcmp(argv[i], "--quick")) {
			mpix = 2;
			reps = 3;
		} else if (!strcmp(argv[i], "--isa") && i + 1 < argc) {
			i++;
			isa = !strcmp(argv[i], "c")        ? KG_EST_ISA_C
			      : !strcmp(argv[i], "avx2")   ? KG_EST_ISA_AVX2
			      : !strcmp(argv[i], "avx512") ? KG_EST_ISA_AVX512
			                                   : KG_EST_ISA_AUTO;
		} else if (!strcmp(argv[i], "--methods") && i + 1 < argc)
			nmethods = atoi(argv[++i]);
		else if (!strcmp(argv[i], "--output") && i + 1 < argc)
			only = argv[++i];
		else if (!strcmp(argv[i], "--json") && i + 1 < argc)
			json_path = argv[++i];
		else if (!strcmp(argv[i], "--help")) {
			usage(stdout);
			return 0;
		} else {
			usage(stderr);
			return 2;
		}
	}
	if (!(mpix > 0 && mpix <= 100) || reps < 1 || reps > MAX_REPS || nmethods < 1 ||
	    nmethods > 5) {
		fprintf(stderr, "kogei-bench-kernels: --mpix 0..100, --reps 1..%d and --methods 1..5\n",
		        MAX_REPS);
		return 2;
	}
	int height = (int)(mpix * 1e6 / WIDTH + 0.5);
	if (height < 1)
		height = 1;
	size_t npix = (size_t)WIDTH * height;

	/* the paper's model: w = M M2 rho (K = 3), s = B w; root-polynomial fits map their
	 * terms to the same K weights; LUTs sample the degree-3 fit */
	double basis[KG_NBANDS * 3], m[3 * 13];
	make_basis(basis);
	for (int i = 0; i < 3 * 13; i++)
		m[i] = uniform(-0.6, 0.6);
	for (int i = 0; i < 3; i++)
		m[i * 3 + i] += 1.5;
	kg_err err = {{0}};
	method methods[5] = {{"linear (PCA-3, regression, Wiener)", NULL},
	                     {"root-polynomial 2", NULL},
	                     {"root-polynomial 3", NULL},
	                     {"LUT 17^3 (root-poly 3)", NULL},
	                     {"LUT 33^3 (root-poly 3)", NULL}};
	const kg_est_method kinds[3] = {KG_EST_LINEAR, KG_EST_ROOTPOLY2, KG_EST_ROOTPOLY3};
	for (int i = 0; i < 3; i++)
		if (kg_est_kernel_new(&(kg_est_desc){kinds[i], 3, m, NULL, basis, NULL}, &methods[i].k,
		                      &err) < 0)
			goto fail;
	if (kg_est_kernel_new_lut(methods[2].k, 17, 0, 1, &methods[3].k, &err) < 0 ||
	    kg_est_kernel_new_lut(methods[2].k, 33, 0, 1, &methods[4].k, &err) < 0)
		goto fail;

	/* 16 materials for the label output */
	enum { NMAT = 16 };
	double spectra[NMAT * KG_NBANDS];
	kg_est_material mats[NMAT];
	char names[NMAT][16];
	for (int j = 0; j < NMAT; j++) {
		double a = uniform(0.1, 0.8), b = uniform(-0.3, 0.3), ph = uniform(0, 6.28);
		for (int o = 0; o < KG_NBANDS; o++)
			spectra[j * KG_NBANDS + o] = a + b * o / 60.0 + 0.1 * sin(o / 8.0 + ph);
		snprintf(names[j], sizeof(names[j]), "material-%d", j + 1);
		mats[j] = (kg_est_material){names[j], spectra + j * KG_NBANDS};
	}
	kg_est_classifier *cls[5] = {NULL};
	for (int i = 0; i < 5; i++)
		if (kg_est_classifier_new(methods[i].k, mats, NMAT, KG_EST_DIST_SCALE_FREE, &cls[i], &err) <
		    0)
			goto fail;

	const output outputs[] = {
	    {"f32 BSQ", KG_EST_F32_BSQ, 4 * KG_NBANDS},  {"f32 BIP", KG_EST_F32_BIP, 4 * KG_NBANDS},
	    {"f16 BSQ", KG_EST_F16_BSQ, 2 * KG_NBANDS},  {"f16 BIP", KG_EST_F16_BIP, 2 * KG_NBANDS},
	    {"weights (K=3)", KG_EST_WEIGHTS, 4 * 3},     {"labels (16 materials)", KG_EST_LABELS, 5},
	};
	const int nout = sizeof(outputs) / sizeof(outputs[0]);
	int known = !only;
	for (int o = 0; o < nout && !known; o++)
		known = !strcmp(outputs[o].name, only);
	if (!known) {
		fprintf(stderr, "kogei-bench-kernels: --output '%s': expected one of", only);
		for (int o = 0; o < nout; o++)
			fprintf(stderr, "%s '%s'", o ? "," : "", outputs[o].name);
		fprintf(stderr, "\n");
		return 2;
	}

	float *rgb = malloc(sizeof(float) * 3 * npix);
	size_t max_bytes = npix * 4 * KG_NBANDS;
	char *buf = aligned_alloc(64, (max_bytes + 63) & ~(size_t)63);
	float *conf = malloc(sizeof(float) * npix);
	if (!rgb || !buf || !conf) {
		fprintf(stderr, "kogei-bench-kernels: out of memory for %.1f Mpix\n", mpix);
		return 1;
	}
	/* smooth colour gradients plus noise: a photograph's spatial coherence matters to
	 * the LUTs, whose nodes then stay in cache */
	for (int y = 0; y < height; y++)
		for (int x = 0; x < WIDTH; x++)
			for (int c = 0; c < 3; c++)
				rgb[3 * ((size_t)y * WIDTH + x) + c] =
				    (float)(0.48 + 0.4 * sin(x / (150.0 + 40 * c) + y / (90.0 + 30 * c) + c) +
				            uniform(-0.02, 0.02));
	memset(buf, 0, max_bytes); /* fault the pages in once */
	memset(conf, 0, sizeof(float) * npix);

	fprintf(stderr, "kogei-bench-kernels: %d x %d = %.2f Mpix, %d repetitions, %s kernels, "
	        "limit by %s\n",
	        WIDTH, height, npix / 1e6, reps, kg_bench_isa_name(isa),
	        kg_bench_stream_kind());

	if (json_path) {
		if (kg_outfile_open(&json, json_path, 1, &err) < 0)
			goto fail;
		doc = json_pack("{s:s, s:i, s:i, s:i, s:s, s:[]}", "format", "kogei-bench-kernels/1",
		                "width", WIDTH, "height", height, "repetitions", reps, "kernels",
		                kg_bench_isa_name(isa), "results");
		results = json_object_get(doc, "results");
	}
	printf("| method | output | bytes/px | Mpix/s 1 thr | Mpix/s 2 thr | limit 1 thr | limit 2 "
	       "thr | of limit 1 thr | of limit 2 thr |\n");
	printf("|---|---|---:|---:|---:|---:|---:|---:|---:|\n");
	for (int mi = 0; mi < nmethods; mi++)
		for (int o = 0; o < nout; o++) {
			if (only && strcmp(outputs[o].name, only))
				continue;
			double speed[2], limit[2];
			for (int t = 1; t <= 2; t++) {
				kg_est_job job;
				kg_est_job_init(&job, methods[mi].k, outputs[o].format);
				job.classifier = cls[mi];
				job.threads = t;
				job.isa = isa;
				job.clip_level = 1.0f;
				double times[MAX_REPS], limits[MAX_REPS];
				kg_est_dest dest = {buf, outputs[o].format == KG_EST_LABELS ? conf : NULL, NULL};
				for (int r = 0; r < reps; r++) {
					limits[r] = kg_bench_stream_seconds(buf, npix * outputs[o].bytes_per_pixel, t);
					double t0 = kg_bench_now();
					if (kg_est_run(&job, rgb, WIDTH, height, &dest, NULL, &err) < 0)
						goto fail;
					times[r] = kg_bench_now() - t0;
				}
				speed[t - 1] = npix / 1e6 / kg_bench_percentile(times, reps, 0.5);
				limit[t - 1] = npix / 1e6 / kg_bench_percentile(limits, reps, 0.5);
			}
			printf("| %s | %s | %zu | %.1f | %.1f | %.1f | %.1f | %.2f | %.2f |\n", methods[mi].name,
			       outputs[o].name, outputs[o].bytes_per_pixel, speed[0], speed[1], limit[0], limit[1],
			       speed[0] / limit[0], speed[1] / limit[1]);
			fflush(stdout);
			if (results)
				json_array_append_new(results, json_pack(
					"{s:s, s:s, s:I, s:[f,f], s:[f,f], s:[f,f]}", "method", methods[mi].name,
					"output", outputs[o].name, "bytes_per_pixel",
					(json_int_t)outputs[o].bytes_per_pixel, "mpix_s", speed[0], speed[1],
					"limit_mpix_s", limit[0], limit[1], "fraction_of_limit",
					speed[0] / limit[0], speed[1] / limit[1]));
		}
	if (json_path) {
		if (json_dumpf(doc, json.fp, JSON_INDENT(2) | JSON_REAL_PRECISION(6)) != 0 ||
		    fputc('\n', json.fp) == EOF) {
			kg_fail(&err, KG_EIO, "%s: write failed", json_path);
			goto fail;
		}
		json_decref(doc);
		doc = NULL;
		if (kg_outfile_commit(&json, &err) < 0)
			goto fail;
	}
	printf("\nThreads: 1 and 2. Limit: the same bytes written with non-temporal stores. "
	       "Labels write 1 byte of label and 4 of confidence per pixel.\n");
	for (int i = 0; i < 5; i++) {
		kg_est_classifier_free(&cls[i]);
		kg_est_kernel_free(&methods[i].k);
	}
	free(rgb);
	free(buf);
	free(conf);
	return 0;
fail:
	fprintf(stderr, "kogei-bench-kernels: %s\n", err.msg);
	json_decref(doc);
	if (json.fp)
		kg_outfile_abort(&json);
	return 1;
}
