/* The shared fuzz driver: deterministic mutations, the standalone runner and the
 * per-run temporary directory (see fuzz_driver.h). */
#define _XOPEN_SOURCE 700
#include "fuzz_driver.h"

#include <fcntl.h>
#include <ftw.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fsutil.h"

void kg_fuzz_require(const char *name, int cond, const char *what)
{
	if (!cond) {
		fprintf(stderr, "%s: invariant broken: %s\n", name, what);
		abort();
	}
}

/* ---- the temporary directory --------------------------------------------------- */

static char fuzz_dir[64];
static char fuzz_path[4096];

static int remove_entry(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
	(void)st;
	(void)flag;
	(void)ftw;
	return remove(path);
}

static void remove_dir(void)
{
	if (fuzz_dir[0])
		nftw(fuzz_dir, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
}

const char *kg_fuzz_dir(void)
{
	if (!fuzz_dir[0]) {
		const char *tmp = getenv("TMPDIR");
		snprintf(fuzz_dir, sizeof(fuzz_dir), "%s/kg-fuzz-XXXXXX",
		         tmp && *tmp && strlen(tmp) < 40 ? tmp : "/tmp");
		if (!mkdtemp(fuzz_dir)) {
			perror("kg_fuzz_dir: mkdtemp");
			exit(1);
		}
		atexit(remove_dir);
	}
	return fuzz_dir;
}

const char *kg_fuzz_write(const char *leaf, const uint8_t *data, size_t size)
{
	snprintf(fuzz_path, sizeof(fuzz_path), "%s/%s", kg_fuzz_dir(), leaf);
	for (char *s = strchr(fuzz_path + strlen(fuzz_dir) + 1, '/'); s; s = strchr(s + 1, '/')) {
		*s = '\0';
		mkdir(fuzz_path, 0700);
		*s = '/';
	}
	int fd = open(fuzz_path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
	if (fd < 0) {
		perror(fuzz_path);
		exit(1);
	}
	for (size_t done = 0; done < size;) {
		ssize_t n = write(fd, data + done, size - done);
		if (n <= 0) {
			perror(fuzz_path);
			exit(1);
		}
		done += (size_t)n;
	}
	close(fd);
	return fuzz_path;
}

/* ---- mutations -------------------------------------------------------------------- */

/* Deterministic xorshift64 so every run tries the same inputs. */
typedef struct fuzz_rng {
	uint64_t s;
} fuzz_rng;

static size_t below(fuzz_rng *r, size_t n)
{
	r->s ^= r->s << 13;
	r->s ^= r->s >> 7;
	r->s ^= r->s << 17;
	return n ? (size_t)(r->s % n) : 0;
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
		fprintf(stderr, "fuzz driver: out of memory\n");
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

/* Integer and floating-point specials of either byte order. */
static const uint8_t specials[][4] = {
	{ 0xff, 0xff, 0xff, 0xff }, { 0x7f, 0xc0, 0x00, 0x00 }, { 0x00, 0x00, 0xc0, 0x7f },
	{ 0x7f, 0x80, 0x00, 0x00 }, { 0x00, 0x00, 0x80, 0xff }, { 0x80, 0x00, 0x00, 0x00 },
	{ 0x00, 0x00, 0x00, 0x80 }, { 0x03, 0x00, 0x00, 0x00 },
};

static void mutate(const kg_fuzz_target *t, fuzz_rng *r, buffer *b)
{
	int steps = 1 + (int)below(r, 4);
	for (int s = 0; s < steps; s++) {
		switch (below(r, 9)) {
		case 0: /* flip a bit */
			if (b->len)
				b->p[below(r, b->len)] ^= (uint8_t)(1u << below(r, 8));
			break;
		case 1: /* overwrite a byte with a structural one (the NUL included) */
			if (b->len)
				b->p[below(r, b->len)] =
					(uint8_t)t->structural[below(r, strlen(t->structural) + 1)];
			break;
		case 2: /* insert one of the format's words */
			if (t->nwords) {
				const char *w = t->words[below(r, t->nwords)];
				insert(b, below(r, b->len + 1), w, strlen(w));
			}
			break;
		case 3: { /* delete a range */
			size_t at = below(r, b->len + 1), n = below(r, b->len - at + 1);
			n = n > 64 ? 64 : n;
			memmove(b->p + at, b->p + at + n, b->len - at - n);
			b->len -= n;
			break;
		}
		case 4: { /* duplicate a range (repeats lines, records, members) */
			size_t at = below(r, b->len + 1), n = below(r, b->len - at + 1);
			n = n > 256 ? 256 : n;
			uint8_t tmp[256];
			memcpy(tmp, b->p + at, n);
			insert(b, below(r, b->len + 1), tmp, n);
			break;
		}
		case 5: /* truncate */
			b->len = below(r, b->len + 1);
			break;
		case 6: /* overwrite four bytes with a binary special */
			if (b->len >= 4)
				memcpy(b->p + below(r, b->len - 3), specials[below(r, sizeof(specials) / 4)],
				       4);
			break;
		case 7: /* a run longer than the format's limit, now and then */
			if (t->long_line && below(r, 64) == 0) {
				size_t n = t->long_line + 1 + below(r, 16);
				reserve(b, n);
				size_t at = below(r, b->len + 1);
				memmove(b->p + at + n, b->p + at, b->len - at);
				memset(b->p + at, 'x', n);
				b->len += n;
			}
			break;
		default: /* swap two bytes */
			if (b->len >= 2) {
				size_t i = below(r, b->len), j = below(r, b->len);
				uint8_t c = b->p[i];
				b->p[i] = b->p[j];
				b->p[j] = c;
			}
			break;
		}
	}
}

/* ---- the standalone runner --------------------------------------------------------- */

int kg_fuzz_main(const kg_fuzz_target *t, int argc, char **argv)
{
	long mutations = t->mutations;
	int first = 1;
	if (argc > 2 && strcmp(argv[1], "--mutations") == 0) {
		mutations = strtol(argv[2], NULL, 10);
		first = 3;
	}
	if (argc <= first || mutations < 0) {
		fprintf(stderr, "usage: %s [--mutations N] FILE...\n", argv[0]);
		return 2;
	}
	long runs = 0, refused = 0, seeds_refused = 0;
	for (int i = first; i < argc; i++) {
		char *seed;
		size_t len;
		kg_err err = { { 0 } };
		if (kg_read_file(argv[i], &seed, &len, &err) != 0) {
			fprintf(stderr, "%s: %s\n", t->name, err.msg);
			return 1;
		}
		int r = t->run((const uint8_t *)seed, len);
		seeds_refused += r;
		refused += r;
		runs++;
		fuzz_rng rng = { 0x9E3779B97F4A7C15ull ^ ((uint64_t)i * 0x2545F4914F6CDD1Dull) };
		buffer b = { 0 };
		for (long m = 0; m < mutations; m++) {
			b.len = 0;
			reserve(&b, len + 1);
			memcpy(b.p, seed, len);
			b.len = len;
			mutate(t, &rng, &b);
			refused += t->run(b.p, b.len);
			runs++;
		}
		free(b.p);
		free(seed);
	}
	printf("%s: %d seeds (%ld refused), %ld mutations each, %ld inputs, %ld refused, no "
	       "invariant broken\n",
	       t->name, argc - first, seeds_refused, mutations, runs, refused);
	return 0;
}
