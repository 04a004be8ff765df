/* The mesh generators and utilities (render/mesh.c):
 * - icosphere: 20*4^L triangles and 10*4^L+2 vertices, every vertex at radius 1
 *   within 1e-6, unit normals equal to the positions, closed and consistently wound
 *   (every directed edge once, its reverse once), every face facing outward; area and
 *   volume approach 4 pi and 4 pi / 3 as L grows, the error shrinking each level;
 * - plane: two triangles facing +z over the requested square;
 * - lathe: a closed cylinder's volume equals that of the inscribed n-gon prism,
 *   (n/2) R^2 sin(2 pi/n) h, its cap normals are -z/+z and its wall normals radial,
 *   its faces carry their segment's material; bad profiles are refused;
 * - tsuba: watertight by position (creases split vertices, not the surface), wound
 *   outward (positive volume, geometric normals agreeing with the vertex normals),
 *   inside its stated bounds, every region's material present;
 * - kg_mesh_bounds on an empty mesh. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_mesh.h"
#include "kg_test.h"

static void tri_normal(const kg_mesh *m, size_t t, double n[3])
{
	const float *a = &m->pos[m->tri[t * 3] * 3], *b = &m->pos[m->tri[t * 3 + 1] * 3],
	            *c = &m->pos[m->tri[t * 3 + 2] * 3];
	double e1[3], e2[3];
	for (int k = 0; k < 3; k++) {
		e1[k] = (double)b[k] - a[k];
		e2[k] = (double)c[k] - a[k];
	}
	n[0] = e1[1] * e2[2] - e1[2] * e2[1];
	n[1] = e1[2] * e2[0] - e1[0] * e2[2];
	n[2] = e1[0] * e2[1] - e1[1] * e2[0];
}

static double area(const kg_mesh *m)
{
	double s = 0;
	for (size_t t = 0; t < m->ntris; t++) {
		double n[3];
		tri_normal(m, t, n);
		s += 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
	}
	return s;
}

/* Signed volume by the divergence theorem: positive when the faces wind outward. */
static double volume(const kg_mesh *m)
{
	double s = 0;
	for (size_t t = 0; t < m->ntris; t++) {
		const float *a = &m->pos[m->tri[t * 3] * 3], *b = &m->pos[m->tri[t * 3 + 1] * 3],
		            *c = &m->pos[m->tri[t * 3 + 2] * 3];
		s += ((double)a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
		      (double)a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
		      (double)a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) / 6.0;
	}
	return s;
}

/* Directed edges keyed by a vertex id per position (ids[] maps each vertex to the
 * first vertex at the same position, or to itself). The surface is closed and
 * consistently wound when every directed edge occurs once and its reverse once. */
typedef struct edge {
	uint32_t a, b;
} edge;

static int edge_cmp(const void *x, const void *y)
{
	const edge *p = x, *q = y;
	if (p->a != q->a)
		return p->a < q->a ? -1 : 1;
	return p->b < q->b ? -1 : p->b > q->b;
}

static int closed_and_consistent(const kg_mesh *m, const uint32_t *ids, const char *what)
{
	size_t n = m->ntris * 3;
	edge *e = malloc(n * sizeof(edge));
	for (size_t t = 0; t < m->ntris; t++)
		for (int k = 0; k < 3; k++) {
			uint32_t a = m->tri[t * 3 + (size_t)k], b = m->tri[t * 3 + (size_t)(k + 1) % 3];
			e[t * 3 + (size_t)k] = (edge){ ids ? ids[a] : a, ids ? ids[b] : b };
		}
	qsort(e, n, sizeof(edge), edge_cmp);
	int ok = 1;
	for (size_t i = 0; i < n && ok; i++) {
		if (e[i].a == e[i].b) {
			fprintf(stderr, "%s: a collapsed edge at vertex %u\n", what, e[i].a);
			ok = 0;
			break;
		}
		if (i + 1 < n && edge_cmp(&e[i], &e[i + 1]) == 0) {
			fprintf(stderr, "%s: edge %u-%u used twice in the same direction\n", what,
			        e[i].a, e[i].b);
			ok = 0;
		}
		edge rev = { e[i].b, e[i].a };
		if (!bsearch(&rev, e, n, sizeof(edge), edge_cmp)) {
			fprintf(stderr, "%s: edge %u-%u has no opposite (a hole or a flipped face)\n",
			        what, e[i].a, e[i].b);
			ok = 0;
		}
	}
	free(e);
	return ok;
}

/* One id per distinct position (exact float equality), by sorting. */
static const kg_mesh *sort_mesh;

static int pos_cmp(const void *x, const void *y)
{
	const float *p = &sort_mesh->pos[*(const uint32_t *)x * 3],
	            *q = &sort_mesh->pos[*(const uint32_t *)y * 3];
	for (int k = 0; k < 3; k++)
		if (p[k] != q[k])
			return p[k] < q[k] ? -1 : 1;
	return 0;
}

static uint32_t *position_ids(const kg_mesh *m)
{
	uint32_t *order = malloc(m->nverts * sizeof(uint32_t)), *ids = malloc(m->nverts * sizeof(uint32_t));
	for (uint32_t i = 0; i < m->nverts; i++)
		order[i] = i;
	sort_mesh = m;
	qsort(order, m->nverts, sizeof(uint32_t), pos_cmp);
	for (size_t i = 0; i < m->nverts; i++)
		ids[order[i]] = i && pos_cmp(&order[i], &order[i - 1]) == 0 ? ids[order[i - 1]] : order[i];
	free(order);
	return ids;
}

static void test_icosphere(void)
{
	double prev_area_err = INFINITY, prev_vol_err = INFINITY;
	for (unsigned level = 0; level <= 6; level++) {
		kg_err err = { { 0 } };
		kg_mesh *m = NULL;
		char what[64];
		snprintf(what, sizeof(what), "icosphere %u", level);
		CHECK(kg_mesh_icosphere(level, &m, &err) == 0, "%s: %s", what, err.msg);
		if (!m)
			return;
		size_t four = (size_t)1 << (2 * level);
		CHECK(m->ntris == 20 * four && m->nverts == 10 * four + 2, "%s: %zu vertices, %zu "
		      "triangles", what, m->nverts, m->ntris);
		double worst_r = 0, worst_n = 0;
		for (size_t i = 0; i < m->nverts; i++) {
			const float *p = &m->pos[i * 3], *n = &m->normal[i * 3];
			double r = sqrt((double)p[0] * p[0] + (double)p[1] * p[1] + (double)p[2] * p[2]);
			double nl = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
			double d = (double)p[0] * n[0] + (double)p[1] * n[1] + (double)p[2] * n[2];
			worst_r = fmax(worst_r, fabs(r - 1));
			worst_n = fmax(worst_n, fmax(fabs(nl - 1), fabs(d - 1)));
		}
		CHECK(worst_r <= 1e-6, "%s: a vertex is %.3g off radius 1", what, worst_r);
		CHECK(worst_n <= 1e-6, "%s: a normal is %.3g off unit length along the radius", what,
		      worst_n);
		CHECK(closed_and_consistent(m, NULL, what), "%s: not closed and consistently wound",
		      what);
		size_t inward = 0;
		for (size_t t = 0; t < m->ntris; t++) {
			double n[3], c[3] = { 0, 0, 0 };
			tri_normal(m, t, n);
			for (int j = 0; j < 3; j++)
				for (int k = 0; k < 3; k++)
					c[k] += m->pos[m->tri[t * 3 + (size_t)j] * 3 + (size_t)k];
			inward += n[0] * c[0] + n[1] * c[1] + n[2] * c[2] <= 0;
		}
		CHECK(inward == 0, "%s: %zu faces face inward", what, inward);
		double a = area(m), v = volume(m);
		double area_err = 4 * M_PI - a, vol_err = 4 * M_PI / 3 - v;
		CHECK(area_err > 0 && area_err < prev_area_err, "%s: area %.9g (4 pi = %.9g) does not "
		      "approach 4 pi from below", what, a, 4 * M_PI);
		CHECK(vol_err > 0 && vol_err < prev_vol_err, "%s: volume %.9g does not approach 4 pi/3",
		      what, v);
		printf("icosphere %u: %7zu triangles, radius error %.2g, area %.7f (4 pi - area = "
		       "%.2e), volume %.7f\n", level, m->ntris, worst_r, a, area_err, v);
		prev_area_err = area_err;
		prev_vol_err = vol_err;
		kg_mesh_free(&m);
	}
	CHECK(prev_area_err < 4 * M_PI * 1e-3, "level 6 area is %.2e short of 4 pi", prev_area_err);

	kg_err err = { { 0 } };
	kg_mesh *m = NULL;
	CHECK(kg_mesh_icosphere(8, &m, &err) == 0 && m && m->ntris == 1310720 &&
	      m->nverts == 655362, "icosphere 8: %s", err.msg);
	kg_mesh_free(&m);
	CHECK(kg_mesh_icosphere(11, &m, &err) == KG_EINVAL && !m && strstr(err.msg, "level 11"),
	      "icosphere 11 should be refused: %s", err.msg);
}

static void test_plane(void)
{
	kg_err err = { { 0 } };
	kg_mesh *m = NULL;
	CHECK(kg_mesh_plane(2.5f, &m, &err) == 0, "plane: %s", err.msg);
	if (!m)
		return;
	float lo[3], hi[3];
	kg_mesh_bounds(m, lo, hi);
	CHECK(lo[0] == -2.5f && lo[1] == -2.5f && hi[0] == 2.5f && hi[1] == 2.5f && lo[2] == 0 &&
	      hi[2] == 0, "plane: bounds %g %g %g - %g %g %g", lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
	CHECK(m->ntris == 2, "plane: %zu triangles", m->ntris);
	for (size_t t = 0; t < m->ntris; t++) {
		double n[3];
		tri_normal(m, t, n);
		CHECK(n[2] > 0 && fabs(n[0]) + fabs(n[1]) == 0, "plane: triangle %zu faces down", t);
	}
	CHECK_NEAR(area(m), 25.0, 1e-9, "plane area");
	kg_mesh_free(&m);
	CHECK(kg_mesh_plane(0, &m, &err) == KG_EINVAL && !m, "plane 0 should be refused");
}

static void test_lathe(void)
{
	const float R = 0.75f, h = 2.0f;
	const kg_lathe_point cyl[] = { { 0, 0, 1 }, { R, 0, 2 }, { R, h, 3 }, { 0, h, 0 } };
	for (unsigned n = 3; n <= 96; n *= 2) {
		kg_err err = { { 0 } };
		kg_mesh *m = NULL;
		CHECK(kg_mesh_lathe(cyl, 4, n, &m, &err) == 0, "lathe: %s", err.msg);
		if (!m)
			return;
		char what[64];
		snprintf(what, sizeof(what), "cylinder, %u segments", n);
		double prism = 0.5 * n * (double)R * R * sin(2 * M_PI / n) * h;
		CHECK_NEAR(volume(m), prism, 1e-5 * prism, what);
		CHECK(m->ntris == 4 * (size_t)n, "%s: %zu triangles, expected 4n", what, m->ntris);
		uint32_t *ids = position_ids(m);
		CHECK(closed_and_consistent(m, ids, what), "%s: not watertight", what);
		free(ids);
		size_t wrong = 0;
		for (size_t t = 0; t < m->ntris; t++) {
			double g[3];
			tri_normal(m, t, g);
			const float *nv = &m->normal[m->tri[t * 3] * 3];
			float zmean = (m->pos[m->tri[t * 3] * 3 + 2] + m->pos[m->tri[t * 3 + 1] * 3 + 2] +
			               m->pos[m->tri[t * 3 + 2] * 3 + 2]) / 3;
			int mat = m->tri_material[t];
			if (zmean == 0) /* bottom cap */
				wrong += mat != 1 || nv[2] > -0.999999f || g[2] >= 0;
			else if (zmean == h)
				wrong += mat != 3 || nv[2] < 0.999999f || g[2] <= 0;
			else {
				const float *p = &m->pos[m->tri[t * 3] * 3];
				double radial = (nv[0] * p[0] + nv[1] * p[1]) / R;
				wrong += mat != 2 || fabs(radial - 1) > 1e-6 || fabs(nv[2]) > 1e-6;
			}
		}
		CHECK(wrong == 0, "%s: %zu faces with a wrong material or normal", what, wrong);
		kg_mesh_free(&m);
	}
	kg_err err = { { 0 } };
	kg_mesh *m = NULL;
	const kg_lathe_point neg[] = { { 0, 0, 0 }, { -1, 0, 0 } };
	const kg_lathe_point same[] = { { 1, 0, 0 }, { 1, 0, 0 }, { 1, 1, 0 } };
	CHECK(kg_mesh_lathe(neg, 2, 8, &m, &err) == KG_EINVAL && strstr(err.msg, "point 1"),
	      "negative radius: %s", err.msg);
	CHECK(kg_mesh_lathe(same, 3, 8, &m, &err) == KG_EINVAL && strstr(err.msg, "coincide"),
	      "coinciding points: %s", err.msg);
	CHECK(kg_mesh_lathe(cyl, 1, 8, &m, &err) == KG_EINVAL, "one point accepted");
	CHECK(kg_mesh_lathe(cyl, 4, 2, &m, &err) == KG_EINVAL && strstr(err.msg, "segments"),
	      "two segments: %s", err.msg);
	CHECK(m == NULL, "a mesh came back from a refusal");
}

static void test_tsuba(void)
{
	for (unsigned seg = 16; seg <= 256; seg *= 4) {
		kg_err err = { { 0 } };
		kg_mesh *m = NULL;
		CHECK(kg_mesh_tsuba(seg, &m, &err) == 0, "tsuba: %s", err.msg);
		if (!m)
			return;
		char what[64];
		snprintf(what, sizeof(what), "tsuba, %u segments", seg);
		uint32_t *ids = position_ids(m);
		CHECK(closed_and_consistent(m, ids, what), "%s: not watertight", what);
		free(ids);
		double v = volume(m);
		/* Between the plate alone (pi (1 - 0.12^2) 0.05) and the disc at the rim's height. */
		CHECK(v > M_PI * (1 - 0.0144) * 0.05 && v < M_PI * 0.1, "%s: volume %g", what, v);
		float lo[3], hi[3];
		kg_mesh_bounds(m, lo, hi);
		CHECK(lo[0] >= -1.0f && hi[0] <= 1.0f && lo[1] >= -1.0f && hi[1] <= 1.0f && lo[2] == 0 &&
		      hi[2] > 0.09f && hi[2] <= 0.1f, "%s: bounds %g %g %g - %g %g %g", what, lo[0],
		      lo[1], lo[2], hi[0], hi[1], hi[2]);
		size_t regions[KG_TSUBA_NREGIONS] = { 0 }, disagree = 0;
		for (size_t t = 0; t < m->ntris; t++) {
			int r = m->tri_material[t];
			CHECK(r >= 0 && r < KG_TSUBA_NREGIONS, "%s: material %d", what, r);
			if (r >= 0 && r < KG_TSUBA_NREGIONS)
				regions[r]++;
			double g[3], nsum[3] = { 0, 0, 0 };
			tri_normal(m, t, g);
			for (int j = 0; j < 3; j++)
				for (int k = 0; k < 3; k++)
					nsum[k] += m->normal[m->tri[t * 3 + (size_t)j] * 3 + (size_t)k];
			disagree += g[0] * nsum[0] + g[1] * nsum[1] + g[2] * nsum[2] <= 0;
		}
		for (int r = 0; r < KG_TSUBA_NREGIONS; r++)
			CHECK(regions[r] > 0, "%s: no faces of region %d", what, r);
		CHECK(disagree == 0, "%s: %zu faces whose winding disagrees with their normals", what,
		      disagree);
		size_t bad_n = 0;
		for (size_t i = 0; i < m->nverts; i++) {
			const float *n = &m->normal[i * 3];
			bad_n += fabs(sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]) - 1) > 1e-5;
		}
		CHECK(bad_n == 0, "%s: %zu normals are not unit length", what, bad_n);
		printf("tsuba %3u: %6zu triangles, %6zu vertices, volume %.5f, regions %zu/%zu/%zu/%zu\n",
		       seg, m->ntris, m->nverts, v, regions[0], regions[1], regions[2], regions[3]);
		kg_mesh_free(&m);
	}
	kg_err err = { { 0 } };
	kg_mesh *m = NULL;
	CHECK(kg_mesh_tsuba(8, &m, &err) == KG_EINVAL && !m, "tsuba 8 should be refused");
}

int main(void)
{
	test_icosphere();
	test_plane();
	test_lathe();
	test_tsuba();
	kg_mesh empty = { 0 };
	float lo[3], hi[3];
	kg_mesh_bounds(&empty, lo, hi);
	CHECK(lo[0] == 0 && hi[2] == 0, "bounds of an empty mesh");
	return kg_test_done("mesh");
}
