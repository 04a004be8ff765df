/* Writes the DNG of dng_fixture.h through the tests' DNG writer (tests/raw/dng.h):
 * DNGVersion 1.4.0.0, Make, Model, BlackLevel, WhiteLevel, RGGB, and an EXIF directory
 * with ExposureTime and ISOSpeedRatings. */
#include <stdint.h>
#include <stdio.h>

#include "dng.h"
#include "dng_fixture.h"

int dng_fixture_write(const char *path)
{
	static uint16_t raw[DNG_W * DNG_H];
	for (int y = 0; y < DNG_H; y++)
		for (int x = 0; x < DNG_W; x++)
			raw[y * DNG_W + x] = (uint16_t)dng_raw(x, y);
	test_dng d = {.width = DNG_W, .height = DNG_H, .data = raw, .cfa = DNG_CFA,
	              .black = {DNG_BLACK, DNG_BLACK, DNG_BLACK, DNG_BLACK}, .black_dim = 1,
	              .white = DNG_WHITE,
	              .exposure_s = (double)DNG_EXPOSURE_NUM / DNG_EXPOSURE_DEN, .iso = DNG_ISO,
	              .make = DNG_MAKE, .model = DNG_MODEL};
	char msg[256];
	if (test_dng_write(path, &d, msg, sizeof(msg))) {
		fprintf(stderr, "%s\n", msg);
		return -1;
	}
	return 0;
}
