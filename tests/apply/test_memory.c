/* Memory stays bounded whatever the image's size: `kogei estimate` and `kogei
 * classify` of a generated 150 Mpix photograph (15000 x 10000, 16-bit RGB, with a
 * float variance image beside it, both deflate-compressed TIFFs in strips of 16 rows)
 * must each peak under 1 GiB of resident memory, where holding the image alone would
 * take 1.8 GB and its variance another 1.8 GB. The peak is the child's ru_maxrss
 * (wait4), measured here; time is not asserted. The estimate writes K weights (1.8 GB
 * on disk) rather than a 61-band cube (36.6 GB); both go through the same input path.
 * Needs about 3 GB of free disk in /tmp. */
#include <sys/resource.h>
#include <sys/statvfs.h>
#include <tiffio.h>

#include "apply_fixture.h"

enum { W = 15000, H = 10000, STRIP = 16 };
static const long limit_kib = 1L << 20; /* 1 GiB */

/* A smooth scene: a level that varies over the frame and a colour that changes in
 * bands, so the classifier meets every kind of pixel; the variance a fixed fraction
 * of the level. */
static void pixel(int x, int y, float rgb[3])
{
	double level = 0.15 + 0.6 * (0.5 + 0.5 * sin(x * 0.0007) * cos(y * 0.0011));
	int band = (x / 1500 + y / 1000) % 5;
	static const double tint[5][3] = {
		{1.0, 0.8, 0.4}, {0.9, 0.9, 0.9}, {1.0, 0.6, 0.45}, {0.7, 0.65, 0.6}, {0.3, 0.25, 0.2}};
	for (int c = 0; c < 3; c++)
		rgb[c] = (float)(level * tint[band][c]);
}

static int write_tiff(const char *path, int variance)
{
	TIFF *tif = TIFFOpen(path, "w8");
	if (!tif)
		return -1;
	int bits = variance ? 32 : 16;
	TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, (uint32_t)W);
	TIFFSetField(tif, TIFFTAG_IMAGELENGTH, (uint32_t)H);
	TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, 3);
	TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, bits);
	TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, variance ? SAMPLEFORMAT_IEEEFP : SAMPLEFORMAT_UINT);
	TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_RGB);
	TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
	TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_ADOBE_DEFLATE);
	TIFFSetField(tif, TIFFTAG_ZIPQUALITY, 1);
	TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, (uint32_t)STRIP);
	size_t row_bytes = (size_t)W * 3 * (bits / 8);
	unsigned char *row = malloc(row_bytes);
	int ok = row != NULL;
	for (int y = 0; ok && y < H; y++) {
		for (int x = 0; x < W; x++) {
			float v[3];
			pixel(x, y, v);
			for (int c = 0; c < 3; c++) {
				size_t i = (size_t)x * 3 + c;
				if (variance) {
					float var = 1e-6f + 4e-5f * v[c];
					memcpy(row + 4 * i, &var, 4);
				} else {
					uint16_t u = (uint16_t)lrint(v[c] * 65535.0);
					memcpy(row + 2 * i, &u, 2);
				}
			}
		}
		ok = TIFFWriteScanline(tif, row, (uint32_t)y, 0) == 1;
	}
	free(row);
	TIFFClose(tif);
	return ok ? 0 : -1;
}

/* Run kogei with args; *maxrss_kib receives the child's peak resident memory. */
static int run_measured(long *maxrss_kib, const char *const *args)
{
	char *argv[32];
	int n = 0;
	argv[n++] = (char *)fx_kogei;
	for (; args[n - 1] && n < 31; n++)
		argv[n] = (char *)args[n - 1];
	argv[n] = NULL;
	fflush(NULL);
	pid_t pid = fork();
	if (pid == 0) {
		execv(fx_kogei, argv);
		_exit(127);
	}
	int status = 0;
	struct rusage ru;
	memset(&ru, 0, sizeof(ru));
	if (wait4(pid, &status, 0, &ru) != pid)
		return -1;
	*maxrss_kib = ru.ru_maxrss;
	return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

static long long file_size(const char *p)
{
	struct stat st;
	return stat(p, &st) == 0 ? (long long)st.st_size : -1;
}

int main(int argc, char **argv)
{
#if defined(__SANITIZE_ADDRESS__)
	/* AddressSanitizer's shadow memory and quarantine are not the program's. */
	printf("SKIP: built with AddressSanitizer, whose own memory would be measured\n");
	return 77;
#endif
	fx_setup(argc, argv);
	struct statvfs vfs;
	if (statvfs(fx_dir, &vfs) == 0 && (double)vfs.f_bavail * vfs.f_frsize < 4e9) {
		printf("SKIP: less than 4 GB free in %s for a 150 Mpix test\n", fx_dir);
		fx_cleanup();
		return 77;
	}
	const char *cam = fx_path("cam.json"), *img = fx_path("big.tif");
	const char *var = fx_path("big_var.tif"), *cube = fx_path("weights.hdr");
	const char *labels = fx_path("labels.hdr");
	kg_camera_calib *calib = fx_make_camera(cam);
	CHECK(calib != NULL, "synthetic calibration");
	kg_camera_calib_free(&calib);
	CHECK(write_tiff(img, 0) == 0 && write_tiff(var, 1) == 0, "writing the 150 Mpix TIFFs");
	printf("image %lld bytes, variance %lld bytes on disk (%d x %d pixels)\n", file_size(img),
	       file_size(var), W, H);

	long rss = 0;
	const char *est[] = {"estimate", "--calib", cam, img, "--format", "weights", "-o", cube,
	                     "--quiet", NULL};
	CHECK(run_measured(&rss, est) == 0, "kogei estimate of 150 Mpix");
	printf("kogei estimate --format weights, %d x %d: peak RSS %.1f MiB\n", W, H, rss / 1024.0);
	CHECK(rss > 0 && rss < limit_kib, "estimate peaked at %ld KiB: expected under %ld", rss,
	      limit_kib);
	kg_envi *e = NULL;
	kg_err err = {{0}};
	CHECK(kg_envi_open(cube, &e, &err) == 0, "%s", err.msg);
	if (e)
		CHECK(e->meta.samples == W && e->meta.lines == H &&
		      file_size(fx_path("weights.img")) == (long long)W * H * e->meta.bands * 4,
		      "the weights cube's size");
	kg_envi_close(&e);
	const char *done[] = {"weights.hdr", "weights.img", "weights_mask.hdr", "weights_mask.img"};
	for (int i = 0; i < 4; i++)
		unlink(fx_path(done[i]));

	/* camera space (the default) with its survey, regions and composition; four
	 * materials on a coarse angle grid, as memory does not depend on them */
	const char *cls[] = {"classify", "--calib", cam, "--materials",
	                     KG_SOURCE_ROOT "/fixtures/materials/default.json", "--only",
	                     "gold,silver,copper,urushi", "--angles", "0:60:20", "--variance", var,
	                     "--frames", "4", img, "-o", labels, "--quiet", NULL};
	CHECK(run_measured(&rss, cls) == 0, "kogei classify of 150 Mpix with a variance image");
	printf("kogei classify --variance, %d x %d: peak RSS %.1f MiB\n", W, H, rss / 1024.0);
	CHECK(rss > 0 && rss < limit_kib, "classify peaked at %ld KiB: expected under %ld", rss,
	      limit_kib);
	CHECK(file_size(fx_path("labels.img")) == (long long)W * H, "the label map's size");
	fx_cleanup();
	return kg_test_done("apply-memory");
}
