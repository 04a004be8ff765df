/* Sessions killed with SIGKILL stay valid. One capture completes; then `kogei acquire
 * --frames 200` on a real-time sim camera (50 fps) is killed at several moments during
 * its capture, and short captures are killed at random moments of their whole run
 * (0.3 to 1.2 times a full run: metering, frames, outputs, manifest, exit). After every
 * kill session.json must parse, every file it references must exist with its sha256,
 * and every capture completed
 * before must still be there. Finally the session takes another capture, and a
 * completed capture of it replays bit-identically. */
#include <dirent.h>
#include <sys/stat.h>

#include "acq_test.h"
#include "kg_core.h"

static char done_names[64][64];
static int ndone;

/* Check the session and that the captures known to be complete are all in it;
 * returns the number of captures and records the names. */
static int check(const char *s, const char *when)
{
	char names[64][64];
	int n = acq_check_session(s, names, 64);
	CHECK(n >= ndone, "%s: session invalid or lost captures (%d, had %d)", when, n, ndone);
	for (int i = 0; i < ndone && n >= ndone; i++)
		CHECK(!strcmp(names[i], done_names[i]), "%s: capture %d is %s, was %s", when, i,
		      names[i], done_names[i]);
	for (int i = ndone; i < n && i < 64; i++)
		memcpy(done_names[i], names[i], 64);
	if (n > ndone)
		ndone = n;
	return n;
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Returns 1 when the child died of the SIGKILL (0: it had exited already). */
static int kill_after(char *const *args, double delay)
{
	pid_t pid = acq_spawn(args);
	usleep((useconds_t)(delay * 1e6));
	kill(pid, SIGKILL);
	int st;
	waitpid(pid, &st, 0);
	return WIFSIGNALED(st) && WTERMSIG(st) == SIGKILL;
}

/* Files anywhere under dir whose name is a temporary: the old ".tmp" suffix or
 * kogei's named pattern. Frames and outputs are written through files with no name
 * (O_TMPFILE), linked to a hidden name and renamed into place: a SIGKILL between the
 * two leaves that name, which the next recorder removes (its process is gone). */
static int temporaries(const char *dir, char *first, size_t len)
{
	DIR *d = opendir(dir);
	int n = 0;
	for (struct dirent *e; d && (e = readdir(d));) {
		if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
			continue;
		char p[4600];
		snprintf(p, sizeof(p), "%s/%s", dir, e->d_name);
		struct stat st;
		if (lstat(p, &st) == 0 && S_ISDIR(st.st_mode))
			n += temporaries(p, first, len);
		else if (strstr(e->d_name, ".tmp") || strstr(e->d_name, "kogei-tmp")) {
			if (!n && !*first)
				snprintf(first, len, "%s", p);
			n++;
		}
	}
	if (d)
		closedir(d);
	return n;
}

/* Lines of frames/index.jsonl: every frame recorded so far. */
static long recorded_frames(const char *s)
{
	char path[4400];
	snprintf(path, sizeof(path), "%s/frames/index.jsonl", s);
	FILE *f = fopen(path, "r");
	long n = 0;
	for (int c; f && (c = fgetc(f)) != EOF;)
		n += c == '\n';
	if (f)
		fclose(f);
	return n;
}

int main(int argc, char **argv)
{
	acq_init(argc, argv, "acquire-sigkill");
	char s[4200];
	snprintf(s, sizeof(s), "%s", kg_test_path("session"));
	const char *rt = "sim:?realtime=1&fps=50&width=64&height=48";
	int rc = acq_run("acquire", "--camera", rt, "--out", s, "--kind", "chart", "--frames", "3",
	                 NULL);
	CHECK(rc == 0, "first capture: exit %d: %s", rc, acq_errtext);
	CHECK(check(s, "after the first capture") == 1, "one capture");

	/* during the frames of a long capture (200 frames at 50 fps: 4 s) */
	char *long_args[] = {"acquire", "--camera", (char *)rt, "--out", s, "--kind", "chart",
	                     "--frames", "200", NULL};
	const double delays[] = {0.05, 0.3, 0.9, 1.6};
	for (int i = 0; i < 4; i++) {
		long frames_before = recorded_frames(s);
		int killed = kill_after(long_args, delays[i]);
		long frames_during = recorded_frames(s) - frames_before;
		char when[64];
		snprintf(when, sizeof(when), "killed after %.2f s of 200 frames", delays[i]);
		CHECK(killed, "%s: kogei was not running any more when killed", when);
		/* mid-capture indeed: frames of it were recorded (from 0.9 s on, so that a slow
		 * start under sanitizers on a loaded machine still counts) */
		CHECK(delays[i] < 0.85 || (frames_during > 0 && frames_during < 200),
		      "%s: %ld frames of the killed capture recorded, expected 1..199", when,
		      frames_during);
		printf("%s: %ld frames of it were recorded\n", when, frames_during);
		CHECK(check(s, when) == 1, "%s: a killed capture entered the manifest", when);
	}

	/* at random moments of short captures */
	char *short_args[] = {"acquire", "--camera", "sim:?width=320&height=240&format=bayer_rggb12",
	                      "--out", s, "--kind", "object", "--frames", "2", "--exposure", "auto",
	                      NULL};
	double t0 = now_s();
	rc = acq_wait(acq_spawn(short_args), 60);
	double full = now_s() - t0;
	CHECK(rc == 0, "short capture: exit %d: %s", rc, acq_errtext);
	int before = ndone;
	CHECK(check(s, "after a short capture") == before + 1, "the short capture is missing");
	kg_rng rng;
	kg_rng_seed(&rng, 2024);
	int killed_complete = 0;
	for (int i = 0; i < 10; i++) {
		int had = ndone;
		double d = full * (0.3 + 0.9 * kg_rng_uniform(&rng));
		kill_after(short_args, d);
		char when[64];
		snprintf(when, sizeof(when), "short capture killed after %.3f s", d);
		int n = check(s, when);
		CHECK(n == had || n == had + 1, "%s: %d captures, had %d", when, n, had);
		killed_complete += n == had + 1;
	}
	char first[4600] = "";
	int ntmp = temporaries(s, first, sizeof(first));
	CHECK(ntmp == 0, "%d temporaries left behind by the kills (%s)", ntmp, first);
	printf("short capture: %.3f s; 10 kills at 0.3..1.2 of that, %d after the manifest\n",
	       full, killed_complete);

	/* a dead recorder's hidden frame name in the first capture's folder, which no later
	 * capture writes: the next recorder removes it */
	pid_t dead = fork();
	if (dead == 0)
		_exit(0);
	waitpid(dead, NULL, 0);
	char stale[4600];
	snprintf(stale, sizeof(stale), "%s/frames/chart-0001/.000099.raw.kogei-tmp.%ld.AbCdEf", s,
	         (long)dead);
	FILE *sf = fopen(stale, "w");
	CHECK(sf != NULL, "%s: cannot create", stale);
	if (sf)
		fclose(sf);

	/* the session still takes captures, with fresh names */
	int had = ndone;
	rc = acq_run("acquire", "--camera", rt, "--out", s, "--kind", "chart", "--frames", "2",
	             NULL);
	CHECK(rc == 0, "capture after the kills: exit %d: %s", rc, acq_errtext);
	CHECK(check(s, "after the kills") == had + 1, "one more capture");
	CHECK(access(stale, F_OK) != 0, "%s: a dead recorder's temporary is still there", stale);
	printf("captures after the kills: %d (%s ... %s)\n", ndone, done_names[0],
	       done_names[ndone - 1]);

	/* and its recording still replays: the first capture, bit for bit */
	char uri[4400], t[4200], pa[4400], pb[4400];
	snprintf(uri, sizeof(uri), "replay:%s#chart-0001", s);
	snprintf(t, sizeof(t), "%s", kg_test_path("replayed"));
	rc = acq_run("acquire", "--camera", uri, "--out", t, "--kind", "chart", "--frames", "3",
	             NULL);
	CHECK(rc == 0, "replay after the kills: exit %d: %s", rc, acq_errtext);
	snprintf(pa, sizeof(pa), "%s/captures/chart-0001/mean.tif", s);
	snprintf(pb, sizeof(pb), "%s/captures/chart-0001/mean.tif", t);
	CHECK(acq_same_file(pa, pb) == 0, "the replayed mean differs");
	acq_cleanup();
	return kg_test_done("acquire-sigkill");
}
