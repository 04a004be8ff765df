/* glTF 2.0 binary export of a scene (kg_gltf.h): the JSON and BIN chunks of a .glb
 * container (glTF 2.0 specification, section 4.4 "GLB File Format Specification"),
 * written by hand with jansson for the JSON. Coordinates: kogei's scenes are +z up,
 * glTF's +y up, both right-handed: (x, y, z) becomes (x, z, -y). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "kg_config.h"
#include "kg_gltf.h"
#include "render_private.h"

#define GLB_MAGIC 0x46546C67u /* "glTF" */
#define GLB_JSON 0x4E4F534Au  /* "JSON" */
#define GLB_BIN 0x004E4942u   /* "BIN\0" */
#define GL_ARRAY_BUFFER 34962
#define GL_ELEMENT_ARRAY_BUFFER 34963
#define GL_FLOAT 5126
#define GL_UNSIGNED_INT 5125
#define GL_LINEAR 9729
#define GL_LINEAR_MIPMAP_LINEAR 9987
#define GL_CLAMP_TO_EDGE 33071

/* the band of 560 nm on the 400-700 nm, 5 nm grid: a dielectric's single index */
#define BAND_560 ((560 - 400) / 5)

/* ---- materials ------------------------------------------------------------------- */

static double clamp01(double v, int *clipped)
{
	if (v < 0.0 || v > 1.0)
		*clipped = 1;
	return v < 0.0 ? 0.0 : v > 1.0 ? 1.0 : v;
}

/* A reflectance spectrum under D65 with the CIE 1931 observer, as linear sRGB (D65
 * white, so no adaptation), clamped to 0..1. */
static void reflectance_rgb(const kg_spectrum *r, const kg_illuminant *d65, double scale,
                            double out[3], int *clipped)
{
	kg_xyz xyz = kg_reflectance_to_xyz(r, d65);
	kg_rgb c = kg_xyz_to_linear_srgb(xyz, kg_illuminant_white(d65));
	out[0] = clamp01(scale * c.r, clipped);
	out[1] = clamp01(scale * c.g, clipped);
	out[2] = clamp01(scale * c.b, clipped);
}

int kg_gltf_material_pbr(const kg_material *m, kg_gltf_pbr *out, kg_err *err)
{
	kg_check_arg(m && out, err);
	memset(out, 0, sizeof(*out));
	int ret = kg_material_validate(m, err);
	if (ret)
		return ret;
	kg_illuminant *d65 = NULL;
	if ((ret = kg_illuminant_by_name("D65", &d65, err)))
		return ret;
	double weight = m->gloss + m->mirror;
	/* The gloss lobe's facets have the Beckmann RMS slope `roughness`; the mirror
	 * lobe spreads the reflected direction by a Gaussian of width w, i.e. the facet
	 * normal by w / 2: a Beckmann slope of about w / 2. GGX's alpha matches Beckmann's
	 * m at these small slopes (Walter et al., EGSR 2007). */
	double slope_mirror = 0.5 * m->mirror_width;
	out->alpha = weight > 0.0 ? (m->gloss * m->roughness + m->mirror * slope_mirror) / weight
	                          : m->roughness;
	out->roughness = sqrt(out->alpha);
	if (m->kind == KG_MATERIAL_DIELECTRIC) {
		out->metallic = 0.0;
		out->ior = m->nk.n.v[BAND_560];
		out->specular = weight;
		reflectance_rgb(&m->body, d65, 1.0, out->base_color, &out->clipped);
	} else {
		kg_spectrum r;
		out->metallic = 1.0;
		out->specular = 1.0;
		if (!(ret = kg_material_reflectance(m, 0.0, &r, err)))
			reflectance_rgb(&r, d65, weight, out->base_color, &out->clipped);
	}
	kg_illuminant_free(&d65);
	return ret;
}

/* ---- the binary chunk ------------------------------------------------------------ */

typedef struct bin {
	unsigned char *d;
	size_t n, cap;
	int oom;
} bin;

/* Append n bytes at a 4-byte aligned offset, returned. */
static size_t bin_add(bin *b, const void *p, size_t n)
{
	size_t off = (b->n + 3) & ~(size_t)3;
	if (b->oom)
		return 0;
	if (off + n > b->cap) {
		size_t cap = b->cap ? b->cap : 1 << 16;
		while (cap < off + n)
			cap *= 2;
		unsigned char *d = realloc(b->d, cap);
		if (!d) {
			b->oom = 1;
			return 0;
		}
		b->d = d;
		b->cap = cap;
	}
	memset(b->d + b->n, 0, off - b->n);
	if (n)
		memcpy(b->d + off, p, n);
	b->n = off + n;
	return off;
}

/* The JSON document under construction. */
typedef struct doc {
	json_t *root, *views, *accessors, *materials, *meshes, *nodes, *ext_used;
	bin bin;
} doc;

static int add_view(doc *g, const void *p, size_t n, int target)
{
	size_t off = bin_add(&g->bin, p, n);
	json_t *v = json_pack("{s:i, s:I, s:I}", "buffer", 0, "byteOffset", (json_int_t)off,
	                      "byteLength", (json_int_t)n);
	if (target)
		json_object_set_new(v, "target", json_integer(target));
	json_array_append_new(g->views, v);
	return (int)json_array_size(g->views) - 1;
}

static int add_accessor(doc *g, int view, size_t offset, int type, size_t count,
                        const char *shape)
{
	json_t *a = json_pack("{s:i, s:I, s:i, s:I, s:s}", "bufferView", view, "byteOffset",
	                      (json_int_t)offset, "componentType", type, "count",
	                      (json_int_t)count, "type", shape);
	json_array_append_new(g->accessors, a);
	return (int)json_array_size(g->accessors) - 1;
}

static void use_extension(doc *g, const char *name)
{
	size_t i;
	json_t *v;
	json_array_foreach(g->ext_used, i, v)
		if (!strcmp(json_string_value(v), name))
			return;
	json_array_append_new(g->ext_used, json_string(name));
}

static json_t *rgba(const double c[3])
{
	return json_pack("[ffff]", c[0], c[1], c[2], 1.0);
}

static const char *kind_name(kg_material_kind k)
{
	return k == KG_MATERIAL_METAL ? "metal" : k == KG_MATERIAL_ALLOY ? "alloy" : "dielectric";
}

/* A library material as a glTF material. */
static int add_library_material(doc *g, const kg_material *m, kg_err *err)
{
	kg_gltf_pbr pbr;
	int ret = kg_gltf_material_pbr(m, &pbr, err);
	if (ret)
		return ret;
	char what[KG_MATERIAL_NAME_MAX + 64];
	snprintf(what, sizeof(what), "material '%s': name", m->name);
	json_t *name = kg_json_text(what, m->name, err);
	if (!name)
		return KG_EINVAL;
	json_t *extras = json_pack("{s:O, s:s, s:f, s:f, s:f, s:f, s:f, s:b}", "kogei_material",
	                           name, "kind", kind_name(m->kind), "gloss", m->gloss,
	                           "mirror", m->mirror, "beckmann_slope", m->roughness,
	                           "mirror_width_rad", m->mirror_width, "alpha", pbr.alpha,
	                           "base_color_clipped", pbr.clipped);
	json_t *mat = json_pack("{s:o, s:{s:o, s:f, s:f}, s:o}", "name", name,
	                        "pbrMetallicRoughness", "baseColorFactor", rgba(pbr.base_color),
	                        "metallicFactor", pbr.metallic, "roughnessFactor", pbr.roughness,
	                        "extras", extras);
	if (!mat)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	if (m->kind == KG_MATERIAL_DIELECTRIC) {
		json_object_set_new(mat, "extensions",
		                    json_pack("{s:{s:f}, s:{s:f}}", "KHR_materials_ior", "ior", pbr.ior,
		                              "KHR_materials_specular", "specularFactor",
		                              pbr.specular));
		use_extension(g, "KHR_materials_ior");
		use_extension(g, "KHR_materials_specular");
	}
	json_array_append_new(g->materials, mat);
	return 0;
}

/* A region that is no library material: the neutral grey diffuser. */
static void add_neutral_material(doc *g, const char *name)
{
	double grey[3] = {KG_GLTF_NEUTRAL_LEVEL, KG_GLTF_NEUTRAL_LEVEL, KG_GLTF_NEUTRAL_LEVEL};
	json_t *mat = json_pack("{s:s, s:{s:o, s:f, s:f}, s:{s:{s:f}}, s:{s:s}}", "name", name,
	                        "pbrMetallicRoughness", "baseColorFactor", rgba(grey),
	                        "metallicFactor", 0.0, "roughnessFactor", 1.0, "extensions",
	                        "KHR_materials_specular", "specularFactor", 0.0, "extras",
	                        "kogei_material", "none: a neutral grey diffuser");
	use_extension(g, "KHR_materials_specular");
	json_array_append_new(g->materials, mat);
}

/* ---- material regions -------------------------------------------------------------- */

/* The neutral regions after the library's materials: slot s->nmat + NEUTRAL_*. */
enum { NEUTRAL_UNKNOWN, NEUTRAL_BACKGROUND, NEUTRAL_GREY, NEUTRAL_COUNT };
static const char *const neutral_names[NEUTRAL_COUNT] = {"unknown", "background",
                                                         KG_SCENE_NEUTRAL_GREY};

static double dot3(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Where point p falls in the image of view v (pixels, x right, y down); 0 when
 * behind the camera. */
static int project(const rd_view *v, const rd_frame *f, const double p[3], double *px,
                   double *py)
{
	double d[3] = {p[0] - v->pos[0], p[1] - v->pos[1], p[2] - v->pos[2]};
	double z = dot3(d, f->fwd);
	if (!(z > 0.0))
		return 0;
	double aspect = (double)v->width / v->height;
	double x = dot3(d, f->right) / (z * f->tan_half * aspect);
	double y = dot3(d, f->up) / (z * f->tan_half);
	*px = (x + 1.0) * 0.5 * v->width;
	*py = (1.0 - y) * 0.5 * v->height;
	return 1;
}

/* The slot of material index i of the scene (library material or neutral grey). */
static int material_slot(const kg_scene *s, int i)
{
	return s->mat[i] == &s->neutral ? s->nmat + NEUTRAL_GREY : i;
}

/* The slot of a label map's fallback or of an unmapped class named `name`. */
static int label_slot(const kg_scene *s, int mat, const char *name)
{
	if (mat >= 0 && s->mat[mat] != &s->neutral)
		return mat;
	if (name && !strcmp(name, "background"))
		return s->nmat + NEUTRAL_BACKGROUND;
	return s->nmat + NEUTRAL_UNKNOWN;
}

/* Per triangle, its slot (0 .. s->nmat + NEUTRAL_COUNT - 1). */
static int triangle_slots(const kg_scene *s, int *slot, kg_err *err)
{
	const kg_mesh *mesh = s->mesh;
	rd_frame f;
	if (s->assign == RD_ASSIGN_LABEL_MAP)
		rd_view_frame(&s->label.view, &f);
	for (size_t t = 0; t < mesh->ntris; t++) {
		if (s->tri_background && s->tri_background[t]) {
			slot[t] = s->nmat + NEUTRAL_BACKGROUND;
			continue;
		}
		switch (s->assign) {
		case RD_ASSIGN_ONE: slot[t] = material_slot(s, 0); break;
		case RD_ASSIGN_FACE:
		case RD_ASSIGN_VERTEX: slot[t] = material_slot(s, s->tri_mat[t]); break;
		case RD_ASSIGN_LABEL_MAP: {
			const rd_label_map *lm = &s->label;
			double p[3] = {0, 0, 0}, px, py;
			for (int k = 0; k < 3; k++)
				for (int i = 0; i < 3; i++)
					p[i] += mesh->pos[3 * mesh->tri[3 * t + k] + i] / 3.0;
			int sl = label_slot(s, lm->fallback, NULL);
			if (project(&lm->view, &f, p, &px, &py) && px >= 0.0 && px < lm->width &&
			    py >= 0.0 && py < lm->height) {
				int label = lm->labels[(size_t)py * (size_t)lm->width + (size_t)px];
				sl = label_slot(s, lm->class_mat[label] >= 0 ? lm->class_mat[label]
				                                             : lm->fallback,
				                lm->class_mat[label] >= 0 ? NULL : lm->class_names[label]);
			}
			slot[t] = sl;
			break;
		}
		default: return kg_fail(err, KG_EINVAL, "%s: unknown material assignment", s->path);
		}
	}
	return 0;
}

/* ---- geometry ---------------------------------------------------------------------- */

static void to_gltf(const double in[3], float out[3])
{
	out[0] = (float)in[0];
	out[1] = (float)in[2];
	out[2] = (float)-in[1];
}

/* Unit vertex normals in glTF's frame: the mesh's, else the angle-weighted mean of the
 * faces' (kg_mesh_compute_normals on a copy of the positions would do the same). */
static int vertex_normals(const kg_mesh *m, float *out, kg_err *err)
{
	double *acc = calloc(m->nverts * 3, sizeof(double));
	if (!acc)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	if (m->normal) {
		for (size_t i = 0; i < 3 * m->nverts; i++)
			acc[i] = m->normal[i];
	} else {
		for (size_t t = 0; t < m->ntris; t++) {
			const uint32_t *c = m->tri + 3 * t;
			double p[3][3];
			for (int k = 0; k < 3; k++)
				for (int i = 0; i < 3; i++)
					p[k][i] = m->pos[3 * c[k] + i];
			double e1[3], e2[3], n[3];
			for (int i = 0; i < 3; i++)
				e1[i] = p[1][i] - p[0][i], e2[i] = p[2][i] - p[0][i];
			n[0] = e1[1] * e2[2] - e1[2] * e2[1];
			n[1] = e1[2] * e2[0] - e1[0] * e2[2];
			n[2] = e1[0] * e2[1] - e1[1] * e2[0];
			double len = sqrt(dot3(n, n));
			if (!(len > 0.0))
				continue;
			for (int k = 0; k < 3; k++) {
				/* the triangle's angle at corner k */
				double a[3], b[3];
				for (int i = 0; i < 3; i++) {
					a[i] = p[(k + 1) % 3][i] - p[k][i];
					b[i] = p[(k + 2) % 3][i] - p[k][i];
				}
				double la = sqrt(dot3(a, a)), lb = sqrt(dot3(b, b));
				double cosang = la > 0 && lb > 0 ? dot3(a, b) / (la * lb) : 1.0;
				double ang = acos(cosang < -1 ? -1 : cosang > 1 ? 1 : cosang);
				for (int i = 0; i < 3; i++)
					acc[3 * c[k] + i] += ang * n[i] / len;
			}
		}
	}
	for (size_t v = 0; v < m->nverts; v++) {
		double *n = acc + 3 * v;
		double len = sqrt(dot3(n, n));
		if (!(len > 0.0) || !isfinite(len))
			n[0] = 0, n[1] = 0, n[2] = 1, len = 1;
		double u[3] = {n[0] / len, n[1] / len, n[2] / len};
		to_gltf(u, out + 3 * v);
	}
	free(acc);
	return 0;
}

/* Texture coordinates: where each vertex falls in the label map's image (else the
 * scene camera's), 0..1 across it, v down as glTF's. */
static void vertex_uvs(const kg_scene *s, float *uv)
{
	const rd_view *v = s->assign == RD_ASSIGN_LABEL_MAP ? &s->label.view : &s->view;
	rd_frame f;
	rd_view_frame(v, &f);
	for (size_t i = 0; i < s->mesh->nverts; i++) {
		double p[3] = {s->mesh->pos[3 * i], s->mesh->pos[3 * i + 1], s->mesh->pos[3 * i + 2]};
		double px = 0, py = 0;
		if (!project(v, &f, p, &px, &py) || !isfinite(px) || !isfinite(py))
			px = py = 0;
		uv[2 * i] = (float)(px / v->width);
		uv[2 * i + 1] = (float)(py / v->height);
	}
}

/* A unit quaternion (x, y, z, w) of the rotation whose matrix has columns c0 c1 c2. */
static void quaternion(const double c0[3], const double c1[3], const double c2[3], double q[4])
{
	double m00 = c0[0], m10 = c0[1], m20 = c0[2];
	double m01 = c1[0], m11 = c1[1], m21 = c1[2];
	double m02 = c2[0], m12 = c2[1], m22 = c2[2];
	double tr = m00 + m11 + m22;
	if (tr > 0) {
		double k = 0.5 / sqrt(tr + 1.0);
		q[3] = 0.25 / k, q[0] = (m21 - m12) * k, q[1] = (m02 - m20) * k, q[2] = (m10 - m01) * k;
	} else if (m00 > m11 && m00 > m22) {
		double k = 2.0 * sqrt(1.0 + m00 - m11 - m22);
		q[3] = (m21 - m12) / k, q[0] = 0.25 * k, q[1] = (m01 + m10) / k, q[2] = (m02 + m20) / k;
	} else if (m11 > m22) {
		double k = 2.0 * sqrt(1.0 + m11 - m00 - m22);
		q[3] = (m02 - m20) / k, q[0] = (m01 + m10) / k, q[1] = 0.25 * k, q[2] = (m12 + m21) / k;
	} else {
		double k = 2.0 * sqrt(1.0 + m22 - m00 - m11);
		q[3] = (m10 - m01) / k, q[0] = (m02 + m20) / k, q[1] = (m12 + m21) / k, q[2] = 0.25 * k;
	}
	double len = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
	for (int i = 0; i < 4; i++)
		q[i] /= len;
}

static void vec_gltf(const double in[3], double out[3])
{
	out[0] = in[0], out[1] = in[2], out[2] = -in[1];
}

static void cross(const double a[3], const double b[3], double c[3])
{
	c[0] = a[1] * b[2] - a[2] * b[1];
	c[1] = a[2] * b[0] - a[0] * b[2];
	c[2] = a[0] * b[1] - a[1] * b[0];
}

static void normalise(double v[3])
{
	double n = sqrt(dot3(v, v));
	if (n > 0)
		v[0] /= n, v[1] /= n, v[2] /= n;
}

/* The scene's camera as a glTF camera node (looking down its local -z, +y up). */
static void add_camera(doc *g, const kg_scene *s)
{
	rd_frame f;
	rd_view_frame(&s->view, &f);
	double right[3], up[3], back[3], fwd[3], pos[3], q[4];
	vec_gltf(f.right, right);
	vec_gltf(f.up, up);
	vec_gltf(f.fwd, fwd);
	vec_gltf(s->view.pos, pos);
	for (int i = 0; i < 3; i++)
		back[i] = -fwd[i];
	quaternion(right, up, back, q);
	double dist = sqrt((s->view.look_at[0] - s->view.pos[0]) * (s->view.look_at[0] - s->view.pos[0]) +
	                   (s->view.look_at[1] - s->view.pos[1]) * (s->view.look_at[1] - s->view.pos[1]) +
	                   (s->view.look_at[2] - s->view.pos[2]) * (s->view.look_at[2] - s->view.pos[2]));
	json_object_set_new(g->root, "cameras",
	                    json_pack("[{s:s, s:s, s:{s:f, s:f, s:f, s:f}}]", "name", "kogei camera",
	                              "type", "perspective", "perspective", "aspectRatio",
	                              (double)s->view.width / s->view.height, "yfov",
	                              s->view.fov_deg * M_PI / 180.0, "znear", 1e-3 * dist, "zfar",
	                              1e3 * dist));
	json_array_append_new(g->nodes, json_pack("{s:s, s:i, s:[ffff], s:[fff]}", "name",
	                                          "kogei camera", "camera", 0, "rotation", q[0],
	                                          q[1], q[2], q[3], "translation", pos[0], pos[1],
	                                          pos[2]));
}

/* The directional light (KHR_lights_punctual, shining down its local -z): its colour the
 * illuminant's in linear sRGB (D65 white = 1, 1, 1), its intensity such that a white
 * diffuser it lights head-on has the luminance kogei gives it (Y = intensity), with
 * glTF's Lambertian BRDF 1 / pi: intensity = pi x kogei's intensity / Y(colour). */
static void add_light(doc *g, const kg_scene *s, kg_err *err)
{
	kg_illuminant *d65 = NULL;
	if (!s->has_sun || kg_illuminant_by_name("D65", &d65, err))
		return;
	kg_xyz w = {100.0 * s->white.X, 100.0 * s->white.Y, 100.0 * s->white.Z};
	kg_rgb c = kg_xyz_to_linear_srgb(w, kg_illuminant_white(d65));
	kg_illuminant_free(&d65);
	double mx = fmax(c.r, fmax(c.g, c.b));
	if (!(mx > 0))
		return;
	double col[3] = {fmax(0, c.r / mx), fmax(0, c.g / mx), fmax(0, c.b / mx)};
	double lum = 0.2126 * col[0] + 0.7152 * col[1] + 0.0722 * col[2];
	double dir[3], z[3], x[3], y[3], q[4];
	vec_gltf(s->sun_dir, dir);
	for (int i = 0; i < 3; i++)
		z[i] = dir[i];
	double ref[3] = {0, 1, 0};
	if (fabs(z[1]) > 0.9)
		ref[0] = 1, ref[1] = 0;
	cross(ref, z, x);
	normalise(x);
	cross(z, x, y);
	quaternion(x, y, z, q);
	json_object_set_new(g->root, "extensions",
	                    json_pack("{s:{s:[{s:s, s:s, s:[fff], s:f}]}}", "KHR_lights_punctual",
	                              "lights", "name", "kogei light", "type", "directional", "color",
	                              col[0], col[1], col[2], "intensity",
	                              M_PI * s->sun_intensity / lum));
	json_array_append_new(g->nodes, json_pack("{s:s, s:[ffff], s:{s:{s:i}}}", "name",
	                                          "kogei light", "rotation", q[0], q[1], q[2], q[3],
	                                          "extensions", "KHR_lights_punctual", "light", 0));
	use_extension(g, "KHR_lights_punctual");
}

/* ---- the file ---------------------------------------------------------------------- */

static void put_u32(unsigned char *p, uint32_t v)
{
	p[0] = (unsigned char)v, p[1] = (unsigned char)(v >> 8);
	p[2] = (unsigned char)(v >> 16), p[3] = (unsigned char)(v >> 24);
}

static int write_glb(const char *path, const char *json, const bin *b, kg_err *err)
{
	size_t jlen = strlen(json), jpad = (jlen + 3) & ~(size_t)3;
	size_t blen = (b->n + 3) & ~(size_t)3;
	size_t total = 12 + 8 + jpad + (blen ? 8 + blen : 0);
	if (total > UINT32_MAX)
		return kg_fail(err, KG_EINVAL, "%s: %zu bytes: a glb holds at most 4 GiB", path, total);
	unsigned char head[12 + 8], chunk[8];
	put_u32(head, GLB_MAGIC);
	put_u32(head + 4, 2);
	put_u32(head + 8, (uint32_t)total);
	put_u32(head + 12, (uint32_t)jpad);
	put_u32(head + 16, GLB_JSON);
	kg_outfile o;
	int ret = kg_outfile_open(&o, path, 0, err);
	if (ret)
		return ret;
	static const char spaces[4] = "   ", zeros[4] = {0, 0, 0, 0};
	int ok = fwrite(head, 1, sizeof(head), o.fp) == sizeof(head) &&
	         fwrite(json, 1, jlen, o.fp) == jlen &&
	         fwrite(spaces, 1, jpad - jlen, o.fp) == jpad - jlen;
	if (ok && blen) {
		put_u32(chunk, (uint32_t)blen);
		put_u32(chunk + 4, GLB_BIN);
		ok = fwrite(chunk, 1, 8, o.fp) == 8 && fwrite(b->d, 1, b->n, o.fp) == b->n &&
		     fwrite(zeros, 1, blen - b->n, o.fp) == blen - b->n;
	}
	if (!ok) {
		kg_outfile_abort(&o);
		return kg_fail(err, KG_EIO, "%s: write failed", path);
	}
	return kg_outfile_commit(&o, err);
}

/* The photograph: a PNG file's bytes as they are. */
static int read_png(const char *path, char **data, size_t *len, int *w, int *h, kg_err *err)
{
	int ret = kg_read_file(path, data, len, err);
	if (ret)
		return ret;
	const unsigned char *d = (const unsigned char *)*data;
	static const unsigned char sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
	if (*len < 24 || memcmp(d, sig, 8) || memcmp(d + 12, "IHDR", 4)) {
		free(*data);
		*data = NULL;
		return kg_fail(err, KG_EINVAL, "%s: expected a PNG file (the photograph)", path);
	}
	*w = (int)((uint32_t)d[16] << 24 | (uint32_t)d[17] << 16 | (uint32_t)d[18] << 8 | d[19]);
	*h = (int)((uint32_t)d[20] << 24 | (uint32_t)d[21] << 16 | (uint32_t)d[22] << 8 | d[23]);
	return 0;
}

/* asset.extras.kogei: where the scene came from (paths, names), each checked to be
 * UTF-8 as JSON text must be. */
static int asset_extras_new(const kg_scene *s, const kg_gltf_options *opt, const char *path,
                            json_t **out, kg_err *err)
{
	const char *keys[5] = {"scene", "library", "white", "source", "illuminant"};
	const char *vals[5] = {kg_path_below(s->path, opt->record_dir), s->library_path,
	                       s->white_name,
	                       opt->source ? opt->source : "", s->env_illuminant};
	json_t *k = json_object(), *text[5] = {NULL};
	int ret = k ? 0 : kg_fail(err, KG_ENOMEM, "out of memory");
	for (int i = 0; !ret && i < (s->has_env ? 5 : 4); i++) {
		char what[512];
		snprintf(what, sizeof(what), "%s: asset.extras.kogei.%s%s", path,
		         i == 4 ? "environment." : "", keys[i]);
		if (!(text[i] = kg_json_text(what, vals[i], err)))
			ret = KG_EINVAL;
	}
	for (int i = 0; !ret && i < 4; i++)
		json_object_set_new(k, keys[i], text[i]);
	if (!ret && s->has_env)
		json_object_set_new(k, "environment", json_pack("{s:o, s:f}", "illuminant", text[4],
		                                                "intensity", s->env_intensity));
	if (ret) {
		for (int i = 0; i < 5; i++)
			json_decref(text[i]);
		json_decref(k);
		return ret;
	}
	*out = json_pack("{s:o}", "kogei", k);
	return *out ? 0 : kg_fail(err, KG_ENOMEM, "out of memory");
}

int kg_gltf_write(const kg_scene *s, const kg_gltf_options *opt, const char *path,
                  kg_err *err)
{
	kg_check_arg(s && path, err);
	kg_gltf_options none = {0};
	if (!opt)
		opt = &none;
	const kg_mesh *mesh = s->mesh;
	if (mesh->nverts == 0 || mesh->ntris == 0)
		return kg_fail(err, KG_EINVAL, "%s: the mesh has no triangles: nothing to export",
		               s->path);
	if (mesh->nverts > UINT32_MAX)
		return kg_fail(err, KG_EINVAL, "%s: %zu vertices: glTF indices hold at most %u",
		               s->path, mesh->nverts, UINT32_MAX);
	int nslots = s->nmat + NEUTRAL_COUNT;
	doc g = {0};
	int *slot = malloc(sizeof(int) * mesh->ntris);
	size_t *count = calloc((size_t)nslots, sizeof(size_t));
	float *pos = malloc(sizeof(float) * 3 * mesh->nverts);
	float *nrm = malloc(sizeof(float) * 3 * mesh->nverts);
	float *uv = malloc(sizeof(float) * 2 * mesh->nverts);
	uint32_t *idx = malloc(sizeof(uint32_t) * 3 * mesh->ntris);
	char *png = NULL, *json = NULL;
	size_t png_len = 0;
	int png_w = 0, png_h = 0;
	int ret = slot && count && pos && nrm && uv && idx ? 0
	                                                   : kg_fail(err, KG_ENOMEM, "out of memory");
	if (!ret && opt->photo_png)
		ret = read_png(opt->photo_png, &png, &png_len, &png_w, &png_h, err);
	if (!ret)
		ret = triangle_slots(s, slot, err);
	if (!ret)
		ret = vertex_normals(mesh, nrm, err);
	if (ret)
		goto done;
	vertex_uvs(s, uv);
	float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
	for (size_t v = 0; v < mesh->nverts; v++) {
		double p[3] = {mesh->pos[3 * v], mesh->pos[3 * v + 1], mesh->pos[3 * v + 2]};
		to_gltf(p, pos + 3 * v);
		for (int i = 0; i < 3; i++) {
			lo[i] = fminf(lo[i], pos[3 * v + i]);
			hi[i] = fmaxf(hi[i], pos[3 * v + i]);
		}
	}
	g.root = json_object();
	g.views = json_array();
	g.accessors = json_array();
	g.materials = json_array();
	g.meshes = json_array();
	g.nodes = json_array();
	g.ext_used = json_array();

	/* vertex attributes, shared by every primitive */
	int v_pos = add_view(&g, pos, sizeof(float) * 3 * mesh->nverts, GL_ARRAY_BUFFER);
	int v_nrm = add_view(&g, nrm, sizeof(float) * 3 * mesh->nverts, GL_ARRAY_BUFFER);
	int a_pos = add_accessor(&g, v_pos, 0, GL_FLOAT, mesh->nverts, "VEC3");
	json_object_set_new(json_array_get(g.accessors, (size_t)a_pos), "min",
	                    json_pack("[fff]", (double)lo[0], (double)lo[1], (double)lo[2]));
	json_object_set_new(json_array_get(g.accessors, (size_t)a_pos), "max",
	                    json_pack("[fff]", (double)hi[0], (double)hi[1], (double)hi[2]));
	int a_nrm = add_accessor(&g, v_nrm, 0, GL_FLOAT, mesh->nverts, "VEC3");

	/* the triangles grouped by slot, one index view for all */
	for (size_t t = 0; t < mesh->ntris; t++)
		count[slot[t]]++;
	size_t *first = calloc((size_t)nslots + 1, sizeof(size_t));
	if (!first) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto done;
	}
	for (int k = 0; k < nslots; k++)
		first[k + 1] = first[k] + count[k];
	size_t *fill = calloc((size_t)nslots, sizeof(size_t));
	if (!fill) {
		free(first);
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto done;
	}
	for (size_t t = 0; t < mesh->ntris; t++) {
		size_t at = first[slot[t]] + fill[slot[t]]++;
		memcpy(idx + 3 * at, mesh->tri + 3 * t, sizeof(uint32_t) * 3);
	}
	free(fill);
	int v_idx = add_view(&g, idx, sizeof(uint32_t) * 3 * mesh->ntris, GL_ELEMENT_ARRAY_BUFFER);
	json_t *prims = json_array();
	for (int k = 0; k < nslots && !ret; k++) {
		if (!count[k])
			continue;
		int a_idx = add_accessor(&g, v_idx, sizeof(uint32_t) * 3 * first[k], GL_UNSIGNED_INT,
		                         3 * count[k], "SCALAR");
		int m = (int)json_array_size(g.materials);
		if (k < s->nmat)
			ret = add_library_material(&g, s->mat[k], err);
		else
			add_neutral_material(&g, neutral_names[k - s->nmat]);
		json_array_append_new(prims, json_pack("{s:{s:i, s:i}, s:i, s:i, s:i}", "attributes",
		                                       "POSITION", a_pos, "NORMAL", a_nrm, "indices",
		                                       a_idx, "material", m, "mode", 4));
	}
	free(first);
	json_array_append_new(g.meshes, json_pack("{s:s, s:o}", "name", "object", "primitives",
	                                          prims));
	json_array_append_new(g.nodes, json_pack("{s:s, s:i}", "name", "object", "mesh", 0));

	/* the photograph: the same mesh in one primitive, textured by projection */
	if (!ret && png) {
		int v_uv = add_view(&g, uv, sizeof(float) * 2 * mesh->nverts, GL_ARRAY_BUFFER);
		int a_uv = add_accessor(&g, v_uv, 0, GL_FLOAT, mesh->nverts, "VEC2");
		int v_all = add_view(&g, mesh->tri, sizeof(uint32_t) * 3 * mesh->ntris,
		                     GL_ELEMENT_ARRAY_BUFFER);
		int a_all = add_accessor(&g, v_all, 0, GL_UNSIGNED_INT, 3 * mesh->ntris, "SCALAR");
		int v_png = add_view(&g, png, png_len, 0);
		json_object_set_new(g.root, "images", json_pack("[{s:s, s:i, s:s}]", "name", "photograph",
		                                                "bufferView", v_png, "mimeType",
		                                                "image/png"));
		json_object_set_new(g.root, "samplers",
		                    json_pack("[{s:i, s:i, s:i, s:i}]", "magFilter", GL_LINEAR,
		                              "minFilter", GL_LINEAR_MIPMAP_LINEAR, "wrapS",
		                              GL_CLAMP_TO_EDGE, "wrapT", GL_CLAMP_TO_EDGE));
		json_object_set_new(g.root, "textures", json_pack("[{s:s, s:i, s:i}]", "name",
		                                                  "photograph", "sampler", 0, "source",
		                                                  0));
		int m = (int)json_array_size(g.materials);
		json_array_append_new(g.materials,
		                      json_pack("{s:s, s:{s:{s:i}, s:f, s:f}, s:{s:{}}, s:{s:s}}", "name",
		                                "photograph", "pbrMetallicRoughness",
		                                "baseColorTexture", "index", 0, "metallicFactor", 0.0,
		                                "roughnessFactor", 1.0, "extensions",
		                                "KHR_materials_unlit", "extras", "kogei_material",
		                                "none: the photograph, shown unlit"));
		use_extension(&g, "KHR_materials_unlit");
		json_array_append_new(g.meshes, json_pack("{s:s, s:[{s:{s:i, s:i, s:i}, s:i, s:i, s:i}]}",
		                                          "name", "photograph", "primitives",
		                                          "attributes", "POSITION", a_pos, "NORMAL",
		                                          a_nrm, "TEXCOORD_0", a_uv, "indices", a_all,
		                                          "material", m, "mode", 4));
		/* beside the object, a tenth of its width apart */
		double dx = 1.1 * ((double)hi[0] - (double)lo[0]);
		json_array_append_new(g.nodes, json_pack("{s:s, s:i, s:[fff]}", "name", "photograph",
		                                         "mesh", 1, "translation", dx, 0.0, 0.0));
	}
	if (!ret) {
		add_camera(&g, s);
		add_light(&g, s, err);
	}
	if (!ret && g.bin.oom)
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	if (ret)
		goto done;

	json_t *scene_nodes = json_array();
	for (size_t i = 0; i < json_array_size(g.nodes); i++)
		json_array_append_new(scene_nodes, json_integer((json_int_t)i));
	json_t *asset_extras = NULL;
	if ((ret = asset_extras_new(s, opt, path, &asset_extras, err)))
		goto done;
	json_object_set_new(g.root, "asset",
	                    json_pack("{s:s, s:s, s:o}", "version", "2.0", "generator",
	                              "kogei " KG_VERSION, "extras", asset_extras));
	if (json_array_size(g.ext_used))
		json_object_set(g.root, "extensionsUsed", g.ext_used);
	json_object_set_new(g.root, "scene", json_integer(0));
	json_object_set_new(g.root, "scenes",
	                    json_pack("[{s:s, s:o}]", "name", "kogei", "nodes", scene_nodes));
	json_object_set(g.root, "nodes", g.nodes);
	json_object_set(g.root, "meshes", g.meshes);
	json_object_set(g.root, "materials", g.materials);
	json_object_set(g.root, "accessors", g.accessors);
	json_object_set(g.root, "bufferViews", g.views);
	json_object_set_new(g.root, "buffers",
	                    json_pack("[{s:I}]", "byteLength", (json_int_t)((g.bin.n + 3) & ~(size_t)3)));
	json = json_dumps(g.root, JSON_COMPACT);
	if (!json)
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	else
		ret = write_glb(path, json, &g.bin, err);

done:
	json_decref(g.root);
	json_decref(g.views);
	json_decref(g.accessors);
	json_decref(g.materials);
	json_decref(g.meshes);
	json_decref(g.nodes);
	json_decref(g.ext_used);
	free(g.bin.d);
	free(json);
	free(png);
	free(slot);
	free(count);
	free(pos);
	free(nrm);
	free(uv);
	free(idx);
	return ret;
}

int kg_gltf_write_scene_file(const char *scene_path, const kg_gltf_options *opt,
                             const char *path, kg_err *err)
{
	kg_scene *s = NULL;
	int ret = kg_scene_load(scene_path, &s, err);
	if (!ret)
		ret = kg_gltf_write(s, opt, path, err);
	kg_scene_free(&s);
	return ret;
}
