/* The exposure helper of `kogei acquire --exposure auto` on the sim camera, checked
 * against the scene the camera looks at (the sim sensor is linear: level = scene x
 * exposure / ref_exposure_us), not against the helper's own measurements:
 * - mono and Bayer scenes without a chart: the 99.5th percentile of 5x5 same-colour
 *   means of the scene at the locked exposure must be at the target (brute force here);
 * - a rendered chart with --layout (needs AprilTag): the brightest patch's noise-free
 *   value (`kogei sim chart --truth`) at the locked exposure must be at the target,
 *   although the white card around the patches is brighter;
 * - a black scene: exit 1, the target out of reach, no capture in the session;
 * and the manifest: exposure mode auto, auto exposure read back off, steps recorded. */
#include "acq_test.h"
#include "kg_acquire.h"
#include "kg_core.h"

#define REF_EXPOSURE_US 10000.0 /* the sim camera's default ref_exposure_us */
/* The helper's tolerance (3 %) plus the frame noise of the measurement. */
#define TOLERANCE 0.04

static int cmp_float(const void *a, const void *b)
{
	float x = *(const float *)a, y = *(const float *)b;
	return x < y ? -1 : x > y;
}

/* Brute force: each sample replaced by the mean of same-colour samples within radius
 * r (step 2 on a mosaic), then the percentile (linear between order statistics). */
static double bright_level(const float *v, int w, int h, int mosaic, double scale)
{
	const int r = 2, step = mosaic ? 2 : 1;
	float *b = malloc(sizeof(float) * (size_t)(w * h));
	for (int y = 0; y < h; y++)
		for (int x = 0; x < w; x++) {
			double s = 0;
			int k = 0;
			for (int dy = -r; dy <= r; dy++)
				for (int dx = -r; dx <= r; dx++) {
					int X = x + dx * step, Y = y + dy * step;
					if (X < 0 || Y < 0 || X >= w || Y >= h)
						continue;
					s += fmin(1.0, v[Y * w + X] * scale);
					k++;
				}
			b[y * w + x] = (float)(s / k);
		}
	qsort(b, (size_t)(w * h), sizeof(float), cmp_float);
	double pos = 0.995 * (w * h - 1);
	int k = (int)pos;
	double out = b[k] + (pos - k) * (b[k + 1] - b[k]);
	free(b);
	return out;
}

/* The capture's locked exposure, after checking what the manifest says of the helper. */
static double check_manifest(const char *session, double target)
{
	json_t *root = acq_manifest(session);
	json_t *cap = json_array_get(json_object_get(root, "captures"), 0);
	json_t *st = json_object_get(cap, "settings");
	json_t *helper = json_object_get(cap, "exposure_helper");
	json_t *steps = json_object_get(helper, "steps");
	double t = json_number_value(json_object_get(st, "exposure_us"));
	const char *mode = json_string_value(json_object_get(st, "exposure_mode"));
	CHECK(mode && !strcmp(mode, "auto"), "%s: exposure_mode %s", session, mode ? mode : "null");
	CHECK(json_number_value(json_object_get(st, "auto_exposure")) == 0 &&
	          json_is_number(json_object_get(st, "auto_exposure")),
	      "%s: auto exposure not read back off", session);
	CHECK(json_array_size(steps) >= 1 && json_array_size(steps) <= 10, "%s: %zu steps", session,
	      json_array_size(steps));
	json_t *last = json_array_get(steps, json_array_size(steps) - 1);
	CHECK(fabs(json_number_value(json_object_get(last, "level")) - target) <= 0.03 * target,
	      "%s: last step level %g", session, json_number_value(json_object_get(last, "level")));
	CHECK(fabs(json_number_value(json_object_get(last, "exposure_us")) - t) <= 1e-9 * t,
	      "%s: locked %g differs from the last step", session, t);
	json_decref(root);
	CHECK(acq_check_session(session, NULL, 0) == 1, "%s: one capture", session);
	return t;
}

static void scene_helper(int bayer)
{
	const int w = 160, h = 120;
	kg_image *img;
	kg_err err = {{0}};
	kg_image_new(w, h, 3, &img, &err);
	for (int y = 0; y < h; y++)
		for (int x = 0; x < w; x++) {
			float *p = img->data + (y * w + x) * 3;
			double v = 0.05 + 0.2 * x / w;
			int in = x >= 100 && x < 124 && y >= 40 && y < 64; /* 3 % of the image */
			p[0] = (float)(in ? 0.5 : v);
			p[1] = (float)(in ? 0.6 : v);
			p[2] = (float)(in ? 0.3 : v);
		}
	char scene[4200], uri[4400], session[4200];
	snprintf(scene, sizeof(scene), "%s", kg_test_path(bayer ? "scene-bayer.tif" : "scene.tif"));
	snprintf(session, sizeof(session), "%s", kg_test_path(bayer ? "bayer" : "mono"));
	kg_image_write_tiff(img, scene, 32, &err);
	snprintf(uri, sizeof(uri), "sim:%s?format=%s&fullwell=100000&read=2", scene,
	         bayer ? "bayer_rggb12" : "mono16");
	double target = bayer ? 0.5 : 0.8;
	char tt[16];
	snprintf(tt, sizeof(tt), "%g", target);
	int rc = acq_run("acquire", "--camera", uri, "--out", session, "--kind", "object",
	                 "--frames", "2", "--exposure", "auto", "--target", tt, NULL);
	CHECK(rc == 0, "%s: exit %d: %s", session, rc, acq_errtext);
	if (rc) {
		kg_image_free(&img);
		return;
	}
	double t = check_manifest(session, target);
	/* what the sensor sees: luminance for mono, the CFA colour for Bayer */
	float *v = malloc(sizeof(float) * (size_t)(w * h));
	for (int y = 0; y < h; y++)
		for (int x = 0; x < w; x++) {
			const float *p = img->data + (y * w + x) * 3;
			int c = (y & 1) ? ((x & 1) ? 2 : 1) : ((x & 1) ? 1 : 0); /* RGGB */
			v[y * w + x] = bayer ? p[c] : (float)(0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]);
		}
	double level = bright_level(v, w, h, bayer, t / REF_EXPOSURE_US);
	CHECK(fabs(level - target) <= TOLERANCE * target,
	      "%s: at the locked %.6g us the scene's bright level is %.4f, target %.3f",
	      session, t, level, target);
	printf("%s: locked at %.6g us, scene bright level %.4f (target %.3f)\n",
	       bayer ? "bayer" : "mono", t, level, target);
	free(v);
	kg_image_free(&img);
}

static void chart_helper(void)
{
#if HAVE_APRILTAG
	char layout[4200], css[4200], chart[4200], truth[4200], uri[4400], session[4200];
	snprintf(layout, sizeof(layout), "%s/fixtures/demo/cie-tcs-frame.json", KG_SOURCE_ROOT);
	snprintf(css, sizeof(css), "%s/fixtures/demo/reference_camera.csv", KG_SOURCE_ROOT);
	snprintf(chart, sizeof(chart), "%s", kg_test_path("chart.tif"));
	snprintf(truth, sizeof(truth), "%s", kg_test_path("truth.cgats"));
	snprintf(session, sizeof(session), "%s", kg_test_path("chart"));
	int rc = acq_run("sim", "chart", "--layout", layout, "--camera", css, "--illuminant", "D65",
	                 "--width", "800", "--height", "600", "--depth", "float", "--threads", "1",
	                 "-o", chart, "--truth", truth, NULL);
	CHECK(rc == 0, "sim chart: exit %d: %s", rc, acq_errtext);
	if (rc)
		return;
	snprintf(uri, sizeof(uri), "sim:%s?format=rgb16&fullwell=100000", chart);
	rc = acq_run("acquire", "--camera", uri, "--out", session, "--kind", "chart", "--frames",
	             "2", "--exposure", "auto", "--target", "0.7", "--layout", layout, NULL);
	CHECK(rc == 0, "chart: exit %d: %s", rc, acq_errtext);
	if (rc)
		return;
	double t = check_manifest(session, 0.7);
	kg_patchset *ps = NULL;
	kg_err err = {{0}};
	CHECK(kg_patchset_read(truth, 0, &ps, &err) == 0 && ps->rgb, "%s: %s", truth, err.msg);
	double best = 0;
	for (int i = 0; ps && i < ps->n; i++)
		for (int c = 0; c < 3; c++)
			best = fmax(best, ps->rgb[i][c]);
	double level = best * t / REF_EXPOSURE_US;
	CHECK(fabs(level - 0.7) <= TOLERANCE * 0.7,
	      "chart: at %.6g us the brightest patch is %.4f, target 0.7", t, level);
	/* the card (paper 0.85 of the white level) is brighter than every patch, so the
	 * bright level of the image alone would have stopped lower */
	printf("chart: locked at %.6g us, brightest patch (truth) %.4f (target 0.7)\n", t, level);
	json_t *root = acq_manifest(session);
	json_t *steps = json_object_get(
		json_object_get(json_array_get(json_object_get(root, "captures"), 0), "exposure_helper"),
		"steps");
	const char *m = json_string_value(
		json_object_get(json_array_get(steps, json_array_size(steps) - 1), "measure"));
	CHECK(m && !strcmp(m, "chart"), "the last step was measured by %s", m ? m : "null");
	json_decref(root);
	kg_patchset_free(&ps);
#else
	printf("chart: built without AprilTag, not tested\n");
#endif
}

static void out_of_reach(void)
{
	kg_image *img;
	kg_err err = {{0}};
	kg_image_new(40, 30, 1, &img, &err); /* black */
	char scene[4200], uri[4400], session[4200];
	snprintf(scene, sizeof(scene), "%s", kg_test_path("black.tif"));
	snprintf(session, sizeof(session), "%s", kg_test_path("black"));
	kg_image_write_tiff(img, scene, 32, &err);
	kg_image_free(&img);
	snprintf(uri, sizeof(uri), "sim:%s?read=0", scene);
	int rc = acq_run("acquire", "--camera", uri, "--out", session, "--kind", "object",
	                 "--frames", "2", "--exposure", "auto", NULL);
	CHECK(rc == 1, "black scene: exit %d, expected 1", rc);
	CHECK(strstr(acq_errtext, "out of reach"), "black scene: %s", acq_errtext);
	json_t *root = acq_manifest(session);
	CHECK(!root || json_array_size(json_object_get(root, "captures")) == 0,
	      "black scene: a capture entered the session");
	json_decref(root);
}

int main(int argc, char **argv)
{
	acq_init(argc, argv, "acquire-exposure");
	scene_helper(0);
	scene_helper(1);
	chart_helper();
	out_of_reach();
	acq_cleanup();
	return kg_test_done("acquire-exposure");
}
