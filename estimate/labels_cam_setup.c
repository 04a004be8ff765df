/* Camera-space label maps: what kg_classify_camera_rows prepares before the run: its
 * inputs checked, the run's noise and feed, the materials' models with what the
 * composition needs, and the classes the capture's noise can tell apart. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "labels_cam_private.h"

int lc_check_inputs(const cam_call *c, kg_err *err)
{
	const kg_est_material_set *set = c->set;
	const kg_classify_camera *cam = c->cam;
	const kg_row_source *src = c->src;
	const char *out_hdr = c->out_hdr;
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
	return 0;
}

int lc_run_init(cam_call *c, kg_err *err)
{
	const kg_est_material_set *set = c->set;
	const kg_classify_camera *cam = c->cam;
	const kg_classify_options *copt = c->copt;
	cam_run *run = &c->run;
	kg_apply_options o = *c->opt;
	o.pre = NULL; /* M2 is applied here, with the noise */
	int rc = ap_feed_init(&run->in, c->src, &o, "classify", err);
	if (rc)
		return rc;
	/* no pre here: per-channel clip levels are tested on the image's values below */
	run->in.has_pre = 0;
	run->in.job_clip = run->in.clip;
	run->in.var = copt->variance;
	run->in.var_name = c->info && c->info->variance ? c->info->variance
	                                                : "the variance image";
	run->in.mask = copt->mask;
	if ((rc = ap_check_options(copt, c->src, c->info, "classify", err)))
		return rc;
	memcpy(run->nz.M2, cam->site_to_ref, sizeof(run->nz.M2));
	memcpy(run->nz.R, cam->calib_cov, sizeof(run->nz.R));
	lc_noise_products(&run->nz);
	run->nz.inv_frames = 1.0 / copt->frames;
	run->nz.floor2 = copt->noise_floor * copt->noise_floor;
	run->nz.rel2 = copt->noise_relative * copt->noise_relative;
	run->background_level = (float)copt->background_level;
	run->nm = set->n;
	run->neutral = !cam->no_neutral;
	for (int j = 0; j < set->n; j++)
		run->metal[j] = set->mats && set->mats[j] &&
		                (set->mats[j]->kind == KG_MATERIAL_METAL ||
		                 set->mats[j]->kind == KG_MATERIAL_ALLOY);
	for (int a = 0; a < 3; a++) {
		run->white[a] = 0;
		for (int b = 0; b < KG_NBANDS; b++)
			run->white[a] += cam->response[a * KG_NBANDS + b];
	}
	return 0;
}

/* A material's gold fraction when it is made of the pure metals (silver, copper,
 * gold), or -1. */
static double gold_fraction(const kg_material *mt, const kg_material *const metals[3])
{
	double gold = -1;
	if (mt->kind == KG_MATERIAL_METAL) {
		for (int q = 0; q < 3; q++)
			if (!strcmp(mt->name, metals[q]->name))
				gold = q == 2;
	} else if (mt->kind == KG_MATERIAL_ALLOY) {
		gold = 0;
		for (int c = 0; c < mt->ncomponents && gold >= 0; c++) {
			int known = 0;
			for (int q = 0; q < 3; q++)
				if (!strcmp(mt->component[c].name, metals[q]->name)) {
					known = 1;
					if (q == 2)
						gold += mt->component[c].fraction;
				}
			if (!known)
				gold = -1;
		}
	}
	return gold;
}

int lc_models_new(cam_call *c, kg_err *err)
{
	const kg_classify_camera *cam = c->cam;
	const int nm = c->set->n;
	int rc = kg_cs_model_new(cam->response, c->set->mats, nm, cam->angle_from, cam->angle_to,
	                         cam->angle_step, cam->intensity_lo, cam->intensity_hi, &c->model,
	                         err);
	if (rc)
		return rc;
	c->run.model = c->model;
	if (!(cam->metals[0] && cam->metals[1] && cam->metals[2]))
		return 0;
	if ((rc = kg_cs_model_new(cam->response, cam->metals, 3, cam->angle_from, cam->angle_to,
	                          cam->angle_step, cam->intensity_lo, cam->intensity_hi,
	                          &c->metals, err)))
		return rc;
	c->run.metals = c->metals;
	double glo = INFINITY, ghi = -INFINITY;
	for (int j = 0; j < nm; j++) {
		double gold = gold_fraction(c->set->mats[j], cam->metals);
		c->run.comp_ok[j] = gold >= 0;
		if (gold >= 0) {
			glo = fmin(glo, gold);
			ghi = fmax(ghi, gold);
		}
	}
	c->run.gold_range = ghi >= glo ? ghi - glo : 0;
	return 0;
}

int lc_classes_new(cam_call *c, kg_err *err)
{
	const kg_est_material_set *set = c->set;
	cam_run *run = &c->run;
	kg_est_material_set *classes = &c->classes;
	const int nm = set->n;
	/* a merge distance <= 0 joins nothing: every material its own class */
	kg_cs_merge_groups(c->sep, nm, c->merge_d > 0 ? c->merge_d : 0, run->group);
	/* classes numbered in order of their first member */
	int map[KG_EST_MAX_MATERIALS], nc = 0;
	for (int j = 0; j < nm; j++)
		map[j] = -1;
	for (int j = 0; j < nm; j++) {
		int g = run->group[j];
		if (map[g] < 0)
			map[g] = nc++;
		run->group[j] = map[g];
	}
	run->nc = nc;
	classes->n = nc;
	classes->angle_deg = set->angle_deg;
	classes->names = calloc((size_t)nc, sizeof(*classes->names));
	classes->materials = calloc((size_t)nc, sizeof(*classes->materials));
	classes->spectra = calloc((size_t)nc, sizeof(*classes->spectra));
	if (!classes->names || !classes->materials || !classes->spectra)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (int k = 0; k < nc; k++) {
		size_t used = 0;
		for (int j = 0; j < nm; j++)
			if (run->group[j] == k) {
				int w = snprintf(classes->names[k] + used, sizeof(classes->names[k]) - used,
				                 "%s%s", used ? "|" : "", set->names[j]);
				if (w < 0 || used + (size_t)w >= sizeof(classes->names[k]))
					return kg_fail(err, KG_EINVAL, "%s: the merged class of '%s' has a "
					               "name longer than %d characters", c->out_hdr,
					               set->names[j], KG_EST_CLASS_NAME_MAX - 1);
				used += (size_t)w;
			}
		classes->materials[k].name = classes->names[k];
		classes->materials[k].spectrum = classes->spectra[k].v;
	}
	return 0;
}

void lc_classes_free(kg_est_material_set *classes)
{
	free(classes->names);
	free(classes->materials);
	free(classes->spectra);
}
