/* One capture: camera settings, the exposure helper, N frames averaged, dark and flat,
 * statistics, demosaicing, outputs and the manifest entry (kg_acquire.h). */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "acquire_private.h"

/* The exposure helper stops when the level is within this fraction of the target. */
#define HELPER_TOLERANCE 0.03
/* A measured level at or above this is treated as clipped (how far over is unknown). */
#define HELPER_CLIPPED 0.98
/* Below this there is too little signal to scale from. */
#define HELPER_DARK 0.005

static const char *const kind_names[] = {"chart", "object", "dark", "flat", "background"};

const char *kg_capture_kind_name(kg_capture_kind k)
{
	return (unsigned)k < 5 ? kind_names[k] : "unknown";
}

int kg_capture_kind_parse(const char *text, kg_capture_kind *out, kg_err *err)
{
	for (int i = 0; i < 5; i++)
		if (text && !strcmp(text, kind_names[i])) {
			*out = (kg_capture_kind)i;
			return 0;
		}
	return kg_fail(err, KG_EINVAL, "kind '%s': expected chart, object, dark, flat or background",
	               text ? text : "(none)");
}

void kg_capture_options_default(kg_capture_options *o)
{
	memset(o, 0, sizeof(*o));
	o->kind = KG_CAPTURE_CHART;
	o->frames = 10;
	o->target = 0.8;
	o->max_iterations = 10;
	o->gain = NAN;
	o->record = 1;
}

void kg_capture_result_clear(kg_capture_result *r)
{
	if (!r)
		return;
	kg_image_free(&r->mean);
	kg_image_free(&r->variance);
	kg_image_free(&r->rgb);
	memset(r, 0, sizeof(*r));
}

/* ---- helpers --------------------------------------------------------------------- */

typedef struct cap_ctx {
	kg_session *s;
	kg_camera *cam;
	const kg_capture_options *o;
	kg_capture_result *res;
	int recording;
	json_t *frames; /* [{file, sha256, sequence, timestamp}] */
	json_t *steps;  /* exposure helper */
	json_t *sources; /* files the frames were read from: [{file, sha256}] */
	char source_note[256]; /* how the first of them was decoded */
	char layout_rel[KG_CAPTURE_NAME_MAX + 32]; /* chart_layout as the manifest records it */
} cap_ctx;

static void note(const cap_ctx *c, const char *fmt, ...) KG_PRINTF(2, 3);
static void note(const cap_ctx *c, const char *fmt, ...)
{
	if (!c->o->note)
		return;
	char msg[1024];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	c->o->note(c->o->note_user, msg);
}

/* A camera call's result: stream and device errors make the capture a device failure
 * (a full disk, KG_ENOSPC, is not one: the recording or an output could not be
 * written). */
static int cam(cap_ctx *c, int ret)
{
	if (ret == KG_EIO || ret == KG_ETIMEDOUT || ret == KG_ENODEV)
		c->res->device_failure = 1;
	return ret;
}

static json_t *jnum(double v) { return isfinite(v) ? json_real(v) : json_null(); }

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* A feature read back, NAN when the camera has none. */
static double read_feature(cap_ctx *c, kg_feature f)
{
	kg_feature_info fi;
	double v = NAN;
	if (kg_camera_feature_info(c->cam, f, &fi, NULL) || !fi.available ||
	    kg_camera_get(c->cam, f, &v, NULL))
		return NAN;
	return v;
}

static const char *feature_unit(cap_ctx *c, kg_feature f)
{
	static char unit[16];
	kg_feature_info fi;
	if (kg_camera_feature_info(c->cam, f, &fi, NULL) || !fi.available)
		return "";
	snprintf(unit, sizeof(unit), "%s", fi.unit);
	return unit;
}

static int stream_error(cap_ctx *c, int code, const char *what, kg_err *err)
{
	kg_stream_stats st;
	kg_camera_stats(c->cam, &st);
	c->res->stream = st;
	c->res->device_failure = 1;
	const char *uri = kg_camera_get_info(c->cam)->uri;
	int named = !strncmp(what, "camera '", 8);
	return kg_fail(err, code,
	               "%s%s%scapture %s: %s (%llu completed, %llu dropped, %llu incomplete, "
	               "%llu failed, %llu timeouts, %llu packets resent, %llu packets missing); "
	               "nothing of it was added to the session",
	               named ? "" : "camera '", named ? "" : uri, named ? "" : "': ",
	               c->res->name, what,
	               (unsigned long long)st.completed, (unsigned long long)st.dropped,
	               (unsigned long long)st.incomplete, (unsigned long long)st.failed,
	               (unsigned long long)st.timeouts, (unsigned long long)st.resent,
	               (unsigned long long)st.missing_packets);
}

/* Pop one frame; a timeout or a flagged frame is an error with the counts. */
static int pop_frame(cap_ctx *c, int timeout_ms, kg_frame *f, kg_err *err)
{
	kg_err e = {{0}};
	int ret = kg_camera_pop(c->cam, timeout_ms, f, &e);
	if (ret) {
		cam(c, ret);
		if (ret == KG_ETIMEDOUT || ret == KG_EIO || ret == KG_ENODEV)
			return stream_error(c, ret, e.msg, err);
		if (err)
			*err = e;
		return ret;
	}
	if (f->status != KG_FRAME_OK) {
		char what[128];
		snprintf(what, sizeof(what), "frame %llu was flagged %s by the driver",
		         (unsigned long long)f->sequence,
		         f->status == KG_FRAME_INCOMPLETE ? "incomplete" : "corrupt");
		kg_camera_push(c->cam, f, NULL);
		return stream_error(c, KG_EIO, what, err);
	}
	kg_stream_stats st;
	kg_camera_stats(c->cam, &st);
	if (st.dropped > (uint64_t)c->o->max_dropped) {
		char what[160];
		snprintf(what, sizeof(what),
		         "%llu frame(s) dropped (sequence gap before frame %llu), more than "
		         "--max-dropped %ld",
		         (unsigned long long)st.dropped, (unsigned long long)f->sequence,
		         c->o->max_dropped);
		kg_camera_push(c->cam, f, NULL);
		return stream_error(c, KG_EIO, what, err);
	}
	return 0;
}

/* The recorded file of the frame just popped, as a manifest entry. */
static json_t *frame_entry(cap_ctx *c, const kg_frame *f)
{
	char file[256], sha[65];
	if (!c->recording || kg_camera_record_last(c->cam, file, sizeof(file), sha))
		return NULL;
	return json_pack("{s:s, s:s, s:I, s:o}", "file", file, "sha256", sha, "sequence",
	                 (json_int_t)f->sequence, "timestamp", jnum(f->timestamp));
}

/* A frame read from a file (files:, gphoto2:): the file and its sha256, so the manifest
 * names the originals the capture was made from. */
static int source_entry(cap_ctx *c, const kg_frame *f, kg_err *err)
{
	char sha[65];
	int ret = kg_file_sha256(f->source, sha, err);
	if (ret)
		return ret;
	if (!c->source_note[0] && f->source_note)
		snprintf(c->source_note, sizeof(c->source_note), "%s", f->source_note);
	json_array_append_new(c->sources, json_pack("{s:s, s:s}", "file", f->source, "sha256", sha));
	return 0;
}

/* ---- exposure helper -------------------------------------------------------------- */

static int measure_frame(cap_ctx *c, const kg_frame *f, double *level, int *chart,
                         kg_err *err)
{
	kg_image *img = NULL;
	int ret = kg_frame_to_image(f, c->o->force_nonlinear, &img, err);
	if (ret)
		return ret;
	*chart = 0;
	if (c->o->measure) {
		kg_err e = {{0}};
		ret = c->o->measure(c->o->measure_user, img, level, &e);
		if (!ret)
			*chart = 1;
		else if (ret == KG_ENOENT)
			note(c, "exposure helper: no chart in this frame (%s); using the bright level",
			     e.msg);
		else if (err)
			*err = e;
		if (ret == KG_ENOENT)
			ret = 0;
		else if (ret) {
			kg_image_free(&img);
			return ret;
		}
	}
	if (!*chart)
		ret = kg_bright_level(img, KG_BRIGHT_RADIUS, KG_BRIGHT_PERCENTILE, level, err);
	kg_image_free(&img);
	return ret;
}

/* The next exposure to try from the steps so far. */
static double next_exposure(const kg_capture_result *r, double target)
{
	const kg_exposure_step *s = &r->steps[r->nsteps - 1];
	double t = s->exposure_us, L = s->level;
	if (L >= HELPER_CLIPPED)
		return t * 0.25;
	if (L < HELPER_DARK)
		return t * 10;
	/* Secant through the last two unclipped steps (allows for an offset), else
	 * proportional (the sensor is linear). */
	for (int i = r->nsteps - 2; i >= 0; i--) {
		const kg_exposure_step *p = &r->steps[i];
		if (p->level >= HELPER_CLIPPED || p->level < HELPER_DARK || p->exposure_us == t)
			continue;
		double slope = (L - p->level) / (t - p->exposure_us);
		if (slope > 0) {
			double tn = t + (target - L) / slope;
			if (tn > t * 0.1 && tn < t * 10)
				return tn;
		}
		break;
	}
	return t * target / L;
}

static int exposure_helper(cap_ctx *c, int timeout_ms, kg_err *err)
{
	const kg_capture_options *o = c->o;
	kg_capture_result *r = c->res;
	kg_feature_info fi;
	int ret = cam(c, kg_camera_feature_info(c->cam, KG_FEAT_EXPOSURE_US, &fi, err));
	if (ret)
		return ret;
	if (!fi.available || !fi.writable)
		return kg_fail(err, KG_ENOTSUP,
		               "camera '%s': --exposure auto needs a writable exposure control",
		               kg_camera_get_info(c->cam)->uri);
	double t;
	if ((ret = cam(c, kg_camera_get(c->cam, KG_FEAT_EXPOSURE_US, &t, err))))
		return ret;
	int done = 0;
	int max_it = o->max_iterations > 0 ? o->max_iterations : 10;
	if (max_it > KG_EXPOSURE_MAX_STEPS)
		max_it = KG_EXPOSURE_MAX_STEPS;
	for (int it = 0; it < max_it && !done; it++) {
		/* A fresh stream per step, so no buffered frame has the previous exposure. */
		if (it > 0 && (ret = cam(c, kg_camera_set(c->cam, KG_FEAT_EXPOSURE_US, t, &t, err))))
			return ret;
		int to = timeout_ms > 0 ? timeout_ms : 2000 + (int)(2 * t / 1000);
		if ((ret = cam(c, kg_camera_start(c->cam, 0, err))))
			return ret;
		kg_frame f;
		ret = pop_frame(c, to, &f, err);
		if (ret) {
			kg_camera_stop(c->cam, NULL);
			return ret;
		}
		double level = NAN;
		int chart = 0;
		json_t *entry = frame_entry(c, &f);
		ret = measure_frame(c, &f, &level, &chart, err);
		kg_camera_push(c->cam, &f, NULL);
		int sret = cam(c, kg_camera_stop(c->cam, ret ? NULL : err));
		if (ret || sret) {
			json_decref(entry);
			return ret ? ret : sret;
		}
		r->steps[r->nsteps++] = (kg_exposure_step){t, level, chart};
		if (!entry)
			entry = json_object();
		json_object_set_new(entry, "exposure_us", jnum(t));
		json_object_set_new(entry, "level", jnum(level));
		json_object_set_new(entry, "measure", json_string(chart ? "chart" : "bright level"));
		json_array_append_new(c->steps, entry);
		note(c, "exposure helper: %.6g us gives level %.4f (target %.3f, %s)", t, level,
		     o->target, chart ? "brightest chart patch" : "bright level");
		if (fabs(level - o->target) <= HELPER_TOLERANCE * o->target) {
			done = 1;
			break;
		}
		double tn = next_exposure(r, o->target);
		if (fi.max > fi.min)
			tn = tn < fi.min ? fi.min : tn > fi.max ? fi.max : tn;
		if (fabs(tn - t) <= 1e-9 * t)
			return kg_fail(err, KG_ERANGE,
			               "camera '%s': exposure helper: at the %s exposure %.6g us the level "
			               "is %.4f, the target %.3f is out of reach; %s",
			               kg_camera_get_info(c->cam)->uri,
			               level < o->target ? "longest" : "shortest", t, level, o->target,
			               level < o->target ? "add light or gain"
			                                 : "take light away or lower the gain");
		t = tn;
	}
	if (!done)
		return kg_fail(err, KG_ERANGE,
		               "camera '%s': exposure helper: no exposure within %.0f %% of the target "
		               "%.3f after %d steps (last: %.6g us, level %.4f)",
		               kg_camera_get_info(c->cam)->uri, 100 * HELPER_TOLERANCE, o->target,
		               r->nsteps, t, r->steps[r->nsteps - 1].level);
	/* Lock: auto exposure off (again) and the exposure read back unchanged. */
	kg_feature_info ai;
	if (!kg_camera_feature_info(c->cam, KG_FEAT_AUTO_EXPOSURE, &ai, NULL) && ai.available &&
	    ai.writable && (ret = cam(c, kg_camera_set(c->cam, KG_FEAT_AUTO_EXPOSURE, 0, NULL, err))))
		return ret;
	double back;
	if ((ret = cam(c, kg_camera_get(c->cam, KG_FEAT_EXPOSURE_US, &back, err))))
		return ret;
	if (fabs(back - t) > 0.005 * t)
		return kg_fail(err, KG_ERANGE,
		               "camera '%s': exposure helper: locked at %.6g us but reads back %.6g us",
		               kg_camera_get_info(c->cam)->uri, t, back);
	return 0;
}

/* ---- dark and flat ---------------------------------------------------------------- */

/* Why capture cap's settings differ from these (why[0] == 0 when they match). */
static void settings_differ(const json_t *cap, const kg_frame_format *fmt, double exposure,
                            double gain, double iso, char *why, size_t len)
{
	const json_t *st = json_object_get(cap, "settings");
	const json_t *f = json_object_get(st, "format");
	why[0] = 0;
	const char *pf = json_string_value(json_object_get(f, "pixfmt"));
	const char *cfa = json_string_value(json_object_get(f, "cfa"));
	long bits = (long)json_integer_value(json_object_get(f, "bits"));
	long w = (long)json_integer_value(json_object_get(f, "width"));
	long h = (long)json_integer_value(json_object_get(f, "height"));
	long ox = (long)json_integer_value(json_object_get(f, "offset_x"));
	long oy = (long)json_integer_value(json_object_get(f, "offset_y"));
	if (!pf || strcmp(pf, kg_pixfmt_name(fmt->pixfmt)) || bits != fmt->bits || !cfa ||
	    strcmp(cfa, fmt->cfa)) {
		snprintf(why, len, "format %s%s%s %ld bits, not %s%s%s %d bits", pf ? pf : "?",
		         cfa && *cfa ? " " : "", cfa ? cfa : "", bits, kg_pixfmt_name(fmt->pixfmt),
		         fmt->cfa[0] ? " " : "", fmt->cfa, fmt->bits);
		return;
	}
	if (w != fmt->width || h != fmt->height || ox != fmt->offset_x || oy != fmt->offset_y) {
		snprintf(why, len, "size %ldx%ld+%ld+%ld, not %dx%d+%d+%d", w, h, ox, oy, fmt->width,
		         fmt->height, fmt->offset_x, fmt->offset_y);
		return;
	}
	if (!isnan(exposure)) {
		double e = json_number_value(json_object_get(st, "exposure_us"));
		if (!(fabs(e - exposure) <= 1e-3 * exposure)) {
			snprintf(why, len, "exposure %.6g us, not %.6g us", e, exposure);
			return;
		}
	}
	if (!isnan(gain)) {
		const json_t *g = json_object_get(st, "gain");
		double gv = json_is_number(g) ? json_number_value(g) : NAN;
		if (!(fabs(gv - gain) <= 1e-6 * (1 + fabs(gain)))) {
			snprintf(why, len, "gain %.6g, not %.6g", gv, gain);
			return;
		}
	}
	if (!isnan(iso)) { /* photographic cameras: ISO is their gain */
		const json_t *g = json_object_get(st, "iso");
		double gv = json_is_number(g) ? json_number_value(g) : NAN;
		if (!(fabs(gv - iso) <= 1e-6 * iso))
			snprintf(why, len, "ISO %.6g, not %.6g", gv, iso);
	}
}

/* The mean image of a capture, its sha256 checked against the manifest. */
static int load_mean(cap_ctx *c, const json_t *cap, kg_image **out, kg_err *err)
{
	const char *name = json_string_value(json_object_get(cap, "name"));
	const json_t *m = json_object_get(json_object_get(cap, "outputs"), "mean");
	const char *file = json_string_value(json_object_get(m, "file"));
	const char *sha = json_string_value(json_object_get(m, "sha256"));
	if (!file || !sha)
		return kg_fail(err, KG_EINVAL, "%s/%s: capture %s: outputs.mean: expected file and "
		                               "sha256",
		               kg_session_dir(c->s), KG_SESSION_MANIFEST, name);
	char *path = kg_session_path(c->s, file);
	char got[65];
	int ret = path ? kg_file_sha256(path, got, err) : KG_ENOMEM;
	if (!ret && strcmp(got, sha))
		ret = kg_fail(err, KG_EIO, "%s: sha256 %s, but the manifest records %s (capture %s)",
		              path, got, sha, name);
	if (!ret)
		ret = kg_image_read(path, out, err);
	free(path);
	return ret;
}

/* The named capture of the given kind, or an error saying what is wrong. */
static int find_kind(cap_ctx *c, const char *name, const char *kind, const char *option,
                     const json_t **out, kg_err *err)
{
	const json_t *cap = kg_session_find(c->s, name);
	if (!cap)
		return kg_fail(err, KG_EINVAL, "%s %s: no capture of that name in %s", option, name,
		               kg_session_dir(c->s));
	const char *k = json_string_value(json_object_get(cap, "kind"));
	if (!k || strcmp(k, kind))
		return kg_fail(err, KG_EINVAL, "%s %s: that capture is a %s, expected a %s", option,
		               name, k ? k : "(no kind)", kind);
	*out = cap;
	return 0;
}

/* "" when capture cap of the session was taken with the camera in use (backend, model
 * and serial of its devices.cameras entry), else what differs, into why. */
static void camera_differs(cap_ctx *c, const json_t *cap, char *why, size_t len)
{
	const kg_camera_info *info = kg_camera_get_info(c->cam);
	const char *id = json_string_value(json_object_get(cap, "camera")), *cid;
	const json_t *cams = kg_json_find(kg_session_manifest(c->s), "devices.cameras"), *e,
	             *found = NULL;
	size_t i;
	why[0] = 0;
	json_array_foreach(cams, i, e)
		if (id && (cid = json_string_value(json_object_get(e, "id"))) && !strcmp(cid, id))
			found = e;
	const char *b = json_string_value(json_object_get(found, "backend"));
	const char *m = json_string_value(json_object_get(found, "model"));
	const char *sn = json_string_value(json_object_get(found, "serial"));
	if (!b || !m || !sn || strcmp(b, info->backend) || strcmp(m, info->model) ||
	    strcmp(sn, info->serial))
		snprintf(why, len, "camera %s %s serial %s, not %s %s serial %s", b ? b : "?",
		         m ? m : "?", sn ? sn : "?", info->backend, info->model, info->serial);
}

/* Choose and load the dark and the flat (after the settings are final). */
static int load_corrections(cap_ctx *c, kg_image **dark, kg_image **flat, kg_err *err)
{
	const kg_capture_options *o = c->o;
	kg_capture_result *r = c->res;
	const json_t *dcap = NULL, *fcap = NULL;
	char why[256];
	int ret = 0;
	double iso = read_feature(c, KG_FEAT_ISO);
	if (o->kind != KG_CAPTURE_DARK && !(o->dark && !strcmp(o->dark, "none"))) {
		if (o->dark) {
			if ((ret = find_kind(c, o->dark, "dark", "--dark", &dcap, err)))
				return ret;
			settings_differ(dcap, &r->format, r->exposure_us, r->gain, iso, why, sizeof(why));
			if (!why[0])
				camera_differs(c, dcap, why, sizeof(why));
			if (why[0])
				return kg_fail(err, KG_EINVAL,
				               "--dark %s: taken with %s; a dark must match the capture's "
				               "camera, exposure, gain, format and size",
				               o->dark, why);
		} else {
			json_t *caps = json_object_get(kg_session_manifest(c->s), "captures"), *cap;
			size_t i;
			json_array_foreach(caps, i, cap)
			{
				const char *k = json_string_value(json_object_get(cap, "kind"));
				settings_differ(cap, &r->format, r->exposure_us, r->gain, iso, why, sizeof(why));
				if (!why[0])
					camera_differs(c, cap, why, sizeof(why));
				if (k && !strcmp(k, "dark") && !why[0])
					dcap = cap; /* the latest wins */
			}
			if (!dcap)
				note(c, "no dark subtracted: the session has no dark capture of this camera "
				        "with exposure %.6g us, %s %.6g, %s %dx%d+%d+%d",
				     r->exposure_us, isnan(r->gain) && !isnan(iso) ? "ISO" : "gain",
				     isnan(r->gain) && !isnan(iso) ? iso : r->gain,
				     kg_pixfmt_name(r->format.pixfmt),
				     r->format.width, r->format.height, r->format.offset_x,
				     r->format.offset_y);
		}
	}
	int flat_applies = o->kind != KG_CAPTURE_FLAT && o->kind != KG_CAPTURE_DARK;
	int latest = !o->flat || !strcmp(o->flat, "latest");
	if (o->flat && !flat_applies && strcmp(o->flat, "none"))
		return kg_fail(err, KG_EINVAL, "--flat: does not apply to a %s capture",
		               kg_capture_kind_name(o->kind));
	if (flat_applies && !(o->flat && !strcmp(o->flat, "none"))) {
		/* the session's newest flat of this camera, format and size */
		const json_t *newest = NULL, *cap;
		json_t *caps = json_object_get(kg_session_manifest(c->s), "captures");
		size_t i;
		json_array_foreach(caps, i, cap)
		{
			const char *k = json_string_value(json_object_get(cap, "kind"));
			if (!k || strcmp(k, "flat"))
				continue;
			settings_differ(cap, &r->format, NAN, NAN, NAN, why, sizeof(why));
			if (!why[0])
				camera_differs(c, cap, why, sizeof(why));
			if (!why[0])
				newest = cap; /* the latest wins */
		}
		if (latest) {
			fcap = newest;
			if (!fcap && o->flat)
				return kg_fail(err, KG_EINVAL, "--flat latest: the session has no flat "
				               "capture of this camera with format %s %dx%d+%d+%d",
				               kg_pixfmt_name(r->format.pixfmt), r->format.width,
				               r->format.height, r->format.offset_x, r->format.offset_y);
			if (!fcap)
				note(c, "no flat applied: the session has no flat capture of this camera "
				        "with format %s %dx%d+%d+%d",
				     kg_pixfmt_name(r->format.pixfmt), r->format.width, r->format.height,
				     r->format.offset_x, r->format.offset_y);
		} else {
			if ((ret = find_kind(c, o->flat, "flat", "--flat", &fcap, err)))
				return ret;
			settings_differ(fcap, &r->format, NAN, NAN, NAN, why, sizeof(why));
			if (why[0])
				return kg_fail(err, KG_EINVAL,
				               "--flat %s: taken with %s; a flat must match the capture's "
				               "format and size",
				               o->flat, why);
			const char *nn = json_string_value(json_object_get(newest, "name"));
			if (newest && newest != fcap)
				note(c, "warning: --flat %s is older than the session's newest flat of this "
				        "camera and format, %s (taken %s): the light or the lens may have "
				        "changed since; without --flat the newest is used",
				     o->flat, nn ? nn : "?",
				     json_string_value(json_object_get(newest, "started"))
				         ? json_string_value(json_object_get(newest, "started"))
				         : "later");
		}
		if (fcap &&
		    json_is_null(json_object_get(json_object_get(fcap, "corrections"), "dark")))
			note(c, "flat %s was taken without a dark subtracted: its offset remains in "
			        "the correction",
			     json_string_value(json_object_get(fcap, "name")));
	}
	if (dcap) {
		if ((ret = load_mean(c, dcap, dark, err)))
			return ret;
		snprintf(r->dark, sizeof(r->dark), "%s",
		         json_string_value(json_object_get(dcap, "name")));
		if (!o->dark)
			note(c, "dark %s subtracted (the session's latest with these settings)", r->dark);
	}
	if (fcap) {
		if ((ret = load_mean(c, fcap, flat, err)))
			return ret;
		/* a clipped or too uneven flat is refused before any frame is taken */
		const json_t *cf = kg_json_find(fcap, "statistics.clipped_fraction");
		if ((ret = kg_flat_check_image(*flat, json_is_number(cf) ? json_number_value(cf) : NAN,
		                               json_string_value(json_object_get(fcap, "name")), NULL,
		                               err)))
			return ret;
		snprintf(r->flat, sizeof(r->flat), "%s",
		         json_string_value(json_object_get(fcap, "name")));
		if (latest)
			note(c, "flat %s applied (the session's newest of this camera and format)",
			     r->flat);
	}
	return 0;
}

/* ---- outputs ------------------------------------------------------------------------ */

/* Write img as float32 TIFF at captures/<name>/<file>; its entry for the manifest. */
static int write_output(cap_ctx *c, const kg_image *img, const char *file,
                        const char *description, json_t *outputs, const char *key,
                        kg_err *err)
{
	char rel[KG_CAPTURE_NAME_MAX + 32];
	snprintf(rel, sizeof(rel), "captures/%s/%s", c->res->name, file);
	char *path = kg_session_path(c->s, rel);
	char sha[65];
	int ret = path ? kg_image_write_tiff(img, path, 32, err) : KG_ENOMEM;
	if (!ret)
		ret = kg_file_sha256(path, sha, err);
	free(path);
	if (ret)
		return ret;
	json_object_set_new(outputs, key,
	                    json_pack("{s:s, s:s, s:s, s:i, s:s}", "file", rel, "sha256", sha,
	                              "sample", "float32", "channels", img->channels,
	                              "description", description));
	return 0;
}

static void remove_outputs(cap_ctx *c)
{
	static const char *const files[] = {"mean.tif", "variance.tif", "rgb.tif", "layout.json",
	                                    "layout.cht"};
	char rel[KG_CAPTURE_NAME_MAX + 32];
	for (size_t i = 0; i < sizeof(files) / sizeof(files[0]); i++) {
		snprintf(rel, sizeof(rel), "captures/%s/%s", c->res->name, files[i]);
		char *p = kg_session_path(c->s, rel);
		if (p)
			unlink(p);
		free(p);
	}
	snprintf(rel, sizeof(rel), "captures/%s", c->res->name);
	char *p = kg_session_path(c->s, rel);
	if (p)
		rmdir(p);
	free(p);
}

/* The chart layout the manifest records: a bundled layout's name as it is; a layout
 * file (--layout FILE: a name with a '/', or a file that exists) copied into
 * captures/<name>/layout.json (layout.cht for an ArgyllCMS template), so that what the
 * manifest names is inside the session. */
static int copy_layout(cap_ctx *c, kg_err *err)
{
	const char *l = c->o->chart_layout;
	struct stat st;
	c->layout_rel[0] = 0;
	if (!l)
		return 0;
	if (!strchr(l, '/') && stat(l, &st) != 0) {
		snprintf(c->layout_rel, sizeof(c->layout_rel), "%s", l);
		return 0;
	}
	size_t n = strlen(l);
	snprintf(c->layout_rel, sizeof(c->layout_rel), "captures/%s/%s", c->res->name,
	         n > 4 && !strcasecmp(l + n - 4, ".cht") ? "layout.cht" : "layout.json");
	char *buf = NULL, *path = kg_session_path(c->s, c->layout_rel);
	size_t len = 0;
	kg_outfile o;
	int ret = path ? kg_read_file(l, &buf, &len, err) : KG_ENOMEM;
	if (!ret)
		ret = kg_outfile_open(&o, path, 0, err);
	if (!ret) {
		if (fwrite(buf, 1, len, o.fp) != len) {
			ret = kg_fail_write(err, errno, path, "write failed");
			kg_outfile_abort(&o);
		} else
			ret = kg_outfile_commit(&o, err);
	}
	free(buf);
	free(path);
	return ret;
}

static json_t *format_json(const kg_frame_format *f)
{
	return json_pack("{s:s, s:i, s:s, s:i, s:i, s:i, s:i, s:I}", "pixfmt",
	                 kg_pixfmt_name(f->pixfmt), "bits", f->bits, "cfa", f->cfa, "width",
	                 f->width, "height", f->height, "offset_x", f->offset_x, "offset_y",
	                 f->offset_y, "stride", (json_int_t)f->stride);
}

static json_t *stream_json(const kg_stream_stats *s)
{
	return json_pack("{s:I, s:I, s:I, s:I, s:I, s:I, s:I}", "completed",
	                 (json_int_t)s->completed, "dropped", (json_int_t)s->dropped, "incomplete",
	                 (json_int_t)s->incomplete, "failed", (json_int_t)s->failed, "timeouts",
	                 (json_int_t)s->timeouts, "resent", (json_int_t)s->resent,
	                 "missing_packets", (json_int_t)s->missing_packets);
}

/* ---- the recording's camera file ----------------------------------------------------- */

/* frames/camera.json as it was before this capture's recording rewrote it (NULL when
 * there was none), so a failed capture can put it back. */
typedef struct saved_file {
	char *path;
	char *data;
	size_t len;
} saved_file;

static void save_file(saved_file *f, const kg_session *s, const char *rel)
{
	memset(f, 0, sizeof(*f));
	f->path = kg_session_path(s, rel);
	struct stat st;
	if (f->path && stat(f->path, &st) == 0 && kg_read_file(f->path, &f->data, &f->len, NULL))
		f->data = NULL;
	kg_inputs_forget(f->path); /* rewritten by the recorder */
}

static void restore_file(cap_ctx *c, saved_file *f)
{
	char *now = NULL;
	size_t len = 0;
	if (f->data && (kg_read_file(f->path, &now, &len, NULL) || len != f->len ||
	                memcmp(now, f->data, len))) {
		kg_inputs_forget(f->path);
		kg_outfile o;
		kg_err e = {{0}};
		int ret = kg_outfile_open(&o, f->path, 0, &e);
		if (!ret && fwrite(f->data, 1, f->len, o.fp) != f->len) {
			kg_outfile_abort(&o);
			ret = kg_fail_write(&e, errno, f->path, "write failed");
		} else if (!ret)
			ret = kg_outfile_commit(&o, &e);
		if (ret)
			note(c, "%s: could not put the recording's camera file back: %s", c->res->name,
			     e.msg);
	}
	kg_inputs_forget(f->path);
	free(now);
}

static void saved_file_free(saved_file *f)
{
	free(f->path);
	free(f->data);
}

/* ---- the capture --------------------------------------------------------------------- */

static int setup_camera(cap_ctx *c, kg_err *err)
{
	const kg_capture_options *o = c->o;
	kg_capture_result *r = c->res;
	int ret = cam(c, kg_camera_manual(c->cam, err));
	if (ret)
		return ret;
	const kg_frame_format *w = &o->format;
	if (w->pixfmt || w->bits || w->cfa[0] || w->width || w->height || w->offset_x ||
	    w->offset_y) {
		kg_frame_format got;
		if ((ret = cam(c, kg_camera_set_format(c->cam, w, &got, err))))
			return ret;
		if ((w->pixfmt && got.pixfmt != w->pixfmt) || (w->bits && got.bits != w->bits) ||
		    (w->cfa[0] && strcmp(got.cfa, w->cfa)) || (w->width && got.width != w->width) ||
		    (w->height && got.height != w->height) ||
		    (w->offset_x && got.offset_x != w->offset_x) ||
		    (w->offset_y && got.offset_y != w->offset_y))
			return kg_fail(err, KG_ERANGE,
			               "camera '%s': asked for %s %d bits %dx%d+%d+%d, it settled on %s%s%s "
			               "%d bits %dx%d+%d+%d",
			               kg_camera_get_info(c->cam)->uri, kg_pixfmt_name(w->pixfmt), w->bits,
			               w->width, w->height, w->offset_x, w->offset_y,
			               kg_pixfmt_name(got.pixfmt), got.cfa[0] ? " " : "", got.cfa,
			               got.bits, got.width, got.height, got.offset_x, got.offset_y);
	}
	if ((ret = cam(c, kg_camera_get_format(c->cam, &r->format, err))))
		return ret;
	if (!kg_pixfmt_is_linear(r->format.pixfmt) && !o->force_nonlinear)
		return kg_fail(err, KG_EINVAL,
		               "camera '%s': delivers %s, which is not linear sensor data: refused for "
		               "measurement; choose a linear --format (mono, bayer, rgb) or add "
		               "--force-nonlinear",
		               kg_camera_get_info(c->cam)->uri, kg_pixfmt_name(r->format.pixfmt));
	if (isfinite(o->gain) &&
	    (ret = cam(c, kg_camera_set(c->cam, KG_FEAT_GAIN, o->gain, NULL, err))))
		return ret;
	if (!o->auto_exposure && o->exposure_us > 0 &&
	    (ret = cam(c, kg_camera_set(c->cam, KG_FEAT_EXPOSURE_US, o->exposure_us, NULL, err))))
		return ret;
	return 0;
}

/* Average the frames into r->mean / r->variance (uncorrected). */
static int average(cap_ctx *c, int timeout_ms, kg_err *err)
{
	const kg_capture_options *o = c->o;
	kg_capture_result *r = c->res;
	kg_frame_accum *acc = NULL;
	int ret = kg_frame_accum_new(&r->format, o->force_nonlinear, &acc, err);
	if (ret)
		return ret;
	if ((ret = cam(c, kg_camera_start(c->cam, 0, err)))) {
		kg_frame_accum_free(&acc);
		return ret;
	}
	double t0 = now_s();
	for (int i = 0; i < o->frames && !ret; i++) {
		kg_frame f;
		if ((ret = pop_frame(c, timeout_ms, &f, err)))
			break;
		ret = kg_frame_accum_add(acc, &f, err);
		if (ret == KG_EINVAL && f.fmt.pixfmt == KG_PIX_MJPEG) {
			/* a damaged compressed frame is the camera's fault: fail with the counts */
			char why[sizeof(err->msg)];
			snprintf(why, sizeof(why), "%s", err ? err->msg : "damaged MJPEG frame");
			ret = stream_error(c, KG_EIO, why, err);
		}
		json_t *e = ret ? NULL : frame_entry(c, &f);
		if (e)
			json_array_append_new(c->frames, e);
		if (!ret && f.source)
			ret = source_entry(c, &f, err);
		kg_camera_push(c->cam, &f, NULL);
		if (!ret && o->progress) {
			double dt = now_s() - t0;
			o->progress(o->progress_user, r->name, i + 1, o->frames,
			            dt > 0 ? (i + 1) / dt : 0);
		}
	}
	kg_camera_stats(c->cam, &r->stream);
	int sret = cam(c, kg_camera_stop(c->cam, ret ? NULL : err));
	if (!ret)
		ret = sret;
	if (!ret)
		ret = kg_frame_accum_result(acc, &r->mean, &r->variance, err);
	if (!ret) {
		r->clipped_fraction = kg_frame_accum_clipped_fraction(acc);
		if (kg_frame_accum_saturation(acc, &r->saturation))
			memset(&r->saturation, 0, sizeof(r->saturation));
	}
	kg_frame_accum_free(&acc);
	return ret;
}

static json_t *capture_json(cap_ctx *c, const char *started, const char *ended,
                            const char *mode, int timeout_ms, double frame_rate,
                            json_t *demosaic)
{
	const kg_capture_options *o = c->o;
	const kg_capture_result *r = c->res;
	json_t *settings = json_pack(
		"{s:o, s:o, s:s, s:o, s:o, s:o, s:o, s:o, s:o, s:i, s:s, s:i, s:I, s:b}",
		"exposure_us", jnum(r->exposure_us), "gain", jnum(r->gain), "gain_unit",
		feature_unit(c, KG_FEAT_GAIN), "frame_rate", jnum(frame_rate), "auto_exposure",
		jnum(read_feature(c, KG_FEAT_AUTO_EXPOSURE)), "auto_white_balance",
		jnum(read_feature(c, KG_FEAT_AUTO_WHITE_BALANCE)), "wb_red",
		jnum(read_feature(c, KG_FEAT_WB_RED)), "wb_blue", jnum(read_feature(c, KG_FEAT_WB_BLUE)),
		"format", format_json(&r->format), "frames", o->frames, "exposure_mode", mode,
		"timeout_ms", timeout_ms, "max_dropped", (json_int_t)o->max_dropped, "force_nonlinear",
		o->force_nonlinear);
	/* Photographic cameras (gphoto2:, raw files): ISO, aperture, focal length, lens. */
	const kg_camera_info *info = kg_camera_get_info(c->cam);
	if (settings) {
		json_object_set_new(settings, "iso", jnum(read_feature(c, KG_FEAT_ISO)));
		json_object_set_new(settings, "aperture", jnum(read_feature(c, KG_FEAT_APERTURE)));
		json_object_set_new(settings, "focal_length_mm",
		                    jnum(read_feature(c, KG_FEAT_FOCAL_LENGTH)));
		json_object_set_new(settings, "lens",
		                    info->lens[0] ? json_string(info->lens) : json_null());
	}
	const kg_image_stats *s = &r->stats;
	json_t *stats = json_pack(
		"{s:o, s:o, s:f, s:o, s:o, s:{s:o, s:o, s:o, s:o}, s:I, s:I, s:o}", "clipped_fraction",
		jnum(r->clipped_fraction), "underexposed_fraction", jnum(s->underexposed_fraction),
		"underexposed_level", KG_UNDEREXPOSED_LEVEL, "min", jnum(s->min), "max", jnum(s->max),
		"percentiles", "p1", jnum(s->p01), "p50", jnum(s->p50), "p99", jnum(s->p99), "p99.9",
		jnum(s->p999), "nonfinite", (json_int_t)s->nonfinite, "flat_invalid",
		(json_int_t)r->flat_invalid, "stream", stream_json(&r->stream));
	if (stats && o->kind == KG_CAPTURE_FLAT)
		json_object_set_new(stats, "illuminance_nonuniformity",
		                    jnum(r->illuminance_nonuniformity));
	if (stats && r->saturation.channels > 0) {
		/* per channel (CFA position): where samples pile up (null: nowhere), the clip
		 * level used and the fraction of samples at it */
		json_t *sat = json_array();
		for (int k = 0; k < r->saturation.channels; k++)
			json_array_append_new(
				sat, json_pack("{s:o, s:f, s:f}", "level",
				               r->saturation.found[k] ? json_real(r->saturation.level[k])
				                                      : json_null(),
				               "clip_level", r->saturation.clip[k], "clipped_fraction",
				               r->saturation.fraction[k]));
		json_object_set_new(stats, "saturation", sat);
	}
	json_t *corr = json_pack("{s:o, s:o}", "dark", r->dark[0] ? json_string(r->dark) : json_null(),
	                         "flat", r->flat[0] ? json_string(r->flat) : json_null());
	json_t *cap = json_pack("{s:s, s:s, s:s, s:s, s:o, s:b, s:O, s:o, s:o}", "name", r->name,
	                        "kind", kg_capture_kind_name(o->kind), "started", started, "ended",
	                        ended, "settings", settings, "recorded", o->record, "frames",
	                        c->frames, "corrections", corr, "statistics", stats);
	if (cap && o->auto_exposure)
		json_object_set_new(
			cap, "exposure_helper",
			json_pack("{s:f, s:f, s:s, s:i, s:O, s:b}", "target", o->target, "tolerance",
			          HELPER_TOLERANCE,
			          "measure", o->measure && o->measure_name ? o->measure_name
			                     : "99.5th percentile of 5x5 same-colour means",
			          "iterations", r->nsteps, "steps", c->steps, "locked", 1));
	if (cap && c->layout_rel[0]) {
		json_object_set_new(cap, "chart_layout", json_string(c->layout_rel));
		if (strcmp(c->layout_rel, o->chart_layout)) /* copied: where from */
			json_object_set_new(cap, "chart_layout_source", json_string(o->chart_layout));
	}
	if (cap && json_object_size(o->meta))
		json_object_set_new(cap, "meta", json_deep_copy(o->meta));
	if (cap && json_array_size(c->sources))
		json_object_set_new(cap, "sources",
		                    json_pack("{s:O, s:s}", "files", c->sources, "decoding",
		                              c->source_note));
	if (cap)
		json_object_set_new(cap, "demosaic", demosaic ? demosaic : json_null());
	else
		json_decref(demosaic);
	return cap;
}

int kg_capture_run(kg_session *s, kg_camera *camera, const kg_capture_options *o,
                   kg_capture_result *res, kg_err *err)
{
	kg_check_arg(s && camera && o && res && o->frames >= 1 && o->max_dropped >= 0 &&
	                 (!o->auto_exposure || (o->target > 0 && o->target < 1)),
	             err);
	memset(res, 0, sizeof(*res));
	cap_ctx c = {.s = s, .cam = camera, .o = o, .res = res};
	int ret = o->name ? kg_session_check_name(s, o->name, err)
	                  : kg_session_next_name(s, kg_capture_kind_name(o->kind), res->name, err);
	if (ret)
		return ret;
	if (o->name)
		snprintf(res->name, sizeof(res->name), "%s", o->name);
	if (o->kind == KG_CAPTURE_DARK && o->dark && strcmp(o->dark, "none"))
		return kg_fail(err, KG_EINVAL, "--dark: does not apply to a dark capture");
	/* Fail before any frame when a named dark or flat is not usable at all. */
	const json_t *tmp;
	if (o->dark && strcmp(o->dark, "none") &&
	    (ret = find_kind(&c, o->dark, "dark", "--dark", &tmp, err)))
		return ret;
	if (o->flat && strcmp(o->flat, "latest") && strcmp(o->flat, "none") &&
	    (ret = find_kind(&c, o->flat, "flat", "--flat", &tmp, err)))
		return ret;

	c.frames = json_array();
	c.steps = json_array();
	c.sources = json_array();
	kg_image *dark = NULL, *flat = NULL;
	json_t *demosaic = NULL;
	char started[32], ended[32];
	int wrote = 0, recorded = 0;
	saved_file camera_file = {0};
	if (!c.frames || !c.steps || !c.sources) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto done;
	}
	if ((ret = setup_camera(&c, err)))
		goto done;
	if (o->record) {
		save_file(&camera_file, s, "frames/camera.json");
		if ((ret = cam(&c, kg_camera_record_start(camera, kg_session_dir(s), err))))
			goto done;
		c.recording = 1;
		recorded = 1;
		if ((ret = cam(&c, kg_camera_record_capture(camera, res->name, err))))
			goto done;
	}
	kg_utc_now(started);
	if (o->auto_exposure && (ret = exposure_helper(&c, o->timeout_ms, err)))
		goto done;
	res->exposure_us = read_feature(&c, KG_FEAT_EXPOSURE_US);
	res->gain = read_feature(&c, KG_FEAT_GAIN);
	double frame_rate = read_feature(&c, KG_FEAT_FRAME_RATE);
	if ((ret = load_corrections(&c, &dark, &flat, err)))
		goto done;
	int timeout_ms = o->timeout_ms > 0 ? o->timeout_ms
	                                   : 2000 + (isfinite(res->exposure_us)
	                                                 ? (int)(2 * res->exposure_us / 1000)
	                                                 : 0);
	if ((ret = average(&c, timeout_ms, err)))
		goto done;
	kg_utc_now(ended);
	if (c.recording) {
		c.recording = 0;
		if ((ret = cam(&c, kg_camera_record_stop(camera, err))))
			goto done;
	}

	/* Statistics of what the sensor saw, then the corrections. */
	if ((ret = kg_image_stats_compute(res->mean, &res->stats, err)))
		goto done;
	if (dark && ((ret = kg_correct_dark(res->mean, dark, err))))
		goto done;
	if (flat && ((ret = kg_correct_flat(res->mean, res->variance, flat, &res->flat_invalid, err))))
		goto done;
	res->illuminance_nonuniformity = NAN;
	if (o->kind == KG_CAPTURE_FLAT) {
		if ((ret = kg_flat_nonuniformity(res->mean, &res->illuminance_nonuniformity, err)))
			goto done;
		note(&c, "%s: the light over the frame departs from its mean by up to %.1f %% "
		         "(illuminance non-uniformity, %d x %d blocks)",
		     res->name, 100 * res->illuminance_nonuniformity, KG_FLAT_BLOCKS, KG_FLAT_BLOCKS);
		kg_err why = {{0}};
		if (kg_flat_check_image(res->mean, res->clipped_fraction, res->name, NULL, &why))
			note(&c, "warning: %s; it will be refused as a flat", why.msg);
	}
	if (res->clipped_fraction > 0 && o->kind != KG_CAPTURE_DARK) {
		char where[256] = "";
		if (kg_saturation_below(&res->saturation, 1.0 - 0.5 / res->saturation.steps))
			kg_saturation_format(&res->saturation,
			                     res->format.cfa[0] && res->saturation.channels == 4
			                         ? res->format.cfa : "RGB",
			                     where, sizeof(where));
		if (where[0])
			note(&c, "%s: %.3f %% of the samples reached the sensor's saturation in at "
			         "least one frame (found from the data, below full scale: %s): values "
			         "there are wrong; lower the exposure or gain",
			     res->name, 100 * res->clipped_fraction, where);
		else
			note(&c, "%s: %.3f %% of the samples reached full scale in at least one frame: "
			         "values there are wrong; lower the exposure or gain",
			     res->name, 100 * res->clipped_fraction);
	}
	if (res->stats.underexposed_fraction > 0.5 && o->kind != KG_CAPTURE_DARK)
		note(&c, "%s: %.1f %% of the samples are below %.0f %% of full scale: under-exposed",
		     res->name, 100 * res->stats.underexposed_fraction, 100 * KG_UNDEREXPOSED_LEVEL);
	if (res->flat_invalid)
		note(&c, "%s: %ld samples have no usable flat (below %.0f %% of its mean): set to NaN",
		     res->name, res->flat_invalid, 5.0);
	int bayer = res->format.pixfmt == KG_PIX_BAYER8 || res->format.pixfmt == KG_PIX_BAYER16;
	if (bayer) {
		double step = 0;
		const char *algo = kg_demosaic_algorithm();
		if (algo) {
			if ((ret = kg_demosaic(res->mean, &res->rgb, &step, err)))
				goto done;
			demosaic = json_pack("{s:s, s:f}", "algorithm", algo, "input_step", step);
		} else {
			demosaic = json_pack("{s:n, s:s}", "algorithm", "note",
			                     "built without OpenCV: only the raw mosaic (mean.tif, with "
			                     "its CFA pattern) is stored");
			note(&c, "%s: kogei was built without OpenCV: the raw mosaic is stored, not "
			         "demosaiced",
			     res->name);
		}
	}

	/* Outputs, then the manifest entry that references them. */
	char rel[KG_CAPTURE_NAME_MAX + 16];
	snprintf(rel, sizeof(rel), "captures/%s", res->name);
	/* a real folder below the session, no symbolic link on the way */
	if ((ret = kg_mkdir_below(kg_session_dir(s), rel, err)))
		goto done;
	wrote = 1;
	json_t *outputs = json_object();
	char desc[256];
	snprintf(desc, sizeof(desc), "mean of %d frames, 0..1 of full scale%s%s", o->frames,
	         res->dark[0] ? ", dark subtracted" : "",
	         res->flat[0] ? ", flat-field corrected" : "");
	ret = write_output(&c, res->mean, "mean.tif", desc, outputs, "mean", err);
	if (!ret)
		ret = write_output(&c, res->variance, "variance.tif",
		                   "per-sample variance of the frames (n - 1), in (0..1)^2"
		                   "; divided by the squared flat when one is applied",
		                   outputs, "variance", err);
	if (!ret && res->rgb)
		ret = write_output(&c, res->rgb, "rgb.tif", "the mean demosaiced to RGB", outputs,
		                   "rgb", err);
	if (!ret)
		ret = copy_layout(&c, err);
	/* The outputs' directory entries reach the disk before the manifest names them. */
	for (int k = 0; k < 2 && !ret; k++) {
		char *d = kg_session_path(s, k ? "captures" : rel);
		ret = d ? kg_sync_dir(d, err) : kg_fail(err, KG_ENOMEM, "out of memory");
		free(d);
	}
	json_t *cap = NULL;
	if (!ret) {
		cap = capture_json(&c, started, ended,
		                   o->auto_exposure ? "auto" : o->exposure_us > 0 ? "manual" : "camera",
		                   timeout_ms, frame_rate, demosaic);
		demosaic = NULL; /* capture_json took it */
	}
	if (!ret && cap && json_object_set_new(cap, "outputs", outputs) == 0) {
		outputs = NULL;
		ret = kg_session_append(s, kg_camera_get_info(camera), cap, err);
	} else if (!ret) {
		json_decref(cap);
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	}
	json_decref(outputs);
done:
	if (c.recording)
		kg_camera_record_stop(camera, NULL);
	if (ret && wrote)
		remove_outputs(&c);
	if (ret && recorded) { /* nothing of a failed capture stays, its raw frames neither */
		kg_err e2 = {{0}};
		if (kg_camera_recording_discard(kg_session_dir(s), res->name, &e2))
			note(&c, "%s: could not take the failed capture's frames back out: %s",
			     res->name, e2.msg);
		restore_file(&c, &camera_file);
	}
	saved_file_free(&camera_file);
	json_decref(demosaic);
	json_decref(c.frames);
	json_decref(c.steps);
	json_decref(c.sources);
	kg_image_free(&dark);
	kg_image_free(&flat);
	if (ret) {
		int df = res->device_failure;
		char name[KG_CAPTURE_NAME_MAX];
		memcpy(name, res->name, sizeof(name));
		kg_stream_stats st = res->stream;
		kg_capture_result_clear(res);
		res->device_failure = df;
		res->stream = st;
		memcpy(res->name, name, sizeof(name));
	}
	return ret;
}
