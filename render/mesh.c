/* Mesh utilities and the generators the renderer, its tests and its benchmark use
 * (see kg_mesh.h): the icosphere, a ground plane, surfaces of revolution and the
 * tsuba demo object built from one. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "kg_mesh.h"

int kg_mesh_new(size_t nverts, size_t ntris, unsigned flags, kg_mesh **out, kg_err *err)
{
	kg_check_arg(out != NULL, err);
	*out = NULL;
	if (nverts > UINT32_MAX || ntris > SIZE_MAX / (3 * sizeof(uint32_t)) ||
	    nverts > SIZE_MAX / (3 * sizeof(float)))
		return kg_fail(err, KG_EINVAL, "mesh: %zu vertices and %zu triangles is too many",
		               nverts, ntris);
	kg_mesh *m = calloc(1, sizeof(*m));
	if (!m)
		return kg_fail(err, KG_ENOMEM, "mesh: out of memory");
	m->nverts = nverts;
	m->ntris = ntris;
	size_t nv = nverts ? nverts : 1, nt = ntris ? ntris : 1;
	int bad = !(m->pos = malloc(nv * 3 * sizeof(float)));
	bad |= !(m->tri = malloc(nt * 3 * sizeof(uint32_t)));
	if (flags & KG_MESH_NORMALS)
		bad |= !(m->normal = malloc(nv * 3 * sizeof(float)));
	if (flags & KG_MESH_COLORS)
		bad |= !(m->color = malloc(nv * 3 * sizeof(float)));
	if (flags & KG_MESH_VERT_MATERIAL)
		bad |= !(m->vert_material = malloc(nv * sizeof(int32_t)));
	if (flags & KG_MESH_TRI_MATERIAL)
		bad |= !(m->tri_material = malloc(nt * sizeof(int32_t)));
	if (bad) {
		kg_mesh_free(&m);
		return kg_fail(err, KG_ENOMEM, "mesh: out of memory for %zu vertices and %zu "
		               "triangles", nverts, ntris);
	}
	m->npolygons = ntris;
	*out = m;
	return 0;
}

void kg_mesh_free(kg_mesh **mp)
{
	if (!mp || !*mp)
		return;
	kg_mesh *m = *mp;
	free(m->pos);
	free(m->normal);
	free(m->color);
	free(m->vert_material);
	free(m->tri);
	free(m->tri_material);
	free(m);
	*mp = NULL;
}

void kg_mesh_bounds(const kg_mesh *m, float lo[3], float hi[3])
{
	for (int k = 0; k < 3; k++)
		lo[k] = hi[k] = m && m->nverts ? m->pos[k] : 0.0f;
	for (size_t i = 1; m && i < m->nverts; i++)
		for (int k = 0; k < 3; k++) {
			float v = m->pos[i * 3 + (size_t)k];
			lo[k] = v < lo[k] ? v : lo[k];
			hi[k] = v > hi[k] ? v : hi[k];
		}
}

int kg_mesh_compute_normals(kg_mesh *m, kg_err *err)
{
	kg_check_arg(m != NULL, err);
	double *acc = calloc(m->nverts ? m->nverts * 3 : 1, sizeof(double));
	if (!acc)
		return kg_fail(err, KG_ENOMEM, "mesh: out of memory for normals");
	if (!m->normal && !(m->normal = malloc((m->nverts ? m->nverts : 1) * 3 * sizeof(float)))) {
		free(acc);
		return kg_fail(err, KG_ENOMEM, "mesh: out of memory for normals");
	}
	for (size_t t = 0; t < m->ntris; t++) {
		const uint32_t *v = &m->tri[t * 3];
		double p[3][3], e[3][3], len[3];
		for (int j = 0; j < 3; j++)
			for (int k = 0; k < 3; k++)
				p[j][k] = m->pos[v[j] * 3 + (size_t)k];
		for (int j = 0; j < 3; j++) { /* e[j]: the edge from vertex j to vertex j+1 */
			for (int k = 0; k < 3; k++)
				e[j][k] = p[(j + 1) % 3][k] - p[j][k];
			len[j] = sqrt(e[j][0] * e[j][0] + e[j][1] * e[j][1] + e[j][2] * e[j][2]);
		}
		/* The geometric normal (p1 - p0) x (p2 - p0) = e0 x -e2. */
		double n[3] = { e[0][2] * e[2][1] - e[0][1] * e[2][2],
			            e[0][0] * e[2][2] - e[0][2] * e[2][0],
			            e[0][1] * e[2][0] - e[0][0] * e[2][1] };
		double nl = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
		if (nl == 0 || len[0] == 0 || len[1] == 0 || len[2] == 0)
			continue;
		/* Weighted by the triangle's angle at each vertex: a quad split in two then
		 * counts once at each corner, whichever way it was split. */
		for (int j = 0; j < 3; j++) {
			const double *out = e[j], *in = e[(j + 2) % 3];
			double c = -(out[0] * in[0] + out[1] * in[1] + out[2] * in[2]) /
			           (len[j] * len[(j + 2) % 3]);
			double angle = acos(c < -1 ? -1 : c > 1 ? 1 : c);
			for (int k = 0; k < 3; k++)
				acc[v[j] * 3 + (size_t)k] += angle * n[k] / nl;
		}
	}
	for (size_t i = 0; i < m->nverts; i++) {
		double *n = &acc[i * 3];
		double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
		for (int k = 0; k < 3; k++)
			m->normal[i * 3 + (size_t)k] = len > 0 ? (float)(n[k] / len) : (k == 2 ? 1.0f : 0.0f);
	}
	free(acc);
	return 0;
}

/* ---- icosphere ---------------------------------------------------------------- */

/* Midpoint vertices shared between the two triangles of an edge: an open-addressing
 * table keyed by the edge's vertex pair. */
typedef struct edge_table {
	uint64_t *key;
	uint32_t *val;
	size_t mask;
} edge_table;

static uint32_t midpoint(edge_table *et, double *pos, size_t *nverts, uint32_t a, uint32_t b)
{
	uint64_t key = a < b ? ((uint64_t)a << 32 | b) : ((uint64_t)b << 32 | a);
	size_t h = (size_t)((key * 0x9E3779B97F4A7C15ull) >> 17) & et->mask;
	while (et->key[h] != UINT64_MAX) {
		if (et->key[h] == key)
			return et->val[h];
		h = (h + 1) & et->mask;
	}
	uint32_t v = (uint32_t)(*nverts)++;
	double *p = &pos[(size_t)v * 3];
	for (int k = 0; k < 3; k++)
		p[k] = pos[(size_t)a * 3 + (size_t)k] + pos[(size_t)b * 3 + (size_t)k];
	double len = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
	for (int k = 0; k < 3; k++)
		p[k] /= len;
	et->key[h] = key;
	et->val[h] = v;
	return v;
}

int kg_mesh_icosphere(unsigned level, kg_mesh **out, kg_err *err)
{
	kg_check_arg(out != NULL, err);
	*out = NULL;
	if (level > 10)
		return kg_fail(err, KG_EINVAL, "icosphere: level %u (expected 0..10)", level);
	size_t ntris = (size_t)20 << (2 * level), nverts = (size_t)10 * ((size_t)1 << (2 * level)) + 2;
	/* The icosahedron: vertices (0, +-1, +-phi) and their cyclic permutations. */
	const double phi = (1.0 + sqrt(5.0)) / 2.0;
	static const int8_t base_v[12][3] = {
		{ -1, 2, 0 }, { 1, 2, 0 }, { -1, -2, 0 }, { 1, -2, 0 }, { 0, -1, 2 }, { 0, 1, 2 },
		{ 0, -1, -2 }, { 0, 1, -2 }, { 2, 0, -1 }, { 2, 0, 1 }, { -2, 0, -1 }, { -2, 0, 1 },
	};
	static const uint8_t base_t[20][3] = {
		{ 0, 11, 5 }, { 0, 5, 1 },  { 0, 1, 7 },   { 0, 7, 10 }, { 0, 10, 11 },
		{ 1, 5, 9 },  { 5, 11, 4 }, { 11, 10, 2 }, { 10, 7, 6 }, { 7, 1, 8 },
		{ 3, 9, 4 },  { 3, 4, 2 },  { 3, 2, 6 },   { 3, 6, 8 },  { 3, 8, 9 },
		{ 4, 9, 5 },  { 2, 4, 11 }, { 6, 2, 10 },  { 8, 6, 7 },  { 9, 8, 1 },
	};
	double *pos = malloc(nverts * 3 * sizeof(double));
	uint32_t *tri = malloc(ntris * 3 * sizeof(uint32_t));
	uint32_t *next = malloc(ntris * 3 * sizeof(uint32_t));
	size_t slots = 1;
	while (slots < ntris) /* the last level adds 3/2 * ntris/4 edges: half full at most */
		slots <<= 1;
	edge_table et = { malloc(slots * sizeof(uint64_t)), malloc(slots * sizeof(uint32_t)),
		              slots - 1 };
	kg_mesh *m = NULL;
	int ret = 0;
	if (!pos || !tri || !next || !et.key || !et.val) {
		ret = kg_fail(err, KG_ENOMEM, "icosphere: out of memory for level %u", level);
		goto done;
	}
	for (int i = 0; i < 12; i++) {
		double p[3], len = 0;
		for (int k = 0; k < 3; k++) {
			int c = base_v[i][k];
			p[k] = c == 2 ? phi : c == -2 ? -phi : c;
			len += p[k] * p[k];
		}
		for (int k = 0; k < 3; k++)
			pos[i * 3 + k] = p[k] / sqrt(len);
	}
	for (int t = 0; t < 20; t++)
		for (int k = 0; k < 3; k++)
			tri[t * 3 + k] = base_t[t][k];
	size_t nv = 12, nt = 20;
	for (unsigned l = 0; l < level; l++) {
		memset(et.key, 0xff, slots * sizeof(uint64_t));
		for (size_t t = 0; t < nt; t++) {
			uint32_t a = tri[t * 3], b = tri[t * 3 + 1], c = tri[t * 3 + 2];
			uint32_t ab = midpoint(&et, pos, &nv, a, b), bc = midpoint(&et, pos, &nv, b, c),
			         ca = midpoint(&et, pos, &nv, c, a);
			uint32_t *o = &next[t * 12];
			const uint32_t sub[12] = { a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca };
			memcpy(o, sub, sizeof(sub));
		}
		uint32_t *swap = tri;
		tri = next;
		next = swap;
		nt *= 4;
	}
	if ((ret = kg_mesh_new(nverts, ntris, KG_MESH_NORMALS, &m, err)) != 0)
		goto done;
	for (size_t i = 0; i < nverts * 3; i++)
		m->pos[i] = m->normal[i] = (float)pos[i];
	memcpy(m->tri, tri, ntris * 3 * sizeof(uint32_t));
	*out = m;
done:
	free(pos);
	free(tri);
	free(next);
	free(et.key);
	free(et.val);
	return ret;
}

int kg_mesh_plane(float half_size, kg_mesh **out, kg_err *err)
{
	return kg_mesh_plane_grid(half_size, 1, out, err);
}

int kg_mesh_plane_grid(float half_size, unsigned segments, kg_mesh **out, kg_err *err)
{
	kg_check_arg(out != NULL, err);
	*out = NULL;
	if (!(half_size > 0) || !isfinite(half_size))
		return kg_fail(err, KG_EINVAL, "plane: half size %g (expected a positive number)",
		               (double)half_size);
	if (segments < 1 || segments > 4096)
		return kg_fail(err, KG_EINVAL, "plane: %u segments (expected 1..4096)", segments);
	unsigned n = segments + 1;
	kg_mesh *m;
	int ret = kg_mesh_new((size_t)n * n, 2 * (size_t)segments * segments, KG_MESH_NORMALS, &m,
	                      err);
	if (ret)
		return ret;
	for (unsigned j = 0; j < n; j++)
		for (unsigned i = 0; i < n; i++) {
			size_t v = (size_t)j * n + i;
			float *p = &m->pos[v * 3], *nr = &m->normal[v * 3];
			p[0] = (2.0f * (float)i / (float)segments - 1.0f) * half_size;
			p[1] = (2.0f * (float)j / (float)segments - 1.0f) * half_size;
			p[2] = 0;
			nr[0] = nr[1] = 0;
			nr[2] = 1;
		}
	uint32_t *t = m->tri;
	for (unsigned j = 0; j < segments; j++)
		for (unsigned i = 0; i < segments; i++) {
			uint32_t a = j * n + i, b = a + 1, c = a + n + 1, d = a + n;
			t[0] = a, t[1] = b, t[2] = c, t[3] = a, t[4] = c, t[5] = d;
			t += 6;
		}
	*out = m;
	return 0;
}

/* ---- surfaces of revolution ----------------------------------------------------- */

#define LATHE_CREASE_COS 0.8660254037844387 /* cos 30 degrees */

/* Whether the vertices at inner profile point i are split between the segment before
 * and the segment after it. */
static int lathe_crease(const kg_lathe_point *p, size_t i)
{
	if (p[i - 1].material != p[i].material)
		return 1;
	double a[2] = { p[i].r - p[i - 1].r, p[i].z - p[i - 1].z };
	double b[2] = { p[i + 1].r - p[i].r, p[i + 1].z - p[i].z };
	double c = (a[0] * b[0] + a[1] * b[1]) / (hypot(a[0], a[1]) * hypot(b[0], b[1]));
	return c < LATHE_CREASE_COS;
}

int kg_mesh_lathe(const kg_lathe_point *profile, size_t npoints, unsigned segments,
                  kg_mesh **out, kg_err *err)
{
	kg_check_arg(out != NULL && profile != NULL, err);
	*out = NULL;
	if (npoints < 2 || npoints > 100000)
		return kg_fail(err, KG_EINVAL, "lathe: %zu profile points (expected 2..100000)",
		               npoints);
	if (segments < 3 || segments > 100000)
		return kg_fail(err, KG_EINVAL, "lathe: %u segments (expected 3..100000)", segments);
	for (size_t i = 0; i < npoints; i++) {
		if (!isfinite(profile[i].r) || !isfinite(profile[i].z) || profile[i].r < 0)
			return kg_fail(err, KG_EINVAL,
			               "lathe: profile point %zu (%g, %g): expected r >= 0 and finite "
			               "coordinates", i, (double)profile[i].r, (double)profile[i].z);
		if (i && profile[i].r == profile[i - 1].r && profile[i].z == profile[i - 1].z)
			return kg_fail(err, KG_EINVAL, "lathe: profile points %zu and %zu coincide",
			               i - 1, i);
	}
	/* Each point has a ring of vertices (one pole vertex on the axis), a crease point
	 * two rings; the segment from point i uses ring_out[i] and ring_in[i + 1]. */
	size_t *ring_in = malloc(npoints * sizeof(size_t)), *ring_out = malloc(npoints * sizeof(size_t));
	if (!ring_in || !ring_out) {
		free(ring_in);
		free(ring_out);
		return kg_fail(err, KG_ENOMEM, "lathe: out of memory");
	}
	size_t nv = 0, nt = 0;
	for (size_t i = 0; i < npoints; i++) {
		size_t ring = profile[i].r == 0 ? 1 : segments;
		ring_in[i] = nv;
		if (i > 0 && i + 1 < npoints && lathe_crease(profile, i))
			nv += ring;
		ring_out[i] = nv;
		nv += ring;
		if (i + 1 < npoints)
			nt += (profile[i].r > 0) + (profile[i + 1].r > 0) == 2 ? 2 * (size_t)segments
			      : (profile[i].r > 0) || (profile[i + 1].r > 0)   ? segments
			                                                       : 0;
	}
	kg_mesh *m;
	int ret = kg_mesh_new(nv, nt, KG_MESH_TRI_MATERIAL, &m, err);
	if (ret) {
		free(ring_in);
		free(ring_out);
		return ret;
	}
	for (size_t i = 0; i < npoints; i++) {
		const kg_lathe_point *p = &profile[i];
		size_t ring = p->r == 0 ? 1 : segments;
		for (size_t j = 0; j < ring; j++) {
			double th = 2.0 * M_PI * (double)j / segments;
			float x = (float)(p->r * cos(th)), y = (float)(p->r * sin(th));
			float xyz[3] = { x, y, p->z };
			memcpy(&m->pos[(ring_in[i] + j) * 3], xyz, sizeof(xyz));
			memcpy(&m->pos[(ring_out[i] + j) * 3], xyz, sizeof(xyz));
		}
	}
	size_t t = 0;
	for (size_t i = 0; i + 1 < npoints; i++) {
		size_t a = ring_out[i], b = ring_in[i + 1];
		int apole = profile[i].r == 0, bpole = profile[i + 1].r == 0;
		for (size_t j = 0; j < segments && !(apole && bpole); j++) {
			size_t j1 = (j + 1) % segments;
			uint32_t a0 = (uint32_t)(a + (apole ? 0 : j)), a1 = (uint32_t)(a + (apole ? 0 : j1));
			uint32_t b0 = (uint32_t)(b + (bpole ? 0 : j)), b1 = (uint32_t)(b + (bpole ? 0 : j1));
			/* The quad a0 a1 b1 b0, wound so the normal is (dz, -dr) in the profile
			 * plane: to the right of the direction of travel. */
			if (!bpole) {
				uint32_t *o = &m->tri[t * 3];
				o[0] = a0, o[1] = b1, o[2] = b0;
				m->tri_material[t++] = profile[i].material;
			}
			if (!apole) {
				uint32_t *o = &m->tri[t * 3];
				o[0] = a0, o[1] = a1, o[2] = b1;
				m->tri_material[t++] = profile[i].material;
			}
		}
	}
	free(ring_in);
	free(ring_out);
	if ((ret = kg_mesh_compute_normals(m, err)) != 0) {
		kg_mesh_free(&m);
		return ret;
	}
	*out = m;
	return 0;
}

/* ---- the tsuba ------------------------------------------------------------------ */

/* Shape, in units of the outer radius. */
#define TSUBA_HOLE_R 0.12
#define TSUBA_SEPPA_R 0.30
#define TSUBA_SEPPA_Z 0.058
#define TSUBA_RELIEF_R0 0.38
#define TSUBA_RELIEF_R1 0.85
#define TSUBA_RELIEF_H 0.03
#define TSUBA_PLATE_Z 0.05
#define TSUBA_RIM_IN 0.93
#define TSUBA_RIM_Z 0.06 /* where the rim's round top starts */
#define TSUBA_PETALS 8

/* Height of the relief above the plate at (r, theta): eight petals that swirl
 * outward, fading to zero at both edges of the band so it meets the plate without a
 * crack. */
static double tsuba_relief(double r, double th)
{
	double u = (r - TSUBA_RELIEF_R0) / (TSUBA_RELIEF_R1 - TSUBA_RELIEF_R0);
	/* r comes back from float positions: on the edge rings it is off by an ulp, and
	 * must give exactly zero there. */
	if (u < 1e-5 || u > 1 - 1e-5)
		return 0;
	double petal = 0.5 + 0.5 * cos(TSUBA_PETALS * th + 5.0 * u);
	return TSUBA_RELIEF_H * sin(M_PI * u) * petal * petal;
}

int kg_mesh_tsuba(unsigned segments, kg_mesh **out, kg_err *err)
{
	kg_check_arg(out != NULL, err);
	*out = NULL;
	if (segments < 16 || segments > 4096)
		return kg_fail(err, KG_EINVAL, "tsuba: %u segments (expected 16..4096)", segments);
	const unsigned arc = 12, relief = segments / 4 < 12 ? 12 : segments / 4;
	kg_lathe_point *pr = malloc((16 + arc + relief) * sizeof(*pr));
	if (!pr)
		return kg_fail(err, KG_ENOMEM, "tsuba: out of memory");
	size_t n = 0;
#define PT(r_, z_, mat_) (pr[n++] = (kg_lathe_point){ (float)(r_), (float)(z_), (mat_) })
	/* Counter-clockwise from the inner edge of the lower face. */
	PT(TSUBA_HOLE_R, 0, KG_TSUBA_PLATE);
	PT(1.0, 0, KG_TSUBA_RIM);
	/* The rounded rim: a half circle from the outer edge over to the inner wall. */
	double cr = (1.0 + TSUBA_RIM_IN) / 2, rho = (1.0 - TSUBA_RIM_IN) / 2;
	for (unsigned k = 0; k <= arc; k++) {
		double a = M_PI * k / arc;
		PT(cr + rho * cos(a), TSUBA_RIM_Z + rho * sin(a), KG_TSUBA_RIM);
	}
	PT(TSUBA_RIM_IN, TSUBA_PLATE_Z, KG_TSUBA_PLATE);
	for (unsigned k = 0; k <= relief; k++) {
		double r = TSUBA_RELIEF_R1 - (TSUBA_RELIEF_R1 - TSUBA_RELIEF_R0) * k / relief;
		PT(r, TSUBA_PLATE_Z, k < relief ? KG_TSUBA_RELIEF : KG_TSUBA_PLATE);
	}
	PT(TSUBA_SEPPA_R, TSUBA_PLATE_Z, KG_TSUBA_SEPPA);
	PT(TSUBA_SEPPA_R, TSUBA_SEPPA_Z, KG_TSUBA_SEPPA);
	PT(TSUBA_HOLE_R, TSUBA_SEPPA_Z, KG_TSUBA_SEPPA);
	PT(TSUBA_HOLE_R, 0, KG_TSUBA_SEPPA);
#undef PT
	kg_mesh *m;
	int ret = kg_mesh_lathe(pr, n, segments, &m, err);
	free(pr);
	if (ret)
		return ret;
	/* Raise the relief band: the vertices of its faces. The relief is zero on the
	 * band's two edge rings, so they stay on the plate's. */
	unsigned char *moved = calloc(m->nverts, 1);
	if (!moved) {
		kg_mesh_free(&m);
		return kg_fail(err, KG_ENOMEM, "tsuba: out of memory");
	}
	for (size_t t = 0; t < m->ntris; t++) {
		if (m->tri_material[t] != KG_TSUBA_RELIEF)
			continue;
		for (int k = 0; k < 3; k++) {
			uint32_t v = m->tri[t * 3 + (size_t)k];
			if (moved[v])
				continue;
			moved[v] = 1;
			float *p = &m->pos[(size_t)v * 3];
			double r = hypot(p[0], p[1]), th = atan2(p[1], p[0]);
			p[2] = (float)(p[2] + tsuba_relief(r, th));
		}
	}
	free(moved);
	if ((ret = kg_mesh_compute_normals(m, err)) != 0) {
		kg_mesh_free(&m);
		return ret;
	}
	*out = m;
	return 0;
}
