/* A kogei-scene/1 scene as a Mitsuba 3 scene (XML, one binary PLY per material).
 *
 * Plugins and parameters are those of Mitsuba 3's plugin reference (the
 * pluginparameters tables in its src/bsdfs, src/shapes, src/sensors, src/emitters,
 * src/integrators, src/films, src/samplers, src/rfilters; docs/render.md lists them).
 * Spectra are written as "wavelength:value" lists, which Mitsuba interpolates
 * linearly and takes as zero outside the listed range; the library's n, k are
 * listed on the 61-band grid (400-700 nm) and held at their end values to 360 and
 * 830 nm (Mitsuba's spectral range), so a conductor never sees n = k = 0.
 *
 * The model (optics/, eq. 2 of the paper): f = gloss F D_beckmann(m) G / 4 cos cos
 * + mirror F cone(w), the cone exp(-(delta/w)^2) around the mirror direction. Both
 * lobes become Beckmann microfacet lobes: the gloss lobe with alpha = m (Mitsuba's
 * Beckmann alpha is the RMS slope with the same D as optics/ kg_beckmann), the mirror
 * lobe with alpha = w / 2 (a facet tilted by t turns the reflection by 2 t, so the
 * cone's exp(-delta^2 / w^2) is a Beckmann exp(-t^2 / alpha^2) with alpha = w / 2),
 * mixed by blendbsdf with weight mirror / (gloss + mirror) and scaled by
 * specular_reflectance = gloss + mirror when that is not 1. Alloys (eq. 3/4: the
 * composition-weighted sum of the metals' Fresnel reflectances, the alloy's own
 * surface parameters shared) are nested blendbsdfs of their metals, which is the same
 * sum since the BRDF is linear in F. Dielectrics (lacquer, eq. 5) are roughplastic
 * with int_ior = n (at 550 nm) and the body as diffuse_reflectance. Every BSDF is
 * wrapped in twosided: kogei's surfaces are two-sided. Differences from kogei's own
 * renderer: Smith shadowing instead of the V-groove term, and roughplastic's account of
 * the light reflected inside the coating (kogei neglects it). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "colorimetry.h"
#include "fsutil.h"
#include "render_private.h"

#define MI_LAMBDA_LO 360.0
#define MI_LAMBDA_HI 830.0

/* [A-Za-z0-9._-] kept, anything else '_'; never empty, never starting with '.'. */
static void safe_name(const char *in, char *out, size_t size)
{
	size_t j = 0;
	for (size_t i = 0; in[i] && j + 1 < size; i++) {
		char c = in[i];
		int ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
		         c == '-' || c == '_' || (c == '.' && j > 0);
		out[j++] = ok ? c : '_';
	}
	if (j == 0 && size > 1)
		out[j++] = '_';
	out[j] = '\0';
}

static void indent(FILE *fp, int depth)
{
	for (int i = 0; i < depth; i++)
		fputs("    ", fp);
}

/* <bsdf type="TYPE" id="ID"> on its own line. */
static void bsdf_open(FILE *fp, int depth, const char *type, const char *id)
{
	indent(fp, depth);
	fprintf(fp, "<bsdf type=\"%s\" id=\"", type);
	kg_xml_put(fp, id);
	fputs("\">\n", fp);
}

/* A spectrum on the grid; hold: extend to Mitsuba's range with the end values. */
static void spectrum_values(FILE *fp, int depth, const char *name, const double *v, int hold)
{
	indent(fp, depth);
	fprintf(fp, "<spectrum name=\"%s\" value=\"", name);
	if (hold)
		fprintf(fp, "%.0f:%.6g, ", MI_LAMBDA_LO, v[0]);
	for (int b = 0; b < KG_NBANDS; b++)
		fprintf(fp, "%.0f:%.6g%s", kg_band_nm(b), v[b], b + 1 < KG_NBANDS || hold ? ", " : "");
	if (hold)
		fprintf(fp, "%.0f:%.6g", MI_LAMBDA_HI, v[KG_NBANDS - 1]);
	fputs("\"/>\n", fp);
}

/* An emitter's spectrum on Mitsuba's scale. kogei's image scale is Y = sum over the
 * bands of the scene's weights times L (Y = 1: a white diffuser lit at intensity 1);
 * Mitsuba's is Y = integral of L ybar dlambda / 106.7502594 (MI_CIE_Y_NORMALIZATION in
 * its include/mitsuba/core/spectrum.h), L interpolated linearly between the listed
 * wavelengths. The spectrum is scaled so both give the same Y. */
static void emitter_values(const kg_scene *s, FILE *fp, int depth, const char *name,
                           const float *vf)
{
	double v[KG_NBANDS], yk = 0.0, ym = 0.0;
	for (int b = 0; b < KG_NBANDS; b++)
		yk += s->xyz_w[1][b] * vf[b];
	for (int nm = (int)KG_LAMBDA_MIN; nm <= (int)KG_LAMBDA_MAX; nm++) {
		double x = (nm - KG_LAMBDA_MIN) / KG_LAMBDA_STEP;
		int b = (int)x < KG_NBANDS - 1 ? (int)x : KG_NBANDS - 2;
		double t = x - b, l = (1.0 - t) * vf[b] + t * vf[b + 1];
		double w = nm == (int)KG_LAMBDA_MIN || nm == (int)KG_LAMBDA_MAX ? 0.5 : 1.0;
		ym += w * l * kg_cie1931_cmf[nm - KG_CMF_FIRST_NM][1];
	}
	ym /= 106.7502593994140625;
	double k = ym > 0.0 ? yk / ym : 0.0;
	for (int b = 0; b < KG_NBANDS; b++)
		v[b] = k * vf[b];
	spectrum_values(fp, depth, name, v, 0);
}

/* One lobe of the surface: a rough conductor or a rough plastic. */
static void lobe(FILE *fp, int depth, const char *id, const kg_material *m, const kg_nk *nk,
                 double alpha, double scale)
{
	int dielectric = m->kind == KG_MATERIAL_DIELECTRIC;
	bsdf_open(fp, depth, dielectric ? "roughplastic" : "roughconductor", id);
	indent(fp, depth + 1);
	fputs("<string name=\"distribution\" value=\"beckmann\"/>\n", fp);
	indent(fp, depth + 1);
	fprintf(fp, "<float name=\"alpha\" value=\"%.6g\"/>\n", alpha);
	if (dielectric) {
		indent(fp, depth + 1);
		fprintf(fp, "<float name=\"int_ior\" value=\"%.6g\"/>\n", m->nk.n.v[30]);
		indent(fp, depth + 1);
		fputs("<float name=\"ext_ior\" value=\"1\"/>\n", fp);
		spectrum_values(fp, depth + 1, "diffuse_reflectance", m->body.v, 1);
	} else {
		spectrum_values(fp, depth + 1, "eta", nk->n.v, 1);
		spectrum_values(fp, depth + 1, "k", nk->k.v, 1);
	}
	if (fabs(scale - 1.0) > 1e-12) {
		indent(fp, depth + 1);
		fprintf(fp, "<spectrum name=\"specular_reflectance\" value=\"%.6g\"/>\n", scale);
	}
	indent(fp, depth);
	fputs("</bsdf>\n", fp);
}

/* The surface of one n, k (a metal, or one metal of an alloy, or a dielectric): the
 * gloss and mirror lobes, blended. */
static void surface(FILE *fp, int depth, const char *id, const kg_material *m, const kg_nk *nk)
{
	double sum = m->gloss + m->mirror;
	char a[160], b[160];
	snprintf(a, sizeof(a), "%s_a_gloss", id);
	snprintf(b, sizeof(b), "%s_b_mirror", id);
	if (m->mirror <= 0.0 || m->gloss <= 0.0) {
		int gloss = m->mirror <= 0.0;
		lobe(fp, depth, gloss ? a : b, m, nk, gloss ? m->roughness : 0.5 * m->mirror_width, sum);
		return;
	}
	bsdf_open(fp, depth, "blendbsdf", id);
	indent(fp, depth + 1);
	fprintf(fp, "<!-- gloss lobe (Beckmann, m = %.4g) and mirror lobe (cone width %.4g rad), "
	        "weights %.4g and %.4g -->\n", m->roughness, m->mirror_width, m->gloss, m->mirror);
	indent(fp, depth + 1);
	fprintf(fp, "<float name=\"weight\" value=\"%.6g\"/>\n", m->mirror / sum);
	lobe(fp, depth + 1, a, m, nk, m->roughness, sum);
	lobe(fp, depth + 1, b, m, nk, 0.5 * m->mirror_width, sum);
	indent(fp, depth);
	fputs("</bsdf>\n", fp);
}

/* Components first..last of an alloy: nested blends, each adding one metal with weight
 * c_last / (c_first + ... + c_last). */
static void alloy(FILE *fp, int depth, const char *id, const kg_material *m, int last)
{
	char cid[200];
	char name[KG_MATERIAL_NAME_MAX];
	if (last == 0) {
		safe_name(m->component[0].name, name, sizeof(name));
		snprintf(cid, sizeof(cid), "%s_0_%s", id, name);
		surface(fp, depth, cid, m, &m->component[0].nk);
		return;
	}
	double sum = 0.0;
	for (int i = 0; i <= last; i++)
		sum += m->component[i].fraction;
	bsdf_open(fp, depth, "blendbsdf", id);
	indent(fp, depth + 1);
	fputs("<!-- ", fp);
	kg_xml_put(fp, m->component[last].name);
	fprintf(fp, ": fraction %.4g of the components so far -->\n",
	        sum > 0 ? m->component[last].fraction / sum : 0.0);
	indent(fp, depth + 1);
	fprintf(fp, "<float name=\"weight\" value=\"%.6g\"/>\n",
	        sum > 0 ? m->component[last].fraction / sum : 0.0);
	snprintf(cid, sizeof(cid), "%s_a", id);
	alloy(fp, depth + 1, cid, m, last - 1);
	safe_name(m->component[last].name, name, sizeof(name));
	snprintf(cid, sizeof(cid), "%s_b_%d_%s", id, last, name);
	surface(fp, depth + 1, cid, m, &m->component[last].nk);
	indent(fp, depth);
	fputs("</bsdf>\n", fp);
}

static void material_bsdf(FILE *fp, const kg_material *m, const char *id)
{
	static const char *const kinds[] = {"metal", "alloy", "dielectric"};
	indent(fp, 1);
	fputs("<!-- ", fp);
	kg_xml_put(fp, m->name);
	fprintf(fp, " (%s) -->\n", kinds[m->kind]);
	bsdf_open(fp, 1, "twosided", id);
	char inner[160];
	snprintf(inner, sizeof(inner), "%s_surface", id);
	if (strcmp(m->name, KG_SCENE_NEUTRAL_GREY) == 0 && m->kind == KG_MATERIAL_DIELECTRIC &&
	    m->nk.n.v[0] == 1.0) {
		bsdf_open(fp, 2, "diffuse", inner);
		indent(fp, 3);
		fprintf(fp, "<spectrum name=\"reflectance\" value=\"%.6g\"/>\n", m->body.v[0]);
		indent(fp, 2);
		fputs("</bsdf>\n", fp);
	} else if (m->kind == KG_MATERIAL_ALLOY) {
		alloy(fp, 2, inner, m, m->ncomponents - 1);
	} else {
		surface(fp, 2, inner, m, &m->nk);
	}
	indent(fp, 1);
	fputs("</bsdf>\n", fp);
}

/* The triangles of material mi as a mesh of their own (vertices renumbered). */
static int submesh(const kg_mesh *mesh, const uint16_t *tri_mat, int mi, kg_mesh **out,
                   kg_err *err)
{
	uint32_t *map = malloc(sizeof(uint32_t) * (mesh->nverts ? mesh->nverts : 1));
	if (!map)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	memset(map, 0xff, sizeof(uint32_t) * mesh->nverts);
	size_t nv = 0, nt = 0;
	for (size_t t = 0; t < mesh->ntris; t++) {
		if ((tri_mat ? tri_mat[t] : 0) != mi)
			continue;
		nt++;
		for (int k = 0; k < 3; k++) {
			uint32_t v = mesh->tri[3 * t + k];
			if (map[v] == UINT32_MAX)
				map[v] = (uint32_t)nv++;
		}
	}
	int ret = kg_mesh_new(nv, nt, mesh->normal ? KG_MESH_NORMALS : 0, out, err);
	if (!ret) {
		kg_mesh *m = *out;
		for (size_t v = 0; v < mesh->nverts; v++) {
			if (map[v] == UINT32_MAX)
				continue;
			memcpy(m->pos + 3 * map[v], mesh->pos + 3 * v, 3 * sizeof(float));
			if (mesh->normal)
				memcpy(m->normal + 3 * map[v], mesh->normal + 3 * v, 3 * sizeof(float));
		}
		size_t j = 0;
		for (size_t t = 0; t < mesh->ntris; t++)
			if ((tri_mat ? tri_mat[t] : 0) == mi) {
				for (int k = 0; k < 3; k++)
					m->tri[3 * j + k] = map[mesh->tri[3 * t + k]];
				j++;
			}
		m->npolygons = nt;
	}
	free(map);
	return ret;
}

static char *stem_dir(const char *xml_path)
{
	size_t n = strlen(xml_path);
	if (n > 4 && strcmp(xml_path + n - 4, ".xml") == 0)
		n -= 4;
	char *d = malloc(n + 1);
	if (d) {
		memcpy(d, xml_path, n);
		d[n] = '\0';
	}
	return d;
}

static const char *base_name(const char *p)
{
	const char *s = strrchr(p, '/');
	return s ? s + 1 : p;
}

/* The text the XML takes from input (file names, material names, in comments and
 * attributes) is text XML 1.0 can hold: refused before anything is written. */
/* 1 when label-map class c renders as a library material of another name (a compound
 * class "a|b" as a): its triangles join that material's shape, a comment names it. */
static int class_renamed(const kg_scene *s, int c)
{
	int m = s->label.class_mat[c];
	return m >= 0 && s->mat[m] != &s->neutral && strcmp(s->label.class_names[c], s->mat[m]->name);
}

static int check_texts(const kg_scene *s, const char *xml_path, const char *dir, kg_err *err)
{
	const char *names[3][2] = {{"the scene's file name", base_name(s->path)},
	                           {"its own file name", base_name(xml_path)},
	                           {"the meshes' folder", base_name(dir)}};
	char what[512];
	int ret = 0;
	for (int i = 0; !ret && i < 3; i++) {
		snprintf(what, sizeof(what), "%s: %s", xml_path, names[i][0]);
		ret = kg_xml_check(what, names[i][1], err);
	}
	for (int i = 0; !ret && i < s->nmat; i++) {
		const kg_material *m = s->mat[i];
		snprintf(what, sizeof(what), "%s: material %d: name", xml_path, i + 1);
		ret = kg_xml_check(what, m->name, err);
		for (int c = 0; !ret && m->kind == KG_MATERIAL_ALLOY && c < m->ncomponents; c++) {
			snprintf(what, sizeof(what), "%s: material %d: component %d: name", xml_path, i + 1,
			         c + 1);
			ret = kg_xml_check(what, m->component[c].name, err);
		}
	}
	for (int c = 0; !ret && s->assign == RD_ASSIGN_LABEL_MAP && c < s->label.nclasses; c++)
		if (class_renamed(s, c)) {
			snprintf(what, sizeof(what), "%s: label-map class %d: name", xml_path, c);
			ret = kg_xml_check(what, s->label.class_names[c], err);
		}
	return ret;
}

int kg_scene_write_mitsuba(const kg_scene *s, const char *xml_path, int threads, kg_err *err)
{
	/* the XML's folder must exist: only the meshes' folder is made */
	const char *slash = strrchr(xml_path, '/');
	if (slash && slash != xml_path) {
		char parent[4096];
		struct stat st;
		snprintf(parent, sizeof(parent), "%.*s", (int)(slash - xml_path), xml_path);
		if (stat(parent, &st) != 0 || !S_ISDIR(st.st_mode))
			return kg_fail(err, KG_ENOENT, "%s: the folder %s does not exist", xml_path,
			               parent);
	}
	uint16_t *tri_mat = NULL;
	int ret = rd_scene_triangle_materials(s, threads, &tri_mat, err);
	if (ret)
		return ret;
	char *dir = stem_dir(xml_path);
	int nmat = s->nmat > 0 ? s->nmat : 1;
	char (*ids)[KG_MATERIAL_NAME_MAX] = calloc((size_t)nmat, sizeof(*ids));
	size_t *count = calloc((size_t)nmat, sizeof(size_t));
	if (!dir || !ids || !count)
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	for (size_t t = 0; !ret && t < s->mesh->ntris; t++)
		count[tri_mat ? tri_mat[t] : 0]++;
	/* ids and file names from the material names, which must stay distinct */
	for (int i = 0; !ret && i < s->nmat; i++) {
		safe_name(s->mat[i]->name, ids[i], sizeof(ids[i]));
		for (int j = 0; j < i; j++)
			if (strcmp(ids[i], ids[j]) == 0)
				ret = kg_fail(err, KG_EINVAL, "%s: materials '%s' and '%s' give the same "
				              "file name %s.ply", s->path, s->mat[j]->name, s->mat[i]->name,
				              ids[i]);
	}
	if (!ret)
		ret = check_texts(s, xml_path, dir, err);
	if (!ret)
		ret = kg_mkdir_p(dir, err);
	const char *rel = base_name(dir);
	/* the meshes, each written atomically; the XML last, so it never names a missing
	 * file */
	for (int i = 0; !ret && i < s->nmat; i++) {
		if (!count[i])
			continue;
		kg_mesh *sub = NULL;
		char file[KG_MATERIAL_NAME_MAX + 8];
		snprintf(file, sizeof(file), "%s.ply", ids[i]);
		char *path = kg_path_join(dir, file);
		ret = path ? submesh(s->mesh, tri_mat, i, &sub, err) : kg_fail(err, KG_ENOMEM,
		                                                               "out of memory");
		if (!ret)
			ret = kg_ply_write_format(sub, path, KG_PLY_BINARY_LE, err);
		kg_mesh_free(&sub);
		free(path);
	}
	kg_outfile o = {0};
	if (!ret)
		ret = kg_outfile_open(&o, xml_path, 0, err);
	if (!ret) {
		FILE *fp = o.fp;
		const rd_view *v = &s->view;
		fputs("<?xml version=\"1.0\" encoding=\"utf-8\"?>\n", fp);
		fputs("<!-- Written by kogei from the scene ", fp);
		kg_xml_put(fp, base_name(s->path));
		fputs(" (kogei-scene/1). Mitsuba 3, a spectral variant\n     (scalar_spectral or "
		      "llvm_ad_spectral): mitsuba -m scalar_spectral ", fp);
		kg_xml_put(fp, base_name(xml_path));
		fputs("\n     Units: metres. The spectra are the material library's, on 400-700 nm "
		      "in 5 nm steps;\n     n and k are held at their end values to 360 and 830 nm, "
		      "the lights are zero outside\n     400-700 nm as in kogei. Untested by a "
		      "Mitsuba render: checked against the plugin\n     reference only. -->\n", fp);
		fputs("<scene version=\"3.0.0\">\n", fp);
		indent(fp, 1);
		fprintf(fp, "<integrator type=\"path\">\n");
		indent(fp, 2);
		fprintf(fp, "<!-- kogei's %d surface interactions per path -->\n", s->bounces);
		indent(fp, 2);
		fprintf(fp, "<integer name=\"max_depth\" value=\"%d\"/>\n", s->bounces + 1);
		indent(fp, 1);
		fputs("</integrator>\n", fp);

		double dist = sqrt((v->look_at[0] - v->pos[0]) * (v->look_at[0] - v->pos[0]) +
		                   (v->look_at[1] - v->pos[1]) * (v->look_at[1] - v->pos[1]) +
		                   (v->look_at[2] - v->pos[2]) * (v->look_at[2] - v->pos[2]));
		indent(fp, 1);
		fputs("<sensor type=\"perspective\">\n", fp);
		indent(fp, 2);
		fputs("<string name=\"fov_axis\" value=\"y\"/>\n", fp);
		indent(fp, 2);
		fprintf(fp, "<float name=\"fov\" value=\"%.9g\"/>\n", v->fov_deg);
		indent(fp, 2);
		fprintf(fp, "<float name=\"near_clip\" value=\"%.6g\"/>\n", fmin(0.01, 0.01 * dist));
		indent(fp, 2);
		fprintf(fp, "<float name=\"far_clip\" value=\"%.6g\"/>\n", fmax(1000.0, 1000.0 * dist));
		indent(fp, 2);
		fputs("<transform name=\"to_world\">\n", fp);
		indent(fp, 3);
		fprintf(fp, "<lookat origin=\"%.9g, %.9g, %.9g\" target=\"%.9g, %.9g, %.9g\" "
		        "up=\"%.9g, %.9g, %.9g\"/>\n", v->pos[0], v->pos[1], v->pos[2], v->look_at[0],
		        v->look_at[1], v->look_at[2], v->up[0], v->up[1], v->up[2]);
		indent(fp, 2);
		fputs("</transform>\n", fp);
		indent(fp, 2);
		fputs("<sampler type=\"independent\">\n", fp);
		indent(fp, 3);
		fprintf(fp, "<integer name=\"sample_count\" value=\"%d\"/>\n", s->spp);
		indent(fp, 3);
		fprintf(fp, "<integer name=\"seed\" value=\"%llu\"/>\n",
		        (unsigned long long)(s->seed & 0x7fffffffu));
		indent(fp, 2);
		fputs("</sampler>\n", fp);
		indent(fp, 2);
		fputs("<film type=\"hdrfilm\">\n", fp);
		indent(fp, 3);
		fprintf(fp, "<integer name=\"width\" value=\"%d\"/>\n", v->width);
		indent(fp, 3);
		fprintf(fp, "<integer name=\"height\" value=\"%d\"/>\n", v->height);
		indent(fp, 3);
		fputs("<rfilter type=\"box\"/>\n", fp);
		indent(fp, 2);
		fputs("</film>\n", fp);
		indent(fp, 1);
		fputs("</sensor>\n", fp);

		if (s->has_sun) {
			indent(fp, 1);
			fputs("<!-- kogei's directional light: a white diffuser facing it has Y = its "
			      "intensity (Y = 1: kogei's image white) -->\n", fp);
			indent(fp, 1);
			fputs("<emitter type=\"directional\">\n", fp);
			indent(fp, 2);
			fprintf(fp, "<vector name=\"direction\" value=\"%.9g, %.9g, %.9g\"/>\n", -s->sun_dir[0],
			        -s->sun_dir[1], -s->sun_dir[2]);
			emitter_values(s, fp, 2, "irradiance", s->sun_irradiance);
			indent(fp, 1);
			fputs("</emitter>\n", fp);
		}
		if (s->has_env) {
			float rad[KG_NBANDS];
			if (s->env_coef)
				rd_env_mean(s, rad);
			else
				memcpy(rad, s->env_radiance, sizeof(rad));
			indent(fp, 1);
			fprintf(fp, "<!-- kogei's environment (radiance Y = its intensity)%s -->\n", s->env_coef
			        ? ": its image replaced by its mean radiance over the sphere" : "");
			indent(fp, 1);
			fputs("<emitter type=\"constant\">\n", fp);
			emitter_values(s, fp, 2, "radiance", rad);
			indent(fp, 1);
			fputs("</emitter>\n", fp);
		}

		for (int i = 0; i < s->nmat; i++)
			if (count[i])
				material_bsdf(fp, s->mat[i], ids[i]);
		for (int c = 0; s->assign == RD_ASSIGN_LABEL_MAP && c < s->label.nclasses; c++) {
			if (!class_renamed(s, c) || !count[s->label.class_mat[c]])
				continue;
			indent(fp, 1);
			fputs("<!-- label-map class ", fp);
			kg_xml_put(fp, s->label.class_names[c]);
			fputs(strchr(s->label.class_names[c], '|')
			          ? " (compound: the data did not tell its members apart)" : "", fp);
			fputs(" renders as ", fp);
			kg_xml_put(fp, s->mat[s->label.class_mat[c]]->name);
			fputs(", in its shape -->\n", fp);
		}
		for (int i = 0; i < s->nmat; i++) {
			if (!count[i])
				continue;
			indent(fp, 1);
			fputs("<shape type=\"ply\" id=\"shape_", fp);
			kg_xml_put(fp, ids[i]);
			fputs("\">\n", fp);
			indent(fp, 2);
			fputs("<string name=\"filename\" value=\"", fp);
			kg_xml_put(fp, rel);
			fputc('/', fp);
			kg_xml_put(fp, ids[i]);
			fputs(".ply\"/>\n", fp);
			if (!s->mesh->normal) {
				indent(fp, 2);
				fputs("<boolean name=\"face_normals\" value=\"true\"/>\n", fp);
			}
			indent(fp, 2);
			fputs("<ref id=\"", fp);
			kg_xml_put(fp, ids[i]);
			fputs("\"/>\n", fp);
			indent(fp, 1);
			fputs("</shape>\n", fp);
		}
		fputs("</scene>\n", fp);
		if (ferror(fp))
			ret = kg_fail_write(err, errno, xml_path, "write failed");
	}
	if (!ret)
		ret = kg_outfile_commit(&o, err);
	else
		kg_outfile_abort(&o);
	free(tri_mat);
	free(ids);
	free(count);
	free(dir);
	return ret;
}
