/* Pixel-format and feature names, frame sizes, and kg_frame_to_image on every format
 * against hand-made bytes. YUYV is checked against the ITU-R BT.601 limited-range
 * codes of 75 %/100 % colour bars (published values, not computed here). */
#include <string.h>

#include "camera_test.h"
#include "mjpeg.h"

static kg_frame frame_of(kg_pixfmt pf, int bits, const char *cfa, int w, int h,
                         size_t stride, const void *data, size_t size)
{
	kg_frame f;
	memset(&f, 0, sizeof(f));
	f.fmt.pixfmt = pf;
	f.fmt.bits = bits;
	f.fmt.width = w;
	f.fmt.height = h;
	f.fmt.stride = stride;
	f.fmt.size = size;
	if (cfa)
		memcpy(f.fmt.cfa, cfa, 5);
	f.data = data;
	f.size = size;
	return f;
}

static kg_image *convert(const kg_frame *f, int allow, const char *what)
{
	kg_image *img = NULL;
	kg_err e = {{0}};
	int ret = kg_frame_to_image(f, allow, &img, &e);
	CHECK(ret == 0 && img, "%s: kg_frame_to_image: %d %s", what, ret, e.msg);
	return ret ? NULL : img;
}

static void test_parse(void)
{
	static const struct {
		const char *text;
		kg_pixfmt f;
		int bits;
		const char *cfa;
	} ok[] = {
		{"mono8", KG_PIX_MONO8, 8, ""},         {"mono10", KG_PIX_MONO16, 10, ""},
		{"mono12", KG_PIX_MONO16, 12, ""},      {"mono16", KG_PIX_MONO16, 16, ""},
		{"bayer8", KG_PIX_BAYER8, 8, ""},       {"bayer_rggb12", KG_PIX_BAYER16, 12, "RGGB"},
		{"bayer_bggr8", KG_PIX_BAYER8, 8, "BGGR"}, {"bayer_gbrg16", KG_PIX_BAYER16, 16, "GBRG"},
		{"bayer_grbg10", KG_PIX_BAYER16, 10, "GRBG"}, {"rgb8", KG_PIX_RGB8, 8, ""},
		{"rgb16", KG_PIX_RGB16, 16, ""},        {"yuyv", KG_PIX_YUYV, 8, ""},
		{"mjpeg", KG_PIX_MJPEG, 8, ""},
	};
	for (size_t i = 0; i < sizeof(ok) / sizeof(ok[0]); i++) {
		kg_pixfmt f = KG_PIX_NONE;
		int bits = 0;
		char cfa[5] = "x";
		kg_err e = {{0}};
		int ret = kg_pixfmt_parse(ok[i].text, &f, &bits, cfa, &e);
		CHECK(ret == 0 && f == ok[i].f && bits == ok[i].bits && !strcmp(cfa, ok[i].cfa),
		      "parse '%s': ret %d f %d bits %d cfa '%s' (%s)", ok[i].text, ret, f, bits, cfa,
		      e.msg);
	}
	static const char *const bad[] = {"", "mono9", "mono", "rgb12", "bayer_xxxx8",
	                                   "bayer_rggb", "yuv", "mono8x", "MONO8", "bayer_rggb32"};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		kg_pixfmt f;
		int bits;
		char cfa[5];
		kg_err e = {{0}};
		int ret = kg_pixfmt_parse(bad[i], &f, &bits, cfa, &e);
		CHECK(ret == KG_EINVAL && strstr(e.msg, bad[i]) && strstr(e.msg, "expected"),
		      "parse '%s' should fail naming it: %d '%s'", bad[i], ret, e.msg);
	}
	/* Every format's name parses back to it. */
	for (kg_pixfmt f = KG_PIX_MONO8; f <= KG_PIX_MJPEG; f++) {
		kg_pixfmt g = KG_PIX_NONE;
		CHECK(kg_pixfmt_parse(kg_pixfmt_name(f), &g, NULL, NULL, NULL) == 0 && g == f,
		      "name '%s' does not parse back", kg_pixfmt_name(f));
	}
	for (kg_feature f = 0; f < KG_FEAT_COUNT; f++) {
		kg_feature g = KG_FEAT_COUNT;
		CHECK(kg_feature_parse(kg_feature_name(f), &g, NULL) == 0 && g == f,
		      "feature '%s' does not parse back", kg_feature_name(f));
	}
	kg_feature g;
	kg_err e = {{0}};
	CHECK(kg_feature_parse("exposure", &g, &e) == KG_EINVAL && strstr(e.msg, "exposure_us"),
	      "unknown feature lists the names: %s", e.msg);

	/* Sizes: bytes per pixel times width, times height. */
	static const struct {
		kg_pixfmt f;
		int bpp, ch, linear;
	} sz[] = {{KG_PIX_MONO8, 1, 1, 1}, {KG_PIX_MONO16, 2, 1, 1}, {KG_PIX_BAYER8, 1, 1, 1},
	          {KG_PIX_BAYER16, 2, 1, 1}, {KG_PIX_RGB8, 3, 3, 1}, {KG_PIX_RGB16, 6, 3, 1},
	          {KG_PIX_YUYV, 2, 3, 0}, {KG_PIX_MJPEG, 0, 3, 0}};
	for (size_t i = 0; i < sizeof(sz) / sizeof(sz[0]); i++) {
		kg_frame_format ff;
		memset(&ff, 0, sizeof(ff));
		ff.pixfmt = sz[i].f;
		ff.width = 10;
		ff.height = 7;
		kg_frame_format_fill(&ff);
		CHECK(kg_pixfmt_bytes_per_pixel(sz[i].f) == sz[i].bpp &&
		          kg_pixfmt_channels(sz[i].f) == sz[i].ch &&
		          kg_pixfmt_is_linear(sz[i].f) == sz[i].linear,
		      "%s: bpp/channels/linear", kg_pixfmt_name(sz[i].f));
		if (sz[i].bpp)
			CHECK(ff.stride == (size_t)(10 * sz[i].bpp) && ff.size == ff.stride * 7,
			      "%s: stride %zu size %zu", kg_pixfmt_name(sz[i].f), ff.stride, ff.size);
	}
}

static void test_convert(void)
{
	/* mono8, 3x2 with a padded stride of 4. */
	const unsigned char m8[] = {0, 255, 51, 99, 102, 153, 204, 99};
	kg_frame f = frame_of(KG_PIX_MONO8, 8, NULL, 3, 2, 4, m8, sizeof(m8));
	kg_image *img = convert(&f, 0, "mono8");
	if (img) {
		const float want[] = {0, 1, 0.2f, 0.4f, 0.6f, 0.8f};
		CHECK(img->channels == 1 && img->width == 3 && img->height == 2, "mono8 shape");
		for (int i = 0; i < 6; i++)
			CHECK_NEAR(img->data[i], want[i], 1e-6, "mono8 sample");
		kg_image_free(&img);
	}
	/* mono16 holding 12 bits: 0, 4095, 1000 little-endian. */
	const unsigned char m12[] = {0x00, 0x00, 0xff, 0x0f, 0xe8, 0x03};
	f = frame_of(KG_PIX_MONO16, 12, NULL, 3, 1, 6, m12, sizeof(m12));
	if ((img = convert(&f, 0, "mono12"))) {
		CHECK_NEAR(img->data[0], 0, 1e-7, "mono12 0");
		CHECK_NEAR(img->data[1], 1, 1e-7, "mono12 4095");
		CHECK_NEAR(img->data[2], 1000.0 / 4095.0, 1e-7, "mono12 1000");
		CHECK(img->bits == 12, "mono12 bits %d", img->bits);
		kg_image_free(&img);
	}
	/* bayer8 GRBG 2x2: the CFA pattern travels with the image. */
	const unsigned char b8[] = {10, 20, 30, 40};
	f = frame_of(KG_PIX_BAYER8, 8, "GRBG", 2, 2, 2, b8, sizeof(b8));
	if ((img = convert(&f, 0, "bayer8"))) {
		CHECK(img->cfa && !strcmp(img->cfa, "GRBG") && img->cfa_rows == 2 &&
		          img->cfa_cols == 2,
		      "bayer8 cfa %s", img->cfa ? img->cfa : "(none)");
		CHECK_NEAR(img->data[3], 40.0 / 255.0, 1e-7, "bayer8 sample");
		kg_image_free(&img);
	}
	/* bayer16 holding 10 bits: 1023 and 512. */
	const unsigned char b10[] = {0xff, 0x03, 0x00, 0x02, 0x01, 0x00, 0x00, 0x00};
	f = frame_of(KG_PIX_BAYER16, 10, "BGGR", 2, 2, 4, b10, sizeof(b10));
	if ((img = convert(&f, 0, "bayer10"))) {
		CHECK_NEAR(img->data[0], 1, 1e-7, "bayer10 1023");
		CHECK_NEAR(img->data[1], 512.0 / 1023.0, 1e-7, "bayer10 512");
		CHECK_NEAR(img->data[2], 1.0 / 1023.0, 1e-7, "bayer10 1");
		CHECK(img->cfa && !strcmp(img->cfa, "BGGR"), "bayer10 cfa");
		kg_image_free(&img);
	}
	/* rgb8 2x1. */
	const unsigned char r8[] = {255, 0, 51, 0, 102, 255};
	f = frame_of(KG_PIX_RGB8, 8, NULL, 2, 1, 6, r8, sizeof(r8));
	if ((img = convert(&f, 0, "rgb8"))) {
		const float want[] = {1, 0, 0.2f, 0, 0.4f, 1};
		CHECK(img->channels == 3, "rgb8 channels %d", img->channels);
		for (int i = 0; i < 6; i++)
			CHECK_NEAR(img->data[i], want[i], 1e-6, "rgb8 sample");
		kg_image_free(&img);
	}
	/* rgb16: 65535, 0, 32768. */
	const unsigned char r16[] = {0xff, 0xff, 0x00, 0x00, 0x00, 0x80};
	f = frame_of(KG_PIX_RGB16, 16, NULL, 1, 1, 6, r16, sizeof(r16));
	if ((img = convert(&f, 0, "rgb16"))) {
		CHECK_NEAR(img->data[0], 1, 1e-7, "rgb16 R");
		CHECK_NEAR(img->data[1], 0, 1e-7, "rgb16 G");
		CHECK_NEAR(img->data[2], 32768.0 / 65535.0, 1e-7, "rgb16 B");
		kg_image_free(&img);
	}
	/* YUYV: refused unless forced. Then BT.601 limited-range bars: white Y 235,
	 * black Y 16, 100 % red (Y 81, Cb 90, Cr 240), 100 % blue (Y 41, Cb 240, Cr 110). */
	const unsigned char yuyv[] = {235, 128, 16, 128, 81, 90, 81, 240, 41, 240, 41, 110};
	f = frame_of(KG_PIX_YUYV, 8, NULL, 6, 1, 12, yuyv, sizeof(yuyv));
	kg_image *tmp = NULL;
	kg_err e = {{0}};
	CHECK(kg_frame_to_image(&f, 0, &tmp, &e) == KG_EINVAL && !tmp && strstr(e.msg, "yuyv"),
	      "YUYV refused for measurement: %s", e.msg);
	if ((img = convert(&f, 1, "yuyv"))) {
		const float want[6][3] = {{1, 1, 1}, {0, 0, 0}, {1, 0, 0},
		                          {1, 0, 0}, {0, 0, 1}, {0, 0, 1}};
		for (int p = 0; p < 6; p++)
			for (int c = 0; c < 3; c++)
				CHECK_NEAR(img->data[3 * p + c], want[p][c], 0.01, "yuyv bar");
		kg_image_free(&img);
	}
	f = frame_of(KG_PIX_YUYV, 8, NULL, 5, 1, 10, yuyv, 10);
	CHECK(kg_frame_to_image(&f, 1, &tmp, &e) == KG_EINVAL && strstr(e.msg, "even"),
	      "odd YUYV width refused: %s", e.msg);
	/* MJPEG: refused unless forced; forced, bytes that are no JPEG stream are an error
	 * (real JPEG frames: tests/v4l2). */
	f = frame_of(KG_PIX_MJPEG, 8, NULL, 2, 2, 0, yuyv, sizeof(yuyv));
	CHECK(kg_frame_to_image(&f, 0, &tmp, &e) == KG_EINVAL && !tmp &&
	          strstr(e.msg, "MJPEG") && strstr(e.msg, "unless forced"),
	      "MJPEG refused unless forced: %s", e.msg);
	int want_code = kg_mjpeg_available() ? KG_EINVAL : KG_ENOTSUP;
	CHECK(kg_frame_to_image(&f, 1, &tmp, &e) == want_code && !tmp &&
	          strstr(e.msg, kg_mjpeg_available() ? "SOI" : "without libjpeg"),
	      "MJPEG of 12 bytes, forced: %s", e.msg);
	/* Too few bytes for the format. */
	f = frame_of(KG_PIX_MONO16, 16, NULL, 3, 2, 6, m12, sizeof(m12));
	CHECK(kg_frame_to_image(&f, 0, &tmp, &e) == KG_EINVAL && strstr(e.msg, "6 bytes"),
	      "short frame refused: %s", e.msg);
}

int main(void)
{
	test_parse();
	test_convert();
	return kg_test_done("test_camera_formats");
}
