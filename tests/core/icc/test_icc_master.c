/* The master (core/icc.c): a reflectance cube of known spectra rendered into each
 * working space, then decoded through the profile embedded in master.tif by
 * LittleCMS's own transforms and compared with the spectra's CIELAB under D50 (the
 * truth, from core/colorimetry.c): CIEDE2000 within 0.05 (16-bit quantisation and
 * the profile's s15Fixed16 matrix give about 0.001; a wrong primary, white or tone
 * curve gives whole units). Also: the TRC of each space checked on a neutral of
 * known Y against its specification's formula, NaN written as black, the ICC tag
 * present. The linear float master beside it: flat spectra r (above 1 too) read back
 * as r, r, r, a colour decoded through its linear profile within 0.01; the highlight
 * counts and map of a cube with known bright pixels. Skips (77) without LittleCMS. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "colorimetry.h"
#include "envi.h"
#include "icc.h"
#include "kg_test.h"

#if HAVE_LCMS
#include <lcms2.h>
#include <tiffio.h>

#define W 8
#define H 3

/* pixel i: a smooth spectrum, moderately saturated (inside every space's gamut) */
static double refl(int i, int b)
{
	double wl = 400 + 5 * b;
	if (i == 0)
		return 0.9;  /* near white */
	if (i == 1)
		return 0.18; /* mid grey */
	if (i == 2)
		return NAN;  /* no estimate */
	double c = 420 + 37.0 * (i - 3), s = 40 + 3 * i;
	double g = exp(-0.5 * (wl - c) * (wl - c) / (s * s));
	return 0.1 + 0.3 * g + 0.001 * (i % 5) * (wl - 400) / 3;
}

static double trc_encode(kg_icc_space s, double Y)
{
	switch (s) {
	case KG_ICC_ECIRGB_V2: /* L* / 100 */
		return Y > 216.0 / 24389.0 ? 1.16 * cbrt(Y) - 0.16 : Y * 24389.0 / 2700.0;
	case KG_ICC_ADOBE_RGB:
		return pow(Y, 256.0 / 563.0);
	default:
		return pow(Y, 1 / 1.8);
	}
}

/* The linear master and the highlight counts, on a 4 x 2 cube of known spectra under
 * D50: flat 1.5 (lit), 0.9, 1.2, 2.0 (not lit: not counted), NaN (no estimate), 0.5
 * with the 400 nm band at 1.3, a moderate colour, 0.18. A flat spectrum r has Y = r
 * and, in a space whose white is 1, 1, 1, linear RGB r, r, r: the truth. */
static double refl2(int i, int b)
{
	static const double flat[8] = {1.5, 0.9, 1.2, 2.0, NAN, 0.5, -1, 0.18};
	if (i == 5 && b == 0)
		return 1.3;
	return i == 6 ? refl(4, b) : flat[i];
}

static void linear_master(const char *dir, const kg_illuminant *d50, cmsHPROFILE lab)
{
	enum { W2 = 4, H2 = 2 };
	char cube[512], tif[512], ltif[512];
	snprintf(cube, sizeof(cube), "%s/icc_master_bright.hdr", dir);
	float data[W2 * H2 * KG_NBANDS];
	double wl[KG_NBANDS];
	for (int b = 0; b < KG_NBANDS; b++)
		wl[b] = 400 + 5 * b;
	for (int i = 0; i < W2 * H2; i++)
		for (int b = 0; b < KG_NBANDS; b++)
			data[i * KG_NBANDS + b] = (float)refl2(i, b);
	kg_envi_meta m = {.samples = W2, .lines = H2, .bands = KG_NBANDS, .data_type = KG_ENVI_F32,
	                  .interleave = KG_ENVI_BIP, .wavelength = wl};
	kg_err err = {{0}};
	CHECK(kg_envi_write(cube, &m, KG_LAYOUT_BIP, data, &err) == 0, "%s", err.msg);
	unsigned char lit = 0xff & ~(1u << 3); /* pixel 3 not lit */
	kg_xyz white = kg_illuminant_white(d50);
	const kg_icc_space spaces[] = {KG_ICC_ECIRGB_V2, KG_ICC_ADOBE_RGB, KG_ICC_PROPHOTO};
	for (size_t si = 0; si < 3; si++) {
		kg_icc_space s = spaces[si];
		snprintf(tif, sizeof(tif), "%s/icc_bright_%s.tif", dir, kg_icc_space_name(s));
		snprintf(ltif, sizeof(ltif), "%s/icc_bright_%s_linear.tif", dir, kg_icc_space_name(s));
		kg_master_extra x = {.linear_path = ltif, .map_max_side = 100};
		CHECK(kg_master_write(cube, d50, s, KG_ICC_V2, tif, &lit, NULL, &x, &err) == 0, "%s",
		      err.msg);
		const kg_master_stats *st = &x.stats;
		CHECK(st->counted == 6 && st->above_white == 2 && st->above_clipped == 2 &&
		      st->band_above_one == 3 && st->clipped_top == 2 && st->clipped_low == 0,
		      "%s: counted %ld, above white %ld (clipped %ld), a band above 1 %ld, clipped "
		      "at the top %ld, outside the space %ld: expected 6, 2 (2), 3, 2, 0",
		      kg_icc_space_name(s), st->counted, st->above_white, st->above_clipped,
		      st->band_above_one, st->clipped_top, st->clipped_low);
		CHECK_NEAR(st->max_y, 1.5, 1e-6, "largest Y of the lit pixels");
		CHECK_NEAR(st->max_reflectance, 1.5, 1e-6, "largest band of the lit pixels");
		/* the map: 1:1, the bright pixels red, the others grey (Y, sRGB-encoded) */
		CHECK(x.map && x.map_w == W2 && x.map_h == H2, "map %dx%d", x.map_w, x.map_h);
		if (x.map) {
			const unsigned char red[3] = {KG_MASTER_MAP_ABOVE};
			CHECK(!memcmp(x.map, red, 3) && !memcmp(x.map + 6, red, 3), "bright pixels "
			      "not red in the map");
			int g = (int)lround(255 * (1.055 * pow(0.9, 1 / 2.4) - 0.055));
			CHECK(abs(x.map[3] - g) <= 1 && x.map[3] == x.map[4] && x.map[4] == x.map[5],
			      "pixel 1 in the map: %d %d %d, expected grey %d", x.map[3], x.map[4],
			      x.map[5], g);
			CHECK(x.map[9] == 255 && x.map[10] == 255, "the unlit bright pixel is grey "
			      "(white) in the map, not marked");
			/* the counted pixels: all but 3 (unlit) and 4 (NaN): the whole map */
			CHECK(x.box[0] == 0 && x.box[1] == 0 && x.box[2] == W2 && x.box[3] == H2,
			      "box %d %d %d %d", x.box[0], x.box[1], x.box[2], x.box[3]);
		}
		free(x.map);
		/* the float master read back with libtiff */
		TIFF *t = TIFFOpen(ltif, "r");
		CHECK(t != NULL, "%s: cannot open", ltif);
		if (!t)
			continue;
		uint32_t w = 0, h = 0, icc_len = 0;
		uint16_t bps = 0, spp = 0, fmt = 0, pred = 0;
		void *icc = NULL;
		TIFFGetField(t, TIFFTAG_IMAGEWIDTH, &w);
		TIFFGetField(t, TIFFTAG_IMAGELENGTH, &h);
		TIFFGetField(t, TIFFTAG_BITSPERSAMPLE, &bps);
		TIFFGetField(t, TIFFTAG_SAMPLESPERPIXEL, &spp);
		TIFFGetField(t, TIFFTAG_SAMPLEFORMAT, &fmt);
		TIFFGetField(t, TIFFTAG_PREDICTOR, &pred);
		CHECK(w == W2 && h == H2 && bps == 32 && spp == 3 && fmt == SAMPLEFORMAT_IEEEFP &&
		      pred == PREDICTOR_FLOATINGPOINT, "%s: %ux%u, %u bits, %u samples, format %u, "
		      "predictor %u", ltif, w, h, bps, spp, fmt, pred);
		int has_icc = TIFFGetField(t, TIFFTAG_ICCPROFILE, &icc_len, &icc);
		cmsHPROFILE prof = has_icc ? cmsOpenProfileFromMem(icc, icc_len) : NULL;
		CHECK(prof != NULL, "%s: no embedded profile LittleCMS opens", ltif);
		char desc[160] = "";
		if (prof)
			cmsGetProfileInfoASCII(prof, cmsInfoDescription, "en", "US", desc, sizeof(desc));
		CHECK(strstr(desc, kg_icc_space_description(s)) && strstr(desc, "linear"),
		      "%s: profile '%s'", ltif, desc);
		cmsHTRANSFORM xf = prof ? cmsCreateTransform(prof, TYPE_RGB_FLT, lab, TYPE_Lab_DBL,
		                                             INTENT_RELATIVE_COLORIMETRIC, 0)
		                        : NULL;
		float px[W2 * 3], first[3] = {0, 0, 0};
		for (uint32_t y = 0; w == W2 && y < h; y++) {
			CHECK(TIFFReadScanline(t, px, y, 0) == 1, "%s: row %u", ltif, y);
			if (y == 0)
				memcpy(first, px, sizeof(first));
			for (int xx = 0; xx < W2; xx++) {
				int i = (int)y * W2 + xx;
				double r = refl2(i, 30);
				if (i == 4) {
					CHECK(px[3 * xx] == 0 && px[3 * xx + 1] == 0 && px[3 * xx + 2] == 0,
					      "%s: NaN pixel not 0", ltif);
				} else if (i != 5 && i != 6) { /* flat: r, r, r, above 1 kept */
					for (int c = 0; c < 3; c++)
						CHECK(fabs(px[3 * xx + c] - r) < 1e-3 * (r > 1 ? r : 1),
						      "%s: pixel %d channel %d: %.5f, expected %.3f", ltif, i, c,
						      px[3 * xx + c], r);
				} else if (xf) { /* decoded through the profile: the truth */
					kg_spectrum sp;
					for (int b = 0; b < KG_NBANDS; b++)
						sp.v[b] = refl2(i, b);
					kg_lab truth = kg_xyz_to_lab(kg_reflectance_to_xyz(&sp, d50), white);
					cmsCIELab got;
					cmsDoTransform(xf, px + 3 * xx, &got, 1);
					kg_lab dec = {got.L, got.a, got.b};
					double de = kg_ciede2000(truth, dec);
					CHECK(de < 0.01, "%s: pixel %d decoded dE00 %.4f", ltif, i, de);
				}
			}
		}
		printf("%s linear: pixel 0 %.5f %.5f %.5f (flat 1.5)\n", kg_icc_space_name(s),
		       first[0], first[1], first[2]);
		if (xf)
			cmsDeleteTransform(xf);
		if (prof)
			cmsCloseProfile(prof);
		TIFFClose(t);
	}
}

int main(int argc, char **argv)
{
	const char *dir = argc > 1 ? argv[1] : ".";
	char cube[512], tif[512];
	snprintf(cube, sizeof(cube), "%s/icc_master_cube.hdr", dir);
	kg_err err = {0};
	float *data = malloc(sizeof(float) * W * H * KG_NBANDS);
	double wl[KG_NBANDS];
	for (int b = 0; b < KG_NBANDS; b++)
		wl[b] = 400 + 5 * b;
	for (int i = 0; i < W * H; i++)
		for (int b = 0; b < KG_NBANDS; b++)
			data[(size_t)i * KG_NBANDS + b] = (float)refl(i, b);
	kg_envi_meta m = {.samples = W, .lines = H, .bands = KG_NBANDS, .data_type = KG_ENVI_F32,
	                  .interleave = KG_ENVI_BIP, .wavelength = wl};
	CHECK(kg_envi_write(cube, &m, KG_LAYOUT_BIP, data, &err) == 0, "%s", err.msg);
	kg_illuminant *d50 = NULL;
	CHECK(kg_illuminant_by_name("D50", &d50, &err) == 0, "%s", err.msg);
	kg_xyz white = kg_illuminant_white(d50);
	cmsHPROFILE lab = cmsCreateLab4Profile(NULL);
	const kg_icc_space spaces[] = {KG_ICC_ECIRGB_V2, KG_ICC_ADOBE_RGB, KG_ICC_PROPHOTO};
	double worst = 0;
	for (size_t si = 0; si < 6; si++) {
		kg_icc_space s = spaces[si % 3];
		kg_icc_version v = si < 3 ? KG_ICC_V2 : KG_ICC_V4;
		snprintf(tif, sizeof(tif), "%s/icc_master_%s_v%d.tif", dir, kg_icc_space_name(s),
		         (int)v);
		kg_master_extra mx = {0};
		CHECK(kg_master_write(cube, d50, s, v, tif, NULL, NULL, &mx, &err) == 0, "%s",
		      err.msg);
		CHECK(mx.stats.clipped == 0, "%s: %ld pixels clipped", tif, mx.stats.clipped);
		TIFF *t = TIFFOpen(tif, "r");
		CHECK(t != NULL, "%s: cannot open", tif);
		if (!t)
			continue;
		uint32_t w = 0, h = 0, icc_len = 0;
		uint16_t bps = 0, spp = 0;
		void *icc = NULL;
		TIFFGetField(t, TIFFTAG_IMAGEWIDTH, &w);
		TIFFGetField(t, TIFFTAG_IMAGELENGTH, &h);
		TIFFGetField(t, TIFFTAG_BITSPERSAMPLE, &bps);
		TIFFGetField(t, TIFFTAG_SAMPLESPERPIXEL, &spp);
		int has_icc = TIFFGetField(t, TIFFTAG_ICCPROFILE, &icc_len, &icc);
		CHECK(w == W && h == H && bps == 16 && spp == 3, "%s: %ux%u, %u bits, %u samples", tif,
		      w, h, bps, spp);
		CHECK(has_icc && icc_len > 128, "%s: no ICC profile", tif);
		cmsHPROFILE prof = has_icc ? cmsOpenProfileFromMem(icc, icc_len) : NULL;
		CHECK(prof != NULL, "%s: LittleCMS cannot open the embedded profile", tif);
		double pv = prof ? cmsGetProfileVersion(prof) : 0;
		CHECK(v == KG_ICC_V2 ? pv >= 2 && pv < 3 : pv >= 4 && pv < 5,
		      "%s: profile version %.2f, expected %d", tif, pv, (int)v);
		char desc[128] = "";
		if (prof)
			cmsGetProfileInfoASCII(prof, cmsInfoDescription, "en", "US", desc, sizeof(desc));
		CHECK(strstr(desc, s == KG_ICC_ECIRGB_V2 ? "eciRGB v2" : s == KG_ICC_ADOBE_RGB
		                                                      ? "Adobe RGB" : "ProPhoto"),
		      "%s: description '%s'", tif, desc);
		cmsHTRANSFORM x = prof ? cmsCreateTransform(prof, TYPE_RGB_16, lab, TYPE_Lab_DBL,
		                                            INTENT_RELATIVE_COLORIMETRIC, 0)
		                       : NULL;
		CHECK(x != NULL || !prof, "%s: no transform", tif);
		uint16_t px[W * 3];
		double worst_s = 0;
		for (uint32_t y = 0; x && y < h && y < H; y++) {
			CHECK(TIFFReadScanline(t, px, y, 0) == 1, "%s: row %u", tif, y);
			cmsCIELab got[W];
			cmsDoTransform(x, px, got, W);
			for (int xx = 0; xx < W; xx++) {
				int i = (int)y * W + xx;
				if (i == 2) {
					CHECK(px[3 * xx] == 0 && px[3 * xx + 1] == 0 && px[3 * xx + 2] == 0,
					      "%s: NaN pixel not black", tif);
					continue;
				}
				kg_spectrum r;
				for (int b = 0; b < KG_NBANDS; b++)
					r.v[b] = refl(i, b);
				kg_lab truth = kg_xyz_to_lab(kg_reflectance_to_xyz(&r, d50), white);
				kg_lab dec = {got[xx].L, got[xx].a, got[xx].b};
				double de = kg_ciede2000(truth, dec);
				if (de > worst_s)
					worst_s = de;
				/* v4 holds the spaces' exact curves; v2 a table (eciRGB v2's L*) or an
				 * 8.8 gamma (ProPhoto's 1.8 as 461/256) */
				CHECK(de < (v == KG_ICC_V2 ? 0.1 : 0.05),
				      "%s: pixel %d: truth L %.3f a %.3f b %.3f, decoded L %.3f "
				      "a %.3f b %.3f: dE00 %.4f", tif, i, truth.L, truth.a, truth.b, dec.L,
				      dec.a, dec.b, de);
				if (i == 1) /* neutral, Y = 0.18: every channel the space's TRC of it */
					for (int ch = 0; ch < 3; ch++)
						CHECK_NEAR(px[3 * xx + ch] / 65535.0, trc_encode(s, 0.18),
						           v == KG_ICC_V2 ? 1e-3 : 2e-4, "mid-grey code value");
			}
		}
		printf("%s v%d: worst dE00 %.5f\n", kg_icc_space_name(s), (int)v, worst_s);
		if (worst_s > worst)
			worst = worst_s;
		if (x)
			cmsDeleteTransform(x);
		if (prof)
			cmsCloseProfile(prof);
		TIFFClose(t);
	}
	printf("worst dE00 over the spaces: %.5f\n", worst);
	/* a cube off the grid is refused, naming the file, and nothing is written */
	snprintf(tif, sizeof(tif), "%s/icc_master_bad.tif", dir);
	remove(tif);
	wl[3] = 416;
	snprintf(cube, sizeof(cube), "%s/icc_master_cube_off.hdr", dir);
	CHECK(kg_envi_write(cube, &m, KG_LAYOUT_BIP, data, &err) == 0, "%s", err.msg);
	CHECK(kg_master_write(cube, d50, KG_ICC_ECIRGB_V2, KG_ICC_V2, tif, NULL, NULL, NULL, &err) ==
	          KG_EINVAL,
	      "off-grid cube accepted");
	CHECK(strstr(err.msg, "icc_master_cube") && strstr(err.msg, "expected"), "message: %s",
	      err.msg);
	struct stat st;
	CHECK(stat(tif, &st) != 0, "%s written after a refusal", tif);
	kg_icc_space sp;
	CHECK(kg_icc_space_parse("srgb", &sp, &err) == KG_EINVAL && strstr(err.msg, "ecirgb-v2"),
	      "unknown space: %s", err.msg);
	linear_master(dir, d50, lab);
	cmsCloseProfile(lab);
	kg_illuminant_free(&d50);
	free(data);
	return kg_test_done("icc_master");
}
#else
int main(void)
{
	printf("built without LittleCMS (-Dlcms): skipped\n");
	return 77;
}
#endif
