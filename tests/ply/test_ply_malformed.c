/* Malformed PLY files: each is refused with KG_EINVAL, no mesh, and a message that
 * names the file, says where (header line, data line or byte offset) and what is
 * wrong. Every truncation of a valid binary file is refused as well, and a header
 * that declares 4294967295 faces over a few bytes of data allocates nothing (the
 * sanitizer build would see a huge allocation; the check is on the file size). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_mesh.h"
#include "kg_test.h"
#include "ply_writer.h"

#define HDR3 "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n" \
             "property float z\n"
#define FACE "element face 1\nproperty list uchar int vertex_indices\n"
#define VERTS "0 0 0\n1 0 0\n0 1 0\n"

typedef struct bad_case {
	const char *name;
	const char *text;
	size_t len; /* 0: strlen(text) */
	const char *expect[3]; /* substrings the message must hold */
} bad_case;

static void expect_refusal(const char *name, const void *data, size_t len,
                           const char *const expect[3])
{
	kg_err err = { { 0 } };
	kg_mesh *m = NULL;
	int r = kg_ply_load_mem(data, len, name, &m, &err);
	CHECK(r == KG_EINVAL && m == NULL, "%s: returned %d (expected KG_EINVAL)", name, r);
	CHECK(strncmp(err.msg, name, strlen(name)) == 0, "%s: message does not start with the "
	      "file name: %s", name, err.msg);
	for (int k = 0; k < 3 && expect[k]; k++)
		CHECK(strstr(err.msg, expect[k]) != NULL, "%s: message lacks '%s': %s", name,
		      expect[k], err.msg);
	printf("%-26s %s\n", name, err.msg);
	kg_mesh_free(&m);
}

static const bad_case cases[] = {
	{ "bad-magic.ply", "plx\nformat ascii 1.0\n", 0, { "line 1", "expected 'ply'", "plx" } },
	{ "binary-junk.ply", "\x89PNG\r\n\x1a\n", 8, { "line 1", "expected 'ply'", "\\x89PNG" } },
	{ "no-end-header.ply", HDR3 FACE, 0, { "no end_header", "line 8" } },
	{ "unknown-format.ply", "ply\nformat binary 1.0\nend_header\n", 0,
	  { "line 2", "unknown format 'binary'" } },
	{ "format-version.ply", "ply\nformat ascii 2.0\nend_header\n", 0,
	  { "line 2", "version '2.0'" } },
	{ "no-format.ply", "ply\nelement vertex 0\nend_header\n", 0, { "line 2", "format" } },
	{ "wrong-type.ply",
	  "ply\nformat ascii 1.0\nelement vertex 1\nproperty flaot x\nend_header\n0\n", 0,
	  { "line 4", "unknown type 'flaot'", "expected char" } },
	{ "wrong-list-type.ply",
	  HDR3 "element face 1\nproperty list uchar integer vertex_indices\nend_header\n", 0,
	  { "line 8", "list item", "'integer'" } },
	{ "float-list-count.ply",
	  HDR3 "element face 1\nproperty list float int vertex_indices\nend_header\n", 0,
	  { "line 8", "not an integer type" } },
	{ "list-two-words.ply", HDR3 "element face 1\nproperty list uchar vertex_indices\n"
	  "end_header\n", 0, { "line 8", "property list COUNT_TYPE ITEM_TYPE NAME" } },
	{ "property-first.ply", "ply\nformat ascii 1.0\nproperty float x\nend_header\n", 0,
	  { "line 3", "before any element" } },
	{ "stray-keyword.ply", HDR3 "vertices 3\nend_header\n", 0,
	  { "line 7", "found 'vertices'" } },
	{ "duplicate-property.ply",
	  "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float x\n"
	  "end_header\n", 0, { "line 5", "property x is declared twice" } },
	{ "no-z.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
	  "property float y\nend_header\n0 0\n", 0, { "line 3", "no property z" } },
	{ "no-vertex.ply", "ply\nformat ascii 1.0\nelement face 0\nend_header\n", 0,
	  { "no 'element vertex'" } },
	{ "face-without-list.ply", HDR3 "element face 1\nproperty int vertex_indices\n"
	  "end_header\n" VERTS "0\n", 0, { "line 8", "is a scalar (expected a list)" } },
	{ "count-not-a-number.ply", "ply\nformat ascii 1.0\nelement vertex -3\n", 0,
	  { "line 3", "expected a count", "'-3'" } },
	{ "count-overflow-u64.ply", "ply\nformat ascii 1.0\nelement vertex 18446744073709551616\n"
	  "end_header\n", 0, { "line 3", "expected a count" } },
	{ "count-over-u32.ply", "ply\nformat ascii 1.0\nelement vertex 4294967296\nend_header\n",
	  0, { "line 3", "larger than 4294967295" } },
	{ "count-4294967295-faces.ply",
	  HDR3 "element face 4294967295\nproperty list uchar int vertex_indices\nend_header\n"
	  VERTS "3 0 1 2\n", 0, { "element face", "4294967295", "truncated file or wrong count" } },
	{ "count-4294967295-binary.ply",
	  "ply\nformat binary_little_endian 1.0\nelement vertex 4294967295\nproperty float x\n"
	  "property float y\nproperty float z\nend_header\n\0\0\0\0", 0,
	  { "element vertex", "4294967295", "truncated" } },
	{ "index-out-of-range.ply", HDR3 FACE "end_header\n" VERTS "3 0 1 3\n", 0,
	  { "line 13", "vertex index 3 is out of range", "0 to 2" } },
	{ "index-negative.ply", HDR3 FACE "end_header\n" VERTS "3 0 -1 2\n", 0,
	  { "line 13", "vertex index -1" } },
	{ "list-count-short.ply", HDR3 FACE "end_header\n" VERTS "4 0 1 2\n", 0,
	  { "line 13", "vertex_indices (vertex index)", "the line ends" } },
	{ "list-count-2-extra.ply", HDR3 FACE "end_header\n" VERTS "2 0 1 2\n", 0,
	  { "line 13", "expected the end of the line", "'2'" } },
	{ "list-count-negative.ply",
	  HDR3 "element face 1\nproperty list char int vertex_indices\nend_header\n" VERTS
	  "-3 0 1 2\n", 0, { "line 13", "list count -3 is negative" } },
	{ "list-count-huge.ply", HDR3 FACE "end_header\n" VERTS "255 0 1 2\n", 0,
	  { "line 13", "list count 255 is more than the rest of the file can hold" } },
	{ "nan-ascii.ply", HDR3 "end_header\n0 0 0\n1 nan 0\n0 1 0\n", 0,
	  { "line 9", "vertex 1", "property y is NaN" } },
	{ "inf-ascii.ply", HDR3 "end_header\n0 0 0\n1 0 -inf\n0 1 0\n", 0,
	  { "line 9", "property z is infinite" } },
	{ "too-large-for-float.ply",
	  "ply\nformat ascii 1.0\nelement vertex 1\nproperty double x\nproperty double y\n"
	  "property double z\nend_header\n1e300 0 0\n", 0, { "line 8", "too large for a float" } },
	{ "non-numeric.ply", HDR3 "end_header\n0 0 0\n1 abc 0\n0 1 0\n", 0,
	  { "line 9", "property y", "not a number 'abc'" } },
	{ "comma-decimal.ply", HDR3 "end_header\n0 0 0\n1,5 0 0\n0 1 0\n", 0,
	  { "line 9", "property x", "'1,5'" } },
	{ "non-integer-index.ply", HDR3 FACE "end_header\n" VERTS "3 0 1.5 2\n", 0,
	  { "line 13", "non-integer", "'1.5'" } },
	{ "uchar-out-of-range.ply",
	  "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
	  "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
	  "end_header\n0 0 0 300 0 0\n", 0, { "line 11", "property red", "out of the type's range" } },
	{ "int-too-long.ply", HDR3 FACE "end_header\n" VERTS "3 0 1 00099999999999999\n", 0,
	  { "line 13", "out of the type's range", "'00099999999999999'" } },
	{ "missing-value.ply", HDR3 "end_header\n0 0 0\n1 0\n0.5 1.5 0\n", 0,
	  { "line 9", "property z", "the line ends" } },
	{ "extra-value.ply", HDR3 "end_header\n0 0 0\n1 0 0 7\n0 1 0\n", 0,
	  { "line 9", "expected the end of the line", "'7'" } },
	{ "too-few-lines.ply", HDR3 FACE "end_header\n0.0 0.0 0\n1 0 0\n0 1 0\n", 0,
	  { "element face", "the file ends" } },
	{ "trailing-data.ply", HDR3 "end_header\n" VERTS "0 0 1\n", 0,
	  { "line 11", "after the last element", "'0 0 1" } },
	{ "material-too-large.ply", HDR3 "element face 1\nproperty list uchar int vertex_indices\n"
	  "property uint material\nend_header\n" VERTS "3 0 1 2 4294967295\n", 0,
	  { "line 14", "does not fit a 32-bit material id" } },
	{ "float-material.ply", HDR3 "property float material\nend_header\n", 0,
	  { "line 7", "material is float (expected an integer type)" } },
};

/* A valid binary file of the cube soup, with face materials. */
static void binary_file(tw_buf *b, enum tw_encoding enc)
{
	static const double pos[] = { 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0 };
	static const unsigned len[] = { 3, 3 }, idx[] = { 0, 1, 2, 0, 2, 3 };
	static const int fmat[] = { 4, 5 };
	tw_mesh s = { .nverts = 4, .nfaces = 2, .pos = pos, .face_len = len, .face_idx = idx,
		          .face_material = fmat };
	tw_opts o = { .enc = enc, .pos_type = "float", .count_type = "uchar",
		          .index_type = "int", .extras = 1 };
	tw_write(b, &s, &o);
}

/* The layout the loader's fast paths take: float x y z, triangles with a uchar count
 * and int indices, nothing else. */
static void plain_file(tw_buf *b, enum tw_encoding enc)
{
	static const double pos[] = { 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0 };
	static const unsigned len[] = { 3, 3, 3 }, idx[] = { 0, 1, 2, 0, 2, 3, 1, 3, 2 };
	tw_mesh s = { .nverts = 4, .nfaces = 3, .pos = pos, .face_len = len, .face_idx = idx };
	tw_opts o = { .enc = enc, .pos_type = "float", .count_type = "uchar", .index_type = "int" };
	tw_write(b, &s, &o);
}

static void put_u32(char *at, uint32_t u, enum tw_encoding enc)
{
	if (enc == TW_BE)
		u = __builtin_bswap32(u);
	memcpy(at, &u, 4);
}

static void test_plain_binary(void)
{
	tw_buf b = { 0 };
	for (int enc = TW_LE; enc <= TW_BE; enc++) {
		plain_file(&b, (enum tw_encoding)enc);
		size_t header = (size_t)(strstr(b.p, "end_header\n") - b.p) + 11;
		const char *e = enc == TW_LE ? "le" : "be";
		char name[64], loc[64];
		kg_err err = { { 0 } };
		kg_mesh *m = NULL;
		CHECK(kg_ply_load_mem(b.p, b.len, "plain.ply", &m, &err) == 0 && m && m->ntris == 3,
		      "plain.ply: %s", err.msg);
		kg_mesh_free(&m);
		int refused = 0, total = 0;
		for (size_t cut = header; cut < b.len; cut++, total++) {
			char *copy = malloc(cut);
			memcpy(copy, b.p, cut);
			int r = kg_ply_load_mem(copy, cut, "plain-cut.ply", &m, &err);
			refused += r == KG_EINVAL && !m && strstr(err.msg, "truncated") != NULL;
			if (r != KG_EINVAL || !strstr(err.msg, "truncated"))
				fprintf(stderr, "cut %zu: %d %s\n", cut, r, err.msg);
			kg_mesh_free(&m);
			free(copy);
		}
		CHECK(refused == total, "plain %s: %d of %d truncations refused", e, refused, total);

		char *copy = malloc(b.len);
		float bad[] = { NAN, INFINITY, -INFINITY };
		for (int k = 0; k < 3; k++) { /* vertex 2's z */
			memcpy(copy, b.p, b.len);
			uint32_t u;
			memcpy(&u, &bad[k], 4);
			size_t at = header + 2 * 12 + 8;
			put_u32(copy + at, u, (enum tw_encoding)enc);
			snprintf(name, sizeof(name), "plain-%s-%d.ply", e, k);
			snprintf(loc, sizeof(loc), "byte %zu", at);
			const char *want[3] = { loc, "vertex 2", k ? "property z is infinite"
			                                           : "property z is NaN" };
			expect_refusal(name, copy, b.len, want);
		}
		static const int32_t bad_index[] = { 4, -1, INT32_MIN };
		for (int k = 0; k < 3; k++) { /* face 2's second index */
			memcpy(copy, b.p, b.len);
			size_t at = header + 4 * 12 + 2 * 13 + 1 + 4;
			put_u32(copy + at, (uint32_t)bad_index[k], (enum tw_encoding)enc);
			snprintf(name, sizeof(name), "plain-index-%s-%d.ply", e, k);
			snprintf(loc, sizeof(loc), "byte %zu", at);
			char what[64];
			snprintf(what, sizeof(what), "vertex index %d is out of range", bad_index[k]);
			const char *want[3] = { loc, "face 2", what };
			expect_refusal(name, copy, b.len, want);
		}
		/* Polygons and a degenerate face among triangles: out of the fast path and
		 * back. */
		static const double pos[] = { 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 2, 2, 0 };
		static const unsigned len[] = { 3, 4, 3, 2, 3, 5, 3 };
		static const unsigned idx[] = { 0, 1, 2, 0, 1, 2, 3, 1, 3, 2, 0, 4, 4, 3, 2,
			                            0, 1, 4, 2, 3, 2, 1, 0 };
		tw_mesh mixed = { .nverts = 5, .nfaces = 7, .pos = pos, .face_len = len,
			              .face_idx = idx };
		tw_opts o = { .enc = (enum tw_encoding)enc, .pos_type = "float",
			          .count_type = "uchar", .index_type = "uint" };
		tw_buf mb = { 0 };
		tw_write(&mb, &mixed, &o);
		CHECK(kg_ply_load_mem(mb.p, mb.len, "mixed.ply", &m, &err) == 0, "mixed.ply: %s",
		      err.msg);
		static const uint32_t fan[] = { 0, 1, 2, 0, 1, 2, 0, 2, 3, 1, 3, 2, 4, 3, 2,
			                            0, 1, 4, 0, 4, 2, 0, 2, 3, 2, 1, 0 };
		CHECK(m && m->ntris == 9 && m->degenerate == 1 && m->npolygons == 7 &&
		      memcmp(m->tri, fan, sizeof(fan)) == 0, "mixed.ply: wrong triangles");
		kg_mesh_free(&m);
		free(mb.p);
		free(copy);
	}
	free(b.p);
}

static void test_binary(void)
{
	tw_buf b = { 0 };
	binary_file(&b, TW_LE);
	kg_err err = { { 0 } };
	kg_mesh *m = NULL;
	CHECK(kg_ply_load_mem(b.p, b.len, "valid.ply", &m, &err) == 0, "valid.ply: %s", err.msg);
	kg_mesh_free(&m);
	size_t header = (size_t)(strstr(b.p, "end_header\n") - b.p) + 11;

	/* Every truncation inside the data. */
	int refused = 0, total = 0;
	for (size_t cut = header; cut < b.len; cut++, total++) {
		char *copy = malloc(cut ? cut : 1); /* exact size: ASan sees any over-read */
		memcpy(copy, b.p, cut);
		err.msg[0] = '\0';
		int r = kg_ply_load_mem(copy, cut, "truncated.ply", &m, &err);
		refused += r == KG_EINVAL && !m && strstr(err.msg, "truncated") &&
		           (strstr(err.msg, "byte ") || strstr(err.msg, "line "));
		if (r != KG_EINVAL || !strstr(err.msg, "truncated"))
			CHECK(0, "cut at %zu of %zu: returned %d: %s", cut, b.len, r, err.msg);
		kg_mesh_free(&m);
		free(copy);
	}
	printf("%-26s all %d truncations refused, the last: %s\n", "truncated.ply", total,
	       err.msg);
	CHECK(refused == total, "%d of %d truncations refused with a located message", refused,
	      total);

	/* NaN, Inf and an out-of-range index in binary data, big- and little-endian. */
	for (int enc = TW_LE; enc <= TW_BE; enc++) {
		binary_file(&b, (enum tw_encoding)enc);
		header = (size_t)(strstr(b.p, "end_header\n") - b.p) + 11;
		/* camera: 2 x (4 + 1 + 8 + 8) bytes; vertex 1: list count 1, one float, short. */
		size_t v0 = header + 2 * 21, v1 = v0 + 1 + 2 + 12 + 1, y1 = v1 + 1 + 4 + 2 + 4;
		char *copy = malloc(b.len);
		const char *name = enc == TW_LE ? "nan-le.ply" : "nan-be.ply";
		memcpy(copy, b.p, b.len);
		float nan = NAN;
		uint32_t u;
		memcpy(&u, &nan, 4);
		if (enc == TW_BE)
			u = __builtin_bswap32(u);
		memcpy(copy + y1, &u, 4);
		char loc[64];
		snprintf(loc, sizeof(loc), "byte %zu", y1);
		const char *want[3] = { loc, "vertex 1", "property y is NaN" };
		expect_refusal(name, copy, b.len, want);

		/* The last face's last index (before material and texcoord). */
		memcpy(copy, b.p, b.len);
		size_t idx_at = b.len - (4 + 2 + 16) - 4;
		int32_t big = 4;
		uint32_t w;
		memcpy(&w, &big, 4);
		if (enc == TW_BE)
			w = __builtin_bswap32(w);
		memcpy(copy + idx_at, &w, 4);
		snprintf(loc, sizeof(loc), "byte %zu", idx_at);
		const char *want2[3] = { loc, "face 1", "vertex index 4 is out of range" };
		expect_refusal(enc == TW_LE ? "index-le.ply" : "index-be.ply", copy, b.len, want2);

		/* Bytes after the last element. */
		tw_put(&b, "xyz", 3);
		const char *want3[3] = { "3 bytes after the last element", "'xyz'" };
		expect_refusal("trailing-binary.ply", b.p, b.len, want3);
		free(copy);
	}
	free(b.p);
}

int main(void)
{
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		const bad_case *c = &cases[i];
		size_t len = c->len ? c->len : strlen(c->text);
		char *copy = malloc(len ? len : 1); /* exact size, no terminator to lean on */
		memcpy(copy, c->text, len);
		expect_refusal(c->name, copy, len, c->expect);
		free(copy);
	}
	test_binary();
	test_plain_binary();
	return kg_test_done("ply-malformed");
}
