/* LD_PRELOAD shim serving the fake V4L2 device (fake_v4l2.c) to an unmodified program
 * at one path, so the real `kogei` binary can be tested end to end without a kernel
 * driver (no modules can be loaded here).
 *
 * Intercepted: open, open64, __open_2, __open64_2, openat, openat64, __openat_2 (the
 * fake path gives an eventfd), ioctl and mmap/mmap64 on those fds (served by the fake;
 * mmap maps its memfd), close (forgets the fd). poll needs no interception: the fd is
 * a real eventfd that the fake makes readable while a frame is ready. munmap needs
 * none either: the mapping is a real memfd mapping. It does not fool tools that issue
 * raw system calls (v4l2-ctl through libv4l2).
 *
 * Environment:
 *   KOGEI_FAKE_V4L2          the path served (default /dev/video-kogei-fake)
 *   KOGEI_FAKE_V4L2_FORMAT   the initial pixel format as a fourcc (default "Y16 ")
 *   KOGEI_FAKE_V4L2_SIZE     sensor size WxH (default 160x120)
 *   KOGEI_FAKE_V4L2_STALL    1: no frame is ever delivered */
#undef _FILE_OFFSET_BITS /* define open and mmap under their own names */

#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <linux/videodev2.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include "fake_v4l2.h"

/* glibc's fortified entry points, declared only under _FORTIFY_SOURCE. */
int __open_2(const char *path, int flags);
int __open64_2(const char *path, int flags);
int __openat_2(int dirfd, const char *path, int flags);
int open64(const char *path, int flags, ...);
int openat64(int dirfd, const char *path, int flags, ...);
void *mmap64(void *addr, size_t length, int prot, int flags, int fd, off_t offset);

/* Recursive: the fake itself calls mmap and close, which come back through here. */
static pthread_mutex_t lock = PTHREAD_RECURSIVE_MUTEX_INITIALIZER_NP;
static fake_v4l2 *dev;

static void *real(const char *name)
{
	void *p = dlsym(RTLD_NEXT, name);
	if (!p) {
		fprintf(stderr, "fake_video_preload: no next definition of %s\n", name);
		abort();
	}
	return p;
}

static int is_fake(const char *path)
{
	const char *p = getenv("KOGEI_FAKE_V4L2");
	return !strcmp(path, p && *p ? p : "/dev/video-kogei-fake");
}

static fake_v4l2 *make_device(void)
{
	uint32_t formats[] = {V4L2_PIX_FMT_Y16,    V4L2_PIX_FMT_GREY,  V4L2_PIX_FMT_Y12,
	                      V4L2_PIX_FMT_SRGGB8, V4L2_PIX_FMT_SRGGB12, V4L2_PIX_FMT_RGB24,
	                      V4L2_PIX_FMT_YUYV,   V4L2_PIX_FMT_MJPEG};
	fake_v4l2_config cfg = {.formats = formats,
	                        .nformats = (int)(sizeof(formats) / sizeof(formats[0])),
	                        .width = 160,
	                        .height = 120};
	const char *fmt = getenv("KOGEI_FAKE_V4L2_FORMAT");
	if (fmt && strlen(fmt) >= 3) { /* "Y16" stands for "Y16 " */
		uint32_t want = v4l2_fourcc(fmt[0], fmt[1], fmt[2], fmt[3] ? fmt[3] : ' ');
		for (int i = 1; i < cfg.nformats; i++)
			if (formats[i] == want) {
				formats[i] = formats[0];
				formats[0] = want;
			}
	}
	const char *size = getenv("KOGEI_FAKE_V4L2_SIZE");
	if (size && sscanf(size, "%dx%d", &cfg.width, &cfg.height) != 2) {
		fprintf(stderr, "fake_video_preload: KOGEI_FAKE_V4L2_SIZE '%s': expected WxH\n",
		        size);
		abort();
	}
	const char *stall = getenv("KOGEI_FAKE_V4L2_STALL");
	cfg.stall = stall && !strcmp(stall, "1");
	/* the n-th frame (1-based) flagged V4L2_BUF_FLAG_ERROR, or 100 bytes short */
	const char *error_at = getenv("KOGEI_FAKE_V4L2_ERROR_AT");
	const char *short_at = getenv("KOGEI_FAKE_V4L2_SHORT_AT");
	cfg.error_at = error_at ? atoi(error_at) : 0;
	cfg.short_at = short_at ? atoi(short_at) : 0;
	return fake_v4l2_new(&cfg);
}

static int open_fake(void)
{
	pthread_mutex_lock(&lock);
	if (!dev)
		dev = make_device();
	int fd = dev ? fake_v4l2_open(dev) : -1;
	if (!dev)
		errno = ENOMEM;
	pthread_mutex_unlock(&lock);
	return fd;
}

static int owned(int fd)
{
	pthread_mutex_lock(&lock);
	int yes = dev && fake_v4l2_owns(dev, fd);
	pthread_mutex_unlock(&lock);
	return yes;
}

/* The mode argument exists only with O_CREAT or O_TMPFILE. */
#define MODE_ARG(flags, last)                                                            \
	mode_t mode = 0;                                                                     \
	if ((flags) & (O_CREAT | O_TMPFILE)) {                                               \
		va_list ap;                                                                      \
		va_start(ap, last);                                                              \
		mode = (mode_t)va_arg(ap, int);                                                  \
		va_end(ap);                                                                      \
	}

int open(const char *path, int flags, ...)
{
	if (is_fake(path))
		return open_fake();
	MODE_ARG(flags, flags)
	int (*next)(const char *, int, ...) = real("open");
	return next(path, flags, mode);
}

int open64(const char *path, int flags, ...)
{
	if (is_fake(path))
		return open_fake();
	MODE_ARG(flags, flags)
	int (*next)(const char *, int, ...) = real("open64");
	return next(path, flags, mode);
}

int __open_2(const char *path, int flags)
{
	if (is_fake(path))
		return open_fake();
	int (*next)(const char *, int) = real("__open_2");
	return next(path, flags);
}

int __open64_2(const char *path, int flags)
{
	if (is_fake(path))
		return open_fake();
	int (*next)(const char *, int) = real("__open64_2");
	return next(path, flags);
}

int openat(int dirfd, const char *path, int flags, ...)
{
	if (is_fake(path))
		return open_fake();
	MODE_ARG(flags, flags)
	int (*next)(int, const char *, int, ...) = real("openat");
	return next(dirfd, path, flags, mode);
}

int openat64(int dirfd, const char *path, int flags, ...)
{
	if (is_fake(path))
		return open_fake();
	MODE_ARG(flags, flags)
	int (*next)(int, const char *, int, ...) = real("openat64");
	return next(dirfd, path, flags, mode);
}

int __openat_2(int dirfd, const char *path, int flags)
{
	if (is_fake(path))
		return open_fake();
	int (*next)(int, const char *, int) = real("__openat_2");
	return next(dirfd, path, flags);
}

int ioctl(int fd, unsigned long request, ...)
{
	va_list ap;
	va_start(ap, request);
	void *arg = va_arg(ap, void *);
	va_end(ap);
	if (owned(fd)) {
		pthread_mutex_lock(&lock);
		int ret = fake_v4l2_ioctl(dev, fd, request, arg);
		int e = errno;
		pthread_mutex_unlock(&lock);
		errno = e;
		return ret;
	}
	int (*next)(int, unsigned long, ...) = real("ioctl");
	return next(fd, request, arg);
}

static void *fake_mmap(void *addr, size_t length, int prot, int flags, int fd, off_t offset,
                       const char *name)
{
	if (owned(fd)) {
		pthread_mutex_lock(&lock);
		void *p = fake_v4l2_mmap(dev, addr, length, prot, flags, fd, offset);
		int e = errno;
		pthread_mutex_unlock(&lock);
		errno = e;
		return p;
	}
	void *(*next)(void *, size_t, int, int, int, off_t) = real(name);
	return next(addr, length, prot, flags, fd, offset);
}

void *mmap(void *addr, size_t length, int prot, int flags, int fd, off_t offset)
{
	return fake_mmap(addr, length, prot, flags, fd, offset, "mmap");
}

void *mmap64(void *addr, size_t length, int prot, int flags, int fd, off_t offset)
{
	return fake_mmap(addr, length, prot, flags, fd, offset, "mmap64");
}

int close(int fd)
{
	pthread_mutex_lock(&lock);
	if (dev && fake_v4l2_owns(dev, fd))
		fake_v4l2_release(dev, fd);
	pthread_mutex_unlock(&lock);
	int (*next)(int) = real("close");
	return next(fd);
}
