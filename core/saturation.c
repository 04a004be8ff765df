/* Saturation found from the data (saturation.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

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
	/* one bin more than the histogram: the scan counts non-finite samples there instead
	 * of branching on each sample */
	for (int c = 0; c < channels; c++)
		if (!(h->bins[c] = calloc((size_t)steps + 2, sizeof(uint64_t)))) {
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

/* bin_of for a sample, and steps + 1 when it is not finite (infinite or NaN: the
 * exponent all ones), a bin the histogram then leaves out. */
static inline uint32_t bin_or_dump(float v, int steps)
{
	uint32_t u;
	memcpy(&u, &v, sizeof(u));
	return (u & 0x7f800000u) == 0x7f800000u ? (uint32_t)steps + 1 : (uint32_t)bin_of(v, steps);
}

/* bin_or_dump for n samples, and in top[i % period] the highest of the bins of samples
 * i (period 1, 2 or 3: the channels of a block; top holds period values, raised, never
 * lowered). With SSE2, four samples at a time in single precision, which is close but
 * not exact: x = v * steps + 0.5, computed exactly in bin_of, is within 2^-7 of its
 * float counterpart r (each of the two roundings errs by at most 2^-8 below 2^16; r is
 * clamped to 0.25 .. steps + 0.75, where the bin no longer changes). floor(r) is never
 * below the exact bin floor(x): the half-way points count - 0.5 are floats, and
 * rounding keeps order. So floor(r) is the bin unless r lies less than 2^-7 above an
 * integer (r - floor(r) is exact); a sample with r less than 1/64 above one, or not
 * finite, is binned again by bin_or_dump, and its exact bin raised into top too. A
 * value that is a count divided by steps has r near the count plus 0.5 and is never
 * binned again; an arbitrary float is, one in 64. The maxima can only come out high,
 * which is safe for their use (a block read that need not have been). */
#ifdef __SSE2__
typedef struct bins_sse2 {
	__m128 vs, half, lo, hi, margin;
	__m128i absmask, maxfinite;
} bins_sse2;

/* Four samples: their approximate bins stored, the lanes to redo returned as bits,
 * the bins as floats raised into *m. */
static inline int bins4(const bins_sse2 *q, const float *v, uint32_t *out, __m128 *m)
{
	__m128 f = _mm_loadu_ps(v);
	__m128 r = _mm_add_ps(_mm_mul_ps(f, q->vs), q->half);
	/* maxps gives its second operand for NaN: lo */
	r = _mm_min_ps(_mm_max_ps(r, q->lo), q->hi);
	__m128i k = _mm_cvttps_epi32(r);
	__m128 kf = _mm_cvtepi32_ps(k);
	__m128 frac = _mm_sub_ps(r, kf);
	__m128i nonfinite =
	    _mm_cmpgt_epi32(_mm_and_si128(_mm_castps_si128(f), q->absmask), q->maxfinite);
	_mm_storeu_si128((__m128i *)(void *)out, k);
	*m = _mm_max_ps(*m, kf);
	return _mm_movemask_ps(
	    _mm_or_ps(_mm_cmplt_ps(frac, q->margin), _mm_castsi128_ps(nonfinite)));
}
#endif

static void bins_of(const float *v, size_t n, int steps, uint32_t *out, int period,
                    uint32_t *top)
{
	size_t i = 0;
#ifdef __SSE2__
	bins_sse2 q = {_mm_set1_ps((float)steps), _mm_set1_ps(0.5f), _mm_set1_ps(0.25f),
	               _mm_set1_ps((float)steps + 0.75f), _mm_set1_ps(1.0f / 64),
	               _mm_set1_epi32(0x7fffffff), _mm_set1_epi32(0x7f7fffff)};
	/* twelve samples at a time, a whole number of periods: lane l of vector a holds
	 * sample 4a + l of the twelve */
	__m128 m[3] = {_mm_setzero_ps(), _mm_setzero_ps(), _mm_setzero_ps()};
	for (; i + 12 <= n; i += 12)
		for (int a = 0; a < 3; a++) {
			size_t o = i + 4 * (size_t)a;
			for (int redo = bins4(&q, v + o, out + o, &m[a]); redo; redo &= redo - 1) {
				size_t j = o + (size_t)__builtin_ctz((unsigned)redo);
				out[j] = bin_or_dump(v[j], steps);
				uint32_t *t = top + (j % (size_t)period);
				*t = out[j] > *t ? out[j] : *t;
			}
		}
	float mf[3][4];
	for (int a = 0; a < 3; a++)
		_mm_storeu_ps(mf[a], m[a]);
	for (int a = 0; a < 3; a++)
		for (int l = 0; l < 4; l++) {
			uint32_t b = (uint32_t)mf[a][l], *t = top + (4 * a + l) % period;
			*t = b > *t ? b : *t;
		}
#endif
	for (; i < n; i++) {
		out[i] = bin_or_dump(v[i], steps);
		uint32_t *t = top + (i % (size_t)period);
		*t = out[i] > *t ? out[i] : *t;
	}
}

void kg_sat_hist_add1(kg_sat_hist *h, int c, double v)
{
	if (c < 0 || c >= h->channels || !isfinite(v))
		return;
	h->bins[c][bin_of(v, h->steps)]++;
	h->total[c]++;
}

/* Samples per bins_of call: a small buffer that stays in the first-level cache. */
enum { SAT_CHUNK = 768 };

void kg_sat_hist_add(kg_sat_hist *h, const float *px, size_t n)
{
	int C = h->channels, S = h->steps;
	uint32_t k[SAT_CHUNK];
	size_t per = SAT_CHUNK / (size_t)C; /* whole pixels per chunk */
	for (size_t i = 0; i < n; i += per) {
		size_t m = n - i < per ? n - i : per;
		uint32_t top = 0;
		bins_of(px + i * (size_t)C, m * (size_t)C, S, k, 1, &top);
		for (size_t j = 0; j < m; j++)
			for (int c = 0; c < C; c++)
				h->bins[c][k[j * (size_t)C + (size_t)c]]++;
	}
	/* the samples counted are those not in the extra bin */
	for (int c = 0; c < C; c++) {
		h->total[c] += n - h->bins[c][S + 1];
		h->bins[c][S + 1] = 0;
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
	/* the loop works on local copies, unrolled, which the compiler keeps in registers;
	 * each accumulator sees the same operations in the same order as pixel by pixel */
	double clip[3] = {s->clip[0], s->clip[1], s->clip[2]};
	int found[3] = {s->found[0], s->found[1], s->found[2]};
	double ref[3][3], sum[3][3], sumsq[3][3];
	uint64_t cnt[3][3], piled[3];
	memcpy(ref, f->ref, sizeof(ref));
	memcpy(sum, f->sum, sizeof(sum));
	memcpy(sumsq, f->sumsq, sizeof(sumsq));
	memcpy(cnt, f->n, sizeof(cnt));
	memcpy(piled, f->piled, sizeof(piled));
	for (size_t i = 0; i < n; i++) {
		const float *p = px + 3 * i;
		int hit[3];
#pragma GCC unroll 3
		for (int c = 0; c < 3; c++)
			hit[c] = found[c] && p[c] >= clip[c];
		if (!(hit[0] | hit[1] | hit[2]))
			continue;
#pragma GCC unroll 3
		for (int c = 0; c < 3; c++) {
			if (!hit[c])
				continue;
			piled[c]++;
#pragma GCC unroll 3
			for (int d = 0; d < 3; d++) {
				if (d == c || !(p[d] < clip[d]) || !isfinite(p[d]))
					continue;
				if (!cnt[c][d])
					ref[c][d] = p[d];
				cnt[c][d]++;
				double dv = p[d] - ref[c][d];
				sum[c][d] += dv;
				sumsq[c][d] += dv * dv;
			}
		}
	}
	memcpy(f->ref, ref, sizeof(ref));
	memcpy(f->sum, sum, sizeof(sum));
	memcpy(f->sumsq, sumsq, sizeof(sumsq));
	memcpy(f->n, cnt, sizeof(cnt));
	memcpy(f->piled, piled, sizeof(piled));
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

/* The whole-image scan works on blocks of up to SAT_BLOCK pixels of a row (whole pixels
 * within SAT_CHUNK samples) and keeps each block's highest bin per channel: the passes
 * that concern only samples at or above a clip level then read just the blocks that can
 * hold one. bin_of never decreases as the value grows, so a sample >= clip has a bin >=
 * bin_of(clip): a block whose highest bin in every channel is below that has no such
 * sample (a non-finite sample's bin, steps + 1, sends its block to the exact test). */
enum { SAT_BLOCK = 256 };

typedef struct sat_scan {
	int C, S, mosaic, slots; /* slots: channels kept per block (a mosaic row has 2) */
	size_t W, H, nbx;        /* nbx: blocks per row */
	/* two histograms per channel, alternate pixels in each: consecutive increments of
	 * the same bin (flat areas) do not wait on one another */
	uint32_t *sub[KG_SAT_MAX_CHANNELS][2];
	uint32_t *top;           /* per block and slot, the highest bin */
} sat_scan;

static void scan_free(sat_scan *s)
{
	for (int c = 0; c < KG_SAT_MAX_CHANNELS; c++)
		for (int k = 0; k < 2; k++)
			free(s->sub[c][k]);
	free(s->top);
}

/* The two histograms of each channel into h, emptied. */
static void scan_flush(sat_scan *s, kg_sat_hist *h)
{
	for (int c = 0; c < s->C; c++) {
		uint64_t n = 0;
		uint64_t *bins = h->bins[c];
		uint32_t *a = s->sub[c][0], *b = s->sub[c][1];
		for (int k = 0; k <= s->S; k++) {
			uint64_t v = (uint64_t)a[k] + b[k];
			bins[k] += v;
			n += v;
		}
		h->total[c] += n;
		memset(a, 0, ((size_t)s->S + 2) * sizeof(uint32_t));
		memset(b, 0, ((size_t)s->S + 2) * sizeof(uint32_t));
	}
}

/* The histograms' counts for one block of n interleaved pixels of C channels, their
 * bins in k. */
static void scan_pixels(sat_scan *s, const uint32_t *k, size_t n, int C)
{
	for (size_t i = 0; i < n; i++)
		for (int c = 0; c < C; c++)
			s->sub[c][i & 1][k[i * (size_t)C + (size_t)c]]++;
}

/* The same for 3 channels, two pixels at a time. */
static void scan_rgb(sat_scan *s, const uint32_t *k, size_t n)
{
	uint32_t *r0 = s->sub[0][0], *g0 = s->sub[1][0], *b0 = s->sub[2][0];
	uint32_t *r1 = s->sub[0][1], *g1 = s->sub[1][1], *b1 = s->sub[2][1];
	size_t i = 0;
	for (; i + 2 <= n; i += 2, k += 6) {
		r0[k[0]]++;
		g0[k[1]]++;
		b0[k[2]]++;
		r1[k[3]]++;
		g1[k[4]]++;
		b1[k[5]]++;
	}
	if (i < n) {
		r0[k[0]]++;
		g0[k[1]]++;
		b0[k[2]]++;
	}
}

/* One block of a mosaic row: channels base and base + 1 alternate from x0 (even). */
static void scan_mosaic(sat_scan *s, const uint32_t *k, size_t n, int base)
{
	uint32_t *a0 = s->sub[base][0], *a1 = s->sub[base + 1][0];
	uint32_t *b0 = s->sub[base][1], *b1 = s->sub[base + 1][1];
	size_t i = 0;
	for (; i + 4 <= n; i += 4) {
		a0[k[i]]++;
		a1[k[i + 1]]++;
		b0[k[i + 2]]++;
		b1[k[i + 3]]++;
	}
	for (; i < n; i++)
		(i & 1 ? a1 : a0)[k[i]]++;
}

static int scan_image(const kg_image *img, sat_scan *s, kg_sat_hist *h, kg_err *err)
{
	size_t nblocks = s->nbx * s->H;
	if (!(s->top = malloc((nblocks ? nblocks : 1) * (size_t)s->slots * sizeof(uint32_t))))
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (int c = 0; c < s->C; c++)
		for (int k = 0; k < 2; k++)
			if (!(s->sub[c][k] = calloc((size_t)s->S + 2, sizeof(uint32_t))))
				return kg_fail(err, KG_ENOMEM, "out of memory");
	int ch = img->channels;
	size_t block = (size_t)SAT_CHUNK / (size_t)ch;
	if (block > SAT_BLOCK)
		block = SAT_BLOCK;
	uint32_t k[SAT_CHUNK];
	/* a histogram's count may not wrap: each sees at most half the pixels between two
	 * flushes */
	size_t since = 0, limit = (size_t)1 << 31;
	for (size_t y = 0; y < s->H; y++) {
		for (size_t bx = 0; bx < s->nbx; bx++) {
			size_t x0 = bx * block, n = s->W - x0 < block ? s->W - x0 : block;
			const float *p = img->data + (y * s->W + x0) * (size_t)ch;
			uint32_t *top = s->top + (y * s->nbx + bx) * (size_t)s->slots;
			memset(top, 0, (size_t)s->slots * sizeof(uint32_t));
			bins_of(p, n * (size_t)ch, s->S, k, s->slots, top);
			if (s->mosaic)
				scan_mosaic(s, k, n, (int)(y & 1) * 2);
			else if (ch == 3)
				scan_rgb(s, k, n);
			else
				scan_pixels(s, k, n, ch);
			if ((since += n) >= limit) {
				scan_flush(s, h);
				since = 0;
			}
		}
	}
	scan_flush(s, h);
	return 0;
}

/* 1 when block b of row y may hold a sample >= the clip level of a channel marked in
 * want, thr[c] being that clip level's bin. */
static int block_may_clip(const sat_scan *s, size_t y, size_t b, const uint32_t *thr,
                          const int *want)
{
	const uint32_t *top = s->top + (y * s->nbx + b) * (size_t)s->slots;
	for (int j = 0; j < s->slots; j++) {
		int c = s->mosaic ? (int)(y & 1) * 2 + j : j;
		if (want[c] && top[j] >= thr[c])
			return 1;
	}
	return 0;
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
	sat_scan s = {0};
	s.C = C;
	s.S = h.steps;
	s.mosaic = mosaic;
	s.slots = mosaic ? 2 : C;
	s.W = W;
	s.H = H;
	size_t block = (size_t)SAT_CHUNK / (size_t)img->channels;
	if (block > SAT_BLOCK)
		block = SAT_BLOCK;
	s.nbx = (W + block - 1) / block;
	if ((ret = scan_image(img, &s, &h, err))) {
		scan_free(&s);
		kg_sat_hist_free(&h);
		return ret;
	}
	kg_sat_hist_result(&h, nominal_clip, out);
	kg_sat_hist_free(&h);
	uint32_t thr[KG_SAT_MAX_CHANNELS];
	int want[KG_SAT_MAX_CHANNELS];
	if (!mosaic && C == 3 && kg_saturation_below(out, nominal_clip)) {
		/* only pixels with a found channel at or above its clip level count here, in
		 * the order of the image */
		kg_sat_flat f;
		kg_sat_flat_init(&f, out);
		for (int c = 0; c < C; c++) {
			thr[c] = (uint32_t)bin_of(out->clip[c], s.S);
			want[c] = out->found[c];
		}
		for (size_t y = 0; y < H; y++)
			for (size_t b = 0; b < s.nbx; b++)
				if (block_may_clip(&s, y, b, thr, want)) {
					size_t x0 = b * block, n = W - x0 < block ? W - x0 : block;
					kg_sat_flat_add(&f, img->data + (y * W + x0) * 3, n);
				}
		kg_sat_flat_result(&f, out);
	}
	for (int c = 0; c < C; c++) {
		thr[c] = (uint32_t)bin_of(out->clip[c], s.S);
		want[c] = 1;
	}
	size_t any = 0, n = W * H;
	for (size_t y = 0; y < H; y++)
		for (size_t b = 0; b < s.nbx; b++) {
			if (!block_may_clip(&s, y, b, thr, want))
				continue;
			size_t x1 = (b + 1) * block < W ? (b + 1) * block : W;
			for (size_t x = b * block; x < x1; x++) {
				const float *p = img->data + (y * W + x) * (size_t)img->channels;
				int hit = 0;
				if (mosaic)
					hit = p[0] >= out->clip[(y & 1) * 2 + (x & 1)];
				else
					for (int c = 0; c < C; c++)
						hit |= p[c] >= out->clip[c];
				any += (size_t)hit;
			}
		}
	scan_free(&s);
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
