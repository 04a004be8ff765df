/* Optimised kernels for x86-64 with AVX2 and F16C, selected at run time.
 *
 * They compute exactly what the reference computes: the same IEEE operations in the
 * same order (multiplies and adds kept apart, never fused), with flags, terms and
 * LUT weights from the same scalar code (est_stage_*). What they change is the
 * layout of the work: 8 pixels per vector for matrix kernels (the BIP form permutes
 * terms so that each vector is 8 consecutive output values), 8 bands per vector for
 * LUTs, 4 pixels per double vector for classification, and non-temporal stores for
 * large outputs. AVX-512 is not used: the machines this was tuned on lack it. */
#include "est_private.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))

#include <immintrin.h>

#define AVX2 __attribute__((target("avx2,f16c,popcnt")))
#define INLINE_AVX2 __attribute__((target("avx2,f16c,popcnt"), always_inline)) static inline

int est_have_avx2(void)
{
	__builtin_cpu_init();
	return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("f16c") &&
	       __builtin_cpu_supports("popcnt");
}

static inline int lane_mask(size_t valid) { return valid >= 8 ? 0xff : (1 << valid) - 1; }

/* Clamp negative lanes of acc to 0 (keeping -0.0, as the reference does); *lt gets
 * the clamped lanes. */
INLINE_AVX2 __m256 clamp_negative(__m256 acc, __m256 *lt)
{
	*lt = _mm256_cmp_ps(acc, _mm256_setzero_ps(), _CMP_LT_OQ);
	return _mm256_andnot_ps(*lt, acc);
}

/* Matrix kernel, 8 pixels per vector, values band-major into s->vals
 * (band o of pixel i at o * EST_CHUNK + i), for BSQ stores and classification.
 * Inlined once per number of terms so that the term loop unrolls. */
INLINE_AVX2 void matrix_soa_nt(const est_map *mp, const int nt, est_scratch *s, size_t m,
                               est_counts *c)
{
	uint64_t clamped = 0;
	for (int o = 0; o < mp->nb; o++) {
		__m256 a[KG_EST_MAX_TERMS];
		for (int t = 0; t < nt; t++)
			a[t] = _mm256_set1_ps(mp->a[o * nt + t]);
		__m256 off = _mm256_set1_ps(mp->off[o]);
		float *dst = s->vals + (size_t)o * EST_CHUNK;
		for (size_t i = 0; i < m; i += 8) {
			__m256 acc = off;
			for (int t = 0; t < nt; t++)
				acc = _mm256_add_ps(
				    acc, _mm256_mul_ps(a[t], _mm256_load_ps(s->terms + t * EST_TSTRIDE + i)));
			if (mp->clamp) {
				__m256 lt;
				acc = clamp_negative(acc, &lt);
				int bits = _mm256_movemask_ps(lt) & lane_mask(m - i);
				clamped += (uint64_t)__builtin_popcount(bits);
				s->clampbits[i / 8] |= (uint8_t)bits;
			}
			_mm256_store_ps(dst + i, acc);
		}
	}
	c->clamped_values += clamped;
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

/* Matrix kernel straight into BIP (f32, f16 or weights): for 8 pixels the output is
 * 8 * nb consecutive values, i.e. nb vectors; lane l of vector v is band (8v+l) % nb
 * of pixel (8v+l) / nb, whose terms are brought into the lane by a permute. */
INLINE_AVX2 void matrix_bip_nt(const est_plan *p, const int nt, est_scratch *s, size_t m,
                               const est_dst *d, size_t at, est_counts *c)
{
	const est_map *mp = p->map;
	int nb = mp->nb;
	uint64_t clamped = 0;
	int half = p->format == KG_EST_F16_BIP;
	size_t es = half ? 2 : 4;
	char *base = (char *)d->data + at * nb * es;
	int stream = p->stream && ((uintptr_t)base & (half ? 15 : 31)) == 0;
	for (size_t i = 0; i < m; i += 8) {
		size_t rem = m - i;
		__m256 term[KG_EST_MAX_TERMS];
		for (int t = 0; t < nt; t++)
			term[t] = _mm256_load_ps(s->terms + t * EST_TSTRIDE + i);
		/* a partial group goes through tmp */
		float tmp[8 * EST_PAD(KG_NBANDS)];
		char *out = rem >= 8 ? base + i * nb * es : (char *)tmp;
		__m256i remv = _mm256_set1_epi32((int)rem), one = _mm256_set1_epi32(1);
		__m256i clamped_pixels = _mm256_setzero_si256(); /* lane l: pixel bits */
		for (int v = 0; v < nb; v++) {
			__m256i pix = _mm256_load_si256((const __m256i *)(mp->bip_pix + 8 * v));
			__m256 acc = _mm256_load_ps(mp->bip_off + 8 * v);
			const float *coef = mp->bip_coef + (size_t)v * nt * 8;
			for (int t = 0; t < nt; t++)
				acc = _mm256_add_ps(acc,
				                    _mm256_mul_ps(_mm256_load_ps(coef + 8 * t),
				                                  _mm256_permutevar8x32_ps(term[t], pix)));
			if (mp->clamp) {
				__m256 lt;
				acc = clamp_negative(acc, &lt);
				__m256i hit = _mm256_castps_si256(lt);
				if (rem < 8)
					hit = _mm256_and_si256(hit, _mm256_cmpgt_epi32(remv, pix));
				clamped +=
				    (uint64_t)__builtin_popcount(_mm256_movemask_ps(_mm256_castsi256_ps(hit)));
				clamped_pixels = _mm256_or_si256(
				    clamped_pixels, _mm256_and_si256(hit, _mm256_sllv_epi32(one, pix)));
			}
			if (half) {
				__m128i h = _mm256_cvtps_ph(acc, _MM_FROUND_TO_NEAREST_INT);
				__m128i *q = (__m128i *)(out + (size_t)v * 16);
				if (stream && rem >= 8)
					_mm_stream_si128(q, h);
				else
					_mm_storeu_si128(q, h);
			} else {
				float *q = (float *)(out + (size_t)v * 32);
				if (stream && rem >= 8)
					_mm256_stream_ps(q, acc);
				else
					_mm256_storeu_ps(q, acc);
			}
		}
		if (rem < 8)
			memcpy(base + i * nb * es, tmp, rem * nb * es);
		if (mp->clamp) {
			__m128i x = _mm_or_si128(_mm256_castsi256_si128(clamped_pixels),
			                         _mm256_extracti128_si256(clamped_pixels, 1));
			x = _mm_or_si128(x, _mm_shuffle_epi32(x, _MM_SHUFFLE(1, 0, 3, 2)));
			x = _mm_or_si128(x, _mm_shuffle_epi32(x, _MM_SHUFFLE(2, 3, 0, 1)));
			s->clampbits[i / 8] |= (uint8_t)_mm_cvtsi128_si32(x);
		}
	}
	c->clamped_values += clamped;
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
	int k = cl->k;
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

AVX2 static void avx2_matrix_block(const est_plan *p, est_scratch *s, const float *rgb,
                                   size_t n, const est_dst *d, est_counts *c)
{
	for (size_t at = 0; at < n; at += EST_CHUNK) {
		size_t m = n - at < EST_CHUNK ? n - at : EST_CHUNK;
		est_stage_terms(p, s, rgb + 3 * at, m, c);
		switch (p->format) {
		case KG_EST_F32_BSQ:
		case KG_EST_F16_BSQ:
			matrix_soa(p, s, m, c);
			store_bsq(p, s, m, d, at);
			break;
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

/* LUT: 8 bands per vector, one pixel at a time, into s->rows (pixel-major, the
 * map's stride), corners summed in the reference's order. */
AVX2 static void lut_rows(const est_plan *p, est_scratch *s, size_t m, est_counts *c)
{
	const est_map *mp = p->map;
	int n = p->k->lut_n, stride = mp->stride;
	int32_t corner[8];
	for (int q = 0; q < 8; q++)
		corner[q] = est_lut_corner(n, q);
	for (size_t i = 0; i < m; i++) {
		const float *node[8];
		__m256 w[8];
		for (int q = 0; q < 8; q++) {
			node[q] = mp->lut + (size_t)(s->cell[i] + corner[q]) * stride;
			w[q] = _mm256_set1_ps(s->cw[8 * i + q]);
		}
		float *row = s->rows + i * stride;
		int clamped = 0;
		for (int g = 0; g < stride; g += 8) {
			__m256 acc = _mm256_mul_ps(w[0], _mm256_load_ps(node[0] + g));
			for (int q = 1; q < 8; q++)
				acc = _mm256_add_ps(acc, _mm256_mul_ps(w[q], _mm256_load_ps(node[q] + g)));
			if (mp->clamp) {
				__m256 lt;
				acc = clamp_negative(acc, &lt);
				clamped += __builtin_popcount(_mm256_movemask_ps(lt) &
				                              lane_mask((size_t)(mp->nb - g)));
			}
			_mm256_store_ps(row + g, acc);
		}
		if (clamped) {
			c->clamped_values += (uint64_t)clamped;
			s->clampbits[i / 8] |= (uint8_t)(1u << (i % 8));
		}
	}
}

/* Pixel-major rows into band-major values (zero past m up to a multiple of 8). */
static void rows_to_vals(const est_map *mp, est_scratch *s, size_t m)
{
	size_t m8 = (m + 7) & ~(size_t)7;
	for (int o = 0; o < mp->nb; o++) {
		float *dst = s->vals + (size_t)o * EST_CHUNK;
		for (size_t i = 0; i < m; i++)
			dst[i] = s->rows[i * mp->stride + o];
		for (size_t i = m; i < m8; i++)
			dst[i] = 0.0f;
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
		est_stage_lut(p, s, rgb + 3 * at, m, c);
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
		dsp->block[EST_KIND_MATRIX][f] = avx2_matrix_block;
		dsp->block[EST_KIND_LUT][f] = avx2_lut_block;
	}
}

#else

int est_have_avx2(void) { return 0; }

void est_dsp_init_avx2(est_dsp *dsp) { (void)dsp; }

#endif
