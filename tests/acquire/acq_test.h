/* Helpers of the acquire tests: a scratch directory, running `kogei` (argv[1]) with a
 * time limit, and checking a session directory independently of acquire/ (jansson
 * and OpenSSL directly). */
#ifndef ACQ_TEST_H
#define ACQ_TEST_H

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <jansson.h>
#include <openssl/evp.h>

#include "kg_test.h"

static const char *acq_kogei;

static inline void acq_init(int argc, char **argv, const char *tag)
{
	if (argc < 2) {
		fprintf(stderr, "usage: %s KOGEI\n", argv[0]);
		exit(1);
	}
	acq_kogei = argv[1];
	kg_test_scratch_dir(tag);
}

static inline void acq_cleanup(void)
{
	if (kg_test_failures)
		fprintf(stderr, "files kept in %s\n", kg_test_scratch());
	else
		kg_test_scratch_remove();
}

static char acq_out[1 << 16], acq_errtext[1 << 16];

static inline void acq_slurp(const char *path, char *buf, size_t len)
{
	buf[0] = 0;
	FILE *f = fopen(path, "rb");
	if (!f)
		return;
	size_t n = fread(buf, 1, len - 1, f);
	buf[n] = 0;
	fclose(f);
}

/* Start kogei with the NULL-terminated arguments; stdout and stderr to scratch files. */
static inline pid_t acq_spawn(char *const *args)
{
	char *argv[64];
	int n = 0;
	argv[n++] = (char *)acq_kogei;
	for (int i = 0; args[i] && n < 63; i++)
		argv[n++] = args[i];
	argv[n] = NULL;
	fflush(NULL);
	pid_t pid = fork();
	if (pid == 0) {
		char po[4200], pe[4200];
		snprintf(po, sizeof(po), "%s/stdout.txt", kg_test_scratch());
		snprintf(pe, sizeof(pe), "%s/stderr.txt", kg_test_scratch());
		int o = open(po, O_WRONLY | O_CREAT | O_TRUNC, 0644);
		int e = open(pe, O_WRONLY | O_CREAT | O_TRUNC, 0644);
		dup2(o, 1);
		dup2(e, 2);
		execv(acq_kogei, argv);
		_exit(127);
	}
	return pid;
}

/* Wait for pid at most timeout_s seconds (then SIGKILL it); the exit status, or -1. */
static inline int acq_wait(pid_t pid, double timeout_s)
{
	struct timespec t0, now;
	clock_gettime(CLOCK_MONOTONIC, &t0);
	for (;;) {
		int st;
		pid_t r = waitpid(pid, &st, WNOHANG);
		if (r == pid) {
			char po[4200], pe[4200];
			snprintf(po, sizeof(po), "%s/stdout.txt", kg_test_scratch());
			snprintf(pe, sizeof(pe), "%s/stderr.txt", kg_test_scratch());
			acq_slurp(po, acq_out, sizeof(acq_out));
			acq_slurp(pe, acq_errtext, sizeof(acq_errtext));
			return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
		}
		clock_gettime(CLOCK_MONOTONIC, &now);
		if ((double)(now.tv_sec - t0.tv_sec) + 1e-9 * (double)(now.tv_nsec - t0.tv_nsec) >
		    timeout_s) {
			fprintf(stderr, "kogei did not finish in %.0f s: killed\n", timeout_s);
			kill(pid, SIGKILL);
			waitpid(pid, &st, 0);
			return -1;
		}
		usleep(2000);
	}
}

/* Run kogei with the arguments (NULL-terminated) and return its exit status. */
static inline int acq_run(const char *first, ...)
{
	char *args[64];
	int n = 0;
	va_list ap;
	va_start(ap, first);
	for (const char *a = first; a && n < 63; a = va_arg(ap, const char *))
		args[n++] = (char *)a;
	va_end(ap);
	args[n] = NULL;
	return acq_wait(acq_spawn(args), 60);
}

static inline int acq_sha256_file(const char *path, char hex[65])
{
	FILE *f = fopen(path, "rb");
	if (!f)
		return -1;
	EVP_MD_CTX *ctx = EVP_MD_CTX_new();
	EVP_DigestInit_ex(ctx, EVP_sha256(), NULL);
	unsigned char buf[1 << 15], md[EVP_MAX_MD_SIZE];
	size_t n;
	while ((n = fread(buf, 1, sizeof(buf), f)) > 0)
		EVP_DigestUpdate(ctx, buf, n);
	unsigned len = 0;
	EVP_DigestFinal_ex(ctx, md, &len);
	EVP_MD_CTX_free(ctx);
	fclose(f);
	for (unsigned i = 0; i < len; i++)
		snprintf(hex + 2 * i, 3, "%02x", md[i]);
	return 0;
}

/* Check one {file, sha256} entry of the manifest; 0 when the file matches. */
static inline int acq_check_entry(const char *session, const json_t *e, const char *where)
{
	const char *file = json_string_value(json_object_get(e, "file"));
	const char *sha = json_string_value(json_object_get(e, "sha256"));
	if (!file || !sha) {
		fprintf(stderr, "%s: %s: no file/sha256\n", session, where);
		return -1;
	}
	char path[8192], got[65];
	snprintf(path, sizeof(path), "%s/%s", session, file);
	if (acq_sha256_file(path, got)) {
		fprintf(stderr, "%s: %s: %s is missing\n", session, where, file);
		return -1;
	}
	if (strcmp(got, sha)) {
		fprintf(stderr, "%s: %s: %s has sha256 %s, the manifest says %s\n", session, where,
		        file, got, sha);
		return -1;
	}
	return 0;
}

/* Parse SESSION/session.json and check every referenced file; the number of captures
 * (names copied into names[] when given), or -1 with the reason printed. */
static inline int acq_check_session(const char *session, char names[][64], int max_names)
{
	char path[8192];
	snprintf(path, sizeof(path), "%s/session.json", session);
	json_error_t je;
	json_t *root = json_load_file(path, 0, &je);
	if (!root) {
		fprintf(stderr, "%s: line %d: %s\n", path, je.line, je.text);
		return -1;
	}
	int bad = 0;
	const char *format = json_string_value(json_object_get(root, "format"));
	if (!format || strcmp(format, "kogei-session/1")) {
		fprintf(stderr, "%s: format %s\n", path, format ? format : "(none)");
		bad = 1;
	}
	json_t *caps = json_object_get(root, "captures"), *c, *e;
	size_t i, k;
	const char *key;
	json_array_foreach(caps, i, c)
	{
		const char *name = json_string_value(json_object_get(c, "name"));
		if (names && (int)i < max_names)
			snprintf(names[i], 64, "%s", name ? name : "");
		json_array_foreach(json_object_get(c, "frames"), k, e) bad |=
			acq_check_entry(session, e, "frame") != 0;
		if (json_object_size(json_object_get(c, "outputs")) < 2) {
			fprintf(stderr, "%s: capture %s has no outputs\n", path, name);
			bad = 1;
		}
		json_object_foreach(json_object_get(c, "outputs"), key, e) bad |=
			acq_check_entry(session, e, key) != 0;
	}
	int n = bad ? -1 : (int)json_array_size(caps);
	json_decref(root);
	return n;
}

/* The session's manifest (caller decrefs), or NULL. */
static inline json_t *acq_manifest(const char *session)
{
	char path[8192];
	snprintf(path, sizeof(path), "%s/session.json", session);
	return json_load_file(path, 0, NULL);
}

/* Whole-file comparison; 0 when both exist and are equal. */
static inline int acq_same_file(const char *a, const char *b)
{
	return kg_test_same_file(a, b) ? 0 : -1;
}

#endif
