/* Helpers shared by the camera tests: a scratch directory, scene images, and popping
 * frames with the error printed. */
#ifndef CAMERA_TEST_H
#define CAMERA_TEST_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "kg_camera.h"
#include "kg_test.h"

static char cam_scratch[4096];

/* A fresh directory under $TMPDIR (or /tmp); cam_scratch_remove deletes it. */
static inline const char *cam_scratch_dir(const char *tag)
{
	const char *tmp = getenv("TMPDIR");
	snprintf(cam_scratch, sizeof(cam_scratch), "%s/kogei-%s-XXXXXX",
	         tmp && *tmp ? tmp : "/tmp", tag);
	if (!mkdtemp(cam_scratch)) {
		perror("mkdtemp");
		exit(1);
	}
	return cam_scratch;
}

static inline void cam_scratch_remove(void)
{
	char cmd[4200];
	if (!cam_scratch[0])
		return;
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", cam_scratch);
	if (system(cmd) != 0)
		fprintf(stderr, "could not remove %s\n", cam_scratch);
}

/* "<scratch>/<name>" in a ring of buffers (valid for the next 15 calls). */
static inline const char *cam_path(const char *name)
{
	static char ring[16][4352];
	static int next;
	char *p = ring[next++ % 16];
	snprintf(p, sizeof(ring[0]), "%s/%s", cam_scratch, name);
	return p;
}

/* Exit 1 with the message when a setup step fails (later checks would be noise). */
static inline void cam_must(int ret, const kg_err *e, const char *what)
{
	if (ret) {
		fprintf(stderr, "%s failed (%d): %s\n", what, ret, e->msg);
		exit(1);
	}
}

static inline kg_camera *cam_open(const char *uri)
{
	kg_camera *c = NULL;
	kg_err e = {{0}};
	cam_must(kg_camera_open(uri, &c, &e), &e, uri);
	return c;
}

/* Sample (x, y, channel) of a frame as a number (8- or 16-bit little-endian words). */
static inline unsigned cam_sample(const kg_frame *f, int x, int y, int c)
{
	int ch = kg_pixfmt_channels(f->fmt.pixfmt);
	int wide = kg_pixfmt_bytes_per_pixel(f->fmt.pixfmt) / ch == 2;
	const unsigned char *row = (const unsigned char *)f->data + f->fmt.stride * (size_t)y;
	size_t i = (size_t)x * (size_t)ch + (size_t)c;
	return wide ? (unsigned)(row[2 * i] | row[2 * i + 1] << 8) : row[i];
}

#endif
