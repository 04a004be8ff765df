/* Complex refractive index on the grid: the Lorentz-Drude model of Rakic et al. 1998
 * and user tables (CSV, refractiveindex.info YAML). */
#include <complex.h>
#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "kg_optics.h"

/* ---- Lorentz-Drude model ------------------------------------------------------- */

/* A. D. Rakic, A. B. Djurisic, J. M. Elazar and M. L. Majewski, "Optical properties of
 * metallic films for vertical-cavity optoelectronic devices", Appl. Opt. 37(22),
 * 5271-5283 (1998), table of Lorentz-Drude parameters (all energies in eV):
 *   eps(w) = 1 - f0 wp^2 / (w (w + i G0)) + sum_j fj wp^2 / (wj^2 - w^2 - i w Gj)
 * (time dependence exp(-iwt), so Im eps >= 0 and n + ik = sqrt(eps) has k >= 0).
 * Unused oscillator slots have f = 0. */
#define LD_MAX_OSC 5
typedef struct ld_params {
	const char *element;
	double wp, f0, g0;
	double f[LD_MAX_OSC], g[LD_MAX_OSC], w[LD_MAX_OSC];
} ld_params;

static const ld_params rakic1998_ld[] = {
	{"Ag", 9.01, 0.845, 0.048,
	 {0.065, 0.124, 0.011, 0.840, 5.646},
	 {3.886, 0.452, 0.065, 0.916, 2.419},
	 {0.816, 4.481, 8.185, 9.083, 20.29}},
	{"Au", 9.03, 0.760, 0.053,
	 {0.024, 0.010, 0.071, 0.601, 4.384},
	 {0.241, 0.345, 0.870, 2.494, 2.214},
	 {0.415, 0.830, 2.969, 4.304, 13.32}},
	{"Cu", 10.83, 0.575, 0.030,
	 {0.061, 0.104, 0.723, 0.638, 0.0},
	 {0.378, 1.056, 3.213, 4.305, 0.0},
	 {0.291, 2.957, 5.300, 11.18, 0.0}},
};

/* h c in eV nm (CODATA 2018, exact: h and c are defined constants). */
#define HC_EV_NM 1239.84198433

static const ld_params *ld_find(const char *element, kg_err *err)
{
	for (size_t i = 0; element && i < sizeof(rakic1998_ld) / sizeof(rakic1998_ld[0]); i++)
		if (strcasecmp(element, rakic1998_ld[i].element) == 0)
			return &rakic1998_ld[i];
	kg_fail(err, KG_ENOTSUP, "rakic1998-ld: element '%s': expected Ag, Au or Cu",
	        element ? element : "(none)");
	return NULL;
}

static void ld_eval(const ld_params *p, double lambda_nm, double *n, double *k)
{
	double w = HC_EV_NM / lambda_nm, wp2 = p->wp * p->wp;
	double complex eps = 1.0 - p->f0 * wp2 / (w * (w + I * p->g0));
	for (int j = 0; j < LD_MAX_OSC; j++)
		if (p->f[j] != 0.0)
			eps += p->f[j] * wp2 / (p->w[j] * p->w[j] - w * w - I * w * p->g[j]);
	double complex nk = csqrt(eps);
	*n = creal(nk);
	*k = cimag(nk);
}

int kg_nk_rakic1998_ld_at(const char *element, double lambda_nm, double *n, double *k,
                          kg_err *err)
{
	kg_check_arg(n && k, err);
	const ld_params *p = ld_find(element, err);
	if (!p)
		return KG_ENOTSUP;
	if (!(lambda_nm > 0.0) || !isfinite(lambda_nm))
		return kg_fail(err, KG_EINVAL, "rakic1998-ld: wavelength %g nm: expected a "
		               "positive number", lambda_nm);
	ld_eval(p, lambda_nm, n, k);
	return 0;
}

int kg_nk_rakic1998_ld(const char *element, kg_nk *out, kg_err *err)
{
	kg_check_arg(out, err);
	const ld_params *p = ld_find(element, err);
	if (!p)
		return KG_ENOTSUP;
	for (int i = 0; i < KG_NBANDS; i++)
		ld_eval(p, kg_band_nm(i), &out->n.v[i], &out->k.v[i]);
	return 0;
}

/* ---- Tables -------------------------------------------------------------------- */

/* One tabulated column set: wavelengths (nm) and one or two value columns, with the
 * source line of each row for messages. */
typedef struct column {
	int n, cap;
	double *wl, *a, *b;
	int *line;
} column;

static void column_free(column *c)
{
	free(c->wl);
	free(c->a);
	free(c->b);
	free(c->line);
	memset(c, 0, sizeof(*c));
}

static int column_push(column *c, double wl, double a, double b, int line)
{
	if (c->n == c->cap) {
		int cap = c->cap ? 2 * c->cap : 64;
		double *w = realloc(c->wl, sizeof(*w) * (size_t)cap);
		if (w)
			c->wl = w;
		double *x = realloc(c->a, sizeof(*x) * (size_t)cap);
		if (x)
			c->a = x;
		double *y = realloc(c->b, sizeof(*y) * (size_t)cap);
		if (y)
			c->b = y;
		int *l = realloc(c->line, sizeof(*l) * (size_t)cap);
		if (l)
			c->line = l;
		if (!w || !x || !y || !l)
			return KG_ENOMEM;
		c->cap = cap;
	}
	c->wl[c->n] = wl;
	c->a[c->n] = a;
	c->b[c->n] = b;
	c->line[c->n] = line;
	c->n++;
	return 0;
}

/* Wavelengths must be positive and strictly monotonic (decreasing tables are turned
 * round); values must be >= 0. `val` names the value columns ("n", "k"; NULL when
 * the column is unused). */
static int column_check(const char *name, column *c, const char *va, const char *vb,
                        kg_err *err)
{
	if (c->n == 0)
		return kg_fail(err, KG_EINVAL, "%s: no data rows: expected one row per wavelength",
		               name);
	if (c->n > 1 && c->wl[1] < c->wl[0]) {
		for (int i = 0, j = c->n - 1; i < j; i++, j--) {
			double t = c->wl[i]; c->wl[i] = c->wl[j]; c->wl[j] = t;
			t = c->a[i]; c->a[i] = c->a[j]; c->a[j] = t;
			t = c->b[i]; c->b[i] = c->b[j]; c->b[j] = t;
			int l = c->line[i]; c->line[i] = c->line[j]; c->line[j] = l;
		}
	}
	for (int i = 0; i < c->n; i++) {
		if (!(c->wl[i] > 0.0))
			return kg_fail(err, KG_EINVAL, "%s: line %d: wavelength %g: expected a "
			               "positive number", name, c->line[i], c->wl[i]);
		if (i > 0 && !(c->wl[i] > c->wl[i - 1]))
			return kg_fail(err, KG_EINVAL, "%s: line %d: wavelength %g nm after %g nm: "
			               "expected wavelengths in strictly increasing or decreasing "
			               "order", name, c->line[i], c->wl[i], c->wl[i - 1]);
		if (va && !(c->a[i] >= 0.0))
			return kg_fail(err, KG_EINVAL, "%s: line %d: %s = %g: expected a number >= 0",
			               name, c->line[i], va, c->a[i]);
		if (vb && !(c->b[i] >= 0.0))
			return kg_fail(err, KG_EINVAL, "%s: line %d: %s = %g: expected a number >= 0",
			               name, c->line[i], vb, c->b[i]);
	}
	return 0;
}

static int resample(const char *name, const char *what, const double *wl,
                    const double *val, int n, unsigned flags, kg_spectrum *out, kg_err *err)
{
	char label[512];
	snprintf(label, sizeof(label), "%s: %s", name, what);
	return kg_spectrum_resample(wl, val, n, flags, label, out, err);
}

int kg_nk_parse_csv(const char *text, const char *name, unsigned flags, kg_nk *out,
                    kg_err *err)
{
	kg_check_arg(text && out, err);
	if (!name)
		name = "<memory>";
	kg_csv *t = NULL;
	column c = {0};
	int r = kg_csv_parse(text, strlen(text), name, &t, err);
	if (r != 0)
		return r;
	int cw = kg_csv_column(t, "wavelength_nm"), cn = kg_csv_column(t, "n"),
	    ck = kg_csv_column(t, "k");
	if (cw < 0 || cn < 0 || ck < 0) {
		r = kg_fail(err, KG_EINVAL, "%s: header: no column '%s': expected "
		            "wavelength_nm,n,k", name, cw < 0 ? "wavelength_nm" : cn < 0 ? "n" : "k");
		goto done;
	}
	for (int i = 0; i < t->nrows && r == 0; i++) {
		double w, n, k;
		if ((r = kg_csv_number(t, i, cw, &w, err)) || (r = kg_csv_number(t, i, cn, &n, err)) ||
		    (r = kg_csv_number(t, i, ck, &k, err)))
			break;
		if (column_push(&c, w, n, k, t->row_lines[i]) != 0)
			r = kg_fail(err, KG_ENOMEM, "%s: out of memory", name);
	}
	if (r == 0)
		r = column_check(name, &c, "n", "k", err);
	if (r == 0)
		r = resample(name, "n", c.wl, c.a, c.n, flags, &out->n, err);
	if (r == 0)
		r = resample(name, "k", c.wl, c.b, c.n, flags, &out->k, err);
done:
	column_free(&c);
	kg_csv_free(&t);
	return r;
}

/* -- refractiveindex.info YAML --
 * The database's files are YAML, but measured data use a small, regular subset:
 *
 *   REFERENCES: |            top-level keys at column 0; nested lines are skipped
 *       ...
 *   DATA:
 *     - type: tabulated nk   list items under DATA
 *       data: |              a literal block of whitespace-separated numbers,
 *           0.2 1.1 1.8      indented deeper than its key
 *
 * Lines are read one by one with their indentation; that is all the structure this
 * subset has. */

typedef struct yaml_line {
	const char *s; /* first non-blank character */
	size_t len;    /* up to the end of the line, trailing blanks removed */
	int indent;
	int no;
} yaml_line;

/* The next line at *pos (0 at the end of the text). */
static int next_line(const char **pos, int *no, yaml_line *l)
{
	const char *p = *pos;
	if (!*p)
		return 0;
	const char *e = strchr(p, '\n');
	size_t n = e ? (size_t)(e - p) : strlen(p);
	*pos = e ? e + 1 : p + n;
	(*no)++;
	size_t a = 0;
	while (a < n && (p[a] == ' ' || p[a] == '\t'))
		a++;
	while (n > a && isspace((unsigned char)p[n - 1]))
		n--;
	l->s = p + a;
	l->len = n - a;
	l->indent = (int)a;
	l->no = *no;
	for (size_t i = 0; i < a; i++)
		if (p[i] == '\t')
			l->indent = -1; /* YAML forbids tabs in indentation */
	return 1;
}

static int is_blank(const yaml_line *l)
{
	return l->len == 0 || l->s[0] == '#';
}

/* Split "key: value" (value may be empty); 0 when the line has no "key:". */
static int split_key(const char *s, size_t len, char *key, size_t keysz, char *val,
                     size_t valsz)
{
	const char *colon = memchr(s, ':', len);
	if (!colon || (colon + 1 < s + len && colon[1] != ' '))
		return 0;
	size_t kl = (size_t)(colon - s);
	while (kl > 0 && s[kl - 1] == ' ')
		kl--;
	const char *v = colon + 1, *e = s + len;
	while (v < e && *v == ' ')
		v++;
	if (e - v >= 2 && (*v == '"' || *v == '\'') && e[-1] == *v) {
		v++;
		e--;
	}
	snprintf(key, keysz, "%.*s", (int)kl, s);
	snprintf(val, valsz, "%.*s", (int)(e - v), v);
	return 1;
}

enum { ITEM_NK, ITEM_N, ITEM_K };

/* The DATA list item being read. */
typedef struct yaml_item {
	int kind;   /* ITEM_*, -1 before its type */
	int indent; /* of its '-' (-1 before the first item) */
	int line;   /* where it starts (0: none open) */
	int has_data;
	char type[128];
} yaml_item;

/* An item is complete when the next one starts or DATA ends: it must have had data. */
static int finish_item(const char *name, yaml_item *it, kg_err *err)
{
	int line = it->line;
	it->line = 0;
	if (line && !it->has_data)
		return kg_fail(err, KG_EINVAL, "%s: line %d: DATA item of type '%s' has no "
		               "'data: |' block", name, line, it->type);
	return 0;
}

/* Parse the lines of one `data: |` block (indented deeper than key_indent) into c,
 * or skip them when c is NULL; leaves *pos at the first line after the block. */
static int read_block(const char *name, const char **pos, int *no, int key_indent,
                      int ncols, column *c, kg_err *err)
{
	yaml_line l;
	const char *save = *pos;
	int save_no = *no;
	while (next_line(pos, no, &l)) {
		if (is_blank(&l)) {
			save = *pos;
			save_no = *no;
			continue;
		}
		if (l.indent < 0)
			return kg_fail(err, KG_EINVAL, "%s: line %d: tab in indentation: expected "
			               "spaces", name, l.no);
		if (l.indent <= key_indent) {
			*pos = save; /* not ours: give the line back */
			*no = save_no;
			return 0;
		}
		save = *pos;
		save_no = *no;
		if (!c)
			continue;
		double v[3];
		int got = 0;
		const char *p = l.s, *e = l.s + l.len;
		while (p < e) {
			while (p < e && (*p == ' ' || *p == '\t'))
				p++;
			if (p == e)
				break;
			const char *t = p;
			while (p < e && *p != ' ' && *p != '\t')
				p++;
			char tok[64];
			if (got == ncols || (size_t)(p - t) >= sizeof(tok))
				return kg_fail(err, KG_EINVAL, "%s: line %d: expected %d numbers "
				               "(wavelength in um, %s), found more", name, l.no, ncols,
				               ncols == 3 ? "n, k" : "value");
			snprintf(tok, sizeof(tok), "%.*s", (int)(p - t), t);
			if (kg_cgats_parse_number(tok, &v[got]) != 0)
				return kg_fail(err, KG_EINVAL, "%s: line %d: '%s': expected a finite "
				               "number", name, l.no, tok);
			got++;
		}
		if (got != ncols)
			return kg_fail(err, KG_EINVAL, "%s: line %d: %d number(s): expected %d "
			               "(wavelength in um, %s)", name, l.no, got, ncols,
			               ncols == 3 ? "n, k" : "value");
		if (column_push(c, 1000.0 * v[0], v[1], ncols == 3 ? v[2] : 0.0, l.no) != 0)
			return kg_fail(err, KG_ENOMEM, "%s: out of memory", name);
	}
	return 0;
}

int kg_nk_parse_yaml(const char *text, const char *name, unsigned flags, kg_nk *out,
                     kg_err *err)
{
	kg_check_arg(text && out, err);
	if (!name)
		name = "<memory>";
	column col[3] = {{0}};
	int seen[3] = {0}, seen_line[3] = {0};
	int r = 0, no = 0, in_data = 0, have_data_key = 0;
	yaml_item it = {.kind = -1, .indent = -1};
	const char *pos = text;
	yaml_line l;

	while (r == 0 && next_line(&pos, &no, &l)) {
		if (is_blank(&l))
			continue;
		if (l.indent < 0) {
			r = kg_fail(err, KG_EINVAL, "%s: line %d: tab in indentation: expected spaces",
			            name, l.no);
			break;
		}
		char key[64], val[128];
		if (l.indent == 0) {
			if ((r = finish_item(name, &it, err)) != 0)
				break;
			if (l.len >= 3 && l.s[0] == '-' && l.s[1] == '-' && l.s[2] == '-')
				continue; /* document marker */
			if (!split_key(l.s, l.len, key, sizeof(key), val, sizeof(val))) {
				r = kg_fail(err, KG_EINVAL, "%s: line %d: expected a top-level 'KEY:' "
				            "(refractiveindex.info format)", name, l.no);
				break;
			}
			in_data = strcmp(key, "DATA") == 0;
			if (in_data && *val) {
				r = kg_fail(err, KG_EINVAL, "%s: line %d: DATA: expected a list of items "
				            "on the following lines", name, l.no);
				break;
			}
			have_data_key |= in_data;
			continue;
		}
		if (!in_data)
			continue; /* nested in another top-level key */
		const char *s = l.s;
		size_t len = l.len;
		int indent = l.indent;
		if (s[0] == '-' && (len == 1 || s[1] == ' ')) {
			if ((r = finish_item(name, &it, err)) != 0)
				break;
			it = (yaml_item){.kind = -1, .indent = indent, .line = l.no};
			s += len > 1 ? 2 : 1;
			len -= len > 1 ? 2 : 1;
			indent += 2;
			while (len > 0 && *s == ' ') {
				s++;
				len--;
				indent++;
			}
			if (len == 0)
				continue;
		} else if (it.indent < 0 || indent <= it.indent) {
			r = kg_fail(err, KG_EINVAL, "%s: line %d: expected a DATA list item "
			            "('- type: ...')", name, l.no);
			break;
		}
		if (!split_key(s, len, key, sizeof(key), val, sizeof(val))) {
			r = kg_fail(err, KG_EINVAL, "%s: line %d: expected 'key: value' inside a DATA "
			            "item", name, l.no);
			break;
		}
		if (strcmp(key, "type") == 0) {
			snprintf(it.type, sizeof(it.type), "%s", val);
			it.kind = strcmp(val, "tabulated nk") == 0  ? ITEM_NK
			          : strcmp(val, "tabulated n") == 0 ? ITEM_N
			          : strcmp(val, "tabulated k") == 0 ? ITEM_K
			                                            : -1;
			if (it.kind < 0) {
				r = kg_fail(err, KG_ENOTSUP, "%s: line %d: DATA type '%s' is not "
				            "supported: expected 'tabulated nk', or 'tabulated n' with "
				            "'tabulated k'", name, l.no, val);
				break;
			}
			if (seen[it.kind]) {
				r = kg_fail(err, KG_EINVAL, "%s: line %d: a second '%s' item (the first "
				            "is at line %d): expected one", name, l.no, val,
				            seen_line[it.kind]);
				break;
			}
			seen[it.kind] = 1;
			seen_line[it.kind] = l.no;
		} else if (strcmp(key, "data") == 0) {
			if (it.kind < 0) {
				r = kg_fail(err, KG_EINVAL, "%s: line %d: 'data' before 'type' in a DATA "
				            "item: expected '- type: tabulated ...' first", name, l.no);
				break;
			}
			if (val[0] != '|') {
				r = kg_fail(err, KG_EINVAL, "%s: line %d: data: expected a literal block "
				            "('data: |') of numbers on the following lines", name, l.no);
				break;
			}
			r = read_block(name, &pos, &no, indent, it.kind == ITEM_NK ? 3 : 2,
			               &col[it.kind], err);
			it.has_data = 1;
		} else if (val[0] == '|' || val[0] == '>') {
			r = read_block(name, &pos, &no, indent, 0, NULL, err);
		}
		/* other keys (wavelength_range, ...) carry nothing tabulated data need */
	}
	if (r == 0)
		r = finish_item(name, &it, err);

	if (r == 0 && !have_data_key)
		r = kg_fail(err, KG_EINVAL, "%s: no top-level DATA key: expected a "
		            "refractiveindex.info data file", name);
	else if (r == 0 && seen[ITEM_NK] && (seen[ITEM_N] || seen[ITEM_K]))
		r = kg_fail(err, KG_EINVAL, "%s: both 'tabulated nk' and 'tabulated n'/'k' items: "
		            "expected one or the other", name);
	else if (r == 0 && !seen[ITEM_NK] && !seen[ITEM_N])
		r = kg_fail(err, KG_EINVAL, "%s: DATA holds no 'tabulated nk' or 'tabulated n' "
		            "item", name);

	if (r == 0 && seen[ITEM_NK]) {
		column *c = &col[ITEM_NK];
		if ((r = column_check(name, c, "n", "k", err)) == 0 &&
		    (r = resample(name, "n", c->wl, c->a, c->n, flags, &out->n, err)) == 0)
			r = resample(name, "k", c->wl, c->b, c->n, flags, &out->k, err);
	} else if (r == 0) {
		column *cn = &col[ITEM_N], *ck = &col[ITEM_K];
		if ((r = column_check(name, cn, "n", NULL, err)) == 0)
			r = resample(name, "n", cn->wl, cn->a, cn->n, flags, &out->n, err);
		if (r == 0 && seen[ITEM_K]) {
			if ((r = column_check(name, ck, "k", NULL, err)) == 0)
				r = resample(name, "k", ck->wl, ck->a, ck->n, flags, &out->k, err);
		} else if (r == 0) {
			out->k = kg_spectrum_const(0.0);
		}
	}
	for (int i = 0; i < 3; i++)
		column_free(&col[i]);
	return r;
}

static int has_suffix(const char *s, const char *suffix)
{
	size_t a = strlen(s), b = strlen(suffix);
	return a >= b && strcasecmp(s + a - b, suffix) == 0;
}

int kg_nk_load(const char *path, unsigned flags, kg_nk *out, kg_err *err)
{
	kg_check_arg(path && out, err);
	int csv = has_suffix(path, ".csv");
	if (!csv && !has_suffix(path, ".yml") && !has_suffix(path, ".yaml"))
		return kg_fail(err, KG_ENOTSUP, "%s: unknown n,k table format: expected a name "
		               "ending in .csv (wavelength_nm,n,k) or .yml/.yaml "
		               "(refractiveindex.info)", path);
	char *buf;
	size_t len;
	int r = kg_read_file(path, &buf, &len, err);
	if (r != 0)
		return r;
	if (memchr(buf, '\0', len))
		r = kg_fail(err, KG_EINVAL, "%s: NUL byte: expected a text file", path);
	else if (csv)
		r = kg_nk_parse_csv(buf, path, flags, out, err);
	else
		r = kg_nk_parse_yaml(buf, path, flags, out, err);
	free(buf);
	return r;
}
