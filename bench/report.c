/* The report: bench.md (tables for people), bench.json (every number) and
 * pareto.png (speed against error, one point per method). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_private.h"

/* The error set the Pareto plot and the headline use. */
#define PARETO_TRAIN "CC24"
#define PARETO_NOISY 1

/* Mean of each metric over the cameras of one train -> test pair and noise setting;
 * returns the number of cameras averaged. */
static int error_summary(const kg_bench_results *r, const char *train, int noisy,
                         kg_bench_method m, kg_bench_metrics *mean)
{
	memset(mean, 0, sizeof(*mean));
	int n = 0;
	for (int i = 0; i < r->nerror; i++) {
		const kg_bench_error_row *e = &r->error[i];
		if (strcmp(e->train, train) != 0 || e->noisy != noisy || !e->available[m])
			continue;
		mean->rmse += e->m[m].rmse;
		mean->gfc += e->m[m].gfc;
		mean->de_d65_mean += e->m[m].de_d65_mean;
		mean->de_d65_p95 += e->m[m].de_d65_p95;
		mean->de_a_mean += e->m[m].de_a_mean;
		mean->de_a_p95 += e->m[m].de_a_p95;
		mean->n = e->m[m].n;
		n++;
	}
	if (n) {
		mean->rmse /= n;
		mean->gfc /= n;
		mean->de_d65_mean /= n;
		mean->de_d65_p95 /= n;
		mean->de_a_mean /= n;
		mean->de_a_p95 /= n;
	}
	return n;
}

static const char *test_of(const kg_bench_results *r, const char *train)
{
	for (int i = 0; i < r->nerror; i++)
		if (strcmp(r->error[i].train, train) == 0)
			return r->error[i].test;
	return "?";
}

/* The thread counts measured, in order of first appearance. */
static int thread_counts(const kg_bench_results *r, int *t, int max)
{
	int n = 0;
	for (int i = 0; i < r->nspeed; i++) {
		int seen = 0;
		for (int j = 0; j < n; j++)
			seen |= t[j] == r->speed[i].threads;
		if (!seen && n < max)
			t[n++] = r->speed[i].threads;
	}
	return n;
}

/* The row of a path; KG_EST_ISA_AUTO: of the best path measured (the last in the
 * order C, AVX2, AVX-512). */
static const kg_bench_speed_row *speed_row(const kg_bench_results *r, kg_bench_method m,
                                           kg_est_format f, kg_est_isa isa, int threads)
{
	const kg_bench_speed_row *best = NULL;
	for (int i = 0; i < r->nspeed; i++)
		if (r->speed[i].method == m && r->speed[i].format == f &&
		    r->speed[i].threads == threads &&
		    (isa == KG_EST_ISA_AUTO ? !best || r->speed[i].isa > best->isa
		                            : r->speed[i].isa == isa))
			best = &r->speed[i];
	return best;
}

/* The thread count the Pareto plot uses: 2 if measured, else the largest. */
static int pareto_threads(const kg_bench_results *r)
{
	int t[16], n = thread_counts(r, t, 16), best = 0;
	for (int i = 0; i < n; i++) {
		if (t[i] == 2)
			return 2;
		best = t[i] > best ? t[i] : best;
	}
	return best;
}

static double limit_gb_s(const kg_bench_results *r, double bpp, int threads)
{
	for (int i = 0; i < r->nlimit; i++)
		if (r->limit[i].bytes_per_pixel == bpp && r->limit[i].threads == threads)
			return r->limit[i].gb_s;
	return NAN;
}

/* ---- Markdown ---------------------------------------------------------------------- */

static void md_speed(FILE *fp, const kg_bench_results *r)
{
	int t[16], nt = thread_counts(r, t, 16);
	fprintf(fp, "## Speed\n\n");
	fprintf(fp, "%d x %d pixels (%.1f Mpix), median of %d runs after one warm-up run; "
	            "kernels fitted for %s.\n\n",
	        r->width, r->height, r->width * (double)r->height * 1e-6, r->reps,
	        r->speed_calibration);
	fprintf(fp, "| method | output | path | B/pixel |");
	for (int j = 0; j < nt; j++)
		fprintf(fp, " Mpix/s (%d thr) |", t[j]);
	for (int j = 0; j < nt; j++)
		fprintf(fp, " GB/s (%d thr) |", t[j]);
	for (int j = 0; j < nt; j++)
		fprintf(fp, " of limit (%d thr) |", t[j]);
	fprintf(fp, "\n|---|---|---|--:|");
	for (int j = 0; j < 3 * nt; j++)
		fprintf(fp, "--:|");
	fputc('\n', fp);
	for (int m = 0; m < KG_BENCH_NMETHODS; m++)
		for (int f = 0; f < KG_EST_NFORMATS; f++)
			for (int isa = KG_EST_ISA_C; isa < KG_EST_NISAS; isa++) {
				const kg_bench_speed_row *first = NULL;
				for (int j = 0; j < nt && !first; j++)
					first = speed_row(r, (kg_bench_method)m, (kg_est_format)f, (kg_est_isa)isa, t[j]);
				if (!first)
					continue;
				fprintf(fp, "| %s | %s | %s | %g |", kg_bench_method_name((kg_bench_method)m),
				        kg_bench_format_name((kg_est_format)f), kg_bench_isa_name((kg_est_isa)isa),
				        first->bytes_per_pixel);
				for (int pass = 0; pass < 3; pass++)
					for (int j = 0; j < nt; j++) {
						const kg_bench_speed_row *s = speed_row(r, (kg_bench_method)m,
						                                        (kg_est_format)f, (kg_est_isa)isa, t[j]);
						if (!s)
							fprintf(fp, " - |");
						else if (pass == 0)
							fprintf(fp, " %.1f |", s->mpix_s);
						else if (pass == 1)
							fprintf(fp, " %.2f |", s->gb_s);
						else
							fprintf(fp, " %.2f |", s->fraction);
					}
				fputc('\n', fp);
			}
	fprintf(fp, "\nWrite limit (%s of the same bytes into the same buffer, one "
	            "contiguous share per thread, runs alternating with the kernels'; median "
	            "over the rows that share it):\n\n",
	        r->stream_kind);
	fprintf(fp, "| B/pixel | threads | GB/s | Mpix/s equivalent | rows |\n"
	            "|--:|--:|--:|--:|--:|\n");
	for (int i = 0; i < r->nlimit; i++) {
		const kg_bench_limit_row *l = &r->limit[i];
		fprintf(fp, "| %g | %d | %.2f | %.1f | %d |\n", l->bytes_per_pixel, l->threads,
		        l->gb_s, l->gb_s * 1e3 / l->bytes_per_pixel, l->measurements);
	}
	fputc('\n', fp);
}

static const char *cs_path_name(const kg_bench_camspace_path *p)
{
	static const char *names[2][3] = {{"exact, c", "exact, avx2", "exact, avx512"},
	                                  {"quadratic, c", "quadratic, avx2", "quadratic, avx512"}};
	int w = p->isa == KG_EST_ISA_AVX512 ? 2 : p->isa == KG_EST_ISA_AVX2 ? 1 : 0;
	return names[p->method == KG_CS_QUADRATIC][w];
}

static void md_camspace(FILE *fp, const kg_bench_results *r)
{
	const kg_bench_camspace *cs = &r->camspace;
	int t[16], nt = 0;
	for (int i = 0; i < cs->nrows; i++) {
		int seen = 0;
		for (int j = 0; j < nt; j++)
			seen |= t[j] == cs->rows[i].threads;
		if (!seen && nt < 16)
			t[nt++] = cs->rows[i].threads;
	}
	fprintf(fp, "## Camera-space matching\n\n");
	fprintf(fp, "`kg_cs_match_block_method` on %.2f Mpix: %d materials x %d angles (0-%g "
	            "degrees), intensity %g-%g, readings of the library's materials under the "
	            "synthetic camera and D65 with photon and read noise (%g e- full well, %g e- "
	            "rms) mapped through a colour matrix (a full covariance per pixel); median of "
	            "%d runs after one warm-up, writing the label, both distances, the angle and "
	            "the intensity. Against its method's C reference: every output, each "
	            "material's distance included; against the exact C reference: the share of "
	            "pixels with its label, and with every output bit for bit.\n\n",
	        (double)cs->pixels * 1e-6, cs->materials, cs->angles, cs->angle_to, cs->lo,
	        cs->hi, r->noise.full_well, r->noise.read_noise, r->reps);
	fprintf(fp, "| method, implementation |");
	for (int j = 0; j < nt; j++)
		fprintf(fp, " Mpix/s (%d thr) |", t[j]);
	fprintf(fp, " against its C | labels of exact C | every output of exact C |\n|---|");
	for (int j = 0; j < nt; j++)
		fprintf(fp, "--:|");
	fprintf(fp, "---|--:|--:|\n");
	for (int q = 0; q < KG_BENCH_CS_PATHS; q++) {
		const kg_bench_camspace_path *pa = &cs->paths[q];
		if (!pa->supported) {
			fprintf(fp, "| %s | not supported by this CPU |\n", cs_path_name(pa));
			continue;
		}
		fprintf(fp, "| %s |", cs_path_name(pa));
		for (int j = 0; j < nt; j++) {
			const kg_bench_camspace_row *row = NULL;
			for (int i = 0; i < cs->nrows; i++)
				if (cs->rows[i].path == q && cs->rows[i].threads == t[j])
					row = &cs->rows[i];
			if (row)
				fprintf(fp, " %.2f |", row->mpix_s);
			else
				fprintf(fp, " - |");
		}
		fprintf(fp, " %s | %.6f | %.6f |\n",
		        pa->isa == KG_EST_ISA_C ? "–" : pa->identical ? "bit-identical" : "DIFFERENT",
		        pa->labels_agree, pa->all_agree);
	}
	fprintf(fp, "\nLabels equal to the material drawn: %.4f (exact), %.4f (quadratic); %ld "
	            "pixels refused.\n\n", cs->accuracy, cs->accuracy_quad, cs->refused);
}

static void md_metrics_header(FILE *fp, const char *first)
{
	fprintf(fp, "| %s | spectral RMSE | GFC | ΔE00 D65 mean | ΔE00 D65 p95 | ΔE00 A mean | "
	            "ΔE00 A p95 |\n|---|--:|--:|--:|--:|--:|--:|\n",
	        first);
}

static void md_metrics(FILE *fp, const kg_bench_metrics *m)
{
	fprintf(fp, " %.4f | %.4f | %.2f | %.2f | %.2f | %.2f |\n", m->rmse, m->gfc,
	        m->de_d65_mean, m->de_d65_p95, m->de_a_mean, m->de_a_p95);
}

static void md_error(FILE *fp, const kg_bench_results *r)
{
	fprintf(fp, "## Error\n\n");
	if (r->error_skipped) {
		fprintf(fp, "Skipped: %s.\n\n", r->error_note);
		return;
	}
	char noise[96];
	kg_sim_noise_format(&r->noise, noise, sizeof(noise));
	fprintf(fp, "Cameras:");
	for (int i = 0; i < r->nerror; i++)
		if (i == 0 || strcmp(r->error[i].camera, r->error[i - 1].camera) != 0)
			fprintf(fp, "%s %s", i ? "," : "", r->error[i].camera);
	fprintf(fp, ". Illuminant D65 for the captures (white at %.2f of full scale); noise "
	            "%s (full well e-, read noise e- rms, bits), seed %llu; wiener sigma %g.\n\n",
	        KG_BENCH_WHITE_LEVEL, noise, (unsigned long long)r->seed, r->wiener_sigma);
	static const char *const trains[2] = {"CC24", "Munsell"};
	fprintf(fp, "### Mean over cameras\n\n");
	for (int p = 0; p < 2; p++)
		for (int noisy = 0; noisy < 2; noisy++) {
			kg_bench_metrics m;
			if (!error_summary(r, trains[p], noisy, KG_BENCH_PCA3, &m))
				continue;
			fprintf(fp, "**train %s -> test %s (%d samples), %s**\n\n", trains[p],
			        test_of(r, trains[p]), m.n, noisy ? "with noise" : "noise-free");
			md_metrics_header(fp, "method");
			for (int j = 0; j < KG_BENCH_NMETHODS; j++) {
				int n = error_summary(r, trains[p], noisy, (kg_bench_method)j, &m);
				fprintf(fp, "| %s |", kg_bench_method_name((kg_bench_method)j));
				if (n)
					md_metrics(fp, &m);
				else
					fprintf(fp, " unavailable | | | | | |\n");
			}
			fputc('\n', fp);
		}
	fprintf(fp, "### Per camera\n\n");
	fprintf(fp, "| camera | train -> test | noise | method | K | spectral RMSE | GFC | "
	            "ΔE00 D65 mean | ΔE00 D65 p95 | ΔE00 A mean | ΔE00 A p95 |\n"
	            "|---|---|---|---|--:|--:|--:|--:|--:|--:|--:|\n");
	for (int i = 0; i < r->nerror; i++) {
		const kg_bench_error_row *e = &r->error[i];
		for (int j = 0; j < KG_BENCH_NMETHODS; j++) {
			fprintf(fp, "| %s | %s -> %s | %s | %s |", e->camera, e->train, e->test,
			        e->noisy ? "yes" : "no", kg_bench_method_name((kg_bench_method)j));
			if (j == KG_BENCH_PCA_AUTO)
				fprintf(fp, " %d |", e->K_auto);
			else if (j == KG_BENCH_PCA3 || j == KG_BENCH_LUT33)
				fprintf(fp, " 3 |");
			else
				fprintf(fp, " |");
			if (e->available[j])
				md_metrics(fp, &e->m[j]);
			else
				fprintf(fp, " unavailable: %s | | | | | |\n", e->note[j]);
		}
	}
	fputc('\n', fp);
}

static int write_markdown(const kg_bench_results *r, const char *path, kg_err *err)
{
	kg_outfile o;
	int ret = kg_outfile_open(&o, path, 0, err);
	if (ret)
		return ret;
	FILE *fp = o.fp;
	fprintf(fp, "# kogei bench: speed against error\n\n");
	fprintf(fp, "Command: `%s`  \n", r->command);
	fprintf(fp, "Run: %s on %s%s; error part %.0f s, speed part %.0f s, camera-space "
	            "rows %.0f s.\n\n",
	        r->date, r->machine, r->quick ? " (quick)" : "", r->seconds_error,
	        r->seconds_speed, r->seconds_camspace);
	fprintf(fp,
	        "## How to read\n\n"
	        "- **Error**: each method is fitted on the training chart's simulated camera "
	        "values and estimates the test set's spectra from that camera's values "
	        "(same camera and illuminant). Spectral RMSE and GFC compare the 61 bands "
	        "(400-700 nm); ΔE00 compares the CIE 1931 2° colours of the true and the "
	        "estimated reflectance under D65 and under A (A shows errors that D65 hides). "
	        "Lower is better, except GFC (1 = same shape). pca-auto picks K by "
	        "leave-one-out on the training chart (column K); lut33-pca3 is a 33³ "
	        "trilinear LUT of pca3.\n"
	        "- **Speed**: Mpix/s of `kg_est_run` (the path of `kogei estimate`) writing "
	        "the output into memory: f32-bsq (61 float32 planes), f16-bsq, weights (K "
	        "float32 per pixel, methods with a basis), labels (a byte plus a float "
	        "confidence, %d materials, pca3). GB/s counts output bytes. **of limit** "
	        "divides it by the write limit, the rate at which this machine writes the "
	        "same bytes with non-temporal stores on as many threads: 1.00 means the "
	        "kernel runs at memory speed, and small fractions mark compute-bound "
	        "kernels. **path** is the implementation (all bit-identical): avx2+fma and "
	        "avx512 for every row the CPU can run, c (the reference, fmaf in plain C) "
	        "for pca3's BSQ outputs. The machine drifts 15-30 %% between sessions: "
	        "compare numbers from the same run.\n"
	        "- **Camera-space matching**: Mpix/s of `kg_cs_match_block_method` "
	        "(materials matched where the camera measures, with each pixel's covariance), "
	        "the exact and the quadratic method in C, AVX2 and AVX-512, whether each "
	        "wrote its method's C reference's bytes, and how often its labels and outputs "
	        "are the exact C reference's.\n",
	        r->nmaterials);
	if (r->nerror && r->nspeed)
		fprintf(fp,
		        "- **pareto.png**: speed (f32-bsq, %d thread%s) against the mean ΔE00 (D65) "
		        "and spectral RMSE over the cameras, train CC24 -> test Munsell with "
		        "noise.\n\n",
		        pareto_threads(r), pareto_threads(r) == 1 ? "" : "s");
	else
		fprintf(fp, "- **pareto.png**: not drawn: this run has no error or no speed "
		            "results.\n\n");
	if (r->nspeed)
		md_speed(fp, r);
	if (r->camspace.nrows)
		md_camspace(fp, r);
	md_error(fp, r);
	return kg_outfile_commit(&o, err);
}

/* ---- JSON -------------------------------------------------------------------------- */

static json_t *num(double v) { return isfinite(v) ? json_real(v) : json_null(); }

static json_t *metrics_json(const kg_bench_metrics *m)
{
	json_t *o = json_object();
	json_object_set_new(o, "n", json_integer(m->n));
	json_object_set_new(o, "rmse", num(m->rmse));
	json_object_set_new(o, "gfc", num(m->gfc));
	json_object_set_new(o, "de00_d65_mean", num(m->de_d65_mean));
	json_object_set_new(o, "de00_d65_p95", num(m->de_d65_p95));
	json_object_set_new(o, "de00_a_mean", num(m->de_a_mean));
	json_object_set_new(o, "de00_a_p95", num(m->de_a_p95));
	return o;
}

static int write_json(const kg_bench_results *r, const char *path, kg_err *err)
{
	json_t *root = json_object();
	char noise[96];
	kg_sim_noise_format(&r->noise, noise, sizeof(noise));
	json_object_set_new(root, "format", json_string("kogei-bench/1"));
	json_object_set_new(root, "command", json_string(r->command));
	json_object_set_new(root, "date", json_string(r->date));
	json_object_set_new(root, "machine", json_string(r->machine));
	json_object_set_new(root, "quick", json_boolean(r->quick));

	json_t *e = json_object();
	json_object_set_new(e, "skipped", json_boolean(r->error_skipped));
	json_object_set_new(e, "note", json_string(r->error_note));
	json_object_set_new(e, "illuminant", json_string("D65"));
	json_object_set_new(e, "white_level", json_real(KG_BENCH_WHITE_LEVEL));
	json_object_set_new(e, "noise", json_string(noise));
	json_object_set_new(e, "seed", json_integer((json_int_t)r->seed));
	json_object_set_new(e, "wiener_sigma", json_real(r->wiener_sigma));
	json_object_set_new(e, "percentile", json_string("linear interpolation, p (n - 1)"));
	json_object_set_new(e, "seconds", num(r->seconds_error));
	json_t *rows = json_array();
	for (int i = 0; i < r->nerror; i++) {
		const kg_bench_error_row *er = &r->error[i];
		json_t *o = json_object();
		json_object_set_new(o, "camera", json_string(er->camera));
		json_object_set_new(o, "train", json_string(er->train));
		json_object_set_new(o, "test", json_string(er->test));
		json_object_set_new(o, "noisy", json_boolean(er->noisy));
		json_object_set_new(o, "K_auto", json_integer(er->K_auto));
		json_t *ms = json_object();
		for (int j = 0; j < KG_BENCH_NMETHODS; j++) {
			json_t *mj = er->available[j] ? metrics_json(&er->m[j]) : json_object();
			json_object_set_new(mj, "available", json_boolean(er->available[j]));
			if (!er->available[j])
				json_object_set_new(mj, "note", json_string(er->note[j]));
			json_object_set_new(ms, kg_bench_method_name((kg_bench_method)j), mj);
		}
		json_object_set_new(o, "methods", ms);
		json_array_append_new(rows, o);
	}
	json_object_set_new(e, "rows", rows);
	json_t *summary = json_array();
	static const char *const trains[2] = {"CC24", "Munsell"};
	for (int p = 0; p < 2; p++)
		for (int noisy = 0; noisy < 2; noisy++)
			for (int j = 0; j < KG_BENCH_NMETHODS; j++) {
				kg_bench_metrics m;
				int n = error_summary(r, trains[p], noisy, (kg_bench_method)j, &m);
				if (!n)
					continue;
				json_t *o = metrics_json(&m);
				json_object_set_new(o, "train", json_string(trains[p]));
				json_object_set_new(o, "test", json_string(test_of(r, trains[p])));
				json_object_set_new(o, "noisy", json_boolean(noisy));
				json_object_set_new(o, "method",
				                    json_string(kg_bench_method_name((kg_bench_method)j)));
				json_object_set_new(o, "cameras", json_integer(n));
				json_array_append_new(summary, o);
			}
	json_object_set_new(e, "mean_over_cameras", summary);
	json_object_set_new(root, "error", e);

	json_t *s = json_object();
	json_object_set_new(s, "width", json_integer(r->width));
	json_object_set_new(s, "height", json_integer(r->height));
	json_object_set_new(s, "repetitions", json_integer(r->reps));
	json_object_set_new(s, "statistic", json_string("median, CLOCK_MONOTONIC"));
	json_object_set_new(s, "materials", json_integer(r->nmaterials));
	json_object_set_new(s, "calibration", json_string(r->speed_calibration));
	json_object_set_new(s, "limit_method", json_string(r->stream_kind));
	json_object_set_new(s, "seconds", num(r->seconds_speed));
	json_t *sr = json_array();
	for (int i = 0; i < r->nspeed; i++) {
		const kg_bench_speed_row *x = &r->speed[i];
		json_t *o = json_object();
		json_object_set_new(o, "method", json_string(kg_bench_method_name(x->method)));
		json_object_set_new(o, "format", json_string(kg_bench_format_name(x->format)));
		json_object_set_new(o, "path", json_string(kg_bench_isa_name(x->isa)));
		json_object_set_new(o, "threads", json_integer(x->threads));
		json_object_set_new(o, "bytes_per_pixel", num(x->bytes_per_pixel));
		json_object_set_new(o, "seconds", num(x->seconds));
		json_object_set_new(o, "mpix_per_s", num(x->mpix_s));
		json_object_set_new(o, "gb_per_s", num(x->gb_s));
		json_object_set_new(o, "limit_gb_per_s", num(x->limit_gb_s));
		json_object_set_new(o, "fraction_of_limit", num(x->fraction));
		json_array_append_new(sr, o);
	}
	json_object_set_new(s, "rows", sr);
	json_t *lr = json_array();
	for (int i = 0; i < r->nlimit; i++) {
		json_t *o = json_object();
		json_object_set_new(o, "bytes_per_pixel", num(r->limit[i].bytes_per_pixel));
		json_object_set_new(o, "threads", json_integer(r->limit[i].threads));
		json_object_set_new(o, "measurements", json_integer(r->limit[i].measurements));
		json_object_set_new(o, "gb_per_s", num(r->limit[i].gb_s));
		json_array_append_new(lr, o);
	}
	json_object_set_new(s, "limits", lr);
	json_object_set_new(root, "speed", s);

	const kg_bench_camspace *cs = &r->camspace;
	json_t *c = json_object();
	json_object_set_new(c, "run", json_boolean(cs->nrows > 0));
	json_object_set_new(c, "pixels", json_integer(cs->pixels));
	json_object_set_new(c, "materials", json_integer(cs->materials));
	json_object_set_new(c, "angles", json_integer(cs->angles));
	json_object_set_new(c, "angle_to_deg", num(cs->angle_to));
	json_object_set_new(c, "intensity", json_pack("[ff]", cs->lo, cs->hi));
	json_t *cp = json_array();
	for (int q = 0; q < KG_BENCH_CS_PATHS; q++) {
		const kg_bench_camspace_path *pa = &cs->paths[q];
		json_t *o = json_object();
		json_object_set_new(o, "path", json_string(cs_path_name(pa)));
		json_object_set_new(o, "supported", json_boolean(pa->supported));
		json_object_set_new(o, "bit_identical_to_its_c",
		                    pa->supported ? json_boolean(pa->identical) : json_null());
		json_object_set_new(o, "labels_of_exact_c", num(pa->labels_agree));
		json_object_set_new(o, "all_outputs_of_exact_c", num(pa->all_agree));
		json_array_append_new(cp, o);
	}
	json_object_set_new(c, "paths", cp);
	json_object_set_new(c, "accuracy", num(cs->accuracy));
	json_object_set_new(c, "accuracy_quadratic", num(cs->accuracy_quad));
	json_object_set_new(c, "refused", json_integer(cs->refused));
	json_object_set_new(c, "seconds", num(r->seconds_camspace));
	json_t *cr = json_array();
	for (int i = 0; i < cs->nrows; i++) {
		json_t *o = json_object();
		json_object_set_new(o, "path", json_string(cs_path_name(&cs->paths[cs->rows[i].path])));
		json_object_set_new(o, "threads", json_integer(cs->rows[i].threads));
		json_object_set_new(o, "seconds", num(cs->rows[i].seconds));
		json_object_set_new(o, "mpix_per_s", num(cs->rows[i].mpix_s));
		json_array_append_new(cr, o);
	}
	json_object_set_new(c, "rows", cr);
	json_object_set_new(root, "camspace", c);
	int ret = kg_json_write(root, path, err);
	json_decref(root);
	return ret;
}

/* ---- Pareto plot ------------------------------------------------------------------- */

typedef struct label_box {
	double x0, y0, x1, y1;
} label_box;

static int overlaps(const label_box *boxes, int n, label_box b)
{
	for (int i = 0; i < n; i++)
		if (b.x0 < boxes[i].x1 && boxes[i].x0 < b.x1 && b.y0 < boxes[i].y1 &&
		    boxes[i].y0 < b.y1)
			return 1;
	return 0;
}

/* Label each point beside it, trying a few positions so that labels do not cover
 * each other or the points. */
static void label_points(kg_plot *p, const kg_axes *ax, const double *xs, const double *ys,
                         const int *have)
{
	static const double black[3] = {0, 0, 0};
	static const double dx[6] = {9, 9, -9, -9, 9, -9}, dy[6] = {-6, 14, -6, 14, -20, 28};
	label_box boxes[2 * KG_BENCH_NMETHODS];
	int nb = 0;
	for (int j = 0; j < KG_BENCH_NMETHODS; j++) {
		if (!have[j])
			continue;
		double px = ax->x + (xs[j] - ax->xmin) / (ax->xmax - ax->xmin) * ax->w;
		double py = ax->y + ax->h - (ys[j] - ax->ymin) / (ax->ymax - ax->ymin) * ax->h;
		boxes[nb++] = (label_box){px - 6, py - 6, px + 6, py + 6};
	}
	for (int j = 0; j < KG_BENCH_NMETHODS; j++) {
		if (!have[j])
			continue;
		const char *name = kg_bench_method_name((kg_bench_method)j);
		double w = 7.0 * (double)strlen(name);
		double px = ax->x + (xs[j] - ax->xmin) / (ax->xmax - ax->xmin) * ax->w;
		double py = ax->y + ax->h - (ys[j] - ax->ymin) / (ax->ymax - ax->ymin) * ax->h;
		int pick = 0;
		label_box b = {0};
		for (int c = 0; c < 6; c++) {
			double x0 = dx[c] > 0 ? px + dx[c] : px + dx[c] - w;
			b = (label_box){x0, py + dy[c] - 11, x0 + w, py + dy[c] + 2};
			if (!overlaps(boxes, nb, b)) {
				pick = c;
				break;
			}
			pick = c == 5 ? 0 : pick;
		}
		double x0 = dx[pick] > 0 ? px + dx[pick] : px + dx[pick] - w;
		boxes[nb++] = (label_box){x0, py + dy[pick] - 11, x0 + w, py + dy[pick] + 2};
		kg_plot_text(p, dx[pick] > 0 ? px + dx[pick] : px + dx[pick], py + dy[pick], 12,
		             dx[pick] > 0 ? KG_ALIGN_LEFT : KG_ALIGN_RIGHT, black, "%s", name);
	}
}

static int write_pareto(const kg_bench_results *r, const char *path, kg_err *err)
{
	int threads = pareto_threads(r);
	double speed[KG_BENCH_NMETHODS], de[KG_BENCH_NMETHODS], rmse[KG_BENCH_NMETHODS];
	int have[KG_BENCH_NMETHODS], n = 0;
	double smax = 0, demin = INFINITY, demax = 0, rmin = INFINITY, rmax = 0;
	for (int j = 0; j < KG_BENCH_NMETHODS; j++) {
		kg_bench_metrics m;
		const kg_bench_speed_row *s =
		    speed_row(r, (kg_bench_method)j, KG_EST_F32_BSQ, KG_EST_ISA_AUTO, threads);
		have[j] = s && error_summary(r, PARETO_TRAIN, PARETO_NOISY, (kg_bench_method)j, &m);
		if (!have[j])
			continue;
		speed[j] = s->mpix_s;
		de[j] = m.de_d65_mean;
		rmse[j] = m.rmse;
		smax = fmax(smax, speed[j]);
		demin = fmin(demin, de[j]);
		demax = fmax(demax, de[j]);
		rmin = fmin(rmin, rmse[j]);
		rmax = fmax(rmax, rmse[j]);
		n++;
	}
	if (!n)
		return 0;
	double limit = NAN;
	const kg_bench_speed_row *any = NULL;
	for (int j = 0; j < KG_BENCH_NMETHODS && !any; j++)
		any = speed_row(r, (kg_bench_method)j, KG_EST_F32_BSQ, KG_EST_ISA_AUTO, threads);
	if (any) {
		limit = limit_gb_s(r, any->bytes_per_pixel, threads) * 1e3 / any->bytes_per_pixel;
		smax = fmax(smax, limit);
	}
	kg_plot *p = NULL;
	int ret = kg_plot_new(1360, 600, &p, err);
	if (ret)
		return ret;
	static const double white[3] = {1, 1, 1}, grey[3] = {0.45, 0.45, 0.45},
	                    black[3] = {0, 0, 0};
	kg_plot_fill_rect(p, 0, 0, 1360, 600, white);
	kg_plot_text(p, 640, 26, 16, KG_ALIGN_CENTER, black,
	             "Speed against error: f32 BSQ, %d thread%s; error: train %s -> test %s, "
	             "with noise, mean over cameras",
	             threads, threads == 1 ? "" : "s", PARETO_TRAIN, test_of(r, PARETO_TRAIN));
	for (int panel = 0; panel < 2; panel++) {
		const double *xs = panel ? rmse : de;
		double lo = panel ? rmin : demin, hi = panel ? rmax : demax;
		double pad = fmax(0.15 * (hi - lo), 0.05 * hi);
		kg_axes ax = kg_plot_axes(p, 80 + panel * 570, 60, 480, 470, fmax(0, lo - pad),
		                          hi + pad > lo ? hi + pad : lo + 1, 0, smax * 1.12,
		                          panel ? "mean spectral RMSE" : "mean CIEDE2000 under D65",
		                          "Mpix/s", panel ? "spectral error" : "colour error");
		if (isfinite(limit)) {
			double lx[2] = {ax.xmin, ax.xmax}, ly[2] = {limit, limit};
			kg_plot_line(p, &ax, lx, ly, 2, grey, 1.5, 1);
			kg_plot_text(p, ax.x + ax.w - 6, ax.y + ax.h - limit / ax.ymax * ax.h - 6, 11,
			             KG_ALIGN_RIGHT, grey, "write limit %.0f Mpix/s", limit);
		}
		for (int j = 0; j < KG_BENCH_NMETHODS; j++) {
			if (!have[j])
				continue;
			double rgb[3];
			kg_series_colour(j, rgb);
			kg_plot_points(p, &ax, &xs[j], &speed[j], 1, rgb, 6);
		}
		label_points(p, &ax, xs, speed, have);
	}
	/* Legend: colour of each method. */
	for (int j = 0, row = 0; j < KG_BENCH_NMETHODS; j++) {
		if (!have[j])
			continue;
		double rgb[3];
		kg_series_colour(j, rgb);
		kg_plot_fill_rect(p, 1200, 80 + 22 * row - 6, 12, 12, rgb);
		kg_plot_text(p, 1218, 80 + 22 * row + 5, 12, KG_ALIGN_LEFT, black, "%s",
		             kg_bench_method_name((kg_bench_method)j));
		row++;
	}
	ret = kg_plot_save_png(p, path, err);
	kg_plot_free(&p);
	return ret;
}

int kg_bench_write_report(const kg_bench_results *r, const char *dir, kg_err *err)
{
	kg_check_arg(r && dir, err);
	int ret = kg_mkdir_p(dir, err);
	char *md = kg_path_join(dir, "bench.md");
	char *js = kg_path_join(dir, "bench.json");
	char *png = kg_path_join(dir, "pareto.png");
	if (!ret && (!md || !js || !png))
		ret = kg_fail(err, KG_ENOMEM, "bench: out of memory");
	if (!ret)
		ret = write_markdown(r, md, err);
	if (!ret)
		ret = write_json(r, js, err);
	if (!ret)
		ret = write_pareto(r, png, err);
	free(md);
	free(js);
	free(png);
	return ret;
}
