/* Minimal test harness: each test is a program; it exits 0 on success, 1 on any
 * failed check, 77 when it must be skipped (data or tool missing). */
#ifndef KG_TEST_H
#define KG_TEST_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include "kg_config.h"

static int kg_test_failures;

#define CHECK(cond, ...)                                                              \
	do {                                                                              \
		if (!(cond)) {                                                                \
			fprintf(stderr, "%s:%d: CHECK(%s) failed: ", __FILE__, __LINE__, #cond);  \
			fprintf(stderr, __VA_ARGS__);                                             \
			fputc('\n', stderr);                                                      \
			kg_test_failures++;                                                       \
		}                                                                             \
	} while (0)

#define CHECK_NEAR(a, b, tol, what)                                                   \
	do {                                                                              \
		double a_ = (a), b_ = (b), t_ = (tol);                                        \
		if (!(fabs(a_ - b_) <= t_)) {                                                 \
			fprintf(stderr, "%s:%d: %s: %.10g vs %.10g differ by %.3g > %.3g\n",      \
			        __FILE__, __LINE__, (what), a_, b_, fabs(a_ - b_), t_);           \
			kg_test_failures++;                                                       \
		}                                                                             \
	} while (0)

/* Finish a test: prints a one-line verdict and returns the exit status. */
static inline int kg_test_done(const char *name)
{
	if (kg_test_failures)
		fprintf(stderr, "%s: %d check(s) failed\n", name, kg_test_failures);
	else
		printf("%s: ok\n", name);
	return kg_test_failures ? 1 : 0;
}

static inline void kg_test_skip(const char *why)
{
	printf("SKIP: %s\n", why);
	exit(77);
}

/* ../shared/reference beside the checkout (or $KOGEI_REFERENCE); skips the test
 * with a message when it is absent. */
static inline const char *kg_test_reference_dir(void)
{
	static char buf[4096];
	const char *env = getenv("KOGEI_REFERENCE");
	if (env && *env)
		snprintf(buf, sizeof(buf), "%s", env);
	else
		snprintf(buf, sizeof(buf), "%s/../shared/reference", KG_SOURCE_ROOT);
	struct stat st;
	if (stat(buf, &st) != 0 || !S_ISDIR(st.st_mode)) {
		fprintf(stderr, "reference data not found at %s\n", buf);
		kg_test_skip("../shared/reference is not present");
	}
	return buf;
}

static inline int kg_test_file_exists(const char *path)
{
	struct stat st;
	return stat(path, &st) == 0;
}

/* The test's scratch folder: kg_test_scratch_dir makes a fresh one under $TMPDIR (or
 * /tmp) named kogei-TAG-XXXXXX, kg_test_scratch_remove deletes it (a no-op before it
 * is made), kg_test_scratch is its name ("" before). */
static inline char *kg_test_scratch(void)
{
	static char dir[4096];
	return dir;
}

static inline const char *kg_test_scratch_dir(const char *tag)
{
	char *dir = kg_test_scratch();
	const char *tmp = getenv("TMPDIR");
	snprintf(dir, 4096, "%s/kogei-%s-XXXXXX", tmp && *tmp ? tmp : "/tmp", tag);
	if (!mkdtemp(dir)) {
		perror("mkdtemp");
		exit(1);
	}
	return dir;
}

static inline void kg_test_scratch_remove(void)
{
	const char *dir = kg_test_scratch();
	char cmd[4200];
	if (!dir[0])
		return;
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
	if (system(cmd) != 0)
		fprintf(stderr, "could not remove %s\n", dir);
}

/* "<scratch>/<name>" in a ring of buffers (valid for the next 15 calls). */
static inline const char *kg_test_path(const char *name)
{
	static char ring[16][4352];
	static int next;
	char *p = ring[next++ % 16];
	snprintf(p, sizeof(ring[0]), "%s/%s", kg_test_scratch(), name);
	return p;
}

/* A text file's first len - 1 bytes into buf, NUL-terminated ("" when unreadable). */
static inline void kg_test_slurp(const char *file, char *buf, size_t len)
{
	buf[0] = '\0';
	FILE *fp = fopen(file, "r");
	if (!fp)
		return;
	size_t n = fread(buf, 1, len - 1, fp);
	buf[n] = '\0';
	fclose(fp);
}

/* 1 when both files exist and are equal byte for byte. */
static inline int kg_test_same_file(const char *a, const char *b)
{
	FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
	int same = fa && fb;
	while (same) {
		int ca = fgetc(fa), cb = fgetc(fb);
		same = ca == cb;
		if (ca == EOF || cb == EOF)
			break;
	}
	if (fa)
		fclose(fa);
	if (fb)
		fclose(fb);
	return same;
}

#endif
