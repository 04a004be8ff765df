/* Reading a calibration's inputs: patch files, pairing spectra with RGB by
 * SAMPLE_ID, and the record of where each input came from. */
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include <math.h>

#include <openssl/evp.h>

#include "calib_private.h"

int kg_calib_sha256_file(const char *path, char hex[65], kg_err *err)
{
	char *buf = NULL;
	size_t len = 0;
	unsigned char md[EVP_MAX_MD_SIZE];
	unsigned int mdlen = 0;
	int ret = kg_read_file(path, &buf, &len, err);
	if (ret)
		return ret;
	if (!EVP_Digest(buf, len, md, &mdlen, EVP_sha256(), NULL) || mdlen != 32)
		ret = kg_fail(err, KG_EIO, "%s: sha256 failed", path);
	free(buf);
	if (ret)
		return ret;
	for (unsigned int i = 0; i < mdlen; i++)
		snprintf(hex + 2 * i, 3, "%02x", md[i]);
	return 0;
}

static int has_suffix(const char *s, const char *suffix)
{
	size_t n = strlen(s), m = strlen(suffix);
	return n >= m && strcasecmp(s + n - m, suffix) == 0;
}

static void source_clear(kg_calib_source *s)
{
	free(s->role);
	free(s->path);
	calib_strv_free(s->keyword_names, s->nkeywords);
	calib_strv_free(s->keyword_values, s->nkeywords);
	memset(s, 0, sizeof(*s));
}

void calib_sources_free(kg_calib_source **sources, int *n)
{
	if (!*sources)
		return;
	for (int i = 0; i < *n; i++)
		source_clear(&(*sources)[i]);
	free(*sources);
	*sources = NULL;
	*n = 0;
}

int calib_sources_copy(const kg_calib_source *src, int n, kg_calib_source **out,
                       kg_err *err)
{
	*out = NULL;
	if (n == 0)
		return 0;
	kg_calib_source *d = calloc((size_t)n, sizeof(*d));
	if (!d)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (int i = 0; i < n; i++) {
		d[i].role = strdup(src[i].role);
		d[i].path = strdup(src[i].path);
		memcpy(d[i].sha256, src[i].sha256, sizeof(d[i].sha256));
		d[i].nkeywords = src[i].nkeywords;
		d[i].keyword_names = calib_strv_dup(src[i].keyword_names, src[i].nkeywords);
		d[i].keyword_values = calib_strv_dup(src[i].keyword_values, src[i].nkeywords);
		if (!d[i].role || !d[i].path || !d[i].keyword_names || !d[i].keyword_values) {
			int nn = i + 1;
			calib_sources_free(&d, &nn);
			return kg_fail(err, KG_ENOMEM, "out of memory");
		}
	}
	*out = d;
	return 0;
}

int kg_reference_add_source(kg_reference *ref, const char *role, const char *path,
                            kg_err *err)
{
	kg_check_arg(ref && role && path, err);
	return calib_source_add(&ref->sources, &ref->nsources, role, path, err);
}

/* Append a source: its sha256 and, for a CGATS file, its keywords (devices,
 * illuminant, dates as the instrument wrote them). */
int calib_source_add(kg_calib_source **sources, int *n, const char *role,
                     const char *path, kg_err *err)
{
	kg_calib_source *grown = realloc(*sources, (size_t)(*n + 1) * sizeof(*grown));
	if (!grown)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	*sources = grown;
	kg_calib_source *s = &grown[*n];
	memset(s, 0, sizeof(*s));
	(*n)++;
	s->role = strdup(role);
	s->path = strdup(path);
	if (!s->role || !s->path)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	int ret = kg_calib_sha256_file(path, s->sha256, err);
	if (ret)
		return ret;
	if (has_suffix(path, ".csv") || has_suffix(path, ".json"))
		return 0;
	kg_cgats *cg = NULL;
	ret = kg_cgats_read(path, &cg, err);
	if (ret)
		return ret;
	const kg_cgats_table *t = cg->ntables > 0 ? cg->tables[0] : NULL;
	int nk = t ? t->nkeywords : 0;
	s->keyword_names = calloc(nk > 0 ? (size_t)nk : 1, sizeof(char *));
	s->keyword_values = calloc(nk > 0 ? (size_t)nk : 1, sizeof(char *));
	if (!s->keyword_names || !s->keyword_values) {
		kg_cgats_free(&cg);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	for (int i = 0; i < nk; i++) {
		s->keyword_names[i] = strdup(t->keywords[i].name);
		s->keyword_values[i] = strdup(t->keywords[i].value ? t->keywords[i].value : "");
		s->nkeywords = i + 1;
		if (!s->keyword_names[i] || !s->keyword_values[i]) {
			kg_cgats_free(&cg);
			return kg_fail(err, KG_ENOMEM, "out of memory");
		}
	}
	kg_cgats_free(&cg);
	return 0;
}

int calib_check_encoding(const char *path, kg_err *err)
{
	if (has_suffix(path, ".csv") || has_suffix(path, ".json"))
		return 0;
	kg_cgats *cg = NULL;
	int ret = kg_cgats_read(path, &cg, err);
	if (ret)
		return ret;
	const char *v = cg->ntables > 0 ? kg_cgats_keyword(cg->tables[0], "IMAGE_ENCODING") : NULL;
	if (v && strcmp(v, "jpeg-unstated") == 0)
		ret = kg_fail(err, KG_EINVAL, "%s: IMAGE_ENCODING \"%s\": the patches come from a "
		              "JPEG whose encoding was not stated; a JPEG is gamma-encoded and "
		              "white-balanced by the camera, so its values are not linear camera "
		              "responses. Expected a raw, TIFF or PNG capture, or run kogei chart "
		              "detect with --encoding srgb|linear|gamma:G if you know how the JPEG "
		              "was encoded", path, v);
	kg_cgats_free(&cg);
	return ret;
}

/* Refuse a patch set whose ids repeat. */
static int check_unique(const kg_patchset *ps, const char *what, kg_err *err)
{
	for (int i = 0; i < ps->n; i++)
		for (int j = 0; j < i; j++)
			if (strcmp(ps->ids[i], ps->ids[j]) == 0)
				return kg_fail(err, KG_EINVAL, "%s: SAMPLE_ID %s appears twice (rows %d and %d)",
				               what, ps->ids[i], j + 1, i + 1);
	return 0;
}

int kg_calib_pair(const kg_patchset *spectra, const kg_patchset *rgb, kg_patchset **out,
                  kg_err *err)
{
	return kg_calib_pair_checked(spectra, rgb, NULL, out, NULL, NULL, err);
}

/* The spectra as the first side of a pairing: their XYZ under D65. */
static int spectra_side(const kg_patchset *spectra, const kg_pair_options *opt,
                        calib_pair_side *s, kg_err *err)
{
	calib_d65 d65;
	double(*xyz)[3] = malloc((spectra->n > 0 ? (size_t)spectra->n : 1) * sizeof(*xyz));
	int ret = xyz ? calib_d65_init(&d65, err) : kg_fail(err, KG_ENOMEM, "out of memory");
	for (int i = 0; ret == 0 && i < spectra->n; i++) {
		kg_xyz v = kg_xyz_from_weights(&d65.w, &spectra->spectra[i]);
		xyz[i][0] = v.X;
		xyz[i][1] = v.Y;
		xyz[i][2] = v.Z;
	}
	if (ret == 0)
		ret = calib_pair_side_new(spectra->source ? spectra->source : "spectra", "spectra",
		                          "the spectra's colours (XYZ under D65)", spectra->ids,
		                          spectra->n, (const double(*)[3])xyz, s, err);
	if (ret == 0)
		calib_pair_side_skip(s, opt->exclude, opt->nexclude, NULL, 0);
	free(xyz);
	return ret;
}

/* A camera's patch file as the second side: its RGB, without the patches it flags
 * or clips and the excluded ones. */
static int camera_side(const kg_patchset *rgb, const kg_pair_options *opt,
                       calib_pair_side *s, kg_err *err)
{
	int ret = calib_pair_side_new(rgb->source ? rgb->source : "RGB patch file", "rgb", "",
	                              rgb->ids, rgb->n, (const double(*)[3])rgb->rgb, s, err);
	if (ret == 0)
		calib_pair_side_skip(s, opt->exclude, opt->nexclude, rgb, KG_CALIB_CLIP_LEVEL);
	return ret;
}

static int check_inputs(const kg_patchset *spectra, const kg_patchset *rgb, kg_err *err)
{
	const char *sname = spectra->source ? spectra->source : "spectra";
	const char *rname = rgb->source ? rgb->source : "RGB patch file";
	if (!spectra->spectra)
		return kg_fail(err, KG_EINVAL, "%s: expected spectral fields (SPEC_400 .. SPEC_700)",
		               sname);
	if (!rgb->rgb)
		return kg_fail(err, KG_EINVAL, "%s: expected fields RGB_R RGB_G RGB_B", rname);
	int ret = check_unique(spectra, sname, err);
	return ret ? ret : check_unique(rgb, rname, err);
}

/* Refuse a pairing that leaves most patches without a partner: none at all, or
 * fewer than half of the smaller file's. */
static int check_paired(const calib_pair_side *a, const calib_pair_side *b, int npairs,
                        kg_id_pairing how, kg_err *err)
{
	int smaller = a->n < b->n ? a->n : b->n;
	if (npairs > 0 && 2 * npairs >= smaller)
		return 0;
	char x[256] = "", y[256] = "", name[64];
	calib_list_ids(x, sizeof(x), a->ids, NULL, a->n, 6);
	calib_list_ids(y, sizeof(y), b->ids, NULL, b->n, 6);
	kg_id_pairing_name(how, a->role, b->role, name, sizeof(name));
	if (npairs == 0 && how == KG_ID_PAIRING_NAMES)
		return kg_fail(err, KG_EINVAL,
		               "%s and %s: no SAMPLE_ID in common (spectra: %s; RGB: %s); expected "
		               "the same chart's patch names in both (as written, A1 = A01, or patch "
		               "numbers 1..n against letter-and-number ids)",
		               a->file, b->file, x, y);
	return kg_fail(err, KG_EINVAL,
	               "%s and %s: only %d of their %d and %d patches pair (by %s); expected at "
	               "least half of the smaller file's: they do not seem to name the same "
	               "chart's patches (spectra: %s; RGB: %s)",
	               a->file, b->file, npairs, a->n, b->n, name, x, y);
}

/* The paired patches: spectra in the order of `spectra`, the RGB file's values and ids
 * (the camera file's spelling, which the field chart (rho0) shares). */
static int paired_set(const kg_patchset *spectra, const kg_patchset *rgb,
                      const calib_pair_result *r, kg_patchset **out, kg_err *err)
{
	kg_patchset *ps = NULL;
	int ret = kg_patchset_new(r->npairs, KG_PATCH_SPECTRA | KG_PATCH_RGB, &ps, err);
	for (int i = 0, j = 0; ret == 0 && i < spectra->n; i++) {
		if (r->match[i] < 0)
			continue;
		ret = kg_patchset_set_id(ps, j, rgb->ids[r->match[i]], err);
		ps->spectra[j] = spectra->spectra[i];
		memcpy(ps->rgb[j], rgb->rgb[r->match[i]], sizeof(ps->rgb[j]));
		j++;
	}
	/* the clipped-fraction column (clipping judged on the sensor's codes) goes with the
	 * values, so that the training chart is judged by it and not by its values */
	int stride = 0;
	const double *clip = calib_clipped_column(rgb, &stride);
	if (ret == 0 && clip) {
		ret = kg_patchset_add_extra(ps, "CLIPPED_FRACTION", err);
		for (int i = 0, j = 0; ret == 0 && i < spectra->n; i++)
			if (r->match[i] >= 0)
				ps->extra[(size_t)j++ * ps->nextra] = clip[(size_t)r->match[i] * stride];
	}
	if (ret == 0 && !(ps->source = strdup(rgb->source ? rgb->source : "RGB patch file")))
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	if (ret)
		kg_patchset_free(&ps);
	*out = ps;
	return ret;
}

int kg_calib_pair_checked(const kg_patchset *spectra, const kg_patchset *rgb,
                          const kg_pair_options *opt, kg_patchset **out,
                          kg_pairing_record *rec, const char **rule, kg_err *err)
{
	kg_check_arg(spectra && rgb && out, err);
	kg_pair_options defaults = {KG_ID_PAIRING_NAMES, NULL, 0, NULL};
	if (!opt)
		opt = &defaults;
	if (rule)
		*rule = NULL;
	*out = NULL;
	int ret = check_inputs(spectra, rgb, err);
	if (ret)
		return ret;
	calib_pair_side a = {0}, b = {0};
	calib_pair_result r = {0};
	ret = spectra_side(spectra, opt, &a, err);
	if (ret == 0)
		ret = camera_side(rgb, opt, &b, err);
	if (ret == 0)
		ret = calib_pair_check(&a, &b, opt->pairing, 1, opt->option, &r, err);
	if (ret == 0)
		ret = check_paired(&a, &b, r.npairs, opt->pairing, err);
	if (ret == 0 && rec)
		ret = calib_pair_record(&a, &b, &r, opt->pairing, rec, err);
	if (ret == 0)
		ret = paired_set(spectra, rgb, &r, out, err);
	if (ret == 0 && rule)
		*rule = r.alias;
	calib_pair_result_free(&r);
	calib_pair_side_free(&a);
	calib_pair_side_free(&b);
	return ret;
}

static int listed(const char *const *ids, int n, const char *id)
{
	for (int i = 0; i < n; i++)
		if (strcmp(ids[i], id) == 0)
			return 1;
	return 0;
}

int calib_patchset_without(const kg_patchset *ps, const char *const *ids, int nids,
                           kg_patchset **out, kg_err *err)
{
	*out = NULL;
	int n = 0;
	for (int i = 0; i < ps->n; i++)
		n += !listed(ids, nids, ps->ids[i]);
	unsigned fields = (ps->spectra ? KG_PATCH_SPECTRA : 0) | (ps->rgb ? KG_PATCH_RGB : 0) |
	                  (ps->xyz ? KG_PATCH_XYZ : 0) | (ps->lab ? KG_PATCH_LAB : 0);
	kg_patchset *c = NULL;
	int ret = kg_patchset_new(n, fields, &c, err);
	for (int j = 0; ret == 0 && j < ps->nextra; j++)
		ret = kg_patchset_add_extra(c, ps->extra_names[j], err);
	for (int i = 0, k = 0; ret == 0 && i < ps->n; i++) {
		if (listed(ids, nids, ps->ids[i]))
			continue;
		ret = kg_patchset_set_id(c, k, ps->ids[i], err);
		if (ps->spectra)
			c->spectra[k] = ps->spectra[i];
		if (ps->rgb)
			memcpy(c->rgb[k], ps->rgb[i], sizeof(c->rgb[k]));
		if (ps->xyz)
			memcpy(c->xyz[k], ps->xyz[i], sizeof(c->xyz[k]));
		if (ps->lab)
			memcpy(c->lab[k], ps->lab[i], sizeof(c->lab[k]));
		for (int j = 0; j < ps->nextra; j++)
			c->extra[(size_t)k * ps->nextra + j] = ps->extra[(size_t)i * ps->nextra + j];
		k++;
	}
	if (ret == 0 && ps->source && !(c->source = strdup(ps->source)))
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	if (ret == 0)
		c->spectral_scale = ps->spectral_scale;
	if (ret) {
		kg_patchset_free(&c);
		return ret;
	}
	*out = c;
	return 0;
}

/* A field chart (--field-rgb) that names the very patches the spectra do, one to one,
 * is that chart photographed again: its colours must fit the spectra as the training
 * RGB's do. A field chart of other patches is paired with nothing here (the site
 * calibration pairs it with the site camera's file). */
static int check_field(const kg_patchset *spectra, const kg_patchset *field,
                       const kg_pair_options *opt, kg_err *err)
{
	calib_pair_side a = {0}, b = {0};
	calib_pair_result r = {0};
	int *map = malloc((spectra->n > 0 ? (size_t)spectra->n : 1) * sizeof(int));
	const char *alias;
	int ret = map ? spectra_side(spectra, opt, &a, err) : kg_fail(err, KG_ENOMEM,
	                                                               "out of memory");
	if (ret == 0)
		ret = camera_side(field, opt, &b, err);
	int n = ret == 0 ? calib_pair_map(&a, &b, opt->pairing, map, &alias) : 0;
	if (ret == 0 && n == a.n && n == b.n)
		ret = calib_pair_check(&a, &b, opt->pairing, 1, opt->option, &r, err);
	calib_pair_result_free(&r);
	calib_pair_side_free(&a);
	calib_pair_side_free(&b);
	free(map);
	return ret;
}

/* The chart's reflectance spectra from CGATS (SPEC_*) or from a `patch,name,<nm>...`
 * CSV table. */
static int read_spectra(const char *path, kg_patchset **out, kg_err *err)
{
	if (has_suffix(path, ".csv"))
		return kg_csv_read_spectra_rows(path, KG_PATCH_REFLECTANCE, out, err);
	return kg_patchset_read(path, KG_PATCH_REFLECTANCE, out, err);
}

int kg_reference_fit_files(const char *spectra_path, const char *rgb_path,
                           const char *field_rgb_path, const kg_reference_options *opt,
                           kg_reference **out, kg_err *err)
{
	kg_check_arg(spectra_path && rgb_path && opt && out, err);
	*out = NULL;
	kg_patchset *spectra = NULL, *rgb = NULL, *field = NULL, *train = NULL;
	kg_reference *ref = NULL;
	int ret = read_spectra(spectra_path, &spectra, err);
	if (ret == 0)
		ret = calib_check_encoding(rgb_path, err);
	if (ret == 0 && field_rgb_path)
		ret = calib_check_encoding(field_rgb_path, err);
	if (ret == 0)
		ret = kg_patchset_read(rgb_path, 0, &rgb, err);
	if (ret == 0 && field_rgb_path)
		ret = kg_patchset_read(field_rgb_path, 0, &field, err);
	if (ret == 0 && !spectra->source && !(spectra->source = strdup(spectra_path)))
		ret = KG_ENOMEM;
	if (ret == 0 && !rgb->source && !(rgb->source = strdup(rgb_path)))
		ret = KG_ENOMEM;
	if (ret == 0 && field && !field->source && !(field->source = strdup(field_rgb_path)))
		ret = KG_ENOMEM;
	if (ret == KG_ENOMEM)
		kg_fail(err, ret, "out of memory");
	const char *rule = NULL;
	kg_pair_options popt = {opt->id_pairing, opt->exclude, opt->nexclude,
	                        opt->id_pairing_option};
	kg_pairing_record rec = {.misfit = NAN};
	if (ret == 0)
		ret = kg_calib_pair_checked(spectra, rgb, &popt, &train, &rec, &rule, err);
	if (ret == 0 && field)
		ret = check_field(spectra, field, &popt, err);
	if (ret == 0)
		ret = kg_reference_fit(train, field ? field : rgb, opt, &ref, err);
	if (ret == 0 && rule)
		snprintf(ref->id_rule, sizeof(ref->id_rule), "%s", rule);
	if (ret == 0) {
		ref->pairing = rec;
		memset(&rec, 0, sizeof(rec));
	}
	kg_pairing_record_free(&rec);
	if (ret == 0)
		ret = calib_source_add(&ref->sources, &ref->nsources, "spectra", spectra_path, err);
	if (ret == 0)
		ret = calib_source_add(&ref->sources, &ref->nsources, "rgb", rgb_path, err);
	if (ret == 0 && field_rgb_path)
		ret = calib_source_add(&ref->sources, &ref->nsources, "field_rgb", field_rgb_path,
		                       err);
	kg_patchset_free(&spectra);
	kg_patchset_free(&rgb);
	kg_patchset_free(&field);
	kg_patchset_free(&train);
	if (ret) {
		kg_reference_free(&ref);
		return ret;
	}
	*out = ref;
	return 0;
}
