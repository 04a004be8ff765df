/* Camera raw files through LibRaw (raw.h): the CFA samples with black subtracted and
 * scaled by the white level, nothing else. */
#include "kg_config.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "fsutil.h"
#include "raw.h"

#if HAVE_LIBRAW
#include <libraw/libraw.h>
#endif

/* ---- recognising a raw file ---------------------------------------------------------- */

static const char *const raw_extensions[] = {
	"dng", "cr2", "cr3", "crw", "nef", "nrw", "arw", "srf", "sr2", "orf", "rw2", "raf", "pef",
	"iiq", "3fr", "fff", "erf", "kdc", "dcr", "mos", "mef", "mrw", "srw", "x3f", "rwl",
};

static int has_raw_extension(const char *path)
{
	const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
	if (!dot || (slash && dot < slash) || strlen(dot + 1) > 4)
		return 0;
	char ext[8] = {0};
	for (size_t i = 0; dot[1 + i] && i < sizeof(ext) - 1; i++)
		ext[i] = (char)tolower((unsigned char)dot[1 + i]);
	for (size_t i = 0; i < sizeof(raw_extensions) / sizeof(raw_extensions[0]); i++)
		if (!strcmp(ext, raw_extensions[i]))
			return 1;
	return 0;
}

static uint32_t get_u(const unsigned char *p, int n, int big)
{
	uint32_t v = 0;
	for (int i = 0; i < n; i++)
		v |= (uint32_t)p[big ? n - 1 - i : i] << (8 * i);
	return v;
}

/* A classic TIFF whose first IFD has the DNGVersion tag (50706). */
static int tiff_has_dng_version(FILE *fp)
{
	unsigned char h[8], e[12];
	if (fread(h, 1, 8, fp) != 8)
		return 0;
	int big = h[0] == 'M';
	if (!((h[0] == 'I' && h[1] == 'I') || (h[0] == 'M' && h[1] == 'M')) ||
	    get_u(h + 2, 2, big) != 42)
		return 0;
	if (fseek(fp, (long)get_u(h + 4, 4, big), SEEK_SET))
		return 0;
	unsigned char c[2];
	if (fread(c, 1, 2, fp) != 2)
		return 0;
	unsigned n = get_u(c, 2, big);
	for (unsigned i = 0; i < n && i < 4096; i++) {
		if (fread(e, 1, 12, fp) != 12)
			return 0;
		if (get_u(e, 2, big) == 50706)
			return 1;
	}
	return 0;
}

#if HAVE_LIBRAW
/* A TIFF-based file (DNG, CR2, NEF, ARW, ...) whose first directory or strips lie
 * beyond its end: cut short in a copy or a download. */
static int tiff_truncated(const char *path, char *why, size_t n)
{
	FILE *fp = fopen(path, "rb");
	if (!fp)
		return 0;
	unsigned char h[8];
	int cut = 0;
	long size = fseek(fp, 0, SEEK_END) == 0 ? ftell(fp) : -1;
	if (size >= 8 && fseek(fp, 0, SEEK_SET) == 0 && fread(h, 1, 8, fp) == 8 &&
	    ((h[0] == 'I' && h[1] == 'I') || (h[0] == 'M' && h[1] == 'M'))) {
		uint32_t ifd = get_u(h + 4, 4, h[0] == 'M');
		if ((long)ifd + 2 > size) {
			snprintf(why, n, "its TIFF directory at byte %u lies beyond the end of the "
			         "%ld-byte file", ifd, size);
			cut = 1;
		}
	}
	fclose(fp);
	return cut;
}

/* ISOSpeedRatings (0x8827) in a TIFF's first IFD, where some cameras and converters
 * write it instead of in the EXIF IFD (LibRaw reads it only from there); NAN when the
 * file has none there or is not a TIFF. */
static double tiff_ifd0_iso(FILE *fp)
{
	unsigned char h[8], e[12], c[2], v[4];
	if (fread(h, 1, 8, fp) != 8)
		return NAN;
	int big = h[0] == 'M';
	if (!((h[0] == 'I' && h[1] == 'I') || (h[0] == 'M' && h[1] == 'M')) ||
	    get_u(h + 2, 2, big) != 42)
		return NAN;
	if (fseek(fp, (long)get_u(h + 4, 4, big), SEEK_SET) || fread(c, 1, 2, fp) != 2)
		return NAN;
	unsigned n = get_u(c, 2, big);
	for (unsigned i = 0; i < n && i < 4096; i++) {
		if (fread(e, 1, 12, fp) != 12)
			return NAN;
		if (get_u(e, 2, big) != 0x8827)
			continue;
		unsigned type = get_u(e + 2, 2, big);
		uint32_t count = get_u(e + 4, 4, big);
		int size = type == 3 ? 2 : type == 4 ? 4 : 0; /* SHORT or LONG */
		if (!size || count < 1)
			return NAN;
		if ((uint32_t)size * count <= 4)
			memcpy(v, e + 8, 4);
		else if (fseek(fp, (long)get_u(e + 8, 4, big), SEEK_SET) ||
		         fread(v, 1, (size_t)size, fp) != (size_t)size)
			return NAN;
		double iso = get_u(v, size, big);
		return iso > 0 ? iso : NAN;
	}
	return NAN;
}

/* The ISO of IFD 0 where LibRaw found none. */
static void iso_from_ifd0(const char *path, const void *data, size_t size, kg_raw_meta *m)
{
	if (!m || !isnan(m->iso))
		return;
	FILE *fp = path ? fopen(path, "rb") : fmemopen((void *)(uintptr_t)data, size, "rb");
	if (!fp)
		return;
	m->iso = tiff_ifd0_iso(fp);
	fclose(fp);
}

/* ---- a DNG's own black and white levels -------------------------------------------- */

/* What the raw IFD of a DNG says (DNG 1.4 tags BlackLevelRepeatDim 0xC619, BlackLevel
 * 0xC61A, BlackLevelDeltaH/V 0xC61B/0xC61C, WhiteLevel 0xC61D), read from the bytes
 * themselves: LibRaw may replace the white level by its camera table's (a "NIKON
 * D5100" DNG with WhiteLevel 15520 comes out at 14504) and rounds a fractional black. */
typedef struct dng_levels {
	int has_black, has_white, has_deltas;
	int dim_r, dim_c;  /* BlackLevelRepeatDim */
	double black[4];   /* dim_r x dim_c, row-major (at most 2 x 2 kept) */
	double white;      /* the first sample's */
} dng_levels;

typedef struct tiff_buf {
	const unsigned char *p;
	size_t n;
	int big;
} tiff_buf;

static int tb_u(const tiff_buf *t, size_t off, int size, uint32_t *v)
{
	if (off > t->n || (size_t)size > t->n - off)
		return -1;
	*v = get_u(t->p + off, size, t->big);
	return 0;
}

/* Value i of an entry (SHORT, LONG, RATIONAL, SRATIONAL) as a double; -1 if out of
 * range or of another type. */
static int tb_value(const tiff_buf *t, size_t entry, uint32_t i, double *out)
{
	uint32_t type, count, v, d;
	if (tb_u(t, entry + 2, 2, &type) || tb_u(t, entry + 4, 4, &count) || i >= count)
		return -1;
	int size = type == 3 ? 2 : type == 4 ? 4 : type == 5 || type == 10 ? 8 : 0;
	if (!size || count > (1u << 20))
		return -1;
	size_t data = entry + 8;
	if ((uint64_t)size * count > 4) {
		uint32_t off;
		if (tb_u(t, entry + 8, 4, &off))
			return -1;
		data = off;
	}
	size_t at = data + (size_t)i * (size_t)size;
	if (size <= 4) {
		if (tb_u(t, at, size, &v))
			return -1;
		*out = v;
		return 0;
	}
	if (tb_u(t, at, 4, &v) || tb_u(t, at + 4, 4, &d) || d == 0)
		return -1;
	*out = type == 10 ? (double)(int32_t)v / (double)(int32_t)d : (double)v / (double)d;
	return isfinite(*out) ? 0 : -1;
}

/* The levels of the IFD at off when it holds a CFA image of NewSubFileType 0; 1 when it
 * does, 0 when not, -1 when damaged. */
static int dng_ifd_levels(const tiff_buf *t, size_t off, dng_levels *L, uint32_t *subifds,
                          int *nsub)
{
	uint32_t n, tag, photometric = 0, subfile = 0, v;
	if (tb_u(t, off, 2, &n) || n > 4096)
		return -1;
	dng_levels l = {.dim_r = 1, .dim_c = 1};
	size_t black_entry = 0, white_entry = 0;
	for (uint32_t i = 0; i < n; i++) {
		size_t e = off + 2 + 12 * (size_t)i;
		if (tb_u(t, e, 2, &tag))
			return -1;
		double x;
		if (tag == 0xFE && !tb_value(t, e, 0, &x))
			subfile = (uint32_t)x;
		else if (tag == 0x106 && !tb_value(t, e, 0, &x))
			photometric = (uint32_t)x;
		else if (tag == 0x14A && subifds && nsub) { /* SubIFDs: LONG or IFD offsets */
			uint32_t count, type;
			if (tb_u(t, e + 2, 2, &type) || tb_u(t, e + 4, 4, &count))
				return -1;
			for (uint32_t k = 0; k < count && *nsub < 8; k++) {
				size_t at = count == 1 ? e + 8 : 0;
				if (count > 1) {
					if (tb_u(t, e + 8, 4, &v))
						return -1;
					at = (size_t)v + 4 * (size_t)k;
				}
				if (tb_u(t, at, 4, &v))
					return -1;
				subifds[(*nsub)++] = v;
			}
		} else if (tag == 0xC619) {
			double r, c;
			if (tb_value(t, e, 0, &r) || tb_value(t, e, 1, &c) || r < 1 || c < 1)
				return -1;
			l.dim_r = (int)r;
			l.dim_c = (int)c;
		} else if (tag == 0xC61A)
			black_entry = e;
		else if (tag == 0xC61B || tag == 0xC61C)
			l.has_deltas = 1;
		else if (tag == 0xC61D)
			white_entry = e;
	}
	if (subfile != 0 || photometric != 32803)
		return 0;
	if (white_entry && !tb_value(t, white_entry, 0, &l.white) && l.white > 0)
		l.has_white = 1;
	if (black_entry && l.dim_r <= 2 && l.dim_c <= 2) {
		l.has_black = 1;
		for (int k = 0; k < l.dim_r * l.dim_c; k++)
			if (tb_value(t, black_entry, (uint32_t)k, &l.black[k]))
				l.has_black = 0;
	}
	*L = l;
	return 1;
}

/* The raw (CFA) IFD's levels of a DNG in memory: IFD 0 or one of its SubIFDs. 0 when
 * found. */
static int dng_levels_of(const void *data, size_t size, dng_levels *L)
{
	memset(L, 0, sizeof(*L));
	const unsigned char *p = data;
	if (!p || size < 8 || !((p[0] == 'I' && p[1] == 'I') || (p[0] == 'M' && p[1] == 'M')))
		return -1;
	tiff_buf t = {p, size, p[0] == 'M'};
	uint32_t magic, ifd0;
	if (tb_u(&t, 2, 2, &magic) || magic != 42 || tb_u(&t, 4, 4, &ifd0))
		return -1;
	uint32_t sub[8];
	int nsub = 0;
	int r = dng_ifd_levels(&t, ifd0, L, sub, &nsub);
	if (r)
		return r > 0 ? 0 : -1;
	for (int i = 0; i < nsub; i++)
		if ((r = dng_ifd_levels(&t, sub[i], L, NULL, NULL)) != 0)
			return r > 0 ? 0 : -1;
	return -1;
}

#endif

int kg_raw_is_raw(const char *path)
{
	if (!path)
		return 0;
	if (has_raw_extension(path))
		return 1;
	FILE *fp = fopen(path, "rb");
	if (!fp)
		return 0;
	int dng = tiff_has_dng_version(fp);
	fclose(fp);
	return dng;
}

#if HAVE_LIBRAW

int kg_raw_available(void)
{
	return 1;
}

const char *kg_raw_version(void)
{
	return libraw_version();
}

/* What went wrong inside LibRaw while decoding (its data-error callback). */
typedef struct raw_job {
	libraw_data_t *lr;
	const char *name;
	const void *data; /* the file's bytes (pixels decoded), or NULL */
	size_t size;
	int data_error;
	char data_where[128];
} raw_job;

static void on_data_error(void *user, const char *file, const int offset)
{
	raw_job *j = user;
	if (!j->data_error)
		snprintf(j->data_where, sizeof(j->data_where), "at byte %d", offset);
	(void)file;
	j->data_error = 1;
}

static int lr_fail(raw_job *j, int code, kg_err *err, const char *what)
{
	int ours = code == LIBRAW_FILE_UNSUPPORTED ? KG_ENOTSUP
	           : code == LIBRAW_UNSUFFICIENT_MEMORY ? KG_ENOMEM
	           : code == LIBRAW_IO_ERROR && errno == ENOENT ? KG_ENOENT
	           : KG_EINVAL;
	if (code == LIBRAW_FILE_UNSUPPORTED)
		return kg_fail(err, ours, "%s: not a camera raw file LibRaw %s can read (%s)",
		               j->name, libraw_version(), libraw_strerror(code));
	return kg_fail(err, ours, "%s: %s: %s (truncated or damaged?)", j->name, what,
	               libraw_strerror(code));
}

static void copy_str(char *dst, size_t n, const char *src)
{
	size_t len = src ? strnlen(src, n - 1) : 0;
	memcpy(dst, src ? src : "", len);
	dst[len] = 0;
	/* trailing spaces: some makers pad the EXIF strings */
	for (size_t k = strlen(dst); k > 0 && dst[k - 1] == ' '; k--)
		dst[k - 1] = 0;
}

static double positive_or_nan(double v)
{
	return isfinite(v) && v > 0 ? v : NAN;
}

/* The visible area's 2x2 CFA, or a reason it has none kogei can use. */
static int bayer_pattern(raw_job *j, int unpacked, char cfa[5], kg_err *err)
{
	libraw_data_t *lr = j->lr;
	if (!lr->idata.filters || (unpacked && !lr->rawdata.raw_image))
		return kg_fail(err, KG_ENOTSUP,
		               "%s: no colour filter array data (an sRAW/mRAW, linear or lossy DNG, "
		               "or a Foveon file: the camera or converter already demosaiced it); "
		               "kogei needs the sensor's mosaic",
		               j->name);
	if (lr->idata.filters == 9)
		return kg_fail(err, KG_ENOTSUP,
		               "%s: an X-Trans (6x6) mosaic: kogei demosaics 2x2 Bayer mosaics only",
		               j->name);
	if (lr->idata.filters < 1000 || lr->idata.colors != 3)
		return kg_fail(err, KG_ENOTSUP,
		               "%s: a %d-colour mosaic (filters 0x%x): kogei reads RGB Bayer mosaics "
		               "only",
		               j->name, lr->idata.colors, lr->idata.filters);
	for (int r = 0; r < 16; r++)
		for (int c = 0; c < 16; c++)
			if (libraw_COLOR(lr, r, c) != libraw_COLOR(lr, r % 2, c % 2))
				return kg_fail(err, KG_ENOTSUP,
				               "%s: the mosaic does not repeat every 2x2 pixels", j->name);
	for (int k = 0; k < 4; k++) {
		int idx = libraw_COLOR(lr, k / 2, k % 2);
		char ch = idx >= 0 && idx < 4 ? lr->idata.cdesc[idx] : '?';
		if (ch != 'R' && ch != 'G' && ch != 'B')
			return kg_fail(err, KG_ENOTSUP, "%s: CFA colour '%c' (colours %s): expected R, G "
			               "or B", j->name, ch, lr->idata.cdesc);
		cfa[k] = ch;
	}
	cfa[4] = 0;
	int nr = 0, ng = 0, nb = 0;
	for (int k = 0; k < 4; k++)
		nr += cfa[k] == 'R', ng += cfa[k] == 'G', nb += cfa[k] == 'B';
	if (nr != 1 || ng != 2 || nb != 1)
		return kg_fail(err, KG_ENOTSUP, "%s: CFA pattern %s: expected a Bayer pattern (one "
		               "R, two G, one B)", j->name, cfa);
	return 0;
}

/* Lossy encodings LibRaw decodes but whose values are not the sensor's. */
static int refuse_lossy(raw_job *j, kg_err *err)
{
	libraw_decoder_info_t di;
	memset(&di, 0, sizeof(di));
	if (libraw_get_decoder_info(j->lr, &di) != LIBRAW_SUCCESS || !di.decoder_name)
		return 0;
	static const char *const lossy[] = {"lossy_dng_load_raw", "sony_arw2_load_raw",
	                                    "canon_sraw_load_raw", "nikon_load_sraw",
	                                    "kodak_ycbcr_load_raw", "sony_ycbcr_load_raw"};
	for (size_t i = 0; i < sizeof(lossy) / sizeof(lossy[0]); i++)
		if (strstr(di.decoder_name, lossy[i]))
			return kg_fail(err, KG_ENOTSUP,
			               "%s: a lossy raw encoding (%s): its values are not the sensor's; "
			               "set the camera to uncompressed or lossless raw",
			               j->name, di.decoder_name);
	if (di.decoder_flags & LIBRAW_DECODER_SONYARW2)
		return kg_fail(err, KG_ENOTSUP,
		               "%s: Sony compressed raw (lossy); set the camera to uncompressed or "
		               "lossless raw",
		               j->name);
	return 0;
}

static void fill_meta(raw_job *j, const char cfa[5], kg_raw_meta *m)
{
	libraw_data_t *lr = j->lr;
	memset(m, 0, sizeof(*m));
	if (lr->idata.dng_version)
		snprintf(m->format, sizeof(m->format), "DNG %u.%u.%u.%u",
		         lr->idata.dng_version >> 24, (lr->idata.dng_version >> 16) & 255,
		         (lr->idata.dng_version >> 8) & 255, lr->idata.dng_version & 255);
	else
		snprintf(m->format, sizeof(m->format), "%.24s raw",
		         lr->idata.normalized_make[0] ? lr->idata.normalized_make : lr->idata.make);
	copy_str(m->make, sizeof(m->make), lr->idata.make);
	copy_str(m->model, sizeof(m->model), lr->idata.model);
	copy_str(m->serial, sizeof(m->serial), lr->shootinginfo.BodySerial);
	if (!m->serial[0])
		copy_str(m->serial, sizeof(m->serial), lr->shootinginfo.InternalBodySerial);
	copy_str(m->lens, sizeof(m->lens), lr->lens.Lens);
	/* LibRaw keeps the exposure time as a float: 1/125 s would read 0.0079999998. */
	char t[32];
	snprintf(t, sizeof(t), "%.6g", (double)lr->other.shutter);
	m->exposure_s = positive_or_nan(strtod(t, NULL));
	m->iso = positive_or_nan(lr->other.iso_speed);
	m->aperture = positive_or_nan(lr->other.aperture);
	m->focal_length_mm = positive_or_nan(lr->other.focal_len);
	m->timestamp = (long long)lr->other.timestamp;
	if (cfa)
		memcpy(m->cfa, cfa, 5);
	m->width = lr->sizes.width;
	m->height = lr->sizes.height;
}

/* Black of CFA position (r, c) of the visible area: LibRaw's common black, the black of
 * that colour, and the repeating black pattern (cblack[4] x cblack[5] from cblack[6]). */
static double black_at(const libraw_data_t *lr, int r, int c)
{
	const unsigned *cb = lr->color.cblack;
	int colour = libraw_COLOR((libraw_data_t *)lr, r, c);
	double b = (double)lr->color.black + (colour >= 0 && colour < 4 ? cb[colour] : 0);
	if (cb[4] && cb[5] && 6 + cb[4] * cb[5] <= LIBRAW_CBLACK_SIZE)
		b += cb[6 + (unsigned)(r % (int)cb[4]) * cb[5] + (unsigned)(c % (int)cb[5])];
	return b;
}

static int decode(raw_job *j, kg_image **out, kg_raw_meta *meta, int pixels, kg_err *err)
{
	libraw_data_t *lr = j->lr;
	char cfa[5] = {0};
	int ret;
	if (!pixels) { /* the header only: refuse what decoding would refuse */
		if ((ret = bayer_pattern(j, 0, cfa, err)))
			return ret;
		if (meta)
			fill_meta(j, cfa, meta);
		return 0;
	}
	int code = libraw_unpack(lr);
	if (code != LIBRAW_SUCCESS)
		return lr_fail(j, code, err, "cannot decode the raw data");
	if (j->data_error)
		return kg_fail(err, KG_EINVAL, "%s: the raw data is damaged or truncated (%s)",
		               j->name, j->data_where);
	if ((ret = refuse_lossy(j, err)) || (ret = bayer_pattern(j, 1, cfa, err)))
		return ret;
	const libraw_image_sizes_t *S = &lr->sizes;
	int w = S->width, h = S->height;
	if (w < 2 || h < 2 || S->left_margin + w > S->raw_width ||
	    S->top_margin + h > S->raw_height || S->raw_pitch < 2u * S->raw_width)
		return kg_fail(err, KG_EINVAL, "%s: visible area %dx%d at (%d, %d) of a %dx%d sensor: "
		               "does not fit", j->name, w, h, S->left_margin, S->top_margin,
		               S->raw_width, S->raw_height);
	/* Black and white per CFA position; the white level per channel where the file
	 * gives one (linear_max, black included), else the common maximum. */
	double black[4], white[4];
	for (int k = 0; k < 4; k++) {
		black[k] = black_at(lr, k / 2, k % 2);
		int colour = libraw_COLOR(lr, k / 2, k % 2);
		double lin = colour >= 0 && colour < 4 ? (double)lr->color.linear_max[colour] : 0;
		white[k] = lin > black[k] ? lin : (double)lr->color.maximum;
		if (!(white[k] > black[k]))
			return kg_fail(err, KG_EINVAL, "%s: white level %g not above black level %g",
			               j->name, white[k], black[k]);
	}
	const unsigned *cb = lr->color.cblack;
	int pattern = cb[4] && cb[5] && (cb[4] > 2 || cb[5] > 2 || (2 % cb[4]) || (2 % cb[5]));
	/* A DNG's own WhiteLevel and BlackLevel (fractional ones as they are) win over
	 * LibRaw's: it may take the white level from its camera table and rounds the black.
	 * The black pattern repeats from the active area's corner, the visible area's. */
	dng_levels L;
	char levels_note[96] = "";
	if (lr->idata.dng_version && j->data && !dng_levels_of(j->data, j->size, &L)) {
		if (L.has_white && L.white != white[0])
			snprintf(levels_note, sizeof(levels_note), " (the file's WhiteLevel %g, not "
			         "LibRaw's %g)", L.white, white[0]);
		double nb[4], nw[4];
		for (int k = 0; k < 4; k++) {
			nb[k] = L.has_black && !L.has_deltas
			        ? L.black[(k / 2 % L.dim_r) * L.dim_c + (k % 2 % L.dim_c)] : black[k];
			nw[k] = L.has_white ? L.white : white[k];
			if (!(nw[k] > nb[k]))
				return kg_fail(err, KG_EINVAL, "%s: WhiteLevel %g not above BlackLevel %g",
				               j->name, nw[k], nb[k]);
		}
		memcpy(white, nw, sizeof(nw));
		if (L.has_black && !L.has_deltas) {
			memcpy(black, nb, sizeof(nb));
			pattern = 0;
		}
	}
	kg_image *img = NULL;
	if ((ret = kg_image_new(w, h, 1, &img, err)) ||
	    (ret = kg_image_set_cfa(img, cfa, 2, 2, err))) {
		kg_image_free(&img);
		return ret;
	}
	double range_bits = ceil(log2(white[0] + 1));
	img->bits = range_bits >= 1 && range_bits <= 16 ? (int)range_bits : 16;
	img->is_float = 0;
	const unsigned short *raw = lr->rawdata.raw_image;
	size_t pitch = S->raw_pitch / 2;
	for (int y = 0; y < h; y++) {
		const unsigned short *src = raw + (size_t)(y + S->top_margin) * pitch + S->left_margin;
		float *dst = img->data + (size_t)y * (size_t)w;
		int k0 = (y & 1) * 2;
		if (!pattern) {
			double b0 = black[k0], b1 = black[k0 + 1];
			double s0 = 1.0 / (white[k0] - b0), s1 = 1.0 / (white[k0 + 1] - b1);
			for (int x = 0; x + 1 < w; x += 2) {
				dst[x] = (float)((src[x] - b0) * s0);
				dst[x + 1] = (float)((src[x + 1] - b1) * s1);
			}
			if (w & 1)
				dst[w - 1] = (float)((src[w - 1] - b0) * s0);
		} else {
			for (int x = 0; x < w; x++) {
				int k = k0 + (x & 1);
				double b = black_at(lr, y, x);
				dst[x] = (float)((src[x] - b) / (white[k] - black[k]));
			}
		}
	}
	if (meta) {
		fill_meta(j, cfa, meta);
		for (int k = 0; k < 4; k++) {
			meta->black[k] = black[k];
			meta->white[k] = white[k];
		}
		meta->raw_bits = img->bits;
	}
	snprintf(img->note, sizeof(img->note), "raw %s decoded by LibRaw %s: black %g, white %g%s",
	         meta ? meta->format : "file", libraw_version(), black[0], white[0], levels_note);
	*out = img;
	return 0;
}

/* data: the bytes to decode; path: the file they came from (for the diagnosis of a
 * header LibRaw cannot read), or NULL. Pixels are always decoded from memory: LibRaw's
 * file and memory streams differ on damaged data (a read past the end, a seek beyond
 * it), so one stream for both keeps a file and the same bytes from a camera (gphoto2:)
 * decoding alike or both refused. Without data (the header only, for a folder's
 * listing), LibRaw opens the file itself and reads no more than the header. */
static int run(const char *path, const void *data, size_t size, const char *name,
               kg_image **out, kg_raw_meta *meta, int pixels, kg_err *err)
{
	if (out)
		*out = NULL;
	raw_job j = {.name = name, .data = data, .size = size};
	j.lr = libraw_init(0);
	if (!j.lr)
		return kg_fail(err, KG_ENOMEM, "%s: cannot start LibRaw", name);
	libraw_set_dataerror_handler(j.lr, on_data_error, &j);
	int code = data ? libraw_open_buffer(j.lr, (void *)(uintptr_t)data, size)
	                : libraw_open_file(j.lr, path);
	int ret;
	if (code != LIBRAW_SUCCESS) {
		char why[160];
		if (path && access(path, F_OK) != 0)
			ret = kg_fail(err, KG_ENOENT, "%s: cannot open: no such file", name);
		else if (path && tiff_truncated(path, why, sizeof(why)))
			ret = kg_fail(err, KG_EINVAL, "%s: truncated or damaged: %s", name, why);
		else
			ret = lr_fail(&j, code, err, "cannot read the file's header");
	} else {
		ret = decode(&j, out, meta, pixels, err);
		if (!ret)
			iso_from_ifd0(path, data, size, meta);
	}
	libraw_close(j.lr);
	return ret;
}

static int too_short(const char *name, size_t size, kg_err *err)
{
	return kg_fail(err, KG_EINVAL, "%s: %zu bytes: too short for a raw file",
	               name ? name : "raw data", size);
}

/* The whole file, decoded from memory as kg_raw_read_memory decodes it. */
static int run_file(const char *path, kg_image **out, kg_raw_meta *meta, kg_err *err)
{
	if (out)
		*out = NULL;
	char *data = NULL;
	size_t size = 0;
	int ret = kg_read_file(path, &data, &size, err);
	if (ret)
		return ret;
	ret = size < 16 ? too_short(path, size, err)
	                : run(path, data, size, path, out, meta, 1, err);
	free(data);
	return ret;
}

int kg_raw_read(const char *path, kg_image **out, kg_raw_meta *meta, kg_err *err)
{
	kg_check_arg(path && out, err);
	return run_file(path, out, meta, err);
}

int kg_raw_read_memory(const void *data, size_t size, const char *name, kg_image **out,
                       kg_raw_meta *meta, kg_err *err)
{
	kg_check_arg(data && out, err);
	if (size < 16)
		return too_short(name, size, err);
	return run(NULL, data, size, name ? name : "raw data", out, meta, 1, err);
}

int kg_raw_read_meta(const char *path, kg_raw_meta *meta, kg_err *err)
{
	kg_check_arg(path && meta, err);
	return run(path, NULL, 0, path, NULL, meta, 0, err);
}

#else /* without LibRaw */

int kg_raw_available(void)
{
	return 0;
}

const char *kg_raw_version(void)
{
	return NULL;
}

static int no_libraw(const char *name, kg_err *err)
{
	return kg_fail(err, KG_ENOTSUP, "%s: a camera raw file: this kogei was built without LibRaw "
	               "(install libraw-dev and rebuild with -Dlibraw=enabled)",
	               name ? name : "raw data");
}

int kg_raw_read(const char *path, kg_image **out, kg_raw_meta *meta, kg_err *err)
{
	(void)out;
	(void)meta;
	return no_libraw(path, err);
}

int kg_raw_read_memory(const void *data, size_t size, const char *name, kg_image **out,
                       kg_raw_meta *meta, kg_err *err)
{
	(void)data;
	(void)size;
	(void)out;
	(void)meta;
	return no_libraw(name, err);
}

int kg_raw_read_meta(const char *path, kg_raw_meta *meta, kg_err *err)
{
	(void)meta;
	return no_libraw(path, err);
}

#endif
