/* Paths below a root with no symbolic link on the way (kg_open_below, kg_stat_below,
 * kg_check_below, kg_mkdir_below, kg_read_below): real files and folders are reached
 * and made; a link as a folder of the path or as its last component, an absolute path
 * and ".." are refused with KG_EINVAL naming the link, and nothing is created or
 * written where the link points. */
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "kg_core.h"
#include "kg_test.h"

static int is_empty_dir(const char *p)
{
	char cmd[600];
	snprintf(cmd, sizeof(cmd), "test -z \"$(ls -A '%s')\"", p);
	return system(cmd) == 0;
}

int main(void)
{
	char root[] = "/tmp/kg_below_XXXXXX", out[] = "/tmp/kg_below_out_XXXXXX";
	CHECK(mkdtemp(root) && mkdtemp(out), "mkdtemp");
	char p[600], want[700];
	kg_err e = {{0}};

	/* made and reached */
	CHECK(kg_mkdir_below(root, "a/b/c", &e) == 0, "mkdir a/b/c: %s", e.msg);
	snprintf(p, sizeof(p), "%s/a/b/c", root);
	struct stat st;
	CHECK(stat(p, &st) == 0 && S_ISDIR(st.st_mode), "a/b/c not made");
	CHECK(kg_mkdir_below(root, "a/b/c", &e) == 0, "mkdir a/b/c again: %s", e.msg);
	int fd = kg_open_below(root, "a/b/f.txt", O_WRONLY | O_CREAT | O_TRUNC, 0644, &e);
	CHECK(fd >= 0, "open a/b/f.txt: %s", e.msg);
	if (fd >= 0) {
		CHECK(write(fd, "hello", 5) == 5, "write");
		close(fd);
	}
	char *buf = NULL;
	size_t len = 0;
	CHECK(kg_read_below(root, "a/b/f.txt", &buf, &len, &e) == 0 && len == 5 &&
	          !memcmp(buf, "hello", 5), "read a/b/f.txt: %s", e.msg);
	free(buf);
	CHECK(kg_stat_below(root, "a/b/f.txt", &st, &e) == 0 && S_ISREG(st.st_mode) &&
	          st.st_size == 5, "stat a/b/f.txt: %s", e.msg);
	CHECK(kg_check_below(root, "a/nothing/here", &e) == 0, "a missing path is no link");
	CHECK(kg_stat_below(root, "a/nothing", &st, &e) == KG_ENOENT, "stat of a missing path");

	/* links: a folder on the way, the last component, dangling */
	snprintf(p, sizeof(p), "%s/a/out", root);
	CHECK(symlink(out, p) == 0, "symlink");
	snprintf(p, sizeof(p), "%s/a/file-link", root);
	CHECK(symlink("/etc/passwd", p) == 0, "symlink");
	snprintf(p, sizeof(p), "%s/a/dangling", root);
	snprintf(want, sizeof(want), "%s/not-yet", out);
	CHECK(symlink(want, p) == 0, "symlink");
	static const struct {
		const char *rel, *link;
	} cases[] = {
		{"a/out", "a/out"},           {"a/out/x", "a/out"},   {"a/out/x/y", "a/out"},
		{"a/file-link", "a/file-link"}, {"a/dangling", "a/dangling"},
		{"a/dangling/z", "a/dangling"},
	};
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		snprintf(want, sizeof(want), "%s/%s: is a symbolic link", root, cases[i].link);
		memset(&e, 0, sizeof(e));
		int r = kg_mkdir_below(root, cases[i].rel, &e);
		CHECK(r == KG_EINVAL && strstr(e.msg, want), "mkdir %s: %d %s", cases[i].rel, r, e.msg);
		memset(&e, 0, sizeof(e));
		fd = kg_open_below(root, cases[i].rel, O_WRONLY | O_CREAT | O_APPEND, 0644, &e);
		CHECK(fd == KG_EINVAL && strstr(e.msg, want), "open %s: %d %s", cases[i].rel, fd,
		      e.msg);
		if (fd >= 0)
			close(fd);
		memset(&e, 0, sizeof(e));
		r = kg_check_below(root, cases[i].rel, &e);
		CHECK(r == KG_EINVAL && strstr(e.msg, want), "check %s: %d %s", cases[i].rel, r, e.msg);
		memset(&e, 0, sizeof(e));
		buf = NULL;
		r = kg_read_below(root, cases[i].rel, &buf, &len, &e);
		CHECK(r == KG_EINVAL && !buf && strstr(e.msg, want), "read %s: %d %s", cases[i].rel, r,
		      e.msg);
	}
	CHECK(is_empty_dir(out), "something was made where a link points");

	/* not below the root at all */
	static const char *const bad[] = {"/etc/passwd", "../x", "a/../../x", "a/./b", "", "a//b"};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		memset(&e, 0, sizeof(e));
		fd = kg_open_below(root, bad[i], O_RDONLY, 0, &e);
		CHECK(fd == KG_EINVAL && strstr(e.msg, "expected"), "open '%s': %d %s", bad[i], fd,
		      e.msg);
		if (fd >= 0)
			close(fd);
	}

	char cmd[700];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s' '%s'", root, out);
	CHECK(system(cmd) == 0, "cleanup");
	return kg_test_done("core-below");
}
