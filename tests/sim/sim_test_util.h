/* Helpers shared by the sim tests: a scratch directory and running the kogei
 * program (its path is the test's first argument) with stderr captured. */
#ifndef SIM_TEST_UTIL_H
#define SIM_TEST_UTIL_H

#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "kg_test.h"


static inline void sim_write_text(const char *path, const char *text)
{
	FILE *fp = fopen(path, "w");
	if (!fp || fputs(text, fp) < 0 || fclose(fp) != 0) {
		perror(path);
		exit(1);
	}
}

/* Number of entries in the scratch directory (to see nothing was left behind). */
static inline int sim_scratch_count(void)
{
	char cmd[4200];
	snprintf(cmd, sizeof(cmd), "ls -A '%s' | wc -l", kg_test_scratch());
	FILE *p = popen(cmd, "r");
	int n = -1;
	if (p) {
		if (fscanf(p, "%d", &n) != 1)
			n = -1;
		pclose(p);
	}
	return n;
}

/* Run argv (argv[0] = path of kogei, NULL-terminated); return its exit status and
 * put what it printed on stderr into errbuf. */
static inline int sim_run(char *const argv[], char *errbuf, size_t errlen)
{
	char errpath[4352];
	snprintf(errpath, sizeof(errpath), "%s/.stderr", kg_test_scratch());
	pid_t pid = fork();
	if (pid < 0) {
		perror("fork");
		exit(1);
	}
	if (pid == 0) {
		int fd = open(errpath, O_WRONLY | O_CREAT | O_TRUNC, 0644);
		int null = open("/dev/null", O_WRONLY);
		if (fd < 0 || null < 0)
			_exit(127);
		dup2(fd, 2);
		dup2(null, 1);
		execv(argv[0], argv);
		_exit(127);
	}
	int status = 0;
	waitpid(pid, &status, 0);
	errbuf[0] = '\0';
	FILE *fp = fopen(errpath, "r");
	if (fp) {
		size_t n = fread(errbuf, 1, errlen - 1, fp);
		errbuf[n] = '\0';
		fclose(fp);
	}
	unlink(errpath);
	return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}

#endif
