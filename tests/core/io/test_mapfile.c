/* Files mapped for reading whose pages vanish (core/mapfile.c): a file cut short while
 * mapped reads as zeros past its new end, in any thread, instead of ending the process
 * with SIGBUS, and kg_mapfile_check names the file; a file changed in place is caught
 * too; other mappings stay whole and pass. */
#include <fcntl.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "kg_core.h"
#include "kg_test.h"

enum { LEN = 4 << 20 };

static int make(const char *path)
{
	static unsigned char buf[LEN];
	memset(buf, 0x5a, sizeof(buf));
	FILE *f = fopen(path, "wb");
	int ok = f && fwrite(buf, 1, sizeof(buf), f) == sizeof(buf);
	if (f)
		fclose(f);
	return ok ? open(path, O_RDONLY) : -1;
}

struct part {
	const unsigned char *p;
	size_t from, to;
	uint64_t sum;
};

static void *sum_part(void *arg)
{
	struct part *s = arg;
	for (size_t i = s->from; i < s->to; i++)
		s->sum += ((const volatile unsigned char *)s->p)[i];
	return NULL;
}

int main(void)
{
	char a[4096], b[4096];
	snprintf(a, sizeof(a), "%s", kg_test_path("cut.bin"));
	snprintf(b, sizeof(b), "%s", kg_test_path("whole.bin"));
	int fa = make(a), fb = make(b);
	CHECK(fa >= 0 && fb >= 0, "test files");
	kg_mapfile *ma = NULL, *mb = NULL;
	const void *pa = NULL, *pb = NULL;
	kg_err err = {{0}};
	CHECK(kg_mapfile_open(fa, LEN, 1, a, &ma, &pa, &err) == 0, "%s", err.msg);
	CHECK(kg_mapfile_open(fb, LEN, 0, b, &mb, &pb, &err) == 0, "%s", err.msg);
	close(fa);
	close(fb);
	if (!ma || !mb)
		return 1;

	/* another program cuts the first file to a quarter */
	CHECK(truncate(a, LEN / 4) == 0, "truncate");
	/* two threads read every byte of it, each faulting past the end */
	struct part parts[2] = {{pa, 0, LEN / 2, 0}, {pa, LEN / 2, LEN, 0}};
	pthread_t t[2];
	for (int i = 0; i < 2; i++)
		pthread_create(&t[i], NULL, sum_part, &parts[i]);
	for (int i = 0; i < 2; i++)
		pthread_join(t[i], NULL);
	uint64_t got = parts[0].sum + parts[1].sum;
	CHECK(got == (uint64_t)0x5a * (LEN / 4), "the part still in the file reads as it was, "
	      "the rest as zeros: sum %llu", (unsigned long long)got);
	CHECK(kg_mapfile_check(ma, &err) == KG_EIO && strstr(err.msg, "cut.bin") &&
	          strstr(err.msg, "cut short"),
	      "the cut file is named: %s", err.msg);

	/* the other mapping is whole and passes */
	struct part whole = {pb, 0, LEN, 0};
	sum_part(&whole);
	CHECK(whole.sum == (uint64_t)0x5a * LEN, "the other file reads whole");
	CHECK(kg_mapfile_check(mb, &err) == 0, "the other file passes: %s", err.msg);

	/* changed in place, same size: caught by its modification time */
	struct timespec later[2] = {{0, UTIME_OMIT}, {time(NULL) + 5, 0}};
	int w = open(b, O_WRONLY);
	CHECK(w >= 0 && pwrite(w, "x", 1, 100) == 1 && futimens(w, later) == 0, "rewrite");
	if (w >= 0)
		close(w);
	CHECK(kg_mapfile_check(mb, &err) == KG_EIO && strstr(err.msg, "changed"),
	      "a file changed in place is caught: %s", err.msg);

	kg_mapfile_free(&ma);
	kg_mapfile_free(&mb);
	CHECK(!ma && !mb, "freed");
	/* slots are reused: many maps in turn */
	for (int i = 0; i < 200; i++) {
		int fd = open(b, O_RDONLY);
		kg_mapfile *m = NULL;
		const void *p = NULL;
		CHECK(fd >= 0 && kg_mapfile_open(fd, LEN, 0, b, &m, &p, &err) == 0, "map %d: %s", i,
		      err.msg);
		close(fd);
		kg_mapfile_free(&m);
	}
	unlink(a);
	unlink(b);
	return kg_test_failures ? 1 : 0;
}
