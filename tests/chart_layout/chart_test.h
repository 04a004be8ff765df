/* Shared helpers of the chart layout tests: the bundled layouts and scratch files. */
#ifndef CHART_TEST_H
#define CHART_TEST_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "kg_calib.h"
#include "kg_test.h"

static const char *const bundled_layouts[] = {
	"colorchecker24-frame",
	"colorchecker-passport-frame",
	"colorchecker-sg-frame",
};
#define NBUNDLED ((int)(sizeof(bundled_layouts) / sizeof(bundled_layouts[0])))

static inline const char *source_root(void)
{
	const char *s = getenv("KOGEI_SOURCE_ROOT");
	return s && *s ? s : KG_SOURCE_ROOT;
}

/* fixtures/charts/<name>.json, in a static buffer. */
static inline const char *bundled_path(const char *name)
{
	static char buf[4096];
	snprintf(buf, sizeof(buf), "%s/fixtures/charts/%s.json", source_root(), name);
	return buf;
}

/* A scratch directory removed by the caller (rm_scratch). */
static inline char *make_scratch(void)
{
	char tmpl[] = "/tmp/kogei-chart-XXXXXX";
	char *d = mkdtemp(tmpl);
	if (!d) {
		perror("mkdtemp");
		exit(1);
	}
	return strdup(d);
}

static inline void rm_scratch(char *dir)
{
	char cmd[4200];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", dir);
	if (system(cmd) != 0)
		fprintf(stderr, "could not remove %s\n", dir);
	free(dir);
}

static inline void write_text(const char *path, const char *text)
{
	FILE *fp = fopen(path, "wb");
	if (!fp || fputs(text, fp) < 0 || fclose(fp) != 0) {
		perror(path);
		exit(1);
	}
}

#endif
