#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <png.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <tiffio.h>
#include <unistd.h>

#include "fsutil.h"
#include "image.h"
#include "kg_config.h"

#define MAX_SIDE (1L << 20)

static int check_dims(const char *path, long w, long h, kg_err *err)
{
	if (w < 1 || h < 1 || w > MAX_SIDE || h > MAX_SIDE || w * h > KG_IMAGE_MAX_PIXELS)
		return kg_fail(err, KG_EINVAL, "%s: image of %ld x %ld pixels: expected 1 to %ld per "
		               "side and at most %ld pixels", path, w, h, MAX_SIDE, KG_IMAGE_MAX_PIXELS);
	return 0;
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

int kg_image_read(const char *path, kg_image **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	unsigned char magic[8] = {0};
	FILE *fp = fopen(path, "rb");
	if (!fp)
		return kg_fail(err, errno == ENOENT ? KG_ENOENT : KG_EIO, "%s: cannot open: %s", path,
		               strerror(errno));
	kg_inputs_add(path, fileno(fp));
	size_t n = fread(magic, 1, sizeof(magic), fp);
	fclose(fp);
	if (n >= 8 && png_sig_cmp(magic, 0, 8) == 0)
		return kg_image_read_png(path, out, err);
	if (n >= 4 && ((magic[0] == 'I' && magic[1] == 'I' && (magic[2] == 42 || magic[2] == 43) &&
	                magic[3] == 0) ||
	               (magic[0] == 'M' && magic[1] == 'M' && magic[2] == 0 &&
	                (magic[3] == 42 || magic[3] == 43))))
		return kg_image_read_tiff(path, out, err);
	return kg_fail(err, KG_EINVAL, "%s: unknown image format: expected a TIFF or PNG file", path);
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
	return 1; /* unknown tags and the like: not worth a message */
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

/* Decode the TIFF's pixel data into img, chunk (strip or tile) by chunk. */
static int tiff_pixels(TIFF *tif, const char *path, kg_image *img, int spp, int bits,
                       int is_float, int separate, int invert, struct tiff_msg *msg, kg_err *err)
{
	uint32_t w = (uint32_t)img->width, h = (uint32_t)img->height, tw, th;
	int tiled = TIFFIsTiled(tif);
	tmsize_t size;
	if (tiled) {
		if (!TIFFGetField(tif, TIFFTAG_TILEWIDTH, &tw) || !TIFFGetField(tif, TIFFTAG_TILELENGTH, &th) ||
		    tw < 1 || th < 1 || tw > MAX_SIDE || th > MAX_SIDE)
			return kg_fail(err, KG_EINVAL, "%s: tile size missing or invalid", path);
		size = TIFFTileSize(tif);
	} else {
		uint32_t rps = h;
		TIFFGetFieldDefaulted(tif, TIFFTAG_ROWSPERSTRIP, &rps);
		tw = w;
		th = rps < 1 || rps > h ? h : rps;
		size = TIFFStripSize(tif);
	}
	int spc = separate ? 1 : spp; /* samples per pixel within one chunk */
	size_t bps = (size_t)bits / 8;
	if (size <= 0)
		return kg_fail(err, KG_EINVAL, "%s: strip or tile size invalid: %s", path, tiff_why(msg));
	unsigned char *buf = _TIFFmalloc(size);
	if (!buf)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory for a %lld-byte %s", path,
		               (long long)size, tiled ? "tile" : "strip");
	int nplanes = separate ? (spp < img->channels ? spp : img->channels) : 1;
	int C = img->channels, ret = 0;
	float full = bits == 8 ? 255.0f : 65535.0f;
	for (int p = 0; p < nplanes && !ret; p++)
		for (uint32_t cy = 0; cy < h && !ret; cy += th)
			for (uint32_t cx = 0; cx < w && !ret; cx += tw) {
				tmsize_t got;
				if (tiled)
					got = TIFFReadEncodedTile(tif, TIFFComputeTile(tif, cx, cy, 0, (uint16_t)p), buf,
					                          size);
				else
					got = TIFFReadEncodedStrip(tif, TIFFComputeStrip(tif, cy, (uint16_t)p), buf,
					                           size);
				uint32_t rows = h - cy < th ? h - cy : th, cols = w - cx < tw ? w - cx : tw;
				size_t need = (((size_t)rows - 1) * tw + cols) * (size_t)spc * bps;
				if (got < 0 || (size_t)got < need) {
					ret = kg_fail(err, KG_EINVAL, "%s: %s at row %u: %s", path,
					              tiled ? "tile" : "strip", cy,
					              got < 0 ? tiff_why(msg) : "data truncated");
					break;
				}
				for (uint32_t r = 0; r < rows; r++) {
					const unsigned char *src = buf + (size_t)r * tw * spc * bps;
					float *dst = img->data + (((size_t)(cy + r) * w) + cx) * C;
					for (uint32_t c = 0; c < cols; c++)
						for (int s = 0; s < (separate ? 1 : C); s++) {
							size_t i = (size_t)c * spc + s;
							float v;
							if (is_float)
								memcpy(&v, src + i * 4, 4);
							else if (bits == 8)
								v = src[i] / full;
							else {
								uint16_t u;
								memcpy(&u, src + i * 2, 2);
								v = u / full;
							}
							dst[(size_t)c * C + (separate ? p : s)] = invert ? 1.0f - v : v;
						}
				}
			}
	_TIFFfree(buf);
	return ret;
}

int kg_image_read_tiff(const char *path, kg_image **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	int fd = open(path, O_RDONLY | O_CLOEXEC);
	if (fd < 0)
		return kg_fail(err, errno == ENOENT ? KG_ENOENT : KG_EIO, "%s: cannot open: %s", path,
		               strerror(errno));
	kg_inputs_add(path, fd);
	struct tiff_msg msg = {{0}};
	TIFF *tif = tiff_open_fd(fd, path, "r", &msg);
	if (!tif) {
		close(fd);
		return kg_fail(err, KG_EINVAL, "%s: not a readable TIFF file: %s", path, tiff_why(&msg));
	}
	kg_image *img = NULL;
	int ret = 0;
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
		goto done;
	int is_float = fmt == SAMPLEFORMAT_IEEEFP;
	if (fmt != SAMPLEFORMAT_UINT && fmt != SAMPLEFORMAT_IEEEFP && fmt != SAMPLEFORMAT_VOID) {
		ret = kg_fail(err, KG_ENOTSUP, "%s: %s samples not supported: expected unsigned integer or "
		              "float", path, fmt == SAMPLEFORMAT_INT ? "signed integer" : "complex");
		goto done;
	}
	if (is_float ? bits != 32 : (bits != 8 && bits != 16)) {
		ret = kg_fail(err, KG_ENOTSUP, "%s: %u-bit %s samples not supported: expected 8, 16 or "
		              "32-bit float", path, bits, is_float ? "float" : "integer");
		goto done;
	}
	int channels;
	if (photo == PHOTOMETRIC_RGB && spp >= 3)
		channels = 3;
	else if ((photo == PHOTOMETRIC_MINISBLACK || photo == PHOTOMETRIC_MINISWHITE ||
	          photo == PHOTOMETRIC_CFA) && spp >= 1)
		channels = 1;
	else {
		ret = kg_fail(err, KG_ENOTSUP, "%s: photometric interpretation %u with %u samples per "
		              "pixel not supported: expected grey, RGB or CFA", path, photo, spp);
		goto done;
	}
	if ((ret = kg_image_new((int)w, (int)h, channels, &img, err)))
		goto done;
	img->bits = bits;
	img->is_float = is_float;
	if (spp > channels)
		add_note(img, "extra samples (alpha) dropped");
	if ((ret = tiff_pixels(tif, path, img, spp, bits, is_float, planar == PLANARCONFIG_SEPARATE,
	                       photo == PHOTOMETRIC_MINISWHITE, &msg, err)))
		goto done;
	if ((ret = read_cfa(tif, img)))
		goto done;
	*out = img;
	img = NULL;
done:
	kg_image_free(&img);
	TIFFClose(tif);
	return ret;
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
	struct tiff_msg msg = {{0}};
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

/* State of one libpng call, kept outside the function that calls setjmp so nothing
 * it holds is lost to longjmp. */
struct png_job {
	png_structp png;
	png_infop info;
	FILE *fp;
	unsigned char *pixels;
	png_bytep *rows;
	char msg[256];
};

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

/* Everything between png_read_info and the samples; returns -1 after a libpng error
 * (message in j->msg) or a kg code. */
static int png_read_body(struct png_job *j, const char *path, kg_image **out, kg_err *err)
{
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
	png_set_interlace_handling(j->png);
	png_read_update_info(j->png, j->info);
	int channels = png_get_channels(j->png, j->info), out_depth = png_get_bit_depth(j->png, j->info);
	size_t rowbytes = png_get_rowbytes(j->png, j->info);
	if ((channels != 1 && channels != 3) || (out_depth != 8 && out_depth != 16) ||
	    rowbytes < (size_t)w * channels * (out_depth / 8))
		return kg_fail(err, KG_ENOTSUP, "%s: PNG colour type %d, %d-bit: not supported", path, ct,
		               depth);
	kg_image *img;
	if ((ret = kg_image_new((int)w, (int)h, channels, &img, err)))
		return ret;
	*out = img; /* the caller frees it on failure */
	img->bits = depth;
	img->is_float = 0;
	if (note)
		add_note(img, note);
	j->pixels = malloc(rowbytes * h);
	j->rows = malloc(h * sizeof(png_bytep));
	if (!j->pixels || !j->rows)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	for (png_uint_32 y = 0; y < h; y++)
		j->rows[y] = j->pixels + (size_t)y * rowbytes;
	png_read_image(j->png, j->rows);

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
	float *lut = malloc(levels * sizeof(float));
	if (!lut)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	for (size_t i = 0; i < levels; i++) {
		float v = (float)i / (float)(levels - 1);
		lut[i] = curve == 1 ? srgb_to_linear(v) : curve == 2 ? powf(v, (float)(1.0 / gamma)) : v;
	}
	size_t n = (size_t)w * channels;
	for (png_uint_32 y = 0; y < h; y++) {
		const unsigned char *s = j->rows[y];
		float *d = img->data + (size_t)y * n;
		if (out_depth == 16)
			for (size_t i = 0; i < n; i++)
				d[i] = lut[(s[2 * i] << 8) | s[2 * i + 1]];
		else
			for (size_t i = 0; i < n; i++)
				d[i] = lut[s[i]];
	}
	free(lut);
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

int kg_image_read_png(const char *path, kg_image **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	struct png_job j = {0};
	j.fp = fopen(path, "rb");
	if (!j.fp)
		return kg_fail(err, errno == ENOENT ? KG_ENOENT : KG_EIO, "%s: cannot open: %s", path,
		               strerror(errno));
	kg_inputs_add(path, fileno(j.fp));
	int ret;
	j.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &j, png_error_fn, png_warning_fn);
	j.info = j.png ? png_create_info_struct(j.png) : NULL;
	if (!j.info)
		ret = kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	else if ((ret = png_read_body(&j, path, out, err)) == -1)
		ret = kg_fail(err, KG_EINVAL, "%s: not a readable PNG file: %s", path, j.msg);
	if (ret)
		kg_image_free(out);
	png_job_end(&j, 1);
	fclose(j.fp);
	return ret;
}

/* Write rows of 8- or 16-bit samples prepared by the caller in j->rows. */
static int png_write_body(struct png_job *j, int w, int h, int channels, int bits, int linear)
{
	if (setjmp(png_jmpbuf(j->png)))
		return -1;
	png_init_io(j->png, j->fp);
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
