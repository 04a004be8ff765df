/* Patch sampling: every pixel whose centre maps inside a patch's centred
 * sample_fraction, rasterised row by row, its robust statistics, and its flags
 * (clipped, glare, non-uniform, out of frame, too few pixels). */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"

/* ---- patch sampling ---------------------------------------------------------- */

static double quad_area(const double q[4][2])
{
	double a = 0;
	for (int k = 0; k < 4; k++)
		a += q[k][0] * q[(k + 1) % 4][1] - q[(k + 1) % 4][0] * q[k][1];
	return fabs(a) / 2;
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

/* Where along the row the affine form a + b X is positive: *lo < X < *hi narrowed. */
static void positive_part(double a, double b, double *lo, double *hi)
{
	if (b > 0)
		*lo = fmax(*lo, -a / b);
	else if (b < 0)
		*hi = fmin(*hi, -a / b);
	else if (!(a > 0))
		*hi = -INFINITY;
}

/* The runs of the row's columns [xa, xb) whose pixels are clearly inside one quadrant:
 * more than m (in mm, m twice the exact test's band) inside each side and away from
 * the quadrant boundaries, then one more pixel in at each end. There the per-pixel
 * classification, whose rounding is far below the band, can only take the pixel in
 * that quadrant: the sampler adds those pixels without classifying them. At most 4
 * runs (one a quadrant, as the row crosses them), in order along the row; returns how
 * many. */
static int clear_runs(const span_row *s, double hx, double hy, double m, long xa, long xb,
                      long run[4][2], int quad[4])
{
	int k = 0;
	if (!(hx > 2 * m && hy > 2 * m))
		return 0;
	for (int q = 0; q < 4; q++) {
		double sx = q & 1 ? 1 : -1, sy = q & 2 ? 1 : -1, lo = -INFINITY, hi = INFINITY;
		/* m w < sx A < (hx - m) w and m w < sy B < (hy - m) w, w > 0 */
		positive_part(sx * s->a[0] - m * s->a[2], sx * s->b[0] - m * s->b[2], &lo, &hi);
		positive_part((hx - m) * s->a[2] - sx * s->a[0], (hx - m) * s->b[2] - sx * s->b[0],
		              &lo, &hi);
		positive_part(sy * s->a[1] - m * s->a[2], sy * s->b[1] - m * s->b[2], &lo, &hi);
		positive_part((hy - m) * s->a[2] - sy * s->a[1], (hy - m) * s->b[2] - sy * s->b[1],
		              &lo, &hi);
		/* pixel x's centre is x + 0.5: the columns strictly inside, less one each end */
		double first = floor(lo - 0.5) + 2, last = ceil(hi - 0.5) - 2;
		long r0 = first > (double)xa ? (first < (double)xb ? (long)first : xb) : xa;
		long r1 = last + 1 < (double)xb ? (last + 1 > (double)r0 ? (long)(last + 1) : r0) : xb;
		if (r0 >= r1)
			continue;
		int at = k++;
		while (at > 0 && run[at - 1][0] > r0) {
			run[at][0] = run[at - 1][0];
			run[at][1] = run[at - 1][1];
			quad[at] = quad[at - 1];
			at--;
		}
		run[at][0] = r0;
		run[at][1] = r1;
		quad[at] = q;
	}
	return k;
}

/* One pixel's channels (grey repeated) into the sample buffers at n, counted when
 * clipped: its channel sum, added in the order the quadrant sums expect. */
static inline double take_pixel(const float *px, int C, const float clip3[3], long n,
                                float *ch0, float *ch1, float *ch2, float *sums,
                                long *nclipped)
{
	float v0 = px[0], v1 = px[C == 3 ? 1 : 0], v2 = px[C == 3 ? 2 : 0];
	double sum = 0;
	sum += v0;
	sum += v1;
	sum += v2;
	ch0[n] = v0;
	ch1[n] = v1;
	ch2[n] = v2;
	sums[n] = (float)sum;
	*nclipped += (v0 >= clip3[0]) | (v1 >= clip3[1]) | (v2 >= clip3[2]);
	return sum;
}

/* Sample one patch: every pixel whose centre maps inside the patch's centred
 * sample_fraction. The reference maps every pixel of the region's bounding box
 * through the inverse homography; fast rasterises the region row by row (span_row),
 * classifies by the affine forms and falls back to the reference test within 1e-9
 * of the patch scale of a side or a quadrant boundary, so both take the same pixels
 * in the same order, and counts or selects by radix_pair: the same values. Within a
 * row, the runs of pixels clearly inside one quadrant (clear_runs) are taken without
 * classifying each. */
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
	if (chart_buffers_reserve(buf, cap ? cap : 1, cap ? ix1 - ix0 : 1))
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
		const float *row = chart_image_span(wi, (int)y, (int)xa, (int)((xb - xa - 1) / stride + 1),
		                              stride, buf->row);
		long run[4][2];
		int quad[4], nruns = fast ? clear_runs(&s, hx, hy, 2 * tol, xa, xb, run, quad) : 0;
		/* j: x's pixel in the span, (x - xa) / stride, counted rather than divided. The
		 * pixels before each clear run are classified one by one, the run's are not. */
		long x = xa, j = 0;
		for (int r = 0; r <= nruns; r++) {
			for (long end = r < nruns ? run[r][0] : xb; x < end; x += stride, j++) {
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
				double sum = take_pixel(row + j * C, C, clip3, n, ch0, ch1, ch2, sums, &nclipped);
				switch (q) {
				case 0: qs0 += sum; break;
				case 1: qs1 += sum; break;
				case 2: qs2 += sum; break;
				default: qs3 += sum;
				}
				qn[q]++;
				n++;
			}
			if (r == nruns)
				break;
			int q = quad[r];
			double acc = q == 0 ? qs0 : q == 1 ? qs1 : q == 2 ? qs2 : qs3;
			long n0 = n;
			for (; x < run[r][1]; x += stride, j++) {
				acc += take_pixel(row + j * C, C, clip3, n, ch0, ch1, ch2, sums, &nclipped);
				n++;
			}
			qn[q] += n - n0;
			switch (q) {
			case 0: qs0 = acc; break;
			case 1: qs1 = acc; break;
			case 2: qs2 = acc; break;
			default: qs3 = acc;
			}
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
	/* a sparse sample's pixel stands for stride x stride of the region's */
	double inside = expected > 0 ? (double)n * stride * stride / expected : 0;
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
		} else if (count && !chart_count_values(buf->ch[c], n, wi->count_scale, buf)) {
			chart_counted_stats(buf, n, opt, wi->quantum, &p->rgb[c], &p->sd[c]);
		} else {
			chart_robust_stats(buf->ch[c], buf->work, buf->keys, n, opt, wi->quantum, fast,
			             &p->rgb[c], &p->sd[c]);
		}
	}
	/* Glare: bright outliers in the channel sum, beyond 6 sigma and 5 % of the level. */
	double sum_med, sum_sigma, bright;
	kg_chart_detect_options med_opt = *opt;
	med_opt.statistic = KG_CHART_MEDIAN;
	long nbright = 0;
	if (count && !chart_count_values(buf->sum, n, wi->count_scale, buf)) {
		chart_counted_stats(buf, n, &med_opt, 0, &sum_med, &sum_sigma);
		bright = sum_med + fmax(6 * sum_sigma, 0.05 * fabs(sum_med));
		nbright = chart_counted_above(buf, bright);
	} else {
		memcpy(buf->work, buf->sum, (size_t)n * sizeof(float)); /* keep sums for counting */
		chart_robust_stats(buf->work, buf->ch[0], buf->keys, n, &med_opt, 0, fast, &sum_med,
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
	sample_buffers *bufs; /* one set per thread */
	int fast, stride;
	int failed[MAX_THREADS];
} sample_job;

/* Thread t samples patches t, t + n, ...: each patch alone decides its values. */
static void sample_patches(void *arg, int t, int n)
{
	sample_job *j = arg;
	for (int i = t; i < j->L->npatches && !j->failed[t]; i += n)
		j->failed[t] = sample_patch(j->wi, j->H, j->Hinv, j->L->patch_center[i],
		                            j->L->patch_size[i], j->opt, j->fast, j->stride,
		                            &j->bufs[t], &j->patches[i]) != 0;
}

/* Every patch of L in wi through r->H into r->patches: fast or the reference, every
 * stride-th row and column of each region (1: every pixel; more gives the patch
 * values of a sparse sample, whose pixel counts and flags are those of the sample). */
int chart_sample_all_with(const layout_view *L, work_image *wi,
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
	sample_job j = {L, wi, opt, r->H, Hinv, r->patches, wi->sample_bufs, fast,
	                stride > 1 ? stride : 1, {0}};
	chart_run_parallel(sample_patches, &j, opt->threads);
	for (int t = 0; t < MAX_THREADS; t++)
		if (j.failed[t])
			return kg_fail(err, KG_ENOMEM, "patch sampling: out of memory");
	for (int k = 0; k < 4; k++)
		kg_homography_map(r->H, L->outline[k][0], L->outline[k][1], r->outline[k]);
	return 0;
}

int chart_sample_all(const layout_view *L, work_image *wi,
                      const kg_chart_detect_options *opt, kg_chart_result *r, kg_err *err)
{
	return chart_sample_all_with(L, wi, opt, 1, 1, r, err);
}
