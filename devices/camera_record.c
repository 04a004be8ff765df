/* The frame recorder behind kg_camera_record_* (format: the end of kg_camera.h).
 *
 * Order of writes, so that a recording killed at any instant replays every frame that
 * was completed: the frame goes to a temporary name and is renamed; only then is its
 * line appended to index.jsonl in one write(). Durability against power loss comes
 * from kg_frame_recorder_sync (a syncfs at capture boundaries, on request before a
 * manifest names the frames, and at close), not from an fsync per frame. A frame file without an index line is ignored by replay; an index line
 * without its newline (killed mid-write) is ignored by replay and cut off when a
 * recorder opens the session again, so appending never glues two lines together. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <openssl/evp.h>

#include "camera_driver.h"

#define REC_FORMAT "kogei-camera-recording/1"
#define CAPTURE_MAX 64
#define DEFAULT_CAPTURE "capture"

struct kg_frame_recorder {
	char *session;     /* the session folder */
	char *frames;      /* <session>/frames */
	char *index_path;  /* <session>/frames/index.jsonl */
	int index_fd;      /* O_APPEND */
	off_t index_size;  /* bytes of complete lines */
	char capture[CAPTURE_MAX];
	char *capture_dir; /* NULL until the first frame of the capture */
	long next;         /* number of the capture's next frame file */
	char last_file[CAPTURE_MAX + 32];
	char last_sha[65];
	int unsynced;      /* frames written since the last sync */
};

/* ---- shared with replay -------------------------------------------------------- */

int kg_frame_sha256(const void *data, size_t size, char hex[65])
{
	unsigned char md[EVP_MAX_MD_SIZE];
	unsigned int len = 0;
	if (!EVP_Digest(data, size, md, &len, EVP_sha256(), NULL) || len != 32) {
		hex[0] = 0;
		return KG_EIO;
	}
	for (unsigned i = 0; i < len; i++)
		snprintf(hex + 2 * i, 3, "%02x", md[i]);
	return 0;
}

json_t *kg_frame_format_json(const kg_frame_format *f)
{
	return json_pack("{s:s, s:i, s:s, s:i, s:i, s:i, s:i, s:I, s:I}", "pixfmt",
	                 kg_pixfmt_name(f->pixfmt), "bits", f->bits, "cfa", f->cfa, "width",
	                 f->width, "height", f->height, "offset_x", f->offset_x, "offset_y",
	                 f->offset_y, "stride", (json_int_t)f->stride, "size",
	                 (json_int_t)f->size);
}

int kg_frame_format_from_json(const char *file, const json_t *o, kg_frame_format *f,
                              kg_err *err)
{
	memset(f, 0, sizeof(*f));
	const char *name, *cfa;
	long bits, w, h, ox, oy, stride, size;
	int ret = kg_json_get_string(file, o, "pixfmt", &name, err);
	if (!ret)
		ret = kg_pixfmt_parse(name, &f->pixfmt, NULL, NULL, err);
	if (ret)
		return ret;
	if ((ret = kg_json_get_int(file, o, "bits", 1, 16, &bits, err)) ||
	    (ret = kg_json_get_string(file, o, "cfa", &cfa, err)) ||
	    (ret = kg_json_get_int(file, o, "width", 1, 1L << 20, &w, err)) ||
	    (ret = kg_json_get_int(file, o, "height", 1, 1L << 20, &h, err)) ||
	    (ret = kg_json_get_int(file, o, "offset_x", 0, 1L << 20, &ox, err)) ||
	    (ret = kg_json_get_int(file, o, "offset_y", 0, 1L << 20, &oy, err)) ||
	    /* 0 for MJPEG: compressed frames have no row stride */
	    (ret = kg_json_get_int(file, o, "stride", f->pixfmt == KG_PIX_MJPEG ? 0 : 1, 1L << 40,
	                           &stride, err)) ||
	    (ret = kg_json_get_int(file, o, "size", 1, 1L << 40, &size, err)))
		return ret;
	int bayer = f->pixfmt == KG_PIX_BAYER8 || f->pixfmt == KG_PIX_BAYER16;
	if (strlen(cfa) != (bayer ? 4u : 0u) ||
	    (bayer && strcmp(cfa, "RGGB") && strcmp(cfa, "GRBG") && strcmp(cfa, "GBRG") &&
	     strcmp(cfa, "BGGR")))
		return kg_fail(err, KG_EINVAL, "%s: cfa '%s': expected %s", file, cfa,
		               bayer ? "RGGB, GRBG, GBRG or BGGR" : "\"\" for a non-Bayer format");
	f->bits = (int)bits;
	memcpy(f->cfa, cfa, strlen(cfa) + 1);
	f->width = (int)w;
	f->height = (int)h;
	f->offset_x = (int)ox;
	f->offset_y = (int)oy;
	f->stride = (size_t)stride;
	f->size = (size_t)size;
	size_t row = (size_t)w * (size_t)kg_pixfmt_bytes_per_pixel(f->pixfmt);
	if (f->pixfmt != KG_PIX_MJPEG && (f->stride < row || f->size < f->stride * (size_t)h))
		return kg_fail(err, KG_EINVAL,
		               "%s: format: stride %zu and size %zu do not hold %ldx%ld %s", file,
		               f->stride, f->size, w, h, name);
	return 0;
}

/* ---- writing ------------------------------------------------------------------- */

static int fsync_dir(const char *path, kg_err *err)
{
	int fd = open(path, O_RDONLY | O_DIRECTORY);
	if (fd < 0 || fsync(fd) != 0) {
		int e = errno;
		if (fd >= 0)
			close(fd);
		return kg_fail(err, KG_EIO, "%s: cannot sync directory: %s", path, strerror(e));
	}
	close(fd);
	return 0;
}

/* Names that stay one path component on every filesystem: [A-Za-z0-9._-], not
 * starting with a dot. */
static int capture_name_ok(const char *s) { return kg_name_is_safe(s, CAPTURE_MAX); }

/* Cut a partial last line (a writer killed mid-line) so appends start on a fresh
 * line. */
static int index_repair(kg_frame_recorder *r, kg_err *err)
{
	struct stat st;
	if (fstat(r->index_fd, &st) != 0)
		return kg_fail(err, KG_EIO, "%s: %s", r->index_path, strerror(errno));
	r->index_size = st.st_size;
	if (!st.st_size)
		return 0;
	char *buf;
	size_t len;
	int ret = kg_read_file(r->index_path, &buf, &len, err);
	if (ret)
		return ret;
	size_t keep = len;
	while (keep && buf[keep - 1] != '\n')
		keep--;
	free(buf);
	if (keep == len)
		return 0;
	if (ftruncate(r->index_fd, (off_t)keep) != 0 || fsync(r->index_fd) != 0)
		return kg_fail(err, KG_EIO, "%s: cannot cut the unfinished last line: %s",
		               r->index_path, strerror(errno));
	r->index_size = (off_t)keep;
	return 0;
}

static int write_camera_json(const kg_frame_recorder *r, const kg_camera_info *info,
                             const kg_frame_format *fmt, kg_err *err)
{
	json_t *root = json_pack(
		"{s:s, s:{s:s, s:s, s:s, s:s, s:s, s:s, s:i, s:i}, s:o}", "format", REC_FORMAT,
		"camera", "backend", info->backend, "uri", info->uri, "vendor", info->vendor,
		"model", info->model, "serial", info->serial, "transport", info->transport,
		"sensor_width", info->sensor_width, "sensor_height", info->sensor_height,
		"frame_format", kg_frame_format_json(fmt));
	char *path = kg_path_join(r->frames, "camera.json");
	int ret = root && path ? kg_json_write(root, path, err)
	                       : kg_fail(err, KG_ENOMEM, "%s: out of memory", r->frames);
	json_decref(root);
	free(path);
	return ret;
}

/* The temporaries that killed recorders left in the capture folders under frames (a
 * kill lands between a frame's temporary and its rename; the next capture writes
 * another folder, whose own writes sweep only it). */
static void sweep_captures(const char *frames)
{
	DIR *d = opendir(frames);
	if (!d)
		return;
	for (struct dirent *e; (e = readdir(d));) {
		if (e->d_name[0] == '.')
			continue;
		char *sub = kg_path_join(frames, e->d_name);
		struct stat st;
		if (sub && lstat(sub, &st) == 0 && S_ISDIR(st.st_mode))
			kg_atomicfile_sweep(sub);
		free(sub);
	}
	closedir(d);
}

int kg_frame_recorder_open(const char *session_dir, const kg_camera_info *info,
                           const kg_frame_format *fmt, kg_frame_recorder **out, kg_err *err)
{
	kg_check_arg(session_dir && info && fmt && out, err);
	*out = NULL;
	kg_frame_recorder *r = calloc(1, sizeof(*r));
	if (!r)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", session_dir);
	r->index_fd = -1;
	snprintf(r->capture, sizeof(r->capture), "%s", DEFAULT_CAPTURE);
	r->session = strdup(session_dir);
	r->frames = kg_path_join(session_dir, "frames");
	r->index_path = r->frames ? kg_path_join(r->frames, "index.jsonl") : NULL;
	int ret = r->session && r->index_path
	                  ? 0
	                  : kg_fail(err, KG_ENOMEM, "%s: out of memory", session_dir);
	/* frames/ and its index real files of the session: a symbolic link is refused */
	if (!ret) /* the session folder itself may be new (recording without a manifest) */
		ret = kg_mkdir_p(session_dir, err);
	if (!ret)
		ret = kg_mkdir_below(session_dir, "frames", err);
	if (!ret)
		ret = kg_check_below(session_dir, "frames/camera.json", err);
	if (!ret)
		sweep_captures(r->frames);
	if (!ret) {
		r->index_fd = kg_open_below(session_dir, "frames/index.jsonl",
		                            O_WRONLY | O_CREAT | O_APPEND, 0644, err);
		if (r->index_fd < 0) {
			ret = r->index_fd;
			r->index_fd = -1;
		}
	}
	if (!ret)
		ret = index_repair(r, err);
	if (!ret)
		ret = write_camera_json(r, info, fmt, err);
	if (!ret)
		ret = fsync_dir(r->frames, err);
	if (ret) {
		kg_frame_recorder_close(&r, NULL);
		return ret;
	}
	*out = r;
	return 0;
}

int kg_frame_recorder_capture(kg_frame_recorder *r, const char *capture, kg_err *err)
{
	kg_check_arg(r && capture, err);
	if (!capture_name_ok(capture))
		return kg_fail(err, KG_EINVAL,
		               "%s: capture name '%s': expected 1 to %d letters, digits, '.', '_' "
		               "or '-', not starting with '.'",
		               r->frames, capture, CAPTURE_MAX - 1);
	if (!strcmp(capture, r->capture))
		return 0;
	int ret = kg_frame_recorder_sync(r, err);
	if (ret)
		return ret;
	snprintf(r->capture, sizeof(r->capture), "%s", capture);
	free(r->capture_dir);
	r->capture_dir = NULL;
	return 0;
}

/* Create the capture's folder and continue after the highest frame number in it, so
 * a capture name used again (a recording resumed) never overwrites a frame. */
static int capture_begin(kg_frame_recorder *r, kg_err *err)
{
	r->capture_dir = kg_path_join(r->frames, r->capture);
	if (!r->capture_dir)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", r->frames);
	char rel[CAPTURE_MAX + 16];
	snprintf(rel, sizeof(rel), "frames/%s", r->capture);
	int ret = kg_mkdir_below(r->session, rel, err); /* no symbolic link on the way */
	if (!ret)
		ret = fsync_dir(r->frames, err);
	if (ret) {
		free(r->capture_dir);
		r->capture_dir = NULL;
		return ret;
	}
	r->next = 1;
	kg_atomicfile_sweep(r->capture_dir);
	DIR *d = opendir(r->capture_dir);
	for (struct dirent *e; d && (e = readdir(d));) {
		char *end;
		long n = strtol(e->d_name, &end, 10);
		if (end != e->d_name && !strcmp(end, ".raw") && n >= r->next)
			r->next = n + 1;
	}
	if (d)
		closedir(d);
	return 0;
}

static json_t *json_number_or_null(double v)
{
	return isfinite(v) ? json_real(v) : json_null();
}

/* The frame's bytes to a file with no name (kg_atomicfile) that is put in place when
 * complete, so a killed recorder leaves no partial frame (a kill between its link to a
 * hidden name and the rename leaves that name, removed by sweep_captures). Not fsynced:
 * what a killed process wrote is in the page cache and survives it;
 * kg_frame_recorder_sync makes everything durable against power loss (at every capture
 * boundary, before a manifest names the frames, and at close), so the frame rate is not
 * bounded by one fsync per frame. The folder's stale temporaries are swept once, when
 * the capture begins, and every capture folder's when the recorder opens. */
static int write_frame_file(const char *path, const void *data, size_t size, kg_err *err)
{
	kg_atomicfile t;
	int ret = kg_atomicfile_open_flags(&t, path, KG_ATOMICFILE_NO_SWEEP, err);
	if (ret)
		return ret;
	if (size && kg_write_all(t.fd, data, size) != 0) {
		ret = kg_fail_write(err, errno, path, "write failed");
		kg_atomicfile_abort(&t);
		return ret;
	}
	return kg_atomicfile_commit(&t, err);
}

int kg_frame_recorder_sync(kg_frame_recorder *r, kg_err *err)
{
	kg_check_arg(r, err);
	if (!r->unsynced)
		return 0;
	/* One syncfs covers every frame file, their folders and the index. */
	if (syncfs(r->index_fd) != 0)
		return kg_fail(err, KG_EIO, "%s: cannot sync to disk: %s", r->frames,
		               strerror(errno));
	r->unsynced = 0;
	return 0;
}

int kg_frame_recorder_write(kg_frame_recorder *r, const kg_frame *f, kg_err *err)
{
	kg_check_arg(r && f && (f->data || !f->size), err);
	int ret = 0;
	if (!r->capture_dir && (ret = capture_begin(r, err)))
		return ret;
	char name[CAPTURE_MAX + 32], sha[65];
	snprintf(name, sizeof(name), "frames/%s/%06ld.raw", r->capture, r->next);
	char *path = kg_path_join(r->capture_dir, strrchr(name, '/') + 1);
	if (!path)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", r->frames);
	if (kg_frame_sha256(f->data, f->size, sha)) {
		ret = kg_fail(err, KG_EIO, "%s: sha256 failed (OpenSSL)", path);
		goto done;
	}
	if ((ret = write_frame_file(path, f->data, f->size, err)))
		goto done;
	r->unsynced = 1;

	json_t *line = json_pack("{s:s, s:s, s:s, s:o, s:I, s:I, s:o, s:i, s:o, s:o}", "capture",
	                         r->capture, "file", name, "sha256", sha, "format",
	                         kg_frame_format_json(&f->fmt), "bytes", (json_int_t)f->size,
	                         "sequence", (json_int_t)f->sequence, "timestamp",
	                         json_number_or_null(f->timestamp), "status", f->status,
	                         "exposure_us", json_number_or_null(f->exposure_us), "gain",
	                         json_number_or_null(f->gain));
	char *text = line ? json_dumps(line, JSON_COMPACT | JSON_REAL_PRECISION(17)) : NULL;
	json_decref(line);
	if (!text) {
		ret = kg_fail(err, KG_ENOMEM, "%s: cannot format the index line", r->index_path);
		goto done;
	}
	/* One write() of the whole line, newline included: the NUL json_dumps leaves
	 * becomes the newline. */
	size_t len = strlen(text);
	text[len] = '\n';
	if (kg_write_all(r->index_fd, text, len + 1) != 0) {
		int e = errno;
		/* Take a partial line back so the next append starts cleanly. */
		if (ftruncate(r->index_fd, r->index_size) != 0)
			e = errno;
		char what[CAPTURE_MAX + 64];
		snprintf(what, sizeof(what), "cannot append the line of %s", name);
		ret = kg_fail_write(err, e, r->index_path, what);
	} else {
		r->index_size += (off_t)(len + 1);
		r->next++;
		snprintf(r->last_file, sizeof(r->last_file), "%s", name);
		memcpy(r->last_sha, sha, sizeof(sha));
	}
	free(text);
done:
	free(path);
	return ret;
}

void kg_frame_recorder_last(const kg_frame_recorder *r, char *file, size_t len,
                            char sha256[65])
{
	if (file && len)
		snprintf(file, len, "%s", r->last_file);
	if (sha256)
		memcpy(sha256, r->last_sha, 65);
}

int kg_frame_recorder_close(kg_frame_recorder **pr, kg_err *err)
{
	if (!pr || !*pr)
		return 0;
	kg_frame_recorder *r = *pr;
	*pr = NULL;
	int ret = r->index_fd >= 0 ? kg_frame_recorder_sync(r, err) : 0;
	if (r->index_fd >= 0 && close(r->index_fd) != 0 && !ret)
		ret = kg_fail(err, KG_EIO, "%s: close failed: %s", r->index_path, strerror(errno));
	free(r->capture_dir);
	free(r->index_path);
	free(r->frames);
	free(r->session);
	free(r);
	return ret;
}

/* ---- discarding a failed capture --------------------------------------------------- */

int kg_camera_recording_discard(const char *session_dir, const char *capture, kg_err *err)
{
	kg_check_arg(session_dir && capture, err);
	if (!capture_name_ok(capture))
		return kg_fail(err, KG_EINVAL,
		               "%s: capture name '%s': expected 1 to %d letters, digits, '.', '_' "
		               "or '-', not starting with '.'",
		               session_dir, capture, CAPTURE_MAX - 1);
	char *frames = kg_path_join(session_dir, "frames");
	char *index = frames ? kg_path_join(frames, "index.jsonl") : NULL;
	char *buf = NULL;
	size_t len = 0;
	kg_outfile out = {0};
	struct stat st;
	char rel[CAPTURE_MAX + 16];
	snprintf(rel, sizeof(rel), "frames/%s", capture);
	int ret = index ? 0 : kg_fail(err, KG_ENOMEM, "%s: out of memory", session_dir);
	/* nothing is removed or rewritten through a symbolic link */
	if (!ret && !(ret = kg_check_below(session_dir, "frames/index.jsonl", err)))
		ret = kg_check_below(session_dir, rel, err);
	if (ret || stat(index, &st) != 0) { /* nothing was recorded */
		free(index);
		free(frames);
		return ret;
	}
	ret = kg_read_file(index, &buf, &len, err);
	kg_inputs_forget(index); /* read to be rewritten without one capture's lines */
	if (!ret)
		ret = kg_outfile_open(&out, index, 0, err);
	/* Keep every other line as it is; a last line without its newline (cut off) goes. */
	size_t n = strlen(capture);
	for (char *line = buf, *nl; !ret && line && (nl = memchr(line, '\n', len - (size_t)(line - buf)));
	     line = nl + 1) {
		size_t llen = (size_t)(nl - line) + 1;
		json_t *o = json_loadb(line, llen - 1, 0, NULL);
		const char *cap = json_string_value(json_object_get(o, "capture"));
		const char *file = json_string_value(json_object_get(o, "file"));
		if (cap && !strcmp(cap, capture)) {
			/* only files inside frames/<capture>/ */
			if (file && !strncmp(file, "frames/", 7) && !strncmp(file + 7, capture, n) &&
			    file[7 + n] == '/' && !strchr(file + 8 + n, '/')) {
				char *path = kg_path_join(session_dir, file);
				if (path)
					unlink(path);
				free(path);
			}
		} else if (fwrite(line, 1, llen, out.fp) != llen) {
			ret = kg_fail(err, KG_EIO, "%s: write failed: %s", index, strerror(errno));
		}
		json_decref(o);
	}
	if (!ret)
		ret = kg_outfile_commit(&out, err);
	else
		kg_outfile_abort(&out);
	if (!ret) {
		char *dir = kg_path_join(frames, capture);
		if (dir)
			rmdir(dir); /* fails, harmlessly, if anything else is in it */
		free(dir);
		ret = fsync_dir(frames, err);
	}
	free(buf);
	free(index);
	free(frames);
	return ret;
}
