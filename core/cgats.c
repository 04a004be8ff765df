#include <ctype.h>
#include <limits.h>
#include <stdint.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "cgats.h"
#include "escape.h"
#include "fsutil.h"
#include "text.h"

/* Largest NUMBER_OF_FIELDS accepted; real files have at most a few hundred. */
#define MAX_FIELDS 100000

/* ------------------------------------------------------------------------------- */
/* Tables in memory                                                                 */

static void table_free(kg_cgats_table *t)
{
	if (!t)
		return;
	free(t->type);
	for (int i = 0; i < t->nkeywords; i++) {
		free(t->keywords[i].name);
		free(t->keywords[i].value);
	}
	free(t->keywords);
	for (int i = 0; i < t->nfields; i++)
		free(t->fields[i]);
	free(t->fields);
	if (t->cells)
		for (size_t i = 0; i < (size_t)t->nsets * (size_t)t->nfields; i++)
			free(t->cells[i]);
	free(t->cells);
	free(t->set_lines);
	free(t);
}

void kg_cgats_free(kg_cgats **cg)
{
	if (!cg || !*cg)
		return;
	for (int i = 0; i < (*cg)->ntables; i++)
		table_free((*cg)->tables[i]);
	free((*cg)->tables);
	free((*cg)->path);
	free(*cg);
	*cg = NULL;
}

static kg_cgats *cgats_alloc(const char *path)
{
	kg_cgats *cg = calloc(1, sizeof(*cg));
	if (!cg)
		return NULL;
	cg->path = strdup(path ? path : "<memory>");
	if (!cg->path) {
		free(cg);
		return NULL;
	}
	return cg;
}

static kg_cgats_table *cgats_push_table(kg_cgats *cg, const char *type, int line)
{
	kg_cgats_table **tables = realloc(cg->tables, sizeof(*tables) * (cg->ntables + 1));
	if (!tables)
		return NULL;
	cg->tables = tables;
	kg_cgats_table *t = calloc(1, sizeof(*t));
	if (!t)
		return NULL;
	t->type = strdup(type);
	if (!t->type) {
		free(t);
		return NULL;
	}
	t->path = cg->path;
	t->line = line;
	cg->tables[cg->ntables++] = t;
	return t;
}

/* Make room for element n of an array of n elements grown by doubling (capacity 8,
 * 16, 32, ...: it follows from the count, so it need not be stored). Returns the
 * array, possibly moved, or NULL when out of memory (the old array is kept). */
static void *grow(void *array, int n, size_t elem)
{
	if (n > 0 && (n < 8 || (n & (n - 1)) != 0))
		return array;
	size_t cap = n ? 2 * (size_t)n : 8;
	return realloc(array, cap * elem);
}

static int table_push_keyword(kg_cgats_table *t, const char *name, const char *value,
                              int line)
{
	kg_cgats_kw *kw = grow(t->keywords, t->nkeywords, sizeof(*kw));
	if (!kw)
		return KG_ENOMEM;
	t->keywords = kw;
	char *n = strdup(name), *v = strdup(value);
	if (!n || !v) {
		free(n);
		free(v);
		return KG_ENOMEM;
	}
	kw[t->nkeywords++] = (kg_cgats_kw){ .name = n, .value = v, .line = line };
	return 0;
}

static int table_push_field(kg_cgats_table *t, const char *name)
{
	char **f = grow(t->fields, t->nfields, sizeof(*f));
	if (!f)
		return KG_ENOMEM;
	t->fields = f;
	if (!(f[t->nfields] = strdup(name)))
		return KG_ENOMEM;
	t->nfields++;
	return 0;
}

/* Append a set whose nfields cells are taken over (they must be heap strings). On
 * failure the cells are freed. */
static int table_push_set(kg_cgats_table *t, char **cells, int line)
{
	if (t->nsets == t->cap_sets) {
		int cap = t->cap_sets ? t->cap_sets * 2 : 16;
		if (cap <= t->cap_sets || (size_t)cap > SIZE_MAX / sizeof(char *) / (size_t)t->nfields)
			goto fail;
		char **c = realloc(t->cells, sizeof(*c) * (size_t)cap * (size_t)t->nfields);
		if (!c)
			goto fail;
		t->cells = c;
		int *l = realloc(t->set_lines, sizeof(*l) * (size_t)cap);
		if (!l)
			goto fail;
		t->set_lines = l;
		t->cap_sets = cap;
	}
	memcpy(t->cells + (size_t)t->nsets * (size_t)t->nfields, cells,
	       sizeof(*cells) * (size_t)t->nfields);
	t->set_lines[t->nsets++] = line;
	return 0;
fail:
	for (int i = 0; i < t->nfields; i++)
		free(cells[i]);
	return KG_ENOMEM;
}

/* ------------------------------------------------------------------------------- */
/* Numbers                                                                          */

int kg_cgats_parse_number(const char *text, double *out)
{
	if (!text || !*text)
		return KG_EINVAL;
	/* Plain decimal notation only: strtod alone would also take "nan", "inf" and
	 * hexadecimal floats. */
	for (const char *p = text; *p; p++)
		if (!isdigit((unsigned char)*p) && !strchr("+-.eE", *p))
			return KG_EINVAL;
	char *end;
	double v = strtod(text, &end);
	if (end == text || *end || !isfinite(v))
		return KG_EINVAL;
	*out = v;
	return 0;
}

/* Shortest of %.15g..%.17g that reads back to the same double. */
static void format_number(char *buf, size_t size, double v)
{
	for (int prec = 15; prec <= 17; prec++) {
		snprintf(buf, size, "%.*g", prec, v);
		if (strtod(buf, NULL) == v)
			return;
	}
}

/* Decimal text of v x 10^shift, exact in decimal: the shortest digits that read back
 * as v, with the decimal point moved. Always holds a '.' or an exponent, as ArgyllCMS
 * types a column of bare integers as integers and then refuses it as spectral data.
 * parse_number_shifted(text, -shift) gives v back bit for bit. */
static void format_number_shifted(char *buf, size_t size, double v, int shift)
{
	char e[40];
	for (int prec = 14; prec <= 16; prec++) {
		snprintf(e, sizeof(e), "%.*e", prec, v);
		if (strtod(e, NULL) == v)
			break;
	}
	/* e is [-]d.ddd...e[+-]xx */
	const char *p = e;
	int neg = *p == '-';
	p += neg;
	char digits[24];
	int nd = 0;
	for (; *p && *p != 'e'; p++)
		if (isdigit((unsigned char)*p))
			digits[nd++] = *p;
	while (nd > 1 && digits[nd - 1] == '0')
		nd--;
	digits[nd] = '\0';
	int exp10 = atoi(p + 1) + (v == 0.0 ? 0 : shift);
	if (exp10 < -6 || exp10 > 20) {
		snprintf(buf, size, "%s%c.%se%d", neg ? "-" : "", digits[0],
		         nd > 1 ? digits + 1 : "0", exp10);
		return;
	}
	char out[64];
	int m = 0;
	if (neg)
		out[m++] = '-';
	if (exp10 < 0) {
		out[m++] = '0';
		out[m++] = '.';
		for (int i = 0; i < -exp10 - 1; i++)
			out[m++] = '0';
		for (int i = 0; i < nd; i++)
			out[m++] = digits[i];
	} else {
		for (int i = 0; i <= exp10; i++)
			out[m++] = i < nd ? digits[i] : '0';
		out[m++] = '.';
		if (nd > exp10 + 1)
			for (int i = exp10 + 1; i < nd; i++)
				out[m++] = digits[i];
		else
			out[m++] = '0';
	}
	out[m] = '\0';
	snprintf(buf, size, "%s", out);
}

/* A finite decimal number times 10^shift, rounded once: the decimal exponent is moved
 * in the text before conversion, so that text written by format_number_shifted(v, s)
 * reads back as exactly v with shift -s (a division would round a second time). */
static int parse_number_shifted(const char *text, int shift, double *out)
{
	double v;
	if (kg_cgats_parse_number(text, &v) != 0)
		return KG_EINVAL;
	const char *e = strpbrk(text, "eE");
	size_t mlen = e ? (size_t)(e - text) : strlen(text);
	long exp10 = e ? strtol(e + 1, NULL, 10) : 0;
	char buf[128];
	if (shift == 0 || mlen > 64 || exp10 < -100000 || exp10 > 100000) {
		*out = shift ? v * pow(10.0, shift) : v;
		return isfinite(*out) ? 0 : KG_EINVAL;
	}
	snprintf(buf, sizeof(buf), "%.*se%ld", (int)mlen, text, exp10 + shift);
	*out = strtod(buf, NULL);
	return isfinite(*out) ? 0 : KG_EINVAL;
}

static const char *not_a_number_hint(const char *text)
{
	char low[8] = { 0 };
	for (int i = 0; i < 7 && text[i]; i++)
		low[i] = (char)tolower((unsigned char)text[i]);
	if (strstr(low, "nan") || strstr(low, "inf"))
		return " (NaN and infinity are not accepted)";
	char *end;
	if (*text && strspn(text, "0123456789+-.eE") == strlen(text) &&
	    isinf(strtod(text, &end)) && !*end)
		return " (beyond the largest number a double holds, about 1.8e308)";
	return "";
}

/* ------------------------------------------------------------------------------- */
/* Parsing                                                                          */

typedef struct tokens {
	char *buf; /* copy of the line, tokens are NUL-terminated inside it */
	size_t cap;
	char **tok;
	int n, cap_tok;
	int first_quoted; /* the first token was "quoted" (a cell, never END_DATA) */
} tokens;

static void tokens_free(tokens *tk)
{
	free(tk->buf);
	free(tk->tok);
}

/* Split a line into tokens: runs of non-blanks, or "quoted strings" (quotes removed).
 * '#' outside quotes starts a comment. */
static int tokenize(tokens *tk, const char *line, size_t len, const char *path, int lineno,
                    kg_err *err)
{
	if (len + 1 > tk->cap) {
		char *b = realloc(tk->buf, len + 1);
		if (!b)
			return kg_fail(err, KG_ENOMEM, "%s: line %d: out of memory", path, lineno);
		tk->buf = b;
		tk->cap = len + 1;
	}
	memcpy(tk->buf, line, len);
	tk->buf[len] = '\0';
	tk->n = 0;
	tk->first_quoted = 0;
	char *p = tk->buf, *end = tk->buf + len;
	while (p < end) {
		while (p < end && isspace((unsigned char)*p))
			p++;
		if (p >= end || *p == '#')
			break;
		char *start;
		if (*p == '"') {
			tk->first_quoted |= tk->n == 0;
			start = ++p;
			char *q = memchr(p, '"', (size_t)(end - p));
			if (!q)
				return kg_fail(err, KG_EINVAL, "%s: line %d: unterminated quoted string: "
				               "expected a closing '\"'", path, lineno);
			*q = '\0';
			p = q + 1;
		} else {
			start = p;
			while (p < end && !isspace((unsigned char)*p))
				p++;
			*p++ = '\0';
		}
		if (tk->n == tk->cap_tok) {
			int cap = tk->cap_tok ? tk->cap_tok * 2 : 32;
			char **t = realloc(tk->tok, sizeof(*t) * (size_t)cap);
			if (!t)
				return kg_fail(err, KG_ENOMEM, "%s: line %d: out of memory", path, lineno);
			tk->tok = t;
			tk->cap_tok = cap;
		}
		tk->tok[tk->n++] = start;
	}
	return 0;
}

enum parse_state { EXPECT_TYPE, HEADER, FORMAT, DATA };

typedef struct parser {
	kg_cgats *cg;
	kg_cgats_table *t;
	const char *path;
	enum parse_state state;
	/* NUMBER_OF_FIELDS (-1 if absent). The field list is authoritative: argyll-ref's
	 * ColorChecker.ti2 and FograStrip3.ti1 declare 9 fields, list 8 and have 8 values
	 * per set. A count that disagrees is only mentioned when a set's length is wrong. */
	int declared_fields, fields_line;
	int declared_sets, sets_line;     /* NUMBER_OF_SETS, -1 if absent */
	int format_done;
	int data_line; /* line of BEGIN_DATA */
} parser;

static int parse_count(const char *text, int max, int *out)
{
	double v;
	if (kg_cgats_parse_number(text, &v) != 0 || v != floor(v) || v < 0 || v > max)
		return KG_EINVAL;
	*out = (int)v;
	return 0;
}

static int format_line(parser *ps, tokens *tk, int lineno, kg_err *err)
{
	for (int i = 0; i < tk->n; i++) {
		const char *w = tk->tok[i];
		if (strcmp(w, "END_DATA_FORMAT") == 0) {
			if (i + 1 < tk->n)
				return kg_fail(err, KG_EINVAL, "%s: line %d: '%.40s' after END_DATA_FORMAT: "
				               "expected nothing more on the line", ps->path, lineno,
				               tk->tok[i + 1]);
			if (ps->t->nfields == 0)
				return kg_fail(err, KG_EINVAL, "%s: line %d: BEGIN_DATA_FORMAT lists no "
				               "fields: expected field names such as SAMPLE_ID", ps->path,
				               lineno);
			ps->state = HEADER;
			ps->format_done = 1;
			return 0;
		}
		if (kg_cgats_reserved(w))
			return kg_fail(err, KG_EINVAL, "%s: line %d: %s inside the field list: "
			               "expected END_DATA_FORMAT first", ps->path, lineno, w);
		if (ps->t->nfields >= MAX_FIELDS)
			return kg_fail(err, KG_EINVAL, "%s: line %d: more than %d fields", ps->path,
			               lineno, MAX_FIELDS);
		if (table_push_field(ps->t, w) != 0)
			return kg_fail(err, KG_ENOMEM, "%s: out of memory", ps->path);
	}
	return 0;
}

static int header_line(parser *ps, tokens *tk, int lineno, kg_err *err)
{
	kg_cgats_table *t = ps->t;
	const char *w = tk->tok[0];
	if (strcmp(w, "KEYWORD") == 0) {
		if (tk->n != 2)
			return kg_fail(err, KG_EINVAL, "%s: line %d: KEYWORD: expected one quoted "
			               "name, found %d items", ps->path, lineno, tk->n - 1);
		return 0;
	}
	if (strcmp(w, "NUMBER_OF_FIELDS") == 0 || strcmp(w, "NUMBER_OF_SETS") == 0) {
		int fields = strcmp(w, "NUMBER_OF_FIELDS") == 0, v;
		if (tk->n != 2 || parse_count(tk->tok[1], fields ? MAX_FIELDS : INT_MAX, &v) != 0)
			return kg_fail(err, KG_EINVAL, "%s: line %d: %s: expected a non-negative "
			               "integer, found '%.40s'", ps->path, lineno, w,
			               tk->n > 1 ? tk->tok[1] : "");
		int *dst = fields ? &ps->declared_fields : &ps->declared_sets;
		if (*dst >= 0 && *dst != v)
			return kg_fail(err, KG_EINVAL, "%s: line %d: %s: given twice with different "
			               "values (%d and %d)", ps->path, lineno, w, *dst, v);
		*dst = v;
		if (fields)
			ps->fields_line = lineno;
		else
			ps->sets_line = lineno;
		return 0;
	}
	if (strcmp(w, "BEGIN_DATA_FORMAT") == 0) {
		if (ps->format_done)
			return kg_fail(err, KG_EINVAL, "%s: line %d: second BEGIN_DATA_FORMAT in one "
			               "table: expected BEGIN_DATA", ps->path, lineno);
		ps->state = FORMAT;
		tokens rest = { .tok = tk->tok + 1, .n = tk->n - 1 };
		return format_line(ps, &rest, lineno, err);
	}
	if (strcmp(w, "BEGIN_DATA") == 0) {
		if (!ps->format_done || t->nfields == 0)
			return kg_fail(err, KG_EINVAL, "%s: line %d: BEGIN_DATA before the field "
			               "names: expected BEGIN_DATA_FORMAT ... END_DATA_FORMAT first",
			               ps->path, lineno);
		ps->state = DATA;
		ps->data_line = lineno;
		return 0;
	}
	if (strcmp(w, "END_DATA_FORMAT") == 0 || strcmp(w, "END_DATA") == 0)
		return kg_fail(err, KG_EINVAL, "%s: line %d: %s without its BEGIN: expected "
		               "BEGIN_DATA_FORMAT or BEGIN_DATA", ps->path, lineno, w);

	/* A keyword: one value (usually quoted); a bare value with blanks is joined. */
	const char *value = "";
	char *joined = NULL;
	if (tk->n == 2)
		value = tk->tok[1];
	else if (tk->n > 2) {
		size_t len = 0;
		for (int i = 1; i < tk->n; i++)
			len += strlen(tk->tok[i]) + 1;
		joined = malloc(len);
		if (!joined)
			return kg_fail(err, KG_ENOMEM, "%s: out of memory", ps->path);
		char *end = joined;
		for (int i = 1; i < tk->n; i++) {
			size_t n = strlen(tk->tok[i]);
			memcpy(end, tk->tok[i], n);
			end += n;
			*end++ = ' ';
		}
		end[-1] = '\0';
		value = joined;
	}
	int r = table_push_keyword(t, w, value, lineno);
	free(joined);
	if (r != 0)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", ps->path);
	return 0;
}

static int data_line(parser *ps, tokens *tk, int lineno, kg_err *err)
{
	kg_cgats_table *t = ps->t;
	if (strcmp(tk->tok[0], "END_DATA") == 0 && tk->n == 1 && !tk->first_quoted) {
		if (ps->declared_sets >= 0 && ps->declared_sets != t->nsets)
			return kg_fail(err, KG_EINVAL, "%s: line %d: NUMBER_OF_SETS is %d (line %d) but "
			               "the data have %d sets", ps->path, lineno, ps->declared_sets,
			               ps->sets_line, t->nsets);
		ps->state = EXPECT_TYPE;
		return 0;
	}
	if (tk->n != t->nfields) {
		char note[96] = "";
		if (ps->declared_fields >= 0 && ps->declared_fields != t->nfields)
			snprintf(note, sizeof(note), "; NUMBER_OF_FIELDS (line %d) says %d",
			         ps->fields_line, ps->declared_fields);
		return kg_fail(err, KG_EINVAL, "%s: line %d: set %d has %d values, expected %d "
		               "(one per field, %.60s ... %.60s%s)", ps->path, lineno, t->nsets + 1, tk->n,
		               t->nfields, t->fields[0], t->fields[t->nfields - 1], note);
	}
	char **cells = malloc(sizeof(*cells) * (size_t)t->nfields);
	if (!cells)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", ps->path);
	for (int i = 0; i < t->nfields; i++) {
		if (!(cells[i] = strdup(tk->tok[i]))) {
			for (int j = 0; j < i; j++)
				free(cells[j]);
			free(cells);
			return kg_fail(err, KG_ENOMEM, "%s: out of memory", ps->path);
		}
	}
	int r = table_push_set(t, cells, lineno);
	free(cells);
	if (r != 0)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", ps->path);
	return 0;
}

static int parse_line(parser *ps, tokens *tk, int lineno, kg_err *err)
{
	if (tk->n == 0)
		return 0;
	switch (ps->state) {
	case EXPECT_TYPE:
		if (tk->n != 1 || kg_cgats_reserved(tk->tok[0]))
			return kg_fail(err, KG_EINVAL, "%s: line %d: expected a file-type identifier "
			               "line (e.g. CGATS.17, CTI3, SPECT), found '%.40s'", ps->path,
			               lineno, tk->tok[0]);
		if (!(ps->t = cgats_push_table(ps->cg, tk->tok[0], lineno)))
			return kg_fail(err, KG_ENOMEM, "%s: out of memory", ps->path);
		ps->state = HEADER;
		ps->declared_fields = ps->declared_sets = -1;
		ps->fields_line = ps->sets_line = 0;
		ps->format_done = 0;
		return 0;
	case HEADER:
		return header_line(ps, tk, lineno, err);
	case FORMAT:
		return format_line(ps, tk, lineno, err);
	case DATA:
		return data_line(ps, tk, lineno, err);
	}
	return 0;
}

int kg_cgats_parse(const char *buf, size_t len, const char *name, kg_cgats **out,
                   kg_err *err)
{
	kg_check_arg(out && (buf || len == 0), err);
	*out = NULL;
	parser ps = { .state = EXPECT_TYPE };
	tokens tk = { 0 };
	if (!(ps.cg = cgats_alloc(name)))
		return kg_fail(err, KG_ENOMEM, "out of memory");
	ps.path = ps.cg->path;
	/* Every string kept is UTF-8, so that any of them may reach JSON or HTML. */
	char *converted = NULL;
	int r = kg_text_utf8(buf, len, ps.path, &buf, &len, &converted, err);

	int lineno = 0;
	size_t pos = 0;
	while (pos < len && r == 0) {
		lineno++;
		const char *line = buf + pos;
		const char *nl = memchr(line, '\n', len - pos);
		size_t n = nl ? (size_t)(nl - line) : len - pos;
		pos += n + (nl ? 1 : 0);
		if (n > KG_CGATS_MAX_LINE) {
			r = kg_fail(err, KG_EINVAL, "%s: line %d: line is longer than %d bytes: "
			            "expected CGATS text", ps.path, lineno, KG_CGATS_MAX_LINE);
			break;
		}
		if (memchr(line, '\0', n)) {
			r = kg_fail(err, KG_EINVAL, "%s: line %d: NUL byte: expected CGATS text",
			            ps.path, lineno);
			break;
		}
		if (n > 0 && line[n - 1] == '\r')
			n--;
		r = tokenize(&tk, line, n, ps.path, lineno, err);
		if (r == 0)
			r = parse_line(&ps, &tk, lineno, err);
	}
	tokens_free(&tk);
	free(converted);

	if (r == 0) {
		switch (ps.state) {
		case EXPECT_TYPE:
			if (ps.cg->ntables == 0)
				r = kg_fail(err, KG_EINVAL, "%s: no CGATS table (empty input): expected a "
				            "file-type identifier line such as CGATS.17", ps.path);
			break;
		case HEADER:
			r = kg_fail(err, KG_EINVAL, "%s: line %d: end of file in the header of the "
			            "table starting at line %d: expected %s", ps.path, lineno,
			            ps.t->line, ps.format_done ? "BEGIN_DATA" : "BEGIN_DATA_FORMAT");
			break;
		case FORMAT:
			r = kg_fail(err, KG_EINVAL, "%s: line %d: end of file in the field list: "
			            "expected END_DATA_FORMAT", ps.path, lineno);
			break;
		case DATA:
			r = kg_fail(err, KG_EINVAL, "%s: line %d: end of file after %d sets (file "
			            "truncated?): expected END_DATA for BEGIN_DATA at line %d",
			            ps.path, lineno, ps.t->nsets, ps.data_line);
			break;
		}
	}
	if (r != 0) {
		kg_cgats_free(&ps.cg);
		return r;
	}
	*out = ps.cg;
	return 0;
}

int kg_cgats_read(const char *path, kg_cgats **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	char *buf;
	size_t len;
	int r = kg_read_file(path, &buf, &len, err);
	if (r != 0)
		return r;
	r = kg_cgats_parse(buf, len, path, out, err);
	free(buf);
	return r;
}

/* ------------------------------------------------------------------------------- */
/* Access                                                                           */

int kg_cgats_field(const kg_cgats_table *t, const char *name)
{
	if (!t || !name)
		return -1;
	for (int i = 0; i < t->nfields; i++)
		if (strcmp(t->fields[i], name) == 0)
			return i;
	return -1;
}

const char *kg_cgats_keyword(const kg_cgats_table *t, const char *name)
{
	if (!t || !name)
		return NULL;
	for (int i = 0; i < t->nkeywords; i++)
		if (strcmp(t->keywords[i].name, name) == 0)
			return t->keywords[i].value;
	return NULL;
}

int kg_cgats_keyword_number(const kg_cgats_table *t, const char *name, double *out,
                            kg_err *err)
{
	kg_check_arg(t && name && out, err);
	for (int i = 0; i < t->nkeywords; i++) {
		const kg_cgats_kw *kw = &t->keywords[i];
		if (strcmp(kw->name, name) != 0)
			continue;
		if (kg_cgats_parse_number(kw->value, out) == 0)
			return 0;
		if (kw->line > 0)
			return kg_fail(err, KG_EINVAL, "%s: line %d: keyword %.60s: expected a number, "
			               "found '%.40s'%s", t->path, kw->line, name, kw->value,
			               not_a_number_hint(kw->value));
		return kg_fail(err, KG_EINVAL, "%s: keyword %.60s: expected a number, found '%.40s'%s",
		               t->path, name, kw->value, not_a_number_hint(kw->value));
	}
	return kg_fail(err, KG_ENOENT, "%s: keyword %s: missing", t->path, name);
}

const char *kg_cgats_cell(const kg_cgats_table *t, int set, int field)
{
	if (!t || set < 0 || set >= t->nsets || field < 0 || field >= t->nfields)
		return NULL;
	return t->cells[(size_t)set * (size_t)t->nfields + (size_t)field];
}

/* "line N" for a set read from a file, "set N" for one built in memory. */
static const char *set_where(const kg_cgats_table *t, int set, char buf[32])
{
	if (t->set_lines[set] > 0)
		snprintf(buf, 32, "line %d", t->set_lines[set]);
	else
		snprintf(buf, 32, "set %d", set + 1);
	return buf;
}

int kg_cgats_number(const kg_cgats_table *t, int set, int field, double *out,
                    kg_err *err)
{
	kg_check_arg(t && out, err);
	const char *c = kg_cgats_cell(t, set, field);
	if (!c)
		return kg_fail(err, KG_EINVAL, "%s: no cell at set %d, field %d", t->path, set + 1,
		               field + 1);
	if (kg_cgats_parse_number(c, out) == 0)
		return 0;
	char where[32];
	return kg_fail(err, KG_EINVAL, "%s: %s: field %.60s: expected a number, found "
	               "'%.40s'%s", t->path, set_where(t, set, where), t->fields[field], c,
	               not_a_number_hint(c));
}

/* Wavelengths a spectral field may name, nm: from the vacuum ultraviolet to the mid
 * infrared, wider than any colour instrument reads and narrow enough to catch a name
 * misread (SPEC_5, or SPEC_50000 read as picometres). */
#define SPEC_NM_MIN 100.0
#define SPEC_NM_MAX 5000.0

/* The wavelength part of a spectral field name, or NULL for a field of another kind:
 * CGATS.17's SPEC_<nm> (ArgyllCMS, colord), X-Rite i1Profiler's SPECTRAL_NM<nm> (also
 * SPECTRAL_NM_<nm>) and X-Rite MeasureTool's nm<nm>, each in any case. A name with one
 * of these prefixes is spectral whatever follows ("nmInf", "nm-5", "nm", "SPEC_"). */
static const char *spec_name_number(const char *name)
{
	if (strncasecmp(name, "SPEC_", 5) == 0)
		return name + 5;
	if (strncasecmp(name, "SPECTRAL_NM", 11) == 0)
		return name + 11 + (name[11] == '_');
	if (strncasecmp(name, "NM", 2) == 0)
		return name + 2;
	return NULL;
}

/* What a field name says of its wavelength (spec_name_nm). */
enum spec_name_kind {
	SPEC_NAME_OTHER = 0,    /* not a spectral field */
	SPEC_NAME_NM = 1,       /* a spectral field; *nm holds its wavelength */
	SPEC_NAME_NO_NUMBER = -1, /* a spectral prefix without a plain number after it */
	SPEC_NAME_OUT_OF_RANGE = -2, /* a number outside SPEC_NM_MIN..SPEC_NM_MAX (*nm) */
};

/* Wavelength in a spectral field name (spec_name_number). A spectral name that does not
 * hold a plausible wavelength must not be passed over: dropping a band would
 * interpolate across the gap. colord writes picometres (SPEC_300000 = 300 nm): numbers
 * from 10000 up are read so. */
static enum spec_name_kind spec_name_nm(const char *name, double *nm)
{
	const char *num = spec_name_number(name);
	if (!num)
		return SPEC_NAME_OTHER;
	double v;
	if (kg_cgats_parse_number(num, &v) != 0)
		return SPEC_NAME_NO_NUMBER;
	if (v >= 10000)
		v /= 1000;
	*nm = v;
	return v >= SPEC_NM_MIN && v <= SPEC_NM_MAX ? SPEC_NAME_NM : SPEC_NAME_OUT_OF_RANGE;
}

/* The refusal of a spectral field name whose wavelength is unreadable or implausible. */
static int refuse_spec_name(const kg_cgats_table *t, const char *name,
                            enum spec_name_kind kind, double nm, kg_err *err)
{
	if (kind == SPEC_NAME_NO_NUMBER)
		return kg_fail(err, KG_EINVAL, "%s: field %.60s: expected SPEC_<nm> (or X-Rite's "
		               "SPECTRAL_NM<nm>, nm<nm>) with a finite wavelength in nm as a plain "
		               "number (e.g. SPEC_550, nm550)", t->path, name);
	double raw = nm;
	kg_cgats_parse_number(spec_name_number(name), &raw);
	return kg_fail(err, KG_EINVAL, "%s: field %.60s: %g nm%s: expected a wavelength between "
	               "%g and %g nm", t->path, name, nm,
	               raw >= 10000 ? " (a number from 10000 up is read as picometres)" : "",
	               SPEC_NM_MIN, SPEC_NM_MAX);
}

/* The spectral keywords a table gives (each may be absent). */
typedef struct spectral_keywords {
	int have_start, have_end, have_bands;
	double start, end, bands;
} spectral_keywords;

static int read_spectral_keywords(const kg_cgats_table *t, spectral_keywords *k,
                                  kg_err *err)
{
	static const char *const names[3] = { "SPECTRAL_START_NM", "SPECTRAL_END_NM",
		                                  "SPECTRAL_BANDS" };
	int *have[3] = { &k->have_start, &k->have_end, &k->have_bands };
	double *val[3] = { &k->start, &k->end, &k->bands };
	for (int i = 0; i < 3; i++) {
		int r = kg_cgats_keyword_number(t, names[i], val[i], err);
		if (r == KG_ENOENT)
			continue;
		if (r != 0)
			return r;
		*have[i] = 1;
	}
	if (k->have_bands && (k->bands != floor(k->bands) || k->bands < 1))
		return kg_fail(err, KG_EINVAL, "%s: keyword SPECTRAL_BANDS: expected a positive "
		               "whole number, found %g", t->path, k->bands);
	return 0;
}

/* Field names and keywords must describe the same wavelengths: ArgyllCMS finds its
 * fields by the names the keyword grid rounds to (spec2cie refuses GTIPlus.sp, whose
 * keywords say 80 bands to 750 nm over 40 fields to 730 nm), so a disagreement means
 * one of the two is wrong. Names may be rounded (Argyll's 3.33 nm steps): 1 nm. */
static int check_spectral_keywords(const kg_cgats_table *t, const spectral_keywords *k,
                                   const int *idx, const double *w, int count, kg_err *err)
{
	const double tol = 1.0;
	if (k->have_bands && k->bands != count)
		return kg_fail(err, KG_EINVAL, "%s: keyword SPECTRAL_BANDS is %g but the table has "
		               "%d SPEC_<nm> fields (%.60s ... %.60s): expected one field per band",
		               t->path, k->bands, count, t->fields[idx[0]], t->fields[idx[count - 1]]);
	if (k->have_start && fabs(k->start - w[0]) > tol)
		return kg_fail(err, KG_EINVAL, "%s: keyword SPECTRAL_START_NM is %g but the first "
		               "spectral field is %.60s (%g nm): expected them to agree within 1 nm",
		               t->path, k->start, t->fields[idx[0]], w[0]);
	if (k->have_end && fabs(k->end - w[count - 1]) > tol)
		return kg_fail(err, KG_EINVAL, "%s: keyword SPECTRAL_END_NM is %g but the last "
		               "spectral field is %.60s (%g nm): expected them to agree within 1 nm",
		               t->path, k->end, t->fields[idx[count - 1]], w[count - 1]);
	if (!(k->have_start && k->have_end && k->have_bands) || count < 2)
		return 0;
	for (int i = 0; i < count; i++) {
		double at = k->start + (k->end - k->start) * i / (count - 1);
		if (fabs(at - w[i]) > tol)
			return kg_fail(err, KG_EINVAL, "%s: field %.60s (%g nm) is spectral field %d, "
			               "where SPECTRAL_START_NM %g, SPECTRAL_END_NM %g and "
			               "SPECTRAL_BANDS %g put %g nm: expected the fields in the "
			               "keywords' order and spacing", t->path, t->fields[idx[i]], w[i],
			               i + 1, k->start, k->end, k->bands, at);
	}
	return 0;
}

int kg_cgats_spectral_fields(const kg_cgats_table *t, int **fields, double **wl, int *n,
                             kg_err *err)
{
	kg_check_arg(t && fields && wl && n, err);
	*fields = NULL;
	*wl = NULL;
	*n = 0;
	int count = 0;
	double nm = 0;
	for (int i = 0; i < t->nfields; i++) {
		enum spec_name_kind kind = spec_name_nm(t->fields[i], &nm);
		if (kind < 0)
			return refuse_spec_name(t, t->fields[i], kind, nm, err);
		count += kind;
	}
	if (count == 0)
		return 0;
	int *idx = malloc(sizeof(*idx) * (size_t)count);
	double *w = malloc(sizeof(*w) * (size_t)count);
	if (!idx || !w) {
		free(idx);
		free(w);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", t->path);
	}
	int k = 0, r = 0;
	for (int i = 0; i < t->nfields; i++)
		if (spec_name_nm(t->fields[i], &w[k]) > 0)
			idx[k++] = i;
	for (int i = 1; i < count && r == 0; i++) {
		const char *f = t->fields[idx[i]], *prev = t->fields[idx[i - 1]];
		if (w[i] == w[i - 1])
			r = kg_fail(err, KG_EINVAL, "%s: fields %.60s and %.60s both hold %g nm: "
			            "expected each wavelength once", t->path, prev, f, w[i]);
		else if (w[i] < w[i - 1])
			r = kg_fail(err, KG_EINVAL, "%s: field %.60s: spectral fields must increase in "
			            "wavelength, found it after %.60s", t->path, f, prev);
	}
	spectral_keywords kw = { 0 };
	if (r == 0)
		r = read_spectral_keywords(t, &kw, err);
	if (r == 0)
		r = check_spectral_keywords(t, &kw, idx, w, count, err);
	if (r != 0) {
		free(idx);
		free(w);
		return r;
	}
	/* The keyword grid is exact where the names are rounded (3.33 nm steps). */
	if (kw.have_start && kw.have_end && kw.have_bands && count >= 2)
		for (int i = 0; i < count; i++)
			w[i] = kw.start + (kw.end - kw.start) * i / (count - 1);
	*fields = idx;
	*wl = w;
	*n = count;
	return 0;
}

/* ------------------------------------------------------------------------------- */
/* Building                                                                         */

int kg_cgats_new(const char *type, kg_cgats **out, kg_err *err)
{
	kg_check_arg(out, err);
	*out = NULL;
	kg_cgats *cg = cgats_alloc(NULL);
	if (!cg)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	kg_cgats_table *t;
	int r = kg_cgats_add_table(cg, type, &t, err);
	if (r != 0) {
		kg_cgats_free(&cg);
		return r;
	}
	*out = cg;
	return 0;
}

int kg_cgats_add_table(kg_cgats *cg, const char *type, kg_cgats_table **out,
                       kg_err *err)
{
	kg_check_arg(cg, err);
	if (!type)
		type = "CGATS.17";
	for (const char *p = type; *p; p++)
		if (isspace((unsigned char)*p) || *p == '"' || *p == '#')
			return kg_fail(err, KG_EINVAL, "table type '%.40s': expected one word such as "
			               "CGATS.17", type);
	if (!*type || kg_cgats_reserved(type))
		return kg_fail(err, KG_EINVAL, "table type '%.40s': expected one word such as "
		               "CGATS.17", type);
	kg_cgats_table *t = cgats_push_table(cg, type, 0);
	if (!t)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	if (out)
		*out = t;
	return 0;
}

static int check_name(const char *what, const char *name, kg_err *err)
{
	if (!*name)
		return kg_fail(err, KG_EINVAL, "%s name: expected a word, found an empty name", what);
	for (const char *p = name; *p; p++)
		if (isspace((unsigned char)*p) || *p == '"' || *p == '#')
			return kg_fail(err, KG_EINVAL, "%s name '%.40s': expected a word without "
			               "blanks, quotes or '#'", what, name);
	if (kg_cgats_reserved(name))
		return kg_fail(err, KG_EINVAL, "%s name %s: reserved by CGATS", what, name);
	return 0;
}

int kg_cgats_set_keyword(kg_cgats_table *t, const char *name, const char *value,
                         kg_err *err)
{
	kg_check_arg(t && name && value, err);
	int r = check_name("keyword", name, err);
	if (r != 0)
		return r;
	char what[96];
	snprintf(what, sizeof(what), "keyword %s: value", name);
	if ((r = kg_cgats_check(what, value, err)) != 0)
		return r;
	for (int i = 0; i < t->nkeywords; i++)
		if (strcmp(t->keywords[i].name, name) == 0) {
			char *v = strdup(value);
			if (!v)
				return kg_fail(err, KG_ENOMEM, "out of memory");
			free(t->keywords[i].value);
			t->keywords[i].value = v;
			return 0;
		}
	if (table_push_keyword(t, name, value, 0) != 0)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	return 0;
}

int kg_cgats_set_keyword_number(kg_cgats_table *t, const char *name, double value,
                                kg_err *err)
{
	if (!isfinite(value))
		return kg_fail(err, KG_EINVAL, "keyword %s: expected a finite number", name);
	char buf[64];
	format_number(buf, sizeof(buf), value);
	return kg_cgats_set_keyword(t, name, buf, err);
}

int kg_cgats_set_fields(kg_cgats_table *t, const char *const *names, int n, kg_err *err)
{
	kg_check_arg(t && names && n > 0 && n <= MAX_FIELDS, err);
	if (t->nsets > 0)
		return kg_fail(err, KG_EINVAL, "%s: cannot change the fields of a table that has "
		               "data", t->path);
	for (int i = 0; i < n; i++) {
		kg_check_arg(names[i], err);
		int r = check_name("field", names[i], err);
		if (r != 0)
			return r;
	}
	for (int i = 0; i < t->nfields; i++)
		free(t->fields[i]);
	free(t->fields);
	free(t->cells);
	free(t->set_lines);
	t->fields = NULL;
	t->cells = NULL;
	t->set_lines = NULL;
	t->nfields = t->cap_sets = 0;
	for (int i = 0; i < n; i++)
		if (table_push_field(t, names[i]) != 0)
			return kg_fail(err, KG_ENOMEM, "out of memory");
	return 0;
}

int kg_cgats_add_row(kg_cgats_table *t, const char *const *cells, kg_err *err)
{
	kg_check_arg(t && cells, err);
	if (t->nfields == 0)
		return kg_fail(err, KG_EINVAL, "%s: table has no fields: call kg_cgats_set_fields "
		               "first", t->path);
	char **copy = calloc((size_t)t->nfields, sizeof(*copy));
	if (!copy)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (int i = 0; i < t->nfields; i++) {
		if (!(copy[i] = strdup(cells[i] ? cells[i] : ""))) {
			for (int j = 0; j < i; j++)
				free(copy[j]);
			free(copy);
			return kg_fail(err, KG_ENOMEM, "out of memory");
		}
	}
	int r = table_push_set(t, copy, 0);
	free(copy);
	return r ? kg_fail(err, r, "out of memory") : 0;
}

int kg_cgats_append_set(kg_cgats_table *t, int *set, kg_err *err)
{
	kg_check_arg(t, err);
	if (t->nfields == 0)
		return kg_fail(err, KG_EINVAL, "%s: table has no fields: call kg_cgats_set_fields "
		               "first", t->path);
	char **empty = calloc((size_t)t->nfields, sizeof(*empty));
	if (!empty)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	int r = kg_cgats_add_row(t, (const char *const *)empty, err);
	free(empty);
	if (r == 0 && set)
		*set = t->nsets - 1;
	return r;
}

int kg_cgats_set_cell(kg_cgats_table *t, int set, int field, const char *text,
                      kg_err *err)
{
	kg_check_arg(t && text && set >= 0 && set < t->nsets && field >= 0 &&
	             field < t->nfields, err);
	char *c = strdup(text);
	if (!c)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	size_t k = (size_t)set * (size_t)t->nfields + (size_t)field;
	free(t->cells[k]);
	t->cells[k] = c;
	return 0;
}

int kg_cgats_set_cell_number(kg_cgats_table *t, int set, int field, double v,
                             kg_err *err)
{
	kg_check_arg(t && field >= 0 && field < t->nfields, err);
	if (!isfinite(v))
		return kg_fail(err, KG_EINVAL, "set %d: field %s: expected a finite number", set + 1,
		               t->fields[field]);
	char buf[64];
	format_number(buf, sizeof(buf), v);
	return kg_cgats_set_cell(t, set, field, buf, err);
}

int kg_cgats_add_row_numbers(kg_cgats_table *t, const char *first, const double *vals,
                             int nvals, kg_err *err)
{
	kg_check_arg(t && (vals || nvals == 0), err);
	int off = first ? 1 : 0;
	if (off + nvals != t->nfields)
		return kg_fail(err, KG_EINVAL, "%s: row of %d values for %d fields", t->path,
		               off + nvals, t->nfields);
	for (int i = 0; i < nvals; i++)
		if (!isfinite(vals[i]))
			return kg_fail(err, KG_EINVAL, "%s: field %s: expected a finite number",
			               t->path, t->fields[off + i]);
	int set;
	int r = kg_cgats_append_set(t, &set, err);
	if (r == 0 && first)
		r = kg_cgats_set_cell(t, set, 0, first, err);
	for (int i = 0; i < nvals && r == 0; i++)
		r = kg_cgats_set_cell_number(t, set, off + i, vals[i], err);
	return r;
}

/* ------------------------------------------------------------------------------- */
/* Writing                                                                          */

/* Keywords CGATS.17 predefines; any other keyword is declared with KEYWORD "NAME". */
static int standard_keyword(const char *name)
{
	static const char *const std[] = {
		"ORIGINATOR",       "DESCRIPTOR",         "CREATED",          "MANUFACTURER",
		"MANUFACTURE",      "PROD_DATE",          "SERIAL",           "MATERIAL",
		"INSTRUMENTATION",  "MEASUREMENT_SOURCE", "PRINT_CONDITIONS", "SAMPLE_BACKING",
		"FILE_DESCRIPTOR",  "WEIGHTING_FUNCTION", "COMPUTATIONAL_PARAMETER",
	};
	for (size_t i = 0; i < sizeof(std) / sizeof(std[0]); i++)
		if (strcmp(name, std[i]) == 0)
			return 1;
	return 0;
}

/* Fields CGATS.17 predefines (by name or prefix); others are declared. */
static int standard_field(const char *name)
{
	static const char *const exact[] = { "SAMPLE_ID", "SAMPLE_NAME", "STRING" };
	static const char *const prefix[] = { "SPEC_", "RGB_", "XYZ_", "LAB_", "CMYK_",
		                                  "XYY_",  "LCH_", "D_",   "STDEV_" };
	for (size_t i = 0; i < sizeof(exact) / sizeof(exact[0]); i++)
		if (strcmp(name, exact[i]) == 0)
			return 1;
	for (size_t i = 0; i < sizeof(prefix) / sizeof(prefix[0]); i++)
		if (strncmp(name, prefix[i], strlen(prefix[i])) == 0)
			return 1;
	return 0;
}

/* The declaration of a keyword or field CGATS.17 does not predefine. */
static void put_keyword_line(FILE *fp, const char *name)
{
	fputs("KEYWORD ", fp);
	kg_cgats_put(fp, name, 1);
	fputc('\n', fp);
}

static int write_table(FILE *fp, const kg_cgats_table *t, const char *path, int index,
                       kg_err *err)
{
	if (t->nfields == 0)
		return kg_fail(err, KG_EINVAL, "%s: table %d has no fields", path, index + 1);
	char what[256];
	for (int i = 0; i < t->nkeywords; i++) {
		snprintf(what, sizeof(what), "%s: keyword %s: value", path, t->keywords[i].name);
		if (kg_cgats_check(what, t->keywords[i].value, err))
			return KG_EINVAL;
	}
	size_t ncells = (size_t)t->nsets * (size_t)t->nfields;
	for (size_t i = 0; i < ncells; i++) {
		snprintf(what, sizeof(what), "%s: set %zu: field %s", path, i / (size_t)t->nfields + 1,
		         t->fields[i % (size_t)t->nfields]);
		if (kg_cgats_check(what, t->cells[i], err))
			return KG_EINVAL;
	}

	fprintf(fp, "%s\n\n", t->type);
	for (int i = 0; i < t->nkeywords; i++) {
		const kg_cgats_kw *kw = &t->keywords[i];
		if (!standard_keyword(kw->name))
			put_keyword_line(fp, kw->name);
		fprintf(fp, "%s ", kw->name);
		kg_cgats_put(fp, kw->value, 1);
		fputc('\n', fp);
	}
	for (int i = 0; i < t->nfields; i++)
		if (!standard_field(t->fields[i]))
			put_keyword_line(fp, t->fields[i]);
	fprintf(fp, "\nNUMBER_OF_FIELDS %d\nBEGIN_DATA_FORMAT\n", t->nfields);
	for (int i = 0; i < t->nfields; i++)
		fprintf(fp, "%s%s", i ? "\t" : "", t->fields[i]);
	fprintf(fp, "\nEND_DATA_FORMAT\n\nNUMBER_OF_SETS %d\nBEGIN_DATA\n", t->nsets);
	for (int s = 0; s < t->nsets; s++) {
		for (int i = 0; i < t->nfields; i++) {
			if (i)
				fputc('\t', fp);
			kg_cgats_put(fp, t->cells[(size_t)s * (size_t)t->nfields + (size_t)i], 0);
		}
		fputc('\n', fp);
	}
	fprintf(fp, "END_DATA\n");
	return 0;
}

int kg_cgats_write(const kg_cgats *cg, const char *path, kg_err *err)
{
	kg_check_arg(cg && path, err);
	if (cg->ntables == 0)
		return kg_fail(err, KG_EINVAL, "%s: nothing to write: no tables", path);
	kg_outfile o;
	int r = kg_outfile_open(&o, path, 1, err);
	if (r != 0)
		return r;
	for (int i = 0; i < cg->ntables && r == 0; i++)
		r = write_table(o.fp, cg->tables[i], path, i, err);
	if (r != 0) {
		kg_outfile_abort(&o);
		return r;
	}
	return kg_outfile_commit(&o, err);
}

/* ------------------------------------------------------------------------------- */
/* Patch sets                                                                       */

void kg_patchset_free(kg_patchset **ps)
{
	if (!ps || !*ps)
		return;
	kg_patchset *p = *ps;
	if (p->ids)
		for (int i = 0; i < p->n; i++)
			free(p->ids[i]);
	free(p->ids);
	free(p->spectra);
	free(p->rgb);
	free(p->xyz);
	free(p->lab);
	if (p->extra_names)
		for (int i = 0; i < p->nextra; i++)
			free(p->extra_names[i]);
	free(p->extra_names);
	free(p->extra);
	free(p->source);
	free(p);
	*ps = NULL;
}

int kg_patchset_new(int n, unsigned fields, kg_patchset **out, kg_err *err)
{
	kg_check_arg(out && n > 0, err);
	*out = NULL;
	kg_patchset *ps = calloc(1, sizeof(*ps));
	if (!ps)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	ps->n = n;
	ps->spectral_scale = 1.0;
	size_t un = (size_t)n;
	int bad = !(ps->ids = calloc(un, sizeof(*ps->ids)));
	if (!bad && (fields & KG_PATCH_SPECTRA))
		bad = !(ps->spectra = calloc(un, sizeof(*ps->spectra)));
	if (!bad && (fields & KG_PATCH_RGB))
		bad = !(ps->rgb = calloc(un, sizeof(*ps->rgb)));
	if (!bad && (fields & KG_PATCH_XYZ))
		bad = !(ps->xyz = calloc(un, sizeof(*ps->xyz)));
	if (!bad && (fields & KG_PATCH_LAB))
		bad = !(ps->lab = calloc(un, sizeof(*ps->lab)));
	for (int i = 0; i < n && !bad; i++) {
		char num[16];
		snprintf(num, sizeof(num), "%d", i + 1);
		bad = !(ps->ids[i] = strdup(num));
	}
	if (bad) {
		kg_patchset_free(&ps);
		return kg_fail(err, KG_ENOMEM, "out of memory for %d patches", n);
	}
	*out = ps;
	return 0;
}

int kg_patchset_set_id(kg_patchset *ps, int i, const char *id, kg_err *err)
{
	kg_check_arg(ps && id && i >= 0 && i < ps->n, err);
	char *s = strdup(id);
	if (!s)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	free(ps->ids[i]);
	ps->ids[i] = s;
	return 0;
}

int kg_patchset_add_extra(kg_patchset *ps, const char *name, kg_err *err)
{
	kg_check_arg(ps && name, err);
	int r = check_name("column", name, err);
	if (r != 0)
		return r;
	int m = ps->nextra + 1;
	char **names = realloc(ps->extra_names, sizeof(*names) * (size_t)m);
	if (!names)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	ps->extra_names = names;
	double *x = calloc((size_t)ps->n * (size_t)m, sizeof(*x));
	char *nm = strdup(name);
	if (!x || !nm) {
		free(x);
		free(nm);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	for (int i = 0; i < ps->n; i++)
		for (int j = 0; j < ps->nextra; j++)
			x[(size_t)i * m + j] = ps->extra[(size_t)i * ps->nextra + j];
	free(ps->extra);
	ps->extra = x;
	names[ps->nextra] = nm;
	ps->nextra = m;
	return 0;
}

int kg_patchset_find(const kg_patchset *ps, const char *id)
{
	if (!ps || !id)
		return -1;
	for (int i = 0; i < ps->n; i++)
		if (strcmp(ps->ids[i], id) == 0)
			return i;
	return -1;
}

/* A patch id's parts: "A01", "a1" -> letter 'A', number 1 (kind 2); "7", "07" ->
 * number 7 (kind 1); anything else kind 0. */
static int id_parts(const char *id, int *letter, long *number)
{
	const char *p = id;
	*letter = 0;
	if (isalpha((unsigned char)*p)) {
		*letter = toupper((unsigned char)*p);
		p++;
	}
	if (!isdigit((unsigned char)*p))
		return 0;
	char *end;
	long v = strtol(p, &end, 10);
	if (*end || v < 1 || v > 100000)
		return 0;
	*number = v;
	return *letter ? 2 : 1;
}

/* Key of an id under a rule: 0 exact (no key), 1 the same letter and number whatever
 * the zero padding and case, 2 a plain number n and the grid id of the n-th patch in
 * letter-major order (A1..A<N>, B1.., N the largest number on the grid side). -1 if
 * the id has no key under the rule. */
static long id_key(const char *id, int rule, long per_letter)
{
	int letter;
	long number;
	int kind = id_parts(id, &letter, &number);
	if (kind == 0)
		return -1;
	if (rule == 1)
		return kind == 2 ? (long)(letter - 'A' + 1) * 1000000L + number : number;
	if (kind == 1)
		return number;
	if (number > per_letter)
		return -1;
	return (long)(letter - 'A') * per_letter + number;
}

/* All ids of a kind (1 numbers, 2 letter + number); the largest number of a grid. */
static int ids_all(char *const *ids, int n, int kind, long *max_number)
{
	*max_number = 0;
	for (int i = 0; i < n; i++) {
		int letter;
		long number;
		if (id_parts(ids[i], &letter, &number) != kind)
			return 0;
		if (number > *max_number)
			*max_number = number;
	}
	return n > 0;
}

/* The number of letters a grid spans (A.. its last letter). */
static long grid_letters(char *const *ids, int n)
{
	long last = 0;
	for (int i = 0; i < n; i++) {
		int letter;
		long number;
		if (id_parts(ids[i], &letter, &number) == 2 && letter - 'A' + 1 > last)
			last = letter - 'A' + 1;
	}
	return last;
}

static int match_rule(char *const *a, int na, char *const *b, int nb, int rule, int *match)
{
	long per_letter = 0, max_number = 0, letters = 0;
	if (rule == 2) {
		if (ids_all(a, na, 1, &max_number) && ids_all(b, nb, 2, &per_letter))
			letters = grid_letters(b, nb);
		else if (ids_all(a, na, 2, &per_letter) && ids_all(b, nb, 1, &max_number))
			letters = grid_letters(a, na);
		else
			return 0;
		/* The grid's width is taken as its largest number, which must seat every
		 * number within its letters (24 patches over A..D: 6 a letter). A grid file
		 * missing its last column, or a few ids, would need more letters than it has:
		 * no pairing rather than a wrong one. */
		if (per_letter < 1 || (max_number + per_letter - 1) / per_letter > letters)
			return 0;
	}
	int count = 0;
	for (int i = 0; i < na; i++) {
		match[i] = -1;
		long ka = rule ? id_key(a[i], rule, per_letter) : 0;
		if (rule && ka < 0)
			continue;
		for (int j = 0; j < nb; j++) {
			if (rule == 0 ? strcmp(a[i], b[j]) == 0 : id_key(b[j], rule, per_letter) == ka) {
				match[i] = j;
				count++;
				break;
			}
		}
	}
	return count;
}

int kg_patch_ids_match(char *const *a, int na, char *const *b, int nb, int *match,
                       const char **rule)
{
	static const char *const rules[3] = {
		NULL,
		"the same letter and number (A1 = A01)",
		"patch numbers in letter-major order (1 = A1/A01, 2 = A2, ... as ArgyllCMS "
		"chartread and X-Rite number the ColorChecker)",
	};
	if (rule)
		*rule = NULL;
	if (na <= 0 || !match)
		return 0;
	int *tmp = malloc((size_t)na * sizeof(int));
	if (!tmp)
		return -1;
	int best = -1, best_count = -1;
	for (int r = 0; r < 3; r++) {
		int c = match_rule(a, na, b, nb, r, tmp);
		if (c > best_count) {
			best_count = c;
			best = r;
			memcpy(match, tmp, (size_t)na * sizeof(int));
		}
		if (c == na)
			break;
	}
	free(tmp);
	if (best_count <= 0) {
		for (int i = 0; i < na; i++)
			match[i] = -1;
		return 0;
	}
	if (rule)
		*rule = rules[best];
	return best_count;
}

int kg_patchset_extra_index(const kg_patchset *ps, const char *name)
{
	if (!ps || !name)
		return -1;
	for (int i = 0; i < ps->nextra; i++)
		if (strcmp(ps->extra_names[i], name) == 0)
			return i;
	return -1;
}

/* Fill *dst (nsets x 3) from the three named fields and mark them used. Leaves *dst
 * NULL when none of the three exist; an error when only some do, or when a value's
 * magnitude exceeds max_abs. */
static int read_triplet(const kg_cgats_table *t, const char *const names[3],
                        double max_abs, double (**dst)[3], int *used, kg_err *err)
{
	int f[3], found = 0;
	for (int k = 0; k < 3; k++)
		found += (f[k] = kg_cgats_field(t, names[k])) >= 0;
	if (found == 0)
		return 0;
	if (found < 3)
		for (int k = 0; k < 3; k++)
			if (f[k] < 0)
				return kg_fail(err, KG_EINVAL, "%s: field %s missing: expected %s %s %s "
				               "together", t->path, names[k], names[0], names[1], names[2]);
	double(*v)[3] = calloc((size_t)t->nsets, sizeof(*v));
	if (!v)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", t->path);
	for (int s = 0; s < t->nsets; s++)
		for (int k = 0; k < 3; k++) {
			int r = kg_cgats_number(t, s, f[k], &v[s][k], err);
			char where[32];
			if (r == 0 && !(fabs(v[s][k]) <= max_abs))
				r = kg_fail(err, KG_ERANGE, "%s: %s: field %s: '%.40s': expected a value of "
				            "magnitude at most %g", t->path, set_where(t, s, where),
				            names[k], kg_cgats_cell(t, s, f[k]), max_abs);
			if (r != 0) {
				free(v);
				return r;
			}
		}
	for (int k = 0; k < 3; k++)
		used[f[k]] = 1;
	*dst = v;
	return 0;
}

/* How a table's stored spectral values become fractions (reflectance 0..1): value x
 * 10^shift / norm. The rule, whatever the file-type identifier (CGATS.17, SPECT,
 * CTI3, ...):
 *  1. KG_PATCH_KEEP_SCALE: as stored.
 *  2. SPECTRAL_NORM present: divided by it (ArgyllCMS stores fraction x norm: its
 *     reflectance and transmittance files use 100, its illuminants any level; colord's
 *     matching functions 1). A power of ten moves the decimal point instead.
 *  3. MEAS_TYPE EMISSION or AMBIENT (a spectral power distribution: no percent
 *     convention applies): as stored.
 *  4. Otherwise percent when any value exceeds 1.5 (no reflectance does): ArgyllCMS
 *     writes measured spectra in percent without SPECTRAL_NORM (chartread's .ti3
 *     CTI3 tables, spec2cie's SPECT output), and spec2cie reads every reflective value
 *     as percent; colord's CIE-TCS.sp holds fractions, also without the keyword. */
typedef struct spectral_norm {
	int shift;   /* decimal exponent applied in the text */
	double norm; /* then divided by this */
} spectral_norm;

static int spectral_norm_of(const kg_cgats_table *t, const int *fields, int nspec,
                            unsigned flags, spectral_norm *sn, kg_err *err)
{
	*sn = (spectral_norm){ 0, 1.0 };
	if (flags & KG_PATCH_KEEP_SCALE)
		return 0;
	double norm;
	int r = kg_cgats_keyword_number(t, "SPECTRAL_NORM", &norm, err);
	if (r == 0) {
		if (!(norm > 0))
			return kg_fail(err, KG_EINVAL, "%s: keyword SPECTRAL_NORM: expected a positive "
			               "number, found %g", t->path, norm);
		for (int k = 0; k <= 6; k++)
			if (norm == pow(10.0, k)) {
				sn->shift = -k;
				return 0;
			}
		sn->norm = norm;
		return 0;
	}
	if (r != KG_ENOENT)
		return r;
	const char *meas = kg_cgats_keyword(t, "MEAS_TYPE");
	if (meas && (strcmp(meas, "EMISSION") == 0 || strcmp(meas, "AMBIENT") == 0))
		return 0;
	for (int s = 0; s < t->nsets; s++)
		for (int k = 0; k < nspec; k++) {
			double v;
			if ((r = kg_cgats_number(t, s, fields[k], &v, err)) != 0)
				return r;
			if (v > 1.5) {
				sn->shift = -2;
				return 0;
			}
		}
	return 0;
}

const char *kg_spectral_value_expected(double v, unsigned flags)
{
	if (flags & KG_PATCH_REFLECTANCE)
		return v >= KG_REFLECTANCE_MIN && v <= KG_REFLECTANCE_MAX
		           ? NULL
		           : "expected a reflectance between -1 and 10 (-100 % and 1000 %)";
	return fabs(v) <= KG_SPECTRAL_MAX_ABS ? NULL
	                                      : "expected a spectral value of magnitude at most 1e30";
}

/* A spectral value once scaled (kg_spectral_value_expected). */
static int check_spectral_value(const kg_cgats_table *t, int set, int field, double v,
                                const spectral_norm *sn, unsigned flags, kg_err *err)
{
	const char *expected = kg_spectral_value_expected(v, flags);
	if (!expected)
		return 0;
	char where[32], scaled[64] = "";
	double scale = pow(10.0, sn->shift) / sn->norm;
	if (scale != 1.0)
		snprintf(scaled, sizeof(scaled), " (%g once scaled by %g)", v, scale);
	return kg_fail(err, KG_ERANGE, "%s: %s: field %.60s: '%.40s'%s: %s", t->path,
	               set_where(t, set, where), t->fields[field], kg_cgats_cell(t, set, field),
	               scaled, expected);
}

int kg_cgats_spectra(const kg_cgats_table *t, unsigned flags, double **wl,
                     double **values, int *n, double *scale, kg_err *err)
{
	kg_check_arg(t && wl && values && n, err);
	*values = NULL;
	int *fields = NULL, nspec = 0;
	int r = kg_cgats_spectral_fields(t, &fields, wl, &nspec, err);
	*n = nspec;
	if (r != 0 || nspec == 0)
		return r;
	spectral_norm sn;
	double *v = NULL;
	r = spectral_norm_of(t, fields, nspec, flags, &sn, err);
	if (r == 0 && !(v = malloc(sizeof(*v) * (size_t)nspec * (size_t)(t->nsets ? t->nsets : 1))))
		r = kg_fail(err, KG_ENOMEM, "%s: out of memory", t->path);
	for (int s = 0; s < t->nsets && r == 0; s++)
		for (int k = 0; k < nspec && r == 0; k++) {
			double *dst = &v[(size_t)s * nspec + k];
			if ((r = kg_cgats_number(t, s, fields[k], dst, err)) != 0)
				break;
			/* The cell is a valid finite number: only an overflow can fail here. */
			if (parse_number_shifted(kg_cgats_cell(t, s, fields[k]), sn.shift, dst) != 0)
				*dst = INFINITY;
			else
				*dst /= sn.norm;
			r = check_spectral_value(t, s, fields[k], *dst, &sn, flags, err);
		}
	free(fields);
	if (r != 0) {
		free(v);
		free(*wl);
		*wl = NULL;
		*n = 0;
		return r;
	}
	*values = v;
	if (scale)
		*scale = pow(10.0, sn.shift) / sn.norm;
	return 0;
}

static int read_spectra(const kg_cgats_table *t, kg_patchset *ps, unsigned flags,
                        int *used, kg_err *err)
{
	int *fields = NULL, nspec = 0;
	double *wl = NULL, *val = NULL;
	int r = kg_cgats_spectra(t, flags, &wl, &val, &nspec, &ps->spectral_scale, err);
	if (r != 0 || nspec == 0)
		return r;
	if (!(ps->spectra = calloc((size_t)t->nsets, sizeof(*ps->spectra))))
		r = kg_fail(err, KG_ENOMEM, "%s: out of memory", t->path);
	for (int s = 0; s < t->nsets && r == 0; s++) {
		char what[256];
		if (t->set_lines[s] > 0)
			snprintf(what, sizeof(what), "%s: line %d: sample %.40s", t->path,
			         t->set_lines[s], ps->ids[s]);
		else
			snprintf(what, sizeof(what), "%s: sample %.40s", t->path, ps->ids[s]);
		r = kg_spectrum_resample(wl, val + (size_t)s * nspec, nspec, flags, what,
		                         &ps->spectra[s], err);
	}
	free(val);
	free(wl);
	wl = NULL;
	/* The fields were checked above: this only finds which ones to mark. */
	if (r == 0 && (r = kg_cgats_spectral_fields(t, &fields, &wl, &nspec, err)) == 0)
		for (int k = 0; k < nspec; k++)
			used[fields[k]] = 1;
	free(fields);
	free(wl);
	return r;
}

/* Remaining fields whose every cell is a number become extra columns. */
static int read_extras(const kg_cgats_table *t, kg_patchset *ps, const int *used,
                       kg_err *err)
{
	double v;
	int m = 0;
	int *cols = malloc(sizeof(*cols) * (size_t)t->nfields);
	if (!cols)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", t->path);
	for (int f = 0; f < t->nfields; f++) {
		if (used[f])
			continue;
		int numeric = 1;
		for (int s = 0; s < t->nsets && numeric; s++)
			numeric = kg_cgats_parse_number(kg_cgats_cell(t, s, f), &v) == 0;
		if (numeric)
			cols[m++] = f;
	}
	int r = 0;
	if (m > 0) {
		ps->extra_names = calloc((size_t)m, sizeof(*ps->extra_names));
		ps->extra = malloc(sizeof(*ps->extra) * (size_t)m * (size_t)ps->n);
		if (!ps->extra_names || !ps->extra)
			r = kg_fail(err, KG_ENOMEM, "%s: out of memory", t->path);
		else
			ps->nextra = m;
		for (int j = 0; j < m && r == 0; j++) {
			if (!(ps->extra_names[j] = strdup(t->fields[cols[j]])))
				r = kg_fail(err, KG_ENOMEM, "%s: out of memory", t->path);
			for (int s = 0; s < t->nsets; s++) {
				kg_cgats_parse_number(kg_cgats_cell(t, s, cols[j]), &v);
				ps->extra[(size_t)s * m + j] = v;
			}
		}
	}
	free(cols);
	return r;
}

int kg_patchset_from_table(const kg_cgats_table *t, unsigned flags, kg_patchset **out,
                           kg_err *err)
{
	kg_check_arg(t && out, err);
	*out = NULL;
	if (t->nsets == 0)
		return kg_fail(err, KG_EINVAL, "%s: table has no data sets: expected at least one "
		               "sample", t->path);
	kg_patchset *ps;
	int r = kg_patchset_new(t->nsets, 0, &ps, err);
	if (r != 0)
		return r;
	int *used = calloc((size_t)t->nfields, sizeof(*used));
	if (!used || !(ps->source = strdup(t->path))) {
		free(used);
		kg_patchset_free(&ps);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", t->path);
	}
	static const char *const id_fields[] = { "SAMPLE_ID", "SAMPLE_NAME", "SAMPLE_LOC" };
	for (size_t k = 0; k < sizeof(id_fields) / sizeof(id_fields[0]); k++) {
		int f = kg_cgats_field(t, id_fields[k]);
		if (f < 0)
			continue;
		for (int s = 0; s < t->nsets && r == 0; s++)
			r = kg_patchset_set_id(ps, s, kg_cgats_cell(t, s, f), err);
		used[f] = 1;
		break;
	}
	static const char *const rgb[3] = { "RGB_R", "RGB_G", "RGB_B" };
	static const char *const xyz[3] = { "XYZ_X", "XYZ_Y", "XYZ_Z" };
	static const char *const lab[3] = { "LAB_L", "LAB_A", "LAB_B" };
	if (r == 0)
		r = read_spectra(t, ps, flags, used, err);
	if (r == 0)
		r = read_triplet(t, rgb, KG_RGB_MAX_ABS, &ps->rgb, used, err);
	if (r == 0)
		r = read_triplet(t, xyz, KG_SPECTRAL_MAX_ABS, &ps->xyz, used, err);
	if (r == 0)
		r = read_triplet(t, lab, KG_SPECTRAL_MAX_ABS, &ps->lab, used, err);
	if (r == 0)
		r = read_extras(t, ps, used, err);
	free(used);
	if (r != 0) {
		kg_patchset_free(&ps);
		return r;
	}
	*out = ps;
	return 0;
}

int kg_patchset_from_cgats(const kg_cgats *cg, unsigned flags, kg_patchset **out,
                           kg_err *err)
{
	kg_check_arg(cg && out && cg->ntables > 0, err);
	return kg_patchset_from_table(cg->tables[0], flags, out, err);
}

int kg_patchset_read(const char *path, unsigned flags, kg_patchset **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	kg_cgats *cg;
	int r = kg_cgats_read(path, &cg, err);
	if (r != 0)
		return r;
	r = kg_patchset_from_cgats(cg, flags, out, err);
	kg_cgats_free(&cg);
	return r;
}

static int push_name(char **names, int *n, const char *fmt, ...) KG_PRINTF(3, 4);
static int push_name(char **names, int *n, const char *fmt, ...)
{
	char buf[64];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(buf, sizeof(buf), fmt, ap);
	va_end(ap);
	if (!(names[*n] = strdup(buf)))
		return KG_ENOMEM;
	(*n)++;
	return 0;
}

int kg_patchset_to_cgats(const kg_patchset *ps, unsigned fields,
                         const char *const *keywords, kg_cgats **out, kg_err *err)
{
	kg_check_arg(ps && out && ps->n > 0 && ps->ids, err);
	*out = NULL;
	static const struct {
		unsigned bit;
		const char *what;
	} need[] = { { KG_PATCH_SPECTRA, "spectra" }, { KG_PATCH_RGB, "RGB values" },
		         { KG_PATCH_XYZ, "XYZ values" },  { KG_PATCH_LAB, "L*a*b* values" },
		         { KG_PATCH_EXTRA, "extra columns" } };
	const void *have[] = { ps->spectra, ps->rgb, ps->xyz, ps->lab,
		                   ps->nextra ? (const void *)ps->extra : NULL };
	for (size_t k = 0; k < sizeof(need) / sizeof(need[0]); k++)
		if ((fields & need[k].bit) && !have[k])
			return kg_fail(err, KG_EINVAL, "patch set has no %s to write", need[k].what);

	int nf = 1 + ((fields & KG_PATCH_SPECTRA) ? KG_NBANDS : 0) +
	         ((fields & KG_PATCH_RGB) ? 3 : 0) + ((fields & KG_PATCH_XYZ) ? 3 : 0) +
	         ((fields & KG_PATCH_LAB) ? 3 : 0) + ((fields & KG_PATCH_EXTRA) ? ps->nextra : 0);
	char **names = calloc((size_t)nf, sizeof(*names));
	double *row = malloc(sizeof(*row) * (size_t)nf);
	kg_cgats *cg = NULL;
	kg_cgats_table *t = NULL;
	int n = 0, r = (!names || !row) ? KG_ENOMEM : 0;
	if (r == 0)
		r = push_name(names, &n, "SAMPLE_ID");
	for (int b = 0; b < KG_NBANDS && r == 0 && (fields & KG_PATCH_SPECTRA); b++)
		r = push_name(names, &n, "SPEC_%d", (int)kg_band_nm(b));
	const char *const trip[3][3] = { { "RGB_R", "RGB_G", "RGB_B" },
		                             { "XYZ_X", "XYZ_Y", "XYZ_Z" },
		                             { "LAB_L", "LAB_A", "LAB_B" } };
	const unsigned trip_bit[3] = { KG_PATCH_RGB, KG_PATCH_XYZ, KG_PATCH_LAB };
	for (int k = 0; k < 3; k++)
		for (int j = 0; j < 3 && r == 0 && (fields & trip_bit[k]); j++)
			r = push_name(names, &n, "%s", trip[k][j]);
	for (int j = 0; j < ps->nextra && r == 0 && (fields & KG_PATCH_EXTRA); j++)
		r = push_name(names, &n, "%s", ps->extra_names[j]);
	if (r != 0) {
		r = kg_fail(err, KG_ENOMEM, "out of memory");
		goto done;
	}

	/* spec2cie takes only SPECT and CTI3 tables, and a SPECT table needs MEAS_TYPE. */
	int spectral = (fields & KG_PATCH_SPECTRA) != 0;
	if ((r = kg_cgats_new(spectral ? "SPECT" : "CGATS.17", &cg, err)) != 0)
		goto done;
	t = cg->tables[0];
	int has_originator = 0, has_meas_type = 0;
	for (int k = 0; keywords && keywords[k]; k += 2) {
		if (!keywords[k + 1]) {
			r = kg_fail(err, KG_EINVAL, "keyword %s: no value given", keywords[k]);
			goto done;
		}
		has_originator |= strcmp(keywords[k], "ORIGINATOR") == 0;
		has_meas_type |= strcmp(keywords[k], "MEAS_TYPE") == 0;
		if ((r = kg_cgats_set_keyword(t, keywords[k], keywords[k + 1], err)) != 0)
			goto done;
	}
	if (!has_originator && (r = kg_cgats_set_keyword(t, "ORIGINATOR", "kogei", err)) != 0)
		goto done;
	if (spectral) {
		if ((!has_meas_type && (r = kg_cgats_set_keyword(t, "MEAS_TYPE", "REFLECTIVE", err))) ||
		    (r = kg_cgats_set_keyword_number(t, "SPECTRAL_START_NM", KG_LAMBDA_MIN, err)) ||
		    (r = kg_cgats_set_keyword_number(t, "SPECTRAL_END_NM", KG_LAMBDA_MAX, err)) ||
		    (r = kg_cgats_set_keyword_number(t, "SPECTRAL_BANDS", KG_NBANDS, err)) ||
		    (r = kg_cgats_set_keyword_number(t, "SPECTRAL_NORM", 100.0, err)))
			goto done;
	}
	if ((r = kg_cgats_set_fields(t, (const char *const *)names, nf, err)) != 0)
		goto done;
	for (int i = 0; i < ps->n; i++) {
		int m = 0;
		if (spectral)
			for (int b = 0; b < KG_NBANDS; b++)
				row[m++] = ps->spectra[i].v[b];
		double(*const arrays[3])[3] = { ps->rgb, ps->xyz, ps->lab };
		for (int k = 0; k < 3; k++)
			if (fields & trip_bit[k])
				for (int j = 0; j < 3; j++)
					row[m++] = arrays[k][i][j];
		if (fields & KG_PATCH_EXTRA)
			for (int j = 0; j < ps->nextra; j++)
				row[m++] = ps->extra[(size_t)i * ps->nextra + j];
		if ((r = kg_cgats_add_row_numbers(t, ps->ids[i], row, m, err)) != 0) {
			kg_err_prefix(err, "patch %s", ps->ids[i]);
			goto done;
		}
		/* Spectra in percent: the same digits with the point moved (exact). */
		for (int b = 0; spectral && b < KG_NBANDS && r == 0; b++) {
			char text[64];
			format_number_shifted(text, sizeof(text), row[b], 2);
			r = kg_cgats_set_cell(t, t->nsets - 1, 1 + b, text, err);
		}
		if (r != 0)
			goto done;
	}
done:
	if (names)
		for (int i = 0; i < n; i++)
			free(names[i]);
	free(names);
	free(row);
	if (r != 0)
		kg_cgats_free(&cg);
	*out = cg;
	return r;
}

int kg_patchset_write(const char *path, const kg_patchset *ps, unsigned fields,
                      const char *const *keywords, kg_err *err)
{
	kg_check_arg(path && ps, err);
	kg_cgats *cg;
	int r = kg_patchset_to_cgats(ps, fields, keywords, &cg, err);
	if (r != 0)
		return r;
	r = kg_cgats_write(cg, path, err);
	kg_cgats_free(&cg);
	return r;
}
