/* Robust statistics of a patch's values by counting, for values that lie near
 * integers once scaled (integer codes and what demosaicing averages of them): the
 * same order statistics as selection, in one pass; and the sampler's buffers. */
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"

int chart_buffers_reserve(sample_buffers *b, long n, long row)
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

void chart_buffers_free(sample_buffers *b)
{
	for (int k = 0; k < 3; k++)
		free(b->ch[k]);
	free(b->sum);
	free(b->work);
	free(b->keys);
	free(b->row);
	free(b->cnt);
	free(b->seen);
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
 * than the values are many, or no memory. The walks skip empty bins 64 at a time (the
 * seen bits), so a range of up to 64 keys a value costs about what the values do:
 * a region across two patches of different colours still counts. */
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

/* The counts of the last values counted back to zero: only the bins seen. */
static void clear_counts(sample_buffers *b)
{
	for (long w = 0; w < (b->nb + 63) / 64; w++) {
		for (uint64_t m = b->seen[w]; m; m &= m - 1)
			b->cnt[w * 64 + __builtin_ctzll(m)] = 0;
		b->seen[w] = 0;
	}
	b->nb = 0;
}

int chart_count_values(const float *v, long n, float scale, sample_buffers *b)
{
	clear_counts(b);
	uint32_t lo = UINT32_MAX, hi = 0;
	if (count_keys(v, n, scale, b->keys, &lo, &hi))
		return -1;
	long nb = n ? (long)(hi - lo) + 1 : 0;
	if (nb > COUNT_MAX_BINS || nb > 64 * n + 65536)
		return -1;
	if (nb > b->bins_cap) {
		/* grown, the new bins zeroed like the rest */
		long ow = (b->bins_cap + 63) / 64, nw = (nb + 63) / 64;
		int32_t *c = realloc(b->cnt, (size_t)nb * sizeof(*c));
		if (!c)
			return -1;
		b->cnt = c;
		memset(c + b->bins_cap, 0, (size_t)(nb - b->bins_cap) * sizeof(*c));
		uint64_t *w = realloc(b->seen, (size_t)nw * sizeof(*w));
		if (!w)
			return -1;
		b->seen = w;
		memset(w + ow, 0, (size_t)(nw - ow) * sizeof(*w));
		b->bins_cap = nb;
	}
	int32_t *cnt = b->cnt;
	uint64_t *seen = b->seen;
	const uint32_t *keys = b->keys;
	for (long i = 0; i < n; i++) {
		uint32_t k = keys[i] - lo;
		cnt[k]++;
		seen[k / 64] |= (uint64_t)1 << (k % 64);
	}
	b->lo = lo;
	b->nb = nb;
	b->inv = 1.0f / scale;
	return 0;
}

/* The first bin at or after k with a count (nb when none). */
static long next_bin(const sample_buffers *b, long k)
{
	if (k >= b->nb)
		return b->nb;
	long w = k / 64, nw = (b->nb + 63) / 64;
	uint64_t m = b->seen[w] & (~(uint64_t)0 << (k % 64));
	while (!m) {
		if (++w >= nw)
			return b->nb;
		m = b->seen[w];
	}
	return w * 64 + __builtin_ctzll(m);
}

/* The last bin at or before k with a count (-1 when none). */
static long prev_bin(const sample_buffers *b, long k)
{
	if (k < 0)
		return -1;
	long w = k / 64;
	uint64_t m = b->seen[w] & (~(uint64_t)0 >> (63 - k % 64));
	while (!m) {
		if (--w < 0)
			return -1;
		m = b->seen[w];
	}
	return w * 64 + 63 - __builtin_clzll(m);
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

/* chart_robust_stats from the counts of chart_count_values: the same numbers. The median's
 * absolute deviations come from walking outward from the median in both directions
 * at once, each side's deviations growing as it goes. Every walk visits only the bins
 * with a count, in order. */
void chart_counted_stats(const sample_buffers *b, long n, const kg_chart_detect_options *opt,
                          double quantum, double *loc, double *sigma)
{
	const int32_t *cnt = b->cnt;
	long nb = b->nb;
	rank_pick m = {{n / 2 - 1, n / 2}, 0, {0, 0}};
	long up = next_bin(b, 0);
	while (!pick(&m, bin_value(b, up), cnt[up]))
		up = next_bin(b, up + 1);
	double med = pick_median(&m, n);
	float fm = (float)med;
	/* the deviations fabsf(v - fm), as the selection computes them */
	for (up = next_bin(b, 0); up < nb && !(bin_value(b, up) >= fm); up = next_bin(b, up + 1))
		;
	long down = prev_bin(b, up - 1);
	rank_pick d = {{n / 2 - 1, n / 2}, 0, {0, 0}};
	for (;;) {
		float du = up < nb ? fabsf(bin_value(b, up) - fm) : INFINITY;
		float dd = down >= 0 ? fabsf(bin_value(b, down) - fm) : INFINITY;
		int done;
		if (du <= dd) {
			done = pick(&d, du, cnt[up]);
			up = next_bin(b, up + 1);
		} else {
			done = pick(&d, dd, cnt[down]);
			down = prev_bin(b, down - 1);
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
		for (long k = next_bin(b, 0); k < nb && at < n - cut; k = next_bin(b, k + 1)) {
			for (long i = 0; i < cnt[k] && at < n - cut; i++, at++)
				if (at >= cut)
					s += bin_value(b, k);
		}
		*loc = s / (double)(n - 2 * cut);
	} else if (quantum > 0) {
		long below = 0, at = 0;
		for (long k = next_bin(b, 0); k < nb; k = next_bin(b, k + 1)) {
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
long chart_counted_above(const sample_buffers *b, double t)
{
	long c = 0;
	for (long k = prev_bin(b, b->nb - 1); k >= 0 && bin_value(b, k) > t; k = prev_bin(b, k - 1))
		c += b->cnt[k];
	return c;
}
