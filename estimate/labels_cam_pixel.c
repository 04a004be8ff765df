/* Camera-space label maps: the per-pixel compute (match, neutral-diffuse alternative,
 * unknown test, composition fit). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "labels_cam_private.h"

/* ---- composition -------------------------------------------------------------------- */

/* One pixel's composition fit: the metals' readings M (3 x 3, row-major, column j
 * metal j), the pixel's reading x and its inverse covariance Ci, and, for the active
 * sets of one and two metals, the normal equations G = M^T Ci M and h = M^T Ci x. */
typedef struct comp_fit {
	double M[9], x[3], Ci[9], G[9], h[3];
} comp_fit;

/* |x - M w|^2 in the metric Ci */
static double comp_residual(const comp_fit *f, const double w[3])
{
	double e[3], r = 0;
	for (int c = 0; c < 3; c++)
		e[c] = f->x[c] - f->M[3 * c] * w[0] - f->M[3 * c + 1] * w[1] - f->M[3 * c + 2] * w[2];
	for (int a = 0; a < 3; a++)
		r += e[a] * (f->Ci[3 * a] * e[0] + f->Ci[3 * a + 1] * e[1] + f->Ci[3 * a + 2] * e[2]);
	return r;
}

/* Least squares of x on one or two of the metals (the set `use`, bits; the others 0)
 * by Cramer's rule on their normal equations, the residual from the weights (not from
 * G and h, which cancel where the fit is near exact). +Inf when singular or a weight
 * is negative. */
static double fit_subset(const comp_fit *f, unsigned use, double w[3])
{
	int idx[3], k = 0;
	for (int j = 0; j < 3; j++) {
		w[j] = 0;
		if (use & (1u << j))
			idx[k++] = j;
	}
	const double *G = f->G, *h = f->h;
	double v[2];
	if (k == 1) {
		double g = G[4 * idx[0]];
		if (!(g > 1e-300))
			return INFINITY;
		v[0] = h[idx[0]] / g;
	} else {
		int a = idx[0], b = idx[1];
		double gaa = G[4 * a], gab = G[3 * a + b], gbb = G[4 * b];
		double det = gaa * gbb - gab * gab;
		if (!(det > 1e-300))
			return INFINITY;
		v[0] = (h[a] * gbb - h[b] * gab) / det;
		v[1] = (h[b] * gaa - h[a] * gab) / det;
	}
	for (int a = 0; a < k; a++) {
		if (!(v[a] >= 0))
			return INFINITY;
		w[idx[a]] = v[a];
	}
	return comp_residual(f, w);
}

/* One pixel's Ag, Cu, Au fractions at angle index k: x = sum_i w_i mu_i (the alloy
 * model is the fractions' weighted sum of the metals' reflectances, times the
 * intensity sum_i w_i), w >= 0, least squares in the metric of the pixel's inverse
 * covariance. Three readings and three weights: w = M^-1 x fits exactly, and where it
 * is >= 0 it is the answer; else the best of the six sets of one and two metals. The
 * Cramer-Rao standard deviations of the fractions come from the unconstrained Fisher
 * information's inverse, (M^T C^-1 M)^-1 = M^-1 C M^-T, through c = w / sum w. out: 3
 * fractions, 3 sds; NaN when nothing fits or the covariance is not positive
 * definite. */
void est_composition_pixel(const kg_cs_model *metals, int k, const float *xf,
                           const float *cf, float out[6])
{
	for (int i = 0; i < 6; i++)
		out[i] = NAN;
	double C[9] = {cf[0], cf[1], cf[2], cf[1], cf[3], cf[4], cf[2], cf[4], cf[5]};
	/* positive definite: every leading minor > 0 (Sylvester) */
	double det = C[0] * (C[4] * C[8] - C[5] * C[7]) + C[1] * (C[5] * C[6] - C[3] * C[8]) +
	             C[2] * (C[3] * C[7] - C[4] * C[6]);
	comp_fit f;
	if (!(C[0] > 0) || !(C[0] * C[4] - C[1] * C[1] > 0) || !(det > 0) ||
	    kg_mat3_inverse(C, f.Ci) != 0)
		return;
	f.x[0] = xf[0], f.x[1] = xf[1], f.x[2] = xf[2];
	for (int j = 0; j < 3; j++) {
		const double *mu = metals->mu + 3 * ((size_t)j * metals->nangles + k);
		for (int a = 0; a < 3; a++)
			f.M[3 * a + j] = mu[a];
	}
	double Mi[9], w[3] = {0}, best = INFINITY;
	int invertible = kg_mat3_inverse(f.M, Mi) == 0;
	if (invertible) {
		for (int a = 0; a < 3; a++)
			w[a] = Mi[3 * a] * f.x[0] + Mi[3 * a + 1] * f.x[1] + Mi[3 * a + 2] * f.x[2];
		if (w[0] >= 0 && w[1] >= 0 && w[2] >= 0)
			best = 0; /* exact */
	}
	if (!(best == 0)) {
		double CiM[9];
		for (int a = 0; a < 3; a++)
			for (int j = 0; j < 3; j++)
				CiM[3 * a + j] = f.Ci[3 * a] * f.M[j] + f.Ci[3 * a + 1] * f.M[3 + j] +
				                 f.Ci[3 * a + 2] * f.M[6 + j];
		for (int a = 0; a < 3; a++) {
			f.h[a] = CiM[a] * f.x[0] + CiM[3 + a] * f.x[1] + CiM[6 + a] * f.x[2];
			for (int b = a; b < 3; b++)
				f.G[3 * a + b] = f.G[3 * b + a] =
					f.M[a] * CiM[b] + f.M[3 + a] * CiM[3 + b] + f.M[6 + a] * CiM[6 + b];
		}
		w[0] = w[1] = w[2] = 0;
		for (unsigned use = 1; use < 7; use++) {
			double t[3];
			double r = fit_subset(&f, use, t);
			if (r < best) {
				best = r;
				memcpy(w, t, sizeof(w));
			}
		}
	}
	double sum = w[0] + w[1] + w[2];
	if (!isfinite(best) || !(sum > 0))
		return;
	/* Fi = M^-1 C M^-T; J = (I - c 1^T) / sum, row i (e_i - c_i 1) / sum:
	 * J_i Fi J_i^T = (Fi_ii - 2 c_i r_i + c_i^2 t) / sum^2, r = Fi 1, t = 1^T Fi 1 */
	double Fi[9], MC[9], r[3], t = 0;
	if (invertible) {
		for (int a = 0; a < 3; a++)
			for (int b = 0; b < 3; b++)
				MC[3 * a + b] = Mi[3 * a] * C[b] + Mi[3 * a + 1] * C[3 + b] +
				                Mi[3 * a + 2] * C[6 + b];
		for (int a = 0; a < 3; a++)
			for (int b = a; b < 3; b++)
				Fi[3 * a + b] = Fi[3 * b + a] = MC[3 * a] * Mi[3 * b] +
				                                MC[3 * a + 1] * Mi[3 * b + 1] +
				                                MC[3 * a + 2] * Mi[3 * b + 2];
		for (int a = 0; a < 3; a++) {
			r[a] = Fi[3 * a] + Fi[3 * a + 1] + Fi[3 * a + 2];
			t += r[a];
		}
	}
	for (int i = 0; i < 3; i++) {
		double c = w[i] / sum;
		out[i] = (float)c;
		if (!invertible)
			continue;
		double v = (Fi[4 * i] - 2.0 * c * r[i] + c * c * t) / (sum * sum);
		out[3 + i] = (float)sqrt(v > 0 ? v : 0);
	}
}

/* The neutral-diffuse alternative: min over s > 0 of (x - s w)^T C^-1 (x - s w), w the
 * reading of a flat reflectance of 1 (any level: a grey card, paper, cloth); +Inf where
 * C is not positive definite or the best level is not positive. */
static double neutral_d2(const double w[3], const float *xf, const float *cf)
{
	double C[9] = {cf[0], cf[1], cf[2], cf[1], cf[3], cf[4], cf[2], cf[4], cf[5]}, Ci[9];
	if (!(C[0] > 0) || kg_mat3_inverse(C, Ci) != 0)
		return INFINITY;
	double x[3] = {xf[0], xf[1], xf[2]}, Cw[3], Cx[3];
	for (int a = 0; a < 3; a++) {
		Cw[a] = Ci[3 * a] * w[0] + Ci[3 * a + 1] * w[1] + Ci[3 * a + 2] * w[2];
		Cx[a] = Ci[3 * a] * x[0] + Ci[3 * a + 1] * x[1] + Ci[3 * a + 2] * x[2];
	}
	double ww = w[0] * Cw[0] + w[1] * Cw[1] + w[2] * Cw[2];
	double wx = x[0] * Cw[0] + x[1] * Cw[1] + x[2] * Cw[2];
	double xx = x[0] * Cx[0] + x[1] * Cx[1] + x[2] * Cx[2];
	if (!(ww > 0) || !(wx > 0) || !(xx > 0))
		return INFINITY;
	double d = xx - wx * wx / ww;
	return d > 0 ? d : 0;
}

/* exp(arg), with the arguments whose exp is 0 in double (below -745.2) answered without
 * libm's underflow path: most materials' weights in a posterior are these. */

void lc_cam_compute(void *user, void *inbuf, size_t n, uint8_t *labels, float *conf,
                        uint8_t *mask, uint64_t *nonfinite, uint64_t *clipped)
{
	const cam_run *r = user;
	planes pl = ap_feed_planes(&r->in, inbuf, n);
	cam_planes cp = lc_cam_planes_of(r, inbuf, n);
	const float c0 = r->in.clip3[0], c1 = r->in.clip3[1], c2 = r->in.clip3[2];
	/* Pixels refused before matching (masked out, flagged, dark) are labelled here;
	 * the others are packed to the front of x and cov (their indices in idx, which
	 * borrows the posterior plane), matched, and their results spread back. */
	uint32_t *idx = (uint32_t *)cp.post;
	uint8_t *best = (uint8_t *)cp.best; /* bytes, at the front of its plane */
	size_t m = 0;
	for (size_t i = 0; i < n; i++) {
		const float *px = pl.raw + 3 * i;
		if (!isfinite(px[0]) || !isfinite(px[1]) || !isfinite(px[2])) {
			mask[i] = KG_EST_MASK_NONFINITE;
			++*nonfinite;
		} else if (px[0] >= c0 || px[1] >= c1 || px[2] >= c2) {
			mask[i] = KG_EST_MASK_CLIPPED;
			++*clipped;
		} else {
			mask[i] = 0;
		}
		cp.fshare[i] = 0.0f;
		if (pl.mask && pl.mask[i] == 0.0f)
			labels[i] = r->background;
		else if (mask[i])
			labels[i] = KG_EST_LABEL_NONE;
		else if (fmaxf(px[0], fmaxf(px[1], px[2])) < r->background_level)
			labels[i] = r->background;
		else {
			double x[3], c[6];
			lc_pixel_noise(&r->nz, px, pl.var ? pl.var + 3 * i : NULL, x, c);
			for (int a = 0; a < 3; a++)
				cp.x[3 * m + a] = (float)x[a];
			for (int e = 0; e < 6; e++)
				cp.cov[6 * m + e] = (float)c[e];
			/* l^2 / tr(C): times a relative variance's trace, its share of the
			 * pixel's noise */
			double tot = c[0] + c[3] + c[5];
			double lev = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) / 3.0;
			cp.fshare[i] = tot > 0 && isfinite(tot) ? (float)(lev / tot) : 0.0f;
			labels[i] = 0xff; /* to be matched */
			idx[m++] = (uint32_t)i;
		}
		conf[i] = NAN;
	}
	kg_cs_block out = {best, NULL, NULL, cp.angle, cp.scale, cp.d2};
	kg_cs_match_block(r->model, cp.x, cp.cov, m, &out);
	const int nm = r->nm;
	/* The neutral-diffuse alternative (x, cov and the match still packed). It is not
	 * offered where the best material is a metal or an alloy whose own prediction (at
	 * its fitted angle and intensity) is itself within the unknown bound of a flat
	 * spectrum at this pixel's noise: a near-neutral metal (silver, a silvery alloy)
	 * and a grey surface as bright are not told apart by colour, and the pixel stays
	 * the metal's (or unknown). A dielectric's near-neutral part is its surface
	 * reflection, which a card shares: there the distances decide. */
	for (size_t k = 0; k < m; k++) {
		double d = INFINITY;
		int near = 0;
		if (r->neutral && best[k] != KG_CS_NO_MATCH && r->metal[best[k]]) {
			const kg_cs_model *md = r->model;
			double step = md->nangles > 1 ? md->angle_deg[1] - md->angle_deg[0] : 1.0;
			int ka = (int)lround((cp.angle[k] - md->angle_deg[0]) / step);
			ka = ka < 0 ? 0 : ka >= md->nangles ? md->nangles - 1 : ka;
			const double *mu = md->mu + 3 * ((size_t)best[k] * md->nangles + ka);
			float pred[3];
			for (int a = 0; a < 3; a++)
				pred[a] = (float)(cp.scale[k] * mu[a]);
			near = neutral_d2(r->white, pred, cp.cov + 6 * k) <= r->threshold;
		}
		if (r->neutral && !near)
			d = neutral_d2(r->white, cp.x + 3 * k, cp.cov + 6 * k);
		cp.flat[idx[k]] = (float)d;
	}
	for (size_t k = m; k-- > 0;) { /* idx[k] >= k: from the back, nothing is overwritten early */
		size_t i = idx[k];
		if (i == k)
			continue;
		best[i] = best[k];
		cp.angle[i] = cp.angle[k];
		cp.scale[i] = cp.scale[k];
		memmove(cp.d2 + i * (size_t)nm, cp.d2 + k * (size_t)nm, sizeof(float) * (size_t)nm);
	}
	/* composition of the pixels whose best material is made of silver, copper and gold,
	 * at its fitted angle (x and cov are still packed; idx still holds the pixels) */
	for (size_t i = 0; i < 6 * n; i++)
		cp.comp[i] = NAN;
	for (size_t k = 0; r->metals && k < m; k++) {
		size_t i = idx[k];
		if (best[i] == KG_CS_NO_MATCH || !r->comp_ok[best[i]])
			continue;
		const kg_cs_model *md = r->model;
		double step = md->nangles > 1 ? md->angle_deg[1] - md->angle_deg[0] : 1.0;
		int ka = (int)lround((cp.angle[i] - md->angle_deg[0]) / step);
		ka = ka < 0 ? 0 : ka >= r->metals->nangles ? r->metals->nangles - 1 : ka;
		est_composition_pixel(r->metals, ka, cp.x + 3 * k, cp.cov + 6 * k, cp.comp + 6 * i);
	}
	for (size_t i = 0; i < n; i++) {
		const float *d2 = cp.d2 + i * (size_t)nm;
		if (labels[i] != 0xff) {
			cp.post[i] = cp.angle[i] = cp.scale[i] = NAN;
			continue;
		}
		if (best[i] == KG_CS_NO_MATCH && cp.flat[i] <= r->threshold) {
			labels[i] = r->background; /* a flat spectrum explains it, no material does */
			cp.post[i] = cp.angle[i] = cp.scale[i] = NAN;
			continue;
		}
		if (best[i] == KG_CS_NO_MATCH) {
			labels[i] = r->unknown;
			cp.post[i] = cp.angle[i] = cp.scale[i] = NAN;
			continue;
		}
		/* classes: the least distance of their members */
		double dc[KG_EST_MAX_MATERIALS], dmin = INFINITY;
		for (int c = 0; c < r->nc; c++)
			dc[c] = INFINITY;
		for (int j = 0; j < nm; j++) {
			double d = d2[j];
			if (d < dc[r->group[j]])
				dc[r->group[j]] = d;
			if (d < dmin)
				dmin = d;
		}
		int cb = r->group[best[i]];
		double second = INFINITY, sum = 0, mine = 0;
		for (int c = 0; c < r->nc; c++)
			if (c != cb && dc[c] < second)
				second = dc[c];
		for (int j = 0; j < nm; j++) {
			double w = exp_or_zero(-0.5 * (d2[j] - dmin));
			sum += w;
			if (r->group[j] == cb)
				mine += w;
		}
		if (cp.flat[i] <= r->threshold &&
		    (dmin > r->threshold || cp.flat[i] + NEUTRAL_MARGIN < dmin)) {
			/* a flat spectrum explains the pixel and fits clearly better than every
			 * material (or no material fits): a neutral diffuse surface (grey card,
			 * paper, cloth), not the nearest material */
			labels[i] = r->background;
			cp.post[i] = cp.angle[i] = cp.scale[i] = NAN;
			for (int e = 0; e < 6; e++)
				cp.comp[6 * i + e] = NAN;
		} else if (dmin > r->threshold) {
			labels[i] = r->unknown;
			cp.post[i] = cp.angle[i] = cp.scale[i] = NAN;
			for (int e = 0; e < 6; e++)
				cp.comp[6 * i + e] = NAN;
		} else {
			labels[i] = (uint8_t)(cb + 1);
			conf[i] = (float)(second - dmin);
			cp.post[i] = (float)(mine / sum);
		}
	}
}
