/* Camera-space block matching for x86-64 with AVX2 and FMA, selected at run time: the
 * kernels of camspace_simd.h on 8 pixels per vector. Two vectors (16 pixels) share each
 * broadcast in KG_CS_EXACT (about 10 % faster than one vector alone); KG_CS_QUADRATIC
 * keeps one, its per-pixel terms already filling the 16 registers. */
#include "est_private.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))

#include <immintrin.h>

#define TARGET __attribute__((target("avx2,fma")))
#define INLINE __attribute__((target("avx2,fma"), always_inline)) static inline

#define V __m256
#define VI __m256i
#define M __m256
#define VN 8
#define IDX3 _mm256_setr_epi32(0, 3, 6, 9, 12, 15, 18, 21)
#define IDX6 _mm256_setr_epi32(0, 6, 12, 18, 24, 30, 36, 42)
#define SET1(f) _mm256_set1_ps(f)
#define SET1I(i) _mm256_set1_epi32(i)
#define ADD(a, b) _mm256_add_ps(a, b)
#define SUB(a, b) _mm256_sub_ps(a, b)
#define MUL(a, b) _mm256_mul_ps(a, b)
#define DIV(a, b) _mm256_div_ps(a, b)
#define SQRT(a) _mm256_sqrt_ps(a)
#define FMA(a, b, c) _mm256_fmadd_ps(a, b, c)
#define FMS(a, b, c) _mm256_fmsub_ps(a, b, c)
#define NEG(a) _mm256_xor_ps(a, _mm256_set1_ps(-0.0f))
#define MIN(a, b) _mm256_min_ps(a, b)
#define MAX(a, b) _mm256_max_ps(a, b)
#define LT(a, b) _mm256_cmp_ps(a, b, _CMP_LT_OQ)
#define GT(a, b) _mm256_cmp_ps(a, b, _CMP_GT_OQ)
#define ABSLT(a, b)                                                                          \
	_mm256_cmp_ps(_mm256_and_ps(a, _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff))), b,   \
	              _CMP_LT_OQ)
#define MAND(a, b) _mm256_and_ps(a, b)
#define MBITS(m) _mm256_movemask_ps(m)
#define SEL(m, f, t) _mm256_blendv_ps(f, t, m)
#define SELI(m, f, t)                                                                        \
	_mm256_castps_si256(_mm256_blendv_ps(_mm256_castsi256_ps(f), _mm256_castsi256_ps(t), m))
#define ADDI(a, b) _mm256_add_epi32(a, b)
#define BCAST(p) _mm256_broadcast_ss(p)
#define GATHER(p, vi) _mm256_i32gather_ps(p, vi, 4)
#define PERMUTE(p, vi) _mm256_permutevar8x32_ps(_mm256_loadu_ps(p), vi)
#define STOREU(p, v) _mm256_storeu_ps(p, v)
#define STORE_BYTES(p, vi) store_bytes(p, vi)

INLINE void store_bytes(uint8_t *p, __m256i v)
{
	__m128i b16 = _mm_packus_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
	_mm_storel_epi64((__m128i *)p, _mm_packus_epi16(b16, b16));
}

#include "camspace_simd.h"

TARGET static void exact16(const kg_cs_model *m, const float *x, const float *cov, size_t i,
                           const kg_cs_block *out)
{
	exact_vectors(m, x, cov, i, out, 2);
}

TARGET static void exact8(const kg_cs_model *m, const float *x, const float *cov, size_t i,
                          const kg_cs_block *out)
{
	exact_vectors(m, x, cov, i, out, 1);
}

TARGET static void quad8(const kg_cs_model *m, const float *tab, const float *x,
                         const float *cov, size_t i, const kg_cs_block *out)
{
	quad_vectors(m, tab, x, cov, i, out, 1);
}

size_t est_cs_match_avx2(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                         const kg_cs_block *out)
{
	size_t i = 0;
	for (; i + 16 <= n; i += 16)
		exact16(m, x, cov, i, out);
	for (; i + 8 <= n; i += 8)
		exact8(m, x, cov, i, out);
	return i;
}

size_t est_cs_quad_avx2(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                        const kg_cs_block *out)
{
	float *tab = n >= 8 ? quad_table(m) : NULL;
	size_t i = 0;
	for (; i + 8 <= n; i += 8)
		quad8(m, tab, x, cov, i, out);
	free(tab);
	return i;
}

#else

size_t est_cs_match_avx2(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                         const kg_cs_block *out)
{
	(void)m, (void)x, (void)cov, (void)n, (void)out;
	return 0;
}

size_t est_cs_quad_avx2(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                        const kg_cs_block *out)
{
	(void)m, (void)x, (void)cov, (void)n, (void)out;
	return 0;
}

#endif
