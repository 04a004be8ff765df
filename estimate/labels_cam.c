/* Camera-space label maps: kg_classify_camera_rows.
 *
 * Each pixel's site reading rho is mapped into the reference camera's space, x = M2 rho,
 * with the covariance
 *   C = M2 diag(v) M2^T + l^2 R,   l^2 = |x|^2 / 3,
 * v the noise of the pixel's channels (the variance image over the frames averaged, or
 * the noise model) and R the calibration residual's relative covariance (what M2 leaves
 * of the chart, per squared level). camspace.c matches x against every declared material
 * over the angles and intensities (kg_cs_match_block).
 *
 * Before the run a survey pass (a second reading of the image and its variance) finds
 * the capture's noise: the mean C over the pixels that will be classified, at their
 * mean level. At that noise kg_cs_separability gives every pair's distance; pairs
 * closer than the merge distance are one compound class "a|b", and the label map holds
 * classes, not materials: no per-pixel distinction is written that the noise cannot
 * support.
 *
 * Regions: connected components (4-neighbours) of the per-pixel classes, found while
 * the rows stream past (union-find over the runs of each row, with each run's sums of
 * the materials' distances), or the ids of a user region map. Each region is decided on
 * its pooled likelihood, sum over its pixels of every material's d2. The calibration's
 * part of the noise is the same error in every pixel and does not average out: with f
 * its share of a pixel's variance, N pixels weigh as N / (1 + N f) independent ones, so
 * the pooled differences are scaled by 1 / (1 + N f). A compound class resolves into
 * one material where that material's share of the class's pooled posterior is 0.99 or
 * more. The region's "unknown" test adds the decided material's own model error (its
 * model_rsd: the spread of published optical constants, the alloy rule, a template's
 * scatter), also one error for the whole region, to f. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "apply_private.h"

#define MAX_PROVISIONAL (1 << 20) /* runs of the union-find; above, no regions */
#define MAX_USER_REGIONS 65536
#define RESOLVE_POSTERIOR 0.99
#define TABLE_MIN_PIXELS 100 /* regions listed in LABELS.json */
/* The neutral-diffuse alternative takes a pixel a material also fits only when its d2
 * is less by this (a likelihood ratio of e^0.5 = 1.65 in its favour). A material that
 * fits about as well keeps the pixel: black lacquer at grazing incidence is mostly its
 * neutral surface reflection. Measured (docs/estimate.md): a margin of 0 gives 994 of
 * the 2303 urushi dome pixels of apply-classify-camera to background, 1 gives 11, 2
 * gives 4; of a 20 % grey card's pixels under the noise model (no variance image)
 * 99.4 %, 98.5 %, 95.2 % read background, 67 % at 4, 11 % at 6.63. */
#define NEUTRAL_MARGIN 1.0

int kg_class_holds(const char *cls, const char *m)
{
	size_t lm = strlen(m);
	for (const char *p = cls; p && *p;) {
		const char *bar = strchr(p, '|');
		size_t len = bar ? (size_t)(bar - p) : strlen(p);
		if (len == lm && strncmp(p, m, lm) == 0)
			return 1;
		p = bar ? bar + 1 : NULL;
	}
	return 0;
}

void kg_classify_camera_init(kg_classify_camera *c)
{
	memset(c, 0, sizeof(*c));
	for (int i = 0; i < 3; i++)
		c->site_to_ref[4 * i] = 1.0;
	c->angle_from = 0;
	c->angle_to = 70;
	c->angle_step = 5;
	c->intensity_lo = 0.3;
	c->intensity_hi = 1.0;
	c->merge_distance = 0;
	c->regions = 1;
}

/* ---- the per-pixel noise ------------------------------------------------------------ */

typedef struct noise {
	double M2[9], R[9];
	double P[6][3]; /* M2[a][ch] M2[b][ch] for the covariance's 6 entries (a, b) */
	double inv_frames, floor2, rel2;
} noise;

static const int cov_ia[6] = {0, 0, 0, 1, 1, 2}, cov_ib[6] = {0, 1, 2, 1, 2, 2};

/* nz->P from nz->M2 */
static void noise_products(noise *nz)
{
	for (int e = 0; e < 6; e++)
		for (int ch = 0; ch < 3; ch++)
			nz->P[e][ch] = nz->M2[3 * cov_ia[e] + ch] * nz->M2[3 * cov_ib[e] + ch];
}

/* The variances v of a site reading's channels and x = M2 rho; returns l^2 = |x|^2 / 3.
 * The covariance of x is linear in v and l^2: c = sum_ch P[.][ch] v[ch] + l^2 R. */
static double pixel_parts(const noise *nz, const float *rho, const float *var, double x[3],
                          double v[3])
{
	for (int ch = 0; ch < 3; ch++) {
		double r = rho[ch] > 0.0f ? rho[ch] : 0.0;
		v[ch] = var ? var[ch] * nz->inv_frames : nz->floor2 + nz->rel2 * r * r;
	}
	for (int a = 0; a < 3; a++)
		x[a] = nz->M2[3 * a] * rho[0] + nz->M2[3 * a + 1] * rho[1] + nz->M2[3 * a + 2] * rho[2];
	return (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) / 3.0;
}

/* x = M2 rho and its covariance (6 values) in double. */
static void pixel_noise(const noise *nz, const float *rho, const float *var, double x[3],
                        double c[6])
{
	double v[3];
	double l2 = pixel_parts(nz, rho, var, x, v);
	for (int e = 0; e < 6; e++) {
		double s = 0;
		for (int ch = 0; ch < 3; ch++)
			s += nz->P[e][ch] * v[ch];
		c[e] = s + l2 * nz->R[3 * cov_ia[e] + cov_ib[e]];
	}
}


/* ---- the run ---------------------------------------------------------------------------- */

typedef struct cam_run {
	const kg_cs_model *model;
	noise nz;
	feed in;
	size_t base;  /* floats per pixel the feed writes */
	int nm, nc;   /* materials, classes */
	int group[KG_EST_MAX_MATERIALS];   /* material -> class index */
	double threshold;                  /* unknown above; +Inf: no test */
	double model_tr[KG_EST_MAX_MATERIALS]; /* the materials' model relative variances */
	int dof;                           /* of a pixel's d2 */
	/* composition: the pure metals' readings (silver, copper, gold) at the model's
	 * angles, and which materials are made of them */
	const kg_cs_model *metals; /* NULL: no composition */
	uint8_t comp_ok[KG_EST_MAX_MATERIALS];
	double gold_range;         /* of the declared Ag-Cu-Au materials' gold fractions */
	float background_level;
	uint8_t unknown, background;
	int neutral;      /* the neutral-diffuse alternative is on */
	uint8_t metal[KG_EST_MAX_MATERIALS]; /* the material is a metal or an alloy */
	double white[3];  /* its reading: F times a flat reflectance of 1 */
} cam_run;

/* The extra planes after the feed's, per block of n pixels. */
typedef struct cam_planes {
	float *x, *cov, *post, *angle, *scale, *best, *fshare, *comp, *flat, *d2;
} cam_planes;

static size_t extra_floats(int nm) { return 3 + 6 + 5 + 6 + 1 + (size_t)nm; }

static cam_planes cam_planes_of(const cam_run *r, void *in, size_t n)
{
	float *p = (float *)in + r->base * n;
	cam_planes c;
	c.x = p;
	c.cov = p + 3 * n;
	c.post = p + 9 * n;
	c.angle = p + 10 * n;
	c.scale = p + 11 * n;
	c.best = p + 12 * n;
	c.fshare = p + 13 * n; /* l^2 / tr(C): a systematic term's share per unit trace */
	c.comp = p + 14 * n;   /* 6 per pixel: Ag, Cu, Au fractions, their sds */
	c.flat = p + 20 * n;   /* the neutral-diffuse alternative's d2 */
	c.d2 = p + 21 * n;
	return c;
}

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
static inline double exp_or_zero(double arg) { return arg <= -750.0 ? 0.0 : exp(arg); }

static void cam_compute(void *user, void *inbuf, size_t n, uint8_t *labels, float *conf,
                        uint8_t *mask, uint64_t *nonfinite, uint64_t *clipped)
{
	const cam_run *r = user;
	planes pl = ap_feed_planes(&r->in, inbuf, n);
	cam_planes cp = cam_planes_of(r, inbuf, n);
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
			pixel_noise(&r->nz, px, pl.var ? pl.var + 3 * i : NULL, x, c);
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

/* ---- regions ----------------------------------------------------------------------- */

typedef struct run_seg {
	int x0, x1; /* inclusive */
	uint32_t id;
	uint8_t label;
} run_seg;

typedef struct regions {
	int on, overflow, user;
	double user_scale; /* a user map's values to region numbers */
	const char *user_name; /* its file, for messages */
	int dof;           /* of a pixel's d2 */
	int nm;
	/* union-find over provisional ids (connected components) or user ids */
	uint32_t *parent;
	uint8_t *label;
	uint64_t *count;
	double *d2;        /* nm per id */
	double *f_sum;     /* l^2 / tr(C) of the pixels, summed */
	double cal_tr;     /* the calibration residual's relative covariance: its trace */
	const double *model_tr; /* per material, its model's relative covariance's trace */
	double *comp;      /* 6 per id: sum of c / sd^2 and of 1 / sd^2 for Ag, Cu, Au */
	uint32_t n, cap;
	run_seg *prev, *cur;
	int nprev, ncur, width;
	/* after the run */
	uint32_t *final;   /* id -> region number (1-based), 0 none */
	uint32_t nfinal;
	double *q999;      /* 1001: chi-square's 99.9 % point by degrees of freedom; 0: not
	                      yet computed */
} regions;

static void regions_free(regions *g)
{
	free(g->parent);
	free(g->label);
	free(g->count);
	free(g->d2);
	free(g->f_sum);
	free(g->comp);
	free(g->prev);
	free(g->cur);
	free(g->final);
	free(g->q999);
	memset(g, 0, sizeof(*g));
}

static int regions_grow(regions *g, uint32_t need, kg_err *err)
{
	if (need <= g->cap)
		return 0;
	uint32_t cap = g->cap ? g->cap : 4096;
	while (cap < need)
		cap *= 2;
	uint32_t *p = realloc(g->parent, sizeof(uint32_t) * cap);
	if (p)
		g->parent = p;
	uint8_t *l = realloc(g->label, cap);
	if (l)
		g->label = l;
	uint64_t *c = realloc(g->count, sizeof(uint64_t) * cap);
	if (c)
		g->count = c;
	double *d = realloc(g->d2, sizeof(double) * (size_t)cap * (size_t)g->nm);
	if (d)
		g->d2 = d;
	double *f = realloc(g->f_sum, sizeof(double) * cap);
	if (f)
		g->f_sum = f;
	double *cm = realloc(g->comp, sizeof(double) * 6 * cap);
	if (cm)
		g->comp = cm;
	if (!p || !l || !c || !d || !f || !cm)
		return kg_fail(err, KG_ENOMEM, "classify: out of memory for the regions");
	g->cap = cap;
	return 0;
}

static uint32_t find_root(uint32_t *parent, uint32_t a)
{
	while (parent[a] != a) {
		parent[a] = parent[parent[a]];
		a = parent[a];
	}
	return a;
}

static void unite(regions *g, uint32_t a, uint32_t b)
{
	a = find_root(g->parent, a);
	b = find_root(g->parent, b);
	if (a < b)
		g->parent[b] = a;
	else if (b < a)
		g->parent[a] = b;
}

static uint32_t new_id(regions *g, uint8_t label)
{
	uint32_t id = g->n++;
	g->parent[id] = id;
	g->label[id] = label;
	g->count[id] = 0;
	g->f_sum[id] = 0;
	memset(g->comp + 6 * (size_t)id, 0, 6 * sizeof(double));
	memset(g->d2 + (size_t)id * g->nm, 0, sizeof(double) * (size_t)g->nm);
	return id;
}

/* The runs of one row of labels (classes 1..nc only), each given a provisional id when
 * assign is set (pass 1) or in the same order again (pass 2). */
static int row_runs(const uint8_t *lab, int width, int nc, run_seg *out)
{
	int n = 0;
	for (int x = 0; x < width;) {
		uint8_t l = lab[x];
		int x1 = x;
		while (x1 + 1 < width && lab[x1 + 1] == l)
			x1++;
		if (l >= 1 && l <= nc)
			out[n++] = (run_seg){x, x1, 0, l};
		x = x1 + 1;
	}
	return n;
}

/* Link the current row's runs to the previous row's (ids given in order from *next). */
static void link_rows(regions *g, run_seg *cur, int ncur, const run_seg *prev, int nprev,
                      int assign)
{
	int p = 0;
	for (int i = 0; i < ncur; i++) {
		if (assign)
			cur[i].id = new_id(g, cur[i].label);
		else
			cur[i].id = g->n++;
		while (p < nprev && prev[p].x1 < cur[i].x0)
			p++;
		for (int q = p; q < nprev && prev[q].x0 <= cur[i].x1; q++)
			if (prev[q].label == cur[i].label && assign)
				unite(g, cur[i].id, prev[q].id);
	}
}

/* A pixel's composition into a region's sums (inverse-variance weights). */
static void add_comp(double *acc, const float *c)
{
	for (int q = 0; q < 3; q++) {
		double sd = c[3 + q];
		if (!isfinite(c[q]) || !isfinite(sd))
			continue;
		double w = 1.0 / (sd > 1e-6 ? sd * sd : 1e-12);
		acc[q] += w * c[q];
		acc[3 + q] += w;
	}
}

/* Pass 1, one row: its runs, their unions, and each pixel's distances added to its
 * run's sums. */
static int regions_row(regions *g, const uint8_t *lab, const float *d2, const float *fshare,
                       const float *comp, int nc, kg_err *err)
{
	if (!g->on || g->overflow)
		return 0;
	g->ncur = row_runs(lab, g->width, nc, g->cur);
	if (g->n + (uint32_t)g->ncur > MAX_PROVISIONAL) {
		g->overflow = 1;
		return 0;
	}
	int rc = regions_grow(g, g->n + (uint32_t)g->ncur, err);
	if (rc)
		return rc;
	link_rows(g, g->cur, g->ncur, g->prev, g->nprev, 1);
	for (int i = 0; i < g->ncur; i++) {
		run_seg *s = &g->cur[i];
		double *acc = g->d2 + (size_t)s->id * g->nm;
		for (int x = s->x0; x <= s->x1; x++) {
			const float *d = d2 + (size_t)x * g->nm;
			for (int j = 0; j < g->nm; j++)
				acc[j] += d[j];
			g->f_sum[s->id] += fshare[x];
			add_comp(g->comp + 6 * (size_t)s->id, comp + 6 * (size_t)x);
		}
		g->count[s->id] += (uint64_t)(s->x1 - s->x0 + 1);
	}
	run_seg *t = g->prev;
	g->prev = g->cur;
	g->cur = t;
	g->nprev = g->ncur;
	return 0;
}

/* User regions: ids straight from the map. */
static int regions_user_row(regions *g, int y, const float *ids, const uint8_t *lab,
                            const float *d2, const float *fshare, const float *comp, int nc,
                            kg_err *err)
{
	for (int x = 0; x < g->width; x++) {
		double v = ids[x] * g->user_scale, rv = floor(v + 0.5);
		if (!(rv >= 0 && rv < MAX_USER_REGIONS) || fabs(v - rv) > 1e-3)
			return kg_fail(err, KG_EINVAL, "%s: pixel (%d, %d) holds %g: expected a whole "
			               "region number from 0 (none) to %d",
			               g->user_name ? g->user_name : "the region map", x, y, v,
			               MAX_USER_REGIONS - 1);
		uint32_t id = (uint32_t)rv;
		if (!id || lab[x] < 1 || lab[x] > nc)
			continue;
		double *acc = g->d2 + (size_t)id * g->nm;
		const float *d = d2 + (size_t)x * g->nm;
		for (int j = 0; j < g->nm; j++)
			acc[j] += d[j];
		g->f_sum[id] += fshare[x];
		add_comp(g->comp + 6 * (size_t)id, comp + 6 * (size_t)x);
		g->count[id]++;
	}
	return 0;
}

/* Roots' sums, and region numbers in order of first appearance. */
static int regions_resolve(regions *g, kg_err *err)
{
	if (!(g->final = calloc(g->n ? g->n : 1, sizeof(uint32_t))))
		return kg_fail(err, KG_ENOMEM, "classify: out of memory for the regions");
	if (!g->user)
		for (uint32_t id = 0; id < g->n; id++) {
			uint32_t r = find_root(g->parent, id);
			if (r == id)
				continue;
			g->count[r] += g->count[id];
			g->f_sum[r] += g->f_sum[id];
			for (int q = 0; q < 6; q++)
				g->comp[6 * (size_t)r + q] += g->comp[6 * (size_t)id + q];
			for (int j = 0; j < g->nm; j++)
				g->d2[(size_t)r * g->nm + j] += g->d2[(size_t)id * g->nm + j];
			g->count[id] = 0;
		}
	for (uint32_t id = 0; id < g->n; id++)
		if (g->count[id] && (g->user || find_root(g->parent, id) == id)) {
			++g->nfinal;
			g->final[id] = g->user ? id : g->nfinal; /* a user map keeps its numbers */
		}
	return 0;
}

/* A region's decision (see the top of the file). */
typedef struct region_decision {
	int unknown;     /* no declared material explains the region */
	int cls;         /* class index */
	int material;    /* the material it resolves to, or -1 (the compound class) */
	double posterior;
	double d2_mean;  /* the decided label's pooled distance per pixel */
} region_decision;

static region_decision decide(const regions *g, uint32_t id, const int *group, int nc)
{
	const double *D = g->d2 + (size_t)id * g->nm;
	double N = (double)g->count[id], lev = g->f_sum[id] / N;
	/* the comparison between materials: the calibration's error is one error for the
	 * whole region */
	double s = 1.0 / (1.0 + N * lev * g->cal_tr);
	double dmin = INFINITY, pc[KG_EST_MAX_MATERIALS] = {0}, sum = 0, w[KG_EST_MAX_MATERIALS];
	for (int j = 0; j < g->nm; j++)
		dmin = fmin(dmin, D[j]);
	for (int j = 0; j < g->nm; j++) {
		w[j] = exp_or_zero(-0.5 * s * (D[j] - dmin));
		sum += w[j];
		pc[group[j]] += w[j];
	}
	region_decision r = {0, 0, -1, 0, 0};
	for (int c = 1; c < nc; c++)
		if (pc[c] > pc[r.cls])
			r.cls = c;
	int jbest = -1, members = 0;
	for (int j = 0; j < g->nm; j++)
		if (group[j] == r.cls) {
			members++;
			if (jbest < 0 || w[j] > w[jbest])
				jbest = j;
		}
	r.posterior = pc[r.cls] / sum;
	if (members == 1 || w[jbest] / pc[r.cls] >= RESOLVE_POSTERIOR) {
		r.material = jbest;
		r.posterior = w[jbest] / sum;
	}
	r.d2_mean = D[jbest] / N;
	/* the pooled unknown test: the decided member's summed d2 against chi-square with
	 * dof N s degrees of freedom (its 99.9 % point; Wilson-Hilferty above 1000), s
	 * now with the material's own model error beside the calibration's: both are one
	 * error for the whole region. (The model error is left out of the comparison
	 * between materials: the published constants' spread moves the predictions of
	 * every material made of the same metals together.) */
	s = 1.0 / (1.0 + N * lev * (g->cal_tr + (g->model_tr ? g->model_tr[jbest] : 0.0)));
	double dof = ceil(g->dof * N * s), q;
	if (dof <= 1000) {
		/* one bisection per degree of freedom, not per region */
		double *qc = &g->q999[(int)dof];
		if (!(*qc > 0))
			*qc = kg_chi2_quantile(0.999, (int)dof);
		q = *qc;
	}
	else {
		double h = 2.0 / (9.0 * dof), z = 3.090232306167813;
		q = dof * pow(1.0 - h + z * sqrt(h), 3.0);
	}
	r.unknown = s * D[jbest] > q;
	return r;
}

/* A region's composition: inverse-variance means of its pixels' fractions, their sds
 * widened by sqrt(1 + N f) (the calibration's error does not average out). out: 3
 * fractions, 3 sds, NaN without data; gold NaN where its sd is not below gold_range. */
static void region_composition(const regions *g, uint32_t id, double gold_range, double out[6])
{
	const double *a = g->comp + 6 * (size_t)id;
	double N = (double)g->count[id], f = g->f_sum[id] / N * g->cal_tr;
	for (int q = 0; q < 3; q++) {
		out[q] = a[3 + q] > 0 ? a[q] / a[3 + q] : NAN;
		out[3 + q] = a[3 + q] > 0 ? sqrt((1.0 + N * f) / a[3 + q]) : NAN;
	}
	if (!(out[5] < gold_range))
		out[2] = NAN;
}

static const char *region_label(const region_decision *d, const kg_est_material_set *set,
                                const kg_est_material_set *classes)
{
	return d->unknown ? "unknown" : d->material >= 0 ? set->names[d->material]
	                                                 : classes->names[d->cls];
}

/* A connected region's pixels' class beside its decision, and why they differ:
 * "pixel_class", "differs", "why" (null when they agree). The label map shows the
 * pixels' classes; the decision is the table's. */
static void region_why(json_t *row, const regions *g, uint32_t id, const region_decision *d,
                       const char *label, const kg_est_material_set *classes)
{
	if (g->user || g->label[id] == 0 || g->label[id] > classes->n)
		return;
	const char *px = classes->names[g->label[id] - 1];
	int differs = strcmp(px, label) != 0;
	char why[320];
	if (!differs)
		why[0] = 0;
	else if (d->unknown)
		snprintf(why, sizeof(why), "refused as unknown on the pooled test: its pixels' mean "
		         "d2 against the nearest material is %.2f (%d expected), a misfit that, "
		         "pooled over %llu pixels, exceeds the bound; each pixel alone reads %s",
		         d->d2_mean, g->dof, (unsigned long long)g->count[id], px);
	else if (kg_class_holds(px, label))
		snprintf(why, sizeof(why), "resolved: the pooled pixels single out %s within the "
		         "merged class %s (its share of the class's posterior >= %.2f)", label, px,
		         RESOLVE_POSTERIOR);
	else
		snprintf(why, sizeof(why), "the pooled likelihood of its pixels prefers %s to %s, "
		         "which each pixel alone reads", label, px);
	json_object_set_new(row, "pixel_class", json_string(px));
	json_object_set_new(row, "differs", json_boolean(differs));
	json_object_set_new(row, "why", differs ? json_string(why) : json_null());
}

/* ---- the sink -------------------------------------------------------------------- */

typedef struct cam_sink {
	kg_envi_writer *labels, *conf, *mask, *comp;
	staging stage;
	progress prog;
	const cam_run *run;
	const kg_row_source *region_map;
	float *region_row;
	int nclasses;
	uint64_t count[KG_EST_MAX_MATERIALS + 3];
	class_stats *cs;
	uint8_t *preview;
	int pw, ph, next_py, height;
	float *conf4;   /* a block's 4 bands, BIP */
	size_t conf4_cap;
	regions reg;
} cam_sink;

static int cam_sink_fn(void *user, const kg_est_block *b, kg_err *err)
{
	cam_sink *s = user;
	const cam_run *r = s->run;
	size_t n = (size_t)b->rows * b->width;
	uint8_t *lab = (uint8_t *)b->data;
	const float *margin = b->confidence;
	planes pl = ap_feed_planes(&r->in, b->input, n);
	cam_planes cp = cam_planes_of(r, (void *)b->input, n);
	if (n > s->conf4_cap) {
		float *c = realloc(s->conf4, sizeof(float) * 4 * n);
		if (!c)
			return kg_fail(err, KG_ENOMEM, "classify: out of memory");
		s->conf4 = c;
		s->conf4_cap = n;
	}
	for (size_t i = 0; i < n; i++) {
		s->count[lab[i]]++;
		float *c4 = s->conf4 + 4 * i;
		c4[0] = margin[i];
		c4[1] = cp.post[i];
		c4[2] = cp.angle[i];
		c4[3] = cp.scale[i];
		if (lab[i] == KG_EST_LABEL_NONE || lab[i] > s->nclasses)
			continue;
		class_stats *c = &s->cs[lab[i] - 1];
		if (!c->hi && !(c->hi = calloc(HIST_BINS, sizeof(uint32_t))))
			return kg_fail(err, KG_ENOMEM, "classify: out of memory for the margins");
		c->hi[ap_order_key(margin[i]) >> 16]++;
		c->count++;
		c->margin_sum += margin[i];
		for (int ch = 0; ch < 3; ch++)
			c->rgb_sum[ch] += pl.raw[3 * i + ch];
	}
	int rc = 0;
	if (s->reg.on)
		for (int y = 0; y < b->rows && !rc; y++) {
			size_t o = (size_t)y * b->width;
			const float *fshare = cp.fshare + o;
			const float *d2 = cp.d2 + o * (size_t)r->nm;
			if (s->reg.user) {
				rc = s->region_map->read(s->region_map->user, b->y0 + y, 1, s->region_row, err);
				if (!rc)
					rc = regions_user_row(&s->reg, b->y0 + y, s->region_row, lab + o, d2,
					                      fshare, cp.comp + 6 * o, s->nclasses, err);
			} else {
				rc = regions_row(&s->reg, lab + o, d2, fshare, cp.comp + 6 * o, s->nclasses,
				                 err);
			}
		}
	if (rc)
		return rc;
	for (; s->next_py < s->ph; s->next_py++) {
		int sy = (int)((long)s->next_py * s->height / s->ph);
		if (sy >= b->y0 + b->rows)
			break;
		const uint8_t *row = lab + (size_t)(sy - b->y0) * b->width;
		for (int x = 0; x < s->pw; x++)
			s->preview[(size_t)s->next_py * s->pw + x] = row[(long)x * b->width / s->pw];
	}
	if (s->comp) {
		/* gold only where its sd is below the declared range */
		for (size_t i = 0; i < n; i++)
			if (!(cp.comp[6 * i + 5] < r->gold_range))
				cp.comp[6 * i + 2] = NAN;
		rc = kg_envi_writer_put(s->comp, b->y0, b->y0 + b->rows, KG_LAYOUT_BIP, cp.comp, err);
		if (rc)
			return rc;
	}
	rc = ap_put_bytes(s->labels, &s->stage, b, lab, err);
	if (!rc)
		rc = kg_envi_writer_put(s->conf, b->y0, b->y0 + b->rows, KG_LAYOUT_BIP, s->conf4, err);
	if (!rc)
		rc = ap_put_bytes(s->mask, &s->stage, b, b->mask, err);
	ap_progress_rows(&s->prog, b->y0 + b->rows);
	return rc;
}

/* ---- the noise survey -------------------------------------------------------------- */

typedef struct survey_result {
	uint64_t pixels;
	/* per channel, the variance of a site reading rho: a + b rho + c rho^2 (fitted to the
	 * variance image by least squares, c = 0; or the noise model: floor^2, 0, rel^2) */
	double va[3], vb[3], vc[3];
	double cov[9];   /* mean covariance */
	double level;    /* mean intensity, in the model's units */
	double rms;      /* mean rms reading */
	double calib_share;
} survey_result;

static int survey(const cam_run *r, const kg_classify_camera *cam, const kg_cs_model *m,
                  survey_result *out, kg_err *err)
{
	memset(out, 0, sizeof(*out));
	const kg_row_source *img = cam->survey, *var = cam->survey_variance;
	double vsum[3] = {0}, l2sum = 0, lsum = 0;
	double rs[3] = {0}, rs2[3] = {0}, vs[3] = {0}, vrs[3] = {0};
	uint64_t count = 0;
	if (img) {
		int W = img->width, H = img->height;
		int band = (int)(((size_t)1 << 18) / (size_t)W);
		band = band < 1 ? 1 : band > H ? H : band;
		float *buf = malloc(sizeof(float) * 3 * (size_t)band * W);
		float *vbuf = var ? malloc(sizeof(float) * 3 * (size_t)band * W) : NULL;
		int rc = buf && (!var || vbuf) ? 0 : kg_fail(err, KG_ENOMEM, "out of memory");
		for (int y = 0; y < H && !rc; y += band) {
			int rows = H - y < band ? H - y : band;
			rc = img->read(img->user, y, rows, buf, err);
			if (!rc && var)
				rc = var->read(var->user, y, rows, vbuf, err);
			size_t n = (size_t)rows * W;
			for (size_t i = 0; i < n && !rc; i++) {
				const float *p = buf + 3 * i;
				if (!isfinite(p[0] + p[1] + p[2]) || p[0] >= r->in.clip3[0] ||
				    p[1] >= r->in.clip3[1] || p[2] >= r->in.clip3[2] ||
				    fmaxf(p[0], fmaxf(p[1], p[2])) < fmaxf(r->background_level, 1e-6f))
					continue;
				if (var && !(vbuf[3 * i] >= 0 && vbuf[3 * i + 1] >= 0 && vbuf[3 * i + 2] >= 0 &&
				             isfinite(vbuf[3 * i] + vbuf[3 * i + 1] + vbuf[3 * i + 2])))
					continue; /* the run refuses it, naming the pixel */
				/* the mean covariance from the means of its parts (it is linear
				 * in them), not pixel by pixel */
				double x[3], v[3];
				double l2 = pixel_parts(&r->nz, p, var ? vbuf + 3 * i : NULL, x, v);
				for (int ch = 0; ch < 3; ch++)
					vsum[ch] += v[ch];
				l2sum += l2;
				for (int ch = 0; var && ch < 3; ch++) {
					double rho = p[ch]; /* v[ch]: the variance image's, per frame */
					rs[ch] += rho;
					rs2[ch] += rho * rho;
					vs[ch] += v[ch];
					vrs[ch] += v[ch] * rho;
				}
				lsum += sqrt(l2);
				count++;
			}
		}
		free(buf);
		free(vbuf);
		if (rc)
			return rc;
	}
	/* the models' mean rms reading at intensity 1 */
	double mu_rms = 0;
	for (int i = 0; i < m->n * m->nangles; i++) {
		const double *mu = m->mu + 3 * (size_t)i;
		mu_rms += sqrt((mu[0] * mu[0] + mu[1] * mu[1] + mu[2] * mu[2]) / 3.0);
	}
	mu_rms /= m->n * m->nangles;
	double c[6];
	if (count) {
		double n = (double)count;
		for (int e = 0; e < 6; e++) {
			double s = 0;
			for (int ch = 0; ch < 3; ch++)
				s += r->nz.P[e][ch] * (vsum[ch] / n);
			c[e] = s + l2sum / n * r->nz.R[3 * cov_ia[e] + cov_ib[e]];
		}
		out->rms = lsum / n;
	} else {
		/* no survey: the noise model at the middle of the intensity range */
		out->rms = 0.5 * (m->lo + m->hi) * mu_rms;
		float rho[3];
		double x[3];
		for (int ch = 0; ch < 3; ch++)
			rho[ch] = (float)out->rms;
		pixel_noise(&r->nz, rho, NULL, x, c);
	}
	for (int e = 0; e < 6; e++)
		out->cov[3 * cov_ia[e] + cov_ib[e]] = out->cov[3 * cov_ib[e] + cov_ia[e]] = c[e];
	out->pixels = count;
	for (int ch = 0; ch < 3; ch++) {
		if (!var || !count) {
			out->va[ch] = r->nz.floor2;
			out->vb[ch] = 0;
			out->vc[ch] = r->nz.rel2;
			continue;
		}
		double n = (double)count, mr = rs[ch] / n, mv = vs[ch] / n;
		double sxx = rs2[ch] / n - mr * mr, sxy = vrs[ch] / n - mr * mv;
		double b = sxx > 0 ? sxy / sxx : 0, a = mv - b * mr;
		if (b < 0) {
			b = 0;
			a = mv;
		}
		if (a < 0) {
			a = 0;
			b = rs2[ch] > 0 ? vrs[ch] / rs2[ch] : 0;
		}
		out->va[ch] = a > 1e-14 ? a : 1e-14;
		out->vb[ch] = b;
		out->vc[ch] = 0;
	}
	double level = mu_rms > 0 ? out->rms / mu_rms : 1.0;
	out->level = level < m->lo ? m->lo : level > m->hi ? m->hi : level;
	double tr = out->cov[0] + out->cov[4] + out->cov[8];
	double cal = out->rms * out->rms * (r->nz.R[0] + r->nz.R[4] + r->nz.R[8]);
	out->calib_share = tr > 0 ? cal / tr : 0;
	return 0;
}


/* Every pair's separability with each reading's own noise: material i at angle k at
 * the survey's level x = level mu, its site reading M2^-1 x, that reading's variance
 * from the survey's noise model through M2, and the calibration's l^2 R. */
static int separability(const cam_run *r, const kg_cs_model *m, const survey_result *sv,
                        double *d, kg_err *err)
{
	double Mi[9];
	if (kg_mat3_inverse(r->nz.M2, Mi))
		return kg_fail(err, KG_EINVAL, "M2: expected an invertible 3 x 3 matrix (the site "
		               "calibration's), got a singular one");
	size_t nr = (size_t)m->n * (size_t)m->nangles;
	double *covs = malloc(sizeof(double) * 9 * nr);
	if (!covs)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (size_t q = 0; q < nr; q++) {
		double x[3], rho[3], v[3];
		for (int a = 0; a < 3; a++)
			x[a] = sv->level * m->mu[3 * q + a];
		for (int a = 0; a < 3; a++)
			rho[a] = Mi[3 * a] * x[0] + Mi[3 * a + 1] * x[1] + Mi[3 * a + 2] * x[2];
		for (int c = 0; c < 3; c++) {
			double p = rho[c] > 0 ? rho[c] : 0;
			v[c] = sv->va[c] + sv->vb[c] * p + sv->vc[c] * p * p;
		}
		double l2 = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) / 3.0;
		double *C = covs + 9 * q;
		for (int a = 0; a < 3; a++)
			for (int b = 0; b < 3; b++) {
				double s = 0;
				for (int c = 0; c < 3; c++)
					s += r->nz.M2[3 * a + c] * r->nz.M2[3 * b + c] * v[c];
				C[3 * a + b] = s + l2 * r->nz.R[3 * a + b];
			}
	}
	int rc = kg_cs_separability_each(m, covs, sv->level, d, err);
	free(covs);
	return rc;
}

/* ---- LABELS.json ------------------------------------------------------------------ */

static json_t *mat3(const double *m)
{
	json_t *a = json_array();
	for (int i = 0; i < 3; i++)
		json_array_append_new(a, json_pack("[fff]", m[3 * i], m[3 * i + 1], m[3 * i + 2]));
	return a;
}

static int write_json(const char *path, const kg_est_material_set *set,
                      const kg_est_material_set *classes, const int *group,
                      const kg_classify_camera *cam, const kg_classify_options *copt,
                      const kg_cs_model *m, const survey_result *sv, const double *sep,
                      double merge_d, const kg_row_source *img, const kg_apply_options *opt,
                      const kg_classify_info *info, const char *const files[6],
                      const regions *reg, const kg_classify_result *res, double threshold,
                      const cam_run *run, kg_err *err)
{
	const int nm = set->n, nc = classes->n;
	json_t *root = json_object();
	json_object_set_new(root, "format", json_string("kogei-labels/1"));
	const char *keys[4] = {"image", "calib", "materials", "method"};
	const char *vals[4] = {info ? info->image : NULL, info ? info->calib : NULL,
	                       info ? info->materials : NULL, "camera"};
	for (int i = 0; i < 4; i++)
		json_object_set_new(root, keys[i], vals[i] ? json_string(vals[i]) : json_null());
	json_object_set_new(root, "clip_level", ap_json_num(opt->clip_level));
	{ /* per channel: the clip level, or the saturation found from the data below it */
		json_t *cl = json_array();
		for (int c = 0; c < 3; c++)
			json_array_append_new(cl, ap_json_num(opt->clip_rgb[c] > 0 &&
			                                      opt->clip_rgb[c] < opt->clip_level
			                                          ? opt->clip_rgb[c] : opt->clip_level));
		json_object_set_new(root, "clip_levels", cl);
	}
	json_object_set_new(root, "width", json_integer(img->width));
	json_object_set_new(root, "height", json_integer(img->height));
	json_object_set_new(root, "pixels", json_integer((json_int_t)res->stats.pixels));
	json_t *cs = json_object();
	json_object_set_new(cs, "description",
	                    json_string("each pixel's reading mapped through M2 into the "
	                                "reference camera's space and matched against every "
	                                "declared material's predicted reading over the angles "
	                                "and intensities, by the noise-weighted (Mahalanobis) "
	                                "distance d2"));
	json_object_set_new(cs, "angles_deg", json_pack("[fff]", cam->angle_from, cam->angle_to,
	                                                cam->angle_step));
	json_object_set_new(cs, "intensity", json_pack("[ff]", cam->intensity_lo,
	                                               cam->intensity_hi));
	json_object_set_new(cs, "M2", mat3(cam->site_to_ref));
	json_t *tm = json_array();
	for (int j = 0; j < m->n; j++)
		if (m->templated[j])
			json_array_append_new(tm, json_string(m->names[j]));
	json_object_set_new(cs, "coupon_templates", tm);
	json_object_set_new(cs, "calibration_covariance", mat3(cam->calib_cov));
	json_object_set_new(cs, "neutral_diffuse",
	                    cam->no_neutral
	                        ? json_false()
	                        : json_string("a pixel a flat reflectance at any level fits "
	                                      "better than every declared material (and within "
	                                      "the unknown bound) is background: a grey card, "
	                                      "paper, cloth"));
	json_object_set_new(cs, "response", json_string(cam->response_source[0]
	                                                    ? cam->response_source
	                                                    : "given"));
	json_t *nz = json_object();
	if (copt->variance) {
		json_object_set_new(nz, "noise", json_string("variance image"));
		json_object_set_new(nz, "variance", json_string(info && info->variance ? info->variance
		                                                                       : "given"));
		json_object_set_new(nz, "frames", json_integer(copt->frames));
	} else {
		json_object_set_new(nz, "noise", json_string("model"));
		json_object_set_new(nz, "noise_relative", json_real(copt->noise_relative));
		json_object_set_new(nz, "noise_floor", json_real(copt->noise_floor));
	}
	json_object_set_new(nz, "survey_pixels", json_integer((json_int_t)sv->pixels));
	json_object_set_new(nz, "variance_model",
	                    json_pack("{s:s,s:[fff],s:[fff],s:[fff]}", "form",
	                              "per site channel: a + b rho + c rho^2", "a", sv->va[0],
	                              sv->va[1], sv->va[2], "b", sv->vb[0], sv->vb[1], sv->vb[2],
	                              "c", sv->vc[0], sv->vc[1], sv->vc[2]));
	json_object_set_new(nz, "mean_covariance", mat3(sv->cov));
	json_object_set_new(nz, "mean_rms_reading", json_real(sv->rms));
	json_object_set_new(nz, "level", json_real(sv->level));
	json_object_set_new(nz, "calibration_share", json_real(sv->calib_share));
	json_object_set_new(cs, "noise", nz);
	json_t *u = json_object();
	json_object_set_new(u, "enabled", json_boolean(isfinite(threshold)));
	json_object_set_new(u, "statistic", json_string("d2 of the best material"));
	json_object_set_new(u, "threshold", ap_json_num(threshold));
	json_object_set_new(u, "dof", json_integer(res->dof));
	json_object_set_new(u, "probability", isfinite(threshold) && copt->unknown_threshold == 0
	                                          ? json_real(0.999)
	                                          : json_null());
	json_object_set_new(cs, "unknown", u);
	json_object_set_new(root, "camera_space", cs);

	/* separability */
	json_t *sj = json_object(), *names = json_array(), *dtab = json_array(),
	       *ptab = json_array(), *pairs = json_array();
	for (int i = 0; i < nm; i++) {
		json_array_append_new(names, json_string(set->names[i]));
		json_t *dr = json_array(), *pr = json_array();
		for (int j = 0; j < nm; j++) {
			double d = sep[(size_t)i * nm + j];
			json_array_append_new(dr, ap_json_num(i == j ? 0.0 : d));
			json_array_append_new(pr, i == j ? json_null() : ap_json_num(kg_cs_pixels_for(d)));
		}
		json_array_append_new(dtab, dr);
		json_array_append_new(ptab, pr);
	}
	for (int i = 0; i < nm; i++)
		for (int j = i + 1; j < nm; j++) {
			double d = sep[(size_t)i * nm + j];
			if (kg_cs_pixels_for(d) <= 1)
				continue;
			json_array_append_new(pairs, json_pack("{s:s,s:s,s:o,s:o,s:b}", "a", set->names[i],
			                                       "b", set->names[j], "distance", ap_json_num(d),
			                                       "pixels_for_1pc", ap_json_num(kg_cs_pixels_for(d)),
			                                       "merged", group[i] == group[j]));
		}
	json_object_set_new(sj, "materials", names);
	json_object_set_new(sj, "distance", dtab);
	json_object_set_new(sj, "pixels_for_1pc", ptab);
	json_object_set_new(sj, "pairs_needing_pooling", pairs);
	json_object_set_new(sj, "merge_distance", ap_json_num(merge_d));
	json_object_set_new(sj, "description",
	                    json_string("least noise-weighted distance between two materials over "
	                                "every angle and intensity at the capture's noise (each "
	                                "reading at the survey's level with its own covariance "
	                                "from the fitted variance model and the calibration); a "
	                                "pixel tells "
	                                "them apart with error Phi(-d/2); pixels_for_1pc: pixels "
	                                "a region must pool for a 1 % error; pairs closer than "
	                                "merge_distance are one class"));
	json_object_set_new(root, "separability", sj);
	json_t *merges = json_array();
	for (int c = 0; c < nc; c++) {
		int members = 0;
		for (int j = 0; j < nm; j++)
			members += group[j] == c;
		if (members < 2)
			continue;
		json_t *mm = json_array();
		for (int j = 0; j < nm; j++)
			if (group[j] == c)
				json_array_append_new(mm, json_string(set->names[j]));
		json_array_append_new(merges, mm);
	}
	json_object_set_new(root, "merges", merges);

	json_t *fs = json_object();
	const char *fkeys[6] = {"labels", "confidence", "mask", "preview", "regions",
	                        "regions_csv"};
	for (int i = 0; i < 6; i++)
		json_object_set_new(fs, fkeys[i], files[i] ? json_string(files[i]) : json_null());
	json_object_set_new(root, "files", fs);
	json_object_set_new(root, "confidence",
	                    json_string("bands: margin (d2 of the runner-up class minus the "
	                                "chosen class's, noise-weighted), posterior (of the "
	                                "chosen class over the declared materials, equal "
	                                "priors), angle_deg and intensity (the best material's "
	                                "fit); NaN for unclassified, unknown and background"));
	json_t *classes_j = json_array();
	json_t *c0 = json_pack("{s:i,s:s,s:I}", "label", 0, "name", "unclassified", "pixels",
	                       (json_int_t)res->unclassified);
	json_array_append_new(classes_j, c0);
	for (int c = 0; c < nc; c++) {
		const kg_class_summary *k = &res->classes[c];
		unsigned char col[3];
		ap_label_colour(classes, c + 1, col);
		json_t *o = json_object();
		json_object_set_new(o, "label", json_integer(c + 1));
		json_object_set_new(o, "name", json_string(k->name));
		json_t *mm = json_array();
		for (int j = 0; j < nm; j++)
			if (group[j] == c)
				json_array_append_new(mm, json_string(set->names[j]));
		json_object_set_new(o, "members", mm);
		json_object_set_new(o, "pixels", json_integer((json_int_t)k->pixels));
		json_object_set_new(o, "fraction", json_real(k->fraction));
		json_object_set_new(o, "colour", json_pack("[iii]", col[0], col[1], col[2]));
		json_t *ms = json_null();
		if (k->pixels && isfinite(k->mean_spectrum[0])) {
			ms = json_array();
			for (int l = 0; l < KG_NBANDS; l++)
				json_array_append_new(ms, ap_json_num(k->mean_spectrum[l]));
		}
		json_object_set_new(o, "mean_spectrum", ms);
		json_object_set_new(o, "confidence",
		                    json_pack("{s:o,s:o,s:o}", "mean", ap_json_num(k->margin_mean),
		                              "median", ap_json_num(k->margin_median), "p5",
		                              ap_json_num(k->margin_p5)));
		json_array_append_new(classes_j, o);
	}
	json_array_append_new(classes_j, ap_refusal_class(classes, ap_label_unknown(classes),
	                                                   res->unknown, res->stats.pixels));
	json_array_append_new(classes_j, ap_refusal_class(classes, ap_label_background(classes),
	                                                  res->background, res->stats.pixels));
	json_object_set_new(root, "classes", classes_j);

	json_t *comp = json_object();
	json_object_set_new(comp, "enabled", json_boolean(run->metals != NULL));
	if (run->metals) {
		json_object_set_new(comp, "metals", json_pack("[sss]", cam->metals[0]->name,
		                                              cam->metals[1]->name,
		                                              cam->metals[2]->name));
		json_object_set_new(comp, "file", cam->composition_hdr
		                                      ? json_string(cam->composition_hdr)
		                                      : json_null());
		json_object_set_new(comp, "gold_range", json_real(run->gold_range));
		json_object_set_new(comp, "description",
		                    json_string("Ag, Cu and Au fractions (>= 0, summing to 1) of the "
		                                "pixels whose best material is made of these metals, "
		                                "fitted in camera space at the fitted angle (the alloy "
		                                "model is linear in the fractions), with Cramer-Rao "
		                                "standard deviations; gold is given only where its sd "
		                                "is below gold_range, the range of gold fractions of "
		                                "the declared materials; regions: inverse-variance "
		                                "means, sds widened by sqrt(1 + N f)"));
	}
	json_object_set_new(root, "composition", comp);
	json_t *rj = json_object();
	json_object_set_new(rj, "enabled", json_boolean(reg->on && !reg->overflow));
	json_object_set_new(rj, "source", json_string(reg->user ? "region map"
	                                              : "connected components of the classes"));
	if (reg->overflow)
		json_object_set_new(rj, "note", json_string("more than 1048576 runs of classes: "
		                                            "regions were not formed"));
	json_object_set_new(rj, "count", json_integer(reg->nfinal));
	json_object_set_new(rj, "decision",
	                    json_string("pooled likelihood: sum of each material's d2 over the "
	                                "region's pixels, the differences scaled by 1 / (1 + N f) "
	                                "(f: the calibration's share of a pixel's noise, which "
	                                "pooling does not reduce); a compound class resolves to "
	                                "a member whose share of its posterior is >= 0.99; "
	                                "'unknown' when the decided material's summed d2, scaled "
	                                "by 1 / (1 + N f') with f' the calibration's and the "
	                                "material's own model error's (model_rsd) share, "
	                                "exceeds the 99.9 % point of chi-square with dof "
	                                "N / (1 + N f') degrees of freedom"));
	json_t *table = json_array();
	if (reg->on && !reg->overflow && reg->final) {
		int listed = 0;
		for (uint32_t id = 0; id < reg->n && listed < 2000; id++) {
			uint32_t f = reg->final[id];
			if (!f || reg->count[id] < TABLE_MIN_PIXELS)
				continue;
			region_decision d = decide(reg, id, group, nc);
			double c[6];
			region_composition(reg, id, run->gold_range, c);
			json_t *cj = json_null();
			if (run->metals && (isfinite(c[0]) || isfinite(c[1])))
				cj = json_pack("{s:o,s:o,s:o,s:o,s:o,s:o}", "ag", ap_json_num(c[0]), "cu",
				               ap_json_num(c[1]), "au", ap_json_num(c[2]), "sd_ag",
				               ap_json_num(c[3]), "sd_cu", ap_json_num(c[4]), "sd_au",
				               ap_json_num(c[5]));
			json_t *row = json_pack("{s:I,s:I,s:s,s:s,s:o,s:o}", "region", (json_int_t)f,
			                        "pixels", (json_int_t)reg->count[id], "class",
			                        classes->names[d.cls], "label",
			                        region_label(&d, set, classes), "posterior",
			                        ap_json_num(d.posterior), "composition", cj);
			region_why(row, reg, id, &d, region_label(&d, set, classes), classes);
			if (!json_object_get(row, "pixel_class")) /* user regions: none */
				json_object_set_new(row, "pixel_class", json_null());
			json_array_append_new(table, row);
			listed++;
		}
	}
	json_object_set_new(rj, "min_pixels_listed", json_integer(TABLE_MIN_PIXELS));
	json_object_set_new(rj, "table", table);
	json_object_set_new(root, "regions", rj);
	int rc = kg_json_write(root, path, err);
	json_decref(root);
	if (rc)
		kg_err_prefix(err, "%s: ", path);
	return rc;
}

/* ---- region map and table (pass 2) ------------------------------------------------- */

/* The region map of connected components: pass 1's runs found again in the written
 * labels, in the same order, so each gets its provisional id and its root's number. */
static int write_region_map(regions *g, const kg_est_material_set *classes,
                            const char *labels_hdr, const char *reg_hdr, written *done,
                            kg_err *err)
{
	const int W = g->width;
	kg_envi *el = NULL;
	kg_envi_writer *w = NULL;
	int rc = kg_envi_open(labels_hdr, &el, err);
	if (rc)
		return rc;
	const int H = el->meta.lines;
	kg_envi_meta m = {0};
	m.samples = W;
	m.lines = H;
	m.bands = 1;
	m.data_type = KG_ENVI_U32;
	m.interleave = KG_ENVI_BSQ;
	m.description = "kogei classify regions: region number per pixel (0: none), as in "
	                "the regions table";
	float *lab = malloc(sizeof(float) * W), *out = malloc(sizeof(float) * W);
	uint8_t *lab8 = malloc((size_t)W);
	run_seg *a = malloc(sizeof(run_seg) * ((size_t)W + 1));
	run_seg *b = malloc(sizeof(run_seg) * ((size_t)W + 1));
	if (!lab || !out || !lab8 || !a || !b)
		rc = kg_fail(err, KG_ENOMEM, "out of memory");
	if (!rc)
		rc = kg_envi_writer_open(reg_hdr, &m, &w, err);
	uint32_t saved_n = g->n;
	g->n = 0;
	int na = 0;
	for (int y = 0; y < H && !rc; y++) {
		rc = kg_envi_read(el, 0, y, W, 1, KG_LAYOUT_BIP, lab, err);
		if (rc)
			break;
		for (int x = 0; x < W; x++)
			lab8[x] = (uint8_t)lab[x];
		{
			int nb = row_runs(lab8, W, classes->n, b);
			link_rows(g, b, nb, a, na, 0);
			for (int x = 0; x < W; x++)
				out[x] = 0;
			for (int i = 0; i < nb; i++) {
				float f = (float)g->final[find_root(g->parent, b[i].id)];
				for (int x = b[i].x0; x <= b[i].x1; x++)
					out[x] = f;
			}
			run_seg *t = a;
			a = b;
			b = t;
			na = nb;
		}
		rc = kg_envi_writer_put(w, y, y + 1, KG_LAYOUT_BIP, out, err);
	}
	g->n = saved_n;
	kg_envi_close(&el);
	free(lab);
	free(out);
	free(lab8);
	free(a);
	free(b);
	if (!rc) {
		rc = kg_envi_writer_finish(&w, err);
		if (!rc)
			ap_written_add_envi(done, reg_hdr);
	} else if (w) {
		kg_envi_writer_abort(&w);
	}
	return rc;
}

/* The table of every region (CSV). */
static int write_region_table(const regions *g, const kg_est_material_set *set,
                              const kg_est_material_set *classes, const int *group,
                              double gold_range, const char *csv_path, written *done,
                              kg_err *err)
{
	kg_outfile of;
	int rc = kg_outfile_open(&of, csv_path, 0, err);
	if (rc)
		return rc;
	fprintf(of.fp, "region,pixels,class,label,posterior,mean_d2,ag,cu,au,sd_ag,sd_cu,sd_au\n");
	for (uint32_t id = 0; id < g->n; id++) {
		uint32_t f = g->final[id];
		if (!f)
			continue;
		region_decision d = decide(g, id, group, classes->n);
		double c[6];
		region_composition(g, id, gold_range, c);
		fprintf(of.fp, "%u,%llu,%s,%s,%.6g,%.6g", f, (unsigned long long)g->count[id],
		        classes->names[d.cls], region_label(&d, set, classes), d.posterior, d.d2_mean);
		for (int q = 0; q < 6; q++)
			isfinite(c[q]) ? fprintf(of.fp, ",%.4f", c[q]) : fprintf(of.fp, ",");
		fprintf(of.fp, "\n");
	}
	rc = kg_outfile_commit(&of, err);
	if (!rc)
		ap_written_add(done, csv_path);
	return rc;
}

/* ---- the call --------------------------------------------------------------------- */

static void set_free_classes(kg_est_material_set *c)
{
	free(c->names);
	free(c->materials);
	free(c->spectra);
}

int kg_classify_camera_rows(const kg_est_kernel *k, const kg_est_material_set *set,
                            const kg_classify_camera *cam, const kg_row_source *src,
                            const kg_apply_options *opt, const kg_classify_options *copt,
                            const kg_classify_info *info, const char *out_hdr,
                            kg_classify_result *res, kg_err *err)
{
	kg_check_arg(set && cam && src && out_hdr, err);
	kg_apply_options dflt;
	if (!opt) {
		kg_apply_options_init(&dflt);
		opt = &dflt;
	}
	kg_classify_options cdflt;
	if (!copt) {
		kg_classify_options_init(&cdflt);
		copt = &cdflt;
	}
	if (res)
		memset(res, 0, sizeof(*res));
	if (!set->mats)
		return kg_fail(err, KG_EINVAL, "%s: camera-space matching needs the library's "
		               "materials (kg_est_material_set_new)", out_hdr);
	if (!cam->response)
		return kg_fail(err, KG_EINVAL, "%s: camera-space matching needs the reference "
		               "camera's spectral response", out_hdr);
	if (set->n > 254)
		return kg_fail(err, KG_EINVAL, "%s: %d materials: camera-space matching takes at most "
		               "254", out_hdr, set->n);
	int bad = kg_mat3_check_invertible(cam->site_to_ref, NULL, "M2", err);
	if (bad)
		return bad;
	for (int i = 0; i < 9; i++)
		if (!isfinite(cam->calib_cov[i]))
			return kg_fail(err, KG_EINVAL, "%s: the calibration covariance: expected "
			               "finite values", out_hdr);
	if (cam->region_map && (cam->region_map->width != src->width ||
	                        cam->region_map->height != src->height ||
	                        cam->region_map->channels != 1))
		return kg_fail(err, KG_EINVAL, "%s: the region map %s is %d x %d with %d channel%s: "
		               "expected one grey channel of the image's size, %d x %d", out_hdr,
		               cam->region_map_name ? cam->region_map_name : "", cam->region_map->width,
		               cam->region_map->height, cam->region_map->channels,
		               cam->region_map->channels == 1 ? "" : "s", src->width, src->height);
	for (int j = 0; j < set->n; j++) {
		const kg_material_template *t = &set->mats[j]->tmpl;
		if (t->n && t->reference[0] && cam->reference_sha256 && cam->reference_sha256[0] &&
		    strcmp(t->reference, cam->reference_sha256) != 0)
			return kg_fail(err, KG_EINVAL, "%s: material '%s': its coupon template was learned "
			               "through another reference calibration (sha256 %.12s..., this "
			               "calibration's reference is %.12s...): learn it again through this "
			               "one, or use a library without it", out_hdr, set->mats[j]->name,
			               t->reference, cam->reference_sha256);
	}
	cam_run run;
	memset(&run, 0, sizeof(run));
	kg_apply_options o = *opt;
	o.pre = NULL; /* M2 is applied here, with the noise */
	int rc = ap_feed_init(&run.in, src, &o, "classify", err);
	if (rc)
		return rc;
	/* no pre here: per-channel clip levels are tested on the image's values below */
	run.in.has_pre = 0;
	run.in.job_clip = run.in.clip;
	run.in.var = copt->variance;
	run.in.var_name = info && info->variance ? info->variance : "the variance image";
	run.in.mask = copt->mask;
	if ((rc = ap_check_options(copt, src, info, "classify", err)))
		return rc;
	memcpy(run.nz.M2, cam->site_to_ref, sizeof(run.nz.M2));
	memcpy(run.nz.R, cam->calib_cov, sizeof(run.nz.R));
	noise_products(&run.nz);
	run.nz.inv_frames = 1.0 / copt->frames;
	run.nz.floor2 = copt->noise_floor * copt->noise_floor;
	run.nz.rel2 = copt->noise_relative * copt->noise_relative;
	run.background_level = (float)copt->background_level;
	run.nm = set->n;
	run.neutral = !cam->no_neutral;
	for (int j = 0; j < set->n; j++)
		run.metal[j] = set->mats && set->mats[j] && (set->mats[j]->kind == KG_MATERIAL_METAL ||
		                                             set->mats[j]->kind == KG_MATERIAL_ALLOY);
	for (int a = 0; a < 3; a++) {
		run.white[a] = 0;
		for (int b = 0; b < KG_NBANDS; b++)
			run.white[a] += cam->response[a * KG_NBANDS + b];
	}

	kg_cs_model *model = NULL, *metals = NULL;
	double *sep = NULL;
	kg_est_material_set classes = {0};
	kg_classify_result local = {0};
	kg_envi_writer *ws[4] = {NULL, NULL, NULL, NULL};
	char *conf_path = NULL, *mask_path = NULL, *json_path = NULL, *png_path = NULL,
	     *reg_path = NULL, *csv_path = NULL;
	const char *paths[4] = {out_hdr, NULL, NULL, NULL};
	cam_sink sink = {0};
	written done = {0};
	survey_result sv;
	const int W = src->width, H = src->height;
	const int nm = set->n;
	double merge_d = cam->merge_distance == 0 ? KG_CS_MERGE_DISTANCE : cam->merge_distance;

	if ((rc = kg_cs_model_new(cam->response, set->mats, nm, cam->angle_from, cam->angle_to,
	                          cam->angle_step, cam->intensity_lo, cam->intensity_hi, &model,
	                          err)))
		goto out;
	run.model = model;
	if (cam->metals[0] && cam->metals[1] && cam->metals[2]) {
		if ((rc = kg_cs_model_new(cam->response, cam->metals, 3, cam->angle_from,
		                          cam->angle_to, cam->angle_step, cam->intensity_lo,
		                          cam->intensity_hi, &metals, err)))
			goto out;
		run.metals = metals;
		double glo = INFINITY, ghi = -INFINITY;
		for (int j = 0; j < nm; j++) {
			const kg_material *mt = set->mats[j];
			double gold = -1;
			if (mt->kind == KG_MATERIAL_METAL) {
				for (int q = 0; q < 3; q++)
					if (!strcmp(mt->name, cam->metals[q]->name))
						gold = q == 2;
			} else if (mt->kind == KG_MATERIAL_ALLOY) {
				gold = 0;
				for (int c = 0; c < mt->ncomponents && gold >= 0; c++) {
					int known = 0;
					for (int q = 0; q < 3; q++)
						if (!strcmp(mt->component[c].name, cam->metals[q]->name)) {
							known = 1;
							if (q == 2)
								gold += mt->component[c].fraction;
						}
					if (!known)
						gold = -1;
				}
			}
			run.comp_ok[j] = gold >= 0;
			if (gold >= 0) {
				glo = fmin(glo, gold);
				ghi = fmax(ghi, gold);
			}
		}
		run.gold_range = ghi >= glo ? ghi - glo : 0;
	}
	if ((rc = survey(&run, cam, model, &sv, err)))
		goto out;
	if (!(sep = malloc(sizeof(double) * (size_t)nm * nm))) {
		rc = kg_fail(err, KG_ENOMEM, "out of memory");
		goto out;
	}
	if ((rc = separability(&run, model, &sv, sep, err))) {
		kg_err_prefix(err, "%s: ", out_hdr);
		goto out;
	}
	/* a merge distance <= 0 joins nothing: every material its own class */
	kg_cs_merge_groups(sep, nm, merge_d > 0 ? merge_d : 0, run.group);
	/* classes numbered in order of their first member */
	{
		int map[KG_EST_MAX_MATERIALS], nc = 0;
		for (int j = 0; j < nm; j++)
			map[j] = -1;
		for (int j = 0; j < nm; j++) {
			int g = run.group[j];
			if (map[g] < 0)
				map[g] = nc++;
			run.group[j] = map[g];
		}
		run.nc = nc;
	}
	classes.n = run.nc;
	classes.angle_deg = set->angle_deg;
	classes.names = calloc((size_t)run.nc, sizeof(*classes.names));
	classes.materials = calloc((size_t)run.nc, sizeof(*classes.materials));
	classes.spectra = calloc((size_t)run.nc, sizeof(*classes.spectra));
	if (!classes.names || !classes.materials || !classes.spectra) {
		rc = kg_fail(err, KG_ENOMEM, "out of memory");
		goto out;
	}
	for (int c = 0; c < run.nc; c++) {
		size_t used = 0;
		for (int j = 0; j < nm; j++)
			if (run.group[j] == c) {
				int w = snprintf(classes.names[c] + used, sizeof(classes.names[c]) - used,
				                 "%s%s", used ? "|" : "", set->names[j]);
				if (w < 0 || used + (size_t)w >= sizeof(classes.names[c])) {
					rc = kg_fail(err, KG_EINVAL, "%s: the merged class of '%s' has a name "
					             "longer than %d characters", out_hdr, set->names[j],
					             KG_EST_CLASS_NAME_MAX - 1);
					goto out;
				}
				used += (size_t)w;
			}
		classes.materials[c].name = classes.names[c];
		classes.materials[c].spectrum = classes.spectra[c].v;
	}
	/* the reading's 3 channels less the fitted intensity (the angle, weakly determined,
	 * is not counted: the bound errs towards keeping a material) */
	run.dof = cam->intensity_hi > cam->intensity_lo ? 2 : 3;
	run.unknown = (uint8_t)ap_label_unknown(&classes);
	run.background = (uint8_t)ap_label_background(&classes);
	run.threshold = copt->unknown_threshold > 0 ? copt->unknown_threshold
	                                            : kg_chi2_quantile(0.999, run.dof);
	local.unknown_threshold = run.threshold;
	local.dof = run.dof;
	sink.reg.dof = run.dof;
	sink.reg.cal_tr = run.nz.R[0] + run.nz.R[4] + run.nz.R[8];
	for (int j = 0; j < nm; j++) {
		const double *u = set->mats[j]->model_rsd;
		run.model_tr[j] = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
	}
	sink.reg.model_tr = run.model_tr;

	if ((rc = kg_apply_side_path(out_hdr, "_confidence.hdr", &conf_path, err)) ||
	    (rc = kg_apply_side_path(out_hdr, ".json", &json_path, err)) ||
	    (rc = kg_apply_side_path(out_hdr, ".png", &png_path, err)) ||
	    (rc = kg_apply_side_path(out_hdr, "_regions.hdr", &reg_path, err)) ||
	    (rc = kg_apply_side_path(out_hdr, "_regions.csv", &csv_path, err)) ||
	    (rc = kg_inputs_check_output(json_path, err)) ||
	    (rc = kg_inputs_check_output(png_path, err)) ||
	    (rc = kg_inputs_check_output(csv_path, err)))
		goto out;
	ap_preview_size(W, H, &sink.pw, &sink.ph);
	sink.preview = malloc((size_t)sink.pw * sink.ph);
	sink.cs = calloc((size_t)run.nc, sizeof(*sink.cs));
	sink.region_row = cam->region_map ? malloc(sizeof(float) * (size_t)W) : NULL;
	if (!sink.preview || !sink.cs || (cam->region_map && !sink.region_row)) {
		rc = kg_fail(err, KG_ENOMEM, "classify: out of memory");
		goto out;
	}
	sink.reg.on = cam->regions || cam->region_map;
	sink.reg.user = cam->region_map != NULL;
	sink.reg.user_scale = cam->region_scale > 0 ? cam->region_scale : 1.0;
	sink.reg.user_name = cam->region_map_name;
	sink.reg.nm = nm;
	sink.reg.width = W;
	if (sink.reg.on) {
		sink.reg.prev = malloc(sizeof(run_seg) * ((size_t)W + 1));
		sink.reg.cur = malloc(sizeof(run_seg) * ((size_t)W + 1));
		sink.reg.q999 = calloc(1001, sizeof(double));
		if (!sink.reg.prev || !sink.reg.cur || !sink.reg.q999) {
			rc = kg_fail(err, KG_ENOMEM, "classify: out of memory");
			goto out;
		}
		if (sink.reg.user) {
			if ((rc = regions_grow(&sink.reg, MAX_USER_REGIONS, err)))
				goto out;
			for (uint32_t id = 0; id < MAX_USER_REGIONS; id++)
				new_id(&sink.reg, 0);
		}
	}
	char desc[200];
	snprintf(desc, sizeof(desc), "kogei classify: camera-space matching, %d materials in %d "
	         "classes, angles %g-%g deg, intensity %g-%g", nm, run.nc, cam->angle_from,
	         cam->angle_to, cam->intensity_lo, cam->intensity_hi);
	if ((rc = ap_open_label_map(out_hdr, W, H, &classes,
	                            opt->description ? opt->description : desc, &ws[0], err)))
		goto out;
	const char *band[4] = {"margin", "posterior", "angle_deg", "intensity"};
	if ((rc = ap_open_floats(conf_path, W, H, 4,
	                         "kogei classify confidence (camera space): margin = d2 of the "
	                         "runner-up class minus the chosen class's; posterior of the "
	                         "chosen class; the best material's fitted incidence angle "
	                         "(degrees) and intensity; NaN for unclassified, unknown and "
	                         "background pixels",
	                         band, &ws[1], err)))
		goto out;
	paths[1] = conf_path;
	if ((rc = ap_open_mask(out_hdr, W, H, &mask_path, &ws[2], err)))
		goto out;
	paths[2] = mask_path;
	int nws = 3;
	if (cam->composition_hdr) {
		if (!run.metals) {
			rc = kg_fail(err, KG_EINVAL, "%s: composition: the library's silver, copper and "
			             "gold are needed", cam->composition_hdr);
			goto out;
		}
		const char *cband[6] = {"ag", "cu", "au", "sd_ag", "sd_cu", "sd_au"};
		if ((rc = ap_open_floats(cam->composition_hdr, W, H, 6,
		                         "kogei classify composition: Ag, Cu, Au fractions and their "
		                         "Cramer-Rao standard deviations, fitted in camera space; NaN "
		                         "where not fitted, and au where its sd is not below the "
		                         "declared materials' range of gold fractions",
		                         cband, &ws[3], err)))
			goto out;
		paths[3] = cam->composition_hdr;
		nws = 4;
	}

	kg_est_job job;
	kg_est_job_init(&job, NULL, KG_EST_LABELS);
	ap_feed_job(&run.in, &job);
	run.base = job.in_bytes / sizeof(float);
	job.in_bytes += sizeof(float) * extra_floats(nm);
	job.compute = cam_compute;
	job.compute_user = &run;
	job.threads = opt->threads;
	job.block_rows = opt->block_rows;
	sink.labels = ws[0];
	sink.conf = ws[1];
	sink.mask = ws[2];
	sink.comp = ws[3];
	sink.run = &run;
	sink.region_map = cam->region_map;
	sink.nclasses = run.nc;
	sink.height = H;
	ap_progress_init(&sink.prog, opt, "classify", W, H);
	rc = kg_est_run_stream(&job, NULL, W, H, cam_sink_fn, &sink, &local.stats, err);
	if (rc) {
		kg_err_prefix(err, "%s: ", out_hdr);
		goto out;
	}
	if ((rc = ap_check_estimable(&local.stats, &run.in, "classify", err)))
		goto out;
	if ((rc = ap_finish_all(ws, paths, nws, &done, err)))
		goto out;
	if ((rc = ap_margin_pass(sink.cs, run.nc, out_hdr, conf_path, 4, W, H, err)) ||
	    (rc = ap_summarise(k, &classes, sink.count, sink.cs, (size_t)W * H, &local, err)))
		goto out;
	int have_regions = sink.reg.on && !sink.reg.overflow;
	if (have_regions) {
		if ((rc = regions_resolve(&sink.reg, err)) ||
		    (!sink.reg.user &&
		     (rc = write_region_map(&sink.reg, &classes, out_hdr, reg_path, &done, err))) ||
		    (rc = write_region_table(&sink.reg, set, &classes, run.group, run.gold_range,
		                             csv_path, &done, err)))
			goto out;
		local.nregions = (int)sink.reg.nfinal;
	}
	const char *files[6] = {out_hdr, conf_path, mask_path, png_path,
	                        have_regions && !sink.reg.user ? reg_path
	                        : sink.reg.user                ? cam->region_map_name
	                                                       : NULL,
	                        have_regions ? csv_path : NULL};
	if ((rc = write_json(json_path, set, &classes, run.group, cam, copt, model, &sv, sep,
	                     merge_d, src, opt, info, files, &sink.reg, &local, run.threshold,
	                     &run, err)))
		goto out;
	ap_written_add(&done, json_path);
	if ((rc = ap_write_preview(png_path, &classes, sink.preview, sink.pw, sink.ph, &local,
	                           !copt->preview_no_legend,
	                           err)))
		goto out;
	ap_written_add(&done, png_path);

out:
	for (int i = 0; i < 4; i++)
		if (ws[i])
			kg_envi_writer_abort(&ws[i]);
	ap_written_clear(&done, rc != 0);
	if (rc == 0 && res)
		*res = local;
	else
		kg_classify_result_free(&local);
	ap_class_stats_free(sink.cs, run.nc);
	free(sink.preview);
	free(sink.stage.v);
	free(sink.conf4);
	free(sink.region_row);
	regions_free(&sink.reg);
	set_free_classes(&classes);
	kg_cs_model_free(&model);
	kg_cs_model_free(&metals);
	free(sep);
	free(conf_path);
	free(mask_path);
	free(json_path);
	free(png_path);
	free(reg_path);
	free(csv_path);
	return rc;
}
