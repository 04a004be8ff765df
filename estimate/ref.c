/* The reference kernels: one pixel at a time, written to be obviously right. Also
 * the scalar stages the optimised kernels share with them, and the dispatch table. */
#include <stdlib.h>
#include <string.h>

#include "est_private.h"

static void count_flags(unsigned flags, est_counts *c)
{
	c->nonfinite += (flags & KG_EST_MASK_NONFINITE) != 0;
	c->clipped += (flags & KG_EST_MASK_CLIPPED) != 0;
}

static void store_value(const est_plan *p, const est_dst *d, size_t i, int o, float v)
{
	size_t nb = (size_t)p->map->nb;
	switch (p->format) {
	case KG_EST_F32_BSQ:
		((float *)d->data)[o * d->plane_stride + i] = v;
		break;
	case KG_EST_F16_BSQ:
		((uint16_t *)d->data)[o * d->plane_stride + i] = kg_f16_from_f32(v);
		break;
	case KG_EST_F16_BIP:
		((uint16_t *)d->data)[i * nb + o] = kg_f16_from_f32(v);
		break;
	default: /* F32_BIP, WEIGHTS */
		((float *)d->data)[i * nb + o] = v;
		break;
	}
}

/* EST_REF_CLONES: fmaf is one instruction where the CPU has FMA (est_private.h). */
EST_REF_CLONES static void ref_block(const est_plan *p, est_scratch *s, const float *rgb, size_t n,
                                 const est_dst *d, est_counts *c)
{
	const kg_est_kernel *k = p->k;
	const est_map *m = p->map;
	float v[EST_PAD(KG_NBANDS)];
	for (size_t i = 0; i < n; i++) {
		const float *px = rgb + 3 * i;
		unsigned flags = est_pixel_flags(px, p->clip);
		count_flags(flags, c);
		if (k->method == KG_EST_LUT) {
			float w[8];
			int32_t cell = est_lut_cell(k, px, flags, w);
			for (int o = 0; o < m->nb; o++)
				v[o] = est_lut_band(m, k->lut_n, cell, w, o);
		} else {
			float t[KG_EST_MAX_TERMS];
			est_pixel_terms(k->method, px, flags, t);
			for (int o = 0; o < m->nb; o++)
				v[o] = est_matrix_band(m, k->nterms, o, t);
		}
		if (m->clamp) {
			int clamped = 0;
			for (int o = 0; o < m->nb; o++)
				if (v[o] < 0.0f) {
					v[o] = 0.0f;
					clamped++;
				}
			if (clamped) {
				flags |= KG_EST_MASK_CLAMPED;
				c->clamped_pixels++;
				c->clamped_values += (uint64_t)clamped;
			}
		}
		if (p->format == KG_EST_LABELS) {
			uint8_t label = KG_EST_LABEL_NONE;
			float margin = NAN;
			if (!(flags & (KG_EST_MASK_NONFINITE | KG_EST_MASK_CLIPPED))) {
				double dv[KG_EST_MAX_K];
				est_weights_to_v(p->cls, v, dv);
				est_classify_pixel(p->cls, dv, &label, &margin);
			}
			((uint8_t *)d->data)[i] = label;
			if (d->conf)
				d->conf[i] = margin;
		} else {
			for (int o = 0; o < m->nb; o++)
				store_value(p, d, i, o, v[o]);
		}
		if (d->mask)
			d->mask[i] = (uint8_t)flags;
	}
}

void *est_alloc_zeroed(size_t bytes)
{
	size_t n = bytes ? (bytes + 63) & ~(size_t)63 : 64; /* a multiple of the alignment */
	void *p = aligned_alloc(64, n);
	if (p)
		memset(p, 0, n);
	return p;
}

int est_scratch_init(est_scratch *s)
{
	memset(s, 0, sizeof(*s));
	s->terms = est_alloc_zeroed(sizeof(float) * KG_EST_MAX_TERMS * EST_TSTRIDE);
	s->vals = est_alloc_zeroed(sizeof(float) * 64 * EST_CHUNK);
	s->rows = est_alloc_zeroed(sizeof(float) * 64 * EST_CHUNK);
	s->cell = est_alloc_zeroed(sizeof(int32_t) * EST_CHUNK);
	s->cw = est_alloc_zeroed(sizeof(float) * 8 * EST_CHUNK);
	s->flags = est_alloc_zeroed(EST_CHUNK);
	s->clampbits = est_alloc_zeroed(EST_CHUNK / 8);
	s->terms2 = est_alloc_zeroed(sizeof(float) * KG_EST_MAX_TERMS * EST_TSTRIDE);
	s->flags2 = est_alloc_zeroed(EST_CHUNK);
	if (!s->terms || !s->vals || !s->rows || !s->cell || !s->cw || !s->flags || !s->clampbits ||
	    !s->terms2 || !s->flags2) {
		est_scratch_fini(s);
		return KG_ENOMEM;
	}
	return 0;
}

void est_scratch_fini(est_scratch *s)
{
	free(s->terms);
	free(s->vals);
	free(s->rows);
	free(s->cell);
	free(s->cw);
	free(s->flags);
	free(s->clampbits);
	free(s->terms2);
	free(s->flags2);
	memset(s, 0, sizeof(*s));
}

void est_dsp_init_c(est_dsp *dsp)
{
	for (int k = 0; k < EST_NKINDS; k++)
		for (int f = 0; f < KG_EST_NFORMATS; f++)
			dsp->block[k][f] = ref_block;
}

int est_dsp_init(est_dsp *dsp, kg_est_isa isa)
{
	est_dsp_init_c(dsp);
	if (isa == KG_EST_ISA_C)
		return 0;
	if ((int)isa < 0 || isa >= KG_EST_NISAS)
		return KG_EINVAL;
	int avx2 = est_have_avx2(), avx512 = avx2 && est_have_avx512();
	if ((isa == KG_EST_ISA_AVX2 && !avx2) || (isa == KG_EST_ISA_AVX512 && !avx512))
		return KG_ENOTSUP;
	if (avx2)
		est_dsp_init_avx2(dsp);
	if (avx512 && isa != KG_EST_ISA_AVX2)
		est_dsp_init_avx512(dsp);
	return 0;
}
