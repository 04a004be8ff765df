/* The Aravis backend against a camera described the way current machine-vision cameras
 * are: Aravis' fake GigE Vision camera served in this process on 127.0.0.1 with the
 * GenICam description tests/aravis/kogei-gv-camera.xml (float ExposureTime in us and
 * Gain in dB instead of ExposureTimeAbs and GainRaw, ExposureAuto and GainAuto,
 * BalanceWhiteAuto, BalanceRatio behind BalanceRatioSelector, Mono12/16, BayerRG12/16,
 * BayerGB16 and a Mono12Packed kogei does not read), opened by address (no
 * discovery). Run inside netns.sh.
 *
 * Checked through kogei's API, and each setting also in the fake's own registers:
 *   - features resolve to the float names (feature info's native name), with the
 *     description's bounds and step; values read back, land in the registers the fake
 *     makes its frames with, and are what the fill callback saw; the camera's rounding
 *     (whole microseconds) is reported, out-of-range values are refused;
 *   - kg_camera_manual turns ExposureAuto, GainAuto and BalanceWhiteAuto off (they
 *     start on) and sets the red and blue ratios to 1 through the selector, leaving
 *     green alone; auto white balance on and off again reads back;
 *   - the camera starts in Mono12Packed: reading the format is refused naming it;
 *   - Mono16, Mono12, BayerRG12, BayerRG16, BayerGB16 and BayerBG8 negotiate with the
 *     right bits and CFA on a region, frames injected through the fill callback arrive
 *     byte for byte over GVSP (12-bit ones hold 12-bit samples and convert on 4095),
 *     with consecutive sequence numbers and clean stream counters;
 *   - negotiation without bits takes the deepest format, a CFA the camera lacks is
 *     refused listing what it offers, a region off the sensor is refused;
 *   - the packet size asked for lands in GevSCPSPacketSize. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "aravis_inject.h"
#include "kg_camera.h"
#include "kg_test.h"

#define SERIAL "KGXML1"
#define PACKET_SIZE 1500
/* GigE Vision bootstrap: stream channel 0 packet size (low 16 bits). */
#define GVBS_SCPS0 0x0d04
/* Registers of kogei-gv-camera.xml in the fake's manufacturer range. */
#define REG_EXPOSURE_AUTO 0xa000
#define REG_BALANCE_WHITE_AUTO 0xa004
#define REG_BALANCE_RATIO(sel) (0xa010u + 4u * (sel)) /* 0 red, 1 green, 2 blue */
/* Enumeration values there. */
#define EXPOSURE_AUTO_OFF 0
#define EXPOSURE_AUTO_CONTINUOUS 2
#define GAIN_AUTO_OFF 1
#define GAIN_AUTO_CONTINUOUS 2
#define BWA_OFF 0
#define BWA_CONTINUOUS 2
#define PIXEL_FORMAT_MONO12_PACKED 0x010c0006u

/* The fill callback: aravis_inject.h's frames, then, for formats with fewer significant
 * bits than their 16-bit words, every sample masked to those bits (a 12-bit camera
 * never sets the top 4 bits). */
typedef struct filler {
	inject in; /* first: inject_fill takes it as its user data */
	guint32 mask;     /* 0: bytes as generated; else each 16-bit sample & mask */
	guint32 last_pf;  /* pixel format of the last frame filled */
} filler;

static filler fl;

static void fill(ArvBuffer *b, void *user, guint32 exposure_us, guint32 gain, ArvPixelFormat pf)
{
	filler *f = user;
	inject_fill(b, &f->in, exposure_us, gain, pf);
	g_mutex_lock(&f->in.lock);
	guint32 mask = f->mask;
	size_t size = f->in.last_size;
	f->last_pf = (guint32)pf;
	g_mutex_unlock(&f->in.lock);
	if (mask)
		inject_mask_samples((uint8_t *)arv_buffer_get_data(b, NULL), size, mask);
}


static guint32 reg(guint32 address)
{
	guint32 v = 0;
	arv_fake_camera_read_register(fl.in.fake, address, &v);
	return v;
}

static void set_reg(guint32 address, guint32 v)
{
	arv_fake_camera_write_register(fl.in.fake, address, v);
}

static float reg_float(guint32 address)
{
	guint32 v = reg(address);
	float x;
	memcpy(&x, &v, 4);
	return x;
}

static void set_reg_float(guint32 address, float x)
{
	guint32 v;
	memcpy(&v, &x, 4);
	set_reg(address, v);
}

/* ---- features ------------------------------------------------------------------ */

static void check_exposure(kg_camera *c)
{
	kg_err err = {{0}};
	kg_feature_info fi;
	memset(&fi, 0, sizeof(fi));
	int ret = kg_camera_feature_info(c, KG_FEAT_EXPOSURE_US, &fi, &err);
	CHECK(ret == 0 && fi.available && fi.writable && !strcmp(fi.native, "ExposureTime") &&
	          !strcmp(fi.unit, "us") && fi.min == 10 && fi.max == 2e6 && fi.step == 0,
	      "exposure: ret %d native '%s' unit '%s' %g..%g step %g: %s", ret, fi.native, fi.unit,
	      fi.min, fi.max, fi.step, err.msg);
	double got = 0;
	ret = kg_camera_set(c, KG_FEAT_EXPOSURE_US, 2500, &got, &err);
	CHECK(ret == 0 && got == 2500, "set exposure 2500: got %g: %s", got, err.msg);
	CHECK(reg(ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US) == 2500,
	      "fake exposure register %u, expected 2500",
	      reg(ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US));
	/* The camera holds whole microseconds: kogei reports where it settled. */
	ret = kg_camera_set(c, KG_FEAT_EXPOSURE_US, 1234.4, &got, &err);
	CHECK(ret == 0 && got == 1234 && reg(ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US) == 1234,
	      "set exposure 1234.4: got %g, register %u: %s", got,
	      reg(ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US), err.msg);
	ret = kg_camera_set(c, KG_FEAT_EXPOSURE_US, 5e6, NULL, &err);
	CHECK(ret == KG_ERANGE && strstr(err.msg, "exposure_us") && strstr(err.msg, "10..2e+06"),
	      "exposure above range: %d %s", ret, err.msg);
	CHECK(reg(ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US) == 1234,
	      "a refused exposure reached the camera: register %u",
	      reg(ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US));
	ret = kg_camera_set(c, KG_FEAT_EXPOSURE_US, 2500, NULL, &err);
	double back = 0;
	if (!ret)
		ret = kg_camera_get(c, KG_FEAT_EXPOSURE_US, &back, &err);
	CHECK(ret == 0 && back == 2500, "exposure reads %g: %s", back, err.msg);
}

static void check_gain(kg_camera *c)
{
	kg_err err = {{0}};
	kg_feature_info fi;
	memset(&fi, 0, sizeof(fi));
	int ret = kg_camera_feature_info(c, KG_FEAT_GAIN, &fi, &err);
	CHECK(ret == 0 && fi.available && fi.writable && !strcmp(fi.native, "Gain") &&
	          !strcmp(fi.unit, "dB") && fi.min == 0 && fi.max == 24 && fabs(fi.step - 0.1) < 1e-12,
	      "gain: ret %d native '%s' unit '%s' %g..%g step %g: %s", ret, fi.native, fi.unit, fi.min,
	      fi.max, fi.step, err.msg);
	/* 0.1 dB steps: the register holds tenths of a dB. */
	static const struct {
		double set, back;
		guint32 raw;
	} cases[] = {{3.5, 3.5, 35}, {2.3, 2.3, 23}, {2.34, 2.3, 23}, {0, 0, 0}, {24, 24, 240}};
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		double got = -1;
		ret = kg_camera_set(c, KG_FEAT_GAIN, cases[i].set, &got, &err);
		CHECK(ret == 0 && fabs(got - cases[i].back) < 1e-9 &&
		          reg(ARV_FAKE_CAMERA_REGISTER_GAIN_RAW) == cases[i].raw,
		      "set gain %g dB: got %.17g (expected %g), register %u (expected %u): %s",
		      cases[i].set, got, cases[i].back, reg(ARV_FAKE_CAMERA_REGISTER_GAIN_RAW),
		      cases[i].raw, err.msg);
	}
	ret = kg_camera_set(c, KG_FEAT_GAIN, 30, NULL, &err);
	CHECK(ret == KG_ERANGE && strstr(err.msg, "gain 30 dB"), "gain above range: %d %s", ret,
	      err.msg);
	ret = kg_camera_set(c, KG_FEAT_GAIN, 3.5, NULL, &err);
	CHECK(ret == 0 && reg(ARV_FAKE_CAMERA_REGISTER_GAIN_RAW) == 35, "gain 3.5: %s", err.msg);
}

static void check_frame_rate(kg_camera *c)
{
	kg_err err = {{0}};
	kg_feature_info fi;
	memset(&fi, 0, sizeof(fi));
	int ret = kg_camera_feature_info(c, KG_FEAT_FRAME_RATE, &fi, &err);
	CHECK(ret == 0 && !strcmp(fi.native, "AcquisitionFrameRate") && fi.max == 500,
	      "frame rate: '%s' max %g: %s", fi.native, fi.max, err.msg);
	double got = 0;
	ret = kg_camera_set(c, KG_FEAT_FRAME_RATE, 100, &got, &err);
	CHECK(ret == 0 && fabs(got - 100) < 1e-9 &&
	          reg(ARV_FAKE_CAMERA_REGISTER_ACQUISITION_FRAME_PERIOD_US) == 10000,
	      "frame rate 100: got %g, period register %u us: %s", got,
	      reg(ARV_FAKE_CAMERA_REGISTER_ACQUISITION_FRAME_PERIOD_US), err.msg);
}

static double get_feature(kg_camera *c, kg_feature f)
{
	kg_err err = {{0}};
	double v = NAN;
	int ret = kg_camera_get(c, f, &v, &err);
	CHECK(ret == 0, "get %s: %s", kg_feature_name(f), err.msg);
	return v;
}

/* The camera starts with every automatic control on and the ratios away from 1. */
static void check_auto_and_balance(kg_camera *c)
{
	kg_err err = {{0}};
	kg_feature_info fi;
	static const struct {
		kg_feature f;
		const char *native, *unit;
	} names[] = {
		{KG_FEAT_AUTO_EXPOSURE, "ExposureAuto+GainAuto", "bool"},
		{KG_FEAT_AUTO_WHITE_BALANCE, "BalanceWhiteAuto", "bool"},
		{KG_FEAT_WB_RED, "BalanceRatio[Red]", "x"},
		{KG_FEAT_WB_BLUE, "BalanceRatio[Blue]", "x"},
	};
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++) {
		memset(&fi, 0, sizeof(fi));
		int ret = kg_camera_feature_info(c, names[i].f, &fi, &err);
		CHECK(ret == 0 && fi.available && fi.writable && !strcmp(fi.native, names[i].native) &&
		          !strcmp(fi.unit, names[i].unit),
		      "%s: ret %d available %d native '%s' unit '%s' (expected '%s' '%s'): %s",
		      kg_feature_name(names[i].f), ret, fi.available, fi.native, fi.unit,
		      names[i].native, names[i].unit, err.msg);
	}
	memset(&fi, 0, sizeof(fi));
	kg_camera_feature_info(c, KG_FEAT_WB_RED, &fi, &err);
	CHECK(fi.min == 0.125 && fi.max == 8, "wb_red bounds %g..%g", fi.min, fi.max);

	CHECK(get_feature(c, KG_FEAT_AUTO_EXPOSURE) == 1, "auto exposure should read on");
	CHECK(get_feature(c, KG_FEAT_AUTO_WHITE_BALANCE) == 1, "auto white balance should read on");
	CHECK_NEAR(get_feature(c, KG_FEAT_WB_RED), (double)1.8f, 0, "wb_red before manual");
	CHECK_NEAR(get_feature(c, KG_FEAT_WB_BLUE), (double)1.4f, 0, "wb_blue before manual");

	int ret = kg_camera_manual(c, &err);
	CHECK(ret == 0, "manual: %s", err.msg);
	CHECK(reg(REG_EXPOSURE_AUTO) == EXPOSURE_AUTO_OFF &&
	          reg(ARV_FAKE_CAMERA_REGISTER_GAIN_MODE) == GAIN_AUTO_OFF &&
	          reg(REG_BALANCE_WHITE_AUTO) == BWA_OFF,
	      "manual: ExposureAuto %u GainAuto %u BalanceWhiteAuto %u in the camera",
	      reg(REG_EXPOSURE_AUTO), reg(ARV_FAKE_CAMERA_REGISTER_GAIN_MODE),
	      reg(REG_BALANCE_WHITE_AUTO));
	CHECK(reg_float(REG_BALANCE_RATIO(0)) == 1.0f && reg_float(REG_BALANCE_RATIO(2)) == 1.0f &&
	          reg_float(REG_BALANCE_RATIO(1)) == 1.2f,
	      "manual: ratios red %g green %g blue %g in the camera (green is not kogei's)",
	      reg_float(REG_BALANCE_RATIO(0)), reg_float(REG_BALANCE_RATIO(1)),
	      reg_float(REG_BALANCE_RATIO(2)));
	CHECK(get_feature(c, KG_FEAT_AUTO_EXPOSURE) == 0, "auto exposure should read off");
	CHECK(get_feature(c, KG_FEAT_AUTO_WHITE_BALANCE) == 0, "auto white balance should read off");

	double got = -1;
	ret = kg_camera_set(c, KG_FEAT_AUTO_WHITE_BALANCE, 1, &got, &err);
	CHECK(ret == 0 && got == 1 && reg(REG_BALANCE_WHITE_AUTO) == BWA_CONTINUOUS,
	      "auto white balance on: got %g register %u: %s", got, reg(REG_BALANCE_WHITE_AUTO),
	      err.msg);
	ret = kg_camera_set(c, KG_FEAT_AUTO_WHITE_BALANCE, 0, &got, &err);
	CHECK(ret == 0 && got == 0 && reg(REG_BALANCE_WHITE_AUTO) == BWA_OFF,
	      "auto white balance off: got %g register %u: %s", got, reg(REG_BALANCE_WHITE_AUTO),
	      err.msg);

	/* The selector routes each ratio to its own register. */
	ret = kg_camera_set(c, KG_FEAT_WB_BLUE, 2.25, &got, &err);
	CHECK(ret == 0 && got == 2.25 && reg_float(REG_BALANCE_RATIO(2)) == 2.25f &&
	          reg_float(REG_BALANCE_RATIO(0)) == 1.0f,
	      "wb_blue 2.25: got %g, registers red %g blue %g: %s", got,
	      reg_float(REG_BALANCE_RATIO(0)), reg_float(REG_BALANCE_RATIO(2)), err.msg);
	CHECK(get_feature(c, KG_FEAT_WB_RED) == 1, "wb_red after setting blue");
	ret = kg_camera_set(c, KG_FEAT_WB_RED, 9, NULL, &err);
	CHECK(ret == KG_ERANGE, "wb_red 9 (above 8): %d %s", ret, err.msg);
	ret = kg_camera_manual(c, &err);
	CHECK(ret == 0 && reg_float(REG_BALANCE_RATIO(2)) == 1.0f, "manual again: blue %g: %s",
	      reg_float(REG_BALANCE_RATIO(2)), err.msg);
}

/* ---- formats ------------------------------------------------------------------- */

typedef struct fmt_case {
	const char *name; /* GenICam name */
	guint32 arv;
	kg_pixfmt pf;
	int bits;
	const char *cfa;
} fmt_case;

static const fmt_case formats[] = {
	{"Mono16", ARV_PIXEL_FORMAT_MONO_16, KG_PIX_MONO16, 16, ""},
	{"Mono12", ARV_PIXEL_FORMAT_MONO_12, KG_PIX_MONO16, 12, ""},
	{"BayerRG12", ARV_PIXEL_FORMAT_BAYER_RG_12, KG_PIX_BAYER16, 12, "RGGB"},
	{"BayerRG16", ARV_PIXEL_FORMAT_BAYER_RG_16, KG_PIX_BAYER16, 16, "RGGB"},
	{"BayerGB16", ARV_PIXEL_FORMAT_BAYER_GB_16, KG_PIX_BAYER16, 16, "GBRG"},
	{"BayerBG8", ARV_PIXEL_FORMAT_BAYER_BG_8, KG_PIX_BAYER8, 8, "BGGR"},
};

enum { W = 320, H = 240, X0 = 64, Y0 = 32, NFRAMES = 6 };

static int frames_ok, frames_total;

/* Frame k as the camera sent it, seen through kg_frame_to_image: one raw channel on
 * 0..1 of 2^bits - 1, the CFA attached, no sample above full scale. */
static void check_image(const fmt_case *fc, const kg_frame *f)
{
	kg_err err = {{0}};
	kg_image *img = NULL;
	int ret = kg_frame_to_image(f, 0, &img, &err);
	CHECK(ret == 0, "%s: to image: %s", fc->name, err.msg);
	if (ret)
		return;
	CHECK(img->channels == 1 && img->width == W && img->height == H,
	      "%s: image %dx%d x %d", fc->name, img->width, img->height, img->channels);
	if (fc->cfa[0])
		CHECK(img->cfa && !strcmp(img->cfa, fc->cfa) && img->cfa_rows == 2 && img->cfa_cols == 2,
		      "%s: image CFA '%s'", fc->name, img->cfa ? img->cfa : "(none)");
	else
		CHECK(!img->cfa, "%s: a mono image has CFA '%s'", fc->name, img->cfa);
	double full = (double)((1u << fc->bits) - 1u);
	long bad = 0;
	unsigned maxv = 0;
	const uint8_t *d = f->data;
	for (size_t i = 0; i < (size_t)W * H; i++) {
		unsigned v = fc->bits > 8 ? (unsigned)(d[2 * i] | d[2 * i + 1] << 8) : d[i];
		if (v > maxv)
			maxv = v;
		if (fabs(img->data[i] - v / full) > 1e-6)
			bad++;
	}
	CHECK(!bad, "%s: %ld samples differ from value / %g", fc->name, bad, full);
	CHECK(maxv <= (unsigned)full && maxv > (unsigned)full * 0.99,
	      "%s: largest sample %u for %d bits", fc->name, maxv, fc->bits);
	kg_image_free(&img);
}

static void stream_format(kg_camera *c, const fmt_case *fc)
{
	kg_err err = {{0}};
	kg_frame_format want = {.pixfmt = fc->pf, .bits = fc->bits, .width = W, .height = H,
	                        .offset_x = X0, .offset_y = Y0};
	snprintf(want.cfa, sizeof(want.cfa), "%s", fc->cfa);
	kg_frame_format got;
	memset(&got, 0, sizeof(got));
	int ret = kg_camera_set_format(c, &want, &got, &err);
	CHECK(ret == 0, "%s: set_format: %s", fc->name, err.msg);
	if (ret)
		return;
	size_t bpp = (size_t)kg_pixfmt_bytes_per_pixel(fc->pf);
	CHECK(got.pixfmt == fc->pf && got.bits == fc->bits && !strcmp(got.cfa, fc->cfa) &&
	          got.width == W && got.height == H && got.offset_x == X0 && got.offset_y == Y0 &&
	          got.stride == W * bpp && got.size == (size_t)W * H * bpp,
	      "%s: got %s %d bits cfa '%s' %dx%d+%d+%d stride %zu size %zu", fc->name,
	      kg_pixfmt_name(got.pixfmt), got.bits, got.cfa, got.width, got.height, got.offset_x,
	      got.offset_y, got.stride, got.size);
	CHECK(reg(ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT) == fc->arv &&
	          reg(ARV_FAKE_CAMERA_REGISTER_WIDTH) == W && reg(ARV_FAKE_CAMERA_REGISTER_HEIGHT) == H &&
	          reg(ARV_FAKE_CAMERA_REGISTER_X_OFFSET) == X0 &&
	          reg(ARV_FAKE_CAMERA_REGISTER_Y_OFFSET) == Y0,
	      "%s: camera registers: pixel format 0x%08x (expected 0x%08x), %ux%u+%u+%u", fc->name,
	      reg(ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT), fc->arv, reg(ARV_FAKE_CAMERA_REGISTER_WIDTH),
	      reg(ARV_FAKE_CAMERA_REGISTER_HEIGHT), reg(ARV_FAKE_CAMERA_REGISTER_X_OFFSET),
	      reg(ARV_FAKE_CAMERA_REGISTER_Y_OFFSET));

	guint32 mask = fc->bits > 8 && fc->bits < 16 ? (1u << fc->bits) - 1u : 0;
	g_mutex_lock(&fl.in.lock);
	fl.in.filled = 0;
	fl.mask = mask;
	g_mutex_unlock(&fl.in.lock);
	ret = kg_camera_start(c, 4, &err);
	CHECK(ret == 0, "%s: start: %s", fc->name, err.msg);
	if (ret)
		return;
	uint64_t first_seq = 0;
	int ok = 0;
	for (int k = 0; k < NFRAMES; k++) {
		kg_frame f;
		ret = kg_camera_pop(c, 2000, &f, &err);
		CHECK(ret == 0, "%s: pop %d: %s", fc->name, k, err.msg);
		if (ret)
			break;
		int good = f.status == KG_FRAME_OK;
		CHECK(good, "%s: frame %d status %d", fc->name, k, f.status);
		CHECK(f.fmt.pixfmt == fc->pf && f.fmt.bits == fc->bits && !strcmp(f.fmt.cfa, fc->cfa) &&
		          f.fmt.width == W && f.fmt.height == H,
		      "%s: frame %d is %s %d bits '%s' %dx%d", fc->name, k, kg_pixfmt_name(f.fmt.pixfmt),
		      f.fmt.bits, f.fmt.cfa, f.fmt.width, f.fmt.height);
		int same = inject_matches_masked(&f, (uint64_t)k, mask);
		CHECK(same, "%s: frame %d is not the injected frame", fc->name, k);
		good = good && same;
		if (k == 0)
			first_seq = f.sequence;
		CHECK(f.sequence == first_seq + (uint64_t)k, "%s: frame %d sequence %llu after %llu",
		      fc->name, k, (unsigned long long)f.sequence, (unsigned long long)first_seq);
		/* The settings the frame was taken with: kogei's record of them, and what the
		 * camera passed to the fill (the frame header of 16-bit formats carries it). */
		CHECK(f.exposure_us == 2500 && fabs(f.gain - 3.5) < 1e-9,
		      "%s: frame %d recorded exposure %g gain %g", fc->name, k, f.exposure_us, f.gain);
		if (!mask && f.size >= 16) {
			guint32 e, g;
			memcpy(&e, (const uint8_t *)f.data + 8, 4);
			memcpy(&g, (const uint8_t *)f.data + 12, 4);
			CHECK(e == 2500 && g == 35, "%s: frame %d taken with exposure %u us, raw gain %u",
			      fc->name, k, e, g);
		}
		if (k == 0 && fc->bits > 8)
			check_image(fc, &f);
		ok += good;
		ret = kg_camera_push(c, &f, &err);
		CHECK(ret == 0, "%s: push: %s", fc->name, err.msg);
	}
	g_mutex_lock(&fl.in.lock);
	guint32 pf = fl.last_pf, e = fl.in.exposure_us, g = fl.in.gain;
	g_mutex_unlock(&fl.in.lock);
	CHECK(pf == fc->arv && e == 2500 && g == 35,
	      "%s: the fake filled 0x%08x with exposure %u gain %u", fc->name, pf, e, g);
	kg_stream_stats st;
	kg_camera_stats(c, &st);
	CHECK(st.completed >= NFRAMES && !st.failed && !st.incomplete && !st.dropped &&
	          !st.missing_packets && !st.timeouts,
	      "%s: completed %llu failed %llu incomplete %llu dropped %llu missing %llu timeouts %llu",
	      fc->name, (unsigned long long)st.completed, (unsigned long long)st.failed,
	      (unsigned long long)st.incomplete, (unsigned long long)st.dropped,
	      (unsigned long long)st.missing_packets, (unsigned long long)st.timeouts);
	ret = kg_camera_stop(c, &err);
	CHECK(ret == 0, "%s: stop: %s", fc->name, err.msg);
	printf("%-9s %2d bits %-4s: %d/%d frames byte for byte\n", fc->name, fc->bits, fc->cfa, ok,
	       NFRAMES);
	frames_ok += ok;
	frames_total += NFRAMES;
	g_mutex_lock(&fl.in.lock);
	fl.mask = 0;
	g_mutex_unlock(&fl.in.lock);
}

static void check_negotiation(kg_camera *c)
{
	kg_err err = {{0}};
	kg_frame_format got;
	/* No bits, no CFA: the deepest Bayer format, the current pattern first (from
	 * BayerGB8: BayerGB16, not BayerRG16; from BayerRG16 it stays). */
	kg_frame_format want = {.pixfmt = KG_PIX_BAYER8};
	snprintf(want.cfa, sizeof(want.cfa), "GBRG");
	int ret = kg_camera_set_format(c, &want, &got, &err);
	CHECK(ret == 0 && reg(ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT) == ARV_PIXEL_FORMAT_BAYER_GB_8,
	      "bayer8 GBRG: %s", err.msg);
	want = (kg_frame_format){.pixfmt = KG_PIX_BAYER16};
	ret = kg_camera_set_format(c, &want, &got, &err);
	CHECK(ret == 0 && got.bits == 16 && !strcmp(got.cfa, "GBRG") &&
	          reg(ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT) == ARV_PIXEL_FORMAT_BAYER_GB_16,
	      "bayer16 from BayerGB8: %d bits '%s' (0x%08x): %s", got.bits, got.cfa,
	      reg(ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT), err.msg);
	want = (kg_frame_format){.pixfmt = KG_PIX_BAYER16};
	snprintf(want.cfa, sizeof(want.cfa), "RGGB");
	ret = kg_camera_set_format(c, &want, &got, &err);
	CHECK(ret == 0 && got.bits == 16 && !strcmp(got.cfa, "RGGB") &&
	          reg(ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT) == ARV_PIXEL_FORMAT_BAYER_RG_16,
	      "bayer16 RGGB: %d bits '%s': %s", got.bits, got.cfa, err.msg);
	want = (kg_frame_format){.pixfmt = KG_PIX_BAYER16};
	ret = kg_camera_set_format(c, &want, &got, &err);
	CHECK(ret == 0 && !strcmp(got.cfa, "RGGB") &&
	          reg(ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT) == ARV_PIXEL_FORMAT_BAYER_RG_16,
	      "bayer16 from BayerRG16: %d bits '%s': %s", got.bits, got.cfa, err.msg);
	want = (kg_frame_format){.pixfmt = KG_PIX_MONO16};
	ret = kg_camera_set_format(c, &want, &got, &err);
	CHECK(ret == 0 && got.bits == 16 && !got.cfa[0] &&
	          reg(ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT) == ARV_PIXEL_FORMAT_MONO_16,
	      "mono16: %d bits: %s", got.bits, err.msg);
	/* Refusals name what was asked and what the camera offers; the camera is left as
	 * it was. */
	want = (kg_frame_format){.pixfmt = KG_PIX_BAYER16, .bits = 12};
	snprintf(want.cfa, sizeof(want.cfa), "GBRG");
	ret = kg_camera_set_format(c, &want, &got, &err);
	CHECK(ret == KG_ENOTSUP && strstr(err.msg, "bayer16 with 12 bits GBRG") &&
	          strstr(err.msg, "BayerRG12") && strstr(err.msg, "BayerGB16") &&
	          strstr(err.msg, "Mono12Packed"),
	      "bayer12 GBRG: %d %s", ret, err.msg);
	want = (kg_frame_format){.pixfmt = KG_PIX_MONO16, .bits = 14};
	ret = kg_camera_set_format(c, &want, &got, &err);
	CHECK(ret == KG_ENOTSUP && strstr(err.msg, "mono16 with 14 bits"), "mono14: %d %s", ret,
	      err.msg);
	want = (kg_frame_format){.pixfmt = KG_PIX_RGB16};
	ret = kg_camera_set_format(c, &want, &got, &err);
	CHECK(ret == KG_ENOTSUP, "rgb16: %d %s", ret, err.msg);
	CHECK(reg(ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT) == ARV_PIXEL_FORMAT_MONO_16,
	      "a refused format changed the camera's: 0x%08x",
	      reg(ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT));

	/* The region: the far corner of the sensor, then the whole sensor, then off it. */
	want = (kg_frame_format){.width = W, .height = H, .offset_x = 2048 - W, .offset_y = 2048 - H};
	ret = kg_camera_set_format(c, &want, &got, &err);
	CHECK(ret == 0 && got.offset_x == 2048 - W && got.offset_y == 2048 - H &&
	          reg(ARV_FAKE_CAMERA_REGISTER_X_OFFSET) == 2048 - W &&
	          reg(ARV_FAKE_CAMERA_REGISTER_Y_OFFSET) == 2048 - H,
	      "corner region: %dx%d+%d+%d: %s", got.width, got.height, got.offset_x, got.offset_y,
	      err.msg);
	want = (kg_frame_format){.width = 2048, .height = 2048};
	ret = kg_camera_set_format(c, &want, &got, &err);
	CHECK(ret == 0 && got.width == 2048 && got.height == 2048 && got.offset_x == 0 &&
	          got.offset_y == 0 && reg(ARV_FAKE_CAMERA_REGISTER_WIDTH) == 2048 &&
	          reg(ARV_FAKE_CAMERA_REGISTER_X_OFFSET) == 0,
	      "whole sensor: %dx%d+%d+%d: %s", got.width, got.height, got.offset_x, got.offset_y,
	      err.msg);
	want = (kg_frame_format){.width = W, .height = H, .offset_x = 2048 - W + 2};
	ret = kg_camera_set_format(c, &want, &got, &err);
	CHECK(ret == KG_ERANGE && strstr(err.msg, "2048x2048 sensor"), "region off the sensor: %d %s",
	      ret, err.msg);
	CHECK(reg(ARV_FAKE_CAMERA_REGISTER_WIDTH) == 2048, "a refused region reached the camera");
}

int main(int argc, char **argv)
{
	if (argc != 2) {
		fprintf(stderr, "usage: test_aravis_genicam GENICAM.xml (inside netns.sh)\n");
		return 1;
	}
	if (!kg_test_file_exists(argv[1]))
		kg_test_skip("the GenICam description for the fake camera is missing");
	ArvGvFakeCamera *gv = arv_gv_fake_camera_new_full("127.0.0.1", SERIAL, argv[1]);
	if (!gv || !arv_gv_fake_camera_is_running(gv)) {
		if (gv)
			g_object_unref(gv);
		kg_test_skip("the fake GigE Vision camera cannot listen on 127.0.0.1");
	}
	ArvFakeCamera *fake = arv_gv_fake_camera_get_fake_camera(gv);
	size_t xml_size = 0;
	const char *xml = arv_fake_camera_get_genicam_xml(fake, &xml_size);
	CHECK(xml && xml_size > 0 && g_strstr_len(xml, (gssize)xml_size, "KogeiTestCamera"),
	      "the fake does not serve %s", argv[1]);
	inject_attach(&fl.in, fake);
	arv_fake_camera_set_fill_pattern(fake, fill, &fl);

	/* Power-on state: every automatic control on, ratios away from 1, and a pixel
	 * format kogei does not read. */
	set_reg(REG_EXPOSURE_AUTO, EXPOSURE_AUTO_CONTINUOUS);
	set_reg(ARV_FAKE_CAMERA_REGISTER_GAIN_MODE, GAIN_AUTO_CONTINUOUS);
	set_reg(REG_BALANCE_WHITE_AUTO, BWA_CONTINUOUS);
	set_reg_float(REG_BALANCE_RATIO(0), 1.8f);
	set_reg_float(REG_BALANCE_RATIO(1), 1.2f);
	set_reg_float(REG_BALANCE_RATIO(2), 1.4f);
	set_reg(ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT, PIXEL_FORMAT_MONO12_PACKED);

	kg_err err = {{0}};
	kg_camera *c = NULL;
	char uri[64];
	snprintf(uri, sizeof(uri), "aravis:127.0.0.1?packet_size=%d", PACKET_SIZE);
	int ret = kg_camera_open(uri, &c, &err);
	CHECK(ret == 0, "open %s: %s", uri, err.msg);
	if (ret) {
		g_object_unref(gv);
		arv_shutdown();
		return kg_test_done("aravis-gv-genicam");
	}
	const kg_camera_info *info = kg_camera_get_info(c);
	CHECK(!strcmp(info->transport, "GigE Vision") && !strcmp(info->serial, SERIAL) &&
	          !strcmp(info->vendor, "Aravis") && info->sensor_width == 2048 &&
	          info->sensor_height == 2048,
	      "info: transport '%s' vendor '%s' serial '%s' sensor %dx%d", info->transport,
	      info->vendor, info->serial, info->sensor_width, info->sensor_height);

	kg_frame_format cur;
	ret = kg_camera_get_format(c, &cur, &err);
	CHECK(ret == KG_ENOTSUP && strstr(err.msg, "Mono12Packed"),
	      "a Mono12Packed camera: %d %s", ret, err.msg);

	check_exposure(c);
	check_gain(c);
	check_frame_rate(c);
	check_auto_and_balance(c);

	for (size_t i = 0; i < sizeof(formats) / sizeof(formats[0]); i++)
		stream_format(c, &formats[i]);
	guint32 scps = reg(GVBS_SCPS0) & 0xffff;
	CHECK(scps == PACKET_SIZE, "GevSCPSPacketSize register %u, asked for %d", scps, PACKET_SIZE);
	check_negotiation(c);
	printf("%d/%d frames in %zu formats byte for byte; packet size %u\n", frames_ok,
	       frames_total, sizeof(formats) / sizeof(formats[0]), scps);

	kg_camera_free(&c);
	g_object_unref(gv);
	arv_shutdown();
	return kg_test_done("aravis-gv-genicam");
}
