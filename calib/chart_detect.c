/* Chart detection: AprilTag fiducials (libapriltag) give points whose positions on the
 * chart are known; a homography mm -> px fitted to all of them (normalised DLT, a
 * consensus over pairs of tags against outliers and other charts, then Levenberg-
 * Marquardt on the reprojection error) places every patch; each patch is sampled
 * over an inner region with robust statistics. Tagless ColorCheckers go through
 * OpenCV's mcc detector (chart_mcc.cpp) when it is available.
 * Raw CFA frames are demosaiced bilinearly here.
 *
 * Pixel coordinates: (0, 0) is the top-left corner of the top-left pixel, so pixel
 * (i, j) has its centre at (i + 0.5, j + 0.5). libapriltag reports corners with
 * pixel centres at integers; they are shifted by half a pixel on the way in. */
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <cairo.h>

#include "kg_calib.h"
#include "kg_config.h"

#if KG_HAVE_MCC
#include "chart_mcc.h"
#define MCC_MIN_SIDE 100L
#endif
#if HAVE_APRILTAG
/* The largest side libapriltag's segmentation takes after decimation. */
#define APRILTAG_MAX_SIDE 32767L
#include <apriltag/apriltag.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagStandard41h12.h>
#endif

/* ---- homographies ------------------------------------------------------------ */

void kg_homography_map(const double H[9], double x, double y, double out[2])
{
	double w = H[6] * x + H[7] * y + H[8];
	out[0] = (H[0] * x + H[1] * y + H[2]) / w;
	out[1] = (H[3] * x + H[4] * y + H[5]) / w;
}

int kg_homography_invert(const double H[9], double inv[9])
{
	double a = H[0], b = H[1], c = H[2], d = H[3], e = H[4], f = H[5], g = H[6],
	       h = H[7], i = H[8];
	double A = e * i - f * h, B = -(d * i - f * g), C = d * h - e * g;
	double det = a * A + b * B + c * C;
	if (!isfinite(det) || fabs(det) < 1e-300)
		return KG_EINVAL;
	double m[9] = {A, -(b * i - c * h), b * f - c * e, B, a * i - c * g, -(a * f - c * d),
	               C, -(a * h - b * g), a * e - b * d};
	for (int k = 0; k < 9; k++)
		inv[k] = m[k] / det;
	return 0;
}

static void mat3_mul(const double a[9], const double b[9], double out[9])
{
	double t[9];
	for (int r = 0; r < 3; r++)
		for (int c = 0; c < 3; c++)
			t[r * 3 + c] = a[r * 3] * b[c] + a[r * 3 + 1] * b[3 + c] + a[r * 3 + 2] * b[6 + c];
	memcpy(out, t, sizeof(t));
}

/* Hartley normalisation: centroid to the origin, mean distance sqrt(2). */
static void normaliser(const double (*p)[2], int n, double T[9])
{
	double cx = 0, cy = 0, d = 0;
	for (int i = 0; i < n; i++) {
		cx += p[i][0];
		cy += p[i][1];
	}
	cx /= n;
	cy /= n;
	for (int i = 0; i < n; i++)
		d += hypot(p[i][0] - cx, p[i][1] - cy);
	d /= n;
	double s = d > 0 ? sqrt(2.0) / d : 1.0;
	double t[9] = {s, 0, -s * cx, 0, s, -s * cy, 0, 0, 1};
	memcpy(T, t, sizeof(t));
}

/* Solve the n x n system A x = b in place (partial pivoting). 0 or -1 if singular. */
static int solve_dense(double *A, double *b, int n)
{
	for (int k = 0; k < n; k++) {
		int p = k;
		for (int i = k + 1; i < n; i++)
			if (fabs(A[i * n + k]) > fabs(A[p * n + k]))
				p = i;
		if (!(fabs(A[p * n + k]) > 1e-300))
			return -1;
		if (p != k) {
			for (int j = 0; j < n; j++) {
				double t = A[k * n + j];
				A[k * n + j] = A[p * n + j];
				A[p * n + j] = t;
			}
			double t = b[k];
			b[k] = b[p];
			b[p] = t;
		}
		for (int i = k + 1; i < n; i++) {
			double f = A[i * n + k] / A[k * n + k];
			for (int j = k; j < n; j++)
				A[i * n + j] -= f * A[k * n + j];
			b[i] -= f * b[k];
		}
	}
	for (int k = n - 1; k >= 0; k--) {
		double s = b[k];
		for (int j = k + 1; j < n; j++)
			s -= A[k * n + j] * b[j];
		b[k] = s / A[k * n + k];
	}
	return 0;
}

/* Sum of squared reprojection errors of normalised points under h (h[8] = 1). */
static double sq_error(const double h[9], const double (*src)[2], const double (*dst)[2],
                       int n)
{
	double s = 0;
	for (int i = 0; i < n; i++) {
		double q[2];
		kg_homography_map(h, src[i][0], src[i][1], q);
		s += (q[0] - dst[i][0]) * (q[0] - dst[i][0]) + (q[1] - dst[i][1]) * (q[1] - dst[i][1]);
	}
	return s;
}

/* Levenberg-Marquardt on the 8 free entries of h (h[8] fixed at 1), in normalised
 * coordinates where that parametrisation is well conditioned. */
static void refine_lm(double h[9], const double (*src)[2], const double (*dst)[2], int n)
{
	double lambda = 1e-3, err = sq_error(h, src, dst, n);
	for (int it = 0; it < 50; it++) {
		double JtJ[64] = {0}, Jtr[8] = {0};
		for (int i = 0; i < n; i++) {
			double X = src[i][0], Y = src[i][1];
			double w = h[6] * X + h[7] * Y + 1.0;
			double x = (h[0] * X + h[1] * Y + h[2]) / w, y = (h[3] * X + h[4] * Y + h[5]) / w;
			double jx[8] = {X / w, Y / w, 1 / w, 0, 0, 0, -x * X / w, -x * Y / w};
			double jy[8] = {0, 0, 0, X / w, Y / w, 1 / w, -y * X / w, -y * Y / w};
			double rx = dst[i][0] - x, ry = dst[i][1] - y;
			for (int a = 0; a < 8; a++) {
				Jtr[a] += jx[a] * rx + jy[a] * ry;
				for (int b = 0; b < 8; b++)
					JtJ[a * 8 + b] += jx[a] * jx[b] + jy[a] * jy[b];
			}
		}
		int improved = 0;
		while (lambda < 1e10) {
			double A[64], d[8], cand[9];
			memcpy(A, JtJ, sizeof(A));
			memcpy(d, Jtr, sizeof(d));
			for (int a = 0; a < 8; a++)
				A[a * 8 + a] += lambda * (JtJ[a * 8 + a] + 1e-12);
			if (solve_dense(A, d, 8) == 0) {
				for (int a = 0; a < 8; a++)
					cand[a] = h[a] + d[a];
				cand[8] = 1.0;
				double e = sq_error(cand, src, dst, n);
				if (e < err) {
					double gain = err - e;
					memcpy(h, cand, sizeof(cand));
					err = e;
					lambda = fmax(lambda * 0.3, 1e-12);
					improved = gain > 1e-14 * (err + 1e-30);
					break;
				}
			}
			lambda *= 10;
		}
		if (!improved)
			break;
	}
}

int kg_homography_fit(const double (*src)[2], const double (*dst)[2], int n, int refine,
                      double H[9], double *rms, kg_err *err)
{
	kg_check_arg(src && dst && H, err);
	if (n < 4)
		return kg_fail(err, KG_EINVAL, "homography: %d point pairs; at least 4 are needed", n);
	double Ts[9], Td[9];
	normaliser(src, n, Ts);
	normaliser(dst, n, Td);
	double (*ns)[2] = malloc((size_t)n * sizeof(*ns));
	double (*nd)[2] = malloc((size_t)n * sizeof(*nd));
	kg_mat *A = NULL, *vt = NULL;
	int ret = 0;
	if (!ns || !nd) {
		ret = kg_fail(err, KG_ENOMEM, "homography: out of memory");
		goto done;
	}
	for (int i = 0; i < n; i++) {
		kg_homography_map(Ts, src[i][0], src[i][1], ns[i]);
		kg_homography_map(Td, dst[i][0], dst[i][1], nd[i]);
	}
	/* Two rows per pair; a 9th zero row when n == 4 so the SVD returns all of V. */
	int rows = 2 * n < 9 ? 9 : 2 * n;
	if ((ret = kg_mat_new(rows, 9, &A, err)))
		goto done;
	for (int i = 0; i < n; i++) {
		double X = ns[i][0], Y = ns[i][1], x = nd[i][0], y = nd[i][1];
		double r0[9] = {-X, -Y, -1, 0, 0, 0, x * X, x * Y, x};
		double r1[9] = {0, 0, 0, -X, -Y, -1, y * X, y * Y, y};
		memcpy(A->a + (2 * i) * 9, r0, sizeof(r0));
		memcpy(A->a + (2 * i + 1) * 9, r1, sizeof(r1));
	}
	if ((ret = kg_svd(A, NULL, NULL, &vt, err)))
		goto done;
	double h[9];
	for (int k = 0; k < 9; k++)
		h[k] = vt->a[8 * 9 + k];
	if (!(fabs(h[8]) > 1e-12)) {
		ret = kg_fail(err, KG_EINVAL, "homography: degenerate point configuration");
		goto done;
	}
	for (int k = 0; k < 9; k++)
		h[k] /= h[8];
	if (refine && n > 4)
		refine_lm(h, (const double (*)[2])ns, (const double (*)[2])nd, n);
	/* H = Td^-1 h Ts */
	double Tdi[9];
	if (kg_homography_invert(Td, Tdi)) {
		ret = kg_fail(err, KG_EINVAL, "homography: degenerate point configuration");
		goto done;
	}
	double t[9];
	mat3_mul(h, Ts, t);
	mat3_mul(Tdi, t, H);
	for (int k = 0; k < 9; k++)
		if (!isfinite(H[k])) {
			ret = kg_fail(err, KG_EINVAL, "homography: degenerate point configuration");
			goto done;
		}
	double scale = H[8];
	if (fabs(scale) > 1e-300)
		for (int k = 0; k < 9; k++)
			H[k] /= scale;
	if (rms)
		*rms = sqrt(sq_error(H, src, dst, n) / n);
done:
	free(ns);
	free(nd);
	kg_mat_free(&A);
	kg_mat_free(&vt);
	return ret;
}

/* ---- options, results -------------------------------------------------------- */

void kg_chart_detect_options_default(kg_chart_detect_options *o)
{
	memset(o, 0, sizeof(*o));
	o->decimate = 0;
	o->threads = 2;
	o->sample_fraction = 0.6;
	o->statistic = KG_CHART_MEDIAN;
	o->trim = 0.1;
	o->family = NULL;
	o->tagless = 0;
	o->min_tags = 0;
	o->min_pixels = 30;
	o->clip_level = 0;
	o->nonuniformity_limit = 0.05;
	o->glare_fraction = 0.01;
}

const char *kg_chart_statistic_name(kg_chart_statistic s)
{
	return s == KG_CHART_TRIMMED_MEAN ? "trimmed-mean" : "median";
}

int kg_chart_statistic_parse(const char *name, kg_chart_statistic *out, kg_err *err)
{
	if (strcmp(name, "median") == 0)
		*out = KG_CHART_MEDIAN;
	else if (strcmp(name, "trimmed-mean") == 0)
		*out = KG_CHART_TRIMMED_MEAN;
	else
		return kg_fail(err, KG_EINVAL, "statistic '%s': expected median or trimmed-mean",
		               name);
	return 0;
}

void kg_chart_result_free(kg_chart_result **pr)
{
	kg_chart_result *r = *pr;
	if (!r)
		return;
	free(r->tags);
	for (int i = 0; i < r->npatches; i++)
		free(r->patches[i].id);
	free(r->patches);
	for (int i = 0; i < r->nwarnings; i++)
		free(r->warnings[i]);
	free(r->warnings);
	free(r);
	*pr = NULL;
}

static int add_warning(kg_chart_result *r, const char *fmt, ...) KG_PRINTF(2, 3);
static int add_warning(kg_chart_result *r, const char *fmt, ...)
{
	char buf[1024];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(buf, sizeof(buf), fmt, ap);
	va_end(ap);
	char **w = realloc(r->warnings, (size_t)(r->nwarnings + 1) * sizeof(*w));
	if (!w)
		return KG_ENOMEM;
	r->warnings = w;
	if (!(w[r->nwarnings] = strdup(buf)))
		return KG_ENOMEM;
	r->nwarnings++;
	return 0;
}

#if HAVE_APRILTAG
/* Append "a, b, c" (ints) to buf. */
static void list_ints(char *buf, size_t len, const int *v, int n)
{
	size_t at = strlen(buf);
	for (int i = 0; i < n && at < len; i++)
		at += (size_t)snprintf(buf + at, len - at, "%s%d", i ? ", " : "", v[i]);
}
#endif

static double now_seconds(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* ---- input images ------------------------------------------------------------ */

/* Every stage states the image sides it supports, and an image outside them is refused
 * before the stage runs: a corrupted width or height field in a TIFF or PNG must end
 * in a message, not in a crash or an assertion inside a library. */
static int check_sides(int width, int height, long min_side, long max_side, const char *stage,
                       const char *hint, kg_err *err)
{
	if (width >= min_side && height >= min_side && width <= max_side && height <= max_side)
		return 0;
	if (max_side >= INT_MAX)
		return kg_fail(err, KG_EINVAL, "image %d x %d px: %s needs at least %ld px per side%s",
		               width, height, stage, min_side, hint ? hint : "");
	return kg_fail(err, KG_EINVAL, "image %d x %d px: %s needs %ld to %ld px per side%s",
	               width, height, stage, min_side, max_side, hint ? hint : "");
}

/* Bilinear demosaic of a CFA frame of R, G and B letters: each missing colour is the
 * mean of the 3 x 3 neighbours that carry it (edges clamped). */
static int demosaic_bilinear(const kg_image *raw, float *rgb, kg_err *err)
{
	int W = raw->width, Hh = raw->height, cr = raw->cfa_rows, cc = raw->cfa_cols;
	int colour[64];
	if (cr * cc > 64)
		return kg_fail(err, KG_ENOTSUP, "CFA repeat of %dx%d is too large", cr, cc);
	for (int k = 0; k < cr * cc; k++) {
		const char *p = strchr("RGB", raw->cfa[k]);
		if (!p || !raw->cfa[k])
			return kg_fail(err, KG_ENOTSUP,
			               "CFA pattern %.*s: only R, G and B filters can be demosaiced",
			               cr * cc, raw->cfa);
		colour[k] = (int)(p - "RGB");
	}
	for (int y = 0; y < Hh; y++) {
		for (int x = 0; x < W; x++) {
			double sum[3] = {0, 0, 0};
			int cnt[3] = {0, 0, 0};
			int own = colour[(y % cr) * cc + x % cc];
			for (int dy = -1; dy <= 1; dy++) {
				int yy = y + dy < 0 ? 0 : y + dy >= Hh ? Hh - 1 : y + dy;
				for (int dx = -1; dx <= 1; dx++) {
					int xx = x + dx < 0 ? 0 : x + dx >= W ? W - 1 : x + dx;
					int c = colour[(yy % cr) * cc + xx % cc];
					sum[c] += raw->data[(size_t)yy * W + xx];
					cnt[c]++;
				}
			}
			float *o = rgb + ((size_t)y * W + x) * 3;
			for (int c = 0; c < 3; c++)
				o[c] = c == own ? raw->data[(size_t)y * W + x]
				                : (cnt[c] ? (float)(sum[c] / cnt[c]) : 0.0f);
		}
	}
	return 0;
}

/* The image as the sampler sees it: interleaved linear floats with 1 or 3 channels. */
typedef struct work_image {
	int width, height, channels;
	const float *data;
	float *owned;
	double clip_level;
	double quantum; /* step between the source's integer codes (0: float or demosaiced) */
} work_image;

static int prepare_image(const kg_image *img, const kg_chart_detect_options *opt,
                         work_image *wi, kg_err *err)
{
	memset(wi, 0, sizeof(*wi));
	wi->width = img->width;
	wi->height = img->height;
	wi->channels = img->channels;
	wi->data = img->data;
	if (opt->clip_level > 0)
		wi->clip_level = opt->clip_level;
	else if (img->is_float || img->bits <= 0 || img->bits > 16)
		wi->clip_level = 1.0;
	else
		wi->clip_level = 1.0 - 0.5 / (double)((1L << img->bits) - 1);
	if (!img->is_float && img->bits > 0 && img->bits <= 16)
		wi->quantum = 1.0 / (double)((1L << img->bits) - 1);
	if (img->channels == 1 && img->cfa) {
		size_t n = (size_t)img->width * img->height * 3;
		wi->owned = malloc(n * sizeof(float));
		if (!wi->owned)
			return kg_fail(err, KG_ENOMEM, "demosaic: out of memory");
		int ret = demosaic_bilinear(img, wi->owned, err);
		if (ret) {
			free(wi->owned);
			wi->owned = NULL;
			return ret;
		}
		wi->channels = 3;
		wi->data = wi->owned;
		wi->quantum = 0;
	} else if (img->channels != 1 && img->channels != 3) {
		return kg_fail(err, KG_EINVAL, "image has %d channels: expected 1 or 3",
		               img->channels);
	}
	return 0;
}

static double luminance(const work_image *wi, size_t i)
{
	const float *p = wi->data + i * wi->channels;
	if (wi->channels == 1)
		return p[0];
	return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
}

enum { GREY_BINS = 4096 };

/* The exposure shown as white to the detectors: the 99.5th percentile of the
 * luminance (a histogram over 0..4 of full scale, every 7th pixel); 1 if that is 0. */
static double white_level(const work_image *wi)
{
	enum { BINS = GREY_BINS };
	static const double top = 4.0;
	size_t n = (size_t)wi->width * wi->height;
	long hist[BINS] = {0};
	for (size_t i = 0; i < n; i += 7) {
		double y = luminance(wi, i);
		int b = y <= 0 || !isfinite(y) ? 0 : y >= top ? BINS - 1 : (int)(y / top * BINS);
		hist[b]++;
	}
	long total = 0, acc = 0;
	for (int b = 0; b < BINS; b++)
		total += hist[b];
	double white = 1.0;
	for (int b = 0; b < BINS; b++) {
		acc += hist[b];
		if (acc >= 0.995 * total) {
			white = (b + 1) * top / BINS;
			break;
		}
	}
	return white > 1e-6 ? white : 1.0;
}

/* An 8-bit grey picture for tag detection and the overlay: luminance scaled so its
 * 99.5th percentile is white, then sRGB-encoded (a lookup table of 4096 steps). */
static unsigned char *grey8(const work_image *wi, double *scale_out)
{
	enum { BINS = GREY_BINS };
	size_t n = (size_t)wi->width * wi->height;
	unsigned char *g = malloc(n ? n : 1);
	if (!g)
		return NULL;
	double white = white_level(wi);
	unsigned char lut[BINS];
	for (int b = 0; b < BINS; b++) {
		double v = (b + 0.5) / BINS;
		double e = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
		lut[b] = (unsigned char)lrint(fmin(fmax(e, 0), 1) * 255);
	}
	double k = BINS / white;
	for (size_t i = 0; i < n; i++) {
		double y = luminance(wi, i) * k;
		int b = !(y > 0) ? 0 : y >= BINS - 1 ? BINS - 1 : (int)y;
		g[i] = lut[b];
	}
	*scale_out = 1.0 / white;
	return g;
}

/* ---- tags -------------------------------------------------------------------- */

typedef struct layout_view {
	const char *name;
	const char *family;
	int ntags;
	const int *tag_ids;
	const double (*tag_corners)[4][2]; /* mm, apriltag order */
	int npatches;
	char *const *patch_ids;
	const double (*patch_center)[2];
	const double (*patch_size)[2];
	double outline[4][2]; /* mm, the bounding box of tags and patches */
} layout_view;

#if HAVE_APRILTAG
static int layout_tag_index(const layout_view *L, int id)
{
	for (int i = 0; i < L->ntags; i++)
		if (L->tag_ids[i] == id)
			return i;
	return -1;
}

static apriltag_family_t *family_create(const char *name)
{
	if (!strcmp(name, "tag36h11"))
		return tag36h11_create();
	if (!strcmp(name, "tagStandard41h12"))
		return tagStandard41h12_create();
	if (!strcmp(name, "tag25h9"))
		return tag25h9_create();
	if (!strcmp(name, "tag16h5"))
		return tag16h5_create();
	if (!strcmp(name, "tagCircle21h7"))
		return tagCircle21h7_create();
	return NULL;
}

static void family_destroy(apriltag_family_t *f)
{
	const char *name = f->name;
	if (!strcmp(name, "tag36h11"))
		tag36h11_destroy(f);
	else if (!strcmp(name, "tagStandard41h12"))
		tagStandard41h12_destroy(f);
	else if (!strcmp(name, "tag25h9"))
		tag25h9_destroy(f);
	else if (!strcmp(name, "tag16h5"))
		tag16h5_destroy(f);
	else
		tagCircle21h7_destroy(f);
}

static int run_apriltag(const unsigned char *grey, int width, int height, const char *family,
                        int decimate, int threads, kg_chart_result *r, kg_err *err)
{
	apriltag_family_t *tf = family_create(family);
	if (!tf)
		return kg_fail(err, KG_EINVAL,
		               "tag family '%s': expected tag36h11, tagStandard41h12, tag25h9, "
		               "tag16h5 or tagCircle21h7", family);
	apriltag_detector_t *td = apriltag_detector_create();
	if (!td) {
		family_destroy(tf);
		return kg_fail(err, KG_ENOMEM, "apriltag: out of memory");
	}
	apriltag_detector_add_family_bits(td, tf, 1);
	td->quad_decimate = (float)decimate;
	td->quad_sigma = 0;
	td->nthreads = threads;
	td->refine_edges = 1;
	td->decode_sharpening = 0.25;
	image_u8_t im = {.width = width, .height = height, .stride = width,
	                 .buf = (uint8_t *)grey};
	zarray_t *dets = apriltag_detector_detect(td, &im);
	int ret = 0;
	int n = dets ? zarray_size(dets) : 0;
	if (n > 0) {
		r->tags = calloc((size_t)n, sizeof(*r->tags));
		if (!r->tags)
			ret = kg_fail(err, KG_ENOMEM, "apriltag: out of memory");
	}
	for (int i = 0; i < n && !ret; i++) {
		apriltag_detection_t *d;
		zarray_get(dets, i, &d);
		kg_chart_tag_found *t = &r->tags[r->ntags++];
		t->id = d->id;
		t->hamming = d->hamming;
		t->margin = d->decision_margin;
		for (int k = 0; k < 4; k++) {
			t->corners[k][0] = d->p[k][0] + 0.5;
			t->corners[k][1] = d->p[k][1] + 0.5;
		}
	}
	if (dets)
		apriltag_detections_destroy(dets);
	apriltag_detector_destroy(td);
	family_destroy(tf);
	return ret;
}

/* Largest corner distance of tag t under H (mm -> px), in pixels. */
static double tag_error(const double H[9], const kg_chart_tag_found *t, const double (*mm)[2])
{
	double e = 0;
	for (int k = 0; k < 4; k++) {
		double q[2];
		kg_homography_map(H, mm[k][0], mm[k][1], q);
		e = fmax(e, hypot(q[0] - t->corners[k][0], q[1] - t->corners[k][1]));
	}
	return e;
}

static double tag_side_px(const kg_chart_tag_found *t)
{
	double s = 0;
	for (int k = 0; k < 4; k++)
		s += hypot(t->corners[k][0] - t->corners[(k + 1) % 4][0],
		           t->corners[k][1] - t->corners[(k + 1) % 4][1]);
	return s / 4;
}

/* Fit H to the corners of the tags marked used. */
static int fit_used(const layout_view *L, const kg_chart_result *r, int refine, double H[9],
                    double *rms, kg_err *err)
{
	int n = 0;
	for (int i = 0; i < r->ntags; i++)
		n += r->tags[i].used ? 4 : 0;
	double (*src)[2] = malloc((size_t)(n ? n : 1) * sizeof(*src));
	double (*dst)[2] = malloc((size_t)(n ? n : 1) * sizeof(*dst));
	if (!src || !dst) {
		free(src);
		free(dst);
		return kg_fail(err, KG_ENOMEM, "homography: out of memory");
	}
	int at = 0;
	for (int i = 0; i < r->ntags; i++) {
		if (!r->tags[i].used)
			continue;
		int li = layout_tag_index(L, r->tags[i].id);
		for (int k = 0; k < 4; k++, at++) {
			src[at][0] = L->tag_corners[li][k][0];
			src[at][1] = L->tag_corners[li][k][1];
			dst[at][0] = r->tags[i].corners[k][0];
			dst[at][1] = r->tags[i].corners[k][1];
		}
	}
	int ret = kg_homography_fit((const double (*)[2])src, (const double (*)[2])dst, n, refine,
	                            H, rms, err);
	free(src);
	free(dst);
	return ret;
}

/* Mark the tags consistent with H (the closest of duplicates of an id) as used;
 * returns their number and the sum of their errors. */
static int classify_tags(const layout_view *L, kg_chart_result *r, const double H[9],
                         double tol_px, double tol_rel, double *sum_err)
{
	int count = 0;
	double sum = 0;
	for (int i = 0; i < r->ntags; i++)
		r->tags[i].used = 0;
	for (int i = 0; i < r->ntags; i++) {
		kg_chart_tag_found *t = &r->tags[i];
		int li = layout_tag_index(L, t->id);
		if (li < 0)
			continue;
		double e = tag_error(H, t, L->tag_corners[li]);
		t->error = e;
		if (!(e <= fmax(tol_px, tol_rel * tag_side_px(t))))
			continue;
		int dup = -1;
		for (int j = 0; j < i; j++)
			if (r->tags[j].used && r->tags[j].id == t->id)
				dup = j;
		if (dup >= 0) {
			if (r->tags[dup].error <= e)
				continue;
			r->tags[dup].used = 0;
			sum -= r->tags[dup].error;
			count--;
		}
		t->used = 1;
		sum += e;
		count++;
	}
	*sum_err = sum;
	return count;
}

/* Choose the tags of one chart: every pair of tags with layout ids proposes a
 * homography; the one most tags agree with wins (ties: the smaller error). Then the
 * fit over all agreeing tags is refined and the agreement re-checked. */
static int select_tags(const layout_view *L, kg_chart_result *r, const kg_chart_detect_options *opt,
                       kg_err *err)
{
	int *cand = malloc((size_t)(r->ntags ? r->ntags : 1) * sizeof(int));
	if (!cand)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	int nc = 0;
	for (int i = 0; i < r->ntags; i++)
		if (layout_tag_index(L, r->tags[i].id) >= 0)
			cand[nc++] = i;
	int ret = 0;
	int best = -1;
	double best_err = INFINITY, bestH[9];
	kg_err tmp;
	if (nc == 1) {
		r->tags[cand[0]].used = 1;
		if ((ret = fit_used(L, r, 0, bestH, NULL, err)))
			goto done;
		best = 1;
	}
	for (int a = 0; a < nc; a++) {
		for (int b = a + 1; b < nc; b++) {
			kg_chart_tag_found *ta = &r->tags[cand[a]], *tb = &r->tags[cand[b]];
			if (ta->id == tb->id)
				continue;
			for (int i = 0; i < r->ntags; i++)
				r->tags[i].used = i == cand[a] || i == cand[b];
			double H[9], s;
			if (fit_used(L, r, 0, H, NULL, &tmp))
				continue;
			int count = classify_tags(L, r, H, 3.0, 0.1, &s);
			if (count > best || (count == best && s < best_err)) {
				best = count;
				best_err = s;
				memcpy(bestH, H, sizeof(bestH));
			}
		}
	}
	if (best < 0) {
		ret = kg_fail(err, KG_ENOENT, "no consistent set of tags");
		goto done;
	}
	double s;
	classify_tags(L, r, bestH, 3.0, 0.1, &s);
	for (int pass = 0; pass < 2; pass++) {
		if ((ret = fit_used(L, r, 1, r->H, &r->rms_px, err)))
			goto done;
		int n_used = 0;
		for (int i = 0; i < r->ntags; i++)
			n_used += r->tags[i].used;
		if (n_used < 2)
			break;
		classify_tags(L, r, r->H, fmax(1.5, 5 * r->rms_px), 0.1, &s);
	}
	ret = fit_used(L, r, 1, r->H, &r->rms_px, err);
	(void)opt;
done:
	free(cand);
	return ret;
}
#endif

/* ---- patch sampling ---------------------------------------------------------- */

static int cmp_float(const void *a, const void *b)
{
	float x = *(const float *)a, y = *(const float *)b;
	return (x > y) - (x < y);
}

/* k-th smallest of v[0..n) (reorders v). */
static float select_kth(float *v, long n, long k)
{
	long lo = 0, hi = n - 1;
	while (lo < hi) {
		float pivot = v[lo + (hi - lo) / 2];
		long i = lo, j = hi;
		while (i <= j) {
			while (v[i] < pivot)
				i++;
			while (v[j] > pivot)
				j--;
			if (i <= j) {
				float t = v[i];
				v[i] = v[j];
				v[j] = t;
				i++;
				j--;
			}
		}
		if (k <= j)
			hi = j;
		else if (k >= i)
			lo = i;
		else
			break;
	}
	return v[k];
}

static double median_of(float *v, long n)
{
	if (n % 2)
		return select_kth(v, n, n / 2);
	double a = select_kth(v, n, n / 2);
	double b = select_kth(v, n / 2, n / 2 - 1);
	return 0.5 * (a + b);
}

/* Median of integer codes q apart, interpolated within the median's code as for
 * grouped data: the sample median of 8-bit pixels is stuck on a code (half a step is
 * 5 % of a dark patch), while noise spreading pixels over neighbouring codes tells
 * where the underlying value lies between them. */
static double grouped_median(const float *v, long n, double med, double q)
{
	long below = 0, at = 0;
	for (long i = 0; i < n; i++) {
		if (v[i] < med - 0.5 * q)
			below++;
		else if (v[i] <= med + 0.5 * q)
			at++;
	}
	if (at == 0)
		return med;
	return med - 0.5 * q + q * (0.5 * n - below) / at;
}

/* Robust location and spread of v[0..n): the statistic asked for and 1.4826 MAD.
 * quantum > 0: the values are integer codes that far apart. */
static void robust_stats(float *v, float *work, long n, const kg_chart_detect_options *opt,
                         double quantum, double *loc, double *sigma)
{
	double med = median_of(v, n);
	for (long i = 0; i < n; i++)
		work[i] = fabsf(v[i] - (float)med);
	*sigma = 1.4826 * median_of(work, n);
	if (opt->statistic == KG_CHART_TRIMMED_MEAN) {
		qsort(v, (size_t)n, sizeof(float), cmp_float);
		long cut = (long)floor(opt->trim * n);
		if (2 * cut >= n)
			cut = (n - 1) / 2;
		double s = 0;
		for (long i = cut; i < n - cut; i++)
			s += v[i];
		*loc = s / (double)(n - 2 * cut);
	} else {
		*loc = quantum > 0 ? grouped_median(v, n, med, quantum) : med;
	}
}

static double quad_area(const double q[4][2])
{
	double a = 0;
	for (int k = 0; k < 4; k++)
		a += q[k][0] * q[(k + 1) % 4][1] - q[(k + 1) % 4][0] * q[k][1];
	return fabs(a) / 2;
}

typedef struct sample_buffers {
	float *ch[3];
	float *sum;
	float *work;
	long cap;
} sample_buffers;

static int buffers_reserve(sample_buffers *b, long n)
{
	if (n <= b->cap)
		return 0;
	float **arrs[5] = {&b->ch[0], &b->ch[1], &b->ch[2], &b->sum, &b->work};
	for (int k = 0; k < 5; k++) {
		float *p = realloc(*arrs[k], (size_t)n * sizeof(float));
		if (!p)
			return KG_ENOMEM;
		*arrs[k] = p;
	}
	b->cap = n;
	return 0;
}

static void buffers_free(sample_buffers *b)
{
	for (int k = 0; k < 3; k++)
		free(b->ch[k]);
	free(b->sum);
	free(b->work);
}

static void flag(kg_chart_sample *p, unsigned f, const char *why)
{
	p->flags |= f;
	size_t at = strlen(p->warning);
	snprintf(p->warning + at, sizeof(p->warning) - at, "%s%s", at ? "; " : "", why);
}

static int sample_patch(const work_image *wi, const double H[9], const double Hinv[9],
                        const double center[2], const double size[2],
                        const kg_chart_detect_options *opt, sample_buffers *buf,
                        kg_chart_sample *p)
{
	double hx = 0.5 * opt->sample_fraction * size[0], hy = 0.5 * opt->sample_fraction * size[1];
	double cx = center[0], cy = center[1];
	double corners_mm[4][2] = {{cx - hx, cy - hy}, {cx + hx, cy - hy}, {cx + hx, cy + hy},
	                           {cx - hx, cy + hy}};
	double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
	for (int k = 0; k < 4; k++) {
		kg_homography_map(H, corners_mm[k][0], corners_mm[k][1], p->quad[k]);
		x0 = fmin(x0, p->quad[k][0]);
		x1 = fmax(x1, p->quad[k][0]);
		y0 = fmin(y0, p->quad[k][1]);
		y1 = fmax(y1, p->quad[k][1]);
	}
	double expected = quad_area(p->quad);
	long ix0 = (long)floor(fmax(x0, 0)), ix1 = (long)ceil(fmin(x1, wi->width));
	long iy0 = (long)floor(fmax(y0, 0)), iy1 = (long)ceil(fmin(y1, wi->height));
	long cap = (ix1 > ix0 && iy1 > iy0) ? (ix1 - ix0) * (iy1 - iy0) : 0;
	if (!isfinite(expected) || cap > KG_IMAGE_MAX_PIXELS)
		cap = 0;
	if (buffers_reserve(buf, cap ? cap : 1))
		return KG_ENOMEM;
	long n = 0;
	double qsum[4] = {0, 0, 0, 0};
	long qn[4] = {0, 0, 0, 0};
	int C = wi->channels;
	for (long y = iy0; y < iy1 && cap; y++) {
		for (long x = ix0; x < ix1; x++) {
			double m[2];
			kg_homography_map(Hinv, x + 0.5, y + 0.5, m);
			double u = m[0] - cx, v = m[1] - cy;
			if (!(fabs(u) <= hx && fabs(v) <= hy))
				continue;
			const float *px = wi->data + ((size_t)y * wi->width + x) * C;
			double s = 0;
			int clipped = 0;
			for (int c = 0; c < 3; c++) {
				float val = px[C == 3 ? c : 0];
				buf->ch[c][n] = val;
				s += val;
				clipped |= val >= wi->clip_level;
			}
			buf->sum[n] = (float)s;
			int q = (u >= 0) + 2 * (v >= 0);
			qsum[q] += s;
			qn[q]++;
			p->clipped_fraction += clipped;
			n++;
		}
	}
	p->pixels = n;
	if (n > 0)
		p->clipped_fraction /= (double)n;
	double inside = expected > 0 ? n / expected : 0;
	if (n == 0) {
		p->flags |= KG_CHART_FLAG_REJECTED;
		flag(p, KG_CHART_FLAG_OUT_OF_FRAME, "outside the image");
		for (int c = 0; c < 3; c++)
			p->rgb[c] = p->sd[c] = NAN;
		p->nonuniformity = NAN;
		return 0;
	}
	if (inside < 0.9)
		flag(p, KG_CHART_FLAG_OUT_OF_FRAME, "partly outside the image");
	for (int c = 0; c < 3; c++)
		robust_stats(buf->ch[c], buf->work, n, opt, wi->quantum, &p->rgb[c], &p->sd[c]);
	/* Glare: bright outliers in the channel sum, beyond 6 sigma and 5 % of the level. */
	double sum_med, sum_sigma;
	kg_chart_detect_options med_opt = *opt;
	med_opt.statistic = KG_CHART_MEDIAN;
	memcpy(buf->work, buf->sum, (size_t)n * sizeof(float)); /* keep sums for counting */
	robust_stats(buf->work, buf->ch[0], n, &med_opt, 0, &sum_med, &sum_sigma);
	double bright = sum_med + fmax(6 * sum_sigma, 0.05 * fabs(sum_med));
	long nbright = 0;
	for (long i = 0; i < n; i++)
		nbright += buf->sum[i] > bright;
	/* Non-uniformity: spread of the four quadrant means relative to the mean. */
	double qmin = INFINITY, qmax = -INFINITY, total = 0;
	for (int q = 0; q < 4; q++) {
		total += qsum[q];
		if (qn[q] > 0) {
			qmin = fmin(qmin, qsum[q] / qn[q]);
			qmax = fmax(qmax, qsum[q] / qn[q]);
		}
	}
	double mean = total / n;
	p->nonuniformity = fabs(mean) > 1e-12 ? (qmax - qmin) / fabs(mean) : 0;
	char why[96];
	if (p->clipped_fraction > 0) {
		snprintf(why, sizeof(why), "clipped (%.1f %% of pixels)", 100 * p->clipped_fraction);
		flag(p, KG_CHART_FLAG_CLIPPED, why);
	}
	if ((double)nbright / n > opt->glare_fraction) {
		snprintf(why, sizeof(why), "glare (%.1f %% of pixels much brighter than the rest)",
		         100.0 * nbright / n);
		flag(p, KG_CHART_FLAG_GLARE, why);
	}
	if (p->nonuniformity > opt->nonuniformity_limit) {
		snprintf(why, sizeof(why), "non-uniform (quadrants differ by %.1f %%: occluded, "
		         "shadowed or glare?)", 100 * p->nonuniformity);
		flag(p, KG_CHART_FLAG_NONUNIFORM, why);
	}
	if (n < opt->min_pixels) {
		snprintf(why, sizeof(why), "too few pixels (%ld < %d)", n, opt->min_pixels);
		flag(p, KG_CHART_FLAG_FEW_PIXELS, why);
	}
	return 0;
}

static int sample_all(const layout_view *L, const work_image *wi,
                      const kg_chart_detect_options *opt, kg_chart_result *r, kg_err *err)
{
	double Hinv[9];
	if (kg_homography_invert(r->H, Hinv))
		return kg_fail(err, KG_EINVAL, "the chart's homography is singular");
	r->patches = calloc((size_t)(L->npatches ? L->npatches : 1), sizeof(*r->patches));
	if (!r->patches)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	sample_buffers buf = {0};
	int ret = 0;
	for (int i = 0; i < L->npatches; i++) {
		kg_chart_sample *p = &r->patches[i];
		r->npatches++;
		if (!(p->id = strdup(L->patch_ids[i]))) {
			ret = kg_fail(err, KG_ENOMEM, "out of memory");
			break;
		}
		if (sample_patch(wi, r->H, Hinv, L->patch_center[i], L->patch_size[i], opt, &buf, p)) {
			ret = kg_fail(err, KG_ENOMEM, "patch sampling: out of memory");
			break;
		}
	}
	buffers_free(&buf);
	for (int k = 0; k < 4; k++)
		kg_homography_map(r->H, L->outline[k][0], L->outline[k][1], r->outline[k]);
	return ret;
}

/* ---- the detector ------------------------------------------------------------ */

static int patch_summary_warnings(kg_chart_result *r)
{
	int nflag = 0, nrej = 0;
	for (int i = 0; i < r->npatches; i++) {
		nflag += r->patches[i].flags != 0;
		nrej += (r->patches[i].flags & KG_CHART_FLAG_REJECTED) != 0;
	}
	if (!nflag)
		return 0;
	char buf[900] = "";
	size_t at = 0;
	for (int i = 0; i < r->npatches && at < sizeof(buf) - 1; i++)
		if (r->patches[i].flags)
			at += (size_t)snprintf(buf + at, sizeof(buf) - at, "%s%s: %s", at ? "; " : "",
			                       r->patches[i].id, r->patches[i].warning);
	return add_warning(r, "%d patch%s flagged%s: %s", nflag, nflag == 1 ? "" : "es",
	                   nrej ? " (rejected ones are left out of the patch file)" : "", buf);
}

static int detect_with_tags(const layout_view *L, const work_image *wi,
                            const kg_chart_detect_options *opt, kg_chart_result *r,
                            kg_err *err)
{
#if HAVE_APRILTAG
	double t0 = now_seconds(), scale;
	unsigned char *g = grey8(wi, &scale);
	if (!g)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	long npix = (long)wi->width * wi->height;
	int big = wi->width > wi->height ? wi->width : wi->height;
	int decimate = opt->decimate > 0 ? opt->decimate : npix < 4000000 ? 2 : 4;
	while (opt->decimate == 0 && big > APRILTAG_MAX_SIDE * (long)decimate)
		decimate *= 2; /* automatic decimation keeps within libapriltag's coordinates */
	const char *family = opt->family ? opt->family : L->family ? L->family : "tag36h11";
	r->decimate = decimate;
	/* libapriltag decimates a side s to 1 + (s - 1) / d pixels; below 3 it reads out of
	 * bounds, and its segmentation keeps doubled coordinates in 16 bits (it asserts a
	 * side < 32768). */
	char stage[96];
	snprintf(stage, sizeof(stage), "the tag detector (libapriltag, decimate %d)", decimate);
	int ret = check_sides(wi->width, wi->height, 2L * decimate + 1,
	                      APRILTAG_MAX_SIDE * (long)decimate, stage,
	                      opt->decimate && big > APRILTAG_MAX_SIDE * (long)decimate
	                          ? "; a larger --decimate takes larger images" : NULL,
	                      err);
	if (!ret)
		ret = run_apriltag(g, wi->width, wi->height, family, decimate,
		                   opt->threads > 0 ? opt->threads : 1, r, err);
	free(g);
	r->tag_seconds = now_seconds() - t0;
	if (ret)
		return ret;
	int nknown = 0, nforeign = 0, foreign[16];
	for (int i = 0; i < r->ntags; i++) {
		if (layout_tag_index(L, r->tags[i].id) >= 0)
			nknown++;
		else if (nforeign < 16)
			foreign[nforeign++] = r->tags[i].id;
	}
	if (nknown == 0) {
		if (r->ntags > 0) {
			char ids[200] = "";
			list_ints(ids, sizeof(ids), foreign, nforeign);
			return kg_fail(err, KG_ENOENT,
			               "no %s tag of layout %s in the image (found %d other tag%s: %s)",
			               family, L->name, r->ntags, r->ntags == 1 ? "" : "s", ids);
		}
		return kg_fail(err, KG_ENOENT,
		               "no %s tags found in the image: is the chart of layout %s in view, "
		               "lit and in focus?", family, L->name);
	}
	if (nforeign) {
		char ids[200] = "";
		list_ints(ids, sizeof(ids), foreign, nforeign);
		if ((ret = add_warning(r, "ignored %d tag%s not in layout %s: %s", nforeign,
		                       nforeign == 1 ? "" : "s", L->name, ids)))
			return kg_fail(err, ret, "out of memory");
	}
	if ((ret = select_tags(L, r, opt, err)))
		return ret;
	int used = 0, inconsistent = 0, missing = 0;
	int used_ids[64] = {0}, bad_ids[64] = {0}, missing_ids[64] = {0};
	for (int i = 0; i < r->ntags; i++) {
		if (r->tags[i].used && used < 64)
			used_ids[used++] = r->tags[i].id;
		else if (!r->tags[i].used && layout_tag_index(L, r->tags[i].id) >= 0 && inconsistent < 64)
			bad_ids[inconsistent++] = r->tags[i].id;
	}
	for (int j = 0; j < L->ntags; j++) {
		int seen = 0;
		for (int i = 0; i < r->ntags; i++)
			seen |= r->tags[i].used && r->tags[i].id == L->tag_ids[j];
		if (!seen && missing < 64)
			missing_ids[missing++] = L->tag_ids[j];
	}
	r->ntags_used = used;
	if (used < opt->min_tags) {
		char ids[200] = "";
		list_ints(ids, sizeof(ids), used_ids, used);
		return kg_fail(err, KG_ENOENT,
		               "only %d tag%s of layout %s found (%s); at least %d are needed to "
		               "place the patches", used, used == 1 ? "" : "s", L->name, ids,
		               opt->min_tags);
	}
	if (inconsistent) {
		char ids[200] = "";
		list_ints(ids, sizeof(ids), bad_ids, inconsistent);
		ret = add_warning(r, "ignored %d tag%s with ids of the layout that do not fit the "
		                  "chosen chart (another chart in the frame, or misread): %s",
		                  inconsistent, inconsistent == 1 ? "" : "s", ids);
		if (ret)
			return kg_fail(err, ret, "out of memory");
	}
	if (missing) {
		char ids[200] = "", uids[200] = "";
		list_ints(ids, sizeof(ids), missing_ids, missing);
		list_ints(uids, sizeof(uids), used_ids, used);
		if (used <= 3)
			ret = add_warning(r, "homography determined from %d tags' corners (%d points; "
			                  "tags %s); tag%s %s not found (occluded or out of frame): "
			                  "patch positions are less certain far from the tags found",
			                  used, 4 * used, uids, missing == 1 ? "" : "s", ids);
		else
			ret = add_warning(r, "tag%s %s of layout %s not found (occluded or out of frame)",
			                  missing == 1 ? "" : "s", ids, L->name);
		if (ret)
			return kg_fail(err, ret, "out of memory");
	}
	return 0;
#else
	(void)L;
	(void)wi;
	(void)opt;
	(void)r;
	return kg_fail(err, KG_ENOTSUP, "kogei was built without libapriltag: tag detection is "
	               "unavailable");
#endif
}

/* The layout as flat arrays. */
typedef struct layout_arrays {
	int *tag_ids;
	double (*tag_corners)[4][2];
	char **patch_ids;
	double (*patch_center)[2];
	double (*patch_size)[2];
} layout_arrays;

static void layout_arrays_free(layout_arrays *a)
{
	free(a->tag_ids);
	free(a->tag_corners);
	free(a->patch_ids);
	free(a->patch_center);
	free(a->patch_size);
}

static int make_view(const kg_chart_layout *l, layout_view *v, layout_arrays *a, kg_err *err)
{
	memset(v, 0, sizeof(*v));
	memset(a, 0, sizeof(*a));
	size_t nt = l->ntags > 0 ? (size_t)l->ntags : 1, np = l->npatches > 0 ? (size_t)l->npatches : 1;
	a->tag_ids = malloc(nt * sizeof(*a->tag_ids));
	a->tag_corners = malloc(nt * sizeof(*a->tag_corners));
	a->patch_ids = malloc(np * sizeof(*a->patch_ids));
	a->patch_center = malloc(np * sizeof(*a->patch_center));
	a->patch_size = malloc(np * sizeof(*a->patch_size));
	if (!a->tag_ids || !a->tag_corners || !a->patch_ids || !a->patch_center || !a->patch_size) {
		layout_arrays_free(a);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	for (int i = 0; i < l->ntags; i++) {
		a->tag_ids[i] = l->tags[i].id;
		memcpy(a->tag_corners[i], l->tags[i].corners_mm, sizeof(a->tag_corners[i]));
	}
	for (int i = 0; i < l->npatches; i++) {
		a->patch_ids[i] = (char *)l->patches[i].id;
		memcpy(a->patch_center[i], l->patches[i].center_mm, sizeof(a->patch_center[i]));
		memcpy(a->patch_size[i], l->patches[i].size_mm, sizeof(a->patch_size[i]));
	}
	v->name = l->name;
	v->family = l->family[0] ? l->family : NULL;
	v->ntags = l->ntags;
	v->tag_ids = a->tag_ids;
	v->tag_corners = (const double (*)[4][2])a->tag_corners;
	v->npatches = l->npatches;
	v->patch_ids = a->patch_ids;
	v->patch_center = (const double (*)[2])a->patch_center;
	v->patch_size = (const double (*)[2])a->patch_size;
	const double *ca = l->chart_area_mm;
	double o[4][2] = {{ca[0], ca[1]}, {ca[0] + ca[2], ca[1]}, {ca[0] + ca[2], ca[1] + ca[3]},
	                  {ca[0], ca[1] + ca[3]}};
	memcpy(v->outline, o, sizeof(o));
	return 0;
}

/* ---- tagless: OpenCV mcc ------------------------------------------------------ */

#if KG_HAVE_MCC
/* The patches of a ColorChecker 24 layout by chart position, row-major from A01
 * (dark skin) to D06 (black 2): 1 when the layout has exactly these 24 ids. */
static int colorchecker24_patches(const kg_chart_layout *l, int idx[24])
{
	if (l->npatches != 24)
		return 0;
	for (int i = 0; i < 24; i++) {
		char id[8];
		snprintf(id, sizeof(id), "%c%02d", 'A' + i / 6, i % 6 + 1);
		if ((idx[i] = kg_chart_layout_find_patch(l, id)) < 0)
			return 0;
	}
	return 1;
}

/* mcc's box in layout mm (tl, tr, br, bl as the chart is read, A01 top left): the
 * centres of A01, A06 and D01 give one pitch along a row and down a column, and the
 * box lies KG_MCC24_BOX_MARGIN_PITCH pitches beyond the outer patch centres. */
static void mcc24_box_mm(const layout_view *L, const int idx[24], double box[4][2])
{
	const double *a1 = L->patch_center[idx[0]], *a6 = L->patch_center[idx[5]],
	             *d1 = L->patch_center[idx[18]];
	double m = KG_MCC24_BOX_MARGIN_PITCH;
	double uv[4][2] = {{-m, -m}, {5 + m, -m}, {5 + m, 3 + m}, {-m, 3 + m}};
	for (int k = 0; k < 4; k++)
		for (int c = 0; c < 2; c++)
			box[k][c] = a1[c] + uv[k][0] * (a6[c] - a1[c]) / 5 + uv[k][1] * (d1[c] - a1[c]) / 3;
}

static double quad_signed_area(const double q[4][2])
{
	double a = 0;
	for (int k = 0; k < 4; k++)
		a += q[k][0] * q[(k + 1) % 4][1] - q[(k + 1) % 4][0] * q[k][1];
	return a / 2;
}

static void samples_free(kg_chart_sample *p, int n)
{
	for (int i = 0; p && i < n; i++)
		free(p[i].id);
	free(p);
}

static double patch_level(const kg_chart_sample *p)
{
	return p->rgb[0] + p->rgb[1] + p->rgb[2];
}

/* How far the sampled patches are from a ColorChecker read the right way up; lower
 * is better. One point for each step of the neutral row D01..D06 that does not
 * darken and for each patch brighter than the white D01 (a missing value counts as
 * wrong); plus the spread of log(r/g) and log(b/g) over D01..D05, which share one
 * chromaticity whatever the white balance; plus the mean non-uniformity, high when
 * the sampled regions straddle patches. */
static double orientation_score(const kg_chart_sample *p, const int idx[24])
{
	double score = 0;
	for (int k = 18; k < 23; k++)
		score += !(patch_level(&p[idx[k]]) >= patch_level(&p[idx[k + 1]]));
	for (int i = 0; i < 18; i++)
		score += !(patch_level(&p[idx[18]]) >= patch_level(&p[idx[i]]));
	double sum[2] = {0, 0}, sq[2] = {0, 0};
	for (int k = 18; k < 23; k++) {
		const double *c = p[idx[k]].rgb;
		if (!(c[0] > 0 && c[1] > 0 && c[2] > 0))
			return score + 10;
		double v[2] = {log(c[0] / c[1]), log(c[2] / c[1])};
		for (int j = 0; j < 2; j++) {
			sum[j] += v[j];
			sq[j] += v[j] * v[j];
		}
	}
	for (int j = 0; j < 2; j++)
		score += sqrt(fmax(sq[j] / 5 - (sum[j] / 5) * (sum[j] / 5), 0));
	double nonuniformity = 0;
	for (int i = 0; i < 24; i++)
		nonuniformity += isfinite(p[idx[i]].nonuniformity) ? p[idx[i]].nonuniformity : 1.0;
	return score + nonuniformity / 24;
}

/* Find a ColorChecker 24 without tags: mcc gives the box around its patches; the
 * homography from the box in layout mm to the box in the image places the patches,
 * which sample_all measures as on the tag path. Of the four ways the box's corners
 * can meet the chart's, the one whose patches look most like a ColorChecker read
 * the right way up (orientation_score) wins: mcc's own choice is not trusted. */
static int detect_tagless(const kg_chart_layout *l, const layout_view *L, const work_image *wi,
                          const kg_chart_detect_options *opt, kg_chart_result *r, kg_err *err)
{
	int idx[24];
	if (!colorchecker24_patches(l, idx))
		return kg_fail(err, KG_ENOTSUP, "layout %s is not a ColorChecker 24 (24 patches "
		               "A01..D06): the tagless detector (OpenCV mcc) finds only that chart",
		               l->name);
	/* mcc keeps only contours of at least 100 px (its minContourLengthAllowed), i.e.
	 * patches of 25 px: a ColorChecker 24 of 4 x 6 patches spans 100 px or more. */
	int ret = check_sides(wi->width, wi->height, MCC_MIN_SIDE, INT_MAX,
	                      "the tagless detector (OpenCV mcc)", NULL, err);
	if (ret)
		return ret;
	double t0 = now_seconds(), box_px[4][2], box_mm[4][2], cost = 0;
	ret = kg_mcc_find_colorchecker(wi->data, wi->width, wi->height, wi->channels,
	                               white_level(wi), opt->threads, box_px, &cost, err);
	r->tag_seconds += now_seconds() - t0;
	if (ret)
		return ret;
	r->tagless = 1;
	r->decimate = 0;
	r->rms_px = 0;
	mcc24_box_mm(L, idx, box_mm);
	/* A photograph does not mirror the chart: give mcc's corners the layout's winding. */
	if ((quad_signed_area(box_mm) > 0) != (quad_signed_area((const double (*)[2])box_px) > 0)) {
		double t[2] = {box_px[1][0], box_px[1][1]};
		memcpy(box_px[1], box_px[3], sizeof(t));
		memcpy(box_px[3], t, sizeof(t));
	}
	double score[4], H[4][9], angle[4];
	kg_chart_sample *sampled[4] = {NULL, NULL, NULL, NULL}; /* each turn's patches */
	int best = 0, upright = 0;
	for (int turn = 0; turn < 4; turn++) {
		double dst[4][2];
		for (int k = 0; k < 4; k++)
			memcpy(dst[k], box_px[(k + turn) % 4], sizeof(dst[k]));
		if ((ret = kg_homography_fit((const double (*)[2])box_mm, (const double (*)[2])dst, 4,
		                             0, H[turn], NULL, err)))
			break;
		memcpy(r->H, H[turn], sizeof(r->H));
		ret = sample_all(L, wi, opt, r, err);
		sampled[turn] = r->patches;
		r->patches = NULL;
		r->npatches = 0;
		if (ret)
			break;
		score[turn] = orientation_score(sampled[turn], idx);
		if (score[turn] < score[best])
			best = turn;
		double a1[2], a6[2];
		kg_homography_map(H[turn], L->patch_center[idx[0]][0], L->patch_center[idx[0]][1], a1);
		kg_homography_map(H[turn], L->patch_center[idx[5]][0], L->patch_center[idx[5]][1], a6);
		angle[turn] = atan2(a6[1] - a1[1], a6[0] - a1[0]) * 180 / M_PI;
		if (fabs(angle[turn]) < fabs(angle[upright]))
			upright = turn;
	}
	/* One step out of order or a patch brighter than the white: no turn reads as a
	 * ColorChecker (other colours on its geometry, such as an object's tiles, or bad
	 * light). Neither the patches nor mcc, whose choice also rests on the
	 * ColorChecker's colours, can then say which patch is which: refused. */
	int uncertain = !ret && score[best] >= 1;
	for (int turn = 0; turn < 4; turn++)
		if (ret || uncertain || turn != best)
			samples_free(sampled[turn], L->npatches);
	if (ret)
		return ret;
	if (uncertain)
		return kg_fail(err, KG_ENOENT,
		               "the tagless detector (OpenCV mcc, fit cost %.3g) found a box, but "
		               "its patches do not read as layout %s in any of its 4 turns: the "
		               "neutral row D01-D06 does not darken from D01, the brightest patch "
		               "(best score %.3f, a ColorChecker scores below 1). No ColorChecker "
		               "in view (other colours on its geometry), or light too uneven or "
		               "clipped to tell; row A01-A06 would run at %.0f degrees from the "
		               "image's x axis", cost, l->name, score[best], angle[upright]);
	r->patches = sampled[best];
	r->npatches = L->npatches;
	memcpy(r->H, H[best], sizeof(r->H));
	for (int k = 0; k < 4; k++)
		kg_homography_map(r->H, L->outline[k][0], L->outline[k][1], r->outline[k]);
	double next = INFINITY;
	for (int turn = 0; turn < 4; turn++)
		if (turn != best)
			next = fmin(next, score[turn]);
	ret = add_warning(r, "chart placed by the tagless detector (OpenCV mcc, fit cost "
	                  "%.3g) from the 4 corners of its box, not by tags; orientation "
	                  "chosen from the patches (neutral row D01-D06 darkening from D01, "
	                  "the brightest patch): score %.3f, next best of the 4 turns %.3f, "
	                  "%s mcc's own; row A01-A06 runs at %.0f degrees clockwise from the "
	                  "image's x axis", cost, score[best], next,
	                  best == 0 ? "agreeing with" : "overruling", angle[best]);
	return ret ? kg_fail(err, ret, "out of memory") : 0;
}
#else
static int detect_tagless(const kg_chart_layout *l, const layout_view *L, const work_image *wi,
                          const kg_chart_detect_options *opt, kg_chart_result *r, kg_err *err)
{
	(void)L;
	(void)wi;
	(void)opt;
	(void)r;
	if (l->ntags == 0)
		return kg_fail(err, KG_ENOTSUP, "layout %s has no tags: it can only be found by the "
		               "tagless detector (OpenCV mcc), not available in this build", l->name);
	return kg_fail(err, KG_ENOTSUP, "tagless detection (OpenCV mcc) is not available in "
	               "this build");
}
#endif

/* No tags seen at all: a ColorChecker may still be in view without its frame. */
static int tagless_fallback(const kg_chart_layout *l, const kg_chart_result *r, int ret)
{
#if KG_HAVE_MCC
	int idx[24];
	return (ret == KG_ENOENT || ret == KG_ENOTSUP) && r->ntags == 0 &&
	       colorchecker24_patches(l, idx);
#else
	(void)l;
	(void)r;
	(void)ret;
	return 0;
#endif
}

int kg_chart_detect(const kg_chart_layout *l, const kg_image *img,
                    const kg_chart_detect_options *options, kg_chart_result **out,
                    kg_err *err)
{
	kg_check_arg(l && img && img->data && out, err);
	*out = NULL;
	double t0 = now_seconds();
	kg_chart_detect_options opt;
	if (options)
		opt = *options;
	else
		kg_chart_detect_options_default(&opt);
	if (!(opt.sample_fraction > 0))
		opt.sample_fraction = l->sample_fraction > 0 ? l->sample_fraction : 0.6;
	if (opt.sample_fraction > 1 || opt.trim < 0 || opt.trim >= 0.5 || opt.decimate < 0 ||
	    opt.min_tags < 0)
		return kg_fail(err, KG_EINVAL, "chart detection: sample fraction %g (expected "
		               "0..1), trim %g (0..0.5), decimate %d (>= 0) or min tags %d (>= 0) "
		               "out of range", opt.sample_fraction, opt.trim, opt.decimate,
		               opt.min_tags);
	/* min_tags 0: the default of 2 tags, with the ColorChecker fallback. */
	int fallback = opt.min_tags == 0;
	if (fallback)
		opt.min_tags = 2;
	if (l->npatches < 1)
		return kg_fail(err, KG_EINVAL, "layout %s has no patches", l->name);
	/* the sampler's pixel indexing, for images that did not come from core's readers */
	int ret = check_sides(img->width, img->height, 1, INT_MAX, "chart detection",
	                      NULL, err);
	if (ret)
		return ret;
	layout_view L;
	layout_arrays arrays;
	ret = make_view(l, &L, &arrays, err);
	if (ret)
		return ret;
	work_image wi;
	kg_chart_result *r = calloc(1, sizeof(*r));
	if (!r) {
		layout_arrays_free(&arrays);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	snprintf(r->layout, sizeof(r->layout), "%s", l->name);
	if ((ret = prepare_image(img, &opt, &wi, err)))
		goto fail;
	int tagless = opt.tagless || l->ntags == 0;
	if (!tagless) {
		kg_err tag_err = {{0}};
		ret = detect_with_tags(&L, &wi, &opt, r, &tag_err);
		if (ret && fallback && tagless_fallback(l, r, ret)) {
			kg_err mcc_err = {{0}};
			ret = detect_tagless(l, &L, &wi, &opt, r, &mcc_err);
			if (ret)
				kg_fail(err, ret, "%s; %s", tag_err.msg, mcc_err.msg);
			else if (add_warning(r, "%s: fell back to the tagless detector", tag_err.msg))
				ret = kg_fail(err, KG_ENOMEM, "out of memory");
		} else if (ret) {
			kg_fail(err, ret, "%s", tag_err.msg);
		} else {
			ret = sample_all(&L, &wi, &opt, r, err);
		}
		if (ret)
			goto fail;
	} else if ((ret = detect_tagless(l, &L, &wi, &opt, r, err))) {
		goto fail;
	}
	if ((ret = patch_summary_warnings(r))) {
		ret = kg_fail(err, ret, "out of memory");
		goto fail;
	}
	r->total_seconds = now_seconds() - t0;
	free(wi.owned);
	layout_arrays_free(&arrays);
	*out = r;
	return 0;
fail:
	free(wi.owned);
	layout_arrays_free(&arrays);
	kg_chart_result_free(&r);
	return ret;
}

int kg_chart_result_patchset(const kg_chart_result *r, kg_patchset **out, kg_err *err)
{
	kg_check_arg(r && out, err);
	static const char *const extra[] = {"RGB_R_SD", "RGB_G_SD", "RGB_B_SD", "CLIPPED_FRACTION",
	                                    "NONUNIFORMITY", "PIXELS", "FLAGS"};
	int n = 0;
	for (int i = 0; i < r->npatches; i++)
		n += !(r->patches[i].flags & KG_CHART_FLAG_REJECTED);
	if (n == 0)
		return kg_fail(err, KG_ENOENT, "chart %s: no patch could be sampled", r->layout);
	kg_patchset *ps = NULL;
	int ret = kg_patchset_new(n, KG_PATCH_RGB, &ps, err);
	for (int k = 0; k < 7 && !ret; k++)
		ret = kg_patchset_add_extra(ps, extra[k], err);
	int j = 0;
	for (int i = 0; i < r->npatches && !ret; i++) {
		const kg_chart_sample *p = &r->patches[i];
		if (p->flags & KG_CHART_FLAG_REJECTED)
			continue;
		if ((ret = kg_patchset_set_id(ps, j, p->id, err)))
			break;
		double *e = ps->extra + (size_t)j * ps->nextra;
		for (int c = 0; c < 3; c++) {
			ps->rgb[j][c] = p->rgb[c];
			e[c] = p->sd[c];
		}
		e[3] = p->clipped_fraction;
		e[4] = p->nonuniformity;
		e[5] = (double)p->pixels;
		e[6] = p->flags;
		j++;
	}
	if (ret) {
		kg_patchset_free(&ps);
		return ret;
	}
	*out = ps;
	return 0;
}

/* ---- overlay ----------------------------------------------------------------- */

static void path_quad(cairo_t *cr, const double q[4][2], double s)
{
	cairo_move_to(cr, q[0][0] * s, q[0][1] * s);
	for (int k = 1; k < 4; k++)
		cairo_line_to(cr, q[k][0] * s, q[k][1] * s);
	cairo_close_path(cr);
}

static void label(cairo_t *cr, double x, double y, double size, const char *text,
                  double r, double g, double b)
{
	cairo_text_extents_t ext;
	cairo_set_font_size(cr, size);
	cairo_text_extents(cr, text, &ext);
	double tx = x - ext.width / 2 - ext.x_bearing, ty = y - ext.height / 2 - ext.y_bearing;
	cairo_move_to(cr, tx, ty);
	cairo_text_path(cr, text);
	cairo_set_source_rgb(cr, 0, 0, 0);
	cairo_set_line_width(cr, fmax(1.5, size / 6));
	cairo_stroke(cr);
	cairo_move_to(cr, tx, ty);
	cairo_set_source_rgb(cr, r, g, b);
	cairo_show_text(cr, text);
}

int kg_chart_overlay_write(const kg_chart_result *r, const kg_image *img, const char *path,
                           int max_side, kg_err *err)
{
	kg_check_arg(r && img && img->data && path, err);
	if (max_side <= 0)
		max_side = 1600;
	kg_chart_detect_options opt;
	kg_chart_detect_options_default(&opt);
	work_image wi;
	int ret = prepare_image(img, &opt, &wi, err);
	if (ret)
		return ret;
	double scale_px;
	unsigned char *g = NULL;
	int big = img->width > img->height ? img->width : img->height;
	int step = (big + max_side - 1) / max_side;
	if (step < 1)
		step = 1;
	int W = (img->width + step - 1) / step, Hh = (img->height + step - 1) / step;
	double s = 1.0 / step;
	cairo_surface_t *surf = cairo_image_surface_create(CAIRO_FORMAT_RGB24, W, Hh);
	cairo_t *cr = cairo_create(surf);
	unsigned char *rgb = malloc((size_t)W * Hh * 3);
	if (cairo_status(cr) != CAIRO_STATUS_SUCCESS || !rgb) {
		ret = kg_fail(err, KG_ENOMEM, "overlay: out of memory");
		goto done;
	}
	/* Background: each output pixel is the mean of its step x step block, with the
	 * exposure normalisation of the tag detector, sRGB-encoded. */
	g = grey8(&wi, &scale_px);
	if (!g) {
		ret = kg_fail(err, KG_ENOMEM, "overlay: out of memory");
		goto done;
	}
	cairo_surface_flush(surf);
	unsigned char *dst = cairo_image_surface_get_data(surf);
	int stride = cairo_image_surface_get_stride(surf);
	for (int y = 0; y < Hh; y++) {
		for (int x = 0; x < W; x++) {
			double acc[3] = {0, 0, 0};
			int cnt = 0;
			for (int yy = y * step; yy < (y + 1) * step && yy < img->height; yy++)
				for (int xx = x * step; xx < (x + 1) * step && xx < img->width; xx++) {
					const float *p = wi.data + ((size_t)yy * wi.width + xx) * wi.channels;
					for (int c = 0; c < 3; c++)
						acc[c] += p[wi.channels == 3 ? c : 0];
					cnt++;
				}
			uint32_t pix = 0;
			for (int c = 0; c < 3; c++) {
				double v = fmin(fmax(acc[c] / cnt * scale_px, 0), 1);
				v = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
				pix = (pix << 8) | (uint32_t)lrint(v * 255);
			}
			memcpy(dst + (size_t)y * stride + 4 * x, &pix, 4);
		}
	}
	cairo_surface_mark_dirty(surf);
	cairo_select_font_face(cr, "DejaVu Sans", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_BOLD);
	double lw = fmax(1.5, W / 800.0);
	double font = fmax(10, W / 90.0);
	/* chart outline */
	if (r->npatches > 0) {
		cairo_set_source_rgb(cr, 0.2, 0.6, 1.0);
		cairo_set_line_width(cr, lw);
		path_quad(cr, r->outline, s);
		cairo_stroke(cr);
	}
	for (int i = 0; i < r->ntags; i++) {
		const kg_chart_tag_found *t = &r->tags[i];
		if (t->used)
			cairo_set_source_rgb(cr, 0.1, 0.9, 0.2);
		else
			cairo_set_source_rgb(cr, 1.0, 0.55, 0.0);
		cairo_set_line_width(cr, 1.5 * lw);
		path_quad(cr, t->corners, s);
		cairo_stroke(cr);
		double cx = 0, cy = 0;
		for (int k = 0; k < 4; k++) {
			cx += t->corners[k][0] * s / 4;
			cy += t->corners[k][1] * s / 4;
		}
		char txt[32];
		snprintf(txt, sizeof(txt), "%d%s", t->id, t->used ? "" : "?");
		label(cr, cx, cy, font * 1.2, txt, t->used ? 0.1 : 1.0, t->used ? 0.9 : 0.55,
		      t->used ? 0.2 : 0.0);
	}
	for (int i = 0; i < r->npatches; i++) {
		const kg_chart_sample *p = &r->patches[i];
		int bad = p->flags != 0;
		if (bad)
			cairo_set_source_rgb(cr, 1, 0.1, 0.1);
		else
			cairo_set_source_rgb(cr, 1, 1, 1);
		cairo_set_line_width(cr, bad ? 2 * lw : lw);
		path_quad(cr, p->quad, s);
		cairo_stroke(cr);
		if (p->flags & (KG_CHART_FLAG_REJECTED | KG_CHART_FLAG_CLIPPED |
		                KG_CHART_FLAG_GLARE)) {
			cairo_move_to(cr, p->quad[0][0] * s, p->quad[0][1] * s);
			cairo_line_to(cr, p->quad[2][0] * s, p->quad[2][1] * s);
			cairo_move_to(cr, p->quad[1][0] * s, p->quad[1][1] * s);
			cairo_line_to(cr, p->quad[3][0] * s, p->quad[3][1] * s);
			cairo_stroke(cr);
		}
		double cx = 0, cy = 0;
		for (int k = 0; k < 4; k++) {
			cx += p->quad[k][0] * s / 4;
			cy += p->quad[k][1] * s / 4;
		}
		label(cr, cx, cy, font, p->id, bad ? 1 : 1, bad ? 0.3 : 1, bad ? 0.3 : 1);
		if (bad) {
			char why[32];
			snprintf(why, sizeof(why), "%s",
			         p->flags & KG_CHART_FLAG_REJECTED ? "rejected"
			         : p->flags & KG_CHART_FLAG_CLIPPED ? "clipped"
			         : p->flags & KG_CHART_FLAG_GLARE ? "glare"
			         : p->flags & KG_CHART_FLAG_OUT_OF_FRAME ? "out of frame"
			         : p->flags & KG_CHART_FLAG_NONUNIFORM ? "non-uniform" : "few pixels");
			label(cr, cx, cy + font * 1.1, font * 0.8, why, 1, 0.3, 0.3);
		}
	}
	char title[160];
	snprintf(title, sizeof(title), "%s: %d tags used, RMS %.2f px%s", r->layout, r->ntags_used,
	         r->rms_px, r->tagless ? " (tagless)" : "");
	cairo_set_font_size(cr, font);
	cairo_move_to(cr, font * 0.5 + 1, font * 1.5 + 1);
	cairo_set_source_rgb(cr, 0, 0, 0);
	cairo_show_text(cr, title);
	cairo_move_to(cr, font * 0.5, font * 1.5);
	cairo_set_source_rgb(cr, 1, 1, 0.3);
	cairo_show_text(cr, title);
	cairo_surface_flush(surf);
	for (int y = 0; y < Hh; y++)
		for (int x = 0; x < W; x++) {
			uint32_t pix;
			memcpy(&pix, dst + (size_t)y * stride + 4 * x, 4);
			unsigned char *o = rgb + ((size_t)y * W + x) * 3;
			o[0] = (pix >> 16) & 255;
			o[1] = (pix >> 8) & 255;
			o[2] = pix & 255;
		}
	ret = kg_png_write_rgb8(path, rgb, W, Hh, err);
done:
	free(g);
	free(rgb);
	cairo_destroy(cr);
	cairo_surface_destroy(surf);
	free(wi.owned);
	return ret;
}
