/* The fake V4L2 devices behind the backend's ops table (see fake_ops.h). */
#include "fake_ops.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

static fake_v4l2 *owner(fake_ops *o, int fd)
{
	for (int i = 0; i < o->n; i++)
		if (fake_v4l2_owns(o->node[i].dev, fd))
			return o->node[i].dev;
	return NULL;
}

static int f_open(void *user, const char *path, int flags)
{
	fake_ops *o = user;
	for (int i = 0; i < o->n; i++)
		if (!strcmp(o->node[i].path, path))
			return fake_v4l2_open(o->node[i].dev);
	errno = ENOENT;
	return -1;
}

static int f_close(void *user, int fd)
{
	fake_v4l2 *dev = owner(user, fd);
	if (dev)
		fake_v4l2_release(dev, fd);
	return close(fd);
}

static int f_ioctl(void *user, int fd, unsigned long request, void *arg)
{
	fake_v4l2 *dev = owner(user, fd);
	if (!dev) {
		errno = EBADF;
		return -1;
	}
	return fake_v4l2_ioctl(dev, fd, request, arg);
}

static void *f_mmap(void *user, void *addr, size_t length, int prot, int flags, int fd,
                    off_t offset)
{
	fake_v4l2 *dev = owner(user, fd);
	if (!dev) {
		errno = EBADF;
		return MAP_FAILED;
	}
	return fake_v4l2_mmap(dev, addr, length, prot, flags, fd, offset);
}

static int f_munmap(void *user, void *addr, size_t length) { return munmap(addr, length); }

static int f_poll(void *user, struct pollfd *fds, nfds_t nfds, int timeout_ms)
{
	return poll(fds, nfds, timeout_ms);
}

static int f_scan(void *user, void (*each)(const char *path, void *ctx), void *ctx)
{
	fake_ops *o = user;
	for (int i = 0; i < o->n; i++)
		each(o->node[i].path, ctx);
	return 0;
}

void fake_ops_install(fake_ops *o)
{
	memset(o, 0, sizeof(*o));
	o->ops = (kg_v4l2_ops){.user = o,
	                       .open = f_open,
	                       .close = f_close,
	                       .ioctl = f_ioctl,
	                       .mmap = f_mmap,
	                       .munmap = f_munmap,
	                       .poll = f_poll,
	                       .scan = f_scan};
	kg_v4l2_set_ops(&o->ops);
}

void fake_ops_add(fake_ops *o, const char *path, fake_v4l2 *dev)
{
	if (o->n == FAKE_OPS_MAX)
		return;
	snprintf(o->node[o->n].path, sizeof(o->node[o->n].path), "%s", path);
	o->node[o->n++].dev = dev;
}
