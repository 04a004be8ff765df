/* kogei process, OUTDIR: what a run may write where, and each run as a transaction
 * (kg_pipeline.h, docs/formats.md "Processed session").
 *
 * Before anything is written: OUTDIR is not the session nor inside it; it is new,
 * empty, or an earlier output of this session (its process.json names the session's
 * id, or for a session recorded before ids, its manifest's "created", wherever the
 * session now lies); a file or folder at an object's name that the
 * earlier process.json does not list is never replaced; no input (--mask, --reference,
 * --spectra, --mesh, --layout, --materials, the session) lies inside what the run
 * would replace. A folder this run created for OUTDIR is removed when the run fails.
 *
 * The run under the OUTDIR lock: leftovers of dead runs are cleared first (recover);
 * every new object folder, camera.json, reference.json, chart_overlay.png, then
 * process.json and report.html are staged in OUTDIR/.kogei-run.PID; when all are
 * complete the staging folder is renamed .kogei-commit.PID (the journal: from here
 * the run is completed, by this process or by the next run's recover), each object
 * folder is swapped in (a displaced one to .kogei-old.PID), then the files with
 * process.json and report.html last, and the journal is removed. A run that fails or
 * is interrupted before the rename leaves OUTDIR as it was.
 *
 * Signals (kg_process_watch_signals, the command line only): SIGINT, SIGTERM and
 * SIGHUP are taken by one thread, which says what OUTDIR holds, removes the staging
 * folder (and OUTDIR when this run created it) and ends the process by the signal;
 * during the swap it waits for the swap to end. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "pipeline_private.h"
#include "report_private.h"

#define STAGE_TAG ".kogei-run."
#define COMMIT_TAG ".kogei-commit."
#define OLD_TAG ".kogei-old."
#define TRASH_TAG ".kogei-trash."

/* The files of OUTDIR itself, in the order a commit puts them in place. */
static const char *const top_files[] = {"camera.json", "reference.json", "chart_overlay.png",
                                        "conformance.json", "camera.icc", "camera.ti3",
                                        "process.json", "report.html"};
enum { NTOP = sizeof(top_files) / sizeof(top_files[0]) };

static int is_top_file(const char *name)
{
	for (int i = 0; i < NTOP; i++)
		if (!strcmp(name, top_files[i]))
			return 1;
	return 0;
}

/* ---- the signal watcher's view of the run ----------------------------------------- */

enum { PHASE_NONE, PHASE_OPEN, PHASE_DONE };

static struct {
	pthread_mutex_t lock; /* held by the run while it changes OUTDIR's visible state */
	int enabled;
	int phase;
	char *outdir, *stage;
	char **created; /* folders this run created for OUTDIR, parents first */
	int ncreated;
	char kept[1024]; /* what OUTDIR keeps if the run stops now */
} watch = {.lock = PTHREAD_MUTEX_INITIALIZER};

static int remove_entry(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
	(void)st;
	(void)flag;
	(void)ftw;
	return remove(path);
}

void proc_remove_tree(const char *path)
{
	nftw(path, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
}

/* The staging folder out of the way of writers still running (their next file in it
 * fails), then removed. */
static void discard_stage(const char *outdir, const char *stage)
{
	char trash[4200];
	snprintf(trash, sizeof(trash), "%s/" TRASH_TAG "%ld", outdir, (long)getpid());
	proc_remove_tree(trash);
	if (rename(stage, trash) == 0)
		proc_remove_tree(trash);
	else
		proc_remove_tree(stage);
}

static void remove_created(char **created, int n)
{
	for (int i = n - 1; i >= 0; i--)
		rmdir(created[i]);
}

static void *watcher(void *arg)
{
	const sigset_t *set = arg;
	int sig = 0;
	while (sigwait(set, &sig) != 0)
		;
	const char *name = sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "SIGHUP";
	pthread_mutex_lock(&watch.lock); /* a swap under way ends first */
	if (watch.phase == PHASE_OPEN) {
		if (watch.stage)
			discard_stage(watch.outdir, watch.stage);
		remove_created(watch.created, watch.ncreated);
		fprintf(stderr, "kogei process: interrupted by %s: %s\n", name, watch.kept);
	} else if (watch.phase == PHASE_DONE) {
		fprintf(stderr, "kogei process: interrupted by %s after the run was complete: %s "
		        "holds its results\n", name, watch.outdir);
	} else {
		fprintf(stderr, "kogei process: interrupted by %s; nothing was written\n", name);
	}
	fflush(stderr);
	/* end by the signal itself, as without the watcher */
	signal(sig, SIG_DFL);
	sigset_t one;
	sigemptyset(&one);
	sigaddset(&one, sig);
	pthread_sigmask(SIG_UNBLOCK, &one, NULL);
	raise(sig);
	_exit(128 + sig);
}

int kg_process_watch_signals(void)
{
	static sigset_t set;
	static const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
	sigemptyset(&set);
	for (size_t i = 0; i < sizeof(sigs) / sizeof(sigs[0]); i++) {
		struct sigaction old;
		/* an ignored signal (nohup, a background job) stays ignored */
		if (sigaction(sigs[i], NULL, &old) == 0 && !(old.sa_flags & SA_SIGINFO) &&
		    old.sa_handler == SIG_IGN)
			continue;
		sigaddset(&set, sigs[i]);
	}
	if (pthread_sigmask(SIG_BLOCK, &set, NULL) != 0)
		return -1;
	pthread_t t;
	if (pthread_create(&t, NULL, watcher, &set) != 0) {
		pthread_sigmask(SIG_UNBLOCK, &set, NULL);
		return -1;
	}
	pthread_detach(t);
	pthread_mutex_lock(&watch.lock);
	watch.enabled = 1;
	pthread_mutex_unlock(&watch.lock);
	return 0;
}

static void watch_set(proc *p, int phase)
{
	if (!watch.enabled) /* set once, before any run */
		return;
	pthread_mutex_lock(&watch.lock);
	watch.phase = phase;
	watch.outdir = (char *)p->o->outdir;
	watch.stage = p->stage;
	watch.created = p->created;
	watch.ncreated = p->ncreated;
	pthread_mutex_unlock(&watch.lock);
}

/* ---- paths -------------------------------------------------------------------------- */

/* path made absolute with every symbolic link resolved, also when its last
 * components do not exist yet (those are taken as written, "." and ".." lexically). */
char *proc_abs_path(const char *path)
{
	char *r = realpath(path, NULL);
	if (r)
		return r;
	size_t n = strlen(path);
	const char *tail = path;
	char *base = NULL;
	for (size_t i = n; i-- > 0;) {
		if (path[i] != '/')
			continue;
		char *head = i ? strndup(path, i) : strdup("/");
		if (!head)
			return NULL;
		base = realpath(head, NULL);
		free(head);
		if (base) {
			tail = path + i + 1;
			break;
		}
	}
	if (!base && !(base = realpath(".", NULL)))
		return NULL;
	size_t cap = strlen(base) + strlen(tail) + 2;
	char *out = malloc(cap);
	if (!out) {
		free(base);
		return NULL;
	}
	strcpy(out, base);
	free(base);
	for (const char *s = tail; *s;) {
		size_t len = strcspn(s, "/");
		if ((len == 1 && s[0] == '.') || len == 0) {
		} else if (len == 2 && s[0] == '.' && s[1] == '.') {
			char *slash = strrchr(out, '/');
			if (slash && slash != out)
				*slash = '\0';
			else
				strcpy(out, "/");
		} else {
			size_t l = strlen(out);
			if (l > 1)
				out[l++] = '/';
			memcpy(out + l, s, len);
			out[l + len] = '\0';
		}
		s += len;
		while (*s == '/')
			s++;
	}
	return out;
}

/* a is dir or inside it (both absolute). */
int proc_is_under(const char *a, const char *dir)
{
	size_t n = strlen(dir);
	if (n == 1 && dir[0] == '/')
		return 1;
	return !strncmp(a, dir, n) && (a[n] == '\0' || a[n] == '/');
}

/* The pid of a name "<tag><pid>", or 0. */
static long tag_pid(const char *name, const char *tag)
{
	size_t n = strlen(tag);
	if (strncmp(name, tag, n) || !name[n])
		return 0;
	char *end;
	long pid = strtol(name + n, &end, 10);
	return *end == '\0' && pid > 0 ? pid : 0;
}

/* An old kogei's per-object temporaries: ".<name>.partial-<pid>" (kind 1) and
 * ".<name>.old-<pid>" (kind 2); the object's name into obj. 0: neither. */
static int old_style(const char *entry, char *obj, size_t size)
{
	static const char *const kinds[2] = {".partial-", ".old-"};
	if (entry[0] != '.')
		return 0;
	for (int k = 0; k < 2; k++) {
		const char *at = NULL;
		for (const char *s = strstr(entry + 1, kinds[k]); s; s = strstr(s + 1, kinds[k]))
			at = s;
		if (!at || at == entry + 1)
			continue;
		const char *d = at + strlen(kinds[k]);
		if (!*d || strspn(d, "0123456789") != strlen(d))
			continue;
		snprintf(obj, size, "%.*s", (int)(at - entry - 1), entry + 1);
		return k + 1;
	}
	return 0;
}

/* ---- the swap ------------------------------------------------------------------------ */

/* Put the journal's contents in place in outdir: each object folder (the one there
 * before moved to old), then the files, process.json and report.html last; then the
 * journal and old removed. Also completes a swap that stopped half-way. */
static int apply_commit(const char *outdir, const char *journal, const char *old, kg_err *err)
{
	DIR *d = opendir(journal);
	if (!d)
		return kg_fail(err, KG_EIO, "%s: cannot open: %s", journal, strerror(errno));
	int ret = 0;
	char from[4200], to[4200], aside[4200];
	for (struct dirent *e; !ret && (e = readdir(d));) {
		if (e->d_name[0] == '.' || is_top_file(e->d_name))
			continue;
		snprintf(from, sizeof(from), "%s/%s", journal, e->d_name);
		snprintf(to, sizeof(to), "%s/%s", outdir, e->d_name);
		struct stat st;
		if (lstat(to, &st) == 0) {
			snprintf(aside, sizeof(aside), "%s/%s", old, e->d_name);
			if (mkdir(old, 0777) != 0 && errno != EEXIST)
				ret = kg_fail(err, KG_EIO, "%s: cannot create: %s", old, strerror(errno));
			proc_remove_tree(aside);
			if (!ret && rename(to, aside) != 0)
				ret = kg_fail(err, KG_EIO, "%s: cannot move the earlier results aside: %s",
				              to, strerror(errno));
		}
		if (!ret && rename(from, to) != 0)
			ret = kg_fail(err, KG_EIO, "%s: cannot move %s into place: %s", to, from,
			              strerror(errno));
	}
	closedir(d);
	for (int i = 0; i < NTOP && !ret; i++) {
		snprintf(from, sizeof(from), "%s/%s", journal, top_files[i]);
		snprintf(to, sizeof(to), "%s/%s", outdir, top_files[i]);
		if (access(from, F_OK) == 0 && rename(from, to) != 0)
			ret = kg_fail(err, KG_EIO, "%s: cannot move %s into place: %s", to, from,
			              strerror(errno));
	}
	if (ret)
		return ret;
	int fd = open(outdir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (fd >= 0) {
		fsync(fd);
		close(fd);
	}
	proc_remove_tree(journal);
	proc_remove_tree(old);
	return 0;
}

/* A progress line "<who>: ..." to progress (NULL: none). */
static void say(FILE *progress, const char *who, const char *fmt, ...) KG_PRINTF(3, 4);
static void say(FILE *progress, const char *who, const char *fmt, ...)
{
	if (!progress)
		return;
	va_list ap;
	va_start(ap, fmt);
	fprintf(progress, "%s: ", who);
	vfprintf(progress, fmt, ap);
	fputc('\n', progress);
	fflush(progress);
	va_end(ap);
}

/* Leftovers of runs that died (SIGKILL, a crash, power): under the lock no other run
 * is live, so every staging, trash and old folder goes, and a journal is completed.
 * Progress lines go to progress as "<who>: ...". */
static int recover_dir(const char *out, FILE *progress, const char *who, kg_err *err)
{
	DIR *d = opendir(out);
	if (!d)
		return kg_fail(err, KG_EIO, "%s: cannot open: %s", out, strerror(errno));
	char **names = NULL;
	size_t n = 0, cap = 0;
	for (struct dirent *e; (e = readdir(d));) {
		if (e->d_name[0] != '.' || !strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
			continue;
		if (n == cap) {
			cap = cap ? 2 * cap : 8;
			char **g = realloc(names, cap * sizeof(*names));
			if (!g)
				break;
			names = g;
		}
		if (!(names[n] = strdup(e->d_name)))
			break;
		n++;
	}
	closedir(d);
	int ret = 0;
	char path[4200], old[4200], obj[256], final[4200];
	/* journals first: a completed swap leaves nothing for the rest */
	for (size_t i = 0; i < n && !ret; i++) {
		long pid = tag_pid(names[i], COMMIT_TAG);
		if (!pid)
			continue;
		snprintf(path, sizeof(path), "%s/%s", out, names[i]);
		snprintf(old, sizeof(old), "%s/" OLD_TAG "%ld", out, pid);
		ret = apply_commit(out, path, old, err);
		if (ret)
			kg_err_prefix(err, "completing the results of an interrupted run (process "
			              "%ld): ", pid);
		else
			say(progress, who, "completed the results of a run that was stopped while it "
			              "put them in place (process %ld)", pid);
	}
	for (size_t i = 0; i < n && !ret; i++) {
		snprintf(path, sizeof(path), "%s/%s", out, names[i]);
		int kind = old_style(names[i], obj, sizeof(obj));
		if (tag_pid(names[i], STAGE_TAG) || tag_pid(names[i], TRASH_TAG) ||
		    tag_pid(names[i], OLD_TAG) || kind == 1) {
			proc_remove_tree(path);
			say(progress, who, "removed %s, left by an interrupted run", path);
		} else if (kind == 2) {
			/* an old kogei moved the earlier folder aside and stopped before its new
			 * one was in place: the earlier one back (process.json describes it) */
			snprintf(final, sizeof(final), "%s/%s", out, obj);
			if (access(final, F_OK) != 0 && kg_name_is_safe(obj, 256) &&
			    rename(path, final) == 0) {
				say(progress, who, "restored %s from %s, left by an interrupted run", final,
				              path);
			} else {
				proc_remove_tree(path);
				say(progress, who, "removed %s, left by an interrupted run", path);
			}
		}
	}
	for (size_t i = 0; i < n; i++)
		free(names[i]);
	free(names);
	kg_atomicfile_sweep(out);
	return ret;
}

static int recover(proc *p)
{
	return recover_dir(p->o->outdir, p->o->progress, "kogei process", p->err);
}

/* ---- before anything is written ---------------------------------------------------- */

static int is_object_name(const proc *p, const char *name)
{
	for (int i = 0; i < p->ncaps; i++)
		if (p->caps[i].kind == KG_CAPTURE_OBJECT && !strcmp(p->caps[i].name, name))
			return 1;
	return 0;
}

/* Inputs inside what the run would replace: an object's folder, or a file of
 * OUTDIR's own. */
static int check_inputs(proc *p, const char *outabs)
{
	const kg_process_options *o = p->o;
	const struct {
		const char *what, *path;
	} in[] = {{"the session", o->session}, {"--reference", o->reference},
	          {"--spectra", o->spectra},   {"--mask", o->mask},
	          {"--mesh", o->mesh},         {"--layout", o->layout},
	          {"--materials", o->materials}};
	char place[4200];
	for (size_t k = 0; k < sizeof(in) / sizeof(in[0]); k++) {
		if (!in[k].path)
			continue;
		char *r = realpath(in[k].path, NULL);
		if (!r)
			continue; /* a bundled name, or missing: the step that reads it says so */
		int ret = 0;
		for (int i = 0; i < p->ncaps && !ret; i++) {
			if (p->caps[i].kind != KG_CAPTURE_OBJECT)
				continue;
			snprintf(place, sizeof(place), "%s/%s", outabs, p->caps[i].name);
			if (proc_is_under(r, place))
				ret = kg_fail(p->err, KG_EINVAL, "%s %s: is inside %s/%s, the folder this run "
				              "writes for capture %s (replacing what is there): move it out "
				              "of %s or choose another -o", in[k].what, in[k].path,
				              o->outdir, p->caps[i].name, p->caps[i].name, o->outdir);
		}
		for (int i = 0; i < NTOP && !ret; i++) {
			if (!strcmp(top_files[i], "reference.json") && o->reference)
				continue; /* written by lab sessions only */
			snprintf(place, sizeof(place), "%s/%s", outabs, top_files[i]);
			if (!strcmp(r, place))
				ret = kg_fail(p->err, KG_EINVAL, "%s %s: is %s/%s, which this run writes: "
				              "copy it elsewhere or choose another -o", in[k].what,
				              in[k].path, o->outdir, top_files[i]);
		}
		free(r);
		if (ret)
			return ret;
	}
	return 0;
}

/* OUTDIR and its missing parents created; each noted for removal on failure. */
static int make_outdir(proc *p)
{
	char *path = strdup(p->o->outdir);
	if (!path)
		return kg_fail(p->err, KG_ENOMEM, "out of memory");
	size_t n = strlen(path);
	int ret = 0;
	for (size_t i = 1; i <= n && !ret; i++) {
		if (path[i] != '/' && path[i] != '\0')
			continue;
		char c = path[i];
		path[i] = '\0';
		if (mkdir(path, 0777) == 0) {
			char **g = realloc(p->created, (size_t)(p->ncreated + 1) * sizeof(*g));
			if (g) {
				p->created = g;
				if ((g[p->ncreated] = strdup(path)))
					p->ncreated++;
			}
		} else if (errno != EEXIST) {
			ret = kg_fail_write(p->err, errno, path, "cannot create");
		}
		path[i] = c;
	}
	free(path);
	struct stat st;
	if (!ret && (stat(p->o->outdir, &st) != 0 || !S_ISDIR(st.st_mode)))
		ret = kg_fail(p->err, KG_EINVAL, "%s: exists and is not a directory", p->o->outdir);
	return ret;
}

const json_t *proc_previous_object(const proc *p, const char *name)
{
	const json_t *e;
	size_t i;
	json_array_foreach(json_object_get(p->previous, "objects"), i, e)
	{
		const char *dir = json_string_value(json_object_get(e, "dir"));
		if (!dir)
			dir = json_string_value(json_object_get(e, "capture"));
		if (dir && !strcmp(dir, name))
			return e;
	}
	return NULL;
}

static void describe_kept_locked(proc *p);

/* What an interrupted run leaves: the previous results, or nothing. */
static void describe_kept(proc *p)
{
	if (!watch.enabled)
		return;
	pthread_mutex_lock(&watch.lock);
	describe_kept_locked(p);
	pthread_mutex_unlock(&watch.lock);
}

static void describe_kept_locked(proc *p)
{
	char *k = watch.kept;
	size_t size = sizeof(watch.kept), at = 0;
	if (!p->previous) {
		snprintf(k, size, p->ncreated ? "nothing was written (%s, which this run created, "
		         "removed)" : "nothing was written; %s is as it was", p->o->outdir);
		return;
	}
	const json_t *e;
	size_t i, n = json_array_size(json_object_get(p->previous, "objects"));
	at += (size_t)snprintf(k, size, "%s keeps the results of its previous run (%s", p->o->outdir,
	                       json_string_value(json_object_get(p->previous, "created"))
	                           ? json_string_value(json_object_get(p->previous, "created"))
	                           : "process.json");
	json_array_foreach(json_object_get(p->previous, "objects"), i, e)
	{
		const char *c = json_string_value(json_object_get(e, "capture"));
		if (at >= size - 64)
			break;
		if (i == 6) {
			at += (size_t)snprintf(k + at, size - at, " and %zu more", n - 6);
			break;
		}
		at += (size_t)snprintf(k + at, size - at, "%s %s", i ? "," : ":", c ? c : "?");
	}
	if (at < size)
		snprintf(k + at, size - at, "); nothing of this run was kept");
}

/* The earlier run's process.json: this session's, or the folder is refused. */
static int check_previous(proc *p, const char *pj)
{
	kg_err e = {{0}};
	json_t *prev = NULL;
	if (kg_json_load(pj, &prev, &e) == 0) {
		kg_inputs_forget(pj); /* our own record: replaced at the end */
		const char *f = json_string_value(json_object_get(prev, "format"));
		if (f && !strcmp(f, KG_PROCESS_FORMAT))
			p->previous = prev;
		else
			json_decref(prev);
	}
	if (!p->previous)
		return kg_fail(p->err, KG_EINVAL, "%s: exists but is not a %s file: refusing to write "
		               "into %s", pj, KG_PROCESS_FORMAT, p->o->outdir);
	/* The session is its id (session.json "id"), wherever it lies: a session moved or
	 * copied to another disk is the same session. Results of a session recorded before
	 * ids are matched by the time it was recorded. */
	const json_t *s = json_object_get(p->previous, "session");
	const char *path = json_string_value(json_object_get(s, "path"));
	const char *real = json_string_value(json_object_get(s, "realpath"));
	const char *id = json_string_value(json_object_get(s, "id"));
	const char *my_id = json_string_value(json_object_get(p->manifest, "id"));
	const char *created = json_string_value(json_object_get(s, "created"));
	const char *mine = json_string_value(json_object_get(p->manifest, "created"));
	int same_created = !created || !mine || !strcmp(created, mine);
	int same = id && my_id ? !strcmp(id, my_id) : same_created;
	if (same || p->o->accept_rerecorded)
		return 0;
	char differs[1024];
	size_t at = 0;
	if (id && my_id)
		at += (size_t)snprintf(differs + at, sizeof(differs) - at, "session id %s there, %s "
		                       "here", id, my_id);
	if (!same_created && at < sizeof(differs))
		at += (size_t)snprintf(differs + at, sizeof(differs) - at, "%srecorded %s there, %s "
		                       "here", at ? "; " : "", created, mine);
	if (!at)
		snprintf(differs, sizeof(differs), "recorded at the same time, but one has an id "
		         "and the other not");
	return kg_fail(p->err, KG_EINVAL, "%s: holds the results of another session (%s, now "
	               "processing %s: %s): one folder holds one session's results; choose "
	               "another -o",
	               p->o->outdir, real ? real : path ? path : "?", p->o->session, differs);
}

/* What is in OUTDIR: nothing, or this session's earlier output; nothing at an
 * object's or a file's name that this tool did not write. */
static int check_contents(proc *p)
{
	const char *out = p->o->outdir;
	DIR *d = opendir(out);
	if (!d)
		return kg_fail(p->err, KG_EIO, "%s: cannot open: %s", out, strerror(errno));
	char seen[512] = "";
	size_t at = 0;
	int n = 0;
	for (struct dirent *e; (e = readdir(d));) {
		if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
			continue;
		if (n < 4 && at < sizeof(seen))
			at += (size_t)snprintf(seen + at, sizeof(seen) - at, "%s%s", n ? ", " : "",
			                       e->d_name);
		n++;
	}
	closedir(d);
	if (n == 0)
		return 0;
	char path[4200];
	struct stat st;
	snprintf(path, sizeof(path), "%s/process.json", out);
	if (lstat(path, &st) != 0)
		return kg_fail(p->err, KG_EINVAL, "%s: is not empty (%s%s) and holds no process.json, "
		               "so it is not an earlier output of kogei process: choose a new or "
		               "empty folder", out, seen, n > 4 ? ", ..." : "");
	int ret = check_previous(p, path);
	for (int i = 0; i < p->ncaps && !ret; i++) {
		const proc_capture *c = &p->caps[i];
		if (c->kind != KG_CAPTURE_OBJECT)
			continue;
		snprintf(path, sizeof(path), "%s/%s", out, c->name);
		if (lstat(path, &st) != 0)
			continue;
		if (!proc_previous_object(p, c->name))
			ret = kg_fail(p->err, KG_EINVAL, "%s: exists, and %s/process.json does not list "
			              "it as written by kogei process: capture %s's results would "
			              "replace it; move it or choose another -o", path, out, c->name);
		else if (!S_ISDIR(st.st_mode))
			ret = kg_fail(p->err, KG_EINVAL, "%s: is not a folder, so kogei process did not "
			              "write it: capture %s's results would replace it; move it or "
			              "choose another -o", path, c->name);
	}
	for (int i = 0; i < NTOP && !ret; i++) {
		snprintf(path, sizeof(path), "%s/%s", out, top_files[i]);
		if (lstat(path, &st) == 0 && !S_ISREG(st.st_mode))
			ret = kg_fail(p->err, KG_EINVAL, "%s: is not a file (a folder or a link), so "
			              "kogei process did not write it: move it or choose another -o",
			              path);
	}
	return ret;
}

int proc_outdir_open(proc *p)
{
	const kg_process_options *o = p->o;
	struct stat st;
	if (stat(o->outdir, &st) == 0 && !S_ISDIR(st.st_mode))
		return kg_fail(p->err, KG_EINVAL, "%s: exists and is not a directory", o->outdir);
	p->session_abs = realpath(o->session, NULL);
	char *outabs = proc_abs_path(o->outdir);
	int ret = p->session_abs && outabs ? 0 : kg_fail(p->err, KG_EIO, "%s: cannot resolve: %s",
	                                                 p->session_abs ? o->outdir : o->session,
	                                                 strerror(errno));
	if (!ret && !strcmp(outabs, p->session_abs))
		ret = kg_fail(p->err, KG_EINVAL, "%s: is the session directory: choose another -o",
		              o->outdir);
	else if (!ret && proc_is_under(outabs, p->session_abs))
		ret = kg_fail(p->err, KG_EINVAL, "%s: is inside the session directory %s: the results "
		              "would replace the session's own files; choose another -o", o->outdir,
		              o->session);
	if (!ret)
		ret = check_inputs(p, outabs);
	free(outabs);
	if (!ret)
		ret = make_outdir(p);
	if (!ret) {
		describe_kept(p);
		watch_set(p, PHASE_OPEN);
		p->lock_fd = open(o->outdir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
		if (p->lock_fd < 0)
			ret = kg_fail(p->err, KG_EIO, "%s: cannot open: %s", o->outdir, strerror(errno));
		else if (flock(p->lock_fd, LOCK_EX | LOCK_NB) != 0)
			ret = kg_fail(p->err, errno == EWOULDBLOCK ? KG_EINVAL : KG_EIO,
			              "%s: in use by another kogei process (the folder is locked); wait "
			              "for it to finish or choose another -o", o->outdir);
	}
	if (!ret) {
		pthread_mutex_lock(&watch.lock); /* a signal waits for the repairs */
		ret = recover(p);
		pthread_mutex_unlock(&watch.lock);
	}
	if (!ret)
		ret = check_contents(p);
	if (!ret) {
		describe_kept(p);
		char stage[4200];
		snprintf(stage, sizeof(stage), "%s/" STAGE_TAG "%ld", o->outdir, (long)getpid());
		if (mkdir(stage, 0777) != 0)
			ret = kg_fail_write(p->err, errno, stage, "cannot create");
		else if (!(p->stage = strdup(stage)))
			ret = kg_fail(p->err, KG_ENOMEM, "out of memory");
		watch_set(p, PHASE_OPEN);
	}
	return ret;
}

/* ---- the end of the run --------------------------------------------------------------- */

/* The tree under path, 8 levels at most: file() on each regular file, dir() on each
 * folder after its entries (either may be NULL); the first failure ends the walk. */
static int walk_tree(const char *path, int depth, int (*file)(const char *, kg_err *),
                     int (*dir)(const char *, kg_err *), kg_err *err)
{
	DIR *d = opendir(path);
	if (!d)
		return dir ? dir(path, err) : 0;
	int ret = 0;
	char sub[4200];
	for (struct dirent *e; !ret && (e = readdir(d));) {
		if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
			continue;
		snprintf(sub, sizeof(sub), "%s/%s", path, e->d_name);
		struct stat st;
		if (lstat(sub, &st) != 0)
			continue;
		if (S_ISDIR(st.st_mode) && depth < 8)
			ret = walk_tree(sub, depth + 1, file, dir, err);
		else if (S_ISREG(st.st_mode) && file)
			ret = file(sub, err);
	}
	closedir(d);
	return !ret && dir ? dir(path, err) : ret;
}

/* A folder flushed to disk. */
static int sync_folder(const char *path, kg_err *err)
{
	int fd = open(path, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (fd < 0)
		return kg_fail(err, KG_EIO, "%s: cannot open: %s", path, strerror(errno));
	int ret = fsync(fd) != 0 && errno != EINVAL ? kg_fail_write(err, errno, path,
	                                                            "cannot flush to disk")
	                                            : 0;
	close(fd);
	return ret;
}

/* Every file under path (a folder about to be displaced) checked against the inputs
 * of the run. */
static int check_tree(const char *path, kg_err *err)
{
	return walk_tree(path, 0, kg_inputs_check_output, NULL, err);
}

/* Every folder of the staging tree flushed to disk (its files already are, by their
 * writers), so a crash after the renames cannot leave entries that point nowhere. */
static int sync_tree(const char *path, kg_err *err)
{
	return walk_tree(path, 0, NULL, sync_folder, err);
}

/* The files under path are this tool's outputs, some read back while they were made
 * (labels.json, the report's images): not inputs of a later job in this process (the
 * console), whose swap would otherwise refuse to replace them. */
static void forget_tree(const char *path, int depth)
{
	DIR *d = opendir(path);
	if (!d) {
		kg_inputs_forget(path);
		return;
	}
	char sub[4200];
	for (struct dirent *e; (e = readdir(d));) {
		if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
			continue;
		snprintf(sub, sizeof(sub), "%s/%s", path, e->d_name);
		if (depth < 8)
			forget_tree(sub, depth + 1);
	}
	closedir(d);
}

int proc_outdir_commit(proc *p, json_t *root)
{
	const char *out = p->o->outdir;
	char from[4200], to[4200];
	snprintf(from, sizeof(from), "%s/process.json", p->stage);
	int ret = kg_json_write(root, from, p->err);
	if (!ret)
		ret = report_write_staged(out, p->stage, p->err);
	/* nothing read by this run is replaced */
	DIR *d = ret ? NULL : opendir(p->stage);
	if (!ret && !d)
		ret = kg_fail(p->err, KG_EIO, "%s: cannot open: %s", p->stage, strerror(errno));
	for (struct dirent *e; d && !ret && (e = readdir(d));) {
		if (e->d_name[0] == '.')
			continue;
		snprintf(to, sizeof(to), "%s/%s", out, e->d_name);
		if (is_top_file(e->d_name))
			ret = kg_inputs_check_output(to, p->err);
		else if (is_object_name(p, e->d_name))
			ret = check_tree(to, p->err);
		if (ret)
			kg_err_prefix(p->err, "nothing replaced: ");
	}
	if (d)
		closedir(d);
	if (!ret)
		ret = sync_tree(p->stage, p->err);
	if (ret)
		return ret;
	char journal[4200], old[4200];
	snprintf(journal, sizeof(journal), "%s/" COMMIT_TAG "%ld", out, (long)getpid());
	snprintf(old, sizeof(old), "%s/" OLD_TAG "%ld", out, (long)getpid());
	pthread_mutex_lock(&watch.lock);
	if (rename(p->stage, journal) != 0) {
		ret = kg_fail(p->err, KG_EIO, "%s: cannot rename to %s: %s", p->stage, journal,
		              strerror(errno));
	} else {
		free(p->stage);
		p->stage = NULL;
		ret = apply_commit(out, journal, old, p->err);
		if (ret)
			kg_err_prefix(p->err, "%s: the results are complete in %s, but: ", out, journal);
		else
			p->committed = 1;
	}
	pthread_mutex_unlock(&watch.lock);
	if (ret)
		return ret;
	watch_set(p, PHASE_DONE);
	for (int i = 0; i < NTOP; i++) {
		snprintf(to, sizeof(to), "%s/%s", out, top_files[i]);
		kg_inputs_forget(to);
	}
	for (int i = 0; i < p->ncaps; i++)
		if (p->caps[i].kind == KG_CAPTURE_OBJECT) {
			snprintf(to, sizeof(to), "%s/%s", out, p->caps[i].name);
			forget_tree(to, 0);
		}
	return 0;
}

void proc_outdir_close(proc *p, int failed)
{
	pthread_mutex_lock(&watch.lock);
	if (p->stage)
		discard_stage(p->o->outdir, p->stage);
	if (failed && !p->committed)
		remove_created(p->created, p->ncreated);
	watch.phase = p->committed ? PHASE_DONE : PHASE_NONE;
	watch.stage = NULL;
	watch.created = NULL;
	watch.ncreated = 0;
	pthread_mutex_unlock(&watch.lock);
	free(p->stage);
	p->stage = NULL;
	for (int i = 0; i < p->ncreated; i++)
		free(p->created[i]);
	free(p->created);
	p->created = NULL;
	p->ncreated = 0;
	free(p->session_abs);
	p->session_abs = NULL;
	if (p->lock_fd >= 0)
		close(p->lock_fd);
	p->lock_fd = -1;
}

/* ---- readers: OUTDIR settled before it is read ------------------------------------- */

/* 1 when outdir holds a journal: a run is putting its results in place, or died
 * doing so. */
static int in_commit(const char *outdir)
{
	DIR *d = opendir(outdir);
	if (!d)
		return 0;
	int found = 0;
	for (struct dirent *e; !found && (e = readdir(d));)
		found = tag_pid(e->d_name, COMMIT_TAG) != 0;
	closedir(d);
	return found;
}

int kg_outdir_in_commit(const char *outdir)
{
	return outdir && in_commit(outdir);
}

int kg_outdir_settle(const char *outdir, const char *who, FILE *progress, int wait_ms,
                     int *lock_fd, kg_err *err)
{
	kg_check_arg(outdir && who, err);
	if (lock_fd)
		*lock_fd = -1;
	else if (!in_commit(outdir))
		return 0; /* whole, and a reader holds no lock: a run may start at any time */
	int fd = open(outdir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (fd < 0)
		return kg_fail(err, errno == ENOENT ? KG_ENOENT : KG_EIO, "%s: cannot open: %s",
		               outdir, strerror(errno));
	for (int waited = 0;; waited += 10) {
		if (flock(fd, LOCK_EX | LOCK_NB) == 0) {
			/* no run is live: complete or clear what a dead one left */
			int ret = recover_dir(outdir, progress, who, err);
			if (ret || !lock_fd)
				close(fd);
			else
				*lock_fd = fd;
			return ret;
		}
		if (errno != EWOULDBLOCK) {
			int e = errno;
			close(fd);
			return kg_fail(err, KG_EIO, "%s: cannot lock: %s", outdir, strerror(e));
		}
		/* a live run: its staging is invisible until it puts the results in place,
		 * which takes a moment; a reader that needs no lock goes on when it is done */
		if (!lock_fd && !in_commit(outdir)) {
			close(fd);
			return 0;
		}
		if (waited >= wait_ms) {
			close(fd);
			return kg_fail(err, KG_EBUSY,
			               "%s: in use by another kogei process, %s (the folder is "
			               "locked); wait for it to finish",
			               outdir, lock_fd ? "which is writing its results"
			                               : "which is putting its results in place");
		}
		struct timespec ts = {0, 10 * 1000 * 1000};
		nanosleep(&ts, NULL);
	}
}

void kg_outdir_unlock(int *lock_fd)
{
	if (lock_fd && *lock_fd >= 0) {
		close(*lock_fd);
		*lock_fd = -1;
	}
}
