/* Homographies (mm -> px) for chart detection: normalised DLT, then Levenberg-Marquardt
 * on the reprojection error. */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"

/* ---- homographies ------------------------------------------------------------ */

void kg_homography_map(const double H[9], double x, double y, double out[2])
{
	double w = H[6] * x + H[7] * y + H[8];
	out[0] = (H[0] * x + H[1] * y + H[2]) / w;
	out[1] = (H[3] * x + H[4] * y + H[5]) / w;
}

int kg_homography_invert(const double H[9], double inv[9])
{
	double a = H[0], b = H[1], c = H[2], d = H[3], e = H[4], f = H[5], g = H[6],
	       h = H[7], i = H[8];
	double A = e * i - f * h, B = -(d * i - f * g), C = d * h - e * g;
	double det = a * A + b * B + c * C;
	if (!isfinite(det) || fabs(det) < 1e-300)
		return KG_EINVAL;
	double m[9] = {A, -(b * i - c * h), b * f - c * e, B, a * i - c * g, -(a * f - c * d),
	               C, -(a * h - b * g), a * e - b * d};
	for (int k = 0; k < 9; k++)
		inv[k] = m[k] / det;
	return 0;
}

static void mat3_mul(const double a[9], const double b[9], double out[9])
{
	double t[9];
	for (int r = 0; r < 3; r++)
		for (int c = 0; c < 3; c++)
			t[r * 3 + c] = a[r * 3] * b[c] + a[r * 3 + 1] * b[3 + c] + a[r * 3 + 2] * b[6 + c];
	memcpy(out, t, sizeof(t));
}

/* Hartley normalisation: centroid to the origin, mean distance sqrt(2). */
static void normaliser(const double (*p)[2], int n, double T[9])
{
	double cx = 0, cy = 0, d = 0;
	for (int i = 0; i < n; i++) {
		cx += p[i][0];
		cy += p[i][1];
	}
	cx /= n;
	cy /= n;
	for (int i = 0; i < n; i++)
		d += hypot(p[i][0] - cx, p[i][1] - cy);
	d /= n;
	double s = d > 0 ? sqrt(2.0) / d : 1.0;
	double t[9] = {s, 0, -s * cx, 0, s, -s * cy, 0, 0, 1};
	memcpy(T, t, sizeof(t));
}

/* Solve the n x n system A x = b in place (partial pivoting). 0 or -1 if singular. */
static int solve_dense(double *A, double *b, int n)
{
	for (int k = 0; k < n; k++) {
		int p = k;
		for (int i = k + 1; i < n; i++)
			if (fabs(A[i * n + k]) > fabs(A[p * n + k]))
				p = i;
		if (!(fabs(A[p * n + k]) > 1e-300))
			return -1;
		if (p != k) {
			for (int j = 0; j < n; j++) {
				double t = A[k * n + j];
				A[k * n + j] = A[p * n + j];
				A[p * n + j] = t;
			}
			double t = b[k];
			b[k] = b[p];
			b[p] = t;
		}
		for (int i = k + 1; i < n; i++) {
			double f = A[i * n + k] / A[k * n + k];
			for (int j = k; j < n; j++)
				A[i * n + j] -= f * A[k * n + j];
			b[i] -= f * b[k];
		}
	}
	for (int k = n - 1; k >= 0; k--) {
		double s = b[k];
		for (int j = k + 1; j < n; j++)
			s -= A[k * n + j] * b[j];
		b[k] = s / A[k * n + k];
	}
	return 0;
}

/* Sum of squared reprojection errors of normalised points under h (h[8] = 1). */
static double sq_error(const double h[9], const double (*src)[2], const double (*dst)[2],
                       int n)
{
	double s = 0;
	for (int i = 0; i < n; i++) {
		double q[2];
		kg_homography_map(h, src[i][0], src[i][1], q);
		s += (q[0] - dst[i][0]) * (q[0] - dst[i][0]) + (q[1] - dst[i][1]) * (q[1] - dst[i][1]);
	}
	return s;
}

/* Levenberg-Marquardt on the 8 free entries of h (h[8] fixed at 1), in normalised
 * coordinates where that parametrisation is well conditioned. */
static void refine_lm(double h[9], const double (*src)[2], const double (*dst)[2], int n)
{
	double lambda = 1e-3, err = sq_error(h, src, dst, n);
	for (int it = 0; it < 50; it++) {
		double JtJ[64] = {0}, Jtr[8] = {0};
		for (int i = 0; i < n; i++) {
			double X = src[i][0], Y = src[i][1];
			double w = h[6] * X + h[7] * Y + 1.0;
			double x = (h[0] * X + h[1] * Y + h[2]) / w, y = (h[3] * X + h[4] * Y + h[5]) / w;
			double jx[8] = {X / w, Y / w, 1 / w, 0, 0, 0, -x * X / w, -x * Y / w};
			double jy[8] = {0, 0, 0, X / w, Y / w, 1 / w, -y * X / w, -y * Y / w};
			double rx = dst[i][0] - x, ry = dst[i][1] - y;
			for (int a = 0; a < 8; a++) {
				Jtr[a] += jx[a] * rx + jy[a] * ry;
				for (int b = 0; b < 8; b++)
					JtJ[a * 8 + b] += jx[a] * jx[b] + jy[a] * jy[b];
			}
		}
		int improved = 0;
		while (lambda < 1e10) {
			double A[64], d[8], cand[9];
			memcpy(A, JtJ, sizeof(A));
			memcpy(d, Jtr, sizeof(d));
			for (int a = 0; a < 8; a++)
				A[a * 8 + a] += lambda * (JtJ[a * 8 + a] + 1e-12);
			if (solve_dense(A, d, 8) == 0) {
				for (int a = 0; a < 8; a++)
					cand[a] = h[a] + d[a];
				cand[8] = 1.0;
				double e = sq_error(cand, src, dst, n);
				if (e < err) {
					double gain = err - e;
					memcpy(h, cand, sizeof(cand));
					err = e;
					lambda = fmax(lambda * 0.3, 1e-12);
					improved = gain > 1e-14 * (err + 1e-30);
					break;
				}
			}
			lambda *= 10;
		}
		if (!improved)
			break;
	}
}

int kg_homography_fit(const double (*src)[2], const double (*dst)[2], int n, int refine,
                      double H[9], double *rms, kg_err *err)
{
	kg_check_arg(src && dst && H, err);
	if (n < 4)
		return kg_fail(err, KG_EINVAL, "homography: %d point pairs; at least 4 are needed", n);
	double Ts[9], Td[9];
	normaliser(src, n, Ts);
	normaliser(dst, n, Td);
	double (*ns)[2] = malloc((size_t)n * sizeof(*ns));
	double (*nd)[2] = malloc((size_t)n * sizeof(*nd));
	kg_mat *A = NULL, *vt = NULL;
	int ret = 0;
	if (!ns || !nd) {
		ret = kg_fail(err, KG_ENOMEM, "homography: out of memory");
		goto done;
	}
	for (int i = 0; i < n; i++) {
		kg_homography_map(Ts, src[i][0], src[i][1], ns[i]);
		kg_homography_map(Td, dst[i][0], dst[i][1], nd[i]);
	}
	/* Two rows per pair; a 9th zero row when n == 4 so the SVD returns all of V. */
	int rows = 2 * n < 9 ? 9 : 2 * n;
	if ((ret = kg_mat_new(rows, 9, &A, err)))
		goto done;
	for (int i = 0; i < n; i++) {
		double X = ns[i][0], Y = ns[i][1], x = nd[i][0], y = nd[i][1];
		double r0[9] = {-X, -Y, -1, 0, 0, 0, x * X, x * Y, x};
		double r1[9] = {0, 0, 0, -X, -Y, -1, y * X, y * Y, y};
		memcpy(A->a + (2 * i) * 9, r0, sizeof(r0));
		memcpy(A->a + (2 * i + 1) * 9, r1, sizeof(r1));
	}
	if ((ret = kg_svd(A, NULL, NULL, &vt, err)))
		goto done;
	double h[9];
	for (int k = 0; k < 9; k++)
		h[k] = vt->a[8 * 9 + k];
	if (!(fabs(h[8]) > 1e-12)) {
		ret = kg_fail(err, KG_EINVAL, "homography: degenerate point configuration");
		goto done;
	}
	for (int k = 0; k < 9; k++)
		h[k] /= h[8];
	if (refine && n > 4)
		refine_lm(h, (const double (*)[2])ns, (const double (*)[2])nd, n);
	/* H = Td^-1 h Ts */
	double Tdi[9];
	if (kg_homography_invert(Td, Tdi)) {
		ret = kg_fail(err, KG_EINVAL, "homography: degenerate point configuration");
		goto done;
	}
	double t[9];
	mat3_mul(h, Ts, t);
	mat3_mul(Tdi, t, H);
	for (int k = 0; k < 9; k++)
		if (!isfinite(H[k])) {
			ret = kg_fail(err, KG_EINVAL, "homography: degenerate point configuration");
			goto done;
		}
	double scale = H[8];
	if (fabs(scale) > 1e-300)
		for (int k = 0; k < 9; k++)
			H[k] /= scale;
	if (rms)
		*rms = sqrt(sq_error(H, src, dst, n) / n);
done:
	free(ns);
	free(nd);
	kg_mat_free(&A);
	kg_mat_free(&vt);
	return ret;
}
