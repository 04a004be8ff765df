/* Scratch directories for the I/O tests. */
#ifndef KG_IO_UTIL_H
#define KG_IO_UTIL_H

#include <dirent.h>
#include <ftw.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char io_dir[4096];

static inline int io_rm(const char *p, const struct stat *st, int flag, struct FTW *f)
{
	return remove(p);
}

static inline void io_cleanup(void)
{
	if (io_dir[0])
		nftw(io_dir, io_rm, 16, FTW_DEPTH | FTW_PHYS);
}

/* A fresh directory under $TMPDIR (or /tmp), removed at exit. */
static inline const char *io_tmpdir(const char *name)
{
	const char *t = getenv("TMPDIR");
	snprintf(io_dir, sizeof(io_dir), "%s/kg-%s-XXXXXX", t && *t ? t : "/tmp", name);
	if (!mkdtemp(io_dir)) {
		perror("mkdtemp");
		exit(1);
	}
	atexit(io_cleanup);
	return io_dir;
}

static inline char *io_path(const char *name)
{
	static char buf[8][4200];
	static int k;
	char *b = buf[k++ % 8];
	snprintf(b, sizeof(buf[0]), "%s/%s", io_dir, name);
	return b;
}

/* Number of entries in the scratch directory (to see that nothing was left behind). */
static inline int io_count_files(void)
{
	DIR *d = opendir(io_dir);
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
