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

/* The per-pixel decision's constants: the degrees of freedom of a pixel's d2, the
 * unknown and background labels, the unknown threshold, the regions' noise. */
static void decision_setup(cam_call *c)
{
	cam_run *run = &c->run;
	regions *reg = &c->sink.reg;
	/* the reading's 3 channels less the fitted intensity (the angle, weakly determined,
	 * is not counted: the bound errs towards keeping a material) */
	run->dof = c->cam->intensity_hi > c->cam->intensity_lo ? 2 : 3;
	run->unknown = (uint8_t)ap_label_unknown(&c->classes);
	run->background = (uint8_t)ap_label_background(&c->classes);
	run->threshold = c->copt->unknown_threshold > 0 ? c->copt->unknown_threshold
	                                                : kg_chi2_quantile(0.999, run->dof);
	c->files.local.unknown_threshold = run->threshold;
	c->files.local.dof = run->dof;
	reg->dof = run->dof;
	reg->cal_tr = run->nz.R[0] + run->nz.R[4] + run->nz.R[8];
	for (int j = 0; j < run->nm; j++) {
		const double *u = c->set->mats[j]->model_rsd;
		run->model_tr[j] = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
	}
	reg->model_tr = run->model_tr;
}

/* The sink's buffers: the preview, the classes' statistics, a row of the user's region
 * map, and the regions' runs (and ids of a user map). */
static int sink_alloc(cam_call *c, kg_err *err)
{
	const kg_classify_camera *cam = c->cam;
	cam_sink *sink = &c->sink;
	regions *reg = &sink->reg;
	const int W = c->src->width, H = c->src->height;
	ap_preview_size(W, H, &sink->pw, &sink->ph);
	sink->preview = malloc((size_t)sink->pw * sink->ph);
	sink->cs = calloc((size_t)c->run.nc, sizeof(*sink->cs));
	sink->region_row = cam->region_map ? malloc(sizeof(float) * (size_t)W) : NULL;
	if (!sink->preview || !sink->cs || (cam->region_map && !sink->region_row))
		return kg_fail(err, KG_ENOMEM, "classify: out of memory");
	reg->on = cam->regions || cam->region_map;
	reg->user = cam->region_map != NULL;
	reg->user_scale = cam->region_scale > 0 ? cam->region_scale : 1.0;
	reg->user_name = cam->region_map_name;
	reg->nm = c->run.nm;
	reg->width = W;
	if (!reg->on)
		return 0;
	reg->prev = malloc(sizeof(run_seg) * ((size_t)W + 1));
	reg->cur = malloc(sizeof(run_seg) * ((size_t)W + 1));
	reg->q999 = calloc(1001, sizeof(double));
	if (!reg->prev || !reg->cur || !reg->q999)
		return kg_fail(err, KG_ENOMEM, "classify: out of memory");
	if (reg->user) {
		int rc = lc_regions_grow(reg, MAX_USER_REGIONS, err);
		if (rc)
			return rc;
		for (uint32_t id = 0; id < MAX_USER_REGIONS; id++)
			lc_new_id(reg, 0);
	}
	return 0;
}

/* The label map, its confidence (margin, posterior, angle, intensity), the mask and,
 * when asked for, the composition cube. */
static int open_outputs(cam_call *c, kg_err *err)
{
	const kg_classify_camera *cam = c->cam;
	const int W = c->src->width, H = c->src->height;
	char desc[200];
	snprintf(desc, sizeof(desc), "kogei classify: camera-space matching, %d materials in %d "
	         "classes, angles %g-%g deg, intensity %g-%g", c->run.nm, c->run.nc,
	         cam->angle_from, cam->angle_to, cam->intensity_lo, cam->intensity_hi);
	const char *band[4] = {"margin", "posterior", "angle_deg", "intensity"};
	int rc = ap_call_open(&c->files, c->out_hdr, W, H, &c->classes,
	                      c->opt->description ? c->opt->description : desc, 4,
	                      "kogei classify confidence (camera space): margin = d2 of the "
	                      "runner-up class minus the chosen class's; posterior of the "
	                      "chosen class; the best material's fitted incidence angle "
	                      "(degrees) and intensity; NaN for unclassified, unknown and "
	                      "background pixels",
	                      band, err);
	if (rc || !cam->composition_hdr)
		return rc;
	if (!c->run.metals)
		return kg_fail(err, KG_EINVAL, "%s: composition: the library's silver, copper and "
		               "gold are needed", cam->composition_hdr);
	const char *cband[6] = {"ag", "cu", "au", "sd_ag", "sd_cu", "sd_au"};
	if ((rc = ap_open_floats(cam->composition_hdr, W, H, 6,
	                         "kogei classify composition: Ag, Cu, Au fractions and their "
	                         "Cramer-Rao standard deviations, fitted in camera space; NaN "
	                         "where not fitted, and au where its sd is not below the "
	                         "declared materials' range of gold fractions",
	                         cband, &c->files.ws[3], err)))
		return rc;
	c->files.paths[3] = cam->composition_hdr;
	c->files.nws = 4;
	return 0;
}

/* The run: every block through lc_cam_compute into the sink, then the margins' pass
 * and the classes' summary. */
static int run_blocks(cam_call *c, kg_err *err)
{
	const int W = c->src->width, H = c->src->height;
	cam_run *run = &c->run;
	cam_sink *sink = &c->sink;
	kg_est_job job;
	kg_est_job_init(&job, NULL, KG_EST_LABELS);
	ap_feed_job(&run->in, &job);
	run->base = job.in_bytes / sizeof(float);
	job.in_bytes += sizeof(float) * lc_extra_floats(run->nm);
	job.compute = lc_cam_compute;
	job.compute_user = run;
	job.threads = c->opt->threads;
	job.block_rows = c->opt->block_rows;
	sink->labels = c->files.ws[0];
	sink->conf = c->files.ws[1];
	sink->mask = c->files.ws[2];
	sink->comp = c->files.ws[3];
	sink->run = run;
	sink->region_map = c->cam->region_map;
	sink->nclasses = run->nc;
	sink->height = H;
	ap_progress_init(&sink->prog, c->opt, "classify", W, H);
	int rc = ap_call_stream(&c->files, &job, W, H, lc_cam_sink_fn, sink, &run->in, c->out_hdr,
	                        err);
	if (!rc)
		rc = ap_call_summary(&c->files, c->k, &c->classes, sink->count, sink->cs, c->out_hdr,
		                     4, W, H, err);
	return rc;
}

/* After the run: the regions (map and table), LABELS.json and the preview. */
static int write_results(cam_call *c, kg_err *err)
{
	const kg_classify_camera *cam = c->cam;
	regions *reg = &c->sink.reg;
	classify_call *f = &c->files;
	int rc, have_regions = reg->on && !reg->overflow;
	if (have_regions) {
		if ((rc = lc_regions_resolve(reg, err)) ||
		    (!reg->user && (rc = lc_write_region_map(reg, c->set, &c->classes, c->run.group,
		                                             c->out_hdr, c->reg_path, c->mat_path,
		                                             &f->done, err))) ||
		    (rc = lc_write_region_table(reg, c->set, &c->classes, c->run.group,
		                                c->run.gold_range, c->csv_path, &f->done, err)))
			return rc;
		f->local.nregions = (int)reg->nfinal;
	}
	const char *files[7] = {c->out_hdr, f->conf_path, f->mask_path, f->png_path,
	                        have_regions && !reg->user ? c->reg_path
	                        : reg->user                ? cam->region_map_name
	                                                   : NULL,
	                        have_regions ? c->csv_path : NULL,
	                        have_regions && !reg->user ? c->mat_path : NULL};
	if ((rc = lc_write_json(f->json_path, c->set, &c->classes, c->run.group, cam, c->copt,
	                        c->model, &c->sv, c->sep, c->merge_d, c->src, c->opt, c->info,
	                        files, reg, &f->local, c->run.threshold, &c->run, err)))
		return rc;
	ap_written_add(&f->done, f->json_path);
	return ap_call_preview(f, &c->classes, c->sink.preview, c->sink.pw, c->sink.ph,
	                       !c->copt->preview_no_legend, err);
}

static void cam_call_free(cam_call *c, int rc, kg_classify_result *res)
{
	ap_call_cleanup(&c->files, rc, res);
	ap_class_stats_free(c->sink.cs, c->run.nc);
	free(c->sink.preview);
	free(c->sink.stage.v);
	free(c->sink.conf4);
	free(c->sink.region_row);
	lc_regions_free(&c->sink.reg);
	lc_classes_free(&c->classes);
	kg_cs_model_free(&c->model);
	kg_cs_model_free(&c->metals);
	free(c->sep);
	free(c->flat_sep);
	free(c->reg_path);
	free(c->csv_path);
	free(c->mat_path);
}

int kg_classify_camera_rows(const kg_est_kernel *k, const kg_est_material_set *set,
                            const kg_classify_camera *cam, const kg_row_source *src,
                            const kg_apply_options *opt, const kg_classify_options *copt,
                            const kg_classify_info *info, const char *out_hdr,
                            kg_classify_result *res, kg_err *err)
{
	kg_check_arg(set && cam && src && out_hdr, err);
	cam_call call, *c = &call;
	memset(c, 0, sizeof(*c));
	ap_call_begin(&c->files, out_hdr, &opt, &copt, res);
	c->k = k;
	c->set = set;
	c->cam = cam;
	c->src = src;
	c->opt = opt;
	c->copt = copt;
	c->info = info;
	c->out_hdr = out_hdr;
	c->merge_d = cam->merge_distance == 0 ? KG_CS_MERGE_DISTANCE : cam->merge_distance;
	int rc = lc_check_inputs(c, err);
	if (!rc)
		rc = lc_run_init(c, err);
	if (rc)
		return rc;
	if ((rc = lc_models_new(c, err)) || (rc = lc_survey(&c->run, cam, c->model, &c->sv, err)))
		goto out;
	if (!(c->sep = malloc(sizeof(double) * (size_t)set->n * set->n))) {
		rc = kg_fail(err, KG_ENOMEM, "out of memory");
		goto out;
	}
	if ((rc = lc_separability(&c->run, c->model, &c->sv, c->sep, err))) {
		kg_err_prefix(err, "%s: ", out_hdr);
		goto out;
	}
	if ((rc = lc_classes_new(c, err)))
		goto out;
	decision_setup(c);
	if (!(c->flat_sep = malloc(sizeof(double) * (size_t)set->n))) {
		rc = kg_fail(err, KG_ENOMEM, "out of memory");
		goto out;
	}
	if ((rc = lc_flat_separability(&c->run, c->model, &c->sv, c->flat_sep, err))) {
		kg_err_prefix(err, "%s: ", out_hdr);
		goto out;
	}
	c->sink.reg.sep = c->sep;
	c->sink.reg.flat_sep = c->flat_sep;
	if ((rc = ap_call_paths(&c->files, out_hdr, err)) ||
	    (rc = kg_apply_side_path(out_hdr, "_regions.hdr", &c->reg_path, err)) ||
	    (rc = kg_apply_side_path(out_hdr, "_regions.csv", &c->csv_path, err)) ||
	    (rc = kg_apply_side_path(out_hdr, "_materials.hdr", &c->mat_path, err)) ||
	    (rc = kg_inputs_check_output(c->csv_path, err)) || (rc = sink_alloc(c, err)) ||
	    (rc = open_outputs(c, err)) || (rc = run_blocks(c, err)))
		goto out;
	rc = write_results(c, err);
out:
	cam_call_free(c, rc, res);
	return rc;
}
