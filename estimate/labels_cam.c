/* Camera-space label maps: kg_classify_camera_rows.
 *
 * Each pixel's site reading rho is mapped into the reference camera's space, x = M2 rho,
 * with the covariance
 *   C = M2 diag(v) M2^T + l^2 R,   l^2 = |x|^2 / 3,
 * v the noise of the pixel's channels (the variance image over the frames averaged, or
 * the noise model) and R the calibration residual's relative covariance (what M2 leaves
 * of the chart, per squared level). camspace.c matches x against every declared material
 * over the angles and intensities (kg_cs_match_block).
 *
 * Before the run a survey pass (a second reading of the image and its variance) finds
 * the capture's noise: the mean C over the pixels that will be classified, at their
 * mean level. At that noise kg_cs_separability gives every pair's distance; pairs
 * closer than the merge distance are one compound class "a|b", and the label map holds
 * classes, not materials: no per-pixel distinction is written that the noise cannot
 * support.
 *
 * Regions: connected components (4-neighbours) of the per-pixel classes, found while
 * the rows stream past (union-find over the runs of each row, with each run's sums of
 * the materials' distances), or the ids of a user region map. Each region is decided on
 * its pooled likelihood, sum over its pixels of every material's d2. The calibration's
 * part of the noise is the same error in every pixel and does not average out: with f
 * its share of a pixel's variance, N pixels weigh as N / (1 + N f) independent ones, so
 * the pooled differences are scaled by 1 / (1 + N f). A compound class resolves into
 * one material where that material's share of the class's pooled posterior is 0.99 or
 * more. The region's "unknown" test adds the decided material's own model error (its
 * model_rsd: the spread of published optical constants, the alloy rule, a template's
 * scatter), also one error for the whole region, to f. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "labels_cam_private.h"

int kg_class_holds(const char *cls, const char *m)
{
	size_t lm = strlen(m);
	for (const char *p = cls; p && *p;) {
		const char *bar = strchr(p, '|');
		size_t len = bar ? (size_t)(bar - p) : strlen(p);
		if (len == lm && strncmp(p, m, lm) == 0)
			return 1;
		p = bar ? bar + 1 : NULL;
	}
	return 0;
}

void kg_classify_camera_init(kg_classify_camera *c)
{
	memset(c, 0, sizeof(*c));
	for (int i = 0; i < 3; i++)
		c->site_to_ref[4 * i] = 1.0;
	c->angle_from = 0;
	c->angle_to = 70;
	c->angle_step = 5;
	c->intensity_lo = 0.3;
	c->intensity_hi = 1.0;
	c->merge_distance = 0;
	c->regions = 1;
}

/* ---- the call --------------------------------------------------------------------- */

static void set_free_classes(kg_est_material_set *c)
{
	free(c->names);
	free(c->materials);
	free(c->spectra);
}

int kg_classify_camera_rows(const kg_est_kernel *k, const kg_est_material_set *set,
                            const kg_classify_camera *cam, const kg_row_source *src,
                            const kg_apply_options *opt, const kg_classify_options *copt,
                            const kg_classify_info *info, const char *out_hdr,
                            kg_classify_result *res, kg_err *err)
{
	kg_check_arg(set && cam && src && out_hdr, err);
	kg_apply_options dflt;
	if (!opt) {
		kg_apply_options_init(&dflt);
		opt = &dflt;
	}
	kg_classify_options cdflt;
	if (!copt) {
		kg_classify_options_init(&cdflt);
		copt = &cdflt;
	}
	if (res)
		memset(res, 0, sizeof(*res));
	if (!set->mats)
		return kg_fail(err, KG_EINVAL, "%s: camera-space matching needs the library's "
		               "materials (kg_est_material_set_new)", out_hdr);
	if (!cam->response)
		return kg_fail(err, KG_EINVAL, "%s: camera-space matching needs the reference "
		               "camera's spectral response", out_hdr);
	if (set->n > 254)
		return kg_fail(err, KG_EINVAL, "%s: %d materials: camera-space matching takes at most "
		               "254", out_hdr, set->n);
	int bad = kg_mat3_check_invertible(cam->site_to_ref, NULL, "M2", err);
	if (bad)
		return bad;
	for (int i = 0; i < 9; i++)
		if (!isfinite(cam->calib_cov[i]))
			return kg_fail(err, KG_EINVAL, "%s: the calibration covariance: expected "
			               "finite values", out_hdr);
	if (cam->region_map && (cam->region_map->width != src->width ||
	                        cam->region_map->height != src->height ||
	                        cam->region_map->channels != 1))
		return kg_fail(err, KG_EINVAL, "%s: the region map %s is %d x %d with %d channel%s: "
		               "expected one grey channel of the image's size, %d x %d", out_hdr,
		               cam->region_map_name ? cam->region_map_name : "", cam->region_map->width,
		               cam->region_map->height, cam->region_map->channels,
		               cam->region_map->channels == 1 ? "" : "s", src->width, src->height);
	for (int j = 0; j < set->n; j++) {
		const kg_material_template *t = &set->mats[j]->tmpl;
		if (t->n && t->reference[0] && cam->reference_sha256 && cam->reference_sha256[0] &&
		    strcmp(t->reference, cam->reference_sha256) != 0)
			return kg_fail(err, KG_EINVAL, "%s: material '%s': its coupon template was learned "
			               "through another reference calibration (sha256 %.12s..., this "
			               "calibration's reference is %.12s...): learn it again through this "
			               "one, or use a library without it", out_hdr, set->mats[j]->name,
			               t->reference, cam->reference_sha256);
	}
	cam_run run;
	memset(&run, 0, sizeof(run));
	kg_apply_options o = *opt;
	o.pre = NULL; /* M2 is applied here, with the noise */
	int rc = ap_feed_init(&run.in, src, &o, "classify", err);
	if (rc)
		return rc;
	/* no pre here: per-channel clip levels are tested on the image's values below */
	run.in.has_pre = 0;
	run.in.job_clip = run.in.clip;
	run.in.var = copt->variance;
	run.in.var_name = info && info->variance ? info->variance : "the variance image";
	run.in.mask = copt->mask;
	if ((rc = ap_check_options(copt, src, info, "classify", err)))
		return rc;
	memcpy(run.nz.M2, cam->site_to_ref, sizeof(run.nz.M2));
	memcpy(run.nz.R, cam->calib_cov, sizeof(run.nz.R));
	lc_noise_products(&run.nz);
	run.nz.inv_frames = 1.0 / copt->frames;
	run.nz.floor2 = copt->noise_floor * copt->noise_floor;
	run.nz.rel2 = copt->noise_relative * copt->noise_relative;
	run.background_level = (float)copt->background_level;
	run.nm = set->n;
	run.neutral = !cam->no_neutral;
	for (int j = 0; j < set->n; j++)
		run.metal[j] = set->mats && set->mats[j] && (set->mats[j]->kind == KG_MATERIAL_METAL ||
		                                             set->mats[j]->kind == KG_MATERIAL_ALLOY);
	for (int a = 0; a < 3; a++) {
		run.white[a] = 0;
		for (int b = 0; b < KG_NBANDS; b++)
			run.white[a] += cam->response[a * KG_NBANDS + b];
	}

	kg_cs_model *model = NULL, *metals = NULL;
	double *sep = NULL;
	kg_est_material_set classes = {0};
	kg_classify_result local = {0};
	kg_envi_writer *ws[4] = {NULL, NULL, NULL, NULL};
	char *conf_path = NULL, *mask_path = NULL, *json_path = NULL, *png_path = NULL,
	     *reg_path = NULL, *csv_path = NULL;
	const char *paths[4] = {out_hdr, NULL, NULL, NULL};
	cam_sink sink = {0};
	written done = {0};
	survey_result sv;
	const int W = src->width, H = src->height;
	const int nm = set->n;
	double merge_d = cam->merge_distance == 0 ? KG_CS_MERGE_DISTANCE : cam->merge_distance;

	if ((rc = kg_cs_model_new(cam->response, set->mats, nm, cam->angle_from, cam->angle_to,
	                          cam->angle_step, cam->intensity_lo, cam->intensity_hi, &model,
	                          err)))
		goto out;
	run.model = model;
	if (cam->metals[0] && cam->metals[1] && cam->metals[2]) {
		if ((rc = kg_cs_model_new(cam->response, cam->metals, 3, cam->angle_from,
		                          cam->angle_to, cam->angle_step, cam->intensity_lo,
		                          cam->intensity_hi, &metals, err)))
			goto out;
		run.metals = metals;
		double glo = INFINITY, ghi = -INFINITY;
		for (int j = 0; j < nm; j++) {
			const kg_material *mt = set->mats[j];
			double gold = -1;
			if (mt->kind == KG_MATERIAL_METAL) {
				for (int q = 0; q < 3; q++)
					if (!strcmp(mt->name, cam->metals[q]->name))
						gold = q == 2;
			} else if (mt->kind == KG_MATERIAL_ALLOY) {
				gold = 0;
				for (int c = 0; c < mt->ncomponents && gold >= 0; c++) {
					int known = 0;
					for (int q = 0; q < 3; q++)
						if (!strcmp(mt->component[c].name, cam->metals[q]->name)) {
							known = 1;
							if (q == 2)
								gold += mt->component[c].fraction;
						}
					if (!known)
						gold = -1;
				}
			}
			run.comp_ok[j] = gold >= 0;
			if (gold >= 0) {
				glo = fmin(glo, gold);
				ghi = fmax(ghi, gold);
			}
		}
		run.gold_range = ghi >= glo ? ghi - glo : 0;
	}
	if ((rc = lc_survey(&run, cam, model, &sv, err)))
		goto out;
	if (!(sep = malloc(sizeof(double) * (size_t)nm * nm))) {
		rc = kg_fail(err, KG_ENOMEM, "out of memory");
		goto out;
	}
	if ((rc = lc_separability(&run, model, &sv, sep, err))) {
		kg_err_prefix(err, "%s: ", out_hdr);
		goto out;
	}
	/* a merge distance <= 0 joins nothing: every material its own class */
	kg_cs_merge_groups(sep, nm, merge_d > 0 ? merge_d : 0, run.group);
	/* classes numbered in order of their first member */
	{
		int map[KG_EST_MAX_MATERIALS], nc = 0;
		for (int j = 0; j < nm; j++)
			map[j] = -1;
		for (int j = 0; j < nm; j++) {
			int g = run.group[j];
			if (map[g] < 0)
				map[g] = nc++;
			run.group[j] = map[g];
		}
		run.nc = nc;
	}
	classes.n = run.nc;
	classes.angle_deg = set->angle_deg;
	classes.names = calloc((size_t)run.nc, sizeof(*classes.names));
	classes.materials = calloc((size_t)run.nc, sizeof(*classes.materials));
	classes.spectra = calloc((size_t)run.nc, sizeof(*classes.spectra));
	if (!classes.names || !classes.materials || !classes.spectra) {
		rc = kg_fail(err, KG_ENOMEM, "out of memory");
		goto out;
	}
	for (int c = 0; c < run.nc; c++) {
		size_t used = 0;
		for (int j = 0; j < nm; j++)
			if (run.group[j] == c) {
				int w = snprintf(classes.names[c] + used, sizeof(classes.names[c]) - used,
				                 "%s%s", used ? "|" : "", set->names[j]);
				if (w < 0 || used + (size_t)w >= sizeof(classes.names[c])) {
					rc = kg_fail(err, KG_EINVAL, "%s: the merged class of '%s' has a name "
					             "longer than %d characters", out_hdr, set->names[j],
					             KG_EST_CLASS_NAME_MAX - 1);
					goto out;
				}
				used += (size_t)w;
			}
		classes.materials[c].name = classes.names[c];
		classes.materials[c].spectrum = classes.spectra[c].v;
	}
	/* the reading's 3 channels less the fitted intensity (the angle, weakly determined,
	 * is not counted: the bound errs towards keeping a material) */
	run.dof = cam->intensity_hi > cam->intensity_lo ? 2 : 3;
	run.unknown = (uint8_t)ap_label_unknown(&classes);
	run.background = (uint8_t)ap_label_background(&classes);
	run.threshold = copt->unknown_threshold > 0 ? copt->unknown_threshold
	                                            : kg_chi2_quantile(0.999, run.dof);
	local.unknown_threshold = run.threshold;
	local.dof = run.dof;
	sink.reg.dof = run.dof;
	sink.reg.cal_tr = run.nz.R[0] + run.nz.R[4] + run.nz.R[8];
	for (int j = 0; j < nm; j++) {
		const double *u = set->mats[j]->model_rsd;
		run.model_tr[j] = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
	}
	sink.reg.model_tr = run.model_tr;

	if ((rc = kg_apply_side_path(out_hdr, "_confidence.hdr", &conf_path, err)) ||
	    (rc = kg_apply_side_path(out_hdr, ".json", &json_path, err)) ||
	    (rc = kg_apply_side_path(out_hdr, ".png", &png_path, err)) ||
	    (rc = kg_apply_side_path(out_hdr, "_regions.hdr", &reg_path, err)) ||
	    (rc = kg_apply_side_path(out_hdr, "_regions.csv", &csv_path, err)) ||
	    (rc = kg_inputs_check_output(json_path, err)) ||
	    (rc = kg_inputs_check_output(png_path, err)) ||
	    (rc = kg_inputs_check_output(csv_path, err)))
		goto out;
	ap_preview_size(W, H, &sink.pw, &sink.ph);
	sink.preview = malloc((size_t)sink.pw * sink.ph);
	sink.cs = calloc((size_t)run.nc, sizeof(*sink.cs));
	sink.region_row = cam->region_map ? malloc(sizeof(float) * (size_t)W) : NULL;
	if (!sink.preview || !sink.cs || (cam->region_map && !sink.region_row)) {
		rc = kg_fail(err, KG_ENOMEM, "classify: out of memory");
		goto out;
	}
	sink.reg.on = cam->regions || cam->region_map;
	sink.reg.user = cam->region_map != NULL;
	sink.reg.user_scale = cam->region_scale > 0 ? cam->region_scale : 1.0;
	sink.reg.user_name = cam->region_map_name;
	sink.reg.nm = nm;
	sink.reg.width = W;
	if (sink.reg.on) {
		sink.reg.prev = malloc(sizeof(run_seg) * ((size_t)W + 1));
		sink.reg.cur = malloc(sizeof(run_seg) * ((size_t)W + 1));
		sink.reg.q999 = calloc(1001, sizeof(double));
		if (!sink.reg.prev || !sink.reg.cur || !sink.reg.q999) {
			rc = kg_fail(err, KG_ENOMEM, "classify: out of memory");
			goto out;
		}
		if (sink.reg.user) {
			if ((rc = lc_regions_grow(&sink.reg, MAX_USER_REGIONS, err)))
				goto out;
			for (uint32_t id = 0; id < MAX_USER_REGIONS; id++)
				lc_new_id(&sink.reg, 0);
		}
	}
	char desc[200];
	snprintf(desc, sizeof(desc), "kogei classify: camera-space matching, %d materials in %d "
	         "classes, angles %g-%g deg, intensity %g-%g", nm, run.nc, cam->angle_from,
	         cam->angle_to, cam->intensity_lo, cam->intensity_hi);
	if ((rc = ap_open_label_map(out_hdr, W, H, &classes,
	                            opt->description ? opt->description : desc, &ws[0], err)))
		goto out;
	const char *band[4] = {"margin", "posterior", "angle_deg", "intensity"};
	if ((rc = ap_open_floats(conf_path, W, H, 4,
	                         "kogei classify confidence (camera space): margin = d2 of the "
	                         "runner-up class minus the chosen class's; posterior of the "
	                         "chosen class; the best material's fitted incidence angle "
	                         "(degrees) and intensity; NaN for unclassified, unknown and "
	                         "background pixels",
	                         band, &ws[1], err)))
		goto out;
	paths[1] = conf_path;
	if ((rc = ap_open_mask(out_hdr, W, H, &mask_path, &ws[2], err)))
		goto out;
	paths[2] = mask_path;
	int nws = 3;
	if (cam->composition_hdr) {
		if (!run.metals) {
			rc = kg_fail(err, KG_EINVAL, "%s: composition: the library's silver, copper and "
			             "gold are needed", cam->composition_hdr);
			goto out;
		}
		const char *cband[6] = {"ag", "cu", "au", "sd_ag", "sd_cu", "sd_au"};
		if ((rc = ap_open_floats(cam->composition_hdr, W, H, 6,
		                         "kogei classify composition: Ag, Cu, Au fractions and their "
		                         "Cramer-Rao standard deviations, fitted in camera space; NaN "
		                         "where not fitted, and au where its sd is not below the "
		                         "declared materials' range of gold fractions",
		                         cband, &ws[3], err)))
			goto out;
		paths[3] = cam->composition_hdr;
		nws = 4;
	}

	kg_est_job job;
	kg_est_job_init(&job, NULL, KG_EST_LABELS);
	ap_feed_job(&run.in, &job);
	run.base = job.in_bytes / sizeof(float);
	job.in_bytes += sizeof(float) * lc_extra_floats(nm);
	job.compute = lc_cam_compute;
	job.compute_user = &run;
	job.threads = opt->threads;
	job.block_rows = opt->block_rows;
	sink.labels = ws[0];
	sink.conf = ws[1];
	sink.mask = ws[2];
	sink.comp = ws[3];
	sink.run = &run;
	sink.region_map = cam->region_map;
	sink.nclasses = run.nc;
	sink.height = H;
	ap_progress_init(&sink.prog, opt, "classify", W, H);
	rc = kg_est_run_stream(&job, NULL, W, H, lc_cam_sink_fn, &sink, &local.stats, err);
	if (rc) {
		kg_err_prefix(err, "%s: ", out_hdr);
		goto out;
	}
	if ((rc = ap_check_estimable(&local.stats, &run.in, "classify", err)))
		goto out;
	if ((rc = ap_finish_all(ws, paths, nws, &done, err)))
		goto out;
	if ((rc = ap_margin_pass(sink.cs, run.nc, out_hdr, conf_path, 4, W, H, err)) ||
	    (rc = ap_summarise(k, &classes, sink.count, sink.cs, (size_t)W * H, &local, err)))
		goto out;
	int have_regions = sink.reg.on && !sink.reg.overflow;
	if (have_regions) {
		if ((rc = lc_regions_resolve(&sink.reg, err)) ||
		    (!sink.reg.user &&
		     (rc = lc_write_region_map(&sink.reg, &classes, out_hdr, reg_path, &done, err))) ||
		    (rc = lc_write_region_table(&sink.reg, set, &classes, run.group, run.gold_range,
		                             csv_path, &done, err)))
			goto out;
		local.nregions = (int)sink.reg.nfinal;
	}
	const char *files[6] = {out_hdr, conf_path, mask_path, png_path,
	                        have_regions && !sink.reg.user ? reg_path
	                        : sink.reg.user                ? cam->region_map_name
	                                                       : NULL,
	                        have_regions ? csv_path : NULL};
	if ((rc = lc_write_json(json_path, set, &classes, run.group, cam, copt, model, &sv, sep,
	                     merge_d, src, opt, info, files, &sink.reg, &local, run.threshold,
	                     &run, err)))
		goto out;
	ap_written_add(&done, json_path);
	if ((rc = ap_write_preview(png_path, &classes, sink.preview, sink.pw, sink.ph, &local,
	                           !copt->preview_no_legend,
	                           err)))
		goto out;
	ap_written_add(&done, png_path);

out:
	for (int i = 0; i < 4; i++)
		if (ws[i])
			kg_envi_writer_abort(&ws[i]);
	ap_written_clear(&done, rc != 0);
	if (rc == 0 && res)
		*res = local;
	else
		kg_classify_result_free(&local);
	ap_class_stats_free(sink.cs, run.nc);
	free(sink.preview);
	free(sink.stage.v);
	free(sink.conf4);
	free(sink.region_row);
	lc_regions_free(&sink.reg);
	set_free_classes(&classes);
	kg_cs_model_free(&model);
	kg_cs_model_free(&metals);
	free(sep);
	free(conf_path);
	free(mask_path);
	free(json_path);
	free(png_path);
	free(reg_path);
	free(csv_path);
	return rc;
}
