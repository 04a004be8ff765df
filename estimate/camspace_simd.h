/* The camera-space block kernels of both methods (camspace.c describes them), written
 * once for any vector width: camspace_avx2.c (8 lanes) and camspace_avx512.c (16 lanes)
 * each define the vector types and operations below and include this file once.
 *
 * Each kernel performs its C reference's IEEE operations in the same order, lane by
 * lane, so the outputs are bit-identical. What makes that hold:
 *   - multiplies and adds are fused exactly where the reference calls fmaf (FMA),
 *     never elsewhere (estimate/ is built with -ffp-contract=off); sqrt and division
 *     are the correctly rounded instructions, as sqrtf and / in the reference;
 *   - MAX(a, lo) is by definition `a > lo ? a : lo` (the second operand when either is
 *     NaN, or for zeros of either sign) and MIN(a, hi) is `a < hi ? a : hi`: the
 *     reference's clamps, NaN included; likewise MIN(d, dj) is `d < dj ? d : dj`, the
 *     running minimum that keeps the first of equal distances and never takes a NaN;
 *   - lanes the reference refuses (covariance not positive definite, x not finite) are
 *     computed with whatever their values give and overwritten at the end with the
 *     reference's KG_CS_NO_MATCH and NaNs.
 * The model's values are broadcast one candidate (material, angle) at a time, so every
 * lane walks the candidates in the reference's order. NV vectors share each broadcast:
 * their independent chains keep the vector ports busy. The work is bound by arithmetic,
 * with no memory traffic to speak of (a pixel reads 36 bytes, the model stays in L1).
 *
 * The including file defines: V (float vector), VI (int32 vector), M (lane mask), VN
 * (lanes), INLINE (always-inline with its target), IDX3 / IDX6 (VI: 0, 3, 6, .. and
 * 0, 6, 12, ..), and SET1(f), SET1I(i), ADD, SUB, MUL, DIV, SQRT, FMA(a, b, c) = a b + c
 * and FMS(a, b, c) = a b - c in one rounding, NEG (sign flipped), MIN, MAX (as above), LT, GT (ordered compares),
 * ABSLT(a, b) (|a| < b), MAND, MBITS (a mask's lanes as bits), SEL(m, f, t) and
 * SELI(m, f, t) (m ? t : f per lane), ADDI, BCAST(p) (*p in every lane), GATHER(p, vi),
 * PERMUTE(p, vi) (p[vi] per lane from the VN values at p), STOREU(p, v) and
 * STORE_BYTES(p, vi) (the low byte of each lane). */
#include <stdlib.h>

typedef struct lanes {
	M ok;
	V l3, l6, l7, i0, i4, i8, y0, y1, y2;
	V best, second, best_a, best_t;
	VI bj;
} lanes;

/* camspace.c's px_factor, and the fold's start. */
INLINE void lanes_init(lanes *p, const float *x, const float *cov)
{
	V c0 = GATHER(cov, IDX6), c1 = GATHER(cov + 1, IDX6), c2 = GATHER(cov + 2, IDX6);
	V c3 = GATHER(cov + 3, IDX6), c4 = GATHER(cov + 4, IDX6), c5 = GATHER(cov + 5, IDX6);
	V x0 = GATHER(x, IDX3), x1 = GATHER(x + 1, IDX3), x2 = GATHER(x + 2, IDX3);
	const V zero = SET1(0.0f), one = SET1(1.0f), inf = SET1(INFINITY), nan = SET1(NAN);
	V l0 = SQRT(c0);
	p->l3 = DIV(c1, l0);
	p->l6 = DIV(c2, l0);
	V l4 = SQRT(SUB(c3, MUL(p->l3, p->l3)));
	p->l7 = DIV(SUB(c4, MUL(p->l6, p->l3)), l4);
	V l8 = SQRT(SUB(SUB(c5, MUL(p->l6, p->l6)), MUL(p->l7, p->l7)));
	V sum = ADD(ADD(x0, x1), x2);
	p->ok = MAND(MAND(GT(l0, zero), GT(l4, zero)), MAND(GT(l8, zero), ABSLT(sum, inf)));
	p->i0 = DIV(one, l0);
	p->i4 = DIV(one, l4);
	p->i8 = DIV(one, l8);
	p->y0 = MUL(x0, p->i0);
	p->y1 = MUL(SUB(x1, MUL(p->l3, p->y0)), p->i4);
	p->y2 = MUL(SUB(SUB(x2, MUL(p->l6, p->y0)), MUL(p->l7, p->y1)), p->i8);
	p->best = p->second = inf;
	p->best_a = p->best_t = nan;
	p->bj = SET1I(0);
}

/* camspace.c's exact_candidate: the squared distance d and intensity a. */
INLINE void candidate(const lanes *p, V m0, V m1, V m2, V lo, V hi, V *d, V *a)
{
	V v0 = MUL(m0, p->i0);
	V v1 = MUL(SUB(m1, MUL(p->l3, v0)), p->i4);
	V v2 = MUL(SUB(SUB(m2, MUL(p->l6, v0)), MUL(p->l7, v1)), p->i8);
	V vv = ADD(ADD(MUL(v0, v0), MUL(v1, v1)), MUL(v2, v2));
	V vy = ADD(ADD(MUL(v0, p->y0), MUL(v1, p->y1)), MUL(v2, p->y2));
	*a = MIN(MAX(DIV(vy, vv), lo), hi);
	V e0 = SUB(p->y0, MUL(*a, v0));
	V e1 = SUB(p->y1, MUL(*a, v1));
	V e2 = SUB(p->y2, MUL(*a, v2));
	*d = ADD(ADD(MUL(e0, e0), MUL(e1, e1)), MUL(e2, e2));
}

/* A material's distance into out->d2 (NaN in refused lanes), then camspace.c's
 * fold_material: dj < best: second = best, best = dj; else dj < second: second = dj. */
INLINE void lanes_fold(lanes *l, const kg_cs_model *m, const kg_cs_block *out, size_t i,
                       int j, V dj, V aj, V tj)
{
	if (out->d2) {
		float v[VN];
		STOREU(v, SEL(l->ok, SET1(NAN), dj));
		for (int z = 0; z < VN; z++)
			out->d2[(i + (size_t)z) * (size_t)m->n + (size_t)j] = v[z];
	}
	M lt = LT(dj, l->best);
	l->second = SEL(lt, MIN(dj, l->second), l->best);
	l->best = MIN(dj, l->best);
	l->bj = SELI(lt, l->bj, SET1I(j));
	l->best_a = SEL(lt, l->best_a, aj);
	l->best_t = SEL(lt, l->best_t, tj);
}

/* camspace.c's store_pixel. With no lane to match, the materials were skipped: their
 * distances are the refusal's NaNs. */
INLINE void lanes_store(const lanes *p, const kg_cs_model *m, const kg_cs_block *out, size_t i,
                        int okbits)
{
	const V nan = SET1(NAN);
	if (!okbits && out->d2)
		for (size_t z = 0; z < (size_t)VN * (size_t)m->n; z++)
			out->d2[i * (size_t)m->n + z] = NAN;
	STORE_BYTES(out->best + i, SELI(p->ok, SET1I(KG_CS_NO_MATCH), p->bj));
	if (out->d2best)
		STOREU(out->d2best + i, SEL(p->ok, nan, p->best));
	if (out->d2second)
		STOREU(out->d2second + i, SEL(p->ok, nan, p->second));
	if (out->angle_deg)
		STOREU(out->angle_deg + i, SEL(p->ok, nan, p->best_t));
	if (out->scale)
		STOREU(out->scale + i, SEL(p->ok, nan, p->best_a));
}

/* KG_CS_EXACT: pixels i .. i + VN NV - 1. */
INLINE void exact_vectors(const kg_cs_model *m, const float *x, const float *cov, size_t i,
                          const kg_cs_block *out, const int NV)
{
	const V inf = SET1(INFINITY), nan = SET1(NAN);
	lanes p[2];
	int okbits = 0;
#pragma GCC unroll 2
	for (int q = 0; q < NV; q++) {
		lanes_init(&p[q], x + 3 * (i + VN * (size_t)q), cov + 6 * (i + VN * (size_t)q));
		okbits |= MBITS(p[q].ok);
	}
	const V lo = SET1((float)m->lo), hi = SET1((float)m->hi);
	const float *mu = m->muf;
	for (int j = 0; j < m->n && okbits; j++) {
		V dj[2], aj[2], tj[2];
#pragma GCC unroll 2
		for (int q = 0; q < NV; q++) {
			dj[q] = inf;
			aj[q] = tj[q] = nan;
		}
		for (int k = 0; k < m->nangles; k++, mu += 3) {
			V m0 = BCAST(mu), m1 = BCAST(mu + 1), m2 = BCAST(mu + 2), t = BCAST(m->anglef + k);
#pragma GCC unroll 2
			for (int q = 0; q < NV; q++) {
				V d, a;
				candidate(&p[q], m0, m1, m2, lo, hi, &d, &a);
				M lt = LT(d, dj[q]);
				dj[q] = MIN(d, dj[q]);
				aj[q] = SEL(lt, aj[q], a);
				tj[q] = SEL(lt, tj[q], t);
			}
		}
#pragma GCC unroll 2
		for (int q = 0; q < NV; q++)
			lanes_fold(&p[q], m, out, i + VN * (size_t)q, j, dj[q], aj[q], tj[q]);
	}
#pragma GCC unroll 2
	for (int q = 0; q < NV; q++)
		lanes_store(&p[q], m, out, i + VN * (size_t)q, okbits);
}

/* KG_CS_QUADRATIC's per-pixel terms (camspace.c's match_one_quad): Q = C^-1 and
 * b = Q x, in the order est_cs_quad_terms gives them for the model's component c. */
typedef struct quad {
	V t0, t1, t2, t3, t4, t5, t6, t7, t8;
} quad;

INLINE void quad_init(quad *q, const lanes *p, int c)
{
	V w00 = p->i0, w11 = p->i4, w22 = p->i8;
	V w10 = MUL(MUL(NEG(p->l3), w00), p->i4);
	V w21 = MUL(MUL(NEG(p->l7), w11), p->i8);
	V w20 = MUL(SUB(MUL(NEG(p->l6), w00), MUL(p->l7, w10)), p->i8);
	V q00 = FMA(w20, w20, FMA(w10, w10, MUL(w00, w00)));
	V q11 = FMA(w21, w21, MUL(w11, w11));
	V q22 = MUL(w22, w22);
	V q01 = FMA(w20, w21, MUL(w10, w11));
	V q02 = MUL(w20, w22);
	V q12 = MUL(w21, w22);
	V b0 = FMA(w20, p->y2, FMA(w10, p->y1, MUL(w00, p->y0)));
	V b1 = FMA(w21, p->y2, MUL(w11, p->y1));
	V b2 = MUL(w22, p->y2);
	/* Q_cc, Q_ii, Q_jj, Q_ij, Q_ci, Q_cj, b_c, b_i, b_j for the others i < j */
	if (c == 0)
		*q = (quad){q00, q11, q22, q12, q01, q02, b0, b1, b2};
	else if (c == 1)
		*q = (quad){q11, q00, q22, q02, q01, q12, b1, b0, b2};
	else
		*q = (quad){q22, q00, q11, q01, q02, q12, b2, b0, b1};
}

/* The chosen candidates' predictions and angles, lane by lane: from tab (each
 * material's values of mu0, mu1, mu2 and the angle, VN each, padded) by a permute
 * where the model has at most VN angles, else gathered from the model. */
INLINE void quad_pick(const kg_cs_model *m, const float *tab, int j, VI kj, V *m0, V *m1,
                      V *m2, V *t)
{
	if (tab) {
		const float *tj = tab + 4 * VN * (size_t)j;
		*m0 = PERMUTE(tj, kj);
		*m1 = PERMUTE(tj + VN, kj);
		*m2 = PERMUTE(tj + 2 * VN, kj);
		*t = PERMUTE(tj + 3 * VN, kj);
		return;
	}
	VI c = ADDI(kj, SET1I(j * m->nangles));
	VI c3 = ADDI(ADDI(c, c), c);
	*m0 = GATHER(m->muf, c3);
	*m1 = GATHER(m->muf + 1, c3);
	*m2 = GATHER(m->muf + 2, c3);
	*t = GATHER(m->anglef, kj);
}

/* quad_pick's table for the model (NULL, gathers, for more than VN angles or without
 * memory); free() it. */
static float *quad_table(const kg_cs_model *m)
{
	const int na = m->nangles;
	float *tab = na <= VN ? calloc((size_t)m->n * 4 * VN, sizeof(float)) : NULL;
	for (int j = 0; tab && j < m->n; j++)
		for (int k = 0; k < na; k++) {
			float *tj = tab + 4 * VN * (size_t)j;
			for (int c = 0; c < 3; c++)
				tj[c * VN + k] = m->muf[3 * ((size_t)j * na + k) + c];
			tj[3 * VN + k] = m->anglef[k];
		}
	return tab;
}

/* KG_CS_QUADRATIC: pixels i .. i + VN NV - 1. Per material, the angle of least
 * s = alpha ((alpha vv - vy) - vy) (match_one_quad), then that candidate exactly. */
INLINE void quad_vectors(const kg_cs_model *m, const float *tab, const float *x,
                         const float *cov, size_t i, const kg_cs_block *out, const int NV)
{
	const V inf = SET1(INFINITY), nan = SET1(NAN);
	lanes p[2];
	quad w[2];
	int okbits = 0;
#pragma GCC unroll 2
	for (int q = 0; q < NV; q++) {
		lanes_init(&p[q], x + 3 * (i + VN * (size_t)q), cov + 6 * (i + VN * (size_t)q));
		quad_init(&w[q], &p[q], m->ppc);
		okbits |= MBITS(p[q].ok);
	}
	const V lo = SET1((float)m->lo), hi = SET1((float)m->hi);
	const int na = m->nangles;
	for (int j = 0; j < m->n && okbits; j++) {
		const float *pp = m->ppf + KG_CS_PP * (size_t)j * na;
		V sj[2];
		VI kj[2];
#pragma GCC unroll 2
		for (int q = 0; q < NV; q++) {
			sj[q] = inf;
			kj[q] = SET1I(0);
		}
		VI kv = SET1I(0);
		for (int k = 0; k < na; k++, pp += KG_CS_PP, kv = ADDI(kv, SET1I(1))) {
#pragma GCC unroll 2
			for (int q = 0; q < NV; q++) {
				const quad *u = &w[q];
				V vv = FMA(u->t1, BCAST(pp), u->t0);
				vv = FMA(u->t2, BCAST(pp + 1), vv);
				vv = FMA(u->t3, BCAST(pp + 2), vv);
				vv = FMA(u->t4, BCAST(pp + 3), vv);
				vv = FMA(u->t5, BCAST(pp + 4), vv);
				V vy = FMA(u->t7, BCAST(pp + 5), u->t6);
				vy = FMA(u->t8, BCAST(pp + 6), vy);
				V a = MIN(MAX(DIV(vy, vv), BCAST(pp + 7)), BCAST(pp + 8));
				V s = MUL(a, SUB(FMS(a, vv, vy), vy));
				M lt = LT(s, sj[q]);
				sj[q] = MIN(s, sj[q]);
				kj[q] = SELI(lt, kj[q], kv);
			}
		}
#pragma GCC unroll 2
		for (int q = 0; q < NV; q++) {
			V m0, m1, m2, t, d, a;
			quad_pick(m, tab, j, kj[q], &m0, &m1, &m2, &t);
			candidate(&p[q], m0, m1, m2, lo, hi, &d, &a);
			/* the exact method's update from its start (INFINITY, NaN, NaN) */
			M fin = LT(d, inf);
			lanes_fold(&p[q], m, out, i + VN * (size_t)q, j, MIN(d, inf), SEL(fin, nan, a),
			           SEL(fin, nan, t));
		}
	}
#pragma GCC unroll 2
	for (int q = 0; q < NV; q++)
		lanes_store(&p[q], m, out, i + VN * (size_t)q, okbits);
}
