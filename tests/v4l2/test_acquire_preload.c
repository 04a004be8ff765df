/* End to end: the real `kogei acquire` records from the fake V4L2 device served by the
 * LD_PRELOAD shim (fake_video_preload.so), and the session holds the device's bytes.
 *
 *   kogei acquire --camera v4l2:/dev/video-kogei-fake --out S --kind chart --frames 4
 *
 * must exit 0; the session verifies (every file's sha256); its one capture lists 4
 * frames whose raw bytes are exactly the device's Y16 frames (fake_v4l2_sample at
 * the sequence numbers in frames/index.jsonl), and its mean.tif is their average on
 * the 0..1 scale. A device that never delivers must give exit 3, a message with the
 * counts, and no capture in the session.
 *
 * usage: test_acquire_preload KOGEI SHIM */
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "fake_v4l2.h"
#include "kg_acquire.h"
#include "kg_test.h"

#define FAKE_PATH "/dev/video-kogei-fake"
#define FW 160 /* the shim's default sensor */
#define FH 120

/* Run kogei with the shim preloaded; output to log. Returns the exit status, or -1 when
 * it did not exit (killed after 60 s). */
static int run_kogei(const char *kogei, const char *shim, const char *session, int stall,
                     const char *log)
{
	pid_t pid = fork();
	if (pid == 0) {
		int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
		if (fd < 0)
			_exit(126);
		dup2(fd, 1);
		dup2(fd, 2);
		setenv("LD_PRELOAD", shim, 1);
		setenv("KOGEI_FAKE_V4L2", FAKE_PATH, 1);
		setenv("KOGEI_FAKE_V4L2_FORMAT", "Y16", 1);
		if (stall)
			setenv("KOGEI_FAKE_V4L2_STALL", "1", 1);
		/* The sanitizer runtime is linked into kogei, the shim is preloaded before it. */
		const char *asan = getenv("ASAN_OPTIONS");
		char opts[512];
		snprintf(opts, sizeof(opts), "%s%sverify_asan_link_order=0", asan ? asan : "",
		         asan && *asan ? ":" : "");
		setenv("ASAN_OPTIONS", opts, 1);
		alarm(60);
		execl(kogei, kogei, "acquire", "--camera", "v4l2:" FAKE_PATH, "--out", session,
		      "--kind", "chart", "--frames", "4", "--timeout-ms", "300", (char *)NULL);
		_exit(127);
	}
	int st;
	if (pid < 0 || waitpid(pid, &st, 0) != pid)
		return -1;
	return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static char *slurp(const char *path)
{
	char *buf = NULL;
	size_t len;
	kg_err err;
	return kg_read_file(path, &buf, &len, &err) ? NULL : buf;
}

/* The sequence number index.jsonl records for a frame file, or -1. */
static long sequence_of(const char *session, const char *file)
{
	char path[4096];
	snprintf(path, sizeof(path), "%s/frames/index.jsonl", session);
	char *text = slurp(path);
	long seq = -1;
	for (char *line = text ? strtok(text, "\n") : NULL; line && seq < 0;
	     line = strtok(NULL, "\n")) {
		json_t *o = json_loads(line, 0, NULL);
		const char *f = json_string_value(json_object_get(o, "file"));
		if (f && !strcmp(f, file))
			seq = (long)json_integer_value(json_object_get(o, "sequence"));
		json_decref(o);
	}
	free(text);
	return seq;
}

static void check_session(const char *session)
{
	kg_err err = {{0}};
	kg_session *s = NULL;
	int ret = kg_session_open(session, &s, &err);
	CHECK(ret == 0, "session: %s", err.msg);
	if (ret)
		return;
	long nfiles = 0;
	CHECK(kg_session_verify(s, &nfiles, &err) == 0 && nfiles >= 5, "verify (%ld files): %s",
	      nfiles, err.msg);
	const json_t *caps = json_object_get(kg_session_manifest(s), "captures");
	CHECK(json_array_size(caps) == 1, "%zu captures", json_array_size(caps));
	const json_t *cap = json_array_get(caps, 0);
	const json_t *frames = json_object_get(cap, "frames");
	CHECK(json_array_size(frames) == 4, "%zu frames", json_array_size(frames));

	/* The mean the session should hold: the device's frames averaged. */
	double *sum = calloc((size_t)FW * FH, sizeof(double));
	size_t k;
	const json_t *fr;
	json_array_foreach(frames, k, fr)
	{
		const char *file = json_string_value(json_object_get(fr, "file"));
		long seq = file ? sequence_of(session, file) : -1;
		CHECK(seq >= 0, "frame %zu (%s) not in frames/index.jsonl", k, file ? file : "?");
		if (seq < 0)
			continue;
		char path[4096];
		snprintf(path, sizeof(path), "%s/%.2000s", session, file);
		char *raw = NULL;
		size_t len = 0;
		CHECK(kg_read_file(path, &raw, &len, &err) == 0 && len == (size_t)FW * FH * 2,
		      "%s: %zu bytes, expected %d: %s", path, len, FW * FH * 2, err.msg);
		if (len != (size_t)FW * FH * 2) {
			free(raw);
			continue;
		}
		const uint8_t *b = (const uint8_t *)raw;
		int bad = 0;
		for (int y = 0; y < FH; y++)
			for (int x = 0; x < FW; x++) {
				size_t i = (size_t)y * FW + x;
				uint32_t want = fake_v4l2_sample(x, y, 0, (uint32_t)seq, 16);
				uint32_t got = (uint32_t)(b[2 * i] | b[2 * i + 1] << 8);
				bad += got != want;
				sum[i] += want / 65535.0;
			}
		CHECK(!bad, "%s: %d samples differ from the device's frame %ld", path, bad, seq);
		free(raw);
	}
	const char *mean_file =
	    json_string_value(json_object_get(json_object_get(json_object_get(cap, "outputs"),
	                                                      "mean"),
	                                      "file"));
	char path[4096];
	snprintf(path, sizeof(path), "%s/%.2000s", session, mean_file ? mean_file : "(none)");
	kg_image *mean = NULL;
	ret = kg_image_read(path, &mean, &err);
	CHECK(ret == 0 && mean->width == FW && mean->height == FH && mean->channels == 1,
	      "mean image %s: %s", path, err.msg);
	if (!ret && mean->width == FW && mean->height == FH) {
		double worst = 0;
		for (size_t i = 0; i < (size_t)FW * FH; i++)
			worst = fmax(worst, fabs(mean->data[i] - sum[i] / 4));
		CHECK(worst < 1e-6, "mean differs from the frames' average by %g", worst);
	}
	kg_image_free(&mean);
	free(sum);
	kg_session_free(&s);
}

int main(int argc, char **argv)
{
	if (argc != 3) {
		fprintf(stderr, "usage: %s KOGEI SHIM\n", argv[0]);
		return 2;
	}
	/* Absolute paths: the shim is preloaded by path. */
	char kogei[4096], shim[4096];
	if (!realpath(argv[1], kogei) || !realpath(argv[2], shim)) {
		fprintf(stderr, "%s or %s: not found\n", argv[1], argv[2]);
		return 1;
	}
	char dir[] = "/tmp/kogei-v4l2-XXXXXX";
	if (!mkdtemp(dir))
		return 1;
	char session[256], log[512];
	snprintf(session, sizeof(session), "%s/session", dir);
	snprintf(log, sizeof(log), "%s/log", dir);

	int rc = run_kogei(kogei, shim, session, 0, log);
	char *text = slurp(log);
	CHECK(rc == 0, "kogei acquire exit %d:\n%s", rc, text ? text : "");
	free(text);
	if (rc == 0)
		check_session(session);

	/* A device that never delivers: exit 3 with the counts, nothing captured. */
	char stalled[256];
	snprintf(stalled, sizeof(stalled), "%s/stalled", dir);
	rc = run_kogei(kogei, shim, stalled, 1, log);
	text = slurp(log);
	CHECK(rc == 3 && text && strstr(text, "no frame within 300 ms") &&
	          strstr(text, "0 complete") && strstr(text, "v4l2:" FAKE_PATH),
	      "stalled device: exit %d:\n%s", rc, text ? text : "");
	free(text);
	snprintf(log, sizeof(log), "%s/session.json", stalled);
	json_t *root = NULL;
	kg_err err;
	if (!kg_json_load(log, &root, &err))
		CHECK(json_array_size(json_object_get(root, "captures")) == 0,
		      "a failed capture entered the manifest");
	json_decref(root);

	char cmd[300];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
	if (system(cmd) != 0)
		fprintf(stderr, "could not remove %s\n", dir);
	return kg_test_done("v4l2-acquire-preload");
}
