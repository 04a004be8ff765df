/* Camera-space label maps: the per-pixel noise, the planes of a block, and the survey
 * of the capture's noise before the run (with the materials' separability at it). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "labels_cam_private.h"

/* ---- the per-pixel noise ------------------------------------------------------------ */

static const int cov_ia[6] = {0, 0, 0, 1, 1, 2}, cov_ib[6] = {0, 1, 2, 1, 2, 2};

/* nz->P from nz->M2 */
void lc_noise_products(noise *nz)
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
void lc_pixel_noise(const noise *nz, const float *rho, const float *var, double x[3],
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

size_t lc_extra_floats(int nm) { return 3 + 6 + 5 + 6 + 1 + (size_t)nm; }

cam_planes lc_cam_planes_of(const cam_run *r, void *in, size_t n)
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

/* ---- the noise survey -------------------------------------------------------------- */

int lc_survey(const cam_run *r, const kg_classify_camera *cam, const kg_cs_model *m,
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
		lc_pixel_noise(&r->nz, rho, NULL, x, c);
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
int lc_separability(const cam_run *r, const kg_cs_model *m, const survey_result *sv,
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

/* Each material's separability from the neutral-diffuse alternative (a flat
 * reflectance at any level, run->white times a positive scale): over the material's
 * angles, its reading at the survey's level with that reading's own covariance (as in
 * lc_separability), the least whitened distance to the flat ray. +Inf where the
 * alternative is not offered: without it (--no-neutral), and for a metal or alloy one
 * of whose readings lies within the unknown bound of a flat one (the per-pixel step then
 * keeps its pixels the metal's: a near-neutral metal and a grey surface as bright are
 * not told apart by colour). */
static double dot3(const double *a, const double *b)
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

int lc_flat_separability(const cam_run *r, const kg_cs_model *m, const survey_result *sv,
                         double *d, kg_err *err)
{
	double Mi[9];
	if (kg_mat3_inverse(r->nz.M2, Mi))
		return kg_fail(err, KG_EINVAL, "M2: expected an invertible 3 x 3 matrix (the site "
		               "calibration's), got a singular one");
	for (int i = 0; i < m->n; i++) {
		double best = INFINITY;
		for (int k = 0; r->neutral && k < m->nangles; k++) {
			const double *mu = m->mu + 3 * ((size_t)i * m->nangles + k);
			double x[3], rho[3], v[3], C[9], Ci[9];
			for (int a = 0; a < 3; a++)
				x[a] = sv->level * mu[a];
			for (int a = 0; a < 3; a++)
				rho[a] = dot3(Mi + 3 * a, x);
			for (int c = 0; c < 3; c++) {
				double p = rho[c] > 0 ? rho[c] : 0;
				v[c] = sv->va[c] + sv->vb[c] * p + sv->vc[c] * p * p;
			}
			double l2 = dot3(x, x) / 3.0;
			const double *M2 = r->nz.M2;
			for (int a = 0; a < 3; a++)
				for (int b = 0; b < 3; b++) {
					double s = 0;
					for (int c = 0; c < 3; c++)
						s += M2[3 * a + c] * M2[3 * b + c] * v[c];
					C[3 * a + b] = s + l2 * r->nz.R[3 * a + b];
				}
			if (kg_mat3_inverse(C, Ci))
				continue;
			const double *w = r->white;
			double Cw[3], Cx[3];
			for (int a = 0; a < 3; a++) {
				Cw[a] = dot3(Ci + 3 * a, w);
				Cx[a] = dot3(Ci + 3 * a, x);
			}
			double ww = dot3(w, Cw), wx = dot3(x, Cw), xx = dot3(x, Cx);
			if (!(ww > 0))
				continue;
			/* a positive best level: the flat reading nearest x; else the origin */
			double d2 = wx > 0 ? xx - wx * wx / ww : xx;
			d2 = d2 > 0 ? d2 : 0;
			if (r->metal[i] && d2 <= r->threshold) {
				best = INFINITY;
				break;
			}
			best = fmin(best, sqrt(d2));
		}
		d[i] = best;
	}
	return 0;
}
