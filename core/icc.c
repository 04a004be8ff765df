/* Colour-managed outputs with LittleCMS: working-space profiles and the master TIFF. */
#include "icc.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include "envi.h"
#include "fsutil.h"
#include "kg_config.h"

static const struct {
	kg_icc_space s;
	const char *name, *desc;
} spaces[] = {
	{KG_ICC_ECIRGB_V2, "ecirgb-v2", "eciRGB v2"},
	{KG_ICC_ADOBE_RGB, "adobe-rgb", "Adobe RGB (1998) compatible"},
	{KG_ICC_PROPHOTO, "prophoto", "ProPhoto RGB (ROMM RGB) compatible"},
	{KG_ICC_NONE, "none", "none"},
};

int kg_icc_space_parse(const char *name, kg_icc_space *out, kg_err *err)
{
	for (size_t i = 0; name && i < sizeof(spaces) / sizeof(spaces[0]); i++)
		if (strcasecmp(name, spaces[i].name) == 0) {
			*out = spaces[i].s;
			return 0;
		}
	return kg_fail(err, KG_EINVAL, "master space '%s': expected ecirgb-v2, adobe-rgb, "
	               "prophoto or none", name ? name : "");
}

int kg_icc_version_parse(const char *name, kg_icc_version *out, kg_err *err)
{
	if (name && (!strcasecmp(name, "2") || !strcasecmp(name, "v2"))) {
		*out = KG_ICC_V2;
		return 0;
	}
	if (name && (!strcasecmp(name, "4") || !strcasecmp(name, "v4"))) {
		*out = KG_ICC_V4;
		return 0;
	}
	return kg_fail(err, KG_EINVAL, "ICC version '%s': expected 2 or 4", name ? name : "");
}

const char *kg_icc_space_name(kg_icc_space s)
{
	for (size_t i = 0; i < sizeof(spaces) / sizeof(spaces[0]); i++)
		if (spaces[i].s == s)
			return spaces[i].name;
	return "none";
}

const char *kg_icc_space_description(kg_icc_space s)
{
	for (size_t i = 0; i < sizeof(spaces) / sizeof(spaces[0]); i++)
		if (spaces[i].s == s)
			return spaces[i].desc;
	return "none";
}

int kg_icc_camera_matrix(const double (*rgb)[3], const double (*xyz)[3], int n, int skip,
                         double M[9], kg_err *err)
{
	if (n - (skip >= 0 && skip < n) < 3)
		return kg_fail(err, KG_EINVAL, "camera profile: %d patches, expected at least 3",
		               n - (skip >= 0 && skip < n));
	/* normal equations: (R^T R) M^T = R^T X */
	double A[9] = {0}, Bm[9] = {0};
	for (int i = 0; i < n; i++)
		for (int r = 0; i != skip && r < 3; r++)
			for (int c = 0; c < 3; c++) {
				A[3 * r + c] += rgb[i][r] * rgb[i][c];
				Bm[3 * r + c] += rgb[i][r] * xyz[i][c];
			}
	double det = A[0] * (A[4] * A[8] - A[5] * A[7]) - A[1] * (A[3] * A[8] - A[5] * A[6]) +
	             A[2] * (A[3] * A[7] - A[4] * A[6]);
	if (!(fabs(det) > 1e-14))
		return kg_fail(err, KG_EINVAL, "camera profile: the patches' camera values are "
		               "collinear: expected three independent colours");
	double inv[9] = {
		(A[4] * A[8] - A[5] * A[7]) / det, (A[2] * A[7] - A[1] * A[8]) / det,
		(A[1] * A[5] - A[2] * A[4]) / det, (A[5] * A[6] - A[3] * A[8]) / det,
		(A[0] * A[8] - A[2] * A[6]) / det, (A[2] * A[3] - A[0] * A[5]) / det,
		(A[3] * A[7] - A[4] * A[6]) / det, (A[1] * A[6] - A[0] * A[7]) / det,
		(A[0] * A[4] - A[1] * A[3]) / det,
	};
	/* xyz = M rgb: M[3 * out + in] = (inv Bm)[3 * in + out] */
	for (int in = 0; in < 3; in++)
		for (int out = 0; out < 3; out++) {
			double v = 0;
			for (int k = 0; k < 3; k++)
				v += inv[3 * in + k] * Bm[3 * k + out];
			M[3 * out + in] = v;
		}
	return 0;
}

#if HAVE_LCMS
#include <lcms2.h>
#include <tiffio.h>

int kg_icc_available(void)
{
	return 1;
}

/* The space's profile (NULL for none or when LittleCMS fails). */
static cmsHPROFILE space_profile(kg_icc_space s, kg_icc_version v)
{
	cmsCIExyY white;
	cmsCIExyYTRIPLE prim;
	cmsToneCurve *curve = NULL;
	switch (s) {
	case KG_ICC_ECIRGB_V2: {
		/* the CIE L* curve, device -> linear: Y = ((v + 0.16) / 1.16)^3 above
		 * v = 0.08, v / 9.033 below (kappa = 24389 / 27 / 100) */
		double par[5] = {3.0, 1.0 / 1.16, 0.16 / 1.16, 2700.0 / 24389.0, 0.08};
		white = *cmsD50_xyY();
		prim = (cmsCIExyYTRIPLE){{0.67, 0.33, 1}, {0.21, 0.71, 1}, {0.14, 0.08, 1}};
		curve = cmsBuildParametricToneCurve(NULL, 4, par);
		break;
	}
	case KG_ICC_ADOBE_RGB:
		white = (cmsCIExyY){0.3127, 0.3290, 1};
		prim = (cmsCIExyYTRIPLE){{0.64, 0.33, 1}, {0.21, 0.71, 1}, {0.15, 0.06, 1}};
		curve = cmsBuildGamma(NULL, 563.0 / 256.0);
		break;
	case KG_ICC_PROPHOTO:
		white = *cmsD50_xyY();
		prim = (cmsCIExyYTRIPLE){{0.7347, 0.2653, 1}, {0.1596, 0.8404, 1}, {0.0366, 0.0001, 1}};
		curve = cmsBuildGamma(NULL, 1.8);
		break;
	default:
		return NULL;
	}
	if (!curve)
		return NULL;
	cmsToneCurve *curves[3] = {curve, curve, curve};
	cmsHPROFILE h = cmsCreateRGBProfile(&white, &prim, curves);
	cmsFreeToneCurve(curve);
	if (!h)
		return NULL;
	cmsSetProfileVersion(h, v == KG_ICC_V4 ? 4.3 : 2.4);
	cmsMLU *desc = cmsMLUalloc(NULL, 1), *cprt = cmsMLUalloc(NULL, 1);
	int ok = desc && cprt && cmsMLUsetASCII(desc, "en", "US", kg_icc_space_description(s)) &&
	         cmsMLUsetASCII(cprt, "en", "US", "No copyright, use freely") &&
	         cmsWriteTag(h, cmsSigProfileDescriptionTag, desc) &&
	         cmsWriteTag(h, cmsSigCopyrightTag, cprt);
	cmsMLUfree(desc);
	cmsMLUfree(cprt);
	if (!ok) {
		cmsCloseProfile(h);
		return NULL;
	}
	return h;
}

int kg_icc_profile_bytes(kg_icc_space s, kg_icc_version v, unsigned char **buf, size_t *len,
                         kg_err *err)
{
	*buf = NULL;
	*len = 0;
	cmsHPROFILE h = space_profile(s, v);
	cmsUInt32Number n = 0;
	if (!h || !cmsSaveProfileToMem(h, NULL, &n) || n == 0 || !(*buf = malloc(n)) ||
	    !cmsSaveProfileToMem(h, *buf, &n)) {
		if (h)
			cmsCloseProfile(h);
		free(*buf);
		*buf = NULL;
		return kg_fail(err, KG_EIO, "LittleCMS: cannot build the %s profile",
		               kg_icc_space_description(s));
	}
	cmsCloseProfile(h);
	*len = n;
	return 0;
}

/* IEEE binary16 bits to a float (kogei's f16 cubes: "kogei sample format = ieee-half",
 * stored as data type 12, which kg_envi_read gives as the integer 0..65535). */
static float half_to_float(float stored)
{
	unsigned h = (unsigned)stored;
	unsigned sign = h >> 15, ex = (h >> 10) & 31, man = h & 1023;
	float v;
	if (ex == 0)
		v = ldexpf((float)man, -24);
	else if (ex == 31)
		v = man ? NAN : INFINITY;
	else
		v = ldexpf((float)(man | 1024), (int)ex - 25);
	return sign ? -v : v;
}

int kg_master_write(const char *cube, const kg_illuminant *ill, kg_icc_space space,
                    kg_icc_version ver, const char *path, const unsigned char *lit,
                    long *clipped, kg_err *err)
{
	kg_envi *e = NULL;
	cmsHPROFILE xyz = NULL, rgb = NULL;
	cmsHTRANSFORM t = NULL;
	unsigned char *icc = NULL;
	size_t icc_len = 0;
	float *band = NULL;
	double *xyzrow = NULL, *out = NULL;
	uint16_t *row = NULL;
	TIFF *tif = NULL;
	kg_outfile o;
	int have_out = 0;
	long nclip = 0;
	int ret = kg_envi_open(cube, &e, err);
	if (ret)
		return ret;
	const kg_envi_meta *m = &e->meta;
	const char *fmt = kg_envi_get(e, "kogei sample format");
	int half = fmt && !strcmp(fmt, "ieee-half") && m->data_type == KG_ENVI_U16;
	if (m->bands != KG_NBANDS || !m->wavelength)
		ret = kg_fail(err, KG_EINVAL, "%s: %d bands: expected the %d-band grid (400-700 nm "
		              "at 5 nm) with its wavelengths", cube, m->bands, KG_NBANDS);
	for (int b = 0; !ret && b < KG_NBANDS; b++)
		if (fabs(m->wavelength[b] - (400.0 + 5.0 * b)) > 0.01)
			ret = kg_fail(err, KG_EINVAL, "%s: band %d at %g nm: expected %g nm", cube,
			              b + 1, m->wavelength[b], 400.0 + 5.0 * b);
	if (!ret)
		ret = kg_icc_profile_bytes(space, ver, &icc, &icc_len, err);
	if (!ret) {
		/* encoded through the profile it embeds, so a reader decodes what was meant
		 * within that profile's precision: a v2 profile holds eciRGB v2's L* curve as
		 * a 4096-entry table and ProPhoto's gamma 1.8 as 461/256, whose decoded
		 * colours differ from the exact curves' by up to about 0.07 CIEDE2000 */
		xyz = cmsCreateXYZProfile();
		rgb = cmsOpenProfileFromMem(icc, (cmsUInt32Number)icc_len);
		t = xyz && rgb ? cmsCreateTransform(xyz, TYPE_XYZ_DBL, rgb, TYPE_RGB_DBL,
		                                    INTENT_RELATIVE_COLORIMETRIC, cmsFLAGS_NOCACHE |
		                                    cmsFLAGS_NOOPTIMIZE)
		               : NULL;
		if (!t)
			ret = kg_fail(err, KG_EIO, "LittleCMS: cannot build the XYZ to %s transform",
			              kg_icc_space_description(space));
	}
	const int W = m->samples, H = m->lines;
	const int rows = 16;
	if (!ret) {
		band = malloc(sizeof(float) * (size_t)W * rows * KG_NBANDS);
		xyzrow = malloc(sizeof(double) * 3 * (size_t)W);
		row = malloc(sizeof(uint16_t) * 3 * (size_t)W);
		out = malloc(sizeof(double) * 3 * (size_t)W);
		if (!band || !xyzrow || !row || !out)
			ret = kg_fail(err, KG_ENOMEM, "out of memory");
	}
	if (!ret && !(ret = kg_outfile_open(&o, path, 0, err))) {
		have_out = 1;
		int fd = dup(fileno(o.fp));
		tif = fd < 0 ? NULL : TIFFFdOpen(fd, path, "w");
		if (!tif) {
			if (fd >= 0)
				close(fd);
			ret = kg_fail(err, KG_EIO, "%s: cannot start TIFF", path);
		}
	}
	if (!ret && !(TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, (uint32_t)W) &&
	              TIFFSetField(tif, TIFFTAG_IMAGELENGTH, (uint32_t)H) &&
	              TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, (uint16_t)3) &&
	              TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, (uint16_t)16) &&
	              TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, SAMPLEFORMAT_UINT) &&
	              TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_RGB) &&
	              TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG) &&
	              TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_ADOBE_DEFLATE) &&
	              TIFFSetField(tif, TIFFTAG_PREDICTOR, PREDICTOR_HORIZONTAL) &&
	              TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, TIFFDefaultStripSize(tif, 0)) &&
	              TIFFSetField(tif, TIFFTAG_SOFTWARE, "kogei " KG_VERSION) &&
	              TIFFSetField(tif, TIFFTAG_ICCPROFILE, (uint32_t)icc_len, icc)))
		ret = kg_fail(err, KG_EIO, "%s: cannot set the TIFF tags", path);
	kg_xyz_weights wts;
	/* the ICC D50 (ICC.1:2010, 0.9642, 1, 0.8249): what the profile connection space
	 * calls white; the illuminant's own white (on kogei's grid) is adapted to it */
	kg_xyz white = {0, 0, 0}, d50 = {96.42, 100.0, 82.49};
	if (!ret) {
		kg_xyz_weights_reflectance(ill, &wts);
		white = kg_illuminant_white(ill);
	}
	for (int y0 = 0; !ret && y0 < H; y0 += rows) {
		int h = H - y0 < rows ? H - y0 : rows;
		ret = kg_envi_read(e, 0, y0, W, h, KG_LAYOUT_BIP, band, err);
		for (size_t i = 0; half && !ret && i < (size_t)W * h * KG_NBANDS; i++)
			band[i] = half_to_float(band[i]);
		for (int yr = 0; !ret && yr < h; yr++) {
			for (int x = 0; x < W; x++) {
				const float *s = band + ((size_t)yr * W + x) * KG_NBANDS;
				kg_xyz c = {0, 0, 0};
				int finite = 1;
				for (int b = 0; b < KG_NBANDS; b++) {
					if (!isfinite(s[b])) {
						finite = 0;
						break;
					}
					c.X += wts.w[0][b] * s[b];
					c.Y += wts.w[1][b] * s[b];
					c.Z += wts.w[2][b] * s[b];
				}
				if (!finite)
					c = (kg_xyz){0, 0, 0};
				else
					c = kg_bradford_adapt(c, white, d50);
				/* the ICC connection space: the white at Y = 1, D50 */
				xyzrow[3 * x] = c.X / 100.0;
				xyzrow[3 * x + 1] = c.Y / 100.0;
				xyzrow[3 * x + 2] = c.Z / 100.0;
			}
			cmsDoTransform(t, xyzrow, out, (cmsUInt32Number)W);
			for (int x = 0; x < W; x++) {
				int cl = 0;
				for (int ch = 0; ch < 3; ch++) {
					double v = out[3 * x + ch];
					if (!(v >= 0)) {
						cl |= v < 0;
						v = 0;
					} else if (v > 1) {
						cl = 1;
						v = 1;
					}
					row[3 * x + ch] = (uint16_t)lround(v * 65535.0);
				}
				size_t i = (size_t)(y0 + yr) * (size_t)W + (size_t)x;
				if (cl && (!lit || (lit[i / 8] >> (i % 8) & 1)))
					nclip++;
			}
			if (TIFFWriteScanline(tif, row, (uint32_t)(y0 + yr), 0) != 1)
				ret = kg_fail(err, KG_EIO, "%s: cannot write TIFF", path);
		}
	}
	if (tif) {
		if (!ret && !TIFFFlush(tif))
			ret = kg_fail(err, KG_EIO, "%s: cannot write TIFF", path);
		TIFFClose(tif);
	}
	if (have_out) {
		if (ret)
			kg_outfile_abort(&o);
		else
			ret = kg_outfile_commit(&o, err);
	}
	if (t)
		cmsDeleteTransform(t);
	if (xyz)
		cmsCloseProfile(xyz);
	if (rgb)
		cmsCloseProfile(rgb);
	free(icc);
	free(band);
	free(xyzrow);
	free(out);
	free(row);
	kg_envi_close(&e);
	if (clipped)
		*clipped = nclip;
	return ret;
}

int kg_icc_camera_profile(const double (*rgb)[3], const double (*xyz)[3], int n,
                          const char *description, kg_icc_version ver, double m[9],
                          unsigned char **buf, size_t *len, kg_err *err)
{
	*buf = NULL;
	*len = 0;
	double M[9];
	int ret = kg_icc_camera_matrix(rgb, xyz, n, -1, M, err);
	if (ret)
		return ret;
	if (m)
		memcpy(m, M, sizeof(M));
	cmsHPROFILE h = cmsCreateProfilePlaceholder(NULL);
	cmsToneCurve *lin = cmsBuildGamma(NULL, 1.0);
	int ok = h && lin;
	if (ok) {
		cmsSetProfileVersion(h, ver == KG_ICC_V4 ? 4.3 : 2.4);
		cmsSetDeviceClass(h, cmsSigInputClass);
		cmsSetColorSpace(h, cmsSigRgbData);
		cmsSetPCS(h, cmsSigXYZData);
		cmsSetHeaderRenderingIntent(h, INTENT_RELATIVE_COLORIMETRIC);
		cmsCIEXYZ col[3];
		for (int c = 0; c < 3; c++)
			col[c] = (cmsCIEXYZ){M[c], M[3 + c], M[6 + c]};
		cmsMLU *desc = cmsMLUalloc(NULL, 1), *cprt = cmsMLUalloc(NULL, 1);
		ok = desc && cprt && cmsMLUsetASCII(desc, "en", "US", description) &&
		     cmsMLUsetASCII(cprt, "en", "US", "No copyright, use freely") &&
		     cmsWriteTag(h, cmsSigProfileDescriptionTag, desc) &&
		     cmsWriteTag(h, cmsSigCopyrightTag, cprt) &&
		     cmsWriteTag(h, cmsSigMediaWhitePointTag, cmsD50_XYZ()) &&
		     cmsWriteTag(h, cmsSigRedColorantTag, &col[0]) &&
		     cmsWriteTag(h, cmsSigGreenColorantTag, &col[1]) &&
		     cmsWriteTag(h, cmsSigBlueColorantTag, &col[2]) &&
		     cmsWriteTag(h, cmsSigRedTRCTag, lin) && cmsLinkTag(h, cmsSigGreenTRCTag, cmsSigRedTRCTag) &&
		     cmsLinkTag(h, cmsSigBlueTRCTag, cmsSigRedTRCTag);
		cmsMLUfree(desc);
		cmsMLUfree(cprt);
	}
	cmsUInt32Number sz = 0;
	ok = ok && cmsMD5computeID(h) && cmsSaveProfileToMem(h, NULL, &sz) && sz > 0 &&
	     (*buf = malloc(sz)) && cmsSaveProfileToMem(h, *buf, &sz);
	if (lin)
		cmsFreeToneCurve(lin);
	if (h)
		cmsCloseProfile(h);
	if (!ok) {
		free(*buf);
		*buf = NULL;
		return kg_fail(err, KG_EIO, "LittleCMS: cannot build the camera profile");
	}
	*len = sz;
	return 0;
}

#else

int kg_icc_camera_profile(const double (*rgb)[3], const double (*xyz)[3], int n,
                          const char *description, kg_icc_version ver, double m[9],
                          unsigned char **buf, size_t *len, kg_err *err)
{
	*buf = NULL;
	*len = 0;
	return kg_fail(err, KG_ENOTSUP, "camera profile: kogei was built without LittleCMS");
}

int kg_icc_available(void)
{
	return 0;
}

int kg_icc_profile_bytes(kg_icc_space s, kg_icc_version v, unsigned char **buf, size_t *len,
                         kg_err *err)
{
	*buf = NULL;
	*len = 0;
	return kg_fail(err, KG_ENOTSUP, "%s profile: kogei was built without LittleCMS",
	               kg_icc_space_description(s));
}

int kg_master_write(const char *cube, const kg_illuminant *ill, kg_icc_space space,
                    kg_icc_version ver, const char *path, const unsigned char *lit,
                    long *clipped, kg_err *err)
{
	if (clipped)
		*clipped = 0;
	return kg_fail(err, KG_ENOTSUP, "%s: kogei was built without LittleCMS", path);
}

#endif
