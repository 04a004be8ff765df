#include <float.h>
#include <lapacke.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "linalg.h"

/* Far above any matrix the station builds (charts, bases, covariances), low enough
 * that rows * cols * 8 cannot overflow. */
#define KG_MAT_MAX_ELEMS ((size_t)1 << 32)

int kg_mat_new(int rows, int cols, kg_mat **out, kg_err *err)
{
	kg_check_arg(out, err);
	*out = NULL;
	if (rows < 1 || cols < 1 || (size_t)rows * (size_t)cols > KG_MAT_MAX_ELEMS)
		return kg_fail(err, KG_EINVAL, "matrix of %d x %d: expected 1 to %zu elements",
		               rows, cols, KG_MAT_MAX_ELEMS);
	kg_mat *m = calloc(1, sizeof(*m) + (size_t)rows * (size_t)cols * sizeof(double));
	if (!m)
		return kg_fail(err, KG_ENOMEM, "matrix of %d x %d: out of memory", rows, cols);
	m->rows = rows;
	m->cols = cols;
	m->a = (double *)(m + 1);
	*out = m;
	return 0;
}

int kg_mat_from(int rows, int cols, const double *data, kg_mat **out, kg_err *err)
{
	kg_check_arg(data, err);
	int ret = kg_mat_new(rows, cols, out, err);
	if (ret == 0)
		memcpy((*out)->a, data, (size_t)rows * (size_t)cols * sizeof(double));
	return ret;
}

int kg_mat_copy(const kg_mat *m, kg_mat **out, kg_err *err)
{
	kg_check_arg(m, err);
	return kg_mat_from(m->rows, m->cols, m->a, out, err);
}

int kg_mat_identity(int n, kg_mat **out, kg_err *err)
{
	int ret = kg_mat_new(n, n, out, err);
	if (ret == 0)
		for (int i = 0; i < n; i++)
			kg_mat_set(*out, i, i, 1.0);
	return ret;
}

void kg_mat_free(kg_mat **m)
{
	if (m) {
		free(*m);
		*m = NULL;
	}
}

int kg_mat_isfinite(const kg_mat *m)
{
	size_t n = (size_t)m->rows * (size_t)m->cols;
	for (size_t i = 0; i < n; i++)
		if (!isfinite(m->a[i]))
			return 0;
	return 1;
}

int kg_mat_check_finite(const kg_mat *m, const char *what, kg_err *err)
{
	kg_check_arg(m, err);
	size_t n = (size_t)m->rows * (size_t)m->cols;
	for (size_t i = 0; i < n; i++)
		if (!isfinite(m->a[i]))
			return kg_fail(err, KG_EINVAL,
			               "%s: element (%zu, %zu) of the %d x %d matrix is %g: expected "
			               "finite numbers",
			               what ? what : "matrix", i / (size_t)m->cols, i % (size_t)m->cols,
			               m->rows, m->cols, m->a[i]);
	return 0;
}

double kg_mat_max_abs_diff(const kg_mat *a, const kg_mat *b)
{
	if (a->rows != b->rows || a->cols != b->cols)
		return INFINITY;
	double d = 0;
	size_t n = (size_t)a->rows * (size_t)a->cols;
	for (size_t i = 0; i < n; i++) {
		double e = fabs(a->a[i] - b->a[i]);
		if (!(e <= d))
			d = e; /* NaN propagates */
	}
	return d;
}

int kg_mat_mul(const kg_mat *a, enum kg_trans ta, const kg_mat *b, enum kg_trans tb,
               kg_mat **out, kg_err *err)
{
	kg_check_arg(a && b && out, err);
	*out = NULL;
	int m = ta ? a->cols : a->rows, ka = ta ? a->rows : a->cols;
	int kb = tb ? b->cols : b->rows, n = tb ? b->rows : b->cols;
	if (ka != kb)
		return kg_fail(err, KG_EINVAL,
		               "matrix product: inner dimensions differ (%d x %d%s times %d x %d%s)",
		               a->rows, a->cols, ta ? " transposed" : "", b->rows, b->cols,
		               tb ? " transposed" : "");
	kg_mat *c;
	int ret = kg_mat_new(m, n, &c, err);
	if (ret)
		return ret;
	/* a(i,k) and b(k,j) through strides, so one loop serves all four cases. */
	long as_i = ta ? 1 : a->cols, as_k = ta ? a->cols : 1;
	long bs_k = tb ? 1 : b->cols, bs_j = tb ? b->cols : 1;
	for (int i = 0; i < m; i++)
		for (int k = 0; k < ka; k++) {
			double aik = a->a[i * as_i + k * as_k];
			const double *bk = b->a + k * bs_k;
			double *ci = c->a + (long)i * n;
			for (int j = 0; j < n; j++)
				ci[j] += aik * bk[j * bs_j];
		}
	*out = c;
	return 0;
}

int kg_mat_transpose(const kg_mat *a, kg_mat **out, kg_err *err)
{
	kg_check_arg(a && out, err);
	int ret = kg_mat_new(a->cols, a->rows, out, err);
	if (ret)
		return ret;
	for (int r = 0; r < a->rows; r++)
		for (int c = 0; c < a->cols; c++)
			kg_mat_set(*out, c, r, kg_mat_get(a, r, c));
	return 0;
}

static double default_rtol(const kg_mat *a, double rtol)
{
	if (rtol > 0)
		return rtol;
	return (a->rows > a->cols ? a->rows : a->cols) * DBL_EPSILON;
}

static int lapack_fail(kg_err *err, const char *what, lapack_int info)
{
	if (info == LAPACK_WORK_MEMORY_ERROR || info == LAPACK_TRANSPOSE_MEMORY_ERROR)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", what);
	if (info > 0)
		return kg_fail(err, KG_ERANGE, "%s: the iteration did not converge (info %d)", what,
		               (int)info);
	return kg_fail(err, KG_EINVAL, "%s: LAPACK rejected argument %d", what, (int)-info);
}

int kg_svd(const kg_mat *a, kg_mat **u, kg_mat **s, kg_mat **vt, kg_err *err)
{
	kg_check_arg(a, err);
	if (u)
		*u = NULL;
	if (s)
		*s = NULL;
	if (vt)
		*vt = NULL;
	int ret = kg_mat_check_finite(a, "SVD", err);
	if (ret)
		return ret;
	int m = a->rows, n = a->cols, k = m < n ? m : n;
	kg_mat *w = NULL, *uu = NULL, *ss = NULL, *vv = NULL, *sup = NULL;
	if ((ret = kg_mat_copy(a, &w, err)) || (ret = kg_mat_new(k, 1, &ss, err)) ||
	    (ret = kg_mat_new(k, 1, &sup, err)) || (u && (ret = kg_mat_new(m, k, &uu, err))) ||
	    (vt && (ret = kg_mat_new(k, n, &vv, err))))
		goto done;
	double dummy = 0;
	lapack_int info = LAPACKE_dgesvd(LAPACK_ROW_MAJOR, u ? 'S' : 'N', vt ? 'S' : 'N', m, n,
	                                 w->a, n, ss->a, uu ? uu->a : &dummy, k,
	                                 vv ? vv->a : &dummy, n, sup->a);
	if (info != 0) {
		ret = lapack_fail(err, "SVD", info);
		goto done;
	}
	if (u) {
		*u = uu;
		uu = NULL;
	}
	if (s) {
		*s = ss;
		ss = NULL;
	}
	if (vt) {
		*vt = vv;
		vv = NULL;
	}
done:
	kg_mat_free(&w);
	kg_mat_free(&uu);
	kg_mat_free(&ss);
	kg_mat_free(&vv);
	kg_mat_free(&sup);
	return ret;
}

static int count_rank(const kg_mat *s, double tol)
{
	int r = 0;
	double smax = s->a[0];
	for (int i = 0; i < s->rows; i++)
		if (s->a[i] > tol * smax)
			r++;
	return r;
}

int kg_pinv(const kg_mat *a, double rtol, kg_mat **pinv, int *rank, kg_mat **s, kg_err *err)
{
	kg_check_arg(a && pinv, err);
	*pinv = NULL;
	if (s)
		*s = NULL;
	kg_mat *u = NULL, *sv = NULL, *vt = NULL, *p = NULL;
	int ret = kg_svd(a, &u, &sv, &vt, err);
	if (ret)
		goto done;
	int m = a->rows, n = a->cols, k = sv->rows;
	int r = count_rank(sv, default_rtol(a, rtol));
	if ((ret = kg_mat_new(n, m, &p, err)))
		goto done;
	/* pinv = V diag(1/s) U^T over the r retained singular values (s is sorted). */
	for (int l = 0; l < r; l++) {
		double inv = 1.0 / sv->a[l];
		for (int i = 0; i < n; i++) {
			double vi = kg_mat_get(vt, l, i) * inv;
			double *pi = p->a + (long)i * m;
			for (int j = 0; j < m; j++)
				pi[j] += vi * u->a[(long)j * k + l];
		}
	}
	*pinv = p;
	p = NULL;
	if (rank)
		*rank = r;
	if (s) {
		*s = sv;
		sv = NULL;
	}
done:
	kg_mat_free(&u);
	kg_mat_free(&sv);
	kg_mat_free(&vt);
	kg_mat_free(&p);
	return ret;
}

int kg_cond(const kg_mat *a, double rtol, double *cond, kg_err *err)
{
	kg_check_arg(a && cond, err);
	kg_mat *s = NULL;
	int ret = kg_svd(a, NULL, &s, NULL, err);
	if (ret)
		return ret;
	double smax = s->a[0], smin = s->a[s->rows - 1];
	*cond = (smax == 0 || smin <= default_rtol(a, rtol) * smax) ? INFINITY : smax / smin;
	kg_mat_free(&s);
	return 0;
}

int kg_lstsq(const kg_mat *x, const kg_mat *y, double lambda, double rtol, kg_mat **b,
             int *rank, kg_err *err)
{
	kg_check_arg(x && y && b, err);
	*b = NULL;
	if (x->rows != y->rows)
		return kg_fail(err, KG_EINVAL,
		               "least squares: X has %d rows but Y has %d: expected the same number",
		               x->rows, y->rows);
	if (!(lambda >= 0) || !isfinite(lambda))
		return kg_fail(err, KG_EINVAL,
		               "least squares: ridge parameter %g: expected a finite number >= 0", lambda);
	int ret = kg_mat_check_finite(y, "least squares: Y", err);
	if (ret)
		return ret;
	kg_mat *u = NULL, *s = NULL, *vt = NULL, *t = NULL;
	if ((ret = kg_svd(x, &u, &s, &vt, err))) {
		kg_err_prefix(err, "least squares: X");
		goto done;
	}
	int r = count_rank(s, default_rtol(x, rtol));
	/* B = V diag(f) U^T Y with f = 1/s (retained values) or s / (s^2 + lambda). */
	if ((ret = kg_mat_mul(u, KG_TRANS, y, KG_NOTRANS, &t, err)))
		goto done;
	for (int l = 0; l < s->rows; l++) {
		double sl = s->a[l];
		double f = lambda > 0 ? sl / (sl * sl + lambda) : (l < r ? 1.0 / sl : 0.0);
		for (int j = 0; j < t->cols; j++)
			t->a[(long)l * t->cols + j] *= f;
	}
	if ((ret = kg_mat_mul(vt, KG_TRANS, t, KG_NOTRANS, b, err)))
		goto done;
	if (rank)
		*rank = r;
done:
	kg_mat_free(&u);
	kg_mat_free(&s);
	kg_mat_free(&vt);
	kg_mat_free(&t);
	return ret;
}

int kg_eigsym(const kg_mat *a, kg_mat **values, kg_mat **vectors, kg_err *err)
{
	kg_check_arg(a, err);
	if (values)
		*values = NULL;
	if (vectors)
		*vectors = NULL;
	if (a->rows != a->cols)
		return kg_fail(err, KG_EINVAL, "eigen-decomposition: matrix is %d x %d: expected square",
		               a->rows, a->cols);
	int ret = kg_mat_check_finite(a, "eigen-decomposition", err);
	if (ret)
		return ret;
	int n = a->rows;
	double amax = 0;
	for (long i = 0; i < (long)n * n; i++)
		amax = fmax(amax, fabs(a->a[i]));
	for (int i = 0; i < n; i++)
		for (int j = i + 1; j < n; j++)
			if (fabs(kg_mat_get(a, i, j) - kg_mat_get(a, j, i)) > 1e-10 * amax)
				return kg_fail(err, KG_EINVAL,
				               "eigen-decomposition: elements (%d, %d) = %.17g and (%d, %d) = "
				               "%.17g differ: expected a symmetric matrix",
				               i, j, kg_mat_get(a, i, j), j, i, kg_mat_get(a, j, i));
	kg_mat *w = NULL, *ev = NULL, *vals = NULL, *vecs = NULL;
	if ((ret = kg_mat_copy(a, &w, err)) || (ret = kg_mat_new(n, 1, &ev, err)) ||
	    (ret = kg_mat_new(n, 1, &vals, err)) || (ret = kg_mat_new(n, n, &vecs, err)))
		goto done;
	lapack_int info = LAPACKE_dsyevd(LAPACK_ROW_MAJOR, vectors ? 'V' : 'N', 'U', n, w->a, n,
	                                 ev->a);
	if (info != 0) {
		ret = lapack_fail(err, "eigen-decomposition", info);
		goto done;
	}
	/* LAPACK sorts ascending; PCA wants the largest first. Each eigenvector's sign is
	 * fixed so that its largest component is positive, for reproducible bases. */
	for (int j = 0; j < n; j++) {
		int src = n - 1 - j;
		vals->a[j] = ev->a[src];
		if (!vectors)
			continue;
		int imax = 0;
		for (int i = 1; i < n; i++)
			if (fabs(kg_mat_get(w, i, src)) > fabs(kg_mat_get(w, imax, src)))
				imax = i;
		double sign = kg_mat_get(w, imax, src) < 0 ? -1.0 : 1.0;
		for (int i = 0; i < n; i++)
			kg_mat_set(vecs, i, j, sign * kg_mat_get(w, i, src));
	}
	if (values) {
		*values = vals;
		vals = NULL;
	}
	if (vectors) {
		*vectors = vecs;
		vecs = NULL;
	}
done:
	kg_mat_free(&w);
	kg_mat_free(&ev);
	kg_mat_free(&vals);
	kg_mat_free(&vecs);
	return ret;
}

int kg_mat3_inverse(const double a[9], double out[9])
{
	double c0 = a[4] * a[8] - a[5] * a[7], c1 = a[5] * a[6] - a[3] * a[8],
	       c2 = a[3] * a[7] - a[4] * a[6];
	double det = a[0] * c0 + a[1] * c1 + a[2] * c2;
	if (!(fabs(det) > 0) || !isfinite(det))
		return -1;
	double id = 1.0 / det;
	out[0] = c0 * id;
	out[1] = (a[2] * a[7] - a[1] * a[8]) * id;
	out[2] = (a[1] * a[5] - a[2] * a[4]) * id;
	out[3] = c1 * id;
	out[4] = (a[0] * a[8] - a[2] * a[6]) * id;
	out[5] = (a[2] * a[3] - a[0] * a[5]) * id;
	out[6] = c2 * id;
	out[7] = (a[1] * a[6] - a[0] * a[7]) * id;
	out[8] = (a[0] * a[4] - a[1] * a[3]) * id;
	return 0;
}

int kg_mat3_check_invertible(const double a[9], const char *file, const char *what,
                             kg_err *err)
{
	kg_check_arg(a && what, err);
	const char *f = file ? file : "", *sep = file ? ": " : "";
	for (int i = 0; i < 9; i++)
		if (!isfinite(a[i]))
			return kg_fail(err, KG_EINVAL, "%s%s%s is singular (element [%d][%d] is %g): "
			               "expected a finite, invertible 3 x 3 matrix; recalibrate",
			               f, sep, what, i / 3, i % 3, a[i]);
	kg_mat *m = NULL, *s = NULL;
	int ret = kg_mat_from(3, 3, a, &m, err);
	if (!ret)
		ret = kg_svd(m, NULL, &s, NULL, err);
	kg_mat_free(&m);
	if (ret)
		return ret;
	double sv[3] = { s->a[0], s->a[1], s->a[2] };
	kg_mat_free(&s);
	int rank = 0;
	for (int i = 0; i < 3; i++)
		rank += sv[0] > 0 && sv[i] > KG_MAT3_RCOND_MIN * sv[0];
	if (rank < 3)
		return kg_fail(err, KG_EINVAL, "%s%s%s is singular (rank %d < 3; singular values "
		               "%.3g %.3g %.3g): expected an invertible 3 x 3 matrix; recalibrate",
		               f, sep, what, rank, sv[0], sv[1], sv[2]);
	return 0;
}
