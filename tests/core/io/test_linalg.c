/* Linear algebra on hard cases: rank-deficient and nearly collinear matrices, pinv
 * identities, least squares and ridge against closed forms worked out without
 * LAPACK, SVD reconstruction, symmetric eigen-decomposition, NaN refused. */
#include <float.h>
#include <string.h>

#include "kg_core.h"
#include "kg_test.h"

static unsigned long long rng = 88172645463325252ull;

static double urand(void)
{
	rng ^= rng << 13;
	rng ^= rng >> 7;
	rng ^= rng << 17;
	return (double)(rng >> 11) / 9007199254740992.0 * 2.0 - 1.0;
}

static kg_mat *random_mat(int r, int c)
{
	kg_mat *m;
	if (kg_mat_new(r, c, &m, NULL))
		abort();
	for (int i = 0; i < r * c; i++)
		m->a[i] = urand();
	return m;
}

static kg_mat *mul(const kg_mat *a, enum kg_trans ta, const kg_mat *b, enum kg_trans tb)
{
	kg_mat *c;
	kg_err err;
	if (kg_mat_mul(a, ta, b, tb, &c, &err)) {
		fprintf(stderr, "%s\n", err.msg);
		abort();
	}
	return c;
}

/* Inverse of a 3 x 3 matrix by cofactors: a closed form independent of LAPACK. */
static void inv3(const double a[9], double o[9])
{
	double c00 = a[4] * a[8] - a[5] * a[7], c01 = a[5] * a[6] - a[3] * a[8],
	       c02 = a[3] * a[7] - a[4] * a[6];
	double det = a[0] * c00 + a[1] * c01 + a[2] * c02;
	o[0] = c00 / det;
	o[1] = (a[2] * a[7] - a[1] * a[8]) / det;
	o[2] = (a[1] * a[5] - a[2] * a[4]) / det;
	o[3] = c01 / det;
	o[4] = (a[0] * a[8] - a[2] * a[6]) / det;
	o[5] = (a[2] * a[3] - a[0] * a[5]) / det;
	o[6] = c02 / det;
	o[7] = (a[1] * a[6] - a[0] * a[7]) / det;
	o[8] = (a[0] * a[4] - a[1] * a[3]) / det;
}

/* (X^T X + lambda I)^-1 X^T Y for X n x 3, the textbook normal equations. */
static kg_mat *normal_equations(const kg_mat *x, const kg_mat *y, double lambda)
{
	kg_mat *xtx = mul(x, KG_TRANS, x, KG_NOTRANS), *xty = mul(x, KG_TRANS, y, KG_NOTRANS);
	for (int i = 0; i < 3; i++)
		xtx->a[i * 3 + i] += lambda;
	double inv[9];
	inv3(xtx->a, inv);
	kg_mat *im, *b;
	kg_mat_from(3, 3, inv, &im, NULL);
	b = mul(im, KG_NOTRANS, xty, KG_NOTRANS);
	kg_mat_free(&xtx);
	kg_mat_free(&xty);
	kg_mat_free(&im);
	return b;
}

static double fro(const kg_mat *m)
{
	double s = 0;
	for (int i = 0; i < m->rows * m->cols; i++)
		s += m->a[i] * m->a[i];
	return sqrt(s);
}

static void test_basics(void)
{
	double a[6] = {1, 2, 3, 4, 5, 6}, b[6] = {7, 8, 9, 10, 11, 12};
	kg_mat *A, *B, *C, *T;
	kg_mat_from(2, 3, a, &A, NULL);
	kg_mat_from(3, 2, b, &B, NULL);
	C = mul(A, KG_NOTRANS, B, KG_NOTRANS);
	double want[4] = {58, 64, 139, 154};
	for (int i = 0; i < 4; i++)
		CHECK_NEAR(C->a[i], want[i], 0, "A B");
	kg_mat_free(&C);
	C = mul(B, KG_TRANS, A, KG_TRANS); /* (A B)^T */
	CHECK_NEAR(kg_mat_get(C, 0, 1), 139, 0, "B^T A^T");
	CHECK_NEAR(kg_mat_get(C, 1, 0), 64, 0, "B^T A^T");
	kg_mat_transpose(A, &T, NULL);
	CHECK(T->rows == 3 && T->cols == 2 && kg_mat_get(T, 2, 1) == 6, "transpose");
	kg_err err;
	kg_mat *bad = NULL;
	CHECK(kg_mat_mul(A, KG_NOTRANS, A, KG_NOTRANS, &bad, &err) == KG_EINVAL && !bad,
	      "inner dimension mismatch refused");
	CHECK(strstr(err.msg, "inner dimensions") != NULL, "message: %s", err.msg);
	CHECK(kg_mat_new(0, 3, &bad, &err) == KG_EINVAL, "empty matrix refused");
	kg_mat_free(&A);
	kg_mat_free(&B);
	kg_mat_free(&C);
	kg_mat_free(&T);
}

static void check_svd(int r, int c)
{
	kg_mat *A = random_mat(r, c), *U, *S, *Vt;
	kg_err err;
	CHECK(kg_svd(A, &U, &S, &Vt, &err) == 0, "svd %dx%d: %s", r, c, err.msg);
	int k = r < c ? r : c;
	CHECK(U->rows == r && U->cols == k && S->rows == k && Vt->rows == k && Vt->cols == c,
	      "thin shapes");
	for (int i = 0; i + 1 < k; i++)
		CHECK(S->a[i] >= S->a[i + 1] && S->a[i + 1] >= 0, "singular values sorted");
	kg_mat *US;
	kg_mat_copy(U, &US, NULL);
	for (int i = 0; i < r; i++)
		for (int j = 0; j < k; j++)
			US->a[i * k + j] *= S->a[j];
	kg_mat *R = mul(US, KG_NOTRANS, Vt, KG_NOTRANS);
	CHECK(kg_mat_max_abs_diff(R, A) <= 1e-12, "U S Vt = A to 1e-12 (%dx%d): %.3g", r, c,
	      kg_mat_max_abs_diff(R, A));
	kg_mat *UtU = mul(U, KG_TRANS, U, KG_NOTRANS), *I;
	kg_mat_identity(k, &I, NULL);
	CHECK(kg_mat_max_abs_diff(UtU, I) <= 1e-12, "U orthonormal");
	kg_mat_free(&A);
	kg_mat_free(&U);
	kg_mat_free(&S);
	kg_mat_free(&Vt);
	kg_mat_free(&US);
	kg_mat_free(&R);
	kg_mat_free(&UtU);
	kg_mat_free(&I);
}

/* The Penrose identities, to tol (round-off grows with the condition number). */
static void check_pinv_identities(const kg_mat *A, double rtol, double tol, const char *what)
{
	kg_mat *P;
	kg_err err;
	CHECK(kg_pinv(A, rtol, &P, NULL, NULL, &err) == 0, "%s: pinv: %s", what, err.msg);
	kg_mat *AP = mul(A, KG_NOTRANS, P, KG_NOTRANS), *PA = mul(P, KG_NOTRANS, A, KG_NOTRANS);
	kg_mat *APA = mul(AP, KG_NOTRANS, A, KG_NOTRANS), *PAP = mul(PA, KG_NOTRANS, P, KG_NOTRANS);
	kg_mat *APt, *PAt;
	kg_mat_transpose(AP, &APt, NULL);
	kg_mat_transpose(PA, &PAt, NULL);
	CHECK(kg_mat_max_abs_diff(APA, A) <= tol, "%s: A A+ A = A (%.3g)", what,
	      kg_mat_max_abs_diff(APA, A));
	CHECK(kg_mat_max_abs_diff(PAP, P) <= tol * (1 + fro(P)), "%s: A+ A A+ = A+ (%.3g)", what,
	      kg_mat_max_abs_diff(PAP, P));
	CHECK(kg_mat_max_abs_diff(AP, APt) <= tol, "%s: A A+ symmetric", what);
	CHECK(kg_mat_max_abs_diff(PA, PAt) <= tol, "%s: A+ A symmetric", what);
	kg_mat_free(&P);
	kg_mat_free(&AP);
	kg_mat_free(&PA);
	kg_mat_free(&APA);
	kg_mat_free(&PAP);
	kg_mat_free(&APt);
	kg_mat_free(&PAt);
}

static void test_rank_deficient(void)
{
	/* Column 3 = column 1 + column 2: rank 2, infinite condition number. */
	kg_mat *A = random_mat(6, 3);
	for (int i = 0; i < 6; i++)
		A->a[i * 3 + 2] = A->a[i * 3] + A->a[i * 3 + 1];
	kg_mat *P, *S;
	int rank = -1;
	kg_err err;
	CHECK(kg_pinv(A, 0, &P, &rank, &S, &err) == 0, "pinv: %s", err.msg);
	CHECK(rank == 2, "rank %d, expected 2", rank);
	CHECK(S->rows == 3 && S->a[2] <= 1e-14 * S->a[0], "smallest singular value ~0: %g", S->a[2]);
	double cond = 0;
	CHECK(kg_cond(A, 0, &cond, &err) == 0 && isinf(cond), "cond of rank-deficient = inf (%g)", cond);
	check_pinv_identities(A, 0, 1e-12, "rank 2");
	/* Least squares picks the minimum-norm solution: B is orthogonal to the null
	 * space (1, 1, -1). */
	kg_mat *Y = random_mat(6, 1), *B;
	CHECK(kg_lstsq(A, Y, 0, 0, &B, &rank, &err) == 0 && rank == 2, "lstsq rank 2");
	CHECK_NEAR(B->a[0] + B->a[1] - B->a[2], 0, 1e-12, "minimum norm solution");
	kg_mat_free(&B);
	/* All zeros: rank 0, pinv 0, cond inf. */
	kg_mat *Z;
	kg_mat_new(3, 3, &Z, NULL);
	CHECK(kg_pinv(Z, 0, &B, &rank, NULL, &err) == 0 && rank == 0 && fro(B) == 0, "zero matrix");
	CHECK(kg_cond(Z, 0, &cond, &err) == 0 && isinf(cond), "cond of zero = inf");
	kg_mat_free(&A);
	kg_mat_free(&P);
	kg_mat_free(&S);
	kg_mat_free(&Y);
	kg_mat_free(&B);
	kg_mat_free(&Z);
}

static void test_collinear(void)
{
	/* A 3-patch-like chart whose third column nearly repeats the first. */
	kg_mat *A = random_mat(8, 3);
	for (int i = 0; i < 8; i++)
		A->a[i * 3 + 2] = A->a[i * 3] + 1e-9 * urand();
	double cond = 0;
	int rank = 0;
	kg_mat *P;
	kg_err err;
	CHECK(kg_cond(A, 0, &cond, &err) == 0 && isfinite(cond) && cond > 1e8,
	      "nearly collinear: large finite cond (%g)", cond);
	CHECK(kg_pinv(A, 0, &P, &rank, NULL, &err) == 0 && rank == 3, "full rank by default tol");
	kg_mat_free(&P);
	CHECK(kg_pinv(A, 1e-6, &P, &rank, NULL, &err) == 0 && rank == 2,
	      "rank 2 under rtol 1e-6 (%d)", rank);
	double cond_trunc = 0;
	CHECK(kg_cond(A, 1e-6, &cond_trunc, &err) == 0 && isinf(cond_trunc),
	      "cond inf under rtol 1e-6");
	/* With cond ~1e9 the identities hold to cond * eps; once the tiny singular value
	 * is dropped they hold to round-off again, except A A+ A = A, which misses by
	 * the dropped component (~1e-9). */
	check_pinv_identities(A, 0, 1e-15 * cond, "collinear, default rtol");
	kg_mat *P2, *AP, *APA;
	kg_pinv(A, 1e-6, &P2, NULL, NULL, NULL);
	AP = mul(A, KG_NOTRANS, P2, KG_NOTRANS);
	APA = mul(AP, KG_NOTRANS, A, KG_NOTRANS);
	double miss = kg_mat_max_abs_diff(APA, A);
	CHECK(miss > 1e-12 && miss < 1e-8, "truncated pinv misses A by the dropped part (%.3g)", miss);
	kg_mat_free(&P2);
	kg_mat_free(&AP);
	kg_mat_free(&APA);
	kg_mat_free(&P);
	kg_mat_free(&A);
	kg_mat *W = random_mat(4, 7);
	check_pinv_identities(W, 0, 1e-12, "wide 4x7");
	kg_mat_free(&W);
}

static void test_lstsq(void)
{
	kg_mat *X = random_mat(12, 3), *Y = random_mat(12, 2), *B, *C;
	int rank = 0;
	kg_err err;
	CHECK(kg_lstsq(X, Y, 0, 0, &B, &rank, &err) == 0 && rank == 3, "lstsq: %s", err.msg);
	C = normal_equations(X, Y, 0);
	CHECK(B->rows == 3 && B->cols == 2, "B is 3 x 2");
	CHECK(kg_mat_max_abs_diff(B, C) <= 1e-12, "lstsq = normal equations (%.3g)",
	      kg_mat_max_abs_diff(B, C));
	kg_mat_free(&B);
	kg_mat_free(&C);
	/* Ridge: equals (X^T X + lambda I)^-1 X^T Y and shrinks as lambda grows. */
	double prev = INFINITY;
	double lambdas[] = {0, 0.01, 0.1, 1, 10, 1e6};
	for (size_t i = 0; i < sizeof(lambdas) / sizeof(lambdas[0]); i++) {
		CHECK(kg_lstsq(X, Y, lambdas[i], 0, &B, NULL, &err) == 0, "ridge: %s", err.msg);
		C = normal_equations(X, Y, lambdas[i]);
		CHECK(kg_mat_max_abs_diff(B, C) <= 1e-12, "ridge %g = closed form (%.3g)", lambdas[i],
		      kg_mat_max_abs_diff(B, C));
		double n = fro(B);
		CHECK(n < prev, "lambda %g shrinks the solution (%g vs %g)", lambdas[i], n, prev);
		prev = n;
		kg_mat_free(&B);
		kg_mat_free(&C);
	}
	CHECK(prev < 1e-4, "huge lambda drives B to 0 (%g)", prev);
	CHECK(kg_lstsq(X, Y, -1, 0, &B, NULL, &err) == KG_EINVAL && !B, "negative lambda refused");
	CHECK(strstr(err.msg, "ridge") != NULL, "message: %s", err.msg);
	kg_mat *Y5 = random_mat(5, 2);
	CHECK(kg_lstsq(X, Y5, 0, 0, &B, NULL, &err) == KG_EINVAL, "row mismatch refused");
	kg_mat_free(&Y5);
	kg_mat_free(&X);
	kg_mat_free(&Y);
}

static void test_nonfinite(void)
{
	kg_mat *A = random_mat(4, 3), *U = NULL, *P = NULL, *Y = random_mat(4, 1), *B = NULL;
	kg_err err;
	A->a[5] = NAN;
	CHECK(kg_svd(A, &U, NULL, NULL, &err) == KG_EINVAL && !U, "NaN refused by SVD");
	CHECK(strstr(err.msg, "(1, 2)") && strstr(err.msg, "nan") && strstr(err.msg, "finite"),
	      "message names the element: %s", err.msg);
	CHECK(kg_pinv(A, 0, &P, NULL, NULL, &err) == KG_EINVAL && !P, "NaN refused by pinv");
	double c;
	CHECK(kg_cond(A, 0, &c, &err) == KG_EINVAL, "NaN refused by cond");
	A->a[5] = 1;
	Y->a[2] = INFINITY;
	CHECK(kg_lstsq(A, Y, 0, 0, &B, NULL, &err) == KG_EINVAL && !B, "Inf in Y refused");
	CHECK(strstr(err.msg, "Y") && strstr(err.msg, "inf"), "message: %s", err.msg);
	kg_mat_free(&A);
	kg_mat_free(&Y);
}

static void test_eigsym(void)
{
	double a[4] = {2, 1, 1, 2};
	kg_mat *A, *L, *V;
	kg_err err;
	kg_mat_from(2, 2, a, &A, NULL);
	CHECK(kg_eigsym(A, &L, &V, &err) == 0, "eigsym: %s", err.msg);
	CHECK_NEAR(L->a[0], 3, 1e-14, "largest eigenvalue first");
	CHECK_NEAR(L->a[1], 1, 1e-14, "smallest eigenvalue");
	CHECK_NEAR(kg_mat_get(V, 0, 0), M_SQRT1_2, 1e-14, "eigenvector (1,1)/sqrt2");
	CHECK_NEAR(kg_mat_get(V, 1, 0), M_SQRT1_2, 1e-14, "eigenvector (1,1)/sqrt2");
	kg_mat_free(&A);
	kg_mat_free(&L);
	kg_mat_free(&V);

	/* PCA: eigenvalues of X^T X are the squared singular values of X, and the
	 * eigenvectors satisfy (X^T X) v = lambda v. */
	kg_mat *X = random_mat(30, 5), *S;
	A = mul(X, KG_TRANS, X, KG_NOTRANS);
	CHECK(kg_eigsym(A, &L, &V, &err) == 0, "eigsym 5x5: %s", err.msg);
	kg_svd(X, NULL, &S, NULL, NULL);
	for (int i = 0; i < 5; i++)
		CHECK_NEAR(L->a[i], S->a[i] * S->a[i], 1e-12 * L->a[0], "lambda = s^2");
	kg_mat *AV = mul(A, KG_NOTRANS, V, KG_NOTRANS);
	for (int i = 0; i < 5; i++)
		for (int j = 0; j < 5; j++)
			CHECK_NEAR(kg_mat_get(AV, i, j), L->a[j] * kg_mat_get(V, i, j), 1e-12 * L->a[0],
			           "A v = lambda v");
	A->a[1] += 1e-3;
	kg_mat *L2 = NULL;
	CHECK(kg_eigsym(A, &L2, NULL, &err) == KG_EINVAL && !L2, "asymmetric refused");
	CHECK(strstr(err.msg, "symmetric") != NULL, "message: %s", err.msg);
	kg_mat_free(&X);
	kg_mat_free(&S);
	kg_mat_free(&A);
	kg_mat_free(&L);
	kg_mat_free(&V);
	kg_mat_free(&AV);
}

/* kg_mat3_inverse: A A^-1 = I on a badly scaled matrix, -1 and out untouched for a
 * singular or non-finite one. And kg_err_prefix keeps one ": " between prefix and
 * message whether or not the prefix ends with one. */
static void test_mat3_inverse(void)
{
	const double a[9] = {2.0, -1.0, 0.5, 1e-3, 3.0, -2.0, 4.0, 0.25, 1.0};
	double inv[9], worst = 0;
	CHECK(kg_mat3_inverse(a, inv) == 0, "an invertible matrix inverted");
	for (int r = 0; r < 3; r++)
		for (int c = 0; c < 3; c++) {
			double s = 0;
			for (int k = 0; k < 3; k++)
				s += a[3 * r + k] * inv[3 * k + c];
			worst = fmax(worst, fabs(s - (r == c)));
		}
	CHECK(worst < 1e-14, "A A^-1 - I: %g", worst);
	const double sing[9] = {1, 2, 3, 2, 4, 6, 0, 1, 1};
	double out[9] = {7, 7, 7, 7, 7, 7, 7, 7, 7};
	CHECK(kg_mat3_inverse(sing, out) == -1 && out[0] == 7, "a singular matrix refused");
	const double nan_m[9] = {NAN, 0, 0, 0, 1, 0, 0, 0, 1};
	CHECK(kg_mat3_inverse(nan_m, out) == -1, "a non-finite matrix refused");
	kg_err e = {{0}};
	kg_fail(&e, KG_EINVAL, "bad value");
	kg_err_prefix(&e, "%s", "a.json");
	CHECK(!strcmp(e.msg, "a.json: bad value"), "prefix without a colon: '%s'", e.msg);
	kg_err_prefix(&e, "%s: ", "dir");
	CHECK(!strcmp(e.msg, "dir: a.json: bad value"), "prefix ending in ': ': '%s'", e.msg);
}

/* kg_mat3_check_invertible: a well-conditioned but badly scaled matrix passes (its
 * condition number far below 1e10); zeros, rank 1 and 2, a row repeated to 1e-13 and
 * a NaN are refused with one message naming the file, the matrix and the rank. */
static void test_mat3_check(void)
{
	kg_err e = {{0}};
	const double ok[9] = {1e-6, 0, 0, 0, 2e-6, 1e-7, 0, 0, 3e-6};
	CHECK(kg_mat3_check_invertible(ok, "cam.json", "M2", &e) == 0, "invertible: %s", e.msg);
	const double scaled[9] = {1e8, 0, 0, 0, 1, 0, 0, 0, 1e-1}; /* condition 1e9 */
	CHECK(kg_mat3_check_invertible(scaled, "cam.json", "M2", &e) == 0, "cond 1e9: %s", e.msg);
	const struct {
		double a[9];
		const char *want;
	} bad[] = {
		{{0, 0, 0, 0, 0, 0, 0, 0, 0}, "cam.json: M2 is singular (rank 0 < 3;"},
		{{1, 2, 3, 2, 4, 6, 3, 6, 9}, "cam.json: M2 is singular (rank 1 < 3;"},
		{{1, 2, 3, 2, 4, 6, 0, 1, 1}, "cam.json: M2 is singular (rank 2 < 3;"},
		{{1, 0.5, 0.2, 0.1, 1, 0.3, 0.1, 1 + 1e-13, 0.3}, "cam.json: M2 is singular (rank 2 < 3;"},
		{{1e11, 0, 0, 0, 1, 0, 0, 0, 1e-1}, "cam.json: M2 is singular (rank 1 < 3;"},
		{{1, 0, 0, 0, NAN, 0, 0, 0, 1}, "cam.json: M2 is singular (element [1][1] is nan)"},
	};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		memset(&e, 0, sizeof(e));
		CHECK(kg_mat3_check_invertible(bad[i].a, "cam.json", "M2", &e) == KG_EINVAL &&
		          strncmp(e.msg, bad[i].want, strlen(bad[i].want)) == 0,
		      "case %zu: '%s', expected it to start '%s'", i, e.msg, bad[i].want);
	}
	CHECK(kg_mat3_check_invertible(bad[0].a, NULL, "M2", &e) == KG_EINVAL &&
	          strncmp(e.msg, "M2 is singular (rank 0", 22) == 0,
	      "no file: '%s'", e.msg);
}

int main(void)
{
	test_mat3_check();
	test_mat3_inverse();
	test_basics();
	check_svd(7, 4);
	check_svd(4, 7);
	check_svd(61, 3);
	check_svd(1, 1);
	test_rank_deficient();
	test_collinear();
	test_lstsq();
	test_nonfinite();
	test_eigsym();
	return kg_test_done("linalg");
}
