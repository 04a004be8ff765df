/* Fuzz target for the PLY loader (render/ply.c).
 *
 * Built with libFuzzer (meson -Dfuzzing=true, clang) it is a plain
 * LLVMFuzzerTestOneInput. Otherwise (KG_FUZZ_STANDALONE) a main() runs the target over
 * every file named on the command line and over deterministic mutations of each: bit
 * flips, PLY words (keywords, type names, formats, huge and negative counts, nan),
 * binary specials (0xffffffff, NaN and Inf floats), deletions, duplications and
 * truncations, so the ordinary test run walks the error paths under the sanitizers.
 * `fuzz_ply --mutations N FILE...` sets the number of mutations per file (default
 * 3000) for longer runs.
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

#include "kg_mesh.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static long inputs_loaded; /* for the standalone runner's summary */

static void require(int cond, const char *what)
{
	if (!cond) {
		fprintf(stderr, "fuzz-ply: invariant broken: %s\n", what);
		abort();
	}
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

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	/* An exact-size copy, so reading one byte past the end is an ASan error. */
	uint8_t *copy = malloc(size ? size : 1);
	if (!copy)
		return 0;
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
		inputs_loaded++;
	}
	free(copy);
	return 0;
}

#ifdef KG_FUZZ_STANDALONE

/* Deterministic xorshift64 so every run tries the same inputs. */
static uint64_t rng_state;

static uint64_t rng(void)
{
	rng_state ^= rng_state << 13;
	rng_state ^= rng_state >> 7;
	rng_state ^= rng_state << 17;
	return rng_state;
}

static size_t below(size_t n)
{
	return n ? (size_t)(rng() % n) : 0;
}

typedef struct buffer {
	uint8_t *p;
	size_t len, cap;
} buffer;

static void reserve(buffer *b, size_t extra)
{
	if (b->len + extra <= b->cap)
		return;
	size_t cap = (b->len + extra) * 2;
	uint8_t *p = realloc(b->p, cap);
	if (!p) {
		fprintf(stderr, "fuzz-ply: out of memory\n");
		exit(1);
	}
	b->p = p;
	b->cap = cap;
}

static void insert(buffer *b, size_t at, const void *src, size_t n)
{
	reserve(b, n);
	memmove(b->p + at + n, b->p + at, b->len - at);
	memcpy(b->p + at, src, n);
	b->len += n;
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

static const uint8_t specials[][4] = {
	{ 0xff, 0xff, 0xff, 0xff }, { 0x7f, 0xc0, 0x00, 0x00 }, { 0x00, 0x00, 0xc0, 0x7f },
	{ 0x7f, 0x80, 0x00, 0x00 }, { 0x00, 0x00, 0x80, 0xff }, { 0x80, 0x00, 0x00, 0x00 },
	{ 0x00, 0x00, 0x00, 0x80 }, { 0x03, 0x00, 0x00, 0x00 },
};

static void mutate(buffer *b)
{
	int steps = 1 + (int)below(4);
	for (int s = 0; s < steps; s++) {
		switch (below(8)) {
		case 0: /* flip a bit */
			if (b->len)
				b->p[below(b->len)] ^= (uint8_t)(1u << below(8));
			break;
		case 1: /* overwrite a byte with a structural character */
			if (b->len)
				b->p[below(b->len)] = (uint8_t)"\n\r\t -.e0139\xff\0"[below(14)];
			break;
		case 2: { /* insert a PLY word */
			const char *w = words[below(sizeof(words) / sizeof(words[0]))];
			insert(b, below(b->len + 1), w, strlen(w));
			break;
		}
		case 3: { /* delete a range */
			size_t at = below(b->len + 1), n = below(b->len - at + 1);
			n = n > 64 ? 64 : n;
			memmove(b->p + at, b->p + at + n, b->len - at - n);
			b->len -= n;
			break;
		}
		case 4: { /* duplicate a range (repeats properties, elements, records) */
			size_t at = below(b->len + 1), n = below(b->len - at + 1);
			n = n > 256 ? 256 : n;
			uint8_t tmp[256];
			memcpy(tmp, b->p + at, n);
			insert(b, below(b->len + 1), tmp, n);
			break;
		}
		case 5: /* truncate */
			b->len = below(b->len + 1);
			break;
		case 6: /* overwrite four bytes with a binary special */
			if (b->len >= 4)
				memcpy(b->p + below(b->len - 3), specials[below(sizeof(specials) / 4)], 4);
			break;
		default: /* swap two bytes */
			if (b->len >= 2) {
				size_t i = below(b->len), j = below(b->len);
				uint8_t t = b->p[i];
				b->p[i] = b->p[j];
				b->p[j] = t;
			}
			break;
		}
	}
}

int main(int argc, char **argv)
{
	long mutations = 3000;
	int first = 1;
	if (argc > 2 && strcmp(argv[1], "--mutations") == 0) {
		mutations = strtol(argv[2], NULL, 10);
		first = 3;
	}
	if (argc <= first || mutations < 0) {
		fprintf(stderr, "usage: %s [--mutations N] FILE...\n", argv[0]);
		return 2;
	}
	long runs = 0;
	for (int i = first; i < argc; i++) {
		char *seed;
		size_t len;
		kg_err err = { { 0 } };
		if (kg_read_file(argv[i], &seed, &len, &err) != 0) {
			fprintf(stderr, "fuzz-ply: %s\n", err.msg);
			return 1;
		}
		LLVMFuzzerTestOneInput((const uint8_t *)seed, len);
		runs++;
		rng_state = 0x9E3779B97F4A7C15ull ^ ((uint64_t)i * 0x2545F4914F6CDD1Dull);
		buffer b = { 0 };
		for (long m = 0; m < mutations; m++) {
			b.len = 0;
			reserve(&b, len + 1);
			memcpy(b.p, seed, len);
			b.len = len;
			mutate(&b);
			LLVMFuzzerTestOneInput(b.p, b.len);
			runs++;
		}
		free(b.p);
		free(seed);
	}
	printf("fuzz-ply: %ld inputs from %d seed files (%ld loaded, the rest refused), no "
	       "invariant broken\n", runs, argc - first, inputs_loaded);
	return 0;
}

#endif
