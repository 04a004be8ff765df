/* kogei process, the calibration: the chart capture's image, the chart found and
 * sampled, flagged patches left out, the reference (lab sessions) and M2 fitted and
 * checked, camera.json written, and the colour accuracy of the site estimate on the
 * chart against its measured spectra (kg_pipeline.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "kg_sim.h"
#include "pipeline_private.h"

/* The largest chart frame detected and sampled as it is (32 Mpix, 384 MB as float
 * RGB); larger ones are binned (proc_chart_image). */
#define CHART_MAX_PIXELS (32L << 20)

/* A layout by path, else by bundled name (fixtures/charts/NAME.json, or the demo's). */
static char *resolve_layout(const char *name)
{
	if (access(name, R_OK) == 0)
		return strdup(name);
	char rel[256];
	static const char *const dirs[] = {"charts", "demo"};
	for (int i = 0; i < 2; i++) {
		snprintf(rel, sizeof(rel), "%s/%s.json", dirs[i], name);
		char *p = kg_data_path(rel);
		if (p && access(p, R_OK) == 0)
			return p;
		free(p);
	}
	return NULL;
}

static int load_layout(proc *p)
{
	const char *name = p->o->layout;
	if (!name) {
		/* the manifest's: a bundled name or a file inside the session, nothing else */
		name = json_string_value(json_object_get(p->chart->j, "chart_layout"));
		if (!name)
			return kg_fail(p->err, KG_EINVAL, "%s: chart capture %s records no chart layout "
			               "(acquire --layout L): give --layout",
			               p->manifest_path, p->chart->name);
		const json_t *caps = json_object_get(p->manifest, "captures");
		size_t i = 0;
		while (i < json_array_size(caps) && json_array_get(caps, i) != p->chart->j)
			i++;
		char key[64];
		snprintf(key, sizeof(key), "captures[%zu].chart_layout", i);
		int ret = kg_chart_layout_resolve_session(p->o->session, p->manifest_path, key, name,
		                                          &p->layout_path, p->err);
		if (!ret)
			ret = proc_input(p, "layout", p->layout_path, NULL);
		if (!ret)
			ret = kg_chart_layout_load(p->layout_path, &p->layout, p->err);
		return ret;
	}
	p->layout_path = resolve_layout(name);
	if (!p->layout_path)
		return kg_fail(p->err, KG_ENOENT, "chart layout '%s': no such file and not a bundled "
		               "layout (colorchecker24-frame, colorchecker-passport-frame, "
		               "colorchecker-sg-frame, cie-tcs-frame)", name);
	int ret = proc_input(p, "layout", p->layout_path, NULL);
	if (!ret)
		ret = kg_chart_layout_load(p->layout_path, &p->layout, p->err);
	return ret;
}

static const proc_capture *choose_chart(proc *p)
{
	const proc_capture *c = NULL;
	for (int i = 0; i < p->ncaps; i++) {
		const proc_capture *x = &p->caps[i];
		if (p->o->chart ? !strcmp(x->name, p->o->chart) : x->kind == KG_CAPTURE_CHART)
			c = x;
	}
	return c;
}

/* The Lab of a reflectance under an illuminant's weights. */
static kg_lab lab_of(const kg_xyz_weights *w, kg_xyz white, const kg_spectrum *s)
{
	return kg_xyz_to_lab(kg_xyz_from_weights(w, s), white);
}

/* Three values; null where not finite (a rejected patch has none). */
static json_t *triple_json(const double v[3])
{
	if (!isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2]))
		return json_null();
	return json_pack("[fff]", v[0], v[1], v[2]);
}

static json_t *spectrum_json(const kg_spectrum *s)
{
	json_t *a = json_array();
	for (int b = 0; b < KG_NBANDS; b++)
		json_array_append_new(a, json_real(s->v[b]));
	return a;
}

/* The standard deviation of L* (D50) of a patch's estimate from its pixel spread:
 * each channel's spread through the slope of L* in that channel (central
 * differences), the channels taken as independent. */
static json_t *noise_l(const kg_site_map *map, const kg_xyz_weights *w, kg_xyz white,
                       const kg_chart_sample *s)
{
	double var = 0;
	for (int c = 0; c < 3; c++) {
		if (!isfinite(s->sd[c]) || !isfinite(s->rgb[c]))
			return json_null();
		double h = 1e-4 + 1e-3 * fabs(s->rgb[c]);
		double lo[3] = {s->rgb[0], s->rgb[1], s->rgb[2]}, hi[3] = {lo[0], lo[1], lo[2]};
		lo[c] -= h;
		hi[c] += h;
		kg_spectrum a, b;
		kg_site_map_apply(map, lo, &a);
		kg_site_map_apply(map, hi, &b);
		double slope = (lab_of(w, white, &b).L - lab_of(w, white, &a).L) / (2 * h);
		var += slope * slope * s->sd[c] * s->sd[c];
	}
	return json_real(sqrt(var));
}

/* Held-out estimates: for each usable patch, the calibration refitted without it
 * (leave-one-out) and its RGB through that fit; v[0] NaN where none (flagged, or the
 * fit without the patch is not possible). A site session (a reference given) refits
 * M2; a lab session, whose reference comes from this chart (train), refits the
 * reference too, since M2 on the chart the reference was fitted to is the identity. */
static int heldout_estimates(proc *p, const kg_chart_result *res, const kg_patchset *ps,
                             const kg_patchset *train, char **flagged, int nflagged,
                             kg_spectrum **out)
{
	kg_spectrum *h = calloc((size_t)res->npatches, sizeof(*h));
	const char **ex = calloc((size_t)nflagged + 1, sizeof(*ex));
	if (!h || !ex) {
		free(h);
		free(ex);
		return kg_fail(p->err, KG_ENOMEM, "out of memory");
	}
	for (int i = 0; i < nflagged; i++)
		ex[i] = flagged[i];
	for (int i = 0; i < res->npatches; i++) {
		h[i].v[0] = NAN;
		const kg_chart_sample *s = &res->patches[i];
		if (s->flags || p->cam->k <= 4)
			continue;
		kg_camera_options copt;
		kg_camera_options_default(&copt);
		ex[nflagged] = s->id;
		copt.exclude = ex;
		copt.nexclude = nflagged + 1;
		copt.max_residual = 1e9; /* held out: never refused for its residual */
		copt.force = 1;
		kg_camera_calib *cam = NULL;
		kg_reference *ref = NULL;
		const kg_site_map *map = NULL;
		kg_err e;
		int ok = 1;
		if (train) {
			kg_reference_options ropt;
			kg_reference_options_default(&ropt);
			ropt.exclude = ex;
			ropt.nexclude = nflagged + 1;
			ok = kg_reference_fit(train, ps, &ropt, &ref, &e) == 0;
		}
		if (ok && kg_camera_fit(ref ? ref : p->ref, ps, &copt, &cam, &e) == 0 &&
		    kg_camera_site_map(cam, KG_METHOD_AUTO, &map, &e) == 0)
			kg_site_map_apply(map, s->rgb, &h[i]);
		kg_camera_calib_free(&cam);
		kg_reference_free(&ref);
	}
	free(ex);
	*out = h;
	return 0;
}

/* The --verify capture: the chart found and sampled in it as in the chart capture. */
static int verify_chart(proc *p, const kg_chart_detect_options *dopt, kg_chart_result **out)
{
	const proc_capture *c = NULL;
	for (int i = 0; i < p->ncaps; i++)
		if (p->caps[i].name && !strcmp(p->caps[i].name, p->o->verify))
			c = &p->caps[i];
	if (!c)
		return kg_fail(p->err, KG_EINVAL, "%s: --verify %s: no capture of that name (expected "
		               "a second capture of the chart)", p->manifest_path, p->o->verify);
	if (c == p->chart)
		return kg_fail(p->err, KG_EINVAL, "--verify %s: is the chart capture the calibration "
		               "is fitted to (expected another capture of the chart)", p->o->verify);
	proc_image img = {0};
	int bin = 1;
	int ret = proc_chart_image(p, c, CHART_MAX_PIXELS, 1.0f, &img, &bin);
	if (!ret && (ret = kg_chart_detect(p->layout, img.rgb, dopt, out, p->err)))
		kg_err_prefix(p->err, "--verify %s: no chart %s: ", c->name, p->layout->name);
	proc_image_clear(&img);
	if (!ret)
		proc_progress(p, "verification: chart found in capture %s", c->name);
	return ret;
}

/* The patches of the chart with their flags, and where measured spectra are known,
 * the site estimate against them (ΔE00 under D50 and D65; ΔL*, ΔE(a*b*) under D50). */
static int patches_json(proc *p, const kg_chart_result *res, const kg_patchset *measured,
                        const kg_spectrum *heldout, const kg_chart_result *verify,
                        json_t **out)
{
	kg_illuminant *d50 = NULL, *d65 = NULL;
	kg_xyz_weights w50, w65;
	const kg_site_map *map = NULL;
	int ret = kg_illuminant_by_name("D50", &d50, p->err);
	if (!ret)
		ret = kg_illuminant_by_name("D65", &d65, p->err);
	if (!ret)
		ret = kg_camera_site_map(p->cam, KG_METHOD_AUTO, &map, p->err);
	if (ret)
		goto done;
	kg_xyz_weights_reflectance(d50, &w50);
	kg_xyz_weights_reflectance(d65, &w65);
	kg_xyz white50 = kg_illuminant_white(d50), white65 = kg_illuminant_white(d65);
	json_t *list = json_array();
	for (int i = 0; i < res->npatches; i++) {
		const kg_chart_sample *s = &res->patches[i];
		const kg_chart_patch *lp = &p->layout->patches[i];
		int used = 0;
		for (int k = 0; k < p->cam->k; k++)
			if (!strcmp(p->cam->ids[k], s->id))
				used = 1;
		json_t *e = json_pack("{s:s, s:s, s:o, s:o, s:I, s:i, s:b, s:s}", "id", s->id, "name",
		                      lp->name, "rgb", triple_json(s->rgb), "sd", triple_json(s->sd),
		                      "pixels", (json_int_t)s->pixels, "flags", (int)s->flags, "used",
		                      used, "warning", s->warning);
		int mi = measured ? kg_patchset_find(measured, s->id) : -1;
		if (mi < 0 && measured && lp->alias[0])
			mi = kg_patchset_find(measured, lp->alias);
		if (mi >= 0 && !(s->flags & KG_CHART_FLAG_REJECTED)) {
			kg_spectrum est;
			kg_site_map_apply(map, s->rgb, &est);
			const kg_spectrum *m = &measured->spectra[mi];
			kg_lab a50 = lab_of(&w50, white50, m), b50 = lab_of(&w50, white50, &est);
			kg_lab a65 = lab_of(&w65, white65, m), b65 = lab_of(&w65, white65, &est);
			double chroma = hypot(a50.a, a50.b);
			json_object_set_new(e, "measured", spectrum_json(m));
			json_object_set_new(e, "estimated", spectrum_json(&est));
			json_object_set_new(e, "de00_d50", json_real(kg_ciede2000(a50, b50)));
			json_object_set_new(e, "de00_d65", json_real(kg_ciede2000(a65, b65)));
			json_object_set_new(e, "dL", json_real(b50.L - a50.L));
			json_object_set_new(e, "dab", json_real(hypot(b50.a - a50.a, b50.b - a50.b)));
			json_object_set_new(e, "noise_L", noise_l(map, &w50, white50, s));
			if (heldout && isfinite(heldout[i].v[0])) {
				kg_lab h50 = lab_of(&w50, white50, &heldout[i]);
				json_object_set_new(e, "de00_d50_heldout", json_real(kg_ciede2000(a50, h50)));
			} else {
				json_object_set_new(e, "de00_d50_heldout", json_null());
			}
			const kg_chart_sample *v = verify && i < verify->npatches ? &verify->patches[i]
			                                                          : NULL;
			if (v && !v->flags && !strcmp(v->id, s->id)) {
				kg_spectrum ve;
				kg_site_map_apply(map, v->rgb, &ve);
				kg_lab v50 = lab_of(&w50, white50, &ve);
				json_object_set_new(e, "de00_d50_verify", json_real(kg_ciede2000(a50, v50)));
				/* the verification capture's tone, white balance and noise: its
				 * response is not the one the calibration was fitted to */
				json_object_set_new(e, "dL_verify", json_real(v50.L - a50.L));
				json_object_set_new(e, "dab_verify",
				                    json_real(hypot(v50.a - a50.a, v50.b - a50.b)));
				json_object_set_new(e, "noise_L_verify", noise_l(map, &w50, white50, v));
			}
			/* neutral: the measured patch's chroma C*ab under D50 below 4 */
			json_object_set_new(e, "neutral", json_boolean(chroma < 4.0));
		} else {
			json_object_set_new(e, "measured", json_null());
			json_object_set_new(e, "estimated", json_null());
			json_object_set_new(e, "de00_d50", json_null());
			json_object_set_new(e, "de00_d65", json_null());
			json_object_set_new(e, "dL", json_null());
			json_object_set_new(e, "dab", json_null());
			json_object_set_new(e, "noise_L", json_null());
			json_object_set_new(e, "de00_d50_heldout", json_null());
			json_object_set_new(e, "neutral", json_false());
		}
		json_array_append_new(list, e);
	}
	*out = list;
done:
	kg_illuminant_free(&d50);
	kg_illuminant_free(&d65);
	return ret;
}

static double cond_of(int rows, int cols, const double *m, kg_err *err)
{
	kg_mat *a = NULL;
	double c = NAN;
	if (kg_mat_from(rows, cols, m, &a, err) == 0 && kg_cond(a, 0, &c, err) != 0)
		c = NAN;
	kg_mat_free(&a);
	return c;
}

/* camera.json's camera: the chart capture's, from the session's manifest. */
static void chart_identity(const proc *p, kg_camera_identity *id)
{
	const proc_capture *c = p->chart;
	memset(id, 0, sizeof(*id));
	const char *b = json_string_value(json_object_get(c->camera, "backend"));
	const char *m = json_string_value(json_object_get(c->camera, "model"));
	const char *s = json_string_value(json_object_get(c->camera, "serial"));
	if (!b || !m || !s)
		return;
	id->known = 1;
	snprintf(id->backend, sizeof(id->backend), "%s", b);
	snprintf(id->model, sizeof(id->model), "%s", m);
	snprintf(id->serial, sizeof(id->serial), "%s", s);
	snprintf(id->pixfmt, sizeof(id->pixfmt), "%s", c->pixfmt ? c->pixfmt : "");
	id->white_level = c->bits > 0 && c->bits < 31 ? (1L << c->bits) - 1 : 0;
	const char *dm = json_string_value(kg_json_find(c->j, "demosaic.algorithm"));
	snprintf(id->demosaic, sizeof(id->demosaic), "%s", dm ? dm : "none");
	snprintf(id->capture, sizeof(id->capture), "%s", c->name);
}

/* The chart's measured spectra for the report: --spectra, else the reference's. */
static int measured_spectra(proc *p, kg_patchset **out)
{
	*out = NULL;
	const char *path = p->o->spectra;
	if (!path && p->ref)
		for (int i = 0; i < p->ref->nsources; i++)
			if (!strcmp(p->ref->sources[i].role, "spectra"))
				path = p->ref->sources[i].path;
	if (!path)
		return 0;
	if (access(path, R_OK) != 0) {
		proc_warn(p, NULL, "%s: the reference's chart spectra cannot be read: no colour "
		          "accuracy against measured spectra (give --spectra)", path);
		return 0;
	}
	int ret = p->o->spectra ? 0 : proc_input(p, "spectra", path, NULL);
	if (!ret)
		ret = kg_sim_read_spectra(path, 0, out, p->err);
	return ret;
}

/* The light field removed from the chart's patch values (calib/light_field.c). */
/* The patches of the spectra or of the chart that found no partner, left out. */
static void note_unpaired(proc *p, const kg_pairing_record *rec, const char *spectra)
{
	const char *file[2] = {spectra, "the chart"};
	for (int s = 0; s < 2; s++) {
		if (!rec->nunpaired[s])
			continue;
		char list[400] = "";
		size_t at = 0;
		for (int i = 0; i < rec->nunpaired[s] && at < sizeof(list); i++)
			at += (size_t)snprintf(list + at, sizeof(list) - at, "%s%s", i ? ", " : "",
			                       rec->unpaired[s][i]);
		proc_warn(p, NULL, "%s: %d patch%s paired with nothing in %s, left out: %s", file[s],
		          rec->nunpaired[s], rec->nunpaired[s] == 1 ? "" : "es", file[1 - s], list);
	}
}

/* calibration.spectral_uncertainty: per band, the RMS error of the default method's
 * leave-one-out estimates over the reference chart (each patch estimated by the
 * calibration refitted without it), the uncertainty of an estimated spectrum; null
 * when the reference holds none (files of earlier versions). */
static json_t *uncertainty_json(const proc *p)
{
	const kg_spectral_map *m = p->ref ? &p->ref->maps[p->cam->method] : NULL;
	if (!m || !m->available || !isfinite(m->loo_band[0]))
		return json_null();
	json_t *band = json_array();
	for (int l = 0; l < KG_NBANDS; l++)
		json_array_append_new(band, json_real(m->loo_band[l]));
	const kg_reference *r = p->ref;
	json_t *prior = json_pack("{s:s, s:b, s:i, s:o}", "white_source", r->neutral_white_source,
	                          "added", r->neutral_prior, "weight", r->neutral_weight,
	                          "tilt_before", isfinite(r->neutral_tilt_before)
	                                             ? json_real(r->neutral_tilt_before)
	                                             : json_null());
	return json_pack("{s:s, s:o, s:o, s:o, s:s}", "method", kg_method_name(m->method),
	                 "loo_band_rmse", band, "neutral_tilt",
	                 isfinite(m->neutral_tilt) ? json_real(m->neutral_tilt) : json_null(),
	                 "neutral_prior", prior ? prior : json_null(), "description",
	                 "per band (400-700 nm, 5 nm), the RMS error over the reference chart of "
	                 "the method's leave-one-out estimates: the spectral uncertainty of an "
	                 "estimate; the report draws it as a band of +- this around each "
	                 "material's mean spectrum. neutral_tilt: the largest relative "
	                 "departure from flat of the method's estimate of a flat grey (0.2 and "
	                 "0.8); neutral_prior: whether flat greys joined the fit because the "
	                 "chart holds no neutral patches (reference.json's neutral_prior)");
}

/* A flare measurement (calib/flare.c) as process.json records it, or null. */
static json_t *flare_one(const kg_flare *f)
{
	if (!f->found)
		return json_null();
	json_t *ids = json_array();
	for (int i = 0; i < f->n; i++)
		json_array_append_new(ids, json_string(f->ids[i]));
	return json_pack("{s:o, s:[fff], s:[fff], s:[fff]}", "neutrals", ids, "white_fraction",
	                 f->white_fraction[0], f->white_fraction[1], f->white_fraction[2],
	                 "offset", f->offset[0], f->offset[1], f->offset[2], "residual",
	                 isfinite(f->residual[0]) ? f->residual[0] : 0.0,
	                 isfinite(f->residual[1]) ? f->residual[1] : 0.0,
	                 isfinite(f->residual[2]) ? f->residual[2] : 0.0);
}

/* calibration.flare: the reference chart's (and whether the reference fit removed it,
 * with the leave-one-out that decided) and the site chart's (removed from the site
 * values and from every object's). */
static json_t *flare_json(const kg_reference *ref, const kg_camera_calib *cam)
{
	json_t *o = json_object();
	json_object_set_new(o, "reference", flare_one(&ref->flare));
	json_object_set_new(o, "reference_removed", json_boolean(ref->flare_removed));
	json_object_set_new(o, "loo_de00_kept", isfinite(ref->flare_loo_kept)
	                                            ? json_real(ref->flare_loo_kept)
	                                            : json_null());
	json_object_set_new(o, "loo_de00_removed", isfinite(ref->flare_loo_removed)
	                                               ? json_real(ref->flare_loo_removed)
	                                               : json_null());
	json_object_set_new(o, "site", flare_one(&cam->flare));
	json_object_set_new(o, "site_removed", json_boolean(cam->flare_removed));
	return o;
}

static json_t *light_field_json(const kg_chart_light *f)
{
	if (!f->fitted)
		return json_pack("{s:b}", "fitted", 0);
	json_t *coef = json_array();
	for (int k = 0; k < 15; k++)
		json_array_append_new(coef, json_real(f->coef[k]));
	return json_pack("{s:b, s:i, s:f, s:f, s:f, s:i, s:[ff], s:f, s:o}", "fitted", 1, "degree",
	                 f->degree, "variation", f->variation, "min", f->min, "max", f->max,
	                 "patches", f->used, "origin_mm", f->origin_mm[0], f->origin_mm[1],
	                 "scale_mm", f->scale_mm, "coefficients", coef);
}

/* The illuminance non-uniformity acquire measured on the flat named (null when none
 * or not recorded). */
static json_t *flat_nonuniformity(const proc *p, const char *flat)
{
	for (int i = 0; flat && flat[0] && i < p->ncaps; i++)
		if (p->caps[i].name && strcmp(p->caps[i].name, flat) == 0) {
			const json_t *v =
				kg_json_find(p->caps[i].j, "statistics.illuminance_nonuniformity");
			return json_is_number(v) ? json_real(json_number_value(v)) : json_null();
		}
	return json_null();
}

/* The patches the site fit left out for not fitting the others through M2 (a card over
 * them: calib/site.c), flagged in the chart's result as the detector's are, so
 * process.json, the report and the held-out estimates treat them alike. */
static void note_m2_misfits(proc *p, const kg_camera_calib *cam, kg_chart_result *res,
                            char **flagged, int *nflagged)
{
	for (int f = 0; f < cam->nflagged; f++) {
		if (cam->flagged_flags[f] != KG_CHART_FLAG_MISFIT)
			continue;
		for (int i = 0; i < res->npatches; i++) {
			kg_chart_sample *s = &res->patches[i];
			if (strcmp(s->id, cam->flagged_ids[f]) || s->flags)
				continue;
			s->flags |= KG_CHART_FLAG_MISFIT;
			snprintf(s->warning, sizeof(s->warning), "does not fit the other patches "
			         "through M2 against the reference's chart: covered or painted over?");
			flagged[(*nflagged)++] = s->id;
			proc_warn(p, NULL, "chart: patch %s left out of M2: %s", s->id, s->warning);
		}
	}
}

int proc_calibrate(proc *p)
{
	const kg_process_options *o = p->o;
	kg_err *err = p->err;
	proc_image img = {0};
	kg_chart_result *res = NULL;
	kg_patchset *ps = NULL, *spectra = NULL, *train = NULL, *measured = NULL;
	kg_camera_calib *cam = NULL;
	char **flagged = NULL;
	int nflagged = 0, ret = 0;
	char *ref_out = kg_path_join(p->stage, "reference.json");
	char *cam_out = kg_path_join(p->stage, "camera.json");
	char *overlay = kg_path_join(p->stage, "chart_overlay.png");
	if (!ref_out || !cam_out || !overlay)
		return kg_fail(err, KG_ENOMEM, "out of memory");

	if (!(p->chart = choose_chart(p))) {
		ret = o->chart ? kg_fail(err, KG_EINVAL, "%s: no capture named '%s'", p->manifest_path,
		                         o->chart)
		               : kg_fail(err, KG_EINVAL, "%s: no chart capture (acquire --kind "
		                         "chart): a session without the chart cannot be calibrated",
		                         p->manifest_path);
		goto done;
	}
	if (p->chart->kind != KG_CAPTURE_CHART)
		proc_warn(p, NULL, "capture %s is of kind %s, used as the chart capture (--chart)",
		          p->chart->name, kg_capture_kind_name(p->chart->kind));
	if ((ret = proc_objects_precheck(p)) || (ret = load_layout(p)))
		goto done;
	if (o->reference) {
		if (!(ret = proc_input(p, "reference", o->reference, NULL)))
			ret = kg_reference_load(o->reference, &p->ref, err);
		if (ret)
			goto done;
	}
	if (o->spectra && (ret = proc_input(p, "spectra", o->spectra, NULL)))
		goto done;

	proc_progress(p, "chart: capture %s, layout %s", p->chart->name, p->layout->name);
	kg_chart_detect_options dopt;
	kg_chart_detect_options_default(&dopt);
	/* A frame above CHART_MAX_PIXELS is binned for detection and sampling, so memory
	 * stays bounded; its homography is then scaled back to the frame's pixels. The
	 * clip level is the detector's for a float image (full scale). */
	int bin = 1;
	if ((ret = proc_chart_image(p, p->chart, CHART_MAX_PIXELS, 1.0f, &img, &bin)))
		goto done;
	p->chart_width = bin > 1 ? (int)p->chart->width : img.rgb->width;
	p->chart_height = bin > 1 ? (int)p->chart->height : img.rgb->height;
	if (bin > 1)
		proc_warn(p, NULL, "chart: capture %s of %ldx%ld pixels binned %dx%d (%dx%d) to find "
		          "and sample the chart; patch values are means of the bins", p->chart->name,
		          p->chart->width, p->chart->height, bin, bin, img.rgb->width,
		          img.rgb->height);
	if (o->min_tags > 0)
		dopt.min_tags = o->min_tags;
	if (o->threads > 0)
		dopt.threads = o->threads;
	if ((ret = kg_chart_detect(p->layout, img.rgb, &dopt, &res, err))) {
		kg_err_prefix(err, "capture %s: %s chart %s: ", p->chart->name,
		              ret == KG_ENOENT ? "no" : "refused the", p->layout->name);
		goto done;
	}
	memcpy(p->chart_H, res->H, sizeof(p->chart_H));
	for (int k = 0; k < 6; k++) /* binned px -> the frame's px: x and y rows times bin */
		p->chart_H[k] *= bin;
	for (int i = 0; i < res->nwarnings; i++)
		proc_warn(p, NULL, "chart: %s", res->warnings[i]);
	if ((ret = kg_chart_result_patchset(res, &ps, err)))
		goto done;

	/* Flagged patches are left out of every fit. */
	flagged = calloc((size_t)res->npatches + 1, sizeof(*flagged));
	if (!flagged) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto done;
	}
	char flagged_list[1024] = "";
	size_t at = 0;
	for (int i = 0; i < res->npatches; i++)
		if (res->patches[i].flags) {
			flagged[nflagged++] = res->patches[i].id;
			if (at < sizeof(flagged_list) - 1)
				at += (size_t)snprintf(flagged_list + at, sizeof(flagged_list) - at,
				                       "%s%s (%s)", at ? "; " : "", res->patches[i].id,
				                       res->patches[i].warning);
		}
	int usable = res->npatches - nflagged;
	proc_progress(p, "chart found (%s): %d of %d patches usable%s%s",
	              res->tagless ? "tagless" : "tags", usable, res->npatches,
	              nflagged ? ", left out: " : "", flagged_list);
	if (usable < 3) {
		ret = kg_fail(err, KG_EINVAL, "capture %s: only %d of the %d patches of %s are "
		              "usable, 3 at least are needed; flagged: %s (is it the right layout, "
		              "evenly lit and not clipped?)",
		              p->chart->name, usable, res->npatches, p->layout->name, flagged_list);
		goto done;
	}

	if (!p->ref) { /* a lab session: the reference from this chart */
		kg_reference_options ropt;
		kg_reference_options_default(&ropt);
		ropt.exclude = (const char *const *)flagged;
		ropt.nexclude = nflagged;
		kg_pairing_record rec = {.misfit = NAN};
		ret = kg_sim_read_spectra(o->spectra, 0, &spectra, err);
		if (!ret)
			ret = kg_calib_pair_checked(spectra, ps, NULL, &train, &rec, NULL, err);
		if (!ret)
			ret = kg_reference_fit(train, ps, &ropt, &p->ref, err);
		if (!ret) {
			note_unpaired(p, &rec, o->spectra);
			p->ref->pairing = rec;
		} else {
			kg_pairing_record_free(&rec);
		}
		if (!ret)
			ret = kg_reference_add_source(p->ref, "spectra", o->spectra, err);
		if (ret) {
			kg_err_prefix(err, "capture %s with %s: reference calibration: ", p->chart->name,
			              o->spectra);
			goto done;
		}
		proc_progress(p, "reference fitted: K = %d, leave-one-out RMSE %.4f", p->ref->K,
		              p->ref->maps[p->ref->method].loo_rmse);
	}

	kg_camera_options copt;
	kg_camera_options_default(&copt);
	copt.exclude = (const char *const *)flagged;
	copt.nexclude = nflagged;
	copt.max_residual = o->max_residual;
	copt.force = o->force;
	if ((ret = kg_camera_fit(p->ref, ps, &copt, &cam, err))) {
		kg_err_prefix(err, "capture %s: site calibration: ", p->chart->name);
		goto done;
	}
	note_m2_misfits(p, cam, res, flagged, &nflagged);
	if (cam->k <= 3)
		proc_warn(p, NULL, "M2 rests on %d patches and cannot be checked (--force)", cam->k);
	chart_identity(p, &cam->identity);
	p->cam = cam;
	cam = NULL;
	if ((ret = measured_spectra(p, &measured)))
		goto done;

	/* Everything checked: the files. */
	if (!o->reference) {
		if ((ret = kg_reference_save(p->ref, ref_out, err)))
			goto done;
		proc_progress(p, "reference calibration: %s/reference.json", o->outdir);
	}
	if ((ret = kg_camera_save(p->cam, cam_out, err)))
		goto done;
	proc_progress(p, "site calibration: %s/camera.json (M2 residual %.2f %%, %d patches)",
	              o->outdir,
	              100 * p->cam->residual_relative, p->cam->k);
	if ((ret = kg_chart_overlay_write(res, img.rgb, overlay, 0, err)))
		goto done;

	json_t *patches = NULL;
	kg_spectrum *heldout = NULL;
	if (measured && (ret = heldout_estimates(p, res, ps, o->reference ? NULL : train, flagged,
	                                              nflagged, &heldout)))
		goto done;
	kg_chart_result *vres = NULL;
	if (o->verify && !measured)
		proc_warn(p, NULL, "--verify %s: no measured chart spectra, nothing to verify against",
		          o->verify);
	if (measured && o->verify && (ret = verify_chart(p, &dopt, &vres))) {
		free(heldout);
		goto done;
	}
	ret = patches_json(p, res, measured, heldout, vres, &patches);
	kg_chart_result_free(&vres);
	free(heldout);
	if (ret)
		goto done;
	json_t *tags = json_array();
	for (int i = 0; i < res->ntags; i++)
		if (res->tags[i].used)
			json_array_append_new(tags, json_integer(res->tags[i].id));
	const json_t *s = json_object_get(p->chart->j, "settings");
	p->calibration = json_pack(
		"{s:s, s:s, s:s, s:s, s:s, s:o, s:f, s:s, s:O, s:O, s:O, s:O, s:f, s:o, s:o, s:f, "
		"s:f, s:o, s:f, s:o, s:o, s:i}",
		"file", "camera.json", "chart_capture", p->chart->name, "layout", p->layout->name,
		"layout_file", p->layout_path, "detector", res->tagless ? "tagless" : "apriltag",
		"tags_used", tags, "homography_rms_px", res->rms_px, "overlay", "chart_overlay.png",
		"exposure_us", kg_json_find(s, "exposure_us") ? kg_json_find(s, "exposure_us")
		                                              : json_null(),
		"gain", kg_json_find(s, "gain") ? kg_json_find(s, "gain") : json_null(), "gain_unit",
		kg_json_find(s, "gain_unit") ? kg_json_find(s, "gain_unit") : json_null(), "frames",
		kg_json_find(s, "frames") ? kg_json_find(s, "frames") : json_null(), "cond_M",
		cond_of(p->cam->K, 3, p->cam->M, err), "dark", img.dark[0] ? json_string(img.dark)
		                                                           : json_null(),
		"flat", img.flat[0] ? json_string(img.flat) : json_null(), "cond_M2",
		cond_of(3, 3, p->cam->M2, err), "residual_relative", p->cam->residual_relative, "M2",
		json_pack("[fffffffff]", p->cam->M2[0], p->cam->M2[1], p->cam->M2[2], p->cam->M2[3],
		          p->cam->M2[4], p->cam->M2[5], p->cam->M2[6], p->cam->M2[7], p->cam->M2[8]),
		"cond_rho_r", p->cam->cond, "patches", patches,
		"spectra_source", measured && measured->source ? json_string(measured->source)
		                                               : json_null(),
		"patches_used", p->cam->k);
	if (!p->calibration) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto done;
	}
	if ((ret = proc_camera_icc(p, measured)))
		goto done;
	json_t *making = proc_capture_making(p->chart);
	json_object_update(p->calibration, making);
	json_decref(making);
	json_t *fl = json_array();
	for (int i = 0; i < nflagged; i++)
		json_array_append_new(fl, json_string(flagged[i]));
	json_object_set_new(p->calibration, "patches_flagged", fl);
	json_object_set_new(p->calibration, "decimate", json_integer(res->decimate));
	json_object_set_new(p->calibration, "flare", flare_json(p->ref, p->cam));
	json_object_set_new(p->calibration, "spectral_uncertainty", uncertainty_json(p));
	{ /* a flat grey estimated with shape the chart does not hold (a chart with neutral
	   * patches says itself what its greys are, shape included): say so, the cube's
	   * spectra carry it */
		const kg_spectral_map *m = p->ref ? &p->ref->maps[p->cam->method] : NULL;
		if (m && m->available && m->neutral_tilt > KG_CALIB_MAX_NEUTRAL_TILT &&
		    strcmp(p->ref->neutral_white_source, "neutrals") != 0)
			proc_warn(p, NULL, "calibration: method %s estimates a flat grey with %.0f %% "
			          "of spectral shape (limit %.0f %%) even with flat greys in its fit: a "
			          "slope or bump of that size in an estimated spectrum is not supported "
			          "by the chart (a chart with neutral patches narrows it)",
			          kg_method_name(m->method), 100 * m->neutral_tilt,
			          100 * KG_CALIB_MAX_NEUTRAL_TILT);
	}
	json_object_set_new(p->calibration, "light_field", light_field_json(&res->light));
	json_object_set_new(p->calibration, "flat_illuminance_nonuniformity",
	                    flat_nonuniformity(p, img.flat));
	{ /* the imaging-quality analysis, also OUTDIR/conformance.json */
		const json_t *nu = json_object_get(p->calibration, "flat_illuminance_nonuniformity");
		json_t *conf = kg_conformance(patches, json_is_number(nu) ? json_number_value(nu)
		                                                           : NAN);
		if (conf)
			kg_conformance_edges(conf, p->layout, res, img.rgb, bin);
		char *conf_out = kg_path_join(p->stage, "conformance.json");
		json_t *doc = json_pack("{s:s, s:O}", "caveat", KG_CONFORMANCE_CAVEAT,
		                        "characteristics", conf);
		ret = conf_out && doc ? kg_json_write(doc, conf_out, err)
		                      : kg_fail(err, KG_ENOMEM, "out of memory");
		json_decref(doc);
		free(conf_out);
		json_object_set_new(p->calibration, "conformance", conf);
		if (ret)
			goto done;
	}
	json_object_set_new(p->calibration, "detect_seconds", json_real(res->total_seconds));
	if (!o->reference)
		json_object_set_new(p->calibration, "reference_file", json_string("reference.json"));
	/* What the calibration rests on: the inputs read so far, by role and content (not
	 * where they lie: a session moved to another disk is unchanged), and the
	 * parameters. */
	json_t *content = json_array();
	size_t i;
	json_t *in;
	json_array_foreach(p->inputs, i, in)
		json_array_append_new(content, json_pack("{s:O, s:O}", "role",
		                                         json_object_get(in, "role"), "sha256",
		                                         json_object_get(in, "sha256")));
	p->calib_key = json_pack("{s:o, s:f, s:i, s:b}", "inputs", content,
	                         "max_residual", o->max_residual, "min_tags", o->min_tags, "force",
	                         o->force);
done:
	proc_image_clear(&img);
	kg_chart_result_free(&res);
	kg_patchset_free(&ps);
	kg_patchset_free(&spectra);
	kg_patchset_free(&train);
	kg_patchset_free(&measured);
	kg_camera_calib_free(&cam);
	free(flagged);
	free(ref_out);
	free(cam_out);
	free(overlay);
	return ret;
}
