/* A collection's entries: the task that runs one (kogei process, then its state written
 * atomically), the record of them all (collection.json, through collection_html.c
 * index.html), the status and the thumbnails. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "collection_private.h"

/* ---- the task -------------------------------------------------------------------------- */

static volatile sig_atomic_t task_signal;
static volatile pid_t task_child;

static void task_on_signal(int sig)
{
	task_signal = sig;
	if (task_child > 0)
		kill(task_child, sig);
}

static void task_catch_signals(void)
{
	static const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
	for (size_t i = 0; i < sizeof(sigs) / sizeof(sigs[0]); i++) {
		struct sigaction old, sa;
		if (sigaction(sigs[i], NULL, &old) != 0 ||
		    (!(old.sa_flags & SA_SIGINFO) && old.sa_handler == SIG_IGN))
			continue;
		memset(&sa, 0, sizeof(sa));
		sa.sa_handler = task_on_signal;
		sigemptyset(&sa.sa_mask);
		sigaction(sigs[i], &sa, NULL);
	}
}

/* The reason of a failed run: the last line of its log that is kogei's error ("kogei:
 * MESSAGE", not a note or a warning), without the prefix; else NULL. */
static char *log_reason(const char *log)
{
	FILE *fp = fopen(log, "r");
	if (!fp)
		return NULL;
	char *line = NULL, *reason = NULL;
	size_t cap = 0;
	ssize_t n;
	while ((n = getline(&line, &cap, fp)) > 0) {
		while (n > 0 && (line[n - 1] == '\n' || line[n - 1] == '\r'))
			line[--n] = 0;
		if (strncmp(line, "kogei: ", 7) || !strncmp(line + 7, "note:", 5) ||
		    !strncmp(line + 7, "warning:", 8))
			continue;
		free(reason);
		reason = strdup(line + 7);
	}
	free(line);
	fclose(fp);
	return reason;
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int kg_collection_task(const char *out, int index, const char *job, int threads,
                       const char *self, int *done, kg_err *err)
{
	kg_check_arg(out && done, err);
	*done = 0;
	json_t *plan = NULL;
	int ret = coll_plan_load(out, &plan, err);
	if (ret)
		return ret;
	json_t *entries = json_object_get(plan, "entries");
	json_t *e = json_array_get(entries, (size_t)index);
	const char *name = json_string_value(json_object_get(e, "name"));
	json_t *args = json_object_get(e, "args");
	if (index < 0 || !e || !name || !kg_name_is_safe(name, COLL_NAME_MAX) ||
	    !json_is_array(args)) {
		json_decref(plan);
		return kg_fail(err, KG_EINVAL, "%s: entry %d: expected an entry of the plan (0 to %zu)",
		               out, index, json_array_size(entries) - 1);
	}
	char *exe = coll_self(self), *log = coll_log_path(out, name), *state = coll_state_path(out, name);
	char *logdir = coll_path(out, "logs"), *statedir = coll_path(out, "entries");
	size_t nargs = json_array_size(args);
	char **argv = calloc(nargs + 4, sizeof(char *));
	char threads_s[16];
	snprintf(threads_s, sizeof(threads_s), "%d", threads);
	if (!exe || !log || !state || !logdir || !statedir || !argv) {
		ret = kg_fail(err, exe ? KG_ENOMEM : KG_EIO, "%s", exe ? "out of memory"
		              : "cannot find the kogei executable (/proc/self/exe)");
		goto out;
	}
	if ((ret = kg_mkdir_p(logdir, err)) || (ret = kg_mkdir_p(statedir, err)))
		goto out;
	argv[0] = exe;
	for (size_t i = 0; i < nargs; i++)
		argv[i + 1] = (char *)json_string_value(json_array_get(args, i));
	if (threads > 0) {
		argv[nargs + 1] = "--threads";
		argv[nargs + 2] = threads_s;
	}
	int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
	if (fd < 0) {
		ret = kg_fail(err, KG_EIO, "%s: cannot write: %s", log, strerror(errno));
		goto out;
	}
	char started[32];
	coll_now(started);
	dprintf(fd, "kogei collection: %s: entry %d (list line %lld), job %s, started %s\n", name,
	        index, (long long)json_integer_value(json_object_get(e, "line")), job ? job : "-",
	        started);
	fflush(NULL);
	task_catch_signals();
	double t0 = now_s();
	pid_t pid = fork();
	if (pid == 0) {
		dup2(fd, 1);
		dup2(fd, 2);
		int nul = open("/dev/null", O_RDONLY);
		if (nul >= 0)
			dup2(nul, 0);
		execv(exe, argv);
		dprintf(2, "kogei: %s: cannot run: %s\n", exe, strerror(errno));
		_exit(127);
	}
	if (pid < 0) {
		close(fd);
		ret = kg_fail(err, KG_EIO, "cannot start kogei process: %s", strerror(errno));
		goto out;
	}
	task_child = pid;
	if (task_signal)
		kill(pid, task_signal);
	int st = 0;
	while (waitpid(pid, &st, 0) < 0 && errno == EINTR)
		;
	task_child = 0;
	double seconds = now_s() - t0;
	close(fd);
	int ok = WIFEXITED(st) && WEXITSTATUS(st) == 0;
	if (!ok && (task_signal || (WIFSIGNALED(st) && (WTERMSIG(st) == SIGINT ||
	                                                WTERMSIG(st) == SIGTERM ||
	                                                WTERMSIG(st) == SIGHUP)))) {
		/* stopped, not failed: the entry stays as it was */
		ret = kg_fail(err, -EINTR, "%s: interrupted: the entry stays as it was", name);
		goto out;
	}
	char *reason = NULL;
	if (!ok) {
		reason = log_reason(log);
		if (!reason) {
			char buf[128];
			if (WIFSIGNALED(st))
				snprintf(buf, sizeof(buf), "kogei process was killed by signal %d (%s)",
				         WTERMSIG(st), strsignal(WTERMSIG(st)));
			else
				snprintf(buf, sizeof(buf), "kogei process ended with exit status %d",
				         WIFEXITED(st) ? WEXITSTATUS(st) : -1);
			reason = strdup(buf);
		}
	}
	char finished[32];
	coll_now(finished);
	char *log_rel = NULL;
	if (asprintf(&log_rel, ".collection/logs/%s.log", name) < 0)
		log_rel = NULL;
	json_t *s = json_pack("{s:s, s:s, s:s, s:o, s:s, s:s, s:s, s:f, s:i, s:s?, s:O}",
	                      "format", COLL_ENTRY_FORMAT, "name", name, "status",
	                      ok ? "done" : "failed", "reason",
	                      reason ? kg_json_message(reason) : json_null(), "job",
	                      job ? job : "local", "started", started, "finished", finished,
	                      "seconds", round(seconds * 1000) / 1000,
	                      "exit", WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st), "log",
	                      log_rel, "key", json_object_get(e, "key"));
	free(reason);
	free(log_rel);
	if (ok)
		coll_thumbs_make(out, name);
	ret = s ? kg_json_write(s, state, err) : kg_fail(err, KG_ENOMEM, "out of memory");
	json_decref(s);
	*done = ok && !ret;
out:
	free(exe);
	free(log);
	free(state);
	free(logdir);
	free(statedir);
	free(argv);
	json_decref(plan);
	return ret;
}

/* ---- thumbnails ------------------------------------------------------------------------ */

#define THUMB_MAX 128 /* the longer side, pixels */

static unsigned char srgb8(float v)
{
	double x = v > 0 ? (v < 1 ? v : 1) : 0;
	x = x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1 / 2.4) - 0.055;
	return (unsigned char)lround(255 * x);
}

static void thumb_one(const char *src, const char *dst)
{
	kg_image *img = NULL;
	if (kg_image_read(src, &img, NULL) || !img->data || img->channels < 1) {
		kg_image_free(&img);
		return;
	}
	kg_inputs_forget(src);
	int w = img->width, h = img->height;
	double f = (double)THUMB_MAX / (w > h ? w : h);
	if (f > 1)
		f = 1;
	int tw = (int)fmax(1, lround(w * f)), th = (int)fmax(1, lround(h * f));
	unsigned char *rgb = malloc((size_t)tw * th * 3);
	if (rgb) {
		/* each thumbnail pixel the mean of the source pixels it covers */
		for (int y = 0; y < th; y++)
			for (int x = 0; x < tw; x++) {
				int x0 = x * w / tw, x1 = (x + 1) * w / tw, y0 = y * h / th, y1 = (y + 1) * h / th;
				double sum[3] = {0, 0, 0};
				int n = 0;
				for (int yy = y0; yy < (y1 > y0 ? y1 : y0 + 1); yy++)
					for (int xx = x0; xx < (x1 > x0 ? x1 : x0 + 1); xx++, n++)
						for (int c = 0; c < 3; c++)
							sum[c] += img->data[((size_t)yy * w + xx) * img->channels +
							                    (img->channels == 3 ? c : 0)];
				for (int c = 0; c < 3; c++)
					rgb[((size_t)y * tw + x) * 3 + c] = srgb8((float)(sum[c] / n));
			}
		kg_png_write_rgb8(dst, rgb, tw, th, NULL);
	}
	free(rgb);
	kg_image_free(&img);
}

void coll_thumbs_make(const char *out, const char *name)
{
	char *dir = coll_thumb_dir(out, name), *outdir = kg_path_join(out, name);
	char *pj_path = outdir ? kg_path_join(outdir, "process.json") : NULL;
	json_t *pj = NULL;
	if (dir && pj_path && kg_mkdir_p(dir, NULL) == 0 && kg_json_load(pj_path, &pj, NULL) == 0) {
		kg_inputs_forget(pj_path);
		size_t i;
		const json_t *obj;
		json_array_foreach(json_object_get(pj, "objects"), i, obj)
		{
			const char *cap = json_string_value(json_object_get(obj, "capture"));
			const char *photo = json_string_value(json_object_get(obj, "photo"));
			if (!cap || !photo || !kg_name_is_safe(cap, COLL_NAME_MAX) ||
			    !kg_relpath_is_safe(photo, 256))
				continue;
			char *src = kg_path_join(outdir, photo), *file = NULL;
			if (src && asprintf(&file, "%s/%s.png", dir, cap) >= 0)
				thumb_one(src, file);
			free(src);
			free(file);
		}
	}
	json_decref(pj);
	free(dir);
	free(outdir);
	free(pj_path);
}

/* ---- the record ------------------------------------------------------------------------ */

/* The held-out colour differences of a processed session (process.json
 * calibration.patches: a verification capture's when there, else leave-one-out), as
 * {basis, n, mean, p90, max}, or null. */
static json_t *heldout_de(const json_t *pj)
{
	const json_t *patches = kg_json_find(pj, "calibration.patches");
	size_t n = json_array_size(patches);
	if (!n)
		return json_null();
	const char *key = "de00_d50_heldout";
	size_t i;
	const json_t *p;
	json_array_foreach(patches, i, p)
		if (json_is_number(json_object_get(p, "de00_d50_verify")))
			key = "de00_d50_verify";
	double *v = malloc(n * sizeof(double));
	if (!v)
		return json_null();
	json_array_foreach(patches, i, p)
	{
		const json_t *x = json_object_get(p, key);
		v[i] = json_is_number(x) ? json_number_value(x) : NAN;
	}
	kg_de_summary s;
	json_t *r = kg_de_summarise(v, (int)n, &s, NULL)
	                ? json_null()
	                : json_pack("{s:s, s:i, s:f, s:f, s:f}", "basis",
	                            strcmp(key, "de00_d50_verify") ? "leave-one-out"
	                                                           : "verification capture",
	                            "n", s.n, "mean", s.mean, "p90", s.p90, "max", s.max);
	free(v);
	return r ? r : json_null();
}

/* The conformance grade of a processed session (its conformance.json): the lowest ISO
 * 19264-1 level and the fewest FADGI stars over the measured characteristics. */
static json_t *grade_of(const char *outdir)
{
	char *path = kg_path_join(outdir, "conformance.json");
	json_t *cj = NULL, *r = NULL;
	if (path && kg_json_load(path, &cj, NULL) == 0) {
		kg_inputs_forget(path);
		int measured = 0, worst = -1, stars = 5, total = 0;
		size_t i;
		const json_t *c;
		json_array_foreach(json_object_get(cj, "characteristics"), i, c)
		{
			total++;
			if (!json_is_true(json_object_get(c, "measured")))
				continue;
			measured++;
			const char *lv = json_string_value(json_object_get(c, "level"));
			int l = lv && strlen(lv) == 1 && lv[0] >= 'A' && lv[0] <= 'C' ? lv[0] - 'A' : 3;
			worst = l > worst ? l : worst;
			int s = (int)json_integer_value(json_object_get(c, "stars"));
			stars = s < stars ? s : stars;
		}
		static const char *const levels[] = {"A", "B", "C", "none"};
		if (measured)
			r = json_pack("{s:s, s:i, s:i, s:i}", "iso19264_1", levels[worst], "fadgi_stars",
			              stars, "measured", measured, "of", total);
	}
	json_decref(cj);
	free(path);
	return r ? r : json_null();
}

/* A done entry's objects from OUT/NAME/process.json. */
static json_t *objects_of(const char *out, const char *name, const json_t *given, json_t **de,
                          json_t **grade)
{
	char *outdir = kg_path_join(out, name);
	char *pj_path = outdir ? kg_path_join(outdir, "process.json") : NULL;
	json_t *pj = NULL, *list = json_array();
	*de = json_null();
	*grade = json_null();
	if (pj_path && kg_json_load(pj_path, &pj, NULL) == 0) {
		kg_inputs_forget(pj_path);
		json_decref(*de);
		json_decref(*grade);
		*de = heldout_de(pj);
		*grade = grade_of(outdir);
		size_t i;
		const json_t *obj;
		json_array_foreach(json_object_get(pj, "objects"), i, obj)
		{
			/* the object's record, the list's meta.KEY columns over it (as kogei
			 * process puts its --meta over the captures' records) */
			json_t *meta = json_object();
			const json_t *own = json_object_get(obj, "meta");
			if (meta && json_is_object(own))
				json_object_update(meta, (json_t *)own);
			if (meta && json_is_object(given))
				json_object_update(meta, (json_t *)given);
			const json_t *acc = json_object_get(meta, "accession");
			const json_t *w = json_object_get(obj, "warnings");
			json_t *o = json_pack("{s:O?, s:O?, s:O?, s:o, s:O, s:O, s:s, s:O?}", "name",
			                      json_object_get(obj, "capture"), "accession",
			                      json_is_string(acc) ? acc : NULL, "title",
			                      json_object_get(meta, "title"), "warnings",
			                      json_is_array(w) ? json_incref((json_t *)w) : json_array(),
			                      "de00_heldout", *de, "grade", *grade, "report",
			                      "report.html", "photo", json_object_get(obj, "photo"));
			/* its IIIF manifest, where one was written (OUTDIR-relative) */
			const json_t *man = json_object_get(json_object_get(obj, "manifest"), "path");
			if (o && json_is_string(man))
				json_object_set(o, "manifest", (json_t *)man);
			if (o && json_object_size(meta))
				json_object_set(o, "meta", meta);
			json_decref(meta);
			if (o)
				json_array_append_new(list, o);
		}
	}
	json_decref(pj);
	free(pj_path);
	free(outdir);
	return list;
}

static json_t *make_record(const char *out, const json_t *plan, kg_collection_counts *c)
{
	char when[32];
	coll_now(when);
	json_t *entries = json_array();
	memset(c, 0, offsetof(kg_collection_counts, array_job));
	size_t i;
	const json_t *e;
	json_array_foreach(json_object_get(plan, "entries"), i, e)
	{
		json_t *state = NULL;
		coll_status s = coll_entry_status(out, e, &state);
		const char *name = json_string_value(json_object_get(e, "name"));
		c->entries++;
		c->done += s == COLL_DONE;
		c->failed += s == COLL_FAILED;
		c->pending += s == COLL_PENDING;
		json_t *de = json_null(), *grade = json_null();
		json_t *objects = s == COLL_DONE && name ? objects_of(out, name, json_object_get(e, "meta"), &de, &grade) : json_array();
		json_t *time = state ? json_pack("{s:O?, s:O?, s:O?}", "started",
		                                 json_object_get(state, "started"), "finished",
		                                 json_object_get(state, "finished"), "seconds",
		                                 json_object_get(state, "seconds"))
		                     : json_null();
		json_t *entry = json_pack(
			"{s:O, s:O, s:{s:O, s:O}, s:O, s:s, s:O?, s:O?, s:o, s:s, s:O?, s:o, s:o, s:o}",
			"name", json_object_get(e, "name"), "line", json_object_get(e, "line"), "session",
			"given", json_object_get(e, "session"), "path", json_object_get(e, "session_path"),
			"meta", json_object_get(e, "meta"), "status",
			s == COLL_DONE ? "done" : s == COLL_FAILED ? "failed" : "pending", "reason",
			state ? json_object_get(state, "reason") : NULL, "job",
			state ? json_object_get(state, "job") : NULL, "time", time ? time : json_null(),
			"output", name ? name : "", "log", state ? json_object_get(state, "log") : NULL,
			"de00_heldout", de, "grade", grade, "objects", objects);
		if (entry)
			json_array_append_new(entries, entry);
		json_decref(state);
	}
	return json_pack("{s:s, s:s, s:O?, s:O?, s:O?, s:{s:i, s:i, s:i, s:i}, s:o}", "format",
	                 COLL_FORMAT, "written", when, "engine", json_object_get(plan, "engine"),
	                 "list", json_object_get(plan, "list"), "list_path",
	                 json_object_get(plan, "list_path"), "counts", "entries", c->entries, "done",
	                 c->done, "failed", c->failed, "pending", c->pending, "entries", entries);
}

int kg_collection_finish(const char *out, kg_collection_counts *c, kg_err *err)
{
	kg_check_arg(out && c, err);
	json_t *plan = NULL;
	int ret = coll_plan_load(out, &plan, err);
	if (ret)
		return ret;
	json_t *record = make_record(out, plan, c);
	char *path = kg_path_join(out, "collection.json");
	if (!record || !path)
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	if (!ret)
		ret = kg_json_write(record, path, err);
	if (!ret)
		ret = coll_html_write(out, record, err);
	if (!ret)
		ret = coll_iiif_write(out, plan, record, err);
	free(path);
	json_decref(record);
	json_decref(plan);
	return ret;
}

void kg_collection_print_failures(const char *out, FILE *fp)
{
	json_t *plan = NULL;
	if (coll_plan_load(out, &plan, NULL))
		return;
	size_t i;
	const json_t *e;
	json_array_foreach(json_object_get(plan, "entries"), i, e)
	{
		json_t *state = NULL;
		if (coll_entry_status(out, e, &state) == COLL_FAILED) {
			char shown[4200];
			const char *r = json_string_value(json_object_get(state, "reason"));
			fprintf(fp, "kogei collection: %s (%s line %lld): failed: %s\n",
			        json_string_value(json_object_get(e, "name")),
			        json_string_value(json_object_get(plan, "list")),
			        (long long)json_integer_value(json_object_get(e, "line")),
			        kg_text_visible(r ? r : "no reason recorded", SIZE_MAX, shown,
			                        sizeof(shown)));
		}
		json_decref(state);
	}
	json_decref(plan);
}

int kg_collection_status(const char *out, FILE *fp, kg_collection_counts *c, kg_err *err)
{
	kg_check_arg(out && fp && c, err);
	memset(c, 0, sizeof(*c));
	json_t *plan = NULL;
	int ret = coll_plan_load(out, &plan, err);
	if (ret)
		return ret;
	coll_count(out, plan, c);
	fprintf(fp, "%s: %d entries: %d done, %d failed, %d pending (engine %s, list %s)\n", out,
	        c->entries, c->done, c->failed, c->pending,
	        json_string_value(json_object_get(plan, "engine")),
	        json_string_value(json_object_get(plan, "list")));
	char job[64];
	int tasks = 0, a = coll_slurm_active(out, job, &tasks);
	if (a == 1)
		fprintf(fp, "%s: Slurm job %s: %d job(s) or task(s) queued or running\n", out, job,
		        tasks);
	else if (a < 0)
		fprintf(fp, "%s: Slurm job %s: squeue did not answer\n", out, job);
	json_decref(plan);
	fflush(fp);
	kg_collection_print_failures(out, fp);
	return 0;
}
