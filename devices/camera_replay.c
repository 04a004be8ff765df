/* replay: the frames recorded in a session served back as a camera, bit for bit
 * (recording format: the end of kg_camera.h; written by camera_record.c).
 *
 * URI replay:SESSION_DIR[#CAPTURE]. SESSION_DIR holds frames/index.jsonl (the frames
 * folder itself is accepted too); #CAPTURE serves only that capture's frames.
 *
 * The recording is validated at open (kg_camera_recording_validate: every line, and
 * every file there with its recorded size; KG_EINVAL naming the line). Frames come
 * back in the order recorded, with their recorded format, sequence, timestamp, status
 * and settings; each file's size and sha256 are checked again as it is served, and a
 * mismatch is KG_EIO naming the file. exposure_us and gain read back
 * as the next frame was recorded with. Setting one of them to another value is
 * accepted (it reads back as set), but the next pop then fails (KG_EINVAL) naming the
 * frame, the recorded and the requested value: a replay cannot re-expose. The end of
 * the recording is KG_EIO "recording ended after N frames". */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "camera_driver.h"

#define REPLAY_MAX_BUFFERS 64
#define REPLAY_DEFAULT_BUFFERS 4

typedef struct replay_cam {
	char *base;       /* the session folder */
	char *index_path; /* for messages */
	kg_rec_frame *frames;
	int nframes, next;
	kg_frame_format fmt0; /* camera.json: the format when recording started */
	double want_exposure, want_gain, want_fps; /* NAN: nothing set */
	int nbuf;
	void *buf[REPLAY_MAX_BUFFERS];
	int held[REPLAY_MAX_BUFFERS];
} replay_cam;

static void replay_close(void *state)
{
	replay_cam *s = state;
	if (!s)
		return;
	for (int i = 0; i < s->nframes; i++) {
		free(s->frames[i].file);
		free(s->frames[i].capture);
	}
	for (int i = 0; i < REPLAY_MAX_BUFFERS; i++)
		free(s->buf[i]);
	free(s->frames);
	free(s->base);
	free(s->index_path);
	free(s);
}

static int is_file(const char *path)
{
	struct stat st;
	return path && stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

/* ---- reading the recording ------------------------------------------------------- */

/* Every complete line of the index (a last line without its newline is a write that
 * was cut off, and is ignored), keeping only `capture`'s frames when one is named. */
static int read_index(replay_cam *s, const char *capture, kg_err *err)
{
	char *buf;
	size_t len;
	int ret = kg_read_file(s->index_path, &buf, &len, err);
	if (ret)
		return ret;
	int cap = 0, lineno = 0;
	char *seen = NULL; /* capture names for the message when `capture` has no frames */
	size_t seen_len = 0, pos = 0;
	for (char *line; !ret && (line = kg_rec_next_line(buf, len, &pos, &lineno));) {
		if (s->nframes == cap) {
			int nc = cap ? 2 * cap : 64;
			kg_rec_frame *f = realloc(s->frames, sizeof(*f) * (size_t)nc);
			if (!f) {
				ret = kg_fail(err, KG_ENOMEM, "%s: out of memory", s->index_path);
				break;
			}
			s->frames = f;
			cap = nc;
		}
		kg_rec_frame *fr = &s->frames[s->nframes];
		memset(fr, 0, sizeof(*fr));
		if ((ret = kg_rec_parse_line(s->index_path, line, lineno, fr, err)))
			break;
		if (capture && strcmp(capture, fr->capture)) {
			size_t n = strlen(fr->capture);
			if (!seen || !strstr(seen, fr->capture)) {
				char *ns = realloc(seen, seen_len + n + 3);
				if (ns) {
					snprintf(ns + seen_len, n + 3, "%s%s", seen_len ? ", " : "", fr->capture);
					seen_len += n + (seen_len ? 2 : 0);
					seen = ns;
				}
			}
			kg_rec_frame_clear(fr);
			continue;
		}
		s->nframes++;
	}
	if (!ret && capture && !s->nframes)
		ret = kg_fail(err, KG_EINVAL, "%s: no frames of capture '%s' (recorded: %s)",
		              s->index_path, capture, seen ? seen : "none");
	free(seen);
	free(buf);
	return ret;
}

static int replay_open(const char *target, void **state, kg_camera_info *info, kg_err *err)
{
	if (!*target)
		return kg_fail(err, KG_EINVAL, "expected replay:SESSION_DIR[#CAPTURE]");
	replay_cam *s = calloc(1, sizeof(*s));
	char *dir = strdup(target);
	char *frames = NULL;
	if (!s || !dir) {
		free(s);
		free(dir);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	s->want_exposure = s->want_gain = s->want_fps = NAN;
	char *capture = strrchr(dir, '#');
	if (capture)
		*capture++ = 0;
	int ret = 0;
	/* SESSION_DIR, or its frames folder. */
	s->index_path = kg_path_join(dir, "frames/index.jsonl");
	if (s->index_path && is_file(s->index_path)) {
		s->base = strdup(dir);
		frames = kg_path_join(dir, "frames");
	} else {
		free(s->index_path);
		s->index_path = kg_path_join(dir, "index.jsonl");
		if (s->index_path && is_file(s->index_path)) {
			s->base = kg_path_join(dir, "..");
			frames = strdup(dir);
		} else if (s->index_path) {
			ret = kg_fail(err, KG_ENOENT,
			              "%s: no recorded frames (expected %s/frames/index.jsonl)", dir, dir);
		}
	}
	if (!ret && (!s->index_path || !s->base || !frames))
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	if (!ret)
		ret = kg_camera_recording_validate(s->base, err);
	if (!ret)
		ret = kg_rec_read_camera(frames, info, &s->fmt0, err);
	if (!ret)
		ret = read_index(s, capture && *capture ? capture : NULL, err);
	free(frames);
	free(dir);
	if (ret) {
		replay_close(s);
		return ret;
	}
	snprintf(info->transport, sizeof(info->transport), "replay");
	*state = s;
	return 0;
}

/* ---- features -------------------------------------------------------------------- */

/* The frame the next pop serves, or the last one once the recording has ended. */
static const kg_rec_frame *upcoming(const replay_cam *s)
{
	if (!s->nframes)
		return NULL;
	return &s->frames[s->next < s->nframes ? s->next : s->nframes - 1];
}

/* Equal as kg_camera_set judges a read-back: within 0.5 %. */
static int same_setting(double want, double recorded)
{
	return isnan(want) || fabs(want - recorded) <= 0.005 * fabs(recorded) + 1e-9;
}

static int replay_feature_info(void *state, kg_feature f, kg_feature_info *o, kg_err *err)
{
	(void)state;
	(void)err;
	static const char *const unit[KG_FEAT_COUNT] = {
		[KG_FEAT_EXPOSURE_US] = "us", [KG_FEAT_GAIN] = "recorded",
		[KG_FEAT_FRAME_RATE] = "fps", [KG_FEAT_AUTO_EXPOSURE] = "bool",
		[KG_FEAT_AUTO_WHITE_BALANCE] = "bool"};
	if (!unit[f])
		return 0; /* not recorded: not available */
	o->available = o->writable = 1;
	if (f == KG_FEAT_AUTO_EXPOSURE || f == KG_FEAT_AUTO_WHITE_BALANCE) {
		o->max = 1;
		o->step = 1;
	}
	snprintf(o->unit, sizeof(o->unit), "%s", unit[f]);
	snprintf(o->native, sizeof(o->native), "recorded %s", kg_feature_name(f));
	return 0;
}

static int replay_get(void *state, kg_feature f, double *v, kg_err *err)
{
	replay_cam *s = state;
	const kg_rec_frame *fr = upcoming(s);
	switch (f) {
	case KG_FEAT_EXPOSURE_US:
	case KG_FEAT_GAIN: {
		double want = f == KG_FEAT_GAIN ? s->want_gain : s->want_exposure;
		double rec = fr ? (f == KG_FEAT_GAIN ? fr->gain : fr->exposure_us) : NAN;
		*v = isnan(rec) || !same_setting(want, rec) ? want : rec;
		return 0;
	}
	case KG_FEAT_FRAME_RATE:
		*v = isnan(s->want_fps) ? 0 : s->want_fps;
		return 0;
	case KG_FEAT_AUTO_EXPOSURE:
	case KG_FEAT_AUTO_WHITE_BALANCE:
		*v = 0;
		return 0;
	default:
		return kg_fail(err, KG_ENOTSUP, "%s is not recorded", kg_feature_name(f));
	}
}

static int replay_set(void *state, kg_feature f, double v, kg_err *err)
{
	replay_cam *s = state;
	switch (f) {
	case KG_FEAT_EXPOSURE_US: s->want_exposure = v; return 0;
	case KG_FEAT_GAIN: s->want_gain = v; return 0;
	case KG_FEAT_FRAME_RATE: s->want_fps = v; return 0; /* served as fast as popped */
	case KG_FEAT_AUTO_EXPOSURE:
	case KG_FEAT_AUTO_WHITE_BALANCE:
		if (v == 0)
			return 0;
		return kg_fail(err, KG_ENOTSUP, "%s: a replay serves recorded frames and cannot "
		                                "run automatic control",
		               kg_feature_name(f));
	default:
		return kg_fail(err, KG_ENOTSUP, "%s is not recorded", kg_feature_name(f));
	}
}

/* ---- format ---------------------------------------------------------------------- */

static int replay_get_format(void *state, kg_frame_format *out, kg_err *err)
{
	(void)err;
	const replay_cam *s = state;
	const kg_rec_frame *fr = upcoming(s);
	*out = fr ? fr->fmt : s->fmt0;
	return 0;
}

/* The recorded format is the only one: a request must agree with it. */
static int replay_set_format(void *state, const kg_frame_format *want, kg_frame_format *got,
                             kg_err *err)
{
	kg_frame_format rec;
	replay_get_format(state, &rec, err);
	if ((want->pixfmt && want->pixfmt != rec.pixfmt) || (want->bits && want->bits != rec.bits) ||
	    (want->cfa[0] && strcmp(want->cfa, rec.cfa)) ||
	    (want->width && want->width != rec.width) ||
	    (want->height && want->height != rec.height) ||
	    (want->offset_x && want->offset_x != rec.offset_x) ||
	    (want->offset_y && want->offset_y != rec.offset_y))
		return kg_fail(err, KG_EINVAL,
		               "format: the recording holds %s/%d%s%s %dx%d at (%d, %d); it cannot "
		               "deliver %s/%d %dx%d at (%d, %d)",
		               kg_pixfmt_name(rec.pixfmt), rec.bits, rec.cfa[0] ? " " : "", rec.cfa,
		               rec.width, rec.height, rec.offset_x, rec.offset_y,
		               kg_pixfmt_name(want->pixfmt ? want->pixfmt : rec.pixfmt),
		               want->bits ? want->bits : rec.bits, want->width ? want->width : rec.width,
		               want->height ? want->height : rec.height, want->offset_x,
		               want->offset_y);
	*got = rec;
	return 0;
}

/* ---- stream ---------------------------------------------------------------------- */

static int replay_start(void *state, int nbuffers, kg_err *err)
{
	replay_cam *s = state;
	int n;
	int ret = kg_buffers_count(nbuffers, REPLAY_DEFAULT_BUFFERS, REPLAY_MAX_BUFFERS, &n, err);
	if (ret)
		return ret;
	if (n < s->nbuf)
		for (int i = n; i < s->nbuf; i++)
			if (s->held[i])
				return kg_fail(err, KG_EINVAL, "buffer %d is still held (kg_camera_push)", i);
	s->nbuf = n > s->nbuf ? n : s->nbuf;
	return 0;
}

static int replay_stop(void *state, kg_err *err)
{
	(void)state;
	(void)err;
	return 0;
}

/* A frame is served only with the settings it was recorded with. */
static int check_setting(const kg_rec_frame *fr, const char *name, double want, double rec,
                         kg_err *err)
{
	if (isnan(rec) || same_setting(want, rec))
		return 0;
	return kg_fail(err, KG_EINVAL,
	               "frame %s (index line %d) was recorded with %s %.10g but %.10g is set; a "
	               "replay cannot take it again with other settings",
	               fr->file, fr->line, name, rec, want);
}

static int replay_pop(void *state, int timeout_ms, kg_frame *frame, kg_err *err)
{
	(void)timeout_ms;
	replay_cam *s = state;
	if (s->next >= s->nframes)
		return kg_fail(err, KG_EIO, "recording ended after %d frames (%s)", s->nframes,
		               s->index_path);
	const kg_rec_frame *fr = &s->frames[s->next];
	int ret = check_setting(fr, "exposure_us", s->want_exposure, fr->exposure_us, err);
	if (!ret)
		ret = check_setting(fr, "gain", s->want_gain, fr->gain, err);
	if (ret)
		return ret;
	int slot = kg_buffers_free_slot(s->held, s->nbuf, err);
	if (slot < 0)
		return KG_EINVAL;
	char *path = kg_path_join(s->base, fr->file);
	if (!path)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	char *data = NULL;
	size_t len = 0;
	kg_err rerr = {{0}};
	ret = kg_read_file(path, &data, &len, &rerr);
	char sha[65] = "";
	if (ret)
		ret = kg_fail(err, KG_EIO, "frame %s (index line %d): %s", fr->file, fr->line,
		              rerr.msg);
	else if (len != fr->bytes)
		ret = kg_fail(err, KG_EIO, "%s: %zu bytes, but %zu were recorded (index line %d)",
		              path, len, fr->bytes, fr->line);
	else if (kg_frame_sha256(data, len, sha) || strcmp(sha, fr->sha256))
		ret = kg_fail(err, KG_EIO,
		              "%s: sha256 %s does not match the recorded %s (index line %d): the "
		              "file changed after recording",
		              path, sha, fr->sha256, fr->line);
	free(path);
	if (ret) {
		free(data);
		return ret;
	}
	free(s->buf[slot]);
	s->buf[slot] = data;
	s->held[slot] = 1;
	frame->fmt = fr->fmt;
	frame->data = data;
	frame->size = len;
	frame->sequence = fr->sequence;
	frame->timestamp = fr->timestamp;
	frame->status = fr->status;
	frame->exposure_us = fr->exposure_us;
	frame->gain = fr->gain;
	frame->slot = slot;
	s->next++;
	return 0;
}

static int replay_push(void *state, kg_frame *frame, kg_err *err)
{
	replay_cam *s = state;
	int ret = kg_buffers_release(s->held, s->buf, s->nbuf, frame, err);
	if (ret)
		return ret;
	free(s->buf[frame->slot]);
	s->buf[frame->slot] = NULL;
	return 0;
}

const kg_camera_driver kg_camera_replay_driver = {
	.scheme = "replay",
	.description = "frames recorded in a session: replay:SESSION_DIR[#CAPTURE]",
	.open = replay_open,
	.close = replay_close,
	.feature_info = replay_feature_info,
	.get = replay_get,
	.set = replay_set,
	.set_format = replay_set_format,
	.get_format = replay_get_format,
	.start = replay_start,
	.stop = replay_stop,
	.pop = replay_pop,
	.push = replay_push,
};
