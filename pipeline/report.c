/* The operator's report: OUTDIR/report.html from OUTDIR/process.json and the files
 * it names (kg_pipeline.h, docs/report.md).
 *
 * process.json is read through a small set of getters that remember the first
 * missing or mistyped required key; the page is written to a temporary file that is
 * renamed into place only when no key was missing, so a bad record leaves no report
 * rather than a misleading one. */
#include <ctype.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "report_private.h"

typedef struct report {
	const char *outdir;
	const char *stage; /* a run's staging folder, looked in first; NULL: none */
	char *file;   /* OUTDIR/process.json, named in messages */
	json_t *root;
	FILE *fp;
	kg_err *err;
	int ret;      /* first error met, 0 if none */

	/* Colour accuracy of the chart, from the per-patch values. */
	kg_de_summary d50, d65;
	int graded;   /* d50 holds at least one value */
	kg_de_summary held;  /* held-out ΔE00 D50 (leave-one-out); n 0: none */
	const kg_de_summary *g; /* what the verdicts grade: held when it has values */
	const char *basis;      /* "held-out" or "in-sample" */
	const char *held_how;   /* "leave-one-out" or "verification capture" */
	int accepted, forced;
	long warnings;
} report;

/* ---- process.json --------------------------------------------------------------- */

static int failed(report *r, int code, const char *fmt, ...) KG_PRINTF(3, 4);
static int failed(report *r, int code, const char *fmt, ...)
{
	if (r->ret)
		return r->ret;
	char msg[sizeof(r->err->msg)];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	r->ret = kg_fail(r->err, code, "%s", msg);
	return r->ret;
}

/* The value at a key path (printf-style), required to exist; NULL (and r->ret set)
 * when it does not. */
static json_t *vget(report *r, const char *fmt, va_list ap, char *path, size_t size)
{
	vsnprintf(path, size, fmt, ap);
	if (r->ret)
		return NULL;
	json_t *v = NULL;
	kg_err e;
	int ret = kg_json_get(r->file, r->root, path, &v, &e);
	if (ret) {
		failed(r, ret, "%s", e.msg);
		return NULL;
	}
	return v;
}

/* Whether a key path exists (keys process.json gained later: older records lack them). */
static int has(report *r, const char *fmt, ...) KG_PRINTF(2, 3);
static int has(report *r, const char *fmt, ...)
{
	char path[256];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(path, sizeof(path), fmt, ap);
	va_end(ap);
	return kg_json_find(r->root, path) != NULL;
}

/* What a getter accepts (typed): one kind, and null too with JK_NULLABLE. */
enum { JK_STRING, JK_NUMBER, JK_BOOL, JK_ARRAY, JK_NULLABLE = 0x10 };

/* The value at a key path (printf-style), required to exist and to be of kind; NULL
 * when it is missing or of another kind (r->ret set) or an allowed null. */
static json_t *typed(report *r, int kind, const char *fmt, ...) KG_PRINTF(3, 4);
static json_t *typed(report *r, int kind, const char *fmt, ...)
{
	static const char *const expected[] = {"a string", "a number", "true or false",
	                                       "an array"};
	char path[256];
	va_list ap;
	va_start(ap, fmt);
	json_t *v = vget(r, fmt, ap, path, sizeof(path));
	va_end(ap);
	int nullable = (kind & JK_NULLABLE) != 0;
	kind &= ~JK_NULLABLE;
	if (!v || (nullable && json_is_null(v)))
		return NULL;
	int ok = kind == JK_STRING   ? json_is_string(v)
	         : kind == JK_NUMBER ? json_is_number(v)
	         : kind == JK_BOOL   ? json_is_boolean(v)
	                             : json_is_array(v);
	if (!ok) {
		failed(r, KG_EINVAL, "%s: key '%s': expected %s%s", r->file, path, expected[kind],
		       nullable ? " or null" : "");
		return NULL;
	}
	return v;
}

static const char *string_or_empty(const json_t *v)
{
	return v ? json_string_value(v) : "";
}

static double number_or_nan(const json_t *v)
{
	return v ? json_number_value(v) : NAN;
}

static int is_true(const json_t *v)
{
	return json_is_true(v);
}

static json_t *array_size(json_t *v, int *n)
{
	*n = v ? (int)json_array_size(v) : 0;
	return v;
}

/* The getters, each (r, fmt, ...): a string ("" when missing), a string or null
 * (NULL), a number (NaN when missing), a number or null (NaN), a boolean, and an
 * array (NULL when missing; its size in *n, 0 when missing). */
#define str(r, ...) string_or_empty(typed((r), JK_STRING, __VA_ARGS__))
#define opt_str(r, ...) json_string_value(typed((r), JK_STRING | JK_NULLABLE, __VA_ARGS__))
#define num(r, ...) number_or_nan(typed((r), JK_NUMBER, __VA_ARGS__))
#define opt_num(r, ...) number_or_nan(typed((r), JK_NUMBER | JK_NULLABLE, __VA_ARGS__))
#define flag(r, ...) is_true(typed((r), JK_BOOL, __VA_ARGS__))
#define arr(r, n, ...) array_size(typed((r), JK_ARRAY, __VA_ARGS__), (n))

/* A spectrum on the 61-band grid into out, or null (returns NULL). */
static const double *spectrum(report *r, double out[KG_NBANDS], const char *fmt, ...)
	KG_PRINTF(3, 4);
static const double *spectrum(report *r, double out[KG_NBANDS], const char *fmt, ...)
{
	char path[256];
	va_list ap;
	va_start(ap, fmt);
	json_t *v = vget(r, fmt, ap, path, sizeof(path));
	va_end(ap);
	if (!v || json_is_null(v))
		return NULL;
	if (!json_is_array(v) || json_array_size(v) != KG_NBANDS) {
		failed(r, KG_EINVAL, "%s: key '%s': expected null or an array of %d reflectances "
		       "(400-700 nm every 5 nm)", r->file, path, KG_NBANDS);
		return NULL;
	}
	for (int b = 0; b < KG_NBANDS; b++) {
		json_t *x = json_array_get(v, b);
		if (!json_is_number(x)) {
			failed(r, KG_EINVAL, "%s: key '%s[%d]': expected a number", r->file, path, b);
			return NULL;
		}
		out[b] = json_number_value(x);
	}
	return out;
}

/* ---- HTML pieces ------------------------------------------------------------------ */

#define text(r, s) kg_html_put((r)->fp, (s))
#define textf(r, ...) kg_html_putf((r)->fp, __VA_ARGS__)

static void html(report *r, const char *fmt, ...) KG_PRINTF(2, 3);
static void html(report *r, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	vfprintf(r->fp, fmt, ap);
	va_end(ap);
}

/* A number with `digits` decimals, or an em dash for a missing value. */
static void put_num(report *r, double v, int digits)
{
	if (isfinite(v))
		html(r, "%.*f", digits, v);
	else
		html(r, "&mdash;");
}

static void put_verdict(report *r, int pass, const char *yes, const char *no)
{
	html(r, "<span class=\"%s\">%s</span>", pass ? "pass" : "fail", pass ? yes : no);
}

/* Any JSON value as text: devices and parameters carry keys the report does not know. */
static void put_json(report *r, const json_t *v)
{
	if (json_is_string(v)) {
		text(r, json_string_value(v));
	} else if (json_is_integer(v)) {
		html(r, "%" JSON_INTEGER_FORMAT, json_integer_value(v));
	} else if (json_is_real(v)) {
		html(r, "%.6g", json_real_value(v));
	} else if (json_is_true(v) || json_is_false(v)) {
		html(r, "%s", json_is_true(v) ? "true" : "false");
	} else if (json_is_array(v)) {
		size_t i;
		json_t *x;
		if (json_array_size(v) == 0)
			html(r, "(empty list)");
		json_array_foreach(v, i, x) {
			if (i)
				html(r, ", ");
			put_json(r, x);
		}
	} else if (json_is_object(v)) {
		const char *k;
		json_t *x;
		int first = 1;
		json_object_foreach((json_t *)v, k, x) {
			html(r, "%s", first ? "" : "; ");
			text(r, k);
			html(r, ": ");
			put_json(r, x);
			first = 0;
		}
	} else {
		html(r, "<span class=\"none\">none</span>");
	}
}

/* A row of a two-column key/value table; the value is escaped text or "none". */
static void row(report *r, const char *key, const char *value)
{
	html(r, "<tr><th scope=\"row\">");
	text(r, key);
	html(r, "</th><td>");
	if (value)
		text(r, value);
	else
		html(r, "<span class=\"none\">none</span>");
	html(r, "</td></tr>\n");
}

/* A number with `digits` decimals (an em dash when missing) and its unit (may be ""). */
static void num_row(report *r, const char *key, double v, int digits, const char *unit)
{
	html(r, "<tr><th scope=\"row\">");
	text(r, key);
	html(r, "</th><td>");
	put_num(r, v, digits);
	html(r, "%s</td></tr>\n", unit);
}

static void rowf(report *r, const char *key, const char *fmt, ...) KG_PRINTF(3, 4);
static void rowf(report *r, const char *key, const char *fmt, ...)
{
	char *buf = NULL;
	va_list ap;
	va_start(ap, fmt);
	int n = vasprintf(&buf, fmt, ap);
	va_end(ap);
	row(r, key, n >= 0 ? buf : "(out of memory)");
	free(buf);
}

/* A record (--meta) at process.json's key "where" as a table, known keys first; 0 when
 * there is none (absent or empty). */
static int put_record(report *r, const char *where, const char *caption)
{
	const json_t *meta = kg_json_find(r->root, where);
	if (!meta || r->ret)
		return 0;
	if (kg_meta_validate(r->file, where, meta, r->err)) {
		r->ret = KG_EINVAL;
		return 0;
	}
	if (!json_object_size(meta))
		return 0;
	html(r, "<table class=\"record\">");
	if (caption) {
		html(r, "<caption>");
		text(r, caption);
		html(r, "</caption>");
	}
	html(r, "\n");
	const char *keys[KG_META_MAX_KEYS];
	int n = kg_meta_ordered_keys(meta, keys, KG_META_MAX_KEYS);
	for (int i = 0; i < n; i++)
		row(r, keys[i], json_string_value(json_object_get(meta, keys[i])));
	html(r, "</table>\n");
	return 1;
}

/* A path process.json names is read only inside OUTDIR: relative, no "..", no
 * absolute path, no symbolic link on the way (kg_read_below); anything else would let
 * a process.json put any file of the machine into the page. */
#define REPORT_REL_MAX 256

/* The folder a file process.json names is read from: a run's staging folder where it
 * holds that file, else OUTDIR. */
static const char *file_base(report *r, const char *rel)
{
	struct stat st;
	if (r->stage && kg_stat_below(r->stage, rel, &st, NULL) == 0)
		return r->stage;
	return r->outdir;
}

/* A PNG of OUTDIR (path relative to it) inlined, or a sentence saying why it is not
 * there: missing, unreadable, or refused as a path outside OUTDIR (a warning). */
static void put_image_file(report *r, const char *rel, const char *alt, const char *cls)
{
	if (!kg_relpath_is_safe(rel, REPORT_REL_MAX)) {
		html(r, "<p class=\"missing\"><span class=\"fail\">warning</span> ");
		textf(r, "%s: not shown: %s names '%s', expected a path inside %s (relative, no "
		      "'..', no absolute path)", alt, r->file, rel, r->outdir);
		html(r, "</p>");
		return;
	}
	char *data = NULL;
	size_t len = 0;
	kg_err e = {{0}};
	int ret = kg_read_below(file_base(r, rel), rel, &data, &len, &e);
	if (!ret)
		ret = report_put_png(r->fp, (unsigned char *)data, len, alt, cls, rel, &e);
	if (ret) { /* a symbolic link on the way, or not a regular file: a warning */
		html(r, "<p class=\"missing\">%s",
		     ret == KG_EINVAL ? "<span class=\"fail\">warning</span> " : "");
		textf(r, "%s: not shown: %s", alt, ret == KG_ENOENT ? "the file is missing" : e.msg);
		html(r, " (");
		text(r, rel);
		html(r, ")</p>");
	}
	free(data);
}

/* A link to a file of OUTDIR (path relative to it, percent-encoded), said to be missing
 * or refused (outside OUTDIR) when it is. */
static void put_link(report *r, const char *rel)
{
	if (!kg_relpath_is_safe(rel, REPORT_REL_MAX)) {
		html(r, "<code>");
		text(r, rel);
		html(r, "</code> <span class=\"fail\">not inside the output folder: not read</span>");
		return;
	}
	html(r, "<a href=\"");
	for (const unsigned char *c = (const unsigned char *)rel; *c; c++)
		if (isalnum(*c) || strchr("-._~/", *c))
			html(r, "%c", *c);
		else
			html(r, "%%%02X", *c);
	html(r, "\"><code>");
	text(r, rel);
	html(r, "</code></a>");
	struct stat st;
	if (kg_stat_below(file_base(r, rel), rel, &st, NULL) != 0)
		html(r, " <span class=\"fail\">missing</span>");
}

/* An object's key, or NULL when absent (optional sections: camera-space labels, the
 * linear master, the highlights). */
static json_t *object_key(report *r, int i, const char *key)
{
	return json_object_get(json_array_get(json_object_get(r->root, "objects"), (size_t)i), key);
}

static double jnum(const json_t *o, const char *key)
{
	const json_t *v = json_object_get(o, key);
	return json_is_number(v) ? json_number_value(v) : NAN;
}

/* The object's master (objects[i].master): a link, its colour space and illuminant. */
static void put_master(report *r, int i)
{
	char key[64];
	snprintf(key, sizeof(key), "objects[%d].master", i);
	const json_t *m = kg_json_find(r->root, key);
	if (!m) /* written before masters existed */
		return;
	const char *rel = json_is_object(m) ? opt_str(r, "objects[%d].master.path", i) : NULL;
	if (!rel) {
		html(r, ", no master (see the warnings)");
		return;
	}
	html(r, ", master ");
	put_link(r, rel);
	html(r, " (16-bit RGB in ");
	text(r, str(r, "objects[%d].master.profile", i));
	html(r, ", its ICC profile embedded; rendered under ");
	text(r, str(r, "objects[%d].master.illuminant", i));
	html(r, ", ");
	text(r, str(r, "objects[%d].master.intent", i));
	double clipped = opt_num(r, "objects[%d].master.clipped_pixels", i);
	if (isfinite(clipped) && clipped > 0) {
		const char *counted = opt_str(r, "objects[%d].master.clipped_counted", i);
		textf(r, "; %.0f %s clipped: outside the space or brighter than its white", clipped,
		      counted && !strcmp(counted, "lit pixels") ? "lit pixels" : "pixels");
	}
	html(r, ")");
	/* the linear float master beside it (absent in files of earlier versions) */
	json_t *lin = object_key(r, i, "master_linear");
	const char *lrel = json_string_value(json_object_get(lin, "path"));
	if (lrel) {
		html(r, ", linear master ");
		put_link(r, lrel);
		html(r, " (32-bit float, the same primaries and white, linear, the diffuse white at "
		        "1.0, unclipped)");
	}
}

/* The highlights above the diffuse white (objects[i].highlights, absent in files of
 * earlier versions): their share of the lit pixels, and where they are. */
static void put_highlights(report *r, int i)
{
	json_t *h = object_key(r, i, "highlights");
	if (!json_is_object(h))
		return;
	double n = jnum(h, "counted"), above = jnum(h, "above_white");
	double fa = jnum(h, "above_white_fraction"), fc = jnum(h, "clipped_in_master_fraction");
	double fb = jnum(h, "band_above_one_fraction"), outside = jnum(h, "outside_primaries");
	const char *what = json_string_value(json_object_get(h, "counted_what"));
	const char *map = json_string_value(json_object_get(h, "map"));
	const char *ill = opt_str(r, "objects[%d].master.illuminant", i);
	what = what ? what : "lit pixels";
	html(r, "<h4>Highlights above the diffuse white</h4>\n<p>");
	if (!(above > 0)) {
		textf(r, "None: no %s brighter than the diffuse white (the perfect diffuser under "
		      "%s; Y up to %.2f, a band's reflectance up to %.2f).", what, ill ? ill : "",
		      jnum(h, "max_y"), jnum(h, "max_reflectance"));
	} else {
		textf(r, "%.1f %% of the %s (%.0f of %.0f) are brighter than the diffuse white (the "
		      "perfect diffuser under %s), Y up to %.2f: specular reflection (polished "
		      "metal, glaze) or more light on the object than on the chart, not a colour "
		      "error. master.tif holds them at full scale (with bright saturated colours, "
		      "%.1f %% of the %s are at full scale in a channel there); master_linear.tif "
		      "keeps their values.", 100 * fa, what, above, n, ill ? ill : "",
		      jnum(h, "max_y"), 100 * fc, what);
	}
	textf(r, " A band's reflectance estimate is above 1 in %.1f %% of the %s (up to %.2f).",
	      100 * fb, what, jnum(h, "max_reflectance"));
	html(r, "</p>\n");
	if (map) {
		html(r, "<figure>");
		put_image_file(r, map, "highlight map", "photo");
		html(r, "<figcaption>");
		textf(r, "Highlight map: red, the %s above the diffuse white (%.1f %%), at full "
		      "scale in master.tif; orange, the %.0f at full scale in a channel though no "
		      "brighter than the diffuse white; blue, the %.0f outside the master's "
		      "primaries, clipped; grey, the master's Y (0..1) elsewhere. Cropped to the "
		      "lit part of the image; a map pixel is a block of the image when the image is "
		      "larger than 800 pixels a side, coloured when any of its pixels is.", what,
		      100 * fa, jnum(h, "clipped_not_above_white"), outside);
		html(r, "</figcaption></figure>\n");
	}
}

/* The files of an object capture the page does not show (cube, label map, scene, the
 * master): named, and said to be missing when they are. */
static void put_file_list(report *r, int i)
{
	static const struct {
		const char *key, *label;
	} files[] = {
		{"cube", "reflectance cube"},
		{"labels", "label map"},
		{"scene", "render scene"},
	};
	html(r, "<p>Files:");
	for (size_t k = 0; k < sizeof(files) / sizeof(files[0]); k++) {
		const char *rel = opt_str(r, "objects[%d].%s", i, files[k].key);
		if (!rel || !rel[0]) { /* not written (--cube none) */
			html(r, "%s no %s", k ? "," : "", files[k].label);
			continue;
		}
		struct stat st;
		int inside = kg_relpath_is_safe(rel, REPORT_REL_MAX);
		html(r, "%s %s <code>", k ? "," : "", files[k].label);
		text(r, rel);
		html(r, "</code>%s",
		     !inside ? " <span class=\"fail\">not inside the output folder: not read</span>"
		     : kg_stat_below(file_base(r, rel), rel, &st, NULL) == 0
		             ? "" : " <span class=\"fail\">missing</span>");
	}
	put_master(r, i);
	html(r, ".</p>\n");
}

static void put_figure(report *r, const report_panel *panels, int n, int cols,
                       const char *title, const char *solid, const char *dashed,
                       const char *caption)
{
	unsigned char *png = NULL;
	size_t len = 0;
	kg_err e = {{0}};
	html(r, "<figure>");
	int ret = report_figure_spectra(panels, n, cols, title, solid, dashed, &png, &len, &e);
	if (!ret)
		ret = report_put_png(r->fp, png, len, title, "fig", "figure", &e);
	if (ret) {
		html(r, "<p class=\"missing\">");
		textf(r, "figure not drawn: %s", e.msg);
		html(r, "</p>");
	}
	html(r, "<figcaption>");
	text(r, caption);
	html(r, "</figcaption></figure>\n");
	free(png);
}

/* A list of warning strings (an array at key path `key`), or "none". */
static int put_warning_list(report *r, const char *key, const char *scope)
{
	int n;
	json_t *w = arr(r, &n, "%s", key);
	if (n == 0) {
		html(r, "<p>none</p>\n");
		return 0;
	}
	html(r, "<ul class=\"warnings\">\n");
	for (int i = 0; i < n; i++) {
		html(r, "<li>");
		if (scope) {
			html(r, "<span class=\"scope\">");
			text(r, scope);
			html(r, "</span> ");
		}
		json_t *x = json_array_get(w, i);
		if (json_is_string(x))
			text(r, json_string_value(x));
		else
			failed(r, KG_EINVAL, "%s: key '%s[%d]': expected a string", r->file, key, i);
		html(r, "</li>\n");
	}
	html(r, "</ul>\n");
	return n;
}

/* ---- the numbers behind the verdicts ------------------------------------------- */

static int summarise(report *r)
{
	int n;
	arr(r, &n, "calibration.patches");
	double *d50 = malloc(sizeof(double) * (n + 1)), *d65 = malloc(sizeof(double) * (n + 1));
	if (!d50 || !d65) {
		free(d50);
		free(d65);
		return failed(r, KG_ENOMEM, "%s: out of memory", r->file);
	}
	int have = 0;
	for (int i = 0; i < n; i++) {
		d50[i] = opt_num(r, "calibration.patches[%d].de00_d50", i);
		d65[i] = opt_num(r, "calibration.patches[%d].de00_d65", i);
		have += isfinite(d50[i]);
	}
	kg_err e;
	if (!r->ret && have) {
		if (kg_de_summarise(d50, n, &r->d50, &e) || kg_de_summarise(d65, n, &r->d65, &e))
			failed(r, KG_EINVAL, "%s: calibration.patches: %s", r->file, e.msg);
		else
			r->graded = 1;
	}
	r->g = &r->d50;
	r->basis = "in-sample";
	/* held out: a verification capture's patches (--verify), else leave-one-out */
	const char *key = "de00_d50_heldout";
	for (int i = 0; i < n && !r->ret; i++)
		if (has(r, "calibration.patches[%d].de00_d50_verify", i))
			key = "de00_d50_verify";
	for (int i = 0; i < n && !r->ret; i++)
		d50[i] = has(r, "calibration.patches[%d].%s", i, key)
		             ? opt_num(r, "calibration.patches[%d].%s", i, key)
		             : NAN;
	int nheld = 0;
	for (int i = 0; i < n; i++)
		nheld += isfinite(d50[i]);
	if (!r->ret && nheld) {
		if (kg_de_summarise(d50, n, &r->held, &e))
			failed(r, KG_EINVAL, "%s: calibration.patches: %s", r->file, e.msg);
		r->g = &r->held;
		r->basis = strcmp(key, "de00_d50_verify") ? "held-out" : "held-out, verification capture";
		r->held_how = strcmp(key, "de00_d50_verify") ? "leave-one-out" : "verification capture";
	}
	free(d50);
	free(d65);

	/* Accepted: the relative residual within the --max-residual limit and at least
	 * --min-tags tags found; a calibration outside them was used only when forced. */
	int ntags;
	arr(r, &ntags, "calibration.tags_used");
	double residual = num(r, "calibration.residual_relative");
	double limit = num(r, "parameters.max_residual");
	double min_tags = num(r, "parameters.min_tags");
	r->accepted = residual <= limit && ntags >= min_tags;
	r->forced = flag(r, "parameters.force");

	int nobj, nw;
	arr(r, &nw, "warnings");
	arr(r, &nobj, "objects");
	for (int i = 0; i < nobj; i++)
		arr(r, &nw, "objects[%d].warnings", i); /* each checked to be an array */
	r->warnings = kg_process_warning_count(r->root);
	return r->ret;
}

/* ---- sections ------------------------------------------------------------------ */

static void section_begin(report *r, const char *id, const char *title)
{
	html(r, "<section id=\"%s\">\n<h2>%s</h2>\n", id, title);
}

static void section_end(report *r)
{
	html(r, "</section>\n");
}

static void section_summary(report *r)
{
	int nobj;
	json_t *objects = arr(r, &nobj, "objects");
	int skipped = 0;
	for (int i = 0; i < nobj && objects; i++)
		skipped += flag(r, "objects[%d].skipped", i);
	section_begin(r, "summary", "Summary");
	html(r, "<table class=\"kv\">\n");
	row(r, "Session", str(r, "session.path"));
	row(r, "Processed (UTC)", str(r, "created"));
	rowf(r, "Software", "%s %s", str(r, "software.name"), str(r, "software.version"));
	if (skipped)
		rowf(r, "Objects", "%d object capture%s (%d unchanged since the last run, shown "
		     "from that run's files)", nobj, nobj == 1 ? "" : "s", skipped);
	else
		rowf(r, "Objects", "%d object capture%s", nobj, nobj == 1 ? "" : "s");
	html(r, "<tr><th scope=\"row\">Warnings</th><td>%ld (<a href=\"#warnings\">list</a>)"
	        "</td></tr>\n</table>\n", r->warnings);

	html(r, "<h3>Verdicts</h3>\n<ul class=\"verdicts\">\n<li>Calibration: ");
	if (r->accepted)
		put_verdict(r, 1, "accepted", "");
	else
		put_verdict(r, 0, "", r->forced ? "outside its limits, used because forced"
		                                : "not accepted");
	html(r, " (relative residual ");
	put_num(r, num(r, "calibration.residual_relative"), 4);
	html(r, ", limit ");
	put_num(r, num(r, "parameters.max_residual"), 4);
	html(r, ")</li>\n");
	if (r->graded) {
		html(r, "<li>FADGI 4-star colour accuracy: ");
		put_verdict(r, kg_grade_fadgi4(r->g), "pass", "fail");
		html(r, " (%s: mean &Delta;E<sub>00</sub> %.2f, 90th percentile %.2f, under D50)"
		        "</li>\n", r->basis, r->g->mean, r->g->p90);
		html(r, "<li>ISO 19264-1 level A colour accuracy: ");
		put_verdict(r, kg_grade_iso19264_a(r->g), "pass", "fail");
		html(r, " (%s: mean &Delta;E<sub>00</sub> %.2f, maximum %.2f, under D50)</li>\n",
		     r->basis, r->g->mean, r->g->max);
	} else {
		html(r, "<li>FADGI 4-star and ISO 19264-1 level A: <span class=\"fail\">not "
		        "graded</span>: no patch has both a measured and an estimated spectrum"
		        "</li>\n");
	}
	html(r, "</ul>\n<p class=\"caveat\">" KG_CONFORMANCE_CAVEAT "</p>\n");
	section_end(r);
}

/* calibration.flare (files of earlier versions lack it): the reference chart's, whether
 * removing it validated better, and the site chart's. */
static void put_flare(report *r)
{
	if (!has(r, "calibration.flare"))
		return;
	static const char *const sides[2] = {"reference", "site"};
	static const char *const labels[2] = {"Flare, reference chart", "Flare, site chart"};
	for (int s = 0; s < 2 && !r->ret; s++) {
		const json_t *f = kg_json_find(r->root, "calibration.flare");
		f = json_object_get(f, sides[s]);
		if (s == 1 && !json_is_object(f))
			continue; /* the site's is only measured against a flare-free reference */
		html(r, "<tr><th scope=\"row\">%s</th><td>", labels[s]);
		if (!json_is_object(f)) {
			html(r, "not measured (no three neutral patches from dark to light with spectra)");
		} else {
			textf(r, "the %zu neutral patches meet zero at %.2f %% (R), %.2f %% (G), "
			      "%.2f %% (B) of white",
			      json_array_size(json_object_get(f, "neutrals")),
			      100 * num(r, "calibration.flare.%s.white_fraction[0]", sides[s]),
			      100 * num(r, "calibration.flare.%s.white_fraction[1]", sides[s]),
			      100 * num(r, "calibration.flare.%s.white_fraction[2]", sides[s]));
			if (s == 0) {
				double kept = opt_num(r, "calibration.flare.loo_de00_kept");
				double rem = opt_num(r, "calibration.flare.loo_de00_removed");
				if (flag(r, "calibration.flare.reference_removed"))
					textf(r, "; removed before the fit (leave-one-out ΔE00 %.2f, %.2f with "
					      "it kept)", rem, kept);
				else if (isfinite(rem))
					textf(r, "; kept (leave-one-out ΔE00 %.2f, %.2f with it removed)", kept,
					      rem);
				else
					text(r, "; kept");
			} else {
				text(r, flag(r, "calibration.flare.site_removed")
				            ? "; removed from the site chart before M2 and from every object"
				            : "; kept");
			}
		}
		html(r, "</td></tr>\n");
	}
}

static void section_calibration(report *r)
{
	section_begin(r, "calibration", "Calibration");
	const char *overlay = opt_str(r, "calibration.overlay");
	html(r, "<figure>");
	if (overlay)
		put_image_file(r, overlay, "chart overlay", "photo");
	else
		html(r, "<p class=\"missing\">no chart overlay was written</p>");
	html(r, "<figcaption>The site chart as detected: patch sampling areas and tags "
	        "drawn over the chart photograph.</figcaption></figure>\n");

	put_record(r, "calibration.meta", "Record of the chart capture");
	int ntags, npatches;
	json_t *tags = arr(r, &ntags, "calibration.tags_used");
	json_t *patches = arr(r, &npatches, "calibration.patches");
	html(r, "<table class=\"kv\">\n");
	row(r, "Calibration file", str(r, "calibration.file"));
	const json_t *cicc = kg_json_find(r->root, "calibration.camera_icc");
	if (cicc) {
		html(r, "<tr><th scope=\"row\">Camera input profile</th><td>");
		const char *icc = json_is_object(cicc) ? opt_str(r, "calibration.camera_icc.path")
		                                       : NULL;
		if (!icc) {
			html(r, "<span class=\"none\">none (no LittleCMS, or no measured chart "
			        "spectra)</span>");
		} else {
			put_link(r, icc);
			const json_t *iv = kg_json_find(r->root, "calibration.camera_icc.icc_version");
			if (json_is_integer(iv))
				html(r, " (ICC v%d input profile, matrix/shaper, camera RGB to the D50 "
				        "profile connection space; ",
				     (int)json_integer_value(iv));
			else
				html(r, " (ICC input profile, matrix/shaper, camera RGB to the D50 "
				        "profile connection space; ");
			textf(r, "fitted on %.0f patches, ΔE00 mean %.2f, max %.2f",
			      num(r, "calibration.camera_icc.patches"),
			      num(r, "calibration.camera_icc.fit_de00_mean"),
			      num(r, "calibration.camera_icc.fit_de00_max"));
			/* held out: each patch through the matrix fitted on the others (files of
			 * earlier versions lack it) */
			double lm = has(r, "calibration.camera_icc.loo_de00_mean")
			                    ? opt_num(r, "calibration.camera_icc.loo_de00_mean")
			                    : NAN;
			if (isfinite(lm))
				textf(r, "; held out (leave-one-out) mean %.2f, max %.2f", lm,
				      opt_num(r, "calibration.camera_icc.loo_de00_max"));
			html(r, "); ");
			put_link(r, str(r, "calibration.camera_icc.ti3"));
			html(r, " (ArgyllCMS colprof input, CGATS XYZ_RGB)");
		}
		html(r, "</td></tr>\n");
	}
	row(r, "Chart capture", str(r, "calibration.chart_capture"));
	row(r, "Chart layout", str(r, "calibration.layout"));
	row(r, "Detector", str(r, "calibration.detector"));
	html(r, "<tr><th scope=\"row\">Tags used</th><td>");
	if (ntags) {
		put_json(r, tags);
		html(r, " (%d)", ntags);
	} else {
		html(r, "none");
	}
	html(r, "</td></tr>\n");
	num_row(r, "Homography RMS", num(r, "calibration.homography_rms_px"), 2, " px");
	row(r, "Chart spectra", opt_str(r, "calibration.spectra_source"));
	put_flare(r);
	/* the light over the chart: removed from the patch values, and the flat's */
	html(r, "<tr><th scope=\"row\">Light over the chart</th><td>");
	if (has(r, "calibration.light_field") && flag(r, "calibration.light_field.fitted")) {
		html(r, "varies by ");
		put_num(r, 100 * num(r, "calibration.light_field.variation"), 1);
		html(r, " %% (");
		put_num(r, num(r, "calibration.light_field.min"), 3);
		html(r, " to ");
		put_num(r, num(r, "calibration.light_field.max"), 3);
		html(r, " of its mean; degree ");
		put_num(r, num(r, "calibration.light_field.degree"), 0);
		html(r, ", from ");
		put_num(r, num(r, "calibration.light_field.patches"), 0);
		html(r, " patches), removed from the patch values");
	} else {
		html(r, "not estimated");
	}
	html(r, "</td></tr>\n<tr><th scope=\"row\">Flat: illuminance non-uniformity</th><td>");
	double fnu = has(r, "calibration.flat_illuminance_nonuniformity")
	                 ? opt_num(r, "calibration.flat_illuminance_nonuniformity")
	                 : NAN;
	if (isfinite(fnu)) {
		put_num(r, 100 * fnu, 2);
		html(r, " %%");
	} else {
		html(r, "no flat measured");
	}
	html(r, "</td></tr>\n");
	num_row(r, "Condition number of M", num(r, "calibration.cond_M"), 2, "");
	num_row(r, "Condition number of M2", num(r, "calibration.cond_M2"), 2, "");
	html(r, "<tr><th scope=\"row\">Relative residual</th><td>");
	put_num(r, num(r, "calibration.residual_relative"), 4);
	html(r, " (limit ");
	put_num(r, num(r, "parameters.max_residual"), 4);
	html(r, ")</td></tr>\n</table>\n");

	html(r, "<h3>M2: site camera RGB to reference camera RGB</h3>\n"
	        "<p>3 &times; 3, dimensionless (linear camera values on a 0..1 scale); rows: "
	        "the reference camera's R, G, B; columns: the site camera's R, G, B.</p>\n"
	        "<table class=\"matrix\">\n");
	int nm2;
	json_t *m2 = arr(r, &nm2, "calibration.M2");
	if (m2 && nm2 != 9)
		failed(r, KG_EINVAL, "%s: key 'calibration.M2': expected 9 numbers (row-major), "
		       "got %d", r->file, nm2);
	for (int i = 0; i < 3; i++) {
		html(r, "<tr>");
		for (int j = 0; j < 3; j++) {
			html(r, "<td>");
			put_num(r, nm2 == 9 ? num(r, "calibration.M2[%d]", 3 * i + j) : NAN, 4);
			html(r, "</td>");
		}
		html(r, "</tr>\n");
	}
	html(r, "</table>\n");

	int used = 0, flagged = 0;
	for (int i = 0; i < npatches && patches; i++) {
		int u = flag(r, "calibration.patches[%d].used", i);
		used += u;
		flagged += !u || num(r, "calibration.patches[%d].flags", i) != 0;
	}
	html(r, "<h3>Patches</h3>\n<p>%d of %d patches used; %d flagged.</p>\n", used, npatches,
	     flagged);
	if (flagged) {
		html(r, "<table><thead><tr><th>patch</th><th>name</th><th>used</th>"
		        "<th>flags</th><th>reason</th></tr></thead><tbody>\n");
		for (int i = 0; i < npatches; i++) {
			int u = flag(r, "calibration.patches[%d].used", i);
			double f = num(r, "calibration.patches[%d].flags", i);
			if (u && f == 0)
				continue;
			const char *why = str(r, "calibration.patches[%d].warning", i);
			html(r, "<tr><td>");
			text(r, str(r, "calibration.patches[%d].id", i));
			html(r, "</td><td>");
			text(r, str(r, "calibration.patches[%d].name", i));
			html(r, "</td><td>%s</td><td>0x%lx</td><td>", u ? "yes" : "no",
			     isfinite(f) && f >= 0 ? (unsigned long)f : 0UL);
			if (why[0])
				text(r, why);
			else
				html(r, "<span class=\"none\">no reason recorded</span>");
			html(r, "</td></tr>\n");
		}
		html(r, "</tbody></table>\n");
	}
	section_end(r);
}

static void summary_rows(report *r, const char *label, int digits, double d50, double d65)
{
	html(r, "<tr class=\"aggregate\"><th colspan=\"4\" scope=\"row\">%s</th><td>", label);
	put_num(r, d50, digits);
	html(r, "</td><td>");
	put_num(r, d65, digits);
	html(r, "</td><td colspan=\"2\"></td></tr>\n");
}

static void grade_row(report *r, const char *standard, const char *criterion,
                      const char *rule, double value, int pass)
{
	html(r, "<tr><td>%s</td><td>%s</td><td>%s</td><td>", standard, criterion, rule);
	put_num(r, value, 2);
	html(r, "</td><td>");
	put_verdict(r, pass, "pass", "fail");
	html(r, "</td></tr>\n");
}

/* The imaging-quality analysis (calibration.conformance, written by runs since it
 * was added; older records lack it). */
static void conformance_table(report *r)
{
	int n;
	if (!has(r, "calibration.conformance"))
		return;
	arr(r, &n, "calibration.conformance");
	html(r, "<h3>Imaging-quality analysis (ISO 19264-1, FADGI 2023)</h3>\n<table "
	        "id=\"conformance\"><thead><tr><th>characteristic</th><th>value</th><th>unit</th>"
	        "<th>ISO 19264-1 level</th><th>FADGI stars</th><th>note</th></tr></thead>"
	        "<tbody>\n");
	for (int i = 0; i < n; i++) {
		html(r, "<tr><td>");
		text(r, str(r, "calibration.conformance[%d].id", i));
		html(r, "</td><td>");
		put_num(r, opt_num(r, "calibration.conformance[%d].value", i), 2);
		html(r, "</td><td>");
		text(r, str(r, "calibration.conformance[%d].unit", i));
		html(r, "</td><td>");
		const char *lv = opt_str(r, "calibration.conformance[%d].level", i);
		int measured = flag(r, "calibration.conformance[%d].measured", i);
		text(r, lv ? lv : measured ? "none or no limit" : "not measured");
		html(r, "</td><td>%d</td><td>", (int)num(r, "calibration.conformance[%d].stars", i));
		text(r, str(r, "calibration.conformance[%d].note", i));
		html(r, "</td></tr>\n");
	}
	html(r, "</tbody></table>\n");
}

static void section_color_accuracy(report *r)
{
	section_begin(r, "color-accuracy", "Colour accuracy");
	int n;
	arr(r, &n, "calibration.patches");
	html(r, "<p>Each chart patch's spectrum estimated from the site camera (s = B M M2 "
	        "&rho;) against the spectrum the spectrophotometer measured, as CIEDE2000 "
	        "colour differences &Delta;E<sub>00</sub> (CIE 1931 2&deg; observer) under "
	        "the illuminants D50 and D65. &Delta;L* (tone) and &Delta;E(a*b*) = "
	        "&radic;(&Delta;a*&sup2; + &Delta;b*&sup2;) (white balance) are under D50. "
	        "All differences are in CIELAB units (dimensionless). The 90th percentile is "
	        "the nearest rank: the &lceil;0.9&nbsp;n&rceil;-th smallest value.</p>\n");
	html(r, "<table class=\"num\"><thead><tr><th>patch</th><th>name</th><th>used</th>"
	        "<th>neutral</th><th>&Delta;E<sub>00</sub> D50</th>"
	        "<th>&Delta;E<sub>00</sub> D65</th><th>&Delta;L* D50</th>"
	        "<th>&Delta;E(a*b*) D50</th></tr></thead><tbody>\n");
	int nneutral = 0;
	double dab_sum = 0, dab_max = 0, dl_sum = 0, dl_max = 0;
	for (int i = 0; i < n; i++) {
		int neutral = flag(r, "calibration.patches[%d].neutral", i);
		double dl = opt_num(r, "calibration.patches[%d].dL", i);
		double dab = opt_num(r, "calibration.patches[%d].dab", i);
		html(r, "<tr><td>");
		text(r, str(r, "calibration.patches[%d].id", i));
		html(r, "</td><td class=\"name\">");
		text(r, str(r, "calibration.patches[%d].name", i));
		html(r, "</td><td>%s</td><td>%s</td><td>",
		     flag(r, "calibration.patches[%d].used", i) ? "yes" : "no", neutral ? "yes" : "");
		put_num(r, opt_num(r, "calibration.patches[%d].de00_d50", i), 2);
		html(r, "</td><td>");
		put_num(r, opt_num(r, "calibration.patches[%d].de00_d65", i), 2);
		html(r, "</td><td>");
		put_num(r, dl, 2);
		html(r, "</td><td>");
		put_num(r, dab, 2);
		html(r, "</td></tr>\n");
		if (neutral && isfinite(dl) && isfinite(dab)) {
			nneutral++;
			dab_sum += dab;
			dab_max = fmax(dab_max, dab);
			dl_sum += fabs(dl);
			dl_max = fmax(dl_max, fabs(dl));
		}
	}
	html(r, "</tbody><tfoot>\n");
	if (r->graded) {
		summary_rows(r, "mean", 2, r->d50.mean, r->d65.mean);
		summary_rows(r, "90th percentile (nearest rank)", 2, r->d50.p90, r->d65.p90);
		summary_rows(r, "maximum", 2, r->d50.max, r->d65.max);
	}
	html(r, "</tfoot></table>\n");

	html(r, "<h3>Grades</h3>\n");
	if (r->graded) {
		html(r, "<table id=\"heldout\" class=\"num\"><thead><tr><th>&Delta;E<sub>00</sub> "
		        "D50</th><th>in-sample</th><th>held-out (%s)</th></tr></thead>"
		        "<tbody>\n", r->held_how ? r->held_how : "leave-one-out");
		const char *agg[] = {"mean", "90th percentile", "maximum"};
		double in[] = {r->d50.mean, r->d50.p90, r->d50.max};
		double out[] = {r->held.mean, r->held.p90, r->held.max};
		for (int k = 0; k < 3; k++) {
			html(r, "<tr><th scope=\"row\">%s</th><td>", agg[k]);
			put_num(r, in[k], 2);
			html(r, "</td><td>");
			put_num(r, r->held.n ? out[k] : NAN, 2);
			html(r, "</td></tr>\n");
		}
		html(r, "</tbody></table>\n<p>In-sample: the patches the calibration was fitted "
		        "to. Held-out: each patch through the calibration refitted without it, or "
		        "a second capture of the chart (--verify) through the calibration. Graded on the %s figures, "
		        "&Delta;E<sub>00</sub> under D50 over the %d patches with a value.</p>\n"
		        "<table><thead><tr><th>standard</th><th>criterion</th>"
		        "<th>requirement</th><th>value</th><th>verdict</th></tr></thead><tbody>\n",
		     r->basis, r->g->n);
		grade_row(r, "FADGI 4-star", "mean &Delta;E<sub>00</sub>", "&lt; 2", r->g->mean,
		          r->g->mean < KG_FADGI4_MEAN_BELOW);
		grade_row(r, "FADGI 4-star", "90th percentile &Delta;E<sub>00</sub>", "&lt; 4",
		          r->g->p90, r->g->p90 < KG_FADGI4_P90_BELOW);
		grade_row(r, "ISO 19264-1 level A", "mean &Delta;E<sub>00</sub>", "&le; 4",
		          r->g->mean, r->g->mean <= KG_ISO19264_A_MEAN_AT_MOST);
		grade_row(r, "ISO 19264-1 level A", "maximum &Delta;E<sub>00</sub>", "&le; 10",
		          r->g->max, r->g->max <= KG_ISO19264_A_MAX_AT_MOST);
		html(r, "</tbody></table>\n<ul class=\"verdicts\"><li>FADGI 4-star (%s): ",
		     r->basis);
		put_verdict(r, kg_grade_fadgi4(r->g), "pass", "fail");
		html(r, "</li><li>ISO 19264-1 level A (%s): ", r->basis);
		put_verdict(r, kg_grade_iso19264_a(r->g), "pass", "fail");
		html(r, "</li></ul>\n<p class=\"caveat\">" KG_CONFORMANCE_CAVEAT "</p>\n");
		conformance_table(r);
	} else {
		html(r, "<p class=\"missing\">Not graded: no patch has a colour difference (the "
		        "chart's measured spectra or the estimates are missing).</p>\n");
	}

	html(r, "<h3>White balance and tone (neutral patches)</h3>\n");
	if (nneutral)
		html(r, "<p>%d neutral patch%s: white balance &Delta;E(a*b*) mean %.2f, maximum "
		        "%.2f; tone |&Delta;L*| mean %.2f, maximum %.2f (under D50; reported, not "
		        "graded here).</p>\n", nneutral, nneutral == 1 ? "" : "es",
		     dab_sum / nneutral, dab_max, dl_sum / nneutral, dl_max);
	else
		html(r, "<p class=\"missing\">No neutral patch has &Delta;L* and &Delta;E(a*b*) "
		        "values.</p>\n");

	report_panel *panels = calloc(n > 0 ? n : 1, sizeof(*panels));
	double (*spectra)[2][KG_NBANDS] = calloc(n > 0 ? n : 1, sizeof(*spectra));
	char (*titles)[64] = calloc(n > 0 ? n : 1, sizeof(*titles));
	if (!panels || !spectra || !titles) {
		failed(r, KG_ENOMEM, "%s: out of memory", r->file);
	} else if (n > 0) {
		for (int i = 0; i < n; i++) {
			snprintf(titles[i], sizeof(titles[i]), "%s %s",
			         str(r, "calibration.patches[%d].id", i),
			         str(r, "calibration.patches[%d].name", i));
			panels[i].title = titles[i];
			panels[i].solid = spectrum(r, spectra[i][0], "calibration.patches[%d].measured", i);
			panels[i].dashed = spectrum(r, spectra[i][1], "calibration.patches[%d].estimated", i);
			panels[i].note = !panels[i].solid && !panels[i].dashed ? "no spectra"
			                 : !panels[i].solid ? "not measured"
			                 : !panels[i].dashed ? "not estimated" : NULL;
		}
		if (!r->ret)
			put_figure(r, panels, n, 4, "Chart patches: estimated against measured reflectance",
			           "measured (spectrophotometer)", "estimated (site camera)",
			           "Reflectance (0..1) against wavelength (400-700 nm) for every chart "
			           "patch; each panel has its own scale.");
	}
	free(panels);
	free(spectra);
	free(titles);
	section_end(r);
}

/* Camera-space labels: the pairs of materials a pixel cannot tell apart at the
 * capture's noise, and the classes merged for it. */
static void put_separability(report *r, int i)
{
	json_t *sep = object_key(r, i, "separability");
	if (!json_is_object(sep))
		return;
	html(r, "<h4>What the data can tell apart</h4>\n<p>");
	json_t *merges = json_object_get(sep, "merges");
	if (json_array_size(merges) == 0) {
		textf(r, "Every declared material is its own class: no pair is closer than %.3g "
		      "noise sigmas at this capture's noise.", jnum(sep, "merge_distance"));
	} else {
		textf(r, "At this capture's noise (with the angle and intensity unknown) a single "
		      "pixel cannot tell these materials apart (closer than %.3g noise sigmas); each "
		      "group is one class of the label map: ", jnum(sep, "merge_distance"));
		size_t g;
		json_t *grp;
		json_array_foreach(merges, g, grp) {
			size_t k;
			json_t *m;
			if (g)
				text(r, "; ");
			json_array_foreach(grp, k, m) {
				if (k)
					text(r, " | ");
				text(r, json_string_value(m));
			}
		}
		text(r, ".");
	}
	html(r, "</p>\n");
	json_t *pairs = json_object_get(sep, "pairs");
	if (json_array_size(pairs) == 0)
		return;
	html(r, "<table class=\"num\"><caption>Pairs a single pixel confuses more than 1 %% of "
	        "the time: noise-weighted distance (in noise sigmas) and the pixels a region must "
	        "pool for a 1 %% error</caption><thead><tr><th>material</th><th>material</th>"
	        "<th>distance</th><th>pixels for 1 %%</th><th>one class</th></tr></thead><tbody>\n");
	size_t k;
	json_t *p;
	json_array_foreach(pairs, k, p) {
		html(r, "<tr><td class=\"name\">");
		text(r, json_string_value(json_object_get(p, "a")));
		html(r, "</td><td class=\"name\">");
		text(r, json_string_value(json_object_get(p, "b")));
		html(r, "</td><td>");
		put_num(r, jnum(p, "distance"), 2);
		html(r, "</td><td>");
		put_num(r, jnum(p, "pixels_for_1pc"), 0);
		html(r, "</td><td>%s</td></tr>\n",
		     json_is_true(json_object_get(p, "merged")) ? "yes" : "no");
	}
	html(r, "</tbody></table>\n");
}

/* Camera-space labels: the regions of 100 pixels or more, decided on their pooled
 * likelihood, with their composition. */
static void put_regions(report *r, int i)
{
	json_t *reg = object_key(r, i, "regions");
	if (!json_is_object(reg))
		return;
	html(r, "<h4>Regions</h4>\n");
	if (!json_is_true(json_object_get(reg, "enabled"))) {
		html(r, "<p class=\"missing\">");
		const char *note = json_string_value(json_object_get(reg, "note"));
		text(r, note ? note : "No regions were formed.");
		html(r, "</p>\n");
		return;
	}
	json_t *table = json_object_get(reg, "table");
	html(r, "<p>");
	textf(r, "%.0f regions (connected pixels of one class); those of 100 pixels or more, "
	      "each decided on its pixels' pooled likelihood (which can resolve a merged class "
	      "or refuse the region as unknown):", jnum(reg, "count"));
	html(r, "</p>\n");
	json_t *small = json_object_get(reg, "small");
	if (json_is_object(small)) {
		html(r, "<p class=\"small-regions\">");
		textf(r, "Too small for the noise: %.0f regions (%.0f pixels; %.0f of the %.0f "
		      "one-pixel regions) hold fewer pixels than a pooled decision against "
		      "their surroundings needs for a 1 %% error, and take their surroundings' "
		      "label in the material map the render uses (%.0f regions, %.0f pixels, "
		      "unknown: amid nothing decided); the label map keeps each pixel's class.",
		      jnum(small, "merged_regions"), jnum(small, "merged_pixels"),
		      jnum(small, "one_pixel_regions") - jnum(small, "one_pixel_regions_kept"),
		      jnum(small, "one_pixel_regions"), jnum(small, "unknown_regions"),
		      jnum(small, "unknown_pixels"));
		html(r, "</p>\n");
	}
	if (json_array_size(table) == 0) {
		html(r, "<p class=\"missing\">No region of 100 pixels or more.</p>\n");
		return;
	}
	html(r, "<table class=\"num regions\"><thead><tr><th>region</th><th>pixels</th>"
	        "<th>label</th><th>pixels read</th><th>posterior</th><th>Ag</th><th>Cu</th>"
	        "<th>Au</th><th>why the region differs</th></tr></thead><tbody>\n");
	size_t k;
	json_t *e;
	json_array_foreach(table, k, e) {
		if (k == 40) {
			html(r, "<tr class=\"aggregate\"><td colspan=\"9\">");
			textf(r, "%zu more in the labels' regions table", json_array_size(table) - 40);
			html(r, "</td></tr>\n");
			break;
		}
		int differs = json_is_true(json_object_get(e, "differs"));
		html(r, "<tr%s><td>%.0f</td><td>", differs ? " class=\"differs\"" : "",
		     jnum(e, "region"));
		put_num(r, jnum(e, "pixels"), 0);
		html(r, "</td><td class=\"name\">");
		text(r, json_string_value(json_object_get(e, "label")));
		html(r, "</td><td class=\"name\">");
		const char *pxc = json_string_value(json_object_get(e, "pixel_class"));
		text(r, pxc ? pxc : "");
		html(r, "</td><td>");
		put_num(r, jnum(e, "posterior"), 3);
		json_t *c = json_object_get(e, "composition");
		static const char *const el[3][2] = {{"ag", "sd_ag"}, {"cu", "sd_cu"}, {"au", "sd_au"}};
		for (int q = 0; q < 3; q++) {
			html(r, "</td><td>");
			double v = jnum(c, el[q][0]), sd = jnum(c, el[q][1]);
			if (isfinite(v)) {
				put_num(r, v, 3);
				html(r, " &plusmn; ");
				put_num(r, sd, 3);
			} else {
				html(r, "&mdash;");
			}
		}
		html(r, "</td><td class=\"why\">");
		const char *why = json_string_value(json_object_get(e, "why"));
		text(r, why ? why : "");
		html(r, "</td></tr>\n");
	}
	html(r, "</tbody></table>\n");
}

/* The regions (of the table) whose decision differs from their pixels' class. */
static int regions_differing(report *r, int i)
{
	json_t *table = json_object_get(object_key(r, i, "regions"), "table");
	size_t k;
	json_t *e;
	int n = 0;
	json_array_foreach(table, k, e)
		n += json_is_true(json_object_get(e, "differs"));
	return n;
}

static void put_object(report *r, int i)
{
	const char *capture = str(r, "objects[%d].capture", i);
	html(r, "<article class=\"object\" id=\"object-%d\">\n<h3>", i + 1);
	text(r, capture);
	/* the object's identity in its heading: its own accession and title */
	const char *acc = has(r, "objects[%d].meta.accession", i)
	                          ? opt_str(r, "objects[%d].meta.accession", i)
	                          : NULL;
	const char *title =
		has(r, "objects[%d].meta.title", i) ? opt_str(r, "objects[%d].meta.title", i) : NULL;
	if (acc || title) {
		html(r, " <small>");
		textf(r, "%s%s%s", acc ? acc : "", acc && title ? ", " : "", title ? title : "");
		html(r, "</small>");
	}
	html(r, "</h3>\n");
	char where[64];
	snprintf(where, sizeof(where), "objects[%d].meta", i);
	put_record(r, where, "Record of this object");
	if (flag(r, "objects[%d].skipped", i))
		html(r, "<p class=\"note\">Unchanged since the last run: not processed again; shown "
		        "from the files that run wrote.</p>\n");
	double pixels = num(r, "objects[%d].pixels", i);
	html(r, "<p>");
	textf(r, "%.0f x %.0f pixels (%.0f), folder %s.",
	      num(r, "objects[%d].width", i), num(r, "objects[%d].height", i), pixels,
	      str(r, "objects[%d].dir", i));
	html(r, "</p>\n");
	put_file_list(r, i);
	html(r, "<div class=\"images\">\n<figure>");
	put_image_file(r, str(r, "objects[%d].photo", i), "photograph", "photo");
	html(r, "<figcaption>Photograph (site camera, display sRGB).</figcaption></figure>\n"
	        "<figure>");
	put_image_file(r, str(r, "objects[%d].labels_png", i), "label map", "map");
	html(r, "<figcaption>Label map: each pixel's class; colours as in the legend below "
	        "(the legend in the image is the same).</figcaption></figure>\n<figure>");
	put_image_file(r, str(r, "objects[%d].confidence_png", i), "confidence map", "map");
	html(r, "<figcaption>Confidence map (camera-space labels: the posterior of the "
	        "chosen class, black 0 to white 1; eq. 11 labels: the margin to the runner-up "
	        "material; brighter is more certain).</figcaption></figure>\n</div>\n");

	int differing = regions_differing(r, i);
	if (differing) {
		html(r, "<p class=\"note differs\">");
		textf(r, "The label map, this legend, labels.json's classes, the spectra and the "
		      "render show each pixel's own label. %d region%s %s decided otherwise on "
		      "%s pooled pixels: see the Regions table, which says why.", differing,
		      differing == 1 ? "" : "s", differing == 1 ? "is" : "are",
		      differing == 1 ? "its" : "their");
		html(r, "</p>\n");
	}
	int nclasses;
	arr(r, &nclasses, "objects[%d].classes", i);
	html(r, "<table class=\"num legend\"><caption>Materials: legend, pixel counts and "
	        "fractions of the image</caption><thead><tr><th></th><th>class</th>"
	        "<th>pixels</th><th>fraction (%%)</th></tr></thead><tbody>\n");
	for (int c = 0; c < nclasses; c++) {
		double rgb[3];
		for (int k = 0; k < 3; k++)
			rgb[k] = fmin(fmax(num(r, "objects[%d].classes[%d].colour[%d]", i, c, k), 0), 255);
		html(r, "<tr><td><span class=\"swatch\" style=\"background:rgb(%d,%d,%d)\"></span>"
		        "</td><td class=\"name\">", (int)rgb[0], (int)rgb[1], (int)rgb[2]);
		/* the full name; a compound class may break after each '|' */
		const char *cname = str(r, "objects[%d].classes[%d].name", i, c);
		for (const char *q = cname; q;) {
			const char *bar = strchr(q, '|');
			textf(r, "%.*s", bar ? (int)(bar - q + 1) : (int)strlen(q), q);
			if (bar)
				html(r, "<wbr>");
			q = bar ? bar + 1 : NULL;
		}
		html(r, "</td><td>");
		put_num(r, num(r, "objects[%d].classes[%d].pixels", i, c), 0);
		html(r, "</td><td>");
		put_num(r, 100 * num(r, "objects[%d].classes[%d].fraction", i, c), 2);
		html(r, "</td></tr>\n");
	}
	static const struct {
		const char *key, *label;
	} rest[] = {
		{"unknown_fraction", "unknown (no declared material explains the pixel)"},
		{"background_fraction", "background"},
		{"unclassified_fraction", "unclassified (not estimated: clipped or dark)"},
	};
	for (size_t k = 0; k < sizeof(rest) / sizeof(rest[0]); k++) {
		double f = num(r, "objects[%d].%s", i, rest[k].key);
		/* unknown and background are already rows of the legend (with their colour)
		 * when labels.json lists them as classes */
		int listed = 0;
		for (int c = 0; c < nclasses && !listed; c++) {
			const char *name = str(r, "objects[%d].classes[%d].name", i, c);
			size_t len = strlen(name);
			listed = len && strncmp(name, rest[k].key, len) == 0 && rest[k].key[len] == '_';
		}
		if (listed)
			continue;
		html(r, "<tr class=\"aggregate\"><td></td><td class=\"name\">%s</td><td>",
		     rest[k].label);
		put_num(r, f * pixels, 0);
		html(r, "</td><td>");
		put_num(r, 100 * f, 2);
		html(r, "</td></tr>\n");
	}
	html(r, "</tbody></table>\n");
	put_separability(r, i);
	put_regions(r, i);
	put_highlights(r, i);

	report_panel *panels = calloc(nclasses > 0 ? nclasses : 1, sizeof(*panels));
	double (*spectra)[2][KG_NBANDS] = calloc(nclasses > 0 ? nclasses : 1, sizeof(*spectra));
	/* the calibration's spectral uncertainty (leave-one-out, per band), when recorded */
	double band_v[KG_NBANDS];
	const double *band = NULL;
	if (has(r, "calibration.spectral_uncertainty.loo_band_rmse"))
		band = spectrum(r, band_v, "calibration.spectral_uncertainty.loo_band_rmse");
	if (!panels || !spectra) {
		failed(r, KG_ENOMEM, "%s: out of memory", r->file);
	} else if (nclasses == 0) {
		html(r, "<p class=\"missing\">No material classes: no spectra figure.</p>\n");
	} else {
		for (int c = 0; c < nclasses; c++) {
			panels[c].title = str(r, "objects[%d].classes[%d].name", i, c);
			panels[c].solid = spectrum(r, spectra[c][0],
			                           "objects[%d].classes[%d].model_spectrum", i, c);
			panels[c].dashed = spectrum(r, spectra[c][1],
			                            "objects[%d].classes[%d].mean_spectrum", i, c);
			panels[c].band = panels[c].dashed ? band : NULL;
			panels[c].note = !panels[c].solid && !panels[c].dashed ? "no spectra"
			                 : !panels[c].solid ? "no library model"
			                 : !panels[c].dashed ? "no estimate" : NULL;
		}
		if (!r->ret)
			put_figure(r, panels, nclasses, 4, "Mean estimated reflectance against the "
			           "library model per material", "library model", "estimated, mean",
			           "Reflectance (0..1) against wavelength (400-700 nm) of each "
			           "material's pixels (mean of the estimates) and of its library model "
			           "(cf. the paper's Figs. 11-12); each panel has its own scale; the "
			           "shaded band is the calibration's spectral uncertainty, the RMS "
			           "error per band of its leave-one-out estimates over the chart.");
	}
	free(panels);
	free(spectra);

	const char *render = opt_str(r, "objects[%d].render", i);
	html(r, "<h4>Render of the scene</h4>\n");
	if (render) {
		html(r, "<figure>");
		put_image_file(r, render, "render", "photo");
		html(r, "<figcaption>");
		textf(r, "%s rendered as it is (spectral, white-balanced to the scene's light): "
		      "each pixel's class as in the label map; unknown, background and unclassified "
		      "pixels are no library material and render as a neutral grey diffuser.",
		      str(r, "objects[%d].scene", i));
		html(r, "</figcaption></figure>\n");
	} else {
		html(r, "<p class=\"missing\">not rendered: built without Embree</p>\n");
	}
	html(r, "<h4>Warnings</h4>\n");
	char key[64];
	snprintf(key, sizeof(key), "objects[%d].warnings", i);
	put_warning_list(r, key, NULL);
	html(r, "</article>\n");
}

static void section_objects(report *r)
{
	section_begin(r, "objects", "Objects");
	int n;
	arr(r, &n, "objects");
	if (n == 0)
		html(r, "<p>No object captures in this session.</p>\n");
	for (int i = 0; i < n && !r->ret; i++)
		put_object(r, i);
	section_end(r);
}

/* scale: the object's exposure relative to the chart's, NAN for the chart itself. */
static void acquisition_row(report *r, const char *who, const char *prefix, double scale)
{
	html(r, "<tr><td>");
	text(r, who);
	html(r, "</td><td>");
	put_num(r, opt_num(r, "%s.exposure_us", prefix), 0);
	html(r, "</td><td>");
	put_num(r, opt_num(r, "%s.gain", prefix), 2);
	html(r, "</td><td>");
	put_num(r, has(r, "%s.aperture", prefix) ? opt_num(r, "%s.aperture", prefix) : NAN, 1);
	html(r, "</td><td>");
	put_num(r, num(r, "%s.frames", prefix), 0);
	html(r, "</td><td>");
	if (isfinite(scale))
		html(r, "%.4g", scale);
	else
		html(r, "1 (chart)");
	html(r, "</td><td>");
	const char *dark = opt_str(r, "%s.dark", prefix), *flat = opt_str(r, "%s.flat", prefix);
	text(r, dark ? dark : "none");
	html(r, "</td><td>");
	text(r, flat ? flat : "none");
	html(r, "</td><td>");
	const char *dem = has(r, "%s.demosaic", prefix) ? opt_str(r, "%s.demosaic", prefix) : NULL;
	const char *dec =
		has(r, "%s.raw_decoding", prefix) ? opt_str(r, "%s.raw_decoding", prefix) : NULL;
	text(r, dem ? dem : has(r, "%s.demosaic", prefix) ? "none (not a mosaic)" : "not recorded");
	if (dec) {
		html(r, "<br><small>raw: ");
		text(r, dec);
		html(r, "</small>");
	}
	html(r, "</td></tr>\n");
}

/* A JSON object as a table of its keys and values. */
static void put_kv_table(report *r, json_t *obj)
{
	html(r, "<table class=\"kv\">\n");
	const char *k;
	json_t *v;
	json_object_foreach(obj, k, v) {
		html(r, "<tr><th scope=\"row\">");
		text(r, k);
		html(r, "</th><td>");
		put_json(r, v);
		html(r, "</td></tr>\n");
	}
	html(r, "</table>\n");
}

static void put_devices(report *r, const char *kind, const char *title)
{
	int n;
	json_t *list = arr(r, &n, "devices.%s", kind);
	html(r, "<h3>%s</h3>\n", title);
	if (n == 0)
		html(r, "<p>none recorded</p>\n");
	for (int i = 0; i < n; i++) {
		json_t *d = json_array_get(list, i);
		if (!json_is_object(d)) {
			failed(r, KG_EINVAL, "%s: key 'devices.%s[%d]': expected an object", r->file,
			       kind, i);
			return;
		}
		put_kv_table(r, d);
	}
}

static void section_provenance(report *r)
{
	section_begin(r, "provenance", "Provenance");
	html(r, "<table class=\"kv\">\n");
	row(r, "Session", str(r, "session.path"));
	row(r, "Session manifest sha256", str(r, "session.manifest_sha256"));
	row(r, "Processed (UTC)", str(r, "created"));
	rowf(r, "Software", "%s %s", str(r, "software.name"), str(r, "software.version"));
	row(r, "Record", "process.json (kogei-process/1)");
	html(r, "<tr><th scope=\"row\">Condition numbers</th><td>M ");
	put_num(r, num(r, "calibration.cond_M"), 2);
	html(r, ", M2 ");
	put_num(r, num(r, "calibration.cond_M2"), 2);
	html(r, "</td></tr>\n</table>\n");

	put_devices(r, "cameras", "Cameras");
	put_devices(r, "spectrometers", "Spectrometers");

	html(r, "<h3>Acquisition</h3>\n<table class=\"num\"><thead><tr><th>capture</th>"
	        "<th>exposure (&micro;s)</th><th>gain (");
	text(r, str(r, "calibration.gain_unit"));
	html(r, ")</th><th>aperture (f/)</th><th>frames averaged</th><th>exposure scale (&times; chart)</th><th>dark</th><th>flat</th><th>demosaicing</th></tr></thead>"
	        "<tbody>\n");
	acquisition_row(r, str(r, "calibration.chart_capture"), "calibration", NAN);
	int n;
	arr(r, &n, "objects");
	for (int i = 0; i < n && !r->ret; i++) {
		char prefix[32];
		snprintf(prefix, sizeof(prefix), "objects[%d]", i);
		acquisition_row(r, str(r, "objects[%d].capture", i), prefix,
		                num(r, "objects[%d].exposure_scale", i));
	}
	html(r, "</tbody></table>\n");

	html(r, "<h3>Input files</h3>\n<table class=\"files\"><thead><tr><th>role</th>"
	        "<th>path</th><th>sha256</th></tr></thead><tbody>\n");
	arr(r, &n, "inputs");
	for (int i = 0; i < n; i++) {
		html(r, "<tr><td>");
		text(r, str(r, "inputs[%d].role", i));
		html(r, "</td><td class=\"path\">");
		text(r, str(r, "inputs[%d].path", i));
		html(r, "</td><td class=\"hash\">");
		text(r, str(r, "inputs[%d].sha256", i));
		html(r, "</td></tr>\n");
	}
	html(r, "</tbody></table>\n");

	html(r, "<h3>Parameters</h3>\n");
	json_t *params = kg_json_find(r->root, "parameters");
	if (!json_is_object(params))
		failed(r, KG_EINVAL, "%s: key 'parameters': expected an object", r->file);
	else
		put_kv_table(r, params);
	section_end(r);
}

static void section_warnings(report *r)
{
	section_begin(r, "warnings", "Warnings");
	if (r->warnings == 0) {
		html(r, "<p>none</p>\n");
	} else {
		html(r, "<h3>Session</h3>\n");
		put_warning_list(r, "warnings", NULL);
		int n;
		arr(r, &n, "objects");
		for (int i = 0; i < n; i++) {
			char key[64];
			snprintf(key, sizeof(key), "objects[%d].warnings", i);
			html(r, "<h3>");
			text(r, str(r, "objects[%d].capture", i));
			html(r, "</h3>\n");
			put_warning_list(r, key, NULL);
		}
	}
	section_end(r);
}

static const char style[] =
	"body{font-family:'DejaVu Sans',Verdana,Arial,sans-serif;font-size:15px;line-height:1.45;"
	"color:#1a1a1a;background:#fff;max-width:1180px;margin:0 auto;padding:24px 28px}"
	"h1{font-size:26px;margin:0 0 4px}h2{font-size:21px;border-bottom:2px solid #444;"
	"padding-bottom:4px;margin:34px 0 12px}h3{font-size:17px;margin:22px 0 8px}"
	"h4{font-size:15px;margin:16px 0 6px}.sub{color:#555;margin:0}"
	"nav{margin:12px 0 0;font-size:14px}nav a{margin-right:14px;color:#234}"
	"table{border-collapse:collapse;margin:8px 0 14px;font-size:14px}"
	"th,td{border:1px solid #bbb;padding:3px 8px;text-align:left;vertical-align:top}"
	"thead th{background:#eee}table.kv th{background:#f5f5f5;font-weight:600;width:16em}"
	"table.num td{text-align:right;font-variant-numeric:tabular-nums}"
	"table.num td.name,table.num td:first-child{text-align:left}table.num td.why{"
	"text-align:left;font-size:12px;min-width:14em}tr.differs td{background:#fff6e0}"
	"table.legend td.name{overflow-wrap:normal}table.matrix td{text-align:right;min-width:6em;"
	"font-variant-numeric:tabular-nums}caption{caption-side:top;text-align:left;"
	"color:#444;padding:2px 0 4px}tr.aggregate th,tr.aggregate td{background:#f5f5f5}"
	"td.hash,td.path{font-family:'DejaVu Sans Mono',monospace;font-size:12px;"
	"word-break:break-all}.pass{color:#fff;background:#1b7a36;padding:1px 7px;"
	"border-radius:3px;font-weight:600}.fail{color:#fff;background:#b3261e;"
	"padding:1px 7px;border-radius:3px;font-weight:600}.none{color:#777}"
	".missing{color:#7a4b00;background:#fff6e0;border-left:4px solid #e0a000;"
	"padding:4px 8px}.note{background:#eef4ff;border-left:4px solid #4a78c2;"
	"padding:4px 8px}ul.verdicts li{margin:3px 0}ul.warnings li{margin:2px 0}"
	"figure{margin:10px 0 16px}figcaption{font-size:13px;color:#444;margin-top:4px}"
	"img{max-width:100%;height:auto;border:1px solid #ccc}img.photo{min-width:min(100%,480px)}"
	".images img{width:100%}img.map{image-rendering:pixelated}"
	".images{display:flex;flex-wrap:wrap;gap:14px}.images figure{flex:1 1 320px;margin:0}"
	".swatch{display:inline-block;width:18px;height:14px;border:1px solid #333;"
	"vertical-align:middle}article.object{border-top:1px solid #ccc;margin-top:18px}"
	"code{font-family:'DejaVu Sans Mono',monospace;font-size:13px}"
	"footer{margin-top:36px;color:#666;font-size:12px;border-top:1px solid #ccc;"
	"padding-top:6px}"
	"@media print{body{max-width:none;padding:0;font-size:11pt}nav{display:none}"
	"section,article.object{break-before:page}section#summary{break-before:auto}"
	"figure,table,tr{break-inside:avoid}.pass,.fail{border:1px solid #000}}";

/* The records at the top: one row per object with its own record (its capture's
 * --meta), in the session's order, linked to its section; then what the run itself was
 * given (process --meta), which applies to every object. Never merged: two objects are
 * two records. */
static void section_records(report *r)
{
	json_t *objects = json_object_get(r->root, "objects");
	int n;
	arr(r, &n, "objects");
	json_t *keys_all = json_object(); /* the union of the objects' keys */
	for (int i = 0; i < n && !r->ret; i++) {
		char where[64];
		snprintf(where, sizeof(where), "objects[%d].meta", i);
		const json_t *m = kg_json_find(r->root, where);
		if (m && kg_meta_validate(r->file, where, m, r->err))
			r->ret = KG_EINVAL;
		else if (json_is_object(m))
			json_object_update(keys_all, (json_t *)m);
	}
	const json_t *run = json_object_get(r->root, "meta");
	if (r->ret ||
	    (!json_object_size(keys_all) && !(json_is_object(run) && json_object_size(run)))) {
		json_decref(keys_all);
		return;
	}
	section_begin(r, "record", n == 1 ? "Object record" : "Object records");
	const char *keys[KG_META_MAX_KEYS];
	int nk = kg_meta_ordered_keys(keys_all, keys, KG_META_MAX_KEYS);
	if (nk) {
		html(r, "<table class=\"records\">\n<tr><th scope=\"col\">object</th>");
		for (int k = 0; k < nk; k++) {
			html(r, "<th scope=\"col\">");
			text(r, keys[k]);
			html(r, "</th>");
		}
		html(r, "</tr>\n");
		for (int i = 0; i < n; i++) {
			const json_t *m = json_object_get(json_array_get(objects, (size_t)i), "meta");
			html(r, "<tr id=\"record-%d\"><th scope=\"row\"><a href=\"#object-%d\">",
			     i + 1, i + 1);
			text(r, str(r, "objects[%d].capture", i));
			html(r, "</a></th>");
			for (int k = 0; k < nk; k++) {
				const char *v = json_string_value(json_object_get(m, keys[k]));
				html(r, "<td>");
				if (v)
					text(r, v);
				else
					html(r, "<span class=\"none\">not given</span>");
				html(r, "</td>");
			}
			html(r, "</tr>\n");
		}
		html(r, "</table>\n");
	}
	json_decref(keys_all);
	put_record(r, "meta", "Given to this run (kogei process --meta), for every object");
	section_end(r);
}

static void write_page(report *r)
{
	html(r, "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
	        "<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; "
	        "img-src data:; style-src 'unsafe-inline'\">\n"
	        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
	        "<title>Spectral measurement report: ");
	text(r, str(r, "session.path"));
	html(r, "</title>\n<style>%s</style>\n</head>\n<body>\n<header>\n"
	        "<h1>Spectral measurement report</h1>\n<p class=\"sub\">", style);
	textf(r, "Session %s, processed %s by %s %s", str(r, "session.path"), str(r, "created"),
	      str(r, "software.name"), str(r, "software.version"));
	html(r, "</p>\n<nav><a href=\"#summary\">Summary</a><a href=\"#calibration\">"
	        "Calibration</a><a href=\"#color-accuracy\">Colour accuracy</a>"
	        "<a href=\"#objects\">Objects</a><a href=\"#provenance\">Provenance</a>"
	        "<a href=\"#warnings\">Warnings</a></nav>\n</header>\n");
	section_records(r);
	section_summary(r);
	section_calibration(r);
	section_color_accuracy(r);
	section_objects(r);
	section_provenance(r);
	section_warnings(r);
	html(r, "<footer>");
	textf(r, "Written by %s %s from process.json; every figure and image is contained in "
	      "this file.", str(r, "software.name"), str(r, "software.version"));
	html(r, "</footer>\n</body>\n</html>\n");
}

int kg_report_write(const char *outdir, kg_err *err)
{
	kg_check_arg(outdir, err);
	int lock = -1;
	int ret = kg_outdir_settle(outdir, "kogei report", stderr, 0, &lock, err);
	if (ret == KG_ENOENT)
		ret = 0; /* said below, as process.json missing */
	if (!ret)
		ret = report_write_staged(outdir, NULL, err);
	kg_outdir_unlock(&lock);
	return ret;
}

int report_write_staged(const char *outdir, const char *stage, kg_err *err)
{
	kg_check_arg(outdir, err);
	kg_err local;
	report r = {.outdir = outdir, .stage = stage, .err = err ? err : &local};
	char *out = kg_path_join(stage ? stage : outdir, "report.html");
	r.file = kg_path_join(stage ? stage : outdir, "process.json");
	if (!out || !r.file) {
		free(out);
		free(r.file);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	int ret = kg_json_load(r.file, &r.root, r.err);
	if (!ret) {
		const char *format = str(&r, "format");
		if (!r.ret && strcmp(format, "kogei-process/1") != 0)
			failed(&r, KG_EINVAL, "%s: key 'format': expected \"kogei-process/1\"",
			       r.file);
		ret = r.ret ? r.ret : summarise(&r);
	}
	kg_outfile o = {0};
	if (!ret)
		ret = kg_outfile_open(&o, out, 0, r.err);
	if (!ret) {
		r.fp = o.fp;
		write_page(&r);
		ret = r.ret;
		if (!ret && ferror(o.fp))
			ret = kg_fail(err, KG_EIO, "%s: write failed", out);
		if (ret)
			kg_outfile_abort(&o);
		else
			ret = kg_outfile_commit(&o, r.err);
	}
	json_decref(r.root);
	free(r.file);
	free(out);
	return ret;
}
