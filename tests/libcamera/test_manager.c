/* The libcamera CameraManager behind the shim (one per process, reference-counted):
 * - references nest: the manager exists while any is held and is gone after the last;
 * - started and stopped several times, it lists the same cameras each time and leaves
 *   no thread and no file descriptor behind (libcamera starts a thread and opens udev
 *   and event descriptors per start); the sanitizer build checks memory;
 * - opening a missing camera repeatedly takes and gives back its reference;
 * - threads taking and dropping references at once end with none held. */
#include <dirent.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "kg_camera.h"
#include "kg_test.h"

#if HAVE_LIBCAMERA
#include "lc_shim.h"

enum { CYCLES = 6, THREADS = 4, ROUNDS = 20 };

/* LTTng-UST, which libcamera links where it is installed (Debian pulls it in with other
 * packages), starts its listener threads ("<name>-ust") once per process, when the
 * first camera manager loads: they are the tracer's, not the manager's, and not counted. */
static int tracer_thread(const char *tid)
{
	char path[320], comm[32] = "";
	snprintf(path, sizeof(path), "/proc/self/task/%s/comm", tid);
	FILE *fp = fopen(path, "r");
	if (!fp)
		return 0;
	if (!fgets(comm, sizeof(comm), fp))
		comm[0] = '\0';
	fclose(fp);
	comm[strcspn(comm, "\n")] = '\0';
	size_t n = strlen(comm);
	return n >= 4 && !strcmp(comm + n - 4, "-ust");
}

static int count_entries(const char *dir)
{
	DIR *d = opendir(dir);
	if (!d)
		return -1;
	int n = 0;
	struct dirent *e;
	int tasks = !strcmp(dir, "/proc/self/task");
	while ((e = readdir(d)))
		n += e->d_name[0] != '.' && !(tasks && tracer_thread(e->d_name));
	closedir(d);
	return n - (!strcmp(dir, "/proc/self/fd")); /* the DIR's own descriptor */
}

static void *churn(void *arg)
{
	int *failures = arg;
	for (int i = 0; i < ROUNDS; i++) {
		kg_err e = {{0}};
		if (kg_lc_manager_ref(&e)) {
			(*failures)++;
			continue;
		}
		if (kg_lc_list(NULL, NULL, &e) < 0)
			(*failures)++;
		kg_lc_manager_unref();
	}
	return NULL;
}
#endif

int main(void)
{
#if !HAVE_LIBCAMERA
	kg_test_skip("the libcamera backend is not built (pkg-config libcamera and a C++ "
	             "compiler are needed)");
	return 77;
#else
	kg_err e = {{0}};
	CHECK(kg_lc_manager_refs() == 0, "a manager exists before any reference");
	int threads0 = count_entries("/proc/self/task");
	int fds0 = -1, count0 = -1;
	for (int cycle = 0; cycle < CYCLES; cycle++) {
		int ret = kg_lc_manager_ref(&e);
		CHECK(ret == 0, "cycle %d: starting the manager: %s", cycle, e.msg);
		if (ret)
			break;
		CHECK(kg_lc_manager_refs() == 1, "cycle %d: %d references", cycle, kg_lc_manager_refs());
		CHECK(count_entries("/proc/self/task") > threads0,
		      "cycle %d: the started manager runs no thread of its own", cycle);
		ret = kg_lc_manager_ref(&e); /* nested: same manager */
		CHECK(ret == 0 && kg_lc_manager_refs() == 2, "cycle %d: nested reference: %d refs",
		      cycle, kg_lc_manager_refs());
		int count = kg_lc_list(NULL, NULL, &e);
		CHECK(count >= 0, "cycle %d: listing: %s", cycle, e.msg);
		if (cycle == 0)
			count0 = count;
		CHECK(count == count0, "cycle %d lists %d cameras, cycle 0 %d", cycle, count, count0);
		kg_lc_manager_unref();
		CHECK(kg_lc_manager_refs() == 1, "cycle %d: inner release left %d", cycle,
		      kg_lc_manager_refs());
		kg_lc_manager_unref();
		CHECK(kg_lc_manager_refs() == 0, "cycle %d: %d references after the last release",
		      cycle, kg_lc_manager_refs());
		/* a stopped thread leaves /proc/self/task when it has exited: give it a second */
		int threads = count_entries("/proc/self/task");
		for (int wait = 0; wait < 100 && threads != threads0; wait++) {
			nanosleep(&(struct timespec){.tv_nsec = 10000000}, NULL);
			threads = count_entries("/proc/self/task");
		}
		CHECK(threads == threads0, "cycle %d: %d threads after stop, %d before", cycle, threads,
		      threads0);
		/* libcamera keeps what it opens once per process (its log stream, ...): the
		 * descriptors after the first cycle are the baseline */
		int fds = count_entries("/proc/self/fd");
		if (cycle == 0)
			fds0 = fds;
		CHECK(fds == fds0, "cycle %d: %d descriptors open, %d after cycle 0", cycle, fds, fds0);
	}
	printf("libcamera %s: %d start/stop cycles, %d camera(s), %d thread(s), %d fds\n",
	       kg_lc_version(), CYCLES, count0, threads0, fds0);

	/* an extra release does not underflow */
	kg_lc_manager_unref();
	CHECK(kg_lc_manager_refs() == 0, "release without a reference: %d", kg_lc_manager_refs());

	/* a missing camera: each failed open gives its reference back */
	for (int i = 0; i < 3; i++) {
		kg_camera *c = NULL;
		int ret = kg_camera_open("libcamera:missing-camera", &c, &e);
		CHECK(ret == KG_ENODEV && !c, "open of a missing camera: %d (%s)", ret, e.msg);
		CHECK(kg_lc_manager_refs() == 0, "failed open %d left %d references", i,
		      kg_lc_manager_refs());
	}

	/* references from several threads at once */
	pthread_t th[THREADS];
	int failures[THREADS] = {0};
	for (int i = 0; i < THREADS; i++)
		CHECK(pthread_create(&th[i], NULL, churn, &failures[i]) == 0, "pthread_create %d", i);
	for (int i = 0; i < THREADS; i++) {
		pthread_join(th[i], NULL);
		CHECK(failures[i] == 0, "thread %d: %d failed calls", i, failures[i]);
	}
	CHECK(kg_lc_manager_refs() == 0, "%d references after the threads", kg_lc_manager_refs());
	CHECK(count_entries("/proc/self/task") == threads0, "threads left after the churn: %d",
	      count_entries("/proc/self/task") - threads0);
	return kg_test_done("libcamera-manager");
#endif
}
