/* Triangle meshes for the renderer, and the PLY loader (render/ply.c).
 *
 * PLY (Turk 1994; the format of scanners and of Debian's assimp-testmodels): ASCII,
 * binary_little_endian and binary_big_endian; element `vertex` with x y z and, when
 * present, nx ny nz, red green blue (uchar 0..255 or float 0..1) and a per-vertex
 * material id (an int property named `material` or `material_index`); element `face`
 * with a list property `vertex_indices` (or `vertex_index`) of any list/count types,
 * polygons fan-triangulated, and an optional per-face `material`/`material_index`.
 * Other elements and properties are skipped by their declared types. */
#ifndef KG_MESH_H
#define KG_MESH_H

#include <stddef.h>
#include <stdint.h>

#include "kg_core.h"

typedef struct kg_mesh {
	size_t nverts, ntris;
	float *pos;          /* nverts x 3 */
	float *normal;       /* nverts x 3, or NULL when the file has none */
	float *color;        /* nverts x 3 on 0..1, or NULL */
	int32_t *vert_material; /* nverts, or NULL */
	uint32_t *tri;       /* ntris x 3 vertex indices, every index < nverts */
	int32_t *tri_material; /* ntris (the face's id, copied to each of its triangles),
	                          or NULL */
	size_t npolygons;    /* faces in the file (before triangulation) */
	size_t degenerate;   /* faces with fewer than 3 vertices, skipped */
} kg_mesh;

/* Load a PLY file. Errors (KG_EINVAL) name the file, the line (header, ASCII) or byte
 * offset (binary), the element and property, and what was expected: bad magic,
 * unknown format or type, truncated data, a vertex index out of range, counts that
 * do not fit in memory. */
int kg_ply_load(const char *path, kg_mesh **out, kg_err *err);
/* The same from memory (fuzzing, tests); name is used in messages. */
int kg_ply_load_mem(const void *data, size_t len, const char *name, kg_mesh **out,
                    kg_err *err);
void kg_mesh_free(kg_mesh **m);

/* Write a mesh as binary little-endian PLY (positions, normals and colours when
 * present, per-face material ids when present); atomic. */
int kg_ply_write(const kg_mesh *m, const char *path, kg_err *err);

/* Axis-aligned bounds of the positions. */
void kg_mesh_bounds(const kg_mesh *m, float lo[3], float hi[3]);

#endif
