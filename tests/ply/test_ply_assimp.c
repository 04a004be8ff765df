/* The PLY loader on every PLY file of Debian's assimp-testmodels
 * (/usr/share/assimp/models/PLY, or $KOGEI_ASSIMP_MODELS/PLY), compared with an
 * independent reading by tests/ply/ply_count.py: vertex and face counts (which must
 * also equal the header's), triangles after fan triangulation, degenerate faces, the
 * sum of the triangles' vertex indices, the bounds of the positions, and which
 * attributes are present. A file whose data are shorter than its header declares
 * (pond.0.ply in Debian 12: 69 bytes short, every CR of the binary data stripped by a
 * line-ending conversion) must be refused with a message naming the element.
 * invalid/empty.ply must be refused with a clear message.
 * Skipped (77) without the package or without python3. */
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_mesh.h"
#include "kg_test.h"

typedef struct counts {
	unsigned long long vdecl, vfound, fdecl, ffound, tris, degenerate, indexsum;
	double bounds[6];
	int have_bounds, ok, has_normals, has_colors;
} counts;

static int has_word(const char *line, const char *w)
{
	size_t n = strlen(w);
	for (const char *p = line; (p = strstr(p, w)) != NULL; p += n)
		if ((p == line || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\n' || p[n] == '\0'))
			return 1;
	return 0;
}

static int independent_counts(const char *path, counts *c)
{
	memset(c, 0, sizeof(*c));
	char cmd[8192];
	snprintf(cmd, sizeof(cmd), "/usr/bin/python3 '%s/tests/ply/ply_count.py' '%s'",
	         KG_SOURCE_ROOT, path);
	FILE *fp = popen(cmd, "r");
	if (!fp)
		return -1;
	char line[4096];
	while (fgets(line, sizeof(line), fp)) {
		char name[256];
		unsigned long long d, f;
		if (sscanf(line, "ELEMENT %255s %llu %llu", name, &d, &f) == 3) {
			if (strcmp(name, "vertex") == 0)
				c->vdecl = d, c->vfound = f;
			else if (strcmp(name, "face") == 0)
				c->fdecl = d, c->ffound = f;
		} else if (strncmp(line, "VERTEX_PROPERTIES", 17) == 0) {
			c->has_normals = has_word(line, "nx") && has_word(line, "ny") && has_word(line, "nz");
			c->has_colors = (has_word(line, "red") && has_word(line, "green") &&
			                 has_word(line, "blue")) ||
			                (has_word(line, "diffuse_red") && has_word(line, "diffuse_green") &&
			                 has_word(line, "diffuse_blue"));
		} else if (sscanf(line, "TRIANGLES %llu DEGENERATE %llu", &c->tris, &c->degenerate) == 2) {
		} else if (sscanf(line, "INDEXSUM %llu", &c->indexsum) == 1) {
		} else if (sscanf(line, "BOUNDS %lf %lf %lf %lf %lf %lf", &c->bounds[0], &c->bounds[1],
		                  &c->bounds[2], &c->bounds[3], &c->bounds[4], &c->bounds[5]) == 6) {
			c->have_bounds = 1;
		} else if (strncmp(line, "STATUS ok", 9) == 0)
			c->ok = 1;
	}
	return pclose(fp) == 0 ? 0 : -1;
}

static int by_name(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

static void check_file(const char *path)
{
	counts c;
	if (independent_counts(path, &c) != 0) {
		CHECK(0, "%s: ply_count.py failed", path);
		return;
	}
	kg_err err = { { 0 } };
	kg_mesh *m = NULL;
	int r = kg_ply_load(path, &m, &err);
	if (!c.ok) {
		CHECK(r == KG_EINVAL && m == NULL, "%s: the data are short of the header (%llu of %llu "
		      "vertices), yet the loader returned %d", path, c.vfound, c.vdecl, r);
		CHECK(strstr(err.msg, path) && strstr(err.msg, "element"),
		      "%s: the refusal should name the file and the element: %s", path, err.msg);
		printf("%s: short of its header (%llu of %llu vertices found); refused: %s\n", path,
		       c.vfound, c.vdecl, err.msg);
		return;
	}
	CHECK(r == 0, "%s: %s", path, err.msg);
	if (r != 0)
		return;
	CHECK(c.vfound == c.vdecl && c.ffound == c.fdecl, "%s: python found %llu/%llu vertices "
	      "and %llu/%llu faces", path, c.vfound, c.vdecl, c.ffound, c.fdecl);
	CHECK(m->nverts == c.vdecl, "%s: %zu vertices, the header says %llu", path, m->nverts,
	      c.vdecl);
	CHECK(m->npolygons == c.fdecl, "%s: %zu faces, the header says %llu", path, m->npolygons,
	      c.fdecl);
	CHECK(m->ntris == c.tris, "%s: %zu triangles, python counts %llu", path, m->ntris, c.tris);
	CHECK(m->degenerate == c.degenerate, "%s: %zu degenerate faces, python counts %llu", path,
	      m->degenerate, c.degenerate);
	unsigned long long sum = 0;
	int in_range = 1;
	for (size_t i = 0; i < m->ntris * 3; i++) {
		sum += m->tri[i];
		in_range &= m->tri[i] < m->nverts;
	}
	CHECK(in_range, "%s: a vertex index is out of range", path);
	CHECK(sum == c.indexsum, "%s: triangle index sum %llu, python %llu", path, sum, c.indexsum);
	CHECK(!!m->normal == c.has_normals, "%s: normals %s", path, m->normal ? "loaded" : "missing");
	CHECK(!!m->color == c.has_colors, "%s: colours %s", path, m->color ? "loaded" : "missing");
	for (size_t i = 0; m->color && i < m->nverts * 3; i++)
		if (!(m->color[i] >= 0 && m->color[i] <= 1)) {
			CHECK(0, "%s: colour %zu = %g is off 0..1", path, i, (double)m->color[i]);
			break;
		}
	if (c.have_bounds) {
		float lo[3], hi[3];
		kg_mesh_bounds(m, lo, hi);
		for (int k = 0; k < 3; k++) {
			CHECK_NEAR(lo[k], c.bounds[k], 1e-6 * (1 + fabs(c.bounds[k])), path);
			CHECK_NEAR(hi[k], c.bounds[3 + k], 1e-6 * (1 + fabs(c.bounds[3 + k])), path);
		}
	}
	printf("%s: %zu vertices, %zu faces -> %zu triangles%s%s: as python reads it\n", path,
	       m->nverts, m->npolygons, m->ntris, m->normal ? ", normals" : "",
	       m->color ? ", colours" : "");
	kg_mesh_free(&m);
}

int main(void)
{
	const char *env = getenv("KOGEI_ASSIMP_MODELS");
	const char *root = env && *env ? env : "/usr/share/assimp/models";
	char dir[4096];
	snprintf(dir, sizeof(dir), "%s/PLY", root);
	DIR *d = opendir(dir);
	if (!d) {
		fprintf(stderr, "%s: not found\n", dir);
		kg_test_skip("assimp-testmodels is not installed (no /usr/share/assimp/models/PLY)");
	}
	if (!kg_test_file_exists("/usr/bin/python3")) {
		closedir(d);
		kg_test_skip("/usr/bin/python3 is not installed");
	}
	char *names[256];
	int n = 0;
	struct dirent *de;
	while ((de = readdir(d)) != NULL && n < 256) {
		size_t len = strlen(de->d_name);
		if (len > 4 && strcasecmp(de->d_name + len - 4, ".ply") == 0)
			names[n++] = kg_path_join(dir, de->d_name);
	}
	closedir(d);
	qsort(names, (size_t)n, sizeof(names[0]), by_name);
	CHECK(n > 0, "no .ply files in %s", dir);
	for (int i = 0; i < n; i++) {
		check_file(names[i]);
		free(names[i]);
	}

	char empty[4096];
	snprintf(empty, sizeof(empty), "%s/invalid/empty.ply", root);
	if (kg_test_file_exists(empty)) {
		kg_err err = { { 0 } };
		kg_mesh *m = NULL;
		int r = kg_ply_load(empty, &m, &err);
		CHECK(r == KG_EINVAL && m == NULL, "%s: returned %d", empty, r);
		CHECK(strstr(err.msg, empty) && strstr(err.msg, "empty") && strstr(err.msg, "'ply'"),
		      "%s: message should say the file is empty and 'ply' was expected: %s", empty,
		      err.msg);
		printf("%s: refused: %s\n", empty, err.msg);
	}
	return kg_test_done("ply-assimp");
}
