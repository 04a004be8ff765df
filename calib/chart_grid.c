/* The patch-grid finder: a ColorChecker 24 without tags found as what it is, a 6 x 4
 * grid of uniform patches, on the reduced copy the tagless detector looks at. It
 * runs before OpenCV mcc (chart_tagless.c) because it needs none of mcc's fixed costs
 * (OpenCV's colour tables, an upscaled copy): a box it gives is refined, its turns
 * sampled and its orientation chosen exactly as mcc's, and when no box of its reads
 * as the layout, mcc looks as before.
 *
 * 1. Uniform regions: the luminance, square-rooted so dark patches keep their edges
 *    against the chart's black, has its gradient thresholded (a few times the median
 *    gradient, the image's own noise); 4-connected runs of the flat pixels are the
 *    regions.
 * 2. Patch candidates: regions of a parallelogram's shape (its area 12 sqrt(det S) for
 *    S the covariance of its pixels, as for any parallelogram), not touching the border.
 * 3. The grid: for each candidate, its nearest like-sized neighbour and the nearest
 *    one across give two lattice steps; the candidates whose lattice coordinates are
 *    near integers are its grid, which a homography (lattice -> image) then re-reads
 *    twice, so perspective does not lose the far patches. The grid with the most
 *    patches whose cells span exactly 6 x 4 is kept; its homography places the box
 *    that mcc's would be (chart_mcc24_box_mm). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"
#include "select.h"

#if KG_HAVE_MCC

typedef struct blob {
	double n, x, y, sxx, syy, sxy; /* pixels, centroid, covariance */
	int touches;
} blob;

typedef struct grid_fit {
	int count;
	double H[9];    /* (col, row) -> px of the reduced copy */
	double rms;     /* of the centroids about the grid, in pitches */
	int member[24];
} grid_fit;

/* The square-rooted luminance of every pixel, relative to white. */
static float *flat_luma(const float *img, int w, int h, int C, double white)
{
	float *g = malloc((size_t)w * h * sizeof(float));
	if (!g)
		return NULL;
	float inv = white > 0 ? (float)(1.0 / white) : 1.0f;
	for (size_t i = 0; i < (size_t)w * h; i++) {
		const float *p = img + i * (size_t)C;
		float y = C == 3 ? 0.25f * (p[0] + 2 * p[1] + p[2]) : p[0];
		y *= inv;
		y = y > 0 ? (y < 1 ? y : 1) : 0;
		g[i] = sqrtf(y);
	}
	return g;
}

/* Flat pixels (1) where the gradient stays below a few times its median. */
static unsigned char *flat_mask(const float *g, int w, int h)
{
	size_t n = (size_t)w * h;
	float *grad = malloc(n * sizeof(float));
	unsigned char *m = calloc(n, 1);
	if (!grad || !m) {
		free(grad);
		free(m);
		return NULL;
	}
	for (int y = 0; y < h; y++)
		for (int x = 0; x < w; x++) {
			size_t i = (size_t)y * w + x;
			if (x == 0 || y == 0 || x == w - 1 || y == h - 1) {
				grad[i] = INFINITY;
				continue;
			}
			grad[i] = fabsf(g[i + 1] - g[i - 1]) + fabsf(g[i + w] - g[i - w]);
		}
	/* the median from a sparse sample: every 7th interior pixel */
	size_t ns = 0;
	float *s = malloc((n / 7 + 1) * sizeof(float));
	if (!s) {
		free(grad);
		free(m);
		return NULL;
	}
	for (size_t i = 0; i < n; i += 7)
		if (isfinite(grad[i]))
			s[ns++] = grad[i];
	float med = ns ? kg_select_kth(s, ns, ns / 2) : 0;
	free(s);
	float t = 4 * med;
	t = t < 0.015f ? 0.015f : t > 0.08f ? 0.08f : t;
	for (size_t i = 0; i < n; i++)
		m[i] = grad[i] < t;
	free(grad);
	return m;
}

/* The 4-connected regions of the mask, as blobs (their moments). */
static blob *find_blobs(unsigned char *m, int w, int h, int *nb)
{
	size_t n = (size_t)w * h;
	int *stack = malloc(n * sizeof(int));
	int cap = 256, k = 0;
	blob *b = malloc((size_t)cap * sizeof(*b));
	if (!stack || !b) {
		free(stack);
		free(b);
		return NULL;
	}
	for (size_t start = 0; start < n; start++) {
		if (m[start] != 1)
			continue;
		double cnt = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
		int touches = 0, top = 0;
		stack[top++] = (int)start;
		m[start] = 2;
		while (top) {
			int i = stack[--top], x = i % w, y = i / w;
			double X = x + 0.5, Y = y + 0.5;
			cnt++;
			sx += X;
			sy += Y;
			sxx += X * X;
			syy += Y * Y;
			sxy += X * Y;
			touches |= x <= 1 || y <= 1 || x >= w - 2 || y >= h - 2;
			if (x > 0 && m[i - 1] == 1) {
				m[i - 1] = 2;
				stack[top++] = i - 1;
			}
			if (x < w - 1 && m[i + 1] == 1) {
				m[i + 1] = 2;
				stack[top++] = i + 1;
			}
			if (y > 0 && m[i - w] == 1) {
				m[i - w] = 2;
				stack[top++] = i - w;
			}
			if (y < h - 1 && m[i + w] == 1) {
				m[i + w] = 2;
				stack[top++] = i + w;
			}
		}
		if (cnt < 25)
			continue;
		if (k == cap) {
			blob *nbp = realloc(b, (size_t)(cap *= 2) * sizeof(*b));
			if (!nbp) {
				free(stack);
				free(b);
				return NULL;
			}
			b = nbp;
		}
		double mx = sx / cnt, my = sy / cnt;
		b[k++] = (blob){cnt, mx, my, sxx / cnt - mx * mx, syy / cnt - my * my,
		                sxy / cnt - mx * my, touches};
	}
	free(stack);
	*nb = k;
	return b;
}

/* Whether a blob has a patch's shape: a parallelogram (area 12 sqrt(det) of its
 * covariance, within 15 %) no more than 2.5 times longer than wide, inside the image. */
static int patch_like(const blob *b, long max_area)
{
	if (b->touches || b->n > (double)max_area)
		return 0;
	double det = b->sxx * b->syy - b->sxy * b->sxy;
	if (!(det > 0))
		return 0;
	double fill = b->n / (12 * sqrt(det));
	double tr = b->sxx + b->syy, disc = sqrt(fmax(tr * tr / 4 - det, 0));
	double l1 = tr / 2 + disc, l2 = tr / 2 - disc;
	return fill > 0.85 && fill < 1.15 && l2 > 0 && l1 / l2 < 6.25;
}

/* The candidates on the grid of homography G (lattice -> px), one per cell within 7
 * cells of the origin, nearest its cell's centre: their cells in cu, cv; the count. */
static int assign(const blob *c, int nc, const double G[9], int *cu, int *cv, int *who)
{
	enum { SPAN = 15 };
	double best[SPAN * SPAN];
	int owner[SPAN * SPAN];
	for (int k = 0; k < SPAN * SPAN; k++) {
		best[k] = INFINITY;
		owner[k] = -1;
	}
	double Ginv[9];
	if (kg_homography_invert(G, Ginv))
		return 0;
	for (int i = 0; i < nc; i++) {
		double m[2];
		kg_homography_map(Ginv, c[i].x, c[i].y, m);
		double u = m[0], v = m[1], ru = round(u), rv = round(v), d = hypot(u - ru, v - rv);
		if (!(d < 0.25) || fabs(ru) > 7 || fabs(rv) > 7)
			continue;
		int cell = (int)(rv + 7) * SPAN + (int)(ru + 7);
		if (d < best[cell]) {
			best[cell] = d;
			owner[cell] = i;
		}
	}
	int n = 0;
	for (int k = 0; k < SPAN * SPAN; k++)
		if (owner[k] >= 0) {
			cu[n] = k % SPAN - 7;
			cv[n] = k / SPAN - 7;
			who[n] = owner[k];
			n++;
		}
	return n;
}

/* The homography (col, row) -> px through the assigned cells; 0 when they are too
 * few or all on one line. */
static int fit_cells(const blob *c, const int *cu, const int *cv, const int *who, int n,
                     double G[9])
{
	if (n < 6)
		return 0;
	int u0 = cu[0], v0 = cv[0], ud = 0, vd = 0;
	for (int i = 1; i < n; i++) {
		ud |= cu[i] != u0;
		vd |= cv[i] != v0;
	}
	if (!ud || !vd)
		return 0;
	double (*src)[2] = malloc((size_t)n * sizeof(*src)), (*dst)[2] = malloc((size_t)n * sizeof(*dst));
	if (!src || !dst) {
		free(src);
		free(dst);
		return 0;
	}
	for (int i = 0; i < n; i++) {
		src[i][0] = cu[i];
		src[i][1] = cv[i];
		dst[i][0] = c[who[i]].x;
		dst[i][1] = c[who[i]].y;
	}
	kg_err e = {{0}};
	int ok = kg_homography_fit((const double (*)[2])src, (const double (*)[2])dst, n, 0, G, NULL,
	                           &e) == 0;
	free(src);
	free(dst);
	return ok;
}

/* The grid grown from candidate i: its steps to the nearest like-sized neighbour and
 * the nearest across, then the homography refitted twice. 0 when it is no 6 x 4. */
static int grow_grid(const blob *c, int nc, int i, grid_fit *out)
{
	double si = sqrt(c[i].n);
	int j = -1, k = -1;
	double dj = INFINITY, dk = INFINITY;
	for (int q = 0; q < nc; q++) {
		double r = c[q].n / c[i].n, d = hypot(c[q].x - c[i].x, c[q].y - c[i].y);
		if (q == i || r < 0.4 || r > 2.5 || d < 1.0 * si || d > 3.0 * si)
			continue;
		if (d < dj) {
			dj = d;
			j = q;
		}
	}
	if (j < 0)
		return 0;
	double a[2] = {c[j].x - c[i].x, c[j].y - c[i].y};
	for (int q = 0; q < nc; q++) {
		double r = c[q].n / c[i].n;
		double b[2] = {c[q].x - c[i].x, c[q].y - c[i].y}, d = hypot(b[0], b[1]);
		if (q == i || q == j || r < 0.4 || r > 2.5 || d < 0.5 * dj || d > 2.0 * dj)
			continue;
		double sine = fabs(a[0] * b[1] - a[1] * b[0]) / (dj * d);
		if (sine > 0.5 && d < dk) {
			dk = d;
			k = q;
		}
	}
	if (k < 0)
		return 0;
	/* the affine lattice of the two steps from candidate i, then the homography
	 * refitted to the cells it assigns, three times */
	double G[9] = {a[0], c[k].x - c[i].x, c[i].x, a[1], c[k].y - c[i].y, c[i].y, 0, 0, 1};
	int cu[225], cv[225], who[225];
	int n = assign(c, nc, G, cu, cv, who);
	for (int it = 0; it < 3; it++) {
		if (!fit_cells(c, cu, cv, who, n, G))
			return 0;
		n = assign(c, nc, G, cu, cv, who);
	}
	if (n < 12 || n > 24)
		return 0;
	int umin = 99, umax = -99, vmin = 99, vmax = -99;
	for (int q = 0; q < n; q++) {
		umin = cu[q] < umin ? cu[q] : umin;
		umax = cu[q] > umax ? cu[q] : umax;
		vmin = cv[q] < vmin ? cv[q] : vmin;
		vmax = cv[q] > vmax ? cv[q] : vmax;
	}
	int du = umax - umin, dv = vmax - vmin;
	if (!((du == 5 && dv == 3) || (du == 3 && dv == 5)))
		return 0;
	/* (col, row): col along the 6 patches, row along the 4 */
	for (int q = 0; q < n; q++) {
		int u = cu[q] - umin, v = cv[q] - vmin;
		cu[q] = du == 5 ? u : v;
		cv[q] = du == 5 ? v : u;
	}
	if (!fit_cells(c, cu, cv, who, n, G))
		return 0;
	double e2 = 0, pitch = 0;
	for (int q = 0; q < n; q++) {
		double m[2], p0[2], p1[2];
		kg_homography_map(G, cu[q], cv[q], m);
		e2 += (m[0] - c[who[q]].x) * (m[0] - c[who[q]].x) +
		      (m[1] - c[who[q]].y) * (m[1] - c[who[q]].y);
		kg_homography_map(G, cu[q] + 0.5, cv[q], p1);
		kg_homography_map(G, cu[q] - 0.5, cv[q], p0);
		pitch += hypot(p1[0] - p0[0], p1[1] - p0[1]);
	}
	out->count = n;
	memcpy(out->H, G, sizeof(out->H));
	out->rms = sqrt(e2 / n) / (pitch / n);
	for (int q = 0; q < 24; q++)
		out->member[q] = -1;
	for (int q = 0; q < n; q++)
		out->member[cv[q] * 6 + cu[q]] = who[q];
	return 1;
}

int chart_grid_find(const float *img, int w, int h, int C, double white, int max,
                    double (*boxes)[4][2], double *costs, int *counts)
{
	if (!img || w < 16 || h < 16 || (C != 1 && C != 3) || max < 1)
		return 0;
	float *g = flat_luma(img, w, h, C, white);
	int n = g ? chart_grid_find_encoded(g, w, h, max, boxes, costs, counts) : 0;
	free(g);
	return n;
}

int chart_grid_find_grey8(const unsigned char *grey, int w, int h, int q, int max,
                          double (*boxes)[4][2], double *costs, int *counts, int *rw, int *rh)
{
	int gw = q > 0 ? w / q : 0, gh = q > 0 ? h / q : 0;
	*rw = gw;
	*rh = gh;
	if (!grey || gw < 16 || gh < 16)
		return 0;
	float *g = malloc((size_t)gw * gh * sizeof(float));
	if (!g)
		return 0;
	for (int y = 0; y < gh; y++)
		for (int x = 0; x < gw; x++) {
			unsigned sum = 0;
			for (int dy = 0; dy < q; dy++)
				for (int dx = 0; dx < q; dx++)
					sum += grey[(size_t)(y * q + dy) * w + x * q + dx];
			g[(size_t)y * gw + x] = (float)sum / (255.0f * (float)(q * q));
		}
	int n = chart_grid_find_encoded(g, gw, gh, max, boxes, costs, counts);
	free(g);
	return n;
}

int chart_grid_find_encoded(const float *g, int w, int h, int max, double (*boxes)[4][2],
                            double *costs, int *counts)
{
	if (!g || w < 16 || h < 16 || max < 1)
		return 0;
	unsigned char *m = flat_mask(g, w, h);
	int nb = 0;
	blob *b = m ? find_blobs(m, w, h, &nb) : NULL;
	free(m);
	if (!b)
		return 0;
	/* the patch candidates, in place */
	int nc = 0;
	long max_area = (long)w * h / 24;
	for (int i = 0; i < nb; i++)
		if (patch_like(&b[i], max_area))
			b[nc++] = b[i];
	/* growing every candidate's grid costs nc^2: a picture this cluttered is left to mcc */
	if (nc > 4000)
		nc = 0;
	int found = 0;
	unsigned char *taken = calloc((size_t)(nc ? nc : 1), 1);
	while (taken && found < max) {
		grid_fit best = {0}, f;
		for (int i = 0; i < nc; i++)
			if (!taken[i] && grow_grid(b, nc, i, &f) &&
			    (f.count > best.count || (f.count == best.count && f.rms < best.rms))) {
				int clash = 0;
				for (int q = 0; q < 24; q++)
					clash |= f.member[q] >= 0 && taken[f.member[q]];
				if (!clash)
					best = f;
			}
		if (!best.count)
			break;
		double mg = KG_MCC24_BOX_MARGIN_PITCH;
		double uv[4][2] = {{-mg, -mg}, {5 + mg, -mg}, {5 + mg, 3 + mg}, {-mg, 3 + mg}};
		for (int k = 0; k < 4; k++)
			kg_homography_map(best.H, uv[k][0], uv[k][1], boxes[found][k]);
		costs[found] = best.rms;
		counts[found] = best.count;
		for (int q = 0; q < 24; q++)
			if (best.member[q] >= 0)
				taken[best.member[q]] = 1;
		found++;
	}
	free(taken);
	free(b);
	return found;
}

#endif
