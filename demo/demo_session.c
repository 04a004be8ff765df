/* `kogei demo`: the bundled session (fixtures/demo/session, recorded by
 * fixtures/demo/make_session.sh) replayed through the replay: camera with acquire/, as
 * `kogei acquire --camera replay:SESSION#CAPTURE` would: the reference camera's chart
 * into DIR/lab-session, the site camera's chart and object into DIR/site-session,
 * which kogei process then takes as recorded sessions. */
#include <ftw.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "demo_private.h"
#include "kg_acquire.h"

static int remove_entry(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
	(void)st;
	(void)flag;
	(void)ftw;
	return remove(path);
}

/* A session a previous demo run left in dir is removed (captures keep their names
 * from run to run); anything else there is left for kg_session_open to refuse. */
static int clear_previous(const char *dir, kg_err *err)
{
	char *manifest = kg_path_join(dir, KG_SESSION_MANIFEST);
	if (!manifest)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	json_t *root = NULL;
	int ret = 0;
	if (access(manifest, F_OK) == 0 && kg_json_load(manifest, &root, NULL) == 0) {
		const char *format = json_string_value(json_object_get(root, "format"));
		if (format && !strcmp(format, KG_SESSION_FORMAT) &&
		    nftw(dir, remove_entry, 16, FTW_DEPTH | FTW_PHYS) != 0)
			ret = kg_fail(err, KG_EIO, "%s: cannot remove the previous demo session", dir);
	}
	json_decref(root);
	free(manifest);
	return ret;
}

static void note(void *user, const char *message)
{
	(void)user;
	printf("  note: %s\n", message);
}

/* The options that reproduce a bundled capture: its kind, frame count, settings. */
static int options_from(const char *file, const json_t *cap, kg_capture_options *o,
                        kg_err *err)
{
	const char *kind, *pixfmt, *cfa;
	long frames, bits, w, h, ox, oy;
	double exposure;
	const json_t *gain = kg_json_find(cap, "settings.gain");
	int ret;
	if ((ret = kg_json_get_string(file, cap, "kind", &kind, err)) ||
	    (ret = kg_capture_kind_parse(kind, &o->kind, err)) ||
	    (ret = kg_json_get_int(file, cap, "settings.frames", 1, 100000, &frames, err)) ||
	    (ret = kg_json_get_number(file, cap, "settings.exposure_us", &exposure, err)) ||
	    (ret = kg_json_get_string(file, cap, "settings.format.pixfmt", &pixfmt, err)) ||
	    (ret = kg_pixfmt_parse(pixfmt, &o->format.pixfmt, NULL, NULL, err)) ||
	    (ret = kg_json_get_int(file, cap, "settings.format.bits", 1, 16, &bits, err)) ||
	    (ret = kg_json_get_string(file, cap, "settings.format.cfa", &cfa, err)) ||
	    (ret = kg_json_get_int(file, cap, "settings.format.width", 1, 1L << 20, &w, err)) ||
	    (ret = kg_json_get_int(file, cap, "settings.format.height", 1, 1L << 20, &h, err)) ||
	    (ret = kg_json_get_int(file, cap, "settings.format.offset_x", 0, 1L << 20, &ox, err)) ||
	    (ret = kg_json_get_int(file, cap, "settings.format.offset_y", 0, 1L << 20, &oy, err)))
		return ret;
	if (strlen(cfa) >= sizeof(o->format.cfa))
		return kg_fail(err, KG_EINVAL, "%s: settings.format.cfa '%s': expected 4 letters",
		               file, cfa);
	o->frames = (int)frames;
	o->exposure_us = exposure;
	o->gain = json_is_number(gain) ? json_number_value(gain) : NAN;
	o->format.bits = (int)bits;
	snprintf(o->format.cfa, sizeof(o->format.cfa), "%s", cfa);
	o->format.width = (int)w;
	o->format.height = (int)h;
	o->format.offset_x = (int)ox;
	o->format.offset_y = (int)oy;
	o->dark = "none"; /* the bundle has no darks or flats; its captures were taken without */
	o->flat = "none";
	o->chart_layout = json_string_value(json_object_get(cap, "chart_layout"));
	return 0;
}

void demo_photos_free(demo_photos *p)
{
	kg_image_free(&p->reference_chart);
	kg_image_free(&p->site_chart);
	kg_image_free(&p->object);
}

int demo_session_replay(demo_ctx *d, demo_photos *out)
{
	static const char *const names[3] = {DEMO_CAPTURE_REFERENCE, DEMO_CAPTURE_SITE,
	                                     DEMO_CAPTURE_OBJECT};
	static const char *const into[3] = {"lab-session", "site-session", "site-session"};
	kg_image **slots[3] = {&out->reference_chart, &out->site_chart, &out->object};
	memset(out, 0, sizeof(*out));
	char *bundle = kg_data_path(DEMO_SESSION);
	char *bundle_manifest = bundle ? kg_path_join(bundle, KG_SESSION_MANIFEST) : NULL;
	char *lab = demo_path(d, into[0]), *site = demo_path(d, into[1]);
	json_t *recorded = NULL;
	kg_session *sessions[2] = {NULL, NULL};
	int ret = bundle_manifest && lab && site ? 0 : kg_fail(&d->err, KG_ENOMEM, "out of memory");
	if (!ret && access(bundle_manifest, R_OK) != 0)
		ret = kg_fail(&d->err, KG_ENOENT,
		              "%s: the bundled demo session is missing (fixtures/demo/session; "
		              "fixtures/demo/make_session.sh records it)",
		              bundle_manifest);
	if (!ret)
		ret = kg_json_load(bundle_manifest, &recorded, &d->err);
	for (int k = 0; k < 2 && !ret; k++) {
		const char *dir = k ? site : lab;
		ret = clear_previous(dir, &d->err);
		if (!ret)
			ret = kg_session_open(dir, &sessions[k], &d->err);
	}
	for (int i = 0; i < 3 && !ret; i++) {
		kg_session *s = sessions[i ? 1 : 0];
		const json_t *cap = NULL, *c;
		size_t k;
		json_array_foreach(json_object_get(recorded, "captures"), k, c)
		{
			const char *n = json_string_value(json_object_get(c, "name"));
			if (n && !strcmp(n, names[i]))
				cap = c;
		}
		if (!cap) {
			ret = kg_fail(&d->err, KG_EINVAL, "%s: no capture '%s'", bundle_manifest,
			              names[i]);
			break;
		}
		kg_capture_options o;
		kg_capture_options_default(&o);
		o.name = names[i];
		o.note = note;
		if ((ret = options_from(bundle_manifest, cap, &o, &d->err)))
			break;
		char uri[4200];
		snprintf(uri, sizeof(uri), "replay:%s#%s", bundle, names[i]);
		kg_camera *camera = NULL;
		kg_capture_result res;
		memset(&res, 0, sizeof(res));
		ret = kg_camera_open(uri, &camera, &d->err);
		if (!ret)
			ret = kg_capture_run(s, camera, &o, &res, &d->err);
		kg_camera_free(&camera);
		if (ret) {
			kg_capture_result_clear(&res);
			break;
		}
		/* The recording's outputs are not bundled, their sha256 are: compare. */
		const char *want =
			json_string_value(kg_json_find(cap, "outputs.mean.sha256"));
		const json_t *mine = kg_session_find(s, names[i]);
		const char *got = json_string_value(kg_json_find(mine, "outputs.mean.sha256"));
		printf("  replayed %s: %d frames of %s%s%s %dx%d, exposure %.6g us; mean %s\n",
		       names[i], o.frames, kg_pixfmt_name(res.format.pixfmt),
		       res.format.cfa[0] ? " " : "", res.format.cfa, res.format.width,
		       res.format.height, res.exposure_us,
		       want && got && !strcmp(want, got)
		           ? "bit-identical to the recording's"
		           : "differs from the recording's (another kogei version wrote it)");
		char rel[128];
		snprintf(rel, sizeof(rel), "%s/captures/%s/%s.tif", into[i], names[i],
		         res.rgb ? "rgb" : "mean");
		char *path = demo_path(d, rel);
		if (path)
			demo_wrote(d, path, res.rgb ? "the averaged photograph, demosaiced (float TIFF)"
			                            : "the averaged photograph (float TIFF)");
		free(path);
		/* charts: the demosaiced RGB, else the raw mosaic (its CFA attached, which
		 * chart detection demosaics itself); the object: its RGB mean */
		if (res.rgb) {
			*slots[i] = res.rgb;
			res.rgb = NULL;
		} else {
			*slots[i] = res.mean;
			res.mean = NULL;
		}
		kg_capture_result_clear(&res);
	}
	if (ret)
		demo_photos_free(out);
	kg_session_free(&sessions[0]);
	kg_session_free(&sessions[1]);
	json_decref(recorded);
	free(bundle);
	free(bundle_manifest);
	free(lab);
	free(site);
	return ret;
}
