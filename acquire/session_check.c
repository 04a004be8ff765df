/* The one validation of a session's files every reader runs (kg_acquire.h,
 * kg_session_manifest_validate): the manifest's types, ranges and names, every path it
 * holds staying inside the session and naming a file that is there, and the recording
 * (kg_camera_recording_validate). */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "acquire_private.h"

#define PATH_KEY 160

typedef struct check_ctx {
	const char *file; /* the manifest, for messages */
	char *dir;        /* the session */
	const json_t *root;
	kg_err *err;
} check_ctx;

static int is_hex64(const char *s)
{
	return s && strlen(s) == 64 && strspn(s, "0123456789abcdef") == 64;
}

/* A number (> 0 when positive is set) or null at key. */
static int number_or_null(check_ctx *c, const char *key, int positive)
{
	const json_t *v = kg_json_find(c->root, key);
	if (json_is_null(v))
		return 0;
	if (!json_is_number(v) || (positive && !(json_number_value(v) > 0)))
		return kg_fail(c->err, KG_EINVAL, "%s: %s: expected a number%s or null", c->file, key,
		               positive ? " > 0" : "");
	return 0;
}

/* {file, sha256} at key: file a safe relative path under prefix ("frames/NAME/"), a
 * regular file of the session (symbolic links are refused: they could leave it). */
static int file_entry(check_ctx *c, const char *key, const char *prefix)
{
	char k[PATH_KEY + 16];
	const char *file, *sha;
	int ret;
	snprintf(k, sizeof(k), "%s.file", key);
	if ((ret = kg_json_get_string(c->file, c->root, k, &file, c->err)))
		return ret;
	if (strncmp(file, prefix, strlen(prefix)) || !kg_relpath_is_safe(file, KG_CAPTURE_NAME_MAX))
		return kg_fail(c->err, KG_EINVAL,
		               "%s: %s: '%s': expected a path %s<file> inside the session (names of "
		               "[A-Za-z0-9._-], no '..')",
		               c->file, k, file, prefix);
	snprintf(k, sizeof(k), "%s.sha256", key);
	if ((ret = kg_json_get_string(c->file, c->root, k, &sha, c->err)))
		return ret;
	if (!is_hex64(sha))
		return kg_fail(c->err, KG_EINVAL, "%s: %s: '%s': expected 64 lower-case hex digits",
		               c->file, k, sha);
	struct stat st;
	kg_err e = {{0}};
	int r = kg_stat_below(c->dir, file, &st, &e);
	if (r && r != KG_ENOENT) { /* a symbolic link on the way */
		if (c->err)
			*c->err = e;
		return r;
	}
	if (r || !S_ISREG(st.st_mode))
		return kg_fail(c->err, KG_EINVAL,
		               "%s: %s.file: '%s': expected a regular file in the session %s", c->file,
		               key, file, c->dir);
	return 0;
}

static int check_cameras(check_ctx *c)
{
	json_t *cams;
	int ret = kg_json_get(c->file, c->root, "devices.cameras", &cams, c->err);
	if (ret)
		return ret;
	if (!json_is_array(cams))
		return kg_fail(c->err, KG_EINVAL, "%s: devices.cameras: expected an array", c->file);
	static const char *const strings[] = {"id",    "backend", "uri",      "vendor",
	                                      "model", "serial",  "transport"};
	for (size_t i = 0; i < json_array_size(cams); i++) {
		char k[PATH_KEY];
		const char *v;
		long n;
		for (size_t f = 0; f < sizeof(strings) / sizeof(strings[0]); f++) {
			snprintf(k, sizeof(k), "devices.cameras[%zu].%s", i, strings[f]);
			if ((ret = kg_json_get_string(c->file, c->root, k, &v, c->err)))
				return ret;
		}
		for (int f = 0; f < 2; f++) {
			snprintf(k, sizeof(k), "devices.cameras[%zu].%s", i,
			         f ? "sensor_height" : "sensor_width");
			if ((ret = kg_json_get_int(c->file, c->root, k, 0, 1L << 20, &n, c->err)))
				return ret;
		}
		const char *id = json_string_value(json_object_get(json_array_get(cams, i), "id"));
		for (size_t j = 0; j < i; j++)
			if (!strcmp(id, json_string_value(json_object_get(json_array_get(cams, j), "id"))))
				return kg_fail(c->err, KG_EINVAL,
				               "%s: devices.cameras[%zu].id: '%s' is also entry %zu's: expected "
				               "unique ids",
				               c->file, i, id, j);
	}
	return 0;
}

static int has_camera(const json_t *root, const char *id)
{
	const json_t *cams = kg_json_find(root, "devices.cameras"), *e;
	size_t i;
	json_array_foreach(cams, i, e)
	{
		const char *v = json_string_value(json_object_get(e, "id"));
		if (v && !strcmp(v, id))
			return 1;
	}
	return 0;
}

static int check_format(check_ctx *c, const char *key)
{
	char k[PATH_KEY + 16];
	const char *v;
	long n;
	kg_pixfmt pf;
	int ret;
	snprintf(k, sizeof(k), "%s.pixfmt", key);
	if ((ret = kg_json_get_string(c->file, c->root, k, &v, c->err)))
		return ret;
	if (kg_pixfmt_parse(v, &pf, NULL, NULL, NULL))
		return kg_fail(c->err, KG_EINVAL, "%s: %s: '%s': expected a pixel format kogei knows",
		               c->file, k, v);
	snprintf(k, sizeof(k), "%s.cfa", key);
	if ((ret = kg_json_get_string(c->file, c->root, k, &v, c->err)))
		return ret;
	if (strlen(v) > 4 || strspn(v, "RGB") != strlen(v))
		return kg_fail(c->err, KG_EINVAL, "%s: %s: '%s': expected \"\" or a 2x2 pattern (RGGB)",
		               c->file, k, v);
	static const struct {
		const char *key;
		long min, max;
	} ints[] = {{"bits", 1, 32},           {"width", 1, 1L << 20},   {"height", 1, 1L << 20},
	            {"offset_x", 0, 1L << 20}, {"offset_y", 0, 1L << 20}};
	for (size_t i = 0; i < sizeof(ints) / sizeof(ints[0]); i++) {
		snprintf(k, sizeof(k), "%s.%s", key, ints[i].key);
		if ((ret = kg_json_get_int(c->file, c->root, k, ints[i].min, ints[i].max, &n, c->err)))
			return ret;
	}
	return 0;
}

/* corrections.dark / .flat: null, or an earlier capture of that kind. */
static int check_correction(check_ctx *c, size_t i, const char *which)
{
	char k[PATH_KEY];
	snprintf(k, sizeof(k), "captures[%zu].corrections.%s", i, which);
	const json_t *v = kg_json_find(c->root, k);
	if (!v || json_is_null(v))
		return 0;
	const char *name = json_string_value(v);
	const json_t *caps = json_object_get(c->root, "captures");
	for (size_t j = 0; name && j < i; j++) {
		const json_t *e = json_array_get(caps, j);
		const char *n = json_string_value(json_object_get(e, "name"));
		const char *kind = json_string_value(json_object_get(e, "kind"));
		if (n && !strcmp(n, name) && kind && !strcmp(kind, which))
			return 0;
	}
	return kg_fail(c->err, KG_EINVAL, "%s: %s: expected null or the name of an earlier %s "
	               "capture of the session",
	               c->file, k, which);
}

/* chart_layout: absent or null, a layout's name (one component: the readers take only
 * a bundled layout's), or a regular file under prefix ("captures/NAME/", where acquire
 * copies a --layout FILE) reached with no symbolic link on the way. Never a path
 * elsewhere: a manifest must not make kogei open any file it names. */
static int check_layout(check_ctx *c, const char *key, const char *prefix)
{
	const json_t *v = kg_json_find(c->root, key);
	if (!v || json_is_null(v))
		return 0;
	const char *l = json_string_value(v);
	if (l && kg_name_is_safe(l, KG_CAPTURE_NAME_MAX))
		return 0;
	if (l && !strncmp(l, prefix, strlen(prefix)) && kg_relpath_is_safe(l, KG_CAPTURE_NAME_MAX)) {
		struct stat st;
		kg_err e = {{0}};
		int r = kg_stat_below(c->dir, l, &st, &e);
		if (!r && S_ISREG(st.st_mode))
			return 0;
		if (r && r != KG_ENOENT) { /* a symbolic link on the way */
			if (c->err)
				*c->err = e;
			return r;
		}
	}
	return kg_fail(c->err, KG_EINVAL,
	               "%s: %s: '%s': expected a bundled chart layout's name or a regular file "
	               "%s<file> inside the session (no absolute path, no '..')",
	               c->file, key, l ? l : "(not a string)", prefix);
}

static int check_capture(check_ctx *c, size_t i)
{
	char k[PATH_KEY], prefix[KG_CAPTURE_NAME_MAX + 16];
	const char *name, *v;
	json_t *o;
	long n;
	int ret;
	snprintf(k, sizeof(k), "captures[%zu].name", i);
	if ((ret = kg_json_get_string(c->file, c->root, k, &name, c->err)))
		return ret;
	if (!kg_capture_name_ok(name))
		return kg_fail(c->err, KG_EINVAL,
		               "%s: %s: '%s': expected 1 to %d letters, digits, '.', '_' or '-', not "
		               "starting with '.'",
		               c->file, k, name, KG_CAPTURE_NAME_MAX - 1);
	const json_t *caps = json_object_get(c->root, "captures");
	for (size_t j = 0; j < i; j++)
		if (!strcmp(name, json_string_value(json_object_get(json_array_get(caps, j), "name"))))
			return kg_fail(c->err, KG_EINVAL,
			               "%s: %s: '%s' is also captures[%zu]'s name: expected unique names",
			               c->file, k, name, j);
	snprintf(k, sizeof(k), "captures[%zu].kind", i);
	kg_capture_kind kind;
	if ((ret = kg_json_get_string(c->file, c->root, k, &v, c->err)))
		return ret;
	if (kg_capture_kind_parse(v, &kind, NULL))
		return kg_fail(c->err, KG_EINVAL, "%s: %s: '%s': expected chart, object, dark or flat",
		               c->file, k, v);
	snprintf(k, sizeof(k), "captures[%zu].camera", i);
	if ((ret = kg_json_get_string(c->file, c->root, k, &v, c->err)))
		return ret;
	if (!has_camera(c->root, v))
		return kg_fail(c->err, KG_EINVAL, "%s: %s: '%s': expected the id of an entry of "
		               "devices.cameras", c->file, k, v);
	for (int t = 0; t < 2; t++) {
		snprintf(k, sizeof(k), "captures[%zu].%s", i, t ? "ended" : "started");
		if ((ret = kg_json_get_string(c->file, c->root, k, &v, c->err)))
			return ret;
	}
	snprintf(k, sizeof(k), "captures[%zu].settings.exposure_us", i);
	if ((ret = number_or_null(c, k, 1)))
		return ret;
	snprintf(k, sizeof(k), "captures[%zu].settings.gain", i);
	if ((ret = number_or_null(c, k, 0)))
		return ret;
	snprintf(k, sizeof(k), "captures[%zu].settings.frames", i);
	if ((ret = kg_json_get_int(c->file, c->root, k, 1, 1L << 30, &n, c->err)))
		return ret;
	snprintf(k, sizeof(k), "captures[%zu].settings.format", i);
	if ((ret = check_format(c, k)))
		return ret;

	snprintf(prefix, sizeof(prefix), "frames/%s/", name);
	snprintf(k, sizeof(k), "captures[%zu].frames", i);
	if ((ret = kg_json_get(c->file, c->root, k, &o, c->err)))
		return ret;
	if (!json_is_array(o))
		return kg_fail(c->err, KG_EINVAL, "%s: %s: expected an array", c->file, k);
	for (size_t f = 0; f < json_array_size(o); f++) {
		snprintf(k, sizeof(k), "captures[%zu].frames[%zu]", i, f);
		if ((ret = file_entry(c, k, prefix)))
			return ret;
		snprintf(k, sizeof(k), "captures[%zu].frames[%zu].sequence", i, f);
		if ((ret = kg_json_get_int(c->file, c->root, k, 0, LONG_MAX, &n, c->err)))
			return ret;
	}
	snprintf(k, sizeof(k), "captures[%zu].exposure_helper.steps", i);
	json_t *steps = kg_json_find(c->root, k);
	for (size_t f = 0; f < json_array_size(steps); f++) {
		if (!json_object_get(json_array_get(steps, f), "file"))
			continue;
		snprintf(k, sizeof(k), "captures[%zu].exposure_helper.steps[%zu]", i, f);
		if ((ret = file_entry(c, k, prefix)))
			return ret;
	}

	snprintf(prefix, sizeof(prefix), "captures/%s/", name);
	snprintf(k, sizeof(k), "captures[%zu].outputs", i);
	if ((ret = kg_json_get(c->file, c->root, k, &o, c->err)))
		return ret;
	if (!json_is_object(o) || !json_object_get(o, "mean"))
		return kg_fail(c->err, KG_EINVAL, "%s: %s: expected an object with \"mean\"", c->file,
		               k);
	const char *key;
	json_t *e;
	json_object_foreach(o, key, e)
	{
		if (!kg_name_is_safe(key, KG_CAPTURE_NAME_MAX))
			return kg_fail(c->err, KG_EINVAL, "%s: %s: key '%s': expected a name of "
			               "[A-Za-z0-9._-]", c->file, k, key);
		char ko[PATH_KEY + KG_CAPTURE_NAME_MAX];
		snprintf(ko, sizeof(ko), "captures[%zu].outputs.%s", i, key);
		if ((ret = file_entry(c, ko, prefix)))
			return ret;
	}
	if ((ret = check_correction(c, i, "dark")) || (ret = check_correction(c, i, "flat")))
		return ret;
	json_t *meta = json_array_get(json_object_get(c->root, "captures"), i);
	meta = json_object_get(meta, "meta");
	snprintf(k, sizeof(k), "captures[%zu].meta", i);
	if (meta && (ret = kg_meta_validate(c->file, k, meta, c->err)))
		return ret;
	snprintf(k, sizeof(k), "captures[%zu].chart_layout", i);
	return check_layout(c, k, prefix);
}

int kg_session_id_ok(const char *id)
{
	static const char form[] = "xxxxxxxx-xxxx-xxxx-xxxx-xxxxxxxxxxxx";
	if (!id || strlen(id) != sizeof(form) - 1)
		return 0;
	for (size_t i = 0; form[i]; i++)
		if (form[i] == '-' ? id[i] != '-' : !strchr("0123456789abcdef", id[i]))
			return 0;
	return 1;
}

int kg_session_manifest_validate(const char *file, const json_t *root, kg_err *err)
{
	kg_check_arg(file && root, err);
	const char *slash = strrchr(file, '/');
	check_ctx c = {.file = file, .root = root, .err = err};
	c.dir = slash ? strndup(file, slash == file ? 1 : (size_t)(slash - file)) : strdup(".");
	if (!c.dir)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", file);
	const char *format;
	json_t *caps;
	int ret = json_is_object(root) ? 0 : kg_fail(err, KG_EINVAL, "%s: expected an object", file);
	if (!ret && !(ret = kg_json_get_string(file, root, "format", &format, err)) &&
	    strcmp(format, KG_SESSION_FORMAT))
		ret = kg_fail(err, KG_EINVAL, "%s: format '%s': expected \"%s\"", file, format,
		              KG_SESSION_FORMAT);
	const json_t *id = json_object_get(root, "id");
	if (!ret && id && !kg_session_id_ok(json_string_value(id)))
		ret = kg_fail(err, KG_EINVAL, "%s: id: expected a UUID (8-4-4-4-12 hexadecimal digits)",
		              file);
	if (!ret)
		ret = check_cameras(&c);
	if (!ret && !(ret = kg_json_get(file, root, "captures", &caps, err)) && !json_is_array(caps))
		ret = kg_fail(err, KG_EINVAL, "%s: captures: expected an array", file);
	for (size_t i = 0; !ret && i < json_array_size(caps); i++)
		ret = check_capture(&c, i);
	if (!ret)
		ret = kg_camera_recording_validate(c.dir, err);
	free(c.dir);
	return ret;
}
