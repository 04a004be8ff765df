/* Record -> replay through the public camera API (docs/cameras.md):
 *   - frames recorded from the sim camera come back byte for byte with their format,
 *     sequence, timestamp and settings, and recording the replay gives the same index
 *     and files again;
 *   - the sha256 in the index agrees with coreutils' sha256sum (an outside
 *     implementation) and kg_camera_record_last reports it;
 *   - replay:DIR#CAPTURE serves one capture; the end of the recording is KG_EIO;
 *   - a setting other than the recorded one fails the next pop naming the frame;
 *   - a truncated last index line is ignored (and cut off when recording resumes);
 *     a changed, shortened or missing frame file is an error naming it. */
#include <string.h>

#include "camera_test.h"

#define NA 3 /* frames in capture chart-0001 (bayer_rggb12, 5000 us, 0 dB) */
#define NB 2 /* frames in capture dark-0001 (mono8, 8000 us, 6 dB) */

typedef struct shot {
	unsigned char *data;
	size_t size;
	kg_frame meta;
	char file[256], sha[65];
} shot;

static shot shots[NA + NB];

static void set(kg_camera *c, kg_feature f, double v)
{
	kg_err e = {{0}};
	cam_must(kg_camera_set(c, f, v, NULL, &e), &e, kg_feature_name(f));
}

static void pop_keep(kg_camera *c, shot *s)
{
	kg_frame f;
	kg_err e = {{0}};
	cam_must(kg_camera_pop(c, 1000, &f, &e), &e, "pop");
	s->size = f.size;
	s->data = malloc(f.size);
	memcpy(s->data, f.data, f.size);
	s->meta = f;
	s->meta.data = NULL;
	cam_must(kg_camera_push(c, &f, &e), &e, "push");
}

/* The two captures, from `uri`, recorded into `session`. */
static void record(const char *uri, const char *session, shot *out)
{
	kg_camera *c = cam_open(uri);
	kg_err e = {{0}};
	cam_must(kg_camera_manual(c, &e), &e, "manual");
	cam_must(kg_camera_record_start(c, session, &e), &e, "record_start");
	CHECK(kg_camera_record_capture(c, "../escape", &e) == KG_EINVAL &&
	          strstr(e.msg, "'../escape'"),
	      "capture name with a path refused: %s", e.msg);
	cam_must(kg_camera_record_capture(c, "chart-0001", &e), &e, "capture");
	set(c, KG_FEAT_EXPOSURE_US, 5000);
	set(c, KG_FEAT_GAIN, 0);
	cam_must(kg_camera_start(c, 0, &e), &e, "start");
	for (int i = 0; i < NA + NB; i++) {
		if (i == NA) {
			cam_must(kg_camera_stop(c, &e), &e, "stop");
			cam_must(kg_camera_record_capture(c, "dark-0001", &e), &e, "capture");
			kg_frame_format want;
			memset(&want, 0, sizeof(want));
			want.pixfmt = KG_PIX_MONO8;
			if (!strncmp(uri, "sim:", 4))
				cam_must(kg_camera_set_format(c, &want, NULL, &e), &e, "set_format");
			set(c, KG_FEAT_EXPOSURE_US, 8000);
			set(c, KG_FEAT_GAIN, 6);
			cam_must(kg_camera_start(c, 0, &e), &e, "start");
		}
		pop_keep(c, &out[i]);
		CHECK(kg_camera_record_last(c, out[i].file, sizeof(out[i].file), out[i].sha) == 0,
		      "record_last");
	}
	cam_must(kg_camera_record_stop(c, &e), &e, "record_stop");
	kg_camera_free(&c);
}

static void sha256sum(const char *path, char hex[65])
{
	char cmd[4600];
	hex[0] = 0;
	snprintf(cmd, sizeof(cmd), "sha256sum '%s' 2>/dev/null", path);
	FILE *p = popen(cmd, "r");
	if (!p)
		return;
	if (fscanf(p, "%64s", hex) != 1)
		hex[0] = 0;
	pclose(p);
}

static char *slurp(const char *path, size_t *len)
{
	char *buf = NULL;
	kg_err e = {{0}};
	if (kg_read_file(path, &buf, len, &e)) {
		fprintf(stderr, "%s\n", e.msg);
		return NULL;
	}
	return buf;
}

static void test_recorded_files(const char *session)
{
	char path[4500];
	snprintf(path, sizeof(path), "%s/frames/camera.json", session);
	CHECK(kg_test_file_exists(path), "camera.json written");
	snprintf(path, sizeof(path), "%s/frames/index.jsonl", session);
	size_t len;
	char *index = slurp(path, &len);
	int lines = 0;
	for (size_t i = 0; index && i < len; i++)
		lines += index[i] == '\n';
	CHECK(lines == NA + NB && index[len - 1] == '\n', "index has %d lines", lines);
	int have_tool = 0;
	for (int i = 0; i < NA + NB; i++) {
		char want[64];
		snprintf(want, sizeof(want), "frames/%s/%06d.raw", i < NA ? "chart-0001" : "dark-0001",
		         i < NA ? i + 1 : i - NA + 1);
		CHECK(!strcmp(shots[i].file, want), "record_last file %s, expected %s", shots[i].file,
		      want);
		snprintf(path, sizeof(path), "%s/%s", session, shots[i].file);
		size_t n;
		char *bytes = slurp(path, &n);
		CHECK(bytes && n == shots[i].size && !memcmp(bytes, shots[i].data, n),
		      "%s holds the frame's bytes", path);
		free(bytes);
		char hex[65];
		sha256sum(path, hex);
		if (!hex[0])
			continue;
		have_tool = 1;
		CHECK(!strcmp(hex, shots[i].sha), "%s: sha256sum %s, recorder %s", path, hex,
		      shots[i].sha);
		CHECK(index && strstr(index, hex), "index holds the sha256 of %s", path);
	}
	if (!have_tool)
		printf("note: sha256sum not found; the sha256 was not checked against it\n");
	free(index);
}

static void check_same(const kg_frame *f, const shot *s, const char *what)
{
	CHECK(f->size == s->size && !memcmp(f->data, s->data, s->size), "%s: bytes differ", what);
	CHECK(f->sequence == s->meta.sequence && f->timestamp == s->meta.timestamp &&
	          f->status == s->meta.status && f->exposure_us == s->meta.exposure_us &&
	          f->gain == s->meta.gain,
	      "%s: seq %llu/%llu ts %.17g/%.17g exposure %g/%g gain %g/%g", what,
	      (unsigned long long)f->sequence, (unsigned long long)s->meta.sequence, f->timestamp,
	      s->meta.timestamp, f->exposure_us, s->meta.exposure_us, f->gain, s->meta.gain);
	CHECK(f->fmt.pixfmt == s->meta.fmt.pixfmt && f->fmt.bits == s->meta.fmt.bits &&
	          !strcmp(f->fmt.cfa, s->meta.fmt.cfa) && f->fmt.width == s->meta.fmt.width &&
	          f->fmt.stride == s->meta.fmt.stride,
	      "%s: format %s/%d", what, kg_pixfmt_name(f->fmt.pixfmt), f->fmt.bits);
}

static void test_round_trip(const char *session)
{
	char uri[4500];
	snprintf(uri, sizeof(uri), "replay:%s", session);
	kg_camera *c = cam_open(uri);
	kg_err e = {{0}};
	const kg_camera_info *info = kg_camera_get_info(c);
	CHECK(!strcmp(info->transport, "replay") && !strcmp(info->vendor, "kogei") &&
	          !strcmp(info->serial, "S3") && info->sensor_width == 24,
	      "identity: %s %s %s", info->transport, info->vendor, info->serial);
	cam_must(kg_camera_manual(c, &e), &e, "manual");
	double v = 0;
	cam_must(kg_camera_get(c, KG_FEAT_EXPOSURE_US, &v, &e), &e, "get");
	CHECK(v == 5000, "exposure reads as recorded: %g", v);
	kg_frame_format fmt;
	cam_must(kg_camera_get_format(c, &fmt, &e), &e, "get_format");
	CHECK(fmt.pixfmt == KG_PIX_BAYER16 && !strcmp(fmt.cfa, "RGGB") && fmt.bits == 12,
	      "format as recorded");
	kg_frame_format want = fmt;
	want.pixfmt = KG_PIX_MONO16;
	CHECK(kg_camera_set_format(c, &want, NULL, &e) == KG_EINVAL && strstr(e.msg, "bayer16"),
	      "another format refused: %s", e.msg);
	set(c, KG_FEAT_EXPOSURE_US, 5000);
	set(c, KG_FEAT_GAIN, 0);
	cam_must(kg_camera_start(c, 0, &e), &e, "start");
	kg_frame f;
	for (int i = 0; i < NA; i++) {
		cam_must(kg_camera_pop(c, 100, &f, &e), &e, "replay pop");
		check_same(&f, &shots[i], shots[i].file);
		cam_must(kg_camera_push(c, &f, &e), &e, "push");
	}
	/* 5000 us is still set; the next frame was taken at 8000 us. */
	int ret = kg_camera_pop(c, 100, &f, &e);
	CHECK(ret == KG_EINVAL && strstr(e.msg, "frames/dark-0001/000001.raw") &&
	          strstr(e.msg, "exposure_us 8000") && strstr(e.msg, "5000 is set"),
	      "other exposure: %d %s", ret, e.msg);
	set(c, KG_FEAT_EXPOSURE_US, 8000);
	ret = kg_camera_pop(c, 100, &f, &e);
	CHECK(ret == KG_EINVAL && strstr(e.msg, "gain 6") && strstr(e.msg, "0 is set"),
	      "other gain: %d %s", ret, e.msg);
	set(c, KG_FEAT_GAIN, 6);
	for (int i = NA; i < NA + NB; i++) {
		cam_must(kg_camera_pop(c, 100, &f, &e), &e, "replay pop");
		check_same(&f, &shots[i], shots[i].file);
		cam_must(kg_camera_push(c, &f, &e), &e, "push");
	}
	ret = kg_camera_pop(c, 100, &f, &e);
	CHECK(ret == KG_EIO && strstr(e.msg, "recording ended after 5 frames"), "end: %d %s", ret,
	      e.msg);
	kg_stream_stats st;
	kg_camera_stats(c, &st);
	CHECK(st.completed == NA + NB, "completed %llu", (unsigned long long)st.completed);
	kg_camera_free(&c);

	/* One capture only. */
	snprintf(uri, sizeof(uri), "replay:%s#dark-0001", session);
	c = cam_open(uri);
	cam_must(kg_camera_start(c, 0, &e), &e, "start");
	for (int i = NA; i < NA + NB; i++) {
		cam_must(kg_camera_pop(c, 100, &f, &e), &e, "replay pop");
		check_same(&f, &shots[i], "#dark-0001");
		cam_must(kg_camera_push(c, &f, &e), &e, "push");
	}
	CHECK(kg_camera_pop(c, 100, &f, &e) == KG_EIO && strstr(e.msg, "after 2 frames"),
	      "#capture ends: %s", e.msg);
	kg_camera_free(&c);
	snprintf(uri, sizeof(uri), "replay:%s#nope", session);
	CHECK(kg_camera_open(uri, &c, &e) == KG_EINVAL && strstr(e.msg, "'nope'") &&
	          strstr(e.msg, "chart-0001, dark-0001"),
	      "unknown capture: %s", e.msg);
}

/* Recording the replay gives the same index and frame files. */
static void test_rerecord(const char *session, const char *again)
{
	char uri[4500];
	snprintf(uri, sizeof(uri), "replay:%s", session);
	shot copy[NA + NB];
	memset(copy, 0, sizeof(copy));
	record(uri, again, copy);
	char a[4500], b[4500];
	snprintf(a, sizeof(a), "%s/frames/index.jsonl", session);
	snprintf(b, sizeof(b), "%s/frames/index.jsonl", again);
	size_t la, lb;
	char *ta = slurp(a, &la), *tb = slurp(b, &lb);
	CHECK(ta && tb && la == lb && !memcmp(ta, tb, la), "re-recorded index differs:\n%s\n%s",
	      ta, tb);
	free(ta);
	free(tb);
	for (int i = 0; i < NA + NB; i++) {
		CHECK(!strcmp(copy[i].sha, shots[i].sha), "re-recorded frame %d sha", i);
		free(copy[i].data);
	}
}

static void append(const char *path, const char *text)
{
	FILE *fp = fopen(path, "ab");
	if (!fp || fputs(text, fp) < 0 || fclose(fp)) {
		perror(path);
		exit(1);
	}
}

static int count_frames(const char *uri, kg_err *e, int *ret)
{
	kg_camera *c = NULL;
	int n = 0;
	if ((*ret = kg_camera_open(uri, &c, e)))
		return -1;
	kg_camera_start(c, 0, e);
	kg_frame f;
	while (!(*ret = kg_camera_pop(c, 100, &f, e))) {
		n++;
		kg_camera_push(c, &f, NULL);
	}
	kg_camera_free(&c);
	return n;
}

static void test_damage(const char *session)
{
	char uri[4500], index[4500], frame[4500];
	snprintf(uri, sizeof(uri), "replay:%s", session);
	snprintf(index, sizeof(index), "%s/frames/index.jsonl", session);
	kg_err e = {{0}};
	int ret;

	/* A writer killed mid-line. */
	append(index, "{\"capture\":\"chart-0001\",\"file\":\"frames/chart-0001/0000");
	int n = count_frames(uri, &e, &ret);
	CHECK(n == NA + NB && ret == KG_EIO && strstr(e.msg, "after 5 frames"),
	      "truncated line ignored: %d frames, %s", n, e.msg);
	/* A frame file left without its index line is not served; recording resumes
	 * after it, and the cut line does not glue onto the next one. */
	snprintf(frame, sizeof(frame), "%s/frames/chart-0001/000009.raw", session);
	append(frame, "orphan");
	shot more;
	kg_camera *c = cam_open("sim:?width=24&height=16&format=bayer_rggb12&seed=3");
	cam_must(kg_camera_manual(c, &e), &e, "manual");
	kg_inputs_reset(); /* a new job: the replays above read this session */
	cam_must(kg_camera_record_start(c, session, &e), &e, "record_start again");
	cam_must(kg_camera_record_capture(c, "chart-0001", &e), &e, "capture");
	cam_must(kg_camera_start(c, 0, &e), &e, "start");
	pop_keep(c, &more);
	kg_camera_record_last(c, more.file, sizeof(more.file), more.sha);
	CHECK(!strcmp(more.file, "frames/chart-0001/000010.raw"), "resumed as %s", more.file);
	kg_camera_free(&c);
	free(more.data);
	n = count_frames(uri, &e, &ret);
	CHECK(n == NA + NB + 1 && ret == KG_EIO && strstr(e.msg, "after 6 frames"),
	      "resumed recording: %d frames, %s", n, e.msg);

	/* A changed frame: one byte flipped. */
	snprintf(frame, sizeof(frame), "%s/frames/chart-0001/000002.raw", session);
	size_t len;
	char *bytes = slurp(frame, &len);
	bytes[len / 2] ^= 1;
	FILE *fp = fopen(frame, "wb");
	fwrite(bytes, 1, len, fp);
	fclose(fp);
	n = count_frames(uri, &e, &ret);
	CHECK(n == 1 && ret == KG_EIO && strstr(e.msg, "chart-0001/000002.raw") &&
	          strstr(e.msg, "sha256") && strstr(e.msg, shots[1].sha),
	      "corrupt frame: %d %d %s", n, ret, e.msg);
	/* Shortened, or missing: the recording is refused when replay opens it. */
	fp = fopen(frame, "wb");
	fwrite(bytes, 1, len - 1, fp);
	fclose(fp);
	c = NULL;
	ret = kg_camera_open(uri, &c, &e);
	char want[64];
	snprintf(want, sizeof(want), "holds %zu bytes: expected bytes %zu", len - 1, len);
	CHECK(ret == KG_EINVAL && strstr(e.msg, "index.jsonl: line 2") &&
	          strstr(e.msg, "000002.raw") && strstr(e.msg, want),
	      "short frame: %s", e.msg);
	kg_camera_free(&c);
	remove(frame);
	ret = kg_camera_open(uri, &c, &e);
	CHECK(ret == KG_EINVAL && strstr(e.msg, "file 'frames/chart-0001/000002.raw': expected a "
	                                        "regular file in the session (missing)"),
	      "missing frame: %s", e.msg);
	kg_camera_free(&c);
	bytes[len / 2] ^= 1; /* put the frame back as recorded */
	fp = fopen(frame, "wb");
	fwrite(bytes, 1, len, fp);
	fclose(fp);
	free(bytes);

	/* A complete line that is not a frame record. */
	append(index, "\n{\"capture\": 3}\n");
	c = NULL;
	ret = kg_camera_open(uri, &c, &e);
	CHECK(ret == KG_EINVAL && strstr(e.msg, "index.jsonl: line 8") && strstr(e.msg, "capture"),
	      "bad index line: %d %s", ret, e.msg);
	kg_camera_free(&c);
	snprintf(uri, sizeof(uri), "replay:%s/nowhere", session);
	CHECK(kg_camera_open(uri, &c, &e) == KG_ENOENT && strstr(e.msg, "nowhere"),
	      "no recording: %s", e.msg);
}

int main(void)
{
	const char *dir = kg_test_scratch_dir("camreplay");
	(void)dir;
	char session[4400], again[4400];
	snprintf(session, sizeof(session), "%s", kg_test_path("session"));
	snprintf(again, sizeof(again), "%s", kg_test_path("again"));
	record("sim:?width=24&height=16&format=bayer_rggb12&seed=3&serial=S3", session, shots);
	test_recorded_files(session);
	test_round_trip(session);
	test_rerecord(session, again);
	test_damage(session);
	for (int i = 0; i < NA + NB; i++)
		free(shots[i].data);
	kg_test_scratch_remove();
	return kg_test_done("test_camera_replay");
}
