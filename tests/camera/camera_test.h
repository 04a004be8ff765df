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
