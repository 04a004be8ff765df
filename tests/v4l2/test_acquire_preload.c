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
#include "mjpeg.h"

#define FAKE_PATH "/dev/video-kogei-fake"
#define FW 160 /* the shim's default sensor */
#define FH 120

/* Run kogei acquire with the shim preloaded (the device's current format `format`, a
 * fourcc; a fault such as "KOGEI_FAKE_V4L2_SHORT_AT=2" in its environment, or NULL),
 * writing into session with the extra arguments; output to log. Returns the
 * exit status, or -1 when it did not exit (killed after 60 s). */
static int run_acquire(const char *kogei, const char *shim, const char *camera,
                       const char *session, const char *format, const char *fault,
                       const char *const *extra, const char *log)
{
	const char *argv[32] = {kogei,     "acquire", "--camera", camera,          "--out",
	                        session,   "--kind",  "chart",    "--frames",      "4",
	                        "--timeout-ms", "300"};
	int n = 12;
	for (int i = 0; extra && extra[i] && n < 31; i++)
		argv[n++] = extra[i];
	argv[n] = NULL;
	pid_t pid = fork();
	if (pid == 0) {
		int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
		if (fd < 0)
			_exit(126);
		dup2(fd, 1);
		dup2(fd, 2);
		setenv("LD_PRELOAD", shim, 1);
		setenv("KOGEI_FAKE_V4L2", FAKE_PATH, 1);
		setenv("KOGEI_FAKE_V4L2_FORMAT", format, 1);
		if (fault)
			putenv((char *)fault);
		/* The sanitizer runtime is linked into kogei, the shim is preloaded before it. */
		const char *asan = getenv("ASAN_OPTIONS");
		char opts[512];
		snprintf(opts, sizeof(opts), "%s%sverify_asan_link_order=0", asan ? asan : "",
		         asan && *asan ? ":" : "");
		setenv("ASAN_OPTIONS", opts, 1);
		alarm(60);
		execv(kogei, (char *const *)argv);
		_exit(127);
	}
	int st;
	if (pid < 0 || waitpid(pid, &st, 0) != pid)
		return -1;
	return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static int run_kogei(const char *kogei, const char *shim, const char *session, int stall,
                     const char *log)
{
	return run_acquire(kogei, shim, "v4l2:" FAKE_PATH, session, "Y16",
	                   stall ? "KOGEI_FAKE_V4L2_STALL=1" : NULL, NULL, log);
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

/* The capture's mean image, read through the manifest (NULL on failure). */
static kg_image *capture_mean(const char *session, const json_t *cap)
{
	const char *file = json_string_value(
	    json_object_get(json_object_get(json_object_get(cap, "outputs"), "mean"), "file"));
	char path[4096];
	snprintf(path, sizeof(path), "%s/%.2000s", session, file ? file : "(none)");
	kg_image *img = NULL;
	kg_err err = {{0}};
	CHECK(kg_image_read(path, &img, &err) == 0, "mean image %s: %s", path, err.msg);
	return img;
}

/* MJPEG from a UVC-style device: refused unless forced; forced, the mean of the decoded
 * frames is the average of what the device encoded (within JPEG's loss), and replaying
 * the recorded JPEG bytes gives the same mean to the bit. */
static void test_mjpeg(const char *kogei, const char *shim, const char *dir)
{
	char session[512], log[512], replayed[512];
	snprintf(session, sizeof(session), "%s/mjpeg", dir);
	snprintf(replayed, sizeof(replayed), "%s/mjpeg-replayed", dir);
	snprintf(log, sizeof(log), "%s/log-mjpeg", dir);
	const char *plain[] = {"--format", "mjpeg", NULL};
	int rc = run_acquire(kogei, shim, "v4l2:" FAKE_PATH, session, "MJPG", NULL, plain, log);
	char *text = slurp(log);
	CHECK(rc == 1 && text && strstr(text, "mjpeg") && strstr(text, "--force-nonlinear"),
	      "MJPEG unforced: exit %d:\n%s", rc, text ? text : "");
	free(text);

	const char *forced[] = {"--format", "mjpeg", "--force-nonlinear", NULL};
	rc = run_acquire(kogei, shim, "v4l2:" FAKE_PATH, session, "MJPG", NULL, forced, log);
	text = slurp(log);
	if (!kg_mjpeg_available()) {
		CHECK(rc == 1 && text && strstr(text, "without libjpeg"),
		      "MJPEG forced without libjpeg: exit %d:\n%s", rc, text ? text : "");
		free(text);
		return;
	}
	CHECK(rc == 0, "MJPEG forced: exit %d:\n%s", rc, text ? text : "");
	free(text);
	if (rc)
		return;
	kg_err err = {{0}};
	kg_session *s = NULL;
	CHECK(kg_session_open(session, &s, &err) == 0 && kg_session_verify(s, NULL, &err) == 0,
	      "MJPEG session: %s", err.msg);
	if (!s)
		return;
	const json_t *cap = json_array_get(json_object_get(kg_session_manifest(s), "captures"), 0);
	const char *pixfmt = json_string_value(json_object_get(
	    json_object_get(json_object_get(cap, "settings"), "format"), "pixfmt"));
	CHECK(pixfmt && !strcmp(pixfmt, "mjpeg") &&
	          json_is_true(json_object_get(json_object_get(cap, "settings"), "force_nonlinear")),
	      "manifest: format %s, force_nonlinear recorded", pixfmt ? pixfmt : "(none)");
	const json_t *frames = json_object_get(cap, "frames");
	CHECK(json_array_size(frames) == 4, "%zu MJPEG frames", json_array_size(frames));
	double *want = calloc((size_t)FW * FH * 3, sizeof(double));
	size_t k;
	const json_t *fr;
	json_array_foreach(frames, k, fr)
	{
		long seq = (long)json_integer_value(json_object_get(fr, "sequence"));
		for (int y = 0; y < FH; y++)
			for (int x = 0; x < FW; x++) {
				uint8_t rgb[3];
				fake_v4l2_smooth_rgb(x, y, (uint32_t)seq, rgb);
				for (int c = 0; c < 3; c++)
					want[((size_t)y * FW + x) * 3 + c] += rgb[c] / 255.0 / 4;
			}
	}
	char name[128];
	snprintf(name, sizeof(name), "%s", json_string_value(json_object_get(cap, "name")));
	kg_image *mean = capture_mean(session, cap);
	kg_session_free(&s);
	CHECK(mean && mean->width == FW && mean->height == FH && mean->channels == 3,
	      "MJPEG mean: %dx%dx%d", mean ? mean->width : 0, mean ? mean->height : 0,
	      mean ? mean->channels : 0);
	if (mean && mean->width == FW && mean->height == FH && mean->channels == 3) {
		double worst = 0, sum = 0;
		for (size_t i = 0; i < (size_t)FW * FH * 3; i++) {
			double d = fabs(mean->data[i] - want[i]) * 255;
			worst = fmax(worst, d);
			sum += d;
		}
		sum /= (double)FW * FH * 3;
		CHECK(worst <= 12 && sum <= 1.5,
		      "MJPEG mean within %.2f levels of the encoded frames' (mean %.3f): expected "
		      "<= 12 (mean <= 1.5)",
		      worst, sum);
		printf("MJPEG: forced capture of 4 frames within %.2f levels (mean %.3f) of the "
		       "encoded pattern\n",
		       worst, sum);
	}
	free(want);

	/* The recorded JPEG bytes replay to the same mean, bit for bit. */
	char camera[1200];
	snprintf(camera, sizeof(camera), "replay:%s#%s", session, name);
	const char *again[] = {"--force-nonlinear", NULL};
	rc = run_acquire(kogei, shim, camera, replayed, "MJPG", NULL, again, log);
	text = slurp(log);
	CHECK(rc == 0, "MJPEG replay: exit %d:\n%s", rc, text ? text : "");
	free(text);
	s = NULL;
	if (!rc && kg_session_open(replayed, &s, &err) == 0) {
		kg_image *m2 = capture_mean(
		    replayed, json_array_get(json_object_get(kg_session_manifest(s), "captures"), 0));
		CHECK(m2 && mean && m2->width == mean->width && m2->height == mean->height &&
		          m2->channels == mean->channels &&
		          !memcmp(m2->data, mean->data,
		                  sizeof(float) * (size_t)FW * FH * (size_t)mean->channels),
		      "the replayed MJPEG capture's mean differs from the original's");
		kg_image_free(&m2);
	}
	kg_session_free(&s);
	kg_image_free(&mean);
}

/* Damaged frames end a capture with exit 3, the counts, and nothing of it in the
 * session: a frame the driver flags as erroneous, one that arrives short, and (forced
 * MJPEG) a truncated JPEG. The session's earlier capture stays as it was. */
static void test_damaged(const char *kogei, const char *shim, const char *dir)
{
	char session[512], log[512], manifest[600], index[600], before[1 << 14], after[1 << 14];
	char before_index[1 << 14], after_index[1 << 14];
	snprintf(session, sizeof(session), "%s/damaged", dir);
	snprintf(log, sizeof(log), "%s/log-damaged", dir);
	snprintf(manifest, sizeof(manifest), "%s/session.json", session);
	snprintf(index, sizeof(index), "%s/frames/index.jsonl", session);
	int rc = run_acquire(kogei, shim, "v4l2:" FAKE_PATH, session, "Y16", NULL, NULL, log);
	CHECK(rc == 0, "first capture: exit %d", rc);
	char *m = slurp(manifest), *ix = slurp(index);
	snprintf(before, sizeof(before), "%s", m ? m : "");
	snprintf(before_index, sizeof(before_index), "%s", ix ? ix : "");
	free(m);
	free(ix);
	static const struct {
		const char *fault, *format, *needle;
	} cases[] = {
		{"KOGEI_FAKE_V4L2_ERROR_AT=2", "Y16", "1 failed"},
		{"KOGEI_FAKE_V4L2_SHORT_AT=3", "Y16", "1 incomplete"},
		{"KOGEI_FAKE_V4L2_SHORT_AT=2", "MJPG", "damaged"},
	};
	const char *mjpeg[] = {"--format", "mjpeg", "--force-nonlinear", NULL};
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		int jpeg = !strcmp(cases[i].format, "MJPG");
		if (jpeg && !kg_mjpeg_available())
			continue;
		rc = run_acquire(kogei, shim, "v4l2:" FAKE_PATH, session, cases[i].format,
		                 cases[i].fault, jpeg ? mjpeg : NULL, log);
		char *text = slurp(log);
		CHECK(rc == 3 && text && strstr(text, cases[i].needle) &&
		          strstr(text, "nothing of it was added"),
		      "%s (%s): exit %d, expected 3 naming '%s':\n%s", cases[i].fault, cases[i].format,
		      rc, cases[i].needle, text ? text : "");
		free(text);
		m = slurp(manifest);
		ix = slurp(index);
		snprintf(after, sizeof(after), "%s", m ? m : "");
		snprintf(after_index, sizeof(after_index), "%s", ix ? ix : "");
		free(m);
		free(ix);
		CHECK(!strcmp(before, after), "%s: session.json changed", cases[i].fault);
		CHECK(!strcmp(before_index, after_index), "%s: frames/index.jsonl changed",
		      cases[i].fault);
	}
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

	test_mjpeg(kogei, shim, dir);
	test_damaged(kogei, shim, dir);

	char cmd[300];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
	if (system(cmd) != 0)
		fprintf(stderr, "could not remove %s\n", dir);
	return kg_test_done("v4l2-acquire-preload");
}
