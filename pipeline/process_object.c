/* kogei process, the objects: each object capture checked against the chart's camera,
 * normalised by exposure, estimated, classified, previewed and given a scene; written
 * into a temporary folder renamed into place when complete; skipped when its inputs
 * and parameters have not changed since the last run (kg_pipeline.h); the run puts
 * the folders in place when every one is complete (process_outdir.c). */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "kg_gltf.h"
#include "kg_render.h"
#include "pipeline_private.h"

/* Warned above these (fractions of the object's pixels, of full scale). */
#define PROC_MAX_CLIPPED 0.01
#define PROC_BLACK_LEVEL 0.01
#define PROC_UNDER_LEVEL 0.5
/* A pixel is lit when a channel is above this many sigmas of its noise. */
#define PROC_LIT_SIGMAS 5.0
/* label warnings: unknown pixels among the object's, background pixels in the frame */
#define PROC_UNKNOWN_SHARE 0.25
#define PROC_BACKGROUND_SHARE 0.99

static const char *cam_str(const proc_capture *c, const char *key)
{
	const char *v = c->camera ? json_string_value(json_object_get(c->camera, key)) : NULL;
	return v ? v : "?";
}

/* The object's camera against the chart's: the same device and pixel format. */
static int check_camera(proc *p, const proc_capture *c, json_t *warnings)
{
	const proc_capture *k = p->chart;
	int same = proc_same_camera(c, k) && c->pixfmt && k->pixfmt && !strcmp(c->pixfmt, k->pixfmt) &&
	           c->bits == k->bits;
	if (same)
		return 0;
	char what[640];
	snprintf(what, sizeof(what), "capture %s was taken with %s %s (serial %s, %s %ld bits), the "
	         "chart capture %s with %s %s (serial %s, %s %ld bits)",
	         c->name, cam_str(c, "backend"), cam_str(c, "model"), cam_str(c, "serial"),
	         c->pixfmt ? c->pixfmt : "?", c->bits, k->name, cam_str(k, "backend"),
	         cam_str(k, "model"), cam_str(k, "serial"), k->pixfmt ? k->pixfmt : "?", k->bits);
	if (!p->o->force)
		return kg_fail(p->err, KG_EINVAL, "%s: the calibration is another camera's (--force "
		               "to use it anyway)", what);
	proc_warn(p, warnings, "%s; used anyway (--force)", what);
	return 0;
}

/* The chart's gain over c's, as a factor on the signal: from dB, or 1 when both
 * record the same value in the same other unit (a replayed camera's "recorded"); NAN
 * when it cannot be known. */
static double gain_ratio(const proc_capture *chart, const proc_capture *c)
{
	if (isfinite(chart->gain_linear) && isfinite(c->gain_linear))
		return chart->gain_linear / c->gain_linear;
	if (isfinite(chart->gain) && chart->gain == c->gain && chart->gain_unit && c->gain_unit &&
	    !strcmp(chart->gain_unit, c->gain_unit))
		return 1.0;
	return NAN;
}

/* The background capture for object c (the scene without it): the session's latest
 * background capture before c of the same camera and size, else the first after it;
 * NULL when there is none. */
static const proc_capture *background_of(const proc *p, const proc_capture *c)
{
	const proc_capture *before = NULL, *after = NULL;
	int seen = 0;
	for (int i = 0; i < p->ncaps; i++) {
		const proc_capture *b = &p->caps[i];
		if (b == c)
			seen = 1;
		if (b->kind != KG_CAPTURE_BACKGROUND || !proc_same_camera(b, c) ||
		    b->width != c->width || b->height != c->height)
			continue;
		if (!seen)
			before = b;
		else if (!after)
			after = b;
	}
	return before ? before : after;
}

/* Camera values of c relative to the chart capture's: (t g / N^2)_chart over the
 * object's, N the f-number where both record one. --assume-same-exposure fills in only
 * what is not recorded (an exposure time or a gain taken as equal, ratio 1); what is
 * recorded still scales the values. */
static int exposure_scale(proc *p, const proc_capture *c, json_t *warnings, double *scale)
{
	const proc_capture *k = p->chart;
	double t = k->exposure_us / c->exposure_us, g = gain_ratio(k, c);
	int t_ok = isfinite(t) && t > 0, g_ok = isfinite(g) && g > 0;
	if ((!t_ok || !g_ok) && !p->o->assume_same_exposure)
		return kg_fail(p->err, KG_EINVAL, "capture %s: %s not recorded for it or for the "
		               "chart capture %s, so its values cannot be normalised to the chart's; "
		               "--assume-same-exposure if they were equal",
		               c->name, !t_ok && !g_ok ? "exposure time and gain (dB or ISO)"
		               : !t_ok        ? "exposure time"
		                              : "gain (dB or ISO)",
		               k->name);
	*scale = (t_ok ? t : 1) * (g_ok ? g : 1);
	if (isfinite(k->aperture) && isfinite(c->aperture) &&
	    fabs(k->aperture - c->aperture) > 1e-6 * k->aperture) {
		double a = (c->aperture / k->aperture) * (c->aperture / k->aperture);
		*scale *= a;
		proc_warn(p, warnings, "capture %s: aperture f/%g, the chart capture %s f/%g: "
		          "values scaled by %.4g for the aperture; marked f-numbers are nominal "
		          "(a lens may be off by a sixth of a stop, 8 %%), so the reflectance "
		          "scale is uncertain by as much: shoot the chart and the object at one "
		          "aperture", c->name, c->aperture, k->name, k->aperture, a);
	}
	if (!t_ok || !g_ok)
		proc_warn(p, warnings, "capture %s: %s unknown (not recorded for it or for the chart "
		          "capture %s), assumed equal to the chart capture's "
		          "(--assume-same-exposure); values scaled by %.6g%s",
		          c->name, !t_ok && !g_ok ? "exposure time and gain" : !t_ok ? "exposure time"
		                                                              : "gain",
		          k->name, *scale,
		          t_ok ? " for the recorded exposure times" : g_ok ? " for the recorded gains" : "");
	return 0;
}

const char *proc_cube_name(const proc *p)
{
	return p->o->cube ? p->o->cube : "f32";
}

int proc_cube_format(const proc *p, kg_est_format *format)
{
	const char *name = proc_cube_name(p);
	*format = !strcmp(name, "f16") ? KG_EST_F16_BSQ
	          : !strcmp(name, "weights") ? KG_EST_WEIGHTS : KG_EST_F32_BSQ;
	return strcmp(name, "none") != 0;
}

/* The last part of a path (the library's content is in the calibration key's inputs). */
static const char *file_name(const char *path)
{
	const char *slash = path ? strrchr(path, '/') : NULL;
	return slash ? slash + 1 : path ? path : "";
}

/* What an object's result depends on; equal keys mean the files can be kept. */
static json_t *object_key(proc *p, const proc_capture *c)
{
	json_t *key = json_pack("{s:O, s:s, s:O, s:O, s:o, s:s}", "calibration", p->calib_key, "capture",
	                 c->name, "outputs", json_object_get(c->j, "outputs"), "corrections",
	                 json_object_get(c->j, "corrections"), "parameters",
	                 json_pack("{s:s, s:f, s:o, s:o, s:b, s:b, s:s, s:s, s:[fff], s:[ff]}",
	                           "materials", file_name(p->library_path), "angle_deg",
	                           p->o->angle_deg,
	                           "mesh", p->o->mesh ? json_string(p->o->mesh) : json_null(),
	                           "mask", p->o->mask ? json_string(p->o->mask)
	                                   : background_of(p, c) ? json_string(background_of(p, c)->name)
	                                                         : json_null(),
	                           "render", p->o->render, "assume_same_exposure",
	                           p->o->assume_same_exposure, "cube", proc_cube_name(p), "method",
	                           p->o->method ? p->o->method : "camera", "angles",
	                           p->o->angles[0], p->o->angles[1], p->o->angles[2], "intensity",
	                           p->o->intensity[0], p->o->intensity[1]),
	                 "session", json_string_value(json_object_get(p->manifest, "created"))
	                                ? json_string_value(json_object_get(p->manifest, "created"))
	                                : "");
	if (key) /* what the files say of the object (identity.c) */
		json_object_set_new(key, "identity", proc_identity(p, c));
	if (key) /* the master's space and illuminant (master.c); the third: what it writes
	          * (an object of a run that wrote no master_linear.tif is processed again) */
		json_object_set_new(json_object_get(key, "parameters"), "master",
		                    json_pack("[sss]", p->o->master_space ? p->o->master_space : "ecirgb-v2",
		                              p->o->master_illuminant ? p->o->master_illuminant : "D50",
		                              "master.tif master_linear.tif highlights"));
	if (key) /* the access copy and the manifest's ids (access.c, manifest.c) */
		json_object_set_new(json_object_get(key, "parameters"), "access",
		                    json_pack("[s, i, s*, s*, s*]", proc_access_compression(p),
		                              proc_access_quality(p), p->o->iiif_base,
		                              p->o->iiif_image_api, p->o->files_base));
	/* captures left out change the darks and flats at hand */
	if (key && p->o->nskip > 0) {
		json_t *skip = json_array();
		for (int i = 0; i < p->o->nskip; i++)
			json_array_append_new(skip, json_string(p->o->skip[i]));
		json_object_set_new(json_object_get(key, "parameters"), "skip", skip);
	}
	return key;
}

/* Bands of rows of a cube (every band, BIP: buf holds band rows of them) to a
 * function. */
static int envi_bands(const kg_envi *e, float *buf, int band,
                      int (*fn)(void *user, int y0, int rows, const float *v), void *user,
                      kg_err *err)
{
	int w = e->meta.samples, h = e->meta.lines, ret = 0;
	for (int y = 0; y < h && !ret; y += band) {
		int rows = h - y < band ? h - y : band;
		ret = kg_envi_read(e, 0, y, w, rows, KG_LAYOUT_BIP, buf, err);
		if (!ret)
			ret = fn(user, y, rows, buf);
	}
	return ret;
}

typedef struct conf_scan {
	int w, pass;
	int bands, band; /* the file's bands, the one shown */
	float lo, hi;
	long m, bins[1024];
	int step, ow;
	double top;
	unsigned char *out;
} conf_scan;

static int conf_band(void *user, int y0, int rows, const float *v)
{
	conf_scan *c = user;
	size_t n = (size_t)rows * c->w;
	/* the shown band, packed in place */
	float *p = (float *)v;
	for (size_t i = 0; c->bands > 1 && i < n; i++)
		p[i] = v[i * (size_t)c->bands + (size_t)c->band];
	v = p;
	if (c->pass == 0) {
		for (size_t i = 0; i < n; i++)
			if (isfinite(v[i])) {
				c->lo = c->m ? fminf(c->lo, v[i]) : v[i];
				c->hi = c->m ? fmaxf(c->hi, v[i]) : v[i];
				c->m++;
			}
	} else if (c->pass == 1) {
		for (size_t i = 0; i < n; i++)
			if (isfinite(v[i]))
				c->bins[c->hi > c->lo ? (int)((v[i] - c->lo) / (c->hi - c->lo) * 1023) : 0]++;
	} else {
		for (int y = y0 + (c->step - y0 % c->step) % c->step; y < y0 + rows; y += c->step)
			for (int x = 0; x < c->ow; x++) {
				float f = v[(size_t)(y - y0) * c->w + (size_t)x * c->step];
				unsigned char *o = c->out + ((size_t)(y / c->step) * c->ow + x) * 3;
				if (!isfinite(f)) {
					o[0] = 96, o[1] = 16, o[2] = 16;
					continue;
				}
				double t = fmin(fmax(f / c->top, 0), 1);
				o[0] = o[1] = o[2] = (unsigned char)lround(255 * t);
			}
	}
	return 0;
}

/* The confidence as a grey image at most max_side pixels on its longer side (every
 * step-th pixel, as the photograph's preview), not classified (NaN) dark red. A
 * one-band file (eq. 11: the margin): 0 black, the 95th percentile and up white; a
 * camera-space file (4 bands): its posterior band, 0 black to 1 white. Three passes
 * over the file: the range, a 1024-bin count over the range for the percentile, the
 * image. */
static int confidence_png(const char *hdr, const char *png, int max_side, kg_err *err)
{
	kg_envi *e = NULL;
	int ret = kg_envi_open(hdr, &e, err);
	if (ret)
		return ret;
	int w = e->meta.samples, h = e->meta.lines;
	conf_scan c = {.w = w, .step = 1, .bands = e->meta.bands, .band = e->meta.bands == 4};
	while ((w + c.step - 1) / c.step > max_side || (h + c.step - 1) / c.step > max_side)
		c.step++;
	c.ow = (w + c.step - 1) / c.step;
	int oh = (h + c.step - 1) / c.step;
	int band = (int)((1u << 20) / (unsigned)w) + 1;
	float *v = malloc(sizeof(float) * (size_t)w * (size_t)band * (size_t)c.bands);
	c.out = malloc(3 * (size_t)c.ow * (size_t)oh);
	if (!v || !c.out)
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	for (c.pass = 0; c.pass < 3 && !ret; c.pass++) {
		ret = envi_bands(e, v, band, conf_band, &c, err);
		if (c.pass == 1) {
			c.top = 1;
			if (c.m && c.bands == 1) {
				long acc = 0;
				int b = 0;
				while (b < 1023 && (acc += c.bins[b]) < (long)(0.95 * (double)c.m))
					b++;
				c.top = c.lo + (c.hi - c.lo) * (b + 1) / 1024.0;
				if (!(c.top > 0))
					c.top = c.hi > 0 ? c.hi : 1;
			}
		}
	}
	if (!ret)
		ret = kg_png_write_rgb8(png, c.out, c.ow, oh, err);
	free(v);
	free(c.out);
	kg_envi_close(&e);
	return ret;
}

static void render_progress(void *user, int done, int total)
{
	FILE *fp = user;
	/* a line at every quarter */
	if (fp && total > 0 && (4 * done / total) != (4 * (done - 1) / total))
		fprintf(fp, "kogei process: rendering: %d of %d tiles\n", done, total);
}

static int render_scene(proc *p, const kg_scene *s, const char *png)
{
	kg_image *xyz = NULL;
	kg_render_options ro = {.threads = p->o->threads, .progress = render_progress,
	                        .progress_user = p->o->progress};
	int ret = kg_render(s, &ro, &xyz, NULL, p->err);
	if (!ret)
		ret = kg_render_write_png(xyz, kg_scene_white(s), png, p->err);
	kg_image_free(&xyz);
	return ret;
}

/* The classes of labels.json with their library models, for process.json. */
static int classes_json(proc *p, const char *labels_json, const kg_est_material_set *set,
                        json_t *object, json_t *class_map, const char *fallback)
{
	json_t *lj = NULL;
	int ret = kg_json_load(labels_json, &lj, p->err);
	if (ret)
		return ret;
	json_t *out = json_array();
	const json_t *c;
	size_t i;
	double pixels = json_number_value(json_object_get(lj, "pixels"));
	json_object_set_new(object, "pixels", json_integer((json_int_t)pixels));
	json_object_set_new(object, "unknown_fraction", json_real(0));
	json_object_set_new(object, "background_fraction", json_real(0));
	json_array_foreach(json_object_get(lj, "classes"), i, c)
	{
		const char *name = json_string_value(json_object_get(c, "name"));
		double frac = json_number_value(json_object_get(c, "fraction"));
		if (!name)
			continue;
		if (!strcmp(name, "unclassified")) {
			json_object_set_new(object, "unclassified_fraction", json_real(frac));
			continue;
		}
		if (!strcmp(name, "unknown") || !strcmp(name, "background")) {
			char key[32];
			snprintf(key, sizeof(key), "%s_fraction", name);
			json_object_set_new(object, key, json_real(frac));
		}
		json_t *model = json_null();
		int found = 0;
		for (int j = 0; j < set->n; j++)
			if (!strcmp(set->names[j], name)) {
				found = 1;
				model = json_array();
				for (int b = 0; b < KG_NBANDS; b++)
					json_array_append_new(model, json_real(set->spectra[j].v[b]));
			}
		if (!found && strchr(name, '|')) {
			/* a compound class renders as its first member */
			char first[KG_EST_CLASS_NAME_MAX];
			snprintf(first, sizeof(first), "%.*s", (int)(strchr(name, '|') - name), name);
			json_object_set_new(class_map, name, json_string(first));
		} else if (!found) {
			json_object_set_new(class_map, name, json_string(fallback));
		}
		json_t *e = json_pack("{s:s, s:O, s:O, s:O, s:O, s:o}", "name", name, "pixels",
		                      json_object_get(c, "pixels"), "fraction",
		                      json_object_get(c, "fraction"), "colour",
		                      json_object_get(c, "colour") ? json_object_get(c, "colour")
		                                                   : json_null(),
		                      "mean_spectrum",
		                      json_object_get(c, "mean_spectrum") ? json_object_get(c, "mean_spectrum")
		                                                          : json_null(),
		                      "model_spectrum", model);
		json_array_append_new(out, e);
	}
	json_object_set_new(object, "classes", out);
	/* camera space: what the data can tell apart, the regions and their composition */
	json_t *sep = json_object_get(lj, "separability");
	if (sep)
		json_object_set_new(object, "separability",
		                    json_pack("{s:O,s:O,s:O}", "merge_distance",
		                              json_object_get(sep, "merge_distance"), "pairs",
		                              json_object_get(sep, "pairs_needing_pooling"), "merges",
		                              json_object_get(lj, "merges")));
	const char *keep[2] = {"regions", "composition"};
	for (int k = 0; k < 2; k++)
		if (json_object_get(lj, keep[k]))
			json_object_set(object, keep[k], json_object_get(lj, keep[k]));
	json_decref(lj);
	return 0;
}

/* What the labels do not know, as warnings (process.json's object and session lists,
 * the report, the summary): regions decided unknown, a large share of unknown pixels
 * among the object's (those not background or unclassified) or of background pixels
 * in the frame, and regions whose decided label is not in the class their pixels
 * hold. Regions of the table only (100 pixels or more); at most PROC_LABEL_LIST named
 * per warning. */
#define PROC_LABEL_LIST 8
static void add_warning(json_t *list, const char *fmt, ...) KG_PRINTF(2, 3);
static void add_warning(json_t *list, const char *fmt, ...)
{
	char msg[2048];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	json_array_append_new(list, json_string(msg));
}

json_t *proc_label_warnings(const char *capture, const json_t *object)
{
	json_t *warnings = json_array();
	if (!warnings)
		return NULL;
	double unk = json_number_value(json_object_get(object, "unknown_fraction"));
	double bg = json_number_value(json_object_get(object, "background_fraction"));
	double unc = json_number_value(json_object_get(object, "unclassified_fraction"));
	double obj = 1.0 - bg - unc;
	if (obj > 0 && unk / obj >= PROC_UNKNOWN_SHARE)
		add_warning(warnings, "capture %s: %.1f %% of the object's pixels are unknown "
		          "(%.1f %% of the frame): no declared material explains them within its "
		          "noise; declare the missing material or check the calibration",
		          capture, 100 * unk / obj, 100 * unk);
	if (bg >= PROC_BACKGROUND_SHARE)
		add_warning(warnings, "capture %s: %.1f %% of the pixels are background (masked "
		          "out or dark): the object covers little of the frame", capture, 100 * bg);
	const json_t *table = json_object_get(json_object_get(object, "regions"), "table");
	char unknown_list[512] = "", changed_list[1024] = "";
	int nunknown = 0, nchanged = 0;
	long unknown_px = 0;
	size_t i;
	const json_t *r;
	json_array_foreach(table, i, r)
	{
		const char *label = json_string_value(json_object_get(r, "label"));
		const char *pc = json_string_value(json_object_get(r, "pixel_class"));
		long id = (long)json_integer_value(json_object_get(r, "region"));
		long px = (long)json_integer_value(json_object_get(r, "pixels"));
		if (!label)
			continue;
		if (!strcmp(label, "unknown")) {
			if (nunknown < PROC_LABEL_LIST) {
				size_t u = strlen(unknown_list);
				snprintf(unknown_list + u, sizeof(unknown_list) - u, "%s%ld (%ld px%s%s)",
				         nunknown ? ", " : "", id, px, pc ? ", pixels " : "", pc ? pc : "");
			}
			nunknown++;
			unknown_px += px;
			continue;
		}
		/* a compound label is its class; a member is in it */
		int held = !pc || !strcmp(label, pc) || kg_class_holds(pc, label);
		if (!held) {
			if (nchanged < PROC_LABEL_LIST) {
				size_t u = strlen(changed_list);
				snprintf(changed_list + u, sizeof(changed_list) - u,
				         "%s%ld (%ld px): pixels %s, region %s", nchanged ? "; " : "", id, px,
				         pc, label);
			}
			nchanged++;
		}
	}
	if (nunknown)
		add_warning(warnings, "capture %s: %d region%s of 100 pixels or more decided "
		          "unknown (%ld pixels; no declared material explains the region within its "
		          "noise, calibration and model error): %s%s", capture, nunknown,
		          nunknown == 1 ? "" : "s", unknown_px, unknown_list,
		          nunknown > PROC_LABEL_LIST ? ", ..." : "");
	if (nchanged)
		add_warning(warnings, "capture %s: %d region%s decided otherwise than the class "
		          "%s pixels hold (the pooled likelihood over the region): %s%s", capture,
		          nchanged, nchanged == 1 ? "" : "s", nchanged == 1 ? "its" : "their",
		          changed_list, nchanged > PROC_LABEL_LIST ? "; ..." : "");
	return warnings;
}

/* A source whose rows also go to the photograph's preview as they pass. */
typedef struct preview_tap {
	kg_row_source in;
	proc_preview *pv;
} preview_tap;

static int tap_read(void *user, int y0, int rows, float *out, kg_err *err)
{
	preview_tap *t = user;
	int ret = t->in.read(t->in.user, y0, rows, out, err);
	if (!ret)
		proc_preview_rows(t->pv, y0, rows, out);
	return ret;
}

/* The clamp count that means something: over the lit pixels only. Black or unlit
 * ground is noise about 0, and a reflectance estimate of noise is negative in some
 * band about every other pixel; the rim of a lit region mixes object and ground
 * (lens blur, demosaicing), whose false colours are negative too. A lit pixel clamped
 * is one the calibration does not fit. Lit: inside the --mask (when one is given),
 * estimated (finite, not clipped), and it and its 8 neighbours (those in the image)
 * above the noise: a channel c above PROC_LIT_SIGMAS sigma_c, sigma_c from the
 * capture's variance of the mean when recorded, else the classifier's noise model
 * (floor and relative part). Counted from the estimate's blocks as they are written
 * (observe), a row decided when the next one has arrived. */
enum { LIT_ABOVE = 1, LIT_COUNTED = 2, LIT_CLAMPED = 4 };

typedef struct lit_count {
	proc_pass *var_pass;
	kg_row_source var, mask;
	kg_image_rows *mask_rows;
	int has_var, has_mask;
	int width, height;
	float *vbuf, *mbuf;
	size_t vcap, mcap;
	uint8_t *row[3]; /* LIT_* of rows y mod 3 */
	double floor2, rel2;
	uint64_t lit, clamped;
	unsigned char *bits; /* the lit pixels, bit y * width + x (the master's gamut count) */
} lit_count;

static int lit_grow(float **buf, size_t *cap, size_t n, kg_err *err)
{
	if (n <= *cap)
		return 0;
	float *b = realloc(*buf, n * sizeof(float));
	if (!b)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	*buf = b;
	*cap = n;
	return 0;
}

/* Row y, its neighbours above (y > 0) and below (y + 1 < height) already classed. */
static void lit_decide(lit_count *l, int y)
{
	const uint8_t *r[3] = {y > 0 ? l->row[(y - 1) % 3] : NULL, l->row[y % 3],
	                       y + 1 < l->height ? l->row[(y + 1) % 3] : NULL};
	const int W = l->width;
	for (int x = 0; x < W; x++) {
		if (!(r[1][x] & LIT_COUNTED))
			continue;
		int lit = 1;
		for (int j = 0; j < 3 && lit; j++)
			for (int dx = -1; dx <= 1 && lit && r[j]; dx++)
				if (x + dx >= 0 && x + dx < W && !(r[j][x + dx] & LIT_ABOVE))
					lit = 0;
		if (lit) {
			size_t i = (size_t)y * (size_t)W + (size_t)x;
			l->lit++;
			l->clamped += (r[1][x] & LIT_CLAMPED) != 0;
			l->bits[i / 8] |= (unsigned char)(1u << (i % 8));
		}
	}
}

static int lit_observe(void *user, const kg_est_block *b, const float *raw, kg_err *err)
{
	lit_count *l = user;
	size_t n = (size_t)b->rows * b->width;
	int ret = 0;
	if (b->width != l->width || !raw || !b->mask)
		return kg_fail(err, KG_EINVAL, "lit pixels: a block of %d pixels a row, expected %d",
		               b->width, l->width);
	if (l->has_var && !(ret = lit_grow(&l->vbuf, &l->vcap, 3 * n, err)))
		ret = l->var.read(l->var.user, b->y0, b->rows, l->vbuf, err);
	if (!ret && l->has_mask &&
	    !(ret = lit_grow(&l->mbuf, &l->mcap, (size_t)l->mask.channels * n, err)))
		ret = l->mask.read(l->mask.user, b->y0, b->rows, l->mbuf, err);
	if (ret)
		return ret;
	const double k2 = PROC_LIT_SIGMAS * PROC_LIT_SIGMAS;
	for (int yr = 0; yr < b->rows; yr++) {
		int y = b->y0 + yr;
		uint8_t *out = l->row[y % 3];
		for (int x = 0; x < l->width; x++) {
			size_t i = (size_t)yr * l->width + x;
			uint8_t f = 0;
			for (int ch = 0; ch < 3 && !f; ch++) {
				double v = raw[3 * i + ch];
				double var = l->has_var ? l->vbuf[3 * i + ch] : l->floor2 + l->rel2 * v * v;
				if (v > 0 && v * v > k2 * var)
					f = LIT_ABOVE;
			}
			if (!(b->mask[i] & (KG_EST_MASK_NONFINITE | KG_EST_MASK_CLIPPED)) &&
			    (!l->has_mask || l->mbuf[(size_t)l->mask.channels * i] != 0.0f))
				f |= LIT_COUNTED | (b->mask[i] & KG_EST_MASK_CLAMPED ? LIT_CLAMPED : 0);
			out[x] = f;
		}
		if (y > 0)
			lit_decide(l, y - 1);
		if (y + 1 == l->height)
			lit_decide(l, y);
	}
	return 0;
}

static int lit_open(proc *p, proc_source *src, const proc_image_info *info, lit_count *l)
{
	memset(l, 0, sizeof(*l));
	kg_classify_options copt;
	kg_classify_options_init(&copt);
	l->floor2 = copt.noise_floor * copt.noise_floor;
	l->rel2 = copt.noise_relative * copt.noise_relative;
	l->width = info->width;
	l->height = info->height;
	for (int j = 0; j < 3; j++)
		if (!(l->row[j] = malloc((size_t)info->width)))
			return kg_fail(p->err, KG_ENOMEM, "out of memory");
	if (!(l->bits = calloc(((size_t)info->width * (size_t)info->height + 7) / 8, 1)))
		return kg_fail(p->err, KG_ENOMEM, "out of memory");
	int ret = 0;
	if (info->has_variance && !(ret = proc_pass_open(src, 1, &l->var_pass, &l->var)))
		l->has_var = 1;
	if (!ret && p->object_mask &&
	    !(ret = kg_image_rows_open(p->object_mask, &l->mask_rows, p->err))) {
		kg_row_source_of_rows(l->mask_rows, &l->mask);
		l->has_mask = 1;
	}
	return ret;
}

static void lit_free(lit_count *l)
{
	proc_pass_free(&l->var_pass);
	kg_image_rows_free(&l->mask_rows);
	free(l->vbuf);
	free(l->mbuf);
	free(l->bits);
	for (int j = 0; j < 3; j++)
		free(l->row[j]);
}

/* The estimate's counts into object's "estimate" and its warnings; lit: the clamp count
 * over the lit pixels (NULL when no cube was estimated: labels clamp nothing). */
static void stats_json(proc *p, const proc_capture *c, const kg_est_stats *stats,
                       const lit_count *lit, const char *what, json_t *object)
{
	char line[256];
	kg_est_stats_format(stats, line, sizeof(line));
	proc_progress(p, "%s: %s: %s", c->name, what, line);
	json_t *est = json_pack("{s:I, s:I, s:I, s:I}", "pixels", (json_int_t)stats->pixels,
	                        "nonfinite", (json_int_t)stats->nonfinite, "clipped",
	                        (json_int_t)stats->clipped, "clamped",
	                        (json_int_t)stats->clamped_pixels);
	if (lit) {
		json_object_set_new(est, "lit", json_integer((json_int_t)lit->lit));
		json_object_set_new(est, "clamped_lit", json_integer((json_int_t)lit->clamped));
	}
	json_object_set_new(object, "estimate", est);
	json_t *warnings = json_object_get(object, "warnings");
	double n = (double)stats->pixels;
	if (n > 0 && (double)stats->clipped > PROC_MAX_CLIPPED * n)
		proc_warn(p, warnings, "capture %s: %.1f %% of its pixels clipped (%llu of %llu with "
		          "a channel at full scale; over %g %%): their colour and reflectance are "
		          "wrong; shorten the exposure or lower the gain",
		          c->name, 100 * (double)stats->clipped / n,
		          (unsigned long long)stats->clipped, (unsigned long long)stats->pixels,
		          100 * PROC_MAX_CLIPPED);
	double nl = lit ? (double)lit->lit : 0;
	if (nl > 0 && (double)lit->clamped > PROC_MAX_CLIPPED * nl)
		proc_warn(p, warnings, "capture %s: %.1f %% of its lit pixels clamped (%llu of %llu "
		          "lit pixels%s with a negative reflectance set to 0; over %g %%; lit: it and "
		          "its 8 neighbours have a channel over %g sigma of their noise, so black or "
		          "unlit ground is not counted): the capture does not fit the "
		          "calibration (dark missing or another camera's, another light, a colour "
		          "outside the chart's)",
		          c->name, 100 * (double)lit->clamped / nl, (unsigned long long)lit->clamped,
		          (unsigned long long)lit->lit, lit->has_mask ? " inside the mask" : "",
		          100 * PROC_MAX_CLIPPED, PROC_LIT_SIGMAS);
}

/* The capture's level from the photograph's samples (every channel, after the dark and
 * the flat, before the exposure normalisation): its 99.5th percentile against full
 * scale. Under PROC_BLACK_LEVEL: all black; under PROC_UNDER_LEVEL: under-exposed. */
static void level_warnings(proc *p, const proc_capture *c, proc_preview *pv, double scale,
                           json_t *object)
{
	json_t *warnings = json_object_get(object, "warnings");
	double top = proc_preview_quantile(pv, 0.995) / scale;
	json_object_set_new(object, "level", isfinite(top) ? json_real(top) : json_null());
	if (!(top >= PROC_BLACK_LEVEL))
		proc_warn(p, warnings, "capture %s: all black: its brightest pixels (99.5th "
		          "percentile) reach %.2g %% of full scale: no light reached the sensor "
		          "(light off, lens capped, or a dark recorded as an object?)",
		          c->name, isfinite(top) ? 100 * top : 0.0);
	else if (top < PROC_UNDER_LEVEL)
		proc_warn(p, warnings, "capture %s: under-exposed by more than 50 %%: its brightest "
		          "pixels (99.5th percentile) reach %.1f %% of full scale, so its noise is "
		          "%.1fx what a full exposure gives; expose about %.1fx longer",
		          c->name, 100 * top, sqrt(0.9 / top), 0.9 / top);
}

/* What was (not) done to the capture's dark and flat that the operator should know. */
static void corrections_warnings(proc *p, const proc_capture *c, const proc_image_info *info,
                                 json_t *warnings)
{
	const proc_capture *d = proc_capture_named(p, info->dark);
	if (!info->dark[0])
		proc_warn(p, warnings, "capture %s: no matching dark (same camera, serial %s, "
		          "exposure %.6g us and gain %.6g %s) in the session: not dark-corrected, its "
		          "values keep the sensor's offset",
		          c->name, cam_str(c, "serial"), c->exposure_us, c->gain,
		          c->gain_unit ? c->gain_unit : "");
	else if (!info->dark_by_process && (!d || !proc_dark_matches(d, c)))
		proc_warn(p, warnings, "capture %s: acquire subtracted dark %s, %s: not a matching "
		          "dark (same camera serial, exposure and gain); record the capture again "
		          "with a matching dark",
		          c->name, info->dark,
		          !d ? "which is not in the session (or left out)"
		          : !proc_same_camera(d, c) ? "of another camera"
		                                    : "taken with another exposure, gain or format");
	if (info->flat_by_process)
		proc_warn(p, warnings, "capture %s: flat %s applied by kogei process, where acquire "
		          "recorded \"flat: none\" (acquire --flat %s applies it at capture)",
		          c->name, info->flat, info->flat);
}

/* Estimate the capture into the cube (--cube f32, f16 or weights); *lit_bits: the lit
 * pixels' bitmap (caller frees) for the master. */
static int estimate_pass(proc *p, const proc_capture *c, proc_source *src,
                         const proc_image_info *info, const kg_apply_options *opt,
                         kg_est_format format, const char *cube, unsigned char **lit_bits,
                         json_t *object)
{
	kg_err *err = p->err;
	kg_est_kernel *kern = NULL;
	double pre[9];
	int pre_needed = 0;
	proc_pass *pass = NULL;
	kg_row_source rows;
	kg_apply_options o = *opt;
	lit_count lit;
	/* weights are the PCA kernel's; the spectra the calibration's own method */
	int ret = kg_camera_kernel(p->cam, format == KG_EST_WEIGHTS ? KG_METHOD_PCA : KG_METHOD_AUTO,
	                           0, &kern, pre, &pre_needed, err);
	if (!ret)
		ret = proc_pass_open(src, 0, &pass, &rows);
	int lit_ret = lit_open(p, src, info, &lit);
	if (!ret)
		ret = lit_ret;
	o.observe = lit_observe;
	o.observe_user = &lit;
	kg_est_stats stats;
	if (!ret) {
		o.pre = pre_needed ? pre : NULL;
		proc_progress(p, "%s: estimating %dx%d pixels (%s, %s)", c->name, info->width,
		              info->height, format == KG_EST_WEIGHTS ? "pca" : kg_method_name(p->cam->method),
		              proc_cube_name(p));
		ret = kg_estimate_rows(kern, &rows, format, &o, cube, &stats, err);
	}
	if (!ret) {
		stats_json(p, c, &stats, &lit, "cube written", object);
		*lit_bits = lit.bits;
		lit.bits = NULL;
	}
	lit_free(&lit);
	proc_pass_free(&pass);
	kg_est_kernel_free(&kern);
	return ret;
}

/* Classify the capture, with its variance and the mask read alongside, and the
 * photograph's preview built on the way. */
static int classify_pass(proc *p, const proc_capture *c, proc_source *src, double scale,
                         const proc_image_info *info, const kg_apply_options *opt,
                         const kg_est_material_set *set, const char *labels,
                         const char *photo, const json_t *identity, json_t *object)
{
	kg_err *err = p->err;
	kg_est_kernel *kclass = NULL;
	double pre[9];
	int pre_needed = 0;
	proc_pass *img_pass = NULL, *var_pass = NULL, *survey_pass = NULL, *survey_var_pass = NULL;
	kg_image_rows *mask = NULL;
	kg_row_source img_src, var_src, mask_src, survey_src, survey_var_src;
	preview_tap tap = {0};
	kg_classify_options copt;
	kg_classify_options_init(&copt);
	copt.frames = 1; /* the variance is already of the mean, normalised */
	/* the report shows labels.png beside its own legend (HTML, full names, readable at
	 * any scale): the map alone */
	copt.preview_no_legend = 1;
	copt.record_dir = p->stage; /* labels.json names the files where they end up */
	copt.residual_relative = p->cam->residual_relative;
	kg_apply_options o = *opt;
	o.description = NULL;
	/* classification works in the PCA weights */
	int ret = kg_camera_kernel(p->cam, KG_METHOD_PCA, 0, &kclass, pre, &pre_needed, err);
	if (!ret)
		ret = proc_preview_new(info->width, info->height, 1200, &tap.pv, err);
	if (!ret && !(ret = proc_pass_open(src, 0, &img_pass, &tap.in)))
		img_src = (kg_row_source){tap.in.width, tap.in.height, tap.in.channels, tap_read, &tap};
	if (!ret && info->has_variance && !(ret = proc_pass_open(src, 1, &var_pass, &var_src)))
		copt.variance = &var_src;
	if (!ret && p->object_mask && !(ret = kg_image_rows_open(p->object_mask, &mask, err))) {
		kg_row_source_of_rows(mask, &mask_src);
		copt.mask = &mask_src;
	}
	/* camera-space matching needs the reference camera's response, which references
	 * from before it existed lack: those fall back to eq. 11, and say so */
	int camera = !p->o->method || strcmp(p->o->method, "camera") == 0;
	kg_classify_camera ccam;
	kg_classify_camera_init(&ccam);
	char *composition = NULL;
	if (!ret && camera && !p->cam->response.available) {
		camera = 0;
		proc_warn(p, json_object_get(object, "warnings"),
		          "%s: the reference calibration holds no camera response: labels by eq. 11 "
		          "instead of camera-space matching (recalibrate the reference with this "
		          "version)",
		          c->name);
	}
	if (!ret && camera) {
		ccam.response = &p->cam->response.F[0][0];
		snprintf(ccam.response_source, sizeof(ccam.response_source), "%s",
		         p->cam->response.source);
		memcpy(ccam.site_to_ref, p->cam->M2, sizeof(ccam.site_to_ref));
		kg_camera_residual_cov(p->cam, ccam.calib_cov);
		ccam.reference_sha256 = kg_camera_reference_sha256(p->cam);
		ccam.angle_from = p->o->angles[0];
		ccam.angle_to = p->o->angles[1];
		ccam.angle_step = p->o->angles[2];
		ccam.intensity_lo = p->o->intensity[0];
		ccam.intensity_hi = p->o->intensity[1];
		static const char *const metal_names[3] = {"silver", "copper", "gold"};
		for (int q = 0; q < 3; q++) {
			const kg_material *mt = kg_material_library_find(p->lib, metal_names[q]);
			ccam.metals[q] = mt && mt->kind == KG_MATERIAL_METAL ? mt : NULL;
		}
		if (ccam.metals[0] && ccam.metals[1] && ccam.metals[2] &&
		    !(ret = kg_apply_side_path(labels, "_composition.hdr", &composition, err)))
			ccam.composition_hdr = composition;
		if (!ret && !(ret = proc_pass_open(src, 0, &survey_pass, &survey_src)))
			ccam.survey = &survey_src;
		if (!ret && info->has_variance &&
		    !(ret = proc_pass_open(src, 1, &survey_var_pass, &survey_var_src)))
			ccam.survey_variance = &survey_var_src;
	}
	if (!ret) {
		const json_t *su = json_object_get(p->calibration, "spectral_uncertainty");
		kg_classify_info cinfo = {.calib = "camera.json", .materials = p->library_path,
		                          .method = "pca", .image = c->name,
		                          .variance = info->has_variance ? "the capture's variance" : NULL,
		                          .mask = p->object_mask, .identity = identity,
		                          .spectral_uncertainty = json_is_object(su) ? su : NULL};
		o.pre = pre_needed ? pre : NULL;
		proc_progress(p, "%s: classifying among %d materials (%s)", c->name, set->n,
		              info->has_variance ? "noise from the capture's variance" : "noise model");
		kg_classify_result cres = {0};
		if (camera) {
			cinfo.method = "camera";
			ret = kg_classify_camera_rows(kclass, set, &ccam, &img_src, &o, &copt, &cinfo,
			                              labels, &cres, err);
			if (!ret)
				json_object_set_new(object, "labels_method",
				                    json_pack("{s:s,s:i,s:i,s:i}", "method", "camera",
				                              "materials", set->n, "classes", cres.nclasses,
				                              "regions", cres.nregions));
		} else {
			ret = kg_classify_rows(kclass, set, &img_src, &o, &copt, &cinfo, labels, &cres,
			                       err);
			if (!ret)
				json_object_set_new(object, "labels_method",
				                    json_pack("{s:s,s:i}", "method", "eq11", "materials",
				                              set->n));
		}
		if (!ret && !json_object_get(object, "estimate")) /* no cube: the labels' counts */
			stats_json(p, c, &cres.stats, NULL, "labels written", object);
		kg_classify_result_free(&cres);
	}
	if (!ret)
		level_warnings(p, c, tap.pv, scale, object);
	if (!ret)
		ret = proc_preview_write(tap.pv, photo, err);
	proc_preview_free(&tap.pv);
	kg_image_rows_free(&mask);
	proc_pass_free(&var_pass);
	proc_pass_free(&img_pass);
	proc_pass_free(&survey_pass);
	proc_pass_free(&survey_var_pass);
	free(composition);
	kg_est_kernel_free(&kclass);
	return ret;
}

/* The mask of c from a background capture b (the scene without the object): a pixel
 * is the object's where some channel differs from b's by more than
 * BG_DIFF_RELATIVE of the larger of the two plus BG_DIFF_FLOOR (both normalised to the
 * chart's exposure); written to path (8-bit grey PNG, 255 object, 0 background). */
#define BG_DIFF_RELATIVE 0.05
#define BG_DIFF_FLOOR 0.005
static int background_mask(proc *p, const proc_capture *c, proc_source *src, double scale,
                           const proc_capture *b, const char *path, json_t *object)
{
	kg_err *err = p->err;
	proc_source *bsrc = NULL;
	proc_pass *op = NULL, *bp = NULL;
	kg_row_source os, bs;
	proc_image_info binfo;
	kg_image *mask = NULL;
	float *ob = NULL, *bb = NULL;
	double bscale = 1;
	json_t *scratch = json_array();
	int ret = scratch ? exposure_scale(p, b, scratch, &bscale) : kg_fail(err, KG_ENOMEM,
	                                                                   "out of memory");
	if (!ret)
		ret = proc_source_open(p, b, bscale, 0, &bsrc, &binfo);
	if (!ret)
		ret = proc_pass_open(src, 0, &op, &os);
	if (!ret)
		ret = proc_pass_open(bsrc, 0, &bp, &bs);
	if (!ret && (bs.width != os.width || bs.height != os.height || bs.channels != os.channels))
		ret = kg_fail(err, KG_EINVAL, "background capture %s is %dx%d with %d channels, capture "
		              "%s %dx%d with %d: expected the same size", b->name, bs.width, bs.height,
		              bs.channels, c->name, os.width, os.height, os.channels);
	const int W = os.width, H = os.height, ch = os.channels, band = 64;
	if (!ret)
		ret = kg_image_new(W, H, 1, &mask, err);
	if (!ret && (!(ob = malloc(sizeof(float) * (size_t)W * band * ch)) ||
	             !(bb = malloc(sizeof(float) * (size_t)W * band * ch))))
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	size_t on = 0;
	for (int y0 = 0; !ret && y0 < H; y0 += band) {
		int rows = H - y0 < band ? H - y0 : band;
		if ((ret = os.read(os.user, y0, rows, ob, err)) || (ret = bs.read(bs.user, y0, rows, bb, err)))
			break;
		for (size_t i = 0; i < (size_t)W * rows; i++) {
			int differs = 0;
			for (int k = 0; k < ch; k++) {
				double x = ob[i * ch + k], y = bb[i * ch + k];
				/* a pixel either image cannot read (non-finite) is not the object's */
				if (isfinite(x) && isfinite(y) &&
				    fabs(x - y) > BG_DIFF_RELATIVE * fmax(fabs(x), fabs(y)) + BG_DIFF_FLOOR * scale)
					differs = 1;
			}
			mask->data[(size_t)y0 * W + i] = differs ? 1.0f : 0.0f;
			on += (size_t)differs;
		}
	}
	if (!ret)
		ret = kg_image_write_png(mask, path, 8, err);
	if (!ret) {
		double frac = (double)on / ((double)W * H);
		json_object_set_new(object, "mask_from_background",
		                    json_pack("{s:s, s:f, s:f, s:f, s:s}", "capture", b->name,
		                              "object_fraction", frac, "relative", BG_DIFF_RELATIVE,
		                              "floor", BG_DIFF_FLOOR, "file", "mask.png"));
		proc_progress(p, "%s: masked by its difference from the background capture %s: "
		              "%.1f %% of the pixels are the object's", c->name, b->name, 100 * frac);
		if (frac < 0.001 || frac > 0.95)
			proc_warn(p, json_object_get(object, "warnings"),
			          "%s: %.1f %% of its pixels differ from the background capture %s: is "
			          "that capture the same scene without the object, under the same light?",
			          c->name, 100 * frac, b->name);
	}
	if (ret)
		kg_err_prefix(err, "%s: mask from the background capture %s: ", c->name, b->name);
	free(ob);
	free(bb);
	kg_image_free(&mask);
	proc_pass_free(&op);
	proc_pass_free(&bp);
	proc_source_free(&bsrc);
	json_decref(scratch);
	return ret;
}

/* One object into dir (a temporary folder). Its image is read a band of rows at a
 * time, once for the cube and the photograph's preview and once for the labels, so
 * memory does not grow with the image. */
static int process_into(proc *p, const proc_capture *c, const char *dir, double scale,
                        const kg_est_material_set *set, json_t *object)
{
	kg_err *err = p->err;
	proc_source *src = NULL;
	proc_image_info info;
	char *cube = kg_path_join(dir, "cube.hdr"), *labels = kg_path_join(dir, "labels.hdr");
	char *ljson = kg_path_join(dir, "labels.json"), *photo = kg_path_join(dir, "photo.png");
	char *conf = kg_path_join(dir, "labels_confidence.hdr");
	char *confpng = kg_path_join(dir, "confidence.png");
	char *scene = kg_path_join(dir, "scene.json"), *render = kg_path_join(dir, "render.png");
	char *glb = kg_path_join(dir, "object.glb");
	char *mitsuba = kg_path_join(dir, "object_mitsuba.xml");
	json_t *class_map = json_object();
	/* the object's identity, into each file that carries metadata (identity.c) */
	json_t *identity = proc_identity(p, c);
	int ret = cube && labels && ljson && photo && conf && confpng && scene && render && glb &&
	                  mitsuba && class_map && identity
	              ? 0 : kg_fail(err, KG_ENOMEM, "out of memory");
	if (!ret)
		json_object_set(object, "identity", identity);
	if (!ret)
		ret = proc_source_open(p, c, scale, 0, &src, &info);
	/* the mask: --mask, else the difference from a background capture */
	const proc_capture *bgc = p->o->mask ? NULL : background_of(p, c);
	char *bgmask = bgc ? kg_path_join(dir, "mask.png") : NULL;
	p->object_mask = p->o->mask;
	if (!ret && bgc && !bgmask)
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	if (!ret && bgc && !(ret = background_mask(p, c, src, scale, bgc, bgmask, object)))
		p->object_mask = bgmask;
	if (!ret) {
		json_object_set_new(object, "width", json_integer(info.width));
		json_object_set_new(object, "height", json_integer(info.height));
		json_object_set_new(object, "dark", info.dark[0] ? json_string(info.dark) : json_null());
		json_object_set_new(object, "flat", info.flat[0] ? json_string(info.flat) : json_null());
		corrections_warnings(p, c, &info, json_object_get(object, "warnings"));
	}
	kg_apply_options opt;
	kg_apply_options_init(&opt);
	opt.threads = p->o->threads;
	opt.progress = p->o->progress;
	/* full scale moves with the exposure normalisation */
	opt.clip_level = (float)(0.999 * scale);
	char first[256], *desc = NULL;
	snprintf(first, sizeof(first), "kogei process: reflectance of capture %s", c->name);
	if (!ret)
		ret = proc_identity_envi(identity, first, &desc, err);
	opt.description = desc;
	kg_est_format format;
	unsigned char *lit_bits = NULL;
	if (!ret && proc_cube_format(p, &format))
		ret = estimate_pass(p, c, src, &info, &opt, format, cube, &lit_bits, object);
	if (!ret)
		ret = proc_master(p, c, dir, proc_cube_format(p, &format) ? cube : NULL, lit_bits,
		                  identity, object);
	free(lit_bits);
	if (!ret)
		ret = classify_pass(p, c, src, scale, &info, &opt, set, labels, photo, identity,
		                    object);
	/* unknown, background, unclassified and unseen pixels are no library material:
	 * the render shows them as a neutral grey diffuser */
	const char *fallback = KG_SCENE_NEUTRAL_GREY;
	if (!ret)
		ret = classes_json(p, ljson, set, object, class_map, fallback);
	if (!ret) {
		json_t *lw = proc_label_warnings(c->name, object);
		size_t i;
		json_t *w;
		json_array_foreach(lw, i, w)
			proc_warn(p, json_object_get(object, "warnings"), "%s", json_string_value(w));
		json_decref(lw);
	}
	/* the IIIF access copy and manifest (access.c, manifest.c) */
	if (!ret)
		ret = proc_access(p, c, dir, identity, object);
	if (!ret)
		ret = proc_manifest(p, c, dir, identity, object);
	if (!ret)
		ret = confidence_png(conf, confpng, 1200, err);
	/* the handoff's materials: each region's decision (classify's material map, written
	 * where regions were formed), else the pixels' classes */
	const char *mapfile = "labels.hdr";
	if (!ret) {
		char *mm = kg_path_join(dir, "labels_materials.hdr");
		struct stat st;
		if (!mm)
			ret = kg_fail(err, KG_ENOMEM, "out of memory");
		else if (stat(mm, &st) == 0)
			mapfile = "labels_materials.hdr";
		free(mm);
	}
	if (!ret)
		ret = proc_scene_write(p, scene, mapfile, info.width, info.height, class_map,
		                       fallback, object);
	/* the scene as binary glTF 2.0 (render/kg_gltf.h), the photograph beside it */
	kg_scene *ks = NULL;
	if (!ret && (ret = kg_scene_load(scene, &ks, err)))
		kg_err_prefix(err, "%s: reading %s: ", c->name, scene);
	if (!ret) {
		kg_gltf_options go = {.photo_png = photo, .source = c->name,
		                      .record_dir = p->stage, .identity = identity};
		proc_progress(p, "%s: writing object.glb", c->name);
		if ((ret = kg_gltf_write(ks, &go, glb, err)))
			kg_err_prefix(err, "%s: writing %s: ", c->name, glb);
	}
	/* the scene for Mitsuba 3 (render/kg_render.h): the label map is projected onto the
	 * mesh with Embree, as the renderer does it */
	if (!ret && kg_render_available()) {
		proc_progress(p, "%s: writing object_mitsuba.xml", c->name);
		if ((ret = kg_scene_write_mitsuba(ks, mitsuba, p->o->threads, err)))
			kg_err_prefix(err, "%s: writing %s: ", c->name, mitsuba);
	}
	if (!ret && p->o->render && kg_render_available()) {
		proc_progress(p, "%s: rendering scene.json", c->name);
		ret = render_scene(p, ks, render);
		if (ret)
			kg_err_prefix(err, "%s: rendering %s: ", c->name, scene);
	}
	kg_scene_free(&ks);
	if (ret)
		kg_err_prefix(err, "capture %s: ", c->name);
	proc_source_free(&src);
	json_decref(class_map);
	json_decref(identity);
	free(desc);
	p->object_mask = NULL;
	free(bgmask);
	free(cube);
	free(labels);
	free(ljson);
	free(photo);
	free(conf);
	free(confpng);
	free(scene);
	free(render);
	free(glb);
	free(mitsuba);
	return ret;
}

static void set_paths(json_t *object, const char *name, int rendered, int cube)
{
	static const char *const keys[][2] = {
		{"photo", "photo.png"},         {"cube", "cube.hdr"},
		{"labels", "labels.hdr"},       {"labels_png", "labels.png"},
		{"confidence_png", "confidence.png"}, {"scene", "scene.json"},
		{"gltf", "object.glb"},
	};
	char rel[256];
	json_object_set_new(object, "dir", json_string(name));
	for (size_t i = 0; i < sizeof(keys) / sizeof(keys[0]); i++) {
		snprintf(rel, sizeof(rel), "%s/%s", name, keys[i][1]);
		json_object_set_new(object, keys[i][0], json_string(rel));
	}
	snprintf(rel, sizeof(rel), "%s/render.png", name);
	json_object_set_new(object, "render", rendered ? json_string(rel) : json_null());
	snprintf(rel, sizeof(rel), "%s/object_mitsuba.xml", name);
	json_object_set_new(object, "mitsuba", kg_render_available() ? json_string(rel) : json_null());
	if (!cube)
		json_object_set_new(object, "cube", json_null());
}

/* The material library (a file or a bundled name) and the declared set, into p. */
static int load_materials(proc *p)
{
	const char *mat = p->o->materials ? p->o->materials : "default";
	if (access(mat, R_OK) == 0) {
		p->library_path = strdup(mat);
	} else {
		char rel[256];
		snprintf(rel, sizeof(rel), "materials/%s.json", mat);
		p->library_path = kg_data_path(rel);
		if (p->library_path && access(p->library_path, R_OK) != 0) {
			free(p->library_path);
			p->library_path = NULL;
		}
		if (!p->library_path)
			return kg_fail(p->err, KG_ENOENT, "material library '%s': no such file and not a "
			               "bundled library (default)", mat);
	}
	int ret = proc_input(p, "materials", p->library_path, NULL);
	if (!ret)
		ret = kg_material_library_load(p->library_path, &p->lib, p->err);
	if (!ret)
		ret = kg_est_material_set_new(p->lib, p->library_path, p->o->only, p->o->nonly,
		                              p->o->angle_deg, &p->set, p->err);
	return ret;
}

/* --mask: readable, and of every object capture's size. */
static int check_mask(proc *p)
{
	if (!p->o->mask)
		return 0;
	kg_image_rows *rows = NULL;
	int ret = kg_image_rows_open(p->o->mask, &rows, p->err);
	const kg_image *mask = ret ? NULL : kg_image_rows_header(rows);
	for (int i = 0; i < p->ncaps && !ret; i++) {
		const proc_capture *c = &p->caps[i];
		if (c->kind == KG_CAPTURE_OBJECT && (mask->width != c->width || mask->height != c->height))
			ret = kg_fail(p->err, KG_EINVAL, "%s: the mask is %dx%d, capture %s is %ldx%ld: "
			              "expected a mask of the objects' size", p->o->mask, mask->width,
			              mask->height, c->name, c->width, c->height);
	}
	kg_image_rows_free(&rows);
	return ret;
}

/* Everything about the objects that can refuse the run, checked before anything is
 * written: the materials, the mask, each object's camera and exposure. */
int proc_objects_precheck(proc *p)
{
	int ret = load_materials(p);
	if (!ret)
		ret = check_mask(p);
	if (!ret)
		ret = proc_master_check(p);
	if (ret)
		return ret;
	json_t *scratch = json_array();
	ret = scratch ? 0 : kg_fail(p->err, KG_ENOMEM, "out of memory");
	for (int i = 0; i < p->ncaps && !ret; i++) {
		const proc_capture *c = &p->caps[i];
		double scale;
		if (c->kind != KG_CAPTURE_OBJECT)
			continue;
		if (!p->o->force)
			ret = check_camera(p, c, scratch);
		if (!ret && !p->o->assume_same_exposure)
			ret = exposure_scale(p, c, scratch, &scale);
	}
	json_decref(scratch);
	return ret;
}

int proc_objects(proc *p, json_t *objects, kg_process_summary *sum)
{
	const kg_est_material_set *set = p->set;
	int ret = 0;
	for (int i = 0; i < p->ncaps && !ret; i++) {
		const proc_capture *c = &p->caps[i];
		if (c->kind != KG_CAPTURE_OBJECT)
			continue;
		sum->objects++;
		json_t *object = json_pack("{s:s, s:b, s:[]}", "capture", c->name, "skipped", 0,
		                           "warnings");
		json_t *warnings = json_object_get(object, "warnings");
		double scale = 1;
		if ((ret = check_camera(p, c, warnings)) || (ret = exposure_scale(p, c, warnings, &scale))) {
			json_decref(object);
			break;
		}
		json_t *key = object_key(p, c);
		char *final = kg_path_join(p->o->outdir, c->name);
		char *labels = final ? kg_path_join(final, "labels.hdr") : NULL;
		const json_t *prev = proc_previous_object(p, c->name);
		if (prev && json_equal(json_object_get(prev, "key"), key) && labels &&
		    access(labels, R_OK) == 0) {
			json_t *copy = json_deep_copy(prev);
			json_object_set_new(copy, "skipped", json_true());
			json_array_append_new(objects, copy);
			proc_progress(p, "%s: unchanged since the last run, kept", c->name);
			sum->skipped++;
			json_decref(object);
			json_decref(key);
			free(final);
			free(labels);
			continue;
		}
		json_object_set_new(object, "key", key);
		json_object_set(object, "exposure_us", kg_json_find(c->j, "settings.exposure_us")
		                                           ? kg_json_find(c->j, "settings.exposure_us")
		                                           : json_null());
		json_object_set(object, "gain", kg_json_find(c->j, "settings.gain")
		                                    ? kg_json_find(c->j, "settings.gain")
		                                    : json_null());
		json_object_set_new(object, "frames", json_integer(c->frames));
		json_object_set_new(object, "exposure_scale", json_real(scale));
		json_t *making = proc_capture_making(c);
		json_object_update(object, making);
		json_decref(making);
		if (fabs(scale - 1) > 1e-9)
			proc_progress(p, "%s: exposure %.6g us, gain %.4g %s against the chart's %.6g us, "
			              "%.4g %s: values scaled by %.6g", c->name, c->exposure_us, c->gain,
			              c->gain_unit ? c->gain_unit : "", p->chart->exposure_us,
			              p->chart->gain, p->chart->gain_unit ? p->chart->gain_unit : "",
			              scale);
		char tmp[4200];
		snprintf(tmp, sizeof(tmp), "%s/%s", p->stage, c->name); /* put in place at the end */
		proc_remove_tree(tmp);
		if (!final || !labels)
			ret = kg_fail(p->err, KG_ENOMEM, "out of memory");
		else if (mkdir(tmp, 0777) != 0)
			ret = kg_fail(p->err, KG_EIO, "%s: cannot create it", tmp);
		if (!ret)
			ret = process_into(p, c, tmp, scale, set, object);
		if (ret)
			proc_remove_tree(tmp);
		else {
			kg_est_format format;
			set_paths(object, c->name, p->o->render && kg_render_available(),
			          proc_cube_format(p, &format));
			json_array_append(objects, object);
			sum->processed++;
			proc_progress(p, "%s: done", c->name);
		}
		json_decref(object);
		free(final);
		free(labels);
	}
	if (!ret && sum->objects == 0)
		proc_warn(p, NULL, "the session has no object capture: only the calibration was "
		          "written");
	return ret;
}
