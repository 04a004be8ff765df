/* Fake V4L2 devices behind the backend's ops table, in-process: the paths given to
 * fake_ops_add open fake devices, every other path is ENOENT; scan lists the fake
 * paths in the order added. poll and munmap are the real ones (the fds are eventfds,
 * the buffers memfd mappings). */
#ifndef FAKE_OPS_H
#define FAKE_OPS_H

#include "fake_v4l2.h"
#include "v4l2_ops.h"

#define FAKE_OPS_MAX 4

typedef struct fake_ops {
	kg_v4l2_ops ops; /* ops.user points back here */
	struct {
		char path[64];
		fake_v4l2 *dev;
	} node[FAKE_OPS_MAX];
	int n;
} fake_ops;

/* Start an empty table and install it with kg_v4l2_set_ops. */
void fake_ops_install(fake_ops *o);
/* Serve dev at path (the table does not own dev). */
void fake_ops_add(fake_ops *o, const char *path, fake_v4l2 *dev);

#endif
