/* LD_PRELOAD shim: another program cuts a file short while kogei has it mapped. Right
 * after the first successful mmap of a file of at least 1 MB whose name contains
 * KOGEI_CUT_NAME, the file is truncated to KOGEI_CUT_KEEP (a fraction, default 0.5) of
 * its length through a second descriptor, as `truncate` in another process would: the
 * mapping's pages past the new end are gone, and a read of them raises SIGBUS. */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <dlfcn.h>
#include <fcntl.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/types.h>
#include <unistd.h>

static atomic_int done;

void *mmap(void *addr, size_t len, int prot, int flags, int fd, off_t off)
{
	static void *(*real)(void *, size_t, int, int, int, off_t);
	if (!real)
		real = (void *(*)(void *, size_t, int, int, int, off_t))dlsym(RTLD_NEXT, "mmap");
	void *p = real(addr, len, prot, flags, fd, off);
	const char *want = getenv("KOGEI_CUT_NAME");
	if (p == MAP_FAILED || fd < 0 || len < (1u << 20) || !want || atomic_load(&done))
		return p;
	char link[64], name[4096];
	snprintf(link, sizeof(link), "/proc/self/fd/%d", fd);
	ssize_t n = readlink(link, name, sizeof(name) - 1);
	if (n <= 0)
		return p;
	name[n] = 0;
	if (!strstr(name, want) || atomic_exchange(&done, 1))
		return p;
	const char *keep = getenv("KOGEI_CUT_KEEP");
	double f = keep ? atof(keep) : 0.5;
	int w = open(name, O_WRONLY | O_CLOEXEC);
	if (w >= 0) {
		if (ftruncate(w, (off_t)((double)len * f)) == 0)
			fprintf(stderr, "cut_preload: %s cut to %.0f%% after it was mapped\n", name,
			        f * 100);
		close(w);
	}
	return p;
}
