/* A private temporary directory for a test's input files, removed at exit. */
#ifndef KG_TEST_TMPFILES_H
#define KG_TEST_TMPFILES_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char kg_tmpdir[512];

static void kg_tmpdir_remove(void)
{
	char cmd[600];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", kg_tmpdir);
	if (kg_tmpdir[0] && system(cmd) != 0)
		fprintf(stderr, "could not remove %s\n", kg_tmpdir);
}

/* Create the directory ($TMPDIR or /tmp); exits the test on failure. */
static inline const char *kg_tmpdir_create(const char *name)
{
	const char *base = getenv("TMPDIR") && *getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp";
	snprintf(kg_tmpdir, sizeof(kg_tmpdir), "%s/%s_XXXXXX", base, name);
	if (!mkdtemp(kg_tmpdir)) {
		perror("mkdtemp");
		exit(1);
	}
	atexit(kg_tmpdir_remove);
	return kg_tmpdir;
}

/* Write text to <tmpdir>/<name> (name may hold one existing subdirectory); returns the
 * path in a static buffer. */
static inline const char *kg_tmpfile(const char *name, const char *text)
{
	static char path[1024];
	snprintf(path, sizeof(path), "%s/%s", kg_tmpdir, name);
	FILE *f = fopen(path, "w");
	if (!f || fputs(text, f) < 0 || fclose(f) != 0) {
		perror(path);
		exit(1);
	}
	return path;
}

#endif
