/* Dark subtraction, flat-field correction, image statistics and the robust bright
 * level the exposure helper uses without a chart. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_acquire.h"


static int same_size(const kg_image *a, const kg_image *b, const char *what, kg_err *err)
{
	if (a->width != b->width || a->height != b->height || a->channels != b->channels)
		return kg_fail(err, KG_EINVAL,
		               "%s is %dx%d with %d channel(s); the image is %dx%d with %d: expected "
		               "the same size",
		               what, b->width, b->height, b->channels, a->width, a->height,
		               a->channels);
	if (a->cfa && b->cfa && strcmp(a->cfa, b->cfa))
		return kg_fail(err, KG_EINVAL, "%s has the CFA pattern %s; the image has %s", what,
		               b->cfa, a->cfa);
	return 0;
}

int kg_correct_dark(kg_image *mean, const kg_image *dark, kg_err *err)
{
	kg_check_arg(mean && dark, err);
	int ret = same_size(mean, dark, "the dark", err);
	if (ret)
		return ret;
	size_t n = (size_t)mean->width * (size_t)mean->height * (size_t)mean->channels;
	for (size_t i = 0; i < n; i++)
		mean->data[i] -= dark->data[i];
	return 0;
}

int kg_colour_class(int channels, const char *cfa, int cfa_rows, int cfa_cols, int channel,
                    size_t x, size_t y)
{
	if (channels > 1)
		return channel;
	if (!cfa)
		return 0;
	char l = cfa[(y % (size_t)cfa_rows) * (size_t)cfa_cols + x % (size_t)cfa_cols];
	return l == 'R' ? 0 : l == 'G' ? 1 : l == 'B' ? 2 : 3;
}

/* The colour class of sample i of img. */
static int colour_class(const kg_image *img, size_t i)
{
	size_t C = (size_t)img->channels, p = i / C;
	return kg_colour_class(img->channels, img->cfa, img->cfa_rows, img->cfa_cols, (int)(i % C),
	                       p % (size_t)img->width, p / (size_t)img->width);
}

/* Per colour class of the flat: the cut below which a sample is invalid, and the sum
 * and count of the valid samples (the means over positive samples, then again over
 * the valid ones). */
static void flat_valid_means(const kg_image *flat, size_t n, double cut[4], double sum[4],
                             long count[4])
{
	for (int c = 0; c < 4; c++) {
		sum[c] = 0;
		count[c] = 0;
	}
	for (size_t i = 0; i < n; i++) {
		float v = flat->data[i];
		if (isfinite(v) && v > 0) {
			int c = colour_class(flat, i);
			sum[c] += v;
			count[c]++;
		}
	}
	for (int c = 0; c < 4; c++) {
		cut[c] = count[c] ? KG_FLAT_VALID_FRACTION * sum[c] / (double)count[c] : INFINITY;
		sum[c] = 0;
		count[c] = 0;
	}
	for (size_t i = 0; i < n; i++) {
		float v = flat->data[i];
		int c = colour_class(flat, i);
		if (isfinite(v) && v > cut[c]) {
			sum[c] += v;
			count[c]++;
		}
	}
}

/* ---- the flat low-passed ------------------------------------------------------------ */

int kg_flat_smooth_init(kg_flat_smooth *s, int width, int height, int channels,
                        const char *cfa, int cfa_rows, int cfa_cols, kg_err *err)
{
	memset(s, 0, sizeof(*s));
	if (width < 1 || height < 1 || channels < 1 || (cfa && strlen(cfa) >= sizeof(s->cfa)))
		return kg_fail(err, KG_EINVAL, "flat of %dx%d with %d channel(s): expected a positive "
		               "size", width, height, channels);
	s->width = width;
	s->height = height;
	s->channels = channels;
	if (cfa && cfa[0]) {
		snprintf(s->cfa, sizeof(s->cfa), "%s", cfa);
		s->cfa_rows = cfa_rows;
		s->cfa_cols = cfa_cols;
	}
	int shortest = width < height ? width : height;
	s->block = (int)lround((double)shortest / KG_FLAT_BLOCK_DIVISOR);
	if (s->block < KG_FLAT_BLOCK_MIN)
		s->block = KG_FLAT_BLOCK_MIN;
	if (s->cfa[0] && cfa_rows > 0 && cfa_cols > 0) {
		/* whole tiles per block, and each colour's mean place in its tile */
		int tile = cfa_rows > cfa_cols ? cfa_rows : cfa_cols;
		s->block = (s->block + tile - 1) / tile * tile;
		double n[4] = {0};
		for (int ty = 0; ty < cfa_rows; ty++)
			for (int tx = 0; tx < cfa_cols; tx++) {
				int c = kg_colour_class(1, s->cfa, cfa_rows, cfa_cols, 0, (size_t)tx, (size_t)ty);
				s->ox[c] += tx + 0.5 - 0.5 * cfa_cols;
				s->oy[c] += ty + 0.5 - 0.5 * cfa_rows;
				n[c]++;
			}
		for (int c = 0; c < 4; c++)
			if (n[c] > 0) {
				s->ox[c] /= n[c];
				s->oy[c] /= n[c];
			}
	}
	s->gw = (width + s->block - 1) / s->block;
	s->gh = (height + s->block - 1) / s->block;
	size_t n = (size_t)s->gw * (size_t)s->gh;
	for (int c = 0; c < 4; c++) {
		s->sum[c] = calloc(n, sizeof(double));
		s->count[c] = calloc(n, sizeof(long));
		if (!s->sum[c] || !s->count[c]) {
			kg_flat_smooth_free(s);
			return kg_fail(err, KG_ENOMEM, "out of memory");
		}
	}
	return 0;
}

void kg_flat_smooth_free(kg_flat_smooth *s)
{
	for (int c = 0; c < 4; c++) {
		free(s->sum[c]);
		free(s->count[c]);
		s->sum[c] = NULL;
		s->count[c] = NULL;
	}
}

static int smooth_class(const kg_flat_smooth *s, int channel, int x, int y)
{
	return kg_colour_class(s->channels, s->cfa[0] ? s->cfa : NULL, s->cfa_rows, s->cfa_cols,
	                       channel, (size_t)x, (size_t)y);
}

void kg_flat_smooth_add(kg_flat_smooth *s, const float *rows, int y0, int nrows)
{
	int C = s->channels, B = s->block;
	for (int r = 0; r < nrows; r++) {
		int y = y0 + r;
		if (y < 0 || y >= s->height)
			continue;
		const float *row = rows + (size_t)r * (size_t)s->width * (size_t)C;
		size_t g0 = (size_t)(y / B) * (size_t)s->gw;
		for (int x = 0; x < s->width; x++)
			for (int k = 0; k < C; k++) {
				float v = row[(size_t)x * (size_t)C + (size_t)k];
				if (!(isfinite(v) && v > 0))
					continue;
				int c = smooth_class(s, k, x, y);
				s->sum[c][g0 + (size_t)(x / B)] += v;
				s->count[c][g0 + (size_t)(x / B)]++;
			}
	}
}

void kg_flat_smooth_finish(kg_flat_smooth *s)
{
	size_t n = (size_t)s->gw * (size_t)s->gh;
	for (int c = 0; c < 4; c++) {
		s->lo[c] = s->hi[c] = NAN;
		for (size_t i = 0; i < n; i++) {
			double m = s->count[c][i] ? s->sum[c][i] / (double)s->count[c][i] : NAN;
			s->sum[c][i] = m;
			if (isfinite(m)) {
				s->lo[c] = isnan(s->lo[c]) ? m : fmin(s->lo[c], m);
				s->hi[c] = isnan(s->hi[c]) ? m : fmax(s->hi[c], m);
			}
		}
	}
	s->finished = 1;
}

/* Along one axis of n pixels cut into g blocks of B: the block i0 whose centre is at or
 * before the pixel centre X (clamped to 0..g-2, so the border half-blocks extrapolate)
 * and the weight t of block i0 + 1. */
static void smooth_axis(int n, int B, int g, double X, int *i0, double *t)
{
	if (g < 2) {
		*i0 = 0;
		*t = 0;
		return;
	}
	int i = (int)floor(X / B - 0.5);
	i = i < 0 ? 0 : i > g - 2 ? g - 2 : i;
	double c0 = 0.5 * (i * B + fmin((i + 1) * B, n));
	double c1 = 0.5 * ((i + 1) * B + fmin((i + 2) * B, n));
	*i0 = i;
	*t = (X - c0) / (c1 - c0);
}

double kg_flat_smooth_at(const kg_flat_smooth *s, int channel, int x, int y)
{
	int k = smooth_class(s, channel, x, y);
	const double *m = s->sum[k];
	int i, j;
	double tx, ty;
	smooth_axis(s->width, s->block, s->gw, x + 0.5 - s->ox[k], &i, &tx);
	smooth_axis(s->height, s->block, s->gh, y + 0.5 - s->oy[k], &j, &ty);
	int i1 = s->gw > 1 ? i + 1 : i, j1 = s->gh > 1 ? j + 1 : j;
	size_t W = (size_t)s->gw;
	double a = m[(size_t)j * W + (size_t)i], b = m[(size_t)j * W + (size_t)i1];
	double c = m[(size_t)j1 * W + (size_t)i], d = m[(size_t)j1 * W + (size_t)i1];
	double top = a + tx * (b - a), bottom = c + tx * (d - c);
	return top + ty * (bottom - top);
}

int kg_flat_check(const kg_flat_smooth *s, double clipped_fraction, const char *name,
                  double *ratio, kg_err *err)
{
	static const char *const rgb[] = {"R", "G", "B", "other"};
	double worst = INFINITY;
	int wc = -1;
	for (int c = 0; c < 4; c++)
		if (isfinite(s->lo[c]) && s->hi[c] > 0 && s->lo[c] / s->hi[c] < worst) {
			worst = s->lo[c] / s->hi[c];
			wc = c;
		}
	if (ratio)
		*ratio = wc >= 0 ? worst : NAN;
	if (clipped_fraction > KG_FLAT_MAX_CLIPPED)
		return kg_fail(err, KG_EINVAL,
		               "flat %s is clipped: %.3g %% of its samples reached the sensor's "
		               "saturation when it was taken (its statistics.clipped_fraction; limit "
		               "%.3g %%): where it clipped it does not measure the light; take the "
		               "flat again with less exposure or light",
		               name, 100 * clipped_fraction, 100 * KG_FLAT_MAX_CLIPPED);
	if (wc < 0)
		return kg_fail(err, KG_EINVAL, "flat %s has no valid sample (all at or below 0)",
		               name);
	if (worst < KG_FLAT_MIN_RATIO)
		return kg_fail(err, KG_EINVAL,
		               "flat %s is too uneven: its dimmest part gets %.1f %% of its brightest "
		               "part's light (%s%s, block means of %d x %d px of the smoothed flat: "
		               "%.4g to %.4g; limit %.0f %%): light the target more evenly, centre "
		               "the lamp, or stop the lens down",
		               name, 100 * worst, s->channels == 1 && !s->cfa[0] ? "" : "colour ",
		               s->channels == 1 && !s->cfa[0] ? "grey" : rgb[wc], s->block, s->block,
		               s->lo[wc], s->hi[wc], 100 * KG_FLAT_MIN_RATIO);
	return 0;
}

/* The smoothed flat of a flat in memory. */
static int smooth_image(const kg_image *flat, kg_flat_smooth *s, kg_err *err)
{
	int ret = kg_flat_smooth_init(s, flat->width, flat->height, flat->channels, flat->cfa,
	                              flat->cfa_rows, flat->cfa_cols, err);
	if (ret)
		return ret;
	kg_flat_smooth_add(s, flat->data, 0, flat->height);
	kg_flat_smooth_finish(s);
	return 0;
}

int kg_flat_check_image(const kg_image *flat, double clipped_fraction, const char *name,
                        double *ratio, kg_err *err)
{
	kg_check_arg(flat && flat->data && name, err);
	kg_flat_smooth s;
	int ret = smooth_image(flat, &s, err);
	if (!ret)
		ret = kg_flat_check(&s, clipped_fraction, name, ratio, err);
	kg_flat_smooth_free(&s);
	return ret;
}

int kg_correct_flat(kg_image *mean, kg_image *variance, const kg_image *flat, long *invalid,
                    kg_err *err)
{
	kg_check_arg(mean && flat, err);
	int ret = same_size(mean, flat, "the flat", err);
	if (!ret && variance)
		ret = same_size(mean, variance, "the variance", err);
	if (ret)
		return ret;
	size_t n = (size_t)mean->width * (size_t)mean->height * (size_t)mean->channels;
	double sum[4], cut[4];
	long count[4];
	flat_valid_means(flat, n, cut, sum, count);
	kg_flat_smooth sm;
	if ((ret = smooth_image(flat, &sm, err)))
		return ret;
	long bad = 0;
	size_t C = (size_t)flat->channels, W = (size_t)flat->width;
	for (size_t i = 0; i < n; i++) {
		size_t p = i / C;
		double v = kg_flat_smooth_at(&sm, (int)(i % C), (int)(p % W), (int)(p / W));
		int c = colour_class(flat, i);
		if (!(isfinite(v) && v > cut[c])) {
			mean->data[i] = NAN;
			if (variance)
				variance->data[i] = NAN;
			bad++;
			continue;
		}
		double g = v / (sum[c] / (double)count[c]);
		mean->data[i] = (float)(mean->data[i] / g);
		if (variance)
			variance->data[i] = (float)(variance->data[i] / (g * g));
	}
	kg_flat_smooth_free(&sm);
	if (invalid)
		*invalid = bad;
	return 0;
}

int kg_flat_nonuniformity(const kg_image *flat, double *out, kg_err *err)
{
	kg_check_arg(flat && flat->data && out, err);
	*out = NAN;
	size_t n = (size_t)flat->width * (size_t)flat->height * (size_t)flat->channels;
	double sum[4], cut[4];
	long count[4];
	flat_valid_means(flat, n, cut, sum, count);
	enum { B = KG_FLAT_BLOCKS };
	double bsum[B][B] = {{0}};
	long bcount[B][B] = {{0}};
	size_t C = (size_t)flat->channels, W = (size_t)flat->width, H = (size_t)flat->height;
	for (size_t i = 0; i < n; i++) {
		float v = flat->data[i];
		int c = colour_class(flat, i);
		if (!(isfinite(v) && v > cut[c]))
			continue;
		size_t p = i / C, x = p % W, y = p / W;
		bsum[y * B / H][x * B / W] += v / (sum[c] / (double)count[c]);
		bcount[y * B / H][x * B / W]++;
	}
	double mean = 0;
	int nb = 0;
	for (int a = 0; a < B; a++)
		for (int b = 0; b < B; b++)
			if (bcount[a][b]) {
				mean += bsum[a][b] / (double)bcount[a][b];
				nb++;
			}
	if (!nb)
		return 0;
	mean /= nb;
	double worst = 0;
	for (int a = 0; a < B; a++)
		for (int b = 0; b < B; b++)
			if (bcount[a][b])
				worst = fmax(worst, fabs(bsum[a][b] / (double)bcount[a][b] - mean));
	*out = worst / mean;
	return 0;
}

/* ---- order statistics ------------------------------------------------------------ */

/* Percentile p (0..100) of v[0..n-1] with linear interpolation between order
 * statistics (v is reordered). */
static double percentile(float *v, size_t n, double p)
{
	double pos = p / 100.0 * (double)(n - 1);
	size_t k = (size_t)floor(pos);
	if (k >= n - 1)
		return kg_select_kth(v, n, n - 1);
	kg_select_kth(v, n, k);
	float next = v[k + 1];
	for (size_t i = k + 2; i < n; i++)
		if (v[i] < next)
			next = v[i];
	return v[k] + (pos - (double)k) * ((double)next - v[k]);
}

int kg_image_stats_compute(const kg_image *img, kg_image_stats *out, kg_err *err)
{
	kg_check_arg(img && out, err);
	memset(out, 0, sizeof(*out));
	size_t n = (size_t)img->width * (size_t)img->height * (size_t)img->channels;
	float *v = malloc(n * sizeof(float));
	if (!v)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	size_t m = 0, under = 0;
	for (size_t i = 0; i < n; i++)
		if (isfinite(img->data[i])) {
			v[m++] = img->data[i];
			under += img->data[i] < KG_UNDEREXPOSED_LEVEL;
		}
	out->nonfinite = (long)(n - m);
	if (!m) {
		out->min = out->max = out->p01 = out->p50 = out->p99 = out->p999 = NAN;
		out->underexposed_fraction = NAN;
		free(v);
		return 0;
	}
	out->underexposed_fraction = (double)under / (double)m;
	out->min = out->max = v[0];
	for (size_t i = 1; i < m; i++) {
		if (v[i] < out->min)
			out->min = v[i];
		if (v[i] > out->max)
			out->max = v[i];
	}
	out->p01 = percentile(v, m, 1);
	out->p50 = percentile(v, m, 50);
	out->p99 = percentile(v, m, 99);
	out->p999 = percentile(v, m, 99.9);
	free(v);
	return 0;
}

/* ---- bright level -------------------------------------------------------------- */

/* Box mean of radius r over the finite values of a w x h plane (borders: the samples
 * that exist), in place. sum and cnt are scratch of w * h, colsum and colcnt of w. */
static void box_mean(float *p, int w, int h, int r, double *sum, int *cnt, double *colsum,
                     int *colcnt)
{
	for (int y = 0; y < h; y++) { /* horizontal running sums */
		const float *row = p + (size_t)y * (size_t)w;
		double s = 0;
		int c = 0;
		for (int x = -r; x < w; x++) {
			int add = x + r, drop = x - r - 1;
			if (add < w && isfinite(row[add])) {
				s += row[add];
				c++;
			}
			if (drop >= 0 && isfinite(row[drop])) {
				s -= row[drop];
				c--;
			}
			if (x >= 0) {
				sum[(size_t)y * (size_t)w + (size_t)x] = s;
				cnt[(size_t)y * (size_t)w + (size_t)x] = c;
			}
		}
	}
	memset(colsum, 0, sizeof(double) * (size_t)w); /* vertical, on the row sums */
	memset(colcnt, 0, sizeof(int) * (size_t)w);
	for (int y = -r; y < h; y++) {
		int add = y + r, drop = y - r - 1;
		for (int x = 0; x < w; x++) {
			if (add < h) {
				colsum[x] += sum[(size_t)add * (size_t)w + (size_t)x];
				colcnt[x] += cnt[(size_t)add * (size_t)w + (size_t)x];
			}
			if (drop >= 0) {
				colsum[x] -= sum[(size_t)drop * (size_t)w + (size_t)x];
				colcnt[x] -= cnt[(size_t)drop * (size_t)w + (size_t)x];
			}
			if (y >= 0)
				p[(size_t)y * (size_t)w + (size_t)x] =
					colcnt[x] ? (float)(colsum[x] / colcnt[x]) : NAN;
		}
	}
}

int kg_bright_level(const kg_image *img, int radius, double percentile_p, double *level,
                    kg_err *err)
{
	kg_check_arg(img && level && radius >= 0 && percentile_p >= 0 && percentile_p <= 100,
	             err);
	/* Planes of one colour: each channel; for a mosaic each site of its repeat. */
	int sy_n = 1, sx_n = 1;
	if (img->channels == 1 && img->cfa) {
		sy_n = img->cfa_rows;
		sx_n = img->cfa_cols;
	}
	size_t total = (size_t)img->width * (size_t)img->height * (size_t)img->channels;
	float *all = malloc(total * sizeof(float));
	float *plane = malloc(total * sizeof(float));
	double *sum = malloc(total * sizeof(double));
	int *cnt = malloc(total * sizeof(int));
	double *colsum = malloc((size_t)img->width * sizeof(double));
	int *colcnt = malloc((size_t)img->width * sizeof(int));
	if (!all || !plane || !sum || !cnt || !colsum || !colcnt) {
		free(all);
		free(plane);
		free(sum);
		free(cnt);
		free(colsum);
		free(colcnt);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	size_t m = 0;
	for (int c = 0; c < img->channels; c++)
		for (int sy = 0; sy < sy_n; sy++)
			for (int sx = 0; sx < sx_n; sx++) {
				int w = (img->width - sx + sx_n - 1) / sx_n;
				int h = (img->height - sy + sy_n - 1) / sy_n;
				if (w <= 0 || h <= 0)
					continue;
				for (int y = 0; y < h; y++)
					for (int x = 0; x < w; x++) {
						size_t X = (size_t)(sx + x * sx_n), Y = (size_t)(sy + y * sy_n);
						plane[(size_t)y * (size_t)w + (size_t)x] =
							img->data[(Y * (size_t)img->width + X) * (size_t)img->channels +
							          (size_t)c];
					}
				box_mean(plane, w, h, radius, sum, cnt, colsum, colcnt);
				for (size_t i = 0; i < (size_t)w * (size_t)h; i++)
					if (isfinite(plane[i]))
						all[m++] = plane[i];
			}
	int ret = 0;
	if (!m)
		ret = kg_fail(err, KG_EINVAL, "bright level: the image has no finite sample");
	else
		*level = percentile(all, m, percentile_p);
	free(all);
	free(plane);
	free(sum);
	free(cnt);
	free(colsum);
	free(colcnt);
	return ret;
}
