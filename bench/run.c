/* The whole benchmark: the error experiments over cameras, train/test pairs and noise,
 * then the speed measurements, collected into kg_bench_results. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/utsname.h>
#include <time.h>
#include <unistd.h>

#include "bench_private.h"

#define CC24_FILE "charts/colorchecker24_ohta1997.csv"
#define MUNSELL_FILE "reflectance/munsell_matt_uef1269_5nm.csv"
#define CES_FILE "reflectance/cie2017_cfi_ces99_5nm.csv"
#define BENCH_SEED 20170101u
#define IMAGE_WIDTH 4000
/* Wiener's noise prior: the default of `kogei calib reference`. */
#define WIENER_SIGMA 0.01

/* Four makers, four sensor generations (all measured by NPL or Weta Digital). */
static const char *const bench_cameras[] = {
	"Nikon_D5100", "Canon_EOS_5D_Mark_II", "Sony_ILCE-7M3", "Fujifilm_X-T3",
};
#define NCAMERAS ((int)(sizeof(bench_cameras) / sizeof(bench_cameras[0])))

void kg_bench_config_default(kg_bench_config *c, int quick)
{
	static const int threads[2] = {1, 2};
	memset(c, 0, sizeof(*c));
	c->quick = quick;
	c->mpix = quick ? 2.0 : 12.0;
	c->reps = quick ? 3 : 5;
	c->threads = threads;
	c->nthreads = 2;
	c->nmaterials = 16;
	c->run_error = c->run_speed = c->run_camspace = 1;
	c->camspace_mpix = 1.0;
	c->camspace_step = 5.0;
}

void kg_bench_results_free(kg_bench_results **r)
{
	if (!r || !*r)
		return;
	free((*r)->error);
	free((*r)->speed);
	free((*r)->limit);
	free((*r)->camspace.rows);
	free(*r);
	*r = NULL;
}

static int file_exists(const char *dir, const char *name)
{
	char *p = kg_path_join(dir, name);
	struct stat st;
	int ok = p && stat(p, &st) == 0 && S_ISREG(st.st_mode);
	free(p);
	return ok;
}

static int read_set(const char *dir, const char *name, kg_patchset **out, kg_err *err)
{
	char *p = kg_path_join(dir, name);
	if (!p)
		return kg_fail(err, KG_ENOMEM, "bench: out of memory");
	int ret = kg_sim_read_spectra(p, 0, out, err);
	free(p);
	return ret;
}

static int load_camera(const char *dir, const char *name, kg_sim_camera *cam, kg_err *err)
{
	char file[256];
	snprintf(file, sizeof(file), "cameras/%s.csv", name);
	char *p = kg_path_join(dir, file);
	if (!p)
		return kg_fail(err, KG_ENOMEM, "bench: out of memory");
	int ret = kg_sim_camera_load(p, 0, cam, err);
	free(p);
	return ret;
}

static void describe_machine(kg_bench_results *r)
{
	char model[160] = "unknown CPU";
	FILE *fp = fopen("/proc/cpuinfo", "r");
	if (fp) {
		char line[512];
		while (fgets(line, sizeof(line), fp))
			if (strncmp(line, "model name", 10) == 0) {
				const char *v = strchr(line, ':');
				if (v) {
					snprintf(model, sizeof(model), "%s", v + 1 + (v[1] == ' '));
					model[strcspn(model, "\n")] = '\0';
				}
				break;
			}
		fclose(fp);
	}
	struct utsname u;
	const char *sys = uname(&u) == 0 ? u.machine : "?";
	snprintf(r->machine, sizeof(r->machine), "%s, %ld online CPUs, %s", model,
	         sysconf(_SC_NPROCESSORS_ONLN), sys);
	time_t now = time(NULL);
	struct tm tm;
	gmtime_r(&now, &tm);
	strftime(r->date, sizeof(r->date), "%Y-%m-%d %H:%M UTC", &tm);
}

/* The reference data the error part needs, or a note saying what is missing. */
static int reference_present(const char *dir, char *note, size_t len)
{
	static const char *const files[] = {CC24_FILE, MUNSELL_FILE, CES_FILE};
	if (!dir) {
		snprintf(note, len, "no reference directory given");
		return 0;
	}
	for (size_t i = 0; i < sizeof(files) / sizeof(files[0]); i++)
		if (!file_exists(dir, files[i])) {
			snprintf(note, len,
			         "%s/%s not found: the error part needs the reference data set "
			         "(set KOGEI_REFERENCE or --reference DIR)",
			         dir, files[i]);
			return 0;
		}
	return 1;
}

static int error_part(const kg_bench_config *cfg, const kg_bench_colour *col,
                      kg_bench_results *r, kg_err *err)
{
	kg_patchset *cc24 = NULL, *munsell = NULL, *ces = NULL;
	kg_illuminant *d65 = NULL;
	kg_sim_camera cams[NCAMERAS];
	int ncam = 0;
	int ret = read_set(cfg->reference_dir, CC24_FILE, &cc24, err);
	if (!ret)
		ret = read_set(cfg->reference_dir, MUNSELL_FILE, &munsell, err);
	if (!ret)
		ret = read_set(cfg->reference_dir, CES_FILE, &ces, err);
	if (!ret)
		ret = kg_illuminant_by_name("D65", &d65, err);
	for (int i = 0; i < NCAMERAS && !ret; i++) {
		kg_err cerr = {{0}};
		if (load_camera(cfg->reference_dir, bench_cameras[i], &cams[ncam], &cerr) == 0)
			ncam++;
		else
			bench_progress(cfg, "[error] camera %s left out: %s", bench_cameras[i],
			               cerr.msg);
	}
	if (!ret && ncam == 0) {
		r->error_skipped = 1;
		snprintf(r->error_note, sizeof(r->error_note),
		         "none of the bench's cameras were found under %s/cameras",
		         cfg->reference_dir);
	}
	if (ret || ncam == 0)
		goto done;

	const struct {
		const char *train_name, *test_name;
		const kg_patchset *train, *test;
	} pairs[2] = {
		{"CC24", "Munsell", cc24, munsell},
		{"Munsell", "CES99", munsell, ces},
	};
	int total = ncam * 2 * 2;
	r->error = calloc((size_t)total, sizeof(*r->error));
	if (!r->error) {
		ret = kg_fail(err, KG_ENOMEM, "bench: out of memory");
		goto done;
	}
	for (int c = 0; c < ncam && !ret; c++)
		for (int p = 0; p < 2 && !ret; p++)
			for (int noisy = 0; noisy < 2 && !ret; noisy++) {
				kg_bench_error_row *row = &r->error[r->nerror];
				kg_bench_case bc = {
				    .camera = &cams[c],
				    .illuminant = &d65->spd,
				    .train = pairs[p].train,
				    .test = pairs[p].test,
				    .noise = noisy ? &r->noise : NULL,
				    .seed = r->seed + 2u * (uint64_t)r->nerror,
				    .wiener_sigma = r->wiener_sigma,
				};
				ret = kg_bench_error_case(col, &bc, row, err);
				if (ret) {
					kg_err_prefix(err, "bench: %s, %s -> %s", cams[c].name,
					              pairs[p].train_name, pairs[p].test_name);
					break;
				}
				_Static_assert(sizeof(row->camera) == sizeof(cams[c].name), "camera name");
				memcpy(row->camera, cams[c].name, sizeof(row->camera));
				snprintf(row->train, sizeof(row->train), "%s", pairs[p].train_name);
				snprintf(row->test, sizeof(row->test), "%s", pairs[p].test_name);
				r->nerror++;
				const kg_bench_metrics *m = &row->m[KG_BENCH_PCA3];
				bench_progress(cfg,
				               "[error %d/%d] %-22s %-7s -> %-7s %-9s pca3: RMSE %.4f, "
				               "dE00 D65 %.2f (auto K = %d)",
				               r->nerror, total, row->camera, row->train, row->test,
				               noisy ? "noisy" : "noise-free", m->rmse, m->de_d65_mean,
				               row->K_auto);
			}
done:
	kg_patchset_free(&cc24);
	kg_patchset_free(&munsell);
	kg_patchset_free(&ces);
	kg_illuminant_free(&d65);
	return ret;
}

/* The materials of the label output: the library's at normal incidence, then at
 * 60 degrees, then (if still short, or without a library) spectra of the test set. */
static int speed_materials(const kg_bench_config *cfg, const kg_patchset *fill,
                           kg_spectrum *spectra, char (*names)[64], kg_err *err)
{
	int n = 0;
	for (int a = 0; a < 2 && cfg->materials && n < cfg->nmaterials; a++) {
		kg_sim_material_set *set = NULL;
		kg_err merr = {{0}};
		if (kg_sim_material_set_load(cfg->materials, NULL, a ? 60.0 : 0.0, &set, &merr)) {
			bench_progress(cfg, "[speed] material library not used: %s", merr.msg);
			break;
		}
		for (int i = 0; i < set->n && n < cfg->nmaterials; i++, n++) {
			spectra[n] = set->reflectance[i];
			snprintf(names[n], sizeof(names[n]), "%s%s", set->names[i], a ? "@60deg" : "");
		}
		kg_sim_material_set_free(&set);
	}
	for (int i = 0; n < cfg->nmaterials && i < fill->n; i++, n++) {
		spectra[n] = fill->spectra[i * 7 % fill->n];
		snprintf(names[n], sizeof(names[n]), "sample-%s", fill->ids[i * 7 % fill->n]);
	}
	if (n < cfg->nmaterials)
		return kg_fail(err, KG_EINVAL, "bench: only %d materials for the label output", n);
	return 0;
}

static int speed_part(const kg_bench_config *cfg, kg_bench_results *r, kg_err *err)
{
	kg_patchset *chart = NULL, *scene = NULL;
	kg_sim_camera cam;
	kg_reference *ref3 = NULL, *ref_auto = NULL;
	kg_est_kernel *k[KG_BENCH_NMETHODS] = {0};
	kg_est_classifier *cls = NULL;
	double *chart_rgb = NULL, *scene_rgb = NULL;
	float *rgb = NULL, *conf = NULL;
	void *out = NULL;
	kg_spectrum *mat = NULL;
	char(*mat_names)[64] = NULL;
	kg_est_material *mats = NULL;
	int ret;

	/* The kernels: the first bench camera on the ColorChecker, noise-free; a
	 * synthetic camera and chart when the reference data are absent. */
	char note[256];
	if (cfg->reference_dir && reference_present(cfg->reference_dir, note, sizeof(note)) &&
	    load_camera(cfg->reference_dir, bench_cameras[0], &cam, NULL) == 0) {
		ret = read_set(cfg->reference_dir, CC24_FILE, &chart, err);
		if (!ret)
			ret = read_set(cfg->reference_dir, MUNSELL_FILE, &scene, err);
		snprintf(r->speed_calibration, sizeof(r->speed_calibration),
		         "%s under D65 on ColorChecker 24 (noise-free); image pixels from Munsell",
		         cam.name);
	} else {
		kg_bench_synthetic_camera(&cam);
		ret = kg_bench_synthetic_spectra(24, r->seed, &chart, err);
		if (!ret)
			ret = kg_bench_synthetic_spectra(400, r->seed + 1, &scene, err);
		snprintf(r->speed_calibration, sizeof(r->speed_calibration),
		         "synthetic camera and spectra (reference data absent)");
	}
	kg_illuminant *d65 = NULL;
	if (!ret)
		ret = kg_illuminant_by_name("D65", &d65, err);
	kg_sim_capture cap;
	if (!ret)
		ret = kg_sim_capture_init(&cap, &cam, &d65->spd, KG_BENCH_WHITE_LEVEL, NULL, err);
	kg_illuminant_free(&d65);
	if (ret)
		goto done;
	chart_rgb = malloc(sizeof(double) * 3 * (size_t)chart->n);
	scene_rgb = malloc(sizeof(double) * 3 * (size_t)scene->n);
	if (!chart_rgb || !scene_rgb) {
		ret = kg_fail(err, KG_ENOMEM, "bench: out of memory");
		goto done;
	}
	kg_sim_patches(&cap, chart->spectra, chart->n, r->seed, chart_rgb);
	kg_sim_patches(&cap, scene->spectra, scene->n, r->seed, scene_rgb);
	ret = kg_bench_fit(chart, chart_rgb, 3, r->wiener_sigma, &ref3, err);
	if (!ret)
		ret = kg_bench_fit(chart, chart_rgb, 0, r->wiener_sigma, &ref_auto, err);
	if (!ret)
		ret = kg_bench_kernels_new(ref3, ref_auto, k, NULL, err);
	if (ret)
		goto done;

	/* Classifier over the declared materials. */
	mat = calloc((size_t)cfg->nmaterials, sizeof(*mat));
	mat_names = calloc((size_t)cfg->nmaterials, sizeof(*mat_names));
	mats = calloc((size_t)cfg->nmaterials, sizeof(*mats));
	if (!mat || !mat_names || !mats) {
		ret = kg_fail(err, KG_ENOMEM, "bench: out of memory");
		goto done;
	}
	ret = speed_materials(cfg, scene, mat, mat_names, err);
	for (int i = 0; i < cfg->nmaterials && !ret; i++)
		mats[i] = (kg_est_material){mat_names[i], mat[i].v};
	if (!ret && k[KG_BENCH_PCA3])
		ret = kg_est_classifier_new(k[KG_BENCH_PCA3], mats, cfg->nmaterials,
		                            KG_EST_DIST_PLAIN, &cls, err);
	if (ret)
		goto done;

	/* The image: scene samples in random order under a random shading. */
	r->width = IMAGE_WIDTH;
	r->height = (int)fmax(1.0, floor(cfg->mpix * 1e6 / IMAGE_WIDTH + 0.5));
	size_t npix = (size_t)r->width * (size_t)r->height;
	rgb = malloc(sizeof(float) * 3 * npix);
	conf = malloc(sizeof(float) * npix);
	size_t out_bytes = npix * KG_NBANDS * sizeof(float);
	if (!rgb || !conf || posix_memalign(&out, 4096, out_bytes) != 0) {
		out = NULL;
		ret = kg_fail(err, KG_ENOMEM, "bench: out of memory for a %.1f Mpix image (%.2f GB)",
		              (double)npix * 1e-6, (double)out_bytes * 1e-9);
		goto done;
	}
	kg_rng rng;
	kg_rng_seed(&rng, r->seed);
	for (size_t i = 0; i < npix; i++) {
		const double *s = scene_rgb + 3 * (kg_rng_next(&rng) % (uint64_t)scene->n);
		double shade = 0.3 + 0.7 * kg_rng_uniform(&rng);
		for (int c = 0; c < 3; c++)
			rgb[3 * i + c] = (float)(s[c] * shade);
	}
	/* Fault the output pages in now: that cost belongs to no kernel. */
	memset(out, 0, out_bytes);
	memset(conf, 0, sizeof(float) * npix);
	bench_progress(cfg, "[speed] %dx%d image (%.1f Mpix), %d repetitions, kernels from %s",
	               r->width, r->height, (double)npix * 1e-6, cfg->reps,
	               r->speed_calibration);
	ret = bench_speed_all(cfg, k, cls, rgb, r->width, r->height, out, conf, r, err);
done:
	kg_est_classifier_free(&cls);
	kg_bench_kernels_free(k);
	kg_reference_free(&ref3);
	kg_reference_free(&ref_auto);
	kg_patchset_free(&chart);
	kg_patchset_free(&scene);
	free(chart_rgb);
	free(scene_rgb);
	free(rgb);
	free(conf);
	free(out);
	free(mat);
	free(mat_names);
	free(mats);
	return ret;
}

int kg_bench_run(const kg_bench_config *cfg, kg_bench_results **out, kg_err *err)
{
	kg_check_arg(cfg && out && cfg->nthreads > 0 && cfg->threads && cfg->mpix > 0, err);
	kg_check_arg(cfg->reps > 0 && cfg->nmaterials > 0 &&
	             cfg->nmaterials <= KG_EST_MAX_MATERIALS, err);
	kg_check_arg(!cfg->run_camspace || cfg->camspace_mpix > 0, err);
	*out = NULL;
	kg_bench_results *r = calloc(1, sizeof(*r));
	if (!r)
		return kg_fail(err, KG_ENOMEM, "bench: out of memory");
	snprintf(r->command, sizeof(r->command), "%s", cfg->command ? cfg->command : "");
	describe_machine(r);
	r->quick = cfg->quick;
	r->reps = cfg->reps;
	r->nmaterials = cfg->nmaterials;
	r->noise = (kg_sim_noise){.full_well = 20000, .read_noise = 10, .bits = 12};
	r->seed = BENCH_SEED;
	r->wiener_sigma = WIENER_SIGMA;
	snprintf(r->stream_kind, sizeof(r->stream_kind), "%s", kg_bench_stream_kind());

	kg_bench_colour col;
	int ret = kg_bench_colour_init(&col, err);
	double t0 = kg_bench_now();
	if (!ret && cfg->run_error) {
		if (!reference_present(cfg->reference_dir, r->error_note, sizeof(r->error_note))) {
			r->error_skipped = 1;
			bench_progress(cfg, "[error] skipped: %s", r->error_note);
		} else {
			ret = error_part(cfg, &col, r, err);
		}
	} else if (!cfg->run_error) {
		r->error_skipped = 1;
		snprintf(r->error_note, sizeof(r->error_note), "not run (--no-error)");
	}
	r->seconds_error = kg_bench_now() - t0;
	t0 = kg_bench_now();
	if (!ret && cfg->run_speed)
		ret = speed_part(cfg, r, err);
	r->seconds_speed = kg_bench_now() - t0;
	t0 = kg_bench_now();
	if (!ret && cfg->run_camspace)
		ret = bench_camspace(cfg, r, err);
	r->seconds_camspace = kg_bench_now() - t0;
	if (ret) {
		kg_bench_results_free(&r);
		return ret;
	}
	*out = r;
	return 0;
}
