/* `kogei demo`: the bundled session replayed, then the same job as `kogei process`,
 * and the demo's comparisons with the simulation's truth (kg_demo.h).
 *
 * The session (fixtures/demo/session, recorded from the sim camera by
 * fixtures/demo/make_session.sh) is replayed through the replay: camera into a lab
 * session (the reference camera's chart) and a site session (the site camera's chart
 * and the object); the chart's spectra are measured patch by patch with the simulated
 * spectrophotometer (devices/, as `kogei measure`); kg_process_run turns the lab
 * session into the reference and the site session into its calibration, cube, labels,
 * scene and report. The object's truth (the material and incidence angle of each
 * pixel of the render the object's photograph was taken of, recorded with the
 * session) then judges the cube and the labels. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "demo_private.h"
#include "kg_demo.h"
#include "kg_devices.h"
#include "kg_pipeline.h"

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

/* A shot's detection as process.json records it, judged against the noise-free patch
 * means the session was rendered from (fixtures/demo/<role>_chart_truth.cgats). */
static int shot_from_process(demo_ctx *d, const char *process_json, demo_chart_shot *sh)
{
	static const char channel[3] = {'R', 'G', 'B'};
	char name[64];
	snprintf(name, sizeof(name), "demo/%s_chart_truth.cgats", sh->role);
	char *truth_path = kg_data_path(name);
	kg_patchset *truth = NULL;
	json_t *root = NULL;
	int ret = truth_path ? kg_patchset_read(truth_path, 0, &truth, &d->err)
	                     : kg_fail(&d->err, KG_ENOMEM, "out of memory");
	if (!ret)
		ret = kg_json_load(process_json, &root, &d->err);
	if (!ret) {
		kg_inputs_forget(process_json);
		const json_t *c = json_object_get(root, "calibration"), *e;
		size_t i, at = 0;
		sh->tags_used[0] = '\0';
		sh->ntags_used = 0;
		json_array_foreach(json_object_get(c, "tags_used"), i, e)
		{
			sh->ntags_used++;
			if (at < sizeof(sh->tags_used) - 1)
				at += (size_t)snprintf(sh->tags_used + at, sizeof(sh->tags_used) - at, "%s%d",
				                       at ? "," : "", (int)json_integer_value(e));
		}
		sh->rms_px = json_number_value(json_object_get(c, "homography_rms_px"));
		sh->detect_ms = 1e3 * json_number_value(json_object_get(c, "detect_seconds"));
		sh->decimate = (int)json_integer_value(json_object_get(c, "decimate"));
		sh->npatches = (int)json_array_size(json_object_get(c, "patches"));
		sh->nsampled = sh->nflagged = 0;
		sh->worst_sd = -1;
		sh->max_error = 0;
		json_array_foreach(json_object_get(c, "patches"), i, e)
		{
			const char *id = json_string_value(json_object_get(e, "id"));
			const json_t *rgb = json_object_get(e, "rgb"), *sd = json_object_get(e, "sd");
			if (json_integer_value(json_object_get(e, "flags")))
				sh->nflagged++;
			if (!id || !json_is_array(rgb))
				continue;
			sh->nsampled++;
			int ti = kg_patchset_find(truth, id);
			for (int k = 0; k < 3; k++) {
				double v = json_number_value(json_array_get(rgb, (size_t)k));
				double spread = json_number_value(json_array_get(sd, (size_t)k));
				if (spread > sh->worst_sd) {
					sh->worst_sd = spread;
					snprintf(sh->worst_id, sizeof(sh->worst_id), "%s", id);
					sh->worst_channel = channel[k];
				}
				if (ti >= 0 && truth->rgb)
					sh->max_error = fmax(sh->max_error, 100.0 * fabs(v - truth->rgb[ti][k]));
			}
		}
		const json_t *est = kg_json_find(json_array_get(json_object_get(root, "objects"), 0),
		                                 "estimate");
		if (est) {
			d->est_stats.pixels = (uint64_t)json_integer_value(json_object_get(est, "pixels"));
			d->est_stats.nonfinite =
				(uint64_t)json_integer_value(json_object_get(est, "nonfinite"));
			d->est_stats.clamped_pixels =
				(uint64_t)json_integer_value(json_object_get(est, "clamped"));
		}
		printf("  %s chart: %d tags used (%s), homography RMS %.3f px, %d of %d patches, "
		       "worst spread %.4f (%s %c); within %.3f %% of full scale of the noise-free "
		       "truth\n",
		       sh->role, sh->ntags_used, sh->tags_used, sh->rms_px, sh->nsampled, sh->npatches,
		       sh->worst_sd, sh->worst_id, sh->worst_channel, sh->max_error);
	}
	json_decref(root);
	kg_patchset_free(&truth);
	free(truth_path);
	return ret;
}

/* The object record the demo passes (--meta), an example: every value is made up. */
static json_t *demo_meta(const char *session, kg_err *err)
{
	static const char *const kv[][2] = {
		{"accession", "DEMO-0001"},
		{"title", "Tsuba (sword guard) of shibuichi, gold, copper and urushi (simulated)"},
		{"operator", "kogei demo"},
		{"lighting", NULL},
		{"notes", "An example record: the object, its capture and these values are "
		          "made up by kogei demo."},
	};
	char lighting[160];
	int lab = !strcmp(session, "lab-session");
	snprintf(lighting, sizeof(lighting), "simulated CIE illuminant %s (the %s session)",
	         lab ? DEMO_REFERENCE_ILLUMINANT : DEMO_SITE_ILLUMINANT, lab ? "lab" : "site");
	json_t *m = json_object();
	for (size_t i = 0; m && i < sizeof(kv) / sizeof(kv[0]); i++)
		if (kg_meta_set(m, "demo record", kv[i][0], kv[i][1] ? kv[i][1] : lighting, err)) {
			json_decref(m);
			return NULL;
		}
	if (!m)
		kg_fail(err, KG_ENOMEM, "out of memory");
	return m;
}

/* The same job as `kogei process` on one of the replayed sessions. */
static int demo_process(demo_ctx *d, const char *session, const char *reference,
                        const char *out)
{
	char *s = demo_path(d, session), *o = demo_path(d, out);
	char *spectra = demo_path(d, DEMO_CHART_SPECTRA);
	char *ref = reference ? demo_path(d, reference) : NULL;
	int ret = s && o && spectra && (!reference || ref)
	              ? 0 : kg_fail(&d->err, KG_ENOMEM, "out of memory");
	kg_process_options po;
	kg_process_options_default(&po);
	po.session = s;
	po.outdir = o;
	po.spectra = spectra;
	po.reference = ref;
	po.materials = d->library_path;
	po.angle_deg = DEMO_ANGLE_DEG;
	memcpy(d->angles, po.angles, sizeof(d->angles));
	po.progress = stdout;
	po.command = "kogei demo";
	po.accept_rerecorded = 1; /* the sessions are recorded anew at every run */
	json_t *meta = ret ? NULL : demo_meta(session, &d->err);
	if (!ret && !meta)
		ret = KG_EINVAL; /* the message is in d->err */
	po.meta = meta;
	kg_process_summary sum;
	if (!ret)
		ret = kg_process_run(&po, &sum, &d->err);
	json_decref(meta);
	if (!ret)
		printf("  %s -> %s/: %d object(s), M2 residual %.2f %%, %d warning(s), %.1f s\n",
		       session, out, sum.objects, 100 * sum.residual, sum.warnings, sum.seconds);
	free(s);
	free(o);
	free(spectra);
	free(ref);
	return ret;
}

/* Step 1: the chart measured with the spectrophotometer; steps 2 and 3: kogei process
 * on the lab session (the reference from its chart and the measured spectra) and on
 * the site session (its calibration against that reference, then the object). */
static int demo_calibrate(demo_ctx *d)
{
	kg_patchset *chart = NULL;
	kg_chart_layout *layout = NULL;
	kg_mat *m2 = NULL;
	char *ref_json = demo_path(d, "lab/reference.json");
	char *cam_json = demo_path(d, "site/camera.json");
	char *lab_pj = demo_path(d, "lab/process.json"), *site_pj = demo_path(d, "site/process.json");
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

	printf("[1/7] chart spectra: the %d patches of %s measured with the spectrophotometer "
	       "(%s)\n",
	       layout->npatches, layout->name, DEMO_SPECTRO);
	if ((ret = demo_measure_chart(d, chart)) != 0)
		goto done;

	printf("[2/7] the lab session: kogei process with the measured spectra -> lab/ (the "
	       "reference calibration from the reference camera's chart, under %s)\n",
	       DEMO_REFERENCE_ILLUMINANT);
	if ((ret = demo_process(d, "lab-session", NULL, "lab")) ||
	    (ret = shot_from_process(d, lab_pj, &d->shots[0])) ||
	    (ret = kg_reference_load(ref_json, &d->ref, &d->err)))
		goto done;
	printf("[3/7] the site session: kogei process against lab/reference.json -> site/ (the "
	       "site camera under CIE %s: its chart, then the object)\n",
	       DEMO_SITE_ILLUMINANT);
	if ((ret = demo_process(d, "site-session", "lab/reference.json", "site")) ||
	    (ret = shot_from_process(d, site_pj, &d->shots[1])) ||
	    (ret = kg_camera_load(cam_json, &d->cam, &d->err)))
		goto done;
	ret = kg_mat_from(3, 3, d->cam->M2, &m2, &d->err);
	if (!ret)
		ret = kg_cond(m2, 0, &d->cond_m2, &d->err);
	if (!ret)
		printf("  M2 = rho0 pinv(rho_r): condition number %.3g (site chart %.3g); "
		       "residual %.2f %%\n",
		       d->cond_m2, d->cam->cond, 100.0 * d->cam->residual_relative);
done:
	kg_mat_free(&m2);
	kg_chart_layout_free(&layout);
	kg_patchset_free(&chart);
	free(ref_json);
	free(cam_json);
	free(lab_pj);
	free(site_pj);
	return ret;
}

void demo_region_name(int face_id, char *buf, size_t size)
{
	/* the tsuba's own regions (render/kg_mesh.h, KG_TSUBA_*); the scene's further
	 * parts, the inlays, take the ids after them */
	static const char *const tsuba[] = {"plate", "rim", "relief", "seppa-dai"};
	if (face_id >= 0 && face_id < 4)
		snprintf(buf, size, "%s", tsuba[face_id]);
	else
		snprintf(buf, size, "inlay %d", face_id - 3);
}

/* The scene's regions: each face id of materials.face_ids and its library material. */
static int load_regions(demo_ctx *d, const char *scene_path)
{
	json_t *root = NULL;
	int ret = kg_json_load(scene_path, &root, &d->err);
	const json_t *ids = ret ? NULL : kg_json_find(root, "materials.face_ids");
	if (!ret && !json_is_object(ids))
		ret = kg_fail(&d->err, KG_EINVAL, "%s: key 'materials.face_ids': expected the "
		              "regions' materials", scene_path);
	const char *key;
	json_t *v;
	d->nregions = 0;
	json_object_foreach((json_t *)ids, key, v)
	{
		if (ret)
			break;
		char *end;
		long id = strtol(key, &end, 10);
		const char *name = json_string_value(v);
		int j = -1;
		for (int k = 0; name && k < kg_material_library_count(d->lib); k++)
			if (!strcmp(kg_material_library_get(d->lib, k)->name, name))
				j = k;
		if (*end || id < 0 || id > 65535 || j < 0 || d->nregions >= DEMO_MAX_REGIONS)
			ret = kg_fail(&d->err, KG_EINVAL, "%s: key 'materials.face_ids.%s': expected a "
			              "face id and a material of the default library (at most %d)",
			              scene_path, key, DEMO_MAX_REGIONS);
		else {
			d->region_id[d->nregions] = (int)id;
			d->region_material[d->nregions++] = j;
		}
	}
	if (!ret && d->nregions == 0)
		ret = kg_fail(&d->err, KG_EINVAL, "%s: no regions", scene_path);
	json_decref(root);
	return ret;
}

/* The recorded truth (fixtures/demo/object_truth_*.png, demo_private.h) into
 * d->truth, checked against the library and the photograph's size. */
static int load_truth(demo_ctx *d, const char *labels_path, const char *angle_path)
{
	kg_image *lab = NULL, *ang = NULL;
	kg_render_truth *t = calloc(1, sizeof(*t));
	int nmat = kg_material_library_count(d->lib);
	int ret = t ? 0 : kg_fail(&d->err, KG_ENOMEM, "out of memory");
	if (!ret)
		ret = kg_image_read(labels_path, &lab, &d->err);
	if (!ret)
		ret = kg_image_read(angle_path, &ang, &d->err);
	if (!ret && (lab->channels != 1 || lab->bits != 8 || ang->channels != 1 ||
	             ang->bits != 16 || lab->width != ang->width || lab->height != ang->height))
		ret = kg_fail(&d->err, KG_EINVAL, "%s, %s: expected an 8-bit and a 16-bit grey PNG "
		              "of one size (fixtures/demo/make_session.sh writes them)", labels_path,
		              angle_path);
	size_t n = ret ? 0 : (size_t)lab->width * (size_t)lab->height;
	if (!ret) {
		t->width = lab->width;
		t->height = lab->height;
		t->nclasses = 1 + nmat;
		t->label = malloc(n ? n : 1);
		t->angle_deg = malloc(sizeof(float) * (n ? n : 1));
		t->class_names = calloc((size_t)t->nclasses, sizeof(char *));
		if (!t->label || !t->angle_deg || !t->class_names)
			ret = kg_fail(&d->err, KG_ENOMEM, "out of memory");
	}
	for (int c = 0; !ret && c < t->nclasses; c++)
		if (!(t->class_names[c] =
		          strdup(c ? kg_material_library_get(d->lib, c - 1)->name : "background")))
			ret = kg_fail(&d->err, KG_ENOMEM, "out of memory");
	for (size_t i = 0; !ret && i < n; i++) {
		long c = lrint(lab->data[i] * 255.0);
		long a = lrint(ang->data[i] * 65535.0);
		if (c < 0 || c >= t->nclasses || (c > 0) != (a != DEMO_TRUTH_ANGLE_NONE) ||
		    (a != DEMO_TRUTH_ANGLE_NONE && a > 90 * DEMO_TRUTH_ANGLE_SCALE)) {
			ret = kg_fail(&d->err, KG_EINVAL, "%s, %s: pixel %zu, %zu: class %ld, angle "
			              "value %ld: expected a class below %d and an angle of 0-90 deg "
			              "exactly where the class is not 0", labels_path, angle_path,
			              i % (size_t)t->width, i / (size_t)t->width, c, a, t->nclasses);
			break;
		}
		t->label[i] = (uint8_t)c;
		t->angle_deg[i] = a == DEMO_TRUTH_ANGLE_NONE ? NAN : (float)(a / DEMO_TRUTH_ANGLE_SCALE);
	}
	kg_image_free(&lab);
	kg_image_free(&ang);
	if (ret)
		kg_render_truth_free(&t);
	d->truth = t;
	return ret;
}

int demo_truth_table(demo_ctx *d, float **out)
{
	const kg_render_truth *t = d->truth;
	const int nang = (int)(90 * DEMO_TRUTH_ANGLE_SCALE) + 1;
	int nmat = t->nclasses - 1;
	size_t n = (size_t)t->width * (size_t)t->height;
	float *table = calloc((size_t)nmat * (size_t)nang * KG_NBANDS, sizeof(float));
	char *used = calloc((size_t)nmat + 1, 1);
	int ret = table && used ? 0 : kg_fail(&d->err, KG_ENOMEM, "out of memory");
	for (size_t i = 0; !ret && i < n; i++)
		used[t->label[i]] = 1;
	for (int j = 0; !ret && j < nmat; j++)
		for (int a = 0; used[j + 1] && !ret && a < nang; a++) {
			kg_spectrum s;
			ret = kg_material_reflectance(kg_material_library_get(d->lib, j),
			                              a / DEMO_TRUTH_ANGLE_SCALE * M_PI / 180.0, &s,
			                              &d->err);
			for (int b = 0; !ret && b < KG_NBANDS; b++)
				table[((size_t)j * nang + (size_t)a) * KG_NBANDS + b] = (float)s.v[b];
		}
	free(used);
	if (ret)
		free(table);
	*out = ret ? NULL : table;
	return ret;
}

/* The true reflectance cube: each object pixel's material at its incidence angle,
 * NaN on the background; BIP. */
static int write_truth_cube(demo_ctx *d, const char *path)
{
	const kg_render_truth *t = d->truth;
	const int nang = (int)(90 * DEMO_TRUTH_ANGLE_SCALE) + 1;
	size_t n = (size_t)t->width * (size_t)t->height;
	float *table = NULL;
	float *cube = malloc(sizeof(float) * KG_NBANDS * n);
	int ret = cube ? demo_truth_table(d, &table) : kg_fail(&d->err, KG_ENOMEM, "out of memory");
	for (size_t i = 0; !ret && i < n; i++) {
		float *px = cube + i * KG_NBANDS;
		if (!t->label[i]) {
			for (int b = 0; b < KG_NBANDS; b++)
				px[b] = NAN;
			continue;
		}
		long a = lrint(t->angle_deg[i] * DEMO_TRUTH_ANGLE_SCALE);
		memcpy(px, table + ((size_t)(t->label[i] - 1) * nang + (size_t)a) * KG_NBANDS,
		       sizeof(float) * KG_NBANDS);
	}
	if (!ret) {
		double wl[KG_NBANDS];
		for (int b = 0; b < KG_NBANDS; b++)
			wl[b] = kg_band_nm(b);
		kg_envi_meta meta = {
			.samples = t->width,
			.lines = t->height,
			.bands = KG_NBANDS,
			.data_type = KG_ENVI_F32,
			.interleave = KG_ENVI_BSQ,
			.description = "kogei demo: true reflectance of the object, each pixel's "
			               "material at its incidence angle (NaN: background)",
			.wavelength = wl,
		};
		ret = kg_envi_write(path, &meta, KG_LAYOUT_BIP, cube, &d->err);
	}
	free(cube);
	free(table);
	return ret;
}

/* Step 4: the object's truth, recorded with the session: the material and the
 * incidence angle of every pixel of the render the photograph was taken of. Written
 * out with the photograph (object.tif) for comparison by other tools. */
static int demo_object(demo_ctx *d)
{
	char *image = demo_path(d, "object.tif");
	char *cube = demo_path(d, "object_truth.hdr");
	char *labels = demo_path(d, "object_truth_labels.hdr");
	char *angle = demo_path(d, "object_truth_angle.hdr");
	char *scene = kg_data_path(DEMO_OBJECT_SCENE);
	char *lab_png = kg_data_path(DEMO_TRUTH_LABELS), *ang_png = kg_data_path(DEMO_TRUTH_ANGLE);
	printf("[4/7] the object's truth: the tsuba of fixtures/%s (a library material per "
	       "region, CIE %s studio) as its render recorded it: material and incidence angle "
	       "per pixel\n",
	       DEMO_OBJECT_SCENE, DEMO_SITE_ILLUMINANT);
	int ret = image && cube && labels && angle && scene && lab_png && ang_png
	              ? kg_material_library_load(d->library_path, &d->lib, &d->err)
	              : kg_fail(&d->err, KG_ENOMEM, "out of memory");
	if (!ret)
		ret = load_regions(d, scene);
	if (!ret)
		ret = load_truth(d, lab_png, ang_png);
	/* The photograph is the session's object capture; the truth is that of the render
	 * it was taken of (fixtures/demo/make_session.sh). */
	const kg_image *photo = d->photos.object;
	if (!ret && (d->truth->width != DEMO_OBJECT_WIDTH || d->truth->height != DEMO_OBJECT_HEIGHT))
		ret = kg_fail(&d->err, KG_EINVAL, "%s: %dx%d: the demo's object is %dx%d (the site "
		              "camera's sensor)", lab_png, d->truth->width, d->truth->height,
		              DEMO_OBJECT_WIDTH, DEMO_OBJECT_HEIGHT);
	if (!ret && (!photo || photo->channels != 3 || photo->width != d->truth->width ||
	             photo->height != d->truth->height))
		ret = kg_fail(&d->err, KG_EINVAL,
		              "the session's object capture is %dx%d with %d channels; its truth is "
		              "%dx%d and the demo needs the demosaiced RGB (re-record with "
		              "fixtures/demo/make_session.sh)",
		              photo ? photo->width : 0, photo ? photo->height : 0,
		              photo ? photo->channels : 0, d->truth->width, d->truth->height);
	if (!ret)
		ret = kg_image_write_tiff(photo, image, 32, &d->err);
	if (!ret)
		ret = kg_render_truth_write_labels(d->truth, labels, &d->err);
	if (!ret)
		ret = kg_render_truth_write_angle(d->truth, angle, &d->err);
	if (!ret)
		ret = write_truth_cube(d, cube);
	if (!ret) {
		const kg_render_truth *t = d->truth;
		long count[256] = {0}, n = (long)t->width * t->height;
		float lo = 90, hi = 0;
		for (long i = 0; i < n; i++) {
			count[t->label[i]]++;
			if (t->label[i]) {
				lo = fminf(lo, t->angle_deg[i]);
				hi = fmaxf(hi, t->angle_deg[i]);
			}
		}
		printf("  %dx%d pixels, %ld of the object (incidence %.1f-%.1f deg), %d regions:",
		       t->width, t->height, n - count[0], lo, hi, d->nregions);
		for (int k = 0; k < d->nregions; k++) {
			char name[32];
			demo_region_name(d->region_id[k], name, sizeof(name));
			printf("%s %s %s (%ld px)", k ? "," : "", name,
			       t->class_names[d->region_material[k] + 1],
			       count[d->region_material[k] + 1]);
		}
		printf("\n");
		demo_wrote(d, image, "the site camera's photograph of the object (float TIFF)");
		demo_wrote(d, labels, "truth: the material of each pixel (ENVI classification)");
		demo_wrote(d, angle, "truth: the incidence angle of each pixel (ENVI float32)");
		demo_wrote(d, cube, "truth: reflectance at each pixel's angle (ENVI, 61 bands)");
	}
	free(image);
	free(cube);
	free(labels);
	free(angle);
	free(scene);
	free(lab_png);
	free(ang_png);
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
	kg_render_truth_free(&d->truth);
	kg_material_library_free(&d->lib);
	kg_classify_result_free(&d->classes);
	demo_photos_free(&d->photos);
}

int kg_demo_run(const char *dir, kg_err *err)
{
	demo_ctx d = {
		.dir = dir,
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
	d.library_path = kg_data_path("materials/default.json");
	d.reference_camera = kg_data_path(DEMO_REFERENCE_CAMERA);
	d.site_camera = kg_data_path(DEMO_SITE_CAMERA);
	d.layout_path = kg_data_path(DEMO_CHART_LAYOUT);
	int ret = d.library_path && d.reference_camera && d.site_camera && d.layout_path
	              ? kg_mkdir_p(d.dir, &d.err)
	              : kg_fail(&d.err, KG_ENOMEM, "out of memory");
	if (!ret) {
		printf("kogei demo: writing to %s/\n", d.dir);
		printf("[0/7] the bundled session: its recorded frames replayed through the "
		       "replay: camera and averaged (acquire/) into lab-session/ and "
		       "site-session/\n");
		ret = demo_session_replay(&d, &d.photos);
	}
	if (!ret)
		ret = demo_calibrate(&d);
	if (!ret)
		ret = demo_object(&d);
	if (!ret) {
		printf("[5/7] reflection models of the material library\n");
		ret = demo_materials(&d);
	}
	if (!ret) {
		printf("[6/7] the object rendered in each material of the paper's Fig. 13 "
		       "(render/, Embree)\n");
		ret = demo_render(&d);
	}
	if (!ret) {
		printf("[7/7] against the truth: labels, regions, spectra, the object re-rendered from "
		       "its labels (Embree), summary\n");
		ret = demo_report(&d);
	}
	if (ret && err)
		*err = d.err;
	if (!ret)
		printf("kogei demo: done, %d outputs in %s/; the operator's report: %s/site/report.html\n",
		       d.nwritten, d.dir, d.dir);
	demo_free(&d);
	return ret;
}
