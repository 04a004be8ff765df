/* A minimal DNG writer for the tests (libtiff): one uncompressed 16-bit image in IFD 0
 * (NewSubFileType 0), as a camera's or a converter's DNG holds its raw mosaic, with
 * the tags LibRaw reads: DNGVersion, Make, Model, UniqueCameraModel,
 * CameraSerialNumber, CFARepeatPatternDim/CFAPattern, BlackLevel (one value or a 2x2
 * repeat), WhiteLevel, and in an EXIF directory ExposureTime, FNumber,
 * ISOSpeedRatings, FocalLength and LensModel (iso_ifd0: ISOSpeedRatings in IFD 0
 * instead, as some cameras and converters write it). A
 * photometric of 34892 (LinearRaw) with 3 samples writes an already demosaiced DNG. */
#ifndef KG_TEST_DNG_H
#define KG_TEST_DNG_H

#include <stddef.h>
#include <stdint.h>

typedef struct test_dng {
	int width, height;
	const uint16_t *data;   /* width * height * spp values, row-major */
	const char *cfa;        /* "RGGB", ...; ignored for LinearRaw */
	double black[4];        /* one value (black_dim 1) or the 2x2 repeat (black_dim 2) */
	int black_dim;
	double white;
	double exposure_s, iso, fnumber, focal_mm; /* <= 0: tag left out */
	const char *make, *model, *serial, *lens;  /* NULL: tag left out */
	int linear_raw;         /* 1: PhotometricInterpretation LinearRaw, 3 samples */
	double iso_ifd0;        /* > 0: ISOSpeedRatings (0x8827) written in IFD 0 */
} test_dng;

/* 0, or -1 with a message in msg. */
int test_dng_write(const char *path, const test_dng *d, char *msg, size_t msg_len);

#endif
