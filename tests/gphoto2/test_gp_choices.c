/* The pure parts of the gphoto2 backend (devices/gphoto2/gp_choices.c): choice strings
 * of shutter speeds, ISO speeds, apertures and focal lengths read as numbers, the exact
 * choice for a value or an error naming the nearest ones, raw formats and names,
 * exposure programs, and the conversion of a decoded raw to 16-bit words. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "gp_choices.h"
#include "kg_test.h"


/* text must read as want (relative 1e-9), or not at all when want is NAN */
static void value_is(kg_feature f, const char *text, double want)
{
	double v = -1;
	int ok = kg_gp_choice_value(f, text, &v);
	if (isnan(want))
		CHECK(!ok, "%s '%s': read as %g, expected no number", kg_feature_name(f), text, v);
	else
		CHECK(ok && fabs(v - want) <= 1e-9 * fabs(want), "%s '%s': got %s%g, expected %g",
		      kg_feature_name(f), text, ok ? "" : "no number ", v, want);
}

int main(void)
{
	printf("shutter speed choices to microseconds\n");
	value_is(KG_FEAT_EXPOSURE_US, "1/125", 8000);
	value_is(KG_FEAT_EXPOSURE_US, "1/4000", 250);
	value_is(KG_FEAT_EXPOSURE_US, "1/1.6", 625000);
	value_is(KG_FEAT_EXPOSURE_US, "0.3", 300000);
	value_is(KG_FEAT_EXPOSURE_US, "2", 2e6);
	value_is(KG_FEAT_EXPOSURE_US, "30", 3e7);
	value_is(KG_FEAT_EXPOSURE_US, "2s", 2e6);
	value_is(KG_FEAT_EXPOSURE_US, "30\"", 3e7);
	value_is(KG_FEAT_EXPOSURE_US, "1/250s", 4000);
	value_is(KG_FEAT_EXPOSURE_US, " 1 / 8 ", 125000);
	value_is(KG_FEAT_EXPOSURE_US, "Bulb", NAN);
	value_is(KG_FEAT_EXPOSURE_US, "Time", NAN);
	value_is(KG_FEAT_EXPOSURE_US, "x 250", NAN);
	value_is(KG_FEAT_EXPOSURE_US, "1/0", NAN);
	value_is(KG_FEAT_EXPOSURE_US, "0", NAN);
	value_is(KG_FEAT_EXPOSURE_US, "-1", NAN);
	value_is(KG_FEAT_EXPOSURE_US, "2 minutes", NAN);
	value_is(KG_FEAT_EXPOSURE_US, "", NAN);

	printf("ISO choices\n");
	value_is(KG_FEAT_ISO, "100", 100);
	value_is(KG_FEAT_ISO, "ISO 6400", 6400);
	value_is(KG_FEAT_ISO, "Auto", NAN);
	value_is(KG_FEAT_ISO, "Auto ISO", NAN);
	value_is(KG_FEAT_ISO, "100x", NAN);

	printf("aperture choices\n");
	value_is(KG_FEAT_APERTURE, "f/5.6", 5.6);
	value_is(KG_FEAT_APERTURE, "F8", 8);
	value_is(KG_FEAT_APERTURE, "5.6", 5.6);
	value_is(KG_FEAT_APERTURE, "f/22", 22);
	value_is(KG_FEAT_APERTURE, "implicit auto", NAN);

	printf("focal length values\n");
	value_is(KG_FEAT_FOCAL_LENGTH, "50", 50);
	value_is(KG_FEAT_FOCAL_LENGTH, "24.5 mm", 24.5);
	value_is(KG_FEAT_FOCAL_LENGTH, "35mm", 35);
	value_is(KG_FEAT_FOCAL_LENGTH, "wide", NAN);
	value_is(KG_FEAT_GAIN, "1", NAN);

	printf("range over the numeric choices\n");
	const char *const shutter[] = {"Bulb", "30", "2", "0.3", "1/40", "1/125", "1/4000"};
	int n = (int)(sizeof(shutter) / sizeof(shutter[0]));
	double lo, hi;
	int count = kg_gp_choice_range(KG_FEAT_EXPOSURE_US, shutter, n, &lo, &hi);
	CHECK(count == n - 1 && lo == 250 && hi == 3e7, "shutter range: %d choices %g..%g",
	      count, lo, hi);
	const char *const only_auto[] = {"Auto"};
	count = kg_gp_choice_range(KG_FEAT_ISO, only_auto, 1, &lo, &hi);
	CHECK(count == 0 && lo == 0 && hi == 0, "ISO Auto only: %d choices %g..%g", count, lo, hi);

	printf("picking the exact choice\n");
	kg_err err = {{0}};
	int idx = -1;
	int ret = kg_gp_choice_pick(KG_FEAT_EXPOSURE_US, "shutterspeed", shutter, n, 8000, &idx,
	                            &err);
	CHECK(ret == 0 && idx == 5, "8000 us: ret %d index %d (%s)", ret, idx, err.msg);
	ret = kg_gp_choice_pick(KG_FEAT_EXPOSURE_US, "shutterspeed", shutter, n, 300000, &idx, &err);
	CHECK(ret == 0 && idx == 3, "300000 us: ret %d index %d", ret, idx);
	const char *const third[] = {"1/3", "1/2"};
	ret = kg_gp_choice_pick(KG_FEAT_EXPOSURE_US, "shutterspeed", third, 2, 333333, &idx, &err);
	CHECK(ret == 0 && idx == 0, "333333 us selects 1/3: ret %d index %d", ret, idx);
	const char *const isos[] = {"Auto", "100", "200", "400", "800", "1600"};
	ret = kg_gp_choice_pick(KG_FEAT_ISO, "iso", isos, 6, 400, &idx, &err);
	CHECK(ret == 0 && idx == 3, "ISO 400: ret %d index %d", ret, idx);
	const char *const fnums[] = {"f/2.8", "f/4", "f/5.6", "f/8"};
	ret = kg_gp_choice_pick(KG_FEAT_APERTURE, "aperture", fnums, 4, 5.6, &idx, &err);
	CHECK(ret == 0 && idx == 2, "f/5.6: ret %d index %d", ret, idx);

	printf("a value between choices names the nearest ones\n");
	ret = kg_gp_choice_pick(KG_FEAT_ISO, "iso", isos, 6, 500, &idx, &err);
	CHECK(ret == KG_ERANGE && strstr(err.msg, "iso") && strstr(err.msg, "400") &&
	          strstr(err.msg, "800") && strstr(err.msg, "500"),
	      "ISO 500: ret %d '%s'", ret, err.msg);
	ret = kg_gp_choice_pick(KG_FEAT_EXPOSURE_US, "shutterspeed", shutter, n, 5000, &idx, &err);
	CHECK(ret == KG_ERANGE && strstr(err.msg, "1/4000 (250 us)") &&
	          strstr(err.msg, "1/125 (8000 us)") && !strstr(err.msg, "1/40 "),
	      "5000 us: ret %d '%s'", ret, err.msg);
	ret = kg_gp_choice_pick(KG_FEAT_APERTURE, "aperture", fnums, 4, 11, &idx, &err);
	CHECK(ret == KG_ERANGE && strstr(err.msg, "f/8") && strstr(err.msg, "largest"),
	      "f/11: ret %d '%s'", ret, err.msg);
	ret = kg_gp_choice_pick(KG_FEAT_APERTURE, "aperture", fnums, 4, 1.4, &idx, &err);
	CHECK(ret == KG_ERANGE && strstr(err.msg, "f/2.8") && strstr(err.msg, "smallest"),
	      "f/1.4: ret %d '%s'", ret, err.msg);
	ret = kg_gp_choice_pick(KG_FEAT_ISO, "iso", only_auto, 1, 100, &idx, &err);
	CHECK(ret == KG_ENOTSUP && strstr(err.msg, "iso"), "only Auto: ret %d '%s'", ret, err.msg);

	printf("raw image formats and file names\n");
	static const struct {
		const char *text;
		int raw;
	} formats[] = {{"RAW", 1},          {"RAW + Large Fine JPEG", 1}, {"NEF (Raw)", 1},
	               {"NEF+Basic", 1},    {"cRAW", 1},                  {"ARW", 1},
	               {"Large Fine JPEG", 0}, {"JPEG Fine", 0},          {"sRAW", 0},
	               {"mRAW + JPEG", 0},  {"HEIF", 0},                  {"TIFF", 0}};
	for (size_t i = 0; i < sizeof(formats) / sizeof(formats[0]); i++)
		CHECK(kg_gp_is_raw_choice(formats[i].text) == formats[i].raw, "format '%s': raw %d",
		      formats[i].text, !formats[i].raw);
	CHECK(kg_gp_is_raw_name("IMG_0001.CR2") && kg_gp_is_raw_name("dsc.nef") &&
	          kg_gp_is_raw_name("x.dng") && !kg_gp_is_raw_name("IMG_0001.JPG") &&
	          !kg_gp_is_raw_name("noext") && !kg_gp_is_raw_name(NULL),
	      "raw file names");

	printf("exposure programs\n");
	CHECK(kg_gp_program_is_manual("M") && kg_gp_program_is_manual("Manual") &&
	          kg_gp_program_is_manual("Bulb") && !kg_gp_program_is_manual("P") &&
	          !kg_gp_program_is_manual("AV") && !kg_gp_program_is_manual("Auto"),
	      "manual programs");

	printf("decoded raw to 16-bit words: round(clamp(v, 0, 1) * 65535), little-endian\n");
	const float in[] = {-0.5f, 0.0f, 0.5f, 1.0f, 1.5f, NAN, 1.0f / 65535.0f, 0.25f};
	uint8_t out[2 * 8];
	kg_gp_to_bayer16(in, 8, out);
	const unsigned want[] = {0, 0, 32768, 65535, 65535, 0, 1, 16384};
	for (int i = 0; i < 8; i++) {
		unsigned got = out[2 * i] | (unsigned)out[2 * i + 1] << 8;
		CHECK(got == want[i], "sample %d (%g): %u, expected %u", i, (double)in[i], got,
		      want[i]);
	}

	printf("open errors: permission, another program holding the camera, camera gone\n");
	ret = kg_gp_open_error("Cam X", "usb:001,007", "/dev/bus/usb/001/007", 1, -7, "I/O problem",
	                       NULL, &err);
	printf("  %s\n", err.msg);
	CHECK(ret == KG_EIO && strstr(err.msg, "Cam X") && strstr(err.msg, "/dev/bus/usb/001/007") &&
	          strstr(err.msg, "udev rules") && strstr(err.msg, "libgphoto2-6"),
	      "permission: %d '%s'", ret, err.msg);
	ret = kg_gp_open_error("Cam X", "usb:001,007", "/dev/bus/usb/001/007", 0, -53,
	                       "Could not claim the USB device", "Could not claim interface 0",
	                       &err);
	printf("  %s\n", err.msg);
	CHECK(ret == KG_EIO && strstr(err.msg, "Cam X") && strstr(err.msg, "another program") &&
	          strstr(err.msg, "gvfs-gphoto2-volume-monitor") &&
	          strstr(err.msg, "gio mount -s gphoto2") && strstr(err.msg, "claim interface 0"),
	      "claim: %d '%s'", ret, err.msg);
	ret = kg_gp_open_error("Cam X", "usb:001,007", "", 0, -52, "Could not find the USB device",
	                       NULL, &err);
	CHECK(ret == KG_ENODEV && strstr(err.msg, "udev rules"), "find: %d '%s'", ret, err.msg);
	ret = kg_gp_open_error("Cam X", "usb:001,007", "", 0, -7, "I/O problem", NULL, &err);
	CHECK(ret == KG_ENODEV && strstr(err.msg, "does not answer") && strstr(err.msg, "Cam X"),
	      "gone: %d '%s'", ret, err.msg);
	ret = kg_gp_open_error("Cam X", "ptpip:10.0.0.2", "", 0, -1, "Unspecified error", NULL, &err);
	CHECK(ret == KG_EIO && strstr(err.msg, "ptpip:10.0.0.2"), "other: %d '%s'", ret, err.msg);

	if (kg_test_failures)
		printf("%d check(s) failed\n", kg_test_failures);
	else
		printf("all checks passed\n");
	return kg_test_failures ? 1 : 0;
}
