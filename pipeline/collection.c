/* kogei collection run: the list read and checked into a plan, what to run chosen, the
 * engine started (collection_local.c, collection_slurm.c) and the record written
 * (collection_record.c). Its options are one table for every front end. */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "collection_private.h"

/* ---- the options ----------------------------------------------------------------------- */

#define OPT(field) offsetof(kg_collection_options, field)

static const kg_opt_spec collection_specs[] = {
	{"output", 'o', "OUT", KG_OPT_STRING, OPT(out), KG_OPT_CLI_ONLY,
	 "the collection's folder: OUT/<name>/ per entry (what kogei process writes), "
	 "OUT/collection.json, OUT/index.html; made when missing"},
	{"engine", 0, "local|slurm", KG_OPT_STRING, OPT(engine), 0,
	 "local (the default): worker processes on this machine; slurm: one job array on a "
	 "Slurm cluster through sbatch and squeue, plus a dependent job that writes "
	 "the record"},
	{"jobs", 'j', "N", KG_OPT_STRING, OPT(jobs), 0,
	 "local: N worker processes (default: the cores this process may use); slurm: at most "
	 "N tasks of the array at once (%N, default: no limit)"},
	{"partition", 0, "P", KG_OPT_STRING, OPT(partition), 0,
	 "slurm: the partition to submit to (sbatch --partition)"},
	{"sbatch-args", 0, "\"...\"", KG_OPT_STRING, OPT(sbatch_args), KG_OPT_CLI_ONLY,
	 "slurm: more sbatch options for both jobs, split at blanks (e.g. \"--time=30 "
	 "--mem=4G --account=lab\")"},
	{"no-wait", 0, NULL, KG_OPT_FLAG, OPT(no_wait), 0,
	 "slurm: submit and return (kogei collection status OUT then reads the state)"},
	{"iiif-base", 0, "URL", KG_OPT_STRING, OPT(iiif_base), 0,
	 "the IIIF Image API base under which an image server serves OUT: each session is "
	 "processed with --iiif-base URL/<name> (kogei process --help, docs/iiif.md)"},
	{"iiif-image-api", 0, "3|2", KG_OPT_STRING, OPT(iiif_image_api), 0,
	 "that image server's IIIF Image API version (kogei process --iiif-image-api)"},
	{"files-base", 0, "URL", KG_OPT_STRING, OPT(files_base), 0,
	 "the URL at which OUT's files are published: each session's --files-base "
	 "URL/<name>, and the ids of OUT/collection-manifest.json (default: relative)"},
	{"progress", 0, NULL, KG_OPT_FLAG, OPT(show_progress), KG_OPT_CLI_ONLY,
	 "the progress line (done, failed, remaining, time left) also when standard error is "
	 "not a terminal, one line per change"},
};

const kg_opt_table kg_collection_table = {
	.synopsis = "kogei collection run LIST.csv -o OUT [--engine local|slurm] [--jobs N]\n"
	            "                             [--partition P] [--sbatch-args \"...\"] "
	            "[--no-wait]\n"
	            "                             [--iiif-base URL] [--iiif-image-api 3|2] "
	            "[--files-base URL]\n"
	            "       kogei collection status OUT",
	.description =
		"Every session of a collection. LIST.csv has a header row; columns: session (the\n"
		"session folder) and spectra or reference (the chart's spectra, or a reference\n"
		"calibration), paths relative to the CSV's folder; optional name (the entry's\n"
		"folder in OUT, default the session folder's name), cube and materials (kogei\n"
		"process --cube, --materials) and meta.KEY (--meta KEY=VALUE for every object of\n"
		"the session). Bad rows are refused before anything runs, each named by line and\n"
		"column. Each session is run by kogei process into OUT/<name>/; a failure of one\n"
		"does not stop the others. Running the same command again runs only the entries\n"
		"that failed, are pending, or changed (the session, its inputs or its options).\n"
		"Writes OUT/collection.json, OUT/index.html and OUT/collection-manifest.json (a\n"
		"IIIF Collection of every object's manifest.json). Exit status 0 when every entry is\n"
		"done, 1 when any failed (each named on standard error), 2 for bad usage or a bad\n"
		"list, 3 when the engine fails (sbatch refused, Slurm unreachable).",
	.positional = "LIST.csv",
	.positional_offset = OPT(list),
	.specs = collection_specs,
	.nspecs = (int)(sizeof(collection_specs) / sizeof(collection_specs[0])),
};

void kg_collection_options_default(kg_collection_options *o)
{
	memset(o, 0, sizeof(*o));
}

int kg_collection_check(kg_collection_options *o, kg_err *err)
{
	kg_check_arg(o, err);
	if (!o->list)
		return kg_fail(err, KG_EINVAL, "expected LIST.csv");
	if (!o->out)
		return kg_fail(err, KG_EINVAL, "-o OUT is required");
	if (!o->engine)
		o->engine = "local";
	int slurm = !strcmp(o->engine, "slurm");
	if (!slurm && strcmp(o->engine, "local"))
		return kg_fail(err, KG_EINVAL, "--engine '%.64s': expected local or slurm", o->engine);
	if (!slurm && (o->partition || o->sbatch_args || o->no_wait))
		return kg_fail(err, KG_EINVAL, "%s: only with --engine slurm",
		               o->partition ? "--partition" : o->sbatch_args ? "--sbatch-args"
		                                                             : "--no-wait");
	o->njobs = slurm ? 0 : kg_cpu_count(256);
	if (o->jobs) {
		char *end;
		errno = 0;
		long n = strtol(o->jobs, &end, 10);
		if (errno || end == o->jobs || *end || n < 1 || n > 10000)
			return kg_fail(err, KG_EINVAL, "--jobs '%.64s': expected a whole number from 1 "
			               "to 10000", o->jobs);
		o->njobs = (int)n;
	}
	const char *vals[] = {o->out, o->partition, o->sbatch_args};
	const char *names[] = {"-o", "--partition", "--sbatch-args"};
	for (int i = 0; i < 3; i++) {
		kg_err e = {{0}};
		if (vals[i] && kg_text_check_controls(names[i], vals[i], &e))
			return kg_fail(err, KG_EINVAL, "%s", e.msg);
	}
	/* the IIIF options: kogei process's check (its names are the same) */
	kg_process_options po;
	kg_process_options_default(&po);
	po.iiif_base = o->iiif_base;
	po.iiif_image_api = o->iiif_image_api;
	po.files_base = o->files_base;
	if (kg_process_access_check(&po, err))
		return KG_EINVAL;
	if (o->partition && (!*o->partition || strpbrk(o->partition, " '\"\\")))
		return kg_fail(err, KG_EINVAL, "--partition '%.64s': expected a partition name",
		               o->partition);
	return 0;
}

/* ---- shared helpers -------------------------------------------------------------------- */

char *coll_path(const char *out, const char *rel)
{
	char *p = NULL;
	if (asprintf(&p, "%s/.collection%s%s", out, rel ? "/" : "", rel ? rel : "") < 0)
		return NULL;
	return p;
}

static char *coll_sub(const char *out, const char *dir, const char *name, const char *ext)
{
	char *p = NULL;
	if (asprintf(&p, "%s/.collection/%s/%s%s", out, dir, name, ext) < 0)
		return NULL;
	return p;
}

char *coll_state_path(const char *out, const char *name)
{
	return coll_sub(out, "entries", name, ".json");
}

char *coll_log_path(const char *out, const char *name)
{
	return coll_sub(out, "logs", name, ".log");
}

char *coll_thumb_dir(const char *out, const char *name)
{
	return coll_sub(out, "thumbs", name, "");
}

void coll_now(char buf[32])
{
	time_t t = time(NULL);
	struct tm tm;
	gmtime_r(&t, &tm);
	strftime(buf, 32, "%Y-%m-%dT%H:%M:%SZ", &tm);
}

json_t *coll_text(const char *what, const char *s, kg_err *err)
{
	return kg_json_text(what, s, err);
}

char *coll_self(const char *self)
{
	return realpath(self ? self : "/proc/self/exe", NULL);
}

static volatile sig_atomic_t caught_signal;

static void on_signal(int sig) { caught_signal = sig; }

void coll_catch_signals(void)
{
	static const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
	for (size_t i = 0; i < sizeof(sigs) / sizeof(sigs[0]); i++) {
		struct sigaction old, sa;
		if (sigaction(sigs[i], NULL, &old) != 0 ||
		    (!(old.sa_flags & SA_SIGINFO) && old.sa_handler == SIG_IGN))
			continue;
		memset(&sa, 0, sizeof(sa));
		sa.sa_handler = on_signal;
		sigemptyset(&sa.sa_mask);
		sigaction(sigs[i], &sa, NULL); /* no SA_RESTART: a wait returns EINTR */
	}
}

int coll_signal(void) { return caught_signal; }

void coll_progress(FILE *fp, const kg_collection_counts *c, int remaining, double elapsed,
                   int ran_done, int jobs, const char *what)
{
	if (!fp)
		return;
	char left[64] = "";
	if (ran_done > 0 && remaining > 0) {
		/* the wall time per entry so far (the workers in parallel) times what is left */
		(void)jobs;
		double s = elapsed / ran_done * remaining;
		if (s < 90)
			snprintf(left, sizeof(left), ", about %.0f s left", s);
		else if (s < 5400)
			snprintf(left, sizeof(left), ", about %.0f min left", s / 60);
		else
			snprintf(left, sizeof(left), ", about %.1f h left", s / 3600);
	}
	int tty = isatty(fileno(fp));
	fprintf(fp, "%skogei collection: %d done, %d failed, %d remaining%s%s%s", tty ? "\r" : "",
	        c->done, c->failed, remaining, left, what ? what : "", tty ? "\033[K" : "\n");
	fflush(fp);
}

/* ---- the plan's entries and their states ----------------------------------------------- */

int coll_plan_load(const char *out, json_t **plan, kg_err *err)
{
	*plan = NULL;
	char *path = coll_path(out, "plan.json");
	if (!path)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	struct stat st;
	if (stat(path, &st) != 0) {
		kg_fail(err, KG_EINVAL, "%s: not a collection (no .collection/plan.json: run kogei "
		        "collection run LIST.csv -o %s first)", out, out);
		free(path);
		return KG_EINVAL;
	}
	int ret = kg_json_load(path, plan, err);
	kg_inputs_forget(path);
	const char *format = ret ? NULL : json_string_value(json_object_get(*plan, "format"));
	if (!ret && (!format || strcmp(format, COLL_PLAN_FORMAT) ||
	             !json_is_array(json_object_get(*plan, "entries"))))
		ret = kg_fail(err, KG_EINVAL, "%s: format: expected %s with entries", path,
		              COLL_PLAN_FORMAT);
	free(path);
	if (ret) {
		json_decref(*plan);
		*plan = NULL;
	}
	return ret;
}

coll_status coll_entry_status(const char *out, const json_t *entry, json_t **state)
{
	if (state)
		*state = NULL;
	const char *name = json_string_value(json_object_get(entry, "name"));
	char *path = name ? coll_state_path(out, name) : NULL;
	json_t *s = NULL;
	struct stat st;
	coll_status status = COLL_PENDING;
	if (path && stat(path, &st) == 0 && kg_json_load(path, &s, NULL) == 0) {
		kg_inputs_forget(path);
		const char *v = json_string_value(json_object_get(s, "status"));
		if (json_equal(json_object_get(s, "key"), json_object_get(entry, "key")) && v)
			status = !strcmp(v, "done") ? COLL_DONE : !strcmp(v, "failed") ? COLL_FAILED
			                                                               : COLL_PENDING;
	}
	free(path);
	if (status != COLL_PENDING && state)
		*state = s;
	else
		json_decref(s);
	return status;
}

void coll_count(const char *out, const json_t *plan, kg_collection_counts *c)
{
	c->entries = c->done = c->failed = c->pending = 0;
	size_t i;
	const json_t *e;
	json_array_foreach(json_object_get(plan, "entries"), i, e)
	{
		c->entries++;
		switch (coll_entry_status(out, e, NULL)) {
		case COLL_DONE: c->done++; break;
		case COLL_FAILED: c->failed++; break;
		default: c->pending++; break;
		}
	}
}

/* ---- the list -------------------------------------------------------------------------- */

typedef struct listck {
	const kg_collection_options *o;
	FILE *problems;
	int nproblems;
	const kg_csv *t;
	const char *dir;          /* the CSV's folder */
} listck;

static void problem(listck *l, int line, int col, const char *fmt, ...) KG_PRINTF(4, 5);

static void problem(listck *l, int line, int col, const char *fmt, ...)
{
	char msg[1024], shown[4 * 1024 + 16];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	if (col >= 0)
		fprintf(l->problems, "%s: line %d, column %d (%s): %s\n", l->o->list, line, col + 1,
		        l->t->names[col], kg_text_visible(msg, SIZE_MAX, shown, sizeof(shown)));
	else
		fprintf(l->problems, "%s: line %d: %s\n", l->o->list, line,
		        kg_text_visible(msg, SIZE_MAX, shown, sizeof(shown)));
	l->nproblems++;
}

/* value relative to the CSV's folder (an absolute one as it is), newly allocated. */
static char *below_list(const listck *l, const char *value)
{
	return value[0] == '/' ? strdup(value) : kg_path_join(l->dir, value);
}

/* A file cell: its realpath, or NULL with a problem. */
static char *file_cell(listck *l, int line, int col, const char *value)
{
	char *p = below_list(l, value);
	char *real = p ? realpath(p, NULL) : NULL;
	struct stat st;
	if (!real || stat(real, &st) != 0 || !S_ISREG(st.st_mode)) {
		problem(l, line, col, "'%s': %s: expected a file", value,
		        real ? "not a regular file" : strerror(errno));
		free(real);
		real = NULL;
	}
	free(p);
	return real;
}

static const char *const known_columns[] = {"session", "name", "reference", "spectra", "cube",
                                            "materials"};
enum { C_SESSION, C_NAME, C_REFERENCE, C_SPECTRA, C_CUBE, C_MATERIALS, C_KNOWN };

static int add_sha(json_t *sums, const char *key, const char *path)
{
	char hex[65];
	if (kg_file_sha256(path, hex, NULL))
		return json_object_set_new(sums, key, json_null());
	kg_inputs_forget(path);
	return json_object_set_new(sums, key, json_string(hex));
}

static int append_str(json_t *a, const char *s) { return json_array_append_new(a, json_string(s)); }

/* One row into an entry (NULL when it has problems; those are reported). */
static json_t *row_entry(listck *l, int r, const int *col, const int *meta_cols, int nmeta,
                         const char *out_abs, json_t *names)
{
	const kg_csv *t = l->t;
	int line = t->row_lines[r], before = l->nproblems;
	const char *cell[C_KNOWN];
	for (int k = 0; k < C_KNOWN; k++)
		cell[k] = col[k] >= 0 ? kg_csv_cell(t, r, col[k]) : "";
	char *session = NULL, *ref = NULL, *spectra = NULL, *mat = NULL, *sj = NULL;
	json_t *entry = NULL, *meta = json_object();
	/* the session: a folder with session.json */
	if (!*cell[C_SESSION]) {
		problem(l, line, col[C_SESSION], "empty: expected the session's folder");
	} else {
		char *p = below_list(l, cell[C_SESSION]);
		session = p ? realpath(p, NULL) : NULL;
		sj = session ? kg_path_join(session, "session.json") : NULL;
		struct stat st;
		if (!session)
			problem(l, line, col[C_SESSION], "'%s': %s: expected a session folder",
			        cell[C_SESSION], strerror(errno));
		else if (!sj || stat(sj, &st) != 0)
			problem(l, line, col[C_SESSION], "'%s': no session.json there: expected a "
			        "session folder (kogei acquire --out)", cell[C_SESSION]);
		free(p);
	}
	/* its name */
	char name[COLL_NAME_MAX + 8] = "";
	int name_col = col[C_NAME] >= 0 && *cell[C_NAME] ? col[C_NAME] : col[C_SESSION];
	if (col[C_NAME] >= 0 && *cell[C_NAME]) {
		snprintf(name, sizeof(name), "%s", cell[C_NAME]);
	} else if (*cell[C_SESSION]) {
		size_t n = strlen(cell[C_SESSION]);
		while (n > 1 && cell[C_SESSION][n - 1] == '/')
			n--;
		const char *b = cell[C_SESSION];
		for (size_t i = 0; i < n; i++)
			if (cell[C_SESSION][i] == '/' && i + 1 < n)
				b = cell[C_SESSION] + i + 1;
		snprintf(name, sizeof(name), "%.*s", (int)(n - (size_t)(b - cell[C_SESSION])), b);
	}
	if (*name && (!kg_name_is_safe(name, COLL_NAME_MAX) || !strcmp(name, "collection.json") ||
	              !strcmp(name, "index.html"))) {
		problem(l, line, name_col, "name '%s' is not a safe folder name: expected 1 to %d "
		        "characters of A-Z a-z 0-9 . _ -, not starting with '.'%s", name,
		        COLL_NAME_MAX - 1, col[C_NAME] >= 0 ? "" : " (give a name column)");
		*name = 0;
	} else if (*name) {
		json_t *first = json_object_get(names, name);
		if (first)
			problem(l, line, name_col, "name '%s' is also the name of line %lld: expected "
			        "one entry per name", name, (long long)json_integer_value(first));
		else
			json_object_set_new(names, name, json_integer(line));
	}
	/* the calibration */
	if (!*cell[C_REFERENCE] && !*cell[C_SPECTRA])
		problem(l, line, col[C_SPECTRA] >= 0 ? col[C_SPECTRA] : col[C_REFERENCE],
		        "empty: expected the chart's spectra or a reference calibration");
	if (*cell[C_REFERENCE])
		ref = file_cell(l, line, col[C_REFERENCE], cell[C_REFERENCE]);
	if (*cell[C_SPECTRA])
		spectra = file_cell(l, line, col[C_SPECTRA], cell[C_SPECTRA]);
	const char *cube = cell[C_CUBE];
	if (*cube && strcmp(cube, "f32") && strcmp(cube, "f16") && strcmp(cube, "weights") &&
	    strcmp(cube, "none"))
		problem(l, line, col[C_CUBE], "'%s': expected f32, f16, weights or none", cube);
	if (*cell[C_MATERIALS]) {
		char *p = below_list(l, cell[C_MATERIALS]);
		struct stat st;
		if (p && stat(p, &st) == 0)
			mat = file_cell(l, line, col[C_MATERIALS], cell[C_MATERIALS]);
		else if (strchr(cell[C_MATERIALS], '/'))
			problem(l, line, col[C_MATERIALS], "'%s': %s: expected a material library file "
			        "or a bundled name", cell[C_MATERIALS], strerror(errno));
		else if (!kg_name_is_safe(cell[C_MATERIALS], 128))
			problem(l, line, col[C_MATERIALS], "'%s': expected a material library file or a "
			        "bundled name", cell[C_MATERIALS]);
		else
			mat = strdup(cell[C_MATERIALS]); /* a bundled name: kogei process resolves it */
		free(p);
	}
	for (int m = 0; m < nmeta; m++) {
		const char *v = kg_csv_cell(t, r, meta_cols[m]);
		const char *why = *v ? kg_meta_value_problem(v) : NULL;
		if (why)
			problem(l, line, meta_cols[m], "%s", why);
		else if (*v)
			json_object_set_new(meta, t->names[meta_cols[m]] + 5, json_string(v));
	}
	if (l->nproblems > before || !*name)
		goto done;
	/* the entry: kogei process's arguments and the key of its result */
	json_t *args = json_array(), *key = json_object(), *sums = json_object();
	char *outdir = kg_path_join(out_abs, name);
	append_str(args, "process");
	append_str(args, session);
	append_str(args, "-o");
	append_str(args, outdir);
	if (ref) {
		append_str(args, "--reference");
		append_str(args, ref);
	}
	if (spectra) {
		append_str(args, "--spectra");
		append_str(args, spectra);
	}
	if (mat) {
		append_str(args, "--materials");
		append_str(args, mat);
	}
	if (*cube) {
		append_str(args, "--cube");
		append_str(args, cube);
	}
	const char *k;
	json_t *v;
	json_object_foreach(meta, k, v)
	{
		char *kv = NULL;
		if (asprintf(&kv, "%s=%s", k, json_string_value(v)) >= 0) {
			append_str(args, "--meta");
			append_str(args, kv);
		}
		free(kv);
	}
	/* where the entry's folder is published (collection_iiif.c) */
	const char *bases[3][2] = {{"--iiif-base", l->o->iiif_base},
	                           {"--iiif-image-api", NULL},
	                           {"--files-base", l->o->files_base}};
	for (int b = 0; b < 3; b++) {
		char *url = NULL;
		if (b == 1 && l->o->iiif_image_api) {
			append_str(args, bases[b][0]);
			append_str(args, l->o->iiif_image_api);
		} else if (bases[b][1] && coll_url_join(bases[b][1], name, &url) == 0) {
			append_str(args, bases[b][0]);
			append_str(args, url);
		}
		free(url);
	}
	add_sha(sums, "session.json", sj);
	if (ref)
		add_sha(sums, "reference", ref);
	if (spectra)
		add_sha(sums, "spectra", spectra);
	if (mat && mat[0] == '/')
		add_sha(sums, "materials", mat);
	json_object_set(key, "args", args);
	json_object_set_new(key, "sha256", sums);
	entry = json_pack("{s:s, s:i, s:s, s:s, s:o, s:o, s:o}", "name", name, "line", line,
	                  "session", cell[C_SESSION], "session_path", session, "meta", meta,
	                  "args", args, "key", key);
	meta = NULL;
	free(outdir);
done:
	json_decref(meta);
	free(session);
	free(sj);
	free(ref);
	free(spectra);
	free(mat);
	return entry;
}

int coll_plan_make(const kg_collection_options *o, const char *out_abs, json_t **plan,
                   kg_err *err)
{
	*plan = NULL;
	kg_csv *t = NULL;
	int ret = kg_csv_read(o->list, &t, err);
	if (ret)
		return ret == KG_ENOMEM ? ret : KG_EINVAL;
	kg_inputs_forget(o->list);
	listck l = {.o = o, .problems = o->problems ? o->problems : stderr, .t = t};
	char *dir = kg_path_dir(o->list);
	l.dir = dir;
	int col[C_KNOWN], *meta_cols = calloc((size_t)t->ncols + 1, sizeof(int)), nmeta = 0;
	for (int k = 0; k < C_KNOWN; k++)
		col[k] = -1;
	for (int i = 0; i < t->ncols; i++) {
		const char *n = t->names[i];
		int k = 0;
		while (k < C_KNOWN && strcmp(n, known_columns[k]))
			k++;
		int dup = k < C_KNOWN ? col[k] >= 0 : 0;
		for (int m = 0; m < nmeta && !dup; m++)
			dup = !strcmp(t->names[meta_cols[m]], n);
		if (dup)
			problem(&l, t->header_line, i, "column given twice: expected each column once");
		else if (k < C_KNOWN)
			col[k] = i;
		else if (!strncmp(n, "meta.", 5) && kg_meta_key_ok(n + 5))
			meta_cols[nmeta++] = i;
		else
			problem(&l, t->header_line, i, "unknown column: expected session, name, "
			        "reference, spectra, cube, materials or meta.KEY (KEY of A-Z a-z 0-9 _ . -)");
	}
	if (col[C_SESSION] < 0)
		problem(&l, t->header_line, -1, "no column 'session': expected the sessions' "
		        "folders in a column named session");
	if (col[C_REFERENCE] < 0 && col[C_SPECTRA] < 0)
		problem(&l, t->header_line, -1, "no column 'spectra' or 'reference': expected the "
		        "chart's spectra or a reference calibration of each session");
	if (!t->nrows)
		problem(&l, t->header_line, -1, "no rows: expected one session a row");
	json_t *entries = json_array(), *names = json_object();
	if (!l.nproblems)
		for (int r = 0; r < t->nrows; r++) {
			json_t *e = row_entry(&l, r, col, meta_cols, nmeta, out_abs, names);
			if (e)
				json_array_append_new(entries, e);
		}
	if (l.nproblems) {
		ret = kg_fail(err, KG_EINVAL, "%s: %d problem(s) in the list: nothing run", o->list,
		              l.nproblems);
	} else {
		char *list_real = realpath(o->list, NULL), when[32];
		coll_now(when);
		*plan = json_pack("{s:s, s:s, s:s?, s:s, s:s, s:o, s:s?}", "format",
		                  COLL_PLAN_FORMAT, "list", o->list, "list_path", list_real, "engine",
		                  o->engine, "written", when, "entries", entries, "files_base",
		                  o->files_base);
		entries = NULL;
		free(list_real);
		if (!*plan)
			ret = kg_fail(err, KG_ENOMEM, "out of memory");
	}
	json_decref(entries);
	json_decref(names);
	free(meta_cols);
	free(dir);
	kg_csv_free(&t);
	return ret;
}

/* ---- run ------------------------------------------------------------------------------- */

/* OUT made and locked (OUT/.collection/lock, held until the call returns). */
static int lock_out(const char *out, int *fd, kg_err *err)
{
	char *dir = coll_path(out, NULL), *lock = coll_path(out, "lock");
	int ret = dir && lock ? kg_mkdir_p(dir, err) : kg_fail(err, KG_ENOMEM, "out of memory");
	if (!ret) {
		*fd = open(lock, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
		if (*fd < 0)
			ret = kg_fail(err, KG_EIO, "%s: cannot open: %s", lock, strerror(errno));
		else if (flock(*fd, LOCK_EX | LOCK_NB) != 0) {
			ret = kg_fail(err, KG_EBUSY, "%s: another kogei collection run is using it: wait "
			              "for it to end", out);
			close(*fd);
			*fd = -1;
		}
	}
	free(dir);
	free(lock);
	return ret;
}

int kg_collection_run(const kg_collection_options *o, kg_collection_counts *c,
                      int *signal_out, kg_err *err)
{
	kg_check_arg(o && o->list && o->out && c, err);
	memset(c, 0, sizeof(*c));
	if (signal_out)
		*signal_out = 0;
	struct stat st;
	if (stat(o->list, &st) != 0)
		return kg_fail(err, KG_EINVAL, "%s: %s: expected the collection's CSV list", o->list,
		               strerror(errno));
	/* the list first: a bad one leaves nothing behind, not even OUT */
	json_t *plan = NULL;
	int *run = NULL, nrun = 0, lock = -1, ret;
	char *out = realpath(o->out, NULL);
	if (!out) {
		char cwd[PATH_MAX];
		if (o->out[0] != '/' && !getcwd(cwd, sizeof(cwd)))
			return kg_fail(err, KG_EIO, "cannot read the current folder: %s", strerror(errno));
		if (asprintf(&out, "%s%s%s", o->out[0] == '/' ? "" : cwd, o->out[0] == '/' ? "" : "/",
		             o->out) < 0)
			return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	if ((ret = coll_plan_make(o, out, &plan, err)))
		goto out;
	if (kg_mkdir_p(o->out, err)) {
		ret = KG_EINVAL;
		goto out;
	}
	char *real = realpath(o->out, NULL);
	if (!real) {
		ret = kg_fail(err, KG_EINVAL, "%s: %s", o->out, strerror(errno));
		goto out;
	}
	if (strcmp(real, out)) { /* OUT's path as the kernel resolves it, in every argument */
		free(out);
		out = real;
		json_decref(plan);
		plan = NULL;
		if ((ret = coll_plan_make(o, out, &plan, err)))
			goto out;
	} else {
		free(real);
	}
	if ((ret = lock_out(out, &lock, err)))
		goto out;
	char job[64];
	int tasks = 0;
	if (coll_slurm_active(out, job, &tasks) == 1) {
		ret = kg_fail(err, KG_EBUSY, "%s: Slurm job %s of this collection is still queued or "
		              "running (%d task(s)): wait for it (kogei collection status %s) or "
		              "scancel it", o->out, job, tasks, o->out);
		goto out;
	}
	char *plan_path = coll_path(out, "plan.json");
	ret = plan_path ? kg_json_write(plan, plan_path, err) : kg_fail(err, KG_ENOMEM, "out of memory");
	free(plan_path);
	if (ret)
		goto out;
	/* what to run: failed, pending and changed entries */
	json_t *entries = json_object_get(plan, "entries");
	run = calloc(json_array_size(entries) + 1, sizeof(int));
	int was_failed = 0, was_new = 0;
	size_t i;
	json_t *e;
	json_array_foreach(entries, i, e)
	{
		coll_status s = coll_entry_status(out, e, NULL);
		c->entries++;
		if (s == COLL_DONE) {
			c->done++;
			continue;
		}
		was_failed += s == COLL_FAILED;
		was_new += s == COLL_PENDING;
		run[nrun++] = (int)i;
	}
	if (o->progress)
		fprintf(o->progress, "kogei collection: %d entries: %d done, %d to run (%d failed "
		        "before, %d new or changed)\n", c->entries, c->done, nrun, was_failed, was_new);
	if (!nrun) {
		ret = kg_collection_finish(out, c, err);
		goto out;
	}
	if (!strcmp(o->engine ? o->engine : "local", "slurm"))
		ret = coll_run_slurm(o, out, plan, run, nrun, c, signal_out, err);
	else
		ret = coll_run_local(o, out, plan, run, nrun, c, signal_out, err);
out:
	if (lock >= 0)
		close(lock);
	json_decref(plan);
	free(run);
	free(out);
	return ret;
}
