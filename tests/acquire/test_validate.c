/* Every reader of a session validates it first (kg_session_manifest_validate,
 * kg_camera_recording_validate): a session.json, frames/index.jsonl or
 * frames/camera.json with a wrong type, a value out of range, an unsafe or duplicate
 * capture name, a path leaving the session or a referenced file that is not there, a
 * chart_layout that is neither a bundled layout's name nor a file of captures/NAME/ is
 * refused, naming the file and the key, by `kogei acquire` adding a capture (exit 1,
 * the session left as it was), by replay: and by kg_session_image_identify. A --name
 * outside [A-Za-z0-9._-] is a usage error that creates nothing. */
#include "acq_test.h"
#include "kg_acquire.h"

#define CAM "sim:?width=32&height=24"

static char base[4200];

static int contains(const char *hay, const char *needle) { return strstr(hay, needle) != NULL; }

static void copy_session(const char *to)
{
	char cmd[16384];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s' && cp -a '%s' '%s'", to, base, to);
	CHECK(system(cmd) == 0, "cannot copy the session to %s", to);
}

/* Rewrite SESSION/rel with fn applied to its JSON (one document, or each line of a
 * .jsonl when line >= 1: only that line). */
typedef void (*mutate_fn)(json_t *o);

static void mutate_json(const char *session, const char *rel, mutate_fn fn)
{
	char path[8400];
	snprintf(path, sizeof(path), "%s/%s", session, rel);
	json_t *o = json_load_file(path, 0, NULL);
	CHECK(o != NULL, "%s: cannot load", path);
	if (!o)
		return;
	fn(o);
	CHECK(json_dump_file(o, path, JSON_INDENT(2)) == 0, "%s: cannot write", path);
	json_decref(o);
}

static void mutate_first_line(const char *session, mutate_fn fn)
{
	char path[8400];
	snprintf(path, sizeof(path), "%s/frames/index.jsonl", session);
	static char buf[1 << 20];
	acq_slurp(path, buf, sizeof(buf));
	char *nl = strchr(buf, '\n');
	CHECK(nl != NULL, "%s: no line", path);
	if (!nl)
		return;
	*nl = 0;
	json_t *o = json_loads(buf, 0, NULL);
	fn(o);
	char *text = json_dumps(o, JSON_COMPACT);
	FILE *fp = fopen(path, "wb");
	fprintf(fp, "%s\n%s", text, nl + 1);
	fclose(fp);
	free(text);
	json_decref(o);
}

static json_t *cap(json_t *root, size_t i)
{
	return json_array_get(json_object_get(root, "captures"), i);
}

static void m_string_exposure(json_t *r)
{
	json_object_set_new(json_object_get(cap(r, 1), "settings"), "exposure_us",
	                    json_string("fast"));
}
static void m_negative_width(json_t *r)
{
	json_object_set_new(json_object_get(json_object_get(cap(r, 1), "settings"), "format"),
	                    "width", json_integer(-32));
}
static void m_duplicate_name(json_t *r)
{
	json_object_set_new(cap(r, 1), "name", json_string("dark-0001"));
}
static void m_dotdot_name(json_t *r)
{
	json_object_set_new(cap(r, 0), "name", json_string("../../etc"));
	json_object_set_new(json_object_get(cap(r, 1), "corrections"), "dark",
	                    json_string("../../etc"));
}
static void m_dotdot_file(json_t *r)
{
	json_object_set_new(json_object_get(json_object_get(cap(r, 0), "outputs"), "mean"),
	                    "file", json_string("captures/dark-0001/../../../etc/passwd"));
}
static void m_missing_file(json_t *r)
{
	json_object_set_new(json_object_get(json_object_get(cap(r, 0), "outputs"), "mean"),
	                    "file", json_string("captures/dark-0001/gone.tif"));
}
static void m_unknown_dark(json_t *r)
{
	json_object_set_new(json_object_get(cap(r, 1), "corrections"), "dark",
	                    json_string("dark-0099"));
}
static void m_unknown_camera(json_t *r)
{
	json_object_set_new(cap(r, 1), "camera", json_string("camera-9"));
}
/* chart_layout: only a bundled layout's name or a file under captures/<name>/ */
static void m_layout_passwd(json_t *r)
{
	json_object_set_new(cap(r, 1), "chart_layout", json_string("/etc/passwd"));
}
static void m_layout_dotdot(json_t *r)
{
	json_object_set_new(cap(r, 1), "chart_layout", json_string("../layout.json"));
}
static void m_layout_escape(json_t *r)
{
	json_object_set_new(cap(r, 1), "chart_layout",
	                    json_string("captures/object-0001/../../../etc/passwd"));
}
static void m_layout_other(json_t *r) /* a real file of the session, not this capture's */
{
	json_object_set_new(cap(r, 1), "chart_layout", json_string("frames/camera.json"));
}
static void m_line_capture(json_t *o) { json_object_set_new(o, "capture", json_string("..")); }
static void m_line_file(json_t *o)
{
	json_object_set_new(o, "file", json_string("frames/dark-0001/../../session.json"));
}
static void m_line_exposure(json_t *o)
{
	json_object_set_new(o, "exposure_us", json_string("fast"));
}
static void m_line_bytes(json_t *o) { json_object_set_new(o, "bytes", json_integer(7)); }
static void m_camera_width(json_t *r)
{
	json_object_set_new(json_object_get(r, "camera"), "sensor_width", json_string("wide"));
}

typedef struct bad_case {
	const char *what;
	const char *file; /* "session.json", "frames/camera.json", or NULL: index line 1 */
	mutate_fn fn;
	const char *needle; /* in every reader's message */
	int manifest;       /* 1: the manifest is wrong (replay: does not read it) */
} bad_case;

static void refused(const bad_case *b, int n)
{
	char s[4400], manifest[4500], before[1 << 16], after[1 << 16];
	snprintf(s, sizeof(s), "%s", kg_test_path("bad"));
	for (int i = 0; i < n; i++) {
		copy_session(s);
		if (b[i].file)
			mutate_json(s, b[i].file, b[i].fn);
		else
			mutate_first_line(s, b[i].fn);
		snprintf(manifest, sizeof(manifest), "%s/session.json", s);
		acq_slurp(manifest, before, sizeof(before));

		int rc = acq_run("acquire", "--camera", CAM, "--out", s, "--kind", "object",
		                 "--frames", "1", NULL);
		CHECK(rc == 1, "%s: acquire: exit %d, expected 1 (%s)", b[i].what, rc, acq_errtext);
		CHECK(contains(acq_errtext, b[i].needle), "%s: acquire does not say '%s': %s",
		      b[i].what, b[i].needle, acq_errtext);
		acq_slurp(manifest, after, sizeof(after));
		CHECK(!strcmp(before, after), "%s: the manifest changed", b[i].what);
		char out3[4600];
		snprintf(out3, sizeof(out3), "%s/captures/object-0002", s);
		CHECK(!kg_test_file_exists(out3), "%s: a capture was added", b[i].what);

		json_t *root = json_load_file(manifest, 0, NULL);
		kg_err err = {{0}};
		int ret = kg_session_manifest_validate(manifest, root, &err);
		CHECK(ret == KG_EINVAL && contains(err.msg, b[i].needle),
		      "%s: kg_session_manifest_validate: %d: %s", b[i].what, ret, err.msg);
		json_decref(root);

		kg_session_image img;
		char tif[4600];
		snprintf(tif, sizeof(tif), "%s/captures/object-0001/mean.tif", s);
		memset(&err, 0, sizeof(err));
		ret = kg_session_image_identify(tif, &img, &err);
		CHECK(ret == KG_EINVAL && contains(err.msg, b[i].needle),
		      "%s: kg_session_image_identify: %d: %s", b[i].what, ret, err.msg);

		char uri[4500];
		snprintf(uri, sizeof(uri), "replay:%s", s);
		kg_camera *c = NULL;
		memset(&err, 0, sizeof(err));
		ret = kg_camera_open(uri, &c, &err);
		if (b[i].manifest)
			CHECK(ret == 0, "%s: replay: does not read the manifest, yet: %s", b[i].what,
			      err.msg);
		else
			CHECK(ret == KG_EINVAL && contains(err.msg, b[i].needle),
			      "%s: replay: %d: %s", b[i].what, ret, err.msg);
		kg_camera_free(&c);
	}
}

int main(int argc, char **argv)
{
	acq_init(argc, argv, "validate");
	snprintf(base, sizeof(base), "%s", kg_test_path("base"));
	int rc = acq_run("acquire", "--camera", CAM, "--out", base, "--kind", "dark", "--frames",
	                 "2", "--exposure", "1000", NULL);
	CHECK(rc == 0, "dark: exit %d: %s", rc, acq_errtext);
	rc = acq_run("acquire", "--camera", CAM, "--out", base, "--kind", "object", "--frames",
	             "2", "--exposure", "1000", NULL);
	CHECK(rc == 0, "object: exit %d: %s", rc, acq_errtext);
	CHECK(contains(acq_errtext, "dark dark-0001 subtracted"), "the dark was not used: %s",
	      acq_errtext);

	/* The untouched session passes every reader. */
	char manifest[4500];
	snprintf(manifest, sizeof(manifest), "%s/session.json", base);
	json_t *root = json_load_file(manifest, 0, NULL);
	kg_err err = {{0}};
	CHECK(kg_session_manifest_validate(manifest, root, &err) == 0, "valid session: %s",
	      err.msg);
	json_decref(root);

	static const bad_case cases[] = {
		{"string exposure", "session.json", m_string_exposure,
		 "captures[1].settings.exposure_us", 1},
		{"negative width", "session.json", m_negative_width,
		 "captures[1].settings.format.width", 1},
		{"duplicate name", "session.json", m_duplicate_name, "expected unique names", 1},
		{"name ../../etc as the dark", "session.json", m_dotdot_name,
		 "captures[0].name: '../../etc'", 1},
		{"output leaving the session", "session.json", m_dotdot_file,
		 "captures[0].outputs.mean.file", 1},
		{"output not there", "session.json", m_missing_file,
		 "captures[0].outputs.mean.file: 'captures/dark-0001/gone.tif': expected a regular file",
		 1},
		{"unknown dark", "session.json", m_unknown_dark, "captures[1].corrections.dark", 1},
		{"unknown camera", "session.json", m_unknown_camera, "captures[1].camera", 1},
		{"chart_layout /etc/passwd", "session.json", m_layout_passwd,
		 "captures[1].chart_layout: '/etc/passwd': expected a bundled chart layout", 1},
		{"chart_layout ../", "session.json", m_layout_dotdot,
		 "captures[1].chart_layout: '../layout.json'", 1},
		{"chart_layout leaving captures/NAME", "session.json", m_layout_escape,
		 "captures[1].chart_layout: 'captures/object-0001/../../../etc/passwd'", 1},
		{"chart_layout elsewhere in the session", "session.json", m_layout_other,
		 "captures[1].chart_layout: 'frames/camera.json'", 1},
		{"index: capture ..", NULL, m_line_capture, "line 1: capture '..'", 0},
		{"index: file leaving frames/", NULL, m_line_file,
		 "line 1: file 'frames/dark-0001/../../session.json'", 0},
		{"index: string exposure", NULL, m_line_exposure, "line 1: exposure_us", 0},
		{"index: wrong size", NULL, m_line_bytes, "expected bytes 7", 0},
		{"camera.json: string width", "frames/camera.json", m_camera_width,
		 "camera.sensor_width", 0},
	};
	refused(cases, (int)(sizeof(cases) / sizeof(cases[0])));

	/* --name outside the safe set: a usage error, nothing created. */
	const char *fresh = kg_test_path("fresh");
	static const char *const names[] = {"../../etc", ".hidden", "a/b", "sp ace"};
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++) {
		rc = acq_run("acquire", "--camera", CAM, "--out", fresh, "--kind", "object", "--name",
		             names[i], "--frames", "1", NULL);
		CHECK(rc == 2 && contains(acq_errtext, "--name"), "--name %s: exit %d: %s", names[i],
		      rc, acq_errtext);
		CHECK(!kg_test_file_exists(fresh), "--name %s: the session was created", names[i]);
	}
	acq_cleanup();
	return kg_test_done("acquire-validate");
}
