/* End to end over GigE Vision with recorded frames: this process serves Aravis' fake
 * GigE Vision camera on 127.0.0.1 (with tests/aravis/kogei-gv-camera.xml) and injects,
 * through its fill callback, the raw frames of a 16-bit capture of the bundled
 * recorded session (fixtures/demo/session: the first mono16 or 16-bit bayer16 capture
 * of frames/index.jsonl, each file checked against its sha256), one after the other,
 * round and round. A child process runs
 *   kogei acquire --camera aravis:127.0.0.1 --out S --kind chart --frames N --format mono16
 * The fake serves Mono16, so a Bayer mosaic is sent as it was recorded, its 16-bit
 * words unchanged, labelled Mono16 (no sample is converted).
 *
 * Checked in the session kogei wrote: every recorded .raw is the frame injected for it
 * byte for byte (and its sha256, in the manifest and the index, the fixture's), in the
 * order the camera sent them (sequence = the fake's frame ids, none dropped); the format
 * and settings (exposure and gain as the recording had them, auto white balance off,
 * gain in dB) and clean stream counters; the mean image (float32 TIFF, its sha256 in the
 * manifest) equals the average of the injected frames on 0..1 of 65535 (to the last bit
 * of float32, the rounding of kogei's running mean), the variance image the (n - 1)
 * variance, and the manifest's min and max those of that mean; then
 *   kogei acquire --camera replay:S ...
 * reproduces the mean, the variance and every raw frame bit for bit.
 * usage (inside netns.sh): test_acquire_injected KOGEI GENICAM.xml */
#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <math.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <arv.h>

#include "camera_driver.h"
#include "image.h"
#include "json.h"
#include "aravis_inject.h"
#include "kg_camera.h"
#include "kg_test.h"

extern char **environ;

#define NFRAMES 4
#define MAXREC 8
#define MAXFILLS 4096
#define SERIAL "KGREC1"

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int read_all(const char *path, uint8_t **data, size_t *size)
{
	FILE *f = fopen(path, "rb");
	if (!f)
		return -1;
	size_t cap = 1 << 16, n = 0;
	uint8_t *b = malloc(cap);
	size_t got;
	while (b && (got = fread(b + n, 1, cap - n, f)) > 0) {
		n += got;
		if (n == cap) {
			uint8_t *nb = realloc(b, cap *= 2);
			if (!nb)
				free(b);
			b = nb;
		}
	}
	int bad = ferror(f) || !b;
	fclose(f);
	if (bad) {
		free(b);
		return -1;
	}
	*data = b;
	*size = n;
	return 0;
}

static int same_files(const char *a, const char *b)
{
	uint8_t *da = NULL, *db = NULL;
	size_t na = 0, nb = 0;
	int ok = !read_all(a, &da, &na) && !read_all(b, &db, &nb) && na == nb && !memcmp(da, db, na);
	free(da);
	free(db);
	return ok;
}

static int file_sha256(const char *path, char hex[65])
{
	uint8_t *d = NULL;
	size_t n = 0;
	hex[0] = 0;
	if (read_all(path, &d, &n))
		return -1;
	int ret = kg_frame_sha256(d, n, hex);
	free(d);
	return ret;
}

/* ---- the recording ------------------------------------------------------------ */

typedef struct recording {
	char session[1024];
	char capture[64];
	int n;
	kg_frame_format fmt;
	uint8_t *frame[MAXREC];
	char sha[MAXREC][65];
	double exposure_us, gain;
} recording;

/* The first capture of the index whose frames are mono16 or bayer16 with 16 bits and
 * that has at least two frames; each frame read and checked against its sha256. */
static int load_recording(const char *session, recording *rec)
{
	char path[4096];
	snprintf(path, sizeof(path), "%s/frames/index.jsonl", session);
	FILE *f = fopen(path, "r");
	if (!f)
		return -1;
	char line[8192];
	memset(rec, 0, sizeof(*rec));
	char best[64] = "";
	while (fgets(line, sizeof(line), f)) {
		json_t *o = json_loads(line, 0, NULL);
		const char *cap = json_string_value(json_object_get(o, "capture"));
		const char *pf = json_string_value(kg_json_find(o, "format.pixfmt"));
		json_int_t bits = json_integer_value(kg_json_find(o, "format.bits"));
		int fits = cap && pf && (!strcmp(pf, "mono16") || !strcmp(pf, "bayer16")) && bits == 16;
		if (fits && (!best[0] || !strcmp(best, cap)) && rec->n < MAXREC) {
			kg_err err = {{0}};
			const char *file = json_string_value(json_object_get(o, "file"));
			const char *sha = json_string_value(json_object_get(o, "sha256"));
			kg_frame_format fmt;
			if (file && sha && strlen(sha) == 64 &&
			    !kg_frame_format_from_json(path, json_object_get(o, "format"), &fmt, &err)) {
				char fp[4096];
				snprintf(fp, sizeof(fp), "%s/%s", session, file);
				uint8_t *d = NULL;
				size_t n = 0;
				char got[65];
				if (!read_all(fp, &d, &n) && n == fmt.size && !kg_frame_sha256(d, n, got) &&
				    !strcmp(got, sha) && (!rec->n || fmt.size == rec->fmt.size)) {
					snprintf(best, sizeof(best), "%s", cap);
					rec->fmt = fmt;
					rec->frame[rec->n] = d;
					snprintf(rec->sha[rec->n], 65, "%s", sha);
					rec->exposure_us = json_number_value(json_object_get(o, "exposure_us"));
					rec->gain = json_number_value(json_object_get(o, "gain"));
					rec->n++;
				} else {
					fprintf(stderr, "%s: not as its index line says (%zu bytes)\n", fp, n);
					free(d);
				}
			}
		}
		json_decref(o);
	}
	fclose(f);
	snprintf(rec->capture, sizeof(rec->capture), "%s", best);
	snprintf(rec->session, sizeof(rec->session), "%s", session);
	return rec->n >= 2 ? 0 : -1;
}

/* ---- the camera --------------------------------------------------------------- */

typedef struct server {
	ArvFakeCamera *fake;
	const recording *rec;
	GMutex lock;
	int nfills;
	int which[MAXFILLS];    /* recorded frame injected by fill i */
	guint64 id[MAXFILLS];   /* the fake's frame id for it */
	int wrong_size;         /* fills whose frame size was not the recording's */
	guint32 pf;             /* pixel format of the last fill */
} server;

static void fill(ArvBuffer *b, void *user, guint32 exposure_us, guint32 gain, ArvPixelFormat pf)
{
	(void)exposure_us;
	(void)gain;
	server *s = user;
	size_t size = inject_frame_size(s->fake, pf);
	uint8_t *data = (uint8_t *)arv_buffer_get_data(b, NULL);
	g_mutex_lock(&s->lock);
	int i = s->nfills++;
	int k = i % s->rec->n;
	if (i < MAXFILLS) {
		s->which[i] = k;
		s->id[i] = arv_buffer_get_frame_id(b);
	}
	s->pf = (guint32)pf;
	if (size == s->rec->fmt.size)
		memcpy(data, s->rec->frame[k], size);
	else {
		memset(data, 0, size);
		s->wrong_size++;
	}
	g_mutex_unlock(&s->lock);
}

/* ---- kogei as a child ------------------------------------------------------------ */

/* Run argv with stdout and stderr to log; its exit status, or -1 (killed after
 * timeout_s, or not started). */
static int run(char *const argv[], const char *log, double timeout_s, double *took)
{
	posix_spawn_file_actions_t fa;
	posix_spawn_file_actions_init(&fa);
	posix_spawn_file_actions_addopen(&fa, 1, log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
	posix_spawn_file_actions_adddup2(&fa, 1, 2);
	pid_t pid;
	double t0 = now_s();
	int ret = posix_spawn(&pid, argv[0], &fa, NULL, argv, environ);
	posix_spawn_file_actions_destroy(&fa);
	if (ret) {
		fprintf(stderr, "cannot start %s: %s\n", argv[0], strerror(ret));
		return -1;
	}
	int status = 0;
	for (;;) {
		pid_t r = waitpid(pid, &status, WNOHANG);
		if (r == pid)
			break;
		if (r < 0 && errno != EINTR)
			return -1;
		if (now_s() - t0 > timeout_s) {
			fprintf(stderr, "%s did not finish in %.0f s: killed\n", argv[0], timeout_s);
			kill(pid, SIGKILL);
			waitpid(pid, &status, 0);
			return -1;
		}
		usleep(20000);
	}
	*took = now_s() - t0;
	return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

static void print_file(const char *path)
{
	uint8_t *d = NULL;
	size_t n = 0;
	if (!read_all(path, &d, &n))
		fprintf(stderr, "---- %s\n%.*s----\n", path, (int)n, (const char *)d);
	free(d);
}

static int rm_one(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
	(void)st;
	(void)flag;
	(void)ftw;
	return remove(path);
}

/* ---- checks ------------------------------------------------------------------- */

/* Distance in float32 steps. */
static long ulps(float a, float b)
{
	int32_t ia, ib;
	memcpy(&ia, &a, 4);
	memcpy(&ib, &b, 4);
	if (ia < 0)
		ia = INT32_MIN - ia;
	if (ib < 0)
		ib = INT32_MIN - ib;
	return labs((long)ia - (long)ib);
}

typedef struct expect {
	float *mean, *var;
	float min, max;
} expect;

/* The average and (n - 1) variance, on 0..1 of full scale, of the frames kogei was
 * sent (in double, exactly: sums of 16-bit integers). */
static int expected_images(const recording *rec, const server *srv, int first, expect *e)
{
	size_t n = (size_t)rec->fmt.width * (size_t)rec->fmt.height;
	e->mean = malloc(n * sizeof(float));
	e->var = malloc(n * sizeof(float));
	if (!e->mean || !e->var)
		return -1;
	double full = 65535.0;
	e->min = INFINITY;
	e->max = -INFINITY;
	for (size_t i = 0; i < n; i++) {
		double sum = 0, sum2 = 0;
		for (int k = 0; k < NFRAMES; k++) {
			const uint8_t *d = rec->frame[srv->which[first + k]];
			double x = (double)(d[2 * i] | d[2 * i + 1] << 8);
			sum += x;
			sum2 += x * x;
		}
		double m = sum / NFRAMES;
		double ss = sum2 - sum * sum / NFRAMES; /* exact: integers below 2^53 */
		e->mean[i] = (float)(m / full);
		e->var[i] = (float)(ss / (NFRAMES - 1) / (full * full));
		if (e->mean[i] < e->min)
			e->min = e->mean[i];
		if (e->mean[i] > e->max)
			e->max = e->mean[i];
	}
	return 0;
}

static void check_image(const char *what, const char *path, const float *want, int w, int h,
                        int mean)
{
	kg_err err = {{0}};
	kg_image *img = NULL;
	int ret = kg_image_read(path, &img, &err);
	CHECK(ret == 0, "%s: %s", what, err.msg);
	if (ret)
		return;
	CHECK(img->width == w && img->height == h && img->channels == 1 && img->is_float,
	      "%s: %dx%d x %d, float %d", what, img->width, img->height, img->channels,
	      img->is_float);
	if (img->width != w || img->height != h || img->channels != 1) {
		kg_image_free(&img);
		return;
	}
	size_t n = (size_t)w * h, exact = 0;
	long worst = 0;
	double worst_rel = 0;
	for (size_t i = 0; i < n; i++) {
		long u = ulps(img->data[i], want[i]);
		exact += u == 0;
		if (u > worst)
			worst = u;
		double rel = fabs((double)img->data[i] - want[i]) / (fabs(want[i]) + 1e-30);
		if (want[i] != 0 && rel > worst_rel)
			worst_rel = rel;
	}
	printf("%s: %zu of %zu samples exactly as expected; largest difference %ld float32 "
	       "step(s), relative %.2g\n",
	       what, exact, n, worst, worst_rel);
	/* kogei keeps a running mean (Welford) in double: a sample may round to the
	 * neighbouring float32; the variance is accumulated from that mean. */
	if (mean)
		CHECK(worst <= 1, "%s: a sample is %ld float32 steps from the average", what, worst);
	else
		CHECK(worst_rel <= 1e-6, "%s: relative error %.3g", what, worst_rel);
	kg_image_free(&img);
}

static double num(const json_t *root, const char *path)
{
	const json_t *v = kg_json_find(root, path);
	return json_is_number(v) ? json_number_value(v) : NAN;
}

static const char *str(const json_t *root, const char *path)
{
	const char *v = json_string_value(kg_json_find(root, path));
	return v ? v : "";
}

/* The recorded session's own manifest averaged the same frames (each of them equally
 * often here, when NFRAMES is a multiple of their number) without corrections: its
 * statistics of the mean must be ours. */
static void check_against_recording(const recording *rec, const json_t *cap)
{
	char path[1100];
	snprintf(path, sizeof(path), "%s/session.json", rec->session);
	json_t *root = NULL;
	kg_err err = {{0}};
	if (NFRAMES % rec->n || kg_json_load(path, &root, &err)) {
		printf("statistics not compared with the recording's: %s\n",
		       NFRAMES % rec->n ? "frame counts differ" : err.msg);
		return;
	}
	const json_t *caps = json_object_get(root, "captures"), *rc = NULL;
	for (size_t i = 0; i < json_array_size(caps) && !rc; i++)
		if (!strcmp(str(json_array_get(caps, i), "name"), rec->capture))
			rc = json_array_get(caps, i);
	if (rc && num(rc, "settings.frames") == rec->n && json_is_null(kg_json_find(rc, "corrections.dark")) &&
	    json_is_null(kg_json_find(rc, "corrections.flat"))) {
		static const char *const keys[] = {"statistics.min", "statistics.max",
		                                   "statistics.percentiles.p50",
		                                   "statistics.percentiles.p99"};
		for (size_t i = 0; i < sizeof(keys) / sizeof(keys[0]); i++)
			CHECK(ulps((float)num(cap, keys[i]), (float)num(rc, keys[i])) <= 1,
			      "%s: %.9g over GigE Vision, %.9g in the recorded session", keys[i],
			      num(cap, keys[i]), num(rc, keys[i]));
		printf("statistics (min, max, p50, p99) as in the recorded session's manifest\n");
	} else {
		printf("statistics not compared: the recorded capture %s is not a plain average of "
		       "its %d frames\n", rec->capture, rec->n);
	}
	json_decref(root);
}

/* The fake's frame ids count 1..65535 and wrap to 1; kogei's sequence does not wrap. */
static guint64 wrap_id(guint64 seq)
{
	return (seq - 1) % 65535 + 1;
}

static void check_session(const char *S, const recording *rec, const server *srv, expect *e)
{
	kg_err err = {{0}};
	char path[4096];
	snprintf(path, sizeof(path), "%s/session.json", S);
	json_t *root = NULL;
	int ret = kg_json_load(path, &root, &err);
	CHECK(ret == 0, "%s", err.msg);
	if (ret)
		return;
	CHECK(!strcmp(str(root, "devices.cameras[0].transport"), "GigE Vision") &&
	          !strcmp(str(root, "devices.cameras[0].serial"), SERIAL) &&
	          !strcmp(str(root, "devices.cameras[0].uri"), "aravis:127.0.0.1"),
	      "session camera: transport '%s' serial '%s' uri '%s'",
	      str(root, "devices.cameras[0].transport"), str(root, "devices.cameras[0].serial"),
	      str(root, "devices.cameras[0].uri"));
	const json_t *cap = kg_json_find(root, "captures[0]");
	CHECK(cap && !strcmp(str(cap, "name"), "chart-0001") && !strcmp(str(cap, "kind"), "chart") &&
	          json_is_true(json_object_get(cap, "recorded")),
	      "capture: name '%s' kind '%s'", str(cap, "name"), str(cap, "kind"));
	int w = rec->fmt.width, h = rec->fmt.height;
	CHECK(!strcmp(str(cap, "settings.format.pixfmt"), "mono16") &&
	          num(cap, "settings.format.bits") == 16 && num(cap, "settings.format.width") == w &&
	          num(cap, "settings.format.height") == h &&
	          num(cap, "settings.format.stride") == 2.0 * w && num(cap, "settings.frames") == NFRAMES,
	      "capture format: %s %g bits %gx%g stride %g, %g frames", str(cap, "settings.format.pixfmt"),
	      num(cap, "settings.format.bits"), num(cap, "settings.format.width"),
	      num(cap, "settings.format.height"), num(cap, "settings.format.stride"),
	      num(cap, "settings.frames"));
	/* The camera's own settings, which the recording was made with. */
	CHECK(num(cap, "settings.exposure_us") == rec->exposure_us &&
	          num(cap, "settings.gain") == rec->gain && !strcmp(str(cap, "settings.gain_unit"), "dB") &&
	          num(cap, "settings.auto_exposure") == 0 && num(cap, "settings.auto_white_balance") == 0 &&
	          num(cap, "settings.wb_red") == 1 && num(cap, "settings.wb_blue") == 1,
	      "capture settings: exposure %g us (recorded %g) gain %g %s (recorded %g) auto %g/%g "
	      "wb %g/%g",
	      num(cap, "settings.exposure_us"), rec->exposure_us, num(cap, "settings.gain"),
	      str(cap, "settings.gain_unit"), rec->gain, num(cap, "settings.auto_exposure"),
	      num(cap, "settings.auto_white_balance"), num(cap, "settings.wb_red"),
	      num(cap, "settings.wb_blue"));
	CHECK(num(cap, "statistics.stream.completed") == NFRAMES &&
	          num(cap, "statistics.stream.dropped") == 0 &&
	          num(cap, "statistics.stream.incomplete") == 0 &&
	          num(cap, "statistics.stream.failed") == 0 &&
	          num(cap, "statistics.stream.timeouts") == 0 &&
	          num(cap, "statistics.stream.missing_packets") == 0,
	      "stream: completed %g dropped %g incomplete %g failed %g timeouts %g missing %g",
	      num(cap, "statistics.stream.completed"), num(cap, "statistics.stream.dropped"),
	      num(cap, "statistics.stream.incomplete"), num(cap, "statistics.stream.failed"),
	      num(cap, "statistics.stream.timeouts"), num(cap, "statistics.stream.missing_packets"));

	/* The frames: which fill the first one was, from its sequence (the fake's id). */
	const json_t *frames = json_object_get(cap, "frames");
	CHECK(json_array_size(frames) == NFRAMES, "%zu frames in the manifest",
	      json_array_size(frames));
	double seq0 = num(cap, "frames[0].sequence");
	int first = -1;
	for (int i = 0; i < srv->nfills && i < MAXFILLS && first < 0 && isfinite(seq0); i++)
		if (srv->id[i] == wrap_id((guint64)seq0))
			first = i;
	CHECK(first == 0, "kogei's first frame (sequence %.0f) was fill %d of %d, expected the "
	      "first one", seq0, first, srv->nfills);
	CHECK(srv->nfills >= NFRAMES && !srv->wrong_size && srv->pf == ARV_PIXEL_FORMAT_MONO_16,
	      "the fake filled %d frames, %d of a size other than %zu bytes, last as 0x%08x",
	      srv->nfills, srv->wrong_size, rec->fmt.size, srv->pf);
	if (first < 0 || first + NFRAMES > srv->nfills || first + NFRAMES > MAXFILLS) {
		json_decref(root);
		return;
	}

	/* The index kogei appended: one line per frame, in order. */
	snprintf(path, sizeof(path), "%s/frames/index.jsonl", S);
	FILE *idx = fopen(path, "r");
	CHECK(idx != NULL, "%s: %s", path, strerror(errno));
	char line[8192];
	int nlines = 0;
	for (int i = 0; i < NFRAMES; i++) {
		const json_t *fr = json_array_get(frames, (size_t)i);
		int k = srv->which[first + i];
		const char *file = str(fr, "file");
		const char *sha = str(fr, "sha256");
		char want_file[64];
		snprintf(want_file, sizeof(want_file), "frames/chart-0001/%06d.raw", i + 1);
		CHECK(!strcmp(file, want_file), "frame %d: file '%s'", i, file);
		CHECK(num(fr, "sequence") == seq0 + i &&
		          srv->id[first + i] == wrap_id((guint64)(seq0 + i)),
		      "frame %d: sequence %g, the fake sent id %llu", i, num(fr, "sequence"),
		      (unsigned long long)srv->id[first + i]);
		/* The bytes on disk: the injected recorded frame, exactly. */
		char fp[4096], got_sha[65];
		snprintf(fp, sizeof(fp), "%s/%s", S, file);
		uint8_t *d = NULL;
		size_t n = 0;
		int rd = read_all(fp, &d, &n);
		CHECK(!rd && n == rec->fmt.size && !memcmp(d, rec->frame[k], n),
		      "frame %d (%s): %zu bytes, not recorded frame %d of %s byte for byte", i, fp, n,
		      k + 1, rec->capture);
		file_sha256(fp, got_sha);
		CHECK(!strcmp(sha, rec->sha[k]) && !strcmp(got_sha, rec->sha[k]),
		      "frame %d: manifest sha256 %s, file %s, recorded %s", i, sha, got_sha, rec->sha[k]);
		free(d);
		json_t *o = NULL;
		if (idx && fgets(line, sizeof(line), idx))
			o = json_loads(line, 0, NULL);
		nlines += o != NULL;
		CHECK(o && !strcmp(str(o, "file"), want_file) && !strcmp(str(o, "sha256"), rec->sha[k]) &&
		          !strcmp(str(o, "capture"), "chart-0001") &&
		          !strcmp(str(o, "format.pixfmt"), "mono16") && num(o, "format.bits") == 16 &&
		          num(o, "bytes") == (double)rec->fmt.size && num(o, "status") == 0 &&
		          num(o, "sequence") == seq0 + i && num(o, "exposure_us") == rec->exposure_us &&
		          num(o, "gain") == rec->gain,
		      "index line %d: %s", i + 1, line);
		json_decref(o);
	}
	if (idx) {
		CHECK(!fgets(line, sizeof(line), idx), "index: more than %d lines", nlines);
		fclose(idx);
	}

	/* The images, and the manifest's account of them. */
	if (expected_images(rec, srv, first, e)) {
		CHECK(0, "out of memory");
		json_decref(root);
		return;
	}
	static const char *const outs[] = {"mean", "variance"};
	for (int j = 0; j < 2; j++) {
		char key[64], fp[4096], got_sha[65];
		snprintf(key, sizeof(key), "outputs.%s.file", outs[j]);
		snprintf(fp, sizeof(fp), "%s/%s", S, str(cap, key));
		file_sha256(fp, got_sha);
		snprintf(key, sizeof(key), "outputs.%s.sha256", outs[j]);
		CHECK(!strcmp(got_sha, str(cap, key)), "%s: sha256 %s, manifest %s", fp, got_sha,
		      str(cap, key));
		snprintf(key, sizeof(key), "outputs.%s.channels", outs[j]);
		CHECK(num(cap, key) == 1, "%s: %g channels", outs[j], num(cap, key));
		check_image(j ? "variance" : "mean", fp, j ? e->var : e->mean, w, h, !j);
	}
	CHECK(!kg_json_find(cap, "outputs.rgb"), "a mono16 capture has an rgb output");
	CHECK(ulps((float)num(cap, "statistics.min"), e->min) <= 1 &&
	          ulps((float)num(cap, "statistics.max"), e->max) <= 1,
	      "statistics: min %.9g max %.9g, the average's %.9g %.9g", num(cap, "statistics.min"),
	      num(cap, "statistics.max"), e->min, e->max);
	check_against_recording(rec, cap);
	json_decref(root);
}

int main(int argc, char **argv)
{
	if (argc != 3) {
		fprintf(stderr, "usage: test_acquire_injected KOGEI GENICAM.xml (inside netns.sh)\n");
		return 1;
	}
	char *kogei = argv[1];
	if (access(kogei, X_OK))
		kg_test_skip("the kogei binary is not built");
	if (!kg_test_file_exists(argv[2]))
		kg_test_skip("the GenICam description for the fake camera is missing");
	const char *src = getenv("KOGEI_SOURCE_ROOT");
	char session[1024];
	snprintf(session, sizeof(session), "%s/fixtures/demo/session", src && *src ? src : KG_SOURCE_ROOT);
	static recording rec;
	if (load_recording(session, &rec))
		kg_test_skip("no recorded 16-bit mono or Bayer capture of two or more frames in "
		             "fixtures/demo/session");
	printf("injecting %d frames of %s: %s %d bits %s %dx%d (%zu bytes each), served as Mono16\n",
	       rec.n, rec.capture, kg_pixfmt_name(rec.fmt.pixfmt), rec.fmt.bits, rec.fmt.cfa,
	       rec.fmt.width, rec.fmt.height, rec.fmt.size);

	ArvGvFakeCamera *gv = arv_gv_fake_camera_new_full("127.0.0.1", SERIAL, argv[2]);
	if (!gv || !arv_gv_fake_camera_is_running(gv)) {
		if (gv)
			g_object_unref(gv);
		kg_test_skip("the fake GigE Vision camera cannot listen on 127.0.0.1");
	}
	static server srv;
	srv.fake = arv_gv_fake_camera_get_fake_camera(gv);
	srv.rec = &rec;
	g_mutex_init(&srv.lock);
	/* The recording's size, set on the camera (kogei is not asked for a region). */
	arv_fake_camera_write_register(srv.fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, (guint32)rec.fmt.width);
	arv_fake_camera_write_register(srv.fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT,
	                               (guint32)rec.fmt.height);
	arv_fake_camera_set_fill_pattern(srv.fake, fill, &srv);

	char tmpl[] = "/tmp/kogei-acquire-injected-XXXXXX";
	char *tmp = mkdtemp(tmpl);
	if (!tmp) {
		g_object_unref(gv);
		kg_test_skip("cannot make a temporary directory");
	}
	char S[1024], R[1024], log[1100], frames_arg[16];
	snprintf(S, sizeof(S), "%s/S", tmp);
	snprintf(R, sizeof(R), "%s/R", tmp);
	snprintf(frames_arg, sizeof(frames_arg), "%d", NFRAMES);
	snprintf(log, sizeof(log), "%s/acquire.log", tmp);
	char *acq[] = {kogei, "acquire", "--camera", "aravis:127.0.0.1", "--out", S, "--kind",
	               "chart", "--frames", frames_arg, "--format", "mono16", NULL};
	double took = 0;
	int rc = run(acq, log, 30, &took);
	printf("kogei acquire from aravis:127.0.0.1: exit %d in %.2f s, %d frames filled\n", rc,
	       took, srv.nfills);
	CHECK(rc == 0, "kogei acquire --camera aravis:127.0.0.1 exited %d", rc);
	if (rc)
		print_file(log);
	/* The camera is not needed from here: unreferencing it stops its thread, so the
	 * fill log is final. */
	g_object_unref(gv);

	expect e = {0};
	if (!rc)
		check_session(S, &rec, &srv, &e);

	if (!rc) {
		snprintf(log, sizeof(log), "%s/replay.log", tmp);
		char replay_uri[1100];
		snprintf(replay_uri, sizeof(replay_uri), "replay:%s", S);
		char *rep[] = {kogei, "acquire", "--camera", replay_uri, "--out", R, "--kind", "chart",
		               "--frames", frames_arg, NULL};
		rc = run(rep, log, 30, &took);
		printf("kogei acquire from replay: exit %d in %.2f s\n", rc, took);
		CHECK(rc == 0, "kogei acquire --camera replay: exited %d", rc);
		if (rc)
			print_file(log);
		static const char *const same[] = {"captures/chart-0001/mean.tif",
		                                   "captures/chart-0001/variance.tif",
		                                   "frames/chart-0001/000001.raw",
		                                   "frames/chart-0001/000002.raw",
		                                   "frames/chart-0001/000003.raw",
		                                   "frames/chart-0001/000004.raw"};
		for (size_t i = 0; !rc && i < sizeof(same) / sizeof(same[0]); i++) {
			char a[4200], b[4200];
			snprintf(a, sizeof(a), "%s/%s", S, same[i]);
			snprintf(b, sizeof(b), "%s/%s", R, same[i]);
			CHECK(same_files(a, b), "%s differs between the GigE capture and its replay", same[i]);
		}
		if (!rc)
			printf("replay: mean, variance and %d raw frames bit for bit\n", NFRAMES);
	}

	free(e.mean);
	free(e.var);
	for (int i = 0; i < rec.n; i++)
		free(rec.frame[i]);
	g_mutex_clear(&srv.lock);
	nftw(tmp, rm_one, 16, FTW_DEPTH | FTW_PHYS);
	arv_shutdown();
	return kg_test_done("aravis-acquire-injected");
}
