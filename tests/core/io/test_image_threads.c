/* A TIFF read whole by several readers at once (kg_image_read, each reader on its own
 * libtiff handle): the same image written uncompressed, LZW (with and without the
 * horizontal predictor, strips of many rows and of one), Deflate, tiled with partial
 * edge tiles, separate planes, 8-bit grey and 32-bit float, read on 1, 2, 3 and 7
 * threads, gives exactly the samples of the uncompressed file read on one thread and
 * of the row reader. A compressed file cut short, or with the data of a strip or tile
 * overwritten, is refused with a message that names the file and the first bad strip
 * or tile, the same message whatever the number of threads. kg_image_map decodes the
 * compressed 16-bit ones into the uncompressed file's codes, and refuses the damaged
 * ones with the same message. */
#include <stdint.h>
#include <string.h>
#include <tiffio.h>

#include "io_util.h"
#include "kg_core.h"
#include "kg_test.h"

/* Large enough for the readers to split it (1 Mpix and more, compressed), not a
 * multiple of the tile size. */
enum { W = 1250, H = 900 };

/* Smooth shading, edges and noise: LZW and Deflate neither store it raw nor shrink it
 * to nothing. */
static uint16_t code(uint32_t x, uint32_t y, int c)
{
	uint32_t h = (x * 73856093u) ^ (y * 19349663u) ^ ((uint32_t)c * 83492791u);
	h ^= h >> 13;
	uint32_t v = (x * 40 + y * 25 + (uint32_t)c * 9000) % 50000 + ((x / 97 + y / 61) % 2) * 9000 +
	             (h & 255);
	return (uint16_t)v;
}

typedef struct spec {
	const char *name;
	uint16_t compression, predictor;
	uint32_t rps, tile; /* strips of rps rows (0: one strip), or tiles tile x tile */
	int separate;
	int kind; /* 16: 16-bit RGB; 8: 8-bit grey; 32: float RGB */
} spec;

static int write_spec(const spec *s)
{
	TIFF *tif = TIFFOpen(kg_test_path(s->name), "w");
	if (!tif)
		return -1;
	int C = s->kind == 8 ? 1 : 3, bps = s->kind / 8;
	TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, (uint32_t)W);
	TIFFSetField(tif, TIFFTAG_IMAGELENGTH, (uint32_t)H);
	TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, (uint16_t)C);
	TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, (uint16_t)s->kind);
	TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, s->kind == 32 ? SAMPLEFORMAT_IEEEFP : SAMPLEFORMAT_UINT);
	TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, C == 3 ? PHOTOMETRIC_RGB : PHOTOMETRIC_MINISBLACK);
	TIFFSetField(tif, TIFFTAG_PLANARCONFIG, s->separate ? PLANARCONFIG_SEPARATE : PLANARCONFIG_CONTIG);
	TIFFSetField(tif, TIFFTAG_COMPRESSION, s->compression);
	if (s->predictor)
		TIFFSetField(tif, TIFFTAG_PREDICTOR, s->predictor);
	int planes = s->separate ? C : 1, spc = s->separate ? 1 : C;
	int ok = 1;
	/* sample (x, y, c) of plane p into buf at i */
#define PUT(buf, i, x, y, c)                                                            \
	do {                                                                            \
		uint16_t v_ = code((x), (y), (c));                                      \
		if (s->kind == 8) {                                                     \
			((uint8_t *)(buf))[i] = (uint8_t)(v_ >> 8);                     \
		} else if (s->kind == 16) {                                             \
			((uint16_t *)(buf))[i] = v_;                                    \
		} else {                                                                \
			((float *)(buf))[i] = v_ / 50000.0f;                            \
		}                                                                       \
	} while (0)
	if (s->tile) {
		TIFFSetField(tif, TIFFTAG_TILEWIDTH, s->tile);
		TIFFSetField(tif, TIFFTAG_TILELENGTH, s->tile);
		size_t n = (size_t)s->tile * s->tile * spc;
		unsigned char *t = malloc(n * bps);
		for (int p = 0; ok && t && p < planes; p++)
			for (uint32_t ty = 0; ok && ty < H; ty += s->tile)
				for (uint32_t tx = 0; ok && tx < W; tx += s->tile) {
					memset(t, 0, n * bps);
					for (uint32_t y = ty; y < H && y < ty + s->tile; y++)
						for (uint32_t x = tx; x < W && x < tx + s->tile; x++)
							for (int c = 0; c < spc; c++) {
								size_t i = ((size_t)(y - ty) * s->tile + (x - tx)) * spc + c;
								PUT(t, i, x, y, s->separate ? p : c);
							}
					ok = TIFFWriteTile(tif, t, tx, ty, 0, (uint16_t)p) >= 0;
				}
		ok = ok && t;
		free(t);
	} else {
		TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, s->rps ? s->rps : (uint32_t)H);
		unsigned char *row = malloc((size_t)W * spc * bps);
		for (int p = 0; ok && row && p < planes; p++)
			for (uint32_t y = 0; ok && y < H; y++) {
				for (uint32_t x = 0; x < W; x++)
					for (int c = 0; c < spc; c++)
						PUT(row, (size_t)x * spc + c, x, y, s->separate ? p : c);
				ok = TIFFWriteScanline(tif, row, y, (uint16_t)p) == 1;
			}
		ok = ok && row;
		free(row);
	}
#undef PUT
	TIFFClose(tif);
	return ok ? 0 : -1;
}

static kg_image *read_on(const char *name, int threads, kg_err *err)
{
	kg_image *img = NULL;
	int old = kg_image_set_read_threads(threads);
	if (kg_image_read(kg_test_path(name), &img, err))
		img = NULL;
	kg_image_set_read_threads(old);
	return img;
}

static int same(const kg_image *a, const kg_image *b)
{
	return a && b && a->width == b->width && a->height == b->height &&
	       a->channels == b->channels &&
	       memcmp(a->data, b->data, sizeof(float) * a->width * a->height * a->channels) == 0;
}

/* The row reader, 7 rows at a time (across strip and tile boundaries). */
static int same_as_rows(const char *name, const kg_image *img)
{
	kg_image_rows *r = NULL;
	kg_err err = {{0}};
	if (kg_image_rows_open(kg_test_path(name), &r, &err))
		return 0;
	size_t row = (size_t)W * img->channels;
	float *buf = malloc(sizeof(float) * row * 7);
	int ok = buf != NULL;
	for (int y = 0; ok && y < H; y += 7) {
		int n = H - y < 7 ? H - y : 7;
		ok = kg_image_rows_read(r, n, buf, &err) == 0 &&
		     memcmp(buf, img->data + (size_t)y * row, sizeof(float) * row * n) == 0;
	}
	free(buf);
	kg_image_rows_free(&r);
	return ok;
}

static const int thread_counts[] = {2, 3, 7};

static void test_layouts(void)
{
	const spec specs[] = {
	    {"rgb16_none.tif", COMPRESSION_NONE, 0, 16, 0, 0, 16},
	    {"rgb16_lzw_pred.tif", COMPRESSION_LZW, PREDICTOR_HORIZONTAL, 32, 0, 0, 16},
	    {"rgb16_lzw.tif", COMPRESSION_LZW, 0, 9, 0, 0, 16},
	    {"rgb16_lzw_row.tif", COMPRESSION_LZW, PREDICTOR_HORIZONTAL, 1, 0, 0, 16},
	    {"rgb16_lzw_one.tif", COMPRESSION_LZW, PREDICTOR_HORIZONTAL, 0, 0, 0, 16},
	    {"rgb16_zip.tif", COMPRESSION_ADOBE_DEFLATE, PREDICTOR_HORIZONTAL, 32, 0, 0, 16},
	    {"rgb16_lzw_tile.tif", COMPRESSION_LZW, PREDICTOR_HORIZONTAL, 0, 128, 0, 16},
	    {"rgb16_zip_tile_sep.tif", COMPRESSION_ADOBE_DEFLATE, 0, 0, 64, 1, 16},
	    {"rgb16_lzw_sep.tif", COMPRESSION_LZW, PREDICTOR_HORIZONTAL, 20, 0, 1, 16},
	    {"grey8_none.tif", COMPRESSION_NONE, 0, 16, 0, 0, 8},
	    {"grey8_zip.tif", COMPRESSION_ADOBE_DEFLATE, PREDICTOR_HORIZONTAL, 5, 0, 0, 8},
	    {"rgbf_none.tif", COMPRESSION_NONE, 0, 16, 0, 0, 32},
	    {"rgbf_lzw_fp.tif", COMPRESSION_LZW, PREDICTOR_FLOATINGPOINT, 16, 0, 0, 32},
	};
	kg_image *ref[33] = {0}; /* by kind: the uncompressed file on one thread */
	for (size_t i = 0; i < sizeof(specs) / sizeof(specs[0]); i++) {
		const spec *s = &specs[i];
		kg_err err = {{0}};
		CHECK(write_spec(s) == 0, "%s: written", s->name);
		kg_image *one = read_on(s->name, 1, &err);
		CHECK(one != NULL, "%s: read on 1 thread: %s", s->name, err.msg);
		if (!one)
			continue;
		if (s->compression == COMPRESSION_NONE && !ref[s->kind])
			ref[s->kind] = one;
		CHECK(same(one, ref[s->kind]), "%s: 1 thread: the samples of the uncompressed file",
		      s->name);
		CHECK(same_as_rows(s->name, one), "%s: the row reader's samples", s->name);
		for (size_t k = 0; k < sizeof(thread_counts) / sizeof(thread_counts[0]); k++) {
			kg_image *many = read_on(s->name, thread_counts[k], &err);
			CHECK(many != NULL, "%s: read on %d threads: %s", s->name, thread_counts[k], err.msg);
			CHECK(same(many, one), "%s: %d threads give the samples of one", s->name,
			      thread_counts[k]);
			kg_image_free(&many);
		}
		if (one != ref[s->kind])
			kg_image_free(&one);
	}
	for (int k = 0; k < 33; k++)
		kg_image_free(&ref[k]);
}

/* Overwrite bytes [off, off + n) of a file with a pattern. */
static int scribble(const char *path, uint64_t off, size_t n, unsigned char pattern)
{
	FILE *fp = fopen(path, "r+b");
	if (!fp)
		return -1;
	int ok = fseek(fp, (long)off, SEEK_SET) == 0;
	for (size_t i = 0; ok && i < n; i++)
		ok = fputc(pattern ^ (int)(i * 151), fp) != EOF;
	return fclose(fp) == 0 && ok ? 0 : -1;
}

/* Offset and byte count of strip or tile k. */
static int chunk_at(const char *path, uint32_t k, uint64_t *off, uint64_t *cnt)
{
	TIFF *tif = TIFFOpen(path, "r");
	if (!tif)
		return -1;
	int e1 = 0, e2 = 0;
	*off = TIFFGetStrileOffsetWithErr(tif, k, &e1);
	*cnt = TIFFGetStrileByteCountWithErr(tif, k, &e2);
	TIFFClose(tif);
	return e1 || e2 ? -1 : 0;
}

/* The error of a read on `threads` threads, in msg; 0 when it failed as it should. */
static int read_error(const char *name, int threads, char *msg, size_t size)
{
	kg_err err = {{0}};
	kg_image *img = read_on(name, threads, &err);
	snprintf(msg, size, "%s", err.msg);
	int failed = img == NULL;
	kg_image_free(&img);
	return failed ? 0 : -1;
}

static void expect_same_error(const char *name, const char *want1, const char *want2)
{
	char one[1024], many[1024];
	CHECK(read_error(name, 1, one, sizeof(one)) == 0, "%s: 1 thread: refused", name);
	CHECK(strstr(one, name) && strstr(one, want1) && (!want2 || strstr(one, want2)),
	      "%s: 1 thread: '%s' should name the file and say '%s' and '%s'", name, one, want1,
	      want2 ? want2 : "");
	for (size_t k = 0; k < sizeof(thread_counts) / sizeof(thread_counts[0]); k++) {
		CHECK(read_error(name, thread_counts[k], many, sizeof(many)) == 0,
		      "%s: %d threads: refused", name, thread_counts[k]);
		CHECK(strcmp(one, many) == 0, "%s: %d threads: '%s', 1 thread: '%s'", name,
		      thread_counts[k], many, one);
	}
}

static void test_damaged(void)
{
	const spec lzw = {"bad_lzw.tif", COMPRESSION_LZW, PREDICTOR_HORIZONTAL, 16, 0, 0, 16};
	const spec zip = {"bad_zip.tif", COMPRESSION_ADOBE_DEFLATE, PREDICTOR_HORIZONTAL, 16, 0, 0, 16};
	const spec tiles = {"bad_tiles.tif", COMPRESSION_LZW, PREDICTOR_HORIZONTAL, 0, 128, 0, 16};
	const spec cut = {"cut_lzw.tif", COMPRESSION_LZW, PREDICTOR_HORIZONTAL, 16, 0, 0, 16};
	const spec *all[] = {&lzw, &zip, &tiles, &cut};
	for (size_t i = 0; i < 4; i++)
		CHECK(write_spec(all[i]) == 0, "%s: written", all[i]->name);

	/* two strips' data overwritten, a late one and an early one: the early one is
	 * named, on any number of threads */
	const spec *scribbled[] = {&lzw, &zip, &tiles};
	const uint32_t early[] = {20, 20, 9}, late[] = {50, 50, 60};
	for (size_t i = 0; i < 3; i++) {
		const char *p = kg_test_path(scribbled[i]->name);
		uint64_t off = 0, cnt = 0;
		for (int twice = 0; twice < 2; twice++) {
			uint32_t k = twice ? early[i] : late[i];
			CHECK(chunk_at(p, k, &off, &cnt) == 0 && cnt > 64, "%s: chunk %u found",
			      scribbled[i]->name, k);
			CHECK(scribble(p, off + 4, cnt - 8, 0xA5) == 0, "%s: chunk %u overwritten",
			      scribbled[i]->name, k);
		}
		char at[64];
		if (scribbled[i]->tile)
			snprintf(at, sizeof(at), "tile at row %u", early[i] / ((W + 127) / 128) * 128);
		else
			snprintf(at, sizeof(at), "strip at row %u", early[i] * 16);
		expect_same_error(scribbled[i]->name, at, NULL);
	}

	/* cut short: libtiff writes the directory after the pixels, so a file cut
	 * anywhere in its pixels has lost it */
	const char *p = kg_test_path(cut.name);
	FILE *fp = fopen(p, "rb");
	unsigned char *bytes = NULL;
	long n = 0;
	int cut_ok = fp && fseek(fp, 0, SEEK_END) == 0 && (n = ftell(fp)) > 0 &&
	             fseek(fp, 0, SEEK_SET) == 0 && (bytes = malloc((size_t)n)) &&
	             fread(bytes, 1, (size_t)n, fp) == (size_t)n;
	if (fp)
		fclose(fp);
	CHECK(cut_ok && io_write_bytes(p, bytes, (size_t)(n * 4 / 10)) == 0, "%s: cut", cut.name);
	free(bytes);
	expect_same_error(cut.name, "not a readable TIFF file", NULL);
}

static kg_image *map_on(const char *name, int threads, int *code, kg_err *err)
{
	kg_image *img = NULL;
	int old = kg_image_set_read_threads(threads);
	*code = kg_image_map(kg_test_path(name), &img, err);
	kg_image_set_read_threads(old);
	return *code ? NULL : img;
}

/* kg_image_map (the chart check's reader): a compressed 16-bit file of one plane is
 * decoded into its codes, the uncompressed file's codes exactly, on any number of
 * threads; a damaged one is refused with kg_image_read's message; other layouts are
 * left to kg_image_read (KG_ENOTSUP). Uses the files test_layouts and test_damaged
 * wrote. */
static void test_map_codes(void)
{
	kg_err err = {{0}};
	int code;
	kg_image *ref = map_on("rgb16_none.tif", 1, &code, &err);
	CHECK(ref && ref->u16 && ref->map, "rgb16_none.tif: mapped: %s", err.msg);
	if (!ref)
		return;
	const char *coded[] = {"rgb16_lzw_pred.tif", "rgb16_lzw.tif", "rgb16_lzw_row.tif",
	                       "rgb16_lzw_one.tif", "rgb16_zip.tif", "rgb16_lzw_tile.tif"};
	const int threads[] = {1, 2, 7};
	size_t n = (size_t)W * H * 3;
	for (size_t i = 0; i < sizeof(coded) / sizeof(coded[0]); i++)
		for (size_t k = 0; k < 3; k++) {
			kg_image *img = map_on(coded[i], threads[k], &code, &err);
			CHECK(img && img->u16 && !img->data && img->width == W && img->height == H &&
			          img->channels == 3 && img->bits == 16,
			      "%s: %d threads: decoded into codes: %s", coded[i], threads[k], err.msg);
			CHECK(img && memcmp(img->u16, ref->u16, n * sizeof(uint16_t)) == 0,
			      "%s: %d threads: the uncompressed file's codes", coded[i], threads[k]);
			CHECK(img && kg_image_map_check(img, &err) == 0, "%s: map check", coded[i]);
			kg_image_free(&img);
		}
	kg_image_free(&ref);
	const char *other[] = {"grey8_zip.tif", "rgbf_lzw_fp.tif", "rgb16_lzw_sep.tif",
	                       "rgb16_zip_tile_sep.tif"};
	for (size_t i = 0; i < sizeof(other) / sizeof(other[0]); i++) {
		kg_image *img = map_on(other[i], 0, &code, &err);
		CHECK(code == KG_ENOTSUP && !img, "%s: left to kg_image_read (%d: %s)", other[i], code,
		      err.msg);
		kg_image_free(&img);
	}
	const char *bad[] = {"bad_lzw.tif", "bad_zip.tif", "bad_tiles.tif"};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		char want[1024];
		CHECK(read_error(bad[i], 1, want, sizeof(want)) == 0, "%s: read refused", bad[i]);
		for (size_t k = 0; k < 3; k++) {
			kg_err e = {{0}};
			kg_image *img = map_on(bad[i], threads[k], &code, &e);
			CHECK(!img && code < 0 && code != KG_ENOTSUP && strcmp(e.msg, want) == 0,
			      "%s: %d threads: map refused with '%s', read with '%s'", bad[i], threads[k],
			      e.msg, want);
			kg_image_free(&img);
		}
	}
}

int main(void)
{
	io_tmpdir("image_threads");
	test_layouts();
	test_damaged();
	test_map_codes();
	return kg_test_done("image-threads");
}
