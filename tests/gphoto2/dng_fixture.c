/* Writes the DNG of dng_fixture.h with libtiff: NewSubFileType 0, one strip of 16-bit
 * CFA samples, CFARepeatPatternDim / CFAPattern, DNGVersion 1.4.0.0, Make, Model,
 * UniqueCameraModel, BlackLevel, WhiteLevel, and an EXIF directory with ExposureTime
 * and ISOSpeedRatings. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include <tiffio.h>

#include "dng_fixture.h"

int dng_fixture_write(const char *path)
{
	TIFF *t = TIFFOpen(path, "w");
	if (!t) {
		fprintf(stderr, "%s: cannot create\n", path);
		return -1;
	}
	static const uint8_t dng_version[4] = {1, 4, 0, 0};
	static const uint16_t cfa_dim[2] = {2, 2};
	static const uint8_t cfa_rggb[4] = {0, 1, 1, 2};
	float black = DNG_BLACK;
	uint32_t white = DNG_WHITE;
	uint16_t iso = DNG_ISO;
	TIFFSetField(t, TIFFTAG_SUBFILETYPE, 0);
	TIFFSetField(t, TIFFTAG_IMAGEWIDTH, DNG_W);
	TIFFSetField(t, TIFFTAG_IMAGELENGTH, DNG_H);
	TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, 16);
	TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1);
	TIFFSetField(t, TIFFTAG_COMPRESSION, COMPRESSION_NONE);
	TIFFSetField(t, TIFFTAG_PHOTOMETRIC, 32803); /* CFA */
	TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
	TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, DNG_H);
	TIFFSetField(t, TIFFTAG_MAKE, DNG_MAKE);
	TIFFSetField(t, TIFFTAG_MODEL, DNG_MODEL);
	TIFFSetField(t, TIFFTAG_CFAREPEATPATTERNDIM, cfa_dim);
	TIFFSetField(t, TIFFTAG_CFAPATTERN, 4, cfa_rggb);
	TIFFSetField(t, TIFFTAG_DNGVERSION, dng_version);
	TIFFSetField(t, TIFFTAG_DNGBACKWARDVERSION, dng_version);
	TIFFSetField(t, TIFFTAG_UNIQUECAMERAMODEL, DNG_MAKE " " DNG_MODEL);
	TIFFSetField(t, TIFFTAG_BLACKLEVEL, 1, &black);
	TIFFSetField(t, TIFFTAG_WHITELEVEL, 1, &white);
	TIFFSetField(t, TIFFTAG_EXIFIFD, (uint64_t)0); /* set below */
	uint16_t row[DNG_W];
	int ok = 1;
	for (int y = 0; y < DNG_H && ok; y++) {
		for (int x = 0; x < DNG_W; x++)
			row[x] = (uint16_t)dng_raw(x, y);
		ok = TIFFWriteScanline(t, row, (uint32_t)y, 0) == 1;
	}
	if (ok)
		ok = TIFFWriteDirectory(t) == 1;
	/* the EXIF directory, then IFD 0 rewritten to point at it */
	uint64_t exif_off = 0;
	if (ok)
		ok = TIFFCreateEXIFDirectory(t) == 0 &&
		     TIFFSetField(t, EXIFTAG_EXPOSURETIME,
		                  (double)DNG_EXPOSURE_NUM / DNG_EXPOSURE_DEN) == 1 &&
		     TIFFSetField(t, EXIFTAG_ISOSPEEDRATINGS, 1, &iso) == 1 &&
		     TIFFWriteCustomDirectory(t, &exif_off) == 1;
	if (ok)
		ok = TIFFSetDirectory(t, 0) == 1 && TIFFSetField(t, TIFFTAG_EXIFIFD, exif_off) == 1 &&
		     TIFFRewriteDirectory(t) == 1;
	TIFFClose(t);
	if (!ok) {
		fprintf(stderr, "%s: cannot write the DNG\n", path);
		return -1;
	}
	return 0;
}
