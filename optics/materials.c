/* Materials (metal, alloy, lacquer) and the JSON material library. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_optics.h"

/* Defaults of the optional surface parameters: placeholders for a polished surface
 * until fitted to measurements of the object (documented in kg_optics.h). */
#define DEFAULT_ROUGHNESS 0.1
#define DEFAULT_MIRROR_WIDTH 0.02
#define DEFAULT_GLOSS 0.8
#define DEFAULT_MIRROR 0.2

/* Alloy fractions must sum to 1 within this. */
#define FRACTION_TOL 1e-6

static const char *kind_name(kg_material_kind k)
{
	switch (k) {
	case KG_MATERIAL_METAL: return "metal";
	case KG_MATERIAL_ALLOY: return "alloy";
	case KG_MATERIAL_DIELECTRIC: return "dielectric";
	}
	return "?";
}

static int check_nk(const char *name, const char *field, const kg_nk *nk, int dielectric,
                    kg_err *err)
{
	for (int i = 0; i < KG_NBANDS; i++) {
		double n = nk->n.v[i], k = nk->k.v[i];
		if (!isfinite(n) || !isfinite(k) || n < 0.0 || k < 0.0 || (n == 0.0 && k == 0.0))
			return kg_fail(err, KG_EINVAL, "material '%s': field %s at %g nm: n = %g, "
			               "k = %g: expected finite n >= 0 and k >= 0, not both 0", name,
			               field, kg_band_nm(i), n, k);
		if (dielectric && (k != 0.0 || !(n > 0.0)))
			return kg_fail(err, KG_EINVAL, "material '%s': field %s at %g nm: n = %g, "
			               "k = %g: expected a dielectric's n > 0 and k = 0", name, field,
			               kg_band_nm(i), n, k);
	}
	return 0;
}

/* A name reaches files of every format, messages on a terminal, lists of names (--only
 * a,b,c), compound classes (a|b) and the class names of label maps (an ENVI header
 * list): no control characters, and nothing a label map's header could not hold. */
static int check_name(const char *what, const char *name, kg_err *err)
{
	int ret = kg_text_check_controls(what, name, err);
	if (!ret)
		ret = kg_envi_check(what, name, 1, err);
	const char *bar = strchr(name, '|');
	if (!ret && bar)
		ret = kg_fail(err, KG_EINVAL, "%s: byte %ld: '|' joins the names of a compound "
		              "class (a|b): expected a name without it", what, (long)(bar - name) + 1);
	return ret;
}

int kg_material_validate(const kg_material *mat, kg_err *err)
{
	kg_check_arg(mat, err);
	if (!memchr(mat->name, '\0', sizeof(mat->name)) || !mat->name[0])
		return kg_fail(err, KG_EINVAL, "material: field name: expected 1 to %d characters",
		               KG_MATERIAL_NAME_MAX - 1);
	int ret = check_name("material: field name", mat->name, err);
	if (ret)
		return ret;
	const char *name = mat->name;
	if (!(mat->roughness > 0.0) || !isfinite(mat->roughness))
		return kg_fail(err, KG_EINVAL, "material '%s': field roughness = %g: expected a "
		               "positive RMS facet slope", name, mat->roughness);
	if (!(mat->mirror_width > 0.0) || !isfinite(mat->mirror_width))
		return kg_fail(err, KG_EINVAL, "material '%s': field mirror_width = %g: expected "
		               "a positive angle in radians", name, mat->mirror_width);
	if (!(mat->gloss >= 0.0) || !(mat->mirror >= 0.0) ||
	    !(mat->gloss + mat->mirror <= 1.0 + 1e-12))
		return kg_fail(err, KG_EINVAL, "material '%s': fields gloss = %g, mirror = %g: "
		               "expected weights >= 0 with gloss + mirror <= 1", name, mat->gloss,
		               mat->mirror);
	switch (mat->kind) {
	case KG_MATERIAL_METAL:
		return check_nk(name, "nk", &mat->nk, 0, err);
	case KG_MATERIAL_ALLOY: {
		if (mat->ncomponents < 1 || mat->ncomponents > KG_ALLOY_MAX_COMPONENTS)
			return kg_fail(err, KG_EINVAL, "material '%s': field components: %d given: "
			               "expected 1 to %d metals", name, mat->ncomponents,
			               KG_ALLOY_MAX_COMPONENTS);
		double sum = 0.0;
		for (int i = 0; i < mat->ncomponents; i++) {
			const kg_alloy_component *c = &mat->component[i];
			char field[KG_MATERIAL_NAME_MAX + 32];
			snprintf(field, sizeof(field), "components[%d] (%.*s)", i,
			         KG_MATERIAL_NAME_MAX - 1, c->name);
			if (!(c->fraction >= 0.0 && c->fraction <= 1.0))
				return kg_fail(err, KG_EINVAL, "material '%s': field %s: fraction %g: "
				               "expected a number from 0 to 1", name, field, c->fraction);
			int r = check_nk(name, field, &c->nk, 0, err);
			if (r != 0)
				return r;
			sum += c->fraction;
		}
		if (!(fabs(sum - 1.0) <= FRACTION_TOL))
			return kg_fail(err, KG_EINVAL, "material '%s': field components: fractions "
			               "sum to %.9g: expected 1 within %g", name, sum, FRACTION_TOL);
		return 0;
	}
	case KG_MATERIAL_DIELECTRIC: {
		int r = check_nk(name, "n", &mat->nk, 1, err);
		if (r != 0)
			return r;
		for (int i = 0; i < KG_NBANDS; i++)
			if (!(mat->body.v[i] >= 0.0 && mat->body.v[i] <= 1.0))
				return kg_fail(err, KG_EINVAL, "material '%s': field body at %g nm: %g: "
				               "expected a reflectance from 0 to 1", name, kg_band_nm(i),
				               mat->body.v[i]);
		return 0;
	}
	}
	return kg_fail(err, KG_EINVAL, "material '%s': field kind: expected metal, alloy or "
	               "dielectric", name);
}

/* The material's surface (Fresnel) reflectance per band at cos_i. */
static void surface_fresnel(const kg_material *mat, double cos_i, kg_spectrum *out)
{
	switch (mat->kind) {
	case KG_MATERIAL_METAL:
		kg_nk_reflectance(&mat->nk, cos_i, out);
		return;
	case KG_MATERIAL_ALLOY: {
		/* weights divided by their sum (within 1e-6 of 1), so that a sum slightly
		 * above 1 cannot lift the reflectance above 1 */
		double total = 0.0;
		*out = kg_spectrum_const(0.0);
		for (int c = 0; c < mat->ncomponents; c++) {
			kg_spectrum r;
			kg_nk_reflectance(&mat->component[c].nk, cos_i, &r);
			*out = kg_spectrum_axpy(out, mat->component[c].fraction, &r);
			total += mat->component[c].fraction;
		}
		for (int i = 0; i < KG_NBANDS; i++)
			out->v[i] /= total;
		return;
	}
	case KG_MATERIAL_DIELECTRIC:
		for (int i = 0; i < KG_NBANDS; i++)
			out->v[i] = kg_fresnel_dielectric(mat->nk.n.v[i], 1.0, cos_i);
		return;
	}
}

int kg_material_reflectance(const kg_material *mat, double theta, kg_spectrum *out,
                            kg_err *err)
{
	kg_check_arg(mat && out, err);
	int r = kg_material_validate(mat, err);
	if (r != 0)
		return r;
	/* up to pi/2 within rounding of a conversion from degrees */
	if (!(theta >= 0.0 && theta <= M_PI_2 + 1e-12))
		return kg_fail(err, KG_EINVAL, "material '%s': incidence angle %g rad: expected "
		               "0 to pi/2", mat->name, theta);
	double c = fmax(0.0, cos(theta));
	surface_fresnel(mat, c, out);
	if (mat->kind == KG_MATERIAL_DIELECTRIC)
		for (int i = 0; i < KG_NBANDS; i++)
			out->v[i] += (1.0 - out->v[i]) * mat->body.v[i];
	return 0;
}

int kg_material_eval(const kg_material *mat, const double N[3], const double V[3],
                     const double L[3], kg_spectrum *out, kg_err *err)
{
	kg_check_arg(mat && N && V && L && out, err);
	int r = kg_material_validate(mat, err);
	if (r != 0)
		return r;
	double cos_vh;
	double gloss = kg_lobe_gloss(N, V, L, mat->roughness, &cos_vh);
	double mirror = kg_lobe_mirror(N, V, L, mat->mirror_width, NULL);
	if (isnan(gloss) || isnan(mirror))
		return kg_fail(err, KG_EINVAL, "material '%s': geometry: expected unit vectors "
		               "N, V, L", mat->name);
	double nl = fmin(1.0, N[0] * L[0] + N[1] * L[1] + N[2] * L[2]);
	double nv = N[0] * V[0] + N[1] * V[1] + N[2] * V[2];
	if (!(nl > 0.0) || !(nv > 0.0)) {
		*out = kg_spectrum_const(0.0);
		return 0;
	}
	kg_spectrum f;
	surface_fresnel(mat, cos_vh, &f);
	*out = kg_spectrum_scale(&f, (mat->gloss * gloss + mat->mirror * mirror) * nl);
	if (mat->kind == KG_MATERIAL_DIELECTRIC) {
		kg_spectrum fi;
		surface_fresnel(mat, nl, &fi);
		for (int i = 0; i < KG_NBANDS; i++)
			out->v[i] += (1.0 - fi.v[i]) * mat->body.v[i] * nl / M_PI;
	}
	return 0;
}

/* ---- Library ------------------------------------------------------------------ */

struct kg_material_library {
	int n;
	kg_material *m;
};

void kg_material_library_free(kg_material_library **lib)
{
	if (!lib || !*lib)
		return;
	free((*lib)->m);
	free(*lib);
	*lib = NULL;
}

int kg_material_library_count(const kg_material_library *lib)
{
	return lib ? lib->n : 0;
}

const kg_material *kg_material_library_get(const kg_material_library *lib, int i)
{
	return lib && i >= 0 && i < lib->n ? &lib->m[i] : NULL;
}

void kg_material_library_names(const kg_material_library *lib, char *buf, size_t size)
{
	size_t used = 0;
	buf[0] = '\0';
	for (int i = 0; i < kg_material_library_count(lib) && used + 1 < size; i++) {
		int w = snprintf(buf + used, size - used, "%s%s", i ? ", " : "", lib->m[i].name);
		if (w < 0)
			break;
		used += (size_t)w;
	}
}

const kg_material *kg_material_library_find(const kg_material_library *lib, const char *name)
{
	for (int i = 0; lib && name && i < lib->n; i++)
		if (strcmp(lib->m[i].name, name) == 0)
			return &lib->m[i];
	return NULL;
}

/* Keys an entry may have, by kind (the common ones first). */
static const char *const common_keys[] = {"name", "kind", "note", "source", "roughness",
                                          "mirror_width", "gloss", "mirror", "template",
                                          "model_rsd", NULL};
static const char *const metal_keys[] = {"nk", "extrapolate", NULL};
static const char *const alloy_keys[] = {"components", NULL};
static const char *const dielectric_keys[] = {"n", "body", NULL};

static int in_list(const char *key, const char *const *list)
{
	for (; *list; list++)
		if (strcmp(key, *list) == 0)
			return 1;
	return 0;
}

static int check_keys(const char *label, const json_t *entry, kg_material_kind kind,
                      kg_err *err)
{
	const char *const *own = kind == KG_MATERIAL_METAL   ? metal_keys
	                         : kind == KG_MATERIAL_ALLOY ? alloy_keys
	                                                     : dielectric_keys;
	const char *key;
	json_t *v;
	json_object_foreach((json_t *)entry, key, v) {
		if (in_list(key, common_keys) || in_list(key, own))
			continue;
		char allowed[256] = "";
		for (const char *const *k = own; *k; k++)
			snprintf(allowed + strlen(allowed), sizeof(allowed) - strlen(allowed), "%s%s",
			         k == own ? "" : ", ", *k);
		return kg_fail(err, KG_EINVAL, "%s: field '%s' is not known for a %s: expected "
		               "name, kind, note, source, roughness, mirror_width, gloss, mirror, "
		               "template, %s", label, key, kind_name(kind), allowed);
	}
	return 0;
}

/* An optional number (default when absent). */
static int opt_number(const char *label, const json_t *entry, const char *key, double def,
                      double *out, kg_err *err)
{
	if (!json_object_get(entry, key)) {
		*out = def;
		return 0;
	}
	return kg_json_get_number(label, entry, key, out, err);
}

static int parse_metal(const char *label, const char *dir, const json_t *entry,
                       kg_material *m, kg_err *err)
{
	json_t *nk;
	int r = kg_json_get(label, entry, "nk", &nk, err);
	if (r != 0)
		return r;
	if (json_is_string(nk)) {
		unsigned flags = 0;
		json_t *ex = json_object_get(entry, "extrapolate");
		if (ex && !json_is_boolean(ex))
			return kg_fail(err, KG_EINVAL, "%s: field extrapolate: expected true or false",
			               label);
		if (ex && json_is_true(ex))
			flags |= KG_RESAMPLE_EXTRAPOLATE;
		const char *rel = json_string_value(nk);
		char *path = rel[0] == '/' ? strdup(rel) : kg_path_join(dir, rel);
		if (!path)
			return kg_fail(err, KG_ENOMEM, "%s: out of memory", label);
		r = kg_nk_load(path, flags, &m->nk, err);
		free(path);
		if (r != 0)
			kg_err_prefix(err, "%s: field nk", label);
		return r;
	}
	if (!json_is_object(nk))
		return kg_fail(err, KG_EINVAL, "%s: field nk: expected a file name (.csv, .yml) "
		               "or {\"model\": \"rakic1998-ld\", \"element\": ...}", label);
	const char *model, *element;
	if ((r = kg_json_get_string(label, entry, "nk.model", &model, err)) != 0)
		return r;
	if ((r = kg_json_get_string(label, entry, "nk.element", &element, err)) != 0)
		return r;
	if ((r = kg_nk_model(model, element, &m->nk, err)) != 0)
		kg_err_prefix(err, "%s: field nk", label);
	return r;
}

static int parse_dielectric(const char *label, const json_t *entry, kg_material *m,
                            kg_err *err)
{
	double n;
	int r = kg_json_get_number(label, entry, "n", &n, err);
	if (r != 0)
		return r;
	m->nk.n = kg_spectrum_const(n);
	m->nk.k = kg_spectrum_const(0.0);
	json_t *body;
	if ((r = kg_json_get(label, entry, "body", &body, err)) != 0)
		return r;
	if (json_is_number(body)) {
		m->body = kg_spectrum_const(json_number_value(body));
		return 0;
	}
	json_t *wl, *val;
	if (!json_is_object(body) || kg_json_get(label, entry, "body.wavelength_nm", &wl, err) ||
	    kg_json_get(label, entry, "body.reflectance", &val, err) || !json_is_array(wl) ||
	    json_array_size(wl) != json_array_size(val) || json_array_size(wl) == 0 ||
	    json_array_size(wl) > 100000)
		return kg_fail(err, KG_EINVAL, "%s: field body: expected a reflectance (number) "
		               "or {\"wavelength_nm\": [...], \"reflectance\": [...]} with arrays "
		               "of the same, non-zero length", label);
	int count = (int)json_array_size(wl);
	double *w = malloc(sizeof(*w) * (size_t)count), *v = malloc(sizeof(*v) * (size_t)count);
	if (!w || !v)
		r = kg_fail(err, KG_ENOMEM, "%s: out of memory", label);
	if (r == 0)
		r = kg_json_get_numbers(label, entry, "body.wavelength_nm", count, w, err);
	if (r == 0)
		r = kg_json_get_numbers(label, entry, "body.reflectance", count, v, err);
	if (r == 0) {
		char what[KG_MATERIAL_NAME_MAX + 1200];
		snprintf(what, sizeof(what), "%s: field body", label);
		r = kg_spectrum_resample(w, v, count, 0, what, &m->body, err);
	}
	free(w);
	free(v);
	return r;
}

static int parse_alloy(const char *label, const json_t *entry, const kg_material_library *lib,
                       kg_material *m, kg_err *err)
{
	json_t *comps;
	int r = kg_json_get(label, entry, "components", &comps, err);
	if (r != 0)
		return r;
	if (!json_is_array(comps) || json_array_size(comps) == 0 ||
	    json_array_size(comps) > KG_ALLOY_MAX_COMPONENTS)
		return kg_fail(err, KG_EINVAL, "%s: field components: expected an array of 1 to "
		               "%d {\"material\": name, \"fraction\": number}", label,
		               KG_ALLOY_MAX_COMPONENTS);
	m->ncomponents = (int)json_array_size(comps);
	for (int i = 0; i < m->ncomponents; i++) {
		char key[64];
		const char *metal;
		kg_alloy_component *c = &m->component[i];
		snprintf(key, sizeof(key), "components[%d].material", i);
		if ((r = kg_json_get_string(label, entry, key, &metal, err)) != 0)
			return r;
		snprintf(key, sizeof(key), "components[%d].fraction", i);
		if ((r = kg_json_get_number(label, entry, key, &c->fraction, err)) != 0)
			return r;
		const kg_material *src = kg_material_library_find(lib, metal);
		if (!src)
			return kg_fail(err, KG_EINVAL, "%s: field components[%d].material: '%s' is "
			               "not in the library: expected the name of a metal entry", label,
			               i, metal);
		if (src->kind != KG_MATERIAL_METAL)
			return kg_fail(err, KG_EINVAL, "%s: field components[%d].material: '%s' is "
			               "a %s: expected a metal", label, i, metal, kind_name(src->kind));
		snprintf(c->name, sizeof(c->name), "%s", src->name);
		c->nk = src->nk;
	}
	return 0;
}

/* Name, kind and surface parameters of entry i (the kind-specific parts follow). */
/* "template": {"reference": sha256 or "", "views": [{"angle_deg", "mean" [3],
 * "cov" [9], "pixels"}...]}, angles increasing in [0, 90), finite values, variances
 * >= 0. */
static int parse_template(const char *label, const json_t *t, kg_material_template *out,
                          kg_err *err)
{
	memset(out, 0, sizeof(*out));
	const json_t *views = json_object_get(t, "views");
	const json_t *ref = json_object_get(t, "reference");
	if (!json_is_object(t) || !json_is_array(views) || json_array_size(views) < 1 ||
	    json_array_size(views) > KG_TEMPLATE_MAX_VIEWS || (ref && !json_is_string(ref)))
		return kg_fail(err, KG_EINVAL, "%s: field template: expected {\"reference\": "
		               "sha256, \"views\": [1 to %d views of angle_deg, mean (3), cov (9), "
		               "pixels]}", label, KG_TEMPLATE_MAX_VIEWS);
	if (ref)
		snprintf(out->reference, sizeof(out->reference), "%s", json_string_value(ref));
	size_t i;
	const json_t *v;
	json_array_foreach(views, i, v) {
		const json_t *a = json_object_get(v, "angle_deg"), *mean = json_object_get(v, "mean"),
		             *cov = json_object_get(v, "cov"), *px = json_object_get(v, "pixels");
		int ok = json_is_number(a) && json_is_array(mean) && json_array_size(mean) == 3 &&
		         json_is_array(cov) && json_array_size(cov) == 9 && json_is_integer(px) &&
		         json_integer_value(px) > 0;
		double ang = ok ? json_number_value(a) : NAN;
		ok = ok && ang >= 0 && ang < 90 && (i == 0 || ang > out->angle_deg[i - 1]);
		for (int c = 0; ok && c < 3; c++) {
			const json_t *x = json_array_get(mean, (size_t)c);
			ok = json_is_number(x) && isfinite(json_number_value(x));
			out->mean[i][c] = ok ? json_number_value(x) : 0;
		}
		for (int e = 0; ok && e < 9; e++) {
			const json_t *x = json_array_get(cov, (size_t)e);
			ok = json_is_number(x) && isfinite(json_number_value(x));
			out->cov[i][e] = ok ? json_number_value(x) : 0;
		}
		ok = ok && out->cov[i][0] >= 0 && out->cov[i][4] >= 0 && out->cov[i][8] >= 0;
		if (!ok)
			return kg_fail(err, KG_EINVAL, "%s: field template.views[%zu]: expected "
			               "angle_deg in [0, 90) above the previous view's, mean (3 finite "
			               "numbers), cov (9 finite numbers, variances >= 0) and pixels > 0",
			               label, i);
		out->angle_deg[i] = ang;
		out->pixels[i] = (long)json_integer_value(px);
	}
	out->n = (int)json_array_size(views);
	return 0;
}

/* A coupon template's own scatter: its pixels' sd per channel over the mean reading's
 * level l = |mean| / sqrt(3) (as model_rsd), the largest over its views (it replaces
 * the published constants' spread). */
static void template_rsd(const kg_material_template *t, double out[3])
{
	if (t->n < 1)
		return;
	for (int c = 0; c < 3; c++)
		out[c] = 0;
	for (int v = 0; v < t->n; v++) {
		const double *m = t->mean[v];
		double l = sqrt((m[0] * m[0] + m[1] * m[1] + m[2] * m[2]) / 3.0);
		for (int c = 0; c < 3; c++) {
			double var = t->cov[v][4 * c];
			if (l > 0 && var > 0)
				out[c] = fmax(out[c], fmin(1.0, sqrt(var) / l));
		}
	}
}

static int parse_common(const char *file, int i, const json_t *entry,
                        const kg_material_library *lib, kg_material *m, char *label,
                        size_t labelsz, kg_err *err)
{
	snprintf(label, labelsz, "%s (materials[%d])", file, i);
	if (!json_is_object(entry))
		return kg_fail(err, KG_EINVAL, "%s: expected an object with name and kind", label);
	const char *name, *kind;
	int r = kg_json_get_string(label, entry, "name", &name, err);
	if (r != 0)
		return r;
	if (!name[0] || strlen(name) >= KG_MATERIAL_NAME_MAX)
		return kg_fail(err, KG_EINVAL, "%s: field name: expected 1 to %d characters", label,
		               KG_MATERIAL_NAME_MAX - 1);
	char what[KG_MATERIAL_NAME_MAX + 1100];
	snprintf(what, sizeof(what), "%s: field name", label);
	if ((r = check_name(what, name, err)) != 0)
		return r;
	for (int j = 0; j < i; j++)
		if (strcmp(lib->m[j].name, name) == 0)
			return kg_fail(err, KG_EINVAL, "%s: field name: '%s' is already used by "
			               "materials[%d]: expected unique names", label, name, j);
	snprintf(m->name, sizeof(m->name), "%s", name);
	snprintf(label, labelsz, "%s (materials[%d]): material '%s'", file, i, name);
	if ((r = kg_json_get_string(label, entry, "kind", &kind, err)) != 0)
		return r;
	if (strcmp(kind, "metal") == 0)
		m->kind = KG_MATERIAL_METAL;
	else if (strcmp(kind, "alloy") == 0)
		m->kind = KG_MATERIAL_ALLOY;
	else if (strcmp(kind, "dielectric") == 0)
		m->kind = KG_MATERIAL_DIELECTRIC;
	else
		return kg_fail(err, KG_EINVAL, "%s: field kind: '%s': expected metal, alloy or "
		               "dielectric", label, kind);
	if ((r = check_keys(label, entry, m->kind, err)) != 0)
		return r;
	if ((r = opt_number(label, entry, "roughness", DEFAULT_ROUGHNESS, &m->roughness, err)) ||
	    (r = opt_number(label, entry, "mirror_width", DEFAULT_MIRROR_WIDTH, &m->mirror_width,
	                    err)) ||
	    (r = opt_number(label, entry, "gloss", DEFAULT_GLOSS, &m->gloss, err)) ||
	    (r = opt_number(label, entry, "mirror", DEFAULT_MIRROR, &m->mirror, err)))
		return r;
	const json_t *u = json_object_get(entry, "model_rsd");
	if (u) {
		if (!json_is_array(u) || json_array_size(u) != 3)
			return kg_fail(err, KG_EINVAL, "%s: field model_rsd: expected an array of 3 "
			               "relative sds (r, g, b), each from 0 to 1", label);
		for (size_t c = 0; c < 3; c++) {
			const json_t *v = json_array_get(u, c);
			double d = json_is_number(v) ? json_number_value(v) : NAN;
			if (!(d >= 0 && d <= 1))
				return kg_fail(err, KG_EINVAL, "%s: field model_rsd[%zu]: expected a "
				               "relative sd from 0 to 1", label, c);
			m->model_rsd[c] = d;
		}
	}
	if (json_object_get(entry, "template")) {
		r = parse_template(label, json_object_get(entry, "template"), &m->tmpl, err);
		if (r)
			return r;
		template_rsd(&m->tmpl, m->model_rsd);
	}
	return 0;
}

static const kg_data_name bundled_libraries[] = {
	{"default", "materials/default.json"},
};

int kg_material_library_resolve(const char *arg, char **path, kg_err *err)
{
	return kg_data_resolve(arg, "material library", bundled_libraries,
	                       (int)(sizeof(bundled_libraries) / sizeof(bundled_libraries[0])),
	                       path, err);
}

static int load_library(const char *path, kg_material_library **out, kg_err *err)
{
	json_t *root = NULL, *list;
	kg_material_library *lib = NULL;
	char *dir = NULL;
	const char *format;
	char label[KG_MATERIAL_NAME_MAX + 1024];
	int r = kg_json_load(path, &root, err);
	if (r != 0)
		return r;
	if ((r = kg_json_get_string(path, root, "format", &format, err)) != 0)
		goto done;
	if (strcmp(format, "kogei-materials/1") != 0) {
		r = kg_fail(err, KG_EINVAL, "%s: field format: '%s': expected kogei-materials/1",
		            path, format);
		goto done;
	}
	const char *key;
	json_t *value;
	json_object_foreach(root, key, value) {
		if (strcmp(key, "format") && strcmp(key, "materials") && strcmp(key, "note")) {
			r = kg_fail(err, KG_EINVAL, "%s: field '%s' is not known: expected format, "
			            "materials, note", path, key);
			goto done;
		}
	}
	if ((r = kg_json_get(path, root, "materials", &list, err)) != 0)
		goto done;
	if (!json_is_array(list) || json_array_size(list) == 0 ||
	    json_array_size(list) > 100000) {
		r = kg_fail(err, KG_EINVAL, "%s: field materials: expected a non-empty array of "
		            "material entries", path);
		goto done;
	}
	lib = calloc(1, sizeof(*lib));
	dir = kg_path_dir(path);
	if (!lib || !dir || !(lib->m = calloc(json_array_size(list), sizeof(*lib->m)))) {
		r = kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
		goto done;
	}
	lib->n = (int)json_array_size(list);
	/* metals and dielectrics first, so that alloys may name metals listed after them */
	for (int pass = 0; pass < 2 && r == 0; pass++)
		for (int i = 0; i < lib->n && r == 0; i++) {
			const json_t *entry = json_array_get(list, (size_t)i);
			kg_material *m = &lib->m[i];
			if (pass == 0) {
				r = parse_common(path, i, entry, lib, m, label, sizeof(label), err);
				if (r == 0 && m->kind == KG_MATERIAL_METAL)
					r = parse_metal(label, dir, entry, m, err);
				else if (r == 0 && m->kind == KG_MATERIAL_DIELECTRIC)
					r = parse_dielectric(label, entry, m, err);
			} else {
				snprintf(label, sizeof(label), "%s (materials[%d]): material '%s'", path, i,
				         m->name);
				if (m->kind == KG_MATERIAL_ALLOY)
					r = parse_alloy(label, entry, lib, m, err);
				if (r == 0 && (r = kg_material_validate(m, err)) != 0)
					kg_err_prefix(err, "%s (materials[%d])", path, i);
			}
		}
done:
	json_decref(root);
	free(dir);
	if (r != 0)
		kg_material_library_free(&lib);
	*out = lib;
	return r;
}

int kg_material_library_load(const char *arg, kg_material_library **out, kg_err *err)
{
	kg_check_arg(arg && out, err);
	*out = NULL;
	char *path;
	int r = kg_material_library_resolve(arg, &path, err);
	if (r)
		return r;
	r = load_library(path, out, err);
	free(path);
	return r;
}
