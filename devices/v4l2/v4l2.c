/* V4L2 capture devices (v4l2:/dev/videoN): single-planar capture with mmap streaming.
 *
 * Every system call goes through a kg_v4l2_ops table (v4l2_ops.h) so tests can put a
 * fake device behind it. UVC firmware shapes the control code: exposure mode must be
 * manual before an absolute exposure is accepted, some cameras silently keep auto
 * white balance on, and settings are applied late; so every write is read back with
 * VIDIOC_G_CTRL and what the camera settled on is what we report. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <linux/videodev2.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include "camera_driver.h"
#include "v4l2_ops.h"

/* ---- the libc ops -------------------------------------------------------------- */

static int libc_open(void *user, const char *path, int flags) { return open(path, flags); }

static int libc_close(void *user, int fd) { return close(fd); }

static int libc_ioctl(void *user, int fd, unsigned long request, void *arg)
{
	int r;
	do
		r = ioctl(fd, request, arg);
	while (r == -1 && errno == EINTR);
	return r;
}

static void *libc_mmap(void *user, void *addr, size_t length, int prot, int flags, int fd,
                       off_t offset)
{
	return mmap(addr, length, prot, flags, fd, offset);
}

static int libc_munmap(void *user, void *addr, size_t length) { return munmap(addr, length); }

static int libc_poll(void *user, struct pollfd *fds, nfds_t nfds, int timeout_ms)
{
	return poll(fds, nfds, timeout_ms);
}

static int cmp_int(const void *a, const void *b)
{
	int x = *(const int *)a, y = *(const int *)b;
	return (x > y) - (x < y);
}

/* /dev/video<N>, sorted by N. */
static int libc_scan(void *user, void (*each)(const char *path, void *ctx), void *ctx)
{
	DIR *d = opendir("/dev");
	if (!d)
		return -1;
	int nums[256], n = 0;
	struct dirent *e;
	while ((e = readdir(d)) && n < (int)(sizeof(nums) / sizeof(nums[0]))) {
		char *end;
		if (strncmp(e->d_name, "video", 5) || !e->d_name[5])
			continue;
		long v = strtol(e->d_name + 5, &end, 10);
		if (!*end && v >= 0 && v < 100000)
			nums[n++] = (int)v;
	}
	closedir(d);
	qsort(nums, (size_t)n, sizeof(nums[0]), cmp_int);
	for (int i = 0; i < n; i++) {
		char path[32];
		snprintf(path, sizeof(path), "/dev/video%d", nums[i]);
		each(path, ctx);
	}
	return 0;
}

static const kg_v4l2_ops libc_ops = {
	.open = libc_open,
	.close = libc_close,
	.ioctl = libc_ioctl,
	.mmap = libc_mmap,
	.munmap = libc_munmap,
	.poll = libc_poll,
	.scan = libc_scan,
};

static const kg_v4l2_ops *current_ops = &libc_ops;

void kg_v4l2_set_ops(const kg_v4l2_ops *ops) { current_ops = ops ? ops : &libc_ops; }

/* ---- pixel formats ------------------------------------------------------------- */

/* In order of preference when a request leaves bits or the CFA open. */
static const struct fmt_map {
	uint32_t fourcc;
	kg_pixfmt pixfmt;
	int bits;
	char cfa[5];
} fmt_map[] = {
	{V4L2_PIX_FMT_GREY, KG_PIX_MONO8, 8, ""},
	{V4L2_PIX_FMT_Y16, KG_PIX_MONO16, 16, ""},
	{V4L2_PIX_FMT_Y14, KG_PIX_MONO16, 14, ""},
	{V4L2_PIX_FMT_Y12, KG_PIX_MONO16, 12, ""},
	{V4L2_PIX_FMT_Y10, KG_PIX_MONO16, 10, ""},
	{V4L2_PIX_FMT_SRGGB8, KG_PIX_BAYER8, 8, "RGGB"},
	{V4L2_PIX_FMT_SGRBG8, KG_PIX_BAYER8, 8, "GRBG"},
	{V4L2_PIX_FMT_SGBRG8, KG_PIX_BAYER8, 8, "GBRG"},
	{V4L2_PIX_FMT_SBGGR8, KG_PIX_BAYER8, 8, "BGGR"},
	{V4L2_PIX_FMT_SRGGB16, KG_PIX_BAYER16, 16, "RGGB"},
	{V4L2_PIX_FMT_SGRBG16, KG_PIX_BAYER16, 16, "GRBG"},
	{V4L2_PIX_FMT_SGBRG16, KG_PIX_BAYER16, 16, "GBRG"},
	{V4L2_PIX_FMT_SBGGR16, KG_PIX_BAYER16, 16, "BGGR"},
	{V4L2_PIX_FMT_SRGGB14, KG_PIX_BAYER16, 14, "RGGB"},
	{V4L2_PIX_FMT_SGRBG14, KG_PIX_BAYER16, 14, "GRBG"},
	{V4L2_PIX_FMT_SGBRG14, KG_PIX_BAYER16, 14, "GBRG"},
	{V4L2_PIX_FMT_SBGGR14, KG_PIX_BAYER16, 14, "BGGR"},
	{V4L2_PIX_FMT_SRGGB12, KG_PIX_BAYER16, 12, "RGGB"},
	{V4L2_PIX_FMT_SGRBG12, KG_PIX_BAYER16, 12, "GRBG"},
	{V4L2_PIX_FMT_SGBRG12, KG_PIX_BAYER16, 12, "GBRG"},
	{V4L2_PIX_FMT_SBGGR12, KG_PIX_BAYER16, 12, "BGGR"},
	{V4L2_PIX_FMT_SRGGB10, KG_PIX_BAYER16, 10, "RGGB"},
	{V4L2_PIX_FMT_SGRBG10, KG_PIX_BAYER16, 10, "GRBG"},
	{V4L2_PIX_FMT_SGBRG10, KG_PIX_BAYER16, 10, "GBRG"},
	{V4L2_PIX_FMT_SBGGR10, KG_PIX_BAYER16, 10, "BGGR"},
	{V4L2_PIX_FMT_RGB24, KG_PIX_RGB8, 8, ""},
	{V4L2_PIX_FMT_YUYV, KG_PIX_YUYV, 8, ""},
	{V4L2_PIX_FMT_MJPEG, KG_PIX_MJPEG, 8, ""},
	{V4L2_PIX_FMT_JPEG, KG_PIX_MJPEG, 8, ""},
};
#define NFMT_MAP (sizeof(fmt_map) / sizeof(fmt_map[0]))

static const struct fmt_map *fmt_by_fourcc(uint32_t fourcc)
{
	for (size_t i = 0; i < NFMT_MAP; i++)
		if (fmt_map[i].fourcc == fourcc)
			return &fmt_map[i];
	return NULL;
}

/* "YUYV", "Y16 ": the fourcc as text (trailing blanks kept: they are part of it). */
static const char *fourcc_text(uint32_t f, char out[5])
{
	for (int i = 0; i < 4; i++) {
		char ch = (char)((f >> (8 * i)) & 0xff);
		out[i] = ch >= 32 && ch < 127 ? ch : '?';
	}
	out[4] = 0;
	return out;
}

/* ---- the camera ---------------------------------------------------------------- */

#define MAX_BUFFERS 32
#define MAX_FORMATS 64
#define DEFAULT_BUFFERS 4

typedef struct v4l2_cam {
	const kg_v4l2_ops *ops;
	int fd;
	char path[256];
	uint32_t formats[MAX_FORMATS]; /* offered by VIDIOC_ENUM_FMT */
	int nformats;
	int has_selection; /* VIDIOC_G_SELECTION answers for the crop rectangle */
	uint32_t fourcc;   /* current format, from the last G_FMT */
	kg_frame_format fmt;
	struct {
		void *ptr;
		size_t length;
	} buf[MAX_BUFFERS];
	int nbuf;
	int streaming;
	size_t expected; /* bytes of a complete uncompressed frame */
	uint64_t failed, incomplete;
	int have_seq;
	uint32_t last_seq32;
	uint64_t seq_high; /* V4L2 sequence numbers are 32-bit: count the wraps */
} v4l2_cam;

/* ioctl through the ops table: 0 or -errno. */
static int xioctl(v4l2_cam *c, unsigned long request, void *arg)
{
	return c->ops->ioctl(c->ops->user, c->fd, request, arg) == -1 ? -errno : 0;
}

/* A failed ioctl as a KG_E* code: a vanished device is KG_ENODEV, a refused request
 * KG_ENOTSUP, a value out of range KG_ERANGE, anything else a device failure. */
static int errno_code(int neg_errno)
{
	switch (-neg_errno) {
	case ENODEV:
	case ENXIO:
		return KG_ENODEV;
	case ETIMEDOUT:
		return KG_ETIMEDOUT;
	case ERANGE:
		return KG_ERANGE;
	case EINVAL:
	case ENOTTY:
	case EACCES:
	case EPERM:
		return KG_ENOTSUP;
	default:
		return KG_EIO;
	}
}

static int ioctl_fail(kg_err *err, int ret, const char *what)
{
	return kg_fail(err, errno_code(ret), "%s failed: %s", what, strerror(-ret));
}

/* Fill c->fmt and c->fourcc from a v4l2_pix_format. */
static int fmt_from_pix(v4l2_cam *c, const struct v4l2_pix_format *pix, kg_err *err)
{
	char t[5];
	const struct fmt_map *m = fmt_by_fourcc(pix->pixelformat);
	c->fourcc = pix->pixelformat;
	memset(&c->fmt, 0, sizeof(c->fmt));
	if (!m)
		return kg_fail(err, KG_ENOTSUP,
		               "current pixel format %s is not one kogei reads (choose GREY, Y10, "
		               "Y12, Y16, Bayer 8-16 unpacked, RGB24, YUYV or MJPEG)",
		               fourcc_text(pix->pixelformat, t));
	kg_frame_format *f = &c->fmt;
	f->pixfmt = m->pixfmt;
	f->bits = m->bits;
	memcpy(f->cfa, m->cfa, sizeof(f->cfa));
	f->width = (int)pix->width;
	f->height = (int)pix->height;
	kg_frame_format_fill(f);
	if (m->pixfmt == KG_PIX_MJPEG) {
		f->stride = pix->bytesperline;
		if (pix->sizeimage)
			f->size = pix->sizeimage;
	} else {
		size_t tight = f->stride;
		if (pix->bytesperline > tight)
			f->stride = pix->bytesperline; /* rows padded by the driver */
		f->size = f->stride * (size_t)f->height;
	}
	return 0;
}

static int crop_get(v4l2_cam *c, int target, struct v4l2_rect *r)
{
	struct v4l2_selection s;
	memset(&s, 0, sizeof(s));
	s.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
	s.target = (uint32_t)target;
	int ret = xioctl(c, VIDIOC_G_SELECTION, &s);
	if (!ret)
		*r = s.r;
	return ret;
}

/* The capture format the device has now (VIDIOC_G_FMT). */
static int get_fmt(v4l2_cam *c, struct v4l2_format *vf, kg_err *err)
{
	memset(vf, 0, sizeof(*vf));
	vf->type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
	int ret = xioctl(c, VIDIOC_G_FMT, vf);
	return ret ? ioctl_fail(err, ret, "VIDIOC_G_FMT") : 0;
}

static int refresh_format(v4l2_cam *c, kg_err *err)
{
	struct v4l2_format vf;
	int ret = get_fmt(c, &vf, err);
	if (ret)
		return ret;
	if ((ret = fmt_from_pix(c, &vf.fmt.pix, err)))
		return ret;
	struct v4l2_rect r;
	if (c->has_selection && !crop_get(c, V4L2_SEL_TGT_CROP, &r)) {
		c->fmt.offset_x = r.left;
		c->fmt.offset_y = r.top;
	}
	return 0;
}

/* "YUYV (yuyv), Y16  (mono16), ..." for error messages. */
static void offered_list(const v4l2_cam *c, char *out, size_t len)
{
	size_t n = 0;
	out[0] = 0;
	for (int i = 0; i < c->nformats && n < len; i++) {
		char t[5];
		const struct fmt_map *m = fmt_by_fourcc(c->formats[i]);
		n += (size_t)snprintf(out + n, len - n, "%s%s (%s%s%s)", i ? ", " : "",
		                      fourcc_text(c->formats[i], t),
		                      m ? kg_pixfmt_name(m->pixfmt) : "not supported by kogei",
		                      m && m->cfa[0] ? " " : "", m ? m->cfa : "");
	}
	if (!c->nformats)
		snprintf(out, len, "none");
}

static int offered(const v4l2_cam *c, uint32_t fourcc)
{
	for (int i = 0; i < c->nformats; i++)
		if (c->formats[i] == fourcc)
			return 1;
	return 0;
}

/* ---- open, close, enumerate ---------------------------------------------------- */

/* Open a node and check it is a streaming capture device; *cap filled. Returns the fd
 * or a negative KG_E* code. */
static int open_capture(const kg_v4l2_ops *ops, const char *path, struct v4l2_capability *cap,
                        kg_err *err)
{
	int fd = ops->open(ops->user, path, O_RDWR | O_NONBLOCK | O_CLOEXEC);
	if (fd < 0) {
		int e = errno;
		if (e == ENOENT || e == ENODEV || e == ENXIO)
			return kg_fail(err, KG_ENODEV, "%s: no such device (%s)", path, strerror(e));
		if (e == EACCES || e == EPERM)
			return kg_fail(err, KG_EIO,
			               "%s: %s; the user needs access to video devices (the video "
			               "group, or the uaccess rule installed from udev/)",
			               path, strerror(e));
		return kg_fail(err, KG_EIO, "%s: cannot open: %s", path, strerror(e));
	}
	memset(cap, 0, sizeof(*cap));
	int ret = ops->ioctl(ops->user, fd, VIDIOC_QUERYCAP, cap) == -1 ? -errno : 0;
	const char *why = NULL;
	uint32_t caps = cap->capabilities & V4L2_CAP_DEVICE_CAPS ? cap->device_caps
	                                                         : cap->capabilities;
	if (ret)
		ret = kg_fail(err, ret == -ENOTTY || ret == -EINVAL ? KG_EINVAL : errno_code(ret),
		              "%s: VIDIOC_QUERYCAP failed: %s; expected a V4L2 device", path,
		              strerror(-ret));
	else if (!(caps & V4L2_CAP_VIDEO_CAPTURE))
		why = caps & V4L2_CAP_VIDEO_CAPTURE_MPLANE
		          ? "it captures only through the multi-planar API, which kogei does not "
		            "read (expected V4L2_CAP_VIDEO_CAPTURE)"
		          : "it is not a video capture node (no V4L2_CAP_VIDEO_CAPTURE; a UVC "
		            "camera's second node carries only metadata: use its first node)";
	else if (!(caps & V4L2_CAP_STREAMING))
		why = "it has no streaming I/O (expected V4L2_CAP_STREAMING for mmap streaming)";
	if (why)
		ret = kg_fail(err, KG_ENOTSUP, "%s (%.32s, driver %.16s, capabilities 0x%08x): %s",
		              path, (const char *)cap->card, (const char *)cap->driver, caps, why);
	if (ret) {
		ops->close(ops->user, fd);
		return ret;
	}
	return fd;
}

static const char *transport_of(const struct v4l2_capability *cap)
{
	return strcmp((const char *)cap->driver, "uvcvideo") ? "V4L2" : "UVC";
}

typedef struct scan_ctx {
	const kg_v4l2_ops *ops;
	kg_camera_found_fn found;
	void *user;
	int failures;
	kg_err first_failure;
} scan_ctx;

static void scan_one(const char *path, void *ctx)
{
	scan_ctx *s = ctx;
	struct v4l2_capability cap;
	kg_err e = {{0}};
	int fd = open_capture(s->ops, path, &cap, &e);
	if (fd == KG_ENOTSUP) /* metadata and output nodes are not cameras */
		return;
	if (fd < 0) {
		if (!s->failures++)
			s->first_failure = e;
		return;
	}
	s->ops->close(s->ops->user, fd);
	char uri[300];
	snprintf(uri, sizeof(uri), "v4l2:%s", path);
	s->found(s->user, uri, (const char *)cap.card, (const char *)cap.bus_info,
	         transport_of(&cap));
}

static int v4_enumerate(kg_camera_found_fn found, void *user, kg_err *err)
{
	scan_ctx s = {.ops = current_ops, .found = found, .user = user};
	if (s.ops->scan(s.ops->user, scan_one, &s))
		return kg_fail(err, KG_EIO, "cannot list video devices: %s", strerror(errno));
	if (s.failures)
		return kg_fail(err, KG_EIO, "%d video device(s) could not be examined; the first: %.900s",
		               s.failures, s.first_failure.msg);
	return 0;
}

static void v4_close(void *state)
{
	v4l2_cam *c = state;
	if (!c)
		return;
	if (c->fd >= 0)
		c->ops->close(c->ops->user, c->fd);
	free(c);
}

/* The whole sensor: the crop bounds when the device crops, else the largest frame size
 * of the current format, else the current size. */
static void sensor_size(v4l2_cam *c, int *w, int *h)
{
	struct v4l2_rect r;
	*w = c->fmt.width;
	*h = c->fmt.height;
	if (c->has_selection && !crop_get(c, V4L2_SEL_TGT_CROP_BOUNDS, &r)) {
		*w = (int)r.width;
		*h = (int)r.height;
		return;
	}
	struct v4l2_frmsizeenum fs;
	for (uint32_t i = 0; i < 256; i++) {
		memset(&fs, 0, sizeof(fs));
		fs.index = i;
		fs.pixel_format = c->fourcc;
		if (xioctl(c, VIDIOC_ENUM_FRAMESIZES, &fs))
			break;
		int fw = (int)(fs.type == V4L2_FRMSIZE_TYPE_DISCRETE ? fs.discrete.width
		                                                     : fs.stepwise.max_width);
		int fh = (int)(fs.type == V4L2_FRMSIZE_TYPE_DISCRETE ? fs.discrete.height
		                                                     : fs.stepwise.max_height);
		if ((long)fw * fh > (long)*w * *h) {
			*w = fw;
			*h = fh;
		}
		if (fs.type != V4L2_FRMSIZE_TYPE_DISCRETE)
			break;
	}
}

static int v4_open(const char *target, void **state, kg_camera_info *info, kg_err *err)
{
	if (!target || target[0] != '/')
		return kg_fail(err, KG_EINVAL, "expected a device path after v4l2: (v4l2:/dev/video0)");
	v4l2_cam *c = calloc(1, sizeof(*c));
	if (!c)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	c->ops = current_ops;
	snprintf(c->path, sizeof(c->path), "%s", target);
	struct v4l2_capability cap;
	c->fd = open_capture(c->ops, target, &cap, err);
	if (c->fd < 0) {
		int ret = c->fd;
		free(c);
		return ret;
	}
	for (uint32_t i = 0; c->nformats < MAX_FORMATS; i++) {
		struct v4l2_fmtdesc d;
		memset(&d, 0, sizeof(d));
		d.index = i;
		d.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
		if (xioctl(c, VIDIOC_ENUM_FMT, &d))
			break;
		c->formats[c->nformats++] = d.pixelformat;
	}
	struct v4l2_rect r;
	c->has_selection = !crop_get(c, V4L2_SEL_TGT_CROP, &r);
	/* A current format kogei cannot read is not an error yet: set_format picks one. */
	kg_err fmt_err = {{0}};
	int ret = refresh_format(c, &fmt_err);
	if (ret && !c->fourcc) {
		if (err)
			*err = fmt_err;
		v4_close(c);
		return ret;
	}
	snprintf(info->vendor, sizeof(info->vendor), "%.16s", (const char *)cap.driver);
	snprintf(info->model, sizeof(info->model), "%.32s", (const char *)cap.card);
	/* V4L2 has no serial number; the bus position names the camera instead. */
	snprintf(info->serial, sizeof(info->serial), "%.32s", (const char *)cap.bus_info);
	snprintf(info->transport, sizeof(info->transport), "%s", transport_of(&cap));
	sensor_size(c, &info->sensor_width, &info->sensor_height);
	*state = c;
	return 0;
}

/* ---- controls ------------------------------------------------------------------ */

static const char *cid_name(uint32_t id)
{
	switch (id) {
	case V4L2_CID_EXPOSURE_AUTO:
		return "V4L2_CID_EXPOSURE_AUTO";
	case V4L2_CID_EXPOSURE_ABSOLUTE:
		return "V4L2_CID_EXPOSURE_ABSOLUTE";
	case V4L2_CID_AUTOGAIN:
		return "V4L2_CID_AUTOGAIN";
	case V4L2_CID_GAIN:
		return "V4L2_CID_GAIN";
	case V4L2_CID_ANALOGUE_GAIN:
		return "V4L2_CID_ANALOGUE_GAIN";
	case V4L2_CID_AUTO_WHITE_BALANCE:
		return "V4L2_CID_AUTO_WHITE_BALANCE";
	case V4L2_CID_RED_BALANCE:
		return "V4L2_CID_RED_BALANCE";
	case V4L2_CID_BLUE_BALANCE:
		return "V4L2_CID_BLUE_BALANCE";
	default:
		return "control";
	}
}

/* 1 if the control exists and is not disabled (q filled), 0 if absent, <0 on error. */
static int query(v4l2_cam *c, uint32_t id, struct v4l2_queryctrl *q, kg_err *err)
{
	memset(q, 0, sizeof(*q));
	q->id = id;
	int ret = xioctl(c, VIDIOC_QUERYCTRL, q);
	if (ret == -EINVAL || ret == -ENOTTY)
		return 0;
	if (ret)
		return kg_fail(err, errno_code(ret), "%s: VIDIOC_QUERYCTRL failed: %s", cid_name(id),
		               strerror(-ret));
	return !(q->flags & V4L2_CTRL_FLAG_DISABLED);
}

static int g_ctrl(v4l2_cam *c, uint32_t id, int32_t *v, kg_err *err)
{
	struct v4l2_control ctl = {.id = id};
	int ret = xioctl(c, VIDIOC_G_CTRL, &ctl);
	if (ret)
		return kg_fail(err, errno_code(ret), "%s: VIDIOC_G_CTRL failed: %s", cid_name(id),
		               strerror(-ret));
	*v = ctl.value;
	return 0;
}

static int s_ctrl(v4l2_cam *c, uint32_t id, int32_t v, kg_err *err)
{
	struct v4l2_control ctl = {.id = id, .value = v};
	int ret = xioctl(c, VIDIOC_S_CTRL, &ctl);
	if (ret)
		return kg_fail(err, errno_code(ret), "%s: VIDIOC_S_CTRL to %d refused: %s",
		               cid_name(id), (int)v, strerror(-ret));
	return 0;
}

/* Write a mode control and verify it took: firmware that ignores the write is the
 * reason this exists (auto white balance that stays on). */
static int set_verified(v4l2_cam *c, uint32_t id, int32_t v, const char *meaning, kg_err *err)
{
	int32_t back = 0; /* g_ctrl sets it on success only; GCC cannot see kg_fail is nonzero */
	int ret = s_ctrl(c, id, v, err);
	if (!ret)
		ret = g_ctrl(c, id, &back, err);
	if (!ret && back != v)
		ret = kg_fail(err, KG_ENOTSUP,
		              "%s: wrote %d (%s) but the camera reads back %d: its firmware keeps "
		              "the automatic setting, so frames from it are not fit for measurement",
		              cid_name(id), (int)v, meaning, (int)back);
	return ret;
}

/* Auto exposure "on": the control's default when it is automatic, else the first
 * automatic menu item (UVC cameras offer aperture priority, not full auto). */
static int exposure_auto_on_value(v4l2_cam *c, const struct v4l2_queryctrl *q)
{
	if (q->default_value != V4L2_EXPOSURE_MANUAL)
		return q->default_value;
	static const int autos[] = {V4L2_EXPOSURE_APERTURE_PRIORITY, V4L2_EXPOSURE_AUTO,
	                            V4L2_EXPOSURE_SHUTTER_PRIORITY};
	for (size_t i = 0; i < sizeof(autos) / sizeof(autos[0]); i++) {
		struct v4l2_querymenu m;
		memset(&m, 0, sizeof(m));
		m.id = V4L2_CID_EXPOSURE_AUTO;
		m.index = (uint32_t)autos[i];
		if (!xioctl(c, VIDIOC_QUERYMENU, &m))
			return autos[i];
	}
	return -1;
}

/* Exposure and gain writes need the automatic modes off first (UVC firmware refuses
 * V4L2_CID_EXPOSURE_ABSOLUTE while V4L2_CID_EXPOSURE_AUTO is not manual). */
static int ensure_manual(v4l2_cam *c, uint32_t auto_id, kg_err *err)
{
	struct v4l2_queryctrl q;
	int32_t v = 0; /* g_ctrl sets it on success only; GCC cannot see kg_fail is nonzero */
	int32_t manual = auto_id == V4L2_CID_EXPOSURE_AUTO ? V4L2_EXPOSURE_MANUAL : 0;
	int ret = query(c, auto_id, &q, err);
	if (ret <= 0)
		return ret;
	if ((ret = g_ctrl(c, auto_id, &v, err)) || v == manual)
		return ret;
	return set_verified(c, auto_id, manual, "manual", err);
}

/* How a feature maps onto one V4L2 control: value = raw * scale. */
typedef struct ctrl_map {
	uint32_t id;
	double scale;
	const char *unit;
} ctrl_map;

/* The control behind a numeric feature; returns 1 when found (q filled). */
static int numeric_ctrl(v4l2_cam *c, kg_feature f, ctrl_map *m, struct v4l2_queryctrl *q,
                        kg_err *err)
{
	int ret;
	switch (f) {
	case KG_FEAT_EXPOSURE_US:
		*m = (ctrl_map){V4L2_CID_EXPOSURE_ABSOLUTE, 100.0, "us"}; /* 100 us units */
		return query(c, m->id, q, err);
	case KG_FEAT_GAIN:
		*m = (ctrl_map){V4L2_CID_GAIN, 1.0, "raw"};
		if ((ret = query(c, m->id, q, err)))
			return ret;
		*m = (ctrl_map){V4L2_CID_ANALOGUE_GAIN, 1.0, "raw"};
		return query(c, m->id, q, err);
	case KG_FEAT_WB_RED:
	case KG_FEAT_WB_BLUE:
		/* Register units without a standard unity; the driver's default is taken as
		 * gain 1 (what the sensor does before any balancing). */
		*m = (ctrl_map){f == KG_FEAT_WB_RED ? V4L2_CID_RED_BALANCE : V4L2_CID_BLUE_BALANCE,
		                1.0, "x"};
		if ((ret = query(c, m->id, q, err)) <= 0)
			return ret;
		if (q->default_value <= 0)
			return 0;
		m->scale = 1.0 / q->default_value;
		return 1;
	default:
		return 0;
	}
}

static int frame_rate_range(v4l2_cam *c, double *lo, double *hi)
{
	struct v4l2_frmivalenum fi;
	*lo = INFINITY;
	*hi = 0;
	for (uint32_t i = 0; i < 256; i++) {
		memset(&fi, 0, sizeof(fi));
		fi.index = i;
		fi.pixel_format = c->fourcc;
		fi.width = (uint32_t)c->fmt.width;
		fi.height = (uint32_t)c->fmt.height;
		if (xioctl(c, VIDIOC_ENUM_FRAMEINTERVALS, &fi))
			break;
		struct v4l2_fract a = fi.discrete, b = fi.discrete;
		if (fi.type != V4L2_FRMIVAL_TYPE_DISCRETE) {
			a = fi.stepwise.min;
			b = fi.stepwise.max;
		}
		if (a.numerator && b.numerator) {
			*hi = fmax(*hi, (double)a.denominator / a.numerator);
			*lo = fmin(*lo, (double)b.denominator / b.numerator);
		}
		if (fi.type != V4L2_FRMIVAL_TYPE_DISCRETE)
			break;
	}
	return *hi > 0;
}

static int v4_feature_info(void *state, kg_feature f, kg_feature_info *out, kg_err *err)
{
	v4l2_cam *c = state;
	struct v4l2_queryctrl q, q2;
	ctrl_map m;
	int ret, ret2;
	switch (f) {
	case KG_FEAT_EXPOSURE_US:
	case KG_FEAT_GAIN:
	case KG_FEAT_WB_RED:
	case KG_FEAT_WB_BLUE:
		if ((ret = numeric_ctrl(c, f, &m, &q, err)) <= 0)
			return ret;
		out->available = 1;
		out->writable = !(q.flags & V4L2_CTRL_FLAG_READ_ONLY);
		out->min = q.minimum * m.scale;
		out->max = q.maximum * m.scale;
		out->step = q.step * m.scale;
		snprintf(out->unit, sizeof(out->unit), "%s", m.unit);
		snprintf(out->native, sizeof(out->native), "%s", cid_name(m.id));
		return 0;
	case KG_FEAT_AUTO_EXPOSURE:
	case KG_FEAT_AUTO_WHITE_BALANCE: {
		uint32_t id = f == KG_FEAT_AUTO_EXPOSURE ? V4L2_CID_EXPOSURE_AUTO
		                                         : V4L2_CID_AUTO_WHITE_BALANCE;
		if ((ret = query(c, id, &q, err)) < 0)
			return ret;
		ret2 = 0;
		if (f == KG_FEAT_AUTO_EXPOSURE && (ret2 = query(c, V4L2_CID_AUTOGAIN, &q2, err)) < 0)
			return ret2;
		if (!ret && !ret2)
			return 0;
		out->available = 1;
		out->writable = (!ret || !(q.flags & V4L2_CTRL_FLAG_READ_ONLY)) &&
		                (!ret2 || !(q2.flags & V4L2_CTRL_FLAG_READ_ONLY));
		out->min = 0;
		out->max = 1;
		out->step = 1;
		snprintf(out->unit, sizeof(out->unit), "bool");
		snprintf(out->native, sizeof(out->native), "%s%s%s", ret ? cid_name(id) : "",
		         ret && ret2 ? "+" : "", ret2 ? "V4L2_CID_AUTOGAIN" : "");
		return 0;
	}
	case KG_FEAT_FRAME_RATE: {
		struct v4l2_streamparm p;
		memset(&p, 0, sizeof(p));
		p.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
		if (xioctl(c, VIDIOC_G_PARM, &p) || !p.parm.capture.timeperframe.numerator)
			return 0;
		out->available = 1;
		out->writable = !!(p.parm.capture.capability & V4L2_CAP_TIMEPERFRAME);
		if (!frame_rate_range(c, &out->min, &out->max))
			out->min = out->max = 0; /* not enumerable: no range to check against */
		snprintf(out->unit, sizeof(out->unit), "fps");
		snprintf(out->native, sizeof(out->native), "VIDIOC_S_PARM timeperframe");
		return 0;
	}
	default:
		return 0;
	}
}

static int v4_get(void *state, kg_feature f, double *value, kg_err *err)
{
	v4l2_cam *c = state;
	struct v4l2_queryctrl q;
	ctrl_map m;
	int32_t v;
	int ret;
	switch (f) {
	case KG_FEAT_EXPOSURE_US:
	case KG_FEAT_GAIN:
	case KG_FEAT_WB_RED:
	case KG_FEAT_WB_BLUE:
		if ((ret = numeric_ctrl(c, f, &m, &q, err)) < 0)
			return ret;
		if (!ret)
			break;
		if ((ret = g_ctrl(c, m.id, &v, err)))
			return ret;
		*value = v * m.scale;
		return 0;
	case KG_FEAT_AUTO_EXPOSURE:
	case KG_FEAT_AUTO_WHITE_BALANCE: {
		static const struct {
			kg_feature f;
			uint32_t id;
			int32_t off;
		} modes[] = {{KG_FEAT_AUTO_EXPOSURE, V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL},
		             {KG_FEAT_AUTO_EXPOSURE, V4L2_CID_AUTOGAIN, 0},
		             {KG_FEAT_AUTO_WHITE_BALANCE, V4L2_CID_AUTO_WHITE_BALANCE, 0}};
		int found = 0;
		*value = 0;
		for (size_t i = 0; i < sizeof(modes) / sizeof(modes[0]); i++) {
			if (modes[i].f != f)
				continue;
			if ((ret = query(c, modes[i].id, &q, err)) < 0)
				return ret;
			if (!ret)
				continue;
			if ((ret = g_ctrl(c, modes[i].id, &v, err)))
				return ret;
			found = 1;
			if (v != modes[i].off)
				*value = 1;
		}
		if (!found)
			break;
		return 0;
	}
	case KG_FEAT_FRAME_RATE: {
		struct v4l2_streamparm p;
		memset(&p, 0, sizeof(p));
		p.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
		if ((ret = xioctl(c, VIDIOC_G_PARM, &p)))
			return ioctl_fail(err, ret, "frame rate: VIDIOC_G_PARM");
		const struct v4l2_fract *t = &p.parm.capture.timeperframe;
		if (!t->numerator || !t->denominator)
			return kg_fail(err, KG_EIO, "frame rate: VIDIOC_G_PARM reports no frame "
			                            "interval (timeperframe %u/%u)",
			               t->numerator, t->denominator);
		*value = (double)t->denominator / t->numerator;
		return 0;
	}
	default:
		break;
	}
	return kg_fail(err, KG_ENOTSUP, "%s: this device has no such control",
	               kg_feature_name(f));
}

static int v4_set(void *state, kg_feature f, double value, kg_err *err)
{
	v4l2_cam *c = state;
	struct v4l2_queryctrl q;
	ctrl_map m;
	int ret;
	switch (f) {
	case KG_FEAT_EXPOSURE_US:
	case KG_FEAT_GAIN:
	case KG_FEAT_WB_RED:
	case KG_FEAT_WB_BLUE: {
		if ((ret = numeric_ctrl(c, f, &m, &q, err)) <= 0)
			return ret ? ret : kg_fail(err, KG_ENOTSUP, "%s: no such control",
			                           kg_feature_name(f));
		if (f == KG_FEAT_EXPOSURE_US && (ret = ensure_manual(c, V4L2_CID_EXPOSURE_AUTO, err)))
			return ret;
		if ((f == KG_FEAT_EXPOSURE_US || f == KG_FEAT_GAIN) &&
		    (ret = ensure_manual(c, V4L2_CID_AUTOGAIN, err)))
			return ret;
		if ((f == KG_FEAT_WB_RED || f == KG_FEAT_WB_BLUE) &&
		    (ret = ensure_manual(c, V4L2_CID_AUTO_WHITE_BALANCE, err)))
			return ret;
		double raw = round(value / m.scale);
		if (q.step > 1)
			raw = q.minimum + round((raw - q.minimum) / q.step) * q.step;
		raw = fmin(fmax(raw, q.minimum), q.maximum);
		return s_ctrl(c, m.id, (int32_t)raw, err);
	}
	case KG_FEAT_AUTO_EXPOSURE: {
		int on = value != 0, any = 0;
		if ((ret = query(c, V4L2_CID_EXPOSURE_AUTO, &q, err)) < 0)
			return ret;
		if (ret) {
			any = 1;
			int32_t want = on ? exposure_auto_on_value(c, &q) : V4L2_EXPOSURE_MANUAL;
			if (want < 0)
				return kg_fail(err, KG_ENOTSUP,
				               "V4L2_CID_EXPOSURE_AUTO: the menu offers no automatic mode");
			if ((ret = set_verified(c, V4L2_CID_EXPOSURE_AUTO, want,
			                        on ? "automatic" : "manual", err)))
				return ret;
		}
		if ((ret = query(c, V4L2_CID_AUTOGAIN, &q, err)) < 0)
			return ret;
		if (ret) {
			any = 1;
			if ((ret = set_verified(c, V4L2_CID_AUTOGAIN, on, on ? "on" : "off", err)))
				return ret;
		}
		return any ? 0 : kg_fail(err, KG_ENOTSUP, "auto_exposure: no such control");
	}
	case KG_FEAT_AUTO_WHITE_BALANCE:
		if ((ret = query(c, V4L2_CID_AUTO_WHITE_BALANCE, &q, err)) <= 0)
			return ret ? ret
			           : kg_fail(err, KG_ENOTSUP, "auto_white_balance: no such control");
		return set_verified(c, V4L2_CID_AUTO_WHITE_BALANCE, value != 0,
		                    value != 0 ? "on" : "off", err);
	case KG_FEAT_FRAME_RATE: {
		if (!(value > 0))
			return kg_fail(err, KG_EINVAL, "frame rate %g: expected > 0 fps", value);
		struct v4l2_streamparm p;
		memset(&p, 0, sizeof(p));
		p.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
		struct v4l2_fract *t = &p.parm.capture.timeperframe;
		if (fabs(value - round(value)) < 1e-9) {
			t->numerator = 1;
			t->denominator = (uint32_t)round(value);
		} else {
			t->numerator = 1000;
			t->denominator = (uint32_t)round(value * 1000);
		}
		if ((ret = xioctl(c, VIDIOC_S_PARM, &p)))
			return ioctl_fail(err, ret, "frame rate: VIDIOC_S_PARM");
		return 0;
	}
	default:
		return kg_fail(err, KG_ENOTSUP, "%s: this device has no such control",
		               kg_feature_name(f));
	}
}

/* ---- format and ROI ------------------------------------------------------------ */

static int v4_get_format(void *state, kg_frame_format *out, kg_err *err)
{
	v4l2_cam *c = state;
	int ret = refresh_format(c, err);
	if (!ret)
		*out = c->fmt;
	return ret;
}

static int v4_set_format(void *state, const kg_frame_format *want, kg_frame_format *got,
                         kg_err *err)
{
	v4l2_cam *c = state;
	char t[5], t2[5], list[1024];
	struct v4l2_format vf;
	int ret = get_fmt(c, &vf, err);
	if (ret)
		return ret;
	const struct fmt_map *cur = fmt_by_fourcc(vf.fmt.pix.pixelformat);

	/* The fourcc: the first offered entry of fmt_map matching the request. */
	uint32_t fourcc = vf.fmt.pix.pixelformat;
	if (want->pixfmt != KG_PIX_NONE || want->bits || want->cfa[0]) {
		kg_pixfmt pf = want->pixfmt != KG_PIX_NONE ? want->pixfmt
		               : cur                     ? cur->pixfmt
		                                         : KG_PIX_NONE;
		const struct fmt_map *m = NULL;
		for (size_t i = 0; i < NFMT_MAP && !m; i++)
			if (fmt_map[i].pixfmt == pf && (!want->bits || want->bits == fmt_map[i].bits) &&
			    (!want->cfa[0] || !strcmp(want->cfa, fmt_map[i].cfa)) &&
			    offered(c, fmt_map[i].fourcc))
				m = &fmt_map[i];
		if (!m) {
			offered_list(c, list, sizeof(list));
			return kg_fail(err, KG_ENOTSUP,
			               "pixel format %s%s%s (%d bits) is not offered; this device "
			               "offers %s",
			               kg_pixfmt_name(pf), want->cfa[0] ? " " : "", want->cfa,
			               want->bits ? want->bits : 8, list);
		}
		fourcc = m->fourcc;
	} else if (!cur) {
		offered_list(c, list, sizeof(list));
		return kg_fail(err, KG_ENOTSUP,
		               "current pixel format %s is not one kogei reads; choose one of %s",
		               fourcc_text(fourcc, t), list);
	}

	/* ROI: the crop rectangle on the sensor, when the device crops. */
	uint32_t w = want->width > 0 ? (uint32_t)want->width : vf.fmt.pix.width;
	uint32_t h = want->height > 0 ? (uint32_t)want->height : vf.fmt.pix.height;
	if (want->offset_x || want->offset_y) {
		if (!c->has_selection)
			return kg_fail(err, KG_ENOTSUP,
			               "ROI offset %d,%d: this device does not crop "
			               "(VIDIOC_G_SELECTION unsupported); expected offset 0,0",
			               want->offset_x, want->offset_y);
		if (want->offset_x < 0 || want->offset_y < 0)
			return kg_fail(err, KG_EINVAL, "ROI offset %d,%d: expected >= 0",
			               want->offset_x, want->offset_y);
		struct v4l2_selection s;
		memset(&s, 0, sizeof(s));
		s.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
		s.target = V4L2_SEL_TGT_CROP;
		s.r.left = want->offset_x;
		s.r.top = want->offset_y;
		s.r.width = w;
		s.r.height = h;
		if ((ret = xioctl(c, VIDIOC_S_SELECTION, &s)))
			return ioctl_fail(err, ret, "ROI: VIDIOC_S_SELECTION");
	}

	vf.fmt.pix.pixelformat = fourcc;
	vf.fmt.pix.width = w;
	vf.fmt.pix.height = h;
	vf.fmt.pix.field = V4L2_FIELD_NONE;
	vf.fmt.pix.bytesperline = 0; /* the driver's own stride */
	vf.fmt.pix.sizeimage = 0;
	if ((ret = xioctl(c, VIDIOC_S_FMT, &vf)))
		return ioctl_fail(err, ret, "VIDIOC_S_FMT");
	if (vf.fmt.pix.pixelformat != fourcc)
		return kg_fail(err, KG_ENOTSUP, "VIDIOC_S_FMT: asked for %s, the driver chose %s",
		               fourcc_text(fourcc, t), fourcc_text(vf.fmt.pix.pixelformat, t2));
	if ((ret = refresh_format(c, err)))
		return ret;
	*got = c->fmt;
	return 0;
}

/* ---- streaming ----------------------------------------------------------------- */

static void unmap_all(v4l2_cam *c)
{
	for (int i = 0; i < c->nbuf; i++)
		if (c->buf[i].ptr)
			c->ops->munmap(c->ops->user, c->buf[i].ptr, c->buf[i].length);
	c->nbuf = 0;
	struct v4l2_requestbuffers rb = {.count = 0,
	                                 .type = V4L2_BUF_TYPE_VIDEO_CAPTURE,
	                                 .memory = V4L2_MEMORY_MMAP};
	xioctl(c, VIDIOC_REQBUFS, &rb);
}

static int queue(v4l2_cam *c, int index, kg_err *err)
{
	struct v4l2_buffer b;
	memset(&b, 0, sizeof(b));
	b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
	b.memory = V4L2_MEMORY_MMAP;
	b.index = (uint32_t)index;
	int ret = xioctl(c, VIDIOC_QBUF, &b);
	if (ret)
		return kg_fail(err, errno_code(ret), "VIDIOC_QBUF of buffer %d failed: %s", index,
		               strerror(-ret));
	return 0;
}

static int v4_start(void *state, int nbuffers, kg_err *err)
{
	v4l2_cam *c = state;
	int ret = refresh_format(c, err);
	if (ret)
		return ret;
	c->expected = c->fmt.pixfmt == KG_PIX_MJPEG ? 1 : c->fmt.stride * (size_t)c->fmt.height;
	struct v4l2_requestbuffers rb = {
		.count = (uint32_t)(nbuffers > 0 ? (nbuffers < MAX_BUFFERS ? nbuffers : MAX_BUFFERS)
		                                 : DEFAULT_BUFFERS),
		.type = V4L2_BUF_TYPE_VIDEO_CAPTURE,
		.memory = V4L2_MEMORY_MMAP};
	if ((ret = xioctl(c, VIDIOC_REQBUFS, &rb)))
		return kg_fail(err, errno_code(ret),
		               "VIDIOC_REQBUFS: %s; expected mmap streaming (V4L2_MEMORY_MMAP)",
		               strerror(-ret));
	if (rb.count < 2 || rb.count > MAX_BUFFERS) {
		c->nbuf = 0;
		unmap_all(c);
		return kg_fail(err, KG_EIO, "VIDIOC_REQBUFS granted %u buffers; expected 2..%d",
		               rb.count, MAX_BUFFERS);
	}
	for (c->nbuf = 0; c->nbuf < (int)rb.count; c->nbuf++) {
		struct v4l2_buffer b;
		memset(&b, 0, sizeof(b));
		b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
		b.memory = V4L2_MEMORY_MMAP;
		b.index = (uint32_t)c->nbuf;
		if ((ret = xioctl(c, VIDIOC_QUERYBUF, &b))) {
			ret = ioctl_fail(err, ret, "VIDIOC_QUERYBUF");
			goto error;
		}
		void *p = c->ops->mmap(c->ops->user, NULL, b.length, PROT_READ | PROT_WRITE,
		                       MAP_SHARED, c->fd, (off_t)b.m.offset);
		if (p == MAP_FAILED) {
			ret = kg_fail(err, KG_EIO, "mmap of buffer %d (%u bytes) failed: %s", c->nbuf,
			              b.length, strerror(errno));
			goto error;
		}
		c->buf[c->nbuf].ptr = p;
		c->buf[c->nbuf].length = b.length;
		if (c->fmt.pixfmt != KG_PIX_MJPEG && b.length < c->expected) {
			c->nbuf++;
			ret = kg_fail(err, KG_EIO, "buffer %d holds %u bytes; a %dx%d frame needs %zu",
			              c->nbuf - 1, b.length, c->fmt.width, c->fmt.height, c->expected);
			goto error;
		}
	}
	for (int i = 0; i < c->nbuf; i++)
		if ((ret = queue(c, i, err)))
			goto error;
	int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
	if ((ret = xioctl(c, VIDIOC_STREAMON, &type))) {
		ret = ioctl_fail(err, ret, "VIDIOC_STREAMON");
		goto error;
	}
	c->streaming = 1;
	c->failed = c->incomplete = 0;
	c->have_seq = 0;
	c->seq_high = 0;
	return 0;
error:
	unmap_all(c);
	return ret;
}

static int v4_stop(void *state, kg_err *err)
{
	v4l2_cam *c = state;
	if (!c->streaming)
		return 0;
	int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
	int ret = xioctl(c, VIDIOC_STREAMOFF, &type);
	c->streaming = 0;
	unmap_all(c);
	return ret ? ioctl_fail(err, ret, "VIDIOC_STREAMOFF") : 0;
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static int v4_pop(void *state, int timeout_ms, kg_frame *frame, kg_err *err)
{
	v4l2_cam *c = state;
	double deadline = now_s() + (timeout_ms > 0 ? timeout_ms : 0) * 1e-3;
	struct v4l2_buffer b;
	for (;;) {
		memset(&b, 0, sizeof(b));
		b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
		b.memory = V4L2_MEMORY_MMAP;
		int ret = xioctl(c, VIDIOC_DQBUF, &b);
		if (!ret)
			break;
		if (ret == -ENODEV)
			return kg_fail(err, KG_ENODEV, "the device disappeared while streaming "
			                               "(VIDIOC_DQBUF: %s)",
			               strerror(-ret));
		if (ret != -EAGAIN)
			return ioctl_fail(err, ret, "VIDIOC_DQBUF");
		int left_ms = (int)ceil((deadline - now_s()) * 1e3);
		struct pollfd pfd = {.fd = c->fd, .events = POLLIN};
		int n = left_ms > 0 ? c->ops->poll(c->ops->user, &pfd, 1, left_ms) : 0;
		if (n < 0 && errno == EINTR)
			continue;
		if (n < 0)
			return kg_fail(err, KG_EIO, "poll failed: %s", strerror(errno));
		if (n == 0) {
			/* camera.c appends the stream counts */
			return kg_fail(err, KG_ETIMEDOUT,
			               "no frame within %d ms: the device filled no buffer",
			               timeout_ms);
		}
		if (pfd.revents & (POLLERR | POLLHUP | POLLNVAL))
			return kg_fail(err, KG_EIO, "poll reports an error on the device (revents 0x%x)",
			               (unsigned)pfd.revents);
	}
	if (b.index >= (uint32_t)c->nbuf)
		return kg_fail(err, KG_EIO, "VIDIOC_DQBUF returned buffer %u of %d", b.index,
		               c->nbuf);
	if (c->have_seq && b.sequence < c->last_seq32 && c->last_seq32 - b.sequence > 0x80000000u)
		c->seq_high += 1ull << 32;
	c->have_seq = 1;
	c->last_seq32 = b.sequence;

	frame->fmt = c->fmt;
	frame->data = c->buf[b.index].ptr;
	frame->size = b.bytesused <= c->buf[b.index].length ? b.bytesused : c->buf[b.index].length;
	frame->sequence = c->seq_high | b.sequence;
	frame->timestamp = b.timestamp.tv_sec || b.timestamp.tv_usec
	                       ? (double)b.timestamp.tv_sec + b.timestamp.tv_usec * 1e-6
	                       : now_s();
	frame->slot = (int)b.index;
	frame->status = KG_FRAME_OK;
	if (b.flags & V4L2_BUF_FLAG_ERROR) {
		frame->status = KG_FRAME_CORRUPT;
		c->failed++;
	} else if (frame->size < c->expected) {
		frame->status = KG_FRAME_INCOMPLETE;
		c->incomplete++;
	}
	return 0;
}

static int v4_push(void *state, kg_frame *frame, kg_err *err)
{
	v4l2_cam *c = state;
	if (!c->streaming)
		return 0; /* stop already took every buffer back */
	if (frame->slot < 0 || frame->slot >= c->nbuf)
		return kg_fail(err, KG_EINVAL, "push: buffer %d is not one of this stream's %d",
		               frame->slot, c->nbuf);
	return queue(c, frame->slot, err);
}

static void v4_stats(void *state, kg_stream_stats *out)
{
	v4l2_cam *c = state;
	out->failed = c->failed;
	out->incomplete = c->incomplete;
}

const kg_camera_driver kg_camera_v4l2_driver = {
	.scheme = "v4l2",
	.description = "V4L2 capture devices (UVC webcams, sensor drivers), mmap streaming",
	.enumerate = v4_enumerate,
	.open = v4_open,
	.close = v4_close,
	.feature_info = v4_feature_info,
	.get = v4_get,
	.set = v4_set,
	.set_format = v4_set_format,
	.get_format = v4_get_format,
	.start = v4_start,
	.stop = v4_stop,
	.pop = v4_pop,
	.push = v4_push,
	.stats = v4_stats,
};
