/* Fuzz target for the PLY loader (render/ply.c).
 *
 * Run by the shared fuzz driver (fuzz_driver.h) with PLY words (keywords, type names,
 * formats, huge and negative counts, nan) among its mutations; an input the loader
 * refuses counts as refused.
 *
 * Invariants checked on every input: a refusal is KG_EINVAL with a terminated,
 * non-empty message that starts with the file's name, and no mesh; a success gives
 * triangles whose indices are all below the vertex count, finite positions, normals
 * and colours, consistent counts, and everything is freed (the sanitizers see leaks
 * and over-reads: the input is copied into a buffer of exactly its size). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_driver.h"
#include "kg_mesh.h"

static void require(int cond, const char *what)
{
	kg_fuzz_require("fuzz-ply", cond, what);
}

static void check_mesh(const kg_mesh *m)
{
	require(m->pos && m->tri, "positions and triangles are allocated");
	require(m->degenerate <= m->npolygons, "degenerate faces are among the faces");
	require(m->ntris == 0 || m->npolygons > 0, "triangles come from faces");
	for (size_t i = 0; i < m->ntris * 3; i++)
		require(m->tri[i] < m->nverts, "every vertex index is below the vertex count");
	for (size_t i = 0; i < m->nverts * 3; i++) {
		require(isfinite(m->pos[i]), "positions are finite");
		require(!m->normal || isfinite(m->normal[i]), "normals are finite");
		require(!m->color || isfinite(m->color[i]), "colours are finite");
	}
	float lo[3], hi[3];
	kg_mesh_bounds(m, lo, hi);
	for (int k = 0; k < 3; k++)
		require(lo[k] <= hi[k], "bounds are ordered");
}

static int fuzz_ply_run(const uint8_t *data, size_t size)
{
	/* An exact-size copy, so reading one byte past the end is an ASan error. */
	uint8_t *copy = malloc(size ? size : 1);
	if (!copy)
		return 1;
	memcpy(copy, data, size);
	kg_err err = { { 0 } };
	kg_mesh *m = NULL;
	int r = kg_ply_load_mem(copy, size, "fuzz.ply", &m, &err);
	if (r != 0) {
		require(r == KG_EINVAL || r == KG_ENOMEM, "a refusal is KG_EINVAL (or KG_ENOMEM)");
		require(m == NULL, "no mesh on failure");
		require(memchr(err.msg, '\0', sizeof(err.msg)) != NULL, "message is terminated");
		require(strncmp(err.msg, "fuzz.ply", 8) == 0, "the message names the file");
	} else {
		require(m != NULL, "a mesh on success");
		check_mesh(m);
		kg_mesh_free(&m);
	}
	free(copy);
	return r != 0;
}

static const char *const words[] = {
	"\n", "\r\n", " ", "\t", "0", "-1", "1", "3", "255", "65536", "4294967295",
	"18446744073709551615", "99999999999999999999", "nan", "-inf", "1e39", "1e-45", "0x10",
	"1.5", ".", "e", "ply\n", "format ascii 1.0\n", "format binary_little_endian 1.0\n",
	"format binary_big_endian 1.0\n", "element vertex ", "element face ", "element edge 1\n",
	"property float x\n", "property double z\n", "property uchar red\n",
	"property list uchar int vertex_indices\n", "property list uint8 uint32 vertex_index\n",
	"property list int int tags\n", "property int material\n", "property float nx\n",
	"comment x\n", "obj_info y\n", "end_header\n", "char", "uint16", "float64", "list",
};

static const kg_fuzz_target fuzz_ply = {
	.name = "fuzz-ply",
	.run = fuzz_ply_run,
	.words = words,
	.nwords = sizeof(words) / sizeof(words[0]),
	.structural = "\n\r\t -.e0139\xff",
	.mutations = 3000,
};

KG_FUZZ_TARGET(fuzz_ply)
