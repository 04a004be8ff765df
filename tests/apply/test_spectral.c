/* The ENVI cube (bsq and bip) and the label map written by kogei are read back by
 * Spectral Python (python3-spectral), an independent reader, and must hold exactly
 * what kogei's own reader sees: shape, wavelengths, NaN for flagged pixels, class
 * names with "unclassified" at 0 and a lookup colour per class. Skipped (77) when
 * /usr/bin/python3 cannot import spectral. Arguments: kogei, read_spectral.py. */
#include "apply_fixture.h"

#define W 37
#define H 23

static int dump(const char *hdr, const char *raw, int as_bytes)
{
	kg_envi *e = NULL;
	float *v = fx_read_envi(hdr, &e);
	if (!v)
		return -1;
	size_t n = (size_t)W * H * e->meta.bands;
	FILE *fp = fopen(raw, "wb");
	int ok = fp != NULL;
	for (size_t i = 0; ok && i < n; i++) {
		unsigned char b = (unsigned char)v[i];
		ok = as_bytes ? fwrite(&b, 1, 1, fp) == 1 : fwrite(&v[i], sizeof(float), 1, fp) == 1;
	}
	if (fp)
		ok &= fclose(fp) == 0;
	free(v);
	kg_envi_close(&e);
	return ok ? 0 : -1;
}

int main(int argc, char **argv)
{
	if (system("/usr/bin/python3 -c 'import spectral, numpy' 2>/dev/null") != 0)
		kg_test_skip("/usr/bin/python3 cannot import spectral (python3-spectral) and numpy");
	if (argc < 3) {
		fprintf(stderr, "usage: %s KOGEI read_spectral.py\n", argv[0]);
		return 2;
	}
	fx_setup(argc, argv);
	const char *cam_path = fx_path("cam.json");
	kg_camera_calib *cam = fx_make_camera(cam_path);
	kg_image *img = fx_image(W, H, NULL);
	kg_err err = {{0}};
	CHECK(cam && img, "fixture");
	if (!cam || !img)
		return kg_test_done("apply-spectral");
	const char *tif = fx_path("img.tif");
	char lib[4096];
	snprintf(lib, sizeof(lib), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	CHECK(kg_image_write_tiff(img, tif, 32, &err) == 0, "%s", err.msg);
	CHECK(FX_RUN("estimate", "--calib", cam_path, tif, "-o", fx_path("cube.hdr")) == 0,
	      "estimate: %s", fx_errs);
	CHECK(FX_RUN("estimate", "--calib", cam_path, tif, "-o", fx_path("cube_bip.hdr"),
	             "--interleave", "bip") == 0,
	      "estimate bip: %s", fx_errs);
	CHECK(FX_RUN("classify", "--method", "eq11", "--calib", cam_path, "--materials", lib, "--only",
	             "gold,silver,copper,urushi", tif, "-o", fx_path("labels.hdr")) == 0,
	      "classify: %s", fx_errs);
	CHECK(dump(fx_path("cube.hdr"), fx_path("expect_cube.f32"), 0) == 0, "dump cube");
	CHECK(dump(fx_path("labels.hdr"), fx_path("expect_labels.u8"), 1) == 0, "dump labels");
	char cmd[2048];
	snprintf(cmd, sizeof(cmd), "/usr/bin/python3 '%s' '%s' %d %d", argv[2], fx_dir, W, H);
	fflush(NULL);
	int st = system(cmd);
	CHECK(st == 0, "Spectral Python check failed (status %d)", st);
	kg_image_free(&img);
	kg_camera_calib_free(&cam);
	int rc = kg_test_done("apply-spectral");
	if (rc == 0)
		fx_cleanup();
	else
		fprintf(stderr, "files kept in %s\n", fx_dir);
	return rc;
}
