/* The Aravis backend against Aravis' in-process fake camera (aravis:Fake_1): frames
 * injected through the fake's fill callback come out byte for byte in every pixel
 * format the fake offers and with a region of interest; features map onto the fake's
 * GenICam names (ExposureTimeAbs, GainRaw, AcquisitionFrameRate, GainAuto) and land in
 * its registers; refusals name what was expected. No network is touched: the fake
 * interface is in-process and KOGEI_CAMERA_DISCOVERY=none keeps GigE Vision off. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "aravis/aravis_hook.h"
#include "aravis_inject.h"
#include "kg_camera.h"
#include "kg_test.h"

static inject injected;

static void on_open(void *user, ArvCamera *cam)
{
	ArvDevice *dev = arv_camera_get_device(cam);
	if (ARV_IS_FAKE_DEVICE(dev))
		inject_attach(&injected, arv_fake_device_get_fake_camera(ARV_FAKE_DEVICE(dev)));
}

static guint32 reg(guint32 address)
{
	guint32 v = 0;
	arv_fake_camera_read_register(injected.fake, address, &v);
	return v;
}

/* Stream n frames in format want and check each against the injected bytes. */
static void stream_format(kg_camera *c, const char *name, kg_pixfmt pf, int bits,
                          const char *cfa, int n)
{
	kg_err err = {{0}};
	kg_frame_format want = {.pixfmt = pf, .bits = bits, .width = 96, .height = 64,
	                        .offset_x = 40, .offset_y = 24};
	snprintf(want.cfa, sizeof(want.cfa), "%s", cfa);
	kg_frame_format got;
	int ret = kg_camera_set_format(c, &want, &got, &err);
	CHECK(ret == 0, "%s: set_format: %s", name, err.msg);
	if (ret)
		return;
	CHECK(got.pixfmt == pf && got.bits == (bits ? bits : 8) && !strcmp(got.cfa, cfa),
	      "%s: got %s bits %d cfa '%s'", name, kg_pixfmt_name(got.pixfmt), got.bits, got.cfa);
	CHECK(got.width == 96 && got.height == 64 && got.offset_x == 40 && got.offset_y == 24,
	      "%s: region %dx%d at (%d,%d)", name, got.width, got.height, got.offset_x,
	      got.offset_y);
	size_t bpp = (size_t)kg_pixfmt_bytes_per_pixel(pf);
	CHECK(got.stride == 96 * bpp && got.size == 96 * 64 * bpp, "%s: stride %zu size %zu", name,
	      got.stride, got.size);
	/* The device itself holds the region (its registers, not kogei's idea of them). */
	CHECK(reg(ARV_FAKE_CAMERA_REGISTER_WIDTH) == 96 && reg(ARV_FAKE_CAMERA_REGISTER_HEIGHT) == 64 &&
	          reg(ARV_FAKE_CAMERA_REGISTER_X_OFFSET) == 40 &&
	          reg(ARV_FAKE_CAMERA_REGISTER_Y_OFFSET) == 24,
	      "%s: fake registers %ux%u at (%u,%u)", name, reg(ARV_FAKE_CAMERA_REGISTER_WIDTH),
	      reg(ARV_FAKE_CAMERA_REGISTER_HEIGHT), reg(ARV_FAKE_CAMERA_REGISTER_X_OFFSET),
	      reg(ARV_FAKE_CAMERA_REGISTER_Y_OFFSET));

	injected.filled = 0;
	ret = kg_camera_start(c, 4, &err);
	CHECK(ret == 0, "%s: start: %s", name, err.msg);
	if (ret)
		return;
	uint64_t first_seq = 0;
	for (int k = 0; k < n; k++) {
		kg_frame f;
		ret = kg_camera_pop(c, 2000, &f, &err);
		CHECK(ret == 0, "%s: pop %d: %s", name, k, err.msg);
		if (ret)
			break;
		CHECK(f.status == KG_FRAME_OK, "%s: frame %d status %d", name, k, f.status);
		CHECK(f.fmt.pixfmt == pf && f.fmt.width == 96 && f.fmt.height == 64,
		      "%s: frame %d format %s %dx%d", name, k, kg_pixfmt_name(f.fmt.pixfmt),
		      f.fmt.width, f.fmt.height);
		CHECK(inject_matches(&f, (uint64_t)k), "%s: frame %d is not the injected frame", name,
		      k);
		if (k == 0)
			first_seq = f.sequence;
		CHECK(f.sequence == first_seq + (uint64_t)k, "%s: frame %d sequence %llu after %llu",
		      name, k, (unsigned long long)f.sequence, (unsigned long long)first_seq);
		ret = kg_camera_push(c, &f, &err);
		CHECK(ret == 0, "%s: push: %s", name, err.msg);
	}
	kg_stream_stats st;
	kg_camera_stats(c, &st);
	CHECK(st.completed == (uint64_t)n && !st.failed && !st.incomplete && !st.dropped &&
	          !st.timeouts,
	      "%s: completed %llu failed %llu incomplete %llu dropped %llu timeouts %llu", name,
	      (unsigned long long)st.completed, (unsigned long long)st.failed,
	      (unsigned long long)st.incomplete, (unsigned long long)st.dropped,
	      (unsigned long long)st.timeouts);
	ret = kg_camera_stop(c, &err);
	CHECK(ret == 0, "%s: stop: %s", name, err.msg);
}

static void check_features(kg_camera *c)
{
	kg_err err = {{0}};
	kg_feature_info fi;
	int ret = kg_camera_feature_info(c, KG_FEAT_EXPOSURE_US, &fi, &err);
	CHECK(ret == 0 && fi.available && fi.writable && !strcmp(fi.native, "ExposureTimeAbs") &&
	          !strcmp(fi.unit, "us"),
	      "exposure: ret %d native '%s' unit '%s' %s", ret, fi.native, fi.unit, err.msg);
	double got = 0;
	ret = kg_camera_set(c, KG_FEAT_EXPOSURE_US, 4000, &got, &err);
	CHECK(ret == 0 && got == 4000, "set exposure 4000: got %g: %s", got, err.msg);
	CHECK(reg(ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US) == 4000,
	      "fake exposure register %u, expected 4000",
	      reg(ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US));

	ret = kg_camera_feature_info(c, KG_FEAT_GAIN, &fi, &err);
	CHECK(ret == 0 && fi.available && !strcmp(fi.native, "GainRaw") && !strcmp(fi.unit, "raw") &&
	          fi.step == 1 && fi.max > fi.min,
	      "gain: native '%s' unit '%s' step %g range %g..%g", fi.native, fi.unit, fi.step, fi.min,
	      fi.max);
	ret = kg_camera_set(c, KG_FEAT_GAIN, 3, &got, &err);
	CHECK(ret == 0 && got == 3, "set gain 3: got %g: %s", got, err.msg);
	CHECK(reg(ARV_FAKE_CAMERA_REGISTER_GAIN_RAW) == 3, "fake gain register %u, expected 3",
	      reg(ARV_FAKE_CAMERA_REGISTER_GAIN_RAW));
	ret = kg_camera_set(c, KG_FEAT_GAIN, fi.max + 1, NULL, &err);
	CHECK(ret == KG_ERANGE && strstr(err.msg, "gain"), "gain above range: %d %s", ret, err.msg);

	ret = kg_camera_feature_info(c, KG_FEAT_FRAME_RATE, &fi, &err);
	CHECK(ret == 0 && fi.available && !strcmp(fi.native, "AcquisitionFrameRate"),
	      "frame rate: native '%s'", fi.native);
	ret = kg_camera_set(c, KG_FEAT_FRAME_RATE, 200, &got, &err);
	CHECK(ret == 0 && got == 200, "set frame rate 200: got %g: %s", got, err.msg);
	CHECK(reg(ARV_FAKE_CAMERA_REGISTER_ACQUISITION_FRAME_PERIOD_US) == 5000,
	      "fake frame period %u us, expected 5000",
	      reg(ARV_FAKE_CAMERA_REGISTER_ACQUISITION_FRAME_PERIOD_US));

	/* The fake has GainAuto but no ExposureAuto: auto exposure maps onto GainAuto
	 * (Off = 1, Continuous = 2 in its register). */
	ret = kg_camera_feature_info(c, KG_FEAT_AUTO_EXPOSURE, &fi, &err);
	CHECK(ret == 0 && fi.available && !strcmp(fi.native, "GainAuto"), "auto exposure: '%s'",
	      fi.native);
	ret = kg_camera_set(c, KG_FEAT_AUTO_EXPOSURE, 1, &got, &err);
	CHECK(ret == 0 && got == 1 && reg(ARV_FAKE_CAMERA_REGISTER_GAIN_MODE) == 2,
	      "auto on: got %g register %u: %s", got, reg(ARV_FAKE_CAMERA_REGISTER_GAIN_MODE),
	      err.msg);
	ret = kg_camera_manual(c, &err);
	CHECK(ret == 0 && reg(ARV_FAKE_CAMERA_REGISTER_GAIN_MODE) == 1,
	      "manual: register %u: %s", reg(ARV_FAKE_CAMERA_REGISTER_GAIN_MODE), err.msg);

	for (kg_feature f = KG_FEAT_AUTO_WHITE_BALANCE; f <= KG_FEAT_WB_BLUE; f++) {
		ret = kg_camera_feature_info(c, f, &fi, &err);
		CHECK(ret == 0 && !fi.available, "%s should be absent on the fake", kg_feature_name(f));
		ret = kg_camera_set(c, f, 1, NULL, &err);
		CHECK(ret == KG_ENOTSUP && strstr(err.msg, kg_feature_name(f)), "set %s: %d %s",
		      kg_feature_name(f), ret, err.msg);
	}
}

/* The settings in force travel with each frame: the fake passes its exposure and gain
 * to the fill callback, which writes them into the frame header. */
static void check_frame_settings(kg_camera *c)
{
	kg_err err = {{0}};
	kg_frame_format want = {.pixfmt = KG_PIX_MONO8, .width = 64, .height = 32};
	int ret = kg_camera_set_format(c, &want, NULL, &err);
	if (!ret)
		ret = kg_camera_set(c, KG_FEAT_EXPOSURE_US, 2500, NULL, &err);
	if (!ret)
		ret = kg_camera_set(c, KG_FEAT_GAIN, 7, NULL, &err);
	if (!ret)
		ret = kg_camera_start(c, 2, &err);
	CHECK(ret == 0, "settings run: %s", err.msg);
	if (ret)
		return;
	kg_frame f;
	ret = kg_camera_pop(c, 2000, &f, &err);
	CHECK(ret == 0, "pop: %s", err.msg);
	if (!ret) {
		uint32_t exp_in_frame, gain_in_frame;
		memcpy(&exp_in_frame, (const uint8_t *)f.data + 8, 4);
		memcpy(&gain_in_frame, (const uint8_t *)f.data + 12, 4);
		CHECK(exp_in_frame == 2500 && f.exposure_us == 2500, "exposure: frame %u, kogei %g",
		      exp_in_frame, f.exposure_us);
		CHECK(gain_in_frame == 7 && f.gain == 7, "gain: frame %u, kogei %g", gain_in_frame,
		      f.gain);
		kg_camera_push(c, &f, &err);
	}
	kg_camera_stop(c, &err);
}

static void check_refusals(kg_camera *c)
{
	kg_err err = {{0}};
	kg_frame_format want = {.pixfmt = KG_PIX_MONO16, .bits = 12};
	int ret = kg_camera_set_format(c, &want, NULL, &err);
	CHECK(ret == KG_ENOTSUP && strstr(err.msg, "mono16 with 12 bits") &&
	          strstr(err.msg, "Mono16") && strstr(err.msg, "BayerRG8"),
	      "Mono12 on the fake: %d %s", ret, err.msg);
	want = (kg_frame_format){.pixfmt = KG_PIX_BAYER16};
	ret = kg_camera_set_format(c, &want, NULL, &err);
	CHECK(ret == KG_ENOTSUP, "bayer16 on the fake: %d %s", ret, err.msg);
	want = (kg_frame_format){.width = 2000, .height = 100, .offset_x = 100};
	ret = kg_camera_set_format(c, &want, NULL, &err);
	CHECK(ret == KG_ERANGE && strstr(err.msg, "2048x2048 sensor"), "region outside: %d %s", ret,
	      err.msg);

	kg_camera *bad = NULL;
	ret = kg_camera_open("aravis:Fake_1?packet_size=1000", &bad, &err);
	CHECK(ret == KG_EINVAL && strstr(err.msg, "GigE Vision cameras only"),
	      "packet_size on the fake: %d %s", ret, err.msg);
	kg_camera_free(&bad);
	ret = kg_camera_open("aravis:Fake_1?speed=3", &bad, &err);
	CHECK(ret == KG_EINVAL && strstr(err.msg, "packet_size=BYTES"), "unknown option: %d %s", ret,
	      err.msg);
	kg_camera_free(&bad);
	ret = kg_camera_open("aravis:NoSuchCamera", &bad, &err);
	CHECK(ret == KG_ENODEV && strstr(err.msg, "KOGEI_CAMERA_DISCOVERY=none"),
	      "unknown id with discovery off: %d %s", ret, err.msg);
	kg_camera_free(&bad);
}

static void note(void *user, const char *scheme, const char *message)
{
	if (!strcmp(scheme, "aravis"))
		snprintf(user, 1024, "%s", message);
}

static void found(void *user, const char *uri, const char *model, const char *serial,
                  const char *transport)
{
	CHECK(strncmp(uri, "aravis:", 7), "discovery is off, yet %s was listed", uri);
}

int main(void)
{
	const char *disc = getenv("KOGEI_CAMERA_DISCOVERY");
	if (!disc || strcmp(disc, "none"))
		kg_test_skip("KOGEI_CAMERA_DISCOVERY=none is not set (run through meson test)");
	char message[1024] = "";
	kg_camera_enumerate(found, note, message);
	CHECK(strstr(message, "KOGEI_CAMERA_DISCOVERY=none"), "enumerate note: '%s'", message);

	kg_aravis_set_open_hook(on_open, NULL);
	kg_err err = {{0}};
	kg_camera *c = NULL;
	int ret = kg_camera_open("aravis:Fake_1", &c, &err);
	CHECK(ret == 0, "open aravis:Fake_1: %s", err.msg);
	if (ret)
		return kg_test_done("aravis-fake");
	const kg_camera_info *info = kg_camera_get_info(c);
	CHECK(!strcmp(info->vendor, "Aravis") && !strcmp(info->model, "Fake") &&
	          !strcmp(info->transport, "Aravis fake") && info->sensor_width == 2048 &&
	          info->sensor_height == 2048,
	      "info: '%s' '%s' '%s' %dx%d", info->vendor, info->model, info->transport,
	      info->sensor_width, info->sensor_height);
	CHECK(injected.fake != NULL, "the open hook did not reach the fake camera");

	check_features(c);
	ret = kg_camera_set(c, KG_FEAT_FRAME_RATE, 200, NULL, &err);
	CHECK(ret == 0, "frame rate: %s", err.msg);
	stream_format(c, "mono8", KG_PIX_MONO8, 8, "", 4);
	stream_format(c, "mono16", KG_PIX_MONO16, 16, "", 4);
	stream_format(c, "bayer_rggb8", KG_PIX_BAYER8, 8, "RGGB", 3);
	stream_format(c, "bayer_bggr8", KG_PIX_BAYER8, 8, "BGGR", 3);
	stream_format(c, "bayer_grbg8", KG_PIX_BAYER8, 8, "GRBG", 3);
	stream_format(c, "bayer_gbrg8", KG_PIX_BAYER8, 8, "GBRG", 3);
	stream_format(c, "rgb8", KG_PIX_RGB8, 8, "", 4);
	check_frame_settings(c);
	check_refusals(c);
	kg_camera_free(&c);
	CHECK(c == NULL, "kg_camera_free did not clear the pointer");
	kg_aravis_set_open_hook(NULL, NULL);
	arv_shutdown();
	return kg_test_done("aravis-fake");
}
