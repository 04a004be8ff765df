/* The fake V4L2 capture device (see fake_v4l2.h). */
#include "fake_v4l2.h"

#include <errno.h>
#include <linux/videodev2.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#if FAKE_V4L2_JPEG
#include <stdio.h>

#include <jpeglib.h>
#endif

#define MAX_HANDLES 8
#define MAX_BUFS 8
#define MAX_FORMATS 32
#define LOG_MAX 4096

enum { K_MONO, K_RGB, K_YUYV, K_JPEG };

static const struct fake_fmt {
	uint32_t fourcc;
	int kind, bytes, bits;
	const char *name;
} fake_fmts[] = {
	{V4L2_PIX_FMT_GREY, K_MONO, 1, 8, "8-bit Greyscale"},
	{V4L2_PIX_FMT_Y10, K_MONO, 2, 10, "10-bit Greyscale"},
	{V4L2_PIX_FMT_Y12, K_MONO, 2, 12, "12-bit Greyscale"},
	{V4L2_PIX_FMT_Y16, K_MONO, 2, 16, "16-bit Greyscale"},
	{V4L2_PIX_FMT_SRGGB8, K_MONO, 1, 8, "8-bit Bayer RGRG/GBGB"},
	{V4L2_PIX_FMT_SGRBG8, K_MONO, 1, 8, "8-bit Bayer GRGR/BGBG"},
	{V4L2_PIX_FMT_SGBRG8, K_MONO, 1, 8, "8-bit Bayer GBGB/RGRG"},
	{V4L2_PIX_FMT_SBGGR8, K_MONO, 1, 8, "8-bit Bayer BGBG/GRGR"},
	{V4L2_PIX_FMT_SRGGB10, K_MONO, 2, 10, "10-bit Bayer RGRG/GBGB"},
	{V4L2_PIX_FMT_SGRBG10, K_MONO, 2, 10, "10-bit Bayer GRGR/BGBG"},
	{V4L2_PIX_FMT_SGBRG12, K_MONO, 2, 12, "12-bit Bayer GBGB/RGRG"},
	{V4L2_PIX_FMT_SBGGR12, K_MONO, 2, 12, "12-bit Bayer BGBG/GRGR"},
	{V4L2_PIX_FMT_SRGGB12, K_MONO, 2, 12, "12-bit Bayer RGRG/GBGB"},
	{V4L2_PIX_FMT_SRGGB16, K_MONO, 2, 16, "16-bit Bayer RGRG/GBGB"},
	{V4L2_PIX_FMT_SBGGR16, K_MONO, 2, 16, "16-bit Bayer BGBG/GRGR"},
	{V4L2_PIX_FMT_RGB24, K_RGB, 3, 8, "24-bit RGB 8-8-8"},
	{V4L2_PIX_FMT_YUYV, K_YUYV, 2, 8, "YUYV 4:2:2"},
	{V4L2_PIX_FMT_MJPEG, K_JPEG, 0, 8, "Motion-JPEG"},
	{V4L2_PIX_FMT_NV12, K_MONO, 1, 8, "Y/UV 4:2:0"}, /* offered, not read by kogei */
};

static const struct fake_fmt *fmt_info(uint32_t fourcc)
{
	for (size_t i = 0; i < sizeof(fake_fmts) / sizeof(fake_fmts[0]); i++)
		if (fake_fmts[i].fourcc == fourcc)
			return &fake_fmts[i];
	return NULL;
}

typedef struct fake_ctrl {
	uint32_t id;
	uint32_t type;
	int32_t min, max, step, def, value;
	const char *name;
} fake_ctrl;

static const int fps_list[] = {30, 15, 5};

struct fake_v4l2 {
	fake_v4l2_config cfg;
	uint32_t formats[MAX_FORMATS];
	int handles[MAX_HANDLES];
	int nhandles;
	uint32_t fourcc;
	int width, height;
	struct v4l2_rect crop; /* selection mode: the window on the sensor */
	int fps;
	fake_ctrl ctrls[12];
	int nctrls;
	int memfd;
	uint8_t *mem;
	size_t buflen, memlen;
	int nbufs;
	int buf_fd; /* the handle that owns the buffers */
	int fifo[MAX_BUFS]; /* queued buffers, oldest first */
	int nqueued;
	int stream_fd; /* -1 when not streaming */
	uint32_t delivered, seq;
	fake_v4l2_call log[LOG_MAX];
	int nlog;
};

uint32_t fake_v4l2_sample(int x, int y, int c, uint32_t seq, int bits)
{
	uint32_t h = (uint32_t)x * 0x9E3779B1u ^ (uint32_t)y * 0x85EBCA77u ^
	             (uint32_t)c * 0xC2B2AE3Du ^ seq * 0x27D4EB2Fu;
	h ^= h >> 15;
	h *= 0x2C1B3C6Du;
	h ^= h >> 12;
	h *= 0x297A2D39u;
	h ^= h >> 15;
	return bits >= 32 ? h : h & ((1u << bits) - 1u);
}

void fake_v4l2_smooth_rgb(int x, int y, uint32_t seq, uint8_t rgb[3])
{
	for (int c = 0; c < 3; c++) {
		double v = 128.0 + 90.0 * sin(0.07 * x + 2.1 * c + 0.3 * seq) * cos(0.05 * y - c);
		rgb[c] = (uint8_t)lrint(v);
	}
}

void fake_v4l2_yuyv_rgb(int x, int y, uint32_t seq, uint8_t rgb[3])
{
	for (int c = 0; c < 3; c++)
		rgb[c] = (uint8_t)fake_v4l2_sample(x & ~1, y, c, seq, 8);
}

static void add_ctrl(fake_v4l2 *f, uint32_t id, uint32_t type, int32_t min, int32_t max,
                     int32_t def, const char *name)
{
	f->ctrls[f->nctrls++] = (fake_ctrl){id, type, min, max, 1, def, def, name};
}

fake_v4l2 *fake_v4l2_new(const fake_v4l2_config *cfg)
{
	fake_v4l2 *f = calloc(1, sizeof(*f));
	if (!f || cfg->nformats < 1 || cfg->nformats > MAX_FORMATS) {
		free(f);
		return NULL;
	}
	f->cfg = *cfg;
	memcpy(f->formats, cfg->formats, sizeof(uint32_t) * (size_t)cfg->nformats);
	f->cfg.formats = f->formats;
	if (!f->cfg.driver)
		f->cfg.driver = "uvcvideo";
	if (!f->cfg.device_caps)
		f->cfg.device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
	f->fourcc = cfg->formats[0];
	f->width = cfg->width;
	f->height = cfg->height;
	f->crop = (struct v4l2_rect){0, 0, (uint32_t)cfg->width, (uint32_t)cfg->height};
	f->fps = 30;
	f->memfd = -1;
	f->stream_fd = -1;
	add_ctrl(f, V4L2_CID_EXPOSURE_AUTO, V4L2_CTRL_TYPE_MENU, 0, 3,
	         V4L2_EXPOSURE_APERTURE_PRIORITY, "Auto Exposure");
	add_ctrl(f, V4L2_CID_EXPOSURE_ABSOLUTE, V4L2_CTRL_TYPE_INTEGER, 3, 2047, 156,
	         "Exposure Time, Absolute");
	add_ctrl(f, V4L2_CID_GAIN, V4L2_CTRL_TYPE_INTEGER, 0, 255, 32, "Gain");
	add_ctrl(f, V4L2_CID_AUTO_WHITE_BALANCE, V4L2_CTRL_TYPE_BOOLEAN, 0, 1, 1,
	         "White Balance, Automatic");
	if (cfg->autogain)
		add_ctrl(f, V4L2_CID_AUTOGAIN, V4L2_CTRL_TYPE_BOOLEAN, 0, 1, 1, "Gain, Automatic");
	if (cfg->balance) {
		add_ctrl(f, V4L2_CID_RED_BALANCE, V4L2_CTRL_TYPE_INTEGER, 0, 4095, 1024,
		         "Red Balance");
		add_ctrl(f, V4L2_CID_BLUE_BALANCE, V4L2_CTRL_TYPE_INTEGER, 0, 4095, 1024,
		         "Blue Balance");
	}
	return f;
}

static void free_buffers(fake_v4l2 *f)
{
	if (f->mem)
		munmap(f->mem, f->memlen);
	if (f->memfd >= 0)
		close(f->memfd);
	f->mem = NULL;
	f->memfd = -1;
	f->nbufs = 0;
	f->nqueued = 0;
}

void fake_v4l2_free(fake_v4l2 **pf)
{
	if (!pf || !*pf)
		return;
	free_buffers(*pf);
	free(*pf);
	*pf = NULL;
}

int fake_v4l2_open(fake_v4l2 *f)
{
	if (f->nhandles == MAX_HANDLES) {
		errno = EBUSY;
		return -1;
	}
	int fd = eventfd(0, EFD_SEMAPHORE | EFD_NONBLOCK | EFD_CLOEXEC);
	if (fd >= 0)
		f->handles[f->nhandles++] = fd;
	return fd;
}

int fake_v4l2_owns(const fake_v4l2 *f, int fd)
{
	for (int i = 0; i < f->nhandles; i++)
		if (f->handles[i] == fd)
			return 1;
	return 0;
}

static void signal_ready(fake_v4l2 *f, int n)
{
	uint64_t v = (uint64_t)n;
	if (n > 0 && f->stream_fd >= 0 && !f->cfg.stall &&
	    write(f->stream_fd, &v, sizeof(v)) != (ssize_t)sizeof(v))
		abort(); /* an eventfd write cannot fail short of overflow */
}

static void stream_off(fake_v4l2 *f)
{
	uint64_t v;
	if (f->stream_fd >= 0)
		while (read(f->stream_fd, &v, sizeof(v)) == (ssize_t)sizeof(v))
			;
	f->stream_fd = -1;
	f->nqueued = 0;
}

void fake_v4l2_release(fake_v4l2 *f, int fd)
{
	for (int i = 0; i < f->nhandles; i++)
		if (f->handles[i] == fd) {
			f->handles[i] = f->handles[--f->nhandles];
			if (f->buf_fd == fd) {
				stream_off(f);
				free_buffers(f);
			}
			return;
		}
}

int fake_v4l2_log_count(const fake_v4l2 *f) { return f->nlog; }

const fake_v4l2_call *fake_v4l2_log_at(const fake_v4l2 *f, int i)
{
	return i >= 0 && i < f->nlog ? &f->log[i] : NULL;
}

void fake_v4l2_log_clear(fake_v4l2 *f) { f->nlog = 0; }

static fake_ctrl *ctrl_find(fake_v4l2 *f, uint32_t id)
{
	for (int i = 0; i < f->nctrls; i++)
		if (f->ctrls[i].id == id)
			return &f->ctrls[i];
	return NULL;
}

int32_t fake_v4l2_control(const fake_v4l2 *f, uint32_t id)
{
	for (int i = 0; i < f->nctrls; i++)
		if (f->ctrls[i].id == id)
			return f->ctrls[i].value;
	return 0;
}

/* ---- formats --------------------------------------------------------------------- */

static int offered(const fake_v4l2 *f, uint32_t fourcc)
{
	for (int i = 0; i < f->cfg.nformats; i++)
		if (f->formats[i] == fourcc)
			return 1;
	return 0;
}

static void pix_of(const fake_v4l2 *f, struct v4l2_pix_format *p)
{
	const struct fake_fmt *m = fmt_info(f->fourcc);
	memset(p, 0, sizeof(*p));
	p->width = (uint32_t)f->width;
	p->height = (uint32_t)f->height;
	p->pixelformat = f->fourcc;
	p->field = V4L2_FIELD_NONE;
	p->colorspace = V4L2_COLORSPACE_SRGB;
	if (m->kind == K_JPEG) {
		p->bytesperline = 0;
		p->sizeimage = (uint32_t)(f->width * f->height * 2 + 4096);
	} else {
		p->bytesperline = (uint32_t)(f->width * m->bytes + f->cfg.pad);
		p->sizeimage = p->bytesperline * p->height;
	}
}

static void set_size(fake_v4l2 *f, uint32_t w, uint32_t h)
{
	if (f->cfg.selection) { /* windowing: the crop follows the frame size */
		uint32_t maxw = (uint32_t)f->cfg.width - f->crop.left;
		uint32_t maxh = (uint32_t)f->cfg.height - f->crop.top;
		f->crop.width = w < 16 ? 16 : w > maxw ? maxw : w & ~1u;
		f->crop.height = h < 16 ? 16 : h > maxh ? maxh : h & ~1u;
		f->width = (int)f->crop.width;
		f->height = (int)f->crop.height;
		return;
	}
	/* Discrete sizes: full and half; the nearest in area. */
	long full = (long)f->cfg.width * f->cfg.height, want = (long)w * h;
	int half = labs(want - full / 4) < labs(want - full);
	f->width = half ? f->cfg.width / 2 : f->cfg.width;
	f->height = half ? f->cfg.height / 2 : f->cfg.height;
}

/* ---- frames ---------------------------------------------------------------------- */

static uint8_t clamp_u8(double v) { return v < 0 ? 0 : v > 255 ? 255 : (uint8_t)(v + 0.5); }

#if FAKE_V4L2_JPEG
/* Drop the DHT (FF C4) segments before the scan, as UVC cameras send MJPEG. */
static size_t strip_dht(uint8_t *j, size_t n)
{
	size_t i = 2, o = 2;
	while (i + 4 <= n && j[i] == 0xFF && j[i + 1] != 0xDA) {
		size_t len = 2 + ((size_t)j[i + 2] << 8 | j[i + 3]);
		if (i + len > n)
			break;
		if (j[i + 1] != 0xC4) {
			memmove(j + o, j + i, len);
			o += len;
		}
		i += len;
	}
	memmove(j + o, j + i, n - i);
	return o + (n - i);
}

/* A real baseline JPEG (quality 95, 4:2:0) of fake_v4l2_smooth_rgb; frames with an
 * odd sequence number lack their Huffman tables, like a UVC camera's. */
static size_t fill_jpeg(fake_v4l2 *f, uint8_t *dst, size_t cap, uint32_t seq)
{
	struct jpeg_compress_struct ci;
	struct jpeg_error_mgr je;
	ci.err = jpeg_std_error(&je);
	jpeg_create_compress(&ci);
	unsigned char *out = NULL;
	unsigned long outlen = 0;
	jpeg_mem_dest(&ci, &out, &outlen);
	ci.image_width = (JDIMENSION)f->width;
	ci.image_height = (JDIMENSION)f->height;
	ci.input_components = 3;
	ci.in_color_space = JCS_RGB;
	jpeg_set_defaults(&ci);
	jpeg_set_quality(&ci, 95, TRUE);
	jpeg_start_compress(&ci, TRUE);
	uint8_t *row = malloc((size_t)f->width * 3);
	while (row && ci.next_scanline < ci.image_height) {
		for (int x = 0; x < f->width; x++)
			fake_v4l2_smooth_rgb(x, (int)ci.next_scanline, seq, row + 3 * x);
		JSAMPROW r = row;
		jpeg_write_scanlines(&ci, &r, 1);
	}
	jpeg_finish_compress(&ci);
	jpeg_destroy_compress(&ci);
	free(row);
	size_t n = outlen;
	if (seq & 1)
		n = strip_dht(out, n);
	if (n > cap) {
		fprintf(stderr, "fake_v4l2: a JPEG of %zu bytes does not fit %zu\n", n, cap);
		n = 0;
	}
	memcpy(dst, out, n);
	free(out);
	return n;
}
#else
/* Without libjpeg: FF D8, hash bytes, FF D9 (not decodable). */
static size_t fill_jpeg(fake_v4l2 *f, uint8_t *dst, size_t cap, uint32_t seq)
{
	(void)f;
	(void)cap;
	memset(dst, 0, FAKE_V4L2_JPEG_BYTES);
	dst[0] = 0xFF;
	dst[1] = 0xD8;
	for (int i = 2; i < FAKE_V4L2_JPEG_BYTES - 2; i++)
		dst[i] = (uint8_t)fake_v4l2_sample(i, 0, 0, seq, 8);
	dst[FAKE_V4L2_JPEG_BYTES - 2] = 0xFF;
	dst[FAKE_V4L2_JPEG_BYTES - 1] = 0xD9;
	return FAKE_V4L2_JPEG_BYTES;
}
#endif

static size_t fill(fake_v4l2 *f, uint8_t *dst, uint32_t seq)
{
	const struct fake_fmt *m = fmt_info(f->fourcc);
	struct v4l2_pix_format p;
	pix_of(f, &p);
	if (m->kind == K_JPEG)
		return fill_jpeg(f, dst, p.sizeimage, seq);
	int ox = f->cfg.selection ? (int)f->crop.left : 0;
	int oy = f->cfg.selection ? (int)f->crop.top : 0;
	for (int y = 0; y < f->height; y++) {
		uint8_t *row = dst + (size_t)y * p.bytesperline;
		memset(row, 0xEE, p.bytesperline); /* padding a reader must skip */
		for (int x = 0; x < f->width; x++) {
			int sx = x + ox, sy = y + oy;
			if (m->kind == K_MONO && m->bytes == 1) {
				row[x] = (uint8_t)fake_v4l2_sample(sx, sy, 0, seq, 8);
			} else if (m->kind == K_MONO) {
				uint32_t v = fake_v4l2_sample(sx, sy, 0, seq, m->bits);
				row[2 * x] = (uint8_t)(v & 0xff);
				row[2 * x + 1] = (uint8_t)(v >> 8);
			} else if (m->kind == K_RGB) {
				for (int c = 0; c < 3; c++)
					row[3 * x + c] = (uint8_t)fake_v4l2_sample(sx, sy, c, seq, 8);
			} else { /* YUYV, BT.601 limited range */
				uint8_t rgb[3];
				fake_v4l2_yuyv_rgb(sx, sy, seq, rgb);
				double r = rgb[0] / 255.0, g = rgb[1] / 255.0, b = rgb[2] / 255.0;
				double luma = 0.299 * r + 0.587 * g + 0.114 * b;
				row[2 * x] = clamp_u8(16 + 219 * luma);
				row[2 * x + 1] = (x & 1) ? clamp_u8(128 + 224 * (r - luma) / 1.402)
				                         : clamp_u8(128 + 224 * (b - luma) / 1.772);
			}
		}
	}
	return p.sizeimage;
}

/* ---- ioctls ---------------------------------------------------------------------- */

static int fail(int e)
{
	errno = e;
	return -1;
}

static int ctrl_inactive(fake_v4l2 *f, const fake_ctrl *c)
{
	switch (c->id) {
	case V4L2_CID_EXPOSURE_ABSOLUTE:
		return fake_v4l2_control(f, V4L2_CID_EXPOSURE_AUTO) != V4L2_EXPOSURE_MANUAL;
	case V4L2_CID_GAIN:
		return ctrl_find(f, V4L2_CID_AUTOGAIN) && fake_v4l2_control(f, V4L2_CID_AUTOGAIN);
	case V4L2_CID_RED_BALANCE:
	case V4L2_CID_BLUE_BALANCE:
		return fake_v4l2_control(f, V4L2_CID_AUTO_WHITE_BALANCE) != 0;
	default:
		return 0;
	}
}

static int menu_valid(uint32_t id, int32_t index)
{
	return id != V4L2_CID_EXPOSURE_AUTO || index == V4L2_EXPOSURE_MANUAL ||
	       index == V4L2_EXPOSURE_APERTURE_PRIORITY;
}

static int s_ctrl(fake_v4l2 *f, struct v4l2_control *ctl)
{
	fake_ctrl *c = ctrl_find(f, ctl->id);
	if (!c)
		return fail(EINVAL);
	if (ctrl_inactive(f, c))
		return fail(EACCES); /* uvcvideo refuses writes to inactive controls */
	int32_t v = ctl->value;
	if (c->type == V4L2_CTRL_TYPE_MENU) {
		if (v < c->min || v > c->max || !menu_valid(c->id, v))
			return fail(EINVAL);
	} else {
		v = v < c->min ? c->min : v > c->max ? c->max : v;
	}
	if (c->id == V4L2_CID_AUTO_WHITE_BALANCE && f->cfg.awb_stuck)
		return 0; /* the firmware acknowledges and ignores it */
	c->value = v;
	return 0;
}

static int do_ioctl(fake_v4l2 *f, int fd, unsigned long request, void *arg)
{
	switch (request) {
	case VIDIOC_QUERYCAP: {
		struct v4l2_capability *cap = arg;
		memset(cap, 0, sizeof(*cap));
		strncpy((char *)cap->driver, f->cfg.driver, sizeof(cap->driver) - 1);
		strncpy((char *)cap->card, "kogei fake camera", sizeof(cap->card) - 1);
		strncpy((char *)cap->bus_info, "usb-fake-1.2", sizeof(cap->bus_info) - 1);
		cap->version = 0x060100;
		cap->device_caps = f->cfg.device_caps;
		cap->capabilities = f->cfg.device_caps | V4L2_CAP_DEVICE_CAPS;
		return 0;
	}
	case VIDIOC_ENUM_FMT: {
		struct v4l2_fmtdesc *d = arg;
		if (d->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || d->index >= (uint32_t)f->cfg.nformats)
			return fail(EINVAL);
		d->pixelformat = f->formats[d->index];
		d->flags = fmt_info(d->pixelformat)->kind == K_JPEG ? V4L2_FMT_FLAG_COMPRESSED : 0;
		strncpy((char *)d->description, fmt_info(d->pixelformat)->name,
		        sizeof(d->description) - 1);
		return 0;
	}
	case VIDIOC_G_FMT:
	case VIDIOC_S_FMT:
	case VIDIOC_TRY_FMT: {
		struct v4l2_format *vf = arg;
		if (vf->type != V4L2_BUF_TYPE_VIDEO_CAPTURE)
			return fail(EINVAL);
		if (request == VIDIOC_G_FMT) {
			pix_of(f, &vf->fmt.pix);
			return 0;
		}
		if (request == VIDIOC_S_FMT && f->nbufs)
			return fail(EBUSY);
		/* TRY_FMT changes nothing */
		uint32_t old_fourcc = f->fourcc;
		int old_w = f->width, old_h = f->height;
		struct v4l2_rect old_crop = f->crop;
		uint32_t want = vf->fmt.pix.pixelformat;
		f->fourcc = offered(f, want) && fmt_info(want) ? want : f->formats[0];
		set_size(f, vf->fmt.pix.width, vf->fmt.pix.height);
		pix_of(f, &vf->fmt.pix);
		if (request == VIDIOC_TRY_FMT) {
			f->fourcc = old_fourcc;
			f->width = old_w;
			f->height = old_h;
			f->crop = old_crop;
		}
		return 0;
	}
	case VIDIOC_ENUM_FRAMESIZES: {
		struct v4l2_frmsizeenum *s = arg;
		if (!offered(f, s->pixel_format) || s->index > 1)
			return fail(EINVAL);
		s->type = V4L2_FRMSIZE_TYPE_DISCRETE;
		s->discrete.width = (uint32_t)(s->index ? f->cfg.width / 2 : f->cfg.width);
		s->discrete.height = (uint32_t)(s->index ? f->cfg.height / 2 : f->cfg.height);
		return 0;
	}
	case VIDIOC_ENUM_FRAMEINTERVALS: {
		struct v4l2_frmivalenum *iv = arg;
		if (!offered(f, iv->pixel_format) || iv->index >= 3)
			return fail(EINVAL);
		iv->type = V4L2_FRMIVAL_TYPE_DISCRETE;
		iv->discrete = (struct v4l2_fract){1, (uint32_t)fps_list[iv->index]};
		return 0;
	}
	case VIDIOC_G_PARM:
	case VIDIOC_S_PARM: {
		struct v4l2_streamparm *p = arg;
		if (p->type != V4L2_BUF_TYPE_VIDEO_CAPTURE)
			return fail(EINVAL);
		if (request == VIDIOC_S_PARM) {
			struct v4l2_fract t = p->parm.capture.timeperframe;
			double want = t.numerator ? (double)t.denominator / t.numerator : 30;
			int best = fps_list[0];
			for (size_t i = 1; i < sizeof(fps_list) / sizeof(fps_list[0]); i++)
				if (fabs(fps_list[i] - want) < fabs(best - want))
					best = fps_list[i];
			f->fps = best;
		}
		memset(&p->parm, 0, sizeof(p->parm));
		p->parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
		p->parm.capture.timeperframe = (struct v4l2_fract){1, (uint32_t)f->fps};
		p->parm.capture.readbuffers = 0;
		return 0;
	}
	case VIDIOC_QUERYCTRL: {
		struct v4l2_queryctrl *q = arg;
		fake_ctrl *c = ctrl_find(f, q->id);
		if (!c)
			return fail(EINVAL);
		memset(q, 0, sizeof(*q));
		q->id = c->id;
		q->type = c->type;
		strncpy((char *)q->name, c->name, sizeof(q->name) - 1);
		q->minimum = c->min;
		q->maximum = c->max;
		q->step = c->step;
		q->default_value = c->def;
		q->flags = ctrl_inactive(f, c) ? V4L2_CTRL_FLAG_INACTIVE : 0;
		return 0;
	}
	case VIDIOC_QUERYMENU: {
		struct v4l2_querymenu *m = arg;
		if (m->id != V4L2_CID_EXPOSURE_AUTO || !menu_valid(m->id, (int32_t)m->index) ||
		    m->index > 3)
			return fail(EINVAL);
		strncpy((char *)m->name,
		        m->index == V4L2_EXPOSURE_MANUAL ? "Manual Mode" : "Aperture Priority Mode",
		        sizeof(m->name) - 1);
		return 0;
	}
	case VIDIOC_G_CTRL: {
		struct v4l2_control *ctl = arg;
		fake_ctrl *c = ctrl_find(f, ctl->id);
		if (!c)
			return fail(EINVAL);
		ctl->value = c->value;
		return 0;
	}
	case VIDIOC_S_CTRL:
		return s_ctrl(f, arg);
	case VIDIOC_G_SELECTION:
	case VIDIOC_S_SELECTION: {
		struct v4l2_selection *s = arg;
		if (s->type != V4L2_BUF_TYPE_VIDEO_CAPTURE)
			return fail(EINVAL);
		if (request == VIDIOC_S_SELECTION) {
			if (!f->cfg.selection)
				return fail(ENOTTY);
			if (s->target != V4L2_SEL_TGT_CROP)
				return fail(EINVAL);
			if (f->nbufs)
				return fail(EBUSY);
			int32_t l = s->r.left < 0 ? 0 : s->r.left & ~1;
			int32_t t = s->r.top < 0 ? 0 : s->r.top & ~1;
			if (l > f->cfg.width - 16)
				l = f->cfg.width - 16;
			if (t > f->cfg.height - 16)
				t = f->cfg.height - 16;
			f->crop.left = l;
			f->crop.top = t;
			set_size(f, s->r.width, s->r.height);
			s->r = f->crop;
			return 0;
		}
		if (s->target == V4L2_SEL_TGT_CROP_BOUNDS || s->target == V4L2_SEL_TGT_CROP_DEFAULT) {
			/* uvcvideo answers these with the current frame size */
			s->r = f->cfg.selection
			           ? (struct v4l2_rect){0, 0, (uint32_t)f->cfg.width,
			                                (uint32_t)f->cfg.height}
			           : (struct v4l2_rect){0, 0, (uint32_t)f->width, (uint32_t)f->height};
			return 0;
		}
		if (s->target == V4L2_SEL_TGT_CROP && f->cfg.selection) {
			s->r = f->crop;
			return 0;
		}
		return fail(EINVAL);
	}
	case VIDIOC_REQBUFS: {
		struct v4l2_requestbuffers *rb = arg;
		if (rb->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || rb->memory != V4L2_MEMORY_MMAP)
			return fail(EINVAL);
		if (f->stream_fd >= 0 || (f->nbufs && f->buf_fd != fd))
			return fail(EBUSY);
		free_buffers(f);
		if (!rb->count)
			return 0;
		uint32_t n = rb->count < 2 ? 2 : rb->count > MAX_BUFS ? MAX_BUFS : rb->count;
		struct v4l2_pix_format p;
		pix_of(f, &p);
		size_t page = (size_t)sysconf(_SC_PAGESIZE);
		f->buflen = (p.sizeimage + page - 1) / page * page;
		f->memlen = f->buflen * n;
		f->memfd = memfd_create("fake-v4l2", MFD_CLOEXEC);
		if (f->memfd < 0 || ftruncate(f->memfd, (off_t)f->memlen))
			return -1;
		f->mem = mmap(NULL, f->memlen, PROT_READ | PROT_WRITE, MAP_SHARED, f->memfd, 0);
		if (f->mem == MAP_FAILED) {
			f->mem = NULL;
			return -1;
		}
		f->nbufs = (int)n;
		f->buf_fd = fd;
		rb->count = n;
		return 0;
	}
	case VIDIOC_QUERYBUF:
	case VIDIOC_QBUF: {
		struct v4l2_buffer *b = arg;
		if (b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || b->memory != V4L2_MEMORY_MMAP ||
		    b->index >= (uint32_t)f->nbufs)
			return fail(EINVAL);
		int queued = 0;
		for (int i = 0; i < f->nqueued; i++)
			queued |= f->fifo[i] == (int)b->index;
		if (request == VIDIOC_QUERYBUF) {
			struct v4l2_pix_format p;
			pix_of(f, &p);
			b->length = p.sizeimage;
			b->m.offset = (uint32_t)(b->index * f->buflen);
			b->flags = V4L2_BUF_FLAG_MAPPED | (queued ? V4L2_BUF_FLAG_QUEUED : 0);
			return 0;
		}
		if (queued)
			return fail(EINVAL);
		f->fifo[f->nqueued++] = (int)b->index;
		b->flags = V4L2_BUF_FLAG_MAPPED | V4L2_BUF_FLAG_QUEUED;
		if (f->stream_fd == fd)
			signal_ready(f, 1);
		return 0;
	}
	case VIDIOC_DQBUF: {
		struct v4l2_buffer *b = arg;
		if (b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || b->memory != V4L2_MEMORY_MMAP ||
		    f->stream_fd != fd)
			return fail(EINVAL);
		uint64_t token;
		if (f->cfg.stall || !f->nqueued || read(fd, &token, sizeof(token)) != sizeof(token))
			return fail(EAGAIN);
		int index = f->fifo[0];
		memmove(f->fifo, f->fifo + 1, sizeof(int) * (size_t)--f->nqueued);
		f->delivered++;
		if (f->delivered == (uint32_t)f->cfg.drop_at)
			f->seq += (uint32_t)f->cfg.drop_gap;
		struct timespec ts;
		clock_gettime(CLOCK_MONOTONIC, &ts);
		memset(b, 0, sizeof(*b));
		b->type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
		b->memory = V4L2_MEMORY_MMAP;
		b->index = (uint32_t)index;
		b->sequence = f->seq;
		b->bytesused = (uint32_t)fill(f, f->mem + (size_t)index * f->buflen, f->seq);
		b->field = V4L2_FIELD_NONE;
		b->timestamp.tv_sec = ts.tv_sec;
		b->timestamp.tv_usec = ts.tv_nsec / 1000;
		b->flags = V4L2_BUF_FLAG_MAPPED | V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
		if (f->delivered == (uint32_t)f->cfg.error_at)
			b->flags |= V4L2_BUF_FLAG_ERROR;
		if (f->delivered == (uint32_t)f->cfg.short_at)
			b->bytesused -= 100;
		b->length = (uint32_t)f->buflen;
		f->seq++;
		return 0;
	}
	case VIDIOC_STREAMON:
	case VIDIOC_STREAMOFF: {
		if (*(const int *)arg != V4L2_BUF_TYPE_VIDEO_CAPTURE)
			return fail(EINVAL);
		if (request == VIDIOC_STREAMOFF) {
			stream_off(f);
			return 0;
		}
		if (!f->nbufs)
			return fail(EINVAL);
		if (f->stream_fd >= 0)
			return 0;
		f->stream_fd = fd;
		f->delivered = f->seq = 0;
		signal_ready(f, f->nqueued);
		return 0;
	}
	default:
		return fail(ENOTTY);
	}
}

int fake_v4l2_ioctl(fake_v4l2 *f, int fd, unsigned long request, void *arg)
{
	if (!fake_v4l2_owns(f, fd))
		return fail(EBADF);
	int ret = do_ioctl(f, fd, request, arg);
	int e = ret ? errno : 0;
	if (f->nlog < LOG_MAX) {
		fake_v4l2_call *c = &f->log[f->nlog++];
		*c = (fake_v4l2_call){request, 0, 0, e};
		if (request == VIDIOC_S_CTRL || request == VIDIOC_G_CTRL) {
			c->id = ((const struct v4l2_control *)arg)->id;
			c->value = ((const struct v4l2_control *)arg)->value;
		}
	}
	errno = e;
	return ret;
}

void *fake_v4l2_mmap(fake_v4l2 *f, void *addr, size_t length, int prot, int flags, int fd,
                     off_t offset)
{
	if (!fake_v4l2_owns(f, fd) || !f->mem || offset < 0 ||
	    (size_t)offset + length > f->memlen) {
		errno = EINVAL;
		return MAP_FAILED;
	}
	return mmap(addr, length, prot, flags, f->memfd, offset);
}
