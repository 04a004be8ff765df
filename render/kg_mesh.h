/* Triangle meshes for the renderer: the PLY loader and writer (render/ply.c), mesh
 * utilities and generators (render/mesh.c). The user's view is docs/ply.md.
 *
 * PLY (Turk 1994; the format of scanners and of Debian's assimp-testmodels): ASCII,
 * binary_little_endian and binary_big_endian, every scalar type (char uchar short
 * ushort int uint float double and the int8..float64 names); element `vertex` with
 * x y z and, when all three are present, nx ny nz and red green blue (or
 * diffuse_red ...; integer types divided by their full scale, 255 for uchar, floats
 * taken as they are, then clamped to 0..1), and a per-vertex material id (an integer property named
 * `material` or `material_index`); element `face` with a list property
 * `vertex_indices` (or `vertex_index`) of any count/item types, polygons
 * fan-triangulated, and an optional per-face `material`/`material_index`. Other
 * elements and properties are skipped by their declared types; comments and
 * obj_info are ignored. ASCII data are one element per line; a list property at the
 * end of a line may be left out (read as empty, as assimp does). Positions, normals
 * and colours must be finite; vertex indices must be below the vertex count. */
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

/* Write a mesh as binary little-endian PLY (positions, normals and colours when
 * present, per-face material ids when present); atomic. */
int kg_ply_write(const kg_mesh *m, const char *path, kg_err *err);

typedef enum kg_ply_format {
	KG_PLY_ASCII,
	KG_PLY_BINARY_LE,
	KG_PLY_BINARY_BE,
} kg_ply_format;

/* The same in any of the three encodings (ASCII floats with 9 significant digits, so
 * they read back to the same float); ASCII may go to standard output ("-"). */
int kg_ply_write_format(const kg_mesh *m, const char *path, kg_ply_format format,
                        kg_err *err);

/* ---- mesh utilities and generators (render/mesh.c) ----
 * Generated meshes are in a right-handed frame with +z up; their triangles wind
 * counter-clockwise seen from outside, so the geometric normal (b-a)x(c-a) points
 * out, and their vertex normals are unit length. */

enum {
	KG_MESH_NORMALS = 1,
	KG_MESH_COLORS = 2,
	KG_MESH_VERT_MATERIAL = 4,
	KG_MESH_TRI_MATERIAL = 8,
};

/* An uninitialised mesh of nverts vertices and ntris triangles with the attributes
 * named by flags (KG_MESH_*); positions and triangles always. */
int kg_mesh_new(size_t nverts, size_t ntris, unsigned flags, kg_mesh **out, kg_err *err);

void kg_mesh_free(kg_mesh **m);

/* Axis-aligned bounds of the positions (both 0 for an empty mesh). */
void kg_mesh_bounds(const kg_mesh *m, float lo[3], float hi[3]);

/* Vertex normals as the mean of the unit normals of the triangles around each
 * vertex, weighted by the triangles' angles there (allocated when the mesh has none). Vertices shared only by duplicate
 * positions are not merged, so creases stay sharp where the mesh splits them. */
int kg_mesh_compute_normals(kg_mesh *m, kg_err *err);

/* A unit sphere: an icosahedron subdivided `level` times (0..10), 20*4^level
 * triangles, 10*4^level+2 shared vertices at radius 1, normals = positions. Level 8
 * (1,310,720 triangles) is the benchmark mesh. */
int kg_mesh_icosphere(unsigned level, kg_mesh **out, kg_err *err);

/* A square ground plane of side 2*half_size in z = 0, normal +z, two triangles. */
int kg_mesh_plane(float half_size, kg_mesh **out, kg_err *err);
/* The same plane as a grid of segments x segments squares (1..4096), two triangles
 * each, so a projected label map can give each its own material. */
int kg_mesh_plane_grid(float half_size, unsigned segments, kg_mesh **out, kg_err *err);

/* A surface of revolution about the z axis. The profile runs through points (r >= 0,
 * z) with the solid on its left, i.e. counter-clockwise in the (r, z) half-plane for
 * a closed outline, so normals point to its right; the segment from point i to i+1
 * gets point i's material (the last point's material is unused). Where the material
 * changes or the profile turns by more than 30 degrees the vertices are split, so
 * the crease stays sharp; points with r = 0 are single pole vertices. */
typedef struct kg_lathe_point {
	float r, z;
	int32_t material;
} kg_lathe_point;

int kg_mesh_lathe(const kg_lathe_point *profile, size_t npoints, unsigned segments,
                  kg_mesh **out, kg_err *err);

/* The demo object: a sword guard (tsuba) of radius 1 lying on z = 0, 0.1 thick at
 * its rounded rim, with a central hole, a raised seppa-dai around the hole and an
 * eight-petal swirling relief on its upper face, turned with `segments` steps around
 * (16..4096; 64 gives 4,608 triangles, 256 gives 43,008). Per-face material ids
 * name its regions. */
enum kg_tsuba_region {
	KG_TSUBA_PLATE,  /* the flat ground of both faces */
	KG_TSUBA_RIM,    /* the rounded rim (mimi) and the outer edge */
	KG_TSUBA_RELIEF, /* the petal relief */
	KG_TSUBA_SEPPA,  /* the raised area around the hole and the hole's wall */
	KG_TSUBA_NREGIONS
};

int kg_mesh_tsuba(unsigned segments, kg_mesh **out, kg_err *err);

#endif
