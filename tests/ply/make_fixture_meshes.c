/* Writes the meshes of fixtures/meshes/ from the generators in render/mesh.c, or
 * checks that the checked-in files still match them (the `ply-fixtures` test):
 *
 *   make_fixture_meshes DIR            write DIR/tsuba.ply
 *   make_fixture_meshes --check DIR    compare DIR/tsuba.ply with a fresh tsuba
 *
 * The comparison allows 1e-6 in positions and 1e-5 in normals (libm's sin and cos
 * may differ in the last bit between machines); triangles and materials must be
 * identical. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_mesh.h"

/* The demo object at the resolution of the fixture: 4,608 triangles. */
#define FIXTURE_TSUBA_SEGMENTS 64

static int compare(const kg_mesh *a, const kg_mesh *b, const char *path)
{
	if (a->nverts != b->nverts || a->ntris != b->ntris || !b->normal || !b->tri_material) {
		fprintf(stderr, "%s: %zu vertices, %zu triangles%s; the generator makes %zu and %zu "
		        "with normals and materials\n", path, b->nverts, b->ntris,
		        b->normal && b->tri_material ? "" : ", attributes missing", a->nverts, a->ntris);
		return 1;
	}
	double dp = 0, dn = 0;
	for (size_t i = 0; i < a->nverts * 3; i++) {
		dp = fmax(dp, fabs((double)a->pos[i] - b->pos[i]));
		dn = fmax(dn, fabs((double)a->normal[i] - b->normal[i]));
	}
	int same_tri = memcmp(a->tri, b->tri, a->ntris * 3 * sizeof(uint32_t)) == 0;
	int same_mat = memcmp(a->tri_material, b->tri_material, a->ntris * sizeof(int32_t)) == 0;
	printf("%s: %zu triangles; largest differences from the generator: position %.2g, "
	       "normal %.2g; triangles %s, materials %s\n", path, b->ntris, dp, dn,
	       same_tri ? "identical" : "DIFFER", same_mat ? "identical" : "DIFFER");
	return dp <= 1e-6 && dn <= 1e-5 && same_tri && same_mat ? 0 : 1;
}

int main(int argc, char **argv)
{
	int check = argc == 3 && strcmp(argv[1], "--check") == 0;
	if (!(argc == 2 && argv[1][0] != '-') && !check) {
		fprintf(stderr, "usage: %s [--check] DIR\n", argv[0]);
		return 2;
	}
	kg_err err = { { 0 } };
	kg_mesh *tsuba = NULL;
	if (kg_mesh_tsuba(FIXTURE_TSUBA_SEGMENTS, &tsuba, &err) != 0) {
		fprintf(stderr, "%s\n", err.msg);
		return 1;
	}
	char *path = kg_path_join(argv[argc - 1], "tsuba.ply");
	int status = 0;
	if (check) {
		kg_mesh *file = NULL;
		if (kg_ply_load(path, &file, &err) != 0) {
			fprintf(stderr, "%s\n", err.msg);
			status = 1;
		} else
			status = compare(tsuba, file, path);
		kg_mesh_free(&file);
	} else if (kg_ply_write(tsuba, path, &err) != 0) {
		fprintf(stderr, "%s\n", err.msg);
		status = 1;
	} else
		printf("%s: %zu vertices, %zu triangles\n", path, tsuba->nverts, tsuba->ntris);
	free(path);
	kg_mesh_free(&tsuba);
	return status;
}
