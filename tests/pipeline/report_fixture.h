/* A synthetic processed session for the report's tests: OUTDIR/process.json in the
 * kogei-process/1 schema (docs/formats.md) and the small PNGs it names, written with
 * core's PNG writer. Every number is made up and chosen so that a test can find it
 * in the page: patch i has dE00(D50) = 0.50 + 0.10 i and dE00(D65) = 0.55 + 0.10 i. */
#ifndef REPORT_FIXTURE_H
#define REPORT_FIXTURE_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_core.h"

#define FIXTURE_PATCHES 24
#define FIXTURE_SCRIPT "<script>alert('x')</script> & \"quoted\""

static const char *const fixture_patch_names[FIXTURE_PATCHES] = {
	"dark skin", "light skin", "blue sky", "foliage", "blue flower", "bluish green",
	"orange", "purplish blue", "moderate red", "purple", "yellow green", "orange yellow",
	"blue", "green", "red", "yellow", "magenta", "cyan",
	"white 9.5", "neutral 8", "neutral 6.5", "neutral 5", "neutral 3.5", "black 2",
};

/* A smooth made-up reflectance: a level plus a bump centred at c nm. */
static json_t *fixture_spectrum(double level, double bump, double c)
{
	double v[KG_NBANDS];
	for (int b = 0; b < KG_NBANDS; b++) {
		double x = (kg_band_nm(b) - c) / 60;
		v[b] = level + bump * exp(-x * x);
	}
	json_t *a = json_array();
	for (int b = 0; b < KG_NBANDS; b++)
		json_array_append_new(a, json_real(v[b]));
	return a;
}

/* An RGB8 image of w x h with a pattern depending on `kind` (0 photo, 1 labels,
 * 2 confidence, 3 overlay). */
static int fixture_png(const char *dir, const char *name, int w, int h, int kind)
{
	unsigned char *rgb = malloc((size_t)w * h * 3);
	if (!rgb)
		return -1;
	static const unsigned char classes[4][3] = {{40, 40, 40}, {212, 175, 55}, {60, 60, 90},
	                                            {150, 30, 20}};
	for (int y = 0; y < h; y++)
		for (int x = 0; x < w; x++) {
			unsigned char *p = rgb + 3 * ((size_t)y * w + x);
			int c = (x * 4 / w + y * 2 / h) % 4;
			switch (kind) {
			case 0: p[0] = (unsigned char)(255 * x / w); p[1] = (unsigned char)(255 * y / h);
			        p[2] = 120; break;
			case 1: memcpy(p, classes[c], 3); break;
			case 2: p[0] = p[1] = p[2] = (unsigned char)(255 * (x + y) / (w + h)); break;
			default: p[0] = p[1] = p[2] = (x / 8 + y / 8) % 2 ? 200 : 90;
			}
		}
	char *path = kg_path_join(dir, name);
	kg_err err;
	int ret = path ? kg_png_write_rgb8(path, rgb, w, h, &err) : -1;
	if (ret)
		fprintf(stderr, "%s: %s\n", name, err.msg);
	free(path);
	free(rgb);
	return ret;
}

/* An empty stand-in for a file the report only names (cube, label map). */
static int fixture_touch(const char *dir, const char *name)
{
	char *path = kg_path_join(dir, name);
	FILE *f = path ? fopen(path, "w") : NULL;
	int ret = f && fclose(f) == 0 ? 0 : -1;
	free(path);
	return ret;
}

static json_t *fixture_patches(void)
{
	json_t *patches = json_array();
	for (int i = 0; i < FIXTURE_PATCHES; i++) {
		char id[8];
		snprintf(id, sizeof(id), "%c%02d", 'A' + i / 6, i % 6 + 1);
		int neutral = i >= 18;
		int has_spectra = i != FIXTURE_PATCHES - 1; /* the last: no measured spectrum */
		double level = neutral ? 0.9 - 0.17 * (i - 18) : 0.08 + 0.01 * i;
		json_t *p = json_pack("{s:s, s:s, s:[f,f,f], s:i, s:b, s:s}", "id", id, "name",
		                      fixture_patch_names[i], "rgb", level, level * 0.9, level * 0.8,
		                      "flags", i == 2 ? 4 : 0, "used", i != 2, "warning",
		                      i == 2 ? "clipped in green (12% of its pixels)" : "");
		json_object_set_new(p, "measured", has_spectra
		                    ? fixture_spectrum(level, neutral ? 0 : 0.3, 420 + 12 * i)
		                    : json_null());
		json_object_set_new(p, "estimated",
		                    fixture_spectrum(level * 1.02, neutral ? 0.01 : 0.28, 424 + 12 * i));
		json_object_set_new(p, "de00_d50", has_spectra ? json_real(0.5 + 0.1 * i) : json_null());
		json_object_set_new(p, "de00_d65", has_spectra ? json_real(0.55 + 0.1 * i) : json_null());
		/* held out (leave-one-out): worse than in-sample, as refits without a patch are */
		json_object_set_new(p, "de00_d50_heldout",
		                    has_spectra ? json_real(0.6 + 0.11 * i) : json_null());
		json_object_set_new(p, "dL", has_spectra ? json_real(neutral ? -0.31 - 0.1 * (i - 18)
		                                                           : 0.2) : json_null());
		json_object_set_new(p, "dab", has_spectra ? json_real(neutral ? 0.41 + 0.1 * (i - 18)
		                                                            : 0.7) : json_null());
		json_object_set_new(p, "neutral", json_boolean(neutral));
		json_array_append_new(patches, p);
	}
	return patches;
}

static json_t *fixture_object(const char *capture, int skipped, int rendered)
{
	static const char *const names[3] = {"gold", "shakudo", "urushi"};
	static const int colours[3][3] = {{212, 175, 55}, {60, 60, 90}, {150, 30, 20}};
	json_t *classes = json_array();
	for (int c = 0; c < 3; c++) {
		json_t *k = json_pack("{s:s, s:i, s:f, s:[i,i,i]}", "name", names[c], "pixels",
		                      300 + 100 * c, "fraction", (300 + 100 * c) / 3072.0, "colour",
		                      colours[c][0], colours[c][1], colours[c][2]);
		json_object_set_new(k, "mean_spectrum", fixture_spectrum(0.1 + 0.2 * (2 - c), 0.2, 600 - 80 * c));
		json_object_set_new(k, "model_spectrum", c == 2 ? json_null()
		                    : fixture_spectrum(0.1 + 0.2 * (2 - c), 0.25, 590 - 80 * c));
		json_array_append_new(classes, k);
	}
	char photo[64], labels[64], labels_png[64], conf[64], cube[64], scene[64], render[64];
	snprintf(photo, sizeof(photo), "%s/photo.png", capture);
	snprintf(labels, sizeof(labels), "%s/labels.hdr", capture);
	snprintf(labels_png, sizeof(labels_png), "%s/labels.png", capture);
	snprintf(conf, sizeof(conf), "%s/confidence.png", capture);
	snprintf(cube, sizeof(cube), "%s/cube.hdr", capture);
	snprintf(scene, sizeof(scene), "%s/scene.json", capture);
	snprintf(render, sizeof(render), "%s/render.png", capture);
	json_t *o = json_pack("{s:s, s:s, s:b, s:i, s:i, s:i, s:f, s:s, s:n, s:i, s:i, s:s, s:s,"
	                      " s:s, s:s, s:s, s:s}",
	                      "capture", capture, "dir", capture, "skipped", skipped,
	                      "exposure_us", 5000, "gain", 0, "frames", 16, "exposure_scale", 2.0,
	                      "dark", "dark-0001", "flat", "width", 64, "height", 48, "photo",
	                      photo, "labels", labels, "labels_png", labels_png,
	                      "confidence_png", conf, "cube", cube, "scene", scene);
	json_object_set_new(o, "render", rendered ? json_string(render) : json_null());
	/* the first object has its master (Adobe RGB, under D65), the second none */
	char master[64];
	snprintf(master, sizeof(master), "%s/master.tif", capture);
	json_object_set_new(o, "master", skipped ? json_null()
	                    : json_pack("{s:s, s:s, s:s, s:s, s:s, s:i, s:s}", "path", master,
	                                "space", "adobe-rgb", "profile",
	                                "Adobe RGB (1998) compatible", "illuminant", "D65",
	                                "intent", "relative colorimetric", "clipped_pixels", 7,
	                                "clipped_counted", "lit pixels"));
	json_object_set_new(o, "pixels", json_integer(3072));
	json_object_set_new(o, "unknown_fraction", json_real(0.02));
	json_object_set_new(o, "background_fraction", json_real(0.6));
	json_object_set_new(o, "unclassified_fraction", json_real(0.001));
	json_object_set_new(o, "classes", classes);
	json_object_set_new(o, "warnings", skipped ? json_array()
	                    : json_pack("[s]", "3.1% of the pixels are unknown: no declared "
	                                       "material explains them"));
	return o;
}

/* Write the whole synthetic OUTDIR; 0 on success. */
static int fixture_write(const char *outdir)
{
	kg_err err;
	if (kg_mkdir_p(outdir, &err))
		return fprintf(stderr, "%s\n", err.msg), -1;
	const char *captures[2] = {"object-0001", "object-0002"};
	for (int i = 0; i < 2; i++) {
		char *dir = kg_path_join(outdir, captures[i]);
		int ret = !dir || kg_mkdir_p(dir, &err) || fixture_png(dir, "photo.png", 64, 48, 0) ||
		          fixture_png(dir, "labels.png", 64, 48, 1) ||
		          fixture_png(dir, "confidence.png", 64, 48, 2) ||
		          (i == 1 && fixture_png(dir, "render.png", 64, 48, 0)) ||
		          fixture_touch(dir, "cube.hdr") || fixture_touch(dir, "labels.hdr") ||
		          (i == 0 && fixture_touch(dir, "master.tif"));
		free(dir);
		if (ret)
			return -1;
	}
	if (fixture_png(outdir, "chart_overlay.png", 120, 80, 3) ||
	    fixture_touch(outdir, "camera.icc") || fixture_touch(outdir, "camera.ti3"))
		return -1;

	json_t *calib = json_pack(
		"{s:s, s:s, s:s, s:s, s:[i,i,i,i], s:f, s:s, s:i, s:i, s:s, s:i, s:s, s:n,"
		" s:f, s:f, s:[f,f,f,f,f,f,f,f,f], s:f}",
		"file", "camera.json", "chart_capture", "chart-0001", "layout", "colorchecker24-frame",
		"detector", "apriltag", "tags_used", 0, 1, 2, 3, "homography_rms_px", 0.21,
		"overlay", "chart_overlay.png", "exposure_us", 10000, "gain", 0, "gain_unit", "dB",
		"frames", 16, "dark", "dark-0001", "flat", "cond_M", 12.3, "cond_M2", 3.4, "M2",
		1.0123, 0.0456, -0.0078, 0.0234, 0.9876, 0.0111, -0.0055, 0.0222, 1.0333,
		"residual_relative", 0.012);
	json_object_set_new(calib, "patches", fixture_patches());
	json_object_set_new(calib, "spectra_source", json_string("chart.cgats"));
	json_object_set_new(calib, "camera_icc",
	                    json_pack("{s:s, s:i, s:s, s:i, s:f, s:f, s:f}", "path", "camera.icc",
	                              "icc_version", 2, "ti3", "camera.ti3", "patches", 18, "rgb_scale", 0.65,
	                              "fit_de00_mean", 1.93, "fit_de00_max", 4.41));

	json_t *root = json_pack(
		"{s:s, s:s, s:{s:s, s:s}, s:{s:s, s:s}}", "format", "kogei-process/1", "created",
		"2026-12-01T21:00:00Z", "software", "name", "kogei", "version", "0.1.0", "session",
		"path", "/data/sessions/hawk-2026-12-01", "manifest_sha256",
		"9f86d081884c7d659a2feaa0c55ad015a3bf4f1b2b0b822cd15d6c15b0f00a08");
	json_object_set_new(root, "parameters", json_pack(
		"{s:s, s:s, s:s, s:n, s:s, s:n, s:f, s:i, s:b, s:b, s:s}", "reference", "ref.json",
		"spectra", "chart.cgats", "materials", "default", "only", "layout",
		"colorchecker24-frame", "mesh", "max_residual", 0.05, "min_tags", 0, "force", 0,
		"assume_same_exposure", 0, "method", "pca"));
	json_object_set_new(root, "inputs", json_pack(
		"[{s:s, s:s, s:s}, {s:s, s:s, s:s}]", "role", "reference", "path", "ref.json",
		"sha256", "2c26b46b68ffc68ff99b453c1d30413413422d706483bfa0f98a5e886266e7ae",
		"role", "capture chart-0001 rgb", "path", "captures/chart-0001/rgb.tif", "sha256",
		"fcde2b2edba56bf408601fb721fe9b5c338d10ee429ea04fae5511b68fbf8fb9"));
	json_object_set_new(root, "devices", json_pack(
		"{s:[{s:s, s:s, s:s, s:s}], s:[{s:s, s:s, s:s}]}", "cameras", "backend", "sim",
		"model", "kogei-sim site camera", "serial", "SIM-0002", "pixel_format", "BayerRG12",
		"spectrometers", "backend", "sim", "model", "USB2000+ (simulated)", "serial",
		"SIMSPEC-01"));
	json_object_set_new(root, "calibration", calib);
	json_object_set_new(root, "objects", json_pack("[o, o]", fixture_object(captures[0], 0, 0),
	                                               fixture_object(captures[1], 1, 1)));
	json_object_set_new(root, "warnings", json_pack("[s, s]", FIXTURE_SCRIPT,
	                                                "the flat field is 40 days old"));
	char *path = kg_path_join(outdir, "process.json");
	int ret = path ? kg_json_write(root, path, &err) : -1;
	if (ret)
		fprintf(stderr, "%s\n", path ? err.msg : "out of memory");
	free(path);
	json_decref(root);
	return ret;
}

#endif
