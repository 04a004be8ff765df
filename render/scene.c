/* The scene (handoff) format, "kogei-scene/1" (docs/render.md): parsed and checked
 * here, with messages naming the scene file and the key path. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "render_private.h"

#define SCENE_MAX_ICOSPHERE_LEVEL 8

#define SCENE_FORMAT "kogei-scene/1"
#define MAX_SIZE 16384      /* pixels per side */
#define MAX_SPP 1000000
#define MAX_BOUNCES 64
#define MAX_MATERIALS 65535 /* tri_mat is 16 bits */

/* ---- small helpers ------------------------------------------------------------ */

/* A path from the scene file: absolute as given, relative to the scene's folder. */
static char *scene_relative(const kg_scene *s, const char *name)
{
	if (name[0] == '/')
		return strdup(name);
	char *dir = kg_path_dir(s->path);
	char *p = dir ? kg_path_join(dir, name) : NULL;
	free(dir);
	return p;
}

static int file_exists(const char *path)
{
	struct stat st;
	return stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

/* Refuse keys outside `allowed` (typos would otherwise be silently ignored). */
static int check_keys(const char *file, const json_t *obj, const char *path,
                      const char *const *allowed, kg_err *err)
{
	const char *key;
	json_t *v;
	json_object_foreach((json_t *)obj, key, v) {
		int ok = 0;
		for (int i = 0; allowed[i] && !ok; i++)
			ok = strcmp(key, allowed[i]) == 0;
		if (!ok) {
			char list[512] = "";
			for (int i = 0; allowed[i]; i++) {
				size_t len = strlen(list);
				snprintf(list + len, sizeof(list) - len, "%s%s", i ? ", " : "", allowed[i]);
			}
			return kg_fail(err, KG_EINVAL, "%s: key '%s%s%s': unknown key (expected one "
			               "of: %s)", file, path, *path ? "." : "", key, list);
		}
	}
	return 0;
}

/* An object at path (required). */
static int get_object(const char *file, const json_t *root, const char *path, json_t **out,
                      kg_err *err)
{
	int ret = kg_json_get(file, root, path, out, err);
	if (!ret && !json_is_object(*out))
		ret = kg_fail(err, KG_EINVAL, "%s: key '%s': expected an object", file, path);
	return ret;
}

static int get_vec3(const char *file, const json_t *root, const char *path, double v[3],
                    kg_err *err)
{
	int ret = kg_json_get_numbers(file, root, path, 3, v, err);
	if (!ret && !(isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2])))
		ret = kg_fail(err, KG_EINVAL, "%s: key '%s': expected 3 finite numbers", file, path);
	return ret;
}

/* An optional number in [min, max] (def when absent). */
static int opt_number(const char *file, const json_t *root, const char *path, double def,
                      double min, double max, double *out, kg_err *err)
{
	*out = def;
	if (!kg_json_find(root, path))
		return 0;
	int ret = kg_json_get_number(file, root, path, out, err);
	if (!ret && !(*out >= min && *out <= max))
		ret = kg_fail(err, KG_EINVAL, "%s: key '%s': got %g: expected a number from %g to "
		              "%g", file, path, *out, min, max);
	return ret;
}

static int opt_int(const char *file, const json_t *root, const char *path, long def,
                   long min, long max, long *out, kg_err *err)
{
	*out = def;
	return kg_json_find(root, path) ? kg_json_get_int(file, root, path, min, max, out, err)
	                                : 0;
}

static void normalize3(double v[3])
{
	double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
	for (int i = 0; i < 3; i++)
		v[i] /= n;
}

static void cross3(const double a[3], const double b[3], double out[3])
{
	out[0] = a[1] * b[2] - a[2] * b[1];
	out[1] = a[2] * b[0] - a[0] * b[2];
	out[2] = a[0] * b[1] - a[1] * b[0];
}

void rd_view_frame(const rd_view *v, rd_frame *f)
{
	for (int i = 0; i < 3; i++)
		f->fwd[i] = v->look_at[i] - v->pos[i];
	normalize3(f->fwd);
	cross3(f->fwd, v->up, f->right);
	normalize3(f->right);
	cross3(f->right, f->fwd, f->up);
	f->tan_half = tan(v->fov_deg * M_PI / 360.0);
}

/* A pose: position, look_at, up (default +z), vertical fov_deg. */
static int parse_pose(const char *file, const json_t *root, const char *path, rd_view *v,
                      kg_err *err)
{
	char key[128];
	int ret;
	snprintf(key, sizeof(key), "%s.position", path);
	if ((ret = get_vec3(file, root, key, v->pos, err)))
		return ret;
	snprintf(key, sizeof(key), "%s.look_at", path);
	if ((ret = get_vec3(file, root, key, v->look_at, err)))
		return ret;
	snprintf(key, sizeof(key), "%s.up", path);
	v->up[0] = 0, v->up[1] = 0, v->up[2] = 1;
	if (kg_json_find(root, key) && (ret = get_vec3(file, root, key, v->up, err)))
		return ret;
	snprintf(key, sizeof(key), "%s.fov_deg", path);
	if ((ret = kg_json_get_number(file, root, key, &v->fov_deg, err)))
		return ret;
	if (!(v->fov_deg > 0.0 && v->fov_deg < 180.0))
		return kg_fail(err, KG_EINVAL, "%s: key '%s': got %g: expected a vertical field of "
		               "view in degrees, above 0 and below 180", file, key, v->fov_deg);
	double fwd[3], side[3];
	for (int i = 0; i < 3; i++)
		fwd[i] = v->look_at[i] - v->pos[i];
	double len = sqrt(fwd[0] * fwd[0] + fwd[1] * fwd[1] + fwd[2] * fwd[2]);
	if (!(len > 0.0))
		return kg_fail(err, KG_EINVAL, "%s: key '%s.look_at': expected a point other than "
		               "the position", file, path);
	normalize3(fwd);
	cross3(fwd, v->up, side);
	double ulen = sqrt(v->up[0] * v->up[0] + v->up[1] * v->up[1] + v->up[2] * v->up[2]);
	if (!(sqrt(side[0] * side[0] + side[1] * side[1] + side[2] * side[2]) > 1e-6 * ulen))
		return kg_fail(err, KG_EINVAL, "%s: key '%s.up': expected a direction not parallel "
		               "to the line of sight", file, path);
	return 0;
}

/* A standard illuminant name, else a CGATS file relative to the scene. */
static int load_illuminant(kg_scene *s, const json_t *root, const char *path,
                           kg_illuminant **out, kg_err *err)
{
	const char *name;
	int ret = kg_json_get_string(s->path, root, path, &name, err);
	if (ret)
		return ret;
	if (kg_illuminant_by_name(name, out, NULL) == 0)
		return 0;
	char *file = scene_relative(s, name);
	if (!file)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	if (!file_exists(file))
		ret = kg_fail(err, KG_EINVAL, "%s: key '%s': '%s' is neither a standard illuminant "
		              "(D65, A, E, D50, 5500K, ...) nor a file (looked for %s)", s->path,
		              path, name, file);
	else if ((ret = kg_illuminant_from_file(file, out, err)))
		kg_err_prefix(err, "%s: key '%s'", s->path, path);
	free(file);
	return ret;
}

/* ---- materials ------------------------------------------------------------------ */

int rd_scene_material_index(kg_scene *s, const char *name, const char *field, kg_err *err)
{
	for (int i = 0; i < s->nmat; i++)
		if (strcmp(s->mat[i]->name, name) == 0)
			return i;
	const kg_material *m = kg_material_library_find(s->lib, name);
	if (!m && strcmp(name, KG_SCENE_NEUTRAL_GREY) == 0) {
		/* n = 1: no surface reflection; the flat body alone, a Lambertian grey */
		kg_material *g = &s->neutral;
		memset(g, 0, sizeof(*g));
		snprintf(g->name, sizeof(g->name), "%s", KG_SCENE_NEUTRAL_GREY);
		g->kind = KG_MATERIAL_DIELECTRIC;
		g->nk.n = kg_spectrum_const(1.0);
		g->nk.k = kg_spectrum_const(0.0);
		g->body = kg_spectrum_const(KG_SCENE_NEUTRAL_GREY_LEVEL);
		g->roughness = 0.1;
		g->mirror_width = 0.02;
		m = g;
	}
	if (!m) {
		char known[512] = "";
		for (int i = 0; i < kg_material_library_count(s->lib); i++) {
			size_t len = strlen(known);
			snprintf(known + len, sizeof(known) - len, "%s%s", i ? ", " : "",
			         kg_material_library_get(s->lib, i)->name);
		}
		return kg_fail(err, KG_EINVAL, "%s: key '%s': no material named '%s' in %s (it "
		               "has: %s; and every scene has %s)", s->path, field, name,
		               s->library_path, known, KG_SCENE_NEUTRAL_GREY);
	}
	if (s->nmat >= MAX_MATERIALS)
		return kg_fail(err, KG_EINVAL, "%s: key '%s': more than %d materials", s->path,
		               field, MAX_MATERIALS);
	const kg_material **mat = realloc(s->mat, sizeof(*mat) * (size_t)(s->nmat + 1));
	if (!mat)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	s->mat = mat;
	s->mat[s->nmat] = m;
	return s->nmat++;
}

/* "face_ids" / "vertex_ids": {"<id>": "<material>", ...} onto the mesh's ids. */
static int assign_ids(kg_scene *s, const json_t *root, const char *path, int per_vertex,
                      kg_err *err)
{
	const kg_mesh *mesh = s->mesh;
	const int32_t *ids = per_vertex ? mesh->vert_material : mesh->tri_material;
	if (!ids)
		return kg_fail(err, KG_EINVAL, "%s: key '%s': the mesh has no per-%s material ids "
		               "(a `material` or `material_index` property of its %s element)",
		               s->path, path, per_vertex ? "vertex" : "face",
		               per_vertex ? "vertex" : "face");
	json_t *map;
	int ret = get_object(s->path, root, path, &map, err);
	if (ret)
		return ret;
	size_t n = json_object_size(map);
	if (n == 0)
		return kg_fail(err, KG_EINVAL, "%s: key '%s': expected at least one \"id\": "
		               "\"material\" pair", s->path, path);
	long *key_id = malloc(sizeof(long) * n);
	int *key_mat = malloc(sizeof(int) * n);
	if (!key_id || !key_mat)
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	const char *key;
	json_t *v;
	size_t k = 0;
	json_object_foreach(map, key, v) {
		if (ret)
			break;
		char field[256], *end;
		snprintf(field, sizeof(field), "%s.%s", path, key);
		key_id[k] = strtol(key, &end, 10);
		if (!*key || *end)
			ret = kg_fail(err, KG_EINVAL, "%s: key '%s': expected an integer material id "
			              "as the key", s->path, field);
		else if (!json_is_string(v))
			ret = kg_fail(err, KG_EINVAL, "%s: key '%s': expected a material name", s->path,
			              field);
		else if ((key_mat[k] = rd_scene_material_index(s, json_string_value(v), field,
		                                                err)) < 0)
			ret = key_mat[k];
		k++;
	}
	if (!ret && !(s->tri_mat = malloc(sizeof(uint16_t) * mesh->ntris)))
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	for (size_t t = 0; !ret && t < mesh->ntris; t++) {
		long id;
		if (per_vertex) {
			/* the majority of the corners' ids; the first corner's on a three-way tie */
			const uint32_t *c = mesh->tri + 3 * t;
			long a = ids[c[0]], b = ids[c[1]], d = ids[c[2]];
			id = (b == d) ? b : a;
		} else {
			id = ids[t];
		}
		size_t j = 0;
		while (j < n && key_id[j] != id)
			j++;
		if (j == n)
			ret = id < 0 ? kg_fail(err, KG_EINVAL, "%s: key '%s': triangle %zu has no "
			                       "material id (give its mesh part a face_id)", s->path,
			                       path, t)
			             : kg_fail(err, KG_EINVAL, "%s: key '%s': the mesh has material id "
			                       "%ld (%s %zu) but the map has no \"%ld\"", s->path, path,
			                       id, per_vertex ? "a corner of triangle" : "triangle", t,
			                       id);
		else
			s->tri_mat[t] = (uint16_t)key_mat[j];
	}
	free(key_id);
	free(key_mat);
	if (!ret)
		s->assign = per_vertex ? RD_ASSIGN_VERTEX : RD_ASSIGN_FACE;
	return ret;
}

static int load_label_map(kg_scene *s, const json_t *root, kg_err *err)
{
	static const char *const keys[] = {"file", "camera", "classes", "fallback", NULL};
	static const char *const pose_keys[] = {"position", "look_at", "up", "fov_deg", NULL};
	const char *path = "materials.label_map";
	rd_label_map *lm = &s->label;
	json_t *obj, *cam;
	const char *file, *fallback;
	int ret = get_object(s->path, root, path, &obj, err);
	if (!ret)
		ret = check_keys(s->path, obj, path, keys, err);
	if (!ret)
		ret = get_object(s->path, root, "materials.label_map.camera", &cam, err);
	if (!ret)
		ret = check_keys(s->path, cam, "materials.label_map.camera", pose_keys, err);
	if (!ret)
		ret = parse_pose(s->path, root, "materials.label_map.camera", &lm->view, err);
	if (!ret)
		ret = kg_json_get_string(s->path, root, "materials.label_map.file", &file, err);
	if (!ret)
		ret = kg_json_get_string(s->path, root, "materials.label_map.fallback", &fallback,
		                         err);
	if (!ret && (lm->fallback = rd_scene_material_index(s, fallback,
	                                                    "materials.label_map.fallback",
	                                                    err)) < 0)
		ret = lm->fallback;
	if (ret)
		return ret;
	if (!(lm->path = scene_relative(s, file)))
		return kg_fail(err, KG_ENOMEM, "out of memory");

	kg_envi *e = NULL;
	float *data = NULL;
	if ((ret = kg_envi_open(lm->path, &e, err))) {
		kg_err_prefix(err, "%s: key 'materials.label_map.file'", s->path);
		return ret;
	}
	const kg_envi_meta *m = &e->meta;
	if (m->classes <= 0 || !m->class_names || m->bands != 1)
		ret = kg_fail(err, KG_EINVAL, "%s: key 'materials.label_map.file': %s: expected an "
		              "ENVI Classification file (one band, `classes` and `class names`), "
		              "as `kogei classify` writes", s->path, lm->path);
	else if (m->classes > 256)
		ret = kg_fail(err, KG_EINVAL, "%s: %s: %d classes: expected at most 256", s->path,
		              lm->path, m->classes);
	size_t npix = (size_t)m->samples * (size_t)m->lines;
	/* read in bands of about 4 MB: only the byte map stays */
	int band = (int)((1u << 20) / (unsigned)(m->samples > 0 ? m->samples : 1)) + 1;
	if (!ret) {
		lm->width = lm->view.width = m->samples;
		lm->height = lm->view.height = m->lines;
		lm->nclasses = m->classes;
		data = malloc(sizeof(float) * (size_t)m->samples * (size_t)band);
		lm->labels = malloc(npix);
		lm->class_mat = malloc(sizeof(int) * (size_t)m->classes);
		lm->class_names = calloc((size_t)m->classes, sizeof(char *));
		for (int c = 0; lm->class_names && c < m->classes; c++)
			if (!(lm->class_names[c] = strdup(m->class_names[c])))
				ret = kg_fail(err, KG_ENOMEM, "out of memory");
		if (!data || !lm->labels || !lm->class_mat || !lm->class_names)
			ret = kg_fail(err, KG_ENOMEM, "out of memory");
	}
	for (int y0 = 0; !ret && y0 < m->lines; y0 += band) {
		int rows = m->lines - y0 < band ? m->lines - y0 : band;
		if ((ret = kg_envi_read(e, 0, y0, m->samples, rows, KG_LAYOUT_BIP, data, err))) {
			kg_err_prefix(err, "%s: key 'materials.label_map.file'", s->path);
			break;
		}
		size_t first = (size_t)y0 * (size_t)m->samples, n = (size_t)rows * (size_t)m->samples;
		for (size_t k = 0; !ret && k < n; k++) {
			size_t i = first + k;
			if (!(data[k] >= 0.0f && data[k] < (float)m->classes) || data[k] != floorf(data[k]))
				ret = kg_fail(err, KG_EINVAL, "%s: %s: pixel (%zu, %zu) holds %g: expected a "
				              "class from 0 to %d", s->path, lm->path, i % (size_t)m->samples,
				              i / (size_t)m->samples, (double)data[k], m->classes - 1);
			else
				lm->labels[i] = (uint8_t)data[k];
		}
	}
	json_t *classes = json_object_get(obj, "classes");
	if (!ret && classes && !json_is_object(classes))
		ret = kg_fail(err, KG_EINVAL, "%s: key 'materials.label_map.classes': expected an "
		              "object of \"class name\": \"material\"", s->path);
	if (!ret && classes) {
		/* every key must name a class of the map */
		const char *key;
		json_t *v;
		json_object_foreach(classes, key, v) {
			int found = 0;
			for (int c = 0; c < m->classes && !found; c++)
				found = strcmp(m->class_names[c], key) == 0;
			if (!found) {
				ret = kg_fail(err, KG_EINVAL, "%s: key 'materials.label_map.classes.%s': "
				              "%s has no class of that name", s->path, key, lm->path);
				break;
			}
			if (!json_is_string(v)) {
				ret = kg_fail(err, KG_EINVAL, "%s: key 'materials.label_map.classes.%s': "
				              "expected a material name", s->path, key);
				break;
			}
		}
	}
	for (int c = 0; !ret && c < m->classes; c++) {
		const char *cname = m->class_names[c];
		json_t *mapped = classes ? json_object_get(classes, cname) : NULL;
		char field[256];
		snprintf(field, sizeof(field), "materials.label_map.classes.%s", cname);
		if (mapped) {
			lm->class_mat[c] = rd_scene_material_index(s, json_string_value(mapped), field,
			                                           err);
			ret = lm->class_mat[c] < 0 ? lm->class_mat[c] : 0;
		} else if (c == 0) {
			lm->class_mat[c] = -1; /* unclassified: the fallback */
		} else if (kg_material_library_find(s->lib, cname)) {
			lm->class_mat[c] = rd_scene_material_index(s, cname, field, err);
			ret = lm->class_mat[c] < 0 ? lm->class_mat[c] : 0;
		} else {
			ret = kg_fail(err, KG_EINVAL, "%s: key 'materials.label_map': class %d '%s' of "
			              "%s is not a material of %s: map it in "
			              "materials.label_map.classes", s->path, c, cname, lm->path,
			              s->library_path);
		}
	}
	free(data);
	kg_envi_close(&e);
	if (!ret)
		s->assign = RD_ASSIGN_LABEL_MAP;
	return ret;
}

static int load_materials(kg_scene *s, const json_t *root, kg_err *err)
{
	static const char *const keys[] = {"library", "material", "face_ids", "vertex_ids",
	                                   "label_map", NULL};
	json_t *obj;
	int ret = get_object(s->path, root, "materials", &obj, err);
	if (!ret)
		ret = check_keys(s->path, obj, "materials", keys, err);
	if (ret)
		return ret;
	json_t *lib = json_object_get(obj, "library");
	if (lib && !json_is_string(lib))
		return kg_fail(err, KG_EINVAL, "%s: key 'materials.library': expected a file name",
		               s->path);
	/* A file beside the scene, else a bundled library's name (kg_material_library_resolve);
	 * without the key, the bundled default. */
	const char *lib_name = lib ? json_string_value(lib) : "default";
	char *beside = lib ? scene_relative(s, lib_name) : NULL;
	if (beside && !strchr(lib_name, '/') && !file_exists(beside)) {
		free(beside);
		beside = NULL;
	}
	if (beside)
		s->library_path = beside;
	else if ((ret = kg_material_library_resolve(lib_name, &s->library_path, err))) {
		kg_err_prefix(err, "%s: key 'materials.library': ", s->path);
		return ret;
	}
	if ((ret = kg_material_library_load(s->library_path, &s->lib, err))) {
		kg_err_prefix(err, "%s: key 'materials.library'", s->path);
		return ret;
	}
	static const char *const modes[] = {"material", "face_ids", "vertex_ids", "label_map"};
	int nmodes = 0, mode = -1;
	for (int i = 0; i < 4; i++)
		if (json_object_get(obj, modes[i]))
			nmodes++, mode = i;
	if (nmodes != 1)
		return kg_fail(err, KG_EINVAL, "%s: key 'materials': expected exactly one of "
		               "material, face_ids, vertex_ids, label_map (%d given)", s->path,
		               nmodes);
	switch (mode) {
	case 0: {
		const char *name;
		if ((ret = kg_json_get_string(s->path, root, "materials.material", &name, err)))
			return ret;
		ret = rd_scene_material_index(s, name, "materials.material", err);
		s->assign = RD_ASSIGN_ONE;
		return ret < 0 ? ret : 0;
	}
	case 1: return assign_ids(s, root, "materials.face_ids", 0, err);
	case 2: return assign_ids(s, root, "materials.vertex_ids", 1, err);
	default: return load_label_map(s, root, err);
	}
}

int kg_scene_set_material(kg_scene *s, const char *name, kg_err *err)
{
	kg_check_arg(s && name, err);
	if (!kg_material_library_find(s->lib, name))
		return rd_scene_material_index(s, name, "materials.material", err);
	free(s->tri_mat);
	s->tri_mat = NULL;
	s->nmat = 0;
	s->assign = RD_ASSIGN_ONE;
	int ret = rd_scene_material_index(s, name, "materials.material", err);
	return ret < 0 ? ret : 0;
}

/* ---- mesh ---------------------------------------------------------------------- */

/* One part: "file.ply", or an object with "ply" or "generator" (icosphere, plane,
 * tsuba) and its parameters, an optional uniform "scale", "translate", "face_id" (the
 * material id of every triangle of the part) and "smooth" (compute vertex normals). */
static int load_part(kg_scene *s, const json_t *root, const char *path, kg_mesh **out,
                     kg_err *err)
{
	static const char *const keys[] = {"ply", "generator", "level", "half_size",
	                                   "segments", "scale", "translate", "face_id",
	                                   "smooth", "background", NULL};
	json_t *item;
	char key[128];
	int ret = kg_json_get(s->path, root, path, &item, err);
	if (ret)
		return ret;
	const char *ply = json_is_string(item) ? json_string_value(item) : NULL;
	if (!ply && !json_is_object(item))
		return kg_fail(err, KG_EINVAL, "%s: key '%s': expected a PLY file name or an object "
		               "with \"ply\" or \"generator\"", s->path, path);
	if (!ply && (ret = check_keys(s->path, item, path, keys, err)))
		return ret;
	json_t *gen = ply ? NULL : json_object_get(item, "generator");
	if (gen && json_object_get(item, "ply"))
		return kg_fail(err, KG_EINVAL,
		               "%s: key '%s': both \"ply\" and \"generator\": expected one of them",
		               s->path, path);
	if (!ply && !gen && json_is_string(json_object_get(item, "ply")))
		ply = json_string_value(json_object_get(item, "ply"));
	if (ply) {
		char *file = scene_relative(s, ply);
		if (!file)
			return kg_fail(err, KG_ENOMEM, "out of memory");
		if ((ret = kg_ply_load(file, out, err)))
			kg_err_prefix(err, "%s: key '%s'", s->path, path);
		free(file);
	} else if (json_is_string(gen)) {
		const char *g = json_string_value(gen);
		long v;
		double half;
		if (strcmp(g, "icosphere") == 0) {
			snprintf(key, sizeof(key), "%s.level", path);
			/* at most level 8 (1,310,720 triangles): a one-line scene must not ask
			 * for a 21-million-triangle mesh; larger meshes come from PLY files */
			ret = opt_int(s->path, root, key, 4, 0, SCENE_MAX_ICOSPHERE_LEVEL, &v, err);
			if (!ret)
				ret = kg_mesh_icosphere((unsigned)v, out, err);
		} else if (strcmp(g, "plane") == 0) {
			snprintf(key, sizeof(key), "%s.half_size", path);
			ret = opt_number(s->path, root, key, 1.0, 1e-9, 1e9, &half, err);
			snprintf(key, sizeof(key), "%s.segments", path);
			if (!ret)
				ret = opt_int(s->path, root, key, 1, 1, 4096, &v, err);
			if (!ret)
				ret = kg_mesh_plane_grid((float)half, (unsigned)v, out, err);
		} else if (strcmp(g, "tsuba") == 0) {
			snprintf(key, sizeof(key), "%s.segments", path);
			ret = opt_int(s->path, root, key, 128, 16, 4096, &v, err);
			if (!ret)
				ret = kg_mesh_tsuba((unsigned)v, out, err);
		} else {
			ret = kg_fail(err, KG_EINVAL, "%s: key '%s.generator': got \"%s\": expected "
			              "icosphere, plane or tsuba", s->path, path, g);
		}
	} else {
		ret = kg_fail(err, KG_EINVAL, "%s: key '%s': expected \"ply\": file name or "
		              "\"generator\": name", s->path, path);
	}
	if (ret || json_is_string(item))
		return ret;

	kg_mesh *m = *out;
	double scale = 1.0, t[3] = {0, 0, 0};
	snprintf(key, sizeof(key), "%s.scale", path);
	ret = opt_number(s->path, root, key, 1.0, 1e-12, 1e12, &scale, err);
	snprintf(key, sizeof(key), "%s.translate", path);
	if (!ret && json_object_get(item, "translate"))
		ret = get_vec3(s->path, root, key, t, err);
	for (size_t i = 0; !ret && i < m->nverts; i++)
		for (int k = 0; k < 3; k++)
			m->pos[3 * i + k] = (float)(m->pos[3 * i + k] * scale + t[k]);
	json_t *smooth = json_object_get(item, "smooth");
	if (!ret && smooth && !json_is_boolean(smooth))
		ret = kg_fail(err, KG_EINVAL, "%s: key '%s.smooth': expected true or false",
		              s->path, path);
	if (!ret && json_is_true(smooth)) {
		free(m->normal);
		m->normal = NULL;
		ret = kg_mesh_compute_normals(m, err);
	}
	json_t *bg = json_object_get(item, "background");
	if (!ret && bg && !json_is_boolean(bg))
		ret = kg_fail(err, KG_EINVAL, "%s: key '%s.background': expected true or false",
		              s->path, path);
	if (!ret && json_object_get(item, "face_id")) {
		long id;
		snprintf(key, sizeof(key), "%s.face_id", path);
		ret = kg_json_get_int(s->path, root, key, 0, INT32_MAX, &id, err);
		if (!ret && !m->tri_material && !(m->tri_material = malloc(sizeof(int32_t) *
		                                                           (m->ntris ? m->ntris : 1))))
			ret = kg_fail(err, KG_ENOMEM, "out of memory");
		for (size_t i = 0; !ret && i < m->ntris; i++)
			m->tri_material[i] = (int32_t)id;
	}
	if (ret)
		kg_mesh_free(out);
	return ret;
}

/* Parts joined into one mesh. Normals and per-vertex ids are kept when every part has
 * them; per-face ids when any part has them (-1 on the triangles of parts without). */
static int join_parts(kg_mesh **part, size_t n, kg_mesh **out, kg_err *err)
{
	size_t nv = 0, nt = 0;
	unsigned flags = KG_MESH_NORMALS | KG_MESH_VERT_MATERIAL;
	int any_tri = 0;
	for (size_t i = 0; i < n; i++) {
		nv += part[i]->nverts;
		nt += part[i]->ntris;
		if (!part[i]->normal)
			flags &= ~(unsigned)KG_MESH_NORMALS;
		if (!part[i]->vert_material)
			flags &= ~(unsigned)KG_MESH_VERT_MATERIAL;
		any_tri |= part[i]->tri_material != NULL;
	}
	if (any_tri)
		flags |= KG_MESH_TRI_MATERIAL;
	int ret = kg_mesh_new(nv, nt, flags, out, err);
	if (ret)
		return ret;
	kg_mesh *m = *out;
	size_t v0 = 0, t0 = 0;
	for (size_t i = 0; i < n; i++) {
		const kg_mesh *p = part[i];
		memcpy(m->pos + 3 * v0, p->pos, sizeof(float) * 3 * p->nverts);
		if (m->normal)
			memcpy(m->normal + 3 * v0, p->normal, sizeof(float) * 3 * p->nverts);
		if (m->vert_material)
			memcpy(m->vert_material + v0, p->vert_material, sizeof(int32_t) * p->nverts);
		for (size_t t = 0; t < p->ntris; t++) {
			for (int k = 0; k < 3; k++)
				m->tri[3 * (t0 + t) + k] = (uint32_t)(p->tri[3 * t + k] + v0);
			if (m->tri_material)
				m->tri_material[t0 + t] = p->tri_material ? p->tri_material[t] : -1;
		}
		v0 += p->nverts;
		t0 += p->ntris;
	}
	return 0;
}

/* 1 when a mesh part is marked "background": true. */
static int part_is_background(const json_t *item)
{
	return json_is_object(item) && json_is_true(json_object_get(item, "background"));
}

/* Mark the triangles first .. first + n - 1 as background. */
static int mark_background(kg_scene *s, size_t first, size_t n, kg_err *err)
{
	if (!s->tri_background && !(s->tri_background = calloc(s->mesh->ntris ? s->mesh->ntris
	                                                                       : 1, 1)))
		return kg_fail(err, KG_ENOMEM, "out of memory");
	memset(s->tri_background + first, 1, n);
	return 0;
}

static int load_mesh(kg_scene *s, const json_t *root, kg_err *err)
{
	json_t *mesh;
	int ret = kg_json_get(s->path, root, "mesh", &mesh, err);
	if (ret)
		return ret;
	if (!json_is_array(mesh)) {
		ret = load_part(s, root, "mesh", &s->mesh, err);
		if (!ret && part_is_background(mesh))
			ret = mark_background(s, 0, s->mesh->ntris, err);
	} else {
		size_t n = json_array_size(mesh);
		kg_mesh **part = calloc(n ? n : 1, sizeof(*part));
		if (!n)
			ret = kg_fail(err, KG_EINVAL, "%s: key 'mesh': expected at least one part",
			              s->path);
		else if (!part)
			ret = kg_fail(err, KG_ENOMEM, "out of memory");
		for (size_t i = 0; !ret && i < n; i++) {
			char key[64];
			snprintf(key, sizeof(key), "mesh[%zu]", i);
			ret = load_part(s, root, key, &part[i], err);
		}
		if (!ret)
			ret = join_parts(part, n, &s->mesh, err);
		for (size_t i = 0, t0 = 0; !ret && i < n; t0 += part[i]->ntris, i++)
			if (part_is_background(json_array_get(mesh, i)))
				ret = mark_background(s, t0, part[i]->ntris, err);
		for (size_t i = 0; part && i < n; i++)
			kg_mesh_free(&part[i]);
		free(part);
	}
	if (!ret && s->mesh->ntris == 0)
		ret = kg_fail(err, KG_EINVAL, "%s: key 'mesh': the mesh has no triangles", s->path);
	if (!ret && s->mesh->ntris > UINT32_MAX / 4)
		ret = kg_fail(err, KG_EINVAL, "%s: key 'mesh': %zu triangles: expected fewer than "
		              "%u", s->path, s->mesh->ntris, UINT32_MAX / 4);
	return ret;
}

/* ---- lights -------------------------------------------------------------------- */

/* scale * S normalised to luminance 1 on the image scale. */
static void emitter(const kg_scene *s, const kg_illuminant *ill, double scale, float *out)
{
	kg_spectrum spd = ill->spd;
	double y = 0.0;
	for (int i = 0; i < KG_NBANDS; i++)
		y += s->xyz_w[1][i] * spd.v[i];
	for (int i = 0; i < KG_NBANDS; i++)
		out[i] = (float)(scale * spd.v[i] / y);
}

static int load_environment_image(kg_scene *s, const json_t *root, const kg_illuminant *ill,
                                  kg_err *err)
{
	const char *name;
	int ret = kg_json_get_string(s->path, root, "environment.image", &name, err);
	if (ret)
		return ret;
	char *file = scene_relative(s, name);
	kg_image *img = NULL;
	if (!file)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	if ((ret = kg_image_read(file, &img, err)))
		kg_err_prefix(err, "%s: key 'environment.image'", s->path);
	free(file);
	if (!ret)
		ret = rd_upsampler_init(&s->env_up, ill, err);
	size_t n = ret ? 0 : (size_t)img->width * (size_t)img->height;
	if (!ret && !(s->env_coef = malloc(sizeof(float) * 3 * n)))
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	for (size_t i = 0; !ret && i < n; i++) {
		float rgb[3];
		for (int c = 0; c < 3; c++) {
			rgb[c] = img->data[i * (size_t)img->channels + (img->channels == 3 ? c : 0)];
			if (!(rgb[c] >= 0.0f) || !isfinite(rgb[c])) {
				ret = kg_fail(err, KG_EINVAL, "%s: key 'environment.image': texel (%zu, %zu) "
				              "holds %g: expected finite values >= 0", s->path,
				              i % (size_t)img->width, i / (size_t)img->width,
				              (double)rgb[c]);
				break;
			}
		}
		if (!ret)
			rd_upsample(&s->env_up, rgb, s->env_coef + 3 * i);
	}
	if (!ret) {
		s->env_width = img->width;
		s->env_height = img->height;
	}
	kg_image_free(&img);
	return ret;
}

/* The light and the environment; the white is camera.white when given, else the
 * light's illuminant, else the environment's. */
static int load_lights(kg_scene *s, const json_t *root, kg_err *err)
{
	static const char *const light_keys[] = {"illuminant", "direction", "intensity", NULL};
	static const char *const env_keys[] = {"illuminant", "intensity", "image",
	                                       "rotation_deg", NULL};
	json_t *light = json_object_get(root, "light"), *env = json_object_get(root, "environment");
	kg_illuminant *sun = NULL, *sky = NULL;
	int ret = 0;
	if (!light && !env)
		return kg_fail(err, KG_EINVAL, "%s: keys 'light' and 'environment' are both "
		               "missing: expected a light, an environment or both", s->path);
	if (light) {
		if (!json_is_object(light))
			return kg_fail(err, KG_EINVAL, "%s: key 'light': expected an object", s->path);
		s->has_sun = 1;
		ret = check_keys(s->path, light, "light", light_keys, err);
		if (!ret)
			ret = load_illuminant(s, root, "light.illuminant", &sun, err);
		if (!ret)
			ret = get_vec3(s->path, root, "light.direction", s->sun_dir, err);
		if (!ret && !(fabs(s->sun_dir[0]) + fabs(s->sun_dir[1]) + fabs(s->sun_dir[2]) > 0))
			ret = kg_fail(err, KG_EINVAL, "%s: key 'light.direction': expected a non-zero "
			              "vector towards the light", s->path);
		if (!ret)
			ret = opt_number(s->path, root, "light.intensity", 1.0, 0.0, 1e9,
			                 &s->sun_intensity, err);
		if (!ret)
			normalize3(s->sun_dir);
	}
	if (!ret && env) {
		if (!json_is_object(env))
			ret = kg_fail(err, KG_EINVAL, "%s: key 'environment': expected an object",
			              s->path);
		s->has_env = 1;
		if (!ret)
			ret = check_keys(s->path, env, "environment", env_keys, err);
		if (!ret && json_object_get(env, "illuminant"))
			ret = load_illuminant(s, root, "environment.illuminant", &sky, err);
		else if (!ret)
			ret = kg_illuminant_by_name("D65", &sky, err);
		if (!ret)
			ret = opt_number(s->path, root, "environment.intensity", 1.0, 0.0, 1e9,
			                 &s->env_intensity, err);
		if (!ret)
			ret = opt_number(s->path, root, "environment.rotation_deg", 0.0, -360.0, 360.0,
			                 &s->env_rotation_deg, err);
		if (!ret)
			snprintf(s->env_illuminant, sizeof(s->env_illuminant), "%s", sky->name);
	}
	kg_illuminant *balance = NULL;
	if (!ret && kg_json_find(root, "camera.white"))
		ret = load_illuminant(s, root, "camera.white", &balance, err);
	if (!ret) {
		const kg_illuminant *white = balance ? balance : sun ? sun : sky;
		kg_xyz_weights w;
		kg_xyz_weights_signal(white, &w);
		for (int c = 0; c < 3; c++)
			for (int i = 0; i < KG_NBANDS; i++)
				s->xyz_w[c][i] = (float)(w.w[c][i] / 100.0);
		kg_xyz wp = kg_illuminant_white(white);
		s->white = (kg_xyz){wp.X / 100.0, wp.Y / 100.0, wp.Z / 100.0};
		snprintf(s->white_name, sizeof(s->white_name), "%s", white->name);
		if (sun)
			emitter(s, sun, M_PI * s->sun_intensity, s->sun_irradiance);
		if (sky)
			emitter(s, sky, s->env_intensity, s->env_radiance);
		emitter(s, white, 1.0, s->white_spd);
		emitter(s, sun ? sun : sky, 1.0, s->light_spd);
	}
	if (!ret && env && json_object_get(env, "image"))
		ret = load_environment_image(s, root, sky, err);
	kg_illuminant_free(&sun);
	kg_illuminant_free(&sky);
	kg_illuminant_free(&balance);
	return ret;
}

/* ---- camera and sampling -------------------------------------------------------- */

static int load_camera(kg_scene *s, const json_t *root, kg_err *err)
{
	static const char *const keys[] = {"position", "look_at", "up", "fov_deg", "width",
	                                   "height", "exposure", "white", NULL};
	json_t *cam;
	long w, h;
	int ret = get_object(s->path, root, "camera", &cam, err);
	if (!ret)
		ret = check_keys(s->path, cam, "camera", keys, err);
	if (!ret)
		ret = parse_pose(s->path, root, "camera", &s->view, err);
	if (!ret)
		ret = kg_json_get_int(s->path, root, "camera.width", 1, MAX_SIZE, &w, err);
	if (!ret)
		ret = kg_json_get_int(s->path, root, "camera.height", 1, MAX_SIZE, &h, err);
	if (!ret)
		ret = opt_number(s->path, root, "camera.exposure", 1.0, 0.0, 1e9, &s->exposure, err);
	if (!ret) {
		s->view.width = (int)w;
		s->view.height = (int)h;
	}
	return ret;
}

static int load_sampling(kg_scene *s, const json_t *root, kg_err *err)
{
	static const char *const keys[] = {"spp", "wavelengths", "bounces", "seed", NULL};
	long spp = 16, bounces = 4, seed = 1, wl = 4;
	json_t *obj = json_object_get(root, "sampling");
	int ret = 0;
	if (obj && !json_is_object(obj))
		return kg_fail(err, KG_EINVAL, "%s: key 'sampling': expected an object", s->path);
	if (obj)
		ret = check_keys(s->path, obj, "sampling", keys, err);
	if (!ret)
		ret = opt_int(s->path, root, "sampling.spp", spp, 1, MAX_SPP, &spp, err);
	if (!ret)
		ret = opt_int(s->path, root, "sampling.bounces", bounces, 1, MAX_BOUNCES, &bounces,
		              err);
	if (!ret)
		ret = opt_int(s->path, root, "sampling.seed", seed, 0, (1L << 53), &seed, err);
	json_t *v = obj ? json_object_get(obj, "wavelengths") : NULL;
	if (!ret && v && json_is_string(v)) {
		if (strcmp(json_string_value(v), "all") != 0)
			ret = kg_fail(err, KG_EINVAL, "%s: key 'sampling.wavelengths': got \"%s\": "
			              "expected \"all\" or a number from 1 to %d", s->path,
			              json_string_value(v), KG_RENDER_ALL_BANDS);
		wl = KG_RENDER_ALL_BANDS;
	} else if (!ret && v) {
		ret = kg_json_get_int(s->path, root, "sampling.wavelengths", 1, KG_RENDER_ALL_BANDS,
		                      &wl, err);
	}
	s->spp = (int)spp;
	s->bounces = (int)bounces;
	s->seed = (uint64_t)seed;
	s->wavelengths = (int)wl;
	return ret;
}

/* ---- the scene ------------------------------------------------------------------ */

int kg_scene_load(const char *path, kg_scene **out, kg_err *err)
{
	static const char *const keys[] = {"format", "note", "mesh", "materials", "light",
	                                   "environment", "camera", "sampling", NULL};
	kg_check_arg(path && out, err);
	*out = NULL;
	json_t *root = NULL;
	int ret = kg_json_load(path, &root, err);
	if (ret)
		return ret;
	kg_scene *s = calloc(1, sizeof(*s));
	if (!s || !(s->path = strdup(path))) {
		free(s);
		json_decref(root);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	const char *format;
	if (!json_is_object(root))
		ret = kg_fail(err, KG_EINVAL, "%s: expected a JSON object", path);
	if (!ret)
		ret = kg_json_get_string(path, root, "format", &format, err);
	if (!ret && strcmp(format, SCENE_FORMAT) != 0)
		ret = kg_fail(err, KG_EINVAL, "%s: key 'format': got \"%s\": expected \"%s\"", path,
		              format, SCENE_FORMAT);
	if (!ret)
		ret = check_keys(path, root, "", keys, err);
	if (!ret)
		ret = load_camera(s, root, err);
	if (!ret)
		ret = load_sampling(s, root, err);
	if (!ret)
		ret = load_lights(s, root, err);
	if (!ret)
		ret = load_mesh(s, root, err);
	if (!ret)
		ret = load_materials(s, root, err);
	json_decref(root);
	if (ret)
		kg_scene_free(&s);
	*out = s;
	return ret;
}

void kg_scene_free(kg_scene **sp)
{
	if (!sp || !*sp)
		return;
	kg_scene *s = *sp;
	free(s->path);
	kg_mesh_free(&s->mesh);
	free(s->library_path);
	kg_material_library_free(&s->lib);
	free(s->mat);
	free(s->tri_mat);
	free(s->tri_background);
	free(s->label.path);
	free(s->label.labels);
	free(s->label.class_mat);
	for (int c = 0; s->label.class_names && c < s->label.nclasses; c++)
		free(s->label.class_names[c]);
	free(s->label.class_names);
	free(s->env_coef);
	free(s);
	*sp = NULL;
}

const kg_mesh *kg_scene_mesh(const kg_scene *s)
{
	return s ? s->mesh : NULL;
}

kg_xyz kg_scene_white(const kg_scene *s)
{
	return s->white;
}

const char *kg_scene_white_name(const kg_scene *s)
{
	return s->white_name;
}

void kg_scene_xyz_observer(const kg_scene *s, kg_spectrum out[3])
{
	for (int c = 0; c < 3; c++)
		for (int i = 0; i < KG_NBANDS; i++)
			out[c].v[i] = s->xyz_w[c][i];
}

void kg_scene_light_spectrum(const kg_scene *s, kg_spectrum *out)
{
	for (int i = 0; i < KG_NBANDS; i++)
		out->v[i] = s->light_spd[i];
}

int rd_scene_triangle_materials_plain(const kg_scene *s, uint16_t **out, kg_err *err)
{
	size_t n = s->mesh->ntris;
	*out = NULL;
	if (s->assign == RD_ASSIGN_LABEL_MAP)
		return kg_fail(err, KG_EINVAL, "%s: a label map needs projecting", s->path);
	if (!n)
		return 0;
	if (!(*out = malloc(sizeof(uint16_t) * n)))
		return kg_fail(err, KG_ENOMEM, "out of memory");
	if (s->tri_mat)
		memcpy(*out, s->tri_mat, sizeof(uint16_t) * n);
	else
		memset(*out, 0, sizeof(uint16_t) * n);
	return 0;
}

/* The mean radiance of an image environment over the sphere (texels weighted by
 * their solid angle), per band: what the constant emitter stands for. */
void rd_env_mean(const kg_scene *s, float *out)
{
	double c[3] = {0, 0, 0}, wsum = 0;
	for (int y = 0; y < s->env_height; y++) {
		double w = sin(M_PI * (y + 0.5) / s->env_height);
		for (int x = 0; x < s->env_width; x++) {
			const float *t = s->env_coef + 3 * ((size_t)y * (size_t)s->env_width + (size_t)x);
			for (int i = 0; i < 3; i++)
				c[i] += w * t[i];
			wsum += w;
		}
	}
	for (int b = 0; b < KG_NBANDS; b++) {
		double r = 0;
		for (int i = 0; i < 3; i++)
			r += c[i] / wsum * s->env_up.basis[i][b];
		out[b] = r > 0 ? (float)(r * s->env_radiance[b]) : 0.0f;
	}
}
