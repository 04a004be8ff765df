/* Camera-space block matching for x86-64 with AVX2, selected at run time.
 *
 * match_one (camspace.c) on 8 pixels per vector: the same IEEE operations in the same
 * order, lane by lane, so the two are bit-identical. The pieces that make that hold:
 *   - multiplies and adds are never fused (no FMA here, and estimate/ is built with
 *     -ffp-contract=off); sqrt and division are the correctly rounded vsqrtps and
 *     vdivps, as sqrtf and / in the reference;
 *   - maxps(a, lo) is by definition `a > lo ? a : lo` (the second operand when either is
 *     NaN, or for zeros of either sign) and minps(a, hi) is `a < hi ? a : hi`: the
 *     reference's clamps, NaN included; likewise minps(d, dj) is `d < dj ? d : dj`, the
 *     running minimum that keeps the first of equal distances and never takes a NaN;
 *   - lanes the reference refuses (covariance not positive definite, x not finite) are
 *     computed with whatever their values give and overwritten at the end with the
 *     reference's KG_CS_NO_MATCH and NaNs.
 * The model's predicted readings are broadcast one candidate (material, angle) at a
 * time, so every lane walks the candidates in the reference's order. Two vectors (16
 * pixels) share each broadcast: their independent chains keep the three vector ports
 * busy (about 10 % faster than one vector alone); a last lone vector goes alone.
 * The work is about 40 vector operations per candidate and vector, issued at about
 * three per cycle: bound by arithmetic, with no memory traffic to speak of (a pixel
 * reads 36 bytes, the model stays in L1). */
#include "est_private.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))

#include <immintrin.h>

#define AVX2 __attribute__((target("avx2")))
#define INLINE_AVX2 __attribute__((target("avx2"), always_inline)) static inline

/* Lanes of one vector of 8 pixels: the pixel's Cholesky factor and reciprocals, its
 * whitened reading, and the running results. */
typedef struct lanes {
	__m256 ok, l3, l6, l7, i0, i4, i8, y0, y1, y2;
	__m256 best, second, best_a, best_t;
	__m256i bj;
} lanes;

INLINE_AVX2 void lanes_init(lanes *p, const float *x, const float *cov)
{
	const __m256i idx3 = _mm256_setr_epi32(0, 3, 6, 9, 12, 15, 18, 21);
	const __m256i idx6 = _mm256_setr_epi32(0, 6, 12, 18, 24, 30, 36, 42);
	__m256 c0 = _mm256_i32gather_ps(cov, idx6, 4);
	__m256 c1 = _mm256_i32gather_ps(cov + 1, idx6, 4);
	__m256 c2 = _mm256_i32gather_ps(cov + 2, idx6, 4);
	__m256 c3 = _mm256_i32gather_ps(cov + 3, idx6, 4);
	__m256 c4 = _mm256_i32gather_ps(cov + 4, idx6, 4);
	__m256 c5 = _mm256_i32gather_ps(cov + 5, idx6, 4);
	__m256 x0 = _mm256_i32gather_ps(x, idx3, 4);
	__m256 x1 = _mm256_i32gather_ps(x + 1, idx3, 4);
	__m256 x2 = _mm256_i32gather_ps(x + 2, idx3, 4);
	const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
	const __m256 inf = _mm256_set1_ps(INFINITY), nan = _mm256_set1_ps(NAN);
	const __m256 absmask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
	__m256 l0 = _mm256_sqrt_ps(c0);
	p->l3 = _mm256_div_ps(c1, l0);
	p->l6 = _mm256_div_ps(c2, l0);
	__m256 l4 = _mm256_sqrt_ps(_mm256_sub_ps(c3, _mm256_mul_ps(p->l3, p->l3)));
	p->l7 = _mm256_div_ps(_mm256_sub_ps(c4, _mm256_mul_ps(p->l6, p->l3)), l4);
	__m256 l8 = _mm256_sqrt_ps(_mm256_sub_ps(_mm256_sub_ps(c5, _mm256_mul_ps(p->l6, p->l6)),
	                                         _mm256_mul_ps(p->l7, p->l7)));
	__m256 sum = _mm256_add_ps(_mm256_add_ps(x0, x1), x2);
	p->ok = _mm256_and_ps(
	    _mm256_and_ps(_mm256_cmp_ps(l0, zero, _CMP_GT_OQ), _mm256_cmp_ps(l4, zero, _CMP_GT_OQ)),
	    _mm256_and_ps(_mm256_cmp_ps(l8, zero, _CMP_GT_OQ),
	                  _mm256_cmp_ps(_mm256_and_ps(sum, absmask), inf, _CMP_LT_OQ)));
	p->i0 = _mm256_div_ps(one, l0);
	p->i4 = _mm256_div_ps(one, l4);
	p->i8 = _mm256_div_ps(one, l8);
	p->y0 = _mm256_mul_ps(x0, p->i0);
	p->y1 = _mm256_mul_ps(_mm256_sub_ps(x1, _mm256_mul_ps(p->l3, p->y0)), p->i4);
	p->y2 = _mm256_mul_ps(_mm256_sub_ps(_mm256_sub_ps(x2, _mm256_mul_ps(p->l6, p->y0)),
	                                    _mm256_mul_ps(p->l7, p->y1)),
	                      p->i8);
	p->best = p->second = inf;
	p->best_a = p->best_t = nan;
	p->bj = _mm256_setzero_si256();
}

/* One candidate for the lanes: its squared distance d and intensity a. */
INLINE_AVX2 void candidate(const lanes *p, __m256 m0, __m256 m1, __m256 m2, __m256 lo,
                           __m256 hi, __m256 *d, __m256 *a)
{
	__m256 v0 = _mm256_mul_ps(m0, p->i0);
	__m256 v1 = _mm256_mul_ps(_mm256_sub_ps(m1, _mm256_mul_ps(p->l3, v0)), p->i4);
	__m256 v2 = _mm256_mul_ps(
	    _mm256_sub_ps(_mm256_sub_ps(m2, _mm256_mul_ps(p->l6, v0)), _mm256_mul_ps(p->l7, v1)),
	    p->i8);
	__m256 vv = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(v0, v0), _mm256_mul_ps(v1, v1)),
	                          _mm256_mul_ps(v2, v2));
	__m256 vy = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(v0, p->y0), _mm256_mul_ps(v1, p->y1)),
	                          _mm256_mul_ps(v2, p->y2));
	*a = _mm256_min_ps(_mm256_max_ps(_mm256_div_ps(vy, vv), lo), hi);
	__m256 e0 = _mm256_sub_ps(p->y0, _mm256_mul_ps(*a, v0));
	__m256 e1 = _mm256_sub_ps(p->y1, _mm256_mul_ps(*a, v1));
	__m256 e2 = _mm256_sub_ps(p->y2, _mm256_mul_ps(*a, v2));
	*d = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(e0, e0), _mm256_mul_ps(e1, e1)),
	                   _mm256_mul_ps(e2, e2));
}

INLINE_AVX2 void lanes_store(const lanes *p, const kg_cs_block *out, size_t i)
{
	const __m256 nan = _mm256_set1_ps(NAN);
	__m256i bj = _mm256_castps_si256(
	    _mm256_blendv_ps(_mm256_castsi256_ps(_mm256_set1_epi32(KG_CS_NO_MATCH)),
	                     _mm256_castsi256_ps(p->bj), p->ok));
	__m128i b16 = _mm_packus_epi32(_mm256_castsi256_si128(bj), _mm256_extracti128_si256(bj, 1));
	_mm_storel_epi64((__m128i *)(out->best + i), _mm_packus_epi16(b16, b16));
	if (out->d2best)
		_mm256_storeu_ps(out->d2best + i, _mm256_blendv_ps(nan, p->best, p->ok));
	if (out->d2second)
		_mm256_storeu_ps(out->d2second + i, _mm256_blendv_ps(nan, p->second, p->ok));
	if (out->angle_deg)
		_mm256_storeu_ps(out->angle_deg + i, _mm256_blendv_ps(nan, p->best_t, p->ok));
	if (out->scale)
		_mm256_storeu_ps(out->scale + i, _mm256_blendv_ps(nan, p->best_a, p->ok));
}

/* Pixels i .. i + 8 NV - 1, NV vectors sharing each candidate's broadcast. */
INLINE_AVX2 void match_vectors(const kg_cs_model *m, const float *x, const float *cov, size_t i,
                               const kg_cs_block *out, const int NV)
{
	const __m256 inf = _mm256_set1_ps(INFINITY), nan = _mm256_set1_ps(NAN);
	lanes p[2];
	int okbits = 0;
#pragma GCC unroll 2
	for (int q = 0; q < NV; q++) {
		lanes_init(&p[q], x + 3 * (i + 8 * (size_t)q), cov + 6 * (i + 8 * (size_t)q));
		okbits |= _mm256_movemask_ps(p[q].ok);
	}
	const __m256 lo = _mm256_set1_ps((float)m->lo), hi = _mm256_set1_ps((float)m->hi);
	const float *mu = m->muf;
	for (int j = 0; j < m->n && okbits; j++) {
		__m256 dj[2], aj[2], tj[2];
#pragma GCC unroll 2
		for (int q = 0; q < NV; q++) {
			dj[q] = inf;
			aj[q] = tj[q] = nan;
		}
		for (int k = 0; k < m->nangles; k++, mu += 3) {
			__m256 m0 = _mm256_broadcast_ss(mu), m1 = _mm256_broadcast_ss(mu + 1);
			__m256 m2 = _mm256_broadcast_ss(mu + 2), t = _mm256_broadcast_ss(m->anglef + k);
#pragma GCC unroll 2
			for (int q = 0; q < NV; q++) {
				__m256 d, a;
				candidate(&p[q], m0, m1, m2, lo, hi, &d, &a);
				__m256 lt = _mm256_cmp_ps(d, dj[q], _CMP_LT_OQ);
				dj[q] = _mm256_min_ps(d, dj[q]); /* d < dj ? d : dj */
				aj[q] = _mm256_blendv_ps(aj[q], a, lt);
				tj[q] = _mm256_blendv_ps(tj[q], t, lt);
			}
		}
#pragma GCC unroll 2
		for (int q = 0; q < NV; q++) {
			lanes *l = &p[q];
			if (out->d2) {
				float v[8];
				_mm256_storeu_ps(v, _mm256_blendv_ps(nan, dj[q], l->ok));
				for (int z = 0; z < 8; z++)
					out->d2[(i + 8 * (size_t)q + (size_t)z) * (size_t)m->n + (size_t)j] = v[z];
			}
			__m256 lt = _mm256_cmp_ps(dj[q], l->best, _CMP_LT_OQ);
			/* dj < best: second = best, best = dj; else dj < second: second = dj */
			l->second = _mm256_blendv_ps(_mm256_min_ps(dj[q], l->second), l->best, lt);
			l->best = _mm256_min_ps(dj[q], l->best);
			l->bj = _mm256_castps_si256(_mm256_blendv_ps(
			    _mm256_castsi256_ps(l->bj), _mm256_castsi256_ps(_mm256_set1_epi32(j)), lt));
			l->best_a = _mm256_blendv_ps(l->best_a, aj[q], lt);
			l->best_t = _mm256_blendv_ps(l->best_t, tj[q], lt);
		}
	}
#pragma GCC unroll 2
	for (int q = 0; q < NV; q++) {
		if (!okbits && out->d2)
			for (int z = 0; z < 8; z++)
				for (int j = 0; j < m->n; j++)
					out->d2[(i + 8 * (size_t)q + (size_t)z) * (size_t)m->n + (size_t)j] = NAN;
		lanes_store(&p[q], out, i + 8 * (size_t)q);
	}
}

AVX2 static void match16(const kg_cs_model *m, const float *x, const float *cov, size_t i,
                         const kg_cs_block *out)
{
	match_vectors(m, x, cov, i, out, 2);
}

AVX2 static void match8(const kg_cs_model *m, const float *x, const float *cov, size_t i,
                        const kg_cs_block *out)
{
	match_vectors(m, x, cov, i, out, 1);
}

size_t est_cs_match_avx2(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                         const kg_cs_block *out)
{
	size_t i = 0;
	for (; i + 16 <= n; i += 16)
		match16(m, x, cov, i, out);
	for (; i + 8 <= n; i += 8)
		match8(m, x, cov, i, out);
	return i;
}

#else

size_t est_cs_match_avx2(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                         const kg_cs_block *out)
{
	(void)m, (void)x, (void)cov, (void)n, (void)out;
	return 0;
}

#endif
