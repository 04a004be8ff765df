/* Camera raw files through LibRaw (core/raw.c) and the files: camera backend
 * (devices/camera_files.c), on DNG files this test writes itself (dng.h):
 *   - values linear to the count: (raw - black) / (white - black) for every sample,
 *     with one black level and with a 2x2 black pattern, below-black values negative,
 *     white at 1, for each of the four Bayer patterns;
 *   - the metadata: make, model, serial, lens, exposure, ISO, aperture, focal length;
 *   - kg_image_read and the row reader take DNG files (by extension and by the
 *     DNGVersion tag under a .tif name), from memory too;
 *   - refusals: truncated and damaged files, a demosaiced (LinearRaw) DNG, garbage with
 *     a raw extension, an empty file;
 *   - files:: identity and features from the files, one frame per file in name order as
 *     16-bit values of the decoded samples, set-to-the-same-value only, a format it
 *     cannot give refused, mixed exposures / cameras / sizes refused naming both files,
 *     a pattern matching nothing, TIFF files served too. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "dng.h"
#include "image.h"
#include "kg_camera.h"
#include "kg_test.h"
#include "raw.h"

#define W 40
#define H 30

static char dir[64];

static const char *path_of(const char *name)
{
	static char p[4][256];
	static int k;
	k = (k + 1) % 4;
	snprintf(p[k], sizeof(p[k]), "%s/%s", dir, name);
	return p[k];
}

/* Samples spread over the whole range, some below black and some at white. */
static void fill(uint16_t *d, int seed, double white)
{
	for (int i = 0; i < W * H; i++)
		d[i] = (uint16_t)((i * 97 + seed * 13) % (int)(white + 1));
	d[0] = 0;                     /* below black */
	d[1] = (uint16_t)white;       /* at white */
}

static test_dng base(const uint16_t *d)
{
	test_dng g = {.width = W, .height = H, .data = d, .cfa = "RGGB",
	              .black = {512, 512, 512, 512}, .black_dim = 1, .white = 16383,
	              .exposure_s = 1.0 / 125, .iso = 400, .fnumber = 8, .focal_mm = 100,
	              .make = "Kogei Test", .model = "DNG-14", .serial = "0042",
	              .lens = "Macro 100mm F2.8"};
	return g;
}

static void write_or_die(const char *path, const test_dng *g)
{
	char msg[256];
	if (test_dng_write(path, g, msg, sizeof(msg))) {
		fprintf(stderr, "%s\n", msg);
		exit(1);
	}
}

static const char *cfa_names[] = {"RGGB", "GRBG", "GBRG", "BGGR"};

static void test_linear(void)
{
	static uint16_t d[W * H];
	for (int p = 0; p < 4; p++)
		for (int pattern = 0; pattern < 2; pattern++) {
			fill(d, p, 16383);
			test_dng g = base(d);
			g.cfa = cfa_names[p];
			if (pattern) {
				double b[4] = {500, 510, 520, 530};
				memcpy(g.black, b, sizeof(b));
				g.black_dim = 2;
			}
			const char *f = path_of("linear.dng");
			write_or_die(f, &g);
			kg_image *img = NULL;
			kg_raw_meta m;
			kg_err err = {{0}};
			int ret = kg_raw_read(f, &img, &m, &err);
			CHECK(ret == 0, "%s pattern %d: %s", g.cfa, pattern, err.msg);
			if (ret)
				continue;
			CHECK(img->width == W && img->height == H && img->channels == 1,
			      "%s: size %dx%d x%d", g.cfa, img->width, img->height, img->channels);
			CHECK(img->cfa && !strcmp(img->cfa, g.cfa) && !strcmp(m.cfa, g.cfa),
			      "CFA %s read as %s / %s", g.cfa, img->cfa ? img->cfa : "none", m.cfa);
			double worst = 0;
			for (int y = 0; y < H; y++)
				for (int x = 0; x < W; x++) {
					int site = (y & 1) * 2 + (x & 1);
					double b = g.black[pattern ? site : 0];
					double counts = img->data[y * W + x] * (g.white - b);
					double want = (double)d[y * W + x] - b;
					worst = fmax(worst, fabs(counts - want));
				}
			CHECK(worst < 0.01, "%s pattern %d: worst error %.4f counts", g.cfa, pattern, worst);
			CHECK(img->data[0] < 0, "below black stays negative (%g)", img->data[0]);
			CHECK(fabs(img->data[1] - 1) < 1e-6, "white reads 1 (%g)", img->data[1]);
			for (int k = 0; k < 4; k++)
				CHECK(m.black[k] == g.black[pattern ? k : 0] && m.white[k] == g.white,
				      "black/white of site %d: %g/%g", k, m.black[k], m.white[k]);
			kg_image_free(&img);
		}
	printf("  linear to the count for 4 CFA patterns, common and 2x2 black\n");
}

/* The file's own WhiteLevel and BlackLevel win over LibRaw's camera table: a "NIKON
 * D5100" DNG with WhiteLevel 15520 (LibRaw's table for that model says otherwise), a
 * fractional BlackLevel 12.5 kept as it is, and a 2x2 fractional black pattern. */
static void test_dng_levels(void)
{
	static uint16_t d[W * H];
	fill(d, 3, 15520);
	d[2] = 15520;
	d[3] = 14504;
	for (int pattern = 0; pattern < 2; pattern++) {
		test_dng g = base(d);
		g.make = "NIKON CORPORATION";
		g.model = "NIKON D5100";
		g.white = 15520;
		if (pattern) {
			double b[4] = {12.5, 13.25, 14.75, 15.5};
			memcpy(g.black, b, sizeof(b));
			g.black_dim = 2;
		} else {
			double b[4] = {12.5, 12.5, 12.5, 12.5};
			memcpy(g.black, b, sizeof(b));
		}
		const char *f = path_of("d5100.dng");
		write_or_die(f, &g);
		kg_image *img = NULL;
		kg_raw_meta m;
		kg_err err = {{0}};
		int ret = kg_raw_read(f, &img, &m, &err);
		CHECK(ret == 0, "D5100 DNG: %s", err.msg);
		if (ret)
			continue;
		for (int k = 0; k < 4; k++)
			CHECK(m.white[k] == 15520 && m.black[k] == g.black[pattern ? k : 0],
			      "D5100 DNG pattern %d site %d: white %g black %g, expected the file's "
			      "15520 and %g", pattern, k, m.white[k], m.black[k], g.black[pattern ? k : 0]);
		double worst = 0;
		long over = 0;
		for (int y = 0; y < H; y++)
			for (int x = 0; x < W; x++) {
				int site = (y & 1) * 2 + (x & 1);
				double b = g.black[pattern ? site : 0];
				double want = ((double)d[y * W + x] - b) / (15520 - b);
				worst = fmax(worst, fabs(img->data[y * W + x] - want));
				over += img->data[y * W + x] > 1.0f + 1e-6f;
			}
		CHECK(worst < 1e-6, "D5100 DNG pattern %d: worst error %.3g of full scale", pattern,
		      worst);
		CHECK(over == 0, "D5100 DNG: %ld samples above white (white level too low)", over);
		CHECK(fabs(img->data[2] - 1) < 1e-6, "WhiteLevel 15520 reads 1 (%g)", img->data[2]);
		kg_image_free(&img);
	}
	printf("  DNG WhiteLevel/BlackLevel from the file (NIKON D5100 15520, black 12.5)\n");
}

static void test_meta_and_readers(void)
{
	static uint16_t d[W * H];
	fill(d, 3, 16383);
	test_dng g = base(d);
	const char *f = path_of("meta.dng");
	write_or_die(f, &g);
	kg_raw_meta m;
	kg_err err = {{0}};
	int ret = kg_raw_read_meta(f, &m, &err);
	CHECK(ret == 0, "meta: %s", err.msg);
	CHECK(!strcmp(m.make, "Kogei Test") && !strcmp(m.model, "DNG-14") &&
	          !strcmp(m.serial, "0042"),
	      "identity '%s' '%s' '%s'", m.make, m.model, m.serial);
	CHECK(!strcmp(m.lens, "Macro 100mm F2.8"), "lens '%s'", m.lens);
	CHECK(m.exposure_s == 0.008 && m.iso == 400 && m.aperture == 8 && m.focal_length_mm == 100,
	      "settings %g s ISO %g f/%g %g mm", m.exposure_s, m.iso, m.aperture,
	      m.focal_length_mm);
	CHECK(!strncmp(m.format, "DNG 1.4", 7), "format '%s'", m.format);

	/* ISOSpeedRatings in IFD 0 rather than the EXIF IFD: read too (LibRaw alone
	 * misses it), from a file and from memory */
	test_dng g0 = g;
	g0.iso = 0;
	g0.iso_ifd0 = 250;
	const char *f0 = path_of("iso_ifd0.dng");
	write_or_die(f0, &g0);
	kg_raw_meta m0;
	CHECK(kg_raw_read_meta(f0, &m0, &err) == 0, "meta, ISO in IFD 0: %s", err.msg);
	CHECK(m0.iso == 250 && m0.exposure_s == 0.008, "ISO in IFD 0 read as %g (exposure %g s)",
	      m0.iso, m0.exposure_s);
	{
		FILE *fp = fopen(f0, "rb");
		static unsigned char buf[1 << 20];
		size_t nb = fp ? fread(buf, 1, sizeof(buf), fp) : 0;
		if (fp)
			fclose(fp);
		kg_image *im0 = NULL;
		memset(&m0, 0, sizeof(m0));
		CHECK(kg_raw_read_memory(buf, nb, "iso_ifd0.dng", &im0, &m0, &err) == 0,
		      "memory, ISO in IFD 0: %s", err.msg);
		CHECK(m0.iso == 250, "ISO in IFD 0 from memory read as %g", m0.iso);
		kg_image_free(&im0);
	}
	/* and neither: unknown, not 0 */
	g0.iso_ifd0 = 0;
	write_or_die(f0, &g0);
	CHECK(kg_raw_read_meta(f0, &m0, &err) == 0 && isnan(m0.iso), "no ISO read as %g", m0.iso);

	/* kg_image_read: by extension, and by DNGVersion under a .tif name */
	kg_image *a = NULL, *b = NULL, *c = NULL;
	CHECK(kg_raw_read(f, &a, NULL, &err) == 0, "raw read: %s", err.msg);
	CHECK(kg_image_read(f, &b, &err) == 0, "kg_image_read of a .dng: %s", err.msg);
	const char *tif = path_of("meta_as.tif");
	CHECK(rename(f, tif) == 0, "rename");
	CHECK(kg_raw_is_raw(tif), "a DNG named .tif is recognised by its DNGVersion tag");
	CHECK(kg_image_read(tif, &c, &err) == 0, "kg_image_read of a DNG named .tif: %s", err.msg);
	CHECK(a && b && c && !memcmp(a->data, b->data, sizeof(float) * W * H) &&
	          !memcmp(a->data, c->data, sizeof(float) * W * H) && b->cfa && c->cfa,
	      "the same samples and CFA through every reader");
	/* the row reader */
	kg_image_rows *r = NULL;
	float rows[3 * W];
	CHECK(kg_image_rows_open(tif, &r, &err) == 0, "rows: %s", err.msg);
	if (r && a) {
		const kg_image *h = kg_image_rows_header(r);
		CHECK(h->width == W && h->height == H && h->cfa && !strcmp(h->cfa, "RGGB"),
		      "rows header");
		CHECK(kg_image_rows_read(r, 3, rows, &err) == 0 &&
		          kg_image_rows_read(r, 3, rows, &err) == 0 &&
		          !memcmp(rows, a->data + 3 * W, sizeof(rows)),
		      "rows 3..5 equal: %s", err.msg);
	}
	kg_image_rows_free(&r);
	/* from memory */
	FILE *fp = fopen(tif, "rb");
	static unsigned char buf[1 << 16];
	size_t n = fp ? fread(buf, 1, sizeof(buf), fp) : 0;
	if (fp)
		fclose(fp);
	kg_image *mem = NULL;
	CHECK(kg_raw_read_memory(buf, n, "in memory", &mem, &m, &err) == 0, "memory: %s",
	      err.msg);
	CHECK(mem && a && !memcmp(mem->data, a->data, sizeof(float) * W * H), "memory = file");
	kg_image_free(&a);
	kg_image_free(&b);
	kg_image_free(&c);
	kg_image_free(&mem);
	printf("  metadata; kg_image_read, rows, memory\n");
}

static void expect_fail(const char *file, int want, const char *needle, const char *what)
{
	kg_image *img = NULL;
	kg_err err = {{0}};
	int ret = kg_image_read(file, &img, &err);
	CHECK(ret == want && !img && strstr(err.msg, file) && strstr(err.msg, needle),
	      "%s: got %d '%s', expected %d naming the file and '%s'", what, ret, err.msg, want,
	      needle);
	kg_image_free(&img);
}

static void test_refusals(void)
{
	static uint16_t d[W * H * 3];
	fill(d, 1, 16383);
	test_dng g = base(d);
	const char *f = path_of("whole.dng");
	write_or_die(f, &g);
	/* truncated: the pixel data cut short */
	struct stat st;
	stat(f, &st);
	const char *t = path_of("truncated.dng");
	FILE *in = fopen(f, "rb"), *out = fopen(t, "wb");
	static unsigned char buf[1 << 16];
	size_t n = fread(buf, 1, sizeof(buf), in);
	fwrite(buf, 1, n / 2, out);
	fclose(in);
	fclose(out);
	expect_fail(t, KG_EINVAL, "truncated", "a DNG cut in half");
	/* only the header */
	out = fopen(t, "wb");
	fwrite(buf, 1, 64, out);
	fclose(out);
	{
		kg_image *img = NULL;
		kg_err err = {{0}};
		int ret = kg_image_read(t, &img, &err);
		CHECK(ret < 0 && !img && strstr(err.msg, t), "a 64-byte DNG: %d '%s'", ret, err.msg);
	}
	/* a demosaiced DNG */
	for (int i = 0; i < W * H * 3; i++)
		d[i] = (uint16_t)(600 + i % 9000);
	g.linear_raw = 1;
	const char *lin = path_of("linear_raw.dng");
	write_or_die(lin, &g);
	expect_fail(lin, KG_ENOTSUP, "colour filter array", "a LinearRaw DNG");
	/* garbage under a raw extension; an empty file */
	const char *junk = path_of("junk.cr2");
	out = fopen(junk, "wb");
	for (int i = 0; i < 5000; i++)
		fputc((i * 31) & 255, out);
	fclose(out);
	expect_fail(junk, KG_ENOTSUP, "not a camera raw file", "garbage named .cr2");
	const char *empty = path_of("empty.nef");
	fclose(fopen(empty, "wb"));
	{
		kg_image *img = NULL;
		kg_err err = {{0}};
		int ret = kg_image_read(empty, &img, &err);
		CHECK(ret < 0 && !img && strstr(err.msg, empty), "an empty .nef: %d '%s'", ret,
		      err.msg);
	}
	printf("  refusals: truncated, header only, LinearRaw, garbage, empty\n");
}

/* ---- files: ---------------------------------------------------------------------------- */

static void write_set(const char *prefix, int count, double exposure, const char *serial,
                      int width)
{
	static uint16_t d[W * H];
	for (int k = 0; k < count; k++) {
		fill(d, k, 16383);
		test_dng g = base(d);
		g.exposure_s = exposure;
		g.serial = serial;
		g.width = width;
		g.height = width == W ? H : H - 2;
		char name[64];
		snprintf(name, sizeof(name), "%s_%d.dng", prefix, k);
		write_or_die(path_of(name), &g);
	}
}

static void expect_open_fail(const char *uri, int want, const char *n1, const char *n2)
{
	kg_camera *c = NULL;
	kg_err err = {{0}};
	int ret = kg_camera_open(uri, &c, &err);
	CHECK(ret == want && !c && strstr(err.msg, n1) && (!n2 || strstr(err.msg, n2)),
	      "%s: got %d '%s', expected %d naming '%s' and '%s'", uri, ret, err.msg, want, n1,
	      n2 ? n2 : "");
	kg_camera_free(&c);
}

static void test_files_backend(void)
{
	write_set("shoot/chart", 3, 1.0 / 125, "0042", W);
	char uri[300];
	snprintf(uri, sizeof(uri), "files:%s/shoot/chart_*.dng", dir);
	kg_camera *c = NULL;
	kg_err err = {{0}};
	int ret = kg_camera_open(uri, &c, &err);
	CHECK(ret == 0, "open %s: %s", uri, err.msg);
	if (ret)
		return;
	const kg_camera_info *info = kg_camera_get_info(c);
	CHECK(!strcmp(info->backend, "files") && !strcmp(info->vendor, "Kogei Test") &&
	          !strcmp(info->model, "DNG-14") && !strcmp(info->serial, "0042") &&
	          !strcmp(info->lens, "Macro 100mm F2.8"),
	      "identity %s %s %s %s %s", info->backend, info->vendor, info->model, info->serial,
	      info->lens);
	CHECK(kg_camera_frames_available(c) == 3, "3 frames available (%ld)",
	      kg_camera_frames_available(c));
	double v = 0, got = 0;
	CHECK(kg_camera_get(c, KG_FEAT_EXPOSURE_US, &v, &err) == 0 && fabs(v - 8000) < 1e-6,
	      "exposure %g us", v);
	CHECK(kg_camera_get(c, KG_FEAT_ISO, &v, &err) == 0 && v == 400, "ISO %g", v);
	CHECK(kg_camera_get(c, KG_FEAT_APERTURE, &v, &err) == 0 && v == 8, "aperture %g", v);
	CHECK(kg_camera_set(c, KG_FEAT_EXPOSURE_US, 8000, &got, &err) == 0,
	      "setting the files' own exposure: %s", err.msg);
	ret = kg_camera_set(c, KG_FEAT_EXPOSURE_US, 16000, &got, &err);
	CHECK(ret == KG_ERANGE && strstr(err.msg, "exposure_us"),
	      "another exposure refused: %d '%s'", ret, err.msg);
	kg_feature_info fi;
	CHECK(kg_camera_feature_info(c, KG_FEAT_GAIN, &fi, &err) == 0 && !fi.available,
	      "no gain feature");
	CHECK(kg_camera_manual(c, &err) == 0, "manual: nothing to turn off: %s", err.msg);
	kg_frame_format want = {0}, fmt;
	want.pixfmt = KG_PIX_RGB16;
	ret = kg_camera_set_format(c, &want, &fmt, &err);
	CHECK(ret == KG_ENOTSUP, "rgb16 from raw files refused: %d '%s'", ret, err.msg);
	CHECK(kg_camera_get_format(c, &fmt, &err) == 0 && fmt.pixfmt == KG_PIX_BAYER16 &&
	          fmt.bits == 16 && !strcmp(fmt.cfa, "RGGB") && fmt.width == W && fmt.height == H,
	      "format %s %d bits %s %dx%d", kg_pixfmt_name(fmt.pixfmt), fmt.bits, fmt.cfa,
	      fmt.width, fmt.height);
	CHECK(kg_camera_start(c, 0, &err) == 0, "start: %s", err.msg);
	static uint16_t d[W * H];
	for (int k = 0; k < 3; k++) {
		kg_frame f;
		ret = kg_camera_pop(c, 1000, &f, &err);
		CHECK(ret == 0, "frame %d: %s", k, err.msg);
		if (ret)
			break;
		fill(d, k, 16383);
		const uint16_t *px = f.data;
		int bad = 0;
		for (int i = 0; i < W * H; i++) {
			double val = ((double)d[i] - 512) / (16383 - 512);
			uint16_t want16 = val <= 0 ? 0 : val >= 1 ? 65535 : (uint16_t)lrint(val * 65535);
			bad += abs((int)px[i] - (int)want16) > 1;
		}
		CHECK(bad == 0, "frame %d: %d samples off the file's values", k, bad);
		CHECK(f.sequence == (uint64_t)k && f.source && strstr(f.source, "chart_") &&
		          f.source[strlen(f.source) - 5] == '0' + k && fabs(f.exposure_us - 8000) < 1e-6,
		      "frame %d: sequence %llu, source %s, exposure %g", k,
		      (unsigned long long)f.sequence, f.source ? f.source : "none", f.exposure_us);
		CHECK(f.source_note && strstr(f.source_note, "LibRaw") && strstr(f.source_note, "512"),
		      "source note '%s'", f.source_note ? f.source_note : "");
		kg_camera_push(c, &f, &err);
	}
	kg_frame f;
	ret = kg_camera_pop(c, 1000, &f, &err);
	CHECK(ret < 0 && strstr(err.msg, "all 3"), "a fourth frame: %d '%s'", ret, err.msg);
	kg_camera_free(&c);

	/* not one capture */
	write_set("mixed/a", 1, 1.0 / 125, "0042", W);
	write_set("mixed/b", 1, 1.0 / 60, "0042", W);
	snprintf(uri, sizeof(uri), "files:%s/mixed/*.dng", dir);
	expect_open_fail(uri, KG_EINVAL, "a_0.dng", "exposure time");
	write_set("cams/a", 1, 1.0 / 125, "0042", W);
	write_set("cams/b", 1, 1.0 / 125, "0043", W);
	snprintf(uri, sizeof(uri), "files:%s/cams", dir);
	expect_open_fail(uri, KG_EINVAL, "b_0.dng", "camera");
	write_set("sizes/a", 1, 1.0 / 125, "0042", W);
	write_set("sizes/b", 1, 1.0 / 125, "0042", W - 2);
	snprintf(uri, sizeof(uri), "files:%s/sizes/", dir);
	expect_open_fail(uri, KG_EINVAL, "b_0.dng", "size");
	snprintf(uri, sizeof(uri), "files:%s/shoot/nothing_*.cr3", dir);
	expect_open_fail(uri, KG_ENODEV, "nothing_*.cr3", "no file matches");

	/* TIFF files: a float mosaic with its CFA */
	kg_image *img = NULL;
	kg_image_new(W, H, 1, &img, &err);
	kg_image_set_cfa(img, "GBRG", 2, 2, &err);
	for (int i = 0; i < W * H; i++)
		img->data[i] = (float)(i % 100) / 100.0f;
	mkdir(path_of("tiffs"), 0777);
	CHECK(kg_image_write(img, path_of("tiffs/t1.tif"), 16, &err) == 0, "tiff: %s", err.msg);
	kg_image_free(&img);
	snprintf(uri, sizeof(uri), "files:%s/tiffs", dir);
	ret = kg_camera_open(uri, &c, &err);
	CHECK(ret == 0, "open %s: %s", uri, err.msg);
	if (!ret) {
		CHECK(kg_camera_get_format(c, &fmt, &err) == 0 && fmt.pixfmt == KG_PIX_BAYER16 &&
		          !strcmp(fmt.cfa, "GBRG"),
		      "TIFF mosaic served as bayer16 GBRG (%s %s)", kg_pixfmt_name(fmt.pixfmt),
		      fmt.cfa);
		CHECK(kg_camera_feature_info(c, KG_FEAT_EXPOSURE_US, &fi, &err) == 0 && !fi.available,
		      "a TIFF says nothing of its exposure");
		kg_camera_start(c, 0, &err);
		ret = kg_camera_pop(c, 1000, &f, &err);
		CHECK(ret == 0 && ((const uint16_t *)f.data)[57] == (uint16_t)lrint(0.57 * 65535),
		      "TIFF sample 57: %d", ret ? -1 : ((const uint16_t *)f.data)[57]);
		if (!ret)
			kg_camera_push(c, &f, &err);
		kg_camera_free(&c);
	}
	printf("  files:: identity, features, frames to the count, refusals, TIFF\n");
}

int main(void)
{
	if (!kg_raw_available())
		kg_test_skip("built without LibRaw");
	snprintf(dir, sizeof(dir), "/tmp/kg-raw-XXXXXX");
	if (!mkdtemp(dir))
		return 1;
	mkdir(path_of("shoot"), 0777);
	mkdir(path_of("mixed"), 0777);
	mkdir(path_of("cams"), 0777);
	mkdir(path_of("sizes"), 0777);
	test_linear();
	test_dng_levels();
	test_meta_and_readers();
	test_refusals();
	test_files_backend();
	int fails = kg_test_done("raw");
	if (!fails) {
		char cmd[128];
		snprintf(cmd, sizeof(cmd), "rm -rf %s", dir);
		if (system(cmd)) {
		}
	}
	return fails;
}
