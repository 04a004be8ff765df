/* kogei-bench, the program behind `kogei bench`: speed against error of every
 * estimation method. `kogei bench ARGS` runs it as `kogei-bench ARGS`. */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_bench.h"
#include "kg_config.h"

#define MAX_THREAD_COUNTS 16

/* Exit status as every kogei command: 0 success, 1 bad input, 2 bad usage. */
enum { EXIT_INPUT = 1, EXIT_USAGE = 2 };

static const char usage_bench[] =
	"kogei bench [--quick] [-o DIR] [--threads-list N[,N...]] [--mpix N] [--reps N]\n"
	"            [--reference DIR] [--no-error] [--no-speed] [--no-camspace]\n"
	"            [--camspace-step DEG]\n"
	"  Speed against error of every method (pca K=3 and K=auto, linear, wiener,\n"
	"  rootpoly2, rootpoly3, a 33^3 LUT of pca).\n"
	"  Error: each method trained on ColorChecker 24 and tested on Munsell, and\n"
	"  trained on Munsell and tested on CIE 2017 CES, for four cameras under D65,\n"
	"  with and without sensor noise: spectral RMSE, GFC, mean and 95th-percentile\n"
	"  CIEDE2000 under D65 and A. Needs the reference data set of measured\n"
	"  spectra and camera sensitivities (--reference DIR, or $KOGEI_REFERENCE;\n"
	"  docs/bench.md lists its files); without it the error part is skipped.\n"
	"  Speed: Mpix/s of f32 BSQ, f16, weights and labels (16 materials) output on\n"
	"  an N Mpix image (default 12; --quick 2) for each thread count (default 1,2),\n"
	"  beside the machine's limit for writing the same bytes with non-temporal\n"
	"  stores. Median of --reps runs (default 5; --quick 3).\n"
	"  Camera-space matching: Mpix/s of kg_cs_match_block_method (the library's\n"
	"  materials, angles 0-70 every --camspace-step degrees (default 5: 15 angles),\n"
	"  1 Mpix of noisy readings), the exact and the quadratic method in C, AVX2 and\n"
	"  AVX-512 on each thread count, whether each is bit-identical to its method's C\n"
	"  reference, its labels' agreement with the exact C reference, and accuracy.\n"
	"  Writes DIR/bench.md, DIR/bench.json and DIR/pareto.png (DIR default\n"
	"  out/bench). Progress goes to standard error.";

static int usage_error(const char *fmt, const char *arg)
{
	fputs("kogei bench: ", stderr);
	fprintf(stderr, fmt, arg);
	fprintf(stderr, "\nusage: %s\n", usage_bench);
	return EXIT_USAGE;
}

static void progress(void *user, const char *line)
{
	(void)user;
	fprintf(stderr, "%s\n", line);
}

static int parse_threads(const char *text, int *t, int *n)
{
	*n = 0;
	const char *p = text;
	while (*p) {
		char *end;
		long v = strtol(p, &end, 10);
		if (end == p || v < 1 || v > 256 || *n == MAX_THREAD_COUNTS)
			return -1;
		t[(*n)++] = (int)v;
		if (*end == ',')
			end++;
		else if (*end)
			return -1;
		p = end;
	}
	return *n > 0 ? 0 : -1;
}

static char *command_line(int argc, char **argv)
{
	size_t len = strlen("kogei") + 1;
	for (int i = 0; i < argc; i++)
		len += strlen(argv[i]) + 1;
	char *s = malloc(len);
	if (!s)
		return NULL;
	strcpy(s, "kogei");
	for (int i = 0; i < argc; i++) {
		strcat(s, " ");
		strcat(s, argv[i]);
	}
	return s;
}

int main(int argc, char **argv)
{
	static const struct option opts[] = {
		{"quick", no_argument, NULL, 'q'},
		{"output", required_argument, NULL, 'o'},
		{"threads-list", required_argument, NULL, 't'},
		{"mpix", required_argument, NULL, 'p'},
		{"reps", required_argument, NULL, 'r'},
		{"reference", required_argument, NULL, 'R'},
		{"no-error", no_argument, NULL, 'E'},
		{"no-speed", no_argument, NULL, 'S'},
		{"no-camspace", no_argument, NULL, 'C'},
		{"camspace-step", required_argument, NULL, 'A'},
		{"help", no_argument, NULL, 'h'},
		{0, 0, 0, 0},
	};
	const char *dir = "out/bench", *threads_text = NULL, *reference = NULL;
	double mpix = 0, cs_step = 5;
	long reps = 0;
	int quick = 0, no_error = 0, no_speed = 0, no_camspace = 0;
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "o:h", opts, NULL)) != -1) {
		char *end;
		switch (c) {
		case 'q': quick = 1; break;
		case 'o': dir = optarg; break;
		case 't': threads_text = optarg; break;
		case 'R': reference = optarg; break;
		case 'E': no_error = 1; break;
		case 'S': no_speed = 1; break;
		case 'C': no_camspace = 1; break;
		case 'A':
			cs_step = strtod(optarg, &end);
			if (end == optarg || *end || !(cs_step >= 1 && cs_step <= 70))
				return usage_error("--camspace-step %s: expected degrees from 1 to 70", optarg);
			break;
		case 'p':
			mpix = strtod(optarg, &end);
			if (end == optarg || *end || !isfinite(mpix) || mpix <= 0 || mpix > 1000)
				return usage_error("--mpix %s: expected a number above 0, at most 1000",
				                   optarg);
			break;
		case 'r':
			reps = strtol(optarg, &end, 10);
			if (end == optarg || *end || reps < 1 || reps > 64)
				return usage_error("--reps %s: expected 1 to 64", optarg);
			break;
		case 'h': puts(usage_bench); return 0;
		default: return usage_error("%s", "bad option");
		}
	}
	if (optind != argc)
		return usage_error("unexpected argument '%s'", argv[optind]);

	kg_bench_config cfg;
	kg_bench_config_default(&cfg, quick);
	int threads[MAX_THREAD_COUNTS], nthreads = 0;
	if (threads_text) {
		if (parse_threads(threads_text, threads, &nthreads))
			return usage_error("--threads-list %s: expected thread counts 1-256 "
			                   "separated by commas, e.g. 1,2",
			                   threads_text);
		cfg.threads = threads;
		cfg.nthreads = nthreads;
	}
	if (mpix > 0)
		cfg.mpix = mpix;
	if (reps > 0)
		cfg.reps = (int)reps;
	cfg.run_error = !no_error;
	cfg.run_speed = !no_speed;
	cfg.run_camspace = !no_camspace;
	cfg.camspace_step = cs_step;

	char default_reference[4096];
	const char *env = getenv("KOGEI_REFERENCE");
	snprintf(default_reference, sizeof(default_reference), "%s/../shared/reference",
	         KG_SOURCE_ROOT);
	cfg.reference_dir = reference ? reference : (env && *env ? env : default_reference);
	char *materials = kg_data_path("materials/default.json");
	char *command = command_line(argc, argv);
	cfg.materials = materials;
	cfg.command = command;
	cfg.progress = progress;

	kg_err err = {{0}};
	kg_bench_results *r = NULL;
	int ret = materials && command ? 0 : kg_fail(&err, KG_ENOMEM, "out of memory");
	if (!ret) {
		fprintf(stderr, "kogei bench: %s; reference data %s\n",
		        quick ? "quick run" : "full run", cfg.reference_dir);
		ret = kg_bench_run(&cfg, &r, &err);
	}
	if (!ret)
		ret = kg_bench_write_report(r, dir, &err);
	if (!ret)
		printf("kogei bench: wrote %s/bench.md, %s/bench.json%s%s%s\n", dir, dir,
		       r->nspeed && r->nerror ? ", " : "", r->nspeed && r->nerror ? dir : "",
		       r->nspeed && r->nerror ? "/pareto.png" : "");
	kg_bench_results_free(&r);
	free(materials);
	free(command);
	if (ret) {
		fprintf(stderr, "kogei bench: %s\n", err.msg[0] ? err.msg : "failed");
		return EXIT_INPUT;
	}
	return 0;
}
