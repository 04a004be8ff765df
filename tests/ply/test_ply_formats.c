/* The PLY loader on files written by an independent writer (ply_writer.h):
 * - ASCII, binary little- and big-endian versions of the same mesh load identically;
 * - every scalar type and alias for the positions, every count and item type for the
 *   face lists, with the values expected;
 * - polygons are fan-triangulated, faces of 0..2 vertices counted as degenerate and
 *   skipped, per-face material ids copied to each triangle of the face;
 * - normals, uchar and float colours (clamped to 0..1), per-vertex material ids;
 * - extra properties (scalars and lists) and elements before, between and after the
 *   vertices are skipped, comments and obj_info ignored, \r\n header lines accepted;
 * - ASCII numbers read to the float that strtod gives for the same text;
 * - kg_ply_write / kg_ply_write_format round-trip a mesh exactly in all three
 *   encodings, and leave no temporary file behind. */
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "kg_mesh.h"
#include "kg_test.h"
#include "ply_writer.h"

static const char *const encoding_name[] = { "ascii", "binary_little_endian",
	                                         "binary_big_endian" };

static kg_mesh *load(const tw_buf *b, const char *what)
{
	kg_err err = { { 0 } };
	kg_mesh *m = NULL;
	int r = kg_ply_load_mem(b->p, b->len, what, &m, &err);
	CHECK(r == 0 && m, "%s: %s", what, err.msg);
	return r == 0 ? m : NULL;
}

/* A small polygon soup with integer coordinates (exact in every type): a cube of side
 * 100 whose faces are quads, one pentagon, one triangle and three degenerate faces. */
static const double cube_pos[] = {
	-50, -50, -50, 50, -50, -50, 50, 50, -50, -50, 50, -50,
	-50, -50, 50,  50, -50, 50,  50, 50, 50,  -50, 50, 50,
	0,   0,   100,
};
static const unsigned cube_len[] = { 4, 4, 4, 4, 4, 5, 0, 1, 2, 3 };
static const unsigned cube_idx[] = {
	0, 3, 2, 1, /* bottom */ 0, 1, 5, 4, /* front */ 1, 2, 6, 5, /* right */
	2, 3, 7, 6, /* back */   3, 0, 4, 7, /* left */  4, 5, 8, 6, 7, /* roof pentagon */
	8, /* one vertex */      2, 3, /* an edge */     4, 5, 8, /* a triangle */
};
static const int cube_fmat[] = { 0, 1, 2, 3, 4, 5, 6, 7, 8, 9 };

static const tw_mesh cube = {
	.nverts = 9, .nfaces = 10, .pos = cube_pos, .face_len = cube_len, .face_idx = cube_idx,
	.face_material = cube_fmat,
};

/* The loaded mesh against the soup: positions, fan triangles and their materials. */
static void check_soup(const kg_mesh *m, const tw_mesh *s, const char *what)
{
	if (!m)
		return;
	CHECK(m->nverts == s->nverts, "%s: %zu vertices", what, m->nverts);
	CHECK(m->npolygons == s->nfaces, "%s: %zu faces", what, m->npolygons);
	for (size_t i = 0; i < s->nverts * 3 && m->nverts == s->nverts; i++)
		if (m->pos[i] != (float)s->pos[i]) {
			CHECK(0, "%s: position %zu is %g, wrote %g", what, i, (double)m->pos[i], s->pos[i]);
			break;
		}
	size_t t = 0, at = 0, degenerate = 0;
	for (size_t f = 0; f < s->nfaces; f++) {
		const unsigned *v = &s->face_idx[at];
		degenerate += s->face_len[f] < 3;
		for (unsigned k = 2; k < s->face_len[f]; k++, t++) {
			if (t >= m->ntris)
				continue;
			const uint32_t *got = &m->tri[t * 3];
			CHECK(got[0] == v[0] && got[1] == v[k - 1] && got[2] == v[k],
			      "%s: triangle %zu is %u %u %u, expected the fan %u %u %u", what, t, got[0],
			      got[1], got[2], v[0], v[k - 1], v[k]);
			if (s->face_material)
				CHECK(m->tri_material && m->tri_material[t] == s->face_material[f],
				      "%s: triangle %zu material %d, face %zu has %d", what, t,
				      m->tri_material ? m->tri_material[t] : -1, f, s->face_material[f]);
		}
		at += s->face_len[f];
	}
	CHECK(m->ntris == t, "%s: %zu triangles, expected %zu", what, m->ntris, t);
	CHECK(m->degenerate == degenerate, "%s: %zu degenerate faces, expected %zu", what,
	      m->degenerate, degenerate);
	CHECK(!s->face_material == !m->tri_material, "%s: face materials %s", what,
	      m->tri_material ? "unexpected" : "missing");
}

static void test_types(void)
{
	static const char *const pos_types[] = { "char",  "int8",   "uchar", "uint8", "short",
		                                     "int16", "ushort", "uint16", "int",  "int32",
		                                     "uint",  "uint32", "float", "float32",
		                                     "double", "float64" };
	static const char *const count_types[] = { "uchar", "char",  "ushort", "short",
		                                       "uint",  "int",   "uint8",  "int32" };
	static const char *const index_types[] = { "int",   "uint",   "int32", "uint32", "short",
		                                       "ushort", "char", "uchar", "float", "double" };
	tw_buf b = { 0 };
	int files = 0;
	for (int e = 0; e < 3; e++)
		for (size_t p = 0; p < sizeof(pos_types) / sizeof(pos_types[0]); p++) {
			/* Unsigned position types cannot hold the cube's negative corners. */
			double shifted[sizeof(cube_pos) / sizeof(cube_pos[0])];
			int is_unsigned = pos_types[p][0] == 'u';
			for (size_t i = 0; i < sizeof(shifted) / sizeof(shifted[0]); i++)
				shifted[i] = cube_pos[i] + (is_unsigned ? 50 : 0);
			tw_mesh s = cube;
			s.pos = shifted;
			size_t c = p % (sizeof(count_types) / sizeof(count_types[0]));
			size_t x = p % (sizeof(index_types) / sizeof(index_types[0]));
			tw_opts o = { .enc = (enum tw_encoding)e, .pos_type = pos_types[p],
				          .count_type = count_types[c], .index_type = index_types[x],
				          .extras = (int)(p & 1), .crlf = p == 3 };
			tw_write(&b, &s, &o);
			char what[256];
			snprintf(what, sizeof(what), "%s, x y z %s, list %s %s%s%s", encoding_name[e],
			         o.pos_type, o.count_type, o.index_type, o.extras ? ", extras" : "",
			         o.crlf ? ", crlf header" : "");
			kg_mesh *m = load(&b, what);
			check_soup(m, &s, what);
			kg_mesh_free(&m);
			files++;
		}
	free(b.p);
	printf("types: %d files (3 encodings x 16 position type names, all list types) ok\n",
	       files);
}

/* Three encodings of a generated mesh with normals, colours and materials give the
 * same arrays, bit for bit. */
static void test_three_encodings(void)
{
	kg_err err = { { 0 } };
	kg_mesh *sphere = NULL;
	CHECK(kg_mesh_icosphere(2, &sphere, &err) == 0, "icosphere: %s", err.msg);
	if (!sphere)
		return;
	size_t nv = sphere->nverts, nt = sphere->ntris;
	double *pos = malloc(nv * 3 * sizeof(double)), *nrm = malloc(nv * 3 * sizeof(double));
	unsigned char *rgb = malloc(nv * 3);
	int *vmat = malloc(nv * sizeof(int)), *fmat = malloc(nt * sizeof(int));
	unsigned *len = malloc(nt * sizeof(unsigned)), *idx = malloc(nt * 3 * sizeof(unsigned));
	for (size_t i = 0; i < nv * 3; i++) {
		pos[i] = sphere->pos[i] * 3.25 + 1e-3 * (double)(i % 7);
		nrm[i] = sphere->normal[i];
		rgb[i] = (unsigned char)(i * 37 % 256);
	}
	for (size_t i = 0; i < nv; i++)
		vmat[i] = (int)(i % 5) - 2;
	for (size_t t = 0; t < nt; t++) {
		len[t] = 3;
		fmat[t] = (int)(t % 8);
		for (int k = 0; k < 3; k++)
			idx[t * 3 + (size_t)k] = sphere->tri[t * 3 + (size_t)k];
	}
	tw_mesh s = { .nverts = nv, .nfaces = nt, .pos = pos, .normal = nrm, .rgb = rgb,
		          .vert_material = vmat, .face_len = len, .face_idx = idx,
		          .face_material = fmat };
	kg_mesh *m[3] = { NULL, NULL, NULL };
	tw_buf b = { 0 };
	for (int e = 0; e < 3; e++) {
		tw_opts o = { .enc = (enum tw_encoding)e, .pos_type = "float", .count_type = "uchar",
			          .index_type = "int", .extras = 1 };
		tw_write(&b, &s, &o);
		m[e] = load(&b, encoding_name[e]);
	}
	free(b.p);
	if (m[0] && m[1] && m[2]) {
		for (int e = 1; e < 3; e++) {
			const char *w = encoding_name[e];
			CHECK(m[e]->nverts == nv && m[e]->ntris == nt, "%s: counts", w);
			CHECK(m[e]->normal && m[e]->color && m[e]->vert_material && m[e]->tri_material,
			      "%s: attributes missing", w);
			if (m[e]->nverts != nv || m[e]->ntris != nt || !m[e]->normal || !m[e]->color ||
			    !m[e]->vert_material || !m[e]->tri_material)
				continue;
			CHECK(memcmp(m[e]->pos, m[0]->pos, nv * 3 * sizeof(float)) == 0,
			      "%s: positions differ from ASCII", w);
			CHECK(memcmp(m[e]->normal, m[0]->normal, nv * 3 * sizeof(float)) == 0,
			      "%s: normals differ from ASCII", w);
			CHECK(memcmp(m[e]->color, m[0]->color, nv * 3 * sizeof(float)) == 0,
			      "%s: colours differ from ASCII", w);
			CHECK(memcmp(m[e]->vert_material, m[0]->vert_material, nv * sizeof(int32_t)) == 0,
			      "%s: vertex materials differ from ASCII", w);
			CHECK(memcmp(m[e]->tri, m[0]->tri, nt * 3 * sizeof(uint32_t)) == 0,
			      "%s: triangles differ from ASCII", w);
			CHECK(memcmp(m[e]->tri_material, m[0]->tri_material, nt * sizeof(int32_t)) == 0,
			      "%s: face materials differ from ASCII", w);
		}
		/* And against what was written. */
		const kg_mesh *a = m[0];
		int same = 1;
		for (size_t i = 0; i < nv * 3; i++) {
			same &= a->pos[i] == (float)pos[i] && a->normal[i] == (float)nrm[i];
			same &= a->color[i] == (float)(rgb[i] / 255.0);
		}
		for (size_t i = 0; i < nv; i++)
			same &= a->vert_material[i] == vmat[i];
		for (size_t t = 0; t < nt; t++)
			same &= a->tri_material[t] == fmat[t];
		CHECK(same, "ascii: values differ from those written (uchar colours are /255)");
		printf("three encodings: %zu vertices, %zu triangles with normals, colours and "
		       "materials, identical\n", nv, nt);
	}
	for (int e = 0; e < 3; e++)
		kg_mesh_free(&m[e]);
	kg_mesh_free(&sphere);
	free(pos);
	free(nrm);
	free(rgb);
	free(vmat);
	free(fmat);
	free(len);
	free(idx);
}

/* Float colours (clamped to 0..1), a Blender 2.4x header line without `comment`,
 * blank lines, trailing blanks, a final line without its newline. */
static void test_ascii_details(void)
{
	static const char text[] =
		"ply\nformat ascii 1.0   \nCreated by Blender3D 247 - www.blender.org\n"
		"element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
		"property float red\nproperty float green\nproperty float blue\n"
		"element face 1\nproperty list uchar int vertex_indices\nend_header\n"
		"0 0 0 0.25 0.5 1\n\n1 0 0   1.5 -0.25 0.5  \n0 1 0 1 1 1\n+3 0 00000000000001 2";
	kg_err err = { { 0 } };
	kg_mesh *m = NULL;
	int r = kg_ply_load_mem(text, strlen(text), "details.ply", &m, &err);
	CHECK(r == 0, "details.ply: %s", err.msg);
	if (r == 0) {
		CHECK(m->nverts == 3 && m->ntris == 1 && m->color && !m->normal, "details.ply: shape");
		CHECK(m->color[0] == 0.25f && m->color[1] == 0.5f && m->color[2] == 1.0f,
		      "details.ply: float colours are taken as they are");
		CHECK(m->color[3] == 1.0f && m->color[4] == 0.0f && m->color[5] == 0.5f,
		      "details.ply: float colours out of 0..1 are clamped");
		CHECK(m->pos[6] == 0 && m->pos[7] == 1, "details.ply: third vertex");
		CHECK(m->tri[0] == 0 && m->tri[1] == 1 && m->tri[2] == 2,
		      "details.ply: '+3 0 00000000000001 2' is the triangle 0 1 2");
	}
	kg_mesh_free(&m);
}

/* ASCII numbers against strtod: edge-case spellings and random values in the
 * notations writers use. */
static void test_numbers(void)
{
	static const char *const tokens[] = {
		"0", "-0", "+1", "1.", ".5", "-.5", "1e3", "1E-3", "-2.5e+2", "0.1", "0.3",
		"3.4028234e38", "1.17549435e-38", "1e-45", "123456789012345678901234567890",
		"0.000000000000000000000000000001234", "1.00000000000000000000000000001",
		"16777217", "0.1000000000000000055511151231257827", "7e22", "9007199254740993",
		"2.2250738585072014e-308", "4.9e-324", "1e-400", "000123.4500",
	};
	size_t n = sizeof(tokens) / sizeof(tokens[0]), nrand = 3000;
	tw_buf b = { 0 };
	tw_printf(&b, "ply\nformat ascii 1.0\nelement vertex %zu\nproperty double x\n"
	          "property float y\nproperty float z\nend_header\n", n + nrand);
	char (*text)[64] = malloc((n + nrand) * sizeof(*text));
	uint64_t st = 88172645463325252ull;
	for (size_t i = 0; i < n + nrand; i++) {
		if (i < n)
			snprintf(text[i], sizeof(text[i]), "%s", tokens[i]);
		else {
			st ^= st << 13, st ^= st >> 7, st ^= st << 17;
			double mant = (double)(st >> 11) / 9007199254740992.0;
			int ex = (int)(st % 61) - 30;
			double v = (st & 1 ? -1 : 1) * mant * pow(10, ex);
			static const char *const fmts[] = { "%.17g", "%.9g", "%.6f", "%e", "%.3e", "%g" };
			snprintf(text[i], sizeof(text[i]), fmts[i % 6], v);
		}
		tw_printf(&b, "%s 1 %s\n", text[i], text[i]);
	}
	kg_mesh *m = load(&b, "numbers.ply");
	if (m) {
		int bad = 0;
		for (size_t i = 0; i < n + nrand && bad < 5; i++) {
			float want = (float)strtod(text[i], NULL);
			if (m->pos[i * 3] != want || m->pos[i * 3 + 2] != want) {
				CHECK(0, "'%s' read as %.9g / %.9g, strtod gives %.9g", text[i],
				      (double)m->pos[i * 3], (double)m->pos[i * 3 + 2], (double)want);
				bad++;
			}
		}
		printf("numbers: %zu ASCII spellings read as strtod reads them\n", n + nrand);
	}
	kg_mesh_free(&m);
	free(text);
	free(b.p);
}

static int tmp_files_in(const char *dir)
{
	DIR *d = opendir(dir);
	int n = 0;
	struct dirent *de;
	while (d && (de = readdir(d)) != NULL)
		n += strstr(de->d_name, ".tmp") != NULL;
	if (d)
		closedir(d);
	return n;
}

static void same_mesh(const kg_mesh *a, const kg_mesh *b, const char *what)
{
	CHECK(a->nverts == b->nverts && a->ntris == b->ntris, "%s: counts differ", what);
	if (a->nverts != b->nverts || a->ntris != b->ntris)
		return;
	CHECK(memcmp(a->pos, b->pos, a->nverts * 3 * sizeof(float)) == 0, "%s: positions", what);
	CHECK(memcmp(a->tri, b->tri, a->ntris * 3 * sizeof(uint32_t)) == 0, "%s: triangles", what);
	CHECK(!a->normal == !b->normal &&
	      (!a->normal || memcmp(a->normal, b->normal, a->nverts * 3 * sizeof(float)) == 0),
	      "%s: normals", what);
	CHECK(!a->color == !b->color &&
	      (!a->color || memcmp(a->color, b->color, a->nverts * 3 * sizeof(float)) == 0),
	      "%s: colours", what);
	CHECK(!a->tri_material == !b->tri_material &&
	      (!a->tri_material ||
	       memcmp(a->tri_material, b->tri_material, a->ntris * sizeof(int32_t)) == 0),
	      "%s: face materials", what);
	CHECK(!a->vert_material == !b->vert_material &&
	      (!a->vert_material ||
	       memcmp(a->vert_material, b->vert_material, a->nverts * sizeof(int32_t)) == 0),
	      "%s: vertex materials", what);
}

static void test_writer(void)
{
	char dir[] = "/tmp/kg-ply-XXXXXX";
	if (!mkdtemp(dir)) {
		CHECK(0, "mkdtemp failed");
		return;
	}
	kg_err err = { { 0 } };
	kg_mesh *src = NULL;
	CHECK(kg_mesh_tsuba(32, &src, &err) == 0, "tsuba: %s", err.msg);
	if (!src)
		return;
	src->color = malloc(src->nverts * 3 * sizeof(float));
	src->vert_material = malloc(src->nverts * sizeof(int32_t));
	for (size_t i = 0; i < src->nverts * 3; i++)
		src->color[i] = (float)(i % 11) / 10.0f;
	for (size_t i = 0; i < src->nverts; i++)
		src->vert_material[i] = (int32_t)(i % 3);
	static const kg_ply_format formats[] = { KG_PLY_ASCII, KG_PLY_BINARY_LE, KG_PLY_BINARY_BE };
	for (int f = 0; f < 4; f++) {
		char *path = kg_path_join(dir, "out.ply");
		int r = f < 3 ? kg_ply_write_format(src, path, formats[f], &err)
		              : kg_ply_write(src, path, &err);
		CHECK(r == 0, "write %d: %s", f, err.msg);
		kg_mesh *back = NULL;
		r = kg_ply_load(path, &back, &err);
		CHECK(r == 0, "read back %d: %s", f, err.msg);
		if (back)
			same_mesh(src, back, f < 3 ? encoding_name[f] : "kg_ply_write");
		kg_mesh_free(&back);
		unlink(path);
		free(path);
	}
	CHECK(tmp_files_in(dir) == 0, "a temporary file was left in %s", dir);
	char *bad = kg_path_join(dir, "no/such/dir/out.ply");
	CHECK(kg_ply_write(src, bad, &err) == KG_EIO && strstr(err.msg, "no/such/dir"),
	      "writing into a missing directory: %s", err.msg);
	free(bad);
	rmdir(dir);
	printf("writer: the tsuba round-trips exactly in ascii, binary LE and BE\n");
	kg_mesh_free(&src);
}

int main(void)
{
	test_types();
	test_three_encodings();
	test_ascii_details();
	test_numbers();
	test_writer();
	return kg_test_done("ply-formats");
}
