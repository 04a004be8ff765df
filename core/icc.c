/* Colour-managed outputs with LittleCMS: working-space profiles and the master TIFF. */
#include "icc.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include "envi.h"
#include "escape.h"
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

/* The space's profile (NULL for none or when LittleCMS fails); linear: with linear
 * curves, for the float master. */
static cmsHPROFILE space_profile(kg_icc_space s, kg_icc_version v, int linear)
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
	if (curve && linear) {
		cmsFreeToneCurve(curve);
		curve = cmsBuildGamma(NULL, 1.0);
	}
	if (!curve)
		return NULL;
	cmsToneCurve *curves[3] = {curve, curve, curve};
	cmsHPROFILE h = cmsCreateRGBProfile(&white, &prim, curves);
	cmsFreeToneCurve(curve);
	if (!h)
		return NULL;
	cmsSetProfileVersion(h, v == KG_ICC_V4 ? 4.3 : 2.4);
	char text[160];
	snprintf(text, sizeof(text), "%s%s", kg_icc_space_description(s),
	         linear ? " linear (scene-referred, diffuse white 1.0)" : "");
	cmsMLU *desc = cmsMLUalloc(NULL, 1), *cprt = cmsMLUalloc(NULL, 1);
	int ok = desc && cprt && cmsMLUsetASCII(desc, "en", "US", text) &&
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

static int profile_bytes(kg_icc_space s, kg_icc_version v, int linear, unsigned char **buf,
                         size_t *len, kg_err *err)
{
	*buf = NULL;
	*len = 0;
	cmsHPROFILE h = space_profile(s, v, linear);
	cmsUInt32Number n = 0;
	if (!h || !cmsSaveProfileToMem(h, NULL, &n) || n == 0 || !(*buf = malloc(n)) ||
	    !cmsSaveProfileToMem(h, *buf, &n)) {
		if (h)
			cmsCloseProfile(h);
		free(*buf);
		*buf = NULL;
		return kg_fail(err, KG_EIO, "LittleCMS: cannot build the %s%s profile",
		               kg_icc_space_description(s), linear ? " linear" : "");
	}
	cmsCloseProfile(h);
	*len = n;
	return 0;
}

int kg_icc_profile_bytes(kg_icc_space s, kg_icc_version v, unsigned char **buf, size_t *len,
                         kg_err *err)
{
	return profile_bytes(s, v, 0, buf, len, err);
}

int kg_icc_linear_profile_bytes(kg_icc_space s, kg_icc_version v, unsigned char **buf,
                                size_t *len, kg_err *err)
{
	return profile_bytes(s, v, 1, buf, len, err);
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

/* "YYYY:MM:DD HH:MM:SS", the form TIFF 6.0 gives DateTime. */
static int tiff_datetime_ok(const char *s)
{
	static const char form[] = "dddd:dd:dd dd:dd:dd";
	if (strlen(s) != sizeof(form) - 1)
		return 0;
	for (size_t i = 0; form[i]; i++)
		if (form[i] == 'd' ? !isdigit((unsigned char)s[i]) : s[i] != form[i])
			return 0;
	return 1;
}

/* The tags of kg_tiff_identity (icc.h); the resolution tags always (TIFF 6.0 baseline
 * requires them). */
static int identity_tags(TIFF *tif, const kg_tiff_identity *id, const char *path,
                         kg_err *err)
{
	const struct { uint32_t tag; const char *name, *value; } text[] = {
		{TIFFTAG_IMAGEDESCRIPTION, "ImageDescription", id ? id->description : NULL},
		{TIFFTAG_ARTIST, "Artist", id ? id->artist : NULL},
		{TIFFTAG_COPYRIGHT, "Copyright", id ? id->copyright : NULL},
		{TIFFTAG_DATETIME, "DateTime", id ? id->datetime : NULL},
	};
	for (size_t i = 0; i < sizeof(text) / sizeof(text[0]); i++) {
		if (!text[i].value)
			continue;
		char what[300];
		snprintf(what, sizeof(what), "%s: TIFF %s", path, text[i].name);
		int ret = kg_text_check_controls(what, text[i].value, err);
		if (!ret && text[i].tag == TIFFTAG_DATETIME && !tiff_datetime_ok(text[i].value))
			ret = kg_fail(err, KG_EINVAL, "%s: '%s': expected YYYY:MM:DD HH:MM:SS", what,
			              text[i].value);
		if (ret)
			return ret;
		if (!TIFFSetField(tif, text[i].tag, text[i].value))
			return kg_fail(err, KG_EIO, "%s: cannot set it", what);
	}
	double ppmm = id && id->pixels_per_mm > 0 && isfinite(id->pixels_per_mm)
	                  ? id->pixels_per_mm : 0;
	float res = ppmm > 0 ? (float)(ppmm * 25.4) : 1.0f;
	if (!TIFFSetField(tif, TIFFTAG_XRESOLUTION, res) ||
	    !TIFFSetField(tif, TIFFTAG_YRESOLUTION, res) ||
	    !TIFFSetField(tif, TIFFTAG_RESOLUTIONUNIT, ppmm > 0 ? RESUNIT_INCH : RESUNIT_NONE))
		return kg_fail(err, KG_EIO, "%s: cannot set the TIFF resolution tags", path);
	if (id && id->xmp && id->xmp_len &&
	    !TIFFSetField(tif, TIFFTAG_XMLPACKET, (uint32_t)id->xmp_len, id->xmp))
		return kg_fail(err, KG_EIO, "%s: cannot set the TIFF XMP packet (tag 700)", path);
	return 0;
}

/* A TIFF written through a temporary file (kg_outfile): started, and closed with it
 * committed or, after an error, removed. */
typedef struct tiff_out {
	kg_outfile o;
	int have_out;
	TIFF *tif;
} tiff_out;

static int tiff_start(tiff_out *t, const char *path, kg_err *err)
{
	int ret = kg_outfile_open(&t->o, path, 0, err);
	if (ret)
		return ret;
	t->have_out = 1;
	int fd = dup(fileno(t->o.fp));
	t->tif = fd < 0 ? NULL : TIFFFdOpen(fd, path, "w");
	if (!t->tif) {
		if (fd >= 0)
			close(fd);
		return kg_fail(err, KG_EIO, "%s: cannot start TIFF", path);
	}
	return 0;
}

static int tiff_finish(tiff_out *t, const char *path, int ret, kg_err *err)
{
	if (t->tif) {
		if (!ret && !TIFFFlush(t->tif))
			ret = kg_fail(err, KG_EIO, "%s: cannot write TIFF", path);
		TIFFClose(t->tif);
		t->tif = NULL;
	}
	if (t->have_out) {
		t->have_out = 0;
		if (ret)
			kg_outfile_abort(&t->o);
		else
			ret = kg_outfile_commit(&t->o, err);
	}
	return ret;
}

/* The tags of a master: W x H RGB of `bits` bits (16-bit unsigned or 32-bit IEEE
 * float), LZW, which TIFF 6.0 itself defines (Deflate is an extension that validators
 * flag and archives' guidelines do not list), with the horizontal predictor (the
 * floating-point one, TIFF Technical Note 3, for float), in strips of about 64 KiB:
 * the codec restarts at every strip; the profile and the identity. */
static int master_tags(TIFF *tif, int W, int H, int bits, const unsigned char *icc,
                       size_t icc_len, const kg_tiff_identity *id, const char *path,
                       kg_err *err)
{
	int fl = bits == 32;
	size_t px = (size_t)bits / 8 * 3;
	if (!(TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, (uint32_t)W) &&
	      TIFFSetField(tif, TIFFTAG_IMAGELENGTH, (uint32_t)H) &&
	      TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, (uint16_t)3) &&
	      TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, (uint16_t)bits) &&
	      TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, fl ? SAMPLEFORMAT_IEEEFP : SAMPLEFORMAT_UINT) &&
	      TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_RGB) &&
	      TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG) &&
	      TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_LZW) &&
	      TIFFSetField(tif, TIFFTAG_PREDICTOR, fl ? PREDICTOR_FLOATINGPOINT
	                                              : PREDICTOR_HORIZONTAL) &&
	      TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP,
	                   TIFFDefaultStripSize(tif, (uint32_t)(65536 / (px * (size_t)W) + 1))) &&
	      TIFFSetField(tif, TIFFTAG_SOFTWARE, "kogei " KG_VERSION) &&
	      TIFFSetField(tif, TIFFTAG_ICCPROFILE, (uint32_t)icc_len, icc)))
		return kg_fail(err, KG_EIO, "%s: cannot set the TIFF tags", path);
	return identity_tags(tif, id, path, err);
}

/* XYZ (D50, white Y = 1) to the linear profile's RGB: the inverse of the matrix of its
 * colorant tags, as a reader of the file applies them. */
static int linear_matrix(const unsigned char *icc, size_t len, double inv[9])
{
	cmsHPROFILE h = cmsOpenProfileFromMem(icc, (cmsUInt32Number)len);
	if (!h)
		return -1;
	const cmsTagSignature tags[3] = {cmsSigRedColorantTag, cmsSigGreenColorantTag,
	                                 cmsSigBlueColorantTag};
	double M[9];
	int ok = 1;
	for (int c = 0; c < 3 && ok; c++) {
		const cmsCIEXYZ *v = cmsReadTag(h, tags[c]);
		if (!v) {
			ok = 0;
			break;
		}
		M[c] = v->X;
		M[3 + c] = v->Y;
		M[6 + c] = v->Z;
	}
	cmsCloseProfile(h);
	double det = ok ? M[0] * (M[4] * M[8] - M[5] * M[7]) - M[1] * (M[3] * M[8] - M[5] * M[6]) +
	                  M[2] * (M[3] * M[7] - M[4] * M[6])
	                : 0;
	if (!(fabs(det) > 1e-12))
		return -1;
	inv[0] = (M[4] * M[8] - M[5] * M[7]) / det;
	inv[1] = (M[2] * M[7] - M[1] * M[8]) / det;
	inv[2] = (M[1] * M[5] - M[2] * M[4]) / det;
	inv[3] = (M[5] * M[6] - M[3] * M[8]) / det;
	inv[4] = (M[0] * M[8] - M[2] * M[6]) / det;
	inv[5] = (M[2] * M[3] - M[0] * M[5]) / det;
	inv[6] = (M[3] * M[7] - M[4] * M[6]) / det;
	inv[7] = (M[1] * M[6] - M[0] * M[7]) / det;
	inv[8] = (M[0] * M[4] - M[1] * M[3]) / det;
	return 0;
}

/* The highlight map, a row of blocks at a time: each block's mean Y and worst case. */
enum { MAP_NONE, MAP_LOW, MAP_TOP, MAP_ABOVE };

typedef struct map_acc {
	int step, ow, oh, W;
	int box[4]; /* the counted pixels' blocks: x0, y0, x1, y1 */
	unsigned char *out, *worst;
	double *sum;
	int *n;
} map_acc;

static int map_open(map_acc *m, int W, int H, int max_side)
{
	m->W = W;
	m->step = 1;
	while ((W + m->step - 1) / m->step > max_side || (H + m->step - 1) / m->step > max_side)
		m->step++;
	m->ow = (W + m->step - 1) / m->step;
	m->oh = (H + m->step - 1) / m->step;
	m->out = malloc(3 * (size_t)m->ow * (size_t)m->oh);
	m->worst = calloc((size_t)m->ow, 1);
	m->sum = calloc((size_t)m->ow, sizeof(double));
	m->n = calloc((size_t)m->ow, sizeof(int));
	m->box[0] = m->ow;
	m->box[1] = m->oh;
	return m->out && m->worst && m->sum && m->n ? 0 : -1;
}

static void map_pixel(map_acc *m, int x, int row, double y, int counted, int cat)
{
	int b = x / m->step, r = row / m->step;
	if (counted) {
		m->box[0] = b < m->box[0] ? b : m->box[0];
		m->box[1] = r < m->box[1] ? r : m->box[1];
		m->box[2] = b + 1 > m->box[2] ? b + 1 : m->box[2];
		m->box[3] = r + 1 > m->box[3] ? r + 1 : m->box[3];
	}
	m->sum[b] += isfinite(y) ? y : 0;
	m->n[b]++;
	if (cat > m->worst[b])
		m->worst[b] = (unsigned char)cat;
}

static void map_flush(map_acc *m, int row)
{
	static const unsigned char colour[4][3] = {
		{0, 0, 0}, {KG_MASTER_MAP_LOW}, {KG_MASTER_MAP_TOP}, {KG_MASTER_MAP_ABOVE}};
	unsigned char *o = m->out + 3 * (size_t)row * (size_t)m->ow;
	for (int b = 0; b < m->ow; b++) {
		if (m->worst[b]) {
			memcpy(o + 3 * b, colour[m->worst[b]], 3);
		} else {
			/* the grey: Y (0..1) encoded for the display (sRGB) */
			double y = m->n[b] ? fmin(fmax(m->sum[b] / m->n[b], 0), 1) : 0;
			y = y <= 0.0031308 ? 12.92 * y : 1.055 * pow(y, 1 / 2.4) - 0.055;
			o[3 * b] = o[3 * b + 1] = o[3 * b + 2] = (unsigned char)lround(255 * y);
		}
		m->worst[b] = 0;
		m->sum[b] = 0;
		m->n[b] = 0;
	}
}

static void map_close(map_acc *m)
{
	free(m->out);
	free(m->worst);
	free(m->sum);
	free(m->n);
}

int kg_master_write(const char *cube, const kg_illuminant *ill, kg_icc_space space,
                    kg_icc_version ver, const char *path, const unsigned char *lit,
                    const kg_tiff_identity *id, kg_master_extra *x, kg_err *err)
{
	kg_envi *e = NULL;
	cmsHPROFILE xyz = NULL, rgb = NULL;
	cmsHTRANSFORM t = NULL;
	unsigned char *icc = NULL, *licc = NULL;
	size_t icc_len = 0, licc_len = 0;
	float *band = NULL, *frow = NULL;
	double *xyzrow = NULL, *out = NULL, inv[9];
	double *yrow = NULL, *bmax = NULL;
	uint16_t *row = NULL;
	tiff_out o = {0}, lo = {0};
	map_acc map = {0};
	kg_master_stats st = {0};
	const char *lpath = x ? x->linear_path : NULL;
	int want_map = x && x->map_max_side > 0;
	if (x) {
		x->map = NULL;
		x->map_w = x->map_h = 0;
		memset(x->box, 0, sizeof(x->box));
		x->stats = st;
	}
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
	/* the linear values: the float master's, and what says a channel is above 1 (the
	 * transform below clamps at the top without saying so) */
	if (!ret && !(ret = kg_icc_linear_profile_bytes(space, ver, &licc, &licc_len, err)) &&
	    linear_matrix(licc, licc_len, inv))
		ret = kg_fail(err, KG_EIO, "LittleCMS: cannot read the %s linear profile's matrix",
		              kg_icc_space_description(space));
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
		frow = malloc(sizeof(float) * 3 * (size_t)W);
		yrow = malloc(sizeof(double) * (size_t)W);
		bmax = malloc(sizeof(double) * (size_t)W);
		if (!band || !xyzrow || !row || !out || !frow || !yrow || !bmax ||
		    (want_map && map_open(&map, W, H, x->map_max_side)))
			ret = kg_fail(err, KG_ENOMEM, "out of memory");
	}
	if (!ret)
		ret = tiff_start(&o, path, err);
	if (!ret)
		ret = master_tags(o.tif, W, H, 16, icc, icc_len, id, path, err);
	if (!ret && lpath && !(ret = tiff_start(&lo, lpath, err)))
		ret = master_tags(lo.tif, W, H, 32, licc, licc_len, id, lpath, err);
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
			for (int xx = 0; xx < W; xx++) {
				const float *s = band + ((size_t)yr * W + xx) * KG_NBANDS;
				kg_xyz c = {0, 0, 0};
				int finite = 1;
				double mx = -INFINITY;
				for (int b = 0; b < KG_NBANDS; b++) {
					if (!isfinite(s[b])) {
						finite = 0;
						break;
					}
					c.X += wts.w[0][b] * s[b];
					c.Y += wts.w[1][b] * s[b];
					c.Z += wts.w[2][b] * s[b];
					mx = s[b] > mx ? s[b] : mx;
				}
				/* Y relative to the diffuse white under the illuminant (NaN: none) */
				yrow[xx] = finite ? c.Y / 100.0 : NAN;
				bmax[xx] = mx;
				if (!finite)
					c = (kg_xyz){0, 0, 0};
				else
					c = kg_bradford_adapt(c, white, d50);
				/* the ICC connection space: the white at Y = 1, D50 */
				xyzrow[3 * xx] = c.X / 100.0;
				xyzrow[3 * xx + 1] = c.Y / 100.0;
				xyzrow[3 * xx + 2] = c.Z / 100.0;
			}
			cmsDoTransform(t, xyzrow, out, (cmsUInt32Number)W);
			int y = y0 + yr;
			for (int xx = 0; xx < W; xx++) {
				int cl = 0, top = 0;
				const double *q = xyzrow + 3 * xx;
				for (int ch = 0; ch < 3; ch++) {
					double lin = inv[3 * ch] * q[0] + inv[3 * ch + 1] * q[1] +
					             inv[3 * ch + 2] * q[2];
					frow[3 * xx + ch] = (float)lin;
					/* above the space's white in that channel: at full scale in the
					 * master (a part in 10^5 above: the profile's own rounding) */
					top |= lin > 1 + 1e-5;
					double v = out[3 * xx + ch];
					if (!(v >= 0)) {
						cl |= v < 0;
						v = 0;
					} else if (v > 1) {
						cl = 1;
						v = 1;
					}
					row[3 * xx + ch] = (uint16_t)lround(v * 65535.0);
				}
				cl |= top;
				size_t i = (size_t)y * (size_t)W + (size_t)xx;
				int counted = isfinite(yrow[xx]) && (!lit || (lit[i / 8] >> (i % 8) & 1));
				int above = counted && yrow[xx] > 1, cat = MAP_NONE;
				if (counted) {
					st.counted++;
					st.clipped += cl;
					st.clipped_top += top;
					st.clipped_low += cl && !top;
					st.above_white += above;
					st.above_clipped += above && top;
					st.band_above_one += bmax[xx] > 1;
					st.max_y = fmax(st.max_y, yrow[xx]);
					st.max_reflectance = fmax(st.max_reflectance, bmax[xx]);
					cat = above ? MAP_ABOVE : top ? MAP_TOP : cl ? MAP_LOW : MAP_NONE;
				}
				if (want_map)
					map_pixel(&map, xx, y, yrow[xx], counted, cat);
			}
			if (want_map && ((y + 1) % map.step == 0 || y == H - 1))
				map_flush(&map, y / map.step);
			if (TIFFWriteScanline(o.tif, row, (uint32_t)y, 0) != 1)
				ret = kg_fail(err, KG_EIO, "%s: cannot write TIFF", path);
			if (!ret && lpath && TIFFWriteScanline(lo.tif, frow, (uint32_t)y, 0) != 1)
				ret = kg_fail(err, KG_EIO, "%s: cannot write TIFF", lpath);
		}
	}
	/* the float master first: a failure there leaves neither file */
	if (lpath)
		ret = tiff_finish(&lo, lpath, ret, err);
	ret = tiff_finish(&o, path, ret, err);
	if (!ret && x) {
		x->stats = st;
		if (want_map) {
			x->map = map.out;
			x->map_w = map.ow;
			x->map_h = map.oh;
			if (st.counted)
				memcpy(x->box, map.box, sizeof(x->box));
			map.out = NULL;
		}
	}
	if (ret && lpath)
		remove(lpath);
	if (t)
		cmsDeleteTransform(t);
	if (xyz)
		cmsCloseProfile(xyz);
	if (rgb)
		cmsCloseProfile(rgb);
	map_close(&map);
	free(icc);
	free(licc);
	free(band);
	free(xyzrow);
	free(out);
	free(row);
	free(frow);
	free(yrow);
	free(bmax);
	kg_envi_close(&e);
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

int kg_icc_linear_profile_bytes(kg_icc_space s, kg_icc_version v, unsigned char **buf,
                                size_t *len, kg_err *err)
{
	return kg_icc_profile_bytes(s, v, buf, len, err);
}

int kg_master_write(const char *cube, const kg_illuminant *ill, kg_icc_space space,
                    kg_icc_version ver, const char *path, const unsigned char *lit,
                    const kg_tiff_identity *id, kg_master_extra *x, kg_err *err)
{
	if (x) {
		x->map = NULL;
		x->map_w = x->map_h = 0;
		x->stats = (kg_master_stats){0};
	}
	return kg_fail(err, KG_ENOTSUP, "%s: kogei was built without LittleCMS", path);
}

#endif
