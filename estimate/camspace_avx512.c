/* Camera-space block matching for x86-64 with AVX-512F, selected at run time: the
 * kernels of camspace_simd.h on 16 pixels per vector, two vectors (32 pixels) sharing
 * each broadcast (32 registers hold both); a last vector of 16 alone. */
#include "est_private.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))

#include <immintrin.h>

#define TARGET __attribute__((target("avx512f,avx2,fma,f16c,popcnt")))
#define INLINE                                                                               \
	__attribute__((target("avx512f,avx2,fma,f16c,popcnt"), always_inline)) static inline

#define V __m512
#define VI __m512i
#define M __mmask16
#define VN 16
#define IDX3 _mm512_setr_epi32(0, 3, 6, 9, 12, 15, 18, 21, 24, 27, 30, 33, 36, 39, 42, 45)
#define IDX6 _mm512_setr_epi32(0, 6, 12, 18, 24, 30, 36, 42, 48, 54, 60, 66, 72, 78, 84, 90)
#define SET1(f) _mm512_set1_ps(f)
#define SET1I(i) _mm512_set1_epi32(i)
#define ADD(a, b) _mm512_add_ps(a, b)
#define SUB(a, b) _mm512_sub_ps(a, b)
#define MUL(a, b) _mm512_mul_ps(a, b)
#define DIV(a, b) _mm512_div_ps(a, b)
#define SQRT(a) _mm512_sqrt_ps(a)
#define FMA(a, b, c) _mm512_fmadd_ps(a, b, c)
#define FMS(a, b, c) _mm512_fmsub_ps(a, b, c)
#define NEG(a)                                                                               \
	_mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(a), _mm512_set1_epi32(INT32_MIN)))
#define MIN(a, b) _mm512_min_ps(a, b)
#define MAX(a, b) _mm512_max_ps(a, b)
#define LT(a, b) _mm512_cmp_ps_mask(a, b, _CMP_LT_OQ)
#define GT(a, b) _mm512_cmp_ps_mask(a, b, _CMP_GT_OQ)
#define ABSLT(a, b) _mm512_cmp_ps_mask(_mm512_abs_ps(a), b, _CMP_LT_OQ)
#define MAND(a, b) ((__mmask16)((a) & (b)))
#define MBITS(m) ((int)(m))
#define SEL(m, f, t) _mm512_mask_blend_ps(m, f, t)
#define SELI(m, f, t) _mm512_mask_blend_epi32(m, f, t)
#define ADDI(a, b) _mm512_add_epi32(a, b)
#define BCAST(p) _mm512_set1_ps(*(p))
#define GATHER(p, vi) _mm512_i32gather_ps(vi, p, 4)
#define PERMUTE(p, vi) _mm512_permutexvar_ps(vi, _mm512_loadu_ps(p))
#define STOREU(p, v) _mm512_storeu_ps(p, v)
#define STORE_BYTES(p, vi) _mm_storeu_si128((__m128i *)(p), _mm512_cvtepi32_epi8(vi))

#include "camspace_simd.h"

TARGET static void exact32(const kg_cs_model *m, const float *x, const float *cov, size_t i,
                           const kg_cs_block *out)
{
	exact_vectors(m, x, cov, i, out, 2);
}

TARGET static void exact16(const kg_cs_model *m, const float *x, const float *cov, size_t i,
                           const kg_cs_block *out)
{
	exact_vectors(m, x, cov, i, out, 1);
}

TARGET static void quad32(const kg_cs_model *m, const float *tab, const float *x,
                          const float *cov, size_t i, const kg_cs_block *out)
{
	quad_vectors(m, tab, x, cov, i, out, 2);
}

TARGET static void quad16(const kg_cs_model *m, const float *tab, const float *x,
                          const float *cov, size_t i, const kg_cs_block *out)
{
	quad_vectors(m, tab, x, cov, i, out, 1);
}

size_t est_cs_match_avx512(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                           const kg_cs_block *out)
{
	size_t i = 0;
	for (; i + 32 <= n; i += 32)
		exact32(m, x, cov, i, out);
	for (; i + 16 <= n; i += 16)
		exact16(m, x, cov, i, out);
	return i;
}

size_t est_cs_quad_avx512(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                          const kg_cs_block *out)
{
	float *tab = n >= 16 ? quad_table(m) : NULL;
	size_t i = 0;
	for (; i + 32 <= n; i += 32)
		quad32(m, tab, x, cov, i, out);
	for (; i + 16 <= n; i += 16)
		quad16(m, tab, x, cov, i, out);
	free(tab);
	return i;
}

#else

size_t est_cs_match_avx512(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                           const kg_cs_block *out)
{
	(void)m, (void)x, (void)cov, (void)n, (void)out;
	return 0;
}

size_t est_cs_quad_avx512(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                          const kg_cs_block *out)
{
	(void)m, (void)x, (void)cov, (void)n, (void)out;
	return 0;
}

#endif
