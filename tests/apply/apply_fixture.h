/* Shared pieces of the tests of `kogei estimate` and `kogei classify`:
 *  - a temporary directory and a runner for the kogei program (argv[1] of a test);
 *  - a synthetic calibration that needs no reference data: 40 smooth spectra (not
 *    confined to 3 dimensions, so every method has something to fit), a camera of
 *    three Gaussian sensitivities, and a site camera mixing its channels, fitted
 *    through calib/'s API and saved as CAM.json;
 *  - a small float TIFF with ordinary pixels plus the hard cases: NaN and Inf
 *    channels, clipped channels, and dark saturated colours whose estimate goes
 *    negative (clamped). */
#ifndef APPLY_FIXTURE_H
#define APPLY_FIXTURE_H

#include <dirent.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdint.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "kg_calib.h"
#include "kg_test_camera.h"
#include "kg_test.h"

static const char *fx_kogei;
static char fx_dir[] = "/tmp/kogei-apply-XXXXXX";
static char fx_out[1 << 16], fx_errs[1 << 16];

/* A path in the test directory. Each call returns its own buffer, valid until the
 * program ends (a test makes a few hundred at most). */
static inline const char *fx_path(const char *name)
{
	static char pool[1024][512];
	static int next;
	if (next == 1024) {
		fprintf(stderr, "fx_path: out of path buffers\n");
		exit(1);
	}
	char *p = pool[next++];
	snprintf(p, sizeof(pool[0]), "%s/%s", fx_dir, name);
	return p;
}

static inline void fx_setup(int argc, char **argv)
{
	if (argc < 2) {
		fprintf(stderr, "usage: %s KOGEI\n", argv[0]);
		exit(2);
	}
	fx_kogei = argv[1];
	if (!mkdtemp(fx_dir)) {
		perror("mkdtemp");
		exit(1);
	}
}

/* Remove the directory and everything in it (flat). */
static inline void fx_cleanup(void)
{
	DIR *d = opendir(fx_dir);
	if (!d)
		return;
	for (struct dirent *e; (e = readdir(d));)
		if (strcmp(e->d_name, ".") && strcmp(e->d_name, ".."))
			unlink(fx_path(e->d_name));
	closedir(d);
	rmdir(fx_dir);
}

static inline int fx_count_files(void)
{
	int n = 0;
	DIR *d = opendir(fx_dir);
	if (!d)
		return -1;
	for (struct dirent *e; (e = readdir(d));)
		n += strcmp(e->d_name, ".") && strcmp(e->d_name, "..");
	closedir(d);
	return n;
}

/* Run kogei with args (n of them); stdout and stderr land in fx_out and fx_errs (and
 * stderr is echoed to the test log). Returns the exit status. */
static inline int fx_runv(const char *const *args, int nargs)
{
	char *argv[48];
	int n = 0;
	argv[n++] = (char *)fx_kogei;
	for (int i = 0; i < nargs && n < 47; i++)
		argv[n++] = (char *)args[i];
	argv[n] = NULL;
	char out_path[] = "/tmp/kogei-apply-out-XXXXXX", err_path[] = "/tmp/kogei-apply-err-XXXXXX";
	int fo = mkstemp(out_path), fe = mkstemp(err_path);
	fflush(NULL);
	pid_t pid = fork();
	if (pid == 0) {
		dup2(fo, 1);
		dup2(fe, 2);
		execv(fx_kogei, argv);
		_exit(127);
	}
	int status = 0;
	waitpid(pid, &status, 0);
	close(fo);
	close(fe);
	kg_test_slurp(out_path, fx_out, sizeof(fx_out));
	kg_test_slurp(err_path, fx_errs, sizeof(fx_errs));
	unlink(out_path);
	unlink(err_path);
	fprintf(stderr, "$ kogei");
	for (int i = 1; i < n; i++)
		fprintf(stderr, " %s", argv[i]);
	fprintf(stderr, "\n%s", fx_errs);
	return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/* fx_runv with the arguments given (NULL-terminated). */
static inline int fx_run(const char *first, ...)
{
	const char *args[46];
	int n = 0;
	args[n++] = first;
	va_list ap;
	va_start(ap, first);
	for (const char *a; n < 46 && (a = va_arg(ap, const char *));)
		args[n++] = a;
	va_end(ap);
	return fx_runv(args, n);
}
#define FX_RUN(...) fx_run(__VA_ARGS__, (char *)NULL)

/* ---- the synthetic calibration ---------------------------------------------------- */

static inline double fx_rand(uint64_t *s)
{
	*s ^= *s >> 12;
	*s ^= *s << 25;
	*s ^= *s >> 27;
	return (double)((*s * 2685821657736338717ULL) >> 11) / 9007199254740992.0;
}

static inline void fx_sensitivities(kg_spectrum sens[3], const double mix[9])
{
	static const double centre[3] = {605, 540, 460}, width[3] = {35, 40, 28};
	kg_spectrum base[3];
	for (int c = 0; c < 3; c++)
		for (int l = 0; l < KG_NBANDS; l++)
			base[c].v[l] = exp(-0.5 * pow((kg_band_nm(l) - centre[c]) / width[c], 2));
	for (int r = 0; r < 3; r++)
		for (int l = 0; l < KG_NBANDS; l++)
			sens[r].v[l] = mix[3 * r] * base[0].v[l] + mix[3 * r + 1] * base[1].v[l] +
			               mix[3 * r + 2] * base[2].v[l];
	kg_test_expose(sens);
}

static const double fx_identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
static const double fx_site_mix[9] = {1.00, 0.12, 0.00, 0.06, 0.95, 0.04, 0.00, 0.15, 0.85};

/* Spectra: a smooth level, slope and two bumps with random weights, kept in
 * (0.03, 0.95). */
static inline kg_patchset *fx_chart(int m, const kg_spectrum sens[3], uint64_t seed)
{
	kg_patchset *ps = NULL;
	kg_err err = {{0}};
	if (kg_patchset_new(m, KG_PATCH_SPECTRA | KG_PATCH_RGB, &ps, &err)) {
		fprintf(stderr, "fx_chart: %s\n", err.msg);
		return NULL;
	}
	uint64_t st = seed * 0x9E3779B97F4A7C15ULL + 1;
	for (int i = 0; i < m; i++) {
		double a0 = 0.2 + 0.4 * fx_rand(&st), a1 = (fx_rand(&st) - 0.5) * 0.4;
		double a2 = (fx_rand(&st) - 0.3) * 0.4, a3 = (fx_rand(&st) - 0.5) * 0.3;
		double c2 = 480 + 80 * fx_rand(&st);
		for (int l = 0; l < KG_NBANDS; l++) {
			double x = (kg_band_nm(l) - 550.0) / 150.0;
			double v = a0 + a1 * x + a2 * exp(-0.5 * pow((kg_band_nm(l) - c2) / 40.0, 2)) +
			           a3 * exp(-0.5 * pow((kg_band_nm(l) - 640) / 30.0, 2));
			ps->spectra[i].v[l] = fmin(0.95, fmax(0.03, v));
		}
		for (int c = 0; c < 3; c++)
			ps->rgb[i][c] = kg_spectrum_dot(&sens[c], &ps->spectra[i]);
		char id[16];
		snprintf(id, sizeof(id), "P%d", i + 1);
		kg_patchset_set_id(ps, i, id, &err);
	}
	return ps;
}

/* Fit the synthetic reference and site camera and save the camera to CAM.json in
 * the test directory. Returns the camera (caller frees) or NULL. */
static inline kg_camera_calib *fx_make_camera(const char *cam_path)
{
	kg_spectrum ref_sens[3], site_sens[3];
	fx_sensitivities(ref_sens, fx_identity);
	fx_sensitivities(site_sens, fx_site_mix);
	kg_patchset *chart = fx_chart(40, ref_sens, 7), *site = NULL;
	kg_reference *ref = NULL;
	kg_camera_calib *cam = NULL;
	kg_err err = {{0}};
	kg_reference_options ro;
	kg_reference_options_default(&ro);
	kg_camera_options co;
	kg_camera_options_default(&co);
	int rc = chart ? 0 : -1;
	if (!rc)
		rc = kg_reference_fit(chart, chart, &ro, &ref, &err);
	if (!rc)
		rc = kg_patchset_new(chart->n, KG_PATCH_RGB, &site, &err);
	for (int i = 0; !rc && i < chart->n; i++) {
		for (int c = 0; c < 3; c++)
			site->rgb[i][c] = kg_spectrum_dot(&site_sens[c], &chart->spectra[i]);
		rc = kg_patchset_set_id(site, i, chart->ids[i], &err);
	}
	if (!rc)
		rc = kg_camera_fit(ref, site, &co, &cam, &err);
	if (!rc)
		rc = kg_camera_save(cam, cam_path, &err);
	if (rc) {
		fprintf(stderr, "synthetic calibration: %s\n", err.msg);
		kg_camera_calib_free(&cam);
	}
	kg_reference_free(&ref);
	kg_patchset_free(&chart);
	kg_patchset_free(&site);
	return cam;
}

/* Expected flags of the fixture image's pixels. */
enum { FX_OK, FX_NAN, FX_INF, FX_CLIPPED };

/* A w x h float image of site-camera readings of random smooth spectra (values up
 * to about 0.9), with NaN, Inf and clipped pixels scattered, and a few dark
 * saturated colours that estimate negative. kind[] (may be NULL) receives FX_*. */
static inline kg_image *fx_image(int w, int h, int *kind)
{
	kg_image *img = NULL;
	kg_err err = {{0}};
	if (kg_image_new(w, h, 3, &img, &err)) {
		fprintf(stderr, "fx_image: %s\n", err.msg);
		return NULL;
	}
	uint64_t st = 12345;
	for (int i = 0; i < w * h; i++) {
		float *p = img->data + 3 * i;
		int k = FX_OK;
		double u = fx_rand(&st);
		for (int c = 0; c < 3; c++)
			p[c] = (float)(0.02 + 0.85 * fx_rand(&st));
		if (i % 9 == 4) { /* dark, saturated: one channel near 0 */
			p[(i / 9) % 3] = 0.002f;
			p[((i / 9) + 1) % 3] = 0.3f;
		}
		if (u < 0.03) {
			p[i % 3] = NAN;
			k = FX_NAN;
		} else if (u < 0.05) {
			p[(i + 1) % 3] = (i % 2) ? INFINITY : -INFINITY;
			k = FX_INF;
		} else if (u < 0.08) {
			p[(i + 2) % 3] = (u < 0.065) ? 1.0f : 0.9995f;
			k = FX_CLIPPED;
		}
		if (kind)
			kind[i] = k;
	}
	return img;
}

/* The calibration of the tests on the paper's materials (needs ../shared/reference):
 * reference camera Nikon D5100 and site camera Canon EOS 5D Mark II under D65, both
 * fitted on the ColorChecker 24 (BabelColor average) through noise-free `kogei sim
 * patches`, `kogei calib reference` (pca, K = 3) and `kogei calib camera --method pca`
 * into cam_path. site_camera receives the site camera's sensitivities file (for
 * `kogei sim image`). Returns 1 on success, 0 on failure (fx_errs says why), 77 when
 * the reference files are missing. */
static inline int fx_paper_calibration(const char *cam_path, char *site_camera, size_t len)
{
	const char *refdir = kg_test_reference_dir();
	char chart[8192], refcam[8192];
	snprintf(chart, sizeof(chart), "%s/charts/colorchecker24_babelcolor_avg.csv", refdir);
	snprintf(refcam, sizeof(refcam), "%s/cameras/Nikon_D5100.csv", refdir);
	snprintf(site_camera, len, "%s/cameras/Canon_EOS_5D_Mark_II.csv", refdir);
	if (!kg_test_file_exists(chart) || !kg_test_file_exists(refcam) ||
	    !kg_test_file_exists(site_camera))
		return 77;
	const char *ref_rgb = fx_path("ref.cgats"), *site_rgb = fx_path("site.cgats");
	const char *ref = fx_path("ref.json");
	return FX_RUN("sim", "patches", "--spectra", chart, "--camera", refcam, "--illuminant",
	              "D65", "-o", ref_rgb) == 0 &&
	       FX_RUN("sim", "patches", "--spectra", chart, "--camera", site_camera,
	              "--illuminant", "D65", "-o", site_rgb) == 0 &&
	       FX_RUN("calib", "reference", "--spectra", chart, "--rgb", ref_rgb, "-o", ref) == 0 &&
	       FX_RUN("calib", "camera", "--reference", ref, "--rgb", site_rgb, "--method", "pca",
	              "-o", cam_path) == 0;
}

/* The class names of a classification file into names (at most max; class 0 first);
 * returns how many. */
static inline int fx_class_names(const kg_envi *e, char names[][KG_EST_CLASS_NAME_MAX], int max)
{
	int n = 0;
	for (; e && e->meta.class_names && n < e->meta.classes && n < max; n++)
		snprintf(names[n], KG_EST_CLASS_NAME_MAX, "%s", e->meta.class_names[n]);
	return n;
}

/* Read a whole ENVI file as floats (BIP layout); caller frees. */
static inline float *fx_read_envi(const char *path, kg_envi **out_e)
{
	kg_envi *e = NULL;
	kg_err err = {{0}};
	if (kg_envi_open(path, &e, &err)) {
		fprintf(stderr, "%s\n", err.msg);
		return NULL;
	}
	size_t n = (size_t)e->meta.samples * e->meta.lines * e->meta.bands;
	float *v = malloc(n * sizeof(float));
	if (!v || kg_envi_read(e, 0, 0, e->meta.samples, e->meta.lines, KG_LAYOUT_BIP, v, &err)) {
		fprintf(stderr, "%s: %s\n", path, err.msg);
		free(v);
		kg_envi_close(&e);
		return NULL;
	}
	if (out_e)
		*out_e = e;
	else
		kg_envi_close(&e);
	return v;
}

#endif
