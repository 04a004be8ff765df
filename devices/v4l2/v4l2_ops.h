/* The system calls the V4L2 backend makes, as a table of function pointers (private to
 * devices/v4l2 and its tests). The default calls libc on the real /dev/video* nodes;
 * tests install a fake device so the whole backend runs without a kernel driver
 * (no modules can be loaded here: no vivid, no v4l2loopback).
 *
 * Every entry behaves like the libc call it stands for: -1 (MAP_FAILED for mmap) with
 * errno set on failure. `user` is passed back unchanged. */
#ifndef KG_V4L2_OPS_H
#define KG_V4L2_OPS_H

#include <poll.h>
#include <stddef.h>
#include <sys/types.h>

typedef struct kg_v4l2_ops {
	void *user;
	int (*open)(void *user, const char *path, int flags);
	int (*close)(void *user, int fd);
	int (*ioctl)(void *user, int fd, unsigned long request, void *arg);
	void *(*mmap)(void *user, void *addr, size_t length, int prot, int flags, int fd,
	              off_t offset);
	int (*munmap)(void *user, void *addr, size_t length);
	int (*poll)(void *user, struct pollfd *fds, nfds_t nfds, int timeout_ms);
	/* Call each(path, ctx) for every V4L2 node that may be a camera, in a stable
	 * order; the default lists /dev/video<N> by N. Returns 0 or -1 with errno. */
	int (*scan)(void *user, void (*each)(const char *path, void *ctx), void *ctx);
} kg_v4l2_ops;

/* Install ops for cameras opened (and enumerations started) from now on; NULL restores
 * the libc implementation. A camera keeps the ops it was opened with. Not thread-safe:
 * tests call it before opening anything. */
void kg_v4l2_set_ops(const kg_v4l2_ops *ops);

#endif
