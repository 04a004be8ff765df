/* Images: TIFF and PNG round trips at 8/16/32 bits with 1 and 3 channels (clamping
 * and rounding checked code by code), TIFF layouts written here with libtiff
 * (separate planes, tiles, short strips, alpha, min-is-white, deflate), CFA tags,
 * PNG transfer curves and alpha, and malformed or truncated files that must give
 * errors, not crashes. */
#include <png.h>
#include <stdint.h>
#include <string.h>
#include <tiffio.h>

#include "io_util.h"
#include "kg_core.h"
#include "kg_test.h"

enum { W = 9, H = 5 };

/* Test values: a ramp plus out-of-range values and NaN to exercise clamping. */
static float sample(int x, int y, int c)
{
	if (x == 0 && y == 0)
		return -0.25f;
	if (x == 1 && y == 0)
		return 1.5f;
	if (x == 2 && y == 0)
		return NAN;
	return (float)(x * 37 + y * 101 + c * 13) / 500.0f;
}

static kg_image *make_image(int channels)
{
	kg_image *img;
	if (kg_image_new(W, H, channels, &img, NULL))
		abort();
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++)
			for (int c = 0; c < channels; c++)
				img->data[(y * W + x) * channels + c] = sample(x, y, c);
	return img;
}

/* What a bits-deep integer file should give back for v. */
static float quantised(float v, int bits)
{
	float full = bits == 8 ? 255.0f : 65535.0f;
	if (!(v > 0))
		return 0;
	if (v >= 1)
		return 1;
	return floorf(v * full + 0.5f) / full;
}

static void round_trip(const char *ext, int channels, int bits)
{
	char name[64];
	snprintf(name, sizeof(name), "rt_%d_%d.%s", channels, bits, ext);
	const char *p = kg_test_path(name);
	kg_image *img = make_image(channels), *back = NULL;
	kg_err err = {{0}};
	CHECK(kg_image_write(img, p, bits, &err) == 0, "%s: write: %s", name, err.msg);
	CHECK(kg_image_read(p, &back, &err) == 0, "%s: read: %s", name, err.msg);
	if (back) {
		CHECK(back->width == W && back->height == H && back->channels == channels, "%s: dims",
		      name);
		CHECK(back->bits == bits && back->is_float == (bits == 32), "%s: depth %d", name,
		      back->bits);
		CHECK(back->cfa == NULL && back->note[0] == '\0', "%s: no CFA, no note ('%s')", name,
		      back->note);
		int bad = 0;
		for (int i = 0; i < W * H * channels; i++) {
			float v = img->data[i], r = back->data[i];
			if (bits == 32)
				bad += isnan(v) ? !isnan(r) : r != v;
			else
				bad += fabsf(r - quantised(v, bits)) > 1e-7f;
		}
		CHECK(bad == 0, "%s: %d samples differ", name, bad);
	}
	kg_image_free(&back);
	kg_image_free(&img);
	CHECK(img == NULL, "free nulls");
}

/* ---- TIFF layouts written directly with libtiff ---------------------------------- */

struct tiff_spec {
	const char *name;
	int spp, bits, fmt, photo, planar, tile, rps, compression;
};

/* The expected decoded value of sample s at (x, y) for a spec. */
static float tiff_expected(const struct tiff_spec *t, int x, int y, int s)
{
	unsigned code = (unsigned)(x * 3 + y * 7 + s * 50);
	if (t->fmt == SAMPLEFORMAT_IEEEFP)
		return (float)code / 64.0f;
	float v = t->bits == 8 ? (float)(code % 256) / 255.0f : (float)(code * 200 % 65536) / 65535.0f;
	return t->photo == PHOTOMETRIC_MINISWHITE ? 1.0f - v : v;
}

static void store(const struct tiff_spec *t, unsigned char *dst, size_t i, int x, int y, int s)
{
	unsigned code = (unsigned)(x * 3 + y * 7 + s * 50);
	if (t->fmt == SAMPLEFORMAT_IEEEFP) {
		float f = (float)code / 64.0f;
		memcpy(dst + i * 4, &f, 4);
	} else if (t->bits == 8)
		dst[i] = (unsigned char)(code % 256);
	else {
		uint16_t u = (uint16_t)(code * 200 % 65536);
		memcpy(dst + i * 2, &u, 2);
	}
}

static int write_tiff(const struct tiff_spec *t, int w, int h)
{
	TIFF *tif = TIFFOpen(kg_test_path(t->name), "w");
	if (!tif)
		return -1;
	TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, (uint32_t)w);
	TIFFSetField(tif, TIFFTAG_IMAGELENGTH, (uint32_t)h);
	TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, (uint16_t)t->spp);
	TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, (uint16_t)t->bits);
	TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, (uint16_t)t->fmt);
	TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, (uint16_t)t->photo);
	TIFFSetField(tif, TIFFTAG_PLANARCONFIG, (uint16_t)t->planar);
	TIFFSetField(tif, TIFFTAG_COMPRESSION, (uint16_t)t->compression);
	if (t->spp == 4 || t->spp == 2) {
		uint16_t extra = EXTRASAMPLE_UNASSALPHA;
		TIFFSetField(tif, TIFFTAG_EXTRASAMPLES, 1, &extra);
	}
	int separate = t->planar == PLANARCONFIG_SEPARATE, spc = separate ? 1 : t->spp;
	size_t bps = (size_t)t->bits / 8;
	int ok = 1;
	if (t->tile) {
		TIFFSetField(tif, TIFFTAG_TILEWIDTH, (uint32_t)t->tile);
		TIFFSetField(tif, TIFFTAG_TILELENGTH, (uint32_t)t->tile);
		size_t n = (size_t)t->tile * t->tile * spc * bps;
		unsigned char *buf = calloc(1, n);
		for (int p = 0; p < (separate ? t->spp : 1); p++)
			for (int ty = 0; ty < h; ty += t->tile)
				for (int tx = 0; tx < w; tx += t->tile) {
					for (int r = 0; r < t->tile; r++)
						for (int c = 0; c < t->tile; c++)
							for (int s = 0; s < spc; s++)
								store(t, buf, ((size_t)r * t->tile + c) * spc + s, tx + c, ty + r,
								      separate ? p : s);
					ok &= TIFFWriteTile(tif, buf, (uint32_t)tx, (uint32_t)ty, 0, (uint16_t)p) > 0;
				}
		free(buf);
	} else {
		TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, (uint32_t)t->rps);
		unsigned char *row = calloc(1, (size_t)w * spc * bps);
		for (int p = 0; p < (separate ? t->spp : 1); p++)
			for (int y = 0; y < h; y++) {
				for (int x = 0; x < w; x++)
					for (int s = 0; s < spc; s++)
						store(t, row, (size_t)x * spc + s, x, y, separate ? p : s);
				ok &= TIFFWriteScanline(tif, row, (uint32_t)y, (uint16_t)p) == 1;
			}
		free(row);
	}
	TIFFClose(tif);
	return ok ? 0 : -1;
}

/* The row reader gives the whole reader's values bit for bit, read in bands of uneven
 * heights (1, 2, 3, ... rows), through a row source too; reading past the end is
 * refused. */
static void check_rows(const char *name, const kg_image *whole)
{
	kg_image_rows *r = NULL;
	kg_err err = {{0}};
	CHECK(kg_image_rows_open(kg_test_path(name), &r, &err) == 0, "%s: rows: %s", name, err.msg);
	if (!r)
		return;
	const kg_image *h = kg_image_rows_header(r);
	CHECK(h->width == whole->width && h->height == whole->height &&
	      h->channels == whole->channels && h->bits == whole->bits && !h->data &&
	      !strcmp(h->note, whole->note), "%s: rows header", name);
	kg_row_source src;
	kg_row_source_of_rows(r, &src);
	size_t n = (size_t)whole->width * whole->channels;
	float *buf = malloc((size_t)whole->height * n * sizeof(float));
	int y = 0, step = 1, ok = 1;
	while (y < whole->height && ok) {
		int rows = step < whole->height - y ? step : whole->height - y;
		ok = src.read(src.user, y, rows, buf + (size_t)y * n, &err) == 0;
		y += rows;
		step++;
	}
	CHECK(ok, "%s: rows read: %s", name, err.msg);
	CHECK(ok && memcmp(buf, whole->data, (size_t)whole->height * n * sizeof(float)) == 0,
	      "%s: rows differ from the whole image", name);
	CHECK(kg_image_rows_read(r, 1, buf, &err) == KG_EINVAL && strstr(err.msg, name),
	      "%s: a row past the end refused: %s", name, err.msg);
	free(buf);
	kg_image_rows_free(&r);
	CHECK(r == NULL, "%s: freed", name);
}

static void test_tiff_layouts(void)
{
	const struct tiff_spec specs[] = {
		{"sep16.tif", 3, 16, SAMPLEFORMAT_UINT, PHOTOMETRIC_RGB, PLANARCONFIG_SEPARATE, 0, 3, COMPRESSION_NONE},
		{"tile8.tif", 3, 8, SAMPLEFORMAT_UINT, PHOTOMETRIC_RGB, PLANARCONFIG_CONTIG, 16, 0, COMPRESSION_NONE},
		{"tilesepf.tif", 3, 32, SAMPLEFORMAT_IEEEFP, PHOTOMETRIC_RGB, PLANARCONFIG_SEPARATE, 16, 0, COMPRESSION_NONE},
		{"strips16.tif", 1, 16, SAMPLEFORMAT_UINT, PHOTOMETRIC_MINISBLACK, PLANARCONFIG_CONTIG, 0, 3, COMPRESSION_NONE},
		{"rgba8.tif", 4, 8, SAMPLEFORMAT_UINT, PHOTOMETRIC_RGB, PLANARCONFIG_CONTIG, 0, 7, COMPRESSION_NONE},
		{"greya16sep.tif", 2, 16, SAMPLEFORMAT_UINT, PHOTOMETRIC_MINISBLACK, PLANARCONFIG_SEPARATE, 0, 5, COMPRESSION_NONE},
		{"white8.tif", 1, 8, SAMPLEFORMAT_UINT, PHOTOMETRIC_MINISWHITE, PLANARCONFIG_CONTIG, 0, 4, COMPRESSION_NONE},
		{"deflate16.tif", 3, 16, SAMPLEFORMAT_UINT, PHOTOMETRIC_RGB, PLANARCONFIG_CONTIG, 0, 8, COMPRESSION_ADOBE_DEFLATE},
		{"lzwtilef.tif", 1, 32, SAMPLEFORMAT_IEEEFP, PHOTOMETRIC_MINISBLACK, PLANARCONFIG_CONTIG, 16, 0, COMPRESSION_LZW},
	};
	const int w = 40, h = 21; /* partial tiles and strips on both edges */
	for (size_t k = 0; k < sizeof(specs) / sizeof(specs[0]); k++) {
		const struct tiff_spec *t = &specs[k];
		if (!TIFFIsCODECConfigured((uint16_t)t->compression)) {
			printf("note: %s skipped, codec not built into libtiff\n", t->name);
			continue;
		}
		CHECK(write_tiff(t, w, h) == 0, "%s: libtiff write", t->name);
		kg_image *img = NULL;
		kg_err err = {{0}};
		CHECK(kg_image_read_tiff(kg_test_path(t->name), &img, &err) == 0, "%s: %s", t->name, err.msg);
		if (!img)
			continue;
		int C = t->photo == PHOTOMETRIC_RGB ? 3 : 1;
		CHECK(img->channels == C && img->width == w && img->height == h, "%s: shape", t->name);
		CHECK((t->spp > C) == (strstr(img->note, "dropped") != NULL), "%s: note '%s'", t->name,
		      img->note);
		int bad = 0;
		for (int y = 0; y < h; y++)
			for (int x = 0; x < w; x++)
				for (int s = 0; s < C; s++)
					bad += fabsf(img->data[(y * w + x) * C + s] - tiff_expected(t, x, y, s)) > 1e-7f;
		CHECK(bad == 0, "%s: %d samples differ", t->name, bad);
		check_rows(t->name, img);
		kg_image_free(&img);
	}
}

static void expect_read_error(const char *name, const char *want1, const char *want2)
{
	kg_image *img = NULL;
	kg_err err = {{0}};
	CHECK(kg_image_read(kg_test_path(name), &img, &err) < 0 && !img, "%s: expected an error", name);
	CHECK(strstr(err.msg, name) && strstr(err.msg, want1) && (!want2 || strstr(err.msg, want2)),
	      "%s: message '%s' should name the file and say '%s'", name, err.msg, want1);
	kg_image_free(&img);
}

static void test_tiff_refused(void)
{
	const struct tiff_spec t12 = {"twelve.tif", 1, 12, SAMPLEFORMAT_UINT, PHOTOMETRIC_MINISBLACK,
	                              PLANARCONFIG_CONTIG, 0, 4, COMPRESSION_NONE};
	TIFF *tif = TIFFOpen(kg_test_path(t12.name), "w");
	TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, 4u);
	TIFFSetField(tif, TIFFTAG_IMAGELENGTH, 2u);
	TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, 12);
	TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, 1);
	TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
	unsigned char row[6] = {0};
	TIFFWriteScanline(tif, row, 0, 0);
	TIFFWriteScanline(tif, row, 1, 0);
	TIFFClose(tif);
	expect_read_error("twelve.tif", "12-bit", "expected 8, 16 or 32-bit float");

	tif = TIFFOpen(kg_test_path("signed.tif"), "w");
	TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, 2u);
	TIFFSetField(tif, TIFFTAG_IMAGELENGTH, 1u);
	TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, 16);
	TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, SAMPLEFORMAT_INT);
	TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
	int16_t srow[2] = {-1, 1};
	TIFFWriteScanline(tif, srow, 0, 0);
	TIFFClose(tif);
	expect_read_error("signed.tif", "signed integer", NULL);

	tif = TIFFOpen(kg_test_path("palette.tif"), "w");
	TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, 2u);
	TIFFSetField(tif, TIFFTAG_IMAGELENGTH, 1u);
	TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, 8);
	TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_PALETTE);
	uint16_t map[256] = {0};
	TIFFSetField(tif, TIFFTAG_COLORMAP, map, map, map);
	unsigned char prow[2] = {0, 1};
	TIFFWriteScanline(tif, prow, 0, 0);
	TIFFClose(tif);
	expect_read_error("palette.tif", "expected grey, RGB or CFA", NULL);
}

/* XOR the value of a SHORT or LONG tag in the first directory of a little-endian
 * classic TIFF (as libtiff writes it here); 0 when done. */
static int patch_tag(const char *path, uint16_t tag, uint32_t mask)
{
	FILE *fp = fopen(path, "r+b");
	unsigned char h[8], e[12];
	int done = -1;
	if (fp && fread(h, 1, 8, fp) == 8 && h[0] == 'I') {
		uint32_t ifd = h[4] | h[5] << 8 | h[6] << 16 | (uint32_t)h[7] << 24;
		unsigned char c[2];
		if (fseek(fp, (long)ifd, SEEK_SET) == 0 && fread(c, 1, 2, fp) == 2)
			for (int i = 0, n = c[0] | c[1] << 8; i < n && done; i++) {
				long at = (long)ifd + 2 + 12L * i;
				if (fseek(fp, at, SEEK_SET) || fread(e, 1, 12, fp) != 12)
					break;
				uint16_t t = (uint16_t)(e[0] | e[1] << 8), ty = (uint16_t)(e[2] | e[3] << 8);
				if (t != tag || (ty != 3 && ty != 4) || (ty == 3 && mask > 0xffff))
					continue;
				for (int b = 0; b < (ty == 3 ? 2 : 4); b++)
					e[8 + b] ^= (unsigned char)(mask >> (8 * b));
				done = fseek(fp, at, SEEK_SET) || fwrite(e, 1, 12, fp) != 12;
			}
	}
	if (fp)
		fclose(fp);
	return done;
}

/* A w x h RGB float (grey 8-bit when grey) TIFF with the given strips or tiles and
 * compression, its samples a ramp. */
static void write_layout(const char *name, uint32_t w, uint32_t h, int grey, uint32_t rps,
                         uint32_t tile, uint16_t compression)
{
	TIFF *tif = TIFFOpen(kg_test_path(name), "w");
	int C = grey ? 1 : 3, bps = grey ? 1 : 4;
	TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, w);
	TIFFSetField(tif, TIFFTAG_IMAGELENGTH, h);
	TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, grey ? 8 : 32);
	TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, C);
	TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, grey ? SAMPLEFORMAT_UINT : SAMPLEFORMAT_IEEEFP);
	TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, grey ? PHOTOMETRIC_MINISBLACK : PHOTOMETRIC_RGB);
	TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
	TIFFSetField(tif, TIFFTAG_COMPRESSION, compression);
	if (tile) {
		TIFFSetField(tif, TIFFTAG_TILEWIDTH, tile);
		TIFFSetField(tif, TIFFTAG_TILELENGTH, tile);
		size_t n = (size_t)tile * tile * C * bps;
		unsigned char *buf = calloc(n, 1);
		for (size_t i = 0; i < n; i++)
			buf[i] = (unsigned char)(i * 7);
		for (uint32_t y = 0; y < h; y += tile)
			for (uint32_t x = 0; x < w; x += tile)
				TIFFWriteTile(tif, buf, x, y, 0, 0);
		free(buf);
	} else {
		TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, rps);
		unsigned char *row = malloc((size_t)w * C * bps);
		for (uint32_t y = 0; y < h; y++) {
			for (size_t i = 0; i < (size_t)w * C; i++)
				if (grey)
					row[i] = (unsigned char)(i + y);
				else {
					float v = (float)(i + y) / 1000.0f;
					memcpy(row + 4 * i, &v, 4);
				}
			TIFFWriteScanline(tif, row, y, 0);
		}
		free(row);
	}
	TIFFClose(tif);
}

/* Images that lie about their size: ImageLength with a bit flipped (the strips or
 * tiles cover a sliver of what it declares), refused at once naming the file and the
 * tag, whatever the layout; a strip that decodes to fewer rows than declared. */
static void test_tiff_lies(void)
{
	const struct {
		const char *name;
		uint32_t w, h, rps, tile, flip;
		int grey;
		uint16_t compression;
		const char *want1, *want2;
	} t[] = {
		/* one strip of 48 rows, ImageLength 48 -> 16432 (a SHORT): 343 strips implied */
		{"lie_one_strip.tif", 64, 48, 48, 0, 1u << 14, 0, COMPRESSION_NONE, "StripOffsets 0",
		 "64 x 16432"},
		{"lie_strips.tif", 64, 48, 10, 0, 1u << 14, 0, COMPRESSION_NONE, "StripByteCounts",
		 "64 x 16432"},
		{"lie_deflate.tif", 64, 48, 10, 0, 1u << 14, 0, COMPRESSION_ADOBE_DEFLATE,
		 "StripOffsets 0", "ImageLength"},
		{"lie_lzw.tif", 64, 48, 48, 0, 1u << 14, 0, COMPRESSION_LZW, "StripOffsets 0",
		 "ImageLength"},
		{"lie_tiles.tif", 64, 64, 0, 32, 1u << 14, 0, COMPRESSION_NONE, "TileOffsets 0",
		 "64 x 16448"},
		/* one LZW strip of 64 rows holding 8: ImageLength 8 -> 12, still one strip,
		 * which decodes to 8 rows */
		{"lie_short_decode.tif", 16, 8, 64, 0, 4, 1, COMPRESSION_LZW, "RowsPerStrip 12",
		 "ImageLength 12"},
		/* uncompressed: the strip has 8 rows of bytes, ImageLength says 12 */
		{"lie_short_bytes.tif", 16, 8, 64, 0, 4, 1, COMPRESSION_NONE, "StripByteCounts",
		 "16 x 12"},
	};
	for (size_t i = 0; i < sizeof(t) / sizeof(t[0]); i++) {
		write_layout(t[i].name, t[i].w, t[i].h, t[i].grey, t[i].rps, t[i].tile,
		             t[i].compression);
		kg_image *img = NULL;
		kg_err err = {{0}};
		CHECK(kg_image_read(kg_test_path(t[i].name), &img, &err) == 0 && img &&
		          img->height == (int)t[i].h,
		      "%s: the honest file: %s", t[i].name, err.msg);
		kg_image_free(&img);
		CHECK(patch_tag(kg_test_path(t[i].name), TIFFTAG_IMAGELENGTH, t[i].flip) == 0,
		      "%s: ImageLength patched", t[i].name);
		expect_read_error(t[i].name, t[i].want1, t[i].want2);
		kg_image_rows *r = NULL;
		int ret = kg_image_rows_open(kg_test_path(t[i].name), &r, &err);
		float *rows = NULL;
		if (ret == 0) { /* the short decode is found when its strip is read */
			rows = malloc(sizeof(float) * t[i].w * 3 * 12);
			ret = kg_image_rows_read(r, 12, rows, &err);
		}
		CHECK(ret < 0 && strstr(err.msg, t[i].name) && strstr(err.msg, t[i].want1),
		      "%s: rows: %s", t[i].name, err.msg);
		free(rows);
		kg_image_rows_free(&r);
	}
}

/* A large image of many strips or tiles (4.2 Mpix, partial last band) is read whole
 * by two readers at once: the same samples as the row reader's, row by row, and,
 * for the strips, the ramp written. */
static void test_tiff_two_readers(void)
{
	const struct {
		const char *name;
		uint32_t rps, tile;
	} t[] = {{"big_strips.tif", 7, 0}, {"big_tiles.tif", 0, 256}};
	const uint32_t w = 2048, h = 2050;
	for (size_t i = 0; i < sizeof(t) / sizeof(t[0]); i++) {
		write_layout(t[i].name, w, h, 1, t[i].rps, t[i].tile, COMPRESSION_NONE);
		kg_image *img = NULL;
		kg_image_rows *r = NULL;
		kg_err err = {{0}};
		CHECK(kg_image_read(kg_test_path(t[i].name), &img, &err) == 0 && img &&
		          img->width == (int)w && img->height == (int)h,
		      "%s: read whole: %s", t[i].name, err.msg);
		CHECK(kg_image_rows_open(kg_test_path(t[i].name), &r, &err) == 0, "%s: rows: %s",
		      t[i].name, err.msg);
		float *row = malloc(sizeof(float) * w);
		long differ = 0, ramp = 0;
		for (uint32_t y = 0; img && r && row && y < h; y++) {
			if (kg_image_rows_read(r, 1, row, &err) != 0) {
				differ = -1;
				break;
			}
			differ += memcmp(row, img->data + (size_t)y * w, sizeof(float) * w) != 0;
			for (uint32_t x = 0; !t[i].tile && x < w; x++)
				ramp += img->data[(size_t)y * w + x] != (unsigned char)(x + y) / 255.0f;
		}
		CHECK(differ == 0, "%s: %ld rows differ from the row reader's (%s)", t[i].name,
		      differ, err.msg);
		CHECK(ramp == 0, "%s: %ld samples differ from the ramp written", t[i].name, ramp);
		free(row);
		kg_image_rows_free(&r);
		kg_image_free(&img);
		remove(kg_test_path(t[i].name));
	}
}

/* A 16-bit RGB TIFF of w x h from codes, contiguous strips of rps rows. */
static int write_rgb16(const char *name, int w, int h, int rps, const uint16_t *codes)
{
	TIFF *tif = TIFFOpen(kg_test_path(name), "w");
	if (!tif)
		return -1;
	TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, (uint32_t)w);
	TIFFSetField(tif, TIFFTAG_IMAGELENGTH, (uint32_t)h);
	TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, (uint16_t)3);
	TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, (uint16_t)16);
	TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, (uint16_t)PHOTOMETRIC_RGB);
	TIFFSetField(tif, TIFFTAG_PLANARCONFIG, (uint16_t)PLANARCONFIG_CONTIG);
	TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, (uint32_t)rps);
	int ok = 1;
	for (int y = 0; y < h; y++)
		ok &= TIFFWriteScanline(tif, (void *)(codes + (size_t)y * w * 3), (uint32_t)y, 0) == 1;
	TIFFClose(tif);
	return ok ? 0 : -1;
}

/* kg_image_map: an uncompressed 16-bit grey or RGB TIFF in order is mapped (a
 * compressed one of one plane decoded into its codes), each code reading (through
 * kg_image_u16_lut) as the float the reader gives, and its saturation scan gives what
 * the floats' does; every other layout is KG_ENOTSUP, to be read. */
static void test_tiff_map(void)
{
	const struct tiff_spec specs[] = {
		{"map_rgb16.tif", 3, 16, SAMPLEFORMAT_UINT, PHOTOMETRIC_RGB, PLANARCONFIG_CONTIG, 0, 3, COMPRESSION_NONE},
		{"map_grey16.tif", 1, 16, SAMPLEFORMAT_UINT, PHOTOMETRIC_MINISBLACK, PLANARCONFIG_CONTIG, 0, 21, COMPRESSION_NONE},
		{"map_sep16.tif", 3, 16, SAMPLEFORMAT_UINT, PHOTOMETRIC_RGB, PLANARCONFIG_SEPARATE, 0, 3, COMPRESSION_NONE},
		{"map_tile16.tif", 3, 16, SAMPLEFORMAT_UINT, PHOTOMETRIC_RGB, PLANARCONFIG_CONTIG, 16, 0, COMPRESSION_NONE},
		{"map_rgb8.tif", 3, 8, SAMPLEFORMAT_UINT, PHOTOMETRIC_RGB, PLANARCONFIG_CONTIG, 0, 3, COMPRESSION_NONE},
		{"map_rgba16.tif", 4, 16, SAMPLEFORMAT_UINT, PHOTOMETRIC_RGB, PLANARCONFIG_CONTIG, 0, 3, COMPRESSION_NONE},
		{"map_white16.tif", 1, 16, SAMPLEFORMAT_UINT, PHOTOMETRIC_MINISWHITE, PLANARCONFIG_CONTIG, 0, 3, COMPRESSION_NONE},
		{"map_float.tif", 3, 32, SAMPLEFORMAT_IEEEFP, PHOTOMETRIC_RGB, PLANARCONFIG_CONTIG, 0, 3, COMPRESSION_NONE},
		{"map_deflate16.tif", 3, 16, SAMPLEFORMAT_UINT, PHOTOMETRIC_RGB, PLANARCONFIG_CONTIG, 0, 8, COMPRESSION_ADOBE_DEFLATE},
	};
	const int w = 40, h = 21;
	const float *lut = kg_image_u16_lut();
	for (size_t k = 0; k < sizeof(specs) / sizeof(specs[0]); k++) {
		const struct tiff_spec *t = &specs[k];
		if (!TIFFIsCODECConfigured((uint16_t)t->compression))
			continue;
		CHECK(write_tiff(t, w, h) == 0, "%s: libtiff write", t->name);
		kg_image *read = NULL, *map = NULL;
		kg_err err = {{0}};
		CHECK(kg_image_read(kg_test_path(t->name), &read, &err) == 0, "%s: %s", t->name, err.msg);
		int ret = kg_image_map(kg_test_path(t->name), &map, &err);
		int mappable = k < 2 || t->compression != COMPRESSION_NONE;
		if (!mappable) {
			CHECK(ret == KG_ENOTSUP && !map && strstr(err.msg, t->name),
			      "%s: mapped (%d), expected KG_ENOTSUP naming the file: %s", t->name, ret,
			      err.msg);
		} else {
			CHECK(ret == 0 && map && map->u16 && !map->data, "%s: not mapped: %s", t->name,
			      err.msg);
			if (map && read) {
				CHECK(map->width == read->width && map->height == read->height &&
				          map->channels == read->channels && map->bits == read->bits &&
				          !map->is_float && !strcmp(map->note, read->note),
				      "%s: header differs from the reader's", t->name);
				size_t n = (size_t)w * h * read->channels, bad = 0;
				for (size_t i = 0; i < n; i++)
					bad += memcmp(&lut[map->u16[i]], &read->data[i], sizeof(float)) != 0;
				CHECK(bad == 0, "%s: %zu samples read otherwise than mapped", t->name, bad);
			}
		}
		kg_image_free(&map);
		kg_image_free(&read);
		remove(kg_test_path(t->name));
	}
	/* the saturation scan: R and G pile up below full scale (5 % of the pixels at
	 * 60000 and 60001), B does not; then nothing piles up at all */
	const int sw = 256, sh = 200;
	uint16_t *codes = malloc((size_t)sw * sh * 3 * sizeof(*codes));
	for (int pass = 0; codes && pass < 2; pass++) {
		unsigned s = 99;
		for (size_t i = 0; i < (size_t)sw * sh; i++)
			for (int c = 0; c < 3; c++) {
				s = s * 1103515245u + 12345u;
				uint16_t v = (uint16_t)(5000 + (s >> 8) % 55000);
				if (pass == 0 && c < 2 && (s >> 4) % 20 == 0)
					v = (uint16_t)(60000 + (s >> 12) % 2);
				codes[i * 3 + c] = v;
			}
		CHECK(write_rgb16("map_sat.tif", sw, sh, 16, codes) == 0, "map_sat: write");
		kg_image *read = NULL, *map = NULL;
		kg_err err = {{0}};
		kg_saturation a, b;
		memset(&a, 0, sizeof(a));
		memset(&b, 0, sizeof(b));
		CHECK(kg_image_read(kg_test_path("map_sat.tif"), &read, &err) == 0 &&
		          kg_image_map(kg_test_path("map_sat.tif"), &map, &err) == 0,
		      "map_sat: %s", err.msg);
		if (read && map) {
			CHECK(kg_saturation_of_image(read, 1.0, &a, &err) == 0 &&
			          kg_saturation_of_image(map, 1.0, &b, &err) == 0,
			      "map_sat: saturation: %s", err.msg);
			CHECK(!memcmp(&a, &b, sizeof(a)), "map_sat pass %d: the mapped image's saturation "
			      "differs from the floats' (any %.6f vs %.6f)", pass, b.fraction_any,
			      a.fraction_any);
			CHECK(pass == 1 || (a.found[0] && a.found[1] && !a.found[2] && a.fraction_any > 0.05),
			      "map_sat: the pile-up in R and G not found (%d %d %d, any %.4f)", a.found[0],
			      a.found[1], a.found[2], a.fraction_any);
		}
		kg_image_free(&map);
		kg_image_free(&read);
	}
	free(codes);
	remove(kg_test_path("map_sat.tif"));
}

static void test_cfa(void)
{
	kg_image *img = make_image(1), *back = NULL;
	kg_err err;
	CHECK(kg_image_set_cfa(img, "RGGX", 2, 2, &err) == KG_EINVAL, "bad CFA letter refused");
	CHECK(kg_image_set_cfa(img, "GRBG", 2, 2, &err) == 0, "set CFA");
	CHECK(kg_image_write_tiff(img, kg_test_path("raw.tif"), 16, &err) == 0, "write raw: %s", err.msg);
	CHECK(kg_image_read(kg_test_path("raw.tif"), &back, &err) == 0, "read raw: %s", err.msg);
	if (back)
		CHECK(back->cfa && strcmp(back->cfa, "GRBG") == 0 && back->cfa_rows == 2 &&
		      back->cfa_cols == 2, "CFA pattern read back: %s", back->cfa ? back->cfa : "(none)");
	kg_image_free(&back);
	kg_image_free(&img);
}

/* ---- PNG ------------------------------------------------------------------------- */

static int write_png_raw(const char *name, int w, int h, int color_type, int depth,
                         const unsigned char *pixels, size_t rowbytes, int srgb)
{
	FILE *f = fopen(kg_test_path(name), "wb");
	png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
	png_infop info = png_create_info_struct(png);
	if (setjmp(png_jmpbuf(png))) {
		png_destroy_write_struct(&png, &info);
		fclose(f);
		return -1;
	}
	png_init_io(png, f);
	png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, depth, color_type, PNG_INTERLACE_NONE,
	             PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
	if (srgb)
		png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
	png_write_info(png, info);
	for (int y = 0; y < h; y++)
		png_write_row(png, pixels + (size_t)y * rowbytes);
	png_write_end(png, NULL);
	png_destroy_write_struct(&png, &info);
	fclose(f);
	return 0;
}

/* 16-bit RGB rows (w * 6 bytes each) to a PNG, interlaced (Adam7) or not. */
static int write_png16(const char *name, int w, int h, unsigned char *px, int interlace)
{
	FILE *f = fopen(kg_test_path(name), "wb");
	png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
	png_infop info = png_create_info_struct(png);
	png_bytep *rows = malloc((size_t)h * sizeof(png_bytep));
	for (int y = 0; y < h; y++)
		rows[y] = px + (size_t)y * w * 6;
	int ok = 0;
	if (setjmp(png_jmpbuf(png)) == 0) {
		png_init_io(png, f);
		png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, 16, PNG_COLOR_TYPE_RGB,
		             interlace ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE,
		             PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
		png_write_info(png, info);
		png_write_image(png, rows);
		png_write_end(png, NULL);
		ok = 1;
	}
	png_destroy_write_struct(&png, &info);
	free(rows);
	fclose(f);
	return ok ? 0 : -1;
}

static void test_png_kinds(void)
{
	/* RGBA 8-bit: alpha dropped with a note. */
	unsigned char rgba[2 * 2 * 4] = {10, 20, 30, 255, 40, 50, 60, 0, 70, 80, 90, 128, 255, 0, 1, 2};
	CHECK(write_png_raw("rgba.png", 2, 2, PNG_COLOR_TYPE_RGBA, 8, rgba, 8, 0) == 0, "rgba");
	kg_image *img = NULL;
	kg_err err;
	CHECK(kg_image_read(kg_test_path("rgba.png"), &img, &err) == 0, "read rgba: %s", err.msg);
	if (img) {
		CHECK(img->channels == 3 && strstr(img->note, "alpha"), "alpha dropped: '%s'", img->note);
		CHECK_NEAR(img->data[3], 40 / 255.0, 1e-7, "second pixel red");
		CHECK_NEAR(img->data[11], 1 / 255.0, 1e-7, "last pixel blue");
	}
	kg_image_free(&img);
	/* Grey 2-bit: expanded to 8 bits by replication, so 3 reads as 1.0. */
	unsigned char g2[1] = {0x1B}; /* 0 1 2 3 */
	CHECK(write_png_raw("grey2.png", 4, 1, PNG_COLOR_TYPE_GRAY, 2, g2, 1, 0) == 0, "grey2");
	CHECK(kg_image_read(kg_test_path("grey2.png"), &img, &err) == 0, "read grey2: %s", err.msg);
	if (img) {
		CHECK(img->channels == 1 && img->bits == 2, "2-bit grey");
		CHECK_NEAR(img->data[1], 85 / 255.0, 1e-7, "code 1 of 3");
		CHECK_NEAR(img->data[3], 1.0, 1e-7, "code 3 of 3");
	}
	kg_image_free(&img);
	/* Palette with transparency: expanded to RGB, transparency dropped. */
	{
		FILE *pf = fopen(kg_test_path("pal.png"), "wb");
		png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
		png_infop info = png_create_info_struct(png);
		if (setjmp(png_jmpbuf(png)) == 0) {
			png_init_io(png, pf);
			png_set_IHDR(png, info, 3, 1, 8, PNG_COLOR_TYPE_PALETTE, PNG_INTERLACE_NONE,
			             PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
			png_color pal[2] = {{255, 0, 0}, {0, 51, 255}};
			png_byte trans[1] = {0};
			png_set_PLTE(png, info, pal, 2);
			png_set_tRNS(png, info, trans, 1, NULL);
			png_set_gAMA(png, info, 1.0);
			png_write_info(png, info);
			png_byte row[3] = {0, 1, 1};
			png_write_row(png, row);
			png_write_end(png, NULL);
		}
		png_destroy_write_struct(&png, &info);
		fclose(pf);
	}
	CHECK(kg_image_read(kg_test_path("pal.png"), &img, &err) == 0, "read palette: %s", err.msg);
	if (img) {
		CHECK(img->channels == 3 && strstr(img->note, "transparency"), "palette: '%s'", img->note);
		CHECK_NEAR(img->data[0], 1.0, 1e-7, "palette entry 0 red");
		CHECK_NEAR(img->data[4], 0.2, 1e-7, "palette entry 1 green");
	}
	kg_image_free(&img);
	/* sRGB-tagged: linearised. The preview helper writes sRGB too. */
	unsigned char rgb[2 * 3] = {0, 128, 255, 10, 200, 30};
	CHECK(kg_png_write_rgb8(kg_test_path("preview.png"), rgb, 2, 1, &err) == 0, "preview: %s", err.msg);
	CHECK(kg_image_read(kg_test_path("preview.png"), &img, &err) == 0, "read preview: %s", err.msg);
	if (img) {
		CHECK(strstr(img->note, "sRGB") != NULL, "note says sRGB: '%s'", img->note);
		CHECK_NEAR(img->data[1], 0.2158605, 1e-6, "sRGB 128 -> 0.21586 linear");
		CHECK_NEAR(img->data[2], 1.0, 1e-6, "sRGB 255 -> 1");
	}
	kg_image_free(&img);
	/* 16-bit RGB, plain and Adam7-interlaced: the row reader as the whole reader. */
	for (int interlace = 0; interlace < 2; interlace++) {
		const char *name = interlace ? "adam7.png" : "rows16.png";
		const int w = 13, h = 11;
		unsigned char *px = malloc((size_t)w * h * 6);
		for (int i = 0; i < w * h * 3; i++) {
			px[2 * i] = (unsigned char)(i * 37);
			px[2 * i + 1] = (unsigned char)(i * 11 + interlace);
		}
		CHECK(write_png16(name, w, h, px, interlace) == 0, "%s: libpng write", name);
		CHECK(kg_image_read(kg_test_path(name), &img, &err) == 0, "read %s: %s", name, err.msg);
		if (img) {
			CHECK(fabs(img->data[5] - ((px[10] << 8) | px[11]) / 65535.0) < 1e-7,
			      "%s: sample 5", name);
			check_rows(name, img);
		}
		kg_image_free(&img);
		free(px);
	}
	CHECK(kg_png_write_rgb8(kg_test_path("no.png"), rgb, 0, 1, &err) == KG_EINVAL, "zero width refused");
	kg_image *one = make_image(1);
	CHECK(kg_image_write_png(one, kg_test_path("f.png"), 32, &err) == KG_EINVAL &&
	      strstr(err.msg, "expected 8 or 16"), "32-bit PNG refused: %s", err.msg);
	CHECK(kg_image_write(one, kg_test_path("f.jpg"), 8, &err) == KG_EINVAL &&
	      strstr(err.msg, "f.jpg"), "unknown extension refused: %s", err.msg);
	CHECK(kg_image_write(one, kg_test_path("nodir/f.png"), 8, &err) < 0, "missing directory fails");
	kg_image_free(&one);
}

/* ---- malformed files ---------------------------------------------------------------- */

static unsigned char *slurp(const char *p, size_t *n)
{
	char *b;
	if (kg_read_file(p, &b, n, NULL))
		return NULL;
	return (unsigned char *)b;
}

/* Every truncation and a sweep of corrupted bytes: each read must return cleanly. */
static void torture(const char *src_name, const char *ext)
{
	size_t n;
	unsigned char *orig = slurp(kg_test_path(src_name), &n);
	CHECK(orig != NULL, "read %s", src_name);
	if (!orig)
		return;
	char name[64];
	snprintf(name, sizeof(name), "bad.%s", ext);
	int errors = 0, total = 0;
	for (size_t cut = 0; cut < n; cut += 1 + cut / 16) {
		io_write_bytes(kg_test_path(name), orig, cut);
		kg_image *img = NULL;
		kg_err err = {{0}};
		int ret = kg_image_read(kg_test_path(name), &img, &err);
		CHECK((ret == 0) == (img != NULL), "%s cut at %zu: result and image agree", ext, cut);
		if (ret) {
			errors++;
			CHECK(strstr(err.msg, name) != NULL, "%s cut at %zu: message names file: %s", ext,
			      cut, err.msg);
		}
		total++;
		kg_image_free(&img);
	}
	CHECK(errors > total / 2, "%s: truncations mostly give errors (%d of %d)", ext, errors, total);
	unsigned char *bad = malloc(n);
	unsigned long long r = 12345;
	for (int k = 0; k < 300; k++) {
		memcpy(bad, orig, n);
		for (int j = 0; j < 4; j++) {
			r = r * 6364136223846793005ull + 1442695040888963407ull;
			/* The first and last bytes: headers, TIFF directories (libtiff writes
			 * them last), PNG chunks. */
			size_t span = n < 768 ? n : 768, at = (size_t)(r >> 33) % span;
			if (at >= 256 && n > 768)
				at = n - (at - 256) - 1;
			bad[at] = (unsigned char)(r >> 20);
		}
		io_write_bytes(kg_test_path(name), bad, n);
		kg_image *img = NULL;
		int ret = kg_image_read(kg_test_path(name), &img, NULL);
		CHECK((ret == 0) == (img != NULL), "%s corrupted: result and image agree", ext);
		kg_image_free(&img);
	}
	free(bad);
	free(orig);
}

/* A 4 x 2 8-bit grey TIFF with its directory first and the strip after it, so the
 * pixel data can be cut short. */
static size_t tiny_tiff(unsigned char *b)
{
	static const uint16_t tags[9][2] = {{256, 4}, {257, 2}, {258, 8}, {259, 1}, {262, 1},
	                                    {273, 122}, {277, 1}, {278, 2}, {279, 8}};
	size_t k = 0;
	memcpy(b, "II*\0\x08\0\0\0\x09\0", 10);
	k = 10;
	for (int i = 0; i < 9; i++) {
		uint16_t type = (tags[i][0] == 273 || tags[i][0] == 279) ? 4 : 3;
		uint32_t count = 1, value = tags[i][1];
		memcpy(b + k, &tags[i][0], 2);
		memcpy(b + k + 2, &type, 2);
		memcpy(b + k + 4, &count, 4);
		memcpy(b + k + 8, &value, 4);
		k += 12;
	}
	memset(b + k, 0, 4); /* no next directory */
	k += 4;
	for (int i = 0; i < 8; i++)
		b[k++] = (unsigned char)(i * 30);
	return k;
}

static void test_malformed(void)
{
	unsigned char tiny[160];
	size_t n = tiny_tiff(tiny);
	CHECK(n == 130, "tiny TIFF is %zu bytes", n);
	io_write_bytes(kg_test_path("tiny.tif"), tiny, n);
	kg_image *t = NULL;
	kg_err e;
	CHECK(kg_image_read(kg_test_path("tiny.tif"), &t, &e) == 0, "tiny TIFF: %s", e.msg);
	if (t)
		CHECK_NEAR(t->data[7], 210 / 255.0, 1e-7, "tiny TIFF last pixel");
	kg_image_free(&t);
	io_write_bytes(kg_test_path("cut.tif"), tiny, n - 3);
	expect_read_error("cut.tif", "strip 0 of 1", "lies beyond the end of the 127-byte file");

	torture("rt_3_16.tif", "tif");
	torture("tile8.tif", "tif");
	torture("rt_3_16.png", "png");
	io_write_bytes(kg_test_path("text.tif"), "hello, world\n", 13);
	expect_read_error("text.tif", "expected a TIFF, PNG, JPEG or camera raw file", NULL);
	kg_image *img = NULL;
	kg_err err;
	CHECK(kg_image_read(kg_test_path("missing.png"), &img, &err) == KG_ENOENT && !img, "missing file");
	/* A PNG signature with nothing after it, and a TIFF header pointing nowhere. */
	io_write_bytes(kg_test_path("sig.png"), "\x89PNG\r\n\x1a\n", 8);
	expect_read_error("sig.png", "PNG", NULL);
	io_write_bytes(kg_test_path("hdr.tif"), "II*\0\xff\xff\xff\x7f", 8);
	expect_read_error("hdr.tif", "TIFF", NULL);
}

int main(void)
{
	io_tmpdir("image");
	int bits[] = {8, 16, 32};
	for (int c = 1; c <= 3; c += 2)
		for (int b = 0; b < 3; b++) {
			round_trip("tif", c, bits[b]);
			if (bits[b] != 32)
				round_trip("png", c, bits[b]);
		}
	test_tiff_layouts();
	test_tiff_refused();
	test_tiff_lies();
	test_tiff_two_readers();
	test_tiff_map();
	test_cfa();
	test_png_kinds();
	test_malformed();
	return kg_test_done("image");
}
