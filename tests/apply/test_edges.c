/* Numerical edges of `kogei estimate` and `kogei classify`: an image of which no pixel
 * can be estimated (every pixel clipped, every pixel NaN, or a mixture of the two)
 * exits 1 naming the reason and writes nothing; a partly flagged image (one pixel in
 * four; the others ordinary) succeeds and
 * both summaries name the number and fraction of flagged pixels. Uses the synthetic
 * calibration of apply_fixture.h and the bundled material library. */
#include "apply_fixture.h"

enum { W = 20, H = 10 };

/* A W x H float TIFF: pixel i as kind(i) says (0 ordinary, 1 clipped, 2 NaN). */
static const char *write_image(const char *name, int (*kind)(int))
{
	kg_image *img = NULL;
	kg_err err = {{0}};
	const char *path = fx_path(name);
	CHECK(kg_image_new(W, H, 3, &img, &err) == 0, "%s", err.msg);
	for (int i = 0; img && i < W * H; i++) {
		float *p = img->data + 3 * i;
		switch (kind(i)) {
		case 1: p[0] = p[1] = p[2] = 1.0f; break;
		case 2: p[0] = p[1] = p[2] = NAN; break;
		default:
			for (int c = 0; c < 3; c++)
				p[c] = 0.2f + 0.1f * (float)c + 0.05f * (float)(i % 7);
		}
	}
	CHECK(img && kg_image_write_tiff(img, path, 32, &err) == 0, "%s: %s", name, err.msg);
	kg_image_free(&img);
	return path;
}

static int all_clipped(int i) { return (void)i, 1; }
static int all_nan(int i) { return (void)i, 2; }
static int clipped_or_nan(int i) { return 1 + (i % 2); }
static int quarter_flagged(int i) { return i % 4 == 0 ? 1 + (i / 4) % 2 : 0; }

int main(int argc, char **argv)
{
	fx_setup(argc, argv);
	const char *cam = fx_path("cam.json");
	kg_camera_calib *calib = fx_make_camera(cam);
	CHECK(calib, "fixture");
	kg_camera_calib_free(&calib);
	char lib[4096];
	snprintf(lib, sizeof(lib), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	static const struct {
		const char *name;
		int (*kind)(int);
		const char *counts;
	} refused[] = {
		{"clipped.tif", all_clipped, "(200 clipped"},
		{"nan.tif", all_nan, "(0 clipped"},
		{"mixed.tif", clipped_or_nan, "(100 clipped"},
	};
	const char *images[3];
	for (int i = 0; i < 3; i++)
		images[i] = write_image(refused[i].name, refused[i].kind);
	const char *partial = write_image("partial.tif", quarter_flagged);
	int ninputs = fx_count_files();
	const char *out = fx_path("cube.hdr"), *labels = fx_path("labels.hdr");

	for (int i = 0; i < 3; i++) {
		int rc = FX_RUN("estimate", "--calib", cam, images[i], "-o", out);
		CHECK(rc == 1, "estimate %s: exit %d, expected 1", refused[i].name, rc);
		CHECK(strstr(fx_errs, "no pixel can be estimated") && strstr(fx_errs, "all 200 pixels") &&
		          strstr(fx_errs, refused[i].counts),
		      "estimate %s: message lacks the reason or '%s': %s", refused[i].name,
		      refused[i].counts, fx_errs);
		CHECK(fx_count_files() == ninputs, "estimate %s: %d files, expected the %d inputs",
		      refused[i].name, fx_count_files(), ninputs);
		rc = FX_RUN("classify", "--calib", cam, "--materials", lib, images[i], "-o", labels);
		CHECK(rc == 1, "classify %s: exit %d, expected 1", refused[i].name, rc);
		CHECK(strstr(fx_errs, "no pixel can be estimated") && strstr(fx_errs, refused[i].counts),
		      "classify %s: message: %s", refused[i].name, fx_errs);
		CHECK(fx_count_files() == ninputs, "classify %s: %d files, expected the %d inputs",
		      refused[i].name, fx_count_files(), ninputs);
	}

	/* 50 of 200 pixels flagged: estimated, and the summaries say so */
	int rc = FX_RUN("estimate", "--calib", cam, partial, "-o", out);
	CHECK(rc == 0, "estimate partial.tif: exit %d", rc);
	CHECK(strstr(fx_errs, "flagged 50 (25.000 %)"), "estimate summary: %s", fx_errs);
	rc = FX_RUN("classify", "--calib", cam, "--materials", lib, partial, "-o", labels);
	CHECK(rc == 0, "classify partial.tif: exit %d", rc);
	CHECK(strstr(fx_errs, "flagged 50 (25.000 %)"), "classify summary: %s", fx_errs);
	CHECK(strstr(fx_out, "unclassified (flagged)"), "classify table: %s", fx_out);

	fx_cleanup();
	return kg_test_done("apply-edges");
}
