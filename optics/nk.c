/* Complex refractive index on the grid: published analytic dispersion models (the
 * Lorentz-Drude model of Rakic et al. 1998, Drude-critical-points fits of Vial et al.,
 * the gold model of Le Ru & Etchegoin) and user tables (CSV, refractiveindex.info
 * YAML). */
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

/* ---- Drude-critical-points model ---------------------------------------------- */

/* eps(w) = eps_inf - wD^2 / (w^2 + i gD w)
 *          + sum_p A_p O_p (e^{i phi_p} / (O_p - w - i G_p) + e^{-i phi_p} / (O_p + w + i G_p))
 * with w, wD, gD, O_p, G_p angular frequencies in rad/s and exp(-iwt) time dependence
 * (Im eps >= 0), the form used by A. Vial and T. Laroche (Appl. Phys. B 93, 139 (2008)
 * and earlier papers). */
typedef struct dcp_params {
	double eps_inf, wd, gd;
	double a[2], phi[2], om[2], ga[2];
} dcp_params;

/* A. Vial and T. Laroche, "Comparison of gold and silver dispersion laws suitable for
 * FDTD simulations", Appl. Phys. B 93, 139-143 (2008): Drude + 2 critical points fitted
 * to Johnson & Christy (1972), 200-1000 nm. Checked against two independent public
 * transcriptions of the paper's table (FDTD codes citing it). */
static const dcp_params vial_laroche2008_au = {
	1.1431, 1.3202e16, 1.0805e14,
	{0.26698, 3.0834}, {-1.2371, -1.0968}, {3.8711e15, 4.1684e15}, {4.4642e14, 2.3555e15}};
static const dcp_params vial_laroche2008_ag = {
	15.833, 1.3861e16, 4.5841e13,
	{1.0171, 15.797}, {-0.93935, 1.8087}, {6.6327e15, 9.2726e17}, {1.6666e15, 2.3716e17}};

/* A. Vial, "Use of the critical points model as law of dispersion for the modeling of
 * plasmonic structures using the FDTD method", in J. Bubendorff and F. Lei (eds.),
 * Transworld Research Network (2008), pp. 23-46 (a book chapter): Drude + 2 critical
 * points fitted over 400-1000 nm, gold to Johnson & Christy (1972), silver and copper
 * to Palik's handbook data. Transcribed from the chapter's values as tabulated in the
 * material library of the Aether FDTD code (one secondary source only; the gold entry
 * reproduces J&C to 0.03 in R, which also checks the argument order). */
static const dcp_params vial2008ch_au = {
	1.03, 1.3064e16, 1.1274e14,
	{0.86822, 1.3700}, {-0.60756, -0.087341}, {4.0812e15, 6.4269e15}, {7.3277e14, 6.7371e14}};
static const dcp_params vial2008ch_ag = {
	3.7325, 1.3354e16, 9.6875e13,
	{2.0297, -2.8925}, {-0.70952, -1.4459}, {4.5932e17, 4.7711e16}, {1.0524e18, 3.0719e15}};
static const dcp_params vial2008ch_cu = {
	1.8097, 1.3209e16, 1.4086e14,
	{0.54253, 5.4965}, {-1.5611, 0.79163}, {3.2858e15, 1.1316e16}, {4.0476e14, 4.7327e15}};

/* 2 pi c in nm rad/s (c = 299792458 m/s exactly). */
#define TWO_PI_C_NM (2.0 * 3.14159265358979323846 * 299792458.0e9)

static double complex dcp_eps(const void *params, double lambda_nm)
{
	const dcp_params *p = params;
	double w = TWO_PI_C_NM / lambda_nm;
	double complex eps = p->eps_inf - p->wd * p->wd / (w * w + I * p->gd * w);
	for (int j = 0; j < 2; j++)
		eps += p->a[j] * p->om[j] *
		       (cexp(I * p->phi[j]) / (p->om[j] - w - I * p->ga[j]) +
		        cexp(-I * p->phi[j]) / (p->om[j] + w + I * p->ga[j]));
	return eps;
}

/* ---- Le Ru & Etchegoin gold model ------------------------------------------------ */

/* E. C. Le Ru and P. G. Etchegoin, "Principles of Surface-Enhanced Raman Spectroscopy
 * and related plasmonic effects", Elsevier, Amsterdam (2009), eq. (E.1) with its
 * parameters for gold (the analytic model of P. G. Etchegoin, E. C. Le Ru and M. Meyer,
 * J. Chem. Phys. 125, 164705 (2006), refitted to Johnson & Christy (1972)); lengths in
 * nm, exp(-iwt):
 *   eps = eps_inf (1 - 1 / (lp^2 (1/l^2 + i/(mp l))))
 *         + sum_j A_j/l_j (e^{i phi_j}/(1/l_j - 1/l - i/m_j) + e^{-i phi_j}/(1/l_j + 1/l + i/m_j))
 * Checked against two independent public implementations of eq. (E.1). (The 2006 paper's
 * own parameter set, and its 2007 erratum, could not be cross-checked against a second
 * source and are not included.) */
typedef struct lre_params {
	double eps_inf, lp, mp;
	double a[2], phi[2], l[2], m[2];
} lre_params;

static const lre_params leru_etchegoin2009_au = {
	1.54, 177.5, 14500.0,
	{1.27, 1.1}, {-0.78539816339744831, -0.78539816339744831}, {470.0, 325.0}, {1900.0, 1060.0}};

static double complex lre_eps(const void *params, double l)
{
	const lre_params *p = params;
	double complex eps = p->eps_inf * (1.0 - 1.0 / (p->lp * p->lp * (1.0 / (l * l) +
	                                                               I / (p->mp * l))));
	for (int j = 0; j < 2; j++)
		eps += p->a[j] / p->l[j] *
		       (cexp(I * p->phi[j]) / (1.0 / p->l[j] - 1.0 / l - I / p->m[j]) +
		        cexp(-I * p->phi[j]) / (1.0 / p->l[j] + 1.0 / l + I / p->m[j]));
	return eps;
}

static double complex ld_eps(const void *params, double lambda_nm)
{
	const ld_params *p = params;
	double w = HC_EV_NM / lambda_nm, wp2 = p->wp * p->wp;
	double complex eps = 1.0 - p->f0 * wp2 / (w * (w + I * p->g0));
	for (int j = 0; j < LD_MAX_OSC; j++)
		if (p->f[j] != 0.0)
			eps += p->f[j] * wp2 / (p->w[j] * p->w[j] - w * w - I * w * p->g[j]);
	return eps;
}

/* ---- Models by name ------------------------------------------------------------- */

typedef struct nk_model {
	const char *model, *element, *elements; /* elements: all this model has, for messages */
	double complex (*eps)(const void *params, double lambda_nm);
	const void *params;
} nk_model;

static const nk_model models[] = {
	{"rakic1998-ld", "Ag", "Ag, Au or Cu", ld_eps, &rakic1998_ld[0]},
	{"rakic1998-ld", "Au", "Ag, Au or Cu", ld_eps, &rakic1998_ld[1]},
	{"rakic1998-ld", "Cu", "Ag, Au or Cu", ld_eps, &rakic1998_ld[2]},
	{"vial-laroche2008-dcp", "Ag", "Ag or Au", dcp_eps, &vial_laroche2008_ag},
	{"vial-laroche2008-dcp", "Au", "Ag or Au", dcp_eps, &vial_laroche2008_au},
	{"vial2008ch-dcp", "Ag", "Ag, Au or Cu", dcp_eps, &vial2008ch_ag},
	{"vial2008ch-dcp", "Au", "Ag, Au or Cu", dcp_eps, &vial2008ch_au},
	{"vial2008ch-dcp", "Cu", "Ag, Au or Cu", dcp_eps, &vial2008ch_cu},
	{"leru-etchegoin2009", "Au", "Au", lre_eps, &leru_etchegoin2009_au},
};
#define NMODELS (sizeof(models) / sizeof(models[0]))

static const char model_names[] =
	"rakic1998-ld, vial-laroche2008-dcp, vial2008ch-dcp or leru-etchegoin2009";

static const nk_model *model_find(const char *model, const char *element, kg_err *err)
{
	const nk_model *known = NULL;
	for (size_t i = 0; model && i < NMODELS; i++) {
		if (strcmp(model, models[i].model) != 0)
			continue;
		known = &models[i];
		if (element && strcasecmp(element, models[i].element) == 0)
			return &models[i];
	}
	if (!known)
		kg_fail(err, KG_ENOTSUP, "model '%s' is not known: expected %s",
		        model ? model : "(none)", model_names);
	else
		kg_fail(err, KG_ENOTSUP, "%s: element '%s': expected %s", model,
		        element ? element : "(none)", known->elements);
	return NULL;
}

/* n + ik = sqrt(eps), principal root, so n >= 0 and k has the sign of Im eps. A fit may
 * let Im eps dip slightly below 0 where the metal absorbs little (vial-laroche2008-dcp
 * for Ag does, by up to 0.12 at 410-595 nm, while J&C have +0.2..+0.4: a property of the
 * published parameters, checked in tests/optics/test_nk.c). The index is then taken
 * from conj(eps), i.e. k -> |k|: the Fresnel amplitudes become their complex
 * conjugates, so the reflectance at every angle is exactly the published model's,
 * while n, k >= 0 hold as the materials require. */
static void model_eval(const nk_model *m, double lambda_nm, double *n, double *k)
{
	double complex eps = m->eps(m->params, lambda_nm);
	double complex nk = csqrt(cimag(eps) < 0.0 ? conj(eps) : eps);
	*n = creal(nk);
	*k = cimag(nk);
}

int kg_nk_model_at(const char *model, const char *element, double lambda_nm, double *n,
                   double *k, kg_err *err)
{
	kg_check_arg(n && k, err);
	const nk_model *m = model_find(model, element, err);
	if (!m)
		return KG_ENOTSUP;
	if (!(lambda_nm > 0.0) || !isfinite(lambda_nm))
		return kg_fail(err, KG_EINVAL, "%s: wavelength %g nm: expected a positive number",
		               model, lambda_nm);
	model_eval(m, lambda_nm, n, k);
	return 0;
}

int kg_nk_model(const char *model, const char *element, kg_nk *out, kg_err *err)
{
	kg_check_arg(out, err);
	const nk_model *m = model_find(model, element, err);
	if (!m)
		return KG_ENOTSUP;
	for (int i = 0; i < KG_NBANDS; i++)
		model_eval(m, kg_band_nm(i), &out->n.v[i], &out->k.v[i]);
	return 0;
}

int kg_nk_rakic1998_ld_at(const char *element, double lambda_nm, double *n, double *k,
                          kg_err *err)
{
	return kg_nk_model_at("rakic1998-ld", element, lambda_nm, n, k, err);
}

int kg_nk_rakic1998_ld(const char *element, kg_nk *out, kg_err *err)
{
	return kg_nk_model("rakic1998-ld", element, out, err);
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
