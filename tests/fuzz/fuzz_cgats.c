/* Fuzz target for the CGATS reader, patch-set extraction and the CSV reader.
 *
 * Built with libFuzzer (meson -Dfuzzing=true, clang) it is a plain
 * LLVMFuzzerTestOneInput. Otherwise (KG_FUZZ_STANDALONE) a main() runs the target over
 * every file named on the command line and over a few thousand deterministic mutations
 * of each (byte flips, CGATS words, deletions, duplications, truncations, over-long
 * lines), so the ordinary test run walks the error paths under the sanitizers.
 *
 * Invariants checked on every input: a refusal always carries a message, a success
 * leaves a consistent table, and everything is freed (the sanitizers see leaks). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cgats.h"
#include "csv.h"
#include "fsutil.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void require(int cond, const char *what)
{
	if (!cond) {
		fprintf(stderr, "fuzz-cgats: invariant broken: %s\n", what);
		abort();
	}
}

static void check_refusal(int r, const kg_err *err)
{
	require(r < 0, "return code is 0 or negative");
	require(memchr(err->msg, '\0', sizeof(err->msg)) != NULL, "message is terminated");
	require(err->msg[0] != '\0', "a refusal has a message");
}

static void exercise_table(const kg_cgats_table *t)
{
	require(t->type && t->nfields >= 1 && t->nsets >= 0, "table shape");
	double v;
	for (int s = 0; s < t->nsets; s++)
		for (int f = 0; f < t->nfields; f++) {
			kg_err err = { { 0 } };
			int r = kg_cgats_number(t, s, f, &v, &err);
			if (r != 0)
				check_refusal(r, &err);
		}
	for (int k = 0; k < t->nkeywords; k++) {
		kg_err err = { { 0 } };
		int r = kg_cgats_keyword_number(t, t->keywords[k].name, &v, &err);
		if (r != 0)
			check_refusal(r, &err);
	}
	for (unsigned flags = 0; flags <= KG_RESAMPLE_EXTRAPOLATE; flags++) {
		kg_err err = { { 0 } };
		kg_patchset *ps = NULL;
		int r = kg_patchset_from_table(t, flags, &ps, &err);
		if (r != 0) {
			check_refusal(r, &err);
			require(ps == NULL, "no patch set on failure");
			continue;
		}
		require(ps->n == t->nsets, "one patch per set");
		unsigned fields = (ps->spectra ? KG_PATCH_SPECTRA : 0) | (ps->rgb ? KG_PATCH_RGB : 0) |
		                  (ps->xyz ? KG_PATCH_XYZ : 0) | (ps->lab ? KG_PATCH_LAB : 0) |
		                  (ps->nextra ? KG_PATCH_EXTRA : 0);
		kg_cgats *out = NULL;
		r = kg_patchset_to_cgats(ps, fields, NULL, &out, &err);
		if (r != 0)
			check_refusal(r, &err);
		kg_cgats_free(&out);
		kg_patchset_free(&ps);
	}
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	kg_err err = { { 0 } };
	kg_cgats *cg = NULL;
	int r = kg_cgats_parse((const char *)data, size, "fuzz.cgats", &cg, &err);
	if (r != 0) {
		check_refusal(r, &err);
		require(cg == NULL, "no result on failure");
	} else {
		require(cg->ntables >= 1, "a parsed file has a table");
		for (int k = 0; k < cg->ntables; k++)
			exercise_table(cg->tables[k]);
		kg_cgats_free(&cg);
	}

	kg_csv *csv = NULL;
	kg_err cerr = { { 0 } };
	r = kg_csv_parse((const char *)data, size, "fuzz.csv", &csv, &cerr);
	if (r != 0)
		check_refusal(r, &cerr);
	else {
		double v;
		for (int i = 0; i < csv->nrows; i++)
			for (int c = 0; c < csv->ncols; c++)
				if ((r = kg_csv_number(csv, i, c, &v, &cerr)) != 0)
					check_refusal(r, &cerr);
	}
	kg_csv_free(&csv);
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
		fprintf(stderr, "fuzz-cgats: out of memory\n");
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
	"\n", "\"", "\t", " ", "#", "0", "-1", "1e999", "nan", "inf", "0x1p3", "1.5",
	"\nEND_DATA\n", "\nBEGIN_DATA\n", "\nBEGIN_DATA_FORMAT\n", "END_DATA_FORMAT",
	"\nNUMBER_OF_FIELDS 2\n", "\nNUMBER_OF_SETS 1\n", "\nNUMBER_OF_SETS 99999999999\n",
	"KEYWORD \"X\"\n", "SPEC_400 ", "SPEC_700 ", "SPEC_500000 ", "SAMPLE_ID ", "RGB_R ",
	"XYZ_X ", "LAB_L ", "\nSPECTRAL_NORM \"0\"\n", "\nSPECTRAL_START_NM 400\n",
	"\nCGATS.17\n", "\r\n", "\xff\xfe",
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
				b->p[below(b->len)] = (uint8_t)"\n\t \"#0-.eE\0"[below(11)];
			break;
		case 2: { /* insert a CGATS word */
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
		case 4: { /* duplicate a range (repeats lines, sets, tables) */
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
		case 6: /* an over-long line, now and then */
			if (below(64) == 0) {
				size_t n = (size_t)KG_CGATS_MAX_LINE + 1 + below(16);
				reserve(b, n);
				size_t at = below(b->len + 1);
				memmove(b->p + at + n, b->p + at, b->len - at);
				memset(b->p + at, 'x', n);
				b->len += n;
			}
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

#define MUTATIONS_PER_FILE 3000

int main(int argc, char **argv)
{
	if (argc < 2) {
		fprintf(stderr, "usage: %s FILE...\n", argv[0]);
		return 2;
	}
	long runs = 0;
	for (int i = 1; i < argc; i++) {
		char *seed;
		size_t len;
		kg_err err = { { 0 } };
		if (kg_read_file(argv[i], &seed, &len, &err) != 0) {
			fprintf(stderr, "fuzz-cgats: %s\n", err.msg);
			return 1;
		}
		LLVMFuzzerTestOneInput((const uint8_t *)seed, len);
		runs++;
		rng_state = 0x9E3779B97F4A7C15ull ^ ((uint64_t)i * 0x2545F4914F6CDD1Dull);
		buffer b = { 0 };
		for (int m = 0; m < MUTATIONS_PER_FILE; m++) {
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
	printf("fuzz-cgats: %ld inputs from %d seed files, no crash\n", runs, argc - 1);
	return 0;
}

#endif
