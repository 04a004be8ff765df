/* Minimal test harness: each test is a program; it exits 0 on success, 1 on any
 * failed check, 77 when it must be skipped (data or tool missing). */
#ifndef KG_TEST_H
#define KG_TEST_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>

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

#endif
