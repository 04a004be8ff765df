/* The Slurm engine of kogei collection run, through the commands a cluster has (sbatch,
 * squeue; no Slurm library): one script OUT/.slurm/collection.sbatch submitted twice,
 * as a job array of the entries to run (`task`: one `kogei collection task` each, %N the
 * throttle) and as a job that depends on it (--dependency=afterany: `finish`, the
 * record); the job ids go to OUT/.slurm/job.json and the logs to OUT/.slurm/logs/. Then,
 * unless no_wait, squeue is polled (1 s, growing to 10 s) until neither job is queued
 * or running, with the progress line from the entries' states. */
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "collection_private.h"

#define POLL_MIN_MS 1000
#define POLL_MAX_MS 10000
#define SQUEUE_FAILS_MAX 12 /* squeue failing this many times in a row: the engine failed */
#define MAX_SBATCH_ARGS 64

/* Run argv (a command from the PATH), its standard output into *out (NUL-terminated)
 * and the first line of its standard error into errline; the exit status, or -1 when
 * it could not be started. */
static int run_cmd(char *const argv[], char **out, char errline[512])
{
	int po[2], pe[2];
	*out = NULL;
	errline[0] = 0;
	if (pipe(po) != 0)
		return -1;
	if (pipe(pe) != 0) {
		close(po[0]);
		close(po[1]);
		return -1;
	}
	fflush(NULL);
	pid_t pid = fork();
	if (pid == 0) {
		dup2(po[1], 1);
		dup2(pe[1], 2);
		close(po[0]);
		close(pe[0]);
		int nul = open("/dev/null", O_RDONLY);
		if (nul >= 0)
			dup2(nul, 0);
		execvp(argv[0], argv);
		dprintf(2, "%s: cannot run: %s\n", argv[0], strerror(errno));
		_exit(127);
	}
	close(po[1]);
	close(pe[1]);
	if (pid < 0) {
		close(po[0]);
		close(pe[0]);
		return -1;
	}
	/* both pipes read to their end (poll-free: stderr is read after stdout; the
	 * commands write little) */
	size_t len = 0, cap = 4096;
	char *buf = malloc(cap);
	ssize_t n;
	while (buf && (n = read(po[0], buf + len, cap - len - 1)) != 0) {
		if (n < 0) {
			if (errno == EINTR)
				continue;
			break;
		}
		len += (size_t)n;
		if (len + 1 >= cap) {
			char *b = realloc(buf, cap * 2);
			if (!b)
				break;
			buf = b;
			cap *= 2;
		}
	}
	if (buf)
		buf[len] = 0;
	char ebuf[4096];
	size_t elen = 0;
	while ((n = read(pe[0], ebuf + elen, sizeof(ebuf) - 1 - elen)) != 0) {
		if (n < 0) {
			if (errno == EINTR)
				continue;
			break;
		}
		elen += (size_t)n;
		if (elen + 1 >= sizeof(ebuf)) {
			char drain[512];
			while (read(pe[0], drain, sizeof(drain)) > 0)
				;
			break;
		}
	}
	ebuf[elen] = 0;
	close(po[0]);
	close(pe[0]);
	size_t l = strcspn(ebuf, "\n");
	snprintf(errline, 512, "%.*s", (int)(l < 500 ? l : 500), ebuf);
	int st;
	while (waitpid(pid, &st, 0) < 0)
		if (errno != EINTR)
			return -1;
	*out = buf;
	return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

/* s in single quotes for sh. */
static void put_sh(FILE *fp, const char *s)
{
	fputc('\'', fp);
	for (; *s; s++)
		if (*s == '\'')
			fputs("'\\''", fp);
		else
			fputc(*s, fp);
	fputc('\'', fp);
}

/* The one script of both jobs. */
static int write_script(const char *path, const char *exe, const char *out, kg_err *err)
{
	kg_outfile f;
	int ret = kg_outfile_open(&f, path, 0, err);
	if (ret)
		return ret;
	fputs("#!/bin/sh\n"
	      "# Written by kogei collection run --engine slurm; submitted twice:\n"
	      "#   sbatch --array=INDICES%N ... collection.sbatch task    one entry per task\n"
	      "#   sbatch --dependency=afterany:ARRAY ... collection.sbatch finish\n"
	      "#                                   collection.json and index.html\n"
	      "#SBATCH --job-name=kogei-collection\n"
	      "#SBATCH --ntasks=1\n"
	      "KOGEI=", f.fp);
	put_sh(f.fp, exe);
	fputs("\nOUT=", f.fp);
	put_sh(f.fp, out);
	fputs("\ncase \"${1:-}\" in\n"
	      "task)\n"
	      "\tset -- --job \"slurm:${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID}\"\n"
	      "\t[ -n \"${SLURM_CPUS_PER_TASK:-}\" ] && set -- \"$@\" --threads \"$SLURM_CPUS_PER_TASK\"\n"
	      "\texec \"$KOGEI\" collection task \"$OUT\" \"$SLURM_ARRAY_TASK_ID\" \"$@\" ;;\n"
	      "finish)\n"
	      "\texec \"$KOGEI\" collection finish \"$OUT\" ;;\n"
	      "*)\n"
	      "\techo \"usage: $0 task|finish (submitted by kogei collection run)\" >&2\n"
	      "\texit 2 ;;\n"
	      "esac\n", f.fp);
	ret = kg_outfile_commit(&f, err);
	if (!ret)
		chmod(path, 0755);
	return ret;
}

/* "--array=0,3,5%N" of the entries to run. */
static char *array_spec(const int *run, int nrun, int throttle)
{
	size_t cap = 32 + (size_t)nrun * 12, len = 0;
	char *s = malloc(cap);
	if (!s)
		return NULL;
	len += (size_t)snprintf(s, cap, "--array=");
	for (int i = 0; i < nrun; i++) {
		/* runs of consecutive indices as a-b */
		int j = i;
		while (j + 1 < nrun && run[j + 1] == run[j] + 1)
			j++;
		if (j > i + 1)
			len += (size_t)snprintf(s + len, cap - len, "%s%d-%d", i ? "," : "", run[i], run[j]);
		else
			len += (size_t)snprintf(s + len, cap - len, "%s%d", i ? "," : "", run[i]);
		if (j > i + 1)
			i = j;
	}
	if (throttle > 0)
		snprintf(s + len, cap - len, "%%%d", throttle);
	return s;
}

/* The job id of sbatch --parsable's answer ("ID" or "ID;cluster"). */
static int parse_jobid(const char *answer, char id[32])
{
	size_t n = answer ? strspn(answer, "0123456789") : 0;
	if (!n || n >= 32)
		return -1;
	memcpy(id, answer, n);
	id[n] = 0;
	return 0;
}

static int sbatch(char **argv, char id[32], kg_err *err)
{
	char *answer = NULL, eline[512];
	int st = run_cmd(argv, &answer, eline);
	int ret = 0;
	if (st == -1 || st == 127)
		ret = kg_fail(err, KG_ENODEV, "sbatch: cannot run it (%s): is this a Slurm cluster's "
		              "login node?", eline[0] ? eline : "not found on the PATH");
	else if (st != 0)
		ret = kg_fail(err, KG_ENODEV, "sbatch refused the job (exit %d): %s", st,
		              eline[0] ? eline : "no message");
	else if (parse_jobid(answer, id))
		ret = kg_fail(err, KG_ENODEV, "sbatch: unexpected answer '%.64s': expected a job id",
		              answer ? answer : "");
	free(answer);
	return ret;
}

/* Split the --sbatch-args value at blanks into argv (at most max). */
static int split_args(char *text, char **argv, int max)
{
	int n = 0;
	for (char *tok = strtok(text, " \t"); tok && n < max; tok = strtok(NULL, " \t"))
		argv[n++] = tok;
	return n;
}

static char *slurm_path(const char *out, const char *rel)
{
	char *p = NULL;
	if (asprintf(&p, "%s/.slurm%s%s", out, rel ? "/" : "", rel ? rel : "") < 0)
		return NULL;
	return p;
}

/* How many lines squeue gives for the jobs (their tasks queued or running): >= 0, or
 * -1 when squeue failed (errline says why). A job squeue no longer knows is done. */
static int squeue_count(const char *jobs, char errline[512])
{
	char *answer = NULL;
	char *argv[] = {"squeue", "--noheader", "--array", "--format=%i %T", "--jobs",
	                (char *)jobs, NULL};
	int st = run_cmd(argv, &answer, errline);
	int n = -1;
	if (st == 0 && answer) {
		n = 0;
		for (const char *p = answer; *p; p++)
			n += *p == '\n';
	} else if (st > 0 && st < 127 && strstr(errline, "Invalid job id")) {
		n = 0;
	}
	free(answer);
	return n;
}

int coll_slurm_active(const char *out, char job[64], int *tasks)
{
	char *path = slurm_path(out, "job.json");
	json_t *j = NULL;
	struct stat st;
	int r = 0;
	*tasks = 0;
	job[0] = 0;
	if (path && stat(path, &st) == 0 && kg_json_load(path, &j, NULL) == 0) {
		kg_inputs_forget(path);
		const char *a = json_string_value(json_object_get(j, "array_job"));
		const char *f = json_string_value(json_object_get(j, "finish_job"));
		if (a && f && strlen(a) < 30 && strlen(f) < 30) {
			char jobs[64], eline[512];
			snprintf(jobs, sizeof(jobs), "%s,%s", a, f);
			snprintf(job, 64, "%s", a);
			int n = squeue_count(jobs, eline);
			r = n < 0 ? -1 : n > 0;
			*tasks = n > 0 ? n : 0;
		}
	}
	json_decref(j);
	free(path);
	return r;
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Sleep ms, woken early by a signal. */
static void nap(int ms)
{
	struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
	nanosleep(&ts, NULL);
}

int coll_run_slurm(const kg_collection_options *o, const char *out, const json_t *plan,
                   const int *run, int nrun, kg_collection_counts *c, int *signal_out,
                   kg_err *err)
{
	char *exe = coll_self(o->self), *dir = slurm_path(out, NULL), *logs = slurm_path(out, "logs");
	char *script = slurm_path(out, "collection.sbatch"), *jobfile = slurm_path(out, "job.json");
	char *arr = array_spec(run, nrun, o->njobs);
	char *extra = o->sbatch_args ? strdup(o->sbatch_args) : NULL;
	char *out_task = NULL, *out_finish = NULL, *dep = NULL, *part = NULL;
	int ret = 0;
	if (!exe || !dir || !logs || !script || !jobfile || !arr || (o->sbatch_args && !extra) ||
	    asprintf(&out_task, "--output=%s/task-%%A_%%a.out", logs) < 0 ||
	    asprintf(&out_finish, "--output=%s/finish-%%j.out", logs) < 0 ||
	    (o->partition && asprintf(&part, "--partition=%s", o->partition) < 0)) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto out;
	}
	if ((ret = kg_mkdir_p(logs, err)) || (ret = write_script(script, exe, out, err)))
		goto out;
	time_t submitted = time(NULL);
	/* the array, then the job that writes the record after it */
	char *argv[MAX_SBATCH_ARGS + 16];
	int n = 0;
	argv[n++] = "sbatch";
	argv[n++] = "--parsable";
	argv[n++] = arr;
	argv[n++] = out_task;
	if (part)
		argv[n++] = part;
	char *extra_v[MAX_SBATCH_ARGS];
	int nextra = extra ? split_args(extra, extra_v, MAX_SBATCH_ARGS) : 0;
	for (int i = 0; i < nextra; i++)
		argv[n++] = extra_v[i];
	int fixed = n;
	argv[n++] = script;
	argv[n++] = "task";
	argv[n] = NULL;
	if ((ret = sbatch(argv, c->array_job, err)))
		goto out;
	if (asprintf(&dep, "--dependency=afterany:%s", c->array_job) < 0) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto out;
	}
	n = 0;
	argv[n++] = "sbatch";
	argv[n++] = "--parsable";
	argv[n++] = dep;
	argv[n++] = out_finish;
	for (int i = 4; i < fixed; i++) /* the partition and the extra options */
		argv[n++] = argv[i];
	argv[n++] = script;
	argv[n++] = "finish";
	argv[n] = NULL;
	if ((ret = sbatch(argv, c->finish_job, err)))
		goto out;
	char when[32];
	coll_now(when);
	json_t *j = json_pack("{s:s, s:s, s:s, s:s, s:i}", "array_job", c->array_job, "finish_job",
	                      c->finish_job, "submitted", when, "script", script, "tasks", nrun);
	ret = j ? kg_json_write(j, jobfile, err) : kg_fail(err, KG_ENOMEM, "out of memory");
	json_decref(j);
	if (ret)
		goto out;
	if (o->progress)
		fprintf(o->progress, "kogei collection: submitted Slurm job array %s (%d task(s)) and "
		        "job %s (the record, after it); logs in %s\n", c->array_job, nrun,
		        c->finish_job, logs);
	if (o->no_wait)
		goto out;
	/* wait: squeue until neither job is listed */
	coll_catch_signals();
	char jobs[80], eline[512] = "";
	snprintf(jobs, sizeof(jobs), "%s,%s", c->array_job, c->finish_job);
	int wait_ms = POLL_MIN_MS, fails = 0, last_done = -1, last_failed = -1;
	double t0 = now_s();
	kg_collection_counts start = *c;
	for (;;) {
		int q = squeue_count(jobs, eline);
		if (coll_signal())
			break;
		fails = q < 0 ? fails + 1 : 0;
		if (fails >= SQUEUE_FAILS_MAX) {
			ret = kg_fail(err, KG_ENODEV, "squeue failed %d times in a row: %s (the jobs %s "
			              "may still run: kogei collection status %s)", fails,
			              eline[0] ? eline : "no message", jobs, o->out);
			goto out;
		}
		kg_collection_counts now;
		coll_count(out, plan, &now);
		if (now.done != last_done || now.failed != last_failed) {
			int ran = (now.done - start.done) + (now.failed - start.failed);
			if (ran < 0)
				ran = 0;
			coll_progress(o->progress, &now, nrun - ran > 0 ? nrun - ran : 0, now_s() - t0, ran,
			              o->njobs, NULL);
			last_done = now.done;
			last_failed = now.failed;
		}
		if (q == 0)
			break;
		nap(wait_ms);
		wait_ms = wait_ms * 3 / 2 > POLL_MAX_MS ? POLL_MAX_MS : wait_ms * 3 / 2;
	}
	if (o->progress && isatty(fileno(o->progress)))
		fputc('\n', o->progress);
	if (coll_signal()) {
		*signal_out = coll_signal();
		ret = kg_fail(err, -EINTR, "stopped waiting: Slurm jobs %s go on (kogei collection "
		              "status %s; scancel %s to stop them)", jobs, o->out, c->array_job);
		goto out;
	}
	/* the record: the finish job's; written here when that job did not */
	char *rec = kg_path_join(out, "collection.json");
	struct stat st;
	kg_collection_counts keep = *c;
	int have = rec && stat(rec, &st) == 0 && st.st_mtime >= submitted;
	free(rec);
	if (!have && o->progress)
		fprintf(o->progress, "kogei collection: the record job %s did not write "
		        "collection.json (%s/finish-%s.out): writing it here\n", c->finish_job, logs,
		        c->finish_job);
	if (!have)
		ret = kg_collection_finish(out, c, err);
	else
		coll_count(out, plan, c);
	memcpy(c->array_job, keep.array_job, sizeof(c->array_job));
	memcpy(c->finish_job, keep.finish_job, sizeof(c->finish_job));
	c->ran = c->done + c->failed - start.done - start.failed;
out:
	free(exe);
	free(dir);
	free(logs);
	free(script);
	free(jobfile);
	free(arr);
	free(extra);
	free(out_task);
	free(out_finish);
	free(dep);
	free(part);
	return ret;
}
