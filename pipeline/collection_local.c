/* The local engine of kogei collection run: N worker slots on this machine, each running
 * one entry at a time as `kogei collection task OUT INDEX` (a process of its own, so a
 * crash of one session's run touches no other), the progress line, and the record
 * written at the end. A signal (Ctrl-C, kill) is passed to the running tasks, which
 * let kogei process stop and leave their entry as it was; the record is then written
 * and the run ends by the signal. */
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "collection_private.h"

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static pid_t start_task(const char *exe, const char *out, int index, int slot, int threads)
{
	char idx[16], job[128], thr[16], host[64] = "localhost";
	gethostname(host, sizeof(host) - 1);
	host[sizeof(host) - 1] = 0;
	snprintf(idx, sizeof(idx), "%d", index);
	snprintf(job, sizeof(job), "local:%s:worker-%d", host, slot + 1);
	snprintf(thr, sizeof(thr), "%d", threads);
	fflush(NULL);
	pid_t pid = fork();
	if (pid == 0) {
		char *argv[] = {(char *)exe, "collection", "task", (char *)out, idx, "--job", job,
		                "--threads", thr, NULL};
		execv(exe, argv);
		dprintf(2, "kogei: %s: cannot run: %s\n", exe, strerror(errno));
		_exit(127);
	}
	return pid;
}

int coll_run_local(const kg_collection_options *o, const char *out, const json_t *plan,
                   const int *run, int nrun, kg_collection_counts *c, int *signal_out,
                   kg_err *err)
{
	int jobs = o->njobs > 0 ? o->njobs : kg_cpu_count(256);
	if (jobs > nrun)
		jobs = nrun;
	/* the cores shared among the workers (kogei process --threads) */
	int threads = kg_cpu_count(256) / jobs;
	if (threads < 1)
		threads = 1;
	char *exe = coll_self(o->self);
	pid_t *pids = calloc((size_t)jobs, sizeof(pid_t));
	int *slot_entry = calloc((size_t)jobs, sizeof(int));
	if (!exe || !pids || !slot_entry) {
		free(exe);
		free(pids);
		free(slot_entry);
		return kg_fail(err, exe ? KG_ENOMEM : KG_EIO, "%s", exe ? "out of memory"
		               : "cannot find the kogei executable (/proc/self/exe)");
	}
	coll_catch_signals();
	const json_t *entries = json_object_get(plan, "entries");
	int next = 0, live = 0, finished = 0, sent = 0, ret = 0;
	double t0 = now_s();
	/* c: done and failed over the whole collection, updated as tasks end */
	kg_collection_counts now = *c;
	coll_progress(o->progress, &now, nrun, 0, 0, jobs, NULL);
	for (;;) {
		int sig = coll_signal();
		if (sig && !sent) {
			for (int s = 0; s < jobs; s++)
				if (pids[s] > 0)
					kill(pids[s], sig);
			sent = 1;
		}
		while (!sig && !ret && live < jobs && next < nrun) {
			int s = 0;
			while (pids[s] > 0)
				s++;
			pid_t pid = start_task(exe, out, run[next], s, threads);
			if (pid < 0) {
				ret = kg_fail(err, KG_ENODEV, "cannot start a worker: %s", strerror(errno));
				break;
			}
			pids[s] = pid;
			slot_entry[s] = run[next++];
			live++;
		}
		if (!live)
			break;
		int st;
		pid_t pid = waitpid(-1, &st, 0);
		if (pid < 0) {
			if (errno == EINTR)
				continue;
			break;
		}
		int s = 0;
		while (s < jobs && pids[s] != pid)
			s++;
		if (s == jobs)
			continue;
		pids[s] = 0;
		live--;
		const json_t *e = json_array_get(entries, (size_t)slot_entry[s]);
		coll_status cs = coll_entry_status(out, e, NULL);
		if (cs == COLL_DONE) {
			now.done++;
			finished++;
		} else if (cs == COLL_FAILED) {
			now.failed++;
			finished++;
		}
		if (cs != COLL_PENDING || !coll_signal()) {
			char what[COLL_NAME_MAX + 32];
			snprintf(what, sizeof(what), " (%s %s)",
			         json_string_value(json_object_get(e, "name")),
			         cs == COLL_DONE ? "done" : cs == COLL_FAILED ? "failed" : "not run");
			coll_progress(o->progress, &now, nrun - finished, now_s() - t0, finished, jobs,
			              isatty(fileno(o->progress ? o->progress : stderr)) ? NULL : what);
		}
	}
	if (o->progress && isatty(fileno(o->progress)))
		fputc('\n', o->progress);
	c->ran = finished;
	int sig = coll_signal();
	int fret = kg_collection_finish(out, c, ret ? NULL : err);
	c->ran = finished;
	if (!ret)
		ret = fret;
	if (!ret && sig) {
		*signal_out = sig;
		ret = kg_fail(err, -EINTR, "interrupted by %s: %d entries run, the others stay as they "
		              "were (run the same command again to go on)",
		              sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "SIGHUP", finished);
	}
	free(exe);
	free(pids);
	free(slot_entry);
	return ret;
}
