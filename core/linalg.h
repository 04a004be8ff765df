/* Dense linear algebra on small row-major double matrices, through LAPACKE.
 *
 * A kg_mat is one allocation: the header and rows * cols doubles, element (r, c) at
 * a[r * cols + c]. Vectors are matrices with one column. Matrices come back through
 * out-parameters and are freed with kg_mat_free(&m).
 *
 * Every decomposition refuses NaN or Inf in its input (KG_EINVAL, the message names
 * the element). Tolerances are relative: a singular value s counts when
 * s > rtol * smax; rtol <= 0 selects the default max(rows, cols) * DBL_EPSILON. */
#ifndef KG_LINALG_H
#define KG_LINALG_H

#include "error.h"

typedef struct kg_mat {
	int rows, cols;
	double *a; /* row-major, points just past this header */
} kg_mat;

/* A rows x cols matrix of zeros (rows, cols >= 1). */
int kg_mat_new(int rows, int cols, kg_mat **out, kg_err *err);
/* A rows x cols matrix filled from row-major data. */
int kg_mat_from(int rows, int cols, const double *data, kg_mat **out, kg_err *err);
int kg_mat_copy(const kg_mat *m, kg_mat **out, kg_err *err);
int kg_mat_identity(int n, kg_mat **out, kg_err *err);
void kg_mat_free(kg_mat **m);

static inline double kg_mat_get(const kg_mat *m, int r, int c) { return m->a[(long)r * m->cols + c]; }
static inline void kg_mat_set(kg_mat *m, int r, int c, double v) { m->a[(long)r * m->cols + c] = v; }

/* 1 if every element is finite. */
int kg_mat_isfinite(const kg_mat *m);
/* Fail with a message naming the first non-finite element; `what` names the matrix. */
int kg_mat_check_finite(const kg_mat *m, const char *what, kg_err *err);
/* Largest |a_ij - b_ij| (+inf when the shapes differ). */
double kg_mat_max_abs_diff(const kg_mat *a, const kg_mat *b);

/* Transpose flags for kg_mat_mul. */
enum kg_trans { KG_NOTRANS = 0, KG_TRANS = 1 };

/* out = op(a) op(b) where op is the identity or the transpose. */
int kg_mat_mul(const kg_mat *a, enum kg_trans ta, const kg_mat *b, enum kg_trans tb,
               kg_mat **out, kg_err *err);
int kg_mat_transpose(const kg_mat *a, kg_mat **out, kg_err *err);

/* Thin SVD a = U diag(s) Vt with k = min(rows, cols): U is rows x k, s is k x 1 in
 * decreasing order, Vt is k x cols. Any output may be NULL. */
int kg_svd(const kg_mat *a, kg_mat **u, kg_mat **s, kg_mat **vt, kg_err *err);

/* Moore-Penrose pseudo-inverse (cols x rows) by SVD; singular values at or below
 * rtol * smax are treated as zero. rank and the singular values (k x 1) are
 * returned when the pointers are not NULL. */
int kg_pinv(const kg_mat *a, double rtol, kg_mat **pinv, int *rank, kg_mat **s, kg_err *err);

/* The inverse of a 3 x 3 matrix (row-major) by cofactors; -1 (out untouched) when it
 * is singular or not finite. */
int kg_mat3_inverse(const double a[9], double out[9]);

/* Smallest singular value over the largest below which a 3 x 3 matrix counts as
 * singular (kg_mat3_check_invertible). */
#define KG_MAT3_RCOND_MIN 1e-10

/* Refuse a 3 x 3 matrix (row-major) that is not finite or whose smallest singular
 * value is at or below KG_MAT3_RCOND_MIN times its largest, with one message for
 * every caller: "FILE: WHAT is singular (rank r < 3; singular values ...)". file may
 * be NULL (the message then starts with what). */
int kg_mat3_check_invertible(const double a[9], const char *file, const char *what,
                             kg_err *err);

/* Condition number smax / smin over the min(rows, cols) singular values; +inf when
 * the matrix is rank deficient (smin <= rtol * smax). */
int kg_cond(const kg_mat *a, double rtol, double *cond, kg_err *err);

/* Least squares with optional ridge: the B (p x q) minimising
 * ||X B - Y||^2 + lambda ||B||^2 for X n x p and Y n x q (q right-hand sides).
 * lambda = 0 gives the minimum-norm solution, with singular values of X at or below
 * rtol * smax dropped; lambda > 0 gives the Tikhonov solution
 * V diag(s / (s^2 + lambda)) U^T Y. rank (of X under rtol) may be NULL. */
int kg_lstsq(const kg_mat *x, const kg_mat *y, double lambda, double rtol, kg_mat **b,
             int *rank, kg_err *err);

/* Eigen-decomposition of a symmetric matrix (checked to 1e-10 relative): eigenvalues
 * (n x 1) in decreasing order, eigenvectors as the matching columns of an n x n
 * matrix. Either output may be NULL. For PCA pass X^T X or a covariance. */
int kg_eigsym(const kg_mat *a, kg_mat **values, kg_mat **vectors, kg_err *err);

#endif
