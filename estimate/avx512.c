/* The AVX-512 path, selected at run time on CPUs with AVX-512F (besides AVX2, FMA and
 * F16C). Compiled with function-level target attributes, so it builds on any x86-64
 * compiler and machine; it runs only where est_have_avx512 says the CPU and the OS
 * support it.
 *
 * It computes exactly what the reference computes, like the AVX2 path: the same IEEE
 * operations in the same order, each multiply-add of a band's sum fused (vfmadd, the
 * reference's fmaf), the clamp `v < 0 ? 0 : v` as maxps(0, v), the f16 conversion by
 * vcvtps2ph (round to nearest even, as kg_f16_from_f32).
 *
 * What it changes is the width of the BSQ outputs (f32 and f16 spectra), the outputs
 * whose bytes dominate: 16 pixels per vector, two vectors (32 pixels) per group, every
 * band of the group computed from the terms and written at once into its plane (128
 * bytes of f32, 64 of f16: whole cache lines when the planes are 64-byte aligned),
 * streaming where the run asks for it. Stage 1 (flags and terms), BIP, weights,
 * labels and LUTs are the AVX2 path's: their cost is elsewhere (terms, permutes, the
 * classifier, gathers), and they are already bit-identical. */
#include "est_private.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))

#include <cpuid.h>
#include <immintrin.h>

#define AVX512 __attribute__((target("avx512f,avx2,fma,f16c,popcnt")))
#define INLINE_AVX512                                                                        \
	__attribute__((target("avx512f,avx2,fma,f16c,popcnt"), always_inline)) static inline

int est_have_avx512(void)
{
	__builtin_cpu_init();
	return est_have_avx2() && __builtin_cpu_supports("avx512f");
}

/* Matrix kernel of one chunk straight into the BSQ planes, band by band as the AVX2
 * path does (avx2.c says why), 16 pixels per vector: the band's coefficients are
 * broadcast once, its values for the chunk go to its plane in one sequential run.
 * Lanes past the chunk's end compute from leftover terms and are neither stored nor
 * counted. The clamped bands are counted per pixel in s->cell. */
INLINE_AVX512 void bsq512_nt(const est_plan *p, const int nt, est_scratch *s, size_t m,
                             const est_dst *d, size_t at, const int stream, est_counts *c)
{
	const est_map *mp = p->map;
	const int nb = mp->nb, clamp = mp->clamp, half = p->format == KG_EST_F16_BSQ;
	const float *a = mp->a, *terms = s->terms;
	int32_t *cnt = s->cell;
	const __m512 zero = _mm512_setzero_ps();
	const __m512i one = _mm512_set1_epi32(1);
	const size_t mv = (m + 15) & ~(size_t)15, mfull = m & ~(size_t)15;
	if (clamp)
		memset(cnt, 0, mv * sizeof(int32_t));
	for (int o = 0; o < nb; o++) {
		__m512 coef[KG_EST_MAX_TERMS];
		for (int t = 0; t < nt; t++)
			coef[t] = _mm512_set1_ps(a[(size_t)o * nt + t]);
		const __m512 off = _mm512_set1_ps(mp->off[o]);
		float *dst32 = (float *)d->data + o * d->plane_stride + at;
		uint16_t *dst16 = (uint16_t *)d->data + o * d->plane_stride + at;
		for (size_t i = 0; i < mv; i += 16) {
			__m512 acc = off;
#pragma GCC unroll 16
			for (int t = 0; t < nt; t++)
				acc = _mm512_fmadd_ps(coef[t], _mm512_load_ps(terms + t * EST_TSTRIDE + i), acc);
			if (clamp) {
				__mmask16 lt = _mm512_cmp_ps_mask(acc, zero, _CMP_LT_OQ);
				/* maxps returns its second operand for a NaN and for equal zeros */
				acc = _mm512_max_ps(zero, acc);
				__m512i q = _mm512_load_si512((const void *)(cnt + i));
				_mm512_store_si512((void *)(cnt + i), _mm512_mask_add_epi32(q, lt, q, one));
			}
			if (half) {
				__m256i h = _mm512_cvtps_ph(acc, _MM_FROUND_TO_NEAREST_INT);
				if (i < mfull) {
					if (stream)
						_mm256_stream_si256((__m256i *)(dst16 + i), h);
					else
						_mm256_storeu_si256((__m256i *)(dst16 + i), h);
				} else {
					uint16_t tmp[16];
					_mm256_storeu_si256((__m256i *)tmp, h);
					memcpy(dst16 + i, tmp, (m - i) * sizeof(uint16_t));
				}
			} else if (i < mfull) {
				if (stream)
					_mm512_stream_ps(dst32 + i, acc);
				else
					_mm512_storeu_ps(dst32 + i, acc);
			} else {
				float tmp[16];
				_mm512_storeu_ps(tmp, acc);
				memcpy(dst32 + i, tmp, (m - i) * sizeof(float));
			}
		}
	}
	if (!clamp)
		return;
	__m512i total = _mm512_setzero_si512();
	for (size_t i = 0; i < mv; i += 16) {
		size_t lanes = m - i;
		__mmask16 valid = lanes >= 16 ? (__mmask16)0xffff : (__mmask16)((1u << lanes) - 1);
		__m512i n = _mm512_maskz_loadu_epi32(valid, cnt + i);
		total = _mm512_add_epi32(total, n);
		unsigned hit = (unsigned)_mm512_cmpgt_epi32_mask(n, _mm512_setzero_si512());
		s->clampbits[i / 8] = (uint8_t)(hit & 0xff);
		if (lanes > 8)
			s->clampbits[i / 8 + 1] = (uint8_t)(hit >> 8);
	}
	int sum[16];
	_mm512_storeu_si512((void *)sum, total);
	for (int l = 0; l < 16; l++)
		c->clamped_values += (uint64_t)sum[l];
}

AVX512 static void bsq512(const est_plan *p, est_scratch *s, size_t m, const est_dst *d,
                          size_t at, int stream, est_counts *c)
{
	switch (p->k->nterms) {
	case 3:
		bsq512_nt(p, 3, s, m, d, at, stream, c);
		break;
	case 6:
		bsq512_nt(p, 6, s, m, d, at, stream, c);
		break;
	default:
		bsq512_nt(p, KG_EST_MAX_TERMS, s, m, d, at, stream, c);
		break;
	}
}

/* BSQ matrix blocks: chunk by chunk, the 16-lane kernel where every plane's part of
 * the chunk has the first one's 64-byte alignment (streaming stores need it) or the
 * stores are cached; otherwise that chunk goes through the AVX2 path. */
AVX512 static void avx512_bsq_block(const est_plan *p, est_scratch *s, const float *rgb,
                                    size_t n, const est_dst *d, est_counts *c)
{
	const size_t es = p->format == KG_EST_F16_BSQ ? 2 : 4;
	for (size_t at = 0; at < n; at += EST_CHUNK) {
		size_t m = n - at < EST_CHUNK ? n - at : EST_CHUNK;
		int aligned = (((uintptr_t)d->data + at * es) & 63) == 0 &&
		              ((d->plane_stride * es) & 63) == 0;
		if (p->stream && !aligned) {
			est_dst sub = {(char *)d->data + at * es, d->plane_stride, d->conf ? d->conf + at : NULL,
			               d->mask ? d->mask + at : NULL};
			est_avx2_matrix_block(p, s, rgb + 3 * at, m, &sub, c);
			continue;
		}
		est_avx2_stage_terms(p, s, rgb + 3 * at, m, c);
		bsq512(p, s, m, d, at, p->stream, c);
		est_finish_mask(s, m, d->mask ? d->mask + at : NULL, c);
	}
	if (p->stream)
		_mm_sfence();
}

void est_dsp_init_avx512(est_dsp *dsp)
{
	dsp->block[EST_KIND_MATRIX][KG_EST_F32_BSQ] = avx512_bsq_block;
	dsp->block[EST_KIND_MATRIX][KG_EST_F16_BSQ] = avx512_bsq_block;
}

#else

int est_have_avx512(void) { return 0; }

void est_dsp_init_avx512(est_dsp *dsp) { (void)dsp; }

#endif
