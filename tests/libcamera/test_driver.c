/* The libcamera driver (devices/libcamera/libcamera.c) through kogei's public camera
 * API, with the scripted shim of fake_shim.c in place of libcamera (this machine has
 * no camera libcamera can drive). Checks:
 * - open by index and by id, identity; a missing id is KG_ENODEV naming it;
 * - the first format is the deepest unpacked Bayer the raw stream lists (SBGGR12, not
 *   the packed SBGGR10_CSI2P listed before it), with libcamera's stride;
 * - a format the stream only has packed (bayer10) and one no stream has (mono8) are
 *   refused naming what libcamera settled on and offers; an ROI offset is refused;
 * - rgb8 comes from the processed stream's RGB888 with red and blue swapped, at the
 *   size already set;
 * - features map onto the controls (ranges, units, names; frame_rate through frame
 *   durations); kg_camera_manual turns AE and AWB off;
 * - frames carry the exposure of their own request's metadata, and a new exposure
 *   reads back from metadata once a frame carrying it completes;
 * - sequence gaps count as dropped, a short buffer is incomplete, an empty queue
 *   times out; closing gives everything back. */
#include <stdio.h>
#include <string.h>

#include "kg_camera.h"
#include "kg_test.h"

int kg_lc_test_open_cameras(void); /* fake_shim.c */

static kg_camera *open_cam(const char *uri)
{
	kg_camera *c = NULL;
	kg_err e = {{0}};
	int ret = kg_camera_open(uri, &c, &e);
	CHECK(ret == 0 && c, "open %s: %d %s", uri, ret, e.msg);
	return c;
}

static void check_open(void)
{
	kg_camera *c = open_cam("libcamera:fake/sensor@10");
	if (!c)
		return;
	const kg_camera_info *i = kg_camera_get_info(c);
	CHECK(!strcmp(i->model, "fakesensor") && !strcmp(i->transport, "libcamera") &&
	          i->sensor_width == 4056 && i->sensor_height == 3040 &&
	          !strcmp(i->backend, "libcamera"),
	      "info: model %s transport %s sensor %dx%d backend %s", i->model, i->transport,
	      i->sensor_width, i->sensor_height, i->backend);
	kg_camera_free(&c);
	kg_err e = {{0}};
	int ret = kg_camera_open("libcamera:fake/other", &c, &e);
	CHECK(ret == KG_ENODEV && !c && strstr(e.msg, "libcamera:fake/other"),
	      "missing camera: %d %s", ret, e.msg);
}

static void check_formats(kg_camera *c)
{
	kg_frame_format f;
	kg_err e = {{0}};
	int ret = kg_camera_get_format(c, &f, &e);
	CHECK(ret == 0 && f.pixfmt == KG_PIX_BAYER16 && f.bits == 12 && !strcmp(f.cfa, "BGGR") &&
	          f.width == 64 && f.height == 48 && f.stride == 64 * 2 + 32 &&
	          f.size == f.stride * 48,
	      "first format: %d %s %d bits %s %dx%d stride %zu (%s)", ret,
	      kg_pixfmt_name(f.pixfmt), f.bits, f.cfa, f.width, f.height, f.stride, e.msg);

	kg_frame_format want, got;
	memset(&want, 0, sizeof(want));
	want.pixfmt = KG_PIX_BAYER16;
	want.bits = 10;
	ret = kg_camera_set_format(c, &want, &got, &e);
	CHECK(ret == KG_ENOTSUP && strstr(e.msg, "SBGGR10_CSI2P") && strstr(e.msg, "offers") &&
	          strstr(e.msg, "bayer10"),
	      "bayer10 from a packed-only stream: %d %s", ret, e.msg);

	want.pixfmt = KG_PIX_MONO8;
	want.bits = 0;
	ret = kg_camera_set_format(c, &want, &got, &e);
	CHECK(ret == KG_ENOTSUP && strstr(e.msg, "processed stream") && strstr(e.msg, "raw stream"),
	      "mono8 from neither stream: %d %s", ret, e.msg);

	want.pixfmt = KG_PIX_NONE;
	want.offset_x = 8;
	ret = kg_camera_set_format(c, &want, &got, &e);
	CHECK(ret == KG_ENOTSUP && strstr(e.msg, "ROI"), "ROI offset: %d %s", ret, e.msg);

	/* a size request is validated (rounded to even here) and reported in got */
	memset(&want, 0, sizeof(want));
	want.width = 41;
	want.height = 31;
	ret = kg_camera_set_format(c, &want, &got, &e);
	CHECK(ret == 0 && got.pixfmt == KG_PIX_BAYER16 && got.bits == 12 && got.width == 40 &&
	          got.height == 30,
	      "size 41x31 settles at %dx%d %s %d bits (%d %s)", got.width, got.height,
	      kg_pixfmt_name(got.pixfmt), got.bits, ret, e.msg);
}

static void check_features(kg_camera *c)
{
	kg_feature_info fi;
	kg_err e = {{0}};
	int ret = kg_camera_feature_info(c, KG_FEAT_EXPOSURE_US, &fi, &e);
	CHECK(ret == 0 && fi.available && fi.writable && fi.min == 10 && fi.max == 100000 &&
	          !strcmp(fi.unit, "us") && !strcmp(fi.native, "ExposureTime"),
	      "exposure: %d avail %d %g..%g %s %s", ret, fi.available, fi.min, fi.max, fi.unit,
	      fi.native);
	ret = kg_camera_feature_info(c, KG_FEAT_FRAME_RATE, &fi, &e);
	CHECK(ret == 0 && fabs(fi.min - 1) < 1e-9 && fabs(fi.max - 1e6 / 33333) < 1e-9 &&
	          !strcmp(fi.native, "FrameDurationLimits"),
	      "frame rate %g..%g %s", fi.min, fi.max, fi.native);
	ret = kg_camera_feature_info(c, KG_FEAT_WB_BLUE, &fi, &e);
	CHECK(ret == 0 && !strcmp(fi.native, "ColourGains[1]"), "wb_blue: %s", fi.native);

	ret = kg_camera_manual(c, &e);
	CHECK(ret == 0, "manual: %s", e.msg);
	double v = -1;
	CHECK(kg_camera_get(c, KG_FEAT_AUTO_EXPOSURE, &v, &e) == 0 && v == 0, "AeEnable %g", v);
	CHECK(kg_camera_get(c, KG_FEAT_WB_RED, &v, &e) == 0 && v == 1, "ColourGains[0] %g", v);

	double got = 0;
	ret = kg_camera_set(c, KG_FEAT_FRAME_RATE, 20, &got, &e);
	CHECK(ret == 0 && fabs(got - 20) < 1e-9, "frame rate 20: %d read %g (%s)", ret, got, e.msg);
	ret = kg_camera_set(c, KG_FEAT_EXPOSURE_US, 200000, &got, &e);
	CHECK(ret == KG_ERANGE, "exposure beyond the range: %d (%s)", ret, e.msg);
	ret = kg_camera_set(c, KG_FEAT_EXPOSURE_US, 5000, &got, &e);
	CHECK(ret == 0 && got == 5000, "exposure 5000: %d read %g (%s)", ret, got, e.msg);
}

static void check_stream(kg_camera *c)
{
	kg_err e = {{0}};
	int ret = kg_camera_start(c, 3, &e);
	CHECK(ret == 0, "start: %s", e.msg);
	if (ret)
		return;
	kg_frame f;
	/* three queued requests carry 5000 us (metadata: 4980, whole 30 us lines) */
	for (int i = 0; i < 3; i++) {
		ret = kg_camera_pop(c, 100, &f, &e);
		CHECK(ret == 0 && f.exposure_us == 4980 && f.fmt.pixfmt == KG_PIX_BAYER16,
		      "frame %d: %d exposure %g (%s)", i, ret, f.exposure_us, e.msg);
		if (ret)
			return;
		const uint8_t *p = (const uint8_t *)f.data + f.fmt.stride * 3;
		unsigned v = (unsigned)(p[2 * 5] | p[2 * 5 + 1] << 8);
		CHECK(v == ((5 + 2 * 3 + f.sequence) & 0xfff), "frame %llu pixel (5,3) %u",
		      (unsigned long long)f.sequence, v);
		if (i == 0) { /* a new exposure: the frames already queued keep the old one */
			double got;
			ret = kg_camera_set(c, KG_FEAT_EXPOSURE_US, 8000, &got, &e);
			CHECK(ret == 0 && got == 8000, "exposure 8000 while streaming: %d %g (%s)", ret,
			      got, e.msg);
		}
		kg_camera_push(c, &f, &e);
	}
	kg_stream_stats st;
	kg_camera_stats(c, &st);
	CHECK(st.dropped == 1 && st.completed == 3, "after sequences 1, 2, 4: %llu dropped, %llu complete",
	      (unsigned long long)st.dropped, (unsigned long long)st.completed);
	/* the next frame (sequence 5) carries 8000 us and comes back half filled */
	ret = kg_camera_pop(c, 100, &f, &e);
	CHECK(ret == 0 && f.sequence == 5 && f.status == KG_FRAME_INCOMPLETE &&
	          f.exposure_us == 7980,
	      "sequence %llu status %d exposure %g", (unsigned long long)f.sequence, f.status,
	      f.exposure_us);
	double v;
	CHECK(kg_camera_get(c, KG_FEAT_EXPOSURE_US, &v, &e) == 0 && v == 7980,
	      "exposure read back from metadata: %g", v);
	kg_camera_stats(c, &st);
	CHECK(st.incomplete == 1, "incomplete %llu", (unsigned long long)st.incomplete);
	/* nothing queued: every buffer is out */
	kg_frame held[3];
	int nheld = 0;
	while (nheld < 3 && kg_camera_pop(c, 10, &held[nheld], &e) == 0)
		nheld++;
	ret = kg_camera_pop(c, 10, &held[0], &e);
	CHECK(ret == KG_ETIMEDOUT, "pop with every buffer out: %d (%s)", ret, e.msg);
	kg_camera_stats(c, &st);
	CHECK(st.timeouts >= 1, "timeouts %llu", (unsigned long long)st.timeouts);
	CHECK(kg_camera_stop(c, &e) == 0, "stop: %s", e.msg);
}

static void check_rgb(kg_camera *c)
{
	kg_frame_format want, got;
	kg_err e = {{0}};
	memset(&want, 0, sizeof(want));
	want.pixfmt = KG_PIX_RGB8;
	int ret = kg_camera_set_format(c, &want, &got, &e);
	/* the size is kept (40x30 from check_formats), the stride is libcamera's */
	CHECK(ret == 0 && got.pixfmt == KG_PIX_RGB8 && got.width == 40 && got.height == 30 &&
	          got.stride == 40 * 3 + 16,
	      "rgb8: %d %s %dx%d stride %zu (%s)", ret, kg_pixfmt_name(got.pixfmt), got.width,
	      got.height, got.stride, e.msg);
	if (ret || kg_camera_start(c, 0, &e))
		return;
	kg_frame f;
	ret = kg_camera_pop(c, 100, &f, &e);
	CHECK(ret == 0 && f.status == KG_FRAME_OK, "rgb frame: %d %s", ret, e.msg);
	if (!ret) {
		const uint8_t *p = (const uint8_t *)f.data + f.fmt.stride * 7 + 3 * 9;
		CHECK(p[0] == 30 && p[1] == 20 && p[2] == 10, "RGB888 B,G,R 10,20,30 as rgb8: %d %d %d",
		      p[0], p[1], p[2]);
		kg_image *img = NULL;
		CHECK(kg_frame_to_image(&f, 0, &img, &e) == 0 && img && img->channels == 3,
		      "to image: %s", e.msg);
		kg_image_free(&img);
		kg_camera_push(c, &f, &e);
	}
	kg_camera_stop(c, &e);
}

int main(void)
{
#if !HAVE_LIBCAMERA
	kg_test_skip("the libcamera backend is not built (pkg-config libcamera and a C++ "
	             "compiler are needed)");
	return 77;
#else
	check_open();
	kg_camera *c = open_cam("libcamera:0");
	if (c) {
		check_formats(c);
		check_features(c);
		check_stream(c);
		check_rgb(c);
		kg_camera_free(&c);
	}
	CHECK(kg_lc_test_open_cameras() == 0, "%d cameras left open", kg_lc_test_open_cameras());
	return kg_test_done("libcamera-driver");
#endif
}
