/* Optimised kernels for x86-64 with AVX2, FMA and F16C, selected at run time.
 *
 * They compute exactly what the reference computes: the same IEEE operations in the
 * same order, each multiply-add of a band's sum one FMA instruction (the reference's
 * fmaf), everything else unfused (the cube root is the reference's est_cbrtf lane by
 * lane, the classifier's distances separate multiplies and adds in double, as the
 * reference's). What changes is the layout of the work:
 *   stage 1   8 pixels at a time: deinterleave RGB, flag, expand the terms (or find
 *             the LUT cell and corner weights) into per-chunk scratch;
 *   BSQ       band by band over the chunk, straight from registers into the planes;
 *   labels    8 pixels per vector, all bands, band-major values in s->vals;
 *   BIP       a permute puts 8 consecutive output values in each vector;
 *   LUT       8 bands per vector, one pixel at a time, then 8x8 transposes;
 *   classify  4 pixels per double vector;
 *   stores    non-temporal for large outputs.
 * The AVX-512 path (avx512.c) reuses stage 1, BIP, labels and LUTs from here. */
#include "est_private.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))

#include <cpuid.h>
#include <immintrin.h>

#define AVX2 __attribute__((target("avx2,fma,f16c,popcnt")))
#define INLINE_AVX2 __attribute__((target("avx2,fma,f16c,popcnt"), always_inline)) static inline

/* F16C through CPUID: not every compiler's __builtin_cpu_supports knows it. AVX2's
 * check covers the OS saving the YMM registers, which F16C needs too. */
int est_have_avx2(void)
{
	unsigned a, b, c, d;
	__builtin_cpu_init();
	return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
	       __builtin_cpu_supports("popcnt") &&
	       __get_cpuid(1, &a, &b, &c, &d) && (c & bit_F16C);
}

/* Lanes l with i + l < m, as a mask. */
INLINE_AVX2 __m256 valid_lanes(size_t i, size_t m)
{
	int left = m - i >= 8 ? 8 : (int)(m - i);
	return _mm256_castsi256_ps(
	    _mm256_cmpgt_epi32(_mm256_set1_epi32(left), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)));
}

INLINE_AVX2 void transpose8(__m256 r[8])
{
	__m256 t[8], u[8];
#pragma GCC unroll 4
	for (int k = 0; k < 4; k++) {
		t[2 * k] = _mm256_unpacklo_ps(r[2 * k], r[2 * k + 1]);
		t[2 * k + 1] = _mm256_unpackhi_ps(r[2 * k], r[2 * k + 1]);
	}
#pragma GCC unroll 2
	for (int k = 0; k < 2; k++) {
		u[4 * k + 0] = _mm256_shuffle_ps(t[4 * k], t[4 * k + 2], 0x44);
		u[4 * k + 1] = _mm256_shuffle_ps(t[4 * k], t[4 * k + 2], 0xee);
		u[4 * k + 2] = _mm256_shuffle_ps(t[4 * k + 1], t[4 * k + 3], 0x44);
		u[4 * k + 3] = _mm256_shuffle_ps(t[4 * k + 1], t[4 * k + 3], 0xee);
	}
#pragma GCC unroll 4
	for (int k = 0; k < 4; k++) {
		r[k] = _mm256_permute2f128_ps(u[k], u[k + 4], 0x20);
		r[k + 4] = _mm256_permute2f128_ps(u[k], u[k + 4], 0x31);
	}
}

/* 8 interleaved RGB pixels (fewer at the end of a chunk: the rest read as 0). */
INLINE_AVX2 void load_rgb8(const float *rgb, size_t left, __m256 *r, __m256 *g, __m256 *b)
{
	__m256 a, bb, c;
	if (left >= 8) {
		a = _mm256_loadu_ps(rgb);
		bb = _mm256_loadu_ps(rgb + 8);
		c = _mm256_loadu_ps(rgb + 16);
	} else {
		float tmp[24] = {0};
		memcpy(tmp, rgb, left * 3 * sizeof(float));
		a = _mm256_loadu_ps(tmp);
		bb = _mm256_loadu_ps(tmp + 8);
		c = _mm256_loadu_ps(tmp + 16);
	}
	*r = _mm256_permutevar8x32_ps(_mm256_blend_ps(_mm256_blend_ps(a, bb, 0x92), c, 0x24),
	                              _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5));
	*g = _mm256_permutevar8x32_ps(_mm256_blend_ps(_mm256_blend_ps(a, bb, 0x24), c, 0x49),
	                              _mm256_setr_epi32(1, 4, 7, 2, 5, 0, 3, 6));
	*b = _mm256_permutevar8x32_ps(_mm256_blend_ps(_mm256_blend_ps(a, bb, 0x49), c, 0x92),
	                              _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7));
}

/* est_pixel_flags on 8 lanes: writes the flag bytes, counts them, and returns the
 * lanes to leave unestimated as a mask. */
INLINE_AVX2 __m256 flags8(__m256 r, __m256 g, __m256 b, float clip, __m256 valid,
                          uint8_t *flags, est_counts *c)
{
	const __m256 absmask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
	const __m256 inf = _mm256_set1_ps(INFINITY), cl = _mm256_set1_ps(clip);
	__m256 fin = _mm256_and_ps(
	    _mm256_and_ps(_mm256_cmp_ps(_mm256_and_ps(r, absmask), inf, _CMP_LT_OQ),
	                  _mm256_cmp_ps(_mm256_and_ps(g, absmask), inf, _CMP_LT_OQ)),
	    _mm256_cmp_ps(_mm256_and_ps(b, absmask), inf, _CMP_LT_OQ));
	__m256 over = _mm256_or_ps(_mm256_or_ps(_mm256_cmp_ps(r, cl, _CMP_GE_OQ),
	                                        _mm256_cmp_ps(g, cl, _CMP_GE_OQ)),
	                           _mm256_cmp_ps(b, cl, _CMP_GE_OQ));
	int nonfinite = _mm256_movemask_ps(_mm256_andnot_ps(fin, valid));
	int clipped = _mm256_movemask_ps(_mm256_and_ps(_mm256_and_ps(fin, over), valid));
	if (!(nonfinite | clipped)) {
		memset(flags, 0, 8);
		return _mm256_setzero_ps();
	}
	c->nonfinite += (uint64_t)__builtin_popcount(nonfinite);
	c->clipped += (uint64_t)__builtin_popcount(clipped);
	for (int l = 0; l < 8; l++)
		flags[l] = (uint8_t)(((nonfinite >> l) & 1) * KG_EST_MASK_NONFINITE |
		                     ((clipped >> l) & 1) * KG_EST_MASK_CLIPPED);
	return _mm256_or_ps(_mm256_xor_ps(fin, _mm256_castsi256_ps(_mm256_set1_epi32(-1))), over);
}

/* est_cbrtf on 8 lanes of x >= 0. */
INLINE_AVX2 __m256d cbrt_newton(__m256d y, __m256d x)
{
	const __m256d three = _mm256_set1_pd(3.0);
	for (int k = 0; k < 3; k++) {
		__m256d y2 = _mm256_mul_pd(y, y);
		__m256d num = _mm256_sub_pd(_mm256_mul_pd(y2, y), x);
		__m256d den = _mm256_mul_pd(three, y2);
		y = _mm256_sub_pd(y, _mm256_div_pd(num, den));
	}
	return y;
}

INLINE_AVX2 __m256 cbrt8(__m256 x)
{
	__m256 third = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_castps_si256(x)),
	                             _mm256_set1_ps(1.0f / 3.0f));
	__m256 guess = _mm256_castsi256_ps(
	    _mm256_add_epi32(_mm256_cvttps_epi32(third), _mm256_set1_epi32(EST_CBRT_MAGIC)));
	__m256d lo = cbrt_newton(_mm256_cvtps_pd(_mm256_castps256_ps128(guess)),
	                         _mm256_cvtps_pd(_mm256_castps256_ps128(x)));
	__m256d hi = cbrt_newton(_mm256_cvtps_pd(_mm256_extractf128_ps(guess, 1)),
	                         _mm256_cvtps_pd(_mm256_extractf128_ps(x, 1)));
	__m256 y = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm256_cvtpd_ps(lo)),
	                                _mm256_cvtpd_ps(hi), 1);
	return _mm256_and_ps(_mm256_cmp_ps(x, _mm256_set1_ps(0x1p-120f), _CMP_GE_OQ), y);
}

/* Stage 1 of matrix kernels: est_pixel_flags and est_pixel_terms for m pixels into
 * s->flags and s->terms (term t of pixel i at t * EST_TSTRIDE + i; lanes up to the
 * next multiple of 8 hold the terms of black pixels). */
AVX2 void est_avx2_stage_terms(const est_plan *p, est_scratch *s, const float *rgb, size_t m,
                             est_counts *c)
{
	est_avx2_stage_terms_part(p, s, rgb, m, 0, m, c);
	memset(s->clampbits, 0, EST_CHUNK / 8);
}

/* Stage 1 for pixels [i0, i1) of a chunk of m (rgb its first pixel; i0 a multiple of
 * 8), clampbits left alone. */
AVX2 void est_avx2_stage_terms_part(const est_plan *p, est_scratch *s, const float *rgb,
                                  size_t m, size_t i0, size_t i1, est_counts *c)
{
	kg_est_method method = p->k->method;
	const __m256 zero = _mm256_setzero_ps(), nan = _mm256_set1_ps(NAN);
	for (size_t i = i0; i < i1; i += 8) {
		__m256 r, g, b, t[KG_EST_MAX_TERMS];
		load_rgb8(rgb + 3 * i, m - i, &r, &g, &b);
		__m256 bad = flags8(r, g, b, p->clip, valid_lanes(i, m), s->flags + i, c);
		int nt = 3;
		t[0] = r;
		t[1] = g;
		t[2] = b;
		if (method != KG_EST_LINEAR) {
			__m256 rp = _mm256_and_ps(_mm256_cmp_ps(r, zero, _CMP_GT_OQ), r);
			__m256 gp = _mm256_and_ps(_mm256_cmp_ps(g, zero, _CMP_GT_OQ), g);
			__m256 bp = _mm256_and_ps(_mm256_cmp_ps(b, zero, _CMP_GT_OQ), b);
			t[3] = _mm256_sqrt_ps(_mm256_mul_ps(rp, gp));
			t[4] = _mm256_sqrt_ps(_mm256_mul_ps(gp, bp));
			t[5] = _mm256_sqrt_ps(_mm256_mul_ps(rp, bp));
			nt = 6;
			if (method == KG_EST_ROOTPOLY3) {
				__m256 cr = cbrt8(rp), cg = cbrt8(gp), cb = cbrt8(bp);
				t[6] = _mm256_mul_ps(cr, _mm256_mul_ps(cg, cg));
				t[7] = _mm256_mul_ps(cg, _mm256_mul_ps(cb, cb));
				t[8] = _mm256_mul_ps(cr, _mm256_mul_ps(cb, cb));
				t[9] = _mm256_mul_ps(cg, _mm256_mul_ps(cr, cr));
				t[10] = _mm256_mul_ps(cb, _mm256_mul_ps(cg, cg));
				t[11] = _mm256_mul_ps(cb, _mm256_mul_ps(cr, cr));
				t[12] = _mm256_mul_ps(cr, _mm256_mul_ps(cg, cb));
				nt = 13;
			}
		}
		for (int k = 0; k < nt; k++)
			_mm256_store_ps(s->terms + k * EST_TSTRIDE + i, _mm256_blendv_ps(t[k], nan, bad));
	}
}

/* Stage 1 of LUT kernels: est_lut_cell for m pixels into s->cell and s->cw. */
AVX2 static void stage_lut(const est_plan *p, est_scratch *s, const float *rgb, size_t m,
                           est_counts *c)
{
	const kg_est_kernel *k = p->k;
	const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
	const __m256 lo = _mm256_set1_ps(k->lut_lo), scale = _mm256_set1_ps(k->lut_scale);
	const __m256 top = _mm256_set1_ps((float)(k->lut_n - 1));
	const __m256i top_cell = _mm256_set1_epi32(k->lut_n - 2), n = _mm256_set1_epi32(k->lut_n);
	for (size_t i = 0; i < m; i += 8) {
		__m256 ch[3];
		load_rgb8(rgb + 3 * i, m - i, &ch[0], &ch[1], &ch[2]);
		__m256 bad = flags8(ch[0], ch[1], ch[2], p->clip, valid_lanes(i, m), s->flags + i, c);
		__m256i idx[3];
		__m256 gw[3][2];
		for (int a = 0; a < 3; a++) {
			__m256 x = _mm256_mul_ps(_mm256_sub_ps(ch[a], lo), scale);
			x = _mm256_and_ps(_mm256_cmp_ps(x, zero, _CMP_GT_OQ), x);
			x = _mm256_blendv_ps(x, top, _mm256_cmp_ps(x, top, _CMP_GT_OQ));
			idx[a] = _mm256_min_epi32(_mm256_cvttps_epi32(x), top_cell);
			__m256 f = _mm256_sub_ps(x, _mm256_cvtepi32_ps(idx[a]));
			gw[a][0] = _mm256_sub_ps(one, f);
			gw[a][1] = f;
		}
		__m256i cell = _mm256_add_epi32(
		    _mm256_mullo_epi32(_mm256_add_epi32(_mm256_mullo_epi32(idx[2], n), idx[1]), n),
		    idx[0]);
		cell = _mm256_andnot_si256(_mm256_castps_si256(bad), cell);
		_mm256_store_si256((__m256i *)(s->cell + i), cell);
		__m256 w[8];
		for (int q = 0; q < 8; q++)
			w[q] = _mm256_blendv_ps(
			    _mm256_mul_ps(_mm256_mul_ps(gw[2][q >> 2], gw[1][(q >> 1) & 1]), gw[0][q & 1]),
			    _mm256_set1_ps(NAN), bad);
		transpose8(w);
		for (int l = 0; l < 8; l++)
			_mm256_store_ps(s->cw + 8 * (i + l), w[l]);
	}
	memset(s->clampbits, 0, EST_CHUNK / 8);
}

/* Mask bytes and the clamped-pixel count of a chunk. */
void est_finish_mask(const est_scratch *s, size_t m, uint8_t *mask, est_counts *c)
{
	for (size_t i = 0; i < m; i += 8)
		c->clamped_pixels += (uint64_t)__builtin_popcount(s->clampbits[i / 8]);
	if (!mask)
		return;
	for (size_t i = 0; i < m; i++)
		mask[i] = (uint8_t)(s->flags[i] |
		                    (((s->clampbits[i / 8] >> (i % 8)) & 1) ? KG_EST_MASK_CLAMPED : 0));
}

/* The reference's `v < 0 ? 0 : v` exactly: maxps returns its second operand when
 * the lanes compare equal (-0.0 stays -0.0) or one is NaN (NaN stays NaN). */
INLINE_AVX2 __m256 clamp_negative(__m256 acc)
{
	return _mm256_max_ps(_mm256_setzero_ps(), acc);
}

INLINE_AVX2 uint64_t sum_lanes(__m256i v)
{
	int lanes[8];
	_mm256_storeu_si256((__m256i *)lanes, v);
	uint64_t sum = 0;
	for (int l = 0; l < 8; l++)
		sum += (uint64_t)lanes[l];
	return sum;
}

/* Matrix kernel into band-major values (s->vals: band o of pixel i at
 * o * EST_CHUNK + i), 8 pixels per vector with their terms held in registers.
 * Inlined once per number of terms so that the term loop unrolls. Clamped values
 * are counted per lane (lanes past m, in the last group, are taken back out). */
INLINE_AVX2 void matrix_soa_nt(const est_map *mp, const int nt, est_scratch *s, size_t m,
                               est_counts *c)
{
	const int nb = mp->nb, clamp = mp->clamp;
	const float *a8 = mp->a8, *off8 = mp->off8, *terms = s->terms;
	float *vals = s->vals;
	uint8_t *clampbits = s->clampbits;
	const __m256 zero = _mm256_setzero_ps();
	__m256i count = _mm256_setzero_si256();
	for (size_t i = 0; i < m; i += 8) {
		__m256 term[KG_EST_MAX_TERMS];
		for (int t = 0; t < nt; t++)
			term[t] = _mm256_load_ps(terms + t * EST_TSTRIDE + i);
		__m256 hit = zero;
		__m256i before = count;
		for (int o = 0; o < nb; o++) {
			const float *a = a8 + (size_t)o * nt * 8;
			__m256 acc = _mm256_load_ps(off8 + 8 * o);
#pragma GCC unroll 16
			for (int t = 0; t < nt; t++)
				acc = _mm256_fmadd_ps(_mm256_load_ps(a + 8 * t), term[t], acc);
			if (clamp) {
				__m256 lt = _mm256_cmp_ps(acc, zero, _CMP_LT_OQ);
				acc = clamp_negative(acc);
				hit = _mm256_or_ps(hit, lt);
				count = _mm256_sub_epi32(count, _mm256_castps_si256(lt));
			}
			_mm256_store_ps(vals + (size_t)o * EST_CHUNK + i, acc);
		}
		__m256 valid = valid_lanes(i, m);
		if (m - i < 8)
			count = _mm256_castps_si256(_mm256_blendv_ps(
			    _mm256_castsi256_ps(before), _mm256_castsi256_ps(count), valid));
		clampbits[i / 8] = (uint8_t)_mm256_movemask_ps(_mm256_and_ps(hit, valid));
	}
	c->clamped_values += sum_lanes(count);
}

AVX2 static void matrix_soa(const est_plan *p, est_scratch *s, size_t m, est_counts *c)
{
	switch (p->k->nterms) {
	case 3:
		matrix_soa_nt(p->map, 3, s, m, c);
		break;
	case 6:
		matrix_soa_nt(p->map, 6, s, m, c);
		break;
	default:
		matrix_soa_nt(p->map, KG_EST_MAX_TERMS, s, m, c);
		break;
	}
}

/* Band-major values (s->vals) into BSQ planes, streaming the aligned middle. */
AVX2 static void store_bsq(const est_plan *p, const est_scratch *s, size_t m,
                           const est_dst *d, size_t at)
{
	int half = p->format == KG_EST_F16_BSQ;
	for (int o = 0; o < p->map->nb; o++) {
		const float *src = s->vals + (size_t)o * EST_CHUNK;
		size_t i = 0;
		if (half) {
			uint16_t *dst = (uint16_t *)d->data + o * d->plane_stride + at;
			if (p->stream) {
				size_t head = ((32 - ((uintptr_t)dst & 31)) & 31) / 2;
				for (; i < head && i < m; i++)
					dst[i] = kg_f16_from_f32(src[i]);
			}
			for (; i + 16 <= m; i += 16) {
				__m128i lo = _mm256_cvtps_ph(_mm256_loadu_ps(src + i), _MM_FROUND_TO_NEAREST_INT);
				__m128i hi =
				    _mm256_cvtps_ph(_mm256_loadu_ps(src + i + 8), _MM_FROUND_TO_NEAREST_INT);
				__m256i v = _mm256_inserti128_si256(_mm256_castsi128_si256(lo), hi, 1);
				if (p->stream)
					_mm256_stream_si256((__m256i *)(dst + i), v);
				else
					_mm256_storeu_si256((__m256i *)(dst + i), v);
			}
			for (; i < m; i++)
				dst[i] = kg_f16_from_f32(src[i]);
		} else {
			float *dst = (float *)d->data + o * d->plane_stride + at;
			if (!p->stream) {
				memcpy(dst, src, m * sizeof(float));
				continue;
			}
			size_t head = ((32 - ((uintptr_t)dst & 31)) & 31) / 4;
			for (; i < head && i < m; i++)
				dst[i] = src[i];
			for (; i + 8 <= m; i += 8)
				_mm256_stream_ps(dst + i, _mm256_loadu_ps(src + i));
			for (; i < m; i++)
				dst[i] = src[i];
		}
	}
}

/* Matrix kernel straight into BSQ planes, band by band, without going through
 * s->vals: each band's values for the whole chunk (up to EST_CHUNK pixels: 1 KiB of
 * f32, 512 bytes of f16) are computed from the chunk's terms (in L1, the band's
 * coefficients in registers) and written to their plane in one sequential run, so
 * that every plane receives long runs of whole lines (streaming stores then fill
 * their write-combining buffers and nothing is read for ownership). Measured on a
 * 2-core Zen 1, this beat both the two-pass form (values to s->vals, then copied out)
 * and groups of 32 pixels with every band written at once (61 planes touched 128
 * bytes at a time). The clamped bands are counted per pixel in s->cell (LUT scratch,
 * unused by matrix kernels), which gives both the mask bit and the clamped values. */
/* One band's value at 8 pixels from i: off + sum of coef[t] terms[t], negatives
 * clamped to 0 and counted per lane in cnt (when clamp). */
INLINE_AVX2 __m256 bsq_vector(const int nt, const __m256 *coef, __m256 off,
                              const float *terms, size_t i, int32_t *cnt, const int clamp)
{
	__m256 acc = off;
#pragma GCC unroll 16
	for (int t = 0; t < nt; t++)
		acc = _mm256_fmadd_ps(coef[t], _mm256_load_ps(terms + t * EST_TSTRIDE + i), acc);
	if (clamp) {
		__m256 lt = _mm256_cmp_ps(acc, _mm256_setzero_ps(), _CMP_LT_OQ);
		acc = clamp_negative(acc);
		__m256i *q = (__m256i *)(cnt + i);
		_mm256_store_si256(q, _mm256_sub_epi32(_mm256_load_si256(q), _mm256_castps_si256(lt)));
	}
	return acc;
}

/* One band's values for pixels [0, mfull) (whole vectors) into its plane; the
 * store kind and the clamp are constants, so that each combination gets its own
 * branch-free loop. */
INLINE_AVX2 void bsq_band(const int nt, const __m256 *coef, __m256 off, const float *terms,
                          size_t mfull, void *dst, int32_t *cnt, const int half,
                          const int stream, const int clamp)
{
	for (size_t i = 0; i < mfull; i += 8) {
		__m256 acc = bsq_vector(nt, coef, off, terms, i, cnt, clamp);
		if (half) {
			__m128i h = _mm256_cvtps_ph(acc, _MM_FROUND_TO_NEAREST_INT);
			if (stream)
				_mm_stream_si128((__m128i *)((uint16_t *)dst + i), h);
			else
				_mm_storeu_si128((__m128i *)((uint16_t *)dst + i), h);
		} else if (stream) {
			_mm256_stream_ps((float *)dst + i, acc);
		} else {
			_mm256_storeu_ps((float *)dst + i, acc);
		}
	}
}

INLINE_AVX2 void matrix_bsq_nt(const est_plan *p, const int nt, est_scratch *s, size_t m,
                               const est_dst *d, size_t at, const int stream, est_counts *c)
{
	const est_map *mp = p->map;
	const int nb = mp->nb, clamp = mp->clamp, half = p->format == KG_EST_F16_BSQ;
	const float *a8 = mp->a8, *off8 = mp->off8, *terms = s->terms;
	int32_t *cnt = s->cell;
	const size_t mv = (m + 7) & ~(size_t)7, mfull = m & ~(size_t)7;
	if (clamp)
		memset(cnt, 0, mv * sizeof(int32_t));
	for (int o = 0; o < nb; o++) {
		const float *a = a8 + (size_t)o * nt * 8;
		__m256 coef[KG_EST_MAX_TERMS];
		for (int t = 0; t < nt; t++)
			coef[t] = _mm256_load_ps(a + 8 * t);
		const __m256 off = _mm256_load_ps(off8 + 8 * o);
		void *dst = (char *)d->data + (o * d->plane_stride + at) * (half ? 2 : 4);
		const int kind = (half ? 4 : 0) | (stream ? 2 : 0) | (clamp ? 1 : 0);
		switch (kind) {
		case 0: bsq_band(nt, coef, off, terms, mfull, dst, cnt, 0, 0, 0); break;
		case 1: bsq_band(nt, coef, off, terms, mfull, dst, cnt, 0, 0, 1); break;
		case 2: bsq_band(nt, coef, off, terms, mfull, dst, cnt, 0, 1, 0); break;
		case 3: bsq_band(nt, coef, off, terms, mfull, dst, cnt, 0, 1, 1); break;
		case 4: bsq_band(nt, coef, off, terms, mfull, dst, cnt, 1, 0, 0); break;
		case 5: bsq_band(nt, coef, off, terms, mfull, dst, cnt, 1, 0, 1); break;
		case 6: bsq_band(nt, coef, off, terms, mfull, dst, cnt, 1, 1, 0); break;
		default: bsq_band(nt, coef, off, terms, mfull, dst, cnt, 1, 1, 1); break;
		}
		if (mfull < m) { /* the last, partial vector through a small buffer */
			size_t i = mfull;
			__m256 acc = bsq_vector(nt, coef, off, terms, i, cnt, clamp);
			if (half) {
				uint16_t tmp[8];
				_mm_storeu_si128((__m128i *)tmp, _mm256_cvtps_ph(acc, _MM_FROUND_TO_NEAREST_INT));
				memcpy((uint16_t *)dst + i, tmp, (m - i) * sizeof(uint16_t));
			} else {
				float tmp[8];
				_mm256_storeu_ps(tmp, acc);
				memcpy((float *)dst + i, tmp, (m - i) * sizeof(float));
			}
		}
	}
	if (!clamp)
		return;
	__m256i total = _mm256_setzero_si256();
	for (size_t i = 0; i < mv; i += 8) {
		__m256i n = _mm256_and_si256(_mm256_load_si256((const __m256i *)(cnt + i)),
		                             _mm256_castps_si256(valid_lanes(i, m)));
		total = _mm256_add_epi32(total, n);
		s->clampbits[i / 8] = (uint8_t)_mm256_movemask_ps(
		    _mm256_castsi256_ps(_mm256_cmpgt_epi32(n, _mm256_setzero_si256())));
	}
	c->clamped_values += sum_lanes(total);
}

/* Whether matrix_bsq can write this chunk: every plane's part of it starts on the
 * same 32-byte alignment as the first (so streaming stores, which need it, apply to
 * all or none). */
static int bsq_direct(const est_plan *p, const est_dst *d, size_t at, int *stream)
{
	size_t es = p->format == KG_EST_F16_BSQ ? 2 : 4;
	int aligned = (((uintptr_t)d->data + at * es) & 31) == 0 && ((d->plane_stride * es) & 31) == 0;
	*stream = p->stream && aligned;
	return !p->stream || aligned;
}

AVX2 static void matrix_bsq(const est_plan *p, est_scratch *s, size_t m, const est_dst *d,
                            size_t at, int stream, est_counts *c)
{
	switch (p->k->nterms) {
	case 3:
		matrix_bsq_nt(p, 3, s, m, d, at, stream, c);
		break;
	case 6:
		matrix_bsq_nt(p, 6, s, m, d, at, stream, c);
		break;
	default:
		matrix_bsq_nt(p, KG_EST_MAX_TERMS, s, m, d, at, stream, c);
		break;
	}
}

/* Matrix kernel straight into BIP (f32, f16 or weights): for 8 pixels the output is
 * 8 * nb consecutive values, i.e. nb vectors; lane l of vector v is band (8v+l) % nb
 * of pixel (8v+l) / nb, whose terms a permute brings into the lane. */
INLINE_AVX2 void matrix_bip_nt(const est_plan *p, const int nt, est_scratch *s, size_t m,
                               const est_dst *d, size_t at, est_counts *c)
{
	const est_map *mp = p->map;
	const int nb = mp->nb, half = p->format == KG_EST_F16_BIP, clamp = mp->clamp;
	const size_t es = half ? 2 : 4;
	const float *bip_off = mp->bip_off, *bip_coef = mp->bip_coef, *terms = s->terms;
	const int32_t *bip_pix = mp->bip_pix;
	char *base = (char *)d->data + at * nb * es;
	const int stream = p->stream && ((uintptr_t)base & (half ? 15 : 31)) == 0;
	const __m256i one = _mm256_set1_epi32(1);
	const __m256 zero = _mm256_setzero_ps();
	__m256i count = _mm256_setzero_si256();
	for (size_t i = 0; i < m; i += 8) {
		const size_t rem = m - i;
		__m256 term[KG_EST_MAX_TERMS];
		for (int t = 0; t < nt; t++)
			term[t] = _mm256_load_ps(terms + t * EST_TSTRIDE + i);
		float tmp[8 * EST_PAD(KG_NBANDS)]; /* a partial group goes through tmp */
		char *out = rem >= 8 ? base + i * nb * es : (char *)tmp;
		const int nt_store = stream && rem >= 8;
		const __m256i remv = _mm256_set1_epi32((int)rem);
		__m256i pixels_hit = _mm256_setzero_si256(); /* lane: bit of its pixel */
		for (int v = 0; v < nb; v++) {
			__m256i pix = _mm256_load_si256((const __m256i *)(bip_pix + 8 * v));
			__m256 acc = _mm256_load_ps(bip_off + 8 * v);
			const float *coef = bip_coef + (size_t)v * nt * 8;
#pragma GCC unroll 16
			for (int t = 0; t < nt; t++)
				acc = _mm256_fmadd_ps(_mm256_load_ps(coef + 8 * t),
				                      _mm256_permutevar8x32_ps(term[t], pix), acc);
			if (clamp) {
				__m256i hit = _mm256_castps_si256(_mm256_cmp_ps(acc, zero, _CMP_LT_OQ));
				acc = clamp_negative(acc);
				if (rem < 8)
					hit = _mm256_and_si256(hit, _mm256_cmpgt_epi32(remv, pix));
				count = _mm256_sub_epi32(count, hit);
				pixels_hit = _mm256_or_si256(pixels_hit,
				                             _mm256_and_si256(hit, _mm256_sllv_epi32(one, pix)));
			}
			if (half) {
				__m128i h = _mm256_cvtps_ph(acc, _MM_FROUND_TO_NEAREST_INT);
				__m128i *q = (__m128i *)(out + (size_t)v * 16);
				if (nt_store)
					_mm_stream_si128(q, h);
				else
					_mm_storeu_si128(q, h);
			} else {
				float *q = (float *)(out + (size_t)v * 32);
				if (nt_store)
					_mm256_stream_ps(q, acc);
				else
					_mm256_storeu_ps(q, acc);
			}
		}
		if (rem < 8)
			memcpy(base + i * nb * es, tmp, rem * nb * es);
		__m128i x = _mm_or_si128(_mm256_castsi256_si128(pixels_hit),
		                         _mm256_extracti128_si256(pixels_hit, 1));
		x = _mm_or_si128(x, _mm_shuffle_epi32(x, _MM_SHUFFLE(1, 0, 3, 2)));
		x = _mm_or_si128(x, _mm_shuffle_epi32(x, _MM_SHUFFLE(2, 3, 0, 1)));
		s->clampbits[i / 8] = (uint8_t)_mm_cvtsi128_si32(x);
	}
	c->clamped_values += sum_lanes(count);
}

AVX2 static void matrix_bip(const est_plan *p, est_scratch *s, size_t m, const est_dst *d,
                            size_t at, est_counts *c)
{
	switch (p->k->nterms) {
	case 3:
		matrix_bip_nt(p, 3, s, m, d, at, c);
		break;
	case 6:
		matrix_bip_nt(p, 6, s, m, d, at, c);
		break;
	default:
		matrix_bip_nt(p, KG_EST_MAX_TERMS, s, m, d, at, c);
		break;
	}
}

/* Classification of 4 pixels per double vector from band-major weights in s->vals,
 * repeating est_material_distance and est_classify_pixel lane by lane. */
AVX2 static void classify(const est_plan *p, const est_scratch *s, size_t m,
                          const est_dst *d, size_t at)
{
	const kg_est_classifier *cl = p->cls;
	const int k = cl->k;
	uint8_t *labels = (uint8_t *)d->data + at;
	float *conf = d->conf ? d->conf + at : NULL;
	const __m256d zero = _mm256_setzero_pd(), two = _mm256_set1_pd(2.0);
	for (size_t i = 0; i < m; i += 4) {
		__m256d v[KG_EST_MAX_K];
		for (int l = 0; l < k; l++)
			v[l] = _mm256_add_pd(_mm256_cvtps_pd(_mm_load_ps(s->vals + (size_t)l * EST_CHUNK + i)),
			                     _mm256_set1_pd(cl->mpar[l]));
		__m256d best = _mm256_set1_pd(INFINITY), second = best, lab = zero;
		for (int j = 0; j < cl->n; j++) {
			const double *cj = cl->c + (size_t)j * k;
			__m256d dist;
			if (cl->distance == KG_EST_DIST_PLAIN) {
				dist = _mm256_set1_pd(cl->e[j]);
				for (int l = 0; l < k; l++) {
					__m256d t = _mm256_sub_pd(_mm256_set1_pd(cj[l]), v[l]);
					dist = _mm256_add_pd(dist, _mm256_mul_pd(t, t));
				}
			} else {
				__m256d g = _mm256_set1_pd(cl->g[j]), pr = g;
				for (int l = 0; l < k; l++)
					pr = _mm256_add_pd(pr, _mm256_mul_pd(_mm256_set1_pd(cj[l]), v[l]));
				__m256d a = _mm256_and_pd(_mm256_cmp_pd(pr, zero, _CMP_GT_OQ),
				                          _mm256_mul_pd(pr, _mm256_set1_pd(cl->inv_norm[j])));
				dist = _mm256_add_pd(
				    _mm256_set1_pd(cl->h),
				    _mm256_mul_pd(a, _mm256_sub_pd(_mm256_mul_pd(a, _mm256_set1_pd(cl->q[j])),
				                                   _mm256_mul_pd(two, g))));
				for (int l = 0; l < k; l++) {
					__m256d t = _mm256_sub_pd(v[l], _mm256_mul_pd(a, _mm256_set1_pd(cj[l])));
					dist = _mm256_add_pd(dist, _mm256_mul_pd(t, t));
				}
			}
			__m256d lt_best = _mm256_cmp_pd(dist, best, _CMP_LT_OQ);
			__m256d lt_second = _mm256_cmp_pd(dist, second, _CMP_LT_OQ);
			second = _mm256_blendv_pd(_mm256_blendv_pd(second, dist, lt_second), best, lt_best);
			best = _mm256_blendv_pd(best, dist, lt_best);
			lab = _mm256_blendv_pd(lab, _mm256_set1_pd((double)j), lt_best);
		}
		float margin[4];
		double labd[4];
		_mm_storeu_ps(margin, _mm256_cvtpd_ps(_mm256_sub_pd(second, best)));
		_mm256_storeu_pd(labd, lab);
		for (size_t l = 0; l < 4 && i + l < m; l++) {
			int flagged = s->flags[i + l] & (KG_EST_MASK_NONFINITE | KG_EST_MASK_CLIPPED);
			labels[i + l] = flagged ? KG_EST_LABEL_NONE : (uint8_t)(labd[l] + 1);
			if (conf)
				conf[i + l] = flagged ? NAN : margin[l];
		}
	}
}

AVX2 void est_avx2_matrix_block(const est_plan *p, est_scratch *s, const float *rgb,
                                   size_t n, const est_dst *d, est_counts *c)
{
	for (size_t at = 0; at < n; at += EST_CHUNK) {
		size_t m = n - at < EST_CHUNK ? n - at : EST_CHUNK;
		est_avx2_stage_terms(p, s, rgb + 3 * at, m, c);
		switch (p->format) {
		case KG_EST_F32_BSQ:
		case KG_EST_F16_BSQ: {
			int stream;
			if (bsq_direct(p, d, at, &stream)) {
				matrix_bsq(p, s, m, d, at, stream, c);
			} else {
				matrix_soa(p, s, m, c);
				store_bsq(p, s, m, d, at);
			}
			break;
		}
		case KG_EST_LABELS:
			matrix_soa(p, s, m, c);
			classify(p, s, m, d, at);
			break;
		default:
			matrix_bip(p, s, m, d, at, c);
			break;
		}
		est_finish_mask(s, m, d->mask ? d->mask + at : NULL, c);
	}
	if (p->stream)
		_mm_sfence();
}

/* LUT: 8 bands per vector, one pixel at a time, into s->rows (pixel-major, STRIDE
 * floats per pixel), corners summed in the reference's order. */
INLINE_AVX2 void lut_rows_stride(const est_plan *p, const int stride, est_scratch *s,
                                 size_t m, est_counts *c)
{
	const est_map *mp = p->map;
	const int n = p->k->lut_n, clamp = mp->clamp;
	int32_t corner[8];
	for (int q = 0; q < 8; q++)
		corner[q] = est_lut_corner(n, q) * stride;
	__m256 band_valid[EST_PAD(KG_NBANDS) / 8];
	for (int g = 0; g < stride; g += 8)
		band_valid[g / 8] = valid_lanes((size_t)g, (size_t)mp->nb);
	__m256i count = _mm256_setzero_si256();
	for (size_t i = 0; i < m; i++) {
		const float *node = mp->lut + (size_t)s->cell[i] * stride;
		__m256 w[8];
		for (int q = 0; q < 8; q++)
			w[q] = _mm256_broadcast_ss(s->cw + 8 * i + q);
		float *row = s->rows + i * stride;
		__m256 hit = _mm256_setzero_ps();
		for (int g = 0; g < stride; g += 8) {
			__m256 acc = _mm256_mul_ps(w[0], _mm256_load_ps(node + corner[0] + g));
#pragma GCC unroll 8
			for (int q = 1; q < 8; q++)
				acc = _mm256_fmadd_ps(w[q], _mm256_load_ps(node + corner[q] + g), acc);
			if (clamp) {
				__m256 lt = _mm256_and_ps(_mm256_cmp_ps(acc, _mm256_setzero_ps(), _CMP_LT_OQ),
				                          band_valid[g / 8]);
				acc = clamp_negative(acc);
				hit = _mm256_or_ps(hit, lt);
				count = _mm256_sub_epi32(count, _mm256_castps_si256(lt));
			}
			_mm256_store_ps(row + g, acc);
		}
		if (_mm256_movemask_ps(hit))
			s->clampbits[i / 8] |= (uint8_t)(1u << (i % 8));
	}
	c->clamped_values += sum_lanes(count);
}

AVX2 static void lut_rows(const est_plan *p, est_scratch *s, size_t m, est_counts *c)
{
	switch (p->map->stride) {
	case 8:
		lut_rows_stride(p, 8, s, m, c);
		break;
	case 16:
		lut_rows_stride(p, 16, s, m, c);
		break;
	default:
		lut_rows_stride(p, EST_PAD(KG_NBANDS), s, m, c);
		break;
	}
}

/* Pixel-major rows into band-major values by 8x8 transposes. */
AVX2 static void rows_to_vals(const est_map *mp, est_scratch *s, size_t m)
{
	const int stride = mp->stride;
	for (size_t i = 0; i < m; i += 8)
		for (int g = 0; g < mp->nb; g += 8) {
			__m256 r[8];
#pragma GCC unroll 8
			for (int l = 0; l < 8; l++)
				r[l] = _mm256_load_ps(s->rows + (i + l) * stride + g);
			transpose8(r);
			for (int l = 0; l < 8 && g + l < mp->nb; l++)
				_mm256_store_ps(s->vals + (size_t)(g + l) * EST_CHUNK + i, r[l]);
		}
}

AVX2 static void lut_store_bip(const est_plan *p, const est_scratch *s, size_t m,
                               const est_dst *d, size_t at)
{
	const est_map *mp = p->map;
	size_t nb = (size_t)mp->nb;
	for (size_t i = 0; i < m; i++) {
		const float *row = s->rows + i * mp->stride;
		if (p->format == KG_EST_F16_BIP) {
			uint16_t h[EST_PAD(KG_NBANDS)];
			for (int g = 0; g < mp->stride; g += 8)
				_mm_storeu_si128((__m128i *)(h + g),
				                 _mm256_cvtps_ph(_mm256_load_ps(row + g), _MM_FROUND_TO_NEAREST_INT));
			memcpy((uint16_t *)d->data + (at + i) * nb, h, nb * 2);
		} else {
			memcpy((float *)d->data + (at + i) * nb, row, nb * 4);
		}
	}
}

AVX2 static void avx2_lut_block(const est_plan *p, est_scratch *s, const float *rgb, size_t n,
                                const est_dst *d, est_counts *c)
{
	for (size_t at = 0; at < n; at += EST_CHUNK) {
		size_t m = n - at < EST_CHUNK ? n - at : EST_CHUNK;
		stage_lut(p, s, rgb + 3 * at, m, c);
		lut_rows(p, s, m, c);
		switch (p->format) {
		case KG_EST_F32_BSQ:
		case KG_EST_F16_BSQ:
			rows_to_vals(p->map, s, m);
			store_bsq(p, s, m, d, at);
			break;
		case KG_EST_LABELS:
			rows_to_vals(p->map, s, m);
			classify(p, s, m, d, at);
			break;
		default:
			lut_store_bip(p, s, m, d, at);
			break;
		}
		est_finish_mask(s, m, d->mask ? d->mask + at : NULL, c);
	}
	if (p->stream)
		_mm_sfence();
}

void est_dsp_init_avx2(est_dsp *dsp)
{
	for (int f = 0; f < KG_EST_NFORMATS; f++) {
		dsp->block[EST_KIND_MATRIX][f] = est_avx2_matrix_block;
		dsp->block[EST_KIND_LUT][f] = avx2_lut_block;
	}
}

#else

int est_have_avx2(void) { return 0; }

void est_dsp_init_avx2(est_dsp *dsp) { (void)dsp; }

void est_avx2_stage_terms(const est_plan *p, est_scratch *s, const float *rgb, size_t m,
                          est_counts *c)
{
	(void)p, (void)s, (void)rgb, (void)m, (void)c;
}

void est_avx2_stage_terms_part(const est_plan *p, est_scratch *s, const float *rgb, size_t m,
                               size_t i0, size_t i1, est_counts *c)
{
	(void)p, (void)s, (void)rgb, (void)m, (void)i0, (void)i1, (void)c;
}

void est_finish_mask(const est_scratch *s, size_t m, uint8_t *mask, est_counts *c)
{
	(void)s, (void)m, (void)mask, (void)c;
}

void est_avx2_matrix_block(const est_plan *p, est_scratch *s, const float *rgb, size_t n,
                           const est_dst *d, est_counts *c)
{
	(void)p, (void)s, (void)rgb, (void)n, (void)d, (void)c;
}

#endif
