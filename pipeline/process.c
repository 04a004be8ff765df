/* kogei process: a recorded session in, calibration, maps, scenes and report out
 * (kg_pipeline.h). This file reads the session and its images and runs the steps;
 * process_calib.c finds the chart and calibrates, process_object.c does each object. */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "kg_config.h"
#include "pipeline_private.h"

void kg_process_options_default(kg_process_options *o)
{
	memset(o, 0, sizeof(*o));
	o->max_residual = KG_PROCESS_MAX_RESIDUAL;
	o->angle_deg = 30.0;
	o->method = "camera";
	o->angles[0] = 0;
	o->angles[1] = 70;
	o->angles[2] = 5;
	o->intensity[0] = 0.3;
	o->intensity[1] = 1.0;
	o->render = 1;
	o->cube = "f32";
}

void proc_progress(proc *p, const char *fmt, ...)
{
	if (!p->o->progress)
		return;
	va_list ap;
	va_start(ap, fmt);
	fputs("kogei process: ", p->o->progress);
	vfprintf(p->o->progress, fmt, ap);
	fputc('\n', p->o->progress);
	fflush(p->o->progress);
	va_end(ap);
}

void proc_warn(proc *p, json_t *list, const char *fmt, ...)
{
	char msg[1024];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	/* each warning once, in its scope's list: the session's or its object's */
	json_array_append_new(list ? list : p->warnings, kg_json_message(msg));
	if (p->o->progress)
		fprintf(p->o->progress, "kogei process: warning: %s\n", msg);
}

int proc_input(proc *p, const char *role, const char *path, const char *expected)
{
	char hex[65];
	int ret = kg_file_sha256(path, hex, p->err);
	if (ret)
		return ret;
	if (expected && strcmp(expected, hex))
		return kg_fail(p->err, KG_EIO, "%s: sha256 %s, but %s records %s: the file changed "
		               "after it was recorded", path, hex, p->manifest_path, expected);
	char *abs = realpath(path, NULL); /* provenance: where it is, not where we ran */
	json_t *in = json_pack("{s:s, s:s, s:s}", "role", role, "path", abs ? abs : path,
	                       "sha256", hex);
	if (in && abs && strcmp(abs, path))
		json_object_set_new(in, "given", json_string(path));
	free(abs);
	json_array_append_new(p->inputs, in);
	return 0;
}

int kg_process_warning_count(const json_t *pj)
{
	size_t n = json_array_size(json_object_get(pj, "warnings")), i;
	const json_t *obj;
	json_array_foreach(json_object_get(pj, "objects"), i, obj)
		n += json_array_size(json_object_get(obj, "warnings"));
	return (int)n;
}

/* Records (docs/process.md): each object gets its own capture's "meta", the chart's
 * capture its own (calibration.meta); the run's "meta" is only what the command was
 * given (--meta), never a merge of the objects' (two objects' records are two). */
static json_t *meta_records(const proc *p, json_t *objects)
{
	json_t *all = p->o->meta ? json_deep_copy(p->o->meta) : json_object(), *obj;
	const json_t *cm = p->chart ? json_object_get(p->chart->j, "meta") : NULL;
	if (json_is_object(cm) && json_object_size(cm) && p->calibration)
		json_object_set_new(p->calibration, "meta", json_deep_copy(cm));
	size_t k;
	json_array_foreach(objects, k, obj)
	{
		const char *name = json_string_value(json_object_get(obj, "capture"));
		json_t *m = NULL;
		for (int i = 0; name && i < p->ncaps && !m; i++)
			if (!strcmp(p->caps[i].name, name))
				m = json_object_get(p->caps[i].j, "meta");
		json_object_set_new(obj, "meta", json_is_object(m) ? json_deep_copy(m) : json_object());
	}
	return all;
}

/* ---- the session's manifest --------------------------------------------------- */

static const json_t *find_camera(const json_t *manifest, const char *id)
{
	const json_t *c;
	size_t i;
	json_array_foreach(kg_json_find(manifest, "devices.cameras"), i, c)
	{
		const char *cid = json_string_value(json_object_get(c, "id"));
		if (id && cid && !strcmp(cid, id))
			return c;
	}
	return NULL;
}

/* --skip: the named captures left out of the run (as if not in the session), each
 * of which must be in it. */
static int skip_captures(proc *p)
{
	for (int k = 0; k < p->o->nskip; k++) {
		int found = 0;
		for (int i = 0; i < p->ncaps && !found; i++)
			found = !strcmp(p->caps[i].name, p->o->skip[k]);
		if (!found)
			return kg_fail(p->err, KG_EINVAL, "--skip %s: %s has no capture of that name",
			               p->o->skip[k], p->manifest_path);
	}
	int n = 0;
	for (int i = 0; i < p->ncaps; i++) {
		int skip = 0;
		for (int k = 0; k < p->o->nskip && !skip; k++)
			skip = !strcmp(p->caps[i].name, p->o->skip[k]);
		if (skip) {
			json_array_append_new(p->skipped, json_pack("{s:s, s:s}", "capture",
			                      p->caps[i].name, "kind",
			                      kg_capture_kind_name(p->caps[i].kind)));
			proc_progress(p, "%s: left out (--skip)", p->caps[i].name);
		} else {
			p->caps[n++] = p->caps[i];
		}
	}
	p->ncaps = n;
	return 0;
}

static int read_captures(proc *p)
{
	const json_t *list = json_object_get(p->manifest, "captures");
	if (!json_is_array(list))
		return kg_fail(p->err, KG_EINVAL, "%s: key 'captures': expected an array",
		               p->manifest_path);
	p->ncaps = (int)json_array_size(list);
	p->caps = calloc((size_t)(p->ncaps ? p->ncaps : 1), sizeof(*p->caps));
	if (!p->caps)
		return kg_fail(p->err, KG_ENOMEM, "out of memory");
	for (int i = 0; i < p->ncaps; i++) {
		proc_capture *c = &p->caps[i];
		const char *kind, *cam_id = NULL;
		c->j = json_array_get(list, (size_t)i);
		int ret = kg_json_get_string(p->manifest_path, c->j, "name", &c->name, p->err);
		if (!ret)
			ret = kg_json_get_string(p->manifest_path, c->j, "kind", &kind, p->err);
		if (!ret)
			ret = kg_capture_kind_parse(kind, &c->kind, p->err);
		if (ret) {
			kg_err_prefix(p->err, "%s: capture %d: ", p->manifest_path, i + 1);
			return ret;
		}
		cam_id = json_string_value(json_object_get(c->j, "camera"));
		c->camera = find_camera(p->manifest, cam_id);
		const json_t *s = json_object_get(c->j, "settings");
		const json_t *e = kg_json_find(s, "exposure_us"), *g = kg_json_find(s, "gain");
		const char *unit = json_string_value(kg_json_find(s, "gain_unit"));
		c->exposure_us = json_is_number(e) && json_number_value(e) > 0 ? json_number_value(e)
		                                                               : NAN;
		c->gain_linear = NAN;
		c->gain = json_is_number(g) ? json_number_value(g) : NAN;
		c->gain_unit = unit;
		if (json_is_number(g) && unit && !strcmp(unit, "dB"))
			c->gain_linear = pow(10.0, json_number_value(g) / 20.0);
		/* A photographic camera (raw files, gphoto2:): its gain is the ISO speed, and
		 * the aperture sets the light on the sensor. */
		const json_t *iso = kg_json_find(s, "iso"), *fno = kg_json_find(s, "aperture");
		if (!json_is_number(g) && json_is_number(iso) && json_number_value(iso) > 0) {
			c->gain = json_number_value(iso);
			c->gain_unit = "ISO";
			c->gain_linear = c->gain / 100.0;
		}
		c->aperture = json_is_number(fno) && json_number_value(fno) > 0 ? json_number_value(fno)
		                                                               : NAN;
		c->frames = (long)json_number_value(kg_json_find(s, "frames"));
		c->pixfmt = json_string_value(kg_json_find(s, "format.pixfmt"));
		c->cfa = json_string_value(kg_json_find(s, "format.cfa"));
		c->bits = (long)json_number_value(kg_json_find(s, "format.bits"));
		c->width = (long)json_number_value(kg_json_find(s, "format.width"));
		c->height = (long)json_number_value(kg_json_find(s, "format.height"));
		c->dark = json_string_value(kg_json_find(c->j, "corrections.dark"));
		c->flat = json_string_value(kg_json_find(c->j, "corrections.flat"));
	}
	return skip_captures(p);
}

/* ---- a capture's image ----------------------------------------------------------- */

void proc_image_clear(proc_image *img)
{
	kg_image_free(&img->rgb);
	kg_image_free(&img->variance);
	memset(img, 0, sizeof(*img));
}

static int same_format(const proc_capture *a, const proc_capture *b)
{
	return a->pixfmt && b->pixfmt && !strcmp(a->pixfmt, b->pixfmt) && a->bits == b->bits &&
	       a->width == b->width && a->height == b->height &&
	       ((!a->cfa && !b->cfa) || (a->cfa && b->cfa && !strcmp(a->cfa, b->cfa)));
}

static json_t *num_or_null(double v)
{
	return isfinite(v) ? json_real(v) : json_null();
}

json_t *proc_capture_making(const proc_capture *c)
{
	const json_t *alg = kg_json_find(c->j, "demosaic.algorithm");
	const json_t *dec = kg_json_find(c->j, "sources.decoding");
	const char *mine = kg_demosaic_algorithm();
	int mosaic = c->pixfmt && !strncmp(c->pixfmt, "bayer", 5);
	return json_pack("{s:o, s:o, s:o, s:o, s:o}", "gain", num_or_null(c->gain), "gain_unit",
	                 json_string(c->gain_unit ? c->gain_unit : ""),
	                 "aperture", num_or_null(c->aperture), "demosaic",
	                 json_is_string(alg) ? json_deep_copy(alg)
	                 : mosaic && mine   ? json_string(mine)
	                                    : json_null(),
	                 "raw_decoding", json_is_string(dec) ? json_deep_copy(dec) : json_null());
}

int proc_same_camera(const proc_capture *a, const proc_capture *b)
{
	if (!a->camera || !b->camera)
		return a->camera == b->camera;
	static const char *const keys[] = {"backend", "model", "serial"};
	for (int k = 0; k < 3; k++) {
		const char *x = json_string_value(json_object_get(a->camera, keys[k]));
		const char *y = json_string_value(json_object_get(b->camera, keys[k]));
		if (!x || !y || strcmp(x, y))
			return 0;
	}
	return 1;
}

int proc_dark_matches(const proc_capture *d, const proc_capture *c)
{
	return d->kind == KG_CAPTURE_DARK && proc_same_camera(d, c) && same_format(d, c) &&
	       fabs(d->exposure_us - c->exposure_us) <= 1e-6 * c->exposure_us &&
	       (d->gain_linear == c->gain_linear ||
	        (isnan(d->gain_linear) && isnan(c->gain_linear) &&
	         ((isnan(d->gain) && isnan(c->gain)) || d->gain == c->gain)));
}

const proc_capture *proc_capture_named(const proc *p, const char *name)
{
	for (int i = 0; name && i < p->ncaps; i++)
		if (!strcmp(p->caps[i].name, name))
			return &p->caps[i];
	return NULL;
}

/* The latest dark of the session for c: same camera, format, exposure and gain. */
const proc_capture *proc_matching_dark(const proc *p, const proc_capture *c)
{
	const proc_capture *best = NULL;
	for (int i = 0; i < p->ncaps; i++)
		if (proc_dark_matches(&p->caps[i], c))
			best = &p->caps[i];
	return best;
}

const proc_capture *proc_matching_flat(const proc *p, const proc_capture *c)
{
	const proc_capture *best = NULL;
	for (int i = 0; i < p->ncaps; i++)
		if (p->caps[i].kind == KG_CAPTURE_FLAT && proc_same_camera(&p->caps[i], c) &&
		    same_format(&p->caps[i], c))
			best = &p->caps[i];
	return best;
}

/* ---- previews -------------------------------------------------------------------- */

/* The photograph's preview, built as its rows pass: every step-th pixel of every
 * step-th row (step the smallest that fits max_side), and, for the white point, every
 * stride-th sample of the image's samples in file order, up to PREVIEW_SAMPLES. */
#define PREVIEW_SAMPLES 65536

struct proc_preview {
	int w, h, step, ow, oh;
	float *px;        /* ow x oh x 3 */
	float *samp;
	int nsamp;
	size_t stride, next_sample; /* the next sample index to take */
};

int proc_preview_new(int width, int height, int max_side, proc_preview **out, kg_err *err)
{
	*out = NULL;
	proc_preview *pv = calloc(1, sizeof(*pv));
	if (!pv)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	pv->w = width;
	pv->h = height;
	pv->step = 1;
	while ((width + pv->step - 1) / pv->step > max_side ||
	       (height + pv->step - 1) / pv->step > max_side)
		pv->step++;
	pv->ow = (width + pv->step - 1) / pv->step;
	pv->oh = (height + pv->step - 1) / pv->step;
	pv->px = malloc(sizeof(float) * 3 * (size_t)pv->ow * (size_t)pv->oh);
	pv->samp = malloc(sizeof(float) * PREVIEW_SAMPLES);
	pv->stride = (size_t)width * (size_t)height * 3 / PREVIEW_SAMPLES + 1;
	if (!pv->px || !pv->samp) {
		proc_preview_free(&pv);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	*out = pv;
	return 0;
}

void proc_preview_free(proc_preview **pv)
{
	if (pv && *pv) {
		free((*pv)->px);
		free((*pv)->samp);
		free(*pv);
		*pv = NULL;
	}
}

void proc_preview_rows(proc_preview *pv, int y0, int rows, const float *rgb)
{
	size_t row = (size_t)pv->w * 3, first = (size_t)y0 * row, end = first + rows * row;
	for (; pv->nsamp < PREVIEW_SAMPLES && pv->next_sample < end; pv->next_sample += pv->stride)
		if (isfinite(rgb[pv->next_sample - first]))
			pv->samp[pv->nsamp++] = rgb[pv->next_sample - first];
	for (int y = y0 + (pv->step - y0 % pv->step) % pv->step; y < y0 + rows; y += pv->step)
		for (int x = 0; x < pv->ow; x++)
			memcpy(pv->px + ((size_t)(y / pv->step) * pv->ow + x) * 3,
			       rgb + (size_t)(y - y0) * row + (size_t)x * pv->step * 3, 3 * sizeof(float));
}

static int cmp_float_asc(const void *a, const void *b)
{
	float x = *(const float *)a, y = *(const float *)b;
	return (x > y) - (x < y);
}

double proc_preview_quantile(proc_preview *pv, double q)
{
	if (pv->nsamp <= 0)
		return NAN;
	qsort(pv->samp, (size_t)pv->nsamp, sizeof(float), cmp_float_asc);
	return pv->samp[(int)(q * (pv->nsamp - 1))];
}

int proc_preview_write(proc_preview *pv, const char *path, kg_err *err)
{
	/* white point: the 99.5th percentile of the samples */
	double white = 1.0;
	float *samp = pv->samp;
	int nsamp = pv->nsamp;
	if (nsamp > 0) {
		/* up to PREVIEW_SAMPLES values: sorted in O(n log n) (an insertion sort of 65536
		 * took a fifth of kogei process on the demo session) */
		int k = (int)(0.995 * (nsamp - 1));
		qsort(samp, (size_t)nsamp, sizeof(float), cmp_float_asc);
		white = samp[k] > 1e-6 ? samp[k] / 0.9 : 1.0;
	}
	size_t n = (size_t)pv->ow * (size_t)pv->oh;
	unsigned char *out = malloc(n * 3);
	if (!out)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (size_t i = 0; i < n; i++) {
		const float *px = pv->px + 3 * i;
		unsigned char *o = out + 3 * i;
		if (!isfinite(px[0]) || !isfinite(px[1]) || !isfinite(px[2])) {
			o[0] = 128, o[1] = 0, o[2] = 128;
			continue;
		}
		kg_rgb c = {fmin(fmax(px[0] / white, 0), 1), fmin(fmax(px[1] / white, 0), 1),
		            fmin(fmax(px[2] / white, 0), 1)};
		kg_rgb_to_u8(kg_srgb_encode(c), o);
	}
	int ret = kg_png_write_rgb8(path, out, pv->ow, pv->oh, err);
	free(out);
	return ret;
}

int proc_preview_png(const kg_image *rgb, const char *path, int max_side, kg_err *err)
{
	proc_preview *pv = NULL;
	int ret = proc_preview_new(rgb->width, rgb->height, max_side, &pv, err);
	if (!ret) {
		proc_preview_rows(pv, 0, rgb->height, rgb->data);
		ret = proc_preview_write(pv, path, err);
	}
	proc_preview_free(&pv);
	return ret;
}

/* The devices: the session's cameras, and the spectrophotometer that measured the
 * chart, from the keywords of its spectra file (kogei measure writes them). */
static json_t *devices_json(const proc *p)
{
	json_t *d = json_deep_copy(json_object_get(p->manifest, "devices"));
	if (!json_is_object(d)) {
		json_decref(d);
		d = json_object();
	}
	if (!json_is_array(json_object_get(d, "cameras")))
		json_object_set_new(d, "cameras", json_array());
	if (json_is_array(json_object_get(d, "spectrometers")))
		return d;
	json_t *list = json_array();
	const char *path = json_string_value(kg_json_find(p->calibration, "spectra_source"));
	kg_cgats *cg = NULL;
	kg_err e = {{0}};
	if (path && kg_cgats_read(path, &cg, &e) == 0 && cg->ntables > 0) {
		static const char *const keys[] = {"INSTRUMENT", "SERIAL_NUMBER", "INTEGRATION_TIME_US",
		                                   "SCANS_AVERAGED", "WHITE_REFERENCE",
		                                   "MEASUREMENT_MODE", "CREATED"};
		json_t *o = json_pack("{s:s}", "spectra", path);
		for (size_t k = 0; k < sizeof(keys) / sizeof(keys[0]); k++) {
			const char *v = kg_cgats_keyword(cg->tables[0], keys[k]);
			if (v)
				json_object_set_new(o, keys[k], json_string(v));
		}
		json_array_append_new(list, o);
	}
	kg_cgats_free(&cg);
	json_object_set_new(d, "spectrometers", list);
	return d;
}

/* ---- the run ----------------------------------------------------------------------- */

static void proc_free(proc *p)
{
	free(p->manifest_path);
	json_decref(p->manifest);
	free(p->caps);
	json_decref(p->inputs);
	json_decref(p->warnings);
	json_decref(p->skipped);
	kg_chart_layout_free(&p->layout);
	free(p->layout_path);
	kg_reference_free(&p->ref);
	kg_camera_calib_free(&p->cam);
	json_decref(p->calibration);
	json_decref(p->calib_key);
	free(p->library_path);
	kg_est_material_set_free(&p->set);
	kg_material_library_free(&p->lib);
	json_decref(p->previous);
}

static json_t *jstr_or_null(const char *s)
{
	return s ? json_string(s) : json_null();
}

static json_t *parameters_base(const kg_process_options *o, const char *materials)
{
	json_t *only = json_null();
	if (o->nonly > 0) {
		only = json_array();
		for (int i = 0; i < o->nonly; i++)
			json_array_append_new(only, json_string(o->only[i]));
	}
	json_t *skip = json_array();
	for (int i = 0; i < o->nskip; i++)
		json_array_append_new(skip, json_string(o->skip[i]));
	return json_pack("{s:o, s:o, s:s, s:o, s:o, s:o, s:o, s:f, s:i, s:b, s:b, s:f, s:o, s:s, "
	                 "s:s, s:[fff], s:[ff], s:o}",
	                 "reference", jstr_or_null(o->reference), "spectra", jstr_or_null(o->spectra),
	                 "materials", materials, "only", only, "layout", jstr_or_null(o->layout),
	                 "mesh", jstr_or_null(o->mesh), "mask", jstr_or_null(o->mask),
	                 "max_residual", o->max_residual, "min_tags", o->min_tags, "force", o->force,
	                 "assume_same_exposure", o->assume_same_exposure, "angle_deg", o->angle_deg,
	                 "chart", jstr_or_null(o->chart), "cube", o->cube ? o->cube : "f32",
	                 "method", o->method ? o->method : "camera", "angles", o->angles[0],
	                 o->angles[1], o->angles[2], "intensity", o->intensity[0], o->intensity[1],
	                 "skip", skip);
}

static json_t *parameters_json(const kg_process_options *o, const char *materials)
{
	json_t *p = parameters_base(o, materials);
	if (p) /* the access copy and the manifests (access.c) */
		json_object_set_new(p, "access",
		                    json_pack("{s:s, s:o, s:o, s:s, s:o}", "compression",
		                              o->access_compression ? o->access_compression : "jpeg",
		                              "quality", jstr_or_null(o->access_quality), "iiif_base",
		                              jstr_or_null(o->iiif_base), "iiif_image_api",
		                              o->iiif_image_api ? o->iiif_image_api : "3",
		                              "files_base", jstr_or_null(o->files_base)));
	return p;
}

static void iso_time(char *buf, size_t n)
{
	time_t t = time(NULL);
	struct tm tm;
	gmtime_r(&t, &tm);
	strftime(buf, n, "%Y-%m-%dT%H:%M:%SZ", &tm);
}

int kg_process_run(const kg_process_options *o, kg_process_summary *summary, kg_err *err)
{
	kg_check_arg(o && o->session && o->outdir && (o->reference || o->spectra), err);
	if (o->cube && strcmp(o->cube, "f32") && strcmp(o->cube, "f16") &&
	    strcmp(o->cube, "weights") && strcmp(o->cube, "none"))
		return kg_fail(err, KG_EINVAL, "cube format '%s': expected f32, f16, weights or none",
		               o->cube);
	int bad = kg_process_access_check(o, err);
	if (bad)
		return bad;
	struct timespec t0, t1;
	clock_gettime(CLOCK_MONOTONIC, &t0);
	kg_process_summary sum = {0};
	proc p = {.o = o, .err = err, .lock_fd = -1};
	json_t *objects = json_array(), *root = NULL;
	p.inputs = json_array();
	p.warnings = json_array();
	p.skipped = json_array();
	p.manifest_path = kg_path_join(o->session, KG_SESSION_MANIFEST);
	int ret = p.manifest_path && objects && p.inputs && p.warnings && p.skipped
	              ? 0 : kg_fail(err, KG_ENOMEM, "out of memory");
	if (!ret && access(p.manifest_path, R_OK) != 0)
		ret = kg_fail(err, KG_ENOENT, "%s: not a kogei session (no readable %s)", o->session,
		              KG_SESSION_MANIFEST);
	if (!ret)
		ret = kg_json_load(p.manifest_path, &p.manifest, err);
	if (!ret) {
		const char *f = json_string_value(json_object_get(p.manifest, "format"));
		if (!f || strcmp(f, KG_SESSION_FORMAT))
			ret = kg_fail(err, KG_EINVAL, "%s: key 'format': expected \"%s\"", p.manifest_path,
			              KG_SESSION_FORMAT);
	}
	if (!ret)
		ret = kg_session_manifest_validate(p.manifest_path, p.manifest, err);
	if (!ret)
		ret = kg_file_sha256(p.manifest_path, p.manifest_sha, err);
	if (!ret)
		ret = read_captures(&p);
	if (!ret)
		ret = proc_outdir_open(&p);
	if (!ret) {
		proc_progress(&p, "session %s: %d captures", o->session, p.ncaps);
		ret = proc_calibrate(&p);
	}
	if (!ret)
		ret = proc_objects(&p, objects, &sum);
	if (!ret) {
		char created[32];
		iso_time(created, sizeof(created));
		const char *recorded = json_string_value(json_object_get(p.manifest, "created"));
		root = json_pack("{s:s, s:s, s:{s:s, s:s}, s:{s:s, s:s, s:s, s:o}, s:o, s:O, s:o, "
		                 "s:O, s:O, s:O, s:O}",
		                 "format", KG_PROCESS_FORMAT, "created", created, "software", "name",
		                 "kogei", "version", KG_VERSION, "session", "path", o->session,
		                 "realpath", p.session_abs, "manifest_sha256", p.manifest_sha,
		                 "created", recorded ? json_string(recorded) : json_null(),
		                 "parameters",
		                 parameters_json(o, p.library_path), "inputs", p.inputs, "devices",
		                 devices_json(&p), "calibration", p.calibration,
		                 "calibration_key", p.calib_key, "objects", objects, "warnings",
		                 p.warnings);
		if (!root)
			ret = kg_fail(err, KG_ENOMEM, "out of memory");
		if (!ret && o->command)
			json_object_set_new(root, "command", json_string(o->command));
		const json_t *sid = json_object_get(p.manifest, "id");
		if (!ret && json_is_string(sid))
			json_object_set(json_object_get(root, "session"), "id", (json_t *)sid);
		if (!ret)
			json_object_set(root, "skipped_captures", p.skipped);
		if (!ret)
			json_object_set_new(root, "meta", meta_records(&p, objects));
		if (!ret)
			json_object_set_new(root, "warning_count",
			                    json_integer(kg_process_warning_count(root)));
	}
	if (!ret)
		ret = proc_outdir_commit(&p, root);
	if (!ret)
		proc_progress(&p, "wrote %s/process.json and %s/report.html", o->outdir, o->outdir);
	proc_outdir_close(&p, ret != 0);
	clock_gettime(CLOCK_MONOTONIC, &t1);
	sum.seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
	sum.warnings = kg_process_warning_count(root);
	sum.residual = p.cam ? p.cam->residual_relative : NAN;
	if (summary)
		*summary = sum;
	json_decref(root);
	json_decref(objects);
	proc_free(&p);
	return ret;
}
