/* The tagless detector at reduced resolution: mcc runs on a copy averaged over f x f
 * blocks, and its box is refined on the patch edges at full resolution. */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"

#if KG_HAVE_MCC

/* ---- tagless at reduced resolution -------------------------------------------- */

typedef struct decimate_job {
	const work_image *wi;
	int f, w, h;
	float *out;
	int failed[MAX_THREADS];
} decimate_job;

static void decimate_rows(void *arg, int t, int n)
{
	decimate_job *j = arg;
	const work_image *wi = j->wi;
	int C = wi->channels, f = j->f, w = j->w;
	float *scratch = malloc((size_t)w * f * 3 * sizeof(float));
	double *acc = malloc((size_t)w * C * sizeof(double));
	if (!scratch || !acc) {
		j->failed[t] = 1;
		free(scratch);
		free(acc);
		return;
	}
	for (int oy = (int)((long)j->h * t / n); oy < (int)((long)j->h * (t + 1) / n); oy++) {
		memset(acc, 0, (size_t)w * C * sizeof(double));
		for (int dy = 0; dy < f; dy++) {
			if (C == 3 && !wi->data && wi->u16) {
				/* a mapped image: the same sums of the same floats, read from its
				 * codes without a copy of the row */
				const uint16_t *q = wi->u16 + (size_t)(oy * f + dy) * wi->width * 3;
				const float *lut = wi->lut;
				for (int ox = 0; ox < w; ox++) {
					const uint16_t *p = q + (size_t)ox * f * 3;
					double *a = acc + (size_t)ox * 3, a0 = a[0], a1 = a[1], a2 = a[2];
					for (int dx = 0; dx < f; dx++, p += 3) {
						a0 += lut[p[0]];
						a1 += lut[p[1]];
						a2 += lut[p[2]];
					}
					a[0] = a0;
					a[1] = a1;
					a[2] = a2;
				}
				continue;
			}
			const float *row = chart_image_span(wi, oy * f + dy, 0, w * f, 1, scratch);
			if (C == 3) {
				/* the same sums in the same order, kept in registers over a block */
				for (int ox = 0; ox < w; ox++) {
					const float *p = row + (size_t)ox * f * 3;
					double *a = acc + (size_t)ox * 3, a0 = a[0], a1 = a[1], a2 = a[2];
					for (int dx = 0; dx < f; dx++, p += 3) {
						a0 += p[0];
						a1 += p[1];
						a2 += p[2];
					}
					a[0] = a0;
					a[1] = a1;
					a[2] = a2;
				}
				continue;
			}
			for (int ox = 0; ox < w; ox++)
				for (int dx = 0; dx < f; dx++)
					for (int c = 0; c < C; c++)
						acc[(size_t)ox * C + c] += row[((size_t)ox * f + dx) * C + c];
		}
		float *o = j->out + (size_t)oy * w * C;
		for (int i = 0; i < w * C; i++)
			o[i] = (float)(acc[i] / ((double)f * f));
	}
	free(scratch);
	free(acc);
}

/* The image averaged over f x f blocks (the last W mod f columns and H mod f rows are
 * left out): pixel (i, j) covers [i f, (i + 1) f) x [j f, (j + 1) f) of the original,
 * so a position x in it is x f in the original. Raw frames are demosaiced row by row
 * on the way. NULL when out of memory. */
float *chart_decimate_image(const work_image *wi, int f, int *w, int *h)
{
	decimate_job j = {wi, f, wi->width / f, wi->height / f, NULL, {0}};
	j.out = malloc((size_t)j.w * j.h * wi->channels * sizeof(float));
	if (!j.out)
		return NULL;
	chart_run_parallel(decimate_rows, &j, wi->threads);
	for (int t = 0; t < MAX_THREADS; t++)
		if (j.failed[t]) {
			free(j.out);
			return NULL;
		}
	*w = j.w;
	*h = j.h;
	return j.out;
}

/* The image at (X, Y) px (pixel centres at +0.5) by bilinear interpolation, clamped
 * at the edges, as 3 channels (grey repeated). */
static void image_bilinear(const work_image *wi, double X, double Y, double out[3])
{
	float scratch[12];
	int W = wi->width, Hh = wi->height, C = wi->channels;
	double fx = X - 0.5, fy = Y - 0.5;
	fx = fx < 0 ? 0 : fx > W - 1 ? W - 1 : fx;
	fy = fy < 0 ? 0 : fy > Hh - 1 ? Hh - 1 : fy;
	int x0 = (int)fx < W - 1 ? (int)fx : W - 2, y0 = (int)fy < Hh - 1 ? (int)fy : Hh - 2;
	double ax = fx - x0, ay = fy - y0;
	const float *r0 = chart_image_span(wi, y0, x0, 2, 1, scratch);
	const float *r1 = chart_image_span(wi, y0 + 1, x0, 2, 1, scratch + 6);
	for (int c = 0; c < 3; c++) {
		int k = C == 3 ? c : 0;
		out[c] = (1 - ay) * ((1 - ax) * r0[k] + ax * r0[C + k]) +
		         ay * ((1 - ax) * r1[k] + ax * r1[C + k]);
	}
}

enum { EDGE_SAMPLES = 401, EDGE_ACROSS = 7 };

/* Where a patch edge crosses one profile: from e (mm, the edge as placed) along the
 * outward normal nrm over [-R, R] mm in steps of `step`, each sample the mean of
 * EDGE_ACROSS points over +-across mm along the edge (tan). The edge is the first
 * local maximum of the gradient (summed over the channels) from the inside that
 * reaches half the profile's largest and min_grad, to a fraction of a step by a
 * parabola: the patch's own edge comes before the gap and a neighbour's edge beyond
 * it. 1 and *t (mm along nrm), or 0 when no edge stands out. */
static int edge_on_profile(const work_image *wi, const double H[9], const double e[2],
                           const double nrm[2], const double tan[2], double R, double step,
                           double across, double min_grad, double *t)
{
	double prof[EDGE_SAMPLES][3], g[EDGE_SAMPLES];
	int ns = (int)(2 * R / step) + 1;
	if (ns > EDGE_SAMPLES)
		ns = EDGE_SAMPLES;
	if (ns < 5)
		return 0;
	for (int i = 0; i < ns; i++) {
		double s = -R + i * step, acc[3] = {0, 0, 0};
		for (int a = 0; a < EDGE_ACROSS; a++) {
			double d = across * (2.0 * a / (EDGE_ACROSS - 1) - 1), px[2], v[3];
			kg_homography_map(H, e[0] + nrm[0] * s + tan[0] * d, e[1] + nrm[1] * s + tan[1] * d,
			                  px);
			image_bilinear(wi, px[0], px[1], v);
			for (int c = 0; c < 3; c++)
				acc[c] += v[c];
		}
		for (int c = 0; c < 3; c++)
			prof[i][c] = acc[c] / EDGE_ACROSS;
	}
	double gmax = 0;
	g[0] = g[ns - 1] = 0;
	for (int i = 1; i < ns - 1; i++) {
		g[i] = 0;
		for (int c = 0; c < 3; c++)
			g[i] += fabs(prof[i + 1][c] - prof[i - 1][c]);
		gmax = fmax(gmax, g[i]);
	}
	if (!(gmax >= min_grad))
		return 0;
	for (int i = 2; i < ns - 2; i++) {
		if (g[i] < 0.5 * gmax || g[i] < g[i - 1] || g[i] < g[i + 1])
			continue;
		double den = g[i - 1] - 2 * g[i] + g[i + 1];
		double d = den < 0 ? 0.5 * (g[i - 1] - g[i + 1]) / den : 0;
		*t = -R + (i + d) * step;
		return 1;
	}
	return 0;
}

/* One pass's profiles: 3 across each side of each of the 24 patches, each found or
 * not, in slots by (patch, side, place), so the points keep one order whatever the
 * threads. */
typedef struct profile_job {
	const work_image *wi;
	const layout_view *L;
	const int *idx;
	const double *H;
	double R, step, white;
	int found[24 * 4 * 3];
	double src[24 * 4 * 3][2], dst[24 * 4 * 3][2];
} profile_job;

/* Thread t takes patches t, t + n, ... */
static void profile_patches(void *arg, int t, int n)
{
	profile_job *j = arg;
	for (int i = t; i < 24; i += n) {
		const double *c = j->L->patch_center[j->idx[i]], *s = j->L->patch_size[j->idx[i]];
		for (int k = 0; k < 4; k++) {
			double nrm[2] = {k == 0 ? -1 : k == 1 ? 1 : 0, k == 2 ? -1 : k == 3 ? 1 : 0};
			double tan[2] = {nrm[1], nrm[0]};
			double half_n = 0.5 * (k < 2 ? s[0] : s[1]), half_t = 0.5 * (k < 2 ? s[1] : s[0]);
			for (int q = -1; q <= 1; q++) {
				int slot = (i * 4 + k) * 3 + q + 1;
				double e[2] = {c[0] + nrm[0] * half_n + tan[0] * 0.6 * q * half_t,
				               c[1] + nrm[1] * half_n + tan[1] * 0.6 * q * half_t};
				double d;
				j->found[slot] = edge_on_profile(j->wi, j->H, e, nrm, tan, j->R, j->step,
				                                 0.15 * half_t, 0.02 * j->white, &d);
				if (!j->found[slot])
					continue;
				memcpy(j->src[slot], e, sizeof(e));
				kg_homography_map(j->H, e[0] + nrm[0] * d, e[1] + nrm[1] * d, j->dst[slot]);
			}
		}
	}
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return (x > y) - (x < y);
}

/* Refine the chart's placement H (mm -> px, from mcc's box on the reduced image) on
 * the patch edges at full resolution: three profiles across each side of each of the
 * 24 patches give points of known layout position (the side as the layout draws it,
 * at the profile's place along it); H is fitted to them (DLT and Levenberg-Marquardt),
 * points farther than max(0.5 px, 3 x their median) dropped and H refitted, twice,
 * the second time searching half as far. The layout's patch sides need not be the
 * printed ones: a side found outside on the left is found outside on the right too,
 * and the fit keeps the centres. Returns the points used (0: H is left as it was,
 * fewer than 12 edges found or the fit moved a patch centre by more than the search
 * range), and their RMS distance in px. */
int chart_refine_on_edges(const work_image *wi, const layout_view *L, const int idx[24],
                           double white, double H[9], double *rms)
{
	enum { MAXP = 24 * 4 * 3 };
	double src[MAXP][2], dst[MAXP][2], pc[2], pd[2];
	const double *a1 = L->patch_center[idx[0]], *a2 = L->patch_center[idx[1]];
	double pitch = hypot(a2[0] - a1[0], a2[1] - a1[1]);
	double side = fmin(L->patch_size[idx[0]][0], L->patch_size[idx[0]][1]);
	double gap = fmax(pitch - side, 0);
	double R = fmin(fmax(0.5 * gap, 0.12 * pitch), 0.45 * side);
	kg_homography_map(H, a1[0], a1[1], pc);
	kg_homography_map(H, a2[0], a2[1], pd);
	double px_per_mm = hypot(pd[0] - pc[0], pd[1] - pc[1]) / pitch;
	if (!(px_per_mm > 0) || !(R > 0))
		return 0;
	double Hk[9];
	memcpy(Hk, H, sizeof(Hk));
	int used = 0;
	for (int pass = 0; pass < 2; pass++, R *= 0.5) {
		double step = fmax(0.5 / px_per_mm, 2 * R / (EDGE_SAMPLES - 1));
		int n = 0;
		profile_job *job = malloc(sizeof(*job));
		if (!job)
			goto done;
		*job = (profile_job){.wi = wi, .L = L, .idx = idx, .H = Hk, .R = R, .step = step,
		                     .white = white};
		chart_run_parallel(profile_patches, job, wi->threads);
		for (int m = 0; m < MAXP; m++)
			if (job->found[m]) {
				memcpy(src[n], job->src[m], sizeof(src[n]));
				memcpy(dst[n], job->dst[m], sizeof(dst[n]));
				n++;
			}
		free(job);
		double Hn[9], r = 0;
		for (int round = 0; round < 2; round++) {
			kg_err tmp;
			if (n < 12 || kg_homography_fit((const double (*)[2])src, (const double (*)[2])dst,
			                                n, 1, Hn, &r, &tmp))
				goto done;
			double d[MAXP], sorted[MAXP];
			for (int m = 0; m < n; m++) {
				double q[2];
				kg_homography_map(Hn, src[m][0], src[m][1], q);
				sorted[m] = d[m] = hypot(q[0] - dst[m][0], q[1] - dst[m][1]);
			}
			qsort(sorted, (size_t)n, sizeof(double), cmp_double);
			double keep = fmax(0.5, 3 * sorted[n / 2]);
			int w = 0;
			for (int m = 0; m < n; m++)
				if (d[m] <= keep) {
					memcpy(src[w], src[m], sizeof(src[w]));
					memcpy(dst[w], dst[m], sizeof(dst[w]));
					w++;
				}
			n = w;
		}
		for (int i = 0; i < 24; i++) {
			double p0[2], p1[2];
			kg_homography_map(Hk, L->patch_center[idx[i]][0], L->patch_center[idx[i]][1], p0);
			kg_homography_map(Hn, L->patch_center[idx[i]][0], L->patch_center[idx[i]][1], p1);
			if (!(hypot(p1[0] - p0[0], p1[1] - p0[1]) <= R * px_per_mm))
				goto done;
		}
		memcpy(Hk, Hn, sizeof(Hk));
		used = n;
		*rms = r;
	}
done:
	if (used)
		memcpy(H, Hk, sizeof(Hk));
	return used;
}

#endif
