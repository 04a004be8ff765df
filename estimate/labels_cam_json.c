/* Camera-space label maps: LABELS.json. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "labels_cam_private.h"

/* ---- LABELS.json ------------------------------------------------------------------ */

static json_t *mat3(const double *m)
{
	json_t *a = json_array();
	for (int i = 0; i < 3; i++)
		json_array_append_new(a, json_pack("[fff]", m[3 * i], m[3 * i + 1], m[3 * i + 2]));
	return a;
}

/* The rule for regions too small for the noise: what it did, and the pixels a region
 * of each class needs against each alternative. */
static json_t *small_json(const regions *reg, const kg_est_material_set *set,
                          const kg_est_material_set *classes, const int *group)
{
	const small_stats *st = &reg->small;
	json_t *o = json_object(), *need = json_object();
	json_object_set_new(o, "description",
	                    json_string("a region decided on its pooled distances errs 1 % of "
	                                "the time or less against an alternative at "
	                                "separability d only from (2 z_99 / d)^2 pixels on; a "
	                                "region smaller than that against its surroundings (the "
	                                "label most of its border holds, regions too small "
	                                "themselves and unclassified pixels not counted) takes "
	                                "their label in the material map, or unknown when its "
	                                "border holds no label or unknown; the label map keeps "
	                                "each pixel's class"));
	json_object_set_new(o, "merged_regions", json_integer((json_int_t)st->regions));
	json_object_set_new(o, "merged_pixels", json_integer((json_int_t)st->pixels));
	json_object_set_new(o, "unknown_regions", json_integer((json_int_t)st->unknown_regions));
	json_object_set_new(o, "unknown_pixels", json_integer((json_int_t)st->unknown_pixels));
	json_object_set_new(o, "one_pixel_regions", json_integer((json_int_t)st->one_pixel));
	json_object_set_new(o, "one_pixel_regions_kept",
	                    json_integer((json_int_t)st->one_pixel_kept));
	for (int c = 0; c < classes->n; c++) {
		json_t *row = json_object();
		json_object_set_new(row, "background",
		                    ap_json_num(lc_small_min_pixels(reg, group, c, -1)));
		json_object_set_new(row, "isolated",
		                    ap_json_num(lc_small_min_pixels(reg, group, c, -2)));
		for (int h = 0; h < classes->n; h++) {
			double n = lc_small_min_pixels(reg, group, c, h);
			if (h != c)
				json_object_set_new(row, classes->names[h], ap_json_num(n));
		}
		for (int j = 0; j < set->n; j++) {
			int members = 0;
			for (int i = 0; i < set->n; i++)
				members += group[i] == group[j];
			double n = lc_small_min_pixels(reg, group, c, -3 - j);
			if (members > 1 && group[j] != c)
				json_object_set_new(row, set->names[j], ap_json_num(n));
		}
		json_object_set_new(need, classes->names[c], row);
	}
	json_object_set_new(o, "min_pixels", need);
	return o;
}

int lc_write_json(const char *path, const kg_est_material_set *set,
                      const kg_est_material_set *classes, const int *group,
                      const kg_classify_camera *cam, const kg_classify_options *copt,
                      const kg_cs_model *m, const survey_result *sv, const double *sep,
                      double merge_d, const kg_row_source *img, const kg_apply_options *opt,
                      const kg_classify_info *info, const char *const files[7],
                      const regions *reg, const kg_classify_result *res, double threshold,
                      const cam_run *run, kg_err *err)
{
	const int nm = set->n, nc = classes->n;
	json_t *root = json_object();
	ap_labels_json_inputs(root, info, "camera");
	ap_labels_json_image(root, opt, img, res);
	json_t *cs = json_object();
	json_object_set_new(cs, "description",
	                    json_string("each pixel's reading mapped through M2 into the "
	                                "reference camera's space and matched against every "
	                                "declared material's predicted reading over the angles "
	                                "and intensities, by the noise-weighted (Mahalanobis) "
	                                "distance d2"));
	json_object_set_new(cs, "angles_deg", json_pack("[fff]", cam->angle_from, cam->angle_to,
	                                                cam->angle_step));
	json_object_set_new(cs, "intensity", json_pack("[ff]", cam->intensity_lo,
	                                               cam->intensity_hi));
	json_object_set_new(cs, "M2", mat3(cam->site_to_ref));
	json_t *tm = json_array();
	for (int j = 0; j < m->n; j++)
		if (m->templated[j])
			json_array_append_new(tm, json_string(m->names[j]));
	json_object_set_new(cs, "coupon_templates", tm);
	json_object_set_new(cs, "calibration_covariance", mat3(cam->calib_cov));
	json_object_set_new(cs, "neutral_diffuse",
	                    cam->no_neutral
	                        ? json_false()
	                        : json_string("a pixel a flat reflectance at any level fits "
	                                      "better than every declared material (and within "
	                                      "the unknown bound) is background: a grey card, "
	                                      "paper, cloth"));
	json_object_set_new(cs, "response", json_string(cam->response_source[0]
	                                                    ? cam->response_source
	                                                    : "given"));
	json_t *nz = json_object();
	if (copt->variance) {
		json_object_set_new(nz, "noise", json_string("variance image"));
		json_object_set_new(nz, "variance", json_string(info && info->variance ? info->variance
		                                                                       : "given"));
		json_object_set_new(nz, "frames", json_integer(copt->frames));
	} else {
		json_object_set_new(nz, "noise", json_string("model"));
		json_object_set_new(nz, "noise_relative", json_real(copt->noise_relative));
		json_object_set_new(nz, "noise_floor", json_real(copt->noise_floor));
	}
	json_object_set_new(nz, "survey_pixels", json_integer((json_int_t)sv->pixels));
	json_object_set_new(nz, "variance_model",
	                    json_pack("{s:s,s:[fff],s:[fff],s:[fff]}", "form",
	                              "per site channel: a + b rho + c rho^2", "a", sv->va[0],
	                              sv->va[1], sv->va[2], "b", sv->vb[0], sv->vb[1], sv->vb[2],
	                              "c", sv->vc[0], sv->vc[1], sv->vc[2]));
	json_object_set_new(nz, "mean_covariance", mat3(sv->cov));
	json_object_set_new(nz, "mean_rms_reading", json_real(sv->rms));
	json_object_set_new(nz, "level", json_real(sv->level));
	json_object_set_new(nz, "calibration_share", json_real(sv->calib_share));
	json_object_set_new(cs, "noise", nz);
	json_t *u = json_object();
	json_object_set_new(u, "enabled", json_boolean(isfinite(threshold)));
	json_object_set_new(u, "statistic", json_string("d2 of the best material"));
	json_object_set_new(u, "threshold", ap_json_num(threshold));
	json_object_set_new(u, "dof", json_integer(res->dof));
	json_object_set_new(u, "probability", isfinite(threshold) && copt->unknown_threshold == 0
	                                          ? json_real(0.999)
	                                          : json_null());
	json_object_set_new(cs, "unknown", u);
	json_object_set_new(root, "camera_space", cs);

	/* separability */
	json_t *sj = json_object(), *names = json_array(), *dtab = json_array(),
	       *ptab = json_array(), *pairs = json_array();
	for (int i = 0; i < nm; i++) {
		json_array_append_new(names, json_string(set->names[i]));
		json_t *dr = json_array(), *pr = json_array();
		for (int j = 0; j < nm; j++) {
			double d = sep[(size_t)i * nm + j];
			json_array_append_new(dr, ap_json_num(i == j ? 0.0 : d));
			json_array_append_new(pr, i == j ? json_null() : ap_json_num(kg_cs_pixels_for(d)));
		}
		json_array_append_new(dtab, dr);
		json_array_append_new(ptab, pr);
	}
	for (int i = 0; i < nm; i++)
		for (int j = i + 1; j < nm; j++) {
			double d = sep[(size_t)i * nm + j];
			if (kg_cs_pixels_for(d) <= 1)
				continue;
			json_array_append_new(pairs, json_pack("{s:s,s:s,s:o,s:o,s:b}", "a", set->names[i],
			                                       "b", set->names[j], "distance", ap_json_num(d),
			                                       "pixels_for_1pc", ap_json_num(kg_cs_pixels_for(d)),
			                                       "merged", group[i] == group[j]));
		}
	json_object_set_new(sj, "materials", names);
	json_object_set_new(sj, "distance", dtab);
	json_object_set_new(sj, "pixels_for_1pc", ptab);
	json_object_set_new(sj, "pairs_needing_pooling", pairs);
	json_object_set_new(sj, "merge_distance", ap_json_num(merge_d));
	json_object_set_new(sj, "description",
	                    json_string("least noise-weighted distance between two materials over "
	                                "every angle and intensity at the capture's noise (each "
	                                "reading at the survey's level with its own covariance "
	                                "from the fitted variance model and the calibration); a "
	                                "pixel tells "
	                                "them apart with error Phi(-d/2); pixels_for_1pc: pixels "
	                                "a region must pool for a 1 % error; pairs closer than "
	                                "merge_distance are one class"));
	json_object_set_new(root, "separability", sj);
	json_t *merges = json_array();
	for (int c = 0; c < nc; c++) {
		int members = 0;
		for (int j = 0; j < nm; j++)
			members += group[j] == c;
		if (members < 2)
			continue;
		json_t *mm = json_array();
		for (int j = 0; j < nm; j++)
			if (group[j] == c)
				json_array_append_new(mm, json_string(set->names[j]));
		json_array_append_new(merges, mm);
	}
	json_object_set_new(root, "merges", merges);

	json_t *fs = json_object();
	const char *fkeys[7] = {"labels", "confidence", "mask", "preview", "regions",
	                        "regions_csv", "materials"};
	for (int i = 0; i < 7; i++)
		json_object_set_new(fs, fkeys[i],
		                    files[i] ? json_string(kg_path_below(files[i], copt->record_dir))
		                             : json_null());
	json_object_set_new(root, "files", fs);
	json_object_set_new(root, "confidence",
	                    json_string("bands: margin (d2 of the runner-up class minus the "
	                                "chosen class's, noise-weighted), posterior (of the "
	                                "chosen class over the declared materials, equal "
	                                "priors), angle_deg and intensity (the best material's "
	                                "fit); NaN for unclassified, unknown and background"));
	json_t *classes_j = json_array();
	json_t *c0 = json_pack("{s:i,s:s,s:I}", "label", 0, "name", "unclassified", "pixels",
	                       (json_int_t)res->unclassified);
	json_array_append_new(classes_j, c0);
	for (int c = 0; c < nc; c++) {
		const kg_class_summary *k = &res->classes[c];
		unsigned char col[3];
		ap_label_colour(classes, c + 1, col);
		json_t *o = json_object();
		json_object_set_new(o, "label", json_integer(c + 1));
		json_object_set_new(o, "name", json_string(k->name));
		json_t *mm = json_array();
		for (int j = 0; j < nm; j++)
			if (group[j] == c)
				json_array_append_new(mm, json_string(set->names[j]));
		json_object_set_new(o, "members", mm);
		json_object_set_new(o, "pixels", json_integer((json_int_t)k->pixels));
		json_object_set_new(o, "fraction", json_real(k->fraction));
		json_object_set_new(o, "colour", json_pack("[iii]", col[0], col[1], col[2]));
		json_t *ms = json_null();
		if (k->pixels && isfinite(k->mean_spectrum[0])) {
			ms = json_array();
			for (int l = 0; l < KG_NBANDS; l++)
				json_array_append_new(ms, ap_json_num(k->mean_spectrum[l]));
		}
		json_object_set_new(o, "mean_spectrum", ms);
		json_object_set_new(o, "confidence",
		                    json_pack("{s:o,s:o,s:o}", "mean", ap_json_num(k->margin_mean),
		                              "median", ap_json_num(k->margin_median), "p5",
		                              ap_json_num(k->margin_p5)));
		json_array_append_new(classes_j, o);
	}
	json_array_append_new(classes_j, ap_refusal_class(classes, ap_label_unknown(classes),
	                                                   res->unknown, res->stats.pixels));
	json_array_append_new(classes_j, ap_refusal_class(classes, ap_label_background(classes),
	                                                  res->background, res->stats.pixels));
	json_object_set_new(root, "classes", classes_j);

	json_t *comp = json_object();
	json_object_set_new(comp, "enabled", json_boolean(run->metals != NULL));
	if (run->metals) {
		json_object_set_new(comp, "metals", json_pack("[sss]", cam->metals[0]->name,
		                                              cam->metals[1]->name,
		                                              cam->metals[2]->name));
		json_object_set_new(comp, "file", cam->composition_hdr
		                                      ? json_string(kg_path_below(cam->composition_hdr,
		                                                                copt->record_dir))
		                                      : json_null());
		json_object_set_new(comp, "gold_range", json_real(run->gold_range));
		json_object_set_new(comp, "description",
		                    json_string("Ag, Cu and Au fractions (>= 0, summing to 1) of the "
		                                "pixels whose best material is made of these metals, "
		                                "fitted in camera space at the fitted angle (the alloy "
		                                "model is linear in the fractions), with Cramer-Rao "
		                                "standard deviations; gold is given only where its sd "
		                                "is below gold_range, the range of gold fractions of "
		                                "the declared materials; regions: inverse-variance "
		                                "means, sds widened by sqrt(1 + N f)"));
	}
	json_object_set_new(root, "composition", comp);
	json_t *rj = json_object();
	json_object_set_new(rj, "enabled", json_boolean(reg->on && !reg->overflow));
	json_object_set_new(rj, "source", json_string(reg->user ? "region map"
	                                              : "connected components of the classes"));
	if (reg->overflow)
		json_object_set_new(rj, "note", json_string("more than 1048576 runs of classes: "
		                                            "regions were not formed"));
	json_object_set_new(rj, "count", json_integer(reg->nfinal));
	json_object_set_new(rj, "decision",
	                    json_string("pooled likelihood: sum of each material's d2 over the "
	                                "region's pixels, the differences scaled by 1 / (1 + N f) "
	                                "(f: the calibration's share of a pixel's noise, which "
	                                "pooling does not reduce); a compound class resolves to "
	                                "a member whose share of its posterior is >= 0.99; "
	                                "'unknown' when the decided material's summed d2, scaled "
	                                "by 1 / (1 + N f') with f' the calibration's and the "
	                                "material's own model error's (model_rsd) share, "
	                                "exceeds the 99.9 % point of chi-square with dof "
	                                "N / (1 + N f') degrees of freedom"));
	json_t *table = json_array();
	if (reg->on && !reg->overflow && reg->final) {
		int listed = 0;
		for (uint32_t id = 0; id < reg->n && listed < 2000; id++) {
			uint32_t f = reg->final[id];
			if (!f || reg->count[id] < TABLE_MIN_PIXELS)
				continue;
			region_decision d = lc_decide(reg, id, group, nc);
			const char *merged = reg->merged ? reg->merged[f] : NULL;
			const char *label = merged ? merged : lc_region_label(&d, set, classes);
			double c[6];
			lc_region_composition(reg, id, run->gold_range, c);
			json_t *cj = json_null();
			if (run->metals && !merged && (isfinite(c[0]) || isfinite(c[1])))
				cj = json_pack("{s:o,s:o,s:o,s:o,s:o,s:o}", "ag", ap_json_num(c[0]), "cu",
				               ap_json_num(c[1]), "au", ap_json_num(c[2]), "sd_ag",
				               ap_json_num(c[3]), "sd_cu", ap_json_num(c[4]), "sd_au",
				               ap_json_num(c[5]));
			json_t *row = json_pack("{s:I,s:I,s:s,s:s,s:o,s:o}", "region", (json_int_t)f,
			                        "pixels", (json_int_t)reg->count[id], "class",
			                        classes->names[d.cls], "label", label, "posterior",
			                        merged ? json_null() : ap_json_num(d.posterior),
			                        "composition", cj);
			double need = reg->min_px ? reg->min_px[f] : NAN;
			json_object_set_new(row, "min_pixels", ap_json_num(need));
			json_object_set_new(row, "merged", json_boolean(merged != NULL));
			lc_region_why(row, reg, id, &d, label, merged ? need : 0, classes);
			if (!json_object_get(row, "pixel_class")) /* user regions: none */
				json_object_set_new(row, "pixel_class", json_null());
			json_array_append_new(table, row);
			listed++;
		}
	}
	json_object_set_new(rj, "min_pixels_listed", json_integer(TABLE_MIN_PIXELS));
	if (reg->small.done)
		json_object_set_new(rj, "small", small_json(reg, set, classes, group));
	json_object_set_new(rj, "table", table);
	json_object_set_new(root, "regions", rj);
	int rc = kg_json_write(root, path, err);
	json_decref(root);
	if (rc)
		kg_err_prefix(err, "%s: ", path);
	return rc;
}
