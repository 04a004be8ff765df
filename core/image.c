#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <png.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <tiffio.h>
#include <unistd.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include "fsutil.h"
#include "image.h"
#include "mapfile.h"
#include "raw.h"
#include "kg_config.h"

#if HAVE_JPEG
#include <setjmp.h>
#include <jpeglib.h>
#endif

#define MAX_SIDE (1L << 20)

static int check_dims(const char *path, long w, long h, kg_err *err)
{
	if (w < 1 || h < 1 || w > MAX_SIDE || h > MAX_SIDE || w * h > KG_IMAGE_MAX_PIXELS)
		return kg_fail(err, KG_EINVAL, "%s: image of %ld x %ld pixels: expected 1 to %ld per "
		               "side and at most %ld pixels", path, w, h, MAX_SIDE, KG_IMAGE_MAX_PIXELS);
	return 0;
}

/* Transparent huge pages for a large, still untouched block (calloc maps it fresh):
 * filling a 12 Mpix RGB image of floats otherwise takes 35 000 page faults, about a
 * third of a whole `kogei chart detect` of it on a VM. Only a hint; the 2 MB-aligned
 * inside of the block. */
static void huge_pages(void *p, size_t size)
{
#ifdef MADV_HUGEPAGE
	const uintptr_t huge = (uintptr_t)2 << 20;
	uintptr_t a = ((uintptr_t)p + huge - 1) & ~(huge - 1), b = ((uintptr_t)p + size) & ~(huge - 1);
	if (size >= 4 * huge && b > a)
		(void)madvise((void *)a, b - a, MADV_HUGEPAGE);
#else
	(void)p;
	(void)size;
#endif
}

int kg_image_new(int width, int height, int channels, kg_image **out, kg_err *err)
{
	kg_check_arg(out, err);
	*out = NULL;
	int ret = check_dims("new image", width, height, err);
	if (ret)
		return ret;
	if (channels != 1 && channels != 3)
		return kg_fail(err, KG_EINVAL, "new image: %d channels: expected 1 or 3", channels);
	size_t n = (size_t)width * (size_t)height * (size_t)channels;
	kg_image *img = calloc(1, sizeof(*img) + n * sizeof(float));
	if (!img)
		return kg_fail(err, KG_ENOMEM, "image of %d x %d x %d: out of memory", width, height,
		               channels);
	huge_pages(img, sizeof(*img) + n * sizeof(float));
	img->width = width;
	img->height = height;
	img->channels = channels;
	img->data = (float *)(img + 1);
	img->bits = 32;
	img->is_float = 1;
	*out = img;
	return 0;
}

void kg_image_free(kg_image **img)
{
	if (img && *img) {
		kg_mapfile_free(&(*img)->map);
		free((*img)->cfa);
		free(*img);
		*img = NULL;
	}
}

int kg_image_set_cfa(kg_image *img, const char *pattern, int rows, int cols, kg_err *err)
{
	kg_check_arg(img && pattern, err);
	if (rows < 1 || cols < 1 || rows > 16 || cols > 16 || strlen(pattern) != (size_t)(rows * cols) ||
	    strspn(pattern, "RGBCMYW") != strlen(pattern))
		return kg_fail(err, KG_EINVAL, "CFA pattern '%s' of %d x %d: expected rows * cols letters "
		               "from RGBCMYW (e.g. RGGB, 2 x 2)", pattern, rows, cols);
	char *p = strdup(pattern);
	if (!p)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	free(img->cfa);
	img->cfa = p;
	img->cfa_rows = rows;
	img->cfa_cols = cols;
	return 0;
}

static void add_note(kg_image *img, const char *s)
{
	size_t n = strlen(img->note);
	snprintf(img->note + n, sizeof(img->note) - n, "%s%s", n ? "; " : "", s);
}

int kg_image_write(const kg_image *img, const char *path, int bits, kg_err *err)
{
	kg_check_arg(img && path, err);
	size_t n = strlen(path);
	if ((n > 4 && strcasecmp(path + n - 4, ".tif") == 0) ||
	    (n > 5 && strcasecmp(path + n - 5, ".tiff") == 0))
		return kg_image_write_tiff(img, path, bits, err);
	if (n > 4 && strcasecmp(path + n - 4, ".png") == 0)
		return kg_image_write_png(img, path, bits, err);
	return kg_fail(err, KG_EINVAL, "%s: unknown image type: expected a name ending in .tif, "
	               ".tiff or .png", path);
}

/* Integer sample of a 0..1 value: clamped and rounded; NaN becomes 0. */
static inline unsigned quantise(float v, float full)
{
	if (!(v > 0))
		return 0;
	if (v >= 1)
		return (unsigned)full;
	return (unsigned)(v * full + 0.5f);
}

/* ---- TIFF ------------------------------------------------------------------------ */

struct tiff_msg {
	char text[512];
	/* libtiff's warning that it replaced StripByteCounts or TileByteCounts it found
	 * inconsistent with the declared size by its own estimate ("Bogus" or "Wrong
	 * \"StripByteCounts\" field, ignoring and calculating from imagelength") */
	char counts[256];
};

static int tiff_error(TIFF *tif, void *user, const char *module, const char *fmt, va_list ap)
{
	struct tiff_msg *m = user;
	if (!m->text[0])
		vsnprintf(m->text, sizeof(m->text), fmt, ap);
	return 1;
}

static int tiff_warning(TIFF *tif, void *user, const char *module, const char *fmt, va_list ap)
{
	/* unknown tags and the like: not worth a message; byte counts replaced: kept */
	struct tiff_msg *m = user;
	char text[256];
	vsnprintf(text, sizeof(text), fmt, ap);
	if (!m->counts[0] && strstr(text, "ByteCounts") &&
	    (strstr(text, "Bogus") || strstr(text, "Wrong")))
		snprintf(m->counts, sizeof(m->counts), "%s", text);
	return 1;
}

static TIFF *tiff_open_fd(int fd, const char *path, const char *mode, struct tiff_msg *msg)
{
	TIFFOpenOptions *opts = TIFFOpenOptionsAlloc();
	if (!opts)
		return NULL;
	TIFFOpenOptionsSetErrorHandlerExtR(opts, tiff_error, msg);
	TIFFOpenOptionsSetWarningHandlerExtR(opts, tiff_warning, msg);
	TIFFOpenOptionsSetMaxSingleMemAlloc(opts, (tmsize_t)1 << 31);
	TIFF *tif = TIFFFdOpenExt(fd, path, mode, opts);
	TIFFOpenOptionsFree(opts);
	return tif;
}

static const char *tiff_why(const struct tiff_msg *m)
{
	return m->text[0] ? m->text : "libtiff reported an error";
}

static int read_cfa(TIFF *tif, kg_image *img)
{
	uint16_t *dim = NULL, count = 0;
	uint8_t *pat = NULL;
	if (!TIFFGetField(tif, TIFFTAG_CFAREPEATPATTERNDIM, &dim) ||
	    !TIFFGetField(tif, TIFFTAG_CFAPATTERN, &count, &pat) || !dim || !pat)
		return 0;
	char s[257];
	int n = dim[0] * dim[1];
	if (dim[0] < 1 || dim[1] < 1 || dim[0] > 16 || dim[1] > 16 || count != n) {
		add_note(img, "CFA tags inconsistent, ignored");
		return 0;
	}
	for (int i = 0; i < n; i++) {
		if (pat[i] > 6) {
			add_note(img, "CFA pattern has unknown colour codes, ignored");
			return 0;
		}
		s[i] = "RGBCMYW"[pat[i]];
	}
	s[n] = '\0';
	return kg_image_set_cfa(img, s, dim[0], dim[1], NULL);
}

/* ---- reading a band of rows at a time ----------------------------------------------- */

/* A reader holds at most one strip or row of tiles (TIFF) or one row (PNG) of decoded
 * samples besides the caller's buffer, so memory does not grow with the image (an
 * interlaced PNG, whose rows come in seven passes, is the exception: it is decoded
 * whole when opened). */
struct png_job {
	png_structp png;
	png_infop info;
	FILE *fp;
	unsigned char *pixels;
	png_bytep *rows;
	char msg[256];
};

struct kg_image_rows {
	kg_image *head; /* the description: size, channels, bits, CFA, note; no pixels */
	char *path;
	int y;          /* the next row to deliver */
	/* TIFF */
	TIFF *tif;
	struct tiff_msg msg;
	int spp, separate, invert, tiled;
	int codes; /* tiff_band writes 16-bit codes (kg_image_map), not floats */
	uint32_t tw, th;
	tmsize_t chunk_size;
	unsigned char *chunk; /* one encoded strip or tile, decoded by libtiff */
	float *band;          /* rows [band_y0, band_y0 + th) of the image, channels interleaved */
	long band_y0;
	/* PNG */
	struct png_job pj;
	int png_depth, interlaced;
	size_t rowbytes;
	unsigned char *png_row;
	float *lut; /* code value -> linear 0..1 */
	/* camera raw (LibRaw): decoded whole when opened, rows served from it */
	kg_image *whole;
};

static int rows_new(const char *path, kg_image_rows **out, kg_err *err)
{
	kg_image_rows *r = calloc(1, sizeof(*r));
	if (r)
		r->head = calloc(1, sizeof(*r->head));
	if (r && r->head)
		r->path = strdup(path);
	if (!r || !r->head || !r->path) {
		if (r)
			free(r->head);
		free(r);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	}
	r->band_y0 = -1;
	*out = r;
	return 0;
}

/* n samples of one row of a chunk to floats on the 0..1 scale, four at a time with
 * SSE2 (a division per lane is the same correctly rounded division as the scalar
 * one, so the values are those of the general path). */
#ifdef __SSE2__
/* eight 16-bit lanes of v to eight floats divided by full */
static inline void store8(float *dst, __m128i v, __m128 full)
{
	const __m128i zero = _mm_setzero_si128();
	_mm_storeu_ps(dst, _mm_div_ps(_mm_cvtepi32_ps(_mm_unpacklo_epi16(v, zero)), full));
	_mm_storeu_ps(dst + 4, _mm_div_ps(_mm_cvtepi32_ps(_mm_unpackhi_epi16(v, zero)), full));
}
#endif

static void tiff_row_u16(const unsigned char *src, size_t n, float *dst)
{
	size_t i = 0;
#ifdef __SSE2__
	const __m128 full = _mm_set1_ps(65535.0f);
	for (; i + 8 <= n; i += 8)
		store8(dst + i, _mm_loadu_si128((const __m128i *)(const void *)(src + 2 * i)), full);
#endif
	for (; i < n; i++) {
		uint16_t u;
		memcpy(&u, src + 2 * i, 2);
		dst[i] = u / 65535.0f;
	}
}

static void tiff_row_u8(const unsigned char *src, size_t n, float *dst)
{
	size_t i = 0;
#ifdef __SSE2__
	const __m128i zero = _mm_setzero_si128();
	const __m128 full = _mm_set1_ps(255.0f);
	for (; i + 16 <= n; i += 16) {
		__m128i v = _mm_loadu_si128((const __m128i *)(const void *)(src + i));
		store8(dst + i, _mm_unpacklo_epi8(v, zero), full);
		store8(dst + i + 8, _mm_unpackhi_epi8(v, zero), full);
	}
#endif
	for (; i < n; i++)
		dst[i] = src[i] / 255.0f;
}

/* One row of a chunk of any layout: planes, extra samples, MinIsWhite. */
static void tiff_row_any(const kg_image_rows *r, const unsigned char *src, uint32_t cols,
                         int plane, float *dst)
{
	const kg_image *img = r->head;
	int C = img->channels, bits = img->bits;
	int spc = r->separate ? 1 : r->spp;
	float full = bits == 8 ? 255.0f : 65535.0f;
	for (uint32_t c = 0; c < cols; c++)
		for (int s = 0; s < (r->separate ? 1 : C); s++) {
			size_t i = (size_t)c * spc + s;
			float v;
			if (img->is_float)
				memcpy(&v, src + i * 4, 4);
			else if (bits == 8)
				v = src[i] / full;
			else {
				uint16_t u;
				memcpy(&u, src + i * 2, 2);
				v = u / full;
			}
			dst[(size_t)c * C + (r->separate ? plane : s)] = r->invert ? 1.0f - v : v;
		}
}

/* Decode the band of TIFF rows that starts at row cy (a multiple of th) into band
 * (rows of the image's width, channels interleaved): floats, or with r->codes (a
 * 16-bit file of one plane, nothing extra, not inverted) its codes as they are. */
static int tiff_band(kg_image_rows *r, uint32_t cy, void *band_out, kg_err *err)
{
	float *band = band_out;
	uint16_t *codes = band_out;
	const kg_image *img = r->head;
	uint32_t w = (uint32_t)img->width, h = (uint32_t)img->height, tw = r->tw, th = r->th;
	int C = img->channels, bits = img->bits, is_float = img->is_float;
	int spc = r->separate ? 1 : r->spp; /* samples per pixel within one chunk */
	size_t bps = (size_t)bits / 8;
	int nplanes = r->separate ? (r->spp < C ? r->spp : C) : 1;
	uint32_t rows = h - cy < th ? h - cy : th;
	for (int p = 0; p < nplanes; p++)
		for (uint32_t cx = 0; cx < w; cx += tw) {
			tmsize_t got;
			if (r->tiled)
				got = TIFFReadEncodedTile(r->tif, TIFFComputeTile(r->tif, cx, cy, 0, (uint16_t)p),
				                          r->chunk, r->chunk_size);
			else
				got = TIFFReadEncodedStrip(r->tif, TIFFComputeStrip(r->tif, cy, (uint16_t)p),
				                           r->chunk, r->chunk_size);
			uint32_t cols = w - cx < tw ? w - cx : tw;
			size_t need = (((size_t)rows - 1) * tw + cols) * (size_t)spc * bps;
			if (got < 0 || (size_t)got < need)
				return kg_fail(err, KG_EINVAL, "%s: %s at row %u: %s (%s %u, ImageLength "
				               "%u)", r->path, r->tiled ? "tile" : "strip", cy,
				               got < 0 ? tiff_why(&r->msg)
				                       : "decoded to fewer rows than declared",
				               r->tiled ? "TileLength" : "RowsPerStrip", th, h);
			/* the common layouts (all of a pixel's samples in one chunk, nothing extra,
			 * not inverted) a row at a time, without a branch per sample */
			int plain = !r->separate && spc == C && !r->invert;
			for (uint32_t y = 0; y < rows; y++) {
				const unsigned char *src = r->chunk + (size_t)y * tw * spc * bps;
				size_t n = (size_t)cols * C;
				if (r->codes) {
					memcpy(codes + ((size_t)y * w + cx) * C, src, n * sizeof(uint16_t));
					continue;
				}
				float *dst = band + ((size_t)y * w + cx) * C;
				if (plain && is_float)
					memcpy(dst, src, n * sizeof(float));
				else if (plain && bits == 8)
					tiff_row_u8(src, n, dst);
				else if (plain)
					tiff_row_u16(src, n, dst);
				else
					tiff_row_any(r, src, cols, p, dst);
			}
		}
	return 0;
}

/* Every strip or tile the declared size implies is in the file: an offset past the
 * header and data inside the file, and, uncompressed, at least the bytes its rows
 * need. libtiff fills the entries of a StripOffsets/TileOffsets shorter than the
 * image implies with zeros and may invent byte counts for them (a bit flipped in
 * ImageLength would otherwise read the header as pixels, for millions of rows). */
static int tiff_check_chunks(kg_image_rows *r, uint32_t w, uint32_t h, kg_err *err)
{
	TIFF *tif = r->tif;
	const char *path = r->path;
	struct stat st;
	if (fstat(TIFFFileno(tif), &st) != 0)
		return kg_fail(err, KG_EIO, "%s: cannot stat: %s", path, strerror(errno));
	uint64_t file_size = (uint64_t)st.st_size;
	uint16_t compression = COMPRESSION_NONE;
	TIFFGetFieldDefaulted(tif, TIFFTAG_COMPRESSION, &compression);
	const char *kind = r->tiled ? "tile" : "strip";
	const char *off_tag = r->tiled ? "TileOffsets" : "StripOffsets";
	const char *cnt_tag = r->tiled ? "TileByteCounts" : "StripByteCounts";
	uint32_t n = r->tiled ? TIFFNumberOfTiles(tif) : TIFFNumberOfStrips(tif);
	uint32_t per_plane = r->tiled ? 0 : (h + r->th - 1) / r->th;
	uint32_t planes = r->separate ? (uint32_t)r->spp : 1;
	uint64_t expect_n = r->tiled ? (uint64_t)((w + r->tw - 1) / r->tw) *
	                                       (uint64_t)((h + r->th - 1) / r->th) * planes
	                             : (uint64_t)per_plane * planes;
	if (n == 0 || (uint64_t)n != expect_n)
		return kg_fail(err, KG_EINVAL, "%s: %u %ss: expected %llu for ImageWidth %u, "
		               "ImageLength %u and %s %u", path, n, kind,
		               (unsigned long long)expect_n, w, h,
		               r->tiled ? "TileLength" : "RowsPerStrip", r->th);
	for (uint32_t i = 0; i < n; i++) {
		int err_code = 0;
		uint64_t off = TIFFGetStrileOffsetWithErr(tif, i, &err_code);
		uint64_t cnt = err_code ? 0 : TIFFGetStrileByteCountWithErr(tif, i, &err_code);
		uint32_t y0 = r->tiled ? 0 : (i % per_plane) * r->th;
		uint32_t rows = r->tiled ? r->th : (h - y0 < r->th ? h - y0 : r->th);
		char where[96];
		if (r->tiled)
			snprintf(where, sizeof(where), "tile %u of %u", i, n);
		else
			snprintf(where, sizeof(where), "strip %u of %u (rows %u to %u)", i, n, y0,
			         y0 + rows - 1);
		if (err_code || off < 8 || cnt == 0)
			return kg_fail(err, KG_EINVAL, "%s: %s has no data (%s %llu, %s %llu): the "
			               "file's %ss do not cover the %u x %u pixels ImageWidth and "
			               "ImageLength declare", path, where, off_tag,
			               (unsigned long long)off, cnt_tag, (unsigned long long)cnt, kind,
			               w, h);
		if (off > file_size || cnt > file_size - off)
			return kg_fail(err, KG_EINVAL, "%s: %s lies beyond the end of the %llu-byte "
			               "file (%s %llu, %s %llu): truncated, or ImageLength %u is wrong",
			               path, where, (unsigned long long)file_size, off_tag,
			               (unsigned long long)off, cnt_tag, (unsigned long long)cnt, h);
		if (compression == COMPRESSION_NONE) {
			uint64_t need = r->tiled ? (uint64_t)TIFFTileSize64(tif)
			                         : (uint64_t)TIFFVStripSize64(tif, rows);
			if (cnt < need)
				return kg_fail(err, KG_EINVAL, "%s: %s: %s %llu, expected %llu for "
				               "uncompressed data: the %ss do not cover the %u x %u pixels "
				               "ImageWidth and ImageLength declare", path, where, cnt_tag,
				               (unsigned long long)cnt, (unsigned long long)need, kind, w, h);
		}
	}
	if (r->msg.counts[0])
		return kg_fail(err, KG_EINVAL, "%s: the %s's %s do not match the %u x %u pixels "
		               "ImageWidth and ImageLength declare (libtiff: %s): truncated, or "
		               "ImageLength %u is wrong", path, kind,
		               cnt_tag, w, h, r->msg.counts, h);
	return 0;
}

static int tiff_rows_open(kg_image_rows *r, kg_err *err)
{
	const char *path = r->path;
	int fd = open(path, O_RDONLY | O_CLOEXEC);
	if (fd < 0)
		return kg_fail(err, errno == ENOENT ? KG_ENOENT : KG_EIO, "%s: cannot open: %s", path,
		               strerror(errno));
	kg_inputs_add(path, fd);
	/* "m": read(), not a map of the whole file, which would count as resident as
	 * the file is read (the memory bound is for the process, not only the heap) */
	r->tif = tiff_open_fd(fd, path, "rm", &r->msg);
	if (!r->tif) {
		close(fd);
		return kg_fail(err, KG_EINVAL, "%s: not a readable TIFF file: %s", path,
		               tiff_why(&r->msg));
	}
	TIFF *tif = r->tif;
	kg_image *img = r->head;
	int ret;
	uint32_t w = 0, h = 0;
	uint16_t spp = 1, bits = 1, fmt = SAMPLEFORMAT_UINT, planar = PLANARCONFIG_CONTIG, photo;
	TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &w);
	TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &h);
	TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLESPERPIXEL, &spp);
	TIFFGetFieldDefaulted(tif, TIFFTAG_BITSPERSAMPLE, &bits);
	TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLEFORMAT, &fmt);
	TIFFGetFieldDefaulted(tif, TIFFTAG_PLANARCONFIG, &planar);
	if (!TIFFGetField(tif, TIFFTAG_PHOTOMETRIC, &photo))
		photo = spp >= 3 ? PHOTOMETRIC_RGB : PHOTOMETRIC_MINISBLACK;
	if ((ret = check_dims(path, w, h, err)))
		return ret;
	int is_float = fmt == SAMPLEFORMAT_IEEEFP;
	if (fmt != SAMPLEFORMAT_UINT && fmt != SAMPLEFORMAT_IEEEFP && fmt != SAMPLEFORMAT_VOID)
		return kg_fail(err, KG_ENOTSUP, "%s: %s samples not supported: expected unsigned "
		               "integer or float", path,
		               fmt == SAMPLEFORMAT_INT ? "signed integer" : "complex");
	if (is_float ? bits != 32 : (bits != 8 && bits != 16))
		return kg_fail(err, KG_ENOTSUP, "%s: %u-bit %s samples not supported: expected 8, 16 "
		               "or 32-bit float", path, bits, is_float ? "float" : "integer");
	int channels;
	if (photo == PHOTOMETRIC_RGB && spp >= 3)
		channels = 3;
	else if ((photo == PHOTOMETRIC_MINISBLACK || photo == PHOTOMETRIC_MINISWHITE ||
	          photo == PHOTOMETRIC_CFA) && spp >= 1)
		channels = 1;
	else
		return kg_fail(err, KG_ENOTSUP, "%s: photometric interpretation %u with %u samples "
		               "per pixel not supported: expected grey, RGB or CFA", path, photo, spp);
	img->width = (int)w;
	img->height = (int)h;
	img->channels = channels;
	img->bits = bits;
	img->is_float = is_float;
	if (spp > channels)
		add_note(img, "extra samples (alpha) dropped");
	r->spp = spp;
	r->separate = planar == PLANARCONFIG_SEPARATE;
	r->invert = photo == PHOTOMETRIC_MINISWHITE;
	r->tiled = TIFFIsTiled(tif);
	if (r->tiled) {
		if (!TIFFGetField(tif, TIFFTAG_TILEWIDTH, &r->tw) ||
		    !TIFFGetField(tif, TIFFTAG_TILELENGTH, &r->th) || r->tw < 1 || r->th < 1 ||
		    r->tw > MAX_SIDE || r->th > MAX_SIDE)
			return kg_fail(err, KG_EINVAL, "%s: tile size missing or invalid", path);
		r->chunk_size = TIFFTileSize(tif);
	} else {
		uint32_t rps = h;
		TIFFGetFieldDefaulted(tif, TIFFTAG_ROWSPERSTRIP, &rps);
		r->tw = w;
		r->th = rps < 1 || rps > h ? h : rps;
		r->chunk_size = TIFFStripSize(tif);
	}
	if (r->chunk_size <= 0)
		return kg_fail(err, KG_EINVAL, "%s: strip or tile size invalid: %s", path,
		               tiff_why(&r->msg));
	if ((ret = tiff_check_chunks(r, w, h, err)))
		return ret;
	uint32_t band_rows = r->th < h ? r->th : h;
	r->chunk = _TIFFmalloc(r->chunk_size);
	r->band = malloc((size_t)band_rows * w * channels * sizeof(float));
	if (!r->chunk || !r->band)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory for a %lld-byte %s", path,
		               (long long)r->chunk_size, r->tiled ? "tile" : "strip");
	return read_cfa(tif, img);
}

static int tiff_rows_read(kg_image_rows *r, int rows, float *out, kg_err *err)
{
	size_t row_floats = (size_t)r->head->width * r->head->channels;
	for (int i = 0; i < rows; i++, r->y++) {
		uint32_t cy = (uint32_t)r->y / r->th * r->th;
		uint32_t band_rows = (uint32_t)r->head->height - cy < r->th
		                         ? (uint32_t)r->head->height - cy : r->th;
		if ((uint32_t)r->y == cy && (uint32_t)(rows - i) >= band_rows) {
			/* a whole band asked: decoded straight into the caller's rows */
			int ret = tiff_band(r, cy, out + (size_t)i * row_floats, err);
			if (ret)
				return ret;
			i += (int)band_rows - 1;
			r->y += (int)band_rows - 1;
			continue;
		}
		if (r->band_y0 != (long)cy) {
			r->band_y0 = -1;
			int ret = tiff_band(r, cy, r->band, err);
			if (ret)
				return ret;
			r->band_y0 = cy;
		}
		memcpy(out + (size_t)i * row_floats,
		       r->band + (size_t)(r->y - cy) * row_floats, row_floats * sizeof(float));
	}
	return 0;
}

int kg_image_write_tiff(const kg_image *img, const char *path, int bits, kg_err *err)
{
	kg_check_arg(img && path, err);
	if (bits != 8 && bits != 16 && bits != 32)
		return kg_fail(err, KG_EINVAL, "%s: %d-bit output: expected 8, 16 or 32 (float)", path,
		               bits);
	if (img->channels != 1 && img->channels != 3)
		return kg_fail(err, KG_EINVAL, "%s: %d channels: expected 1 or 3", path, img->channels);
	kg_outfile o;
	int ret = kg_outfile_open(&o, path, 0, err);
	if (ret)
		return ret;
	struct tiff_msg msg;
	memset(&msg, 0, sizeof(msg));
	int fd = dup(fileno(o.fp));
	size_t C = (size_t)img->channels, W = (size_t)img->width, bps = (size_t)bits / 8;
	int big = (uint64_t)W * img->height * C * bps > ((uint64_t)1 << 32) - ((uint64_t)1 << 28);
	TIFF *tif = fd < 0 ? NULL : tiff_open_fd(fd, path, big ? "w8" : "w", &msg);
	if (!tif) {
		if (fd >= 0)
			close(fd);
		kg_outfile_abort(&o);
		return kg_fail(err, KG_EIO, "%s: cannot start TIFF: %s", path, tiff_why(&msg));
	}
	unsigned char *row = malloc(W * C * bps);
	int ok = row != NULL;
	ok = ok && TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, (uint32_t)img->width) &&
	     TIFFSetField(tif, TIFFTAG_IMAGELENGTH, (uint32_t)img->height) &&
	     TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, (uint16_t)C) &&
	     TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, (uint16_t)bits) &&
	     TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT,
	                  bits == 32 ? SAMPLEFORMAT_IEEEFP : SAMPLEFORMAT_UINT) &&
	     TIFFSetField(tif, TIFFTAG_PHOTOMETRIC,
	                  C == 3 ? PHOTOMETRIC_RGB : PHOTOMETRIC_MINISBLACK) &&
	     TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG) &&
	     TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_NONE) &&
	     TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, TIFFDefaultStripSize(tif, 0)) &&
	     TIFFSetField(tif, TIFFTAG_SOFTWARE, "kogei " KG_VERSION);
	if (ok && img->cfa && C == 1) {
		/* Raw frames stay MinIsBlack so any viewer opens them; the pattern rides in
		 * the TIFF/EP CFA tags. */
		uint16_t dim[2] = {(uint16_t)img->cfa_rows, (uint16_t)img->cfa_cols};
		uint8_t pat[256];
		int n = img->cfa_rows * img->cfa_cols;
		for (int i = 0; i < n && i < 256; i++)
			pat[i] = (uint8_t)(strchr("RGBCMYW", img->cfa[i]) - "RGBCMYW");
		ok = TIFFSetField(tif, TIFFTAG_CFAREPEATPATTERNDIM, dim) &&
		     TIFFSetField(tif, TIFFTAG_CFAPATTERN, (uint16_t)n, pat);
	}
	errno = 0;
	for (int y = 0; ok && y < img->height; y++) {
		const float *src = img->data + (size_t)y * W * C;
		size_t n = W * C;
		if (bits == 32)
			memcpy(row, src, n * 4);
		else if (bits == 16)
			for (size_t i = 0; i < n; i++)
				((uint16_t *)row)[i] = (uint16_t)quantise(src[i], 65535.0f);
		else
			for (size_t i = 0; i < n; i++)
				row[i] = (unsigned char)quantise(src[i], 255.0f);
		ok = TIFFWriteScanline(tif, row, (uint32_t)y, 0) == 1;
	}
	ok = ok && TIFFFlush(tif);
	TIFFClose(tif);
	free(row);
	if (!ok) {
		int e = errno; /* libtiff's write() failure, e.g. ENOSPC */
		kg_outfile_abort(&o);
		if (e == ENOSPC || e == EDQUOT)
			return kg_fail_write(err, e, path, "cannot write TIFF");
		return kg_fail(err, KG_EIO, "%s: cannot write TIFF: %s", path, tiff_why(&msg));
	}
	return kg_outfile_commit(&o, err);
}

/* ---- PNG ------------------------------------------------------------------------- */

static void png_error_fn(png_structp png, png_const_charp text)
{
	struct png_job *j = png_get_error_ptr(png);
	snprintf(j->msg, sizeof(j->msg), "%s", text);
	png_longjmp(png, 1);
}

static void png_warning_fn(png_structp png, png_const_charp text) {}

static float srgb_to_linear(float v)
{
	return v <= 0.04045f ? v / 12.92f : powf((v + 0.055f) / 1.055f, 2.4f);
}

/* Everything from png_read_info to the first row; returns -1 after a libpng error
 * (message in j->msg) or a kg code. An interlaced file is decoded whole here. */
static int png_rows_body(kg_image_rows *r, kg_err *err)
{
	struct png_job *j = &r->pj;
	const char *path = r->path;
	kg_image *img = r->head;
	if (setjmp(png_jmpbuf(j->png)))
		return -1;
	png_init_io(j->png, j->fp);
	png_set_user_limits(j->png, MAX_SIDE, MAX_SIDE);
	png_read_info(j->png, j->info);
	png_uint_32 w = png_get_image_width(j->png, j->info), h = png_get_image_height(j->png, j->info);
	int depth = png_get_bit_depth(j->png, j->info), ct = png_get_color_type(j->png, j->info);
	int ret = check_dims(path, w, h, err);
	if (ret)
		return ret;
	const char *note = NULL;
	if (ct == PNG_COLOR_TYPE_PALETTE)
		png_set_palette_to_rgb(j->png);
	if (ct == PNG_COLOR_TYPE_GRAY && depth < 8)
		png_set_expand_gray_1_2_4_to_8(j->png);
	/* Expansion turns a tRNS chunk into alpha; libpng strips alpha after expanding. */
	if ((ct & PNG_COLOR_MASK_ALPHA) || png_get_valid(j->png, j->info, PNG_INFO_tRNS)) {
		png_set_strip_alpha(j->png);
		note = ct & PNG_COLOR_MASK_ALPHA ? "alpha channel dropped" : "transparency dropped";
	}
	r->interlaced = png_set_interlace_handling(j->png) > 1;
	png_read_update_info(j->png, j->info);
	int channels = png_get_channels(j->png, j->info), out_depth = png_get_bit_depth(j->png, j->info);
	r->rowbytes = png_get_rowbytes(j->png, j->info);
	if ((channels != 1 && channels != 3) || (out_depth != 8 && out_depth != 16) ||
	    r->rowbytes < (size_t)w * channels * (out_depth / 8))
		return kg_fail(err, KG_ENOTSUP, "%s: PNG colour type %d, %d-bit: not supported", path, ct,
		               depth);
	img->width = (int)w;
	img->height = (int)h;
	img->channels = channels;
	img->bits = depth;
	img->is_float = 0;
	r->png_depth = out_depth;
	if (note)
		add_note(img, note);

	/* The transfer curve the file declares. */
	int srgb = png_get_valid(j->png, j->info, PNG_INFO_sRGB) != 0;
	double gamma = 1.0;
	if (!srgb && png_get_valid(j->png, j->info, PNG_INFO_gAMA))
		png_get_gAMA(j->png, j->info, &gamma);
	if (!(gamma > 0.01 && gamma < 100))
		gamma = 1.0;
	int curve = srgb ? 1 : fabs(gamma - 1.0) > 1e-3 ? 2 : 0;
	if (curve == 1)
		add_note(img, "linearised from sRGB");
	else if (curve == 2) {
		char s[64];
		snprintf(s, sizeof(s), "linearised from gamma %.5g", gamma);
		add_note(img, s);
	}
	/* A table per code value keeps the curve cheap and exact per code. */
	size_t levels = out_depth == 16 ? 65536 : 256;
	r->lut = malloc(levels * sizeof(float));
	if (!r->lut)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	for (size_t i = 0; i < levels; i++) {
		float v = (float)i / (float)(levels - 1);
		r->lut[i] = curve == 1 ? srgb_to_linear(v) : curve == 2 ? powf(v, (float)(1.0 / gamma)) : v;
	}
	if (!r->interlaced) {
		r->png_row = malloc(r->rowbytes);
		return r->png_row ? 0 : kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	}
	j->pixels = malloc(r->rowbytes * h);
	j->rows = malloc(h * sizeof(png_bytep));
	if (!j->pixels || !j->rows)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory for an interlaced PNG of %u x %u",
		               path, (unsigned)w, (unsigned)h);
	for (png_uint_32 y = 0; y < h; y++)
		j->rows[y] = j->pixels + (size_t)y * r->rowbytes;
	png_read_image(j->png, j->rows);
	return 0;
}

static int png_rows_open(kg_image_rows *r, kg_err *err)
{
	struct png_job *j = &r->pj;
	j->fp = fopen(r->path, "rb");
	if (!j->fp)
		return kg_fail(err, errno == ENOENT ? KG_ENOENT : KG_EIO, "%s: cannot open: %s",
		               r->path, strerror(errno));
	kg_inputs_add(r->path, fileno(j->fp));
	j->png = png_create_read_struct(PNG_LIBPNG_VER_STRING, j, png_error_fn, png_warning_fn);
	j->info = j->png ? png_create_info_struct(j->png) : NULL;
	if (!j->info)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", r->path);
	int ret = png_rows_body(r, err);
	if (ret == -1)
		ret = kg_fail(err, KG_EINVAL, "%s: not a readable PNG file: %s", r->path, j->msg);
	return ret;
}

/* One row from libpng into r->png_row; -1 after a libpng error. */
static int png_next_row(kg_image_rows *r)
{
	if (setjmp(png_jmpbuf(r->pj.png)))
		return -1;
	png_read_row(r->pj.png, r->png_row, NULL);
	return 0;
}

static int png_rows_read(kg_image_rows *r, int rows, float *out, kg_err *err)
{
	size_t n = (size_t)r->head->width * r->head->channels;
	for (int i = 0; i < rows; i++, r->y++) {
		const unsigned char *s = r->interlaced ? r->pj.rows[r->y] : r->png_row;
		if (!r->interlaced && png_next_row(r) != 0)
			return kg_fail(err, KG_EINVAL, "%s: not a readable PNG file: row %d: %s", r->path,
			               r->y, r->pj.msg);
		float *d = out + (size_t)i * n;
		if (r->png_depth == 16)
			for (size_t k = 0; k < n; k++)
				d[k] = r->lut[(s[2 * k] << 8) | s[2 * k + 1]];
		else
			for (size_t k = 0; k < n; k++)
				d[k] = r->lut[s[k]];
	}
	return 0;
}

static void png_job_end(struct png_job *j, int reading)
{
	if (j->png) {
		if (reading)
			png_destroy_read_struct(&j->png, j->info ? &j->info : NULL, NULL);
		else
			png_destroy_write_struct(&j->png, j->info ? &j->info : NULL);
	}
	free(j->pixels);
	free(j->rows);
}

/* ---- the row reader and the whole-image readers on it ------------------------------ */

enum image_kind { KIND_TIFF = 1, KIND_PNG, KIND_RAW, KIND_JPEG };

/* ---- JPEG (libjpeg-turbo), decoded whole when opened ------------------------------ */

int kg_image_encoding_parse(const char *text, kg_image_encoding *enc, kg_err *err)
{
	kg_check_arg(enc, err);
	memset(enc, 0, sizeof(*enc));
	if (text && strcmp(text, "srgb") == 0)
		enc->curve = KG_ENCODING_SRGB;
	else if (text && strcmp(text, "linear") == 0)
		enc->curve = KG_ENCODING_LINEAR;
	else if (text && strncmp(text, "gamma:", 6) == 0) {
		char *end;
		double g = strtod(text + 6, &end);
		if (end == text + 6 || *end || !(g >= 0.2 && g <= 5))
			return kg_fail(err, KG_EINVAL, "--encoding %s: expected gamma:G with G from 0.2 "
			               "to 5 (e.g. gamma:2.2: linear = code^2.2)", text);
		enc->curve = KG_ENCODING_GAMMA;
		enc->gamma = g;
	} else
		return kg_fail(err, KG_EINVAL, "--encoding %s: expected srgb, linear or gamma:G",
		               text ? text : "");
	return 0;
}

void kg_image_encoding_name(const kg_image *img, char *buf, size_t size)
{
	if (!img->jpeg)
		snprintf(buf, size, "linear");
	else if (img->encoding.curve == KG_ENCODING_UNSTATED)
		snprintf(buf, size, "jpeg-unstated");
	else if (img->encoding.curve == KG_ENCODING_SRGB)
		snprintf(buf, size, "jpeg-srgb");
	else if (img->encoding.curve == KG_ENCODING_LINEAR)
		snprintf(buf, size, "jpeg-linear");
	else
		snprintf(buf, size, "jpeg-gamma-%g", img->encoding.gamma);
}

#if HAVE_JPEG
typedef struct {
	struct jpeg_error_mgr pub;
	jmp_buf jump;
	char msg[JMSG_LENGTH_MAX];
} jpeg_err;

static void jpeg_on_error(j_common_ptr cinfo)
{
	jpeg_err *e = (jpeg_err *)cinfo->err;
	(*cinfo->err->format_message)(cinfo, e->msg);
	longjmp(e->jump, 1);
}

/* Warnings (corrupt data libjpeg guesses over) are errors too: a measurement must not
 * read a damaged file. */
static void jpeg_on_message(j_common_ptr cinfo, int level)
{
	if (level < 0)
		jpeg_on_error(cinfo);
}

static int jpeg_decode(kg_image_rows *r, FILE *fp, const kg_image_encoding *enc,
                       kg_err *err)
{
	struct jpeg_decompress_struct cinfo;
	jpeg_err e;
	memset(&e, 0, sizeof(e));
	unsigned char *volatile row = NULL;
	float lut[256];
	cinfo.err = jpeg_std_error(&e.pub);
	e.pub.error_exit = jpeg_on_error;
	e.pub.emit_message = jpeg_on_message;
	if (setjmp(e.jump)) {
		jpeg_destroy_decompress(&cinfo);
		free(row);
		return kg_fail(err, KG_EINVAL, "%s: not a readable JPEG file: %s", r->path, e.msg);
	}
	jpeg_create_decompress(&cinfo);
	jpeg_stdio_src(&cinfo, fp);
	jpeg_read_header(&cinfo, TRUE);
	int channels;
	if (cinfo.jpeg_color_space == JCS_GRAYSCALE) {
		cinfo.out_color_space = JCS_GRAYSCALE;
		channels = 1;
	} else if (cinfo.jpeg_color_space == JCS_YCbCr || cinfo.jpeg_color_space == JCS_RGB) {
		cinfo.out_color_space = JCS_RGB;
		channels = 3;
	} else {
		jpeg_destroy_decompress(&cinfo);
		return kg_fail(err, KG_ENOTSUP, "%s: a CMYK or YCCK JPEG: expected a grey or colour "
		               "(YCbCr, RGB) photograph", r->path);
	}
	cinfo.dct_method = JDCT_ISLOW; /* the accurate integer IDCT: the same on every CPU */
	int ret = check_dims(r->path, (long)cinfo.image_width, (long)cinfo.image_height, err);
	if (ret) {
		jpeg_destroy_decompress(&cinfo);
		return ret;
	}
	jpeg_start_decompress(&cinfo);
	int w = (int)cinfo.output_width, h = (int)cinfo.output_height;
	if ((ret = kg_image_new(w, h, channels, &r->whole, err))) {
		jpeg_destroy_decompress(&cinfo);
		return ret;
	}
	for (int i = 0; i < 256; i++) {
		float v = (float)i / 255.0f;
		lut[i] = enc->curve == KG_ENCODING_LINEAR ? v
		         : enc->curve == KG_ENCODING_GAMMA ? powf(v, (float)enc->gamma)
		                                           : srgb_to_linear(v);
	}
	row = malloc((size_t)w * channels);
	if (!row) {
		jpeg_destroy_decompress(&cinfo);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", r->path);
	}
	while (cinfo.output_scanline < cinfo.output_height) {
		JSAMPROW rp = (JSAMPROW)row;
		int y = (int)cinfo.output_scanline;
		if (jpeg_read_scanlines(&cinfo, &rp, 1) != 1)
			break;
		float *d = r->whole->data + (size_t)y * w * channels;
		for (size_t k = 0; k < (size_t)w * channels; k++)
			d[k] = lut[row[k]];
	}
	jpeg_finish_decompress(&cinfo);
	jpeg_destroy_decompress(&cinfo);
	free(row);
	return 0;
}
#endif

static int jpeg_rows_open(kg_image_rows *r, const kg_image_encoding *enc, kg_err *err)
{
	static const kg_image_encoding unstated = {KG_ENCODING_UNSTATED, 0};
	if (!enc)
		enc = &unstated;
#if HAVE_JPEG
	FILE *fp = fopen(r->path, "rb");
	if (!fp)
		return kg_fail(err, errno == ENOENT ? KG_ENOENT : KG_EIO, "%s: cannot open: %s",
		               r->path, strerror(errno));
	kg_inputs_add(r->path, fileno(fp));
	int ret = jpeg_decode(r, fp, enc, err);
	fclose(fp);
	if (ret)
		return ret;
	kg_image *h = r->head, *w = r->whole;
	h->width = w->width;
	h->height = w->height;
	h->channels = w->channels;
	h->bits = w->bits = 8;
	h->is_float = w->is_float = 0;
	h->jpeg = w->jpeg = 1;
	h->encoding = w->encoding = *enc;
	add_note(h, enc->curve == KG_ENCODING_UNSTATED
	                ? "JPEG: encoding not stated, linearised as sRGB for detection and "
	                  "previews only"
	            : enc->curve == KG_ENCODING_SRGB   ? "JPEG: linearised from sRGB (stated)"
	            : enc->curve == KG_ENCODING_LINEAR ? "JPEG: code values taken as linear (stated)"
	                                               : "JPEG: linearised from a stated gamma");
	memcpy(w->note, h->note, sizeof(w->note));
	return 0;
#else
	(void)enc;
	return kg_fail(err, KG_ENOTSUP, "%s: a JPEG file, but this kogei was built without "
	               "libjpeg (meson option jpeg): convert it to a 16-bit TIFF or PNG, or "
	               "build with libjpeg-turbo", r->path);
#endif
}

static int image_kind(const char *path, kg_err *err)
{
	unsigned char magic[8] = {0};
	FILE *fp = fopen(path, "rb");
	if (!fp)
		return kg_fail(err, errno == ENOENT ? KG_ENOENT : KG_EIO, "%s: cannot open: %s", path,
		               strerror(errno));
	kg_inputs_add(path, fileno(fp));
	size_t n = fread(magic, 1, sizeof(magic), fp);
	fclose(fp);
	if (n >= 8 && png_sig_cmp(magic, 0, 8) == 0)
		return KIND_PNG;
	/* DNG and the TIFF-based raw formats (CR2, NEF, ARW, ...) before plain TIFF: their
	 * first image is often a thumbnail. */
	if (kg_raw_is_raw(path))
		return KIND_RAW;
	if (n >= 4 && ((magic[0] == 'I' && magic[1] == 'I' && (magic[2] == 42 || magic[2] == 43) &&
	                magic[3] == 0) ||
	               (magic[0] == 'M' && magic[1] == 'M' && magic[2] == 0 &&
	                (magic[3] == 42 || magic[3] == 43))))
		return KIND_TIFF;
	if (n >= 3 && magic[0] == 0xFF && magic[1] == 0xD8 && magic[2] == 0xFF)
		return KIND_JPEG;
	return kg_fail(err, KG_EINVAL, "%s: unknown image format: expected a TIFF, PNG, JPEG or "
	               "camera raw file (DNG, CR2, CR3, NEF, ARW, ...)", path);
}

/* A raw file is decoded whole (LibRaw has no row interface); the header copies it. */
static int raw_rows_open(kg_image_rows *r, kg_err *err)
{
	int ret = kg_raw_read(r->path, &r->whole, NULL, err);
	if (ret)
		return ret;
	kg_image *h = r->head, *w = r->whole;
	h->width = w->width;
	h->height = w->height;
	h->channels = w->channels;
	h->bits = w->bits;
	h->is_float = w->is_float;
	memcpy(h->note, w->note, sizeof(h->note));
	return w->cfa ? kg_image_set_cfa(h, w->cfa, w->cfa_rows, w->cfa_cols, err) : 0;
}

static int rows_open_kind(const char *path, int kind, const kg_image_encoding *enc,
                          kg_image_rows **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	kg_image_rows *r = NULL;
	int ret = rows_new(path, &r, err);
	if (ret)
		return ret;
	ret = kind == KIND_PNG    ? png_rows_open(r, err)
	      : kind == KIND_RAW  ? raw_rows_open(r, err)
	      : kind == KIND_JPEG ? jpeg_rows_open(r, enc, err)
	                          : tiff_rows_open(r, err);
	if (ret)
		kg_image_rows_free(&r);
	*out = r;
	return ret;
}

int kg_image_rows_open(const char *path, kg_image_rows **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	int kind = image_kind(path, err);
	return kind < 0 ? kind : rows_open_kind(path, kind, NULL, out, err);
}

int kg_image_rows_open_as(const char *path, const kg_image_encoding *enc,
                          kg_image_rows **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	int kind = image_kind(path, err);
	return kind < 0 ? kind : rows_open_kind(path, kind, enc, out, err);
}

int kg_image_is_jpeg(const char *path)
{
	kg_err e = {{0}};
	return image_kind(path, &e) == KIND_JPEG;
}

const kg_image *kg_image_rows_header(const kg_image_rows *r)
{
	return r->head;
}

int kg_image_rows_read(kg_image_rows *r, int rows, float *out, kg_err *err)
{
	kg_check_arg(r && out && rows >= 0, err);
	if (rows > r->head->height - r->y)
		return kg_fail(err, KG_EINVAL, "%s: rows %d to %d asked of an image of %d rows",
		               r->path, r->y, r->y + rows - 1, r->head->height);
	if (r->whole) {
		size_t row = (size_t)r->head->width * (size_t)r->head->channels;
		memcpy(out, r->whole->data + (size_t)r->y * row, (size_t)rows * row * sizeof(float));
		r->y += rows;
		return 0;
	}
	return r->tif ? tiff_rows_read(r, rows, out, err) : png_rows_read(r, rows, out, err);
}

void kg_image_rows_free(kg_image_rows **pr)
{
	if (!pr || !*pr)
		return;
	kg_image_rows *r = *pr;
	if (r->tif)
		TIFFClose(r->tif);
	if (r->chunk)
		_TIFFfree(r->chunk);
	free(r->band);
	png_job_end(&r->pj, 1);
	if (r->pj.fp)
		fclose(r->pj.fp);
	free(r->png_row);
	free(r->lut);
	kg_image_free(&r->whole);
	kg_image_free(&r->head);
	free(r->path);
	free(r);
	*pr = NULL;
}

/* A whole TIFF image of many bands read by several readers at once, each on its own
 * handle of the file (a libtiff handle is not for two threads), bands straight into
 * the image. Uncompressed, the conversion and the first touch of the image's pages
 * (about half the time of the read of a 72 MB 16-bit TIFF) run on several cores;
 * compressed (LZW, Deflate), the decoding too: a strip or tile is decoded on its own,
 * whichever reader takes it. The readers take the bands in order, one at a time, from
 * a shared counter; a band is decoded whole by one reader, by the function the row
 * reader uses, so the samples are the same whatever the number of readers. A reader
 * stops at its first bad band, and no reader starts a band after the first bad band
 * found so far: every band before the first bad one is decoded, and the error is
 * that of the first bad band in the file's order, as one reader would report it. */
#define READ_THREADS_MAX 16

static _Atomic int read_threads; /* 0: the CPUs this process may use, up to 8 */

int kg_image_set_read_threads(int n)
{
	return atomic_exchange(&read_threads, n < 0 ? 0 : n > READ_THREADS_MAX ? READ_THREADS_MAX : n);
}

struct band_pool {
	void *data;            /* floats, or codes (16-bit) */
	uint32_t bands, th;
	size_t row_bytes;
	_Atomic uint32_t next;      /* the next band to take */
	_Atomic uint32_t first_bad; /* the first bad band found so far; bands: none */
};

struct band_job {
	struct band_pool *pool;
	kg_image_rows *r;
	int ret;
	uint32_t bad; /* the band of ret */
	kg_err err;
};

static void *band_job_main(void *arg)
{
	struct band_job *j = arg;
	struct band_pool *p = j->pool;
	for (;;) {
		uint32_t b = atomic_fetch_add(&p->next, 1);
		if (b >= p->bands || b > atomic_load(&p->first_bad))
			break;
		uint32_t cy = b * p->th;
		int ret = tiff_band(j->r, cy, (unsigned char *)p->data + (size_t)cy * p->row_bytes,
		                    &j->err);
		if (ret) {
			j->ret = ret;
			j->bad = b;
			uint32_t seen = atomic_load(&p->first_bad);
			while (b < seen && !atomic_compare_exchange_weak(&p->first_bad, &seen, b))
				;
			break;
		}
	}
	return NULL;
}

static int same_layout(const kg_image_rows *a, const kg_image_rows *b)
{
	const kg_image *ha = a->head, *hb = b->head;
	return ha->width == hb->width && ha->height == hb->height &&
	       ha->channels == hb->channels && ha->bits == hb->bits &&
	       ha->is_float == hb->is_float && a->spp == b->spp && a->separate == b->separate &&
	       a->invert == b->invert && a->tiled == b->tiled && a->tw == b->tw && a->th == b->th;
}

static int tiff_read_split(kg_image_rows *r, const char *path, void *data, int *done,
                           kg_err *err)
{
	const kg_image *h = r->head;
	uint32_t bands = ((uint32_t)h->height + r->th - 1) / r->th;
	size_t pixels = (size_t)h->width * (size_t)h->height;
	uint16_t compression = COMPRESSION_NONE;
	TIFFGetFieldDefaulted(r->tif, TIFFTAG_COMPRESSION, &compression);
	*done = 0;
	/* Uncompressed, a band is converted, not decoded: worth a second reader from
	 * 4 Mpix. Compressed, its decoding costs more than opening another handle from
	 * 1 Mpix. */
	if (compression == COMPRESSION_NONE ? bands < 8 || pixels < ((size_t)1 << 22)
	                                    : bands < 2 || pixels < ((size_t)1 << 20))
		return 0;
	int want = atomic_load(&read_threads);
	if (want == 0)
		want = kg_cpu_count(8);
	if ((uint32_t)want > bands)
		want = (int)bands;
	if (want < 2)
		return 0;
	struct band_pool pool = {data, bands, r->th,
	                         (size_t)h->width * (size_t)h->channels *
	                             (r->codes ? sizeof(uint16_t) : sizeof(float)),
	                         0, bands};
	struct band_job jobs[READ_THREADS_MAX];
	pthread_t tid[READ_THREADS_MAX];
	int started[READ_THREADS_MAX] = {0};
	memset(jobs, 0, sizeof(jobs));
	int n = 1;
	jobs[0].pool = &pool;
	jobs[0].r = r;
	for (; n < want; n++) {
		kg_image_rows *rn = NULL;
		kg_err en = {{0}};
		if (rows_open_kind(path, KIND_TIFF, NULL, &rn, &en))
			break; /* fewer readers; the first reports what is wrong */
		if (!same_layout(r, rn)) {
			/* the file changed between the opens: never decode another handle's
			 * bands into a buffer sized by the first */
			kg_image_rows_free(&rn);
			break;
		}
		rn->codes = r->codes;
		jobs[n].pool = &pool;
		jobs[n].r = rn;
	}
	if (n < 2)
		return 0;
	for (int k = 1; k < n; k++)
		started[k] = pthread_create(&tid[k], NULL, band_job_main, &jobs[k]) == 0;
	band_job_main(&jobs[0]);
	for (int k = 1; k < n; k++) {
		if (started[k])
			pthread_join(tid[k], NULL);
		else
			band_job_main(&jobs[k]);
		kg_image_rows_free(&jobs[k].r);
	}
	*done = 1;
	r->y = h->height;
	int first = -1;
	for (int k = 0; k < n; k++)
		if (jobs[k].ret && (first < 0 || jobs[k].bad < jobs[first].bad))
			first = k;
	if (first >= 0) {
		*err = jobs[first].err;
		return jobs[first].ret;
	}
	return 0;
}

/* The whole image through the row reader. */
static int read_whole(const char *path, int kind, const kg_image_encoding *enc,
                      kg_image **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	kg_image_rows *r;
	int ret = rows_open_kind(path, kind, enc, &r, err);
	if (ret)
		return ret;
	const kg_image *h = r->head;
	kg_image *img = NULL;
	ret = kg_image_new(h->width, h->height, h->channels, &img, err);
	if (!ret && h->cfa)
		ret = kg_image_set_cfa(img, h->cfa, h->cfa_rows, h->cfa_cols, err);
	if (!ret) {
		img->bits = h->bits;
		img->is_float = h->is_float;
		img->jpeg = h->jpeg;
		img->encoding = h->encoding;
		memcpy(img->note, h->note, sizeof(img->note));
		int done = 0;
		if (kind == KIND_TIFF)
			ret = tiff_read_split(r, path, img->data, &done, err);
		if (!ret && !done)
			ret = kg_image_rows_read(r, h->height, img->data, err);
	}
	kg_image_rows_free(&r);
	if (ret)
		kg_image_free(&img);
	*out = img;
	return ret;
}

int kg_image_read(const char *path, kg_image **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	int kind = image_kind(path, err);
	if (kind == KIND_RAW)
		return kg_raw_read(path, out, NULL, err);
	return kind < 0 ? kind : read_whole(path, kind, NULL, out, err);
}

int kg_image_read_as(const char *path, const kg_image_encoding *enc, kg_image **out,
                     kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	int kind = image_kind(path, err);
	if (kind == KIND_RAW)
		return kg_raw_read(path, out, NULL, err);
	return kind < 0 ? kind : read_whole(path, kind, enc, out, err);
}

static float u16_lut[65536];
static pthread_once_t u16_once = PTHREAD_ONCE_INIT;

static void u16_lut_fill(void)
{
	for (int k = 0; k < 65536; k++)
		u16_lut[k] = (float)k / 65535.0f; /* as tiff_row_u16 */
}

const float *kg_image_u16_lut(void)
{
	pthread_once(&u16_once, u16_lut_fill);
	return u16_lut;
}

/* A compressed 16-bit TIFF of kg_image_map's layout: its codes decoded into memory (by
 * several readers at once when it has many strips or tiles), in the image's block as
 * kg_image_new's floats; frees r. */
static int map_decode_codes(kg_image_rows *r, kg_image **out, kg_err *err)
{
	const kg_image *h = r->head;
	size_t n = (size_t)h->width * (size_t)h->height * (size_t)h->channels;
	kg_image *img = malloc(sizeof(*img) + n * sizeof(uint16_t));
	if (!img) {
		kg_image_rows_free(&r);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory for %zu 16-bit samples", r->path,
		               n);
	}
	memset(img, 0, sizeof(*img));
	huge_pages(img, sizeof(*img) + n * sizeof(uint16_t));
	r->codes = 1;
	int done = 0;
	int ret = tiff_read_split(r, r->path, img + 1, &done, err);
	for (uint32_t cy = 0; !ret && !done && cy < (uint32_t)h->height; cy += r->th)
		ret = tiff_band(r, cy, (uint16_t *)(void *)(img + 1) + (size_t)cy * h->width * h->channels,
		                err);
	if (!ret) {
		img->width = h->width;
		img->height = h->height;
		img->channels = h->channels;
		img->bits = 16;
		img->encoding = h->encoding;
		memcpy(img->note, h->note, sizeof(img->note));
		img->u16 = (const uint16_t *)(const void *)(img + 1);
		*out = img;
	} else
		free(img);
	kg_image_rows_free(&r);
	return ret;
}

int kg_image_map(const char *path, kg_image **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	int kind = image_kind(path, err);
	if (kind < 0)
		return kind;
	if (kind != KIND_TIFF)
		return kg_fail(err, KG_ENOTSUP, "%s: not a TIFF: read, not mapped", path);
	kg_image_rows *r;
	int ret = rows_open_kind(path, KIND_TIFF, NULL, &r, err);
	if (ret)
		return ret;
	const kg_image *h = r->head;
	TIFF *tif = r->tif;
	uint16_t compression = COMPRESSION_NONE;
	TIFFGetFieldDefaulted(tif, TIFFTAG_COMPRESSION, &compression);
	int plain = compression == COMPRESSION_NONE && !r->tiled && !r->separate && !r->invert &&
	            h->bits == 16 && !h->is_float && !h->cfa && r->spp == h->channels &&
	            !TIFFIsByteSwapped(tif);
	/* the strips one after another: rows at a fixed stride from the first */
	size_t row_bytes = (size_t)h->width * (size_t)h->channels * 2;
	uint64_t off0 = plain ? TIFFGetStrileOffset(tif, 0) : 0;
	uint32_t n = plain ? TIFFNumberOfStrips(tif) : 0;
	for (uint32_t i = 0; plain && i < n; i++)
		plain = TIFFGetStrileOffset(tif, i) == off0 + (uint64_t)i * r->th * row_bytes;
	struct stat st;
	int fd = TIFFFileno(tif);
	plain = plain && off0 % 2 == 0 && fstat(fd, &st) == 0 &&
	        off0 + (uint64_t)row_bytes * (uint64_t)h->height <= (uint64_t)st.st_size;
	if (!plain && compression != COMPRESSION_NONE && !r->separate && !r->invert &&
	    h->bits == 16 && !h->is_float && !h->cfa && r->spp == h->channels)
		return map_decode_codes(r, out, err);
	if (!plain) {
		kg_image_rows_free(&r);
		return kg_fail(err, KG_ENOTSUP, "%s: not an uncompressed 16-bit TIFF in one run: "
		               "read, not mapped", path);
	}
	kg_image *img = calloc(1, sizeof(*img));
	/* populate: the page tables filled from the page cache at once, not a fault per
	 * page as the image is read */
	const void *base = NULL;
	if (!img || kg_mapfile_open(fd, (size_t)st.st_size, 1, path, &img->map, &base, NULL)) {
		free(img);
		kg_image_rows_free(&r);
		return kg_fail(err, KG_ENOTSUP, "%s: cannot map: read instead", path);
	}
	img->width = h->width;
	img->height = h->height;
	img->channels = h->channels;
	img->bits = 16;
	img->encoding = h->encoding;
	memcpy(img->note, h->note, sizeof(img->note));
	img->u16 = (const uint16_t *)(const void *)((const unsigned char *)base + off0);
	kg_image_rows_free(&r); /* the map keeps its own descriptor */
	*out = img;
	return 0;
}

int kg_image_map_check(const kg_image *img, kg_err *err)
{
	return img && img->map ? kg_mapfile_check(img->map, err) : 0;
}

int kg_image_read_tiff(const char *path, kg_image **out, kg_err *err)
{
	return read_whole(path, KIND_TIFF, NULL, out, err);
}

int kg_image_read_png(const char *path, kg_image **out, kg_err *err)
{
	return read_whole(path, KIND_PNG, NULL, out, err);
}

/* Write rows of 8- or 16-bit samples prepared by the caller in j->rows. */
static int png_write_body(struct png_job *j, int w, int h, int channels, int bits, int linear)
{
	if (setjmp(png_jmpbuf(j->png)))
		return -1;
	png_init_io(j->png, j->fp);
	/* zlib level 3, not its default 6: `kogei process` of the demo session took
	 * 1.74-1.85 s with 6 and 1.53-1.65 s with 3, its PNGs 3 % larger (lossless
	 * either way; level 1: 1.45-1.55 s for 10 % larger files). */
	png_set_compression_level(j->png, 3);
	png_set_IHDR(j->png, j->info, (png_uint_32)w, (png_uint_32)h, bits,
	             channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
	             PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
	if (linear)
		png_set_gAMA(j->png, j->info, 1.0);
	else
		png_set_sRGB(j->png, j->info, PNG_sRGB_INTENT_PERCEPTUAL);
	png_write_info(j->png, j->info);
	png_write_image(j->png, j->rows);
	png_write_end(j->png, NULL);
	return 0;
}

/* Fill j->pixels / j->rows from either floats (img) or 8-bit RGB (rgb), then write. */
static int png_write_any(const char *path, const kg_image *img, const unsigned char *rgb,
                         int w, int h, int channels, int bits, kg_err *err)
{
	kg_outfile o;
	int ret = kg_outfile_open(&o, path, 0, err);
	if (ret)
		return ret;
	struct png_job j = {0};
	j.fp = o.fp;
	size_t n = (size_t)w * channels, rowbytes = n * (size_t)(bits / 8);
	j.pixels = malloc(rowbytes * (size_t)h);
	j.rows = malloc((size_t)h * sizeof(png_bytep));
	j.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &j, png_error_fn, png_warning_fn);
	j.info = j.png ? png_create_info_struct(j.png) : NULL;
	if (!j.pixels || !j.rows || !j.info) {
		ret = kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
		goto done;
	}
	for (int y = 0; y < h; y++) {
		unsigned char *d = j.rows[y] = j.pixels + (size_t)y * rowbytes;
		if (rgb) {
			memcpy(d, rgb + (size_t)y * n, n);
			continue;
		}
		const float *s = img->data + (size_t)y * n;
		if (bits == 16)
			for (size_t i = 0; i < n; i++) {
				unsigned v = quantise(s[i], 65535.0f);
				d[2 * i] = (unsigned char)(v >> 8);
				d[2 * i + 1] = (unsigned char)(v & 0xff);
			}
		else
			for (size_t i = 0; i < n; i++)
				d[i] = (unsigned char)quantise(s[i], 255.0f);
	}
	if (png_write_body(&j, w, h, channels, bits, rgb == NULL) != 0)
		ret = kg_fail(err, KG_EIO, "%s: cannot write PNG: %s", path, j.msg);
done:
	png_job_end(&j, 0);
	if (ret)
		kg_outfile_abort(&o);
	else
		ret = kg_outfile_commit(&o, err);
	return ret;
}

int kg_image_write_png(const kg_image *img, const char *path, int bits, kg_err *err)
{
	kg_check_arg(img && path, err);
	if (bits != 8 && bits != 16)
		return kg_fail(err, KG_EINVAL, "%s: %d-bit PNG: expected 8 or 16", path, bits);
	if (img->channels != 1 && img->channels != 3)
		return kg_fail(err, KG_EINVAL, "%s: %d channels: expected 1 or 3", path, img->channels);
	return png_write_any(path, img, NULL, img->width, img->height, img->channels, bits, err);
}

int kg_png_write_rgb8(const char *path, const unsigned char *rgb, int width, int height,
                      kg_err *err)
{
	kg_check_arg(path && rgb, err);
	int ret = check_dims(path, width, height, err);
	return ret ? ret : png_write_any(path, NULL, rgb, width, height, 3, 8, err);
}

/* ---- row sources ----------------------------------------------------------------- */

static int image_source_read(void *user, int y0, int rows, float *out, kg_err *err)
{
	const kg_image *img = user;
	size_t n = (size_t)img->width * img->channels;
	if (y0 < 0 || rows < 0 || rows > img->height - y0)
		return kg_fail(err, KG_EINVAL, "image rows %d to %d: outside its %d rows", y0,
		               y0 + rows - 1, img->height);
	memcpy(out, img->data + (size_t)y0 * n, (size_t)rows * n * sizeof(float));
	return 0;
}

void kg_row_source_of_image(const kg_image *img, kg_row_source *s)
{
	*s = (kg_row_source){img->width, img->height, img->channels, image_source_read,
	                     (void *)img};
}

static int rows_source_read(void *user, int y0, int rows, float *out, kg_err *err)
{
	kg_image_rows *r = user;
	if (y0 != r->y)
		return kg_fail(err, KG_EINVAL, "%s: row %d asked, the next is %d: a file is read "
		               "top to bottom once", r->path, y0, r->y);
	return kg_image_rows_read(r, rows, out, err);
}

void kg_row_source_of_rows(kg_image_rows *r, kg_row_source *s)
{
	*s = (kg_row_source){r->head->width, r->head->height, r->head->channels, rows_source_read,
	                     r};
}
