/* Helpers shared by the colorimetry tests: spectra from colord's CGATS files and
 * wavelength columns from the reference CSV files. */
#ifndef KG_TEST_SPECTRA_IO_H
#define KG_TEST_SPECTRA_IO_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_core.h"

#define COLORD_DIR "/usr/share/colord"

/* The spectral sets of the first table of a CGATS file: *wl (n), *v (nsets x n,
 * row-major) and, when the file has SAMPLE_ID, *ids (nsets strings). Fails the whole
 * test program on error, naming the file. */
typedef struct test_spectra {
	int n, nsets;
	double *wl, *v;
	char **ids;
} test_spectra;

static inline void test_spectra_free(test_spectra *s)
{
	for (int i = 0; s->ids && i < s->nsets; i++)
		free(s->ids[i]);
	free(s->ids);
	free(s->wl);
	free(s->v);
	memset(s, 0, sizeof(*s));
}

static inline test_spectra test_spectra_read(const char *path)
{
	test_spectra s = {0};
	kg_err err = {{0}};
	kg_cgats *cg = NULL;
	int *fields = NULL;
	if (kg_cgats_read(path, &cg, &err) != 0 ||
	    kg_cgats_spectral_fields(cg->tables[0], &fields, &s.wl, &s.n, &err) != 0) {
		fprintf(stderr, "%s\n", err.msg);
		exit(1);
	}
	const kg_cgats_table *t = cg->tables[0];
	s.nsets = t->nsets;
	s.v = malloc(sizeof(double) * (size_t)(s.n * s.nsets));
	s.ids = calloc((size_t)s.nsets, sizeof(char *));
	int id_field = kg_cgats_field(t, "SAMPLE_ID");
	if (!s.v || !s.ids || s.n < 2 || s.nsets < 1) {
		fprintf(stderr, "%s: expected spectral data (%d bands, %d sets)\n", path, s.n,
		        s.nsets);
		exit(1);
	}
	for (int j = 0; j < s.nsets; j++) {
		s.ids[j] = strdup(id_field >= 0 ? kg_cgats_cell(t, j, id_field) : "");
		for (int i = 0; i < s.n; i++)
			if (kg_cgats_number(t, j, fields[i], &s.v[j * s.n + i], &err) != 0) {
				fprintf(stderr, "%s\n", err.msg);
				exit(1);
			}
	}
	free(fields);
	kg_cgats_free(&cg);
	return s;
}

/* A two-or-more column numeric CSV with one header row: column 0 into wl, column
 * `col` into v (both sized for `max` rows). Returns the row count; fails the test
 * program when the file is unreadable. */
static inline int test_csv_column(const char *path, int col, double *wl, double *v,
                                  int max)
{
	FILE *fp = fopen(path, "r");
	if (!fp) {
		fprintf(stderr, "%s: cannot open\n", path);
		exit(1);
	}
	char line[4096];
	int n = 0;
	if (!fgets(line, sizeof(line), fp)) {
		fprintf(stderr, "%s: empty\n", path);
		exit(1);
	}
	while (n < max && fgets(line, sizeof(line), fp)) {
		char *p = line, *end;
		double first = strtod(p, &end);
		if (end == p)
			continue;
		double val = 0.0;
		for (int c = 1; c <= col; c++) {
			p = strchr(end, ',');
			if (!p) {
				fprintf(stderr, "%s: row %d: expected column %d\n", path, n + 2, col);
				exit(1);
			}
			val = strtod(p + 1, &end);
		}
		wl[n] = first;
		v[n] = val;
		n++;
	}
	fclose(fp);
	return n;
}

#endif
