/* kogei deposit: a BagIt 1.0 bag (RFC 8493) of one processed OUTDIR (kg_pipeline.h,
 * docs/deposit.md). Its options (one table for the command line and the console) and
 * the operator's bag-info.txt values are in deposit_info.c; the BagIt primitives and
 * the check of a bag in bagit.c.
 *
 * The order of a deposit: the options and the config checked; RESULTS settled and
 * locked, its process.json read (the accessions, the session's id and folder); BAG
 * checked (new, or a bag and force; not inside RESULTS or the session, nor they inside
 * it); the staging folder BAG's parent/.BASE.kogei-tmp.PID made, every payload file
 * linked or copied into it with its sha512, the tag files written, every folder
 * flushed; then one rename (an exchange when an old bag is replaced). */
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "kg_config.h"
#include "pipeline_private.h"

#define ALG "sha512"
#define HEX_MAX 129           /* a sha512 in hex, and its NUL */
#define COPY_BLOCK (1u << 20) /* bytes read (and checked for a signal) at a time */
#define STAGE_TAG ".kogei-tmp."
#define OLD_TAG ".kogei-old."

/* ---- signals ------------------------------------------------------------------------------ */

static volatile sig_atomic_t stop_signal;

static void on_signal(int sig) { stop_signal = sig; }

void kg_deposit_catch_signals(void)
{
	static const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
	for (size_t i = 0; i < sizeof(sigs) / sizeof(sigs[0]); i++) {
		struct sigaction old, sa;
		/* an ignored signal (nohup, a background job) stays ignored */
		if (sigaction(sigs[i], NULL, &old) != 0 || (!(old.sa_flags & SA_SIGINFO) &&
		                                            old.sa_handler == SIG_IGN))
			continue;
		memset(&sa, 0, sizeof(sa));
		sa.sa_handler = on_signal;
		sigemptyset(&sa.sa_mask);
		sigaction(sigs[i], &sa, NULL);
	}
}

int kg_deposit_signal(void) { return stop_signal; }

/* ---- the run's state ------------------------------------------------------------------- */

typedef struct bag_file {
	char *src;                /* where it is read from */
	char *rel;                /* its path in the bag: data/... */
} bag_file;

typedef struct dep {
	const kg_deposit_options *o;
	kg_err *err;
	deposit_info info;        /* the operator's bag-info.txt values */
	json_t *pj;               /* RESULTS/process.json */
	char *pj_path;
	json_t *ids;              /* External-Identifier values */
	const char *session_id;   /* process.json session.id, or NULL */
	char *session_dir;        /* with_session: the session, resolved */
	char *results_abs;
	char *bag_abs, *parent, *base;
	int bag_exists;           /* a bag to replace (force) */
	char *stage;              /* BAG's parent/.BASE.kogei-tmp.PID, while it exists */
	bag_file *files;
	int nfiles, fcap;
	char **dirs;              /* the staging tree's folders, parents first */
	int ndirs, dcap;
	FILE *manifest;           /* manifest-sha512.txt as it is made */
	char *manifest_text;
	size_t manifest_len;
	unsigned char *buf;
	int lock_fd;
} dep;

static int oom(dep *d) { return kg_fail(d->err, KG_ENOMEM, "out of memory"); }

static int interrupted(dep *d)
{
	int sig = stop_signal;
	return kg_fail(d->err, -EINTR, "interrupted by %s: nothing written at %s",
	               sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "SIGHUP", d->o->bag);
}

/* ---- RESULTS and the session ----------------------------------------------------------- */

/* A text value of process.json that goes into bag-info.txt, checked (NULL: absent). */
static int record_value(dep *d, const json_t *v, const char *key, const char **out)
{
	*out = NULL;
	if (!v)
		return 0;
	const char *s = json_string_value(v);
	const char *why = s ? deposit_value_problem(s) : "expected a string";
	if (why)
		return kg_fail(d->err, KG_EINVAL, "%s: %s: %s (it goes into bag-info.txt, one line)",
		               d->pj_path, key, why);
	*out = s;
	return 0;
}

static int add_identifier(dep *d, const json_t *meta, const char *key)
{
	const char *acc;
	int ret = record_value(d, json_object_get(meta, "accession"), key, &acc);
	size_t i;
	const json_t *v;
	json_array_foreach(d->ids, i, v)
		if (acc && !strcmp(json_string_value(v), acc))
			return ret;
	if (!ret && acc && json_array_append_new(d->ids, json_string(acc)))
		ret = oom(d);
	return ret;
}

/* RESULTS/process.json: a kogei-process/1 record; its accessions and session id. */
static int read_results(dep *d)
{
	d->pj_path = kg_path_join(d->o->results, "process.json");
	d->ids = json_array();
	if (!d->pj_path || !d->ids)
		return oom(d);
	struct stat st;
	if (stat(d->pj_path, &st) != 0)
		return kg_fail(d->err, KG_EINVAL, "%s: not the output of kogei process (no "
		               "process.json): nothing to deposit", d->o->results);
	int ret = kg_json_load(d->pj_path, &d->pj, d->err);
	kg_inputs_forget(d->pj_path); /* read to describe the bag, which cannot replace it */
	const char *format = ret ? NULL : json_string_value(json_object_get(d->pj, "format"));
	if (!ret && (!format || strcmp(format, KG_PROCESS_FORMAT)))
		return kg_fail(d->err, KG_EINVAL, "%s: format: expected \"%s\": not the output of kogei "
		               "process", d->pj_path, KG_PROCESS_FORMAT);
	size_t i;
	const json_t *obj;
	json_array_foreach(json_object_get(d->pj, "objects"), i, obj)
	{
		char key[64];
		snprintf(key, sizeof(key), "objects[%zu].meta.accession", i);
		if (!ret)
			ret = add_identifier(d, json_object_get(obj, "meta"), key);
	}
	if (!ret)
		ret = add_identifier(d, json_object_get(d->pj, "meta"), "meta.accession");
	if (!ret)
		ret = record_value(d, kg_json_find(d->pj, "session.id"), "session.id", &d->session_id);
	if (!ret && !(d->results_abs = realpath(d->o->results, NULL)))
		ret = kg_fail(d->err, KG_EIO, "%s: cannot resolve: %s", d->o->results, strerror(errno));
	return ret;
}

/* The session at dir is the one RESULTS was made from: the same id (or, for sessions
 * recorded before ids, the same recording time). */
static int same_session(dep *d, const char *dir)
{
	char *path = kg_path_join(dir, KG_SESSION_MANIFEST);
	json_t *m = NULL;
	int ret = path ? kg_json_load(path, &m, d->err) : oom(d);
	if (path)
		kg_inputs_forget(path);
	const char *id = json_string_value(json_object_get(m, "id"));
	const char *created = json_string_value(json_object_get(m, "created"));
	const char *want_created = json_string_value(kg_json_find(d->pj, "session.created"));
	if (!ret && id && d->session_id && strcmp(id, d->session_id))
		ret = kg_fail(d->err, KG_EINVAL, "%s: session id %s, but %s was made from session %s: "
		              "not its session", dir, id, d->pj_path, d->session_id);
	else if (!ret && (!id || !d->session_id) && created && want_created &&
	         strcmp(created, want_created))
		ret = kg_fail(d->err, KG_EINVAL, "%s: recorded %s, but %s was made from a session "
		              "recorded %s: not its session", dir, created, d->pj_path, want_created);
	json_decref(m);
	free(path);
	return ret;
}

static int holds_session(const char *dir)
{
	char *m = dir ? kg_path_join(dir, KG_SESSION_MANIFEST) : NULL;
	struct stat st;
	int yes = m && stat(m, &st) == 0;
	free(m);
	return yes;
}

/* with_session: --session; else where process.json records the session (its realpath,
 * then its path as given); else a folder of the session's name beside RESULTS that is
 * the same session (a working folder moved or copied whole). */
static int find_session(dep *d)
{
	const char *real = json_string_value(kg_json_find(d->pj, "session.realpath"));
	const char *path = json_string_value(kg_json_find(d->pj, "session.path"));
	const char *name = real ? strrchr(real, '/') : NULL;
	char *parent = kg_path_dir(d->results_abs);
	char *beside = parent && name && name[1] ? kg_path_join(parent, name + 1) : NULL;
	const char *cand[3] = {real, path, beside};
	const char *dir = d->o->session;
	for (int k = 0; !dir && k < 3; k++)
		if (holds_session(cand[k]) && (k < 2 || !same_session(d, cand[k])))
			dir = cand[k];
	int ret = dir ? same_session(d, dir)
	              : kg_fail(d->err, KG_EINVAL, "%s: records its session at %s, which holds no "
	                        "%s now, nor does a folder of its name beside the results (moved?): "
	                        "give the session's folder with --session DIR", d->pj_path,
	                        real ? real : path ? path : "(no session.path)",
	                        KG_SESSION_MANIFEST);
	if (!ret && !(d->session_dir = realpath(dir, NULL)))
		ret = kg_fail(d->err, KG_EIO, "%s: cannot resolve: %s", dir, strerror(errno));
	free(parent);
	free(beside);
	return ret;
}

/* ---- BAG --------------------------------------------------------------------------------- */

/* a and b (absolute) apart: neither inside the other. */
static int apart(dep *d, const char *a, const char *what)
{
	if (proc_is_under(d->bag_abs, a))
		return kg_fail(d->err, KG_EINVAL, "%s: inside %s (%s): choose a bag outside it",
		               d->o->bag, what, a);
	if (proc_is_under(a, d->bag_abs))
		return kg_fail(d->err, KG_EINVAL, "%s: %s (%s) lies inside it: choose another -o",
		               d->o->bag, what, a);
	return 0;
}

static int check_target(dep *d)
{
	const char *bag = d->o->bag;
	struct stat st;
	if (lstat(bag, &st) == 0) {
		char *bagit = kg_path_join(bag, "bagit.txt");
		struct stat bs;
		int is_bag = S_ISDIR(st.st_mode) && bagit && lstat(bagit, &bs) == 0 &&
		             S_ISREG(bs.st_mode);
		free(bagit);
		if (!is_bag)
			return kg_fail(d->err, KG_EINVAL, "%s: exists and is not a bag (no bagit.txt): "
			               "refusing to replace it; choose another -o", bag);
		if (!d->o->force)
			return kg_fail(d->err, KG_EINVAL, "%s: a bag exists there; --force replaces it",
			               bag);
		d->bag_exists = 1;
	} else if (errno != ENOENT) {
		return kg_fail(d->err, KG_EIO, "%s: cannot stat: %s", bag, strerror(errno));
	}
	d->bag_abs = proc_abs_path(bag);
	if (!d->bag_abs)
		return kg_fail(d->err, KG_EINVAL, "%s: cannot resolve its folder: %s", bag,
		               strerror(errno));
	const char *slash = strrchr(d->bag_abs, '/');
	if (!slash || !slash[1] || !strcmp(slash, "/.."))
		return kg_fail(d->err, KG_EINVAL, "%s: expected the path of a new folder", bag);
	d->parent = slash == d->bag_abs ? strdup("/") : strndup(d->bag_abs,
	                                                         (size_t)(slash - d->bag_abs));
	d->base = strdup(slash + 1);
	if (!d->parent || !d->base)
		return oom(d);
	if (stat(d->parent, &st) != 0 || !S_ISDIR(st.st_mode))
		return kg_fail(d->err, KG_EINVAL, "%s: its folder %s does not exist", bag, d->parent);
	int ret = apart(d, d->results_abs, "RESULTS");
	if (!ret && d->session_dir)
		ret = apart(d, d->session_dir, "the session");
	return ret;
}

/* ".BASE<tag><pid>" in BAG's parent: the pid, or 0 when name is not of that form. */
static long tagged_pid(const dep *d, const char *name, const char *tag)
{
	size_t b = strlen(d->base), t = strlen(tag);
	if (name[0] != '.' || strncmp(name + 1, d->base, b) || strncmp(name + 1 + b, tag, t))
		return 0;
	char *end;
	long pid = strtol(name + 1 + b + t, &end, 10);
	return pid > 0 && !*end ? pid : 0;
}

/* What a deposit to the same BAG left when it was killed (SIGKILL, a crash, a power
 * cut), or an earlier failed deposit of this process left: removed. */
static int sweep_visit(void *user, const char *path, const char *rel, const struct stat *st)
{
	const dep *d = user;
	const char *name = strrchr(rel, '/') ? strrchr(rel, '/') + 1 : rel;
	long pid = tagged_pid(d, name, STAGE_TAG);
	if (!pid)
		pid = tagged_pid(d, name, OLD_TAG);
	if (pid && S_ISDIR(st->st_mode) &&
	    (pid == (long)getpid() || (kill((pid_t)pid, 0) != 0 && errno == ESRCH))) {
		proc_remove_tree(path);
		if (d->o->progress)
			fprintf(d->o->progress, "kogei deposit: removed %s, left by a deposit that was "
			        "stopped (process %ld)\n", path, pid);
	}
	return 1;
}

/* ---- staging ------------------------------------------------------------------------------ */

/* path (taken) as a folder of the staging tree, to be flushed at the end. */
static int remember_dir(dep *d, char *path)
{
	if (d->ndirs == d->dcap) {
		int cap = d->dcap ? 2 * d->dcap : 32;
		char **p = path ? realloc(d->dirs, (size_t)cap * sizeof(*p)) : NULL;
		if (!p) {
			free(path);
			return oom(d);
		}
		d->dirs = p;
		d->dcap = cap;
	}
	if (!path)
		return oom(d);
	d->dirs[d->ndirs++] = path;
	return 0;
}

static int add_dir(dep *d, const char *rel)
{
	int ret = remember_dir(d, kg_path_join(d->stage, rel));
	if (!ret && mkdir(d->dirs[d->ndirs - 1], 0755) != 0)
		ret = kg_fail_write(d->err, errno, d->dirs[d->ndirs - 1], "cannot create");
	return ret;
}

static int add_file(dep *d, const char *path, const char *rel)
{
	if (d->nfiles == d->fcap) {
		int cap = d->fcap ? 2 * d->fcap : 64;
		bag_file *p = realloc(d->files, (size_t)cap * sizeof(*p));
		if (!p)
			return oom(d);
		d->files = p;
		d->fcap = cap;
	}
	bag_file *f = &d->files[d->nfiles];
	f->src = strdup(path);
	f->rel = strdup(rel);
	if (!f->src || !f->rel) {
		free(f->src);
		free(f->rel);
		return oom(d);
	}
	d->nfiles++;
	return 0;
}

static int utf8_ok(const char *s)
{
	size_t n = strlen(s);
	for (size_t i = 0; i < n;) {
		unsigned cp;
		int len = kg_utf8_decode((const unsigned char *)s + i, n - i, &cp, NULL);
		if (!len)
			return 0;
		i += (size_t)len;
	}
	return 1;
}

/* kogei's transient entries, never part of a record: a run's staging folder, journal
 * and leftovers (.kogei-run.PID, .kogei-commit.PID, ...) and a writer's temporary
 * (.NAME.kogei-tmp.PID...). */
static int is_transient(const char *name)
{
	return name[0] == '.' && (!strncmp(name, ".kogei-", 7) || strstr(name, STAGE_TAG));
}

/* An entry of RESULTS or the session: a folder made in the staging tree, a file
 * listed; anything else refused. */
static int payload_visit(void *user, const char *path, const char *rel, const struct stat *st)
{
	dep *d = user;
	const char *name = strrchr(rel, '/') + 1;
	if (stop_signal)
		return interrupted(d);
	if (is_transient(name))
		return 1;
	if (!utf8_ok(name))
		return kg_fail(d->err, KG_EINVAL, "%s: its name is not UTF-8, which a bag's manifest "
		               "is: rename it", path);
	if (S_ISDIR(st->st_mode))
		return add_dir(d, rel);
	if (S_ISREG(st->st_mode))
		return add_file(d, path, rel);
	return kg_fail(d->err, KG_EINVAL, "%s: %s: a bag holds files and folders only; replace it "
	               "by what it stands for, or remove it", path,
	               S_ISLNK(st->st_mode) ? "a symbolic link" : "not a regular file");
}

/* Every file of dir under rel in the staging tree (rel made first). */
static int gather(dep *d, const char *dir, const char *rel)
{
	int ret = add_dir(d, rel);
	return ret ? ret : bag_walk(dir, rel, payload_visit, d, d->err);
}

static void say_file(dep *d, int i, unsigned long long size, const char *how)
{
	if (d->o->progress)
		fprintf(d->o->progress, "kogei deposit: [%d/%d] %s (%.1f MB, %s)\n", i + 1, d->nfiles,
		        d->files[i].rel, size / 1e6, how);
}

/* File i into the staging tree (a hard link, else a copy) with its checksum. */
static int place_file(dep *d, int i, kg_deposit_summary *sum)
{
	bag_file *f = &d->files[i];
	char *dst = kg_path_join(d->stage, f->rel);
	if (!dst)
		return oom(d);
	int linked = !d->o->copy && link(f->src, dst) == 0;
	bag_copy c = {.alg = ALG, .src = f->src, .dst = linked ? NULL : dst, .buf = d->buf,
	              .bufsize = COPY_BLOCK, .stop = &stop_signal};
	char hex[HEX_MAX];
	unsigned long long size;
	int ret = bag_digest_file(&c, hex, &size, d->err);
	free(dst);
	if (ret == -EINTR)
		return interrupted(d);
	if (ret)
		return ret;
	fprintf(d->manifest, "%s  ", hex);
	bag_put_path(d->manifest, f->rel);
	fputc('\n', d->manifest);
	sum->files++;
	sum->bytes += size;
	*(linked ? &sum->linked : &sum->copied) += 1;
	say_file(d, i, size, linked ? "linked" : "copied");
	return 0;
}

/* A tag file in the staging folder, and its line in the tag manifest (when given). */
static int write_tag(dep *d, const char *name, const char *text, size_t len, FILE *tagmanifest)
{
	char *path = kg_path_join(d->stage, name);
	if (!path)
		return oom(d);
	int fd = open(path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
	int ret = fd < 0 || kg_write_all(fd, text, len) || fsync(fd) != 0
	              ? kg_fail_write(d->err, errno, path, "write failed")
	              : 0;
	if (fd >= 0 && close(fd) != 0 && !ret)
		ret = kg_fail_write(d->err, errno, path, "write failed");
	free(path);
	char hex[HEX_MAX];
	if (!ret && tagmanifest) {
		if (bag_digest_text(ALG, text, len, hex))
			return kg_fail(d->err, KG_ENOMEM, "cannot compute a %s", ALG);
		fprintf(tagmanifest, "%s  %s\n", hex, name);
	}
	return ret;
}

/* bag-info.txt (RFC 8493, 2.2.2): each value on one line. */
static void bag_info(dep *d, FILE *f, const kg_deposit_summary *sum)
{
	deposit_info_print(&d->info, f);
	size_t i;
	const json_t *v;
	json_array_foreach(d->ids, i, v)
		fprintf(f, "External-Identifier: %s\n", json_string_value(v));
	if (d->session_id)
		fprintf(f, "Internal-Sender-Identifier: %s\n", d->session_id);
	size_t objects = json_array_size(json_object_get(d->pj, "objects"));
	fprintf(f, "Internal-Sender-Description: kogei process results (%s) of %zu object(s) in "
	        "%s\n", KG_PROCESS_FORMAT, objects,
	        d->session_dir ? "data/results/, the session they were made from in data/session/"
	                       : "data/");
	char date[16];
	time_t now = time(NULL);
	struct tm tm;
	strftime(date, sizeof(date), "%Y-%m-%d", localtime_r(&now, &tm));
	fprintf(f, "Bagging-Date: %s\n", date);
	fprintf(f, "Payload-Oxum: %llu.%d\n", sum->bytes, sum->files);
	fprintf(f, "Bag-Software-Agent: kogei %s\n", KG_VERSION);
}

/* The three tag files and the tag manifest over them. */
static int write_tags(dep *d, const kg_deposit_summary *sum)
{
	static const char bagit[] = "BagIt-Version: 1.0\nTag-File-Character-Encoding: UTF-8\n";
	char *info = NULL, *tags = NULL;
	size_t info_len = 0, tags_len = 0;
	FILE *fi = open_memstream(&info, &info_len);
	FILE *ft = open_memstream(&tags, &tags_len);
	int ret = fi && ft && fclose(d->manifest) == 0 ? 0 : oom(d);
	d->manifest = NULL;
	if (!ret) {
		bag_info(d, fi, sum);
		ret = fflush(fi) ? oom(d) : 0;
	}
	if (!ret)
		ret = write_tag(d, "bagit.txt", bagit, sizeof(bagit) - 1, ft);
	if (!ret)
		ret = write_tag(d, "bag-info.txt", info, info_len, ft);
	if (!ret)
		ret = write_tag(d, "manifest-" ALG ".txt", d->manifest_text, d->manifest_len, ft);
	if (ft && fflush(ft) && !ret)
		ret = oom(d);
	if (!ret)
		ret = write_tag(d, "tagmanifest-" ALG ".txt", tags, tags_len, NULL);
	if (fi)
		fclose(fi);
	if (ft)
		fclose(ft);
	free(info);
	free(tags);
	return ret;
}

/* Every folder of the staging tree flushed to disk, deepest first. */
static int sync_dirs(dep *d)
{
	for (int i = d->ndirs - 1; i >= 0; i--) {
		int fd = open(d->dirs[i], O_RDONLY | O_DIRECTORY | O_CLOEXEC);
		if (fd < 0 || (fsync(fd) != 0 && errno != EINVAL)) {
			int e = errno;
			if (fd >= 0)
				close(fd);
			return kg_fail_write(d->err, e, d->dirs[i], "cannot flush to disk");
		}
		close(fd);
	}
	return 0;
}

static int stage_bag(dep *d, kg_deposit_summary *sum)
{
	char name[4200];
	snprintf(name, sizeof(name), "%s/.%s" STAGE_TAG "%ld", d->parent, d->base, (long)getpid());
	int ret = bag_walk(d->parent, "", sweep_visit, d, d->err);
	if (!ret && mkdir(name, 0755) != 0)
		ret = kg_fail_write(d->err, errno, name, "cannot create");
	if (!ret && !(d->stage = strdup(name))) {
		rmdir(name);
		ret = oom(d);
	}
	if (!ret)
		ret = remember_dir(d, strdup(d->stage));
	if (!ret)
		ret = add_dir(d, "data");
	if (!ret && d->session_dir) {
		ret = gather(d, d->o->results, "data/results");
		if (!ret)
			ret = gather(d, d->session_dir, "data/session");
	} else if (!ret) {
		ret = bag_walk(d->o->results, "data", payload_visit, d, d->err);
	}
	if (!ret && !(d->buf = malloc(COPY_BLOCK)))
		ret = oom(d);
	if (!ret && !(d->manifest = open_memstream(&d->manifest_text, &d->manifest_len)))
		ret = oom(d);
	for (int i = 0; !ret && i < d->nfiles; i++)
		ret = place_file(d, i, sum);
	if (!ret)
		ret = write_tags(d, sum);
	if (!ret)
		ret = sync_dirs(d);
	if (!ret && stop_signal)
		ret = interrupted(d);
	return ret;
}

static void sync_parent(const dep *d)
{
	int fd = open(d->parent, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (fd >= 0) {
		fsync(fd);
		close(fd);
	}
}

/* The staging folder renamed to BAG: in one exchange with the bag it replaces (then
 * removed), or where the file system cannot exchange, the old bag moved aside first. */
static int replace_bag(dep *d)
{
	if (renameat2(AT_FDCWD, d->stage, AT_FDCWD, d->bag_abs, RENAME_EXCHANGE) == 0)
		return 0; /* the old bag is at d->stage now, removed with it */
	if (errno != EINVAL && errno != ENOSYS)
		return kg_fail(d->err, KG_EIO, "%s: cannot put the new bag in place: %s", d->o->bag,
		               strerror(errno));
	char old[4200];
	snprintf(old, sizeof(old), "%s/.%s" OLD_TAG "%ld", d->parent, d->base, (long)getpid());
	if (rename(d->bag_abs, old) != 0)
		return kg_fail(d->err, KG_EIO, "%s: cannot move the old bag aside: %s", d->o->bag,
		               strerror(errno));
	if (rename(d->stage, d->bag_abs) != 0) {
		int e = errno;
		rename(old, d->bag_abs);
		return kg_fail(d->err, KG_EIO, "%s: cannot put the new bag in place: %s", d->o->bag,
		               strerror(e));
	}
	free(d->stage);
	d->stage = strdup(old); /* removed at the end, as a stage would be */
	return 0;
}

static int no_entry(const char *path)
{
	struct stat st;
	return lstat(path, &st) != 0 && errno == ENOENT;
}

static int put_in_place(dep *d)
{
	int ret = 0;
	if (d->bag_exists) {
		ret = replace_bag(d);
	} else if (renameat2(AT_FDCWD, d->stage, AT_FDCWD, d->bag_abs, RENAME_NOREPLACE) == 0 ||
	           (errno == EINVAL && no_entry(d->bag_abs) && rename(d->stage, d->bag_abs) == 0)) {
		free(d->stage); /* (the fallback where the file system has no RENAME_NOREPLACE) */
		d->stage = NULL;
	} else {
		ret = kg_fail(d->err, errno == EEXIST ? KG_EINVAL : KG_EIO,
		              "%s: cannot put the bag in place: %s", d->o->bag,
		              errno == EEXIST ? "it appeared while the bag was made; nothing replaced"
		                              : strerror(errno));
	}
	sync_parent(d);
	return ret;
}

static void dep_clear(dep *d)
{
	if (d->stage)
		proc_remove_tree(d->stage);
	free(d->stage);
	for (int i = 0; i < d->nfiles; i++) {
		free(d->files[i].src);
		free(d->files[i].rel);
	}
	free(d->files);
	for (int i = 0; i < d->ndirs; i++)
		free(d->dirs[i]);
	free(d->dirs);
	if (d->manifest)
		fclose(d->manifest);
	free(d->manifest_text);
	free(d->buf);
	deposit_info_clear(&d->info);
	json_decref(d->pj);
	json_decref(d->ids);
	free(d->pj_path);
	free(d->session_dir);
	free(d->results_abs);
	free(d->bag_abs);
	free(d->parent);
	free(d->base);
	kg_outdir_unlock(&d->lock_fd);
}

int kg_deposit_run(const kg_deposit_options *o, kg_deposit_summary *sum, kg_err *err)
{
	kg_check_arg(o && sum, err);
	memset(sum, 0, sizeof(*sum));
	int ret = kg_deposit_check(o, err);
	if (ret)
		return ret;
	if (o->verify)
		return kg_fail(err, KG_EINVAL, "--verify: kg_bag_verify checks a bag");
	dep d = {.o = o, .err = err, .lock_fd = -1};
	ret = deposit_info_load(&d.info, o, err);
	if (!ret)
		ret = kg_outdir_settle(o->results, "kogei deposit", o->progress, 2000, &d.lock_fd, err);
	if (!ret)
		ret = read_results(&d);
	if (!ret && (o->with_session || o->session))
		ret = find_session(&d);
	if (!ret)
		ret = check_target(&d);
	if (!ret)
		ret = stage_bag(&d, sum);
	if (!ret)
		ret = put_in_place(&d);
	sum->identifiers = (int)json_array_size(d.ids);
	dep_clear(&d);
	return ret;
}
