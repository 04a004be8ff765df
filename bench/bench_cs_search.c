/* kogei-bench-cs-search: how much a cheaper search over the angles would change the
 * camera-space matching's results. Every search here is computed in double on the
 * camera-space rows' pixels (bench_camspace.c makes them), and compared with the
 * exhaustive search over every model angle (what both methods of
 * kg_cs_match_block_method compute, in float):
 *   - coarse S, bracket: every S-th angle (and the last), then every angle strictly
 *     between the best coarse angle's two coarse neighbours;
 *   - coarse 2, parabola: every 2nd angle, then the model angle nearest the vertex of
 *     the parabola through the best coarse angle and its two coarse neighbours;
 *   - coarse 2 alone: every 2nd angle (the model of --angles 0:70:10);
 *   - planar: every angle, each prediction replaced by its projection onto the plane
 *     through the origin that fits the material's predictions best (least squares),
 *     so a candidate would cost 5 multiply-adds instead of 9;
 *   - every angle, intensity free: each angle's distance with the intensity unclamped
 *     (a candidate would need no clamps and, unclamped, s = -(p.b)^2 / p^T Q p: a
 *     multiply instead of four operations);
 *   - every angle, intensity >= lo: clamped below only (one clamp fewer).
 * For each search: the candidates it evaluates per material (mean), the share of
 * (pixel, material) pairs it puts at another angle, the pixels whose label differs,
 * and how far the distance at its angle lies above the exhaustive minimum (percentiles
 * over the pairs whose minimum is below 50, the ones that can decide a label or a
 * posterior). A search is only worth building if it evaluates far fewer candidates
 * with no labels changed. Measures, asserts nothing. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_private.h"

#define MAX_ANGLES 64

typedef struct px {
	double l[6]; /* Cholesky factor: l0 l3 l4 l6 l7 l8 (camspace.c's names) */
	double y[3]; /* whitened reading */
} px;

static int px_make(const float *x, const float *c, px *p)
{
	double l0 = sqrt(c[0]), l3 = c[1] / l0, l6 = c[2] / l0;
	double l4 = sqrt(c[3] - l3 * l3), l7 = (c[4] - l6 * l3) / l4;
	double l8 = sqrt(c[5] - l6 * l6 - l7 * l7);
	if (!(l0 > 0 && l4 > 0 && l8 > 0))
		return -1;
	double y0 = x[0] / l0, y1 = (x[1] - l3 * y0) / l4, y2 = (x[2] - l6 * y0 - l7 * y1) / l8;
	*p = (px){{l0, l3, l4, l6, l7, l8}, {y0, y1, y2}};
	return 0;
}

/* The exact distance of prediction mu, intensity clamped to [lo, hi]. */
static double dist(const px *p, const double *mu, double lo, double hi)
{
	const double *l = p->l;
	double v0 = mu[0] / l[0], v1 = (mu[1] - l[1] * v0) / l[2];
	double v2 = (mu[2] - l[3] * v0 - l[4] * v1) / l[5];
	double a = (v0 * p->y[0] + v1 * p->y[1] + v2 * p->y[2]) / (v0 * v0 + v1 * v1 + v2 * v2);
	a = a < lo ? lo : a > hi ? hi : a;
	double e0 = p->y[0] - a * v0, e1 = p->y[1] - a * v1, e2 = p->y[2] - a * v2;
	return e0 * e0 + e1 * e1 + e2 * e2;
}

/* The best-fit plane through the origin of material j's predictions: the normal is the
 * eigenvector of least eigenvalue of G = sum p p^T (the smallest singular direction). */
static void plane_normal(const kg_cs_model *m, int j, double nrm[3])
{
	double G[9] = {0};
	for (int k = 0; k < m->nangles; k++) {
		const double *p = m->mu + 3 * ((size_t)j * m->nangles + k);
		for (int a = 0; a < 3; a++)
			for (int b = 0; b < 3; b++)
				G[a * 3 + b] += p[a] * p[b];
	}
	/* inverse iteration on G: converges to the least eigenvector */
	double I[9];
	double det = G[0] * (G[4] * G[8] - G[5] * G[7]) - G[1] * (G[3] * G[8] - G[5] * G[6]) +
	             G[2] * (G[3] * G[7] - G[4] * G[6]);
	I[0] = (G[4] * G[8] - G[5] * G[7]) / det, I[1] = (G[2] * G[7] - G[1] * G[8]) / det;
	I[2] = (G[1] * G[5] - G[2] * G[4]) / det, I[3] = (G[5] * G[6] - G[3] * G[8]) / det;
	I[4] = (G[0] * G[8] - G[2] * G[6]) / det, I[5] = (G[2] * G[3] - G[0] * G[5]) / det;
	I[6] = (G[3] * G[7] - G[4] * G[6]) / det, I[7] = (G[1] * G[6] - G[0] * G[7]) / det;
	I[8] = (G[0] * G[4] - G[1] * G[3]) / det;
	double e[3] = {0.3, -0.5, 0.8};
	for (int it = 0; it < 200 && isfinite(det) && det != 0; it++) {
		double t[3] = {0};
		for (int a = 0; a < 3; a++)
			for (int b = 0; b < 3; b++)
				t[a] += I[a * 3 + b] * e[b];
		double s = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
		for (int a = 0; a < 3; a++)
			e[a] = t[a] / s;
	}
	memcpy(nrm, e, sizeof(e));
}

enum { S_BRACKET2, S_BRACKET3, S_BRACKET4, S_PARABOLA, S_COARSE2, S_PLANAR, S_FREE, S_LOWER, NSEARCH };
static const char *search_name[NSEARCH] = {
	"coarse 2, bracket", "coarse 3, bracket", "coarse 4, bracket",
	"coarse 2, parabola", "coarse 2 alone", "planar predictions",
	"every angle, intensity free", "every angle, intensity >= lo",
};

/* The angle search s picks among d[0 .. na - 1] (dp: the planar predictions'
 * distances); *evals gets the candidates it evaluated. */
static int pick(int s, const double *d, const double *dp, const double *df,
                const double *dl, int na, int *evals)
{
	if (s == S_FREE || s == S_LOWER) {
		const double *e = s == S_FREE ? df : dl;
		int kp = 0;
		for (int k = 1; k < na; k++)
			kp = e[k] < e[kp] ? k : kp;
		*evals = na;
		return kp;
	}
	if (s == S_PLANAR) {
		int kp = 0;
		for (int k = 1; k < na; k++)
			kp = dp[k] < dp[kp] ? k : kp;
		*evals = na;
		return kp;
	}
	int S = s == S_BRACKET3 ? 3 : s == S_BRACKET4 ? 4 : 2;
	int c[MAX_ANGLES], nc = 0;
	for (int k = 0; k < na; k += S)
		c[nc++] = k;
	if (c[nc - 1] != na - 1)
		c[nc++] = na - 1;
	int cb = 0;
	for (int q = 1; q < nc; q++)
		cb = d[c[q]] < d[c[cb]] ? q : cb;
	int kc = c[cb];
	*evals = nc;
	if (s == S_PARABOLA && cb > 0 && cb < nc - 1) {
		double t0 = c[cb - 1], t1 = c[cb], t2 = c[cb + 1];
		double f0 = d[c[cb - 1]], f1 = d[c[cb]], f2 = d[c[cb + 1]];
		double num = (t1 - t0) * (t1 - t0) * (f1 - f2) - (t1 - t2) * (t1 - t2) * (f1 - f0);
		double den = (t1 - t0) * (f1 - f2) - (t1 - t2) * (f1 - f0);
		double tv = den != 0 ? t1 - 0.5 * num / den : t1;
		int kk = (int)lround(tv);
		kc = kk < (int)t0 ? (int)t0 : kk > (int)t2 ? (int)t2 : kk;
		*evals += kc != c[cb];
	} else if (s <= S_BRACKET4) {
		int lo = cb > 0 ? c[cb - 1] + 1 : 0, hi = cb < nc - 1 ? c[cb + 1] - 1 : na - 1;
		for (int k = lo; k <= hi; k++)
			if (k != c[cb]) {
				kc = d[k] < d[kc] ? k : kc;
				++*evals;
			}
	}
	return kc;
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

int main(int argc, char **argv)
{
	const char *materials = "fixtures/materials/default.json";
	long npix = 200000;
	for (int i = 1; i < argc; i++) {
		if (!strcmp(argv[i], "--pixels") && i + 1 < argc) {
			npix = atol(argv[++i]);
		} else if (!strcmp(argv[i], "--materials") && i + 1 < argc) {
			materials = argv[++i];
		} else {
			fprintf(stderr,
			        "usage: kogei-bench-cs-search [--pixels N] [--materials LIB.json]\n"
			        "  How much cheaper angle searches would change camera-space matching\n"
			        "  (every 5 degrees 0-70, intensity 0.3-1.0, the camera-space rows'\n"
			        "  pixels, default 200000; the library default %s).\n",
			        materials);
			return 2;
		}
	}
	if (npix < 1) {
		fprintf(stderr, "kogei-bench-cs-search: --pixels: expected a positive count\n");
		return 2;
	}
	kg_err err = {0};
	kg_cs_model *m = NULL, *fine = NULL;
	if (bench_cs_models(materials, 5.0, &m, &fine, &err)) {
		fprintf(stderr, "kogei-bench-cs-search: %s\n", err.msg);
		return 1;
	}
	const int na = m->nangles, nm = m->n;
	if (na > MAX_ANGLES || na < 2) {
		fprintf(stderr, "kogei-bench-cs-search: %d angles: expected 2 to %d\n", na, MAX_ANGLES);
		return 1;
	}
	/* the planar predictions */
	double *mup = malloc(sizeof(double) * 3 * (size_t)nm * (size_t)na);
	float *x = malloc(sizeof(float) * 3 * (size_t)npix);
	float *cov = malloc(sizeof(float) * 6 * (size_t)npix);
	uint8_t *truth = malloc((size_t)npix);
	double *excess[NSEARCH];
	size_t nexcess[NSEARCH] = {0};
	long other_angle[NSEARCH] = {0}, other_label[NSEARCH] = {0}, evals[NSEARCH] = {0};
	int ok = mup && x && cov && truth;
	for (int s = 0; s < NSEARCH; s++) {
		excess[s] = malloc(sizeof(double) * (size_t)npix * (size_t)nm);
		ok = ok && excess[s];
	}
	if (!ok) {
		fprintf(stderr, "kogei-bench-cs-search: out of memory for %ld pixels\n", npix);
		return 1;
	}
	for (int j = 0; j < nm; j++) {
		double nrm[3];
		plane_normal(m, j, nrm);
		for (int k = 0; k < na; k++) {
			const double *p = m->mu + 3 * ((size_t)j * na + k);
			double *q = mup + 3 * ((size_t)j * na + k);
			double t = p[0] * nrm[0] + p[1] * nrm[1] + p[2] * nrm[2];
			for (int a = 0; a < 3; a++)
				q[a] = p[a] - t * nrm[a];
		}
	}
	const kg_sim_noise noise = {.full_well = 20000, .read_noise = 10, .bits = 12};
	bench_cs_pixels(fine, &noise, 20261202, (size_t)npix, x, cov, truth);
	long pairs = 0, used = 0;
	for (long i = 0; i < npix; i++) {
		px p;
		if (px_make(x + 3 * i, cov + 6 * i, &p))
			continue;
		used++;
		double best = INFINITY, sbest[NSEARCH];
		int jbest = -1, sj[NSEARCH];
		for (int s = 0; s < NSEARCH; s++)
			sbest[s] = INFINITY, sj[s] = -1;
		for (int j = 0; j < nm; j++) {
			double d[MAX_ANGLES], dp[MAX_ANGLES], df[MAX_ANGLES], dl[MAX_ANGLES];
			int ke = 0;
			for (int k = 0; k < na; k++) {
				d[k] = dist(&p, m->mu + 3 * ((size_t)j * na + k), m->lo, m->hi);
				dp[k] = dist(&p, mup + 3 * ((size_t)j * na + k), m->lo, m->hi);
				df[k] = dist(&p, m->mu + 3 * ((size_t)j * na + k), -INFINITY, INFINITY);
				dl[k] = dist(&p, m->mu + 3 * ((size_t)j * na + k), m->lo, INFINITY);
				ke = d[k] < d[ke] ? k : ke;
			}
			pairs++;
			if (d[ke] < best)
				best = d[ke], jbest = j;
			for (int s = 0; s < NSEARCH; s++) {
				int e, k = pick(s, d, dp, df, dl, na, &e);
				evals[s] += e;
				other_angle[s] += k != ke;
				if (d[ke] < 50)
					excess[s][nexcess[s]++] = d[k] - d[ke];
				if (d[k] < sbest[s])
					sbest[s] = d[k], sj[s] = j;
			}
		}
		for (int s = 0; s < NSEARCH; s++)
			other_label[s] += sj[s] != jbest;
	}
	printf("Camera-space angle searches against the exhaustive one: %ld pixels, %d materials "
	       "x %d angles (0-70 every 5 degrees), intensity %.1f-%.1f, computed in double.\n\n",
	       used, nm, na, m->lo, m->hi);
	printf("| search | candidates per material | pairs at another angle | labels changed | "
	       "excess d p99 | p99.9 | max |\n|---|--:|--:|--:|--:|--:|--:|\n");
	printf("| exhaustive | %d | 0 | 0 | 0 | 0 | 0 |\n", na);
	for (int s = 0; s < NSEARCH; s++) {
		size_t n = nexcess[s];
		qsort(excess[s], n, sizeof(double), cmp_double);
		double p99 = n ? excess[s][(size_t)(0.99 * (double)(n - 1))] : NAN;
		double p999 = n ? excess[s][(size_t)(0.999 * (double)(n - 1))] : NAN;
		printf("| %s | %.2f | %.5f | %ld of %ld | %.3g | %.3g | %.3g |\n", search_name[s],
		       (double)evals[s] / (double)pairs, (double)other_angle[s] / (double)pairs,
		       other_label[s], used, p99, p999, n ? excess[s][n - 1] : NAN);
	}
	for (int s = 0; s < NSEARCH; s++)
		free(excess[s]);
	free(mup);
	free(x);
	free(cov);
	free(truth);
	kg_cs_model_free(&m);
	kg_cs_model_free(&fine);
	return 0;
}
