/* kg_atomicfile (core/fsutil.h) in both of its modes, anonymous (O_TMPFILE) and named
 * (KOGEI_TMPFILE=named, the fallback of file systems without O_TMPFILE): nothing of a
 * file under construction is visible under its final name, an abandoned one leaves
 * no entry, a committed one replaces the earlier file; temporaries of kogei's pattern
 * whose process is dead are removed when a writer opens in their directory, those of
 * a live process are kept; SIGTERM during a named write removes the temporary and
 * still ends the process with SIGTERM. */
#include <dirent.h>
#include <signal.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "kg_core.h"
#include "kg_test.h"

static char dir[] = "/tmp/kogei-atomicfile-XXXXXX";

static int entries(void)
{
	int n = 0;
	DIR *d = opendir(dir);
	for (struct dirent *e; d && (e = readdir(d));)
		n += strcmp(e->d_name, ".") && strcmp(e->d_name, "..");
	if (d)
		closedir(d);
	return n;
}

static void slurp(const char *path, char *buf, size_t n)
{
	buf[0] = '\0';
	FILE *f = fopen(path, "r");
	if (f) {
		buf[fread(buf, 1, n - 1, f)] = '\0';
		fclose(f);
	}
}

static void touch(const char *path)
{
	FILE *f = fopen(path, "w");
	if (f)
		fclose(f);
}

static void modes(const char *mode)
{
	char path[256], buf[64];
	kg_err err = {{0}};
	snprintf(path, sizeof(path), "%s/out-%s.txt", dir, mode);
	setenv("KOGEI_TMPFILE", mode, 1);
	int named = !strcmp(mode, "named");

	kg_outfile o;
	CHECK(kg_outfile_open(&o, path, 0, &err) == 0, "%s: %s", mode, err.msg);
	fputs("first", o.fp);
	CHECK(entries() == named, "%s: %d entries while writing", mode, entries());
	CHECK(!kg_test_file_exists(path), "%s: the final name exists before commit", mode);
	CHECK(named == (o.tmp.tmp_path != NULL), "%s: tmp_path %s", mode,
	      o.tmp.tmp_path ? o.tmp.tmp_path : "NULL");
	kg_outfile_abort(&o);
	CHECK(entries() == 0, "%s: abort left %d entries", mode, entries());

	for (int i = 0; i < 2; i++) {
		CHECK(kg_outfile_open(&o, path, 0, &err) == 0, "%s: %s", mode, err.msg);
		fputs(i ? "second" : "first", o.fp);
		CHECK(kg_outfile_commit(&o, &err) == 0, "%s: %s", mode, err.msg);
		slurp(path, buf, sizeof(buf));
		CHECK(!strcmp(buf, i ? "second" : "first"), "%s: reads '%s'", mode, buf);
		CHECK(entries() == 1, "%s: %d entries after commit %d", mode, entries(), i);
	}
	unlink(path);
}

/* SIGTERM while a named temporary is open: gone, and the child dies of SIGTERM. */
static void signalled(void)
{
	char path[256];
	snprintf(path, sizeof(path), "%s/signalled.txt", dir);
	int ready[2];
	CHECK(pipe(ready) == 0, "pipe");
	fflush(NULL);
	pid_t pid = fork();
	if (pid == 0) {
		setenv("KOGEI_TMPFILE", "named", 1);
		kg_outfile o;
		kg_err err = {{0}};
		if (kg_outfile_open(&o, path, 0, &err) != 0)
			_exit(3);
		fputs("partial", o.fp);
		fflush(o.fp);
		if (write(ready[1], "x", 1) != 1)
			_exit(4);
		pause();
		_exit(5);
	}
	char c;
	CHECK(read(ready[0], &c, 1) == 1, "the child did not open its file");
	CHECK(entries() == 1, "%d entries while the child writes", entries());
	kill(pid, SIGTERM);
	int st = 0;
	waitpid(pid, &st, 0);
	CHECK(WIFSIGNALED(st) && WTERMSIG(st) == SIGTERM, "child status %#x", st);
	CHECK(entries() == 0, "SIGTERM left %d entries", entries());
	close(ready[0]);
	close(ready[1]);
}

static void stale(void)
{
	pid_t dead = fork();
	if (dead == 0)
		_exit(0);
	waitpid(dead, NULL, 0);
	char dead_tmp[256], live_tmp[256], other[256], path[256];
	snprintf(dead_tmp, sizeof(dead_tmp), "%s/.cube.img.kogei-tmp.%ld.Ab3dE9", dir, (long)dead);
	snprintf(live_tmp, sizeof(live_tmp), "%s/.cube.img.kogei-tmp.%ld.Zz0000", dir,
	         (long)getppid());
	snprintf(other, sizeof(other), "%s/cube.img.tmp.123456", dir); /* not kogei's pattern */
	snprintf(path, sizeof(path), "%s/new.txt", dir);
	touch(dead_tmp);
	touch(live_tmp);
	touch(other);
	unsetenv("KOGEI_TMPFILE");
	kg_outfile o;
	kg_err err = {{0}};
	CHECK(kg_outfile_open(&o, path, 0, &err) == 0, "%s", err.msg);
	kg_outfile_abort(&o);
	CHECK(!kg_test_file_exists(dead_tmp), "the dead process's temporary is still there");
	CHECK(kg_test_file_exists(live_tmp), "a live process's temporary was removed");
	CHECK(kg_test_file_exists(other), "a file of another pattern was removed");
	unlink(live_tmp);
	unlink(other);
}

int main(void)
{
	if (!mkdtemp(dir)) {
		perror("mkdtemp");
		return 1;
	}
	modes("anonymous");
	modes("named");
	signalled();
	stale();
	rmdir(dir);
	return kg_test_done("atomicfile");
}
