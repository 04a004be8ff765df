/* The gphoto2 backend driving libgphoto2's real ptp2 driver through a umockdev replay
 * of PTP over USB (make_ptp_replay.py; run by run_ptp_replay.sh inside umockdev-run).
 *
 *   test_gphoto2_ptp config DIR          replay DIR/ptp-config.*: open by model, the
 *                                        identity from DeviceInfo, shutter speed and
 *                                        ISO from their property descriptions, ISO set
 *                                        and read back, a value between choices refused
 *   test_gphoto2_ptp capture DIR DNG     replay DIR/ptp-capture.*: open by port with
 *                                        delete=1 and save=DIR/saved, the format learnt
 *                                        from one capture, one frame captured,
 *                                        downloaded and decoded; its pixels against the
 *                                        DNG's raw values, the bytes downloaded and saved
 *                                        against the DNG
 *
 *   test_gphoto2_ptp preview DIR JPEG    replay DIR/ptp-preview.*: the live view (what the
 *                                        console calls): kg_camera_preview three times,
 *                                        each libgphoto2's capture preview (Nikon's
 *                                        StartLiveView, GetLiveViewImg), the JPEG
 *                                        delivered byte for byte as an MJPEG frame and
 *                                        decoded; the driver counts 3 previews and no
 *                                        capture (and the replay holds no
 *                                        InitiateCapture to answer one)
 *
 * What the camera says is read from DIR/ptp.expect (written by the generator); the
 * DNG's values from dng_fixture.h. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dng_fixture.h"
#include "gphoto2_private.h"
#include "kg_camera.h"
#include "raw.h"
#include "kg_test.h"


/* ---- expectations -------------------------------------------------------------- */

static char expect_text[4096];

static int load_expect(const char *dir)
{
	char path[1024];
	snprintf(path, sizeof(path), "%s/ptp.expect", dir);
	FILE *f = fopen(path, "r");
	if (!f) {
		printf("FAIL: cannot read %s\n", path);
		return -1;
	}
	size_t n = fread(expect_text, 1, sizeof(expect_text) - 1, f);
	expect_text[n] = 0;
	fclose(f);
	return 0;
}

/* The value of key in ptp.expect (static buffer), "" when absent. */
static const char *expect(const char *key)
{
	static char value[256];
	size_t k = strlen(key);
	for (const char *p = expect_text; p && *p;) {
		const char *nl = strchr(p, '\n');
		size_t len = nl ? (size_t)(nl - p) : strlen(p);
		if (len > k && !strncmp(p, key, k) && p[k] == '=') {
			snprintf(value, sizeof(value), "%.*s", (int)(len - k - 1), p + k + 1);
			return value;
		}
		p = nl ? nl + 1 : NULL;
	}
	value[0] = 0;
	return value;
}

static double expect_num(const char *key) { return atof(expect(key)); }

static void *read_all(const char *path, size_t *size)
{
	FILE *f = fopen(path, "rb");
	if (!f)
		return NULL;
	fseek(f, 0, SEEK_END);
	long n = ftell(f);
	fseek(f, 0, SEEK_SET);
	void *b = n >= 0 ? malloc((size_t)n + 1) : NULL;
	if (b && fread(b, 1, (size_t)n, f) != (size_t)n) {
		free(b);
		b = NULL;
	}
	fclose(f);
	*size = (size_t)n;
	return b;
}

/* ---- config -------------------------------------------------------------------- */

static void feature(kg_camera *c, kg_feature f, double min, double max, double now)
{
	kg_feature_info fi;
	kg_err err = {{0}};
	int ret = kg_camera_feature_info(c, f, &fi, &err);
	CHECK(ret == 0 && fi.available && fi.writable && fi.step == 0,
	      "%s: ret %d available %d writable %d step %g (%s)", kg_feature_name(f), ret,
	      fi.available, fi.writable, fi.step, err.msg);
	CHECK(fi.min == min && fi.max == max, "%s: range %g..%g, expected %g..%g",
	      kg_feature_name(f), fi.min, fi.max, min, max);
	double v = NAN;
	ret = kg_camera_get(c, f, &v, &err);
	CHECK(ret == 0 && fabs(v - now) <= 1e-6 * now, "%s: reads %g (ret %d %s), expected %g",
	      kg_feature_name(f), v, ret, err.msg, now);
	printf("  %s (%s): %g..%g %s, now %g\n", kg_feature_name(f), fi.native, fi.min, fi.max,
	       fi.unit, v);
}

static void config(void)
{
	printf("open by model (\"USB PTP Class Camera\"): OpenSession, GetDeviceInfo\n");
	kg_camera *c = NULL;
	kg_err err = {{0}};
	int ret = kg_camera_open("gphoto2:USB PTP Class Camera", &c, &err);
	CHECK(ret == 0, "open: %d %s", ret, err.msg);
	if (ret)
		return;
	const kg_camera_info *info = kg_camera_get_info(c);
	printf("  vendor '%s' model '%s' serial '%s' transport '%s'\n", info->vendor, info->model,
	       info->serial, info->transport);
	CHECK(!strcmp(info->vendor, expect("manufacturer")), "vendor '%s'", info->vendor);
	CHECK(!strcmp(info->model, expect("model")), "model '%s'", info->model);
	CHECK(!strcmp(info->serial, expect("serial")), "serial '%s'", info->serial);
	CHECK(!strcmp(info->transport, "USB PTP"), "transport '%s'", info->transport);

	printf("features from GetDevicePropDesc: ExposureTime as shutterspeed, ExposureIndex "
	       "as iso; the others unavailable\n");
	feature(c, KG_FEAT_EXPOSURE_US, expect_num("exposure_min_us"), expect_num("exposure_max_us"),
	        expect_num("exposure_now_us"));
	feature(c, KG_FEAT_ISO, expect_num("iso_min"), expect_num("iso_max"), expect_num("iso_now"));
	static const kg_feature absent[] = {KG_FEAT_GAIN, KG_FEAT_APERTURE, KG_FEAT_FOCAL_LENGTH,
	                                    KG_FEAT_AUTO_EXPOSURE, KG_FEAT_WB_RED};
	for (size_t i = 0; i < sizeof(absent) / sizeof(absent[0]); i++) {
		kg_feature_info fi;
		ret = kg_camera_feature_info(c, absent[i], &fi, &err);
		CHECK(ret == 0 && !fi.available, "%s: ret %d available %d",
		      kg_feature_name(absent[i]), ret, fi.available);
	}

	double iso_set = expect_num("iso_set"), got = NAN;
	printf("ISO between two choices refused naming the nearest (nothing sent)\n");
	double between = (expect_num("iso_now") + iso_set) / 2 + 1;
	ret = kg_camera_set(c, KG_FEAT_ISO, between, &got, &err);
	printf("  %s\n", err.msg);
	CHECK(ret == KG_ERANGE && strstr(err.msg, "nearest"), "ISO %g: ret %d '%s'", between, ret,
	      err.msg);
	printf("ISO %g: SetDevicePropValue, read back through GetDevicePropDesc\n", iso_set);
	ret = kg_camera_set(c, KG_FEAT_ISO, iso_set, &got, &err);
	CHECK(ret == 0 && got == iso_set, "set ISO %g: ret %d read back %g (%s)", iso_set, ret, got,
	      err.msg);
	printf("close: CloseSession\n");
	kg_camera_free(&c);
}

/* ---- capture ------------------------------------------------------------------- */

static void same_bytes(const char *what, const void *a, size_t na, const void *b, size_t nb)
{
	CHECK(na == nb && !memcmp(a, b, na), "%s: %zu bytes, the DNG written has %zu%s", what, na,
	      nb, na == nb ? " (contents differ)" : "");
}

static void capture(const char *dir, const char *dng_path)
{
	size_t dng_size = 0;
	void *dng = read_all(dng_path, &dng_size);
	CHECK(dng != NULL, "cannot read %s", dng_path);
	if (!dng)
		return;
	char uri[1200];
	snprintf(uri, sizeof(uri), "gphoto2:usb:001,002?delete=1&save=%s/saved", dir);
	printf("open by port (%s)\n", uri);
	kg_camera *c = NULL;
	kg_err err = {{0}};
	int ret = kg_camera_open(uri, &c, &err);
	CHECK(ret == 0, "open: %d %s", ret, err.msg);
	if (ret) {
		free(dng);
		return;
	}
	CHECK(!strcmp(kg_camera_get_info(c)->model, expect("model")), "model '%s'",
	      kg_camera_get_info(c)->model);

	kg_frame_format fmt;
	ret = kg_camera_get_format(c, &fmt, &err);
	const void *data = NULL;
	size_t size = 0;
	const char *name = NULL;
	kg_raw_meta meta;
	kg_err e2 = {{0}};
	if (!kg_raw_available()) {
		printf("no LibRaw in this build: the first capture is downloaded, then refused "
		       "for want of a decoder\n");
		CHECK(ret == KG_ENOTSUP, "get_format: %d %s", ret, err.msg);
		ret = kg_gphoto2_last_file(c, &data, &size, &name, NULL, &e2);
		CHECK(ret == 0, "last file: %d %s", ret, e2.msg);
		if (!ret)
			same_bytes("GetObject", data, size, dng, dng_size);
		kg_camera_free(&c);
		free(dng);
		return;
	}
	printf("get_format: one capture (GetObjectHandles, InitiateCapture, GetObjectHandles, "
	       "GetObjectInfo, GetObject, DeleteObject) decoded to learn the format\n");
	CHECK(ret == 0, "get_format: %d %s", ret, err.msg);
	if (ret) {
		kg_camera_free(&c);
		free(dng);
		return;
	}
	printf("  %s %s %dx%d, %d bits\n", kg_pixfmt_name(fmt.pixfmt), fmt.cfa, fmt.width,
	       fmt.height, fmt.bits);
	CHECK(fmt.pixfmt == KG_PIX_BAYER16 && fmt.bits == 16 && !strcmp(fmt.cfa, DNG_CFA) &&
	          fmt.width == DNG_W && fmt.height == DNG_H && fmt.size == (size_t)DNG_W * DNG_H * 2,
	      "format %s %s %dx%d %d bits", kg_pixfmt_name(fmt.pixfmt), fmt.cfa, fmt.width,
	      fmt.height, fmt.bits);
	ret = kg_gphoto2_last_file(c, &data, &size, &name, NULL, &e2);
	CHECK(ret == 0 && strstr(name, expect("file1")), "last file: %d %s %s", ret,
	      name ? name : "", e2.msg);

	printf("start, pop: the second capture as a frame\n");
	ret = kg_camera_start(c, 0, &err);
	CHECK(ret == 0, "start: %d %s", ret, err.msg);
	kg_frame f;
	ret = ret ? ret : kg_camera_pop(c, 10000, &f, &err);
	CHECK(ret == 0, "pop: %d %s", ret, err.msg);
	if (!ret) {
		printf("  frame %llu: %zu bytes, exposure %g us, source %s\n",
		       (unsigned long long)f.sequence, f.size, f.exposure_us,
		       f.source ? f.source : "(none)");
		printf("  %s\n", f.source_note ? f.source_note : "");
		double want_exp = 1e6 * DNG_EXPOSURE_NUM / DNG_EXPOSURE_DEN;
		CHECK(fabs(f.exposure_us - want_exp) < 1e-3, "exposure %g us from the metadata, "
		      "expected %g", f.exposure_us, want_exp);
		CHECK(f.status == KG_FRAME_OK && f.size == fmt.size, "status %d size %zu", f.status,
		      f.size);
		/* pixels: round(clamp((raw - black) / (white - black), 0, 1) * 65535) */
		const uint8_t *p = f.data;
		int exact = 0, off_by_one = 0, wrong = 0, clipped = 0;
		for (int y = 0; y < DNG_H; y++)
			for (int x = 0; x < DNG_W; x++) {
				double v = ((double)dng_raw(x, y) - DNG_BLACK) / (DNG_WHITE - DNG_BLACK);
				clipped += v < 0 || v > 1;
				v = v < 0 ? 0 : v > 1 ? 1 : v;
				long want = lround(v * 65535);
				size_t i = ((size_t)y * DNG_W + (size_t)x) * 2;
				long got = p[i] | (long)p[i + 1] << 8;
				if (got == want)
					exact++;
				else if (labs(got - want) == 1)
					off_by_one++;
				else if (wrong++ < 5)
					printf("  pixel (%d,%d): raw %u gives %ld, expected %ld\n", x, y,
					       dng_raw(x, y), got, want);
			}
		printf("  pixels: %d exact, %d off by one count (float rounding), %d wrong, %d of "
		       "them clipped at black or white\n",
		       exact, off_by_one, wrong, clipped);
		CHECK(wrong == 0 && exact > 0.99 * DNG_W * DNG_H, "%d pixels wrong, %d exact", wrong,
		      exact);
		ret = kg_gphoto2_last_file(c, &data, &size, &name, &meta, &e2);
		CHECK(ret == 0 && strstr(name, expect("file2")), "last file: %d %s", ret, e2.msg);
		if (!ret) {
			same_bytes("GetObject", data, size, dng, dng_size);
			printf("  metadata: %s %s, ISO %g, exposure %g s\n", meta.make, meta.model, meta.iso,
			       meta.exposure_s);
			CHECK(meta.iso == DNG_ISO && !strcmp(meta.model, DNG_MODEL),
			      "metadata ISO %g model '%s'", meta.iso, meta.model);
		}
		size_t saved_size = 0;
		void *saved = f.source ? read_all(f.source, &saved_size) : NULL;
		CHECK(saved != NULL && strstr(f.source, expect("file2")), "saved file %s",
		      f.source ? f.source : "(none)");
		if (saved)
			same_bytes("the saved original", saved, saved_size, dng, dng_size);
		free(saved);
		ret = kg_camera_push(c, &f, &err);
		CHECK(ret == 0, "push: %d %s", ret, err.msg);
	}
	kg_stream_stats st;
	kg_camera_stats(c, &st);
	CHECK(st.completed == 1 && st.failed == 0, "stats: %llu completed %llu failed",
	      (unsigned long long)st.completed, (unsigned long long)st.failed);
	ret = kg_camera_stop(c, &err);
	CHECK(ret == 0, "stop: %d %s", ret, err.msg);
	printf("close: CloseSession\n");
	kg_camera_free(&c);
	free(dng);
}

/* ---- live view ----------------------------------------------------------------- */

static void preview(const char *jpeg_path)
{
	size_t jpeg_size = 0;
	void *jpeg = read_all(jpeg_path, &jpeg_size);
	CHECK(jpeg != NULL, "cannot read %s", jpeg_path);
	if (!jpeg)
		return;
	kg_camera *c = NULL;
	kg_err err = {{0}};
	int ret = kg_camera_open("gphoto2:usb:001,002", &c, &err);
	CHECK(ret == 0, "open: %d %s", ret, err.msg);
	if (ret) {
		free(jpeg);
		return;
	}
	CHECK(kg_camera_has_preview(c), "the gphoto2 driver has its own preview");
	int n = (int)expect_num("previews");
	for (int k = 1; k <= n; k++) {
		kg_frame f;
		int own = 0;
		printf("preview %d: gp_camera_capture_preview%s\n", k,
		       k == 1 ? " (GetDevicePropValue LiveViewStatus, StartLiveView, DeviceReady, "
		                "GetLiveViewImg twice: ptp2 skips the first image)"
		              : " (GetDevicePropValue LiveViewStatus, GetLiveViewImg)");
		ret = kg_camera_preview(c, 5000, &f, &own, &err);
		CHECK(ret == 0, "preview %d: %d %s", k, ret, err.msg);
		if (ret)
			break;
		CHECK(own == 1, "preview %d: the driver's own preview", k);
		CHECK(f.fmt.pixfmt == KG_PIX_MJPEG && f.fmt.width == 64 && f.fmt.height == 48,
		      "preview %d: %s %dx%d, expected mjpeg 64x48", k, kg_pixfmt_name(f.fmt.pixfmt),
		      f.fmt.width, f.fmt.height);
		CHECK(f.size == jpeg_size && !memcmp(f.data, jpeg, jpeg_size),
		      "preview %d: %zu bytes, the camera's JPEG (after its header) has %zu", k,
		      f.size, jpeg_size);
		CHECK(f.sequence == (uint64_t)k, "preview %d: sequence %llu", k,
		      (unsigned long long)f.sequence);
		kg_image *img = NULL;
		ret = kg_frame_to_image(&f, 1, &img, &err);
		CHECK(ret == 0 && img->width == 64 && img->height == 48 && img->channels == 3,
		      "preview %d decoded: %d %s", k, ret, err.msg);
		if (!ret) {
			/* write_jpeg's pattern: red x*4, green y*5, blue 40 | 200 (quality 95; the
			 * blue step's ringing left out) */
			double worst = 0;
			for (int y = 0; y < 48; y++)
				for (int x = 0; x < 64; x++) {
					const float *p = img->data + 3 * ((size_t)y * 64 + (size_t)x);
					double want[3] = {x * 4 / 255.0, y * 5 / 255.0, (x < 32 ? 40 : 200) / 255.0};
					for (int q = 0; q < 3; q++)
						if (fabs(p[q] - want[q]) > worst && (x < 29 || x > 34))
							worst = fabs(p[q] - want[q]);
				}
			CHECK(worst < 8 / 255.0, "preview %d: decoded pixels off the pattern by %.1f/255",
			      k, worst * 255);
		}
		kg_image_free(&img);
	}
	uint64_t captures = 99, previews = 0;
	ret = kg_gphoto2_counts(c, &captures, &previews);
	CHECK(ret == 0 && previews == (uint64_t)n && captures == 0,
	      "the driver counts %llu previews and %llu full captures, expected %d and 0",
	      (unsigned long long)previews, (unsigned long long)captures, n);
	kg_stream_stats st;
	kg_camera_stats(c, &st);
	CHECK(st.completed == 0, "no stream frame (%llu completed)",
	      (unsigned long long)st.completed);
	printf("close: CloseSession\n");
	kg_camera_free(&c);
	free(jpeg);
}

int main(int argc, char **argv)
{
	if (argc < 3 ||
	    (strcmp(argv[1], "config") && strcmp(argv[1], "capture") && strcmp(argv[1], "preview")) ||
	    (strcmp(argv[1], "config") && argc != 4)) {
		fprintf(stderr, "usage: test_gphoto2_ptp config DIR | capture DIR DNG | preview DIR "
		        "JPEG\n");
		return 2;
	}
	if (load_expect(argv[2]))
		return 1;
	if (!strcmp(argv[1], "config"))
		config();
	else if (!strcmp(argv[1], "capture"))
		capture(argv[2], argv[3]);
	else
		preview(argv[3]);
	if (kg_test_failures)
		printf("%d check(s) failed\n", kg_test_failures);
	else
		printf("all checks passed\n");
	return kg_test_failures ? 1 : 0;
}
