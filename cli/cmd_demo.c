/* `kogei demo`: the whole pipeline on a simulated session, writing everything a
 * person would look at into one folder.
 *
 * The session is simulated from data a fresh machine has: the CIE 13.3 test colour
 * samples of colord-data as the chart (in the AprilTag frame of
 * fixtures/demo/cie-tcs-frame.json), two model cameras (fixtures/demo/), CIE D65
 * and A, and the default material library. The chart's spectra are measured patch by
 * patch with the simulated spectrophotometer (devices/, as `kogei measure`), the chart
 * is photographed (sim/'s chart scenes) and found in the photographs by its tags
 * (calib/'s chart detection); the steps call the same C APIs the commands use
 * (devices/, sim/, calib/, estimate/), never the command line. */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "chart_scene_glue.h"
#include "demo.h"
#include "kg_devices.h"

static const char usage_demo[] =
	"kogei demo [-o DIR]\n"
	"  Runs a simulated session through the whole pipeline and writes its outputs to\n"
	"  DIR (default out/demo): the chart's spectra measured patch by patch with the\n"
	"  simulated spectrophotometer (" DEMO_SPECTRO "),\n"
	"  a photograph of the chart in its AprilTag frame, the\n"
	"  chart found by its tags (overlay, patch file) -> calib reference -> another\n"
	"  photograph by the site camera under another illuminant, found the same way ->\n"
	"  calib camera -> object image of the library's metals, alloys and lacquer ->\n"
	"  estimate (61-band ENVI cube) -> classify (label map), then plots of estimated\n"
	"  against true spectra per material, the confusion matrix and summary.md. Also\n"
	"  the paper's Fig. 7 for nami-shibuichi (table and heat map) and a swatch sheet\n"
	"  of the material library under D65.\n"
	"  Needs " DEMO_CHART " (package colord-data).";

char *demo_path(demo_ctx *d, const char *name)
{
	return kg_path_join(d->dir, name);
}

void demo_wrote(demo_ctx *d, const char *path, const char *what)
{
	printf("  wrote %-40s %s\n", path, what);
	d->nwritten++;
}

/* The paper's Fig. 7 and the swatch sheet of the library. */
static int demo_materials(demo_ctx *d)
{
	char *csv = demo_path(d, "fig7_shibuichi-nami.csv");
	char *png = demo_path(d, "fig7_shibuichi-nami.png");
	char *swatch = demo_path(d, "materials_d65.png");
	kg_material_library *lib = NULL;
	kg_illuminant *d65 = NULL;
	double angles[18], table[KG_NBANDS * 18];
	for (int j = 0; j < 18; j++)
		angles[j] = 5.0 * j;
	int ret = kg_material_library_load(d->library_path, &lib, &d->err);
	if (!ret)
		ret = kg_illuminant_by_name("D65", &d65, &d->err);
	const kg_material *m = NULL;
	if (!ret && !(m = kg_material_library_find(lib, "shibuichi-nami")))
		ret = kg_fail(&d->err, KG_EINVAL, "%s: no material 'shibuichi-nami'",
		              d->library_path);
	if (!ret)
		ret = kg_model_table(m, angles, 18, table, &d->err);
	if (!ret && !(ret = kg_model_table_write_csv(csv, angles, 18, table, &d->err)))
		demo_wrote(d, csv, "Fig. 7 table: reflectance by wavelength x incidence");
	if (!ret && !(ret = kg_model_figure(png, "shibuichi-nami (Ag 25.0 / Cu 74.9 / Au 0.1)",
	                                    angles, 18, table, d65, &d->err)))
		demo_wrote(d, png, "Fig. 7 heat map with the reflected D65 colour");
	if (!ret && !(ret = kg_swatch_sheet(swatch, lib, d65, &d->err)))
		demo_wrote(d, swatch, "swatches of every library material, normal incidence, D65");
	kg_material_library_free(&lib);
	kg_illuminant_free(&d65);
	free(csv);
	free(png);
	free(swatch);
	return ret;
}

/* The detection summary of a shot, from the result and the patch set it gave. */
static void shot_summarise(demo_chart_shot *sh, const kg_chart_result *res,
                           const kg_patchset *ps, const kg_patchset *truth)
{
	static const char channel[3] = {'R', 'G', 'B'};
	size_t at = 0;
	sh->tags_used[0] = '\0';
	for (int i = 0; i < res->ntags && at < sizeof(sh->tags_used) - 1; i++)
		if (res->tags[i].used)
			at += (size_t)snprintf(sh->tags_used + at, sizeof(sh->tags_used) - at, "%s%d",
			                       at ? "," : "", res->tags[i].id);
	sh->ntags_used = res->ntags_used;
	sh->rms_px = res->rms_px;
	sh->npatches = res->npatches;
	sh->nsampled = ps->n;
	sh->nwarnings = res->nwarnings;
	sh->detect_ms = 1e3 * res->total_seconds;
	sh->tag_ms = 1e3 * res->tag_seconds;
	sh->decimate = res->decimate;
	sh->nflagged = 0;
	sh->worst_sd = -1;
	sh->max_error = 0;
	for (int i = 0; i < res->npatches; i++) {
		const kg_chart_sample *p = &res->patches[i];
		if (p->flags)
			sh->nflagged++;
		if (p->flags & KG_CHART_FLAG_REJECTED)
			continue;
		/* The noise-free patch means the session was recorded from, by id. */
		int ti = truth->rgb ? kg_patchset_find(truth, p->id) : -1;
		const double *t = ti >= 0 ? truth->rgb[ti] : NULL;
		for (int c = 0; c < 3; c++) {
			if (p->sd[c] > sh->worst_sd) {
				sh->worst_sd = p->sd[c];
				snprintf(sh->worst_id, sizeof(sh->worst_id), "%s", p->id);
				sh->worst_channel = channel[c];
			}
			if (t)
				sh->max_error = fmax(sh->max_error, 100.0 * fabs(p->rgb[c] - t[c]));
		}
	}
}

/* One camera's photograph of the chart in its frame: the averaged capture replayed
 * from the bundled session (demo_session_replay), the chart found by its tags and
 * sampled (calib/), the overlay and the patch file written. The patch file is what the
 * calibration reads. The noise-free patch means the session was rendered from
 * (fixtures/demo/<role>_chart_truth.cgats) judge the readings. */
static int shoot_chart(demo_ctx *d, const kg_chart_layout *layout, demo_chart_shot *sh)
{
	const kg_image *img = sh == &d->shots[0] ? d->photos.reference_chart : d->photos.site_chart;
	char image_name[128], name[64];
	snprintf(image_name, sizeof(image_name), "session/captures/%s/%s",
	         sh == &d->shots[0] ? DEMO_CAPTURE_REFERENCE : DEMO_CAPTURE_SITE,
	         img && img->cfa ? "mean.tif" : "rgb.tif");
	snprintf(name, sizeof(name), "%s_chart_overlay.png", sh->role);
	char *overlay_path = demo_path(d, name);
	snprintf(name, sizeof(name), "%s_chart.cgats", sh->role);
	char *patch_path = demo_path(d, name);
	snprintf(name, sizeof(name), "demo/%s_chart_truth.cgats", sh->role);
	char *truth_path = kg_data_path(name);
	kg_patchset *truth = NULL;
	kg_chart_result *res = NULL;
	kg_patchset *ps = NULL;
	int ret = truth_path ? kg_patchset_read(truth_path, KG_PATCH_RGB, &truth, &d->err)
	                     : kg_fail(&d->err, KG_ENOMEM, "out of memory");
	if (!ret && !img)
		ret = kg_fail(&d->err, KG_EINVAL, "the session has no %s chart capture", sh->role);
	if (!ret)
		printf("  %s chart photograph: %dx%d, %s, replayed from the session\n", sh->role,
		       img->width, img->height, img->cfa ? "raw Bayer mean" : "demosaiced RGB mean");
	kg_chart_detect_options opt;
	kg_chart_detect_options_default(&opt);
	if (!ret && (ret = kg_chart_detect(layout, img, &opt, &res, &d->err)))
		kg_err_prefix(&d->err, "%s: chart %s not found: ", image_name, layout->name);
	if (!ret)
		ret = kg_chart_result_patchset(res, &ps, &d->err);
	if (!ret) {
		shot_summarise(sh, res, ps, truth);
		printf("  chart found: %d tags used (%s), homography RMS %.3f px, %d of %d patches "
		       "sampled, worst patch spread %.4f (%s %c), %.0f ms (decimate %d)\n",
		       sh->ntags_used, sh->tags_used, sh->rms_px, sh->nsampled, sh->npatches,
		       sh->worst_sd, sh->worst_id, sh->worst_channel, sh->detect_ms, sh->decimate);
		printf("  patch values within %.3f %% of full scale of the noise-free truth\n",
		       sh->max_error);
		for (int i = 0; i < res->nwarnings; i++)
			printf("  warning: %s\n", res->warnings[i]);
	}
	if (!ret && !(ret = kg_chart_overlay_write(res, img, overlay_path, 0, &d->err)))
		demo_wrote(d, overlay_path, "what detection found: tags, outline, sampled regions");
	if (!ret) {
		char seed_text[32], rms[32], decimate[16], pose[128];
		snprintf(seed_text, sizeof(seed_text), "%llu", (unsigned long long)sh->seed);
		snprintf(rms, sizeof(rms), "%.4f", res->rms_px);
		snprintf(decimate, sizeof(decimate), "%d", res->decimate);
		snprintf(pose, sizeof(pose), "tilt %g axis %g rotate %g", sh->tilt_deg,
		         sh->tilt_axis_deg, sh->rotate_deg);
		const char *keywords[] = {
			"ORIGINATOR", "kogei demo",
			"DESCRIPTOR", "chart readings found in a replayed photograph (linear, 0..1)",
			"CHART_LAYOUT", layout->name,
			"IMAGE", image_name, /* relative to the patch file */
			"DETECTOR", "apriltag",
			"TAG_FAMILY", layout->family,
			"TAG_DECIMATE", decimate,
			"TAGS_USED", sh->tags_used[0] ? sh->tags_used : "none",
			"HOMOGRAPHY_RMS_PX", rms,
			"PATCH_STATISTIC", kg_chart_statistic_name(opt.statistic),
			"CAMERA", sh->camera,
			"ILLUMINANT", sh->illuminant,
			"NOISE", sh->noise,
			"POSE", pose,
			"SEED", seed_text,
			"SPECTRA", DEMO_CHART,
			NULL,
		};
		ret = kg_patchset_write(patch_path, ps, KG_PATCH_RGB | KG_PATCH_EXTRA, keywords,
		                        &d->err);
	}
	if (!ret)
		demo_wrote(d, patch_path, sh == &d->shots[0]
		                              ? "the reference camera's chart readings (rho, rho0)"
		                              : "the site camera's chart readings (rho_r)");
	kg_patchset_free(&ps);
	kg_patchset_free(&truth);
	kg_chart_result_free(&res);
	free(truth_path);
	free(overlay_path);
	free(patch_path);
	return ret;
}

/* Per patch of the unattended chart measurement: a compact progress line. */
typedef struct measure_progress {
	demo_ctx *d;
	const kg_patchset *file; /* the spectra the instrument measures */
} measure_progress;

static void measure_patch_done(void *user, int i, int n, const char *id,
                               const kg_spectrum *s)
{
	measure_progress *mp = user;
	demo_spectro_run *sr = &mp->d->spectro;
	int k = kg_patchset_find(mp->file, id);
	double rmse = NAN, worst = 0, worst_nm = 0;
	if (k >= 0) {
		rmse = kg_spectrum_rmse(s, &mp->file->spectra[k]);
		for (int b = 0; b < KG_NBANDS; b++) {
			double e = fabs(s->v[b] - mp->file->spectra[k].v[b]);
			if (e > worst) {
				worst = e;
				worst_nm = kg_band_nm(b);
			}
		}
	}
	if (i < DEMO_MAX_PATCHES) {
		sr->rmse[i] = rmse;
		sr->max_diff[i] = worst;
		if (rmse > sr->rmse_max) {
			sr->rmse_max = rmse;
			sr->rmse_max_at = i;
		}
		if (worst > sr->diff_max) {
			sr->diff_max = worst;
			sr->diff_max_at = i;
			sr->diff_max_nm = worst_nm;
		}
		sr->rmse_mean += rmse / n;
	}
	printf("  [%2d/%d] %-6s %-28s RMSE vs file %.4f, max |diff| %.4f\n", i + 1, n, id,
	       i < DEMO_MAX_PATCHES ? mp->d->patch_names[i] : "", rmse, worst);
}

static void measure_warning(void *user, const char *message)
{
	demo_ctx *d = user;
	d->spectro.nwarnings++;
	printf("  warning: %s\n", message);
}

/* Step 1: the chart's spectra measured with the spectrophotometer, unattended, as
 * `kogei measure --chart LAYOUT --yes` measures them: dark, white (flat 0.99
 * standard), every patch of the layout in order, averaged scans, reflectance on the
 * 61-band grid; written as `kogei measure` writes and compared with the file whose
 * spectra the simulated instrument measures. */
static int demo_measure_chart(demo_ctx *d, const kg_patchset *file)
{
	char *path = demo_path(d, DEMO_CHART_SPECTRA);
	demo_spectro_run *sr = &d->spectro;
	kg_measure_session m = {
		.uri = DEMO_SPECTRO,
		.warn = measure_warning,
		.warn_user = d,
	};
	kg_acquire_options_default(&m.acq);
	m.acq.scans = DEMO_SPECTRO_SCANS;
	kg_patchset *measured = NULL;
	const char *ids[DEMO_MAX_PATCHES];
	for (int i = 0; i < d->npatches; i++)
		ids[i] = d->patch_ids[i];
	struct timespec t0, t1;
	clock_gettime(CLOCK_MONOTONIC, &t0);
	int ret = path ? kg_white_reference_load(NULL, &m.white_refl, &d->err)
	               : kg_fail(&d->err, KG_ENOMEM, "out of memory");
	if (!ret)
		ret = kg_spectro_open(DEMO_SPECTRO, &m.spectro, &d->err);
	if (!ret)
		ret = kg_spectro_set_integration(m.spectro, DEMO_SPECTRO_INTEGRATION_US, &d->err);
	if (!ret) {
		const kg_spectro_info *info = kg_spectro_get_info(m.spectro);
		snprintf(sr->model, sizeof(sr->model), "%s", info->model);
		snprintf(sr->serial, sizeof(sr->serial), "%s", info->serial);
		sr->integration_us = info->integration_us;
		sr->scans = m.acq.scans;
		sr->boxcar = m.acq.boxcar;
		sr->npatches = d->npatches;
		printf("  %s %s (%d pixels, %.0f-%.0f nm), integration %.0f ms, %d scans averaged; "
		       "dark, white (flat 0.99), then each patch\n",
		       info->model, info->serial, info->npixels, kg_spectro_wavelength(info, 0),
		       kg_spectro_wavelength(info, info->npixels - 1), sr->integration_us / 1e3,
		       sr->scans);
		measure_progress mp = {.d = d, .file = file};
		ret = kg_spectro_measure_patches(&m, d->npatches, ids, measure_patch_done, &mp,
		                                 &measured, &d->err);
		if (ret)
			kg_err_prefix(&d->err, "%s: ", DEMO_SPECTRO);
	}
	if (!ret) {
		const char *extra[] = {"DESCRIPTOR", "the demo chart measured with the simulated "
		                                     "spectrophotometer (kogei demo, step 1)",
		                       "CHART_LAYOUT", d->layout_name, NULL};
		ret = kg_measure_write(&m, path, measured, "kogei demo", extra, &d->err);
	}
	clock_gettime(CLOCK_MONOTONIC, &t1);
	sr->ms = 1e3 * (t1.tv_sec - t0.tv_sec) + 1e-6 * (t1.tv_nsec - t0.tv_nsec);
	if (!ret) {
		printf("  measured against the file: RMSE mean %.4f, worst %.4f (%s); largest "
		       "|diff| %.4f (%s at %.0f nm); %.0f ms\n",
		       sr->rmse_mean, sr->rmse_max, d->patch_ids[sr->rmse_max_at], sr->diff_max,
		       d->patch_ids[sr->diff_max_at], sr->diff_max_nm, sr->ms);
		demo_wrote(d, path, "the chart's spectra S as measured (kogei measure's format)");
	}
	kg_patchset_free(&measured);
	kg_measure_session_clear(&m);
	kg_spectro_free(&m.spectro);
	free(path);
	return ret;
}

/* Step 1: the chart measured with the spectrophotometer. Steps 2 and 3: the chart
 * through the reference camera, calib reference with the measured spectra; the same
 * chart through the site camera, calib camera. The photographs render the chart as it
 * is (the file's spectra: the physical samples); the calibration knows only what the
 * spectrophotometer measured. */
static int demo_calibrate(demo_ctx *d)
{
	char *spectra = demo_path(d, DEMO_CHART_SPECTRA);
	char *ref_rgb = demo_path(d, "reference_chart.cgats");
	char *site_rgb = demo_path(d, "site_chart.cgats");
	char *ref_json = demo_path(d, "reference.json");
	char *cam_json = demo_path(d, "camera.json");
	kg_patchset *chart = NULL;
	kg_chart_layout *layout = NULL;
	kg_camera_calib *fitted = NULL;
	kg_mat *m2 = NULL;
	int ret = access(DEMO_CHART, R_OK) == 0
	              ? kg_sim_read_spectra(DEMO_CHART, 0, &chart, &d->err)
	              : kg_fail(&d->err, KG_ENOENT,
	                        "%s: cannot read it: the demo's chart comes from the Debian "
	                        "package colord-data",
	                        DEMO_CHART);
	if (!ret)
		ret = kg_chart_layout_load(d->layout_path, &layout, &d->err);
	if (ret)
		goto done;
	if (layout->npatches > DEMO_MAX_PATCHES) {
		ret = kg_fail(&d->err, KG_EINVAL, "%s: %d patches, the demo takes at most %d",
		              d->layout_path, layout->npatches, DEMO_MAX_PATCHES);
		goto done;
	}
	d->npatches = layout->npatches;
	snprintf(d->layout_name, sizeof(d->layout_name), "%s", layout->name);
	snprintf(d->layout_family, sizeof(d->layout_family), "%s", layout->family);
	d->sample_fraction = layout->sample_fraction;
	for (int i = 0; i < layout->npatches; i++) {
		snprintf(d->patch_ids[i], sizeof(d->patch_ids[i]), "%s", layout->patches[i].id);
		snprintf(d->patch_names[i], sizeof(d->patch_names[i]), "%s", layout->patches[i].name);
	}

	printf("[1/8] chart spectra: the %d patches of %s measured with the spectrophotometer "
	       "(%s)\n",
	       layout->npatches, layout->name, DEMO_SPECTRO);
	if ((ret = demo_measure_chart(d, chart)) != 0)
		goto done;

	printf("[2/8] reference calibration: chart %s (%d patches of %s in an AprilTag frame), "
	       "reference camera under %s; S from %s\n",
	       layout->name, layout->npatches, DEMO_CHART, DEMO_REFERENCE_ILLUMINANT,
	       DEMO_CHART_SPECTRA);
	ret = shoot_chart(d, layout, &d->shots[0]);
	kg_reference_options ropt;
	kg_reference_options_default(&ropt);
	/* S as measured, read back from the file, as `kogei calib reference` would. */
	if (!ret)
		ret = kg_reference_fit_files(spectra, ref_rgb, NULL, &ropt, &d->ref, &d->err);
	if (!ret && !(ret = kg_reference_save(d->ref, ref_json, &d->err))) {
		const kg_spectral_map *pca = &d->ref->maps[KG_METHOD_PCA];
		printf("  PCA K = %d (energy %.4f), M by least squares; leave-one-out RMSE %.4f, "
		       "dE00 %.2f\n",
		       d->ref->K, d->ref->energy[d->ref->K - 1], pca->loo_rmse, pca->loo_de00);
		demo_wrote(d, ref_json, "B, M, rho0 and the chart's residuals");
	}
	if (ret)
		goto done;

	printf("[3/8] site calibration: the same chart, another model camera under CIE %s, "
	       "noise %s\n",
	       DEMO_SITE_ILLUMINANT, DEMO_SITE_NOISE);
	ret = shoot_chart(d, layout, &d->shots[1]);
	kg_camera_options copt;
	kg_camera_options_default(&copt);
	if (!ret)
		ret = kg_camera_fit_files(ref_json, site_rgb, &copt, &fitted, &d->err);
	if (!ret)
		ret = kg_camera_save(fitted, cam_json, &d->err);
	/* Go on from the file, as a later session would. */
	if (!ret)
		ret = kg_camera_load(cam_json, &d->cam, &d->err);
	if (!ret)
		ret = kg_mat_from(3, 3, d->cam->M2, &m2, &d->err);
	if (!ret)
		ret = kg_cond(m2, 0, &d->cond_m2, &d->err);
	if (!ret) {
		printf("  M2 = rho0 pinv(rho_r): condition number %.3g (site chart %.3g); "
		       "residual %.2f %%\n",
		       d->cond_m2, d->cam->cond, 100.0 * d->cam->residual_relative);
		demo_wrote(d, cam_json, "M2 and the site fit");
	}
done:
	kg_mat_free(&m2);
	kg_camera_calib_free(&fitted);
	kg_chart_layout_free(&layout);
	kg_patchset_free(&chart);
	free(spectra);
	free(ref_rgb);
	free(site_rgb);
	free(ref_json);
	free(cam_json);
	return ret;
}

/* Step 3: the object, every sample of the library in the specular view of the site
 * camera. Pixels outside the samples are set to NaN (no data), as a segmentation
 * mask would leave them: estimate and classify flag them instead of labelling the
 * background. */
static int demo_object(demo_ctx *d)
{
	char *image = demo_path(d, "object.tif");
	char *truth = demo_path(d, "object_truth.hdr");
	char *labels = demo_path(d, "object_truth_labels.hdr");
	kg_sim_material_set *set = NULL;
	kg_sim_noise noise;
	kg_sim_capture cap;
	printf("[4/8] object: the library's samples at %g deg incidence, site camera under "
	       "CIE %s\n",
	       DEMO_ANGLE_DEG, DEMO_SITE_ILLUMINANT);
	int ret = kg_sim_noise_parse(DEMO_SITE_NOISE, &noise, &d->err);
	if (!ret)
		ret = kg_sim_capture_load(&cap, d->site_camera, DEMO_SITE_ILLUMINANT,
		                          DEMO_WHITE_LEVEL, &noise, 0, &d->err);
	if (!ret)
		ret = kg_sim_material_set_load(d->library_path, NULL, DEMO_ANGLE_DEG, &set, &d->err);
	if (!ret) {
		kg_sim_scene_desc desc = {
			.materials = set->reflectance,
			.material_names = (const char *const *)set->names,
			.nmaterials = set->n,
			.tile = DEMO_TILE,
			.gap = DEMO_TILE / 4,
			.columns = 5,
			.background = 0.0,
		};
		ret = kg_sim_scene_new(&desc, &cap, DEMO_SEED_OBJECT, &d->scene, &d->err);
	}
	/* The photograph is the session's object capture; the scene supplies the ground
	 * truth it was rendered from (the same layout, fixtures/demo/make_session.sh). */
	const kg_image *photo = d->photos.object;
	if (!ret && (!photo || photo->channels != 3 || photo->width != d->scene->width ||
	             photo->height != d->scene->height))
		ret = kg_fail(&d->err, KG_EINVAL,
		              "the session's object capture is %dx%d with %d channels; the demo's "
		              "scene is %dx%d RGB (re-record with fixtures/demo/make_session.sh)",
		              photo ? photo->width : 0, photo ? photo->height : 0,
		              photo ? photo->channels : 0, d->scene->width, d->scene->height);
	if (!ret) {
		kg_sim_scene *s = d->scene;
		for (long i = 0; i < 3L * s->width * s->height; i++)
			s->rgb[i] = photo->data[i];
		for (long i = 0; i < (long)s->width * s->height; i++)
			if (s->sample[i] < 0)
				s->rgb[3 * i] = s->rgb[3 * i + 1] = s->rgb[3 * i + 2] = NAN;
		ret = kg_sim_scene_write(s, image, KG_SIM_DEPTH_F32, truth, labels, &d->err);
	}
	if (!ret) {
		printf("  %d materials, %dx%d pixels, noise %s\n", d->scene->nclasses - 1,
		       d->scene->width, d->scene->height, DEMO_SITE_NOISE);
		demo_wrote(d, image, "the site camera's image (float TIFF, NaN off the samples)");
		demo_wrote(d, truth, "ground truth: true reflectance cube");
		demo_wrote(d, labels, "ground truth: label map");
	}
	kg_sim_material_set_free(&set);
	free(image);
	free(truth);
	free(labels);
	return ret;
}

/* Step 4: the object image read back, estimated into a cube and classified, with
 * the camera's default method (the paper's PCA, K = 3). */
static int demo_estimate(demo_ctx *d)
{
	char *image = demo_path(d, "object.tif");
	char *cube = demo_path(d, "cube.hdr");
	char *labels = demo_path(d, "labels.hdr");
	char *labels_json = demo_path(d, "labels.json");
	char *labels_png = demo_path(d, "labels.png");
	kg_image *img = NULL;
	kg_est_kernel *kern = NULL;
	kg_material_library *lib = NULL;
	kg_est_material_set *set = NULL;
	double pre[9];
	int pre_needed = 0;
	char stats[256];
	kg_apply_options opt;
	kg_apply_options_init(&opt);
	opt.description = "kogei demo: the object's reflectance, estimated";

	printf("[5/8] estimate and classify (method %s)\n", kg_method_name(d->cam->method));
	int ret = kg_image_read(image, &img, &d->err);
	if (!ret)
		ret = kg_camera_kernel(d->cam, KG_METHOD_AUTO, 0, &kern, pre, &pre_needed, &d->err);
	if (!ret) {
		opt.pre = pre_needed ? pre : NULL;
		ret = kg_estimate_image(kern, img, KG_EST_F32_BSQ, &opt, cube, &d->est_stats,
		                        &d->err);
	}
	if (!ret) {
		kg_est_stats_format(&d->est_stats, stats, sizeof(stats));
		printf("  %s\n", stats);
		demo_wrote(d, cube, "61-band reflectance cube (ENVI float32, BSQ) + cube_mask");
	}
	if (!ret)
		ret = kg_material_library_load(d->library_path, &lib, &d->err);
	if (!ret)
		ret = kg_est_material_set_new(lib, d->library_path, NULL, 0, DEMO_ANGLE_DEG, &set,
		                              &d->err);
	if (!ret) {
		kg_classify_info info = {
			.calib = "camera.json",
			.materials = d->library_path,
			.method = kg_method_name(d->cam->method),
			.image = "object.tif",
		};
		opt.description = NULL;
		ret = kg_classify_image(kern, set, KG_EST_DIST_PLAIN, img, &opt, &info, labels,
		                        &d->classes, &d->err);
	}
	if (!ret) {
		printf("  %d materials at %g deg incidence, plain distance (eq. 11)\n", set->n,
		       DEMO_ANGLE_DEG);
		demo_wrote(d, labels, "label map (ENVI classification) + confidence, mask");
		demo_wrote(d, labels_json, "classes, pixel counts, mean spectra, confidence");
		demo_wrote(d, labels_png, "label map preview");
	}
	kg_est_material_set_free(&set);
	kg_material_library_free(&lib);
	kg_est_kernel_free(&kern);
	kg_image_free(&img);
	free(image);
	free(cube);
	free(labels);
	free(labels_json);
	free(labels_png);
	return ret;
}

static void demo_free(demo_ctx *d)
{
	free(d->library_path);
	free(d->reference_camera);
	free(d->site_camera);
	free(d->layout_path);
	kg_reference_free(&d->ref);
	kg_camera_calib_free(&d->cam);
	kg_sim_scene_free(&d->scene);
	kg_classify_result_free(&d->classes);
	demo_photos_free(&d->photos);
}

int kg_cmd_demo(int argc, char **argv)
{
	demo_ctx d = {
		.dir = "out/demo",
		.shots = {
			{.role = "reference", .camera = DEMO_REFERENCE_CAMERA,
			 .illuminant = DEMO_REFERENCE_ILLUMINANT, .noise = DEMO_REFERENCE_NOISE,
			 .tilt_deg = DEMO_REFERENCE_TILT, .tilt_axis_deg = DEMO_REFERENCE_TILT_AXIS,
			 .rotate_deg = DEMO_REFERENCE_ROTATE, .blur_px = DEMO_REFERENCE_BLUR,
			 .vignetting = DEMO_REFERENCE_VIGNETTING, .seed = DEMO_SEED_REFERENCE},
			{.role = "site", .camera = DEMO_SITE_CAMERA,
			 .illuminant = DEMO_SITE_ILLUMINANT, .noise = DEMO_SITE_NOISE,
			 .tilt_deg = DEMO_SITE_TILT, .tilt_axis_deg = DEMO_SITE_TILT_AXIS,
			 .rotate_deg = DEMO_SITE_ROTATE, .blur_px = DEMO_SITE_BLUR,
			 .vignetting = DEMO_SITE_VIGNETTING, .seed = DEMO_SEED_SITE},
		},
	};
	static const struct option opts[] = {
		{"output", required_argument, NULL, 'o'},
		{"help", no_argument, NULL, 'h'},
		{0, 0, 0, 0},
	};
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "o:h", opts, NULL)) != -1) {
		switch (c) {
		case 'o': d.dir = optarg; break;
		case 'h': puts(usage_demo); return KG_EXIT_OK;
		default: return kg_cli_usage_error(usage_demo, "bad option");
		}
	}
	if (optind != argc)
		return kg_cli_usage_error(usage_demo, "unexpected argument '%s'", argv[optind]);
	d.library_path = kg_data_path("materials/default.json");
	d.reference_camera = kg_data_path(DEMO_REFERENCE_CAMERA);
	d.site_camera = kg_data_path(DEMO_SITE_CAMERA);
	d.layout_path = kg_data_path(DEMO_CHART_LAYOUT);
	int ret = d.library_path && d.reference_camera && d.site_camera && d.layout_path
	              ? kg_mkdir_p(d.dir, &d.err)
	              : kg_fail(&d.err, KG_ENOMEM, "out of memory");
	if (!ret) {
		printf("kogei demo: writing to %s/\n", d.dir);
		printf("[0/8] the bundled session: its recorded frames replayed through the "
		       "replay: camera and averaged (acquire/)\n");
		ret = demo_session_replay(&d, &d.photos);
	}
	if (!ret)
		ret = demo_calibrate(&d);
	if (!ret)
		ret = demo_object(&d);
	if (!ret)
		ret = demo_estimate(&d);
	if (!ret) {
		printf("[6/8] reflection models of the material library\n");
		ret = demo_materials(&d);
	}
	if (!ret) {
		printf("[7/8] the object rendered in each material of the paper's Fig. 13 "
		       "(render/, Embree)\n");
		ret = demo_render(&d);
	}
	if (!ret) {
		printf("[8/8] report: estimated against true spectra, confusion, summary\n");
		ret = demo_report(&d);
	}
	demo_free(&d);
	if (ret)
		return kg_cli_error(&d.err, ret);
	printf("kogei demo: done, %d outputs in %s/\n", d.nwritten, d.dir);
	return KG_EXIT_OK;
}
