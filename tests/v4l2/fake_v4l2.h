/* A fake V4L2 capture device in user space, served two ways: in-process behind the
 * backend's ops table (fake_ops.c) and to a whole program through the LD_PRELOAD shim
 * (fake_video_preload.c).
 *
 * It behaves like a UVC camera where that matters to a client: single-planar capture
 * with mmap streaming; V4L2_CID_EXPOSURE_AUTO is a menu offering only manual (1) and
 * aperture priority (3), and V4L2_CID_EXPOSURE_ABSOLUTE (100 us units) is refused with
 * EACCES while the mode is not manual, as uvcvideo does for inactive controls;
 * V4L2_CID_AUTO_WHITE_BALANCE starts on; frame intervals are 1/30, 1/15 and 1/5 s.
 * Settings persist across opens. Each open returns an eventfd (so poll works on it);
 * buffers live in one memfd that mmap maps. A queued buffer is ready at once (unless
 * the device stalls) and is filled at VIDIOC_DQBUF with fake_v4l2_sample values.
 *
 * Every call returns like the system call it stands for: -1 with errno on failure. */
#ifndef FAKE_V4L2_H
#define FAKE_V4L2_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

typedef struct fake_v4l2_config {
	const uint32_t *formats; /* fourccs offered; the first is the initial format */
	int nformats;
	int width, height;       /* sensor; frame sizes offered: full and half */
	const char *driver;      /* VIDIOC_QUERYCAP driver ("uvcvideo" when NULL) */
	uint32_t device_caps;    /* 0: V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING */
	int pad;                 /* bytes added to every row (bytesperline > width * bpp) */
	int selection;           /* crops through VIDIOC_S_SELECTION (a sensor, not UVC) */
	int balance;             /* has V4L2_CID_RED/BLUE_BALANCE (0..4095, default 1024) */
	int autogain;            /* has V4L2_CID_AUTOGAIN, initially on */
	int awb_stuck;           /* accepts AUTO_WHITE_BALANCE = 0 but stays on */
	int stall;               /* no buffer ever becomes ready */
	int drop_at, drop_gap;   /* the drop_at-th frame (1-based) comes drop_gap sequence
	                            numbers late, as if drop_gap frames were lost */
	int error_at;            /* the error_at-th frame carries V4L2_BUF_FLAG_ERROR */
	int short_at;            /* the short_at-th frame has bytesused 100 bytes short */
} fake_v4l2_config;

typedef struct fake_v4l2 fake_v4l2;

/* One logged ioctl: request, and for controls the id, the value and the errno (0). */
typedef struct fake_v4l2_call {
	unsigned long request;
	uint32_t id;
	int32_t value;
	int error;
} fake_v4l2_call;

fake_v4l2 *fake_v4l2_new(const fake_v4l2_config *cfg);
void fake_v4l2_free(fake_v4l2 **f);

/* A new handle on the device: an eventfd, or -1. fake_v4l2_release forgets a handle
 * (stopping its stream) without closing it: the caller closes the fd. */
int fake_v4l2_open(fake_v4l2 *f);
int fake_v4l2_owns(const fake_v4l2 *f, int fd);
void fake_v4l2_release(fake_v4l2 *f, int fd);

int fake_v4l2_ioctl(fake_v4l2 *f, int fd, unsigned long request, void *arg);
void *fake_v4l2_mmap(fake_v4l2 *f, void *addr, size_t length, int prot, int flags, int fd,
                     off_t offset);

/* Every ioctl since fake_v4l2_new (or the last clear), in order. */
int fake_v4l2_log_count(const fake_v4l2 *f);
const fake_v4l2_call *fake_v4l2_log_at(const fake_v4l2 *f, int i);
void fake_v4l2_log_clear(fake_v4l2 *f);
/* Current value of a control (0 when absent). */
int32_t fake_v4l2_control(const fake_v4l2 *f, uint32_t id);

/* The sample the device delivers at sensor pixel (x, y), channel c, in the frame with
 * sequence number seq, for a format with `bits` significant bits: a hash spread over
 * the whole range 0 .. 2^bits - 1. */
uint32_t fake_v4l2_sample(int x, int y, int c, uint32_t seq, int bits);
/* YUYV frames encode, with BT.601 limited range, the 8-bit R'G'B' that this returns:
 * fake_v4l2_sample(x & ~1, y, 0..2, seq, 8), so both pixels of a pair share one colour
 * and the chroma they share is exact. */
void fake_v4l2_yuyv_rgb(int x, int y, uint32_t seq, uint8_t rgb[3]);
/* MJPEG frames (built with libjpeg, FAKE_V4L2_JPEG): a baseline JPEG at quality 95 of
 * the R'G'B' this returns, a smooth pattern JPEG keeps to a level or two; frames with
 * an odd sequence number come without Huffman tables, as UVC cameras send them.
 * Without libjpeg: FAKE_V4L2_JPEG_BYTES bytes, FF D8 ... FF D9, not decodable. */
void fake_v4l2_smooth_rgb(int x, int y, uint32_t seq, uint8_t rgb[3]);
enum { FAKE_V4L2_JPEG_BYTES = 600 };

#endif
