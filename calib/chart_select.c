/* Robust statistics of a patch's values by selection (radix selection on the fast
 * path): the median or trimmed mean and 1.4826 MAD. */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"

static int cmp_float(const void *a, const void *b)
{
	float x = *(const float *)a, y = *(const float *)b;
	return (x > y) - (x < y);
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
 * and v is left as it is. The values are those kg_select_kth returns. scratch: n keys. */
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

/* Median of v[0..n): by kg_select_kth (reorders v) or, fast, by radix_pair; the same
 * value either way. */
static double median_of(float *v, long n, int fast, uint32_t *scratch)
{
	if (fast) {
		float pair[2];
		radix_pair(v, n, n / 2, scratch, pair);
		return n % 2 ? pair[1] : 0.5 * ((double)pair[1] + pair[0]);
	}
	if (n % 2)
		return kg_select_kth(v, (size_t)n, (size_t)(n / 2));
	double a = kg_select_kth(v, (size_t)n, (size_t)(n / 2));
	double b = kg_select_kth(v, (size_t)(n / 2), (size_t)(n / 2 - 1));
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
void chart_robust_stats(float *v, float *work, uint32_t *scratch, long n,
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
