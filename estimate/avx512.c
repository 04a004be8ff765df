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
 * streaming where the run asks for it; stage 1 (flags and terms, the AVX2 path's code)
 * of the next chunk runs between the groups of the current one. BIP, weights,
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

/* Matrix kernel of one chunk straight into the BSQ planes, 32 pixels at a time: the
 * group's terms stay in registers, and each band's 32 values go to its plane as one
 * whole 64-byte line of f16 or two of f32, streaming where the run asks for it. A full
 * line per non-temporal store needs no write combining across instructions, which is
 * what made the AVX2 path go band by band over a chunk instead (avx2.c); on a Zen 5
 * the groups reach 0.9-1.0 of the write limit against 0.65-0.8 for band by band
 * (bench/bench_kernels.c, back to back in one run). A band's coefficients are
 * broadcast from the plan (one load each, from L1). Lanes past the chunk's end compute
 * from leftover terms and are neither stored nor counted. */
INLINE_AVX512 __m512i pack_f16(__m512 lo, __m512 hi)
{
	return _mm512_inserti64x4(
	    _mm512_castsi256_si512(_mm512_cvtps_ph(lo, _MM_FROUND_TO_NEAREST_INT)),
	    _mm512_cvtps_ph(hi, _MM_FROUND_TO_NEAREST_INT), 1);
}

/* The next chunk, staged group by group while this one's bands are written: its
 * flags and terms go to nx (NULL: no next chunk). The stores of a group leave the
 * vector units idle while they drain; stage 1 of the next chunk fills that time.
 * Only the last chunk of a block is short, and it has no next one: the groups of a
 * chunk with a next one cover all EST_CHUNK of that chunk's pixels. */
typedef struct next_chunk {
	est_scratch *nx;
	const float *rgb;
	size_t m;
} next_chunk;

INLINE_AVX512 void stage_next(const est_plan *p, const next_chunk *nc, size_t i0, size_t i1,
                              est_counts *c)
{
	if (nc->nx && i0 < nc->m)
		est_avx2_stage_terms_part(p, nc->nx, nc->rgb, nc->m, i0, i1 < nc->m ? i1 : nc->m, c);
}

INLINE_AVX512 void bsq512_nt(const est_plan *p, const int nt, est_scratch *s, size_t m,
                             const est_dst *d, size_t at, const int stream, est_counts *c,
                             const next_chunk *nc)
{
	const est_map *mp = p->map;
	const int nb = mp->nb, clamp = mp->clamp, half = p->format == KG_EST_F16_BSQ;
	const float *a = mp->a, *terms = s->terms;
	const __m512 zero = _mm512_setzero_ps();
	const __m512i one = _mm512_set1_epi32(1);
	uint64_t clamped = 0;
	for (size_t i = 0; i < m; i += 32) {
		const size_t left = m - i;
		const __mmask16 v0 = left >= 16 ? (__mmask16)0xffff : (__mmask16)((1u << left) - 1);
		const __mmask16 v1 = left >= 32   ? (__mmask16)0xffff
		                     : left <= 16 ? (__mmask16)0
		                                  : (__mmask16)((1u << (left - 16)) - 1);
		__m512 t0[KG_EST_MAX_TERMS], t1[KG_EST_MAX_TERMS];
		for (int t = 0; t < nt; t++) {
			t0[t] = _mm512_load_ps(terms + t * EST_TSTRIDE + i);
			t1[t] = _mm512_load_ps(terms + t * EST_TSTRIDE + i + 16);
		}
		__m512i n0 = _mm512_setzero_si512(), n1 = n0; /* clamped bands per pixel */
		for (int o = 0; o < nb; o++) {
			__m512 acc0 = _mm512_set1_ps(mp->off[o]), acc1 = acc0;
#pragma GCC unroll 16
			for (int t = 0; t < nt; t++) {
				const __m512 coef = _mm512_set1_ps(a[(size_t)o * nt + t]);
				acc0 = _mm512_fmadd_ps(coef, t0[t], acc0);
				acc1 = _mm512_fmadd_ps(coef, t1[t], acc1);
			}
			if (clamp) {
				const __mmask16 lt0 = _mm512_mask_cmp_ps_mask(v0, acc0, zero, _CMP_LT_OQ);
				const __mmask16 lt1 = _mm512_mask_cmp_ps_mask(v1, acc1, zero, _CMP_LT_OQ);
				n0 = _mm512_mask_add_epi32(n0, lt0, n0, one);
				n1 = _mm512_mask_add_epi32(n1, lt1, n1, one);
				/* maxps returns its second operand for a NaN and for equal zeros */
				acc0 = _mm512_max_ps(zero, acc0);
				acc1 = _mm512_max_ps(zero, acc1);
			}
			const size_t base = (size_t)o * d->plane_stride + at + i;
			if (half) {
				uint16_t *dst = (uint16_t *)d->data + base;
				const __m512i h = pack_f16(acc0, acc1);
				if (left >= 32 && stream)
					_mm512_stream_si512((void *)dst, h);
				else if (left >= 32)
					_mm512_storeu_si512((void *)dst, h);
				else { /* the chunk's last, partial group (AVX-512F has no 16-bit masks) */
					uint16_t tmp[32];
					_mm512_storeu_si512((void *)tmp, h);
					memcpy(dst, tmp, left * sizeof(uint16_t));
				}
			} else {
				float *dst = (float *)d->data + base;
				if (left >= 32 && stream) {
					_mm512_stream_ps(dst, acc0);
					_mm512_stream_ps(dst + 16, acc1);
				} else {
					_mm512_mask_storeu_ps(dst, v0, acc0);
					_mm512_mask_storeu_ps(dst + 16, v1, acc1);
				}
			}
		}
		if (clamp) {
			clamped += (uint64_t)_mm512_reduce_add_epi32(_mm512_add_epi32(n0, n1));
			const uint32_t hit = (uint32_t)_mm512_test_epi32_mask(n0, n0) |
			                     (uint32_t)_mm512_test_epi32_mask(n1, n1) << 16;
			for (size_t b = 0; b < 4 && 8 * b < left; b++)
				s->clampbits[i / 8 + b] = (uint8_t)(hit >> (8 * b));
		}
		stage_next(p, nc, i, i + 32, c);
	}
	c->clamped_values += clamped;
}

/* One group of 64 pixels at i (left = m - i of them in the chunk). full, clamp and
 * stream are constants at each call: a whole group compares without lane masks and
 * stores without tests, so its loop over the bands holds nothing but the kernel (with
 * the masks and tests kept for every group the compiler spilled the masks and
 * reloaded them every band). */
INLINE_AVX512 uint64_t f16_64_group(const est_map *mp, const float *terms, size_t i,
                                    size_t left, uint16_t *dst0, size_t stride,
                                    uint8_t *clampbits, const int full, const int clamp,
                                    const int stream)
{
	enum { NT = 3, V = 4 };
	const int nb = mp->nb;
	const float *a = mp->a;
	const __m512 zero = _mm512_setzero_ps();
	const __m512i one = _mm512_set1_epi32(1);
	__mmask16 valid[V];
	__m512 tv[V][NT];
	__m512i n[V]; /* clamped bands per pixel */
#pragma GCC unroll 4
	for (int v = 0; v < V; v++) {
		size_t at_v = 16 * (size_t)v;
		valid[v] = full || at_v + 16 <= left ? (__mmask16)0xffff
		           : at_v >= left            ? (__mmask16)0
		                                     : (__mmask16)((1u << (left - at_v)) - 1);
		n[v] = _mm512_setzero_si512();
#pragma GCC unroll 4
		for (int t = 0; t < NT; t++)
			tv[v][t] = _mm512_load_ps(terms + t * EST_TSTRIDE + i + at_v);
	}
	for (int o = 0; o < nb; o++) {
		__m512 acc[V];
#pragma GCC unroll 4
		for (int v = 0; v < V; v++)
			acc[v] = _mm512_set1_ps(mp->off[o]);
#pragma GCC unroll 4
		for (int t = 0; t < NT; t++) {
			const __m512 coef = _mm512_set1_ps(a[(size_t)o * NT + t]);
#pragma GCC unroll 4
			for (int v = 0; v < V; v++)
				acc[v] = _mm512_fmadd_ps(coef, tv[v][t], acc[v]);
		}
		if (clamp)
#pragma GCC unroll 4
			for (int v = 0; v < V; v++) {
				const __mmask16 lt = full ? _mm512_cmp_ps_mask(acc[v], zero, _CMP_LT_OQ)
				                          : _mm512_mask_cmp_ps_mask(valid[v], acc[v], zero,
				                                                    _CMP_LT_OQ);
				n[v] = _mm512_mask_add_epi32(n[v], lt, n[v], one);
				acc[v] = _mm512_max_ps(zero, acc[v]); /* as bsq512_nt */
			}
		uint16_t *dst = dst0 + (size_t)o * stride;
#pragma GCC unroll 4
		for (int v = 0; v < V; v += 2) {
			const __m512i h = pack_f16(acc[v], acc[v + 1]);
			const size_t off = 16 * (size_t)v;
			if ((full || left >= off + 32) && stream)
				_mm512_stream_si512((void *)(dst + off), h);
			else if (full || left >= off + 32)
				_mm512_storeu_si512((void *)(dst + off), h);
			else if (left > off) { /* the chunk's last, partial line */
				uint16_t tmp[32];
				_mm512_storeu_si512((void *)tmp, h);
				memcpy(dst + off, tmp, (left - off) * sizeof(uint16_t));
			}
		}
	}
	if (!clamp)
		return 0;
#pragma GCC unroll 4
	for (int v = 0; v < V; v++) { /* n[v] by constant index: kept in registers */
		const uint32_t hit = _mm512_test_epi32_mask(n[v], n[v]);
		for (size_t k = 0; k < 2 && 16 * (size_t)v + 8 * k < left; k++)
			clampbits[(i + 16 * (size_t)v) / 8 + k] = (uint8_t)(hit >> (8 * k));
	}
	return (uint64_t)_mm512_reduce_add_epi32(
	    _mm512_add_epi32(_mm512_add_epi32(n[0], n[1]), _mm512_add_epi32(n[2], n[3])));
}

/* f16 of the 3-term kernels, 64 pixels a group: each band's 64 values go to its plane
 * as two whole lines. With one line a plane per group the kernel was store bound
 * (alone, that pattern of streaming stores over 61 planes ran at half the rate of one
 * contiguous stream; two lines came within 7 % of it), and 64 pixels raised these rows
 * by about 20 % (means of three runs of bench/bench_kernels.c each, back to back;
 * docs/estimate.md). 128 pixels
 * gained nothing more, and the 6-term kernel (24 registers of terms) or f32 (four
 * lines) in groups of 64 were no faster than in groups of 32. */
INLINE_AVX512 void bsq512_f16_64(const est_plan *p, est_scratch *s, size_t m,
                                 const est_dst *d, size_t at, const int stream, est_counts *c,
                                 const next_chunk *nc)
{
	const est_map *mp = p->map;
	const int clamp = mp->clamp;
	const size_t stride = d->plane_stride;
	uint16_t *dst = (uint16_t *)d->data + at;
	uint64_t clamped = 0;
	for (size_t i = 0; i < m; i += 64) {
		const size_t left = m - i;
		const int kind = (left >= 64 ? 4 : 0) | (clamp ? 2 : 0) | (stream ? 1 : 0);
		switch (kind) {
#define F16_GROUP(K)                                                                         \
	case K:                                                                                  \
		clamped += f16_64_group(mp, s->terms, i, left, dst + i, stride, s->clampbits,        \
		                        (K) >> 2 & 1, (K) >> 1 & 1, (K) & 1);                         \
		break;
			F16_GROUP(0) F16_GROUP(1) F16_GROUP(2) F16_GROUP(3)
			F16_GROUP(4) F16_GROUP(5) F16_GROUP(6) F16_GROUP(7)
#undef F16_GROUP
		}
		stage_next(p, nc, i, i + 64, c);
	}
	c->clamped_values += clamped;
}

AVX512 static void bsq512(const est_plan *p, est_scratch *s, size_t m, const est_dst *d,
                          size_t at, int stream, est_counts *c, const next_chunk *nc)
{
	switch (p->k->nterms) {
	case 3:
		if (p->format == KG_EST_F16_BSQ)
			bsq512_f16_64(p, s, m, d, at, stream, c, nc);
		else
			bsq512_nt(p, 3, s, m, d, at, stream, c, nc);
		break;
	case 6:
		bsq512_nt(p, 6, s, m, d, at, stream, c, nc);
		break;
	default:
		bsq512_nt(p, KG_EST_MAX_TERMS, s, m, d, at, stream, c, nc);
		break;
	}
}

/* Whether every plane's part of the chunk at pixel `at` has the 64-byte alignment
 * streaming stores need (es: bytes a value). */
static inline int chunk_aligned(const est_dst *d, size_t at, size_t es)
{
	return (((uintptr_t)d->data + at * es) & 63) == 0 && ((d->plane_stride * es) & 63) == 0;
}

/* BSQ matrix blocks: chunk by chunk, the 16-lane kernel where every plane's part of
 * the chunk has the first one's 64-byte alignment (streaming stores need it) or the
 * stores are cached; otherwise that chunk goes through the AVX2 path. The next
 * chunk's stage 1 runs inside this one's kernel (next_chunk), into the other of two
 * buffers of terms and flags. */
AVX512 static void avx512_bsq_block(const est_plan *p, est_scratch *s, const float *rgb,
                                    size_t n, const est_dst *d, est_counts *c)
{
	const size_t es = p->format == KG_EST_F16_BSQ ? 2 : 4;
	est_scratch cur = *s, nxt = *s;
	nxt.terms = s->terms2;
	nxt.flags = s->flags2;
	int staged = 0; /* cur holds this chunk's stage 1 */
	for (size_t at = 0; at < n; at += EST_CHUNK) {
		size_t m = n - at < EST_CHUNK ? n - at : EST_CHUNK;
		if (p->stream && !chunk_aligned(d, at, es)) {
			est_dst sub = {(char *)d->data + at * es, d->plane_stride, d->conf ? d->conf + at : NULL,
			               d->mask ? d->mask + at : NULL};
			est_avx2_matrix_block(p, s, rgb + 3 * at, m, &sub, c);
			staged = 0;
			continue;
		}
		if (!staged)
			est_avx2_stage_terms_part(p, &cur, rgb + 3 * at, m, 0, m, c);
		memset(cur.clampbits, 0, EST_CHUNK / 8);
		const size_t nat = at + EST_CHUNK;
		const int next_ok = nat < n && (!p->stream || chunk_aligned(d, nat, es));
		next_chunk nc = {next_ok ? &nxt : NULL, rgb + 3 * nat,
		                 next_ok ? (n - nat < EST_CHUNK ? n - nat : EST_CHUNK) : 0};
		bsq512(p, &cur, m, d, at, p->stream, c, &nc);
		est_finish_mask(&cur, m, d->mask ? d->mask + at : NULL, c);
		if (next_ok) {
			float *t = cur.terms;
			uint8_t *f = cur.flags;
			cur.terms = nxt.terms, cur.flags = nxt.flags;
			nxt.terms = t, nxt.flags = f;
		}
		staged = next_ok;
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
