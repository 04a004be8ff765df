/* Bad input to `kogei estimate` and `kogei classify` exits 1 with a message naming
 * the cause, and leaves no file behind (the test directory holds only the inputs
 * afterwards); bad usage exits 2; --help exits 0. Uses the synthetic calibration of
 * apply_fixture.h and the bundled material library. */
#include "apply_fixture.h"

static int ninputs;

/* Exit status 1, stderr containing every expected fragment, nothing new on disk. */
static void expect_refusal(int status, const char *what, const char *frag1, const char *frag2)
{
	CHECK(status == 1, "%s: exit %d, expected 1", what, status);
	CHECK(strstr(fx_errs, frag1), "%s: message lacks '%s': %s", what, frag1, fx_errs);
	if (frag2)
		CHECK(strstr(fx_errs, frag2), "%s: message lacks '%s': %s", what, frag2, fx_errs);
	CHECK(fx_count_files() == ninputs, "%s: %d files in %s, expected the %d inputs", what,
	      fx_count_files(), fx_dir, ninputs);
}

/* The line of stderr that says M2 is singular, or "". */
static void m2_line(char *out, size_t n)
{
	const char *m = strstr(fx_errs, "M2 is singular"), *a = m;
	while (a && a > fx_errs && a[-1] != '\n')
		a--;
	snprintf(out, n, "%.*s", a ? (int)strcspn(a, "\n") : 0, a ? a : "");
}

int main(int argc, char **argv)
{
	fx_setup(argc, argv);
	const char *cam_path = fx_path("cam.json");
	kg_camera_calib *cam = fx_make_camera(cam_path);
	kg_image *img = fx_image(16, 9, NULL), *grey = NULL;
	kg_err err = {{0}};
	CHECK(cam && img, "fixture");
	if (!cam || !img)
		return kg_test_done("apply-refusals");
	const char *tif = fx_path("img.tif"), *grey_tif = fx_path("grey.tif");
	CHECK(kg_image_write_tiff(img, tif, 16, &err) == 0, "%s", err.msg);
	CHECK(kg_image_new(16, 9, 1, &grey, &err) == 0, "%s", err.msg);
	CHECK(kg_image_write_tiff(grey, grey_tif, 16, &err) == 0, "%s", err.msg);
	char lib[4096];
	snprintf(lib, sizeof(lib), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	/* Calibrations whose M2 cannot be right: all zeros, rank 2 (a row repeated), and
	 * nearly singular (a row repeated to 1e-13). */
	const char *bad_m2_path[3] = {fx_path("cam-zero-m2.json"), fx_path("cam-rank2-m2.json"),
	                              fx_path("cam-near-m2.json")};
	double good_m2[9];
	memcpy(good_m2, cam->M2, sizeof(good_m2));
	for (int k = 0; k < 3; k++) {
		memcpy(cam->M2, good_m2, sizeof(good_m2));
		for (int i = 0; i < 9; i++)
			if (k == 0)
				cam->M2[i] = 0;
			else if (i >= 6)
				cam->M2[i] = cam->M2[i - 3] * (k == 2 ? 1 + 1e-13 : 1);
		CHECK(kg_camera_save(cam, bad_m2_path[k], &err) == 0, "%s", err.msg);
	}
	memcpy(cam->M2, good_m2, sizeof(good_m2));
	ninputs = fx_count_files();
	const char *out = fx_path("out.hdr"), *labels = fx_path("labels.hdr");

	expect_refusal(FX_RUN("estimate", "--calib", fx_path("missing.json"), tif, "-o", out),
	               "missing calibration", "missing.json", NULL);
	expect_refusal(FX_RUN("classify", "--calib", fx_path("missing.json"), "--materials", lib,
	                      tif, "-o", labels),
	               "classify, missing calibration", "missing.json", NULL);
	expect_refusal(FX_RUN("estimate", "--calib", cam_path, fx_path("missing.tif"), "-o", out),
	               "missing image", "missing.tif", NULL);
	expect_refusal(FX_RUN("estimate", "--calib", cam_path, grey_tif, "-o", out), "grey image",
	               "expected a 3-channel", "demosaic");
	expect_refusal(FX_RUN("classify", "--calib", cam_path, "--materials", lib, grey_tif, "-o",
	                      labels),
	               "classify, grey image", "expected a 3-channel", "demosaic");
	/* A singular M2: refused by estimate and classify with one message naming the file. */
	for (int k = 0; k < 3; k++) {
		char est_msg[1024], cls_msg[1024];
		expect_refusal(FX_RUN("estimate", "--calib", bad_m2_path[k], tif, "-o", out),
		               "estimate, singular M2", "M2 is singular (rank ", bad_m2_path[k]);
		m2_line(est_msg, sizeof(est_msg));
		expect_refusal(FX_RUN("classify", "--calib", bad_m2_path[k], "--materials", lib, tif,
		                      "-o", labels),
		               "classify, singular M2", "M2 is singular (rank ", bad_m2_path[k]);
		m2_line(cls_msg, sizeof(cls_msg));
		CHECK(est_msg[0] && strstr(est_msg, bad_m2_path[k]) && strcmp(est_msg, cls_msg) == 0,
		      "singular M2 %d: estimate and classify differ:\n  %s\n  %s", k, est_msg, cls_msg);
		CHECK(strstr(est_msg, k == 0 ? "rank 0 < 3" : "rank 2 < 3"), "M2 %d: rank: %s", k,
		      est_msg);
	}
	expect_refusal(FX_RUN("estimate", "--calib", tif, tif, "-o", out),
	               "an image given as calibration", "img.tif", NULL);
	expect_refusal(FX_RUN("classify", "--calib", cam_path, "--materials", lib, "--only",
	                      "gold,unobtainium", tif, "-o", labels),
	               "unknown material", "unobtainium", "shakudo");
	expect_refusal(FX_RUN("classify", "--calib", cam_path, "--materials", lib, "--only",
	                      "gold,gold", tif, "-o", labels),
	               "repeated material", "named twice", NULL);
	expect_refusal(FX_RUN("classify", "--calib", cam_path, "--materials", lib, "--method",
	                      "rootpoly2", tif, "-o", labels),
	               "non-pca classification", "expected camera", NULL);
	expect_refusal(FX_RUN("classify", "--calib", cam_path, "--materials",
	                      fx_path("missing-lib.json"), tif, "-o", labels),
	               "missing library", "missing-lib.json", NULL);
	expect_refusal(FX_RUN("estimate", "--calib", cam_path, "--method", "linear", "--format",
	                      "weights", tif, "-o", out),
	               "weights without a basis", "pca", NULL);
	expect_refusal(FX_RUN("estimate", "--calib", cam_path, tif, "-o",
	                      fx_path("no-such-dir/out.hdr")),
	               "unwritable output", "no-such-dir", NULL);

	/* usage */
	CHECK(FX_RUN("estimate", "--calib", cam_path, tif) == 2, "no -o: expected exit 2");
	CHECK(FX_RUN("estimate", "--calib", cam_path, "-o", out) == 2, "no image: expected exit 2");
	CHECK(FX_RUN("estimate", "--calib", cam_path, tif, "-o", out, "--format", "f64") == 2,
	      "--format f64: expected exit 2");
	CHECK(FX_RUN("estimate", "--calib", cam_path, tif, "-o", out, "--method", "magic") == 2,
	      "--method magic: expected exit 2");
	CHECK(FX_RUN("classify", "--calib", cam_path, "--materials", lib, tif, "-o", labels,
	             "--distance", "cosine") == 2,
	      "--distance cosine: expected exit 2");
	CHECK(FX_RUN("classify", "--calib", cam_path, "--materials", lib, tif, "-o", labels,
	             "--angle", "95") == 2,
	      "--angle 95: expected exit 2");
	const char *bad_refusal[4][2] = {{"--frames", "0"},
	                                 {"--unknown-threshold", "-1"},
	                                 {"--background-level", "2"},
	                                 {"--unknown-threshold", "nan"}};
	for (int i = 0; i < 4; i++)
		CHECK(FX_RUN("classify", "--calib", cam_path, "--materials", lib, tif, "-o", labels,
		             bad_refusal[i][0], bad_refusal[i][1]) == 2,
		      "%s %s: expected exit 2", bad_refusal[i][0], bad_refusal[i][1]);
	expect_refusal(FX_RUN("classify", "--calib", cam_path, "--materials", lib, tif, "-o",
	                      labels, "--variance", grey_tif),
	               "classify, 1-channel variance image", "expected 3", NULL);
	CHECK(fx_count_files() == ninputs, "usage errors left files behind");
	CHECK(FX_RUN("estimate", "--help") == 0 && strstr(fx_out, "--format"), "estimate --help");
	CHECK(FX_RUN("classify", "--help") == 0 && strstr(fx_out, "scale-free") &&
	          strstr(fx_out, "--variance") && strstr(fx_out, "--mask") &&
	          strstr(fx_out, "--background-level") && strstr(fx_out, "--unknown-threshold"),
	      "classify --help");

	kg_image_free(&img);
	kg_image_free(&grey);
	kg_camera_calib_free(&cam);
	int rc = kg_test_done("apply-refusals");
	fx_cleanup();
	return rc;
}
