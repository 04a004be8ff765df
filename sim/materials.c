/* Material samples for scenes: reflectance of library materials at one incidence. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "kg_sim.h"

void kg_sim_material_set_free(kg_sim_material_set **ps)
{
	if (!ps || !*ps)
		return;
	kg_sim_material_set *s = *ps;
	if (s->names)
		for (int i = 0; i < s->n; i++)
			free(s->names[i]);
	free(s->names);
	free(s->reflectance);
	free(s);
	*ps = NULL;
}

/* Split `only` at commas into the materials to take (blanks around names ignored). */
static int select_materials(const kg_material_library *lib, const char *library_path,
                            const char *only, const kg_material ***sel, int *n, kg_err *err)
{
	int count = kg_material_library_count(lib);
	*sel = NULL;
	*n = 0;
	if (!only) {
		*sel = malloc((size_t)(count > 0 ? count : 1) * sizeof(**sel));
		if (!*sel)
			return kg_fail(err, KG_ENOMEM, "%s: out of memory", library_path);
		for (int i = 0; i < count; i++)
			(*sel)[i] = kg_material_library_get(lib, i);
		*n = count;
		return 0;
	}
	int cap = 1;
	for (const char *p = only; *p; p++)
		cap += *p == ',';
	*sel = malloc((size_t)cap * sizeof(**sel));
	char *copy = strdup(only);
	if (!*sel || !copy) {
		free(copy);
		free(*sel);
		*sel = NULL;
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", library_path);
	}
	int ret = 0;
	char *save = NULL;
	for (char *tok = strtok_r(copy, ",", &save); tok && !ret;
	     tok = strtok_r(NULL, ",", &save)) {
		while (*tok == ' ' || *tok == '\t')
			tok++;
		char *end = tok + strlen(tok);
		while (end > tok && (end[-1] == ' ' || end[-1] == '\t'))
			*--end = '\0';
		if (!*tok)
			continue;
		const kg_material *m = kg_material_library_find(lib, tok);
		if (!m) {
			char names[768];
			kg_material_library_names(lib, names, sizeof(names));
			ret = kg_fail(err, KG_EINVAL, "%s: no material '%s' (--only); expected one of: %s",
			              library_path, tok, names);
			break;
		}
		for (int j = 0; j < *n && !ret; j++)
			if ((*sel)[j] == m)
				ret = kg_fail(err, KG_EINVAL, "--only: material '%s' named twice", tok);
		if (!ret)
			(*sel)[(*n)++] = m;
	}
	free(copy);
	if (!ret && *n == 0)
		ret = kg_fail(err, KG_EINVAL, "--only '%s': expected material names separated by commas",
		              only);
	if (ret) {
		free(*sel);
		*sel = NULL;
		*n = 0;
	}
	return ret;
}

int kg_sim_material_set_load(const char *library_path, const char *only, double angle_deg,
                             kg_sim_material_set **out, kg_err *err)
{
	kg_check_arg(library_path && out, err);
	*out = NULL;
	if (!(angle_deg >= 0.0 && angle_deg <= 90.0))
		return kg_fail(err, KG_EINVAL, "angle %g: expected 0 to 90 degrees", angle_deg);
	kg_material_library *lib = NULL;
	int ret = kg_material_library_load(library_path, &lib, err);
	if (ret)
		return ret;
	const kg_material **sel = NULL;
	int n = 0;
	ret = select_materials(lib, library_path, only, &sel, &n, err);
	if (ret) {
		kg_material_library_free(&lib);
		return ret;
	}
	kg_sim_material_set *s = calloc(1, sizeof(*s));
	if (s) {
		s->angle_deg = angle_deg;
		s->names = calloc((size_t)(n > 0 ? n : 1), sizeof(*s->names));
		s->reflectance = malloc((size_t)(n > 0 ? n : 1) * sizeof(*s->reflectance));
	}
	if (!s || !s->names || !s->reflectance) {
		ret = kg_fail(err, KG_ENOMEM, "%s: out of memory", library_path);
		goto done;
	}
	if (n == 0) {
		ret = kg_fail(err, KG_EINVAL, "%s: the library holds no materials", library_path);
		goto done;
	}
	double theta = angle_deg * (M_PI / 180.0);
	for (int i = 0; i < n; i++) {
		s->names[i] = strdup(sel[i]->name);
		s->n = i + 1;
		if (!s->names[i]) {
			ret = kg_fail(err, KG_ENOMEM, "%s: out of memory", library_path);
			goto done;
		}
		ret = kg_material_reflectance(sel[i], theta, &s->reflectance[i], err);
		if (ret) {
			kg_err_prefix(err, "%s: material %s", library_path, sel[i]->name);
			goto done;
		}
	}
done:
	free(sel);
	kg_material_library_free(&lib);
	if (ret) {
		kg_sim_material_set_free(&s);
		return ret;
	}
	*out = s;
	return 0;
}
