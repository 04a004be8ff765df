/* Reading and writing the project's JSON files (calibrations, manifests, material
 * libraries, scenes) over jansson, with messages that name the file, the key path
 * and what was expected.
 *
 * A key path walks nested objects and arrays from the root: "M", "devices.camera.id",
 * "patches[3].rgb". Getters return borrowed values that live as long as the root. */
#ifndef KG_JSON_H
#define KG_JSON_H

#include <jansson.h>

#include "error.h"
#include "linalg.h"

/* Load and parse a file; a syntax error names file:line:column. Duplicate keys in an
 * object are refused. The caller owns *root (json_decref). */
int kg_json_load(const char *path, json_t **root, kg_err *err);

/* The value at a key path, or NULL when any step is missing or of the wrong kind
 * (for optional keys). */
json_t *kg_json_find(const json_t *root, const char *path);

/* Required values. `file` names the document in messages. */
int kg_json_get(const char *file, const json_t *root, const char *path, json_t **out,
                kg_err *err);
int kg_json_get_number(const char *file, const json_t *root, const char *path, double *out,
                       kg_err *err);
/* An integral number within [min, max]. */
int kg_json_get_int(const char *file, const json_t *root, const char *path, long min, long max,
                    long *out, kg_err *err);
int kg_json_get_string(const char *file, const json_t *root, const char *path,
                       const char **out, kg_err *err);
/* An array of exactly n numbers into out[0..n-1]. */
int kg_json_get_numbers(const char *file, const json_t *root, const char *path, int n,
                        double *out, kg_err *err);
/* An array of `rows` arrays of `cols` numbers each; KG_JSON_ANY accepts any size
 * (rows must still all have the same length). */
#define KG_JSON_ANY (-1)
int kg_json_get_matrix(const char *file, const json_t *root, const char *path, int rows,
                       int cols, kg_mat **out, kg_err *err);

/* New JSON values for writing; non-finite numbers are refused (JSON has none). */
int kg_json_numbers(const double *v, int n, json_t **out, kg_err *err);
int kg_json_matrix(const kg_mat *m, json_t **out, kg_err *err);

/* Write root atomically with two-space indentation and a trailing newline. Keys keep
 * their insertion order (stable from run to run). "-" writes to standard output. */
int kg_json_write(const json_t *root, const char *path, kg_err *err);

#endif
