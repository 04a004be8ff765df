/* An interrupted `kogei estimate` leaves its output directory as it was. A cube named
 * cube.hdr is written first from a small image; then a 4000 x 3000 float TIFF (a
 * 2.9 GB f32 cube) is estimated to the same name and the process is killed once it
 * has written 256 MB (its wchar in /proc/PID/io): with SIGTERM, SIGINT and SIGKILL,
 * through anonymous temporaries (O_TMPFILE) and through the named fallback that
 * KOGEI_TMPFILE=named forces. After every kill the directory must hold exactly what it
 * held before, the earlier cube byte for byte, except that a SIGKILL of the named
 * fallback leaves its temporaries, which the next writer in the directory removes. */
#include <signal.h>
#include <time.h>

#include "apply_fixture.h"

enum { BIG_W = 4000, BIG_H = 3000, MAX_FILES = 32 };
static const long long kill_after_bytes = 256LL << 20;

typedef struct entry {
	char name[256];
	long long size;
	uint64_t hash; /* FNV-1a of the contents; 0 for files above 16 MB (size only) */
} entry;

static uint64_t file_hash(const char *path, long long size)
{
	if (size > (16 << 20))
		return 0;
	uint64_t h = 1469598103934665603ULL;
	FILE *f = fopen(path, "rb");
	for (int c; f && (c = fgetc(f)) != EOF;)
		h = (h ^ (uint64_t)c) * 1099511628211ULL;
	if (f)
		fclose(f);
	return h;
}

/* The directory's entries, sorted by name. */
static int snapshot(entry *e)
{
	int n = 0;
	DIR *d = opendir(fx_dir);
	for (struct dirent *de; d && (de = readdir(d)) && n < MAX_FILES;) {
		if (!strcmp(de->d_name, ".") || !strcmp(de->d_name, ".."))
			continue;
		struct stat st;
		const char *p = fx_path(de->d_name);
		if (stat(p, &st) != 0)
			continue;
		snprintf(e[n].name, sizeof(e[n].name), "%s", de->d_name);
		e[n].size = st.st_size;
		e[n].hash = file_hash(p, st.st_size);
		n++;
	}
	if (d)
		closedir(d);
	for (int i = 1; i < n; i++)
		for (int j = i; j > 0 && strcmp(e[j - 1].name, e[j].name) > 0; j--) {
			entry t = e[j];
			e[j] = e[j - 1];
			e[j - 1] = t;
		}
	return n;
}

/* Compare the directory with before; returns the number of differences (printed). */
static int compare(const entry *before, int nb, const char *what)
{
	entry now[MAX_FILES];
	int n = snapshot(now), bad = 0;
	for (int i = 0; i < n; i++) {
		int found = 0;
		for (int j = 0; j < nb && !found; j++)
			found = !strcmp(now[i].name, before[j].name);
		if (!found) {
			fprintf(stderr, "%s: left behind %s (%lld bytes)\n", what, now[i].name, now[i].size);
			bad++;
		}
	}
	for (int j = 0; j < nb; j++) {
		int found = 0;
		for (int i = 0; i < n && !found; i++)
			if (!strcmp(now[i].name, before[j].name)) {
				found = 1;
				if (now[i].size != before[j].size || now[i].hash != before[j].hash) {
					fprintf(stderr, "%s: %s changed\n", what, before[j].name);
					bad++;
				}
			}
		if (!found) {
			fprintf(stderr, "%s: %s is gone\n", what, before[j].name);
			bad++;
		}
	}
	return bad;
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Bytes the process has written so far (wchar), -1 when it is gone. */
static long long written(pid_t pid)
{
	char path[64], line[128];
	snprintf(path, sizeof(path), "/proc/%ld/io", (long)pid);
	FILE *f = fopen(path, "r");
	long long n = -1;
	while (f && fgets(line, sizeof(line), f))
		if (!strncmp(line, "wchar:", 6))
			n = atoll(line + 6);
	if (f)
		fclose(f);
	return n;
}

/* Start `kogei estimate` of big into out, kill it with sig once it has written
 * kill_after_bytes; returns 1 when it died of sig. */
static int interrupted_run(const char *cam, const char *big, const char *out, int named,
                           int sig, const char *what)
{
	fflush(NULL);
	double t0 = now_s();
	pid_t pid = fork();
	if (pid == 0) {
		int null = open("/dev/null", O_WRONLY);
		dup2(null, 1);
		dup2(null, 2);
		if (named)
			setenv("KOGEI_TMPFILE", "named", 1);
		else
			unsetenv("KOGEI_TMPFILE");
		execl(fx_kogei, fx_kogei, "estimate", "--calib", cam, big, "-o", out, "--threads", "1",
		      (char *)NULL);
		_exit(127);
	}
	long long w = 0;
	while ((w = written(pid)) >= 0 && w < kill_after_bytes && now_s() - t0 < 120)
		usleep(2000);
	double t_kill = now_s() - t0;
	kill(pid, sig);
	int st = 0;
	waitpid(pid, &st, 0);
	printf("%s: killed after %.2f s, %lld MB written; exit %s %d, %.2f s after start\n", what,
	       t_kill, w >> 20, WIFSIGNALED(st) ? "signal" : "status",
	       WIFSIGNALED(st) ? WTERMSIG(st) : WEXITSTATUS(st), now_s() - t0);
	return WIFSIGNALED(st) && WTERMSIG(st) == sig;
}

/* Names of the named fallback's temporaries in the directory. */
static int count_named_temporaries(void)
{
	int n = 0;
	DIR *d = opendir(fx_dir);
	for (struct dirent *de; d && (de = readdir(d));)
		n += de->d_name[0] == '.' && strstr(de->d_name, ".kogei-tmp.") != NULL;
	if (d)
		closedir(d);
	return n;
}

int main(int argc, char **argv)
{
	fx_setup(argc, argv);
	const char *cam = fx_path("cam.json"), *small = fx_path("small.tif");
	const char *big = fx_path("big.tif"), *out = fx_path("cube.hdr");
	kg_camera_calib *calib = fx_make_camera(cam);
	kg_image *img = fx_image(64, 48, NULL), *large = NULL;
	kg_err err = {{0}};
	CHECK(calib && img, "fixture");
	CHECK(kg_image_write_tiff(img, small, 32, &err) == 0, "%s", err.msg);
	CHECK(kg_image_new(BIG_W, BIG_H, 3, &large, &err) == 0, "%s", err.msg);
	for (long i = 0; large && i < (long)BIG_W * BIG_H; i++)
		for (int c = 0; c < 3; c++)
			large->data[3 * i + c] = 0.1f + 0.6f * (float)((i * (c + 3)) % 997) / 997.0f;
	CHECK(large && kg_image_write_tiff(large, big, 32, &err) == 0, "%s", err.msg);
	kg_image_free(&large);
	kg_image_free(&img);
	kg_camera_calib_free(&calib);
	if (kg_test_failures)
		return kg_test_done("apply-interrupt");
	CHECK(FX_RUN("estimate", "--calib", cam, small, "-o", out) == 0, "earlier cube: %s",
	      fx_errs);
	entry before[MAX_FILES];
	int nb = snapshot(before);
	CHECK(nb == 7, "%d files before the interrupted runs, expected 7 (cam.json, two images, "
	      "the cube's and the mask's .hdr and .img)", nb);

	static const struct {
		int named, sig;
		const char *what;
	} runs[] = {
		{0, SIGTERM, "O_TMPFILE, SIGTERM"},
		{0, SIGKILL, "O_TMPFILE, SIGKILL"},
		{1, SIGTERM, "named, SIGTERM"},
		{1, SIGINT, "named, SIGINT"},
	};
	for (size_t i = 0; i < sizeof(runs) / sizeof(runs[0]); i++) {
		CHECK(interrupted_run(cam, big, out, runs[i].named, runs[i].sig, runs[i].what),
		      "%s: the process did not die of the signal", runs[i].what);
		CHECK(compare(before, nb, runs[i].what) == 0, "%s: the directory changed",
		      runs[i].what);
	}

	/* SIGKILL of the named fallback: its temporaries stay until the next writer. */
	CHECK(interrupted_run(cam, big, out, 1, SIGKILL, "named, SIGKILL"),
	      "named, SIGKILL: the process did not die of the signal");
	int stale = count_named_temporaries();
	CHECK(stale == 2, "named, SIGKILL: %d temporaries of kogei's pattern, expected the cube's "
	      "and the mask's", stale);
	CHECK(FX_RUN("estimate", "--calib", cam, small, "-o", fx_path("other.hdr")) == 0,
	      "a later estimate: %s", fx_errs);
	CHECK(count_named_temporaries() == 0, "the next writer left %d dead temporaries",
	      count_named_temporaries());
	const char *later[] = {"other.hdr", "other.img", "other_mask.hdr", "other_mask.img"};
	for (int i = 0; i < 4; i++)
		unlink(fx_path(later[i]));
	CHECK(compare(before, nb, "after the next writer") == 0, "the directory changed");

	fx_cleanup();
	return kg_test_done("apply-interrupt");
}
