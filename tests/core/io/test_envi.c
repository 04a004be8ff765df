/* ENVI cubes: round trips for every interleave in float32 and uint16, row blocks
 * written out of order in both input layouts, windows, header metadata and extra
 * keys, classification files, liberal parsing of foreign headers (byte order 1,
 * header offset, micrometres, odd case and braces across lines), and errors. */
#include <stdint.h>
#include <string.h>

#include "io_util.h"
#include "kg_core.h"
#include "kg_test.h"

enum { S = 7, L = 5, B = 4 };

/* The value of band b at (x, y); exact in float32 and, times 1000, in uint16. */
static float value(int x, int y, int b) { return (float)(x * 7 + y * 13 + b * 31) / 1000.0f; }

static const double wl[B] = {400, 405.5, 410, 415.25};
static const char *const names[B] = {"band one", "b2", "b3", "b4"};

static void fill_block(float *blk, int y0, int y1, enum kg_envi_layout layout)
{
	int rows = y1 - y0;
	for (int r = 0; r < rows; r++)
		for (int x = 0; x < S; x++)
			for (int b = 0; b < B; b++) {
				size_t i = layout == KG_LAYOUT_BIP ? ((size_t)r * S + x) * B + b
				                                   : ((size_t)b * rows + r) * S + x;
				blk[i] = value(x, y0 + r, b);
			}
}

static void round_trip(enum kg_envi_interleave il, enum kg_envi_type type)
{
	char name[64];
	snprintf(name, sizeof(name), "cube_%d_%d.hdr", (int)il, (int)type);
	const char *path = kg_test_path(name);
	char basis[] = "{1, 2, 3,\n  4, 5, 6}";
	kg_envi_pair extra[] = {{"kogei basis", basis}, {"kogei format", "weights/1"}};
	kg_envi_meta m = {.samples = S, .lines = L, .bands = B, .data_type = type,
	                  .interleave = il, .description = "test cube\nsecond line",
	                  .wavelength = wl, .band_names = names,
	                  .scale = type == KG_ENVI_U16 ? 1000 : 0, .n_extra = 2, .extra = extra};
	kg_envi_writer *w;
	kg_err err = {{0}};
	int files_before = io_count_files();
	CHECK(kg_envi_writer_open(path, &m, &w, &err) == 0, "open: %s", err.msg);
	/* Blocks out of order, alternating input layouts. */
	int blocks[][2] = {{3, 5}, {0, 2}, {2, 3}};
	float blk[S * L * B];
	for (int k = 0; k < 3; k++) {
		enum kg_envi_layout lay = k % 2 ? KG_LAYOUT_PLANAR : KG_LAYOUT_BIP;
		fill_block(blk, blocks[k][0], blocks[k][1], lay);
		CHECK(kg_envi_writer_put(w, blocks[k][0], blocks[k][1], lay, blk, &err) == 0, "put: %s",
		      err.msg);
	}
	CHECK(!kg_test_file_exists(path), "header not visible before finish");
	CHECK(kg_envi_writer_finish(&w, &err) == 0 && !w, "finish: %s", err.msg);
	CHECK(io_count_files() == files_before + 2, "exactly .hdr and .img written");
	char img[80];
	snprintf(img, sizeof(img), "cube_%d_%d.img", (int)il, (int)type);
	CHECK(kg_test_file_exists(kg_test_path(img)), "data file beside header");

	kg_envi *e;
	CHECK(kg_envi_open(path, &e, &err) == 0, "open for reading: %s", err.msg);
	if (!e)
		return;
	CHECK(e->meta.samples == S && e->meta.lines == L && e->meta.bands == B, "dims");
	CHECK(e->meta.data_type == type && e->meta.interleave == il, "type and interleave");
	CHECK(e->byte_order == 0 && e->header_offset == 0, "byte order 0, no offset");
	CHECK(e->meta.wavelength && e->meta.wavelength[1] == 405.5 && e->meta.wavelength[3] == 415.25,
	      "wavelengths");
	CHECK(e->wavelength_units && strcmp(e->wavelength_units, "Nanometers") == 0, "units");
	CHECK(e->meta.band_names && strcmp(e->meta.band_names[0], "band one") == 0, "band names");
	CHECK(e->meta.description && strstr(e->meta.description, "second line"), "description");
	CHECK(e->meta.classes == 0, "not a classification");
	CHECK(type != KG_ENVI_U16 || e->meta.scale == 1000, "scale factor");
	CHECK(e->meta.n_extra == 2 && strcmp(e->meta.extra[1].key, "kogei format") == 0 &&
	      strcmp(e->meta.extra[1].value, "weights/1") == 0, "extra keys kept in order");
	double *v;
	int n;
	CHECK(kg_envi_get_numbers(e, "kogei basis", &v, &n, &err) == 0 && n == 6 && v[5] == 6,
	      "basis list read back: %s", err.msg);
	free(v);

	float all[S * L * B], planar[S * L * B];
	CHECK(kg_envi_read(e, 0, 0, S, L, KG_LAYOUT_BIP, all, &err) == 0, "read: %s", err.msg);
	CHECK(kg_envi_read(e, 0, 0, S, L, KG_LAYOUT_PLANAR, planar, &err) == 0, "read planar");
	int bad = 0;
	for (int y = 0; y < L; y++)
		for (int x = 0; x < S; x++)
			for (int b = 0; b < B; b++) {
				bad += fabsf(all[(y * S + x) * B + b] - value(x, y, b)) > 1e-6f;
				bad += fabsf(planar[(b * L + y) * S + x] - value(x, y, b)) > 1e-6f;
			}
	CHECK(bad == 0, "interleave %d type %d: %d values differ", (int)il, (int)type, bad);
	/* A window away from the edges, both layouts. */
	float win[3 * 2 * B], winp[3 * 2 * B];
	CHECK(kg_envi_read(e, 2, 1, 3, 2, KG_LAYOUT_BIP, win, &err) == 0, "window: %s", err.msg);
	CHECK(kg_envi_read(e, 2, 1, 3, 2, KG_LAYOUT_PLANAR, winp, &err) == 0, "window planar");
	bad = 0;
	for (int y = 0; y < 2; y++)
		for (int x = 0; x < 3; x++)
			for (int b = 0; b < B; b++) {
				bad += fabsf(win[(y * 3 + x) * B + b] - value(x + 2, y + 1, b)) > 1e-6f;
				bad += fabsf(winp[(b * 2 + y) * 3 + x] - value(x + 2, y + 1, b)) > 1e-6f;
			}
	CHECK(bad == 0, "window: %d values differ", bad);
	CHECK(kg_envi_read(e, 5, 0, 3, 1, KG_LAYOUT_BIP, win, &err) == KG_EINVAL,
	      "window outside refused");
	kg_envi_close(&e);
	CHECK(e == NULL, "close nulls");

	/* Opening by the data file name finds the same header. */
	CHECK(kg_envi_open(kg_test_path(img), &e, &err) == 0 && e->meta.bands == B, "open by data name");
	kg_envi_close(&e);
}

static void test_incomplete_and_abort(void)
{
	kg_envi_meta m = {.samples = S, .lines = L, .bands = B, .data_type = KG_ENVI_F32};
	kg_envi_writer *w;
	kg_err err;
	int before = io_count_files();
	float blk[S * L * B];
	fill_block(blk, 0, 2, KG_LAYOUT_BIP);
	CHECK(kg_envi_writer_open(kg_test_path("partial.hdr"), &m, &w, &err) == 0, "open");
	CHECK(kg_envi_writer_put(w, 0, 2, KG_LAYOUT_BIP, blk, &err) == 0, "put");
	CHECK(kg_envi_writer_put(w, 4, 6, KG_LAYOUT_BIP, blk, &err) == KG_EINVAL,
	      "block past the end refused");
	CHECK(kg_envi_writer_finish(&w, &err) == KG_EINVAL && !w, "finish with missing lines fails");
	CHECK(strstr(err.msg, "lines 2 to 4 were never written") != NULL, "message: %s", err.msg);
	CHECK(io_count_files() == before, "nothing left behind after a failed finish");
	CHECK(kg_envi_writer_open(kg_test_path("aborted.hdr"), &m, &w, &err) == 0, "open");
	kg_envi_writer_abort(&w);
	CHECK(!w && io_count_files() == before, "abort leaves nothing");
	/* Names ENVI cannot hold. */
	const char *bad_names[B] = {"a,b", "c", "d", "e"};
	m.band_names = bad_names;
	CHECK(kg_envi_writer_open(kg_test_path("bad.hdr"), &m, &w, &err) == KG_EINVAL && !w,
	      "comma in band name refused");
	CHECK(strstr(err.msg, "bad.hdr") && strstr(err.msg, "band name"), "message: %s", err.msg);
	m.band_names = NULL;
	kg_envi_pair ex = {"wavelength", "{1}"};
	m.n_extra = 1;
	m.extra = &ex;
	CHECK(kg_envi_writer_open(kg_test_path("bad.hdr"), &m, &w, &err) == KG_EINVAL,
	      "extra key clashing with a standard key refused");
	/* the reader refuses a key given twice: so does the writer */
	kg_envi_pair twice[2] = {{"kogei note", "a"}, {"kogei note", "b"}};
	m.n_extra = 2;
	m.extra = twice;
	CHECK(kg_envi_writer_open(kg_test_path("bad.hdr"), &m, &w, &err) == KG_EINVAL && !w &&
	          strstr(err.msg, "'kogei note' given twice"),
	      "extra key given twice refused: %s", err.msg);
	m.n_extra = 0;
	m.extra = NULL;
	CHECK(io_count_files() == before, "nothing left behind");
}

static void test_classification(void)
{
	enum { W = 6, H = 3 };
	float labels[W * H];
	for (int i = 0; i < W * H; i++)
		labels[i] = (float)(i % 3);
	const char *cn[3] = {"unclassified", "gold", "shakudo"};
	unsigned char lut[9] = {0, 0, 0, 255, 200, 0, 40, 30, 60};
	kg_envi_meta m = {.samples = W, .lines = H, .bands = 1, .data_type = KG_ENVI_U8,
	                  .classes = 3, .class_names = cn, .class_lookup = lut};
	kg_err err;
	CHECK(kg_envi_write(kg_test_path("labels.hdr"), &m, KG_LAYOUT_BIP, labels, &err) == 0,
	      "classification: %s", err.msg);
	kg_envi *e;
	CHECK(kg_envi_open(kg_test_path("labels.hdr"), &e, &err) == 0, "open labels: %s", err.msg);
	if (!e)
		return;
	CHECK(e->meta.classes == 3 && strcmp(e->meta.class_names[2], "shakudo") == 0, "class names");
	CHECK(e->meta.class_lookup && e->meta.class_lookup[4] == 200, "class lookup");
	float back[W * H];
	CHECK(kg_envi_read(e, 0, 0, W, H, KG_LAYOUT_BIP, back, &err) == 0, "read labels");
	CHECK(memcmp(back, labels, sizeof(back)) == 0, "labels round trip");
	kg_envi_close(&e);
	m.data_type = KG_ENVI_F32;
	kg_envi_writer *w;
	CHECK(kg_envi_writer_open(kg_test_path("x.hdr"), &m, &w, &err) == KG_EINVAL,
	      "float classification refused");
}

/* A header as another tool might write it, over big-endian int16 data after a
 * 16-byte embedded header. */
static void test_foreign_header(void)
{
	const char *hdr = "ENVI\r\n"
	                  "; written by hand\n"
	                  "Description = {a foreign\n  cube}\n"
	                  "SAMPLES = 3\n"
	                  "Lines   =2\n"
	                  "bands= 2\n"
	                  "header   offset = 16\n"
	                  "data type = 2\n"
	                  "interleave = BIL\n"
	                  "byte order = 1\n"
	                  "wavelength units = Micrometers\n"
	                  "wavelength = {\n 0.5,\n 0.6 }\n"
	                  "sensor type = Unknown\n";
	CHECK(io_write_bytes(kg_test_path("foreign.hdr"), hdr, strlen(hdr)) == 0, "write header");
	unsigned char data[16 + 3 * 2 * 2 * 2] = {0};
	int k = 16;
	for (int y = 0; y < 2; y++)
		for (int b = 0; b < 2; b++)
			for (int x = 0; x < 3; x++) {
				int16_t v = (int16_t)(-100 * b + 10 * y + x);
				data[k++] = (unsigned char)((uint16_t)v >> 8);
				data[k++] = (unsigned char)((uint16_t)v & 0xff);
			}
	CHECK(io_write_bytes(kg_test_path("foreign.dat"), data, sizeof(data)) == 0, "write data");
	kg_envi *e;
	kg_err err = {{0}};
	CHECK(kg_envi_open(kg_test_path("foreign.hdr"), &e, &err) == 0, "foreign header: %s", err.msg);
	if (!e)
		return;
	CHECK(e->meta.samples == 3 && e->meta.lines == 2 && e->meta.bands == 2, "dims");
	CHECK(e->meta.interleave == KG_ENVI_BIL && e->byte_order == 1 && e->header_offset == 16,
	      "interleave, byte order, offset");
	CHECK(e->meta.wavelength && fabs(e->meta.wavelength[1] - 600) < 1e-9, "micrometres to nm");
	CHECK(e->meta.description && strcmp(e->meta.description, "a foreign\n  cube") == 0,
	      "description across lines: '%s'", e->meta.description);
	CHECK(kg_envi_get(e, "sensor type") && strcmp(kg_envi_get(e, "sensor type"), "Unknown") == 0,
	      "unknown key kept");
	CHECK(strstr(e->data_path, "foreign.dat") != NULL, "data file found: %s", e->data_path);
	float v[12];
	CHECK(kg_envi_read(e, 0, 0, 3, 2, KG_LAYOUT_BIP, v, &err) == 0, "read: %s", err.msg);
	int bad = 0;
	for (int y = 0; y < 2; y++)
		for (int x = 0; x < 3; x++)
			for (int b = 0; b < 2; b++)
				bad += v[(y * 3 + x) * 2 + b] != (float)(-100 * b + 10 * y + x);
	CHECK(bad == 0, "big-endian int16 decoded (%d wrong)", bad);
	kg_envi_close(&e);
}

static void expect_open_error(const char *name, const char *hdr, const char *want)
{
	const char *p = kg_test_path(name);
	CHECK(io_write_bytes(p, hdr, strlen(hdr)) == 0, "write");
	kg_envi *e = NULL;
	kg_err err = {{0}};
	int ret = kg_envi_open(p, &e, &err);
	CHECK(ret < 0 && !e, "%s: expected an error", name);
	char stem[16];
	snprintf(stem, sizeof(stem), "%.3s", name); /* e1.hdr or e1.img: the file is named */
	CHECK(strstr(err.msg, want) && strstr(err.msg, stem), "%s: message '%s' should mention '%s'",
	      name, err.msg, want);
	kg_envi_close(&e);
}

static void test_errors(void)
{
	io_write_bytes(kg_test_path("e1.img"), "12345678", 8);
	io_write_bytes(kg_test_path("e2.img"), "12345678", 8);
	io_write_bytes(kg_test_path("e3.img"), "12345678", 8);
	io_write_bytes(kg_test_path("e4.img"), "12345678", 8);
	io_write_bytes(kg_test_path("e5.img"), "12345678", 8);
	io_write_bytes(kg_test_path("e6.img"), "12345678", 8);
	expect_open_error("e1.hdr", "ENVI\nlines = 2\nbands = 1\ndata type = 4\n", "'samples' is missing");
	expect_open_error("e2.hdr", "ENVI\nsamples = 2\nlines = 2\nbands = 1\ndata type = 4\n",
	                  "e2.img: file is 8 bytes (too short): expected 16");
	expect_open_error("e3.hdr", "ENVI\nsamples = 1\nlines = 1\nbands = 1\ndata type = 4\n"
	                  "wavelength = {1, 2\n", "never closed");
	expect_open_error("e4.hdr", "not an envi header\n", "expected 'ENVI'");
	expect_open_error("e5.hdr", "ENVI\nsamples = x\nlines = 1\nbands = 1\ndata type = 4\n",
	                  "expected an integer");
	expect_open_error("e6.hdr", "ENVI\nsamples = 1\nlines = 1\nbands = 2\ndata type = 1\n"
	                  "wavelength = {1, 2, 3}\n", "expected 2");
	expect_open_error("e7.hdr", "ENVI\nsamples = 1\nlines = 1\nbands = 1\ndata type = 1\n",
	                  "no data file");
	expect_open_error("e8.hdr", "ENVI\nsamples = 1\nlines = 1\nbands = 1\ndata type = 6\n",
	                  "not supported");
	/* a data file larger than the header says, with and without a header offset */
	io_write_bytes(kg_test_path("e9.img"), "12345678", 8);
	expect_open_error("e9.hdr", "ENVI\nsamples = 1\nlines = 1\nbands = 1\ndata type = 4\n",
	                  "e9.img: file is 8 bytes (too long): expected 4");
	io_write_bytes(kg_test_path("e10.img"), "123456789", 9);
	expect_open_error("e10.hdr", "ENVI\nsamples = 1\nlines = 1\nbands = 1\ndata type = 4\n"
	                  "header offset = 4\n", "e10.img: file is 9 bytes (too long): expected 8");
	/* the same key twice, also when spelt differently; the key and the header named */
	io_write_bytes(kg_test_path("e11.img"), "1234", 4);
	expect_open_error("e11.hdr", "ENVI\nsamples = 1\nlines = 1\nbands = 1\ndata type = 4\n"
	                  "lines = 2\n", "e11.hdr: line 6: key 'lines' given twice");
	io_write_bytes(kg_test_path("e12.img"), "1234", 4);
	expect_open_error("e12.hdr", "ENVI\nsamples = 1\nlines = 1\nbands = 1\ndata type = 4\n"
	                  "wavelength = {500}\nWavelength  = {\n 600}\n",
	                  "e12.hdr: line 7: key 'wavelength' given twice");
	/* the same sizes, once each: accepted (the cases above fail for their reason only) */
	io_write_bytes(kg_test_path("e13.img"), "1234", 4);
	const char *e13 = "ENVI\nsamples = 1\nlines = 1\nbands = 1\ndata type = 4\n"
	                  "wavelength = {500}\n";
	io_write_bytes(kg_test_path("e13.hdr"), e13, strlen(e13));
	kg_envi *ok = NULL;
	kg_err err = {{0}};
	CHECK(kg_envi_open(kg_test_path("e13.hdr"), &ok, &err) == 0, "e13: %s", err.msg);
	kg_envi_close(&ok);
}

static void test_paths(void)
{
	char *h, *d;
	CHECK(kg_envi_paths("a/cube.hdr", &h, &d, NULL) == 0 && strcmp(d, "a/cube.img") == 0, "x.hdr");
	free(h);
	free(d);
	CHECK(kg_envi_paths("cube.bin", &h, &d, NULL) == 0 && strcmp(h, "cube.bin.hdr") == 0 &&
	      strcmp(d, "cube.bin") == 0, "data name");
	free(h);
	free(d);
	CHECK(kg_envi_paths("-", &h, &d, NULL) == KG_EINVAL, "stdout refused");
	char *s;
	double v[3] = {0.1, 1e-300, -2};
	CHECK(kg_envi_format_list(v, 3, &s, NULL) == 0 && strcmp(s, "{0.10000000000000001, 1e-300, -2}") == 0,
	      "format list: %s", s);
	free(s);
}

/* A cube large enough that writing and reading go through several internal chunks
 * of lines (about 16 MB of floats per conversion, 4 MB per read). */
static void test_large(void)
{
	enum { LS = 2000, LL = 40, LB = 61 };
	size_t n = (size_t)LS * LL * LB;
	float *cube = malloc(n * sizeof(float)), *back = malloc(n * sizeof(float));
	for (int y = 0; y < LL; y++)
		for (int x = 0; x < LS; x++)
			for (int b = 0; b < LB; b++)
				cube[((size_t)y * LS + x) * LB + b] = (float)((x * 3 + y * 5 + b) % 1000) / 1000.0f;
	enum kg_envi_interleave ils[] = {KG_ENVI_BSQ, KG_ENVI_BIL};
	for (int i = 0; i < 2; i++) {
		kg_envi_meta m = {.samples = LS, .lines = LL, .bands = LB, .data_type = KG_ENVI_U16,
		                  .interleave = ils[i], .scale = 1000};
		kg_err err;
		kg_inputs_reset(); /* the cube read in the last round is written again */
		CHECK(kg_envi_write(kg_test_path("large.hdr"), &m, KG_LAYOUT_BIP, cube, &err) == 0,
		      "large: %s", err.msg);
		kg_envi *e;
		CHECK(kg_envi_open(kg_test_path("large.hdr"), &e, &err) == 0, "large open: %s", err.msg);
		if (!e)
			break;
		CHECK(kg_envi_read(e, 0, 0, LS, LL, KG_LAYOUT_BIP, back, &err) == 0, "large read");
		size_t bad = 0;
		for (size_t k = 0; k < n; k++)
			bad += fabsf(back[k] - cube[k]) > 1e-6f;
		CHECK(bad == 0, "large cube, interleave %d: %zu values differ", (int)ils[i], bad);
		kg_envi_close(&e);
	}
	free(cube);
	free(back);
}

int main(void)
{
	io_tmpdir("envi");
	enum kg_envi_interleave ils[] = {KG_ENVI_BSQ, KG_ENVI_BIL, KG_ENVI_BIP};
	for (int i = 0; i < 3; i++) {
		round_trip(ils[i], KG_ENVI_F32);
		round_trip(ils[i], KG_ENVI_U16);
	}
	test_incomplete_and_abort();
	test_classification();
	test_foreign_header();
	test_errors();
	test_paths();
	test_large();
	return kg_test_done("envi");
}
