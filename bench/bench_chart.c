/* kogei-bench-chart: chart detection and patch sampling time on 12 Mpix simulated
 * photographs, beside the patch-value error.
 *
 * `kogei sim chart` renders the ColorChecker 24 in its AprilTag frame
 * (fixtures/charts/colorchecker24-frame.json; spectra from ../shared/reference when
 * present, else built-in colours) frontally and tilted, with blur, vignetting and
 * sensor noise, as 16-bit TIFF, with its truth, and once more as a raw Bayer (RGGB)
 * frame. Each image is read once; then kg_chart_detect runs for every tag decimation
 * (1, 2, 4) and thread count (1, 2), reporting its stages: image preparation (white
 * level, 8-bit grey, demosaicing), tag detection, patch sampling and the total.
 * The same chart on black paper (its tags vanish: an unframed ColorChecker) goes to
 * the tagless detector twice per thread count: the default path (the patch-grid
 * finder, then mcc, on a reduced copy, its box refined at full resolution) and mcc on
 * the full image
 * (tagless_decimate 1), with the ratio of their totals. Times are the median of
 * --reps runs (CLOCK_MONOTONIC); the error is the largest and the mean
 * |measured - truth| over all patches and channels, in % of full scale. Markdown
 * goes to stdout, JSON to --json.
 *
 *   kogei-bench-chart [--kogei PATH] [--layout L] [--width W --height H] [--reps N]
 *                     [--keep DIR] [--only TEXT] [--json PATH] */
#include <errno.h>
#include <libgen.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "kg_bench.h"
#include "kg_config.h"

#define MAX_REPS 31
#define MAX_ROWS 64

typedef struct row {
	const char *image;
	const char *method; /* "apriltag", "tagless" (reduced + refined) or "mcc" (full) */
	int decimate, threads;
	int ok;
	char note[1024];
	double prepare_s, tag_s, sample_s, total_s;
	double max_err, mean_err; /* % of full scale */
	int patches;
	double ratio; /* tagless rows: the full-image mcc row's total over this one's */
} row;

/* Errors of a result against a truth file. */
static void errors(const kg_chart_result *r, const kg_patchset *truth, row *out)
{
	double worst = 0.0, sum = 0.0;
	int n = 0;
	for (int i = 0; i < truth->n; i++)
		for (int k = 0; k < r->npatches; k++) {
			const kg_chart_sample *s = &r->patches[k];
			if (strcmp(s->id, truth->ids[i]) || (s->flags & KG_CHART_FLAG_REJECTED))
				continue;
			for (int c = 0; c < 3; c++) {
				/* as sampled: the reported value times the light field removed */
				double d = fabs(s->rgb[c] * s->light - truth->rgb[i][c]);
				worst = fmax(worst, d);
				sum += d;
			}
			n++;
		}
	out->patches = n;
	out->max_err = 100.0 * worst;
	out->mean_err = n ? 100.0 * sum / (3.0 * n) : NAN;
}

/* tagless: 0 tags; 1 the tagless detector at its default reduction; 2 mcc on the
 * full image. */
static void measure(const kg_chart_layout *l, const kg_image *img, const kg_patchset *truth,
                    int tagless, int decimate, int threads, int reps, row *out)
{
	double prep[MAX_REPS], tag[MAX_REPS], samp[MAX_REPS], total[MAX_REPS];
	kg_chart_detect_options o;
	kg_chart_detect_options_default(&o);
	o.tagless = tagless > 0;
	o.tagless_decimate = tagless == 2 ? 1 : 0;
	o.decimate = decimate;
	o.threads = threads;
	out->method = tagless == 1 ? "tagless" : tagless == 2 ? "mcc" : "apriltag";
	out->decimate = decimate;
	out->threads = threads;
	for (int k = 0; k < reps; k++) {
		kg_chart_result *r = NULL;
		kg_err err = {{0}};
		double t0 = kg_bench_now();
		int ret = kg_chart_detect(l, img, &o, &r, &err);
		total[k] = kg_bench_now() - t0;
		if (ret) {
			out->ok = 0;
			snprintf(out->note, sizeof(out->note), "%s", err.msg);
			return;
		}
		prep[k] = r->prepare_seconds;
		tag[k] = r->tag_seconds;
		samp[k] = r->sample_seconds;
		if (k == 0) {
			errors(r, truth, out);
			if (tagless)
				out->decimate = r->tagless_decimate;
		}
		kg_chart_result_free(&r);
	}
	out->ok = 1;
	out->prepare_s = kg_bench_percentile(prep, reps, 0.5);
	out->tag_s = kg_bench_percentile(tag, reps, 0.5);
	out->sample_s = kg_bench_percentile(samp, reps, 0.5);
	out->total_s = kg_bench_percentile(total, reps, 0.5);
}

static void write_camera(const char *path)
{
	kg_sim_camera cam;
	kg_bench_synthetic_camera(&cam);
	FILE *fp = fopen(path, "w");
	if (!fp)
		return;
	fprintf(fp, "wavelength_nm,r,g,b\n");
	for (int b = 0; b < KG_NBANDS; b++)
		fprintf(fp, "%g,%.9g,%.9g,%.9g\n", kg_band_nm(b), cam.sens[0].v[b], cam.sens[1].v[b],
		        cam.sens[2].v[b]);
	fclose(fp);
}

int main(int argc, char **argv)
{
	char kogei[4096], layout_path[4096], dir[4096] = "";
	const char *json_path = NULL, *keep = NULL, *only = NULL;
	int width = 4000, height = 3000, reps = 3;
	{
		char self[4096];
		ssize_t n = readlink("/proc/self/exe", self, sizeof(self) - 1);
		self[n > 0 ? n : 0] = '\0';
		snprintf(kogei, sizeof(kogei), "%s/../cli/kogei", dirname(self));
	}
	snprintf(layout_path, sizeof(layout_path), "%s/fixtures/charts/colorchecker24-frame.json",
	         KG_SOURCE_ROOT);
	for (int i = 1; i < argc; i++) {
		const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
		if (!strcmp(a, "--kogei") && v)
			snprintf(kogei, sizeof(kogei), "%s", argv[++i]);
		else if (!strcmp(a, "--layout") && v)
			snprintf(layout_path, sizeof(layout_path), "%s", argv[++i]);
		else if (!strcmp(a, "--json") && v)
			json_path = argv[++i];
		else if (!strcmp(a, "--keep") && v)
			keep = argv[++i];
		else if (!strcmp(a, "--only") && v)
			only = argv[++i];
		else if (!strcmp(a, "--width") && v)
			width = atoi(argv[++i]);
		else if (!strcmp(a, "--height") && v)
			height = atoi(argv[++i]);
		else if (!strcmp(a, "--reps") && v)
			reps = atoi(argv[++i]);
		else {
			fprintf(stderr,
			        "usage: %s [--kogei PATH] [--layout L] [--width W --height H] "
			        "[--reps N] [--keep DIR] [--only TEXT] [--json PATH]\n"
			        "  --only TEXT: only the images whose name contains TEXT (e.g. Bayer)\n",
			        argv[0]);
			return 2;
		}
	}
	if (reps < 1 || reps > MAX_REPS || width < 64 || height < 64) {
		fprintf(stderr, "kogei-bench-chart: --reps 1..%d, --width/--height >= 64\n", MAX_REPS);
		return 2;
	}
	if (keep) {
		snprintf(dir, sizeof(dir), "%s", keep);
		if (mkdir(dir, 0777) != 0 && errno != EEXIST) {
			fprintf(stderr, "kogei-bench-chart: --keep %s: %s\n", dir, strerror(errno));
			return 1;
		}
	} else {
		const char *tmp = getenv("TMPDIR");
		snprintf(dir, sizeof(dir), "%s/kogei-bench-chart-XXXXXX", tmp && *tmp ? tmp : "/tmp");
		if (!mkdtemp(dir)) {
			perror("mkdtemp");
			return 1;
		}
	}
	char camera[4200], spectra[4200], wtext[16], htext[16];
	snprintf(camera, sizeof(camera), "%s/camera.csv", dir);
	write_camera(camera);
	snprintf(spectra, sizeof(spectra), "%s/../shared/reference/charts/colorchecker24_babelcolor_avg.csv",
	         KG_SOURCE_ROOT);
	int have_spectra = access(spectra, R_OK) == 0;
	snprintf(wtext, sizeof(wtext), "%d", width);
	snprintf(htext, sizeof(htext), "%d", height);

	kg_err err = {{0}};
	kg_chart_layout *layout = NULL;
	if (kg_chart_layout_load(layout_path, &layout, &err)) {
		fprintf(stderr, "kogei-bench-chart: %s\n", err.msg);
		return 1;
	}
	static const struct {
		const char *name, *tilt, *rotate, *cfa, *paper;
		int tagless;
	} images[] = {
	    {"frontal", "0", "0", NULL, NULL, 0},
	    {"tilt 35, rotate 15", "35", "15", NULL, NULL, 0},
	    {"frontal, Bayer RGGB", "0", "0", "RGGB", NULL, 0},
	    {"unframed, frontal", "0", "0", NULL, "0.03", 1},
	    {"unframed, tilt 20, rotate 10", "20", "10", NULL, "0.03", 1},
	};
	enum { NIMAGES = sizeof(images) / sizeof(images[0]) };
	/* the whole `kogei chart detect` of the unframed frontal image (subprocess, wall
	 * time) against mcc's detection alone on it (in-process, the full-image mcc row's
	 * detector time), in the same run */
	double whole_s = NAN, mcc_alone_s = NAN;
	int whole_threads = 2;
	row rows[MAX_ROWS];
	int nrows = 0;
	double render_s[NIMAGES] = {0};
	for (int im = 0; im < NIMAGES; im++) {
		char img[4300], truth_path[4300];
		if (only && !strstr(images[im].name, only))
			continue;
		snprintf(img, sizeof(img), "%s/chart%d.tif", dir, im);
		snprintf(truth_path, sizeof(truth_path), "%s/chart%d.cgats", dir, im);
		char *sim[48] = {kogei, "sim", "chart", "--layout", layout_path, "--camera", camera,
		                 "--illuminant", "D65", "--width", wtext, "--height", htext,
		                 "--tilt", (char *)images[im].tilt, "--rotate", (char *)images[im].rotate,
		                 "--blur", "1.0", "--vignetting", "0.2", "--noise", "20000:5:12",
		                 "--depth", "16", "--seed", "11", "-o", img, "--truth", truth_path};
		int n = 31;
		if (have_spectra) {
			sim[n++] = "--spectra";
			sim[n++] = spectra;
		}
		if (images[im].cfa) {
			sim[n++] = "--cfa";
			sim[n++] = (char *)images[im].cfa;
		}
		if (images[im].paper) {
			sim[n++] = "--paper";
			sim[n++] = (char *)images[im].paper;
		}
		sim[n] = NULL;
		double t0 = kg_bench_now();
		if (access(img, R_OK) != 0 || access(truth_path, R_OK) != 0 || !keep) {
			if (kg_bench_run_program(sim, 0) != 0) {
				fprintf(stderr, "kogei-bench-chart: %s sim chart failed\n", kogei);
				return 1;
			}
		}
		render_s[im] = kg_bench_now() - t0;
		kg_image *image = NULL;
		kg_patchset *truth = NULL;
		if (kg_image_read(img, &image, &err) || kg_patchset_read(truth_path, 0, &truth, &err)) {
			fprintf(stderr, "kogei-bench-chart: %s\n", err.msg);
			return 1;
		}
		static const int decimations[] = {1, 2, 4}, threads[] = {1, 2};
		/* the whole command first, before this process runs mcc: OpenCV's worker
		 * threads keep spinning for a while after a parallel call and would take a core
		 * from the command */
		if (images[im].tagless && !strcmp(images[im].name, "unframed, frontal")) {
			char cgats[4400];
			snprintf(cgats, sizeof(cgats), "%s/whole.cgats", dir);
			char *cmd[] = {kogei, "chart", "detect", "--layout", layout_path, "--quiet", img,
			               "-o", cgats, NULL};
			double w[MAX_REPS];
			int ok = 1;
			for (int k = 0; k < reps && ok; k++) {
				double tw = kg_bench_now();
				ok = kg_bench_run_program(cmd, 1) == 0;
				w[k] = kg_bench_now() - tw;
			}
			if (ok)
				whole_s = kg_bench_percentile(w, reps, 0.5);
		}
		for (int t = 0; t < 2 && images[im].tagless; t++) {
			row *full = &rows[nrows++], *fast = &rows[nrows++];
			memset(full, 0, sizeof(*full));
			memset(fast, 0, sizeof(*fast));
			full->image = fast->image = images[im].name;
			measure(layout, image, truth, 1, 0, threads[t], reps, fast);
			measure(layout, image, truth, 2, 0, threads[t], reps, full);
			fast->ratio = fast->ok && full->ok ? full->total_s / fast->total_s : NAN;
			fprintf(stderr, "%s: tagless %.3f s, mcc on the full image %.3f s, %d thread(s)\n",
			        fast->image, fast->total_s, full->total_s, threads[t]);
		}
		if (images[im].tagless && !strcmp(images[im].name, "unframed, frontal")) {
			for (int i = 0; i < nrows; i++)
				if (rows[i].ok && !strcmp(rows[i].method, "mcc") &&
				    rows[i].threads == whole_threads && rows[i].image == images[im].name)
					mcc_alone_s = rows[i].tag_s;
			fprintf(stderr, "%s: whole kogei chart detect %.3f s, mcc alone %.3f s\n",
			        images[im].name, whole_s, mcc_alone_s);
		}
		for (int d = 0; d < 3 && !images[im].tagless; d++)
			for (int t = 0; t < 2; t++) {
				if (images[im].cfa && decimations[d] != 4)
					continue;
				row *r = &rows[nrows++];
				memset(r, 0, sizeof(*r));
				r->image = images[im].name;
				measure(layout, image, truth, 0, decimations[d], threads[t], reps, r);
				fprintf(stderr, "%s: apriltag decimate %d, %d thread(s): %.3f s\n", r->image,
				        r->decimate, r->threads, r->total_s);
			}
		kg_image_free(&image);
		kg_patchset_free(&truth);
	}

	printf("Chart detection + sampling, %d x %d (%.1f Mpix) 16-bit, %s, layout %s, "
	       "median of %d runs. Error: |measured - truth| per channel, %% of full scale.\n\n",
	       width, height, width * (double)height / 1e6,
	       have_spectra ? "ColorChecker spectra (BabelColor)" : "built-in colours",
	       layout->name, reps);
	printf("Framed chart (AprilTags):\n\n");
	printf("| image | decimate | threads | prepare (ms) | tags (ms) | sampling (ms) | total (ms) "
	       "| max err (%%) | mean err (%%) |\n|---|---|---|---|---|---|---|---|---|\n");
	for (int i = 0; i < nrows; i++) {
		const row *r = &rows[i];
		if (strcmp(r->method, "apriltag"))
			continue;
		if (r->ok)
			printf("| %s | %d | %d | %.1f | %.1f | %.1f | %.1f | %.3f | %.4f |\n", r->image,
			       r->decimate, r->threads, 1e3 * r->prepare_s, 1e3 * r->tag_s,
			       1e3 * r->sample_s, 1e3 * r->total_s, r->max_err, r->mean_err);
		else
			printf("| %s | %d | %d | - | - | - | - | - | - (%s) |\n", r->image, r->decimate,
			       r->threads, r->note);
	}
	printf("\nUnframed chart (tagless): the default path (the patch-grid finder, then mcc "
	       "if no grid reads as the layout, on a copy reduced by the decimate shown, box "
	       "refined at full resolution) against mcc on the full image; speed-up: the "
	       "full-image total over the default's.\n\n");
	printf("| image | method | decimate | threads | prepare (ms) | detector (ms) | sampling (ms) "
	       "| total (ms) | max err (%%) | mean err (%%) | speed-up |\n"
	       "|---|---|---|---|---|---|---|---|---|---|---|\n");
	for (int i = 0; i < nrows; i++) {
		const row *r = &rows[i];
		if (!strcmp(r->method, "apriltag"))
			continue;
		char ratio[32] = "";
		if (isfinite(r->ratio) && r->ratio > 0) /* the mcc rows are the baseline */
			snprintf(ratio, sizeof(ratio), "%.1f x", r->ratio);
		if (r->ok)
			printf("| %s | %s | %d | %d | %.1f | %.1f | %.1f | %.1f | %.3f | %.4f | %s |\n",
			       r->image, r->method, r->decimate, r->threads, 1e3 * r->prepare_s,
			       1e3 * r->tag_s, 1e3 * r->sample_s, 1e3 * r->total_s, r->max_err,
			       r->mean_err, ratio);
		else
			printf("| %s | %s | - | %d | - | - | - | - | - | - (%s) | |\n", r->image,
			       r->method, r->threads, r->note);
	}
	printf("\nChart check, whole command against mcc alone (same run): the wall time of the "
	       "whole `kogei chart detect` of the unframed frontal image (a subprocess: reading "
	       "the TIFF, tags looked for, the tagless detector, the CGATS written; %d threads) "
	       "against OpenCV mcc's detection alone on the same image in this process (the "
	       "detector time of the full-image mcc row above).\n\n", whole_threads);
	printf("| check | whole command (ms) | mcc alone (ms) | ratio |\n|---|---|---|---|\n");
	if (isfinite(whole_s) && isfinite(mcc_alone_s))
		printf("| chart check whole command vs mcc alone, same run | %.1f | %.1f | %.1f x |\n",
		       1e3 * whole_s, 1e3 * mcc_alone_s, mcc_alone_s / whole_s);
	else
		printf("| chart check whole command vs mcc alone, same run | - | - | - (not measured) |\n");
	printf("\nRendering (kogei sim chart, all CPUs, incl. TIFF write; 0 when kept):");
	for (int im = 0; im < NIMAGES; im++)
		printf(" %.2f s%s", render_s[im], im + 1 < NIMAGES ? "," : ".\n");

	if (json_path) {
		kg_outfile out;
		kg_err jerr = {{0}};
		if (kg_outfile_open(&out, json_path, 1, &jerr)) {
			fprintf(stderr, "%s\n", jerr.msg);
			return 1;
		}
		FILE *fp = out.fp;
		fprintf(fp, "{\"format\": \"kogei-bench-chart/2\", \"width\": %d, \"height\": %d, "
		            "\"reps\": %d, \"layout\": \"%s\", \"spectra\": %s, \"rows\": [\n",
		        width, height, reps, layout->name, have_spectra ? "true" : "false");
		for (int i = 0; i < nrows; i++) {
			const row *r = &rows[i];
			fprintf(fp, "  {\"image\": \"%s\", \"method\": \"%s\", \"decimate\": %d, "
			            "\"threads\": %d, \"ok\": %s",
			        r->image, r->method, r->decimate, r->threads, r->ok ? "true" : "false");
			if (r->ok)
				fprintf(fp, ", \"prepare_seconds\": %.6f, \"tag_seconds\": %.6f, "
				            "\"sample_seconds\": %.6f, \"total_seconds\": %.6f, "
				            "\"max_error_percent\": %.6f, \"mean_error_percent\": %.6f, "
				            "\"patches\": %d",
				        r->prepare_s, r->tag_s, r->sample_s, r->total_s, r->max_err,
				        r->mean_err, r->patches);
			if (r->ok && isfinite(r->ratio))
				fprintf(fp, ", \"speedup_over_full_mcc\": %.3f", r->ratio);
			else {
				fprintf(fp, ", \"note\": \"");
				for (const char *c = r->note; *c; c++)
					fprintf(fp, (*c == '"' || *c == '\\') ? "\\%c" : "%c", *c);
				fprintf(fp, "\"");
			}
			fprintf(fp, "}%s\n", i + 1 < nrows ? "," : "");
		}
		fprintf(fp, "]");
		if (isfinite(whole_s) && isfinite(mcc_alone_s))
			fprintf(fp, ", \"whole_command\": {\"image\": \"unframed, frontal\", "
			            "\"threads\": %d, \"whole_seconds\": %.6f, \"mcc_alone_seconds\": "
			            "%.6f, \"ratio\": %.3f}", whole_threads, whole_s, mcc_alone_s,
			        mcc_alone_s / whole_s);
		fprintf(fp, "}\n");
		if (kg_outfile_commit(&out, &jerr)) {
			fprintf(stderr, "%s\n", jerr.msg);
			return 1;
		}
	}
	kg_chart_layout_free(&layout);
	if (!keep) {
		char cmd[4300];
		snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
		if (system(cmd) != 0)
			fprintf(stderr, "could not remove %s\n", dir);
	}
	return 0;
}
