/* Scratch directories for the I/O tests. */
#ifndef KG_IO_UTIL_H
#define KG_IO_UTIL_H

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "kg_test.h"

/* A fresh directory under $TMPDIR (or /tmp), removed at exit. */
static inline const char *io_tmpdir(const char *name)
{
	atexit(kg_test_scratch_remove);
	return kg_test_scratch_dir(name);
}

/* Number of entries in the scratch directory (to see that nothing was left behind). */
static inline int io_count_files(void)
{
	DIR *d = opendir(kg_test_scratch());
	int n = 0;
	struct dirent *e;
	while (d && (e = readdir(d)))
		n += e->d_name[0] != '.';
	if (d)
		closedir(d);
	return n;
}

static inline int io_write_bytes(const char *path, const void *data, size_t n)
{
	FILE *f = fopen(path, "wb");
	if (!f)
		return -1;
	size_t k = fwrite(data, 1, n, f);
	return fclose(f) == 0 && k == n ? 0 : -1;
}

#endif
