/* icc_decode MASTER.tif CUBE.hdr ILLUMINANT: decodes every pixel of a master through
 * its embedded ICC profile with LittleCMS (relative colorimetric, to CIELAB D50) and
 * compares it with the cube's reflectance rendered under ILLUMINANT (CIE 1931 2
 * degree, Bradford-adapted to D50 when it is another white). Pixels the master
 * clipped (a channel at 0 or 65535) and non-finite ones are left out. Prints
 * "pixels N clipped C mean M p90 P max X" (CIEDE2000); exit 77 without LittleCMS. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "colorimetry.h"
#include "envi.h"
#include "kg_config.h"

#if HAVE_LCMS
#include <lcms2.h>
#include <tiffio.h>

/* an f16 cube ("kogei sample format = ieee-half", data type 12): the bits to a float */
static float from_half(float stored)
{
	unsigned h = (unsigned)stored, ex = (h >> 10) & 31, man = h & 1023;
	float v = ex == 0 ? ldexpf((float)man, -24)
	          : ex == 31 ? (man ? NAN : INFINITY) : ldexpf((float)(man | 1024), (int)ex - 25);
	return h >> 15 ? -v : v;
}

static int cmp(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

int main(int argc, char **argv)
{
	if (argc != 4) {
		fprintf(stderr, "usage: icc_decode MASTER.tif CUBE.hdr ILLUMINANT\n");
		return 2;
	}
	kg_err err = {0};
	kg_envi *e = NULL;
	kg_illuminant *ill = NULL;
	if (kg_envi_open(argv[2], &e, &err) || kg_illuminant_lookup(argv[3], &ill, &err)) {
		fprintf(stderr, "%s\n", err.msg);
		return 1;
	}
	TIFF *t = TIFFOpen(argv[1], "r");
	uint32_t w = 0, h = 0, n = 0;
	void *icc = NULL;
	if (!t || !TIFFGetField(t, TIFFTAG_IMAGEWIDTH, &w) || !TIFFGetField(t, TIFFTAG_IMAGELENGTH, &h) ||
	    !TIFFGetField(t, TIFFTAG_ICCPROFILE, &n, &icc)) {
		fprintf(stderr, "%s: no TIFF with an ICC profile\n", argv[1]);
		return 1;
	}
	if ((int)w != e->meta.samples || (int)h != e->meta.lines || e->meta.bands != KG_NBANDS) {
		fprintf(stderr, "%s: %ux%u, the cube %dx%d with %d bands\n", argv[1], w, h,
		        e->meta.samples, e->meta.lines, e->meta.bands);
		return 1;
	}
	cmsHPROFILE prof = cmsOpenProfileFromMem(icc, n), lab = cmsCreateLab4Profile(NULL);
	cmsHTRANSFORM x = prof ? cmsCreateTransform(prof, TYPE_RGB_16, lab, TYPE_Lab_DBL,
	                                            INTENT_RELATIVE_COLORIMETRIC, 0) : NULL;
	if (!x) {
		fprintf(stderr, "%s: LittleCMS cannot use the embedded profile\n", argv[1]);
		return 1;
	}
	const char *fmt = kg_envi_get(e, "kogei sample format");
	int half = fmt && !strcmp(fmt, "ieee-half");
	kg_xyz white = kg_illuminant_white(ill), d50 = {96.42, 100, 82.49};
	uint16_t *px = malloc(sizeof(uint16_t) * 3 * w);
	cmsCIELab *got = malloc(sizeof(cmsCIELab) * w);
	float *s = malloc(sizeof(float) * w * KG_NBANDS);
	double *de = malloc(sizeof(double) * (size_t)w * h);
	size_t nde = 0;
	long clipped = 0;
	for (uint32_t y = 0; y < h; y++) {
		if (TIFFReadScanline(t, px, y, 0) != 1 ||
		    kg_envi_read(e, 0, (int)y, (int)w, 1, KG_LAYOUT_BIP, s, &err)) {
			fprintf(stderr, "%s: row %u unreadable %s\n", argv[1], y, err.msg);
			return 1;
		}
		cmsDoTransform(x, px, got, w);
		for (uint32_t i = 0; i < w; i++) {
			kg_spectrum r;
			int finite = 1, cl = 0;
			for (int b = 0; b < KG_NBANDS; b++)
				finite &= isfinite(r.v[b] = half ? from_half(s[(size_t)i * KG_NBANDS + b])
				                                 : s[(size_t)i * KG_NBANDS + b]);
			for (int c = 0; c < 3; c++)
				cl |= px[3 * i + c] == 0 || px[3 * i + c] == 65535;
			clipped += cl;
			if (!finite || cl)
				continue;
			kg_xyz c = kg_bradford_adapt(kg_reflectance_to_xyz(&r, ill), white, d50);
			kg_lab truth = kg_xyz_to_lab(c, d50);
			de[nde++] = kg_ciede2000(truth, (kg_lab){got[i].L, got[i].a, got[i].b});
		}
	}
	double sum = 0;
	for (size_t i = 0; i < nde; i++)
		sum += de[i];
	qsort(de, nde, sizeof(double), cmp);
	printf("pixels %zu clipped %ld mean %.5f p90 %.5f max %.5f\n", nde, clipped,
	       nde ? sum / nde : NAN, nde ? de[(size_t)(0.9 * (nde - 1))] : NAN,
	       nde ? de[nde - 1] : NAN);
	cmsDeleteTransform(x);
	cmsCloseProfile(prof);
	cmsCloseProfile(lab);
	TIFFClose(t);
	kg_envi_close(&e);
	kg_illuminant_free(&ill);
	free(px);
	free(got);
	free(s);
	free(de);
	return nde ? 0 : 1;
}
#else
int main(void)
{
	printf("built without LittleCMS: skipped\n");
	return 77;
}
#endif
