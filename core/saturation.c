/* Saturation found from the data (saturation.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "saturation.h"

/* The sum of bins [lo, hi] and how many of them are occupied. */
static uint64_t window(const uint64_t *hist, int lo, int hi, int *occupied)
{
	uint64_t s = 0;
	int occ = 0;
	for (int b = lo < 0 ? 0 : lo; b <= hi; b++) {
		s += hist[b];
		occ += hist[b] != 0;
	}
	*occupied = occ;
	return s;
}

/* The data's code spacing in bins: the most common gap between consecutive occupied
 * bins (1 for data quantised as the histogram is; 257 for 8-bit values scaled to 16
 * bits; ~17 for a 12-bit raw scaled to 16 bits). Ties go to the smaller gap. */
static int code_spacing(const uint64_t *hist, int nbins)
{
	enum { MAXGAP = 1024 };
	static _Thread_local unsigned count[MAXGAP + 1];
	memset(count, 0, sizeof(count));
	int prev = -1;
	for (int b = 0; b < nbins; b++) {
		if (!hist[b])
			continue;
		if (prev >= 0) {
			int g = b - prev;
			count[g > MAXGAP ? MAXGAP : g]++;
		}
		prev = b;
	}
	int best = 1;
	unsigned n = 0;
	for (int g = 1; g < MAXGAP; g++) /* a gap of MAXGAP or more is not a code spacing */
		if (count[g] > n) {
			n = count[g];
			best = g;
		}
	/* codes that round to neighbouring bins alternate two gaps (17, 18): the pair's */
	if (best + 1 < MAXGAP && count[best + 1] * 2 > count[best])
		best++;
	return best;
}

int kg_saturation_detect(const uint64_t *hist, int nbins)
{
	if (!hist || nbins < 16)
		return -1;
	uint64_t total = 0;
	for (int b = 0; b < nbins; b++)
		total += hist[b];
	int top = nbins - 1;
	while (top >= 0 && !hist[top])
		top--;
	if (top < 0)
		return -1;
	int q = code_spacing(hist, nbins);
	int lo = top - (KG_SAT_CLUSTER_BINS - 1) * q;
	if (lo < 0)
		lo = 0;
	int occ_top;
	uint64_t n_top = window(hist, lo, top, &occ_top);
	if (n_top < KG_SAT_MIN_COUNT || (double)n_top < KG_SAT_MIN_FRACTION * (double)total)
		return -1;
	int w = (int)lround(KG_SAT_WINDOW_FRACTION * (double)(nbins - 1));
	if (w < 8 * q)
		w = 8 * q;
	int wlo = lo - w, whi = lo - 1;
	if (whi < 0)
		return -1;
	if (wlo < 0)
		wlo = 0;
	int occ;
	uint64_t n_below = window(hist, wlo, whi, &occ);
	double codes = (double)(whi - wlo + 1) / q; /* codes the window can hold */
	if (occ < 1 || (double)occ < KG_SAT_MIN_OCCUPANCY * codes)
		return -1;
	double mean = (double)n_below / (double)occ; /* per occupied bin */
	double limit = KG_SAT_RATIO * mean;
	/* The cluster, not the bin: a ceiling that jitters spreads its pile over 2-3 codes. */
	if ((double)n_top <= limit * (occ_top > 0 ? occ_top : 1))
		return -1;
	/* The lowest bin of the cluster that is itself a pile-up (at least one is: the
	 * cluster's largest bin holds more than limit when the cluster does per bin). */
	for (int b = lo; b <= top; b++)
		if ((double)hist[b] > limit)
			return b;
	return top;
}

int kg_saturation_steps(const kg_image *img)
{
	if (!img || img->is_float || img->bits < 8 || img->bits > 16)
		return 65535;
	return (1 << img->bits) - 1;
}

int kg_sat_hist_init(kg_sat_hist *h, int channels, int steps, kg_err *err)
{
	memset(h, 0, sizeof(*h));
	if (channels < 1 || channels > KG_SAT_MAX_CHANNELS || steps < 15 || steps > 65535)
		return kg_fail(err, KG_EINVAL, "saturation histogram: %d channels of %d steps: "
		               "expected 1..%d channels of 15..65535 steps", channels, steps,
		               KG_SAT_MAX_CHANNELS);
	h->channels = channels;
	h->steps = steps;
	for (int c = 0; c < channels; c++)
		if (!(h->bins[c] = calloc((size_t)steps + 1, sizeof(uint64_t)))) {
			kg_sat_hist_free(h);
			return kg_fail(err, KG_ENOMEM, "out of memory");
		}
	return 0;
}

void kg_sat_hist_free(kg_sat_hist *h)
{
	for (int c = 0; c < KG_SAT_MAX_CHANNELS; c++) {
		free(h->bins[c]);
		h->bins[c] = NULL;
	}
}

static inline int bin_of(double v, int steps)
{
	double x = v * steps + 0.5;
	if (!(x > 0))
		return 0;
	if (x >= steps)
		return steps;
	return (int)x;
}

void kg_sat_hist_add1(kg_sat_hist *h, int c, double v)
{
	if (c < 0 || c >= h->channels || !isfinite(v))
		return;
	h->bins[c][bin_of(v, h->steps)]++;
	h->total[c]++;
}

void kg_sat_hist_add(kg_sat_hist *h, const float *px, size_t n)
{
	int C = h->channels, S = h->steps;
	for (size_t i = 0; i < n; i++)
		for (int c = 0; c < C; c++) {
			float v = px[i * (size_t)C + (size_t)c];
			if (isfinite(v)) {
				h->bins[c][bin_of(v, S)]++;
				h->total[c]++;
			}
		}
}

void kg_sat_hist_result(const kg_sat_hist *h, double nominal_clip, kg_saturation *out)
{
	memset(out, 0, sizeof(*out));
	out->channels = h->channels;
	out->steps = h->steps;
	out->nominal = nominal_clip;
	for (int c = 0; c < h->channels; c++) {
		out->clip[c] = nominal_clip;
		out->level[c] = NAN;
		int b = kg_saturation_detect(h->bins[c], h->steps + 1);
		if (b >= 0) {
			double level = (double)b / h->steps;
			double clip = ((double)b - 0.5) / h->steps;
			out->level[c] = level;
			if (clip < nominal_clip && level >= KG_SAT_MIN_LEVEL) {
				out->found[c] = 1;
				out->clip[c] = clip;
			}
		}
		/* the fraction at or above the clip level, from the bins */
		uint64_t n = 0;
		int from = bin_of(out->clip[c], h->steps);
		if ((double)from / h->steps < out->clip[c])
			from++;
		for (int k = from; k <= h->steps; k++)
			n += h->bins[c][k];
		out->fraction[c] = h->total[c] ? (double)n / (double)h->total[c] : 0;
	}
}

void kg_sat_flat_init(kg_sat_flat *f, const kg_saturation *s)
{
	memset(f, 0, sizeof(*f));
	f->sat = *s;
}

void kg_sat_flat_add(kg_sat_flat *f, const float *px, size_t n)
{
	const kg_saturation *s = &f->sat;
	if (s->channels != 3)
		return;
	for (size_t i = 0; i < n; i++) {
		const float *p = px + 3 * i;
		for (int c = 0; c < 3; c++) {
			if (!s->found[c] || !(p[c] >= s->clip[c]))
				continue;
			f->piled[c]++;
			for (int d = 0; d < 3; d++) {
				if (d == c || !(p[d] < s->clip[d]) || !isfinite(p[d]))
					continue;
				if (!f->n[c][d])
					f->ref[c][d] = p[d];
				f->n[c][d]++;
				double dv = p[d] - f->ref[c][d];
				f->sum[c][d] += dv;
				f->sumsq[c][d] += dv * dv;
			}
		}
	}
}

int kg_sat_flat_result(const kg_sat_flat *f, kg_saturation *out)
{
	*out = f->sat;
	int dropped = 0;
	double step = out->steps > 0 ? 1.0 / out->steps : 1.0 / 65535;
	for (int c = 0; c < out->channels && out->channels == 3; c++) {
		if (!out->found[c] || !f->piled[c])
			continue;
		for (int d = 0; d < 3; d++) {
			double n = (double)f->n[c][d];
			if (d == c || n < 0.5 * (double)f->piled[c])
				continue;
			double m = f->sum[c][d] / n, var = f->sumsq[c][d] / n - m * m;
			if (var < 0.25 * step * step) { /* flat where it is not clipped: an object */
				out->found[c] = 0;
				out->clip[c] = out->nominal;
				out->fraction[c] = 0;
				dropped = 1;
				break;
			}
		}
	}
	return dropped;
}

/* Channel of pixel (x, y): the CFA position of a 1-channel 2x2 mosaic, else c. */
static int sat_channels(const kg_image *img, int *mosaic)
{
	*mosaic = img->channels == 1 && img->cfa && img->cfa_rows == 2 && img->cfa_cols == 2;
	return *mosaic ? 4 : img->channels;
}

int kg_saturation_of_image(const kg_image *img, double nominal_clip, kg_saturation *out,
                           kg_err *err)
{
	if (img && !img->data && img->u16)
		return kg_saturation_of_u16(img, nominal_clip, out, err);
	kg_check_arg(img && img->data && out, err);
	int mosaic;
	int C = sat_channels(img, &mosaic);
	if (C > KG_SAT_MAX_CHANNELS)
		return kg_fail(err, KG_EINVAL, "saturation: %d channels: expected at most %d", C,
		               KG_SAT_MAX_CHANNELS);
	kg_sat_hist h;
	int ret = kg_sat_hist_init(&h, C, kg_saturation_steps(img), err);
	if (ret)
		return ret;
	size_t W = (size_t)img->width, H = (size_t)img->height;
	if (mosaic) {
		for (size_t y = 0; y < H; y++)
			for (size_t x = 0; x < W; x++)
				kg_sat_hist_add1(&h, (int)((y & 1) * 2 + (x & 1)), img->data[y * W + x]);
	} else {
		kg_sat_hist_add(&h, img->data, W * H);
	}
	kg_sat_hist_result(&h, nominal_clip, out);
	kg_sat_hist_free(&h);
	if (!mosaic && C == 3 && kg_saturation_below(out, nominal_clip)) {
		kg_sat_flat f;
		kg_sat_flat_init(&f, out);
		kg_sat_flat_add(&f, img->data, W * H);
		kg_sat_flat_result(&f, out);
	}
	size_t any = 0, n = W * H;
	for (size_t y = 0; y < H; y++)
		for (size_t x = 0; x < W; x++) {
			const float *p = img->data + (y * W + x) * (size_t)img->channels;
			int hit = 0;
			if (mosaic)
				hit = p[0] >= out->clip[(y & 1) * 2 + (x & 1)];
			else
				for (int c = 0; c < C; c++)
					hit |= p[c] >= out->clip[c];
			any += (size_t)hit;
		}
	out->fraction_any = n ? (double)any / (double)n : 0;
	return 0;
}

int kg_saturation_of_rows(const kg_row_source *src, int steps, double nominal_clip,
                          kg_saturation *out, kg_err *err)
{
	kg_check_arg(src && src->read && out, err);
	if (src->channels < 1 || src->channels > KG_SAT_MAX_CHANNELS)
		return kg_fail(err, KG_EINVAL, "saturation: %d channels: expected 1..%d",
		               src->channels, KG_SAT_MAX_CHANNELS);
	kg_sat_hist h;
	int ret = kg_sat_hist_init(&h, src->channels, steps, err);
	if (ret)
		return ret;
	int band = 64;
	size_t row = (size_t)src->width * (size_t)src->channels;
	float *buf = malloc(row * (size_t)band * sizeof(float));
	if (!buf) {
		kg_sat_hist_free(&h);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	for (int y = 0; y < src->height && !ret; y += band) {
		int rows = src->height - y < band ? src->height - y : band;
		if (!(ret = src->read(src->user, y, rows, buf, err)))
			kg_sat_hist_add(&h, buf, (size_t)rows * (size_t)src->width);
	}
	free(buf);
	if (!ret)
		kg_sat_hist_result(&h, nominal_clip, out);
	kg_sat_hist_free(&h);
	return ret;
}

int kg_saturation_below(const kg_saturation *s, double nominal_clip)
{
	for (int c = 0; c < s->channels; c++)
		if (s->found[c] && s->clip[c] < nominal_clip)
			return 1;
	return 0;
}

void kg_saturation_format(const kg_saturation *s, const char *names, char *buf, size_t n)
{
	size_t len = 0;
	buf[0] = 0;
	for (int c = 0; c < s->channels && len < n; c++) {
		if (!s->found[c])
			continue;
		char name = names && (int)strlen(names) > c ? names[c] : (char)('0' + c);
		int k = snprintf(buf + len, n - len, "%s%c at %.5f (%d of %d, %.3f %% of samples)",
		                 len ? ", " : "", name, s->level[c], (int)lround(s->level[c] * s->steps),
		                 s->steps, 100 * s->fraction[c]);
		if (k < 0)
			break;
		len += (size_t)k;
	}
}
