/* Which capture of which session an image file is, and the camera that took it
 * (kg_session_image_identify, kg_acquire.h). */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "acquire_private.h"

/* 1 when dir/session.json exists and its format is kogei-session/1; *ret is the
 * validation's result (kg_session_manifest_validate) of such a manifest. */
static int is_session(const char *dir, json_t **root, int *ret, kg_err *err)
{
	char path[PATH_MAX + 16];
	struct stat st;
	snprintf(path, sizeof(path), "%s/%s", dir, KG_SESSION_MANIFEST);
	if (stat(path, &st) != 0 || !S_ISREG(st.st_mode))
		return 0;
	kg_err ignored = {{0}};
	json_t *r = NULL;
	if (kg_json_load(path, &r, &ignored))
		return 0;
	const char *f = json_string_value(json_object_get(r, "format"));
	if (!f || strcmp(f, KG_SESSION_FORMAT) != 0) {
		json_decref(r);
		return 0;
	}
	*root = r;
	*ret = kg_session_manifest_validate(path, r, err);
	return 1;
}

static void copy_string(char *dst, size_t n, const json_t *v, const char *fallback)
{
	const char *s = json_string_value(v);
	snprintf(dst, n, "%s", s ? s : fallback);
}

int kg_session_image_identify(const char *image_path, kg_session_image *out, kg_err *err)
{
	kg_check_arg(image_path && out, err);
	memset(out, 0, sizeof(*out));
	char full[PATH_MAX];
	if (!realpath(image_path, full))
		return kg_fail(err, KG_ENOENT, "%s: %s", image_path, strerror(errno));
	/* Walk up: full = SESSION/captures/NAME/FILE. */
	json_t *root = NULL;
	char dir[PATH_MAX];
	snprintf(dir, sizeof(dir), "%s", full);
	const char *rel = NULL;
	int ret = 0;
	for (char *slash; !root && (slash = strrchr(dir, '/')) != NULL;) {
		*slash = 0;
		if (is_session(dir[0] ? dir : "/", &root, &ret, err))
			rel = full + (slash - dir) + 1;
	}
	if (ret) {
		json_decref(root);
		return ret;
	}
	if (!root)
		return kg_fail(err, KG_ENOENT, "%s: not inside a kogei session (no %s of format "
		               "%s in any directory above it)", image_path, KG_SESSION_MANIFEST,
		               KG_SESSION_FORMAT);
	char name[KG_CAPTURE_NAME_MAX] = "";
	const char *file = NULL;
	if (strncmp(rel, "captures/", 9) == 0) {
		const char *n = rel + 9, *end = strchr(n, '/');
		if (end && (size_t)(end - n) < sizeof(name) && !strchr(end + 1, '/')) {
			memcpy(name, n, (size_t)(end - n));
			name[end - n] = 0;
			file = end + 1;
		}
	}
	char manifest[PATH_MAX + 16];
	snprintf(manifest, sizeof(manifest), "%s/%s", dir, KG_SESSION_MANIFEST);
	if (!file || !kg_capture_name_ok(name)) {
		ret = kg_fail(err, KG_ENOENT, "%s: in session %s but not a capture's output "
		              "(expected captures/<capture>/<file>)", image_path, dir);
		goto done;
	}
	json_t *caps = json_object_get(root, "captures"), *cap = NULL, *c;
	size_t i;
	json_array_foreach(caps, i, c)
	{
		const char *cn = json_string_value(json_object_get(c, "name"));
		if (cn && strcmp(cn, name) == 0)
			cap = c;
	}
	if (!cap) {
		ret = kg_fail(err, KG_EINVAL, "%s: captures: no capture named %s (the image %s "
		              "belongs to a capture that did not finish)", manifest, name,
		              image_path);
		goto done;
	}
	const char *cam_id = json_string_value(json_object_get(cap, "camera"));
	json_t *cams = kg_json_find(root, "devices.cameras"), *cam = NULL;
	json_array_foreach(cams, i, c)
	{
		const char *id = json_string_value(json_object_get(c, "id"));
		if (cam_id && id && strcmp(id, cam_id) == 0)
			cam = c;
	}
	if (!cam) {
		ret = kg_fail(err, KG_EINVAL, "%s: capture %s: camera \"%s\": expected the id of "
		              "an entry of devices.cameras", manifest, name, cam_id ? cam_id : "");
		goto done;
	}
	long bits = 0;
	json_t *fmt = kg_json_find(cap, "settings.format");
	const char *pixfmt = json_string_value(json_object_get(fmt, "pixfmt"));
	json_t *b = json_object_get(fmt, "bits");
	if (!pixfmt || !json_is_integer(b) || (bits = (long)json_integer_value(b)) < 1 || bits > 32) {
		ret = kg_fail(err, KG_EINVAL, "%s: capture %s: settings.format: expected pixfmt "
		              "(a string) and bits (1..32)", manifest, name);
		goto done;
	}
	snprintf(out->session, sizeof(out->session), "%s", dir);
	snprintf(out->capture, sizeof(out->capture), "%s", name);
	copy_string(out->backend, sizeof(out->backend), json_object_get(cam, "backend"), "");
	copy_string(out->model, sizeof(out->model), json_object_get(cam, "model"), "");
	copy_string(out->serial, sizeof(out->serial), json_object_get(cam, "serial"), "");
	snprintf(out->pixfmt, sizeof(out->pixfmt), "%s", pixfmt);
	out->bits = (int)bits;
	out->white_level = (1L << bits) - 1;
	copy_string(out->demosaic, sizeof(out->demosaic),
	            kg_json_find(cap, "demosaic.algorithm"), "none");
done:
	json_decref(root);
	return ret;
}
