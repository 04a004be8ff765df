/* read_names cgats FILE | read_names envi FILE.hdr: the text a file holds as kogei's
 * own readers see it, printed as JSON (ASCII, \u escapes) for test_hostile_names.sh to
 * compare with what went in.
 *   cgats: {"keywords": {NAME: VALUE, ...}, "fields": [...], "sets": [[cell, ...], ...]}
 *          for the first table
 *   envi:  {"description": ..., "class_names": [...], "band_names": [...]} */
#include <stdio.h>
#include <string.h>

#include "kg_core.h"

static json_t *strings(const char *const *s, int n)
{
	json_t *a = json_array();
	for (int i = 0; s && i < n; i++)
		json_array_append_new(a, kg_json_message(s[i]));
	return a;
}

static json_t *cgats_names(const char *path, kg_err *err)
{
	kg_cgats *cg = NULL;
	if (kg_cgats_read(path, &cg, err))
		return NULL;
	const kg_cgats_table *t = cg->tables[0];
	json_t *kw = json_object(), *sets = json_array();
	for (int i = 0; i < t->nkeywords; i++)
		json_object_set_new(kw, t->keywords[i].name, kg_json_message(t->keywords[i].value));
	for (int s = 0; s < t->nsets; s++) {
		json_t *row = json_array();
		for (int f = 0; f < t->nfields; f++)
			json_array_append_new(row, kg_json_message(kg_cgats_cell(t, s, f)));
		json_array_append_new(sets, row);
	}
	json_t *j = json_pack("{s:o, s:o, s:o}", "keywords", kw, "fields",
	                      strings((const char *const *)t->fields, t->nfields), "sets", sets);
	kg_cgats_free(&cg);
	return j;
}

static json_t *envi_names(const char *path, kg_err *err)
{
	kg_envi *e = NULL;
	if (kg_envi_open(path, &e, err))
		return NULL;
	const kg_envi_meta *m = &e->meta;
	json_t *j = json_pack("{s:o, s:o, s:o}", "description",
	                      m->description ? kg_json_message(m->description) : json_null(),
	                      "class_names", strings(m->class_names, m->classes), "band_names",
	                      strings(m->band_names, m->band_names ? m->bands : 0));
	kg_envi_close(&e);
	return j;
}

int main(int argc, char **argv)
{
	if (argc != 3 || (strcmp(argv[1], "cgats") && strcmp(argv[1], "envi"))) {
		fprintf(stderr, "usage: read_names cgats|envi FILE\n");
		return 2;
	}
	kg_err err = {{0}};
	json_t *j = strcmp(argv[1], "cgats") ? envi_names(argv[2], &err)
	                                     : cgats_names(argv[2], &err);
	if (!j) {
		fprintf(stderr, "read_names: %s\n", err.msg);
		return 1;
	}
	json_dumpf(j, stdout, JSON_ENSURE_ASCII | JSON_INDENT(1));
	putchar('\n');
	json_decref(j);
	return 0;
}
