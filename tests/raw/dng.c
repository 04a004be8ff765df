/* The tests' DNG writer (dng.h). */
#include "dng.h"

#include <stdio.h>
#include <string.h>
#include <tiffio.h>

static int cfa_code(char c)
{
	return c == 'R' ? 0 : c == 'G' ? 1 : c == 'B' ? 2 : -1;
}

int test_dng_write(const char *path, const test_dng *d, char *msg, size_t n)
{
	TIFF *t = TIFFOpen(path, "w");
	if (!t) {
		snprintf(msg, n, "%s: cannot create", path);
		return -1;
	}
	int spp = d->linear_raw ? 3 : 1;
	static const uint8_t version[4] = {1, 4, 0, 0}, backward[4] = {1, 1, 0, 0};
	TIFFSetField(t, TIFFTAG_SUBFILETYPE, 0);
	TIFFSetField(t, TIFFTAG_IMAGEWIDTH, (uint32_t)d->width);
	TIFFSetField(t, TIFFTAG_IMAGELENGTH, (uint32_t)d->height);
	TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, 16);
	TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, spp);
	TIFFSetField(t, TIFFTAG_COMPRESSION, COMPRESSION_NONE);
	TIFFSetField(t, TIFFTAG_PHOTOMETRIC, d->linear_raw ? 34892 : PHOTOMETRIC_CFA);
	TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
	TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, (uint32_t)d->height);
	TIFFSetField(t, TIFFTAG_DNGVERSION, version);
	TIFFSetField(t, TIFFTAG_DNGBACKWARDVERSION, backward);
	if (d->make)
		TIFFSetField(t, TIFFTAG_MAKE, d->make);
	if (d->model) {
		TIFFSetField(t, TIFFTAG_MODEL, d->model);
		TIFFSetField(t, TIFFTAG_UNIQUECAMERAMODEL, d->model);
	}
	if (d->serial)
		TIFFSetField(t, TIFFTAG_CAMERASERIALNUMBER, d->serial);
	if (!d->linear_raw) {
		uint16_t dim[2] = {2, 2};
		uint8_t pat[4];
		for (int i = 0; i < 4; i++)
			pat[i] = (uint8_t)cfa_code(d->cfa[i]);
		TIFFSetField(t, TIFFTAG_CFAREPEATPATTERNDIM, dim);
		TIFFSetField(t, TIFFTAG_CFAPATTERN, 4, pat);
	}
	/* BlackLevel is RATIONAL in libtiff's table; the repeat dimensions go first. */
	int nb = d->black_dim == 2 ? 4 : 1;
	uint16_t bdim[2] = {(uint16_t)(nb == 4 ? 2 : 1), (uint16_t)(nb == 4 ? 2 : 1)};
	float black[4];
	for (int i = 0; i < 4; i++)
		black[i] = (float)d->black[i];
	TIFFSetField(t, TIFFTAG_BLACKLEVELREPEATDIM, bdim);
	TIFFSetField(t, TIFFTAG_BLACKLEVEL, nb, black);
	uint32_t white = (uint32_t)d->white;
	TIFFSetField(t, TIFFTAG_WHITELEVEL, 1, &white);
	if (d->iso_ifd0 > 0) {
		/* not a baseline tag of IFD 0 for libtiff: registered for this file */
		static const TIFFFieldInfo iso_field[] = {
			{34855, -1, -1, TIFF_SHORT, FIELD_CUSTOM, 1, 1, "ISOSpeedRatings"}};
		uint16_t iso = (uint16_t)d->iso_ifd0;
		if (TIFFMergeFieldInfo(t, iso_field, 1) || !TIFFSetField(t, 34855, 1, &iso)) {
			TIFFClose(t);
			snprintf(msg, n, "%s: cannot set ISOSpeedRatings in IFD 0", path);
			return -1;
		}
	}
	int exif = d->exposure_s > 0 || d->fnumber > 0 || d->iso > 0 || d->focal_mm > 0 || d->lens;
	if (exif)
		TIFFSetField(t, TIFFTAG_EXIFIFD, (uint64_t)0); /* filled in below */
	size_t row = (size_t)d->width * (size_t)spp;
	for (int y = 0; y < d->height; y++)
		if (TIFFWriteScanline(t, (void *)(d->data + (size_t)y * row), (uint32_t)y, 0) < 0) {
			TIFFClose(t);
			snprintf(msg, n, "%s: cannot write row %d", path, y);
			return -1;
		}
	/* The shooting settings in an EXIF directory, as cameras write them. */
	if (exif) {
		uint64_t exif_offset = 0;
		if (!TIFFWriteDirectory(t) || TIFFCreateEXIFDirectory(t)) {
			TIFFClose(t);
			snprintf(msg, n, "%s: cannot start the EXIF directory", path);
			return -1;
		}
		if (d->exposure_s > 0)
			TIFFSetField(t, EXIFTAG_EXPOSURETIME, d->exposure_s);
		if (d->fnumber > 0)
			TIFFSetField(t, EXIFTAG_FNUMBER, d->fnumber);
		if (d->iso > 0) {
			uint16_t iso = (uint16_t)d->iso;
			TIFFSetField(t, EXIFTAG_ISOSPEEDRATINGS, 1, &iso);
		}
		if (d->focal_mm > 0)
			TIFFSetField(t, EXIFTAG_FOCALLENGTH, d->focal_mm);
		if (d->lens)
			TIFFSetField(t, EXIFTAG_LENSMODEL, d->lens);
		if (!TIFFWriteCustomDirectory(t, &exif_offset) || !TIFFSetDirectory(t, 0) ||
		    !TIFFSetField(t, TIFFTAG_EXIFIFD, exif_offset)) {
			TIFFClose(t);
			snprintf(msg, n, "%s: cannot write the EXIF directory", path);
			return -1;
		}
	}
	TIFFClose(t);
	return 0;
}
