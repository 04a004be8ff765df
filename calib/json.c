/* The calibration files: "kogei-reference/1" and "kogei-camera/1" (JSON).
 *
 * Matrices are arrays of rows. Spectral matrices have one row per band (61 rows:
 * B is 61 x K, A is 61 x T); M is K x 3, M2 3 x 3; RGB of the field and site charts
 * is 3 x k as in the paper (rho0, rho_r: one row per channel, one column per patch),
 * the training RGB m x 3 (one row per patch). Numbers that are not finite (a
 * validation that could not run) are written as null.
 *
 * kogei-reference/1:
 *   format, software, grid {start_nm, step_nm, bands},
 *   method (the default for estimate), method_chosen_by ("option"|"leave-one-out"),
 *   K_chosen_by, K, centred, B, mean and rgb_mean (centred only), M, ridge,
 *   noise_sigma, singular_values, energy (cumulative),
 *   methods {pca|linear|wiener|rootpoly2|rootpoly3: {available, note (if not),
 *     terms, ridge (wiener: lambda_m_sigma2), A, offset, condition_number,
 *     fit_rmse, loo_rmse, loo_de00}},
 *   validation {loo_rmse_by_K, loo_rmse_by_method},
 *   training {patches, ids, rho (m x 3), rmse, gfc, de00_d65, projection_rmse,
 *     weight_residual, mean_rmse, mean_de00_d65, max_de00_d65, condition_number_rho},
 *   field {ids, rho0 (3 x k), condition_number, flagged [{id, flags}]: patches chart
 *         detection flagged, left out of the fit (optional)},
 *   response {source, patches, F (3 x 61), lambda, loo_rmse (3 each), loo_relative}:
 *     the reference camera's spectral response (response.c), null or absent in older
 *     files,
 *   pairing {rule (kg_id_pairing_name), aliases (kg_patch_ids_match's rule, or null),
 *     pairs, checked, misfit (null: not checked), misfit_limit, unpaired {spectra: [id],
 *     rgb: [id]}}: how the spectra and the RGB were paired (pairing.c); absent in older
 *     files and in calibrations fitted without pairing two files,
 *   devices {role: INSTRUMENTATION|DEVICE|CAMERA|... keyword}, illuminant,
 *   sources [{role, path, sha256, keywords {...}}].
 *
 * kogei-camera/1:
 *   format, software, grid, reference {path, sha256}, method, K, centred, B, mean and
 *   rgb_mean (centred only), M, M2, A (= B M M2, 61 x 3) and offset (the pca map),
 *   methods {name: {available, terms, ridge|lambda_m_sigma2, pre (3 x 3), A (61 x T),
 *     offset, loo_rmse}}: s = offset + A x(pre rho_site),
 *   site {patches, ids, rho_r, rho0, residual (3 x k each), residual_rms,
 *     residual_relative, condition_number, condition_number_equilibrated,
 *     singular_values, rank, flagged [{id, flags}]: patches chart detection flagged,
 *     left out, pairing: as the reference's, unpaired {reference, rgb}},
 *   camera {backend, model, serial, pixfmt, white_level, demosaic, capture}: the site
 *     camera, null when unknown (files without the key load as unknown),
 *   response: the reference's, as above,
 *   devices, sources. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "calib_private.h"
#include "kg_config.h"

#define NB KG_NBANDS
#define REFERENCE_FORMAT "kogei-reference/1"
#define CAMERA_FORMAT "kogei-camera/1"

/* ---- writing ------------------------------------------------------------------ */

/* A builder that remembers the first failure, so a document is assembled without
 * checking every call: out of memory, or a string that is not UTF-8 (which JSON cannot
 * hold), remembered with what it was. */
typedef struct jw {
	int bad;
	char text_what[96]; /* the first string that is not UTF-8, e.g. "a patch id" */
	size_t text_offset;    /* its first byte that is not */
	unsigned char text_byte;
} jw;

static json_t *jnum(double v)
{
	return isfinite(v) ? json_real(v) : json_null();
}

static void put(jw *w, json_t *obj, const char *key, json_t *v)
{
	if (!v || json_object_set_new(obj, key, v) != 0)
		w->bad = 1;
}

static json_t *jrow(jw *w, const double *v, int n, int stride)
{
	json_t *a = json_array();
	if (!a) {
		w->bad = 1;
		return NULL;
	}
	for (int i = 0; i < n; i++)
		if (json_array_append_new(a, jnum(v[(size_t)i * stride])) != 0)
			w->bad = 1;
	return a;
}

/* rows x cols, element (r, c) at v[r * rs + c * cs]. */
static json_t *jmat(jw *w, const double *v, int rows, int cols, int rs, int cs)
{
	json_t *a = json_array();
	if (!a) {
		w->bad = 1;
		return NULL;
	}
	for (int r = 0; r < rows; r++)
		if (json_array_append_new(a, jrow(w, v + (size_t)r * rs, cols, cs)) != 0)
			w->bad = 1;
	return a;
}

/* 1 when a string from outside kogei (a path, a file's patch id or keyword) is UTF-8;
 * else 0, remembered with `what` it is. */
static int text_ok(jw *w, const char *what, const char *s)
{
	size_t n = strlen(s), bad = kg_utf8_invalid_at(s, n);
	if (bad == n)
		return 1;
	if (!w->text_what[0]) {
		snprintf(w->text_what, sizeof(w->text_what), "%s", what);
		w->text_offset = bad;
		w->text_byte = (unsigned char)s[bad];
	}
	w->bad = 1;
	return 0;
}

static json_t *jtext(jw *w, const char *what, const char *s)
{
	return text_ok(w, what, s) ? json_string(s) : NULL;
}

static json_t *jstrv(jw *w, const char *what, char *const *v, int n)
{
	json_t *a = json_array();
	if (!a) {
		w->bad = 1;
		return NULL;
	}
	for (int i = 0; i < n; i++)
		if (json_array_append_new(a, jtext(w, what, v[i])) != 0)
			w->bad = 1;
	return a;
}

static int get_flagged(const char *file, const json_t *root, const char *key, int *nflagged,
                       char ***ids, unsigned **flags, kg_err *err);

/* Patches left out because chart detection flagged them: [{id, flags}]. */
static json_t *jflagged(jw *w, int n, char *const *ids, const unsigned *flags)
{
	json_t *a = json_array();
	for (int i = 0; a && i < n; i++)
		if (json_array_append_new(a, json_pack("{s:s, s:i}", "id", ids[i], "flags",
		                                       (int)flags[i])))
			w->bad = 1;
	return a;
}

static json_t *jgrid(jw *w)
{
	json_t *g = json_object();
	put(w, g, "start_nm", json_real(KG_LAMBDA_MIN));
	put(w, g, "step_nm", json_real(KG_LAMBDA_STEP));
	put(w, g, "bands", json_integer(KG_NBANDS));
	return g;
}

static json_t *jterms(jw *w, kg_method m)
{
	json_t *a = json_array();
	for (int t = 0; a && t < kg_method_nterms(m); t++)
		if (json_array_append_new(a, json_string(kg_method_term_name(m, t))) != 0)
			w->bad = 1;
	if (!a)
		w->bad = 1;
	return a;
}

static json_t *jsources(jw *w, const kg_calib_source *s, int n)
{
	json_t *a = json_array();
	for (int i = 0; a && i < n; i++) {
		json_t *o = json_object(), *kw = json_object();
		put(w, o, "role", json_string(s[i].role));
		char what[96];
		snprintf(what, sizeof(what), "the path of the %.40s file", s[i].role);
		put(w, o, "path", jtext(w, what, s[i].path));
		put(w, o, "sha256", s[i].sha256[0] ? json_string(s[i].sha256) : json_null());
		for (int k = 0; kw && k < s[i].nkeywords; k++)
			if (text_ok(w, "a keyword's name in an input file", s[i].keyword_names[k]))
				put(w, kw, s[i].keyword_names[k],
				    jtext(w, "a keyword's value in an input file", s[i].keyword_values[k]));
		put(w, o, "keywords", kw);
		if (json_array_append_new(a, o) != 0)
			w->bad = 1;
	}
	if (!a)
		w->bad = 1;
	return a;
}

/* The first value of any of the keyword names among the sources, or NULL. */
static const char *source_keyword(const kg_calib_source *s, int n, const char *role,
                                  const char *const *names)
{
	for (int i = 0; i < n; i++) {
		if (role && strcmp(s[i].role, role) != 0)
			continue;
		for (int j = 0; names[j]; j++)
			for (int k = 0; k < s[i].nkeywords; k++)
				if (strcmp(s[i].keyword_names[k], names[j]) == 0)
					return s[i].keyword_values[k];
	}
	return NULL;
}

static const char *const device_keywords[] = {"INSTRUMENTATION", "DEVICE", "CAMERA",
                                              "MANUFACTURER", "MODEL", NULL};
static const char *const illuminant_keywords[] = {"ILLUMINANT", "ILLUMINATION_NAME",
                                                  "LIGHT_SOURCE", NULL};

static json_t *jdevices(jw *w, const kg_calib_source *s, int n)
{
	json_t *o = json_object();
	for (int i = 0; o && i < n; i++) {
		const char *v = source_keyword(s, n, s[i].role, device_keywords);
		if (v)
			put(w, o, s[i].role, jtext(w, "a keyword's value in an input file", v));
	}
	if (!o)
		w->bad = 1;
	return o;
}

/* How two files' patches were paired; unpaired ids under the files' roles. */
static json_t *jpairing(jw *w, const kg_pairing_record *rec, const char *alias,
                        const char *first, const char *second)
{
	json_t *o = json_object(), *un = json_object();
	char rule[64];
	kg_id_pairing_name(rec->rule, first, second, rule, sizeof(rule));
	put(w, o, "rule", json_string(rule));
	put(w, o, "aliases", alias[0] ? json_string(alias) : json_null());
	put(w, o, "pairs", json_integer(rec->pairs));
	put(w, o, "checked", json_integer(rec->checked));
	put(w, o, "misfit", jnum(rec->misfit));
	put(w, o, "misfit_limit", json_real(KG_CALIB_PAIR_MAX_MISFIT));
	put(w, un, first, jstrv(w, "a patch id", rec->unpaired[0], rec->nunpaired[0]));
	put(w, un, second, jstrv(w, "a patch id", rec->unpaired[1], rec->nunpaired[1]));
	put(w, o, "unpaired", un);
	return o;
}

/* A chart's flare (calib/flare.c): null when it could not be measured. */
static json_t *jflare(jw *w, const kg_flare *f)
{
	if (!f->found)
		return json_null();
	json_t *o = json_object(), *ids = json_array();
	for (int i = 0; i < f->n; i++)
		json_array_append_new(ids, json_string(f->ids[i]));
	put(w, o, "neutrals", ids);
	put(w, o, "offset", jrow(w, f->offset, 3, 1));
	put(w, o, "slope", jrow(w, f->slope, 3, 1));
	put(w, o, "white_fraction", jrow(w, f->white_fraction, 3, 1));
	put(w, o, "residual", jrow(w, f->residual, 3, 1));
	return o;
}

static json_t *jflare_record(jw *w, const kg_reference *ref)
{
	json_t *o = json_object();
	put(w, o, "training", jflare(w, &ref->flare));
	put(w, o, "field", jflare(w, &ref->field_flare));
	put(w, o, "removed", json_boolean(ref->flare_removed));
	put(w, o, "loo_de00_kept", jnum(ref->flare_loo_kept));
	put(w, o, "loo_de00_removed", jnum(ref->flare_loo_removed));
	put(w, o, "description",
	    json_string("flare (veiling glare) from the neutral patches: camera value = offset + "
	                "slope Y per channel; white_fraction = offset / slope; removed: "
	                "subtracted from the training RGB and rho0 before the fit because the "
	                "chosen method's leave-one-out dE00 was lower"));
	return o;
}

/* The neutral prior (kg_reference's neutral_*), or null when no tilt was measured. */
static json_t *jneutral(jw *w, const kg_reference *ref)
{
	if (!isfinite(ref->neutral_white[0]))
		return json_null();
	json_t *o = json_object();
	put(w, o, "white", jrow(w, ref->neutral_white, 3, 1));
	put(w, o, "white_source", json_string(ref->neutral_white_source));
	put(w, o, "added", json_boolean(ref->neutral_prior));
	put(w, o, "weight", json_integer(ref->neutral_weight));
	put(w, o, "tilt_before", jnum(ref->neutral_tilt_before));
	put(w, o, "method_before", json_string(kg_method_name(ref->neutral_method_before)));
	put(w, o, "loo_de00_before", jnum(ref->neutral_loo_before));
	put(w, o, "tilt", jnum(ref->maps[ref->method].neutral_tilt));
	put(w, o, "description",
	    json_string("white: the camera's value of the perfect diffuser (white_source "
	                "neutrals: the line through the chart's neutral patches at Y = 1; "
	                "response: the learned response's reading of a flat 1), a flat grey t "
	                "reading t white; tilt: the chosen method's largest relative departure "
	                "from flat for such greys. added: without neutral patches and with a "
	                "tilt above 5 % (tilt_before), flat greys (0.05, 0.2, 0.5, 0.9) each "
	                "counted weight times joined the fit; the chart's own patches validate "
	                "every method"));
	return o;
}

static int finish(jw *w, json_t *root, const char *path, kg_err *err)
{
	int ret;
	if (w->text_what[0])
		ret = kg_fail(err, KG_EINVAL, "%s: not written: %s is not UTF-8 text (byte 0x%02X at "
		              "offset %zu): expected UTF-8, which JSON holds", path, w->text_what,
		              w->text_byte, w->text_offset);
	else
		ret = w->bad || !root ? kg_fail(err, KG_ENOMEM, "%s: out of memory building JSON", path)
		                      : kg_json_write(root, path, err);
	json_decref(root);
	return ret;
}

/* The methods object: per method its map and validation. `pre` is NULL for a
 * reference (the maps take reference-camera RGB). */
static json_t *jmap(jw *w, kg_method m, int available, const char *note, int T,
                    const double *A, const double *offset, const double *pre, double lambda,
                    double cond, double fit_rmse, double loo_rmse, double loo_de00)
{
	json_t *o = json_object();
	put(w, o, "available", json_boolean(available));
	if (!available) {
		put(w, o, "note", json_string(note ? note : ""));
		return o;
	}
	put(w, o, "terms", jterms(w, m));
	put(w, o, m == KG_METHOD_WIENER ? "lambda_m_sigma2" : "ridge", jnum(lambda));
	if (pre)
		put(w, o, "pre", jmat(w, pre, 3, 3, 3, 1));
	put(w, o, "A", jmat(w, A, NB, T, T, 1));
	put(w, o, "offset", jrow(w, offset, NB, 1));
	if (!isnan(cond))
		put(w, o, "condition_number", jnum(cond));
	if (!isnan(fit_rmse))
		put(w, o, "fit_rmse", jnum(fit_rmse));
	put(w, o, "loo_rmse", jnum(loo_rmse));
	if (!isnan(loo_de00))
		put(w, o, "loo_de00", jnum(loo_de00));
	return o;
}

static double mean_of(const double *v, int n)
{
	double s = 0;
	for (int i = 0; i < n; i++)
		s += v[i];
	return n ? s / n : NAN;
}

static double max_of(const double *v, int n)
{
	double s = n ? v[0] : NAN;
	for (int i = 1; i < n; i++)
		s = fmax(s, v[i]);
	return s;
}

/* The PCA model shared by both formats. */
static void put_pca(jw *w, json_t *root, int K, int centred, const double *B,
                    const double *mean, const double *M, const double *rgb_mean)
{
	put(w, root, "K", json_integer(K));
	put(w, root, "centred", json_boolean(centred));
	put(w, root, "B", jmat(w, B, NB, K, K, 1));
	if (centred) {
		put(w, root, "mean", jrow(w, mean, NB, 1));
		put(w, root, "rgb_mean", jrow(w, rgb_mean, 3, 1));
	}
	put(w, root, "M", jmat(w, M, K, 3, 3, 1));
}

/* The reference camera's response, or null. */
static json_t *jresponse(jw *w, const kg_response *r)
{
	if (!r->available)
		return json_null();
	json_t *o = json_object();
	put(w, o, "source", jtext(w, "the response's source", r->source));
	put(w, o, "patches", json_integer(r->patches));
	put(w, o, "F", jmat(w, &r->F[0][0], 3, NB, NB, 1));
	put(w, o, "lambda", jrow(w, r->lambda, 3, 1));
	put(w, o, "loo_rmse", jrow(w, r->loo_rmse, 3, 1));
	put(w, o, "loo_relative", jnum(r->loo_relative));
	return o;
}

int kg_reference_save(const kg_reference *ref, const char *path, kg_err *err)
{
	kg_check_arg(ref && path, err);
	jw w = {0};
	json_t *root = json_object();
	put(&w, root, "format", json_string(REFERENCE_FORMAT));
	put(&w, root, "software", json_string("kogei " KG_VERSION));
	put(&w, root, "grid", jgrid(&w));
	put(&w, root, "method", json_string(kg_method_name(ref->method)));
	put(&w, root, "method_chosen_by",
	    json_string(ref->method_auto ? "leave-one-out" : "option"));
	put(&w, root, "K_chosen_by", json_string(ref->basis_auto ? "leave-one-out" : "option"));
	put_pca(&w, root, ref->K, ref->centred, ref->B, ref->mean, ref->M, ref->rgb_mean);
	put(&w, root, "ridge", jnum(ref->ridge));
	put(&w, root, "noise_sigma", jnum(ref->noise_sigma));
	int nsv = ref->m < KG_CALIB_MAX_BASIS ? ref->m : KG_CALIB_MAX_BASIS;
	if (nsv < ref->K)
		nsv = ref->K;
	put(&w, root, "singular_values", jrow(&w, ref->singular_values, nsv, 1));
	put(&w, root, "energy", jrow(&w, ref->energy, nsv, 1));

	json_t *methods = json_object();
	for (int j = 0; j < KG_METHOD_COUNT; j++) {
		const kg_spectral_map *mp = &ref->maps[j];
		json_t *jm = jmap(&w, (kg_method)j, mp->available, mp->note, mp->nterms, mp->A,
		                  mp->offset, NULL, mp->lambda, mp->cond, mp->fit_rmse, mp->loo_rmse,
		                  mp->loo_de00);
		if (mp->available && isfinite(mp->loo_band[0]))
			put(&w, jm, "loo_band_rmse", jrow(&w, mp->loo_band, NB, 1));
		if (mp->available && isfinite(mp->neutral_tilt))
			put(&w, jm, "neutral_tilt", json_real(mp->neutral_tilt));
		put(&w, methods, kg_method_name((kg_method)j), jm);
	}
	put(&w, root, "methods", methods);

	json_t *val = json_object(), *bym = json_object();
	put(&w, val, "loo_rmse_by_K", jrow(&w, ref->loo_by_K, ref->nK, 1));
	for (int j = 0; j < KG_METHOD_COUNT; j++)
		put(&w, bym, kg_method_name((kg_method)j),
		    jnum(ref->maps[j].available ? ref->maps[j].loo_rmse : NAN));
	put(&w, val, "loo_rmse_by_method", bym);
	put(&w, root, "validation", val);

	json_t *tr = json_object();
	put(&w, tr, "patches", json_integer(ref->m));
	put(&w, tr, "ids", jstrv(&w, "a patch id", ref->ids, ref->m));
	put(&w, tr, "rho", jmat(&w, &ref->train_rgb[0][0], ref->m, 3, 3, 1));
	put(&w, tr, "rmse", jrow(&w, ref->rmse, ref->m, 1));
	put(&w, tr, "gfc", jrow(&w, ref->gfc, ref->m, 1));
	put(&w, tr, "de00_d65", jrow(&w, ref->de00, ref->m, 1));
	put(&w, tr, "projection_rmse", jrow(&w, ref->projection_rmse, ref->m, 1));
	put(&w, tr, "weight_residual", jrow(&w, ref->weight_residual, ref->m, 1));
	put(&w, tr, "mean_rmse", jnum(mean_of(ref->rmse, ref->m)));
	put(&w, tr, "mean_de00_d65", jnum(mean_of(ref->de00, ref->m)));
	put(&w, tr, "max_de00_d65", jnum(max_of(ref->de00, ref->m)));
	put(&w, tr, "condition_number_rho", jnum(ref->cond_rho));
	put(&w, root, "training", tr);

	json_t *field = json_object();
	put(&w, field, "ids", jstrv(&w, "a patch id", ref->field_ids, ref->k));
	put(&w, field, "rho0", jmat(&w, &ref->rho0[0][0], 3, ref->k, 1, 3));
	put(&w, field, "condition_number", jnum(ref->cond_rho0));
	put(&w, field, "flagged", jflagged(&w, ref->nflagged, ref->flagged_ids,
	                                   ref->flagged_flags));
	put(&w, root, "field", field);
	put(&w, root, "response", jresponse(&w, &ref->response));
	if (ref->pairing.pairs)
		put(&w, root, "pairing", jpairing(&w, &ref->pairing, ref->id_rule, "spectra", "rgb"));
	put(&w, root, "flare", jflare_record(&w, ref));
	put(&w, root, "neutral_prior", jneutral(&w, ref));

	put(&w, root, "devices", jdevices(&w, ref->sources, ref->nsources));
	const char *ill = source_keyword(ref->sources, ref->nsources, NULL, illuminant_keywords);
	put(&w, root, "illuminant",
	    ill ? jtext(&w, "a keyword's value in an input file", ill) : json_null());
	put(&w, root, "sources", jsources(&w, ref->sources, ref->nsources));
	return finish(&w, root, path, err);
}

int kg_camera_save(const kg_camera_calib *cam, const char *path, kg_err *err)
{
	kg_check_arg(cam && path, err);
	jw w = {0};
	json_t *root = json_object();
	put(&w, root, "format", json_string(CAMERA_FORMAT));
	put(&w, root, "software", json_string("kogei " KG_VERSION));
	put(&w, root, "grid", jgrid(&w));
	json_t *refo = json_object();
	for (int i = 0; i < cam->nsources; i++)
		if (strcmp(cam->sources[i].role, "reference") == 0) {
			put(&w, refo, "path", jtext(&w, "the path of the reference file", cam->sources[i].path));
			put(&w, refo, "sha256", json_string(cam->sources[i].sha256));
		}
	put(&w, root, "reference", refo);
	put(&w, root, "method", json_string(kg_method_name(cam->method)));
	put_pca(&w, root, cam->K, cam->centred, cam->B, cam->mean, cam->M, cam->rgb_mean);
	put(&w, root, "M2", jmat(&w, cam->M2, 3, 3, 3, 1));
	const kg_site_map *pca = &cam->maps[KG_METHOD_PCA];
	put(&w, root, "A", jmat(&w, pca->A, NB, 3, 3, 1));
	put(&w, root, "offset", jrow(&w, pca->offset, NB, 1));

	json_t *methods = json_object();
	for (int j = 0; j < KG_METHOD_COUNT; j++) {
		const kg_site_map *mp = &cam->maps[j];
		put(&w, methods, kg_method_name((kg_method)j),
		    jmap(&w, (kg_method)j, mp->available, "not available on the reference chart",
		         mp->nterms, mp->A, mp->offset, mp->pre, mp->lambda, NAN, NAN, mp->loo_rmse,
		         NAN));
	}
	put(&w, root, "methods", methods);

	json_t *fit = json_object();
	put(&w, fit, "patches", json_integer(cam->k));
	put(&w, fit, "ids", jstrv(&w, "a patch id", cam->ids, cam->k));
	put(&w, fit, "rho_r", jmat(&w, &cam->rho_r[0][0], 3, cam->k, 1, 3));
	put(&w, fit, "rho0", jmat(&w, &cam->rho0[0][0], 3, cam->k, 1, 3));
	put(&w, fit, "residual", jmat(&w, &cam->residual[0][0], 3, cam->k, 1, 3));
	put(&w, fit, "residual_rms", jnum(cam->residual_rms));
	put(&w, fit, "residual_relative", jnum(cam->residual_relative));
	put(&w, fit, "condition_number", jnum(cam->cond));
	put(&w, fit, "condition_number_equilibrated", jnum(cam->cond_equilibrated));
	put(&w, fit, "singular_values", jrow(&w, cam->singular_values, 3, 1));
	put(&w, fit, "rank", json_integer(cam->rank));
	put(&w, fit, "flagged", jflagged(&w, cam->nflagged, cam->flagged_ids, cam->flagged_flags));
	if (cam->pairing.pairs)
		put(&w, fit, "pairing", jpairing(&w, &cam->pairing, cam->id_rule, "reference", "rgb"));
	put(&w, fit, "flare", jflare(&w, &cam->flare));
	put(&w, fit, "flare_removed", json_boolean(cam->flare_removed));
	put(&w, root, "site", fit);
	put(&w, root, "response", jresponse(&w, &cam->response));
	const kg_camera_identity *id = &cam->identity;
	put(&w, root, "camera",
	    id->known ? json_pack("{s:s, s:s, s:s, s:s, s:I, s:s, s:s}", "backend", id->backend,
	                          "model", id->model, "serial", id->serial, "pixfmt", id->pixfmt,
	                          "white_level", (json_int_t)id->white_level, "demosaic",
	                          id->demosaic, "capture", id->capture)
	              : json_null());
	put(&w, root, "devices", jdevices(&w, cam->sources, cam->nsources));
	put(&w, root, "sources", jsources(&w, cam->sources, cam->nsources));
	return finish(&w, root, path, err);
}

/* ---- reading ------------------------------------------------------------------ */

/* A number or null (NAN). */
static int get_num_or_null(const char *file, const json_t *root, const char *path,
                           double *out, kg_err *err)
{
	json_t *v = kg_json_find(root, path);
	if (v && json_is_null(v)) {
		*out = NAN;
		return 0;
	}
	return kg_json_get_number(file, root, path, out, err);
}

/* An array of numbers or nulls of exactly n entries. */
static int get_row(const char *file, const json_t *root, const char *path, int n,
                   double *out, kg_err *err)
{
	json_t *a = NULL;
	int ret = kg_json_get(file, root, path, &a, err);
	if (ret)
		return ret;
	if (!json_is_array(a) || (int)json_array_size(a) != n)
		return kg_fail(err, KG_EINVAL, "%s: %s: expected an array of %d numbers", file, path, n);
	for (int i = 0; i < n; i++) {
		json_t *v = json_array_get(a, (size_t)i);
		if (json_is_null(v))
			out[i] = NAN;
		else if (json_is_number(v))
			out[i] = json_number_value(v);
		else
			return kg_fail(err, KG_EINVAL, "%s: %s[%d]: expected a number", file, path, i);
	}
	return 0;
}

/* A rows x cols matrix into v with element (r, c) at v[r * rs + c * cs]. */
static int get_mat(const char *file, const json_t *root, const char *path, int rows, int cols,
                   double *v, int rs, int cs, kg_err *err)
{
	kg_mat *m = NULL;
	int ret = kg_json_get_matrix(file, root, path, rows, cols, &m, err);
	if (ret)
		return ret;
	for (int r = 0; r < rows; r++)
		for (int c = 0; c < cols; c++)
			v[(size_t)r * rs + (size_t)c * cs] = m->a[r * cols + c];
	kg_mat_free(&m);
	return 0;
}

static int get_strv(const char *file, const json_t *root, const char *path, int n,
                    char ***out, kg_err *err)
{
	json_t *a = NULL;
	int ret = kg_json_get(file, root, path, &a, err);
	if (ret)
		return ret;
	if (!json_is_array(a) || (int)json_array_size(a) != n)
		return kg_fail(err, KG_EINVAL, "%s: %s: expected an array of %d strings", file, path, n);
	char **v = calloc(n > 0 ? (size_t)n : 1, sizeof(char *));
	if (!v)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (int i = 0; i < n; i++) {
		json_t *s = json_array_get(a, (size_t)i);
		if (!json_is_string(s)) {
			calib_strv_free(v, n);
			return kg_fail(err, KG_EINVAL, "%s: %s[%d]: expected a string", file, path, i);
		}
		if (!(v[i] = strdup(json_string_value(s)))) {
			calib_strv_free(v, n);
			return kg_fail(err, KG_ENOMEM, "out of memory");
		}
	}
	*out = v;
	return 0;
}

static int get_bool(const char *file, const json_t *root, const char *path, int *out,
                    kg_err *err)
{
	json_t *v = NULL;
	int ret = kg_json_get(file, root, path, &v, err);
	if (ret)
		return ret;
	if (!json_is_boolean(v))
		return kg_fail(err, KG_EINVAL, "%s: %s: expected true or false", file, path);
	*out = json_is_true(v);
	return 0;
}

/* The length of an array at path (KG_EINVAL when it is not one). */
static int get_len(const char *file, const json_t *root, const char *path, int *n,
                   kg_err *err)
{
	json_t *a = NULL;
	int ret = kg_json_get(file, root, path, &a, err);
	if (ret)
		return ret;
	if (!json_is_array(a))
		return kg_fail(err, KG_EINVAL, "%s: %s: expected an array", file, path);
	*n = (int)json_array_size(a);
	return 0;
}

static int check_header(const char *file, const json_t *root, const char *format,
                        kg_err *err)
{
	const char *f = NULL;
	int ret = kg_json_get_string(file, root, "format", &f, err);
	if (ret)
		return ret;
	if (strcmp(f, format) != 0)
		return kg_fail(err, KG_EINVAL, "%s: format: \"%s\"; expected \"%s\"", file, f, format);
	double start, step;
	long bands;
	ret = kg_json_get_number(file, root, "grid.start_nm", &start, err);
	if (!ret)
		ret = kg_json_get_number(file, root, "grid.step_nm", &step, err);
	if (!ret)
		ret = kg_json_get_int(file, root, "grid.bands", 1, 100000, &bands, err);
	if (ret)
		return ret;
	if (start != KG_LAMBDA_MIN || step != KG_LAMBDA_STEP || bands != KG_NBANDS)
		return kg_fail(err, KG_EINVAL,
		               "%s: grid: %g nm + %g nm x %ld bands; expected 400 nm + 5 nm x 61 bands",
		               file, start, step, bands);
	return 0;
}

static int get_method(const char *file, const json_t *root, kg_method *m, kg_err *err)
{
	const char *name = NULL;
	int ret = kg_json_get_string(file, root, "method", &name, err);
	if (!ret)
		ret = kg_method_parse(name, m, err);
	if (!ret && *m == KG_METHOD_AUTO)
		ret = kg_fail(err, KG_EINVAL, "%s: method: expected a fitted method, not auto", file);
	if (ret)
		kg_err_prefix(err, "%s", file);
	return ret;
}

static int get_pca(const char *file, const json_t *root, int *K, int *centred, double *B,
                   double *mean, double *M, double *rgb_mean, kg_err *err)
{
	long k = 0;
	int ret = kg_json_get_int(file, root, "K", 1, KG_CALIB_MAX_BASIS, &k, err);
	if (!ret)
		ret = get_bool(file, root, "centred", centred, err);
	if (!ret)
		ret = get_mat(file, root, "B", NB, (int)k, B, (int)k, 1, err);
	if (!ret)
		ret = get_mat(file, root, "M", (int)k, 3, M, 3, 1, err);
	if (!ret && *centred)
		ret = kg_json_get_numbers(file, root, "mean", NB, mean, err);
	if (!ret && *centred)
		ret = kg_json_get_numbers(file, root, "rgb_mean", 3, rgb_mean, err);
	*K = (int)k;
	return ret;
}

/* One entry of "methods": availability, A, offset and (site) pre. */
static int get_map(const char *file, const json_t *root, kg_method m, int *available,
                   char *note, size_t notelen, double *A, double *offset, double *pre,
                   double *lambda, double *loo, kg_err *err)
{
	char key[128];
	const char *name = kg_method_name(m);
	int T = kg_method_nterms(m);
	snprintf(key, sizeof(key), "methods.%s.available", name);
	int ret = get_bool(file, root, key, available, err);
	if (ret || !*available) {
		snprintf(key, sizeof(key), "methods.%s.note", name);
		json_t *n = kg_json_find(root, key);
		if (note && n && json_is_string(n))
			snprintf(note, notelen, "%s", json_string_value(n));
		return ret;
	}
	snprintf(key, sizeof(key), "methods.%s.A", name);
	ret = get_mat(file, root, key, NB, T, A, T, 1, err);
	if (!ret) {
		snprintf(key, sizeof(key), "methods.%s.offset", name);
		ret = kg_json_get_numbers(file, root, key, NB, offset, err);
	}
	if (!ret && pre) {
		snprintf(key, sizeof(key), "methods.%s.pre", name);
		ret = get_mat(file, root, key, 3, 3, pre, 3, 1, err);
	}
	if (!ret) {
		snprintf(key, sizeof(key), "methods.%s.%s", name,
		         m == KG_METHOD_WIENER ? "lambda_m_sigma2" : "ridge");
		ret = get_num_or_null(file, root, key, lambda, err);
	}
	if (!ret) {
		snprintf(key, sizeof(key), "methods.%s.loo_rmse", name);
		ret = get_num_or_null(file, root, key, loo, err);
	}
	return ret;
}

static int get_sources(const char *file, const json_t *root, kg_calib_source **out,
                       int *nout, kg_err *err)
{
	json_t *a = kg_json_find(root, "sources");
	if (!a)
		return 0;
	if (!json_is_array(a))
		return kg_fail(err, KG_EINVAL, "%s: sources: expected an array", file);
	int n = (int)json_array_size(a);
	kg_calib_source *s = calloc(n > 0 ? (size_t)n : 1, sizeof(*s));
	if (!s)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	*out = s;
	*nout = n;
	for (int i = 0; i < n; i++) {
		json_t *o = json_array_get(a, (size_t)i);
		json_t *role = json_object_get(o, "role"), *path = json_object_get(o, "path");
		json_t *sha = json_object_get(o, "sha256"), *kw = json_object_get(o, "keywords");
		if (!json_is_string(role) || !json_is_string(path))
			return kg_fail(err, KG_EINVAL, "%s: sources[%d]: expected role and path strings",
			               file, i);
		s[i].role = strdup(json_string_value(role));
		s[i].path = strdup(json_string_value(path));
		if (json_is_string(sha))
			snprintf(s[i].sha256, sizeof(s[i].sha256), "%s", json_string_value(sha));
		int nk = json_is_object(kw) ? (int)json_object_size(kw) : 0;
		s[i].keyword_names = calloc(nk > 0 ? (size_t)nk : 1, sizeof(char *));
		s[i].keyword_values = calloc(nk > 0 ? (size_t)nk : 1, sizeof(char *));
		if (!s[i].role || !s[i].path || !s[i].keyword_names || !s[i].keyword_values)
			return kg_fail(err, KG_ENOMEM, "out of memory");
		const char *key;
		json_t *val;
		int k = 0;
		if (nk)
			json_object_foreach(kw, key, val)
			{
				if (!json_is_string(val))
					return kg_fail(err, KG_EINVAL, "%s: sources[%d].keywords.%s: expected a string",
					               file, i, key);
				s[i].keyword_names[k] = strdup(key);
				s[i].keyword_values[k] = strdup(json_string_value(val));
				s[i].nkeywords = ++k;
				if (!s[i].keyword_names[k - 1] || !s[i].keyword_values[k - 1])
					return kg_fail(err, KG_ENOMEM, "out of memory");
			}
	}
	return 0;
}

/* "response": absent or null (a file from before it existed) leaves it unavailable. */
static int get_response(const char *file, const json_t *root, kg_response *r, kg_err *err)
{
	memset(r, 0, sizeof(*r));
	json_t *o = json_object_get(root, "response");
	if (!o || json_is_null(o))
		return 0;
	const char *src = NULL;
	double patches = 0;
	int ret = kg_json_get_string(file, root, "response.source", &src, err);
	if (!ret)
		ret = kg_json_get_number(file, root, "response.patches", &patches, err);
	if (!ret)
		ret = get_mat(file, root, "response.F", 3, NB, &r->F[0][0], NB, 1, err);
	if (!ret)
		ret = get_row(file, root, "response.lambda", 3, r->lambda, err);
	if (!ret)
		ret = get_row(file, root, "response.loo_rmse", 3, r->loo_rmse, err);
	if (!ret)
		ret = get_num_or_null(file, root, "response.loo_relative", &r->loo_relative, err);
	if (ret)
		return ret;
	for (int c = 0; c < 3; c++)
		for (int l = 0; l < NB; l++)
			if (!isfinite(r->F[c][l]))
				return kg_fail(err, KG_EINVAL, "%s: response.F[%d][%d]: expected a finite "
				               "number", file, c, l);
	snprintf(r->source, sizeof(r->source), "%s", src);
	r->patches = (int)patches;
	r->available = 1;
	return 0;
}

/* An array of strings at path (its length in *n). */
static int get_strv_any(const char *file, const json_t *root, const char *path, char ***out,
                        int *n, kg_err *err)
{
	int ret = get_len(file, root, path, n, err);
	return ret ? ret : get_strv(file, root, path, *n, out, err);
}

/* pairing (at path), optional: how two files' patches were paired. */
/* A flare as jflare wrote it (absent or null: not found). */
static int get_flare(const char *file, const json_t *root, const char *path, kg_flare *f,
                     kg_err *err)
{
	memset(f, 0, sizeof(*f));
	const json_t *o = kg_json_find(root, path);
	if (!o || json_is_null(o))
		return 0;
	char key[96];
	const struct {
		const char *name;
		double *v;
	} rows[] = {{"offset", f->offset},
	            {"slope", f->slope},
	            {"white_fraction", f->white_fraction},
	            {"residual", f->residual}};
	for (size_t r = 0; r < sizeof(rows) / sizeof(rows[0]); r++) {
		snprintf(key, sizeof(key), "%s.%s", path, rows[r].name);
		int ret = kg_json_get_numbers(file, root, key, 3, rows[r].v, err);
		if (ret)
			return ret;
	}
	snprintf(key, sizeof(key), "%s.neutrals", path);
	const json_t *ids = kg_json_find(root, key);
	size_t i;
	const json_t *id;
	json_array_foreach(ids, i, id)
	{
		if (!json_is_string(id) || f->n >= KG_FLARE_MAX_NEUTRALS)
			return kg_fail(err, KG_EINVAL, "%s: key '%s[%zu]': expected a patch id (at most "
			               "%d)", file, key, i, KG_FLARE_MAX_NEUTRALS);
		snprintf(f->ids[f->n++], sizeof(f->ids[0]), "%s", json_string_value(id));
	}
	f->found = 1;
	return 0;
}

static int get_flare_record(const char *file, const json_t *root, kg_reference *ref,
                            kg_err *err)
{
	ref->flare_loo_kept = ref->flare_loo_removed = NAN;
	if (!kg_json_find(root, "flare"))
		return 0; /* files of earlier versions */
	int ret = get_flare(file, root, "flare.training", &ref->flare, err);
	if (!ret)
		ret = get_flare(file, root, "flare.field", &ref->field_flare, err);
	const json_t *rm = kg_json_find(root, "flare.removed");
	if (!ret && !json_is_boolean(rm))
		ret = kg_fail(err, KG_EINVAL, "%s: key 'flare.removed': expected true or false", file);
	if (!ret)
		ref->flare_removed = json_is_true(rm);
	if (!ret)
		ret = get_num_or_null(file, root, "flare.loo_de00_kept", &ref->flare_loo_kept, err);
	if (!ret)
		ret = get_num_or_null(file, root, "flare.loo_de00_removed", &ref->flare_loo_removed,
		                      err);
	return ret;
}

/* The neutral prior's record (absent or null: none). */
static int get_neutral(const char *file, const json_t *root, kg_reference *ref, kg_err *err)
{
	ref->neutral_tilt_before = ref->neutral_loo_before = NAN;
	ref->neutral_white[0] = ref->neutral_white[1] = ref->neutral_white[2] = NAN;
	ref->neutral_method_before = ref->method;
	const json_t *np = kg_json_find(root, "neutral_prior");
	if (!np || json_is_null(np))
		return 0;
	int r0 = kg_json_get_numbers(file, root, "neutral_prior.white", 3, ref->neutral_white, err);
	if (r0)
		return r0;
	const json_t *src = kg_json_find(root, "neutral_prior.white_source");
	if (!json_is_string(src) || (strcmp(json_string_value(src), "neutrals") &&
	                             strcmp(json_string_value(src), "response")))
		return kg_fail(err, KG_EINVAL, "%s: key 'neutral_prior.white_source': expected "
		               "\"neutrals\" or \"response\"", file);
	snprintf(ref->neutral_white_source, sizeof(ref->neutral_white_source), "%s",
	         json_string_value(src));
	const json_t *added = kg_json_find(root, "neutral_prior.added");
	if (!json_is_boolean(added))
		return kg_fail(err, KG_EINVAL, "%s: key 'neutral_prior.added': expected true or false",
		               file);
	ref->neutral_prior = json_is_true(added);
	double wt = 0;
	int ret = get_num_or_null(file, root, "neutral_prior.weight", &wt, err);
	if (!ret && !(wt >= 0 && wt <= 1e6))
		ret = kg_fail(err, KG_EINVAL, "%s: key 'neutral_prior.weight': expected 0 to 1000000",
		              file);
	ref->neutral_weight = ret ? 0 : (int)wt;
	if (!ret)
		ret = get_num_or_null(file, root, "neutral_prior.tilt_before", &ref->neutral_tilt_before,
		                      err);
	if (!ret)
		ret = get_num_or_null(file, root, "neutral_prior.loo_de00_before",
		                      &ref->neutral_loo_before, err);
	const json_t *mb = kg_json_find(root, "neutral_prior.method_before");
	kg_err bad = {{0}};
	if (!ret && (!json_is_string(mb) ||
	             kg_method_parse(json_string_value(mb), &ref->neutral_method_before, &bad)))
		ret = kg_fail(err, KG_EINVAL, "%s: key 'neutral_prior.method_before': expected a "
		              "method name", file);
	return ret;
}

static int get_pairing(const char *file, const json_t *root, const char *path,
                       const char *first, const char *second, kg_pairing_record *rec,
                       char *alias, size_t alias_size, kg_err *err)
{
	kg_pairing_record_free(rec);
	if (!kg_json_find(root, path))
		return 0;
	char key[96];
	const char *rule = NULL;
	long pairs = 0, checked = 0;
	snprintf(key, sizeof(key), "%s.rule", path);
	int ret = kg_json_get_string(file, root, key, &rule, err);
	kg_err bad = {{0}};
	if (!ret && kg_id_pairing_parse(rule, first, second, &rec->rule, &bad))
		ret = kg_fail(err, KG_EINVAL, "%s: %s: %s", file, key, bad.msg);
	snprintf(key, sizeof(key), "%s.aliases", path);
	json_t *al = kg_json_find(root, key);
	if (json_is_string(al))
		snprintf(alias, alias_size, "%s", json_string_value(al));
	snprintf(key, sizeof(key), "%s.pairs", path);
	if (!ret)
		ret = kg_json_get_int(file, root, key, 0, 1 << 24, &pairs, err);
	snprintf(key, sizeof(key), "%s.checked", path);
	if (!ret)
		ret = kg_json_get_int(file, root, key, 0, 1 << 24, &checked, err);
	snprintf(key, sizeof(key), "%s.misfit", path);
	if (!ret)
		ret = get_num_or_null(file, root, key, &rec->misfit, err);
	const char *role[2] = {first, second};
	for (int s = 0; !ret && s < 2; s++) {
		snprintf(key, sizeof(key), "%s.unpaired.%s", path, role[s]);
		ret = get_strv_any(file, root, key, &rec->unpaired[s], &rec->nunpaired[s], err);
	}
	rec->pairs = (int)pairs;
	rec->checked = (int)checked;
	return ret;
}

static int load_reference(const char *file, const json_t *root, kg_reference *ref,
                          kg_err *err)
{
	int ret = check_header(file, root, REFERENCE_FORMAT, err);
	if (!ret)
		ret = get_method(file, root, &ref->method, err);
	if (!ret)
		ret = get_response(file, root, &ref->response, err);
	if (!ret)
		ret = get_pca(file, root, &ref->K, &ref->centred, ref->B, ref->mean, ref->M,
		              ref->rgb_mean, err);
	if (ret)
		return ret;
	const char *by = NULL;
	if (kg_json_get_string(file, root, "method_chosen_by", &by, NULL) == 0)
		ref->method_auto = strcmp(by, "leave-one-out") == 0;
	if (kg_json_get_string(file, root, "K_chosen_by", &by, NULL) == 0)
		ref->basis_auto = strcmp(by, "leave-one-out") == 0;
	ret = get_num_or_null(file, root, "ridge", &ref->ridge, err);
	if (!ret)
		ret = get_num_or_null(file, root, "noise_sigma", &ref->noise_sigma, err);
	int nsv = 0;
	if (!ret)
		ret = get_len(file, root, "singular_values", &nsv, err);
	if (!ret && (nsv > KG_CALIB_MAX_BASIS))
		ret = kg_fail(err, KG_EINVAL, "%s: singular_values: expected at most %d", file,
		              KG_CALIB_MAX_BASIS);
	if (!ret)
		ret = get_row(file, root, "singular_values", nsv, ref->singular_values, err);
	if (!ret)
		ret = get_row(file, root, "energy", nsv, ref->energy, err);
	for (int j = 0; !ret && j < KG_METHOD_COUNT; j++) {
		kg_spectral_map *mp = &ref->maps[j];
		char key[128];
		mp->method = (kg_method)j;
		mp->nterms = kg_method_nterms((kg_method)j);
		mp->cond = mp->fit_rmse = mp->loo_rmse = mp->loo_de00 = NAN;
		for (int l = 0; l < NB; l++)
			mp->loo_band[l] = NAN;
		ret = get_map(file, root, (kg_method)j, &mp->available, mp->note, sizeof(mp->note),
		              mp->A, mp->offset, NULL, &mp->lambda, &mp->loo_rmse, err);
		if (ret || !mp->available)
			continue;
		snprintf(key, sizeof(key), "methods.%s.condition_number", kg_method_name(mp->method));
		if (kg_json_find(root, key))
			ret = get_num_or_null(file, root, key, &mp->cond, err);
		snprintf(key, sizeof(key), "methods.%s.fit_rmse", kg_method_name(mp->method));
		if (!ret && kg_json_find(root, key))
			ret = get_num_or_null(file, root, key, &mp->fit_rmse, err);
		snprintf(key, sizeof(key), "methods.%s.loo_de00", kg_method_name(mp->method));
		if (!ret && kg_json_find(root, key))
			ret = get_num_or_null(file, root, key, &mp->loo_de00, err);
		snprintf(key, sizeof(key), "methods.%s.loo_band_rmse", kg_method_name(mp->method));
		if (!ret && kg_json_find(root, key)) /* files of earlier versions lack it */
			ret = kg_json_get_numbers(file, root, key, NB, mp->loo_band, err);
	}
	if (!ret && !ref->maps[ref->method].available)
		ret = kg_fail(err, KG_EINVAL, "%s: method: %s is marked unavailable in methods", file,
		              kg_method_name(ref->method));
	if (!ret)
		ret = get_len(file, root, "validation.loo_rmse_by_K", &ref->nK, err);
	if (!ret && ref->nK > KG_CALIB_MAX_BASIS)
		ret = kg_fail(err, KG_EINVAL, "%s: validation.loo_rmse_by_K: expected at most %d", file,
		              KG_CALIB_MAX_BASIS);
	for (int K = 0; K < KG_CALIB_MAX_BASIS; K++)
		ref->loo_by_K[K] = NAN;
	if (!ret)
		ret = get_row(file, root, "validation.loo_rmse_by_K", ref->nK, ref->loo_by_K, err);

	long m = 0, k = 0;
	if (!ret)
		ret = kg_json_get_int(file, root, "training.patches", 0, 1 << 24, &m, err);
	if (ret)
		return ret;
	ref->m = (int)m;
	ret = get_strv(file, root, "training.ids", ref->m, &ref->ids, err);
	if (ret)
		return ret;
	size_t sz = (m > 0 ? (size_t)m : 1);
	ref->train_rgb = malloc(sz * sizeof(*ref->train_rgb));
	ref->rmse = malloc(sz * sizeof(double));
	ref->gfc = malloc(sz * sizeof(double));
	ref->de00 = malloc(sz * sizeof(double));
	ref->projection_rmse = malloc(sz * sizeof(double));
	ref->weight_residual = malloc(sz * sizeof(double));
	if (!ref->train_rgb || !ref->rmse || !ref->gfc || !ref->de00 || !ref->projection_rmse ||
	    !ref->weight_residual)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	ret = get_mat(file, root, "training.rho", ref->m, 3, &ref->train_rgb[0][0], 3, 1, err);
	if (!ret)
		ret = get_row(file, root, "training.rmse", ref->m, ref->rmse, err);
	if (!ret)
		ret = get_row(file, root, "training.gfc", ref->m, ref->gfc, err);
	if (!ret)
		ret = get_row(file, root, "training.de00_d65", ref->m, ref->de00, err);
	if (!ret)
		ret = get_row(file, root, "training.projection_rmse", ref->m, ref->projection_rmse, err);
	if (!ret)
		ret = get_row(file, root, "training.weight_residual", ref->m, ref->weight_residual, err);
	if (!ret)
		ret = get_num_or_null(file, root, "training.condition_number_rho", &ref->cond_rho, err);

	if (!ret)
		ret = get_len(file, root, "field.ids", &ref->k, err);
	if (ret)
		return ret;
	k = ref->k;
	if (k < 3)
		return kg_fail(err, KG_EINVAL, "%s: field.ids: %ld patches; expected at least 3", file, k);
	ret = get_strv(file, root, "field.ids", ref->k, &ref->field_ids, err);
	if (ret)
		return ret;
	ref->rho0 = malloc((size_t)k * sizeof(*ref->rho0));
	if (!ref->rho0)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	ret = get_mat(file, root, "field.rho0", 3, ref->k, &ref->rho0[0][0], 1, 3, err);
	if (!ret)
		ret = get_num_or_null(file, root, "field.condition_number", &ref->cond_rho0, err);
	if (!ret)
		ret = get_flagged(file, root, "field.flagged", &ref->nflagged, &ref->flagged_ids,
		                  &ref->flagged_flags, err);
	if (!ret)
		ret = get_sources(file, root, &ref->sources, &ref->nsources, err);
	if (!ret)
		ret = get_pairing(file, root, "pairing", "spectra", "rgb", &ref->pairing, ref->id_rule,
		                  sizeof(ref->id_rule), err);
	if (!ret)
		ret = get_flare_record(file, root, ref, err);
	if (!ret)
		ret = get_neutral(file, root, ref, err);
	calib_reference_derive(ref);
	if (!ret && !isfinite(ref->neutral_white[0]) && ref->response.available) {
		/* files of earlier versions: the response's reading of a flat 1 */
		double one[NB];
		for (int l = 0; l < NB; l++)
			one[l] = 1;
		kg_response_apply(&ref->response, one, ref->neutral_white);
		snprintf(ref->neutral_white_source, sizeof(ref->neutral_white_source), "response");
	}
	for (int j = 0; j < KG_METHOD_COUNT; j++) /* derived, as when it was fitted */
		ref->maps[j].neutral_tilt = kg_spectral_map_neutral_tilt(&ref->maps[j],
		                                                         ref->neutral_white);
	return ret;
}

int kg_reference_load(const char *path, kg_reference **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	json_t *root = NULL;
	int ret = kg_json_load(path, &root, err);
	if (ret)
		return ret;
	kg_reference *ref = calloc(1, sizeof(*ref));
	ret = ref ? load_reference(path, root, ref, err) : kg_fail(err, KG_ENOMEM, "out of memory");
	json_decref(root);
	if (ret) {
		kg_reference_free(&ref);
		return ret;
	}
	*out = ref;
	return 0;
}

/* key (site.flagged, field.flagged), optional: [{id, flags}], the patches left out
 * because chart detection flagged them. */
static int get_flagged(const char *file, const json_t *root, const char *key, int *nflagged,
                       char ***ids, unsigned **flags, kg_err *err)
{
	json_t *a = kg_json_find(root, key);
	if (!a)
		return 0;
	if (!json_is_array(a))
		return kg_fail(err, KG_EINVAL, "%s: %s: expected an array", file, key);
	int n = (int)json_array_size(a);
	*ids = calloc(n > 0 ? (size_t)n : 1, sizeof(char *));
	*flags = calloc(n > 0 ? (size_t)n : 1, sizeof(unsigned));
	if (!*ids || !*flags)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (int i = 0; i < n; i++) {
		json_t *o = json_array_get(a, (size_t)i);
		json_t *id = json_object_get(o, "id"), *f = json_object_get(o, "flags");
		if (!json_is_string(id) || !json_is_integer(f) || json_integer_value(f) < 0)
			return kg_fail(err, KG_EINVAL, "%s: %s[%d]: expected {\"id\": a string, "
			               "\"flags\": a whole number >= 0}", file, key, i);
		if (!((*ids)[i] = strdup(json_string_value(id))))
			return kg_fail(err, KG_ENOMEM, "out of memory");
		(*flags)[i] = (unsigned)json_integer_value(f);
		*nflagged = i + 1;
	}
	return 0;
}

/* camera, optional: the site camera's identity (absent or null: unknown). */
static int get_identity(const char *file, const json_t *root, kg_camera_identity *id,
                        kg_err *err)
{
	memset(id, 0, sizeof(*id));
	json_t *o = kg_json_find(root, "camera");
	if (!o || json_is_null(o))
		return 0;
	if (!json_is_object(o))
		return kg_fail(err, KG_EINVAL, "%s: camera: expected an object or null", file);
	static const char *const keys[] = {"backend", "model", "serial", "pixfmt", "demosaic",
	                                   "capture"};
	char *dst[] = {id->backend, id->model, id->serial, id->pixfmt, id->demosaic, id->capture};
	size_t size[] = {sizeof(id->backend), sizeof(id->model),    sizeof(id->serial),
	                 sizeof(id->pixfmt),  sizeof(id->demosaic), sizeof(id->capture)};
	for (int k = 0; k < 6; k++) {
		json_t *v = json_object_get(o, keys[k]);
		if (!json_is_string(v))
			return kg_fail(err, KG_EINVAL, "%s: camera.%s: expected a string", file, keys[k]);
		snprintf(dst[k], size[k], "%s", json_string_value(v));
	}
	json_t *wl = json_object_get(o, "white_level");
	if (!json_is_integer(wl) || json_integer_value(wl) < 0)
		return kg_fail(err, KG_EINVAL, "%s: camera.white_level: expected a whole number >= 0",
		               file);
	id->white_level = (long)json_integer_value(wl);
	id->known = 1;
	return 0;
}

static int load_camera(const char *file, const json_t *root, kg_camera_calib *cam, kg_err *err)
{
	int ret = check_header(file, root, CAMERA_FORMAT, err);
	if (!ret)
		ret = get_method(file, root, &cam->method, err);
	if (!ret)
		ret = get_response(file, root, &cam->response, err);
	if (!ret)
		ret = get_pca(file, root, &cam->K, &cam->centred, cam->B, cam->mean, cam->M,
		              cam->rgb_mean, err);
	if (!ret)
		ret = get_mat(file, root, "M2", 3, 3, cam->M2, 3, 1, err);
	if (!ret)
		ret = kg_mat3_check_invertible(cam->M2, file, "M2", err);
	for (int j = 0; !ret && j < KG_METHOD_COUNT; j++) {
		kg_site_map *mp = &cam->maps[j];
		mp->method = (kg_method)j;
		mp->nterms = kg_method_nterms((kg_method)j);
		ret = get_map(file, root, (kg_method)j, &mp->available, NULL, 0, mp->A, mp->offset,
		              mp->pre, &mp->lambda, &mp->loo_rmse, err);
	}
	if (!ret && !cam->maps[cam->method].available)
		ret = kg_fail(err, KG_EINVAL, "%s: method: %s is marked unavailable in methods", file,
		              kg_method_name(cam->method));
	long k = 0, rank = 0;
	if (!ret)
		ret = kg_json_get_int(file, root, "site.patches", 3, 1 << 24, &k, err);
	if (ret)
		return ret;
	cam->k = (int)k;
	ret = get_strv(file, root, "site.ids", cam->k, &cam->ids, err);
	if (ret)
		return ret;
	cam->rho_r = malloc((size_t)k * sizeof(*cam->rho_r));
	cam->rho0 = malloc((size_t)k * sizeof(*cam->rho0));
	cam->residual = malloc((size_t)k * sizeof(*cam->residual));
	if (!cam->rho_r || !cam->rho0 || !cam->residual)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	ret = get_mat(file, root, "site.rho_r", 3, cam->k, &cam->rho_r[0][0], 1, 3, err);
	if (!ret)
		ret = get_mat(file, root, "site.rho0", 3, cam->k, &cam->rho0[0][0], 1, 3, err);
	if (!ret)
		ret = get_mat(file, root, "site.residual", 3, cam->k, &cam->residual[0][0], 1, 3, err);
	if (!ret)
		ret = get_num_or_null(file, root, "site.residual_rms", &cam->residual_rms, err);
	if (!ret)
		ret = get_num_or_null(file, root, "site.residual_relative", &cam->residual_relative,
		                      err);
	if (!ret)
		ret = get_num_or_null(file, root, "site.condition_number", &cam->cond, err);
	if (!ret)
		ret = get_num_or_null(file, root, "site.condition_number_equilibrated",
		                      &cam->cond_equilibrated, err);
	if (!ret)
		ret = get_row(file, root, "site.singular_values", 3, cam->singular_values, err);
	if (!ret)
		ret = kg_json_get_int(file, root, "site.rank", 0, 3, &rank, err);
	cam->rank = (int)rank;
	if (!ret)
		ret = get_flagged(file, root, "site.flagged", &cam->nflagged, &cam->flagged_ids,
		                  &cam->flagged_flags, err);
	if (!ret)
		ret = get_pairing(file, root, "site.pairing", "reference", "rgb", &cam->pairing,
		                  cam->id_rule, sizeof(cam->id_rule), err);
	if (!ret)
		ret = get_flare(file, root, "site.flare", &cam->flare, err);
	if (!ret)
		cam->flare_removed = json_is_true(kg_json_find(root, "site.flare_removed"));
	if (!ret)
		ret = get_identity(file, root, &cam->identity, err);
	if (!ret)
		ret = get_sources(file, root, &cam->sources, &cam->nsources, err);
	calib_camera_derive(cam);
	return ret;
}

int kg_camera_load(const char *path, kg_camera_calib **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	json_t *root = NULL;
	int ret = kg_json_load(path, &root, err);
	if (ret)
		return ret;
	kg_camera_calib *cam = calloc(1, sizeof(*cam));
	ret = cam ? load_camera(path, root, cam, err) : kg_fail(err, KG_ENOMEM, "out of memory");
	json_decref(root);
	if (ret) {
		kg_camera_calib_free(&cam);
		return ret;
	}
	*out = cam;
	return 0;
}
