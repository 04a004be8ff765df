/* The V4L2 backend against the fake device behind its ops table: format negotiation and
 * the bytes of every format as float images, ROI, UVC control order and read-back,
 * auto white balance that will not turn off, stream faults (drops, error flags, short
 * buffers, a device that never delivers), capability checks. */
#include <errno.h>
#include <linux/videodev2.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fake_ops.h"
#include "kg_camera.h"
#include "mjpeg.h"
#include "kg_test.h"

#define W 64
#define H 48
#define PAD 8
#define URI "v4l2:/dev/video-kogei-fake"
#define PATH "/dev/video-kogei-fake"

/* What each V4L2 format must become (V4L2 pixel format documentation). */
static const struct want {
	uint32_t fourcc;
	kg_pixfmt pixfmt;
	int bits;
	const char *cfa;
	int bytes; /* per pixel */
} wants[] = {
	{V4L2_PIX_FMT_GREY, KG_PIX_MONO8, 8, "", 1},
	{V4L2_PIX_FMT_Y10, KG_PIX_MONO16, 10, "", 2},
	{V4L2_PIX_FMT_Y12, KG_PIX_MONO16, 12, "", 2},
	{V4L2_PIX_FMT_Y16, KG_PIX_MONO16, 16, "", 2},
	{V4L2_PIX_FMT_SRGGB8, KG_PIX_BAYER8, 8, "RGGB", 1},
	{V4L2_PIX_FMT_SGRBG8, KG_PIX_BAYER8, 8, "GRBG", 1},
	{V4L2_PIX_FMT_SGBRG8, KG_PIX_BAYER8, 8, "GBRG", 1},
	{V4L2_PIX_FMT_SBGGR8, KG_PIX_BAYER8, 8, "BGGR", 1},
	{V4L2_PIX_FMT_SRGGB10, KG_PIX_BAYER16, 10, "RGGB", 2},
	{V4L2_PIX_FMT_SGRBG10, KG_PIX_BAYER16, 10, "GRBG", 2},
	{V4L2_PIX_FMT_SGBRG12, KG_PIX_BAYER16, 12, "GBRG", 2},
	{V4L2_PIX_FMT_SBGGR12, KG_PIX_BAYER16, 12, "BGGR", 2},
	{V4L2_PIX_FMT_SRGGB16, KG_PIX_BAYER16, 16, "RGGB", 2},
	{V4L2_PIX_FMT_RGB24, KG_PIX_RGB8, 8, "", 3},
	{V4L2_PIX_FMT_YUYV, KG_PIX_YUYV, 8, "", 2},
	{V4L2_PIX_FMT_MJPEG, KG_PIX_MJPEG, 8, "", 0},
};
#define NWANTS ((int)(sizeof(wants) / sizeof(wants[0])))

static fake_ops table;

/* A fresh fake at PATH, installed behind the ops table. */
static fake_v4l2 *make_fake(fake_v4l2_config cfg)
{
	uint32_t all[NWANTS];
	if (!cfg.nformats) {
		for (int i = 0; i < NWANTS; i++)
			all[i] = wants[i].fourcc;
		cfg.formats = all;
		cfg.nformats = NWANTS;
	}
	if (!cfg.width) {
		cfg.width = W;
		cfg.height = H;
	}
	fake_v4l2 *f = fake_v4l2_new(&cfg);
	if (!f) {
		fprintf(stderr, "cannot create the fake device\n");
		exit(1);
	}
	fake_ops_install(&table);
	fake_ops_add(&table, PATH, f);
	return f;
}

static kg_camera *open_cam(void)
{
	kg_camera *c = NULL;
	kg_err err = {{0}};
	int ret = kg_camera_open(URI, &c, &err);
	CHECK(ret == 0 && c, "open: %d %s", ret, err.msg);
	if (!c)
		exit(kg_test_done("v4l2"));
	return c;
}

/* A forced MJPEG frame decodes (with or without its Huffman tables: odd sequence numbers
 * come without) to the R'G'B' the fake encoded, within JPEG's loss at quality 95; a
 * damaged one is an error, not a picture. Without libjpeg the message says so. */
/* 1 when the JPEG stream has a DHT (FF C4) segment before its scan. */
static int has_huffman_tables(const uint8_t *j, size_t n)
{
	for (size_t i = 2; i + 4 <= n && j[i] == 0xFF && j[i + 1] != 0xDA;
	     i += 2 + ((size_t)j[i + 2] << 8 | j[i + 3]))
		if (j[i + 1] == 0xC4)
			return 1;
	return 0;
}

static void check_mjpeg(const kg_frame *fr)
{
	kg_err err = {{0}};
	if (kg_mjpeg_available()) /* the fake's real JPEG: odd frames without tables */
		CHECK(has_huffman_tables(fr->data, fr->size) == !(fr->sequence & 1),
		      "MJPEG sequence %llu: Huffman tables %s, expected %s",
		      (unsigned long long)fr->sequence,
		      has_huffman_tables(fr->data, fr->size) ? "present" : "absent",
		      fr->sequence & 1 ? "absent" : "present");
	kg_image *img = NULL;
	int ret = kg_frame_to_image(fr, 1, &img, &err);
	if (!kg_mjpeg_available()) {
		CHECK(ret == KG_ENOTSUP && !img && strstr(err.msg, "without libjpeg"),
		      "MJPEG without libjpeg: %d %s", ret, err.msg);
		return;
	}
	CHECK(ret == 0 && img && img->channels == 3 && img->width == fr->fmt.width &&
	          img->height == fr->fmt.height,
	      "forced MJPEG (sequence %llu): %d %s", (unsigned long long)fr->sequence, ret,
	      err.msg);
	if (!img)
		return;
	double worst = 0, sum = 0;
	for (int y = 0; y < img->height; y++)
		for (int x = 0; x < img->width; x++) {
			uint8_t rgb[3];
			fake_v4l2_smooth_rgb(x, y, (uint32_t)fr->sequence, rgb);
			for (int c = 0; c < 3; c++) {
				double d = fabs(img->data[((size_t)y * img->width + x) * 3 + c] * 255.0 -
				                rgb[c]);
				worst = fmax(worst, d);
				sum += d;
			}
		}
	double mean = sum / ((double)img->width * img->height * 3);
	CHECK(worst <= 12 && mean <= 1.5,
	      "MJPEG sequence %llu decodes to within %.1f levels (mean %.2f): expected <= 12 "
	      "(mean <= 1.5)",
	      (unsigned long long)fr->sequence, worst, mean);
	kg_image_free(&img);

	/* Truncated (the camera's transfer cut short), and of another size than the format. */
	uint8_t *cut = malloc(fr->size);
	memcpy(cut, fr->data, fr->size);
	kg_frame bad = *fr;
	bad.data = cut;
	bad.size = fr->size / 2;
	ret = kg_frame_to_image(&bad, 1, &img, &err);
	CHECK(ret == KG_EINVAL && !img && strstr(err.msg, "MJPEG frame of") &&
	          strstr(err.msg, "frame "),
	      "truncated MJPEG: %d %s", ret, err.msg);
	bad.size = fr->size;
	bad.fmt.width = fr->fmt.width / 2;
	ret = kg_frame_to_image(&bad, 1, &img, &err);
	CHECK(ret == KG_EINVAL && !img && strstr(err.msg, "the camera's format says"),
	      "MJPEG of another size: %d %s", ret, err.msg);
	cut[1] = 0x00;
	bad.fmt.width = fr->fmt.width;
	ret = kg_frame_to_image(&bad, 1, &img, &err);
	CHECK(ret == KG_EINVAL && !img && strstr(err.msg, "SOI"), "not a JPEG: %d %s", ret,
	      err.msg);
	free(cut);
}

/* The image of one frame must hold fake_v4l2_sample of the sensor pixels it shows. */
static void check_image(const kg_frame *fr, const struct want *w, int ox, int oy)
{
	kg_err err = {{0}};
	kg_image *img = NULL;
	int ret = kg_frame_to_image(fr, 0, &img, &err);
	if (w->pixfmt == KG_PIX_MJPEG) {
		CHECK(ret == KG_EINVAL && !img && strstr(err.msg, "MJPEG") &&
		          strstr(err.msg, "unless forced"),
		      "MJPEG must be refused unless forced: %d %s", ret, err.msg);
		const uint8_t *b = fr->data;
		CHECK(fr->size > 4 && b[0] == 0xFF && b[1] == 0xD8 && b[fr->size - 2] == 0xFF &&
		          b[fr->size - 1] == 0xD9,
		      "MJPEG frame of %zu bytes", fr->size);
		check_mjpeg(fr);
		return;
	}
	if (w->pixfmt == KG_PIX_YUYV) {
		CHECK(ret == KG_EINVAL && !img, "YUYV refused for measurement: %d", ret);
		ret = kg_frame_to_image(fr, 1, &img, &err);
	}
	CHECK(ret == 0 && img, "to_image %s: %s", kg_pixfmt_name(w->pixfmt), err.msg);
	if (!img)
		return;
	int ch = w->pixfmt == KG_PIX_RGB8 || w->pixfmt == KG_PIX_YUYV ? 3 : 1;
	CHECK(img->width == fr->fmt.width && img->height == fr->fmt.height &&
	          img->channels == ch,
	      "image %dx%dx%d", img->width, img->height, img->channels);
	double full = (double)((1u << w->bits) - 1);
	int bad = 0;
	double worst = 0;
	for (int y = 0; y < img->height; y++)
		for (int x = 0; x < img->width; x++)
			for (int c = 0; c < ch; c++) {
				double got = img->data[((size_t)y * img->width + x) * ch + c], want;
				double tol = 1e-6;
				if (w->pixfmt == KG_PIX_YUYV) {
					uint8_t rgb[3];
					fake_v4l2_yuyv_rgb(x + ox, y + oy, (uint32_t)fr->sequence, rgb);
					want = rgb[c] / 255.0;
					tol = 0.01; /* 8-bit Y'CbCr quantisation */
				} else {
					want = fake_v4l2_sample(x + ox, y + oy, c, (uint32_t)fr->sequence,
					                        w->bits) /
					       full;
				}
				if (fabs(got - want) > tol) {
					bad++;
					worst = fmax(worst, fabs(got - want));
				}
			}
	CHECK(!bad, "%s %d bits: %d samples differ from the device's, worst by %g",
	      kg_pixfmt_name(w->pixfmt), w->bits, bad, worst);
	if (w->cfa[0])
		CHECK(img->cfa && img->cfa_rows == 2 && img->cfa_cols == 2 &&
		          !strncmp(img->cfa, w->cfa, 4),
		      "CFA %.4s, expected %s", img->cfa ? img->cfa : "(none)", w->cfa);
	kg_image_free(&img);
}

static void test_formats(void)
{
	fake_v4l2 *f = make_fake((fake_v4l2_config){.pad = PAD});
	kg_camera *c = open_cam();
	const kg_camera_info *info = kg_camera_get_info(c);
	CHECK(!strcmp(info->model, "kogei fake camera") && !strcmp(info->transport, "UVC") &&
	          !strcmp(info->serial, "usb-fake-1.2") && info->sensor_width == W &&
	          info->sensor_height == H,
	      "info: %s %s %s %dx%d", info->model, info->transport, info->serial,
	      info->sensor_width, info->sensor_height);
	kg_err err = {{0}};
	for (int i = 0; i < NWANTS; i++) {
		const struct want *w = &wants[i];
		kg_frame_format req = {.pixfmt = w->pixfmt, .bits = w->bits}, got;
		memcpy(req.cfa, w->cfa, strlen(w->cfa) + 1);
		int ret = kg_camera_set_format(c, &req, &got, &err);
		CHECK(ret == 0, "set_format %s %d %s: %s", kg_pixfmt_name(w->pixfmt), w->bits,
		      w->cfa, err.msg);
		if (ret)
			continue;
		CHECK(got.pixfmt == w->pixfmt && got.bits == w->bits && !strcmp(got.cfa, w->cfa) &&
		          got.width == W && got.height == H,
		      "got %s %d bits cfa '%s' %dx%d for %s", kg_pixfmt_name(got.pixfmt), got.bits,
		      got.cfa, got.width, got.height, kg_pixfmt_name(w->pixfmt));
		CHECK(w->pixfmt == KG_PIX_MJPEG || got.stride == (size_t)(W * w->bytes + PAD),
		      "stride %zu, the driver's bytesperline is %d", got.stride, W * w->bytes + PAD);
		CHECK(kg_camera_start(c, 3, &err) == 0, "start: %s", err.msg);
		/* Two frames: the second comes from a re-queued buffer. */
		for (int k = 0; k < 2; k++) {
			kg_frame fr;
			ret = kg_camera_pop(c, 1000, &fr, &err);
			CHECK(ret == 0, "pop %s: %s", kg_pixfmt_name(w->pixfmt), err.msg);
			if (ret)
				break;
			CHECK(fr.status == KG_FRAME_OK && fr.sequence == (uint64_t)k &&
			          fr.timestamp > 0,
			      "frame status %d sequence %llu", fr.status,
			      (unsigned long long)fr.sequence);
			check_image(&fr, w, 0, 0);
			CHECK(kg_camera_push(c, &fr, &err) == 0, "push: %s", err.msg);
		}
		CHECK(kg_camera_stop(c, &err) == 0, "stop: %s", err.msg);
	}

	/* Half size from the discrete frame sizes; the other sizes are what it settles on. */
	kg_frame_format req = {.pixfmt = KG_PIX_MONO8, .width = W / 2, .height = H / 2}, got;
	CHECK(kg_camera_set_format(c, &req, &got, &err) == 0 && got.width == W / 2 &&
	          got.height == H / 2 && got.stride == W / 2 + PAD,
	      "half size: %dx%d stride %zu %s", got.width, got.height, got.stride, err.msg);
	/* No ROI offset without cropping. */
	req = (kg_frame_format){.offset_x = 8, .offset_y = 6};
	int ret = kg_camera_set_format(c, &req, &got, &err);
	CHECK(ret == KG_ENOTSUP && strstr(err.msg, "does not crop") && strstr(err.msg, URI),
	      "ROI on a UVC camera: %d %s", ret, err.msg);
	kg_camera_free(&c);
	fake_v4l2_free(&f);

	/* A UVC camera offers YUYV and MJPEG only: a mono request names what it offers. */
	uint32_t uvc[] = {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG};
	f = make_fake((fake_v4l2_config){.formats = uvc, .nformats = 2});
	c = open_cam();
	req = (kg_frame_format){.pixfmt = KG_PIX_MONO16};
	ret = kg_camera_set_format(c, &req, &got, &err);
	CHECK(ret == KG_ENOTSUP && strstr(err.msg, "YUYV (yuyv)") && strstr(err.msg, "MJPG (mjpeg)"),
	      "format not offered: %d %s", ret, err.msg);
	kg_camera_free(&c);
	fake_v4l2_free(&f);

	/* A current format kogei cannot read: open works, the format must be chosen. */
	uint32_t nv12[] = {V4L2_PIX_FMT_NV12, V4L2_PIX_FMT_GREY};
	f = make_fake((fake_v4l2_config){.formats = nv12, .nformats = 2});
	c = open_cam();
	ret = kg_camera_get_format(c, &got, &err);
	CHECK(ret == KG_ENOTSUP && strstr(err.msg, "NV12"), "NV12: %d %s", ret, err.msg);
	req = (kg_frame_format){.pixfmt = KG_PIX_MONO8};
	CHECK(kg_camera_set_format(c, &req, &got, &err) == 0 && got.pixfmt == KG_PIX_MONO8,
	      "GREY after NV12: %s", err.msg);
	kg_camera_free(&c);
	fake_v4l2_free(&f);
}

static void test_roi(void)
{
	fake_v4l2 *f = make_fake((fake_v4l2_config){.selection = 1, .driver = "fake-sensor"});
	kg_camera *c = open_cam();
	const kg_camera_info *info = kg_camera_get_info(c);
	CHECK(info->sensor_width == W && info->sensor_height == H &&
	          !strcmp(info->transport, "V4L2"),
	      "sensor %dx%d %s", info->sensor_width, info->sensor_height, info->transport);
	kg_err err = {{0}};
	kg_frame_format req = {.pixfmt = KG_PIX_MONO16,
	                       .bits = 12,
	                       .width = 32,
	                       .height = 24,
	                       .offset_x = 8,
	                       .offset_y = 6},
	                got;
	int ret = kg_camera_set_format(c, &req, &got, &err);
	CHECK(ret == 0 && got.width == 32 && got.height == 24 && got.offset_x == 8 &&
	          got.offset_y == 6 && got.bits == 12,
	      "ROI: %d %dx%d+%d+%d %s", ret, got.width, got.height, got.offset_x, got.offset_y,
	      err.msg);
	kg_frame fr;
	if (!ret && !kg_camera_start(c, 2, &err) && !kg_camera_pop(c, 1000, &fr, &err)) {
		static const struct want y12 = {V4L2_PIX_FMT_Y12, KG_PIX_MONO16, 12, "", 2};
		check_image(&fr, &y12, 8, 6);
		kg_camera_push(c, &fr, &err);
	} else {
		CHECK(0, "ROI stream: %s", err.msg);
	}
	kg_camera_free(&c);
	fake_v4l2_free(&f);
}

/* Index in the log of the first S_CTRL of id (with value, if value >= 0), or -1. */
static int find_s_ctrl(const fake_v4l2 *f, uint32_t id, int32_t value, int from)
{
	for (int i = from; i < fake_v4l2_log_count(f); i++) {
		const fake_v4l2_call *k = fake_v4l2_log_at(f, i);
		if (k->request == VIDIOC_S_CTRL && k->id == id && (value < 0 || k->value == value))
			return i;
	}
	return -1;
}

static int find_g_ctrl(const fake_v4l2 *f, uint32_t id, int from)
{
	for (int i = from; i < fake_v4l2_log_count(f); i++) {
		const fake_v4l2_call *k = fake_v4l2_log_at(f, i);
		if (k->request == VIDIOC_G_CTRL && k->id == id)
			return i;
	}
	return -1;
}

static void test_controls(void)
{
	fake_v4l2 *f = make_fake((fake_v4l2_config){.balance = 1, .autogain = 1});
	kg_camera *c = open_cam();
	kg_err err = {{0}};
	kg_feature_info fi;
	CHECK(kg_camera_feature_info(c, KG_FEAT_EXPOSURE_US, &fi, &err) == 0 && fi.available &&
	          fi.writable && fi.min == 300 && fi.max == 204700 && fi.step == 100 &&
	          !strcmp(fi.unit, "us") && !strcmp(fi.native, "V4L2_CID_EXPOSURE_ABSOLUTE"),
	      "exposure info %g..%g step %g %s %s", fi.min, fi.max, fi.step, fi.unit, fi.native);
	CHECK(kg_camera_feature_info(c, KG_FEAT_GAIN, &fi, &err) == 0 && fi.available &&
	          fi.max == 255 && !strcmp(fi.unit, "raw") && !strcmp(fi.native, "V4L2_CID_GAIN"),
	      "gain info %g %s %s", fi.max, fi.unit, fi.native);
	CHECK(kg_camera_feature_info(c, KG_FEAT_FRAME_RATE, &fi, &err) == 0 && fi.available &&
	          fi.writable && fi.min == 5 && fi.max == 30,
	      "frame rate info %g..%g", fi.min, fi.max);
	CHECK(kg_camera_feature_info(c, KG_FEAT_WB_RED, &fi, &err) == 0 && fi.available &&
	          fi.max == 4095.0 / 1024 && !strcmp(fi.unit, "x"),
	      "red balance info max %g %s", fi.max, fi.unit);

	/* The fake refuses an absolute exposure while exposure is automatic. */
	fake_v4l2_log_clear(f);
	double got = 0;
	int ret = kg_camera_set(c, KG_FEAT_EXPOSURE_US, 5000, &got, &err);
	CHECK(ret == 0 && got == 5000, "exposure 5000 us: %d got %g %s", ret, got, err.msg);
	CHECK(fake_v4l2_control(f, V4L2_CID_EXPOSURE_ABSOLUTE) == 50,
	      "device holds %d x 100 us", fake_v4l2_control(f, V4L2_CID_EXPOSURE_ABSOLUTE));
	int i_auto = find_s_ctrl(f, V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL, 0);
	int i_abs = find_s_ctrl(f, V4L2_CID_EXPOSURE_ABSOLUTE, -1, 0);
	CHECK(i_auto >= 0 && i_abs > i_auto, "EXPOSURE_AUTO=manual (%d) before ABSOLUTE (%d)",
	      i_auto, i_abs);
	CHECK(i_abs >= 0 && fake_v4l2_log_at(f, i_abs)->error == 0,
	      "the first EXPOSURE_ABSOLUTE write was refused");
	CHECK(find_g_ctrl(f, V4L2_CID_EXPOSURE_AUTO, i_auto) > i_auto,
	      "EXPOSURE_AUTO read back after the write");
	CHECK(i_abs >= 0 && find_g_ctrl(f, V4L2_CID_EXPOSURE_ABSOLUTE, i_abs) > i_abs,
	      "EXPOSURE_ABSOLUTE read back after the write");
	/* Rounded to the 100 us unit, within one step. */
	CHECK(kg_camera_set(c, KG_FEAT_EXPOSURE_US, 1234, &got, &err) == 0 && got == 1200,
	      "exposure 1234 us settles at %g: %s", got, err.msg);

	/* Back to automatic: UVC offers aperture priority, not full auto. */
	CHECK(kg_camera_set(c, KG_FEAT_AUTO_EXPOSURE, 1, &got, &err) == 0 && got == 1 &&
	          fake_v4l2_control(f, V4L2_CID_EXPOSURE_AUTO) == V4L2_EXPOSURE_APERTURE_PRIORITY &&
	          fake_v4l2_control(f, V4L2_CID_AUTOGAIN) == 1,
	      "auto exposure on: %s", err.msg);
	/* ... and the fake really refuses the absolute exposure now (as UVC firmware does),
	 * so the order above is what made the first write succeed. */
	int fd = -1;
	for (fd = 0; fd < 1024 && !fake_v4l2_owns(f, fd); fd++)
		;
	struct v4l2_control ctl = {.id = V4L2_CID_EXPOSURE_ABSOLUTE, .value = 20};
	CHECK(fake_v4l2_ioctl(f, fd, VIDIOC_S_CTRL, &ctl) == -1 && errno == EACCES,
	      "the fake accepts EXPOSURE_ABSOLUTE in auto mode");

	/* Gain with automatic gain on: AUTOGAIN off first. */
	fake_v4l2_log_clear(f);
	CHECK(kg_camera_set(c, KG_FEAT_GAIN, 100, &got, &err) == 0 && got == 100,
	      "gain 100: got %g %s", got, err.msg);
	int i_ag = find_s_ctrl(f, V4L2_CID_AUTOGAIN, 0, 0);
	int i_gain = find_s_ctrl(f, V4L2_CID_GAIN, 100, 0);
	CHECK(i_ag >= 0 && i_gain > i_ag, "AUTOGAIN off (%d) before GAIN (%d)", i_ag, i_gain);

	/* Manual state: auto exposure and white balance off, balance gains at unity. */
	fake_v4l2_log_clear(f);
	ret = kg_camera_manual(c, &err);
	CHECK(ret == 0, "manual: %s", err.msg);
	CHECK(fake_v4l2_control(f, V4L2_CID_EXPOSURE_AUTO) == V4L2_EXPOSURE_MANUAL &&
	          fake_v4l2_control(f, V4L2_CID_AUTOGAIN) == 0 &&
	          fake_v4l2_control(f, V4L2_CID_AUTO_WHITE_BALANCE) == 0 &&
	          fake_v4l2_control(f, V4L2_CID_RED_BALANCE) == 1024 &&
	          fake_v4l2_control(f, V4L2_CID_BLUE_BALANCE) == 1024,
	      "manual state: auto %d autogain %d awb %d red %d blue %d",
	      fake_v4l2_control(f, V4L2_CID_EXPOSURE_AUTO), fake_v4l2_control(f, V4L2_CID_AUTOGAIN),
	      fake_v4l2_control(f, V4L2_CID_AUTO_WHITE_BALANCE),
	      fake_v4l2_control(f, V4L2_CID_RED_BALANCE),
	      fake_v4l2_control(f, V4L2_CID_BLUE_BALANCE));
	int i_awb = find_s_ctrl(f, V4L2_CID_AUTO_WHITE_BALANCE, 0, 0);
	CHECK(i_awb >= 0 && find_g_ctrl(f, V4L2_CID_AUTO_WHITE_BALANCE, i_awb) > i_awb,
	      "auto white balance written and read back");
	CHECK(kg_camera_set(c, KG_FEAT_WB_RED, 1.5, &got, &err) == 0 && got == 1.5 &&
	          fake_v4l2_control(f, V4L2_CID_RED_BALANCE) == 1536,
	      "red balance 1.5: got %g %s", got, err.msg);

	/* Frame rate through S_PARM; a rate the camera does not offer names what it chose. */
	CHECK(kg_camera_set(c, KG_FEAT_FRAME_RATE, 15, &got, &err) == 0 && got == 15,
	      "15 fps: got %g %s", got, err.msg);
	ret = kg_camera_set(c, KG_FEAT_FRAME_RATE, 20, &got, &err);
	CHECK(ret == KG_ERANGE && strstr(err.msg, "reads back 15"), "20 fps: %d %s", ret,
	      err.msg);
	kg_camera_free(&c);

	/* Settings persist across opens, as on a real camera. */
	c = open_cam();
	CHECK(kg_camera_get(c, KG_FEAT_EXPOSURE_US, &got, &err) == 0 && got == 1200,
	      "exposure after reopen: %g %s", got, err.msg);
	CHECK(kg_camera_get(c, KG_FEAT_AUTO_WHITE_BALANCE, &got, &err) == 0 && got == 0,
	      "awb after reopen: %g %s", got, err.msg);
	kg_camera_free(&c);
	fake_v4l2_free(&f);

	/* Firmware that acknowledges auto white balance off and keeps it on. */
	f = make_fake((fake_v4l2_config){.awb_stuck = 1});
	c = open_cam();
	ret = kg_camera_manual(c, &err);
	CHECK(ret == KG_ENOTSUP && strstr(err.msg, URI) &&
	          strstr(err.msg, "V4L2_CID_AUTO_WHITE_BALANCE") &&
	          strstr(err.msg, "reads back 1"),
	      "stuck AWB: %d %s", ret, err.msg);
	kg_camera_free(&c);
	fake_v4l2_free(&f);
}

static void test_stream_faults(void)
{
	fake_v4l2 *f = make_fake((fake_v4l2_config){.drop_at = 3, .drop_gap = 2, .error_at = 4,
	                                            .short_at = 5});
	kg_camera *c = open_cam();
	kg_err err = {{0}};
	kg_frame_format req = {.pixfmt = KG_PIX_MONO16, .bits = 16}, got;
	CHECK(kg_camera_set_format(c, &req, &got, &err) == 0, "Y16: %s", err.msg);
	CHECK(kg_camera_start(c, 0, &err) == 0, "start: %s", err.msg);
	static const uint64_t seqs[] = {0, 1, 4, 5, 6, 7};
	static const int status[] = {KG_FRAME_OK,      KG_FRAME_OK,         KG_FRAME_OK,
	                             KG_FRAME_CORRUPT, KG_FRAME_INCOMPLETE, KG_FRAME_OK};
	for (int k = 0; k < 6; k++) {
		kg_frame fr;
		int ret = kg_camera_pop(c, 1000, &fr, &err);
		CHECK(ret == 0, "pop %d: %s", k, err.msg);
		if (ret)
			break;
		CHECK(fr.sequence == seqs[k] && fr.status == status[k],
		      "frame %d: sequence %llu status %d, expected %llu %d", k,
		      (unsigned long long)fr.sequence, fr.status, (unsigned long long)seqs[k],
		      status[k]);
		CHECK(fr.status != KG_FRAME_INCOMPLETE || fr.size == got.size - 100,
		      "short frame of %zu bytes", fr.size);
		kg_camera_push(c, &fr, &err);
	}
	kg_stream_stats st;
	kg_camera_stats(c, &st);
	CHECK(st.dropped == 2 && st.failed == 1 && st.incomplete == 1 && st.completed == 4 &&
	          st.timeouts == 0,
	      "stats: dropped %llu failed %llu incomplete %llu completed %llu",
	      (unsigned long long)st.dropped, (unsigned long long)st.failed,
	      (unsigned long long)st.incomplete, (unsigned long long)st.completed);
	/* Stop takes the buffers back: STREAMOFF, then REQBUFS 0. */
	fake_v4l2_log_clear(f);
	CHECK(kg_camera_stop(c, &err) == 0, "stop: %s", err.msg);
	int off = -1, free0 = -1;
	for (int i = 0; i < fake_v4l2_log_count(f); i++) {
		unsigned long r = fake_v4l2_log_at(f, i)->request;
		if (r == VIDIOC_STREAMOFF && off < 0)
			off = i;
		if (r == VIDIOC_REQBUFS)
			free0 = i;
	}
	CHECK(off >= 0 && free0 > off, "STREAMOFF (%d) then REQBUFS 0 (%d)", off, free0);
	kg_camera_free(&c);
	fake_v4l2_free(&f);

	/* A device that never delivers: timeouts with the counts, every time. */
	f = make_fake((fake_v4l2_config){.stall = 1});
	c = open_cam();
	CHECK(kg_camera_start(c, 2, &err) == 0, "start: %s", err.msg);
	for (int k = 1; k <= 2; k++) {
		kg_frame fr;
		int ret = kg_camera_pop(c, 30, &fr, &err);
		char want[64];
		snprintf(want, sizeof(want), "0 complete, 0 dropped, 0 incomplete, 0 failed, %d "
		         "timeouts", k);
		CHECK(ret == KG_ETIMEDOUT && strstr(err.msg, "no frame within 30 ms") &&
		          strstr(err.msg, want) && strstr(err.msg, URI),
		      "stalled device: %d %s", ret, err.msg);
	}
	kg_stream_stats st2;
	kg_camera_stats(c, &st2);
	CHECK(st2.timeouts == 2 && st2.completed == 0, "timeouts %llu",
	      (unsigned long long)st2.timeouts);
	kg_camera_free(&c);
	fake_v4l2_free(&f);
}

static void test_capabilities(void)
{
	kg_err err = {{0}};
	kg_camera *c = NULL;
	fake_v4l2 *f = make_fake((fake_v4l2_config){.device_caps = V4L2_CAP_VIDEO_CAPTURE |
	                                                           V4L2_CAP_READWRITE});
	int ret = kg_camera_open(URI, &c, &err);
	CHECK(ret == KG_ENOTSUP && !c && strstr(err.msg, "V4L2_CAP_STREAMING") &&
	          strstr(err.msg, URI),
	      "no streaming: %d %s", ret, err.msg);
	fake_v4l2_free(&f);
	f = make_fake((fake_v4l2_config){.device_caps = V4L2_CAP_META_CAPTURE |
	                                               V4L2_CAP_STREAMING});
	ret = kg_camera_open(URI, &c, &err);
	CHECK(ret == KG_ENOTSUP && !c && strstr(err.msg, "not a video capture node"),
	      "metadata node: %d %s", ret, err.msg);
	fake_v4l2_free(&f);
	fake_ops_install(&table); /* no devices at all */
	ret = kg_camera_open("v4l2:/dev/video-kogei-absent", &c, &err);
	CHECK(ret == KG_ENODEV && !c && strstr(err.msg, "/dev/video-kogei-absent"),
	      "absent: %d %s", ret, err.msg);
	ret = kg_camera_open("v4l2:video0", &c, &err);
	CHECK(ret == KG_EINVAL && !c, "relative path: %d %s", ret, err.msg);
}

static void found(void *user, const char *uri, const char *model, const char *serial,
                  const char *transport)
{
	char *list = user;
	size_t n = strlen(list);
	snprintf(list + n, 1024 - n, "%s|%s|%s|%s\n", uri, model, serial, transport);
}

static void note(void *user, const char *scheme, const char *message)
{
	if (!strcmp(scheme, "v4l2"))
		CHECK(0, "v4l2 enumeration: %s", message);
}

/* Capture nodes are listed with card and bus; metadata nodes are not cameras. */
static void test_enumerate(void)
{
	fake_v4l2 *cam = make_fake((fake_v4l2_config){0});
	fake_v4l2_config meta = {.device_caps = V4L2_CAP_META_CAPTURE | V4L2_CAP_STREAMING};
	uint32_t grey = V4L2_PIX_FMT_GREY;
	meta.formats = &grey;
	meta.nformats = 1;
	meta.width = W;
	meta.height = H;
	fake_v4l2 *m = fake_v4l2_new(&meta);
	fake_ops_add(&table, "/dev/video-kogei-meta", m);
	char list[1024] = "";
	kg_camera_enumerate(found, note, list);
	char v4l2_lines[1024] = "";
	for (char *line = strtok(list, "\n"); line; line = strtok(NULL, "\n"))
		if (!strncmp(line, "v4l2:", 5)) {
			strcat(v4l2_lines, line);
			strcat(v4l2_lines, "\n");
		}
	CHECK(!strcmp(v4l2_lines, URI "|kogei fake camera|usb-fake-1.2|UVC\n"),
	      "enumerated:\n%s", v4l2_lines);
	fake_v4l2_free(&m);
	fake_v4l2_free(&cam);
}

int main(void)
{
	test_formats();
	test_roi();
	test_controls();
	test_stream_faults();
	test_capabilities();
	test_enumerate();
	/* Back to libc: the fake path is not in /dev. */
	kg_v4l2_set_ops(NULL);
	kg_camera *c = NULL;
	kg_err err = {{0}};
	CHECK(kg_camera_open(URI, &c, &err) == KG_ENODEV && !c, "libc ops: %s", err.msg);
	return kg_test_done("v4l2");
}
