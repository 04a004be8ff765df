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
#include <pthread.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include <cairo.h>

#include "calib_private.h"
#include "kg_calib.h"
#include "kg_config.h"

#if KG_HAVE_MCC
#include "chart_mcc.h"
#define MCC_MIN_SIDE 100L
/* The tagless detector's orientation (orientation_score): the best of the 4 turns
 * must fit the layout's colours with an RMS sine below KG_ORIENT_SCORE_MAX, be
 * KG_ORIENT_MARGIN times better than the next, and its patches must spread by more
 * than KG_ORIENT_SPREAD_MIN (RMS sine from their mean direction). */
#define KG_ORIENT_SCORE_MAX 0.15
#define KG_ORIENT_MARGIN 1.5
#define KG_ORIENT_SPREAD_MIN 0.05
/* mcc's candidate boxes tried, its best first */
#define MCC_CANDIDATES 3
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
	o->light_field = 1;
	o->max_light_variation = 0;
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
	free(r->candidates);
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

/* ---- threads ----------------------------------------------------------------- */

/* fn(arg, t, n) for t = 0..n-1, t = 0 on the caller's thread. Every caller splits its
 * work by t into pieces whose results do not depend on n, so any thread count gives
 * the same numbers. A thread that cannot be started has its share run here. */
typedef void (*par_fn)(void *arg, int t, int n);

typedef struct par_job {
	par_fn fn;
	void *arg;
	int t, n;
} par_job;

static void *par_main(void *p)
{
	par_job *j = p;
	j->fn(j->arg, j->t, j->n);
	return NULL;
}

enum { MAX_THREADS = 64 };

static int clamp_threads(int threads)
{
	return threads < 1 ? 1 : threads > MAX_THREADS ? MAX_THREADS : threads;
}

static void run_parallel(par_fn fn, void *arg, int threads)
{
	int n = clamp_threads(threads);
	pthread_t tid[MAX_THREADS];
	par_job job[MAX_THREADS];
	int started[MAX_THREADS] = {0};
	for (int t = 1; t < n; t++) {
		job[t] = (par_job){fn, arg, t, n};
		started[t] = pthread_create(&tid[t], NULL, par_main, &job[t]) == 0;
	}
	fn(arg, 0, n);
	for (int t = 1; t < n; t++) {
		if (started[t])
			pthread_join(tid[t], NULL);
		else
			fn(arg, t, n);
	}
}

/* ---- the image as the sampler sees it ---------------------------------------- */

/* Interleaved linear floats with 1 or 3 channels. A raw CFA frame is not demosaiced
 * as a whole: the stages read it through image_span, which demosaics the pixels they
 * ask for (the patch regions, every 4th pixel for the white level, the rows of the
 * grey picture), so only what is looked at is converted. */
typedef struct work_image {
	int width, height, channels;
	const float *data; /* NULL for a raw CFA frame until demosaic_all */
	float *owned;
	const kg_image *raw; /* the CFA frame, or NULL */
	int cfa_rows, cfa_cols;
	int colour[64];      /* the CFA repeat's filters: 0 R, 1 G, 2 B */
	/* Per CFA phase, each colour's neighbours in the 3 x 3 window, in raster order, as
	 * offsets in the frame (dy W + dx): the interior pixels' sums without the edge
	 * clamping. */
	ptrdiff_t nb[64][3][9];
	int nbn[64][3];
	double clip_level;
	double clip_ch[3];   /* per colour: the clip level, or the saturation found from the
	                      * data below it (core/saturation.h) */
	char sat_note[200];  /* where saturation was found below full scale, else "" */
	double quantum; /* step between the source's integer codes (0: float or demosaiced) */
	/* Values times count_scale land near integers, distinct values on distinct ones
	 * (integer codes, and the halves and quarters of raw codes that demosaicing
	 * averages), so the sampler can count them; 0 for float images. */
	float count_scale;
	int threads;
} work_image;

/* Bilinear demosaic: each missing colour is the mean of the 3 x 3 neighbours that
 * carry it, edges clamped. This is one pixel (x, y) anywhere, into o (RGB). */
static void demosaic_clamped(const work_image *wi, int y, int x, float *o)
{
	const kg_image *raw = wi->raw;
	int W = raw->width, Hh = raw->height, cr = wi->cfa_rows, cc = wi->cfa_cols;
	const float *d = raw->data;
	double sum[3] = {0, 0, 0};
	int cnt[3] = {0, 0, 0};
	for (int dy = -1; dy <= 1; dy++) {
		int yy = y + dy < 0 ? 0 : y + dy >= Hh ? Hh - 1 : y + dy;
		for (int dx = -1; dx <= 1; dx++) {
			int xx = x + dx < 0 ? 0 : x + dx >= W ? W - 1 : x + dx;
			int c = wi->colour[(yy % cr) * cc + xx % cc];
			sum[c] += d[(size_t)yy * W + xx];
			cnt[c]++;
		}
	}
	int own = wi->colour[(y % cr) * cc + x % cc];
	for (int c = 0; c < 3; c++)
		o[c] = c == own ? d[(size_t)y * W + x] : (cnt[c] ? (float)(sum[c] / cnt[c]) : 0.0f);
}

/* Interior pixels x, x + step, ... (n of them, all with a neighbour on each side) of
 * row y: the phase's neighbour lists, summed in the clamped loop's order, so both give
 * the same values. A mean of 1, 2, 4 or 8 (every 2 x 2 pattern's) is a multiply by
 * the exact reciprocal, equal to the division. */
static void demosaic_interior(const work_image *wi, int y, int x, int n, int step, float *o)
{
	static const double recip[9] = {0, 1, 0.5, 0, 0.25, 0, 0, 0, 0.125};
	const float *row = wi->raw->data + (size_t)y * wi->raw->width;
	int cc = wi->cfa_cols, base = (y % wi->cfa_rows) * cc, px = x % cc, dpx = step % cc;
	for (int i = 0; i < n; i++, x += step, o += 3) {
		int phase = base + px, own = wi->colour[phase];
		const float *p = row + x;
		for (int c = 0; c < 3; c++) {
			int k = wi->nbn[phase][c];
			const ptrdiff_t *off = wi->nb[phase][c];
			if (c == own) {
				o[c] = *p;
				continue;
			}
			double sum = 0;
			switch (k) {
			case 4:
				sum += p[off[0]];
				sum += p[off[1]];
				sum += p[off[2]];
				sum += p[off[3]];
				break;
			case 2:
				sum += p[off[0]];
				sum += p[off[1]];
				break;
			default:
				for (int j = 0; j < k; j++)
					sum += p[off[j]];
			}
			o[c] = !k ? 0.0f : recip[k] != 0 ? (float)(sum * recip[k]) : (float)(sum / k);
		}
		px += dpx;
		if (px >= cc)
			px -= cc;
	}
}

/* Bilinear demosaic of pixels x0, x0 + step, ... (n of them) of row y into out (RGB):
 * the runs of interior pixels through demosaic_interior, the edges clamped. */
static void demosaic_span(const work_image *wi, int y, int x0, int n, int step, float *out)
{
	int W = wi->raw->width, Hh = wi->raw->height;
	int inner_row = y > 0 && y < Hh - 1;
	for (int i = 0; i < n;) {
		int x = x0 + i * step;
		if (!inner_row || x == 0 || x >= W - 1) {
			demosaic_clamped(wi, y, x, out + (size_t)i * 3);
			i++;
			continue;
		}
		int m = (W - 2 - x) / step + 1;
		if (m > n - i)
			m = n - i;
		demosaic_interior(wi, y, x, m, step, out + (size_t)i * 3);
		i += m;
	}
}

/* Pixels x0, x0 + step, ... (n of them) of row y, interleaved: a pointer into the
 * image, or into scratch (n * 3 floats) where they had to be gathered or demosaiced. */
static const float *image_span(const work_image *wi, int y, int x0, int n, int step,
                               float *scratch)
{
	int C = wi->channels;
	if (wi->data && step == 1)
		return wi->data + ((size_t)y * wi->width + x0) * C;
	if (!wi->data) {
		demosaic_span(wi, y, x0, n, step, scratch);
		return scratch;
	}
	for (int i = 0; i < n; i++)
		for (int c = 0; c < C; c++)
			scratch[(size_t)i * C + c] = wi->data[((size_t)y * wi->width + x0 + i * step) * C + c];
	return scratch;
}

typedef struct demosaic_job {
	work_image *wi;
	float *out;
} demosaic_job;

static void demosaic_rows(void *arg, int t, int n)
{
	demosaic_job *j = arg;
	int H = j->wi->height, W = j->wi->width;
	for (int y = (int)((long)H * t / n); y < (int)((long)H * (t + 1) / n); y++)
		demosaic_span(j->wi, y, 0, W, 1, j->out + (size_t)y * W * 3);
}

/* The whole frame demosaiced, for the stages that need every pixel (the overlay, mcc
 * at full resolution). */
static int demosaic_all(work_image *wi, kg_err *err)
{
	if (wi->data)
		return 0;
	wi->owned = malloc((size_t)wi->width * wi->height * 3 * sizeof(float));
	if (!wi->owned)
		return kg_fail(err, KG_ENOMEM, "demosaic: out of memory");
	demosaic_job j = {wi, wi->owned};
	run_parallel(demosaic_rows, &j, wi->threads);
	wi->data = wi->owned;
	return 0;
}

static int prepare_image(const kg_image *img, const kg_chart_detect_options *opt,
                         work_image *wi, kg_err *err)
{
	memset(wi, 0, sizeof(*wi));
	wi->width = img->width;
	wi->height = img->height;
	wi->channels = img->channels;
	wi->data = img->data;
	wi->threads = clamp_threads(opt->threads);
	if (opt->clip_level > 0)
		wi->clip_level = opt->clip_level;
	else if (img->is_float || img->bits <= 0 || img->bits > 16)
		wi->clip_level = 1.0;
	else
		wi->clip_level = 1.0 - 0.5 / (double)((1L << img->bits) - 1);
	for (int c = 0; c < 3; c++)
		wi->clip_ch[c] = wi->clip_level;
	kg_saturation sat;
	int ret0;
	if (!(opt->clip_level > 0) && (img->channels == 3 || img->channels == 1) &&
	    (ret0 = kg_saturation_of_image(img, wi->clip_level, &sat, err)))
		return ret0;
	if (!(opt->clip_level > 0) && kg_saturation_below(&sat, wi->clip_level)) {
		/* each colour clips where its samples pile up (a mosaic's sites by colour) */
		int mosaic = sat.channels == 4 && img->cfa && strlen(img->cfa) >= 4;
		for (int k = 0; k < sat.channels; k++) {
			int c = !mosaic ? (img->channels == 1 ? -1 : k)
			        : img->cfa[k] == 'R' ? 0 : img->cfa[k] == 'G' ? 1 : img->cfa[k] == 'B' ? 2 : -1;
			for (int cc = 0; cc < 3; cc++)
				if ((c < 0 || cc == c) && sat.clip[k] < wi->clip_ch[cc])
					wi->clip_ch[cc] = sat.clip[k];
		}
		kg_saturation_format(&sat, mosaic ? img->cfa : img->channels == 1 ? "Y" : "RGB",
		                     wi->sat_note, sizeof(wi->sat_note));
	}
	if (!img->is_float && img->bits > 0 && img->bits <= 16) {
		wi->quantum = 1.0 / (double)((1L << img->bits) - 1);
		wi->count_scale = (float)((1L << img->bits) - 1);
	}
	if (img->channels == 1 && img->cfa) {
		int cr = img->cfa_rows, cc = img->cfa_cols;
		if (cr < 1 || cc < 1 || cr * cc > 64)
			return kg_fail(err, KG_ENOTSUP, "CFA repeat of %dx%d is too large", cr, cc);
		for (int k = 0; k < cr * cc; k++) {
			const char *p = strchr("RGB", img->cfa[k]);
			if (!p || !img->cfa[k])
				return kg_fail(err, KG_ENOTSUP,
				               "CFA pattern %.*s: only R, G and B filters can be demosaiced",
				               cr * cc, img->cfa);
			wi->colour[k] = (int)(p - "RGB");
		}
		for (int py = 0; py < cr; py++)
			for (int px = 0; px < cc; px++) {
				int phase = py * cc + px;
				for (int dy = -1; dy <= 1; dy++)
					for (int dx = -1; dx <= 1; dx++) {
						int c = wi->colour[((py + dy + cr) % cr) * cc + (px + dx + cc) % cc];
						wi->nb[phase][c][wi->nbn[phase][c]++] =
						    (ptrdiff_t)dy * img->width + dx;
					}
			}
		wi->raw = img;
		wi->cfa_rows = cr;
		wi->cfa_cols = cc;
		wi->channels = 3;
		wi->data = NULL;
		wi->quantum = 0;
		wi->count_scale *= 4;
	} else if (img->channels != 1 && img->channels != 3) {
		return kg_fail(err, KG_EINVAL, "image has %d channels: expected 1 or 3",
		               img->channels);
	}
	return 0;
}

static double luminance(const float *p, int channels)
{
	if (channels == 1)
		return p[0];
	return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
}

enum { GREY_BINS = 4096, WHITE_STEP = 4 };

typedef struct white_job {
	const work_image *wi;
	long (*hist)[GREY_BINS];
	int failed;
} white_job;

static const double WHITE_TOP = 4.0; /* the white level's histogram spans 0..4 */

static int white_bin(double y)
{
	return y <= 0 || !isfinite(y) ? 0 : y >= WHITE_TOP ? GREY_BINS - 1
	                                                   : (int)(y / WHITE_TOP * GREY_BINS);
}

/* The 99.5th percentile of the n threads' histograms (summed into hist[0]); 1 if it
 * is 0. */
static double white_of(long (*hist)[GREY_BINS], int n)
{
	long total = 0, acc = 0;
	for (int t = 1; t < n; t++)
		for (int b = 0; b < GREY_BINS; b++)
			hist[0][b] += hist[t][b];
	for (int b = 0; b < GREY_BINS; b++)
		total += hist[0][b];
	double white = 1.0;
	for (int b = 0; b < GREY_BINS; b++) {
		acc += hist[0][b];
		if (acc >= 0.995 * total) {
			white = (b + 1) * WHITE_TOP / GREY_BINS;
			break;
		}
	}
	return white > 1e-6 ? white : 1.0;
}

static void white_rows(void *arg, int t, int n)
{
	white_job *j = arg;
	const work_image *wi = j->wi;
	int cols = (wi->width + WHITE_STEP - 1) / WHITE_STEP;
	int rows = (wi->height + WHITE_STEP - 1) / WHITE_STEP;
	float *scratch = malloc((size_t)cols * 3 * sizeof(float));
	long *hist = j->hist[t];
	if (!scratch) {
		j->failed = 1;
		return;
	}
	for (int r = (int)((long)rows * t / n); r < (int)((long)rows * (t + 1) / n); r++) {
		const float *p = image_span(wi, r * WHITE_STEP, 0, cols, WHITE_STEP, scratch);
		for (int i = 0; i < cols; i++) {
			hist[white_bin(luminance(p + (size_t)i * wi->channels, wi->channels))]++;
		}
	}
	free(scratch);
}

/* The exposure shown as white to the detectors: the 99.5th percentile of the
 * luminance (a histogram over 0..4 of full scale of every 4th pixel of every 4th row,
 * 1/16 of the image); 1 if that is 0, or if memory ran out. */
static double white_level(const work_image *wi)
{
	int n = wi->threads;
	white_job j = {wi, calloc((size_t)n, sizeof(*j.hist)), 0};
	if (!j.hist)
		return 1.0;
	run_parallel(white_rows, &j, n);
	double white = j.failed ? 1.0 : white_of(j.hist, n);
	free(j.hist);
	return white;
}

/* value / white through the sRGB curve, as 8 bits, in GREY_BINS steps over 0..1 */
static void srgb_lut(unsigned char lut[GREY_BINS])
{
	for (int b = 0; b < GREY_BINS; b++) {
		double v = (b + 0.5) / GREY_BINS;
		double e = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
		lut[b] = (unsigned char)lrint(fmin(fmax(e, 0), 1) * 255);
	}
}

/* The 8-bit code of a luminance already scaled to the table's GREY_BINS steps. */
static unsigned char grey_code(const unsigned char lut[GREY_BINS], float v)
{
	return lut[!(v > 0) ? 0 : v >= GREY_BINS - 1 ? GREY_BINS - 1 : (int)v];
}

typedef struct grey_job {
	const work_image *wi;
	int step, gw, gh; /* every step-th pixel of every step-th row: gw x gh */
	unsigned char *g, lut[GREY_BINS];
	float k;
	int failed;
} grey_job;

static void grey_rows(void *arg, int t, int n)
{
	grey_job *j = arg;
	const work_image *wi = j->wi;
	int gw = j->gw, C = wi->channels;
	int direct = wi->data && j->step == 1;
	float *scratch = direct ? NULL : malloc((size_t)gw * 3 * sizeof(float));
	if (!direct && !scratch) {
		j->failed = 1;
		return;
	}
	const float k = j->k;
	for (int y = (int)((long)j->gh * t / n); y < (int)((long)j->gh * (t + 1) / n); y++) {
		const float *p = image_span(wi, y * j->step, 0, gw, j->step, scratch);
		unsigned char *o = j->g + (size_t)y * gw;
		for (int x = 0; x < gw; x++) {
			const float *q = p + (size_t)x * C;
			float v = (C == 1 ? q[0] : 0.2126f * q[0] + 0.7152f * q[1] + 0.0722f * q[2]) * k;
			o[x] = grey_code(j->lut, v);
		}
	}
	free(scratch);
}

/* An 8-bit grey picture for tag detection and the overlay: luminance scaled so its
 * 99.5th percentile is white, then sRGB-encoded (a lookup table of 4096 steps), in
 * bands of rows over the threads. step 2: every 2nd pixel of every 2nd row only
 * (*gw x *gh), whose every 2nd pixel and row are the ones white_level reads. */
static unsigned char *grey8(const work_image *wi, int step, int *gw, int *gh,
                            double *scale_out)
{
	grey_job j = {.wi = wi, .step = step, .gw = (wi->width + step - 1) / step,
	              .gh = (wi->height + step - 1) / step};
	size_t n = (size_t)j.gw * j.gh;
	if (!(j.g = malloc(n ? n : 1)))
		return NULL;
	double white = white_level(wi);
	srgb_lut(j.lut);
	j.k = (float)(GREY_BINS / white);
	run_parallel(grey_rows, &j, wi->threads);
	if (j.failed) {
		free(j.g);
		return NULL;
	}
	*gw = j.gw;
	*gh = j.gh;
	*scale_out = 1.0 / white;
	return j.g;
}

#if HAVE_APRILTAG /* the tags' grey picture of a mosaic */
/* A 2 x 2 CFA holding R, G and B: each 2 x 2 block's luminance is a weighted sum of
 * its four pixels (each filter's coefficient shared among the pixels behind it), so
 * the tags can be looked for on a half-resolution grey picture built straight from the
 * mosaic, without demosaicing. Returns 0 and the weights, or -1 for other CFAs. */
static int block_weights(const work_image *wi, float w[4])
{
	static const float coef[3] = {0.2126f, 0.7152f, 0.0722f};
	int count[3] = {0, 0, 0};
	if (!wi->raw || wi->cfa_rows != 2 || wi->cfa_cols != 2)
		return -1;
	for (int k = 0; k < 4; k++)
		count[wi->colour[k]]++;
	if (!count[0] || !count[1] || !count[2])
		return -1;
	for (int k = 0; k < 4; k++)
		w[k] = coef[wi->colour[k]] / (float)count[wi->colour[k]];
	return 0;
}

typedef struct binned_job {
	const work_image *wi;
	float w[4];
	int bw, bh; /* the blocks: bw x bh */
	long (*hist)[GREY_BINS];
	unsigned char *g, lut[GREY_BINS];
	float k;
} binned_job;

static float block_luminance(const binned_job *j, const float *r0, const float *r1, int bx)
{
	return j->w[0] * r0[2 * bx] + j->w[1] * r0[2 * bx + 1] + j->w[2] * r1[2 * bx] +
	       j->w[3] * r1[2 * bx + 1];
}

/* The white level's histogram over every 2nd block of every 2nd block row (1/16 of the
 * pixels, as white_level takes of a demosaiced frame). */
static void binned_white_rows(void *arg, int t, int n)
{
	binned_job *j = arg;
	const float *d = j->wi->raw->data;
	int W = j->wi->width, rows = (j->bh + 1) / 2;
	long *hist = j->hist[t];
	for (int r = (int)((long)rows * t / n); r < (int)((long)rows * (t + 1) / n); r++) {
		const float *r0 = d + (size_t)(4 * r) * W, *r1 = r0 + W;
		for (int bx = 0; bx < j->bw; bx += 2)
			hist[white_bin(block_luminance(j, r0, r1, bx))]++;
	}
}

static void binned_grey_rows(void *arg, int t, int n)
{
	binned_job *j = arg;
	const float *d = j->wi->raw->data;
	int W = j->wi->width;
	const float k = j->k;
	for (int by = (int)((long)j->bh * t / n); by < (int)((long)j->bh * (t + 1) / n); by++) {
		const float *r0 = d + (size_t)(2 * by) * W, *r1 = r0 + W;
		unsigned char *o = j->g + (size_t)by * j->bw;
		for (int bx = 0; bx < j->bw; bx++)
			o[bx] = grey_code(j->lut, block_luminance(j, r0, r1, bx) * k);
	}
}

/* The tag detector's grey picture of a Bayer frame at half resolution (the blocks of
 * block_weights; an odd last row or column is left out), white level included. */
static unsigned char *grey8_binned(const work_image *wi, const float w[4], int *bw, int *bh)
{
	int n = wi->threads;
	binned_job j = {.wi = wi, .bw = wi->width / 2, .bh = wi->height / 2};
	memcpy(j.w, w, sizeof(j.w));
	j.hist = calloc((size_t)n, sizeof(*j.hist));
	j.g = malloc((size_t)j.bw * j.bh);
	if (!j.hist || !j.g) {
		free(j.hist);
		free(j.g);
		return NULL;
	}
	run_parallel(binned_white_rows, &j, n);
	double white = white_of(j.hist, n);
	free(j.hist);
	srgb_lut(j.lut);
	j.k = (float)(GREY_BINS / white);
	run_parallel(binned_grey_rows, &j, n);
	*bw = j.bw;
	*bh = j.bh;
	return j.g;
}
#endif /* HAVE_APRILTAG */

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

/* Tags on grey (width x height), each of its pixels `zoom` image pixels a side. */
static int run_apriltag(const unsigned char *grey, int width, int height, int zoom,
                        const char *family, int decimate, int threads, kg_chart_result *r,
                        kg_err *err)
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
	/* libapriltag's workers before 3.4.3 can run a task from a freed array when they
	 * start late (see meson.build): there it runs on the calling thread alone, which
	 * cost 0.4 ms at decimate 4 on 12 Mpix and 38-46 % more tag time at decimate 1-2
	 * (docs/chart-detect.md). */
	td->nthreads = KG_APRILTAG_THREADS_OK ? threads : 1;
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
			t->corners[k][0] = (d->p[k][0] + 0.5) * zoom;
			t->corners[k][1] = (d->p[k][1] + 0.5) * zoom;
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

/* k-th smallest of v[0..n) (reorders v): the reference selection. */
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

/* Floats as unsigned keys in the same order (negative ones reversed below the
 * positive ones). */
static uint32_t float_key(float f)
{
	uint32_t u;
	memcpy(&u, &f, sizeof(u));
	return (u & 0x80000000u) ? ~u : u | 0x80000000u;
}

static float key_float(uint32_t k)
{
	uint32_t u = (k & 0x80000000u) ? k & 0x7fffffffu : ~k;
	float f;
	memcpy(&f, &u, sizeof(f));
	return f;
}

enum { RADIX_BITS = 11 };

/* The (k-1)-th and k-th smallest of v[0..n) (out[0], out[1]; out[0] is out[1] when
 * k = 0) by radix selection on the keys: a histogram of the keys between their least
 * and greatest in 2^11 bins, then only the bin holding rank k again, until a bin is
 * one value (at most 3 rounds for 32 bits). Each round reads its set once or twice
 * where quickselect's partitions read it about 3.4 times with unpredictable branches,
 * and v is left as it is. The values are those select_kth returns. scratch: n keys. */
static void radix_pair(const float *v, long n, long k, uint32_t *scratch, float out[2])
{
	const uint32_t *keys = NULL; /* NULL: the keys of v */
	uint32_t lo = UINT32_MAX, hi = 0;
	for (long i = 0; i < n; i++) {
		uint32_t key = float_key(v[i]);
		lo = key < lo ? key : lo;
		hi = key > hi ? key : hi;
	}
	long m = n, r0 = k - 1, r1 = k;
	for (;;) {
		if (lo == hi) {
			out[0] = out[1] = key_float(lo);
			return;
		}
		uint32_t range = hi - lo;
		int bits = 32 - __builtin_clz(range);
		int shift = bits > RADIX_BITS ? bits - RADIX_BITS : 0;
		long nb = (long)(range >> shift) + 1, hist[1 << RADIX_BITS];
		memset(hist, 0, (size_t)nb * sizeof(hist[0]));
		if (keys)
			for (long i = 0; i < m; i++)
				hist[(keys[i] - lo) >> shift]++;
		else
			for (long i = 0; i < m; i++)
				hist[(float_key(v[i]) - lo) >> shift]++;
		long cum = 0, c1 = 0, b0 = -1, b1 = -1;
		for (long b = 0; b < nb; b++) {
			if (b0 < 0 && r0 >= 0 && r0 < cum + hist[b])
				b0 = b;
			if (r1 < cum + hist[b]) {
				b1 = b;
				c1 = cum;
				break;
			}
			cum += hist[b];
		}
		if (r0 < 0)
			b0 = b1;
		if (b0 != b1 || shift == 0) {
			/* rank k - 1 ends bin b0, rank k starts bin b1 (one value when shift is 0) */
			uint32_t mx = 0, mn = UINT32_MAX;
			for (long i = 0; i < m; i++) {
				uint32_t key = keys ? keys[i] : float_key(v[i]);
				long b = (long)((key - lo) >> shift);
				if (b == b0 && key > mx)
					mx = key;
				if (b == b1 && key < mn)
					mn = key;
			}
			out[0] = key_float(mx);
			out[1] = key_float(mn);
			return;
		}
		long w = 0;
		uint32_t nlo = UINT32_MAX, nhi = 0;
		for (long i = 0; i < m; i++) {
			uint32_t key = keys ? keys[i] : float_key(v[i]);
			if ((long)((key - lo) >> shift) == b1) {
				scratch[w++] = key;
				nlo = key < nlo ? key : nlo;
				nhi = key > nhi ? key : nhi;
			}
		}
		keys = scratch;
		m = w;
		r0 -= c1;
		r1 -= c1;
		lo = nlo;
		hi = nhi;
	}
}

/* Median of v[0..n): by select_kth (reorders v) or, fast, by radix_pair; the same
 * value either way. */
static double median_of(float *v, long n, int fast, uint32_t *scratch)
{
	if (fast) {
		float pair[2];
		radix_pair(v, n, n / 2, scratch, pair);
		return n % 2 ? pair[1] : 0.5 * ((double)pair[1] + pair[0]);
	}
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
 * quantum > 0: the values are integer codes that far apart. fast: radix selection. */
static void robust_stats(float *v, float *work, uint32_t *scratch, long n,
                         const kg_chart_detect_options *opt, double quantum, int fast,
                         double *loc, double *sigma)
{
	double med = median_of(v, n, fast, scratch);
	for (long i = 0; i < n; i++)
		work[i] = fabsf(v[i] - (float)med);
	*sigma = 1.4826 * median_of(work, n, fast, scratch);
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
	uint32_t *keys;
	long cap;
	float *row; /* one row of the region, demosaiced or gathered */
	long row_cap;
	/* counting (count_values): keys lo .. lo + nb - 1 and their counts; a key is its
	 * value (bin_value), inv the 1 / scale it was made with */
	int32_t *cnt;
	float inv;
	long lo, nb, bins_cap;
} sample_buffers;

static int buffers_reserve(sample_buffers *b, long n, long row)
{
	if (n > b->cap) {
		float **arrs[5] = {&b->ch[0], &b->ch[1], &b->ch[2], &b->sum, &b->work};
		for (int k = 0; k < 5; k++) {
			float *p = realloc(*arrs[k], (size_t)n * sizeof(float));
			if (!p)
				return KG_ENOMEM;
			*arrs[k] = p;
		}
		uint32_t *keys = realloc(b->keys, (size_t)n * sizeof(uint32_t));
		if (!keys)
			return KG_ENOMEM;
		b->keys = keys;
		b->cap = n;
	}
	if (row > b->row_cap) {
		float *p = realloc(b->row, (size_t)row * 3 * sizeof(float));
		if (!p)
			return KG_ENOMEM;
		b->row = p;
		b->row_cap = row;
	}
	return 0;
}

static void buffers_free(sample_buffers *b)
{
	for (int k = 0; k < 3; k++)
		free(b->ch[k]);
	free(b->sum);
	free(b->work);
	free(b->keys);
	free(b->row);
	free(b->cnt);
}

/* Counting instead of selecting, for values that lie near integers once scaled
 * (integer codes; the halves and quarters of raw codes that demosaicing averages; sums
 * of such values, a few float steps off the integer): each value's key is its integer
 * k = floor(v scale + 1/2) and its distance in float steps from the float of k / scale,
 * k COUNT_SPREAD + that distance + COUNT_SPREAD / 2. Two values of one integer differ
 * in their distance, and values of different integers are far apart, so the key
 * grows with the value and no two values share one: counting the keys between the
 * least and the greatest, each key's value kept, puts the values in order, and every
 * order statistic is a walk over the counts, equal to what selection finds. Returns -1
 * (select instead) for a value negative (-0 included) or beyond 2^26 / scale or not
 * finite, a distance of half COUNT_SPREAD steps or more, a range of keys much wider
 * than the values are many, or no memory. */
enum { COUNT_SPREAD = 8, COUNT_MAX_BINS = 1 << 22 };

static uint32_t float_bits(float f)
{
	uint32_t u;
	memcpy(&u, &f, sizeof(u));
	return u;
}

/* The keys of v[i0 .. n) into keys, their least and greatest into *lo and *hi (kept
 * if smaller or greater), and whether any value cannot be counted. */
static int count_keys_scalar(const float *v, long i0, long n, float scale, uint32_t *keys,
                             uint32_t *lo, uint32_t *hi)
{
	const float inv = 1.0f / scale;
	uint32_t l = *lo, h = *hi, bad = 0;
	for (long i = i0; i < n; i++) {
		float t = v[i] * scale;
		if (!(t >= 0 && t < 67108864.0f))
			return 1;
		uint32_t k = (uint32_t)(t + 0.5f);
		uint32_t d = float_bits(v[i]) - float_bits((float)k * inv) + COUNT_SPREAD / 2;
		bad |= d >= COUNT_SPREAD;
		uint32_t key = k * COUNT_SPREAD + d;
		keys[i] = key;
		l = key < l ? key : l;
		h = key > h ? key : h;
	}
	*lo = l;
	*hi = h;
	return bad != 0;
}

#ifdef __SSE2__
/* count_keys_scalar four values at a time (SSE2, every x86-64): the same float
 * operations, so the same keys. A value outside the range or off its integer makes
 * the whole call fail, whatever the other lanes hold; the keys of values that pass
 * are below 2^30, so signed comparisons order them. */
static int count_keys(const float *v, long n, float scale, uint32_t *keys, uint32_t *lo,
                      uint32_t *hi)
{
	const float inv = 1.0f / scale;
	const __m128 vs = _mm_set1_ps(scale), vinv = _mm_set1_ps(inv), zero = _mm_setzero_ps(),
	             top = _mm_set1_ps(67108864.0f), half = _mm_set1_ps(0.5f);
	const __m128i spread = _mm_set1_epi32(COUNT_SPREAD / 2),
	              low_bits = _mm_set1_epi32(COUNT_SPREAD - 1);
	__m128i vlo = _mm_set1_epi32(INT32_MAX), vhi = _mm_setzero_si128(),
	        bad = _mm_setzero_si128();
	__m128 in = _mm_castsi128_ps(_mm_set1_epi32(-1));
	long i = 0;
	for (; i + 4 <= n; i += 4) {
		__m128 x = _mm_loadu_ps(v + i), t = _mm_mul_ps(x, vs);
		in = _mm_and_ps(in, _mm_and_ps(_mm_cmpge_ps(t, zero), _mm_cmplt_ps(t, top)));
		__m128i k = _mm_cvttps_epi32(_mm_add_ps(t, half));
		__m128 kf = _mm_mul_ps(_mm_cvtepi32_ps(k), vinv);
		__m128i d = _mm_add_epi32(_mm_sub_epi32(_mm_castps_si128(x), _mm_castps_si128(kf)),
		                          spread);
		bad = _mm_or_si128(bad, _mm_andnot_si128(low_bits, d));
		__m128i key = _mm_add_epi32(_mm_slli_epi32(k, 3), d);
		_mm_storeu_si128((__m128i *)(keys + i), key);
		__m128i lt = _mm_cmplt_epi32(key, vlo), gt = _mm_cmpgt_epi32(key, vhi);
		vlo = _mm_or_si128(_mm_and_si128(lt, key), _mm_andnot_si128(lt, vlo));
		vhi = _mm_or_si128(_mm_and_si128(gt, key), _mm_andnot_si128(gt, vhi));
	}
	if (_mm_movemask_ps(in) != 0xf ||
	    _mm_movemask_epi8(_mm_cmpeq_epi32(bad, _mm_setzero_si128())) != 0xffff)
		return 1;
	uint32_t l[4], h[4];
	_mm_storeu_si128((__m128i *)l, vlo);
	_mm_storeu_si128((__m128i *)h, vhi);
	for (int k = 0; k < 4; k++) {
		*lo = l[k] < *lo ? l[k] : *lo;
		*hi = h[k] > *hi ? h[k] : *hi;
	}
	return count_keys_scalar(v, i, n, scale, keys, lo, hi);
}
#else
static int count_keys(const float *v, long n, float scale, uint32_t *keys, uint32_t *lo,
                      uint32_t *hi)
{
	return count_keys_scalar(v, 0, n, scale, keys, lo, hi);
}
#endif

static int count_values(const float *v, long n, float scale, sample_buffers *b)
{
	uint32_t lo = UINT32_MAX, hi = 0;
	if (count_keys(v, n, scale, b->keys, &lo, &hi))
		return -1;
	long nb = n ? (long)(hi - lo) + 1 : 0;
	if (nb > COUNT_MAX_BINS || nb > 4 * n + 65536)
		return -1;
	if (nb > b->bins_cap) {
		int32_t *c = realloc(b->cnt, (size_t)nb * sizeof(*c));
		if (!c)
			return -1;
		b->cnt = c;
		b->bins_cap = nb;
	}
	memset(b->cnt, 0, (size_t)nb * sizeof(*b->cnt));
	for (long i = 0; i < n; i++)
		b->cnt[b->keys[i] - lo]++;
	b->lo = lo;
	b->nb = nb;
	b->inv = 1.0f / scale;
	return 0;
}

/* The value of counting bin k: its key's integer over scale as count_keys computes
 * it, moved by the key's distance in float steps. */
static float bin_value(const sample_buffers *b, long k)
{
	uint32_t key = (uint32_t)b->lo + (uint32_t)k;
	uint32_t u = float_bits((float)(key / COUNT_SPREAD) * b->inv) + key % COUNT_SPREAD -
	             COUNT_SPREAD / 2;
	float f;
	memcpy(&f, &u, sizeof(f));
	return f;
}

/* Ranks r[0] <= r[1] picked from values arriving in ascending order, c copies each. */
typedef struct rank_pick {
	long r[2], seen;
	float out[2];
} rank_pick;

static int pick(rank_pick *p, float v, long c)
{
	long end = p->seen + c;
	for (int s = 0; s < 2; s++)
		if (p->r[s] >= p->seen && p->r[s] < end)
			p->out[s] = v;
	p->seen = end;
	return end > p->r[1];
}

static double pick_median(const rank_pick *p, long n)
{
	return n % 2 ? p->out[1] : 0.5 * ((double)p->out[1] + p->out[0]);
}

/* robust_stats from the counts of count_values: the same numbers. The median's
 * absolute deviations come from walking outward from the median in both directions
 * at once, each side's deviations growing as it goes. */
static void counted_stats(const sample_buffers *b, long n, const kg_chart_detect_options *opt,
                          double quantum, double *loc, double *sigma)
{
	const int32_t *cnt = b->cnt;
	long nb = b->nb;
	rank_pick m = {{n / 2 - 1, n / 2}, 0, {0, 0}};
	long up = 0;
	while (!pick(&m, bin_value(b, up), cnt[up]))
		for (up++; !cnt[up]; up++)
			;
	double med = pick_median(&m, n);
	float fm = (float)med;
	/* the deviations fabsf(v - fm), as the selection computes them */
	for (up = 0; up < nb && !(cnt[up] && bin_value(b, up) >= fm); up++)
		;
	long down = up - 1;
	while (down >= 0 && !cnt[down])
		down--;
	rank_pick d = {{n / 2 - 1, n / 2}, 0, {0, 0}};
	for (;;) {
		float du = up < nb ? fabsf(bin_value(b, up) - fm) : INFINITY;
		float dd = down >= 0 ? fabsf(bin_value(b, down) - fm) : INFINITY;
		int done;
		if (du <= dd) {
			done = pick(&d, du, cnt[up]);
			for (up++; up < nb && !cnt[up]; up++)
				;
		} else {
			done = pick(&d, dd, cnt[down]);
			for (down--; down >= 0 && !cnt[down]; down--)
				;
		}
		if (done)
			break;
	}
	*sigma = 1.4826 * pick_median(&d, n);
	if (opt->statistic == KG_CHART_TRIMMED_MEAN) {
		long cut = (long)floor(opt->trim * n);
		if (2 * cut >= n)
			cut = (n - 1) / 2;
		double s = 0;
		long at = 0;
		for (long k = 0; k < nb && at < n - cut; k++) {
			for (long i = 0; i < cnt[k] && at < n - cut; i++, at++)
				if (at >= cut)
					s += bin_value(b, k);
		}
		*loc = s / (double)(n - 2 * cut);
	} else if (quantum > 0) {
		long below = 0, at = 0;
		for (long k = 0; k < nb; k++) {
			if (!cnt[k])
				continue;
			if (bin_value(b, k) < med - 0.5 * quantum)
				below += cnt[k];
			else if (bin_value(b, k) <= med + 0.5 * quantum)
				at += cnt[k];
		}
		*loc = at ? med - 0.5 * quantum + quantum * (0.5 * n - below) / at : med;
	} else {
		*loc = med;
	}
}

/* How many of the counted values exceed t. */
static long counted_above(const sample_buffers *b, double t)
{
	long c = 0;
	for (long k = b->nb - 1; k >= 0; k--)
		if (b->cnt[k] && !(bin_value(b, k) > t))
			break;
		else
			c += b->cnt[k];
	return c;
}

static void flag(kg_chart_sample *p, unsigned f, const char *why)
{
	p->flags |= f;
	size_t at = strlen(p->warning);
	snprintf(p->warning + at, sizeof(p->warning) - at, "%s%s", at ? "; " : "", why);
}

/* Whether the pixel centre (X, Y) maps inside the sampled rectangle (half sides hx,
 * hy around the patch centre c, in mm) and in which quadrant: the reference test. */
static int inside_exact(const double Hinv[9], double X, double Y, const double c[2],
                        double hx, double hy, int *q)
{
	double m[2];
	kg_homography_map(Hinv, X, Y, m);
	double u = m[0] - c[0], v = m[1] - c[1];
	if (!(fabs(u) <= hx && fabs(v) <= hy))
		return 0;
	*q = (u >= 0) + 2 * (v >= 0);
	return 1;
}

/* The sampled rectangle along one row of pixel centres, without divisions. With G the
 * inverse homography (signed so that its w is positive over the region), a pixel
 * centre X maps to u = A / w, v = B / w relative to the patch centre, where A, B and
 * w are affine in X: the pixel is inside when |A| <= hx w and |B| <= hy w, four
 * affine inequalities whose solutions are one interval of X. */
typedef struct span_row {
	double a[3], b[3]; /* A, B, w = a + b X */
} span_row;

static void span_row_at(const double G[9], const double c[2], double Y, span_row *s)
{
	double aw = G[7] * Y + G[8];
	s->a[0] = G[1] * Y + G[2] - c[0] * aw;
	s->b[0] = G[0] - c[0] * G[6];
	s->a[1] = G[4] * Y + G[5] - c[1] * aw;
	s->b[1] = G[3] - c[1] * G[6];
	s->a[2] = aw;
	s->b[2] = G[6];
}

/* The columns [*x0, *x1) of pixels whose centres can be inside (one pixel of margin
 * each side: the exact test decides there), within the bounds given. */
static void span_columns(const span_row *s, double hx, double hy, long *x0, long *x1)
{
	double lo = -INFINITY, hi = INFINITY;
	double h[2] = {hx, hy};
	for (int k = 0; k < 2; k++)
		for (int sign = -1; sign <= 1; sign += 2) {
			/* sign * (a + b X) - h (aw + bw X) <= 0 */
			double a = sign * s->a[k] - h[k] * s->a[2], b = sign * s->b[k] - h[k] * s->b[2];
			if (b > 0)
				hi = fmin(hi, -a / b);
			else if (b < 0)
				lo = fmax(lo, -a / b);
			else if (a > 0)
				hi = -INFINITY;
		}
	if (!(lo <= hi)) {
		*x1 = *x0;
		return;
	}
	double da = ceil(lo - 0.5) - 1, db = floor(hi - 0.5) + 2;
	if (da > (double)*x0)
		*x0 = da < (double)*x1 ? (long)da : *x1;
	if (db < (double)*x1)
		*x1 = db > (double)*x0 ? (long)db : *x0;
}

/* Sample one patch: every pixel whose centre maps inside the patch's centred
 * sample_fraction. The reference maps every pixel of the region's bounding box
 * through the inverse homography; fast rasterises the region row by row (span_row),
 * classifies by the affine forms and falls back to the reference test within 1e-9
 * of the patch scale of a side or a quadrant boundary, so both take the same pixels
 * in the same order, and selects by radix_pair: the same values. */
static int sample_patch(const work_image *wi, const double H[9], const double Hinv[9],
                        const double center[2], const double size[2],
                        const kg_chart_detect_options *opt, int fast, int stride,
                        sample_buffers *buf, kg_chart_sample *p)
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
	if (buffers_reserve(buf, cap ? cap : 1, cap ? ix1 - ix0 : 1))
		return KG_ENOMEM;
	/* The fast path needs w of one sign over the box (no horizon inside it). */
	double G[9], wsign = 0;
	for (int k = 0; k < 4 && fast && cap; k++) {
		double X = (k & 1 ? ix1 - 0.5 : ix0 + 0.5), Y = (k & 2 ? iy1 - 0.5 : iy0 + 0.5);
		double w = Hinv[6] * X + Hinv[7] * Y + Hinv[8];
		if (k == 0)
			wsign = w > 0 ? 1 : w < 0 ? -1 : 0;
		else if (!(w * wsign > 0))
			wsign = 0;
	}
	fast = fast && wsign != 0;
	for (int k = 0; k < 9; k++)
		G[k] = wsign * Hinv[k];
	double tol = 1e-9 * (fabs(cx) + fabs(cy) + hx + hy + 1);
	long n = 0, nclipped = 0;
	/* The quadrant sums in registers (q changes a few times a row): each still adds
	 * its pixels in order. */
	double qs0 = 0, qs1 = 0, qs2 = 0, qs3 = 0;
	long qn[4] = {0, 0, 0, 0};
	int C = wi->channels;
	float *ch0 = buf->ch[0], *ch1 = buf->ch[1], *ch2 = buf->ch[2], *sums = buf->sum;
	/* the least float not below the clip level: v >= clip exactly when v >= the level */
	float clip3[3];
	for (int c = 0; c < 3; c++) {
		clip3[c] = (float)wi->clip_ch[c];
		if ((double)clip3[c] < wi->clip_ch[c])
			clip3[c] = nextafterf(clip3[c], INFINITY);
	}
	if (C != 3) /* grey: one channel, its level */
		clip3[1] = clip3[2] = clip3[0];
	for (long y = iy0; y < iy1 && cap; y += stride) {
		double Y = y + 0.5;
		long xa = ix0, xb = ix1;
		span_row s = {{0, 0, 0}, {0, 0, 0}};
		if (fast) {
			span_row_at(G, center, Y, &s);
			span_columns(&s, hx, hy, &xa, &xb);
		}
		if (xa >= xb)
			continue;
		const float *row = image_span(wi, (int)y, (int)xa, (int)((xb - xa - 1) / stride + 1),
		                              stride, buf->row);
		for (long x = xa; x < xb; x += stride) {
			double X = x + 0.5;
			int q = 0, in;
			if (fast) {
				double A = s.a[0] + s.b[0] * X, B = s.a[1] + s.b[1] * X, w = s.a[2] + s.b[2] * X;
				double dA = fabs(A), dB = fabs(B), t = tol * w;
				if (fabs(dA - hx * w) <= t || fabs(dB - hy * w) <= t || dA <= t || dB <= t) {
					in = inside_exact(Hinv, X, Y, center, hx, hy, &q);
				} else {
					in = dA < hx * w && dB < hy * w;
					q = (A > 0) + 2 * (B > 0);
				}
			} else {
				in = inside_exact(Hinv, X, Y, center, hx, hy, &q);
			}
			if (!in)
				continue;
			const float *px = row + (x - xa) / stride * C;
			float v0 = px[0], v1 = px[C == 3 ? 1 : 0], v2 = px[C == 3 ? 2 : 0];
			double sum = 0;
			sum += v0;
			sum += v1;
			sum += v2;
			ch0[n] = v0;
			ch1[n] = v1;
			ch2[n] = v2;
			sums[n] = (float)sum;
			nclipped += (v0 >= clip3[0]) | (v1 >= clip3[1]) | (v2 >= clip3[2]);
			switch (q) {
			case 0: qs0 += sum; break;
			case 1: qs1 += sum; break;
			case 2: qs2 += sum; break;
			default: qs3 += sum;
			}
			qn[q]++;
			n++;
		}
	}
	double qsum[4] = {qs0, qs1, qs2, qs3};
	p->centre_mm[0] = cx;
	p->centre_mm[1] = cy;
	p->half_mm[0] = hx;
	p->half_mm[1] = hy;
	p->light = 1;
	for (int q = 0; q < 4; q++)
		p->quadrant[q] = NAN;
	p->clipped_fraction = (double)nclipped;
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
	/* Grey images repeat their one channel: counted or selected once. */
	int count = fast && wi->count_scale > 0;
	for (int c = 0; c < 3; c++) {
		if (c > 0 && C == 1) {
			p->rgb[c] = p->rgb[0];
			p->sd[c] = p->sd[0];
		} else if (count && !count_values(buf->ch[c], n, wi->count_scale, buf)) {
			counted_stats(buf, n, opt, wi->quantum, &p->rgb[c], &p->sd[c]);
		} else {
			robust_stats(buf->ch[c], buf->work, buf->keys, n, opt, wi->quantum, fast,
			             &p->rgb[c], &p->sd[c]);
		}
	}
	/* Glare: bright outliers in the channel sum, beyond 6 sigma and 5 % of the level. */
	double sum_med, sum_sigma, bright;
	kg_chart_detect_options med_opt = *opt;
	med_opt.statistic = KG_CHART_MEDIAN;
	long nbright = 0;
	if (count && !count_values(buf->sum, n, wi->count_scale, buf)) {
		counted_stats(buf, n, &med_opt, 0, &sum_med, &sum_sigma);
		bright = sum_med + fmax(6 * sum_sigma, 0.05 * fabs(sum_med));
		nbright = counted_above(buf, bright);
	} else {
		memcpy(buf->work, buf->sum, (size_t)n * sizeof(float)); /* keep sums for counting */
		robust_stats(buf->work, buf->ch[0], buf->keys, n, &med_opt, 0, fast, &sum_med,
		             &sum_sigma);
		bright = sum_med + fmax(6 * sum_sigma, 0.05 * fabs(sum_med));
		for (long i = 0; i < n; i++)
			nbright += buf->sum[i] > bright;
	}
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
	for (int q = 0; q < 4; q++)
		p->quadrant[q] = qn[q] > 0 ? qsum[q] / qn[q] : NAN;
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

typedef struct sample_job {
	const layout_view *L;
	const work_image *wi;
	const kg_chart_detect_options *opt;
	const double *H, *Hinv;
	kg_chart_sample *patches;
	int fast, stride;
	int failed[MAX_THREADS];
} sample_job;

/* Thread t samples patches t, t + n, ...: each patch alone decides its values. */
static void sample_patches(void *arg, int t, int n)
{
	sample_job *j = arg;
	sample_buffers buf = {0};
	for (int i = t; i < j->L->npatches && !j->failed[t]; i += n)
		j->failed[t] = sample_patch(j->wi, j->H, j->Hinv, j->L->patch_center[i],
		                            j->L->patch_size[i], j->opt, j->fast, j->stride, &buf,
		                            &j->patches[i]) != 0;
	buffers_free(&buf);
}

/* Every patch of L in wi through r->H into r->patches: fast or the reference, every
 * stride-th row and column of each region (1: every pixel; more gives the patch
 * values of a sparse sample, whose pixel counts and flags are those of the sample). */
static int sample_all_with(const layout_view *L, const work_image *wi,
                           const kg_chart_detect_options *opt, int fast, int stride,
                           kg_chart_result *r, kg_err *err)
{
	double Hinv[9];
	if (kg_homography_invert(r->H, Hinv))
		return kg_fail(err, KG_EINVAL, "the chart's homography is singular");
	r->patches = calloc((size_t)(L->npatches ? L->npatches : 1), sizeof(*r->patches));
	if (!r->patches)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (int i = 0; i < L->npatches; i++) {
		r->npatches++;
		if (!(r->patches[i].id = strdup(L->patch_ids[i])))
			return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	sample_job j = {L, wi, opt, r->H, Hinv, r->patches, fast, stride > 1 ? stride : 1, {0}};
	run_parallel(sample_patches, &j, opt->threads);
	for (int t = 0; t < MAX_THREADS; t++)
		if (j.failed[t])
			return kg_fail(err, KG_ENOMEM, "patch sampling: out of memory");
	for (int k = 0; k < 4; k++)
		kg_homography_map(r->H, L->outline[k][0], L->outline[k][1], r->outline[k]);
	return 0;
}

static int sample_all(const layout_view *L, const work_image *wi,
                      const kg_chart_detect_options *opt, kg_chart_result *r, kg_err *err)
{
	return sample_all_with(L, wi, opt, 1, 1, r, err);
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
	long npix = (long)wi->width * wi->height;
	int big = wi->width > wi->height ? wi->width : wi->height;
	int decimate = opt->decimate > 0 ? opt->decimate : npix < 4000000 ? 2 : 4;
	while (opt->decimate == 0 && big > APRILTAG_MAX_SIDE * (long)decimate)
		decimate *= 2; /* automatic decimation keeps within libapriltag's coordinates */
	/* Decimated by an even factor d, libapriltag finds its quads on every d-th pixel of
	 * every d-th row, which a half-resolution picture holds as its every (d/2)-th: a
	 * Bayer frame's 2 x 2 blocks (d >= 2), or every 2nd pixel of every 2nd row of
	 * other images (d >= 4, where the edge refinement still has 2 or more pixels per
	 * decimated one): half the rows read, no demosaicing. The edges are refined on
	 * that picture. */
	float bw4[4];
	int blocks = !block_weights(wi, bw4), gw, gh;
	int zoom = decimate % 2 == 0 && (blocks || decimate >= 4) &&
	           wi->width / 2 >= decimate + 1 && wi->height / 2 >= decimate + 1 ? 2 : 1;
	unsigned char *g = zoom == 2 && blocks ? grey8_binned(wi, bw4, &gw, &gh)
	                                       : grey8(wi, zoom, &gw, &gh, &scale);
	if (!g)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	double t1 = now_seconds();
	r->prepare_seconds += t1 - t0;
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
		ret = run_apriltag(g, gw, gh, zoom, family, decimate / zoom,
		                   opt->threads > 0 ? opt->threads : 1, r, err);
	free(g);
	r->tag_seconds = now_seconds() - t1;
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

/* The ColorChecker 24's colours as X-Rite publishes them in sRGB (8 bit, D65),
 * row-major from A01 (dark skin) to D06 (black 2). Only their directions in RGB
 * matter below: the camera's own primaries, white balance and exposure are fitted. */
static const unsigned char cc24_srgb8[24][3] = {
	{115, 82, 68},   {194, 150, 130}, {98, 122, 157},  {87, 108, 67},   {133, 128, 177},
	{103, 189, 170}, {214, 126, 44},  {80, 91, 166},   {193, 90, 99},   {94, 60, 108},
	{157, 188, 64},  {224, 163, 46},  {56, 61, 150},   {70, 148, 73},   {175, 54, 60},
	{231, 199, 31},  {187, 86, 149},  {8, 133, 161},   {243, 243, 242}, {200, 200, 200},
	{160, 160, 160}, {122, 122, 121}, {85, 85, 85},    {52, 52, 52},
};

/* A patch whose value can say which colour it is: sampled, in the frame, fewer than
 * half of its pixels clipped (so the median is not), every channel above zero. */
static int colour_usable(const kg_chart_sample *p)
{
	return !(p->flags & (KG_CHART_FLAG_REJECTED | KG_CHART_FLAG_OUT_OF_FRAME)) &&
	       p->clipped_fraction < 0.5 && p->rgb[0] > 0 && p->rgb[1] > 0 && p->rgb[2] > 0 &&
	       isfinite(p->rgb[0] + p->rgb[1] + p->rgb[2]);
}

static void unit3(const double v[3], double u[3])
{
	double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
	for (int c = 0; c < 3; c++)
		u[c] = n > 0 ? v[c] / n : 0;
}

/* sin^2 of the angle between u (unit) and M e, 1 when M e points away from u. */
static double colour_sin2(const double M[9], const double e[3], const double u[3])
{
	double p[3], pp = 0, up = 0;
	for (int r = 0; r < 3; r++) {
		p[r] = M[3 * r] * e[0] + M[3 * r + 1] * e[1] + M[3 * r + 2] * e[2];
		pp += p[r] * p[r];
		up += u[r] * p[r];
	}
	return up > 0 && pp > 0 ? fmax(0, 1 - up * up / pp) : 1;
}

/* M (3 x 3) and per-patch scales s_i minimising sum |u_i - s_i M e_i|^2 over the
 * patches with use[i], by alternating least squares from the plain regression of u
 * on e: the colours up to any camera primaries, white balance and light level per
 * patch. Returns the mean sin^2 of the angles left. */
static double colour_fit(const double u[24][3], const double e[24][3], const int use[24],
                         double M[9])
{
	double s[24];
	for (int i = 0; i < 24; i++)
		s[i] = 1;
	for (int iter = 0; iter < 40; iter++) {
		double A[9] = {0}, B[9] = {0}, Binv[9];
		for (int i = 0; i < 24; i++) {
			if (!use[i])
				continue;
			for (int r = 0; r < 3; r++)
				for (int c = 0; c < 3; c++) {
					A[3 * r + c] += u[i][r] * s[i] * e[i][c];
					B[3 * r + c] += s[i] * s[i] * e[i][r] * e[i][c];
				}
		}
		if (kg_mat3_inverse(B, Binv))
			return 1;
		double F = 0;
		for (int r = 0; r < 3; r++)
			for (int c = 0; c < 3; c++) {
				M[3 * r + c] = A[3 * r] * Binv[c] + A[3 * r + 1] * Binv[3 + c] +
				               A[3 * r + 2] * Binv[6 + c];
				F += M[3 * r + c] * M[3 * r + c];
			}
		if (!(F > 0) || !isfinite(F))
			return 1;
		for (int k = 0; k < 9; k++)
			M[k] /= sqrt(F);
		for (int i = 0; i < 24; i++) {
			if (!use[i])
				continue;
			double p[3], pp = 0, up = 0;
			for (int r = 0; r < 3; r++) {
				p[r] = M[3 * r] * e[i][0] + M[3 * r + 1] * e[i][1] + M[3 * r + 2] * e[i][2];
				pp += p[r] * p[r];
				up += u[i][r] * p[r];
			}
			/* a scale stays positive: a colour pointing away is not explained */
			s[i] = pp > 0 ? fmax(up / pp, 1e-3) : 1e-3;
		}
	}
	double sum = 0;
	int n = 0;
	for (int i = 0; i < 24; i++)
		if (use[i]) {
			sum += colour_sin2(M, e[i], u[i]);
			n++;
		}
	return n ? sum / n : 1;
}

/* How far the sampled patches are from a ColorChecker read in this orientation:
 * the RMS sine of the angles between each patch's colour (camera RGB as a
 * direction: free of its level, so of the light's falloff and the exposure) and the
 * layout's colour through the 3 x 3 matrix that fits them best (any camera, any
 * white balance). The 2 worst patches of 14 or more usable ones are left out of the
 * final fit (glare, dirt). 0 is a perfect match; a wrong orientation must map six
 * greys onto six colours and reads far worse. *used: the patches fitted. */
static double orientation_score(const kg_chart_sample *p, const int idx[24], int *used)
{
	double u[24][3], e[24][3], M[9];
	int use[24], n = 0;
	for (int i = 0; i < 24; i++) {
		const kg_chart_sample *q = &p[idx[i]];
		double lin[3];
		for (int c = 0; c < 3; c++) {
			double v = cc24_srgb8[i][c] / 255.0;
			lin[c] = v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
		}
		unit3(lin, e[i]);
		use[i] = colour_usable(q);
		if (use[i])
			unit3(q->rgb, u[i]);
		n += use[i];
	}
	*used = n;
	if (n < 12)
		return 1;
	double ms = colour_fit(u, e, use, M);
	if (n >= 14) {
		for (int drop = 0; drop < 2; drop++) {
			int worst = -1;
			double w = -1;
			for (int i = 0; i < 24; i++)
				if (use[i] && colour_sin2(M, e[i], u[i]) > w) {
					w = colour_sin2(M, e[i], u[i]);
					worst = i;
				}
			use[worst] = 0;
		}
		ms = colour_fit(u, e, use, M);
	}
	return sqrt(ms);
}

/* How much colour the sampled patches have: the RMS angle (as a sine) of the usable
 * patches' directions from their mean. A grey picture, or an object of one colour,
 * has next to none, and then fits any orientation. */
static double colour_spread(const kg_chart_sample *p, const int idx[24])
{
	double mean[3] = {0, 0, 0}, u[24][3];
	int use[24], n = 0;
	for (int i = 0; i < 24; i++)
		if ((use[i] = colour_usable(&p[idx[i]]))) {
			unit3(p[idx[i]].rgb, u[i]);
			for (int c = 0; c < 3; c++)
				mean[c] += u[i][c];
			n++;
		}
	if (!n)
		return 0;
	double m[3], sum = 0;
	unit3(mean, m);
	for (int i = 0; i < 24; i++)
		if (use[i]) {
			double d = u[i][0] * m[0] + u[i][1] * m[1] + u[i][2] * m[2];
			sum += fmax(0, 1 - d * d);
		}
	return sqrt(sum / n);
}

/* ---- tagless at reduced resolution -------------------------------------------- */

typedef struct decimate_job {
	const work_image *wi;
	int f, w, h;
	float *out;
	int failed[MAX_THREADS];
} decimate_job;

static void decimate_rows(void *arg, int t, int n)
{
	decimate_job *j = arg;
	const work_image *wi = j->wi;
	int C = wi->channels, f = j->f, w = j->w;
	float *scratch = malloc((size_t)w * f * 3 * sizeof(float));
	double *acc = malloc((size_t)w * C * sizeof(double));
	if (!scratch || !acc) {
		j->failed[t] = 1;
		free(scratch);
		free(acc);
		return;
	}
	for (int oy = (int)((long)j->h * t / n); oy < (int)((long)j->h * (t + 1) / n); oy++) {
		memset(acc, 0, (size_t)w * C * sizeof(double));
		for (int dy = 0; dy < f; dy++) {
			const float *row = image_span(wi, oy * f + dy, 0, w * f, 1, scratch);
			if (C == 3) {
				/* the same sums in the same order, kept in registers over a block */
				for (int ox = 0; ox < w; ox++) {
					const float *p = row + (size_t)ox * f * 3;
					double *a = acc + (size_t)ox * 3, a0 = a[0], a1 = a[1], a2 = a[2];
					for (int dx = 0; dx < f; dx++, p += 3) {
						a0 += p[0];
						a1 += p[1];
						a2 += p[2];
					}
					a[0] = a0;
					a[1] = a1;
					a[2] = a2;
				}
				continue;
			}
			for (int ox = 0; ox < w; ox++)
				for (int dx = 0; dx < f; dx++)
					for (int c = 0; c < C; c++)
						acc[(size_t)ox * C + c] += row[((size_t)ox * f + dx) * C + c];
		}
		float *o = j->out + (size_t)oy * w * C;
		for (int i = 0; i < w * C; i++)
			o[i] = (float)(acc[i] / ((double)f * f));
	}
	free(scratch);
	free(acc);
}

/* The image averaged over f x f blocks (the last W mod f columns and H mod f rows are
 * left out): pixel (i, j) covers [i f, (i + 1) f) x [j f, (j + 1) f) of the original,
 * so a position x in it is x f in the original. Raw frames are demosaiced row by row
 * on the way. NULL when out of memory. */
static float *decimate_image(const work_image *wi, int f, int *w, int *h)
{
	decimate_job j = {wi, f, wi->width / f, wi->height / f, NULL, {0}};
	j.out = malloc((size_t)j.w * j.h * wi->channels * sizeof(float));
	if (!j.out)
		return NULL;
	run_parallel(decimate_rows, &j, wi->threads);
	for (int t = 0; t < MAX_THREADS; t++)
		if (j.failed[t]) {
			free(j.out);
			return NULL;
		}
	*w = j.w;
	*h = j.h;
	return j.out;
}

/* The image at (X, Y) px (pixel centres at +0.5) by bilinear interpolation, clamped
 * at the edges, as 3 channels (grey repeated). */
static void image_bilinear(const work_image *wi, double X, double Y, double out[3])
{
	float scratch[12];
	int W = wi->width, Hh = wi->height, C = wi->channels;
	double fx = X - 0.5, fy = Y - 0.5;
	fx = fx < 0 ? 0 : fx > W - 1 ? W - 1 : fx;
	fy = fy < 0 ? 0 : fy > Hh - 1 ? Hh - 1 : fy;
	int x0 = (int)fx < W - 1 ? (int)fx : W - 2, y0 = (int)fy < Hh - 1 ? (int)fy : Hh - 2;
	double ax = fx - x0, ay = fy - y0;
	const float *r0 = image_span(wi, y0, x0, 2, 1, scratch);
	const float *r1 = image_span(wi, y0 + 1, x0, 2, 1, scratch + 6);
	for (int c = 0; c < 3; c++) {
		int k = C == 3 ? c : 0;
		out[c] = (1 - ay) * ((1 - ax) * r0[k] + ax * r0[C + k]) +
		         ay * ((1 - ax) * r1[k] + ax * r1[C + k]);
	}
}

enum { EDGE_SAMPLES = 401, EDGE_ACROSS = 7 };

/* Where a patch edge crosses one profile: from e (mm, the edge as placed) along the
 * outward normal nrm over [-R, R] mm in steps of `step`, each sample the mean of
 * EDGE_ACROSS points over +-across mm along the edge (tan). The edge is the first
 * local maximum of the gradient (summed over the channels) from the inside that
 * reaches half the profile's largest and min_grad, to a fraction of a step by a
 * parabola: the patch's own edge comes before the gap and a neighbour's edge beyond
 * it. 1 and *t (mm along nrm), or 0 when no edge stands out. */
static int edge_on_profile(const work_image *wi, const double H[9], const double e[2],
                           const double nrm[2], const double tan[2], double R, double step,
                           double across, double min_grad, double *t)
{
	double prof[EDGE_SAMPLES][3], g[EDGE_SAMPLES];
	int ns = (int)(2 * R / step) + 1;
	if (ns > EDGE_SAMPLES)
		ns = EDGE_SAMPLES;
	if (ns < 5)
		return 0;
	for (int i = 0; i < ns; i++) {
		double s = -R + i * step, acc[3] = {0, 0, 0};
		for (int a = 0; a < EDGE_ACROSS; a++) {
			double d = across * (2.0 * a / (EDGE_ACROSS - 1) - 1), px[2], v[3];
			kg_homography_map(H, e[0] + nrm[0] * s + tan[0] * d, e[1] + nrm[1] * s + tan[1] * d,
			                  px);
			image_bilinear(wi, px[0], px[1], v);
			for (int c = 0; c < 3; c++)
				acc[c] += v[c];
		}
		for (int c = 0; c < 3; c++)
			prof[i][c] = acc[c] / EDGE_ACROSS;
	}
	double gmax = 0;
	g[0] = g[ns - 1] = 0;
	for (int i = 1; i < ns - 1; i++) {
		g[i] = 0;
		for (int c = 0; c < 3; c++)
			g[i] += fabs(prof[i + 1][c] - prof[i - 1][c]);
		gmax = fmax(gmax, g[i]);
	}
	if (!(gmax >= min_grad))
		return 0;
	for (int i = 2; i < ns - 2; i++) {
		if (g[i] < 0.5 * gmax || g[i] < g[i - 1] || g[i] < g[i + 1])
			continue;
		double den = g[i - 1] - 2 * g[i] + g[i + 1];
		double d = den < 0 ? 0.5 * (g[i - 1] - g[i + 1]) / den : 0;
		*t = -R + (i + d) * step;
		return 1;
	}
	return 0;
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return (x > y) - (x < y);
}

/* Refine the chart's placement H (mm -> px, from mcc's box on the reduced image) on
 * the patch edges at full resolution: three profiles across each side of each of the
 * 24 patches give points of known layout position (the side as the layout draws it,
 * at the profile's place along it); H is fitted to them (DLT and Levenberg-Marquardt),
 * points farther than max(0.5 px, 3 x their median) dropped and H refitted, twice,
 * the second time searching half as far. The layout's patch sides need not be the
 * printed ones: a side found outside on the left is found outside on the right too,
 * and the fit keeps the centres. Returns the points used (0: H is left as it was,
 * fewer than 12 edges found or the fit moved a patch centre by more than the search
 * range), and their RMS distance in px. */
static int refine_on_edges(const work_image *wi, const layout_view *L, const int idx[24],
                           double white, double H[9], double *rms)
{
	enum { MAXP = 24 * 4 * 3 };
	double src[MAXP][2], dst[MAXP][2], pc[2], pd[2];
	const double *a1 = L->patch_center[idx[0]], *a2 = L->patch_center[idx[1]];
	double pitch = hypot(a2[0] - a1[0], a2[1] - a1[1]);
	double side = fmin(L->patch_size[idx[0]][0], L->patch_size[idx[0]][1]);
	double gap = fmax(pitch - side, 0);
	double R = fmin(fmax(0.5 * gap, 0.12 * pitch), 0.45 * side);
	kg_homography_map(H, a1[0], a1[1], pc);
	kg_homography_map(H, a2[0], a2[1], pd);
	double px_per_mm = hypot(pd[0] - pc[0], pd[1] - pc[1]) / pitch;
	if (!(px_per_mm > 0) || !(R > 0))
		return 0;
	double Hk[9];
	memcpy(Hk, H, sizeof(Hk));
	int used = 0;
	for (int pass = 0; pass < 2; pass++, R *= 0.5) {
		double step = fmax(0.5 / px_per_mm, 2 * R / (EDGE_SAMPLES - 1));
		int n = 0;
		for (int i = 0; i < 24; i++) {
			const double *c = L->patch_center[idx[i]], *s = L->patch_size[idx[i]];
			for (int k = 0; k < 4; k++) {
				double nrm[2] = {k == 0 ? -1 : k == 1 ? 1 : 0, k == 2 ? -1 : k == 3 ? 1 : 0};
				double tan[2] = {nrm[1], nrm[0]};
				double half_n = 0.5 * (k < 2 ? s[0] : s[1]), half_t = 0.5 * (k < 2 ? s[1] : s[0]);
				for (int j = -1; j <= 1; j++) {
					double e[2] = {c[0] + nrm[0] * half_n + tan[0] * 0.6 * j * half_t,
					               c[1] + nrm[1] * half_n + tan[1] * 0.6 * j * half_t};
					double t;
					if (!edge_on_profile(wi, Hk, e, nrm, tan, R, step, 0.15 * half_t,
					                     0.02 * white, &t))
						continue;
					memcpy(src[n], e, sizeof(e));
					kg_homography_map(Hk, e[0] + nrm[0] * t, e[1] + nrm[1] * t, dst[n]);
					n++;
				}
			}
		}
		double Hn[9], r = 0;
		for (int round = 0; round < 2; round++) {
			kg_err tmp;
			if (n < 12 || kg_homography_fit((const double (*)[2])src, (const double (*)[2])dst,
			                                n, 1, Hn, &r, &tmp))
				goto done;
			double d[MAXP], sorted[MAXP];
			for (int m = 0; m < n; m++) {
				double q[2];
				kg_homography_map(Hn, src[m][0], src[m][1], q);
				sorted[m] = d[m] = hypot(q[0] - dst[m][0], q[1] - dst[m][1]);
			}
			qsort(sorted, (size_t)n, sizeof(double), cmp_double);
			double keep = fmax(0.5, 3 * sorted[n / 2]);
			int w = 0;
			for (int m = 0; m < n; m++)
				if (d[m] <= keep) {
					memcpy(src[w], src[m], sizeof(src[w]));
					memcpy(dst[w], dst[m], sizeof(dst[w]));
					w++;
				}
			n = w;
		}
		for (int i = 0; i < 24; i++) {
			double p0[2], p1[2];
			kg_homography_map(Hk, L->patch_center[idx[i]][0], L->patch_center[idx[i]][1], p0);
			kg_homography_map(Hn, L->patch_center[idx[i]][0], L->patch_center[idx[i]][1], p1);
			if (!(hypot(p1[0] - p0[0], p1[1] - p0[1]) <= R * px_per_mm))
				goto done;
		}
		memcpy(Hk, Hn, sizeof(Hk));
		used = n;
		*rms = r;
	}
done:
	if (used)
		memcpy(H, Hk, sizeof(Hk));
	return used;
}

static int tagless_box(const kg_chart_layout *l, const layout_view *L, work_image *wi,
                       const kg_chart_detect_options *opt, const int idx[24],
                       const double box_in[4][2], double cost, int f, int small_w,
                       int small_h, double white, int turns_too, kg_chart_result *r,
                       kg_err *err);

/* Find a ColorChecker 24 without tags: mcc gives the box around its patches; the
 * homography from the box in layout mm to the box in the image places the patches,
 * which sample_all measures as on the tag path. Of the four ways the box's corners
 * can meet the chart's, the one whose patches look most like a ColorChecker read
 * the right way up (orientation_score) wins: mcc's own choice is not trusted. */
static int detect_tagless(const kg_chart_layout *l, const layout_view *L, work_image *wi,
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
	double t0 = now_seconds(), boxes[MCC_CANDIDATES][4][2], costs[MCC_CANDIDATES];
	double white = white_level(wi);
	int nboxes = 0;
	/* the region searched (all of the image), for the overlay of a refusal */
	r->searched[0][0] = r->searched[3][0] = 0;
	r->searched[1][0] = r->searched[2][0] = wi->width;
	r->searched[0][1] = r->searched[1][1] = 0;
	r->searched[2][1] = r->searched[3][1] = wi->height;
	r->has_searched = 1;
	int big = wi->width > wi->height ? wi->width : wi->height, small_w = 0, small_h = 0;
	int f = opt->tagless_decimate > 0 ? opt->tagless_decimate : big / 1000;
	while (f > 1 && (wi->width / f < MCC_MIN_SIDE || wi->height / f < MCC_MIN_SIDE))
		f--;
	r->prepare_seconds += now_seconds() - t0;
	if (f > 1) {
		double t1 = now_seconds();
		float *small = decimate_image(wi, f, &small_w, &small_h);
		if (!small)
			return kg_fail(err, KG_ENOMEM, "out of memory");
		double t2 = now_seconds();
		r->prepare_seconds += t2 - t1;
		kg_err small_err = {{0}};
		ret = kg_mcc_find_colorcheckers(small, small_w, small_h, wi->channels, white,
		                                opt->threads, MCC_CANDIDATES, boxes, costs, &nboxes,
		                                &small_err);
		free(small);
		r->tag_seconds += now_seconds() - t2;
		/* Not found on the reduced copy (a chart too small there): the full image
		 * decides, so nothing the full-resolution detector finds is refused. */
		if (ret == KG_ENOENT)
			f = 1;
		else if (ret)
			return kg_fail(err, ret, "%s", small_err.msg);
		else
			for (int b = 0; b < nboxes; b++)
				for (int k = 0; k < 4; k++)
					for (int c = 0; c < 2; c++)
						boxes[b][k][c] *= f;
	}
	if (f <= 1) {
		double t1 = now_seconds();
		if ((ret = demosaic_all(wi, err)))
			return ret;
		double t2 = now_seconds();
		r->prepare_seconds += t2 - t1;
		ret = kg_mcc_find_colorcheckers(wi->data, wi->width, wi->height, wi->channels, white,
		                                opt->threads, MCC_CANDIDATES, boxes, costs, &nboxes,
		                                err);
		r->tag_seconds += now_seconds() - t2;
		if (ret)
			return ret;
	}
	r->tagless = 1;
	r->tagless_decimate = f > 1 ? f : 1;
	r->decimate = 0;
	r->rms_px = 0;
	/* mcc's boxes, its best first: the first whose patches read as the layout is
	 * taken; a refusal reports the best box's reason, and every box tried stays a
	 * candidate for the overlay */
	kg_chart_sample *first_patches = NULL;
	double first_H[9], first_outline[4][2];
	char first_msg[sizeof(err->msg)] = "";
	for (int b = 0; b < nboxes; b++) {
		kg_err box_err = {{0}};
		ret = tagless_box(l, L, wi, opt, idx, boxes[b], costs[b], f, small_w, small_h,
		                  white, b == 0, r, &box_err);
		if (ret == 0) {
			samples_free(first_patches, L->npatches);
			if (b > 0 && add_warning(r, "mcc's best box (fit cost %.3g) was refused (%s); "
			                         "its candidate %d of %d (fit cost %.3g) was taken",
			                         costs[0], first_msg, b + 1, nboxes, costs[b]))
				return kg_fail(err, KG_ENOMEM, "out of memory");
			return 0;
		}
		if (ret != KG_ENOENT) {
			samples_free(first_patches, L->npatches);
			return kg_fail(err, ret, "%s", box_err.msg);
		}
		if (b == 0) {
			/* the best box's regions stay in the result, for the overlay */
			snprintf(first_msg, sizeof(first_msg), "%s", box_err.msg);
			first_patches = r->patches;
			memcpy(first_H, r->H, sizeof(first_H));
			memcpy(first_outline, r->outline, sizeof(first_outline));
		} else {
			samples_free(r->patches, L->npatches);
		}
		r->patches = NULL;
		r->npatches = 0;
	}
	r->patches = first_patches;
	r->npatches = first_patches ? L->npatches : 0;
	memcpy(r->H, first_H, sizeof(r->H));
	memcpy(r->outline, first_outline, sizeof(r->outline));
	if (nboxes > 1)
		return kg_fail(err, KG_ENOENT, "%s; mcc's %d other candidate%s refused too",
		               first_msg, nboxes - 1, nboxes > 2 ? "s were" : " was");
	return kg_fail(err, KG_ENOENT, "%s", first_msg);
}

/* One of mcc's boxes (px, full resolution; found on a copy reduced f x f when f > 1)
 * placed as layout l: its winding fixed, refined on the patch edges (f > 1), each of
 * its 4 turns sampled and the orientation chosen from the patches' colours. 0 with
 * the patches in r; KG_ENOENT when its patches do not read as the layout (the reason
 * in err; the best turn's patches in r and the box, with A01 of each turn when
 * turns_too, added to r's candidates). */
static int tagless_box(const kg_chart_layout *l, const layout_view *L, work_image *wi,
                       const kg_chart_detect_options *opt, const int idx[24],
                       const double box_in[4][2], double cost, int f, int small_w,
                       int small_h, double white, int turns_too, kg_chart_result *r,
                       kg_err *err)
{
	double box_px[4][2], box_mm[4][2], edge_rms = 0;
	int ret = 0, refined = 0;
	memcpy(box_px, box_in, sizeof(box_px));
	mcc24_box_mm(L, idx, box_mm);
	/* A photograph does not mirror the chart: give mcc's corners the layout's winding. */
	if ((quad_signed_area(box_mm) > 0) != (quad_signed_area((const double (*)[2])box_px) > 0)) {
		double t[2] = {box_px[1][0], box_px[1][1]};
		memcpy(box_px[1], box_px[3], sizeof(t));
		memcpy(box_px[3], t, sizeof(t));
	}
	if (f > 1) {
		/* mcc's box, f times coarser than the image's pixels, refined on the patch
		 * edges in the full image; the four turns below use the refined box. */
		double t1 = now_seconds(), H0[9];
		if ((ret = kg_homography_fit((const double (*)[2])box_mm, (const double (*)[2])box_px,
		                             4, 0, H0, NULL, err)))
			return ret;
		refined = refine_on_edges(wi, L, idx, white, H0, &edge_rms);
		if (refined)
			for (int k = 0; k < 4; k++)
				kg_homography_map(H0, box_mm[k][0], box_mm[k][1], box_px[k]);
		r->tag_seconds += now_seconds() - t1;
	}
	double ts = now_seconds();
	double score[4], H[4][9], angle[4];
	kg_chart_sample *sampled[4] = {NULL, NULL, NULL, NULL}; /* each turn's patches */
	int best = 0, upright = 0, full[4] = {0, 0, 0, 0}, used[4] = {0, 0, 0, 0};
	/* Each turn scored first on a sparse sample of its patches, every stride-th row
	 * and column (about a thousand pixels a patch): the wrong turns read as far from a
	 * ColorChecker on that as on all pixels. The best, and every turn within 1.5 times
	 * its score (all four when even the best does not read as a ColorChecker), are
	 * then sampled whole and scored again: those scores decide. */
	double patch_px = fabs(quad_signed_area((const double (*)[2])box_px)) / 24 *
	                  opt->sample_fraction * opt->sample_fraction;
	int stride = (int)sqrt(fmax(patch_px, 1) / 1024);
	stride = stride < 1 ? 1 : stride > 8 ? 8 : stride;
	for (int turn = 0; turn < 4 && !ret; turn++) {
		double dst[4][2];
		for (int k = 0; k < 4; k++)
			memcpy(dst[k], box_px[(k + turn) % 4], sizeof(dst[k]));
		ret = kg_homography_fit((const double (*)[2])box_mm, (const double (*)[2])dst, 4, 0,
		                        H[turn], NULL, err);
	}
	for (int pass = stride > 1 ? 0 : 1; pass < 2 && !ret; pass++) {
		double cheapest = INFINITY;
		for (int turn = 0; pass == 1 && stride > 1 && turn < 4; turn++)
			cheapest = fmin(cheapest, score[turn]);
		for (int turn = 0; turn < 4 && !ret; turn++) {
			if (pass == 1 && stride > 1 &&
			    !(score[turn] <= KG_ORIENT_MARGIN * cheapest + 0.01 ||
			      !(cheapest <= KG_ORIENT_SCORE_MAX)))
				continue;
			memcpy(r->H, H[turn], sizeof(r->H));
			ret = sample_all_with(L, wi, opt, 1, pass == 0 ? stride : 1, r, err);
			samples_free(sampled[turn], L->npatches);
			sampled[turn] = r->patches;
			r->patches = NULL;
			r->npatches = 0;
			if (!ret) {
				score[turn] = orientation_score(sampled[turn], idx, &used[turn]);
				full[turn] = pass == 1;
			}
		}
	}
	for (int turn = 0; turn < 4 && !ret; turn++) {
		/* a turn never sampled whole is never the best */
		if (full[turn] && (!full[best] || score[turn] < score[best]))
			best = turn;
		double a1[2], a6[2];
		kg_homography_map(H[turn], L->patch_center[idx[0]][0], L->patch_center[idx[0]][1], a1);
		kg_homography_map(H[turn], L->patch_center[idx[5]][0], L->patch_center[idx[5]][1], a6);
		angle[turn] = atan2(a6[1] - a1[1], a6[0] - a1[0]) * 180 / M_PI;
		if (fabs(angle[turn]) < fabs(angle[upright]))
			upright = turn;
	}
	/* The best turn must read as a ColorChecker (its colours fit the layout's through
	 * one 3 x 3 matrix), have colour at all (a grey picture fits every turn), and read
	 * clearly better than the next best turn; otherwise neither the patches nor mcc,
	 * whose choice rests on the same colours, can say which patch is which. */
	r->sample_seconds += now_seconds() - ts;
	double next = INFINITY;
	int next_turn = -1;
	for (int turn = 0; turn < 4 && !ret; turn++)
		if (turn != best && score[turn] < next) {
			next = score[turn];
			next_turn = turn;
		}
	double spread = ret ? 0 : colour_spread(sampled[best], idx);
	char why[400] = "";
	if (ret)
		;
	else if (used[best] < 12)
		snprintf(why, sizeof(why), "only %d of its 24 patches can be read (the others are "
		         "clipped, rejected or out of the image; 12 are needed)", used[best]);
	else if (spread < KG_ORIENT_SPREAD_MIN)
		snprintf(why, sizeof(why), "they have next to no colour (spread %.3f, a "
		         "ColorChecker has more than %.2f)", spread, KG_ORIENT_SPREAD_MIN);
	else if (!(score[best] <= KG_ORIENT_SCORE_MAX))
		snprintf(why, sizeof(why), "their colours match the layout's in none of its 4 turns "
		         "(best colour misfit %.3f, a ColorChecker fits below %.2f)", score[best],
		         KG_ORIENT_SCORE_MAX);
	else if (!(next >= KG_ORIENT_MARGIN * score[best]))
		snprintf(why, sizeof(why), "two of its turns match the layout's colours about as "
		         "well (colour misfit %.3f and %.3f, the best must be %.1f times better)",
		         score[best], next, KG_ORIENT_MARGIN);
	int uncertain = !ret && why[0];
	if (uncertain) {
		/* what was tried, for the overlay: mcc's box, A01's corner of each turn */
		int add = turns_too ? 5 : 1;
		kg_chart_candidate *c = realloc(r->candidates,
		                                (size_t)(r->ncandidates + add) * sizeof(*c));
		if (c) {
			r->candidates = c;
			c += r->ncandidates;
			r->ncandidates += add;
			memset(c, 0, (size_t)add * sizeof(*c));
			memcpy(c[0].quad, box_px, sizeof(c[0].quad));
			snprintf(c[0].why, sizeof(c[0].why), "mcc's box (fit cost %.3g): its patches do "
			         "not read as the layout: %s", cost, why);
			for (int turn = 0; turn < 4 && turns_too; turn++) {
				kg_chart_sample *a = &sampled[turn][idx[0]];
				memcpy(c[1 + turn].quad, a->quad, sizeof(c[1 + turn].quad));
				snprintf(c[1 + turn].why, sizeof(c[1 + turn].why), "A01 if turn %d: misfit "
				         "%.3f%s", turn, score[turn], full[turn] ? "" : " (sparse)");
			}
		}
	}
	for (int turn = 0; turn < 4; turn++)
		if (ret || turn != best)
			samples_free(sampled[turn], L->npatches);
	if (ret)
		return ret;
	if (uncertain) {
		/* the best turn's regions stay in the result, for the overlay */
		r->patches = sampled[best];
		r->npatches = L->npatches;
		memcpy(r->H, H[best], sizeof(r->H));
		for (int k = 0; k < 4; k++)
			kg_homography_map(r->H, L->outline[k][0], L->outline[k][1], r->outline[k]);
		return kg_fail(err, KG_ENOENT,
		               "the tagless detector (OpenCV mcc, fit cost %.3g) found a box, but "
		               "its patches do not read as layout %s: %s. No ColorChecker in view "
		               "(other colours on its geometry), or light too coloured, clipped or "
		               "processed to tell; row A01-A06 would run at %.0f degrees from the "
		               "image's x axis", cost, l->name, why, angle[upright]);
	}
	r->patches = sampled[best];
	r->npatches = L->npatches;
	memcpy(r->H, H[best], sizeof(r->H));
	for (int k = 0; k < 4; k++)
		kg_homography_map(r->H, L->outline[k][0], L->outline[k][1], r->outline[k]);
	int next_sparse = next_turn >= 0 && !full[next_turn];
	char sparse[80] = "";
	if (next_sparse)
		snprintf(sparse, sizeof(sparse), " (on every %d%s row and column)", stride,
		         stride == 2 ? "nd" : stride == 3 ? "rd" : "th");
	char how[200] = "";
	if (f > 1 && refined)
		snprintf(how, sizeof(how), " on a %d x %d copy averaged over %d x %d pixels, refined "
		         "on %d points of the patch edges at full resolution (RMS %.2f px)", small_w,
		         small_h, f, f, refined, edge_rms);
	else if (f > 1)
		snprintf(how, sizeof(how), " on a %d x %d copy averaged over %d x %d pixels (too few "
		         "patch edges to refine it at full resolution)", small_w, small_h, f, f);
	ret = add_warning(r, "chart placed by the tagless detector (OpenCV mcc, fit cost "
	                  "%.3g) from the 4 corners of its box%s, not by tags; orientation "
	                  "chosen from the patches' colours (%d patches fitted to the layout's "
	                  "through one 3 x 3 matrix, light level free): colour misfit %.3f, "
	                  "next best of the 4 turns %.3f%s, %s mcc's own; row A01-A06 runs at "
	                  "%.0f degrees clockwise from the image's x axis", cost, how, used[best],
	                  score[best], next, sparse, best == 0 ? "agreeing with" : "overruling",
	                  angle[best]);
	return ret ? kg_fail(err, ret, "out of memory") : 0;
}
#else
static int detect_tagless(const kg_chart_layout *l, const layout_view *L, work_image *wi,
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

/* A refusal: each tag seen becomes a candidate with why it did not place the chart
 * (added after the tagless detector's, if any). Out of memory: left as it is. */
static void refused_tags(const layout_view *L, const kg_chart_detect_options *opt,
                         kg_chart_result *r)
{
	if (r->ntags <= 0)
		return;
	kg_chart_candidate *c = realloc(r->candidates,
	                                (size_t)(r->ncandidates + r->ntags) * sizeof(*c));
	if (!c)
		return;
	r->candidates = c;
	for (int i = 0; i < r->ntags; i++) {
		const kg_chart_tag_found *t = &r->tags[i];
		kg_chart_candidate *k = &c[r->ncandidates++];
		memset(k, 0, sizeof(*k));
		memcpy(k->quad, t->corners, sizeof(k->quad));
		const char *family = opt->family ? opt->family : L->family;
		int of_layout = 0;
		for (int j = 0; j < L->ntags; j++)
			of_layout |= L->tag_ids[j] == t->id;
		if (!of_layout)
			snprintf(k->why, sizeof(k->why), "tag %d (%s): not one of layout %s's tags",
			         t->id, family, L->name);
		else if (t->used)
			snprintf(k->why, sizeof(k->why), "tag %d: of the layout, used, but the chart "
			         "needs %d", t->id, opt->min_tags);
		else if (isfinite(t->error) && t->error > 0)
			snprintf(k->why, sizeof(k->why), "tag %d: of the layout, %.1f px off the chart "
			         "the other tags place", t->id, t->error);
		else
			snprintf(k->why, sizeof(k->why), "tag %d: of the layout, too few with it to "
			         "place the chart (%d needed)", t->id, opt->min_tags);
	}
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
	double tp = now_seconds();
	ret = prepare_image(img, &opt, &wi, err);
	r->prepare_seconds = now_seconds() - tp;
	if (!ret && wi.sat_note[0] &&
	    add_warning(r, "saturation found from the data below full scale: %s; samples there "
	                   "count as clipped", wi.sat_note))
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	if (ret)
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
			double ts = now_seconds();
			ret = sample_all(&L, &wi, &opt, r, err);
			r->sample_seconds = now_seconds() - ts;
		}
		if (ret)
			goto fail;
	} else if ((ret = detect_tagless(l, &L, &wi, &opt, r, err))) {
		goto fail;
	}
	if (opt.light_field && (ret = calib_light_field_apply(r, &opt, err)))
		goto fail;
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
	if (ret == KG_ENOENT && opt.keep_refused)
		refused_tags(&L, &opt, r);
	layout_arrays_free(&arrays);
	if (ret == KG_ENOENT && opt.keep_refused) {
		/* what was searched and seen stays, for the overlay */
		r->refused = 1;
		snprintf(r->refusal, sizeof(r->refusal), "%s", err ? err->msg : "chart not found");
		if (!r->has_searched) {
			r->searched[0][0] = r->searched[3][0] = 0;
			r->searched[1][0] = r->searched[2][0] = img->width;
			r->searched[0][1] = r->searched[1][1] = 0;
			r->searched[2][1] = r->searched[3][1] = img->height;
			r->has_searched = 1;
		}
		r->total_seconds = now_seconds() - t0;
		*out = r;
		return ret;
	}
	kg_chart_result_free(&r);
	return ret;
}

int calib_chart_sample(const kg_chart_layout *l, const kg_image *img, const double H[9],
                       const kg_chart_detect_options *options, int reference,
                       kg_chart_result **out, kg_err *err)
{
	kg_check_arg(l && img && img->data && H && options && out, err);
	*out = NULL;
	kg_chart_detect_options opt = *options;
	if (!(opt.sample_fraction > 0))
		opt.sample_fraction = l->sample_fraction > 0 ? l->sample_fraction : 0.6;
	layout_view L;
	layout_arrays arrays;
	int ret = make_view(l, &L, &arrays, err);
	if (ret)
		return ret;
	work_image wi;
	kg_chart_result *r = calloc(1, sizeof(*r));
	if (!r)
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	if (!ret)
		ret = prepare_image(img, &opt, &wi, err);
	if (!ret) {
		snprintf(r->layout, sizeof(r->layout), "%s", l->name);
		memcpy(r->H, H, sizeof(r->H));
		ret = sample_all_with(&L, &wi, &opt, !reference, 1, r, err);
		free(wi.owned);
	}
	layout_arrays_free(&arrays);
	if (ret)
		kg_chart_result_free(&r);
	*out = r;
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

/* text from (x, y) (the first line's baseline) in lines no wider than maxw, broken
 * at spaces, outlined in black; the baseline below the last line. */
static double wrapped_text(cairo_t *cr, double x, double y, double maxw, double size,
                           const char *text, double r, double g, double b)
{
	char line[1100];
	size_t n = 0;
	cairo_set_font_size(cr, size);
	const char *p = text;
	while (*p) {
		/* the next word, with the spaces before it */
		const char *w = p;
		while (*w == ' ')
			w++;
		const char *end = w;
		while (*end && *end != ' ')
			end++;
		char trial[1100];
		int len = snprintf(trial, sizeof(trial), "%.*s%.*s", (int)n, line,
		                   (int)(n ? end - p : end - w), n ? p : w);
		cairo_text_extents_t ext;
		cairo_text_extents(cr, trial, &ext);
		if (n && (ext.x_advance > maxw || len >= (int)sizeof(line) - 1)) {
			line[n] = '\0';
			cairo_move_to(cr, x, y);
			cairo_text_path(cr, line);
			cairo_set_source_rgb(cr, 0, 0, 0);
			cairo_set_line_width(cr, fmax(1.5, size / 6));
			cairo_stroke(cr);
			cairo_move_to(cr, x, y);
			cairo_set_source_rgb(cr, r, g, b);
			cairo_show_text(cr, line);
			y += size * 1.2;
			n = (size_t)snprintf(line, sizeof(line), "%.*s", (int)(end - w), w);
		} else {
			n = (size_t)snprintf(line, sizeof(line), "%s", trial);
		}
		p = end;
	}
	if (n) {
		cairo_move_to(cr, x, y);
		cairo_text_path(cr, line);
		cairo_set_source_rgb(cr, 0, 0, 0);
		cairo_set_line_width(cr, fmax(1.5, size / 6));
		cairo_stroke(cr);
		cairo_move_to(cr, x, y);
		cairo_set_source_rgb(cr, r, g, b);
		cairo_show_text(cr, line);
		y += size * 1.2;
	}
	return y;
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
	if (!ret)
		ret = demosaic_all(&wi, err);
	if (ret) {
		free(wi.owned);
		return ret;
	}
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
	int gw, gh;
	g = grey8(&wi, 1, &gw, &gh, &scale_px);
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
	/* a refusal: the region searched (dashed yellow) and each candidate tried
	 * (magenta) with why it failed */
	if (r->refused && r->has_searched) {
		double dash[2] = {4 * lw, 3 * lw};
		cairo_set_dash(cr, dash, 2, 0);
		cairo_set_source_rgb(cr, 1, 0.9, 0.2);
		cairo_set_line_width(cr, 2 * lw);
		double q[4][2];
		for (int k = 0; k < 4; k++) {
			/* inset by a line width so the frame of the whole image shows */
			q[k][0] = r->searched[k][0] + (k == 0 || k == 3 ? 1 : -1) * 1.5 * lw / s;
			q[k][1] = r->searched[k][1] + (k < 2 ? 1 : -1) * 1.5 * lw / s;
		}
		path_quad(cr, q, s);
		cairo_stroke(cr);
		cairo_set_dash(cr, NULL, 0, 0);
	}
	double box_text = 0; /* below the last box's reason: mcc's boxes often overlap */
	for (int i = 0; r->refused && i < r->ncandidates; i++) {
		const kg_chart_candidate *c = &r->candidates[i];
		int box = strncmp(c->why, "mcc's box", 9) == 0, turn = !strncmp(c->why, "A01 if", 6);
		cairo_set_source_rgb(cr, 1, 0.2, 1);
		cairo_set_line_width(cr, (box ? 2.5 : 1.5) * lw);
		path_quad(cr, c->quad, s);
		cairo_stroke(cr);
		double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
		for (int k = 0; k < 4; k++) {
			x0 = fmin(x0, c->quad[k][0] * s);
			x1 = fmax(x1, c->quad[k][0] * s);
			y0 = fmin(y0, c->quad[k][1] * s);
			y1 = fmax(y1, c->quad[k][1] * s);
		}
		double size = turn ? font * 0.8 : font;
		double maxw = fmax(x1 - x0, 12 * size);
		if (x0 + maxw > W)
			x0 = fmax(0, W - maxw);
		/* a box's reason below it, each turn's at its A01 region, a tag's below it */
		double y = box ? fmax(fmin(y1 + size * 1.3, Hh - 3 * size), box_text) : y1 + size;
		y = wrapped_text(cr, x0, y, maxw, size, c->why, 1, 0.5, 1);
		if (box)
			box_text = y + 0.3 * size;
	}
	/* chart outline */
	if (r->npatches > 0 && !r->refused) {
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
	if (r->refused) {
		snprintf(title, sizeof(title), "%s NOT FOUND (%d tag%s seen, %d candidate%s)",
		         r->layout, r->ntags, r->ntags == 1 ? "" : "s", r->ncandidates,
		         r->ncandidates == 1 ? "" : "s");
		wrapped_text(cr, font * 0.5, font * 2.9, W - font, font * 0.9, r->refusal, 1, 0.6,
		             0.3);
	}
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
