/* The reference camera's spectral response learned from a chart (calib/response.c),
 * on real data (../shared/reference; skipped without it). Cameras are simulated from
 * published sensitivities (Nikon D5100, Canon EOS 5D Mark II) under CIE D65, white at
 * 0.9 in the brightest channel, noise-free. The response is learned from the 24
 * ColorChecker patches (BabelColor average) and predicts the readings of spectra it
 * never saw:
 *  - the 1269 Munsell matt chips: relative RMS error (all chips, all channels);
 *  - the library's metals and alloys at 30 degrees (the readings the camera-space
 *    classifier compares pixels with): the largest relative error of any channel.
 * Bounds are the errors that keep materials apart: the library's closest pair
 * (copper and shakudo) differs by about 0.5 % in RGB, so the prediction error is
 * reported against it as well. Also: the reference file keeps the response
 * bit for bit, and the site calibration carries it. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "kg_calib.h"
#include "kg_test.h"
#include "kg_test_camera.h"

static char path_buf[8192];

static const char *ref_path(const char *dir, const char *name)
{
	snprintf(path_buf, sizeof(path_buf), "%s/%s", dir, name);
	return path_buf;
}

static kg_patchset *with_rgb(const char *dir, const char *name, const kg_spectrum w[3])
{
	kg_patchset *s = NULL, *ps = NULL;
	kg_err err = {{0}};
	if (kg_csv_read_spectra_rows(ref_path(dir, name), 0, &s, &err) ||
	    kg_patchset_new(s->n, KG_PATCH_SPECTRA | KG_PATCH_RGB, &ps, &err)) {
		fprintf(stderr, "%s\n", err.msg);
		kg_test_failures++;
		kg_patchset_free(&s);
		return NULL;
	}
	for (int i = 0; i < s->n; i++) {
		ps->spectra[i] = s->spectra[i];
		for (int c = 0; c < 3; c++)
			ps->rgb[i][c] = kg_spectrum_dot(&w[c], &s->spectra[i]);
		kg_patchset_set_id(ps, i, s->ids[i], &err);
	}
	kg_patchset_free(&s);
	return ps;
}

/* noise: the chart's readings get this relative Gaussian noise (0: none); the bounds
 * are for that case. */
static void check_camera(const char *dir, const char *camera, const kg_material_library *lib,
                         double noise, double munsell_bound, double metal_bound)
{
	kg_spectrum w[3];
	kg_err err = {{0}};
	CHECK(kg_test_camera_weights(dir, camera, "D65", w, &err) == 0, "%s: %s", camera, err.msg);
	kg_patchset *cc = with_rgb(dir, "charts/colorchecker24_babelcolor_avg.csv", w);
	uint64_t st = 0x9E3779B97F4A7C15ULL;
	for (int i = 0; cc && i < cc->n; i++)
		for (int c = 0; c < 3; c++)
			cc->rgb[i][c] *= 1 + noise * kg_test_gauss(&st);
	kg_patchset *munsell = with_rgb(dir, "reflectance/munsell_matt_uef1269_5nm.csv", w);
	kg_response r;
	int ret = cc && munsell ? kg_response_fit(cc, &r, &err) : -1;
	CHECK(ret == 0, "%s: response: %s", camera, err.msg);
	if (ret) {
		kg_patchset_free(&cc);
		kg_patchset_free(&munsell);
		return;
	}
	double num = 0, den = 0;
	for (int i = 0; i < munsell->n; i++) {
		double p[3];
		kg_response_apply(&r, munsell->spectra[i].v, p);
		for (int c = 0; c < 3; c++) {
			num += (p[c] - munsell->rgb[i][c]) * (p[c] - munsell->rgb[i][c]);
			den += munsell->rgb[i][c] * munsell->rgb[i][c];
		}
	}
	double munsell_rel = sqrt(num / den);
	printf("%s, chart readings with %.1f %% noise: learned from 24 ColorChecker patches "
	       "(lambda %.3g %.3g %.3g, LOO %.5f relative)\n", camera, 100 * noise, r.lambda[0],
	       r.lambda[1], r.lambda[2], r.loo_relative);
	printf("  Munsell 1269 (held out): relative RMS error %.5f\n", munsell_rel);
	CHECK(munsell_rel < munsell_bound, "%s: Munsell relative error %.5f: expected < %g",
	      camera, munsell_rel, munsell_bound);
	double worst = 0;
	for (int j = 0; j < kg_material_library_count(lib); j++) {
		const kg_material *mat = kg_material_library_get(lib, j);
		kg_spectrum s;
		if (kg_material_reflectance(mat, 30.0 * M_PI / 180.0, &s, &err)) {
			CHECK(0, "%s: %s", mat->name, err.msg);
			continue;
		}
		double p[3], t[3], e = 0;
		kg_response_apply(&r, s.v, p);
		for (int c = 0; c < 3; c++) {
			t[c] = kg_spectrum_dot(&w[c], &s);
			e = fmax(e, fabs(p[c] - t[c]) / t[c]);
		}
		printf("  %-26s true %.4f %.4f %.4f predicted %.4f %.4f %.4f (%.3f %%)\n", mat->name,
		       t[0], t[1], t[2], p[0], p[1], p[2], 100 * e);
		worst = fmax(worst, e);
	}
	printf("  library at 30 degrees: largest channel error %.3f %%\n", 100 * worst);
	CHECK(worst < metal_bound, "%s: a library material predicted %.3f %% off: expected < "
	      "%g %%", camera, 100 * worst, 100 * metal_bound);
	kg_patchset_free(&cc);
	kg_patchset_free(&munsell);
}

/* The reference file keeps the response; the site calibration carries it. */
static void check_files(const char *dir)
{
	kg_spectrum w[3];
	kg_err err = {{0}};
	if (kg_test_camera_weights(dir, "cameras/Nikon_D5100.csv", "D65", w, &err))
		return;
	kg_patchset *cc = with_rgb(dir, "charts/colorchecker24_babelcolor_avg.csv", w);
	kg_reference_options opt;
	kg_reference_options_default(&opt);
	kg_reference *ref = NULL, *back = NULL;
	kg_camera_calib *cam = NULL, *cam_back = NULL;
	char tmpl[] = "/tmp/kogei-response-XXXXXX";
	const char *d = mkdtemp(tmpl);
	char rp[256], cp[256];
	snprintf(rp, sizeof(rp), "%s/ref.json", d);
	snprintf(cp, sizeof(cp), "%s/cam.json", d);
	int ret = cc ? kg_reference_fit(cc, cc, &opt, &ref, &err) : -1;
	CHECK(ret == 0 && ref->response.available, "reference fit: %s", err.msg);
	if (!ret)
		ret = kg_reference_save(ref, rp, &err) || kg_reference_load(rp, &back, &err);
	CHECK(ret == 0, "reference round trip: %s", err.msg);
	if (!ret)
		CHECK(back->response.available && !strcmp(back->response.source, "chart") &&
		      memcmp(back->response.F, ref->response.F, sizeof(ref->response.F)) == 0 &&
		      back->response.patches == 24,
		      "the reference file keeps the response bit for bit");
	if (!ret)
		ret = kg_camera_fit(ref, cc, NULL, &cam, &err) || kg_camera_save(cam, cp, &err) ||
		      kg_camera_load(cp, &cam_back, &err);
	CHECK(ret == 0, "camera round trip: %s", err.msg);
	if (!ret)
		CHECK(memcmp(cam_back->response.F, ref->response.F, sizeof(ref->response.F)) == 0,
		      "the site calibration carries the reference's response");
	unlink(rp);
	unlink(cp);
	rmdir(d);
	kg_camera_calib_free(&cam);
	kg_camera_calib_free(&cam_back);
	kg_reference_free(&ref);
	kg_reference_free(&back);
	kg_patchset_free(&cc);
}

/* From the sensitivities: the camera's own weights (unscaled: sensitivity times light,
 * the exposure unknown) fitted to a noisy chart recover the true response within the
 * noise's reach, and predict every library material within 1 %. */
static void check_from_camera(const char *dir, const kg_material_library *lib)
{
	kg_spectrum w[3], raw[3];
	kg_err err = {{0}};
	if (kg_test_camera_weights(dir, "cameras/Nikon_D5100.csv", "D65", w, &err)) {
		CHECK(0, "%s", err.msg);
		return;
	}
	for (int c = 0; c < 3; c++)
		raw[c] = kg_spectrum_scale(&w[c], 3.7 + c); /* any scale: the fit finds it */
	kg_patchset *cc = with_rgb(dir, "charts/colorchecker24_babelcolor_avg.csv", w);
	uint64_t st = 7;
	for (int i = 0; cc && i < cc->n; i++)
		for (int c = 0; c < 3; c++)
			cc->rgb[i][c] *= 1 + 0.005 * kg_test_gauss(&st);
	kg_response r;
	int ret = cc ? kg_response_from_camera(raw, cc, &r, &err) : -1;
	CHECK(ret == 0 && !strcmp(r.source, "camera"), "from the camera: %s", err.msg);
	double worst = 0;
	for (int j = 0; !ret && j < kg_material_library_count(lib); j++) {
		kg_spectrum s;
		if (kg_material_reflectance(kg_material_library_get(lib, j), 30.0 * M_PI / 180.0, &s,
		                            &err))
			continue;
		double p[3];
		kg_response_apply(&r, s.v, p);
		for (int c = 0; c < 3; c++) {
			double t = kg_spectrum_dot(&w[c], &s);
			worst = fmax(worst, fabs(p[c] - t) / t);
		}
	}
	printf("from the D5100's sensitivities, chart with 0.5 %% noise: LOO %.5f relative, "
	       "library at 30 degrees within %.3f %%\n", ret ? NAN : r.loo_relative, 100 * worst);
	CHECK(!ret && worst < 0.01, "from the camera: a library material %.3f %% off", 100 * worst);
	kg_patchset_free(&cc);
}

int main(void)
{
	const char *dir = kg_test_reference_dir();
	char lib_path[4096];
	snprintf(lib_path, sizeof(lib_path), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	kg_material_library *lib = NULL;
	kg_err err = {{0}};
	CHECK(kg_material_library_load(lib_path, &lib, &err) == 0, "%s", err.msg);
	if (lib) {
		/* noise-free: well inside the copper-shakudo difference (0.5 %) */
		check_camera(dir, "cameras/Nikon_D5100.csv", lib, 0, 0.005, 0.0025);
		check_camera(dir, "cameras/Canon_EOS_5D_Mark_II.csv", lib, 0, 0.005, 0.0025);
		/* 0.5 % noise on the chart (a well exposed 16-frame capture) */
		check_camera(dir, "cameras/Nikon_D5100.csv", lib, 0.005, 0.02, 0.02);
		check_camera(dir, "cameras/Canon_EOS_5D_Mark_II.csv", lib, 0.005, 0.02, 0.02);
		check_from_camera(dir, lib);
	}
	check_files(dir);
	kg_material_library_free(&lib);
	return kg_test_done("calib-response");
}
