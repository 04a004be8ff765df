/* LD_PRELOAD shim that starts threads late, at the worst moment for a thread pool
 * whose workers read a task array the creator may still be growing (libapriltag
 * before 3.4.3). Every new thread waits, before its start routine, until its creator
 * next grows a block with realloc (up to 200 ms); that realloc is held until the new
 * thread calls sched_yield (libapriltag's workers do, between taking a task and
 * running it) or 20 ms have passed, and every grown block is moved, its old bytes
 * overwritten with 0xa5 before it is freed, so a pointer kept into it calls garbage.
 * At exit, with KOGEI_LATE_THREADS_LOG set, writes "late N caught M" to that file:
 * N threads started inside a held realloc, M of them took something from the block
 * before it moved. A correct program runs as without the shim, only slower. */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <dlfcn.h>
#include <errno.h>
#include <malloc.h>
#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

static atomic_int window;  /* a creator is inside realloc, holding it for a start */
static atomic_int yielded; /* a late thread yielded inside the window */
static atomic_int pending; /* created, not yet started */
static atomic_int late, caught;
static __thread int is_new;

static int wait_for(atomic_int *flag, int want, int ms)
{
	for (int i = 0; i < ms * 10; i++) {
		if (atomic_load(flag) == want)
			return 1;
		struct timespec ts = {0, 100000};
		nanosleep(&ts, NULL);
	}
	return 0;
}

typedef void *(*start_fn)(void *);
struct start {
	start_fn fn;
	void *arg;
};

static void *late_start(void *p)
{
	struct start s = *(struct start *)p;
	free(p);
	is_new = 1;
	if (wait_for(&window, 1, 200))
		atomic_fetch_add(&late, 1);
	atomic_fetch_sub(&pending, 1);
	return s.fn(s.arg);
}

int pthread_create(pthread_t *t, const pthread_attr_t *a, start_fn fn, void *arg)
{
	int (*real)(pthread_t *, const pthread_attr_t *, start_fn, void *);
	*(void **)&real = dlsym(RTLD_NEXT, "pthread_create");
	struct start *s = malloc(sizeof(*s));
	if (!real || !s) {
		free(s);
		return EAGAIN;
	}
	s->fn = fn;
	s->arg = arg;
	atomic_fetch_add(&pending, 1);
	int rc = real(t, a, late_start, s);
	if (rc) {
		atomic_fetch_sub(&pending, 1);
		free(s);
	}
	return rc;
}

int sched_yield(void)
{
	if (is_new && atomic_load(&window)) {
		atomic_store(&yielded, 1);
		wait_for(&window, 0, 200);
	}
	return (int)syscall(SYS_sched_yield);
}

void *realloc(void *p, size_t n)
{
	if (!p)
		return malloc(n);
	if (n == 0) {
		free(p);
		return NULL;
	}
	int held = !is_new && atomic_load(&pending) > 0;
	if (held) {
		atomic_store(&yielded, 0);
		atomic_store(&window, 1);
		if (wait_for(&yielded, 1, 20))
			atomic_fetch_add(&caught, 1);
	}
	size_t old = malloc_usable_size(p);
	void *q = malloc(n);
	if (q) {
		memcpy(q, p, old < n ? old : n);
		memset(p, 0xa5, old);
		free(p);
	}
	if (held)
		atomic_store(&window, 0);
	return q;
}

__attribute__((destructor)) static void report(void)
{
	const char *path = getenv("KOGEI_LATE_THREADS_LOG");
	FILE *f = path ? fopen(path, "w") : NULL;
	if (f) {
		fprintf(f, "late %d caught %d\n", atomic_load(&late), atomic_load(&caught));
		fclose(f);
	}
}
