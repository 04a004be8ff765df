/* kogei console: the jobs the page starts, one at a time, each in a worker thread
 * through the library calls of the commands (docs/console.md, "Actions"): captures
 * (kg_capture_run, as kogei acquire), the spectrometer's guided chart
 * (kg_measure_flow_chart, as kogei measure --chart), processing (kg_process_run, as
 * kogei process) and the deposit (kg_deposit_run with the options of kogei deposit's
 * table, from the request's JSON). */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "console.h"

#define LOG_MAX 400 /* lines kept */

void console_log(console *c, const char *fmt, ...)
{
	char line[1024];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(line, sizeof(line), fmt, ap);
	va_end(ap);
	json_array_append_new(c->job_log, kg_json_message(line));
	while (json_array_size(c->job_log) > LOG_MAX)
		json_array_remove(c->job_log, 0);
}

static void log_locked(console *c, const char *message)
{
	pthread_mutex_lock(&c->lock);
	console_log(c, "%s", message);
	pthread_mutex_unlock(&c->lock);
}

void console_manifest_refresh(console *c)
{
	json_decref(c->manifest);
	c->manifest = json_deep_copy(kg_session_manifest(c->session));
}

static int exists(const char *path)
{
	struct stat st;
	return stat(path, &st) == 0;
}

json_t *console_state_json(console *c)
{
	char partial[PATH_MAX + 16], report[PATH_MAX + 16];
	snprintf(partial, sizeof(partial), "%s.partial", c->spectra_out);
	snprintf(report, sizeof(report), "%s/report.html", c->outdir);
	json_t *cams = json_array();
	for (int i = 0; i < c->ncameras; i++)
		json_array_append_new(cams, json_string(c->cameras[i]));
	pthread_mutex_lock(&c->lock);
	json_t *j = json_pack(
		"{s:s, s:s, s:s, s:o, s:i, s:o, s:o, s:i, s:b, s:b, s:b, s:b, "
		"s:{s:b, s:s, s:s, s:O, s:o, s:s, s:i, s:i, s:f, s:o, s:o, s:s}}",
		"session", c->session_dir, "outdir", c->outdir, "spectra_out", c->spectra_out,
		"cameras", cams, "camera", c->cam_index, "layout",
		c->chart_layout ? json_string(c->chart_layout->name) : json_null(), "spectro",
		c->spectro_uri ? json_string(c->spectro_uri) : json_null(), "frames", c->frames,
		"spectra_measured", exists(c->spectra_out), "spectra_partial", exists(partial),
		"report", exists(report), "reference", c->reference != NULL, "job", "running",
		c->job_running, "kind", c->job_kind, "title", c->job_title, "log", c->job_log,
		"result", c->job_result ? json_deep_copy(c->job_result) : json_null(), "error",
		c->job_error, "i", c->job_i, "n", c->job_n, "fps", c->job_fps, "prompt",
		c->waiting ? json_string(c->prompt) : json_null(), "waiting", json_boolean(c->waiting),
		"allowed", c->allowed);
	pthread_mutex_unlock(&c->lock);
	return j;
}

json_t *console_session_json(console *c)
{
	pthread_mutex_lock(&c->lock);
	json_t *m = json_deep_copy(c->manifest);
	pthread_mutex_unlock(&c->lock);
	return json_pack("{s:s, s:o}", "session", c->session_dir, "manifest", m);
}

/* ---- the job slot ------------------------------------------------------------------ */

typedef struct job {
	console *c;
	json_t *req;
	void *(*run)(void *);
} job;

static void job_finish(console *c, json_t *result, const char *error)
{
	pthread_mutex_lock(&c->lock);
	json_decref(c->job_result);
	c->job_result = result;
	snprintf(c->job_error, sizeof(c->job_error), "%s", error ? error : "");
	if (error)
		console_log(c, "failed: %s", error);
	c->job_running = 0;
	c->waiting = 0;
	pthread_cond_broadcast(&c->cond);
	pthread_mutex_unlock(&c->lock);
}

static int job_start(console *c, const char *kind, const char *title,
                     void *(*run)(void *), const json_t *req, char *why, size_t n)
{
	pthread_mutex_lock(&c->lock);
	if (c->job_running || c->stop) {
		snprintf(why, n, "busy: %s is running", c->job_running ? c->job_title : "stopping");
		pthread_mutex_unlock(&c->lock);
		return 409;
	}
	if (c->job_joinable) {
		pthread_join(c->job_thread, NULL);
		c->job_joinable = 0;
	}
	job *j = calloc(1, sizeof(*j));
	if (!j) {
		pthread_mutex_unlock(&c->lock);
		snprintf(why, n, "out of memory");
		return 500;
	}
	j->c = c;
	j->req = json_deep_copy(req);
	c->job_running = 1;
	snprintf(c->job_kind, sizeof(c->job_kind), "%s", kind);
	snprintf(c->job_title, sizeof(c->job_title), "%s", title);
	json_array_clear(c->job_log);
	json_decref(c->job_result);
	c->job_result = NULL;
	c->job_error[0] = 0;
	c->job_i = c->job_n = 0;
	c->job_fps = 0;
	if (pthread_create(&c->job_thread, NULL, run, j)) {
		c->job_running = 0;
		json_decref(j->req);
		free(j);
		pthread_mutex_unlock(&c->lock);
		snprintf(why, n, "cannot start a thread");
		return 500;
	}
	c->job_joinable = 1;
	pthread_mutex_unlock(&c->lock);
	return 0;
}

void console_jobs_stop(console *c)
{
	pthread_mutex_lock(&c->lock);
	c->stop = 1;
	if (c->waiting) {
		c->answer = 'q';
		c->waiting = 0;
	}
	pthread_cond_broadcast(&c->cond);
	int joinable = c->job_joinable;
	c->job_joinable = 0;
	pthread_mutex_unlock(&c->lock);
	if (joinable)
		pthread_join(c->job_thread, NULL);
}

/* ---- captures ------------------------------------------------------------------------ */

static void capture_progress(void *user, const char *name, int i, int n, double fps)
{
	console *c = user;
	pthread_mutex_lock(&c->lock);
	c->job_i = i;
	c->job_n = n;
	c->job_fps = fps;
	if (i == n || i % (n >= 10 ? n / 10 : 1) == 0)
		console_log(c, "%s: frame %d/%d  %.1f fps", name, i, n, fps);
	pthread_mutex_unlock(&c->lock);
}

static void capture_note(void *user, const char *message)
{
	char line[1100];
	snprintf(line, sizeof(line), "note: %s", message);
	log_locked(user, line);
}

static const char *jstr(const json_t *req, const char *key)
{
	const char *s = json_string_value(json_object_get(req, key));
	return s && *s ? s : NULL;
}

static double jdbl(const json_t *req, const char *key, double dflt)
{
	const json_t *v = json_object_get(req, key);
	return json_is_number(v) ? json_number_value(v) : dflt;
}

static void *capture_main(void *arg)
{
	job *jb = arg;
	console *c = jb->c;
	json_t *req = jb->req;
	kg_capture_options o;
	kg_capture_options_default(&o);
	kg_capture_kind_parse(jstr(req, "kind"), &o.kind, NULL);
	o.name = jstr(req, "name");
	o.frames = (int)jdbl(req, "frames", c->frames);
	o.exposure_us = jdbl(req, "exposure_us", 0);
	o.gain = jdbl(req, "gain", NAN);
	o.auto_exposure = json_is_true(json_object_get(req, "auto_exposure"));
	o.target = jdbl(req, "target", o.target);
	o.dark = jstr(req, "dark");
	o.flat = jstr(req, "flat");
	o.meta = json_object_get(req, "meta"); /* checked by console_job_capture */
	o.progress = capture_progress;
	o.progress_user = c;
	o.note = capture_note;
	o.note_user = c;
	kg_chart_level cm = {0};
	char measure_name[96] = "";
	if (c->chart_layout && (o.kind == KG_CAPTURE_CHART || o.auto_exposure)) {
		cm.layout = c->chart_layout;
		kg_chart_detect_options_default(&cm.opt);
		o.measure = o.auto_exposure ? kg_chart_brightest_patch : NULL;
		o.measure_user = &cm;
		o.chart_layout = c->layout;
		snprintf(measure_name, sizeof(measure_name), "brightest patch of chart %s",
		         c->chart_layout->name);
		o.measure_name = measure_name;
	}
	kg_err err = {{0}};
	kg_capture_result res;
	memset(&res, 0, sizeof(res));
	int camera = (int)jdbl(req, "camera", -1);
	console_camera_take(c);
	int ret = 0;
	if (camera >= 0)
		ret = console_camera_select(c, camera, &err);
	if (!ret && !c->cam)
		ret = kg_fail(&err, KG_EINVAL, "no camera: start the console with --camera URI");
	if (!ret)
		ret = kg_capture_run(c->session, c->cam, &o, &res, &err);
	json_t *entry = NULL;
	pthread_mutex_lock(&c->lock);
	if (!ret) {
		console_manifest_refresh(c);
		entry = json_deep_copy(kg_session_find(c->session, res.name));
		console_log(c, "%s: in %s/%s (%zu captures)", res.name, c->session_dir,
		            KG_SESSION_MANIFEST,
		            json_array_size(json_object_get(c->manifest, "captures")));
	}
	pthread_mutex_unlock(&c->lock);
	console_camera_give(c);
	kg_capture_result_clear(&res);
	job_finish(c, entry, ret ? err.msg : NULL);
	json_decref(req);
	free(jb);
	return NULL;
}

/* A number field of a request: absent (0), a finite number in lo..hi (1, *out set),
 * else -1 with *why naming the field and what was expected. */
static int num_field(const json_t *req, const char *what, const char *key, double lo,
                     double hi, const char *expect, double *out, char *why, size_t n)
{
	const json_t *v = json_object_get(req, key);
	if (!v)
		return 0;
	double x = json_is_number(v) ? json_number_value(v) : NAN;
	if (!(isfinite(x) && x >= lo && x <= hi)) {
		snprintf(why, n, "%s: '%s': expected %s", what, key, expect);
		return -1;
	}
	*out = x;
	return 1;
}

/* The request's "camera" (an index into the --camera list) into *cam when given:
 * 0, or -1 with *why. */
static int camera_field(console *c, const json_t *req, const char *what, double *cam,
                        char *why, size_t n)
{
	if (num_field(req, what, "camera", 0, c->ncameras - 1, "an index into the --camera list",
	              cam, why, n) < 0 ||
	    *cam != floor(*cam)) {
		snprintf(why, n, "%s: 'camera': expected 0..%d (the --camera list)", what,
		         c->ncameras - 1);
		return -1;
	}
	return 0;
}

/* Feature k of console_feats at value v against the range of camera cam of the list,
 * when it has been opened (the others are checked by the camera when the job sets
 * them): 0, or 400 with *why. */
static int feat_check(console *c, int cam, int k, double v, const char *what, char *why,
                      size_t n)
{
	pthread_mutex_lock(&c->lock);
	if (cam < 0)
		cam = c->cam_index;
	int known = cam >= 0 && cam < c->ncameras && c->feat_known[cam];
	kg_feature_info fi;
	memset(&fi, 0, sizeof(fi));
	if (known)
		fi = c->feat[cam][k];
	pthread_mutex_unlock(&c->lock);
	if (!known)
		return 0;
	if (!fi.available) {
		snprintf(why, n, "%s: '%s': camera %d (%s) has no such control", what,
		         console_feat_keys[k], cam, c->cameras[cam]);
		return 400;
	}
	if (fi.max > fi.min && !(v >= fi.min && v <= fi.max)) {
		snprintf(why, n, "%s: '%s': expected %g..%g %s (the range of camera %d), got %g", what,
		         console_feat_keys[k], fi.min, fi.max, fi.unit, cam, v);
		return 400;
	}
	return 0;
}

int console_job_capture(console *c, const json_t *req, char *why, size_t n)
{
	kg_capture_kind kind;
	kg_err err = {{0}};
	const char *k = jstr(req, "kind"), *name = jstr(req, "name");
	if (!k || kg_capture_kind_parse(k, &kind, &err)) {
		snprintf(why, n, "capture: 'kind': expected chart, object, dark or flat");
		return 400;
	}
	double frames = c->frames, exp = 0, gain = NAN, target = 0.5, cam = -1;
	if (num_field(req, "capture", "frames", 1, 10000, "a whole number 1..10000", &frames, why,
	              n) < 0 ||
	    frames != floor(frames)) {
		snprintf(why, n, "capture: 'frames': expected a whole number 1..10000");
		return 400;
	}
	if (camera_field(c, req, "capture", &cam, why, n))
		return 400;
	if (num_field(req, "capture", "exposure_us", 0, 1e9,
	              "microseconds > 0 (or 0: keep the camera's)", &exp, why, n) < 0 ||
	    num_field(req, "capture", "gain", -1e9, 1e9, "a number (the camera's unit)", &gain, why,
	              n) < 0 ||
	    num_field(req, "capture", "target", 0.01, 0.99,
	              "the brightest patch's level 0.01..0.99 of full scale", &target, why, n) < 0)
		return 400;
	if ((exp > 0 && feat_check(c, (int)cam, 0, exp, "capture", why, n)) ||
	    (isfinite(gain) && feat_check(c, (int)cam, 1, gain, "capture", why, n)))
		return 400;
	if (name && !kg_name_is_safe(name, KG_CAPTURE_NAME_MAX)) {
		snprintf(why, n, "capture: 'name' '%s': expected 1 to %d letters, digits, '.', '_' or "
		         "'-', not starting with '.'", name, KG_CAPTURE_NAME_MAX - 1);
		return 400;
	}
	const json_t *ae = json_object_get(req, "auto_exposure");
	if (ae && !json_is_boolean(ae)) {
		snprintf(why, n, "capture: 'auto_exposure': expected true or false");
		return 400;
	}
	int auto_exp = json_is_true(ae);
	if (auto_exp && kind == KG_CAPTURE_DARK) {
		snprintf(why, n, "capture: a dark has no light to meter: give the exposure of the "
		         "captures it is for");
		return 400;
	}
	const json_t *meta = json_object_get(req, "meta");
	if (meta && !json_is_object(meta)) {
		snprintf(why, n, "capture: 'meta': expected an object of KEY: \"value\" strings");
		return 400;
	}
	json_t *checked = json_object();
	const char *mk;
	const json_t *mv;
	int bad = !checked;
	json_object_foreach((json_t *)meta, mk, mv)
	{
		char what[128];
		snprintf(what, sizeof(what), "capture: 'meta.%.64s'", mk);
		if (bad || !json_is_string(mv)) {
			snprintf(why, n, "%s: expected a string", what);
			bad = 1;
		} else if (kg_meta_set(checked, what, mk, json_string_value(mv), &err)) {
			snprintf(why, n, "%s", err.msg);
			bad = 1;
		}
		if (bad)
			break;
	}
	json_decref(checked);
	if (bad)
		return 400;
	char title[128];
	snprintf(title, sizeof(title), "%s capture of %d frames", k, (int)frames);
	return job_start(c, "capture", title, capture_main, req, why, n);
}

/* ---- settings ----------------------------------------------------------------------- */

int console_settings_set(console *c, const json_t *req, char *why, size_t n)
{
	double cam = -1;
	if (camera_field(c, req, "settings", &cam, why, n))
		return 400;
	/* Every field is checked before any is applied: a bad one changes nothing. */
	double val[3];
	int has[3];
	for (int k = 0; k < 3; k++) {
		has[k] = num_field(req, "settings", console_feat_keys[k], -1e12, 1e12, "a number",
		                   &val[k], why, n);
		if (has[k] < 0 || (has[k] && feat_check(c, (int)cam, k, val[k], "settings", why, n)))
			return 400;
	}
	pthread_mutex_lock(&c->lock);
	int busy = c->job_running && !strcmp(c->job_kind, "capture");
	pthread_mutex_unlock(&c->lock);
	if (busy) {
		snprintf(why, n, "settings: a capture owns the camera");
		return 409;
	}
	kg_err err = {{0}};
	int ret = 0;
	console_camera_take(c);
	if (cam >= 0)
		ret = console_camera_select(c, (int)cam, &err);
	if (!ret && !c->cam)
		ret = kg_fail(&err, KG_EINVAL, "no camera");
	for (int k = 0; !ret && k < 3; k++)
		if (has[k])
			ret = kg_camera_set(c->cam, console_feats[k], val[k], NULL, &err);
	console_camera_give(c);
	if (ret) {
		snprintf(why, n, "%s", err.msg);
		return ret == KG_EINVAL || ret == KG_ERANGE ? 400 : 500;
	}
	return 0;
}

/* ---- the spectrometer chart ------------------------------------------------------------ */

static int ask_page(void *user, const char *allowed, const char *prompt)
{
	console *c = user;
	pthread_mutex_lock(&c->lock);
	snprintf(c->prompt, sizeof(c->prompt), "%s", prompt);
	snprintf(c->allowed, sizeof(c->allowed), "%s", allowed);
	console_log(c, "%s", prompt);
	c->answer = 0;
	c->waiting = 1;
	while (c->waiting && !c->stop)
		pthread_cond_wait(&c->cond, &c->lock);
	int a = c->stop ? 'q' : c->answer;
	c->waiting = 0;
	pthread_mutex_unlock(&c->lock);
	return a;
}

static void say_page(void *user, const char *message) { log_locked(user, message); }

static void *measure_main(void *arg)
{
	job *jb = arg;
	console *c = jb->c;
	int resume = json_is_true(json_object_get(jb->req, "resume"));
	kg_measure_flow m = {0};
	kg_acquire_options_default(&m.s.acq);
	m.s.acq.scans = 3;
	m.white_max_age = 600;
	m.ui.ask = ask_page;
	m.ui.say = say_page;
	m.ui.user = c;
	kg_measure_flow_init(&m);
	kg_err err = {{0}};
	kg_patch_list pl = {0};
	int r = kg_patch_list_load(c->layout, NULL, NULL, &pl, &err);
	if (!r)
		r = kg_white_reference_load(NULL, &m.s.white_refl, &err);
	m.s.uri = c->spectro_uri;
	if (!r)
		r = kg_spectro_open(c->spectro_uri, &m.s.spectro, &err);
	if (!r)
		r = kg_spectro_set_integration(m.s.spectro, 100000, &err);
	if (!r) {
		const kg_spectro_info *info = kg_spectro_get_info(m.s.spectro);
		char line[PATH_MAX + 512];
		snprintf(line, sizeof(line), "%s %s, integration 100 ms, 3 scans averaged, %d patches "
		         "of %s into %s", info->model, info->serial, pl.n, c->chart_layout->name,
		         c->spectra_out);
		say_page(c, line);
		r = kg_measure_flow_chart(&m, &pl, c->spectra_out, resume, 0, &err);
	}
	json_t *result = NULL;
	const char *error = NULL;
	if (r > 0)
		error = "stopped by the operator: what was measured stays in the .partial file; "
		        "measure again with resume to continue";
	else if (r)
		error = err.msg;
	else
		result = json_pack("{s:s, s:i}", "file", c->spectra_out, "patches", pl.n);
	char msg[1100];
	snprintf(msg, sizeof(msg), "%s", error ? error : "");
	kg_measure_session_clear(&m.s);
	kg_spectro_free(&m.s.spectro);
	kg_patch_list_free(&pl);
	job_finish(c, result, error ? msg : NULL);
	json_decref(jb->req);
	free(jb);
	return NULL;
}

/* An optional boolean field: 0, or 400 with *why naming it. */
static int bool_field(const json_t *req, const char *what, const char *key, char *why, size_t n)
{
	const json_t *v = json_object_get(req, key);
	if (v && !json_is_boolean(v)) {
		snprintf(why, n, "%s: '%s': expected true or false", what, key);
		return 400;
	}
	return 0;
}

int console_job_measure(console *c, const json_t *req, char *why, size_t n)
{
	if (bool_field(req, "measure", "resume", why, n))
		return 400;
	if (!c->spectro_uri) {
		snprintf(why, n, "measure: no spectrometer: start the console with --spectro URI");
		return 400;
	}
	if (!c->chart_layout) {
		snprintf(why, n, "measure: no chart layout: start the console with --layout L");
		return 400;
	}
	return job_start(c, "measure", "spectrometer chart", measure_main, req, why, n);
}

int console_job_answer(console *c, const json_t *req, char *why, size_t n)
{
	const char *a = jstr(req, "answer");
	pthread_mutex_lock(&c->lock);
	int st = 0;
	if (!c->waiting) {
		snprintf(why, n, "answer: no measurement is waiting for the operator");
		st = 409;
	} else if (!a || strlen(a) != 1 || (!strchr("mq", a[0]) && !strchr(c->allowed, a[0]))) {
		snprintf(why, n, "answer: expected \"m\" (measure), \"q\" (stop)%s%s",
		         strchr(c->allowed, 'r') ? ", \"r\" (redo the last patch)" : "",
		         strchr(c->allowed, 'w') ? ", \"w\" (white again)" : "");
		st = 400;
	} else {
		c->answer = a[0];
		c->waiting = 0;
		pthread_cond_broadcast(&c->cond);
	}
	pthread_mutex_unlock(&c->lock);
	return st;
}

/* ---- processing --------------------------------------------------------------------- */

static ssize_t progress_write(void *cookie, const char *buf, size_t size)
{
	console *c = cookie;
	/* lines as they come (kg_process_run writes whole lines) */
	char line[1024];
	size_t off = 0;
	while (off < size) {
		const char *nl = memchr(buf + off, '\n', size - off);
		size_t n = nl ? (size_t)(nl - (buf + off)) : size - off;
		snprintf(line, sizeof(line), "%.*s", (int)(n < sizeof(line) ? n : sizeof(line) - 1),
		         buf + off);
		if (n)
			log_locked(c, line);
		off += n + (nl ? 1 : 0);
	}
	return (ssize_t)size;
}

/* A job's progress stream: its lines go to the page's log (NULL when out of memory). */
static FILE *job_progress(console *c)
{
	cookie_io_functions_t io = {.write = progress_write};
	FILE *progress = fopencookie(c, "w", io);
	if (progress)
		setvbuf(progress, NULL, _IOLBF, 0);
	return progress;
}

/* The request's options of the access copy and the manifests (kg_process_access_table:
 * access_compression, access_quality, iiif_base, files_base) into o, checked; "render"
 * is the console's own. */
static int process_access_options(const json_t *req, kg_process_options *o, kg_err *err)
{
	/* a shallow copy: its strings are req's, which outlive it */
	json_t *rest = json_copy((json_t *)req);
	if (!rest)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	json_object_del(rest, "render");
	int ret = kg_opt_from_json(&kg_process_access_table, rest, o, err);
	json_decref(rest);
	return ret ? ret : kg_process_access_check(o, err);
}

static void *process_main(void *arg)
{
	job *jb = arg;
	console *c = jb->c;
	kg_process_options o;
	kg_process_options_default(&o);
	FILE *progress = job_progress(c);
	o.session = c->session_dir;
	o.outdir = c->outdir;
	o.reference = c->reference;
	o.spectra = exists(c->spectra_out) ? c->spectra_out : NULL;
	o.layout = c->layout;
	o.progress = progress;
	o.command = "kogei console";
	o.render = !json_is_false(json_object_get(jb->req, "render"));
	kg_err err = {{0}};
	kg_process_summary sum;
	/* checked when the job was started: the strings are the request's, kept until the
	 * end of the job */
	int ret = process_access_options(jb->req, &o, &err);
	if (!ret)
		ret = o.reference || o.spectra
		          ? kg_process_run(&o, &sum, &err)
		          : kg_fail(&err, KG_EINVAL, "process: no chart spectra (%s) and no "
		                    "--reference: measure the chart with the spectrometer first",
		                    c->spectra_out);
	if (progress)
		fclose(progress);
	json_t *result = ret ? NULL
	                     : json_pack("{s:i, s:i, s:i, s:f, s:i, s:f, s:s}", "objects",
	                                 sum.objects, "processed", sum.processed, "unchanged",
	                                 sum.skipped, "residual", sum.residual, "warnings",
	                                 sum.warnings, "seconds", sum.seconds, "report",
	                                 "/out/report.html");
	job_finish(c, result, ret ? err.msg : NULL);
	json_decref(jb->req);
	free(jb);
	return NULL;
}

int console_job_process(console *c, const json_t *req, char *why, size_t n)
{
	if (bool_field(req, "process", "render", why, n))
		return 400;
	kg_process_options scratch;
	kg_process_options_default(&scratch);
	kg_err err = {{0}};
	if (process_access_options(req, &scratch, &err)) {
		snprintf(why, n, "process: %s", err.msg);
		return 400;
	}
	return job_start(c, "process", "kogei process", process_main, req, why, n);
}

/* ---- the deposit -------------------------------------------------------------------- */

/* The deposit of OUTDIR into OUTDIR.bag beside it, with the request's options
 * (kg_deposit_table: with_session, copy, force, the bag-info values). */
static int deposit_options(console *c, const json_t *req, kg_deposit_options *o, char *bag,
                           size_t size, kg_err *err)
{
	kg_deposit_options_default(o);
	size_t n = strlen(c->outdir);
	while (n > 1 && c->outdir[n - 1] == '/')
		n--;
	snprintf(bag, size, "%.*s.bag", (int)n, c->outdir);
	o->results = c->outdir;
	o->bag = bag;
	int ret = kg_opt_from_json(&kg_deposit_table, req, o, err);
	return ret ? ret : kg_deposit_check(o, err);
}

static void *deposit_main(void *arg)
{
	job *jb = arg;
	console *c = jb->c;
	kg_deposit_options o;
	char bag[PATH_MAX + 8];
	kg_err err = {{0}};
	kg_deposit_summary sum;
	int ret = deposit_options(c, jb->req, &o, bag, sizeof(bag), &err);
	o.progress = job_progress(c);
	if (!ret)
		ret = kg_deposit_run(&o, &sum, &err);
	if (o.progress)
		fclose(o.progress);
	json_t *result = ret ? NULL
	                     : json_pack("{s:s, s:i, s:I, s:i, s:i, s:i}", "bag", bag, "files",
	                                 sum.files, "bytes", (json_int_t)sum.bytes, "linked",
	                                 sum.linked, "copied", sum.copied, "identifiers",
	                                 sum.identifiers);
	if (result)
		log_locked(c, "the bag is complete");
	job_finish(c, result, ret ? err.msg : NULL);
	json_decref(jb->req);
	free(jb);
	return NULL;
}

int console_job_deposit(console *c, const json_t *req, char *why, size_t n)
{
	kg_deposit_options o;
	char bag[PATH_MAX + 8];
	kg_err err = {{0}};
	if (deposit_options(c, req, &o, bag, sizeof(bag), &err)) {
		snprintf(why, n, "deposit: %s", err.msg);
		return 400;
	}
	return job_start(c, "deposit", "kogei deposit", deposit_main, req, why, n);
}
