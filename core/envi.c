#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "envi.h"
#include "escape.h"
#include "fsutil.h"
#include "plot.h"

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
#define HOST_BYTE_ORDER 1
#else
#define HOST_BYTE_ORDER 0
#endif

/* Raw reads and type conversions go through chunks of about this many bytes. */
#define CHUNK_BYTES ((size_t)4 << 20)

static size_t type_size(enum kg_envi_type t)
{
	switch (t) {
	case KG_ENVI_U8: return 1;
	case KG_ENVI_I16:
	case KG_ENVI_U16: return 2;
	case KG_ENVI_I32:
	case KG_ENVI_U32:
	case KG_ENVI_F32: return 4;
	case KG_ENVI_F64: return 8;
	}
	return 0;
}

static const char *interleave_name(enum kg_envi_interleave il)
{
	return il == KG_ENVI_BIL ? "bil" : il == KG_ENVI_BIP ? "bip" : "bsq";
}

static int has_suffix_ci(const char *s, const char *suffix)
{
	size_t n = strlen(s), m = strlen(suffix);
	return n > m && strcasecmp(s + n - m, suffix) == 0;
}

static char *concat(const char *a, size_t alen, const char *b)
{
	size_t blen = strlen(b);
	char *s = malloc(alen + blen + 1);
	if (s) {
		memcpy(s, a, alen);
		memcpy(s + alen, b, blen + 1);
	}
	return s;
}

int kg_envi_paths(const char *path, char **hdr_path, char **data_path, kg_err *err)
{
	kg_check_arg(path && hdr_path && data_path, err);
	*hdr_path = *data_path = NULL;
	if (!*path || strcmp(path, "-") == 0)
		return kg_fail(err, KG_EINVAL, "'%s': an ENVI cube needs a file name (x.hdr)", path);
	size_t n = strlen(path);
	if (has_suffix_ci(path, ".hdr")) {
		*hdr_path = strdup(path);
		*data_path = concat(path, n - 4, ".img");
	} else {
		/* "x.bin.hdr" is found by GDAL and by Spectral Python whatever the extension. */
		*data_path = strdup(path);
		*hdr_path = concat(path, n, ".hdr");
	}
	if (!*hdr_path || !*data_path) {
		free(*hdr_path);
		free(*data_path);
		*hdr_path = *data_path = NULL;
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	}
	return 0;
}

/* ---- header text --------------------------------------------------------------- */

static void put_list_open(FILE *f, const char *key) { fprintf(f, "%s = {", key); }

/* Separator before element i of a list: eight per line, continuation lines indented. */
static void put_list_sep(FILE *f, int i)
{
	if (i > 0)
		fputs(i % 8 == 0 ? ",\n  " : ", ", f);
}

static void put_numbers(FILE *f, const double *v, int n)
{
	for (int i = 0; i < n; i++) {
		put_list_sep(f, i);
		fprintf(f, "%.17g", v[i]);
	}
}

int kg_envi_format_list(const double *v, int n, char **out, kg_err *err)
{
	kg_check_arg(out && n >= 0 && (v || n == 0), err);
	*out = NULL;
	for (int i = 0; i < n; i++)
		if (!isfinite(v[i]))
			return kg_fail(err, KG_EINVAL, "ENVI list: element %d is %g: expected finite numbers",
			               i, v[i]);
	size_t len;
	FILE *f = open_memstream(out, &len);
	if (!f)
		return kg_fail(err, KG_ENOMEM, "ENVI list: out of memory");
	fputc('{', f);
	put_numbers(f, v, n);
	fputc('}', f);
	if (fclose(f) != 0) {
		free(*out);
		*out = NULL;
		return kg_fail(err, KG_ENOMEM, "ENVI list: out of memory");
	}
	return 0;
}

/* A description (list 0) or the element i of a list (band or class names). */
static int check_text(const char *what, int i, const char *s, int list, kg_err *err)
{
	char label[128];
	if (list)
		snprintf(label, sizeof(label), "ENVI header: %s %d '%.40s'", what, i + 1, s ? s : "");
	else
		snprintf(label, sizeof(label), "ENVI header: %s", what);
	if (!s)
		return kg_fail(err, KG_EINVAL, "%s is missing", label);
	return kg_envi_check(label, s, list, err);
}

static const char *const known_keys[] = {
	"samples", "lines", "bands", "header offset", "file type", "data type", "interleave",
	"byte order", "description", "wavelength", "wavelength units", "band names",
	"reflectance scale factor", "classes", "class names", "class lookup",
};

static int is_known_key(const char *k)
{
	for (size_t i = 0; i < sizeof(known_keys) / sizeof(known_keys[0]); i++)
		if (strcmp(k, known_keys[i]) == 0)
			return 1;
	return 0;
}

static int check_extra(const kg_envi_pair *p, kg_err *err)
{
	if (!p->key || !*p->key || !p->value)
		return kg_fail(err, KG_EINVAL, "ENVI header: extra key %s: expected a key and a value",
		               p->key ? p->key : "(null)");
	for (const char *c = p->key; *c; c++)
		if (*c == '=' || *c == '{' || *c == '}' || *c == '\n' || *c == ';' || isupper((unsigned char)*c))
			return kg_fail(err, KG_EINVAL,
			               "ENVI header: extra key '%s': expected lower case without '=', braces, "
			               "';' or newlines", p->key);
	if (is_known_key(p->key))
		return kg_fail(err, KG_EINVAL, "ENVI header: extra key '%s' is written by the writer itself",
		               p->key);
	const char *v = p->value;
	size_t n = strlen(v);
	int braced = n >= 2 && v[0] == '{' && v[n - 1] == '}';
	const char *inner = braced ? v + 1 : v;
	size_t inner_n = braced ? n - 2 : n;
	for (size_t i = 0; i < inner_n; i++)
		if (inner[i] == '{' || inner[i] == '}' || (!braced && inner[i] == '\n'))
			return kg_fail(err, KG_EINVAL,
			               "ENVI header: value of '%s': expected one line, or a list in braces "
			               "with no braces inside", p->key);
	return 0;
}

/* Validate meta and render the header text (caller frees *text). */
static int render_header(const kg_envi_meta *m, char **text, kg_err *err)
{
	*text = NULL;
	if (m->samples < 1 || m->lines < 1 || m->bands < 1)
		return kg_fail(err, KG_EINVAL, "ENVI header: %d samples x %d lines x %d bands: expected "
		               "positive dimensions", m->samples, m->lines, m->bands);
	if (m->data_type != KG_ENVI_U8 && m->data_type != KG_ENVI_I16 &&
	    m->data_type != KG_ENVI_F32 && m->data_type != KG_ENVI_U16 &&
	    m->data_type != KG_ENVI_U32)
		return kg_fail(err, KG_EINVAL, "ENVI header: data type %d: expected 1 (uint8), 2 (int16), "
		               "4 (float32), 12 (uint16) or 13 (uint32)", (int)m->data_type);
	if (m->interleave != KG_ENVI_BSQ && m->interleave != KG_ENVI_BIL &&
	    m->interleave != KG_ENVI_BIP)
		return kg_fail(err, KG_EINVAL, "ENVI header: interleave %d: expected bsq, bil or bip",
		               (int)m->interleave);
	if (!(m->scale >= 0) || !isfinite(m->scale))
		return kg_fail(err, KG_EINVAL, "ENVI header: scale factor %g: expected a positive number "
		               "or 0 for none", m->scale);
	int ret;
	if (m->description && (ret = check_text("description", 0, m->description, 0, err)))
		return ret;
	if (m->wavelength)
		for (int b = 0; b < m->bands; b++)
			if (!isfinite(m->wavelength[b]))
				return kg_fail(err, KG_EINVAL, "ENVI header: wavelength %d is %g: expected finite "
				               "numbers", b, m->wavelength[b]);
	if (m->band_names)
		for (int b = 0; b < m->bands; b++)
			if ((ret = check_text("band name", b, m->band_names[b], 1, err)))
				return ret;
	if (m->classes < 0)
		return kg_fail(err, KG_EINVAL, "ENVI header: %d classes: expected 0 or more", m->classes);
	if (m->classes > 0) {
		if (m->data_type == KG_ENVI_F32)
			return kg_fail(err, KG_EINVAL, "ENVI classification: data type float32: expected an "
			               "integer type (1, 2 or 12)");
		if (m->data_type == KG_ENVI_U8 && m->classes > 256)
			return kg_fail(err, KG_EINVAL, "ENVI classification: %d classes do not fit uint8: "
			               "expected at most 256", m->classes);
		if (m->scale != 0 && m->scale != 1)
			return kg_fail(err, KG_EINVAL, "ENVI classification: scale factor %g: expected none",
			               m->scale);
		if (!m->class_names)
			return kg_fail(err, KG_EINVAL, "ENVI classification: class names are missing");
		for (int c = 0; c < m->classes; c++)
			if ((ret = check_text("class name", c, m->class_names[c], 1, err)))
				return ret;
	}
	if (m->n_extra < 0 || (m->n_extra > 0 && !m->extra))
		return kg_fail(err, KG_EINVAL, "ENVI header: %d extra keys without a list", m->n_extra);
	for (int i = 0; i < m->n_extra; i++) {
		if ((ret = check_extra(&m->extra[i], err)))
			return ret;
		for (int j = 0; j < i; j++)
			if (strcmp(m->extra[i].key, m->extra[j].key) == 0)
				return kg_fail(err, KG_EINVAL, "ENVI header: extra key '%s' given twice: "
				               "expected each key once", m->extra[i].key);
	}

	size_t len;
	FILE *f = open_memstream(text, &len);
	if (!f)
		return kg_fail(err, KG_ENOMEM, "ENVI header: out of memory");
	fputs("ENVI\n", f);
	if (m->description)
		fprintf(f, "description = {%s}\n", m->description);
	fprintf(f, "samples = %d\nlines = %d\nbands = %d\nheader offset = 0\n", m->samples,
	        m->lines, m->bands);
	fprintf(f, "file type = %s\n", m->classes > 0 ? "ENVI Classification" : "ENVI Standard");
	fprintf(f, "data type = %d\ninterleave = %s\nbyte order = %d\n", (int)m->data_type,
	        interleave_name(m->interleave), HOST_BYTE_ORDER);
	if (m->scale > 0)
		fprintf(f, "reflectance scale factor = %.17g\n", m->scale);
	if (m->classes > 0) {
		fprintf(f, "classes = %d\n", m->classes);
		put_list_open(f, "class names");
		for (int c = 0; c < m->classes; c++) {
			put_list_sep(f, c);
			fputs(m->class_names[c], f);
		}
		fputs("}\n", f);
		if (m->class_lookup) {
			put_list_open(f, "class lookup");
			for (int c = 0; c < 3 * m->classes; c++) {
				put_list_sep(f, c);
				fprintf(f, "%d", m->class_lookup[c]);
			}
			fputs("}\n", f);
		}
	}
	if (m->wavelength) {
		fputs("wavelength units = Nanometers\n", f);
		put_list_open(f, "wavelength");
		put_numbers(f, m->wavelength, m->bands);
		fputs("}\n", f);
	}
	if (m->band_names) {
		put_list_open(f, "band names");
		for (int b = 0; b < m->bands; b++) {
			put_list_sep(f, b);
			fputs(m->band_names[b], f);
		}
		fputs("}\n", f);
	}
	for (int i = 0; i < m->n_extra; i++)
		fprintf(f, "%s = %s\n", m->extra[i].key, m->extra[i].value);
	if (fclose(f) != 0) {
		free(*text);
		*text = NULL;
		return kg_fail(err, KG_ENOMEM, "ENVI header: out of memory");
	}
	return 0;
}

/* ---- writer ---------------------------------------------------------------------- */

struct kg_envi_writer {
	int samples, lines, bands;
	enum kg_envi_type type;
	enum kg_envi_interleave interleave;
	float scale;
	size_t tsize;
	char *header, *hdr_path, *data_path;
	kg_atomicfile data; /* the data file under construction */
	int fd;          /* data.fd */
	unsigned char *done; /* one flag per line */
	float *fbuf;         /* a block in file order */
	void *bbuf;          /* the same block converted to the file's type */
	size_t cap;          /* elements available in fbuf and bbuf */
};

static void writer_free(kg_envi_writer *w)
{
	kg_atomicfile_abort(&w->data);
	free(w->header);
	free(w->hdr_path);
	free(w->data_path);
	free(w->done);
	free(w->fbuf);
	free(w->bbuf);
	free(w);
}

int kg_envi_writer_open(const char *path, const kg_envi_meta *meta, kg_envi_writer **out,
                        kg_err *err)
{
	kg_check_arg(path && meta && out, err);
	*out = NULL;
	kg_envi_writer *w = calloc(1, sizeof(*w));
	if (!w)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	w->fd = w->data.fd = w->data.slot = -1;
	int ret = render_header(meta, &w->header, err);
	if (ret) {
		kg_err_prefix(err, "%s", path);
		goto fail;
	}
	if ((ret = kg_envi_paths(path, &w->hdr_path, &w->data_path, err)) ||
	    (ret = kg_inputs_check_output(w->hdr_path, err)) ||
	    (ret = kg_inputs_check_output(w->data_path, err)))
		goto fail;
	w->samples = meta->samples;
	w->lines = meta->lines;
	w->bands = meta->bands;
	w->type = meta->data_type;
	w->interleave = meta->interleave;
	w->scale = meta->scale > 0 ? (float)meta->scale : 1.0f;
	w->tsize = type_size(meta->data_type);
	unsigned long long total = (unsigned long long)w->samples * (unsigned long long)w->lines;
	if (total > (1ull << 40) / (unsigned long long)w->bands) {
		ret = kg_fail(err, KG_EINVAL, "%s: %d x %d x %d: cube too large", path, w->samples,
		              w->lines, w->bands);
		goto fail;
	}
	total *= (unsigned long long)w->bands * w->tsize;
	w->done = calloc((size_t)w->lines, 1);
	if (!w->done) {
		ret = kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
		goto fail;
	}
	if ((ret = kg_atomicfile_open(&w->data, w->data_path, err)))
		goto fail;
	w->fd = w->data.fd;
	if (ftruncate(w->fd, (off_t)total) != 0) {
		ret = kg_fail(err, KG_EIO, "%s: cannot size the data file to %llu bytes: %s",
		              w->data_path, total, strerror(errno));
		goto fail;
	}
	*out = w;
	return 0;
fail:
	writer_free(w);
	return ret;
}

static int pwrite_all(int fd, const void *buf, size_t n, off_t off)
{
	const char *p = buf;
	while (n > 0) {
		ssize_t k = pwrite(fd, p, n, off);
		if (k < 0) {
			if (errno == EINTR)
				continue;
			return -1;
		}
		p += k;
		n -= (size_t)k;
		off += k;
	}
	return 0;
}

/* Element strides (row, x, band) of a block of `rows` lines in a file interleave. */
static void file_strides(enum kg_envi_interleave il, long rows, long w, long bands, long *sr,
                         long *sx, long *sb)
{
	switch (il) {
	case KG_ENVI_BSQ: *sr = w, *sx = 1, *sb = rows * w; break;
	case KG_ENVI_BIL: *sr = bands * w, *sx = 1, *sb = w; break;
	case KG_ENVI_BIP: *sr = w * bands, *sx = bands, *sb = 1; break;
	}
}

static void layout_strides(enum kg_envi_layout l, long rows, long w, long bands, long *sr,
                           long *sx, long *sb)
{
	if (l == KG_LAYOUT_BIP)
		*sr = w * bands, *sx = bands, *sb = 1;
	else
		*sr = w, *sx = 1, *sb = rows * w;
}

/* Copy a rows x w x bands block between two stride sets, scaling. The destination's
 * fastest dimension (x, or the band for BIP) has stride 1 and runs innermost; x is
 * taken in tiles so that a transpose between BIP and planar orders stays in L1. */
static void restride(float *dst, const long ds[3], const float *src, const long ss[3],
                     long rows, long w, long bands, enum kg_envi_interleave dst_order,
                     float scale)
{
	enum { XT = 64 };
	for (long r = 0; r < rows; r++) {
		float *d = dst + r * ds[0];
		const float *s = src + r * ss[0];
		for (long x0 = 0; x0 < w; x0 += XT) {
			long x1 = x0 + XT < w ? x0 + XT : w;
			if (dst_order == KG_ENVI_BIP) /* ds[2] == 1 */
				for (long x = x0; x < x1; x++)
					for (long b = 0; b < bands; b++)
						d[x * ds[1] + b] = s[x * ss[1] + b * ss[2]] * scale;
			else /* ds[1] == 1 */
				for (long b = 0; b < bands; b++)
					for (long x = x0; x < x1; x++)
						d[x + b * ds[2]] = s[x * ss[1] + b * ss[2]] * scale;
		}
	}
}

/* Round to nearest (halves away from zero) and clamp; NaN becomes 0. Written with
 * truncating conversions so it vectorises without SSE4.1's round instruction. */
static inline float round_clamp(float v, float lo, float hi)
{
	v = v != v ? 0.0f : v < lo ? lo : v > hi ? hi : v;
	return (float)(int32_t)(v + (v < 0 ? -0.5f : 0.5f));
}

static void to_type(void *dst, const float *src, size_t n, enum kg_envi_type t)
{
	switch (t) {
	case KG_ENVI_U8:
		for (size_t i = 0; i < n; i++)
			((uint8_t *)dst)[i] = (uint8_t)round_clamp(src[i], 0.0f, 255.0f);
		break;
	case KG_ENVI_I16:
		for (size_t i = 0; i < n; i++)
			((int16_t *)dst)[i] = (int16_t)round_clamp(src[i], -32768.0f, 32767.0f);
		break;
	case KG_ENVI_U16:
		for (size_t i = 0; i < n; i++)
			((uint16_t *)dst)[i] = (uint16_t)round_clamp(src[i], 0.0f, 65535.0f);
		break;
	case KG_ENVI_U32: /* from float: exact up to 2^24 */
		for (size_t i = 0; i < n; i++)
			((uint32_t *)dst)[i] = (uint32_t)round_clamp(src[i], 0.0f, 16777216.0f);
		break;
	default:
		break;
	}
}

/* Write lines y0 .. y0+rows-1 from src, already in file order and type. */
static int write_file_order(kg_envi_writer *w, long y0, long rows, const void *src)
{
	size_t line = (size_t)w->samples * w->tsize;
	if (w->interleave != KG_ENVI_BSQ)
		return pwrite_all(w->fd, src, (size_t)rows * line * (size_t)w->bands,
		                  (off_t)((size_t)y0 * line * (size_t)w->bands));
	size_t plane = (size_t)rows * line;
	for (long b = 0; b < w->bands; b++)
		if (pwrite_all(w->fd, (const char *)src + (size_t)b * plane, plane,
		               (off_t)(((size_t)b * (size_t)w->lines + (size_t)y0) * line)))
			return -1;
	return 0;
}

int kg_envi_writer_put(kg_envi_writer *w, int y0, int y1, enum kg_envi_layout layout,
                       const float *data, kg_err *err)
{
	kg_check_arg(w && data, err);
	if (y0 < 0 || y1 <= y0 || y1 > w->lines)
		return kg_fail(err, KG_EINVAL, "%s: lines %d to %d: expected 0 <= y0 < y1 <= %d",
		               w->data_path, y0, y1, w->lines);
	if (layout != KG_LAYOUT_BIP && layout != KG_LAYOUT_PLANAR)
		return kg_fail(err, KG_EINVAL, "%s: layout %d: expected BIP or planar", w->data_path,
		               (int)layout);
	long rows = y1 - y0, S = w->samples, B = w->bands;
	int bad;
	if (w->type == KG_ENVI_F32 && w->scale == 1.0f &&
	    ((layout == KG_LAYOUT_PLANAR && w->interleave == KG_ENVI_BSQ) ||
	     (layout == KG_LAYOUT_BIP && w->interleave == KG_ENVI_BIP))) {
		bad = write_file_order(w, y0, rows, data); /* already in file order */
	} else {
		/* Convert in bounded chunks of lines so a whole cube needs no second copy. */
		long chunk = (long)(CHUNK_BYTES / sizeof(float) / (size_t)(S * B));
		chunk = chunk < 1 ? 1 : chunk > rows ? rows : chunk;
		size_t need = (size_t)chunk * (size_t)(S * B);
		if (need > w->cap) {
			free(w->fbuf);
			free(w->bbuf);
			w->fbuf = malloc(need * sizeof(float));
			w->bbuf = w->type == KG_ENVI_F32 ? NULL : malloc(need * w->tsize);
			w->cap = w->fbuf && (w->bbuf || w->type == KG_ENVI_F32) ? need : 0;
			if (!w->cap)
				return kg_fail(err, KG_ENOMEM, "%s: out of memory for %ld lines", w->data_path,
				               chunk);
		}
		long ss[3], ds[3];
		layout_strides(layout, rows, S, B, &ss[0], &ss[1], &ss[2]);
		bad = 0;
		for (long r0 = 0; r0 < rows && !bad; r0 += chunk) {
			long n = rows - r0 < chunk ? rows - r0 : chunk;
			file_strides(w->interleave, n, S, B, &ds[0], &ds[1], &ds[2]);
			restride(w->fbuf, ds, data + r0 * ss[0], ss, n, S, B, w->interleave, w->scale);
			if (w->type != KG_ENVI_F32)
				to_type(w->bbuf, w->fbuf, (size_t)(n * S * B), w->type);
			bad = write_file_order(w, y0 + r0, n, w->type == KG_ENVI_F32 ? (void *)w->fbuf : w->bbuf);
		}
	}
	if (bad)
		return kg_fail(err, KG_EIO, "%s: write failed: %s", w->data_path, strerror(errno));
	memset(w->done + y0, 1, (size_t)rows);
	return 0;
}

void kg_envi_writer_abort(kg_envi_writer **w)
{
	if (w && *w) {
		writer_free(*w);
		*w = NULL;
	}
}

int kg_envi_writer_finish(kg_envi_writer **wp, kg_err *err)
{
	kg_check_arg(wp && *wp, err);
	kg_envi_writer *w = *wp;
	*wp = NULL;
	int ret = 0;
	for (int y = 0; y < w->lines; y++)
		if (!w->done[y]) {
			int e = y;
			while (e + 1 < w->lines && !w->done[e + 1])
				e++;
			ret = kg_fail(err, KG_EINVAL, "%s: lines %d to %d were never written", w->data_path,
			              y, e);
			goto out;
		}
	if (fsync(w->fd) != 0) {
		ret = kg_fail(err, KG_EIO, "%s: write failed: %s", w->data_path, strerror(errno));
		goto out;
	}
	kg_outfile hdr;
	if ((ret = kg_outfile_open(&hdr, w->hdr_path, 0, err)))
		goto out;
	if (fputs(w->header, hdr.fp) == EOF) {
		kg_outfile_abort(&hdr);
		ret = kg_fail(err, KG_EIO, "%s: write failed: %s", w->hdr_path, strerror(errno));
		goto out;
	}
	w->fd = -1; /* closed by the commit */
	if ((ret = kg_atomicfile_commit(&w->data, err))) {
		kg_outfile_abort(&hdr);
		goto out;
	}
	if ((ret = kg_outfile_commit(&hdr, err)))
		unlink(w->data_path);
out:
	writer_free(w);
	return ret;
}

int kg_envi_write(const char *path, const kg_envi_meta *meta, enum kg_envi_layout layout,
                  const float *data, kg_err *err)
{
	kg_envi_writer *w;
	int ret = kg_envi_writer_open(path, meta, &w, err);
	if (ret)
		return ret;
	if ((ret = kg_envi_writer_put(w, 0, meta->lines, layout, data, err))) {
		kg_envi_writer_abort(&w);
		return ret;
	}
	return kg_envi_writer_finish(&w, err);
}

int kg_envi_write_label_map(const char *path, int width, int height, const float *labels,
                            int nclasses, const char *const *class_names,
                            const char *description, kg_err *err)
{
	unsigned char *lookup = malloc((size_t)nclasses * 3);
	if (!lookup)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	memset(lookup, 0, 3);
	for (int k = 1; k < nclasses; k++) {
		double rgb[3];
		kg_series_colour(k - 1, rgb);
		for (int c = 0; c < 3; c++)
			lookup[3 * k + c] = (unsigned char)lrint(fmin(fmax(rgb[c], 0.0), 1.0) * 255.0);
	}
	kg_envi_meta meta = {
	    .samples = width,
	    .lines = height,
	    .bands = 1,
	    .data_type = KG_ENVI_U8,
	    .interleave = KG_ENVI_BSQ,
	    .description = description,
	    .classes = nclasses,
	    .class_names = class_names,
	    .class_lookup = lookup,
	};
	int ret = kg_envi_write(path, &meta, KG_LAYOUT_BIP, labels, err);
	free(lookup);
	return ret;
}

/* ---- header parsing ----------------------------------------------------------------- */

struct kg_envi_store {
	int n, cap;
	char **keys, **vals;
	char **strings; /* every other allocation owned by the cube */
	int nstrings, capstrings;
};

static int store_own(struct kg_envi_store *s, void *p)
{
	if (!p)
		return KG_ENOMEM;
	if (s->nstrings == s->capstrings) {
		int cap = s->capstrings ? 2 * s->capstrings : 16;
		char **ns = realloc(s->strings, (size_t)cap * sizeof(*ns));
		if (!ns) {
			free(p);
			return KG_ENOMEM;
		}
		s->strings = ns;
		s->capstrings = cap;
	}
	s->strings[s->nstrings++] = p;
	return 0;
}

static void store_free(struct kg_envi_store *s)
{
	if (!s)
		return;
	for (int i = 0; i < s->n; i++) {
		free(s->keys[i]);
		free(s->vals[i]);
	}
	for (int i = 0; i < s->nstrings; i++)
		free(s->strings[i]);
	free(s->keys);
	free(s->vals);
	free(s->strings);
	free(s);
}

/* Set key (already normalised) to val, replacing an earlier value. Takes both. */
static int store_set(struct kg_envi_store *s, char *key, char *val)
{
	if (!key || !val) {
		free(key);
		free(val);
		return KG_ENOMEM;
	}
	for (int i = 0; i < s->n; i++)
		if (strcmp(s->keys[i], key) == 0) {
			free(s->vals[i]);
			free(key);
			s->vals[i] = val;
			return 0;
		}
	if (s->n == s->cap) {
		int cap = s->cap ? 2 * s->cap : 32;
		char **nk = realloc(s->keys, (size_t)cap * sizeof(*nk));
		if (nk)
			s->keys = nk;
		char **nv = nk ? realloc(s->vals, (size_t)cap * sizeof(*nv)) : NULL;
		if (!nv) {
			free(key);
			free(val);
			return KG_ENOMEM;
		}
		s->vals = nv;
		s->cap = cap;
	}
	s->keys[s->n] = key;
	s->vals[s->n++] = val;
	return 0;
}

static const char *store_get(const struct kg_envi_store *s, const char *key)
{
	for (int i = 0; i < s->n; i++)
		if (strcmp(s->keys[i], key) == 0)
			return s->vals[i];
	return NULL;
}

static char *trim_dup(const char *a, const char *b)
{
	while (a < b && isspace((unsigned char)*a))
		a++;
	while (b > a && isspace((unsigned char)b[-1]))
		b--;
	return strndup(a, (size_t)(b - a));
}

/* Lower case with runs of white space made single spaces. */
static char *normalise_key(const char *a, const char *b)
{
	char *k = trim_dup(a, b);
	if (!k)
		return NULL;
	char *o = k;
	for (const char *p = k; *p; p++) {
		if (isspace((unsigned char)*p)) {
			if (o > k && o[-1] != ' ')
				*o++ = ' ';
		} else
			*o++ = (char)tolower((unsigned char)*p);
	}
	*o = '\0';
	return k;
}

static int parse_text(const char *hdr, const char *text, struct kg_envi_store *s, kg_err *err)
{
	const char *p = text;
	if (strncmp(p, "\xef\xbb\xbf", 3) == 0)
		p += 3;
	while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\n')
		p++;
	if (strncmp(p, "ENVI", 4) != 0)
		return kg_fail(err, KG_EINVAL, "%s: not an ENVI header: expected 'ENVI' on the first line",
		               hdr);
	p += strcspn(p, "\n");
	int line = 1;
	while (*p) {
		p++; /* past '\n' */
		line++;
		const char *eol = p + strcspn(p, "\n");
		const char *eq = memchr(p, '=', (size_t)(eol - p));
		const char *q = p;
		while (q < eol && isspace((unsigned char)*q))
			q++;
		if (!eq || *q == ';') {
			p = eol;
			continue;
		}
		char *key = normalise_key(p, eq);
		int key_line = line;
		const char *v = eq + 1;
		while (v < eol && isspace((unsigned char)*v))
			v++;
		char *val;
		if (v < eol && *v == '{') {
			const char *close = strchr(v, '}');
			if (!close) {
				int r = kg_fail(err, KG_EINVAL, "%s: line %d: key '%s': '{' is never closed", hdr,
				                line, key ? key : "");
				free(key);
				return r;
			}
			for (const char *c = eol; c < close; c = c + 1 + strcspn(c + 1, "\n"))
				line++;
			val = trim_dup(v + 1, close);
			eol = close + strcspn(close, "\n");
		} else {
			val = trim_dup(v, eol);
		}
		if (key && !*key) {
			free(key);
			free(val);
			return kg_fail(err, KG_EINVAL, "%s: line %d: expected 'key = value', found no key",
			               hdr, line);
		}
		const char *before = key ? store_get(s, key) : NULL;
		if (before) {
			int r = kg_fail(err, KG_EINVAL, "%s: line %d: key '%s' given twice (before as "
			                "'%.40s%s', now '%.40s%s'): expected each key once", hdr, key_line,
			                key, before, strlen(before) > 40 ? "..." : "", val ? val : "",
			                val && strlen(val) > 40 ? "..." : "");
			free(key);
			free(val);
			return r;
		}
		if (store_set(s, key, val))
			return kg_fail(err, KG_ENOMEM, "%s: out of memory", hdr);
		p = eol;
	}
	return 0;
}

/* Split a list value on commas into trimmed strings owned by the store; a trailing
 * empty element is dropped. */
static int split_list(struct kg_envi_store *s, const char *val, char ***items, int *n)
{
	*items = NULL;
	*n = 0;
	int cap = 1;
	for (const char *c = val; *c; c++)
		cap += *c == ',';
	char **it = malloc((size_t)cap * sizeof(*it));
	if (store_own(s, it))
		return KG_ENOMEM;
	int k = 0;
	const char *a = val;
	for (;;) {
		const char *b = a + strcspn(a, ",");
		char *item = trim_dup(a, b);
		if (store_own(s, item))
			return KG_ENOMEM;
		it[k++] = item;
		if (!*b)
			break;
		a = b + 1;
	}
	if (k > 0 && !*it[k - 1])
		k--;
	*items = it;
	*n = k;
	return 0;
}

static int parse_double(const char *s, double *out)
{
	char *end;
	errno = 0;
	double v = strtod(s, &end);
	while (isspace((unsigned char)*end))
		end++;
	if (end == s || *end || errno == ERANGE || !isfinite(v))
		return -1;
	*out = v;
	return 0;
}

static int get_long(const char *hdr, const struct kg_envi_store *s, const char *key,
                    long long min, long long max, long long dflt, int required, long long *out,
                    kg_err *err)
{
	const char *v = store_get(s, key);
	if (!v) {
		if (required)
			return kg_fail(err, KG_EINVAL, "%s: key '%s' is missing: expected an integer", hdr,
			               key);
		*out = dflt;
		return 0;
	}
	char *end;
	errno = 0;
	long long x = strtoll(v, &end, 10);
	while (isspace((unsigned char)*end))
		end++;
	if (end == v || *end || errno || x < min || x > max)
		return kg_fail(err, KG_EINVAL, "%s: key '%s': got '%s': expected an integer from %lld "
		               "to %lld", hdr, key, v, min, max);
	*out = x;
	return 0;
}

static int numbers_from(const char *hdr, const char *key, const char *val,
                        struct kg_envi_store *s, double **v, int *n, kg_err *err)
{
	char **items;
	int k;
	if (split_list(s, val, &items, &k))
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", hdr);
	double *d = malloc(((size_t)k + 1) * sizeof(double));
	if (!d)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", hdr);
	for (int i = 0; i < k; i++)
		if (parse_double(items[i], &d[i])) {
			free(d);
			return kg_fail(err, KG_EINVAL, "%s: key '%s': element %d '%s': expected a number",
			               hdr, key, i, items[i]);
		}
	*v = d;
	*n = k;
	return 0;
}

/* A list key that must have exactly n elements (strings owned by the store). */
static int get_names(const char *hdr, struct kg_envi_store *s, const char *key, int n,
                     const char *what, const char *const **out, kg_err *err)
{
	*out = NULL;
	const char *v = store_get(s, key);
	if (!v)
		return 0;
	char **items;
	int k;
	if (split_list(s, v, &items, &k))
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", hdr);
	if (k != n)
		return kg_fail(err, KG_EINVAL, "%s: key '%s': %d names: expected %d (%s)", hdr, key, k,
		               n, what);
	*out = (const char *const *)items;
	return 0;
}

static int interpret(const char *hdr, kg_envi *e, kg_err *err)
{
	struct kg_envi_store *s = e->store;
	kg_envi_meta *m = &e->meta;
	long long x;
	int ret;
	if ((ret = get_long(hdr, s, "samples", 1, INT_MAX, 0, 1, &x, err)))
		return ret;
	m->samples = (int)x;
	if ((ret = get_long(hdr, s, "lines", 1, INT_MAX, 0, 1, &x, err)))
		return ret;
	m->lines = (int)x;
	if ((ret = get_long(hdr, s, "bands", 1, INT_MAX, 0, 1, &x, err)))
		return ret;
	m->bands = (int)x;
	if ((ret = get_long(hdr, s, "data type", 1, 15, 0, 1, &x, err)))
		return ret;
	m->data_type = (enum kg_envi_type)x;
	if (type_size(m->data_type) == 0)
		return kg_fail(err, KG_ENOTSUP, "%s: key 'data type': %lld is not supported: expected "
		               "1, 2, 3, 4, 5, 12 or 13", hdr, x);
	if ((ret = get_long(hdr, s, "header offset", 0, LLONG_MAX / 2, 0, 0, &e->header_offset, err)))
		return ret;
	if ((ret = get_long(hdr, s, "byte order", 0, 1, HOST_BYTE_ORDER, 0, &x, err)))
		return ret;
	e->byte_order = (int)x;

	const char *v = store_get(s, "interleave");
	if (!v || strcasecmp(v, "bsq") == 0)
		m->interleave = KG_ENVI_BSQ;
	else if (strcasecmp(v, "bil") == 0)
		m->interleave = KG_ENVI_BIL;
	else if (strcasecmp(v, "bip") == 0)
		m->interleave = KG_ENVI_BIP;
	else
		return kg_fail(err, KG_EINVAL, "%s: key 'interleave': got '%s': expected bsq, bil or bip",
		               hdr, v);

	m->description = store_get(s, "description");
	if ((v = store_get(s, "reflectance scale factor"))) {
		if (parse_double(v, &m->scale) || !(m->scale > 0))
			return kg_fail(err, KG_EINVAL, "%s: key 'reflectance scale factor': got '%s': "
			               "expected a positive number", hdr, v);
	}

	e->wavelength_units = store_get(s, "wavelength units");
	if ((v = store_get(s, "wavelength"))) {
		double *wl;
		int n;
		if ((ret = numbers_from(hdr, "wavelength", v, s, &wl, &n, err)))
			return ret;
		if (store_own(s, wl))
			return kg_fail(err, KG_ENOMEM, "%s: out of memory", hdr);
		if (n != m->bands)
			return kg_fail(err, KG_EINVAL, "%s: key 'wavelength': %d values: expected %d (one "
			               "per band)", hdr, n, m->bands);
		const char *u = e->wavelength_units;
		if (u && (strcasecmp(u, "micrometers") == 0 || strcasecmp(u, "microns") == 0 ||
		          strcasecmp(u, "um") == 0 || strcmp(u, "\xc2\xb5m") == 0))
			for (int b = 0; b < n; b++)
				wl[b] *= 1000.0;
		m->wavelength = wl;
	}
	if ((ret = get_names(hdr, s, "band names", m->bands, "one per band", &m->band_names, err)))
		return ret;

	v = store_get(s, "file type");
	if (v && strcasecmp(v, "ENVI Classification") == 0) {
		if ((ret = get_long(hdr, s, "classes", 1, 1 << 20, 0, 1, &x, err)))
			return ret;
		m->classes = (int)x;
		if ((ret = get_names(hdr, s, "class names", m->classes, "one per class",
		                     &m->class_names, err)))
			return ret;
		if ((v = store_get(s, "class lookup"))) {
			double *d;
			int n;
			if ((ret = numbers_from(hdr, "class lookup", v, s, &d, &n, err)))
				return ret;
			unsigned char *lut = malloc((size_t)n + 1);
			int bad = !lut || n != 3 * m->classes;
			for (int i = 0; i < n && !bad; i++) {
				bad = !(d[i] >= 0 && d[i] <= 255 && d[i] == floor(d[i]));
				if (!bad)
					lut[i] = (unsigned char)d[i];
			}
			free(d);
			if (store_own(s, lut))
				return kg_fail(err, KG_ENOMEM, "%s: out of memory", hdr);
			if (bad)
				return kg_fail(err, KG_EINVAL, "%s: key 'class lookup': expected %d integers "
				               "from 0 to 255 (RGB per class), got '%s'", hdr, 3 * m->classes, v);
			m->class_lookup = lut;
		}
	}

	int n_extra = 0;
	for (int i = 0; i < s->n; i++)
		n_extra += !is_known_key(s->keys[i]);
	kg_envi_pair *extra = calloc((size_t)n_extra + 1, sizeof(*extra));
	if (store_own(s, extra))
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", hdr);
	for (int i = 0, k = 0; i < s->n; i++)
		if (!is_known_key(s->keys[i]))
			extra[k++] = (kg_envi_pair){s->keys[i], s->vals[i]};
	m->extra = extra;
	m->n_extra = n_extra;
	return 0;
}

/* ---- reader --------------------------------------------------------------------------- */

static int is_file(const char *p)
{
	struct stat st;
	return stat(p, &st) == 0 && S_ISREG(st.st_mode);
}

/* The data file beside a header, tried in Spectral Python's order. */
static char *find_data(const char *hdr, enum kg_envi_interleave il)
{
	size_t stem = strlen(hdr) - 4;
	const char *exts[] = {"", ".img", ".dat", ".sli", ".hyspex", ".raw", NULL,
	                      ".IMG", ".DAT", ".SLI", ".HYSPEX", ".RAW", NULL};
	const char *lower[] = {".bsq", ".bil", ".bip"}, *upper[] = {".BSQ", ".BIL", ".BIP"};
	exts[6] = lower[il];
	exts[12] = upper[il];
	for (size_t i = 0; i < sizeof(exts) / sizeof(exts[0]); i++) {
		char *p = concat(hdr, stem, exts[i]);
		if (!p || is_file(p))
			return p;
		free(p);
	}
	return NULL;
}

void kg_envi_close(kg_envi **ep)
{
	if (!ep || !*ep)
		return;
	kg_envi *e = *ep;
	if (e->fd >= 0)
		close(e->fd);
	store_free(e->store);
	free(e->hdr_path);
	free(e->data_path);
	free(e);
	*ep = NULL;
}

int kg_envi_open(const char *path, kg_envi **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	kg_envi *e = calloc(1, sizeof(*e));
	int ret = 0;
	if (!e || !(e->store = calloc(1, sizeof(*e->store)))) {
		free(e);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	}
	e->fd = -1;
	size_t n = strlen(path);
	if (has_suffix_ci(path, ".hdr")) {
		e->hdr_path = strdup(path);
	} else {
		e->data_path = strdup(path);
		e->hdr_path = concat(path, n, ".hdr");
		const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
		if (e->hdr_path && !is_file(e->hdr_path) && dot && (!slash || dot > slash)) {
			char *alt = concat(path, (size_t)(dot - path), ".hdr");
			if (alt && is_file(alt)) {
				free(e->hdr_path);
				e->hdr_path = alt;
			} else
				free(alt);
		}
	}
	if (!e->hdr_path || (!has_suffix_ci(path, ".hdr") && !e->data_path)) {
		ret = kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
		goto fail;
	}
	char *text;
	if ((ret = kg_read_file(e->hdr_path, &text, NULL, err)))
		goto fail;
	ret = parse_text(e->hdr_path, text, e->store, err);
	free(text);
	if (ret || (ret = interpret(e->hdr_path, e, err)))
		goto fail;
	if (!e->data_path && !(e->data_path = find_data(e->hdr_path, e->meta.interleave))) {
		ret = kg_fail(err, KG_ENOENT, "%s: no data file found beside the header (tried the "
		              "same name without .hdr and with .img, .dat, .raw, .%s)", e->hdr_path,
		              interleave_name(e->meta.interleave));
		goto fail;
	}
	e->fd = open(e->data_path, O_RDONLY | O_CLOEXEC);
	struct stat st;
	if (e->fd < 0 || fstat(e->fd, &st) != 0) {
		ret = kg_fail(err, errno == ENOENT ? KG_ENOENT : KG_EIO, "%s: cannot open: %s",
		              e->data_path, strerror(errno));
		goto fail;
	}
	kg_inputs_add(e->data_path, e->fd);
	kg_envi_meta *m = &e->meta;
	size_t ts = type_size(m->data_type);
	unsigned long long px = (unsigned long long)m->samples * (unsigned long long)m->lines;
	if (px > (1ull << 50) / (unsigned long long)m->bands / ts) {
		ret = kg_fail(err, KG_EINVAL, "%s: %d x %d x %d: expected a cube under 2^50 bytes",
		              e->hdr_path, m->samples, m->lines, m->bands);
		goto fail;
	}
	unsigned long long need = (unsigned long long)e->header_offset + px * m->bands * ts;
	if ((unsigned long long)st.st_size != need) {
		ret = kg_fail(err, KG_EINVAL, "%s: file is %lld bytes (%s): expected %llu for %d "
		              "samples x %d lines x %d bands of %zu-byte data after a %lld-byte header "
		              "offset, as %s says",
		              e->data_path, (long long)st.st_size,
		              (unsigned long long)st.st_size < need ? "too short" : "too long",
		              need, m->samples, m->lines, m->bands, ts, e->header_offset, e->hdr_path);
		goto fail;
	}
	*out = e;
	return 0;
fail:
	kg_envi_close(&e);
	return ret;
}

static int pread_all(int fd, void *buf, size_t n, off_t off)
{
	char *p = buf;
	while (n > 0) {
		ssize_t k = pread(fd, p, n, off);
		if (k < 0 && errno == EINTR)
			continue;
		if (k <= 0) {
			if (k == 0)
				errno = ENODATA;
			return -1;
		}
		p += k;
		n -= (size_t)k;
		off += k;
	}
	return 0;
}

static void swap_bytes(unsigned char *p, size_t n, size_t ts)
{
	for (size_t i = 0; i < n; i++, p += ts)
		for (size_t a = 0, b = ts - 1; a < b; a++, b--) {
			unsigned char t = p[a];
			p[a] = p[b];
			p[b] = t;
		}
}

static void from_type(float *dst, const void *src, size_t n, enum kg_envi_type t, float inv)
{
#define CONVERT(T)                                                                         \
	do {                                                                                   \
		const T *s_ = src;                                                                 \
		for (size_t i = 0; i < n; i++)                                                     \
			dst[i] = (float)s_[i] * inv;                                                   \
	} while (0)
	switch (t) {
	case KG_ENVI_U8: CONVERT(uint8_t); break;
	case KG_ENVI_I16: CONVERT(int16_t); break;
	case KG_ENVI_I32: CONVERT(int32_t); break;
	case KG_ENVI_F32: CONVERT(float); break;
	case KG_ENVI_F64: CONVERT(double); break;
	case KG_ENVI_U16: CONVERT(uint16_t); break;
	case KG_ENVI_U32: CONVERT(uint32_t); break;
	}
#undef CONVERT
}

/* Byte offset of (band b, line y, sample x) in the data file. */
static off_t file_offset(const kg_envi *e, long long b, long long y, long long x)
{
	const kg_envi_meta *m = &e->meta;
	long long S = m->samples, L = m->lines, B = m->bands, i;
	switch (m->interleave) {
	case KG_ENVI_BSQ: i = (b * L + y) * S + x; break;
	case KG_ENVI_BIL: i = (y * B + b) * S + x; break;
	default: i = (y * S + x) * B + b; break;
	}
	return (off_t)(e->header_offset + i * (long long)type_size(m->data_type));
}

int kg_envi_read(const kg_envi *e, int x0, int y0, int w, int h, enum kg_envi_layout layout,
                 float *out, kg_err *err)
{
	kg_check_arg(e && out, err);
	const kg_envi_meta *m = &e->meta;
	if (x0 < 0 || y0 < 0 || w < 1 || h < 1 || x0 > m->samples - w || y0 > m->lines - h)
		return kg_fail(err, KG_EINVAL, "%s: window %dx%d at (%d, %d): expected inside %d x %d",
		               e->data_path, w, h, x0, y0, m->samples, m->lines);
	if (layout != KG_LAYOUT_BIP && layout != KG_LAYOUT_PLANAR)
		return kg_fail(err, KG_EINVAL, "%s: layout %d: expected BIP or planar", e->data_path,
		               (int)layout);
	size_t ts = type_size(m->data_type);
	long B = m->bands, row_elems = (long)w * B;
	long chunk = (long)(CHUNK_BYTES / ((size_t)row_elems * ts));
	chunk = chunk < 1 ? 1 : chunk > h ? h : chunk;
	size_t cap = (size_t)chunk * (size_t)row_elems;
	unsigned char *raw = malloc(cap * ts);
	float *f = malloc(cap * sizeof(float));
	if (!raw || !f) {
		free(raw);
		free(f);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", e->data_path);
	}
	int full = w == m->samples, bad = 0;
	float inv = m->scale > 0 ? (float)(1.0 / m->scale) : 1.0f;
	long os[3];
	layout_strides(layout, h, w, B, &os[0], &os[1], &os[2]);
	for (long r0 = 0; r0 < h && !bad; r0 += chunk) {
		long rows = h - r0 < chunk ? h - r0 : chunk, y = y0 + r0;
		size_t run = (size_t)w * ts;
		/* Read the chunk in file order restricted to the window. */
		switch (m->interleave) {
		case KG_ENVI_BSQ:
			for (long b = 0; b < B && !bad; b++) {
				unsigned char *dst = raw + (size_t)b * rows * run;
				if (full)
					bad = pread_all(e->fd, dst, rows * run, file_offset(e, b, y, 0));
				else
					for (long r = 0; r < rows && !bad; r++)
						bad = pread_all(e->fd, dst + r * run, run, file_offset(e, b, y + r, x0));
			}
			break;
		case KG_ENVI_BIL:
			if (full)
				bad = pread_all(e->fd, raw, rows * B * run, file_offset(e, 0, y, 0));
			else
				for (long r = 0; r < rows && !bad; r++)
					for (long b = 0; b < B && !bad; b++)
						bad = pread_all(e->fd, raw + (r * B + b) * run, run,
						                file_offset(e, b, y + r, x0));
			break;
		case KG_ENVI_BIP:
			if (full)
				bad = pread_all(e->fd, raw, rows * B * run, file_offset(e, 0, y, 0));
			else
				for (long r = 0; r < rows && !bad; r++)
					bad = pread_all(e->fd, raw + r * B * run, B * run, file_offset(e, 0, y + r, x0));
			break;
		}
		if (bad)
			break;
		size_t count = (size_t)rows * (size_t)row_elems;
		if (ts > 1 && e->byte_order != HOST_BYTE_ORDER)
			swap_bytes(raw, count, ts);
		from_type(f, raw, count, m->data_type, inv);
		long fs[3];
		file_strides(m->interleave, rows, w, B, &fs[0], &fs[1], &fs[2]);
		restride(out + r0 * os[0], os, f, fs, rows, w, B,
		         layout == KG_LAYOUT_BIP ? KG_ENVI_BIP : KG_ENVI_BSQ, 1.0f);
	}
	int e_no = errno;
	free(raw);
	free(f);
	if (bad)
		return kg_fail(err, KG_EIO, "%s: read failed: %s", e->data_path,
		               e_no == ENODATA ? "file is shorter than its header says" : strerror(e_no));
	return 0;
}

const char *kg_envi_get(const kg_envi *e, const char *key)
{
	return e && key ? store_get(e->store, key) : NULL;
}

int kg_envi_get_numbers(const kg_envi *e, const char *key, double **v, int *n, kg_err *err)
{
	kg_check_arg(e && key && v && n, err);
	*v = NULL;
	*n = 0;
	const char *val = store_get(e->store, key);
	if (!val)
		return kg_fail(err, KG_EINVAL, "%s: key '%s' is missing", e->hdr_path, key);
	return numbers_from(e->hdr_path, key, val, e->store, v, n, err);
}

void kg_envi_remove_output(const char *path, int envi)
{
	char *hdr = NULL, *data = NULL;
	if (envi && kg_envi_paths(path, &hdr, &data, NULL) == 0) {
		unlink(hdr);
		unlink(data);
	} else {
		unlink(path);
	}
	free(hdr);
	free(data);
}
