#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "fsutil.h"
#include "json.h"

int kg_json_load(const char *path, json_t **root, kg_err *err)
{
	kg_check_arg(path && root, err);
	json_error_t e;
	*root = json_load_file(path, JSON_REJECT_DUPLICATES, &e);
	if (*root) {
		kg_inputs_add(path, -1);
		return 0;
	}
	switch (json_error_code(&e)) {
	case json_error_cannot_open_file:
		return kg_fail(err, access(path, F_OK) != 0 ? KG_ENOENT : KG_EIO, "%s", e.text);
	case json_error_out_of_memory:
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	default:
		return kg_fail(err, KG_EINVAL, "%s:%d:%d: %s", path, e.line, e.column, e.text);
	}
}

static const char *kind(const json_t *v)
{
	switch (json_typeof(v)) {
	case JSON_OBJECT: return "an object";
	case JSON_ARRAY: return "an array";
	case JSON_STRING: return "a string";
	case JSON_INTEGER:
	case JSON_REAL: return "a number";
	case JSON_TRUE:
	case JSON_FALSE: return "a boolean";
	default: return "null";
	}
}

/* Walk a key path. On failure the message names the longest prefix that failed. */
static int walk(const char *file, const json_t *root, const char *path, json_t **out,
                kg_err *err)
{
	*out = NULL;
	if (!root || !path)
		return kg_fail(err, KG_EINVAL, "%s: no document or key path given", file);
	const json_t *cur = root;
	const char *p = path;
	while (*p) {
		int done = (int)(p - path);
		if (*p == '[') {
			char *end;
			errno = 0;
			long idx = strtol(p + 1, &end, 10);
			if (end == p + 1 || *end != ']' || idx < 0 || errno)
				return kg_fail(err, KG_EINVAL, "%s: key path '%s': bad index at '%s'", file,
				               path, p);
			if (!json_is_array(cur))
				return kg_fail(err, KG_EINVAL, "%s: key '%.*s': expected an array, got %s",
				               file, done, done ? path : "(top level)", kind(cur));
			if ((size_t)idx >= json_array_size(cur))
				return kg_fail(err, KG_EINVAL,
				               "%s: key '%.*s': expected at least %ld elements, got %zu", file,
				               done, done ? path : "(top level)", idx + 1,
				               json_array_size(cur));
			cur = json_array_get(cur, (size_t)idx);
			p = end + 1;
			continue;
		}
		if (*p == '.' && p != path)
			p++;
		size_t n = strcspn(p, ".[");
		if (n == 0)
			return kg_fail(err, KG_EINVAL, "%s: key path '%s': empty key", file, path);
		if (!json_is_object(cur))
			return kg_fail(err, KG_EINVAL, "%s: key '%.*s': expected an object, got %s", file,
			               done, done ? path : "(top level)", kind(cur));
		json_t *v = json_object_getn(cur, p, n);
		if (!v)
			return kg_fail(err, KG_EINVAL, "%s: key '%.*s' is missing", file,
			               (int)(p + n - path), path);
		cur = v;
		p += n;
	}
	*out = (json_t *)cur;
	return 0;
}

json_t *kg_json_find(const json_t *root, const char *path)
{
	json_t *v;
	return walk("", root, path, &v, NULL) == 0 ? v : NULL;
}

/* The value at path, a number (string 0) or a string (string 1). */
static int walk_scalar(const char *file, const json_t *root, const char *path, int string,
                       json_t **v, kg_err *err)
{
	int ret = walk(file, root, path, v, err);
	if (ret)
		return ret;
	if (string ? !json_is_string(*v) : !json_is_number(*v))
		return kg_fail(err, KG_EINVAL, "%s: key '%s': expected %s, got %s", file, path,
		               string ? "a string" : "a number", kind(*v));
	return 0;
}

int kg_json_get(const char *file, const json_t *root, const char *path, json_t **out,
                kg_err *err)
{
	kg_check_arg(out, err);
	return walk(file ? file : "(json)", root, path, out, err);
}

int kg_json_get_number(const char *file, const json_t *root, const char *path, double *out,
                       kg_err *err)
{
	kg_check_arg(out, err);
	file = file ? file : "(json)";
	json_t *v;
	int ret = walk_scalar(file, root, path, 0, &v, err);
	if (ret)
		return ret;
	*out = json_number_value(v);
	return 0;
}

int kg_json_get_int(const char *file, const json_t *root, const char *path, long min, long max,
                    long *out, kg_err *err)
{
	kg_check_arg(out, err);
	file = file ? file : "(json)";
	double d;
	int ret = kg_json_get_number(file, root, path, &d, err);
	if (ret)
		return ret;
	if (d != floor(d) || fabs(d) > 9e18 || d < (double)min || d > (double)max)
		return kg_fail(err, KG_EINVAL, "%s: key '%s': got %.17g: expected an integer from %ld to %ld",
		               file, path, d, min, max);
	*out = (long)d;
	return 0;
}

int kg_json_get_string(const char *file, const json_t *root, const char *path,
                       const char **out, kg_err *err)
{
	kg_check_arg(out, err);
	file = file ? file : "(json)";
	json_t *v;
	int ret = walk_scalar(file, root, path, 1, &v, err);
	if (ret)
		return ret;
	*out = json_string_value(v);
	return 0;
}

/* Numbers of one array into out; `what` is the key path shown in messages. */
static int read_row(const char *file, const char *what, const json_t *v, int n, double *out,
                    kg_err *err)
{
	if (!json_is_array(v))
		return kg_fail(err, KG_EINVAL, "%s: key '%s': expected an array of %d numbers, got %s",
		               file, what, n, kind(v));
	if (json_array_size(v) != (size_t)n)
		return kg_fail(err, KG_EINVAL, "%s: key '%s': expected %d numbers, got %zu", file, what,
		               n, json_array_size(v));
	for (int i = 0; i < n; i++) {
		json_t *e = json_array_get(v, (size_t)i);
		if (!json_is_number(e))
			return kg_fail(err, KG_EINVAL, "%s: key '%s[%d]': expected a number, got %s", file,
			               what, i, kind(e));
		out[i] = json_number_value(e);
	}
	return 0;
}

int kg_json_get_numbers(const char *file, const json_t *root, const char *path, int n,
                        double *out, kg_err *err)
{
	kg_check_arg(n >= 0 && (out || n == 0), err);
	file = file ? file : "(json)";
	json_t *v;
	int ret = walk(file, root, path, &v, err);
	return ret ? ret : read_row(file, path, v, n, out, err);
}

int kg_json_get_matrix(const char *file, const json_t *root, const char *path, int rows,
                       int cols, kg_mat **out, kg_err *err)
{
	kg_check_arg(out && (rows > 0 || rows == KG_JSON_ANY) && (cols > 0 || cols == KG_JSON_ANY),
	             err);
	*out = NULL;
	file = file ? file : "(json)";
	json_t *v;
	int ret = walk(file, root, path, &v, err);
	if (ret)
		return ret;
	if (!json_is_array(v) || json_array_size(v) == 0 ||
	    (rows != KG_JSON_ANY && json_array_size(v) != (size_t)rows)) {
		char want[64];
		if (rows == KG_JSON_ANY)
			snprintf(want, sizeof(want), "a non-empty array of rows");
		else
			snprintf(want, sizeof(want), "an array of %d rows", rows);
		if (json_is_array(v))
			return kg_fail(err, KG_EINVAL, "%s: key '%s': expected %s, got %zu rows", file,
			               path, want, json_array_size(v));
		return kg_fail(err, KG_EINVAL, "%s: key '%s': expected %s, got %s", file, path, want,
		               kind(v));
	}
	int r = (int)json_array_size(v);
	if (cols == KG_JSON_ANY) {
		json_t *first = json_array_get(v, 0);
		if (!json_is_array(first) || json_array_size(first) == 0)
			return kg_fail(err, KG_EINVAL,
			               "%s: key '%s[0]': expected a non-empty array of numbers, got %s",
			               file, path, json_is_array(first) ? "an empty array" : kind(first));
		cols = (int)json_array_size(first);
	}
	kg_mat *m;
	if ((ret = kg_mat_new(r, cols, &m, err)))
		return ret;
	size_t n = strlen(path) + 24;
	char *what = malloc(n);
	if (!what) {
		kg_mat_free(&m);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", file);
	}
	for (int i = 0; i < r && ret == 0; i++) {
		snprintf(what, n, "%s[%d]", path, i);
		ret = read_row(file, what, json_array_get(v, (size_t)i), cols, m->a + (long)i * cols,
		               err);
	}
	free(what);
	if (ret)
		kg_mat_free(&m);
	*out = m;
	return ret;
}

int kg_json_numbers(const double *v, int n, json_t **out, kg_err *err)
{
	kg_check_arg(out && n >= 0 && (v || n == 0), err);
	*out = NULL;
	json_t *a = json_array();
	if (!a)
		return kg_fail(err, KG_ENOMEM, "out of memory building JSON");
	for (int i = 0; i < n; i++) {
		if (!isfinite(v[i])) {
			json_decref(a);
			return kg_fail(err, KG_EINVAL, "element %d is %g: expected a finite number (JSON has "
			               "no NaN or Inf)", i, v[i]);
		}
		if (json_array_append_new(a, json_real(v[i])) != 0) {
			json_decref(a);
			return kg_fail(err, KG_ENOMEM, "out of memory building JSON");
		}
	}
	*out = a;
	return 0;
}

int kg_json_matrix(const kg_mat *m, json_t **out, kg_err *err)
{
	kg_check_arg(m && out, err);
	*out = NULL;
	int ret = kg_mat_check_finite(m, "matrix for JSON", err);
	if (ret)
		return ret;
	json_t *a = json_array();
	if (!a)
		return kg_fail(err, KG_ENOMEM, "out of memory building JSON");
	for (int r = 0; r < m->rows; r++) {
		json_t *row;
		if ((ret = kg_json_numbers(m->a + (long)r * m->cols, m->cols, &row, err)))
			break;
		if (json_array_append_new(a, row) != 0) {
			ret = kg_fail(err, KG_ENOMEM, "out of memory building JSON");
			break;
		}
	}
	if (ret)
		json_decref(a);
	else
		*out = a;
	return ret;
}

int kg_json_write(const json_t *root, const char *path, kg_err *err)
{
	kg_check_arg(root && path, err);
	kg_outfile o;
	int ret = kg_outfile_open(&o, path, 1, err);
	if (ret)
		return ret;
	errno = 0;
	if (json_dumpf(root, o.fp, JSON_INDENT(2) | JSON_REAL_PRECISION(17)) != 0 ||
	    fputc('\n', o.fp) == EOF) {
		int e = errno;
		kg_outfile_abort(&o);
		if (e == ENOSPC || e == EDQUOT)
			return kg_fail_write(err, e, path, "cannot write JSON");
		return kg_fail(err, KG_EIO, "%s: cannot write JSON (invalid value or write error)",
		               path);
	}
	return kg_outfile_commit(&o, err);
}
