#include <ctype.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "csv.h"
#include "fsutil.h"
#include "text.h"

/* Longest line accepted (the same cap as for CGATS). */
#define CSV_MAX_LINE KG_CGATS_MAX_LINE

void kg_csv_free(kg_csv **t)
{
	if (!t || !*t)
		return;
	kg_csv *c = *t;
	if (c->names)
		for (int i = 0; i < c->ncols; i++)
			free(c->names[i]);
	free(c->names);
	if (c->cells)
		for (size_t i = 0; i < (size_t)c->nrows * (size_t)c->ncols; i++)
			free(c->cells[i]);
	free(c->cells);
	free(c->row_lines);
	free(c->path);
	free(c);
	*t = NULL;
}

/* Split a line at commas into freshly allocated cells, blanks around each removed. A
 * cell that starts with a double quote (RFC 4180, as kg_csv_put writes) runs to its
 * closing quote, keeping commas and blanks, with "" read as one quote; it must close on
 * its line and only blanks may follow it. KG_EINVAL with *badcol (1-based) otherwise. */
static int split_line(const char *line, size_t len, char ***cells, int *n, int *badcol)
{
	int count = 0, cap = 8, ret = 0;
	char **c = malloc(sizeof(*c) * (size_t)cap);
	size_t pos = 0;
	while (c) {
		size_t a = pos;
		while (a < len && line[a] != ',' && isspace((unsigned char)line[a]))
			a++;
		char *cell;
		size_t next;
		if (a < len && line[a] == '"') {
			cell = malloc(len - a + 1);
			size_t m = 0, i = a + 1;
			int closed = 0;
			while (cell && i < len) {
				if (line[i] == '"' && i + 1 < len && line[i + 1] == '"') {
					cell[m++] = '"';
					i += 2;
				} else if (line[i] == '"') {
					closed = 1;
					i++;
					break;
				} else {
					cell[m++] = line[i++];
				}
			}
			while (i < len && line[i] != ',' && isspace((unsigned char)line[i]))
				i++;
			if (cell && (!closed || (i < len && line[i] != ','))) {
				free(cell);
				*badcol = count + 1;
				ret = KG_EINVAL;
				break;
			}
			if (cell)
				cell[m] = 0;
			next = i;
		} else {
			size_t end = a;
			while (end < len && line[end] != ',')
				end++;
			size_t b = end;
			while (b > a && isspace((unsigned char)line[b - 1]))
				b--;
			cell = strndup(line + a, b - a);
			next = end;
		}
		if (!cell) {
			ret = KG_ENOMEM;
			break;
		}
		if (count == cap) {
			char **g = cap < (1 << 20) ? realloc(c, sizeof(*c) * (size_t)cap * 2) : NULL;
			if (!g) {
				free(cell);
				ret = KG_ENOMEM;
				break;
			}
			c = g;
			cap *= 2;
		}
		c[count++] = cell;
		if (next >= len)
			break;
		pos = next + 1;
	}
	if (!c)
		return KG_ENOMEM;
	if (ret) {
		for (int j = 0; j < count; j++)
			free(c[j]);
		free(c);
		return ret;
	}
	*cells = c;
	*n = count;
	return 0;
}

static int push_row(kg_csv *t, char **cells, int line, int *cap)
{
	if (t->nrows == *cap) {
		int nc = *cap ? *cap * 2 : 64;
		if (nc <= *cap || (size_t)nc > SIZE_MAX / sizeof(char *) / (size_t)t->ncols)
			return KG_ENOMEM;
		char **c = realloc(t->cells, sizeof(*c) * (size_t)nc * (size_t)t->ncols);
		if (!c)
			return KG_ENOMEM;
		t->cells = c;
		int *l = realloc(t->row_lines, sizeof(*l) * (size_t)nc);
		if (!l)
			return KG_ENOMEM;
		t->row_lines = l;
		*cap = nc;
	}
	memcpy(t->cells + (size_t)t->nrows * (size_t)t->ncols, cells,
	       sizeof(*cells) * (size_t)t->ncols);
	t->row_lines[t->nrows++] = line;
	return 0;
}

int kg_csv_parse(const char *buf, size_t len, const char *name, kg_csv **out, kg_err *err)
{
	kg_check_arg(out && (buf || len == 0), err);
	*out = NULL;
	kg_csv *t = calloc(1, sizeof(*t));
	if (!t || !(t->path = strdup(name ? name : "<memory>"))) {
		free(t);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	char *converted = NULL;
	int r = kg_text_utf8(buf, len, t->path, &buf, &len, &converted, err);
	int lineno = 0, cap = 0;
	size_t pos = 0;
	while (pos < len && r == 0) {
		lineno++;
		const char *line = buf + pos;
		const char *nl = memchr(line, '\n', len - pos);
		size_t n = nl ? (size_t)(nl - line) : len - pos;
		pos += n + (nl ? 1 : 0);
		if (n > CSV_MAX_LINE) {
			r = kg_fail(err, KG_EINVAL, "%s: line %d: line is longer than %d bytes: "
			            "expected CSV text", t->path, lineno, CSV_MAX_LINE);
			break;
		}
		if (memchr(line, '\0', n)) {
			r = kg_fail(err, KG_EINVAL, "%s: line %d: NUL byte: expected CSV text", t->path,
			            lineno);
			break;
		}
		size_t a = 0;
		while (a < n && isspace((unsigned char)line[a]))
			a++;
		if (a == n || line[a] == '#')
			continue;
		char **cells;
		int ncells, badcol = 0;
		int sr = split_line(line, n, &cells, &ncells, &badcol);
		if (sr == KG_EINVAL) {
			r = kg_fail(err, KG_EINVAL, "%s: line %d, column %d: a quoted value not closed on "
			            "its line, or text after its closing quote: expected \"...\" (with "
			            "\"\" for a quote inside) between commas", t->path, lineno, badcol);
			break;
		}
		if (sr != 0) {
			r = kg_fail(err, KG_ENOMEM, "%s: out of memory", t->path);
			break;
		}
		if (!t->names) {
			t->names = cells;
			t->ncols = ncells;
			t->header_line = lineno;
			for (int i = 0; i < ncells && r == 0; i++)
				if (!*cells[i])
					r = kg_fail(err, KG_EINVAL, "%s: line %d: header column %d is empty: "
					            "expected a column name", t->path, lineno, i + 1);
			continue;
		}
		if (ncells != t->ncols) {
			r = kg_fail(err, KG_EINVAL, "%s: line %d: %d values, expected %d (one per "
			            "header column, %s ... %s)", t->path, lineno, ncells, t->ncols,
			            t->names[0], t->names[t->ncols - 1]);
		} else if (push_row(t, cells, lineno, &cap) != 0) {
			r = kg_fail(err, KG_ENOMEM, "%s: out of memory", t->path);
		} else {
			free(cells);
			continue;
		}
		for (int i = 0; i < ncells; i++)
			free(cells[i]);
		free(cells);
	}
	free(converted);
	if (r == 0 && !t->names)
		r = kg_fail(err, KG_EINVAL, "%s: empty: expected a header row of column names",
		            t->path);
	if (r != 0) {
		kg_csv_free(&t);
		return r;
	}
	*out = t;
	return 0;
}

int kg_csv_read(const char *path, kg_csv **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	char *buf;
	size_t len;
	int r = kg_read_file(path, &buf, &len, err);
	if (r != 0)
		return r;
	r = kg_csv_parse(buf, len, path, out, err);
	free(buf);
	return r;
}

int kg_csv_column(const kg_csv *t, const char *name)
{
	if (!t || !name)
		return -1;
	for (int i = 0; i < t->ncols; i++)
		if (strcmp(t->names[i], name) == 0)
			return i;
	return -1;
}

const char *kg_csv_cell(const kg_csv *t, int row, int col)
{
	if (!t || row < 0 || row >= t->nrows || col < 0 || col >= t->ncols)
		return NULL;
	return t->cells[(size_t)row * (size_t)t->ncols + (size_t)col];
}

int kg_csv_number(const kg_csv *t, int row, int col, double *out, kg_err *err)
{
	kg_check_arg(t && out, err);
	const char *c = kg_csv_cell(t, row, col);
	if (!c)
		return kg_fail(err, KG_EINVAL, "%s: no cell at row %d, column %d", t->path, row + 1,
		               col + 1);
	if (kg_cgats_parse_number(c, out) == 0)
		return 0;
	return kg_fail(err, KG_EINVAL, "%s: line %d: column %s: expected a finite number, "
	               "found '%.40s'", t->path, t->row_lines[row], t->names[col], c);
}

int kg_csv_read_spectra_rows(const char *path, unsigned flags, kg_patchset **out,
                             kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	kg_csv *t;
	int r = kg_csv_read(path, &t, err);
	if (r != 0)
		return r;
	kg_patchset *ps = NULL;
	int *cols = malloc(sizeof(*cols) * (size_t)t->ncols);
	double *wl = malloc(sizeof(*wl) * (size_t)t->ncols);
	double *val = malloc(sizeof(*val) * (size_t)t->ncols);
	int id = kg_csv_column(t, "patch"), nwl = 0;
	if (!cols || !wl || !val) {
		r = kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
		goto done;
	}
	if (id < 0) {
		r = kg_fail(err, KG_EINVAL, "%s: no column 'patch': expected a header "
		            "patch,name,<wavelengths...>", path);
		goto done;
	}
	for (int c = 0; c < t->ncols; c++)
		if (kg_cgats_parse_number(t->names[c], &wl[nwl]) == 0) {
			if (nwl > 0 && !(wl[nwl] > wl[nwl - 1])) {
				r = kg_fail(err, KG_EINVAL, "%s: header column %s: wavelengths must "
				            "increase, found it after %s", path, t->names[c],
				            t->names[cols[nwl - 1]]);
				goto done;
			}
			cols[nwl++] = c;
		}
	if (nwl == 0) {
		r = kg_fail(err, KG_EINVAL, "%s: no wavelength columns: expected numeric column "
		            "names (nm) after patch,name", path);
		goto done;
	}
	if (t->nrows == 0) {
		r = kg_fail(err, KG_EINVAL, "%s: no rows: expected one spectrum per row", path);
		goto done;
	}
	if ((r = kg_patchset_new(t->nrows, KG_PATCH_SPECTRA, &ps, err)) != 0)
		goto done;
	if (!(ps->source = strdup(path))) {
		r = kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
		goto done;
	}
	for (int i = 0; i < t->nrows && r == 0; i++) {
		r = kg_patchset_set_id(ps, i, kg_csv_cell(t, i, id), err);
		for (int k = 0; k < nwl && r == 0; k++) {
			r = kg_csv_number(t, i, cols[k], &val[k], err);
			const char *expected = r ? NULL : kg_spectral_value_expected(val[k], flags);
			if (expected)
				r = kg_fail(err, KG_ERANGE, "%s: line %d: column %s: '%.40s': %s", path,
				            t->row_lines[i], t->names[cols[k]], kg_csv_cell(t, i, cols[k]),
				            expected);
		}
		if (r == 0) {
			char what[256];
			snprintf(what, sizeof(what), "%s: line %d: patch %.40s", path, t->row_lines[i],
			         ps->ids[i]);
			r = kg_spectrum_resample(wl, val, nwl, flags, what, &ps->spectra[i], err);
		}
	}
done:
	free(cols);
	free(wl);
	free(val);
	kg_csv_free(&t);
	if (r != 0)
		kg_patchset_free(&ps);
	*out = ps;
	return r;
}

int kg_csv_read_columns(const char *path, const char *const *names, int ncol,
                        double **wl, double **vals, int *n, kg_err *err)
{
	kg_check_arg(path && (names || ncol == 0) && ncol >= 0 && wl && vals && n, err);
	*wl = NULL;
	*vals = NULL;
	*n = 0;
	kg_csv *t;
	int r = kg_csv_read(path, &t, err);
	if (r != 0)
		return r;
	double *w = NULL, *v = NULL;
	int *cols = calloc((size_t)ncol + 1, sizeof(*cols));
	int wc = kg_csv_column(t, "wavelength_nm");
	if (wc < 0)
		wc = 0;
	if (!cols) {
		r = kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
		goto done;
	}
	for (int k = 0; k < ncol; k++)
		if ((cols[k] = kg_csv_column(t, names[k])) < 0) {
			r = kg_fail(err, KG_EINVAL, "%s: no column '%s' in the header (found %s ... %s)",
			            path, names[k], t->names[0], t->names[t->ncols - 1]);
			goto done;
		}
	if (t->nrows == 0) {
		r = kg_fail(err, KG_EINVAL, "%s: no rows: expected one row per wavelength", path);
		goto done;
	}
	w = malloc(sizeof(*w) * (size_t)t->nrows);
	v = malloc(sizeof(*v) * (size_t)t->nrows * ((size_t)ncol + 1));
	if (!w || !v) {
		r = kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
		goto done;
	}
	for (int i = 0; i < t->nrows && r == 0; i++) {
		r = kg_csv_number(t, i, wc, &w[i], err);
		if (r == 0 && i > 0 && !(w[i] > w[i - 1]))
			r = kg_fail(err, KG_EINVAL, "%s: line %d: column %s: wavelengths must increase, "
			            "found %g after %g", path, t->row_lines[i], t->names[wc], w[i],
			            w[i - 1]);
		for (int k = 0; k < ncol && r == 0; k++)
			r = kg_csv_number(t, i, cols[k], &v[(size_t)i * ncol + k], err);
	}
	if (r == 0) {
		*wl = w;
		*vals = v;
		*n = t->nrows;
		w = v = NULL;
	}
done:
	free(w);
	free(v);
	free(cols);
	kg_csv_free(&t);
	return r;
}

int kg_csv_read_column_spectra(const char *path, const char *const *names, int ncol,
                               unsigned flags, kg_spectrum *out, kg_err *err)
{
	kg_check_arg(out && ncol > 0, err);
	double *wl, *vals, *col = NULL;
	int n, r = kg_csv_read_columns(path, names, ncol, &wl, &vals, &n, err);
	if (r != 0)
		return r;
	if (!(col = malloc(sizeof(*col) * (size_t)n)))
		r = kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	for (int k = 0; k < ncol && r == 0; k++) {
		for (int i = 0; i < n; i++)
			col[i] = vals[(size_t)i * ncol + k];
		char what[256];
		snprintf(what, sizeof(what), "%s: column %s", path, names[k]);
		r = kg_spectrum_resample(wl, col, n, flags, what, &out[k], err);
	}
	free(col);
	free(wl);
	free(vals);
	return r;
}
