/* kogei-bench-labels: label accuracy against speed for the material classifiers on
 * the ten library materials as a photograph presents them (issue 14, item 8).
 *
 * Setup as the study of the issue: reference camera Nikon D5100, site camera Canon
 * EOS 5D Mark II, both under D65, calibrated on the ColorChecker 24 (BabelColor
 * average) through `kogei sim patches`, `kogei calib reference`, `kogei calib camera`
 * (../shared/reference; --reference DIR). Each scenario is a photograph of the ten
 * materials, one 64 x 64 block each (a region), every pixel at its own incidence
 * angle and intensity, read by the site camera with Gaussian noise of 1 % of the
 * white (40 dB), its variance given:
 *   known        30 degrees, intensity 1
 *   intensity    30 degrees, intensity uniform in 0.3-1.0
 *   angle        angle uniform in 0-70 degrees, intensity 1
 *   both         angle 0-70, intensity 0.3-1.0
 * Methods: eq. 11 plain and scale-free (spectra at 30 degrees: what the method
 * assumes), camera-space matching with the merges off (every material its own class)
 * and on (the default), the search ranges set to what the scenario leaves unknown, and
 * the default with the angles every 10 degrees instead of 5 (half the work).
 * Per pixel: the share of the pixels whose label holds their material (exact for
 * single materials, membership for a compound class); per region: the share of the
 * ten blocks (given as the region map) whose pooled decision holds their material;
 * classes: how many the label map has. Time: the wall time of `kogei classify`
 * (median of --reps runs) over the photograph's pixels, in Mpix/s.
 *
 *   kogei-bench-labels [--kogei PATH] [--reference DIR] [--reps N] [--keep DIR]
 *                      [-o OUT.md] */
#include <libgen.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "kg_bench.h"
#include "kg_calib.h"
#include "kg_config.h"

#define NMAT 10
#define BLOCK 256
#define COLS 5
#define SIGMA 0.009
#define MAX_REPS 9

static const char *mats[NMAT] = {
	"gold", "silver", "copper", "shakudo", "shibuichi-nami", "shibuichi-shiro",
	"shibuichi-jo", "shibuichi-nami-uchisanbu", "shibuichi-nami-sotosanbu", "urushi",
};

typedef struct scenario {
	const char *name, *what;
	double a0, a1, i0, i1;
} scenario;

static const scenario scenarios[] = {
	{"known", "known intensity, 30 deg", 30, 30, 1, 1},
	{"intensity", "unknown intensity (0.3-1.0)", 30, 30, 0.3, 1},
	{"angle", "unknown angle (0-70 deg)", 0, 70, 1, 1},
	{"both", "both unknown", 0, 70, 0.3, 1},
};


static uint64_t rng_state = 2026;
static double uniform(void)
{
	rng_state ^= rng_state << 13;
	rng_state ^= rng_state >> 7;
	rng_state ^= rng_state << 17;
	return ((rng_state >> 11) + 0.5) / 9007199254740992.0;
}
static double gauss(void)
{
	double u = uniform(), v = uniform();
	return sqrt(-2 * log(u)) * cos(2 * M_PI * v);
}

typedef struct result {
	int ok;
	double pixel_acc, region_acc, seconds, mpix_s;
	int classes;
} result;

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

/* Classify the scenario's photograph with args, `reps` times; score the last. */
static void measure(const char *kogei, const char *dir, char **args, int nargs, int reps,
                    const int *truth, int W, int H, int regions, result *res)
{
	memset(res, 0, sizeof(*res));
	char out[4200], csv[4200];
	snprintf(out, sizeof(out), "%s/labels.hdr", dir);
	snprintf(csv, sizeof(csv), "%s/labels_regions.csv", dir);
	char *argv[64];
	int n = 0;
	argv[n++] = (char *)kogei;
	argv[n++] = "classify";
	for (int i = 0; i < nargs; i++)
		argv[n++] = args[i];
	argv[n++] = "-o";
	argv[n++] = out;
	argv[n++] = "--quiet";
	argv[n++] = "--force";
	argv[n] = NULL;
	double t[MAX_REPS];
	for (int r = 0; r < reps; r++) {
		unlink(csv);
		double t0 = kg_bench_now();
		if (kg_bench_run_program(argv, 1) != 0)
			return;
		t[r] = kg_bench_now() - t0;
	}
	qsort(t, (size_t)reps, sizeof(double), cmp_double);
	res->seconds = t[reps / 2];
	res->mpix_s = (double)W * H / 1e6 / res->seconds;
	kg_envi *e = NULL;
	kg_err err = {{0}};
	float *lab = malloc(sizeof(float) * (size_t)W * H);
	if (!lab || kg_envi_open(out, &e, &err) ||
	    kg_envi_read(e, 0, 0, W, H, KG_LAYOUT_BIP, lab, &err)) {
		fprintf(stderr, "kogei-bench-labels: %s\n", err.msg);
		kg_envi_close(&e);
		free(lab);
		return;
	}
	long right = 0, total = 0;
	for (long i = 0; i < (long)W * H; i++) {
		int l = (int)lab[i];
		if (truth[i] < 0)
			continue;
		total++;
		right += l > 0 && l < e->meta.classes &&
		         kg_class_holds(e->meta.class_names[l], mats[truth[i]]);
	}
	res->classes = e->meta.classes - 3;
	res->pixel_acc = total ? (double)right / total : NAN;
	kg_envi_close(&e);
	free(lab);
	res->region_acc = NAN;
	FILE *fp = regions ? fopen(csv, "r") : NULL;
	if (fp) {
		char line[2048];
		int nreg = 0, rright = 0;
		while (fgets(line, sizeof(line), fp)) {
			unsigned id;
			unsigned long long px;
			char cls[256], label[256];
			if (sscanf(line, "%u,%llu,%255[^,],%255[^,],", &id, &px, cls, label) != 4 ||
			    id < 1 || id > NMAT)
				continue;
			nreg++;
			rright += kg_class_holds(label, mats[id - 1]);
			if (!kg_class_holds(label, mats[id - 1]))
				fprintf(stderr, "  region %u (%s) decided %s\n", id, mats[id - 1], label);
		}
		fclose(fp);
		res->region_acc = nreg ? (double)rright / NMAT : NAN;
	}
	res->ok = 1;
}

int main(int argc, char **argv)
{
	char kogei[4096], self[4096], reference[4096], out_md[4096] = "";
	const char *keep = NULL;
	int reps = 3;
	snprintf(self, sizeof(self), "%s", argv[0]);
	snprintf(kogei, sizeof(kogei), "%s/../cli/kogei", dirname(self));
	snprintf(reference, sizeof(reference), "%s/../shared/reference", KG_SOURCE_ROOT);
	for (int i = 1; i < argc; i++) {
		const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
		if (!strcmp(a, "--kogei") && v)
			snprintf(kogei, sizeof(kogei), "%s", argv[++i]);
		else if (!strcmp(a, "--reference") && v)
			snprintf(reference, sizeof(reference), "%s", argv[++i]);
		else if (!strcmp(a, "--reps") && v)
			reps = atoi(argv[++i]);
		else if (!strcmp(a, "--keep") && v)
			keep = argv[++i];
		else if (!strcmp(a, "-o") && v)
			snprintf(out_md, sizeof(out_md), "%s", argv[++i]);
		else {
			fprintf(stderr, "usage: kogei-bench-labels [--kogei PATH] [--reference DIR] "
			                "[--reps N] [--keep DIR] [-o OUT.md]\n");
			return 2;
		}
	}
	reps = reps < 1 ? 1 : reps > MAX_REPS ? MAX_REPS : reps;
	char chart[4300], refcam[4300], sitecam[4300];
	snprintf(chart, sizeof(chart), "%s/charts/colorchecker24_babelcolor_avg.csv", reference);
	snprintf(refcam, sizeof(refcam), "%s/cameras/Nikon_D5100.csv", reference);
	snprintf(sitecam, sizeof(sitecam), "%s/cameras/Canon_EOS_5D_Mark_II.csv", reference);
	if (access(chart, R_OK) || access(refcam, R_OK) || access(sitecam, R_OK)) {
		fprintf(stderr, "kogei-bench-labels: needs %s (the ColorChecker and the cameras)\n",
		        reference);
		return 77;
	}
	char dir[4096];
	if (keep) {
		snprintf(dir, sizeof(dir), "%s", keep);
		mkdir(dir, 0755);
	} else {
		snprintf(dir, sizeof(dir), "/tmp/kogei-bench-labels-XXXXXX");
		if (!mkdtemp(dir)) {
			perror("mkdtemp");
			return 1;
		}
	}
	char p_ref[4300], p_site[4300], p_refjson[4300], p_cam[4300], p_lib[4300];
	snprintf(p_ref, sizeof(p_ref), "%s/ref.cgats", dir);
	snprintf(p_site, sizeof(p_site), "%s/site.cgats", dir);
	snprintf(p_refjson, sizeof(p_refjson), "%s/ref.json", dir);
	snprintf(p_cam, sizeof(p_cam), "%s/cam.json", dir);
	snprintf(p_lib, sizeof(p_lib), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	char *steps[4][16] = {
		{kogei, "sim", "patches", "--spectra", chart, "--camera", refcam, "--illuminant", "D65",
		 "-o", p_ref, NULL},
		{kogei, "sim", "patches", "--spectra", chart, "--camera", sitecam, "--illuminant",
		 "D65", "-o", p_site, NULL},
		{kogei, "calib", "reference", "--spectra", chart, "--rgb", p_ref, "-o", p_refjson,
		 NULL},
		{kogei, "calib", "camera", "--reference", p_refjson, "--rgb", p_site, "--method", "pca",
		 "-o", p_cam, NULL},
	};
	for (int s = 0; s < 4; s++)
		if (kg_bench_run_program(steps[s], 1) != 0) {
			fprintf(stderr, "kogei-bench-labels: step %d of the calibration failed (%s)\n",
			        s + 1, kogei);
			return 1;
		}
	/* the site camera's weights: sensitivities times D65, white at 0.9 */
	kg_err err = {{0}};
	kg_sim_capture cap;
	kg_material_library *lib = NULL;
	if (kg_sim_capture_load(&cap, sitecam, "D65", 0.9, NULL, 0, &err) ||
	    kg_material_library_load(p_lib, &lib, &err)) {
		fprintf(stderr, "kogei-bench-labels: %s\n", err.msg);
		return 1;
	}
	const int W = COLS * BLOCK, H = 2 * BLOCK;
	int *truth = malloc(sizeof(int) * (size_t)W * H);
	kg_image *img = NULL, *var = NULL, *map = NULL;
	if (!truth || kg_image_new(W, H, 3, &img, &err) || kg_image_new(W, H, 3, &var, &err) ||
	    kg_image_new(W, H, 1, &map, &err)) {
		fprintf(stderr, "kogei-bench-labels: out of memory\n");
		return 1;
	}
	FILE *md = out_md[0] ? fopen(out_md, "w") : stdout;
	if (!md) {
		perror(out_md);
		return 1;
	}
	fprintf(md, "# Material labels: accuracy against speed\n\n"
	            "`kogei-bench-labels` (bench/bench_labels.c): the ten library materials, "
	            "%d x %d pixels each, reference Nikon D5100, site Canon EOS 5D Mark II, "
	            "D65, ColorChecker 24, 40 dB (sigma %.3f per channel, its variance given); "
	            "time: median of %d runs of `kogei classify` (whole command: reading, "
	            "survey, matching, writing) on %d x %d pixels, 2 threads.\n\n"
	            "| scenario | method | classes | per pixel | per region | Mpix/s |\n"
	            "|---|---|---:|---:|---:|---:|\n",
	        BLOCK, BLOCK, SIGMA, reps, W, H);
	for (size_t sc = 0; sc < sizeof(scenarios) / sizeof(scenarios[0]); sc++) {
		const scenario *S = &scenarios[sc];
		for (int y = 0; y < H; y++)
			for (int x = 0; x < W; x++) {
				size_t i = (size_t)y * W + x;
				int m = (y / BLOCK) * COLS + x / BLOCK;
				truth[i] = m;
				map->data[i] = (float)(m + 1) / 65535.0f;
				double th = S->a0 + (S->a1 - S->a0) * uniform();
				double a = S->i0 + (S->i1 - S->i0) * uniform();
				kg_spectrum r;
				kg_material_reflectance(kg_material_library_find(lib, mats[m]),
				                        th * M_PI / 180.0, &r, &err);
				double rgb[3];
				kg_sim_capture_mean(&cap, &r, rgb);
				for (int c = 0; c < 3; c++) {
					img->data[3 * i + c] = (float)(a * rgb[c] + SIGMA * gauss());
					var->data[3 * i + c] = (float)(SIGMA * SIGMA);
				}
			}
		char p_img[4300], p_var[4300], p_map[4300];
		snprintf(p_img, sizeof(p_img), "%s/%s.tif", dir, S->name);
		snprintf(p_var, sizeof(p_var), "%s/%s_var.tif", dir, S->name);
		snprintf(p_map, sizeof(p_map), "%s/regions.png", dir);
		kg_inputs_reset(); /* the label maps read back are gone; their inodes may return */
		if (kg_image_write(img, p_img, 32, &err) || kg_image_write(var, p_var, 32, &err) ||
		    kg_image_write(map, p_map, 16, &err)) {
			fprintf(stderr, "kogei-bench-labels: %s\n", err.msg);
			return 1;
		}
		char angles[64], angles10[64], intens[64];
		snprintf(angles, sizeof(angles), "%g:%g:5", S->a0, S->a1);
		snprintf(angles10, sizeof(angles10), "%g:%g:10", S->a0, S->a1);
		snprintf(intens, sizeof(intens), "%g:%g", S->i0, S->i1);
		struct {
			const char *name;
			char *args[24];
			int n, regions;
		} methods[] = {
			{"eq. 11 plain", {"--method", "eq11", "--angle", "30", "--variance", p_var,
			                  "--calib", p_cam, "--materials", p_lib, p_img}, 11, 0},
			{"eq. 11 scale-free", {"--method", "eq11", "--distance", "scale-free", "--angle",
			                       "30", "--variance", p_var, "--calib", p_cam, "--materials",
			                       p_lib, p_img}, 13, 0},
			{"camera space, no merges", {"--angles", angles, "--intensity", intens,
			                             "--merge-distance", "none", "--regions", p_map,
			                             "--variance", p_var, "--calib", p_cam, "--materials",
			                             p_lib, p_img}, 15, 1},
			{"camera space, merged classes", {"--angles", angles, "--intensity", intens,
			                                  "--regions", p_map, "--variance", p_var,
			                                  "--calib", p_cam, "--materials", p_lib, p_img},
			 13, 1},
			{"camera space, merged, 10 deg grid", {"--angles", angles10, "--intensity", intens,
			                                       "--regions", p_map, "--variance", p_var,
			                                       "--calib", p_cam, "--materials", p_lib,
			                                       p_img},
			 13, 1},
		};
		for (size_t mi = 0; mi < sizeof(methods) / sizeof(methods[0]); mi++) {
			result res;
			measure(kogei, dir, methods[mi].args, methods[mi].n, reps, truth, W, H,
			        methods[mi].regions, &res);
			if (!res.ok) {
				fprintf(md, "| %s | %s | failed | | | |\n", S->what, methods[mi].name);
				continue;
			}
			fprintf(md, "| %s | %s | %d | %.3f | ", S->what, methods[mi].name, res.classes,
			        res.pixel_acc);
			if (isfinite(res.region_acc))
				fprintf(md, "%.1f |", res.region_acc);
			else
				fprintf(md, "- |");
			fprintf(md, " %.2f |\n", res.mpix_s);
			fflush(md);
			fprintf(stderr, "%s, %s: %.3f per pixel, %.2f Mpix/s\n", S->name,
			        methods[mi].name, res.pixel_acc, res.mpix_s);
		}
	}
	fprintf(md, "\nPer pixel: a label is right when it holds the pixel's material (a "
	            "compound class 'a|b' holds each of its members). Per region: the ten "
	            "blocks as the region map (`--regions`), each decided on its pooled "
	            "likelihood (camera space only).\n");
	if (md != stdout)
		fclose(md);
	if (!keep) {
		char cmd[4300];
		snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
		if (system(cmd) != 0)
			fprintf(stderr, "kogei-bench-labels: could not remove %s\n", dir);
	}
	kg_image_free(&img);
	kg_image_free(&var);
	kg_image_free(&map);
	free(truth);
	kg_material_library_free(&lib);
	return 0;
}
