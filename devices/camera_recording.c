/* Reading a recording (frames/camera.json and frames/index.jsonl, kg_camera.h): the one
 * parser of its lines and of its camera file, used by replay: and by the validation
 * every reader of a session runs (kg_camera_recording_validate). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "camera_driver.h"

#define REC_FORMAT "kogei-camera-recording/1"
#define NAME_MAX_LEN 64

void kg_rec_frame_clear(kg_rec_frame *fr)
{
	free(fr->file);
	free(fr->capture);
	memset(fr, 0, sizeof(*fr));
}

/* A number, or null (NAN); anything else is refused. */
static int number_or_null(const char *where, const json_t *o, const char *key, double *out,
                          kg_err *err)
{
	const json_t *v = json_object_get(o, key);
	if (!v || json_is_null(v)) {
		*out = NAN;
		return 0;
	}
	if (!json_is_number(v) || !isfinite(json_number_value(v)))
		return kg_fail(err, KG_EINVAL, "%s: %s: expected a finite number or null", where, key);
	*out = json_number_value(v);
	return 0;
}

char *kg_rec_next_line(char *buf, size_t len, size_t *pos, int *lineno)
{
	char *nl;
	while (*pos < len && (nl = memchr(buf + *pos, '\n', len - *pos))) {
		char *line = buf + *pos;
		*nl = 0;
		*pos = (size_t)(nl - buf) + 1;
		++*lineno;
		if (line[strspn(line, " \t\r")])
			return line;
	}
	return NULL;
}

int kg_rec_parse_line(const char *index_path, const char *text, int lineno, kg_rec_frame *fr,
                      kg_err *err)
{
	memset(fr, 0, sizeof(*fr));
	json_error_t je;
	json_t *o = json_loads(text, JSON_REJECT_DUPLICATES, &je);
	if (!json_is_object(o)) {
		json_decref(o);
		return kg_fail(err, KG_EINVAL, "%s: line %d: expected one JSON object (%s)",
		               index_path, lineno, je.text);
	}
	/* Messages from the JSON getters name "<index>: line N". */
	char where[4200];
	snprintf(where, sizeof(where), "%s: line %d", index_path, lineno);
	const char *path, *capture, *sha;
	json_t *fmt;
	long status;
	json_int_t bytes, seq;
	int ret;
	if ((ret = kg_json_get_string(where, o, "capture", &capture, err)) ||
	    (ret = kg_json_get_string(where, o, "file", &path, err)) ||
	    (ret = kg_json_get_string(where, o, "sha256", &sha, err)) ||
	    (ret = kg_json_get(where, o, "format", &fmt, err)) ||
	    (ret = kg_frame_format_from_json(where, fmt, &fr->fmt, err)) ||
	    (ret = kg_json_get_int(where, o, "status", 0, 2, &status, err)) ||
	    (ret = number_or_null(where, o, "timestamp", &fr->timestamp, err)) ||
	    (ret = number_or_null(where, o, "exposure_us", &fr->exposure_us, err)) ||
	    (ret = number_or_null(where, o, "gain", &fr->gain, err)))
		goto done;
	const json_t *jb = json_object_get(o, "bytes"), *js = json_object_get(o, "sequence");
	if (!json_is_integer(jb) || !json_is_integer(js) ||
	    (bytes = json_integer_value(jb)) < 0 || (seq = json_integer_value(js)) < 0) {
		ret = kg_fail(err, KG_EINVAL, "%s: bytes and sequence: expected whole numbers >= 0",
		              where);
		goto done;
	}
	if (!(fr->exposure_us > 0) && !isnan(fr->exposure_us)) {
		ret = kg_fail(err, KG_EINVAL, "%s: exposure_us %g: expected a number > 0 or null",
		              where, fr->exposure_us);
		goto done;
	}
	if (strlen(sha) != 64 || strspn(sha, "0123456789abcdef") != 64) {
		ret = kg_fail(err, KG_EINVAL, "%s: sha256 '%s': expected 64 hex digits", where, sha);
		goto done;
	}
	if (!kg_name_is_safe(capture, NAME_MAX_LEN)) {
		ret = kg_fail(err, KG_EINVAL,
		              "%s: capture '%s': expected 1 to %d letters, digits, '.', '_' or '-', "
		              "not starting with '.'",
		              where, capture, NAME_MAX_LEN - 1);
		goto done;
	}
	/* frames/<capture>/<file>: nothing that leaves the capture's folder. */
	size_t nc = strlen(capture);
	if (strncmp(path, "frames/", 7) || strncmp(path + 7, capture, nc) || path[7 + nc] != '/' ||
	    !kg_relpath_is_safe(path, NAME_MAX_LEN) || strchr(path + 8 + nc, '/')) {
		ret = kg_fail(err, KG_EINVAL, "%s: file '%s': expected frames/%s/<n>.raw", where,
		              path, capture);
		goto done;
	}
	fr->file = strdup(path);
	fr->capture = strdup(capture);
	if (!fr->file || !fr->capture) {
		ret = kg_fail(err, KG_ENOMEM, "%s: out of memory", where);
		goto done;
	}
	memcpy(fr->sha256, sha, 65);
	fr->bytes = (size_t)bytes;
	fr->sequence = (uint64_t)seq;
	fr->status = (int)status;
	fr->line = lineno;
done:
	if (ret)
		kg_rec_frame_clear(fr);
	json_decref(o);
	return ret;
}

int kg_rec_read_camera(const char *frames_dir, kg_camera_info *info, kg_frame_format *fmt0,
                       kg_err *err)
{
	char *path = kg_path_join(frames_dir, "camera.json");
	json_t *root = NULL;
	const char *format, *vendor, *model, *serial;
	long w, h;
	json_t *fmt;
	int ret = path ? kg_json_load(path, &root, err) : KG_ENOMEM;
	if (!ret && !(ret = kg_json_get_string(path, root, "format", &format, err)) &&
	    strcmp(format, REC_FORMAT))
		ret = kg_fail(err, KG_EINVAL, "%s: format '%s': expected %s", path, format,
		              REC_FORMAT);
	if (!ret && !(ret = kg_json_get_string(path, root, "camera.vendor", &vendor, err)) &&
	    !(ret = kg_json_get_string(path, root, "camera.model", &model, err)) &&
	    !(ret = kg_json_get_string(path, root, "camera.serial", &serial, err)) &&
	    !(ret = kg_json_get_int(path, root, "camera.sensor_width", 0, 1L << 20, &w, err)) &&
	    !(ret = kg_json_get_int(path, root, "camera.sensor_height", 0, 1L << 20, &h, err)) &&
	    !(ret = kg_json_get(path, root, "frame_format", &fmt, err)) &&
	    !(ret = kg_frame_format_from_json(path, fmt, fmt0, err)) && info) {
		snprintf(info->vendor, sizeof(info->vendor), "%s", vendor);
		snprintf(info->model, sizeof(info->model), "%s", model);
		snprintf(info->serial, sizeof(info->serial), "%s", serial);
		info->sensor_width = (int)w;
		info->sensor_height = (int)h;
	}
	json_decref(root);
	free(path);
	return ret;
}

int kg_camera_recording_validate(const char *session_dir, kg_err *err)
{
	kg_check_arg(session_dir, err);
	char *frames = kg_path_join(session_dir, "frames");
	char *index = frames ? kg_path_join(frames, "index.jsonl") : NULL;
	if (!index) {
		free(frames);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", session_dir);
	}
	struct stat st;
	int ret = 0;
	char *buf = NULL;
	size_t len = 0;
	/* the recording's files are real files of the session: no symbolic link */
	if ((ret = kg_check_below(session_dir, "frames/index.jsonl", err)) ||
	    (ret = kg_check_below(session_dir, "frames/camera.json", err)))
		goto done;
	if (stat(index, &st) != 0)
		goto done; /* nothing recorded */
	kg_frame_format fmt0;
	char *camera = kg_path_join(frames, "camera.json");
	if (!camera) {
		ret = kg_fail(err, KG_ENOMEM, "%s: out of memory", session_dir);
		goto done;
	}
	ret = kg_rec_read_camera(frames, NULL, &fmt0, err);
	if (!ret)
		ret = kg_read_file(index, &buf, &len, err);
	/* The recording's own files, rewritten by the next capture: not inputs. */
	kg_inputs_forget(camera);
	kg_inputs_forget(index);
	free(camera);
	if (ret)
		goto done;
	int lineno = 0;
	size_t pos = 0;
	for (char *line; !ret && (line = kg_rec_next_line(buf, len, &pos, &lineno));) {
		kg_rec_frame fr;
		if ((ret = kg_rec_parse_line(index, line, lineno, &fr, err)))
			break;
		char *p = kg_path_join(session_dir, fr.file);
		kg_err e = {{0}};
		int r = p ? kg_stat_below(session_dir, fr.file, &st, &e) : 0;
		if (!p)
			ret = kg_fail(err, KG_ENOMEM, "%s: out of memory", index);
		else if (r && r != KG_ENOENT) { /* a symbolic link on the way */
			ret = r;
			if (err)
				*err = e;
		} else if (r || !S_ISREG(st.st_mode))
			ret = kg_fail(err, KG_EINVAL, "%s: line %d: file '%s': expected a regular file "
			              "in the session (%s)", index, lineno, fr.file,
			              r ? "missing" : "not a regular file");
		else if ((size_t)st.st_size != fr.bytes)
			ret = kg_fail(err, KG_EINVAL, "%s: line %d: file '%s' holds %lld bytes: "
			              "expected bytes %zu", index, lineno, fr.file,
			              (long long)st.st_size, fr.bytes);
		free(p);
		kg_rec_frame_clear(&fr);
	}
done:
	free(buf);
	free(index);
	free(frames);
	return ret;
}
