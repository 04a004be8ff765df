/* Slanted-edge SFR (ISO 12233) and colour channel misregistration (sfr.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sfr.h"

#define BIN (1.0 / KG_SFR_OVERSAMPLE) /* px */
#define FSTEP 0.0025                  /* cycles/px: the grid the crossings are found on */
#define FMAX 1.0

static double hamming(double x, double half)
{
	if (half <= 0 || fabs(x) >= half)
		return 0.08;
	return 0.54 + 0.46 * cos(M_PI * x / half);
}

/* The LSF window: 1 over the middle half, a Hamming-shaped taper (to 0.08) over the
 * outer quarter each side. A Hamming window over the whole of a narrow band (a tag
 * side's) weighs down the LSF's own tails and raises the MTF; the taper keeps the
 * window's purpose (the ESF's flat-part noise and the band's ends) without that. */
static double taper(double x, double half)
{
	double ax = fabs(x), flat = half / 2;
	if (ax <= flat)
		return 1;
	return hamming(ax - flat, half - flat);
}

static double sinc(double x)
{
	return fabs(x) < 1e-12 ? 1.0 : sin(M_PI * x) / (M_PI * x);
}

/* Sample at across index u, along index t of the region (channel c; c = -1: the
 * mean of the channels). */
typedef struct view {
	const kg_image *img;
	int x0, y0, vertical;
} view;

static double px(const view *v, int u, int t, int c)
{
	int x = v->vertical ? v->x0 + u : v->x0 + t;
	int y = v->vertical ? v->y0 + t : v->y0 + u;
	const float *p = v->img->data + ((size_t)y * v->img->width + x) * v->img->channels;
	if (c >= 0)
		return p[c];
	double s = 0;
	for (int k = 0; k < v->img->channels; k++)
		s += p[k];
	return s / v->img->channels;
}

/* Least squares pos = a + b t over the lines with ok[t]. */
static int fit_line(const double *pos, const int *ok, int n, double *a, double *b,
                    double *rms)
{
	double s = 0, st = 0, sp = 0, stt = 0, stp = 0;
	for (int t = 0; t < n; t++) {
		if (!ok[t])
			continue;
		double tt = t + 0.5;
		s += 1;
		st += tt;
		sp += pos[t];
		stt += tt * tt;
		stp += tt * pos[t];
	}
	double det = s * stt - st * st;
	if (s < 3 || det <= 0)
		return -1;
	*b = (s * stp - st * sp) / det;
	*a = (sp - *b * st) / s;
	double r = 0;
	for (int t = 0; t < n; t++)
		if (ok[t]) {
			double d = pos[t] - (*a + *b * (t + 0.5));
			r += d * d;
		}
	*rms = sqrt(r / s);
	return 0;
}

/* Crossing of level by the curve m on the FSTEP grid, linear between samples. */
static int crossing(const double *m, int n, double level, double *f)
{
	for (int k = 1; k < n; k++)
		if (m[k] < level) {
			double d = m[k - 1] - m[k];
			double fr = d > 0 ? (m[k - 1] - level) / d : 0;
			*f = (k - 1 + fr) * FSTEP;
			return 1;
		}
	*f = (n - 1) * FSTEP;
	return 0;
}

int kg_sfr_measure(const kg_image *img, const kg_sfr_roi *roi, kg_sfr_result *out,
                   kg_err *err)
{
	kg_check_arg(img && roi && out, err);
	kg_check_arg(img->channels == 1 || img->channels == 3, err);
	memset(out, 0, sizeof *out);
	const char *ctx = "sfr";
	if (roi->w < 8 || roi->h < 8 || roi->x < 0 || roi->y < 0 ||
	    roi->x + roi->w > img->width || roi->y + roi->h > img->height)
		return kg_fail(err, KG_EINVAL,
		               "%s: region %d,%d,%d,%d: expected at least 8 x 8 px inside the "
		               "%d x %d image", ctx, roi->x, roi->y, roi->w, roi->h, img->width,
		               img->height);
	if (roi->has_line && !(roi->half_width >= 2))
		return kg_fail(err, KG_EINVAL, "%s: region %d,%d,%d,%d: half_width %g: expected "
		               "at least 2 px", ctx, roi->x, roi->y, roi->w, roi->h,
		               roi->half_width);
	view v = {img, roi->x, roi->y, 1};
	double pa = 0, pb = 0; /* prior line: across = pa + pb * along, region coordinates */
	if (roi->has_line) {
		double dx = roi->p1[0] - roi->p0[0], dy = roi->p1[1] - roi->p0[1];
		v.vertical = fabs(dy) >= fabs(dx);
		double du = v.vertical ? dx : dy, dt = v.vertical ? dy : dx;
		if (dt == 0)
			return kg_fail(err, KG_EINVAL, "%s: region %d,%d,%d,%d: the edge's end points "
			               "coincide", ctx, roi->x, roi->y, roi->w, roi->h);
		pb = du / dt;
		double u0 = (v.vertical ? roi->p0[0] - roi->x : roi->p0[1] - roi->y);
		double t0 = (v.vertical ? roi->p0[1] - roi->y : roi->p0[0] - roi->x);
		pa = u0 - pb * t0;
	} else {
		double gx = 0, gy = 0;
		for (int y = 0; y + 1 < roi->h; y++)
			for (int x = 0; x + 1 < roi->w; x++) {
				double c = px(&v, x, y, -1);
				gx += fabs(px(&v, x + 1, y, -1) - c);
				gy += fabs(px(&v, x, y + 1, -1) - c);
			}
		v.vertical = gx >= gy;
	}
	int W = v.vertical ? roi->w : roi->h; /* across */
	int L = v.vertical ? roi->h : roi->w; /* along */
	int nch = img->channels;
	int rc = KG_EINVAL;
	double *pos = malloc(sizeof(double) * L);
	int *ok = malloc(sizeof(int) * L);
	int nb_max = 4 * KG_SFR_OVERSAMPLE * (W + 2);
	double *sum = calloc((size_t)nb_max * (nch + 1), sizeof(double));
	double *sq = calloc((size_t)nb_max * (nch + 1), sizeof(double));
	long *cnt = calloc((size_t)nb_max, sizeof(long));
	double *lsf = malloc(sizeof(double) * nb_max);
	int nf = (int)lround(FMAX / FSTEP) + 1;
	double *m = malloc(sizeof(double) * nf);
	if (!pos || !ok || !sum || !sq || !cnt || !lsf || !m) {
		rc = kg_fail(err, KG_ENOMEM, "%s: out of memory", ctx);
		goto done;
	}

	/* the edge's polarity over the region (or the band) */
	double sgn = 0;
	for (int t = 0; t < L; t++)
		for (int u = 0; u + 1 < W; u++) {
			if (roi->has_line && fabs(u + 1 - (pa + pb * (t + 0.5))) > roi->half_width)
				continue;
			sgn += px(&v, u + 1, t, -1) - px(&v, u, t, -1);
		}
	sgn = sgn >= 0 ? 1 : -1;

	/* per line: centroid of the derivative; twice, windowed about the first fit */
	double a = pa, b = pb, rms = 0;
	int have = roi->has_line;
	for (int pass = 0; pass < 3; pass++) {
		double half = roi->has_line ? roi->half_width : W / 2.0;
		for (int t = 0; t < L; t++) {
			double c = a + b * (t + 0.5);
			double s0 = 0, s1 = 0;
			for (int u = 0; u + 1 < W; u++) {
				double at = u + 1; /* between the centres of u and u + 1 */
				double w = 1;
				if (have) {
					if (fabs(at - c) > half)
						continue;
					if (pass > 0 || roi->has_line)
						w = hamming(at - c, half);
				}
				double dv = sgn * (px(&v, u + 1, t, -1) - px(&v, u, t, -1)) * w;
				s0 += dv;
				s1 += dv * at;
			}
			ok[t] = s0 > 0;
			pos[t] = ok[t] ? s1 / s0 : 0;
		}
		if (fit_line(pos, ok, L, &a, &b, &rms) != 0) {
			rc = kg_fail(err, KG_EINVAL, "%s: region %d,%d,%d,%d: no edge: fewer than 3 "
			             "lines show a step", ctx, roi->x, roi->y, roi->w, roi->h);
			goto done;
		}
		have = 1;
	}
	int used = 0;
	for (int t = 0; t < L; t++)
		used += ok[t];
	double angle = atan(b) * 180 / M_PI;
	out->vertical = v.vertical;
	out->angle_deg = v.vertical ? -angle : angle;
	out->fit_rms = rms;
	out->lines = used;
	if (rms > 0.5 || used < L / 2) {
		rc = kg_fail(err, KG_EINVAL, "%s: region %d,%d,%d,%d: no straight edge: the edge "
		             "positions of %d of %d lines scatter %.2f px about a line (expected "
		             "at most 0.5 px)", ctx, roi->x, roi->y, roi->w, roi->h, used, L, rms);
		goto done;
	}
	if (fabs(angle) < KG_SFR_MIN_ANGLE || fabs(angle) > KG_SFR_MAX_ANGLE) {
		rc = kg_fail(err, KG_EINVAL, "%s: region %d,%d,%d,%d: the edge is slanted %.2f "
		             "degrees from the image axis (expected %g to %g)", ctx, roi->x,
		             roi->y, roi->w, roi->h, fabs(angle), KG_SFR_MIN_ANGLE,
		             KG_SFR_MAX_ANGLE);
		goto done;
	}
	/* the across range every line covers */
	double hw = 1e30;
	for (int t = 0; t < L; t++) {
		double c = a + b * (t + 0.5);
		hw = fmin(hw, fmin(c, W - c));
	}
	if (roi->has_line)
		hw = fmin(hw, roi->half_width);
	if (hw < 4) {
		rc = kg_fail(err, KG_EINVAL, "%s: region %d,%d,%d,%d: the edge passes within %.1f "
		             "px of the region's side (expected 4 px of flat either side)", ctx,
		             roi->x, roi->y, roi->w, roi->h, hw < 0 ? 0 : hw);
		goto done;
	}
	double cs = cos(atan(b));
	double R = hw * cs; /* perpendicular */
	int nb = 2 * (int)floor(R / BIN);
	if (nb > nb_max)
		nb = nb_max;
	double r0 = -nb / 2 * BIN; /* left edge of bin 0 */
	long npix = 0;
	for (int t = 0; t < L; t++) {
		double c = a + b * (t + 0.5);
		for (int u = 0; u < W; u++) {
			double dd = (u + 0.5 - c) * cs;
			int k = (int)floor((dd - r0) / BIN);
			if (k < 0 || k >= nb || fabs(u + 0.5 - c) > hw)
				continue;
			for (int ch = 0; ch <= nch; ch++) {
				double val = px(&v, u, t, ch < nch ? ch : -1);
				sum[(size_t)ch * nb_max + k] += val;
				sq[(size_t)ch * nb_max + k] += val * val;
				if (ch < nch && (npix == 0 || val > out->peak[ch]))
					out->peak[ch] = val;
			}
			cnt[k]++;
			npix++;
		}
	}
	out->pixels = npix;
	int empty = 0;
	for (int k = 0; k < nb; k++)
		empty += cnt[k] == 0;
	if (empty > nb / 10) {
		rc = kg_fail(err, KG_EINVAL, "%s: region %d,%d,%d,%d: %d of %d bins of 1/%d px "
		             "are empty (expected a longer edge or a larger slant)", ctx, roi->x,
		             roi->y, roi->w, roi->h, empty, nb, KG_SFR_OVERSAMPLE);
		goto done;
	}
	out->length = used / cs;
	double tc = L / 2.0, uc = a + b * tc;
	out->centre[0] = v.vertical ? roi->x + uc : roi->x + tc;
	out->centre[1] = v.vertical ? roi->y + tc : roi->y + uc;
	out->channels = nch;

	/* the window for the edge positions: 3 times the 10-90 % rise of the mean
	 * channel's ESF (at least 4 px), in bins; a centroid over the whole band would
	 * gather the flat parts' noise */
	double wpos;
	{
		const double *s = sum + (size_t)nch * nb_max;
		int qn = nb / 4, k50 = -1;
		double lo = 0, hi = 0;
		for (int k = 0; k < qn; k++) {
			lo += cnt[k] ? s[k] / cnt[k] : 0;
			hi += cnt[nb - 1 - k] ? s[nb - 1 - k] / cnt[nb - 1 - k] : 0;
		}
		lo /= qn;
		hi /= qn;
		/* normalised ESF value of bin k (rises from 0 to 1) */
#define ESFN(k) (cnt[k] ? (s[k] / cnt[k] - lo) / (hi - lo) : NAN)
		for (int k = 0; k + 1 < nb; k++)
			if (ESFN(k) < 0.5 && ESFN(k + 1) >= 0.5 &&
			    (k50 < 0 || abs(k - nb / 2) < abs(k50 - nb / 2)))
				k50 = k;
		int k10 = k50 < 0 ? 0 : k50, k90 = k50 < 0 ? nb - 1 : k50;
		while (k10 > 0 && !(ESFN(k10) <= 0.1))
			k10--;
		while (k90 < nb - 1 && !(ESFN(k90) >= 0.9))
			k90++;
		/* the 10-90 % rise, the crossings interpolated between bins */
		double x10 = k10, x90 = k90;
		if (k10 + 1 < nb && ESFN(k10) <= 0.1 && ESFN(k10 + 1) > ESFN(k10))
			x10 = k10 + (0.1 - ESFN(k10)) / (ESFN(k10 + 1) - ESFN(k10));
		if (k90 > 0 && ESFN(k90) >= 0.9 && ESFN(k90) > ESFN(k90 - 1))
			x90 = k90 - (ESFN(k90) - 0.9) / (ESFN(k90) - ESFN(k90 - 1));
#undef ESFN
		wpos = fmax(3.0 * (k90 - k10), 4.0 * KG_SFR_OVERSAMPLE);
		out->rise = (x90 - x10) * BIN;
		out->band = R;
	}
	for (int ch = 0; ch < nch; ch++) {
		double *s = sum + (size_t)ch * nb_max, *q = sq + (size_t)ch * nb_max;
		double *e = malloc(sizeof(double) * nb);
		if (!e) {
			rc = kg_fail(err, KG_ENOMEM, "%s: out of memory", ctx);
			goto done;
		}
		for (int k = 0; k < nb; k++)
			e[k] = cnt[k] ? s[k] / cnt[k] : NAN;
		for (int k = 0; k < nb; k++) /* empty bins: from the nearest filled ones */
			if (isnan(e[k])) {
				int lo = k - 1, hi = k + 1;
				while (lo >= 0 && isnan(e[lo]))
					lo--;
				while (hi < nb && cnt[hi] == 0)
					hi++;
				if (lo < 0)
					e[k] = e[hi];
				else if (hi >= nb)
					e[k] = e[lo];
				else
					e[k] = e[lo] + (e[hi] - e[lo]) * (k - lo) / (double)(hi - lo);
			}
		/* flat parts: the outer quarter each side */
		int qn = nb / 4;
		double lo = 0, hi = 0, var = 0;
		long nv = 0;
		for (int k = 0; k < qn; k++) {
			lo += e[k];
			hi += e[nb - 1 - k];
		}
		lo /= qn;
		hi /= qn;
		for (int k = 0; k < nb; k++)
			if ((k < qn || k >= nb - qn) && cnt[k]) {
				var += q[k] - s[k] * s[k] / cnt[k];
				nv += cnt[k];
			}
		kg_sfr_channel *o = &out->ch[ch];
		o->contrast = fabs(hi - lo);
		o->noise = nv > 1 ? sqrt(fmax(var, 0) / (nv - 1)) : 0;
		if (!(o->contrast > 1e-6) || o->contrast < 5 * o->noise) {
			free(e);
			rc = kg_fail(err, KG_EINVAL, "%s: region %d,%d,%d,%d: no edge in channel %d: "
			             "step %.4g against noise %.4g (expected a step of at least 5 "
			             "times the noise)", ctx, roi->x, roi->y, roi->w, roi->h, ch,
			             o->contrast, o->noise);
			goto done;
		}
		/* line spread function, at the bin boundaries k + 1 */
		int n = nb - 1;
		double c0 = 0, c1 = 0;
		for (int k = 0; k < n; k++) {
			lsf[k] = sgn * (e[k + 1] - e[k]);
			c0 += lsf[k];
			c1 += lsf[k] * k;
		}
		free(e);
		double cen = c0 != 0 ? c1 / c0 : n / 2.0;
		/* window about the centroid, then the centroid again for the position */
		c0 = c1 = 0;
		for (int k = 0; k < n; k++) {
			lsf[k] *= taper(k - cen, n / 2.0);
			c0 += lsf[k];
			c1 += lsf[k] * k;
		}
		double cw = c0 != 0 ? c1 / c0 : cen;
		double cp = cw;
		for (int it = 0; it < 4; it++) {
			double p0 = 0, p1 = 0;
			for (int k = 0; k < n; k++) {
				double w = hamming(k - cp, fmin(wpos, n / 2.0));
				if (fabs(k - cp) >= fmin(wpos, n / 2.0))
					continue;
				p0 += lsf[k] * w;
				p1 += lsf[k] * w * k;
			}
			if (p0 > 0)
				cp = p1 / p0;
		}
		o->position = r0 + (cp + 1) * BIN;
		/* DFT at FSTEP cycles/px, normalised at 0, derivative's sinc removed */
		double f0 = 0;
		for (int k = 0; k < n; k++)
			f0 += lsf[k];
		for (int j = 0; j < nf; j++) {
			double f = j * FSTEP, re = 0, im = 0;
			for (int k = 0; k < n; k++) {
				double ph = 2 * M_PI * f * (k - cw) * BIN;
				re += lsf[k] * cos(ph);
				im -= lsf[k] * sin(ph);
			}
			m[j] = sqrt(re * re + im * im) / fabs(f0) / sinc(f * BIN);
		}
		for (int j = 0; j < KG_SFR_CURVE; j++)
			o->mtf[j] = m[(int)lround(j * (FMAX / (KG_SFR_CURVE - 1)) / FSTEP)];
		crossing(m, nf, 0.5, &o->mtf50);
		o->mtf10_reached = crossing(m, nf, 0.1, &o->mtf10);
		o->efficiency = fmin(o->mtf10 / 0.5, 1.0);
	}
	/* the blur against the band: a band too narrow for the edge's spread cuts off the
	 * LSF's tails (the MTF reads too high) */
	if (!(out->band >= KG_SFR_BAND_RISE * out->rise)) {
		out->too_blurred = 1;
		rc = kg_fail(err, KG_EINVAL, "%s: region %d,%d,%d,%d: too blurred for the band: the "
		             "edge's 10-90 %% rise of %.2f px needs a band of %.2f px either side "
		             "(%g times the rise), the band is %.2f px", ctx, roi->x, roi->y, roi->w,
		             roi->h, out->rise, KG_SFR_BAND_RISE * out->rise, KG_SFR_BAND_RISE,
		             out->band);
		goto done;
	}
	out->mtf10_reached = 1;
	for (int ch = 0; ch < nch; ch++) {
		out->mtf50 += out->ch[ch].mtf50 / nch;
		out->mtf10 += out->ch[ch].mtf10 / nch;
		out->efficiency += out->ch[ch].efficiency / nch;
		out->mtf10_reached &= out->ch[ch].mtf10_reached;
		for (int k = 0; k < ch; k++)
			out->misregistration = fmax(out->misregistration,
			                            fabs(out->ch[ch].position - out->ch[k].position));
	}
	rc = 0;
done:
	free(pos);
	free(ok);
	free(sum);
	free(sq);
	free(cnt);
	free(lsf);
	free(m);
	return rc;
}

int kg_sfr_edge_band(const kg_sfr_edge *e, double half_width, const kg_image *img,
                     kg_sfr_roi *roi)
{
	if (!e || !img || !roi || !(half_width >= 4))
		return -1;
	double a0[2] = {e->roi.p0[0], e->roi.p0[1]}, a1[2] = {e->roi.p1[0], e->roi.p1[1]};
	double hw = half_width;
	int vert = fabs(a1[1] - a0[1]) >= fabs(a1[0] - a0[0]);
	double x0, x1, y0, y1;
	if (vert) {
		x0 = fmin(a0[0], a1[0]) - hw;
		x1 = fmax(a0[0], a1[0]) + hw;
		y0 = fmin(a0[1], a1[1]);
		y1 = fmax(a0[1], a1[1]);
	} else {
		y0 = fmin(a0[1], a1[1]) - hw;
		y1 = fmax(a0[1], a1[1]) + hw;
		x0 = fmin(a0[0], a1[0]);
		x1 = fmax(a0[0], a1[0]);
	}
	kg_sfr_roi ro;
	memset(&ro, 0, sizeof ro);
	/* the whole band inside the region (pixels beyond it are not used) */
	ro.x = (int)floor(x0);
	ro.y = (int)floor(y0);
	ro.w = (int)ceil(x1) - ro.x;
	ro.h = (int)ceil(y1) - ro.y;
	if (ro.x < 0 || ro.y < 0 || ro.x + ro.w > img->width || ro.y + ro.h > img->height ||
	    ro.w < 8 || ro.h < 8)
		return -1;
	ro.has_line = 1;
	memcpy(ro.p0, a0, sizeof a0);
	memcpy(ro.p1, a1, sizeof a1);
	ro.half_width = hw;
	*roi = ro;
	return 0;
}

int kg_sfr_find_edges(const kg_chart_layout *l, const kg_chart_result *r,
                      const kg_image *img, double min_length_px, kg_sfr_edge **edges,
                      int *n, kg_err *err)
{
	kg_check_arg(l && r && img && edges && n, err);
	*edges = NULL;
	*n = 0;
	int border;
	if (l->ntags == 0)
		return kg_fail(err, KG_EINVAL, "sfr: layout %s: no tags (expected AprilTags "
		               "whose edges to measure)", l->name);
	if (strcmp(l->family, "tag36h11") == 0)
		border = 8;
	else if (strcmp(l->family, "tagStandard41h12") == 0)
		border = 5;
	else
		return kg_fail(err, KG_EINVAL, "sfr: layout %s: tag family \"%s\" (expected "
		               "tag36h11 or tagStandard41h12)", l->name, l->family);
	if (min_length_px <= 0)
		min_length_px = 20;
	kg_sfr_edge *e = calloc((size_t)r->ntags * 4 + 1, sizeof *e);
	if (!e)
		return kg_fail(err, KG_ENOMEM, "sfr: out of memory");
	int m = 0;
	for (int i = 0; i < r->ntags; i++) {
		const kg_chart_tag_found *tg = &r->tags[i];
		if (kg_chart_layout_find_tag(l, tg->id) < 0)
			continue;
		double side = 0;
		for (int s = 0; s < 4; s++) {
			const double *p = tg->corners[s], *q = tg->corners[(s + 1) % 4];
			side += hypot(q[0] - p[0], q[1] - p[1]) / 4;
		}
		double cell = side / border;
		for (int s = 0; s < 4; s++) {
			const double *p = tg->corners[s], *q = tg->corners[(s + 1) % 4];
			double dx = q[0] - p[0], dy = q[1] - p[1], len = hypot(dx, dy);
			if (!(len > 0))
				continue;
			double ang = fmod(fabs(atan2(dy, dx)) * 180 / M_PI, 90);
			if (ang > 45)
				ang = 90 - ang;
			if (ang < 2 || ang > 10)
				continue;
			double trim = 0.5 * cell, use = len - 2 * trim;
			double hw = 0.8 * cell;
			if (use < min_length_px || hw < 4)
				continue;
			kg_sfr_edge *ed = &e[m];
			memset(ed, 0, sizeof *ed);
			ed->roi.p0[0] = p[0] + dx / len * trim;
			ed->roi.p0[1] = p[1] + dy / len * trim;
			ed->roi.p1[0] = q[0] - dx / len * trim;
			ed->roi.p1[1] = q[1] - dy / len * trim;
			ed->tag_id = tg->id;
			ed->side = s;
			ed->angle_deg = ang;
			ed->length_px = use;
			ed->cell_px = cell;
			if (kg_sfr_edge_band(ed, hw, img, &ed->roi) == 0)
				m++;
		}
	}
	*edges = e;
	*n = m;
	return 0;
}
