/* Reference calibration: the chart's moments, the PCA basis, the regressions of
 * every method and their leave-one-out validation. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "calib_private.h"

#define NB KG_NBANDS
#define TMAX KG_CALIB_MAX_TERMS
#define KMAX KG_CALIB_MAX_BASIS

/* "Within tolerance of the best" for the choice of K and of the method. */
#define CHOICE_ABS_TOL 1e-6
/* A held-out patch whose leverage is this close to 1 determines a coefficient on its
 * own: leave-one-out cannot predict it. */
#define MIN_LOO_DENOM 1e-9

/* Sums over the patches of a chart for the PCA model: all its fit needs.
 * Subtracting one patch's contribution gives the sums without it, so a
 * leave-one-out refit costs one 61 x 61 eigen-decomposition and a 3 x 3 solve. */
typedef struct moments {
	double n;
	double ss[NB * NB]; /* sum s s^T */
	double s[NB];       /* sum s */
	double xx[9];       /* sum rho rho^T */
	double xs[3 * NB];  /* sum rho s^T */
	double x[3];        /* sum rho */
} moments;

static void moments_add(moments *mo, const kg_spectrum *s, const double rgb[3],
                        double sign)
{
	mo->n += sign;
	for (int l = 0; l < NB; l++) {
		mo->s[l] += sign * s->v[l];
		for (int j = 0; j < NB; j++)
			mo->ss[l * NB + j] += sign * s->v[l] * s->v[j];
	}
	for (int c = 0; c < 3; c++) {
		mo->x[c] += sign * rgb[c];
		for (int d = 0; d < 3; d++)
			mo->xx[c * 3 + d] += sign * rgb[c] * rgb[d];
		for (int l = 0; l < NB; l++)
			mo->xs[c * NB + l] += sign * rgb[c] * s->v[l];
	}
}

/* The least-squares map from RGB to spectra on moments, with a ridge:
 * A (61 x 3) = ((G + lambda I)^-1 C)^T, i.e. A = S^T rho (rho^T rho + lambda I)^-1.
 * The charts reaching here passed the collinearity check, so G is well
 * conditioned. cond: that of rho, sqrt(cond(G + lambda I)). */
static int regress_rgb(const double *G, const double *C, double lambda, double *A,
                       double *cond, kg_err *err)
{
	kg_mat *g = NULL, *gi = NULL;
	double c = INFINITY;
	int rank = 0;
	int ret = kg_mat_new(3, 3, &g, err);
	if (ret)
		return ret;
	for (int t = 0; t < 3; t++)
		for (int u = 0; u < 3; u++)
			g->a[t * 3 + u] = G[t * 3 + u] + (t == u ? lambda : 0.0);
	ret = kg_cond(g, 0, &c, err);
	if (ret == 0)
		ret = kg_pinv(g, 0, &gi, &rank, NULL, err);
	if (ret == 0 && rank < 3)
		ret = kg_fail(err, KG_ERANGE, "rho^T rho is singular (rank %d of 3)", rank);
	if (ret == 0) {
		for (int l = 0; l < NB; l++)
			for (int t = 0; t < 3; t++)
				A[l * 3 + t] = gi->a[t * 3] * C[l] + gi->a[t * 3 + 1] * C[NB + l] +
				               gi->a[t * 3 + 2] * C[2 * NB + l];
	}
	if (cond)
		*cond = sqrt(c);
	kg_mat_free(&g);
	kg_mat_free(&gi);
	return ret;
}

/* A regression method from the SVD of its m x T design matrix X = U diag(sv) V^T:
 * A = S^T X (X^T X + lambda I)^-1 = S^T U diag(sv / (sv^2 + lambda)) V^T, computed
 * without forming X^T X (whose condition number is the square of X's; the degree-3
 * root-polynomial terms are nearly collinear). Also the leverages
 * h_i = [X (X^T X + lambda I)^-1 X^T]_ii, which give leave-one-out predictions in
 * closed form. Without a ridge, a rank-deficient X makes the method unavailable. */
static int fit_design(const kg_patchset *train, kg_method m, double lambda,
                      kg_spectral_map *map, double *h, kg_err *err)
{
	int n = train->n, T = kg_method_nterms(m);
	kg_mat *X = NULL, *U = NULL, *sv = NULL, *Vt = NULL;
	double P[KG_CALIB_MAX_TERMS * NB], f[KG_CALIB_MAX_TERMS], g[KG_CALIB_MAX_TERMS];
	map->method = m;
	map->nterms = T;
	map->lambda = lambda;
	memset(map->offset, 0, sizeof(map->offset));
	int ret = kg_mat_new(n, T, &X, err);
	for (int i = 0; ret == 0 && i < n; i++)
		kg_method_terms(m, train->rgb[i], X->a + (size_t)i * T);
	if (ret == 0)
		ret = kg_svd(X, &U, &sv, &Vt, err);
	if (ret)
		goto done;
	/* kg_svd is thin: r = min(n, T) singular values, U n x r, Vt r x T. */
	int r = sv->rows;
	double smax = sv->a[0], smin = r < T ? 0.0 : sv->a[r - 1];
	double tol = (n > T ? n : T) * 2.220446049250313e-16 * smax;
	map->cond = smin > tol ? smax / smin : INFINITY;
	if (lambda == 0 && !(smin > tol)) {
		ret = kg_fail(err, KG_ERANGE,
		              "its %d terms are linearly dependent on this chart (%d patches; "
		              "condition number %.3g); a ridge (--ridge) would regularise it",
		              T, n, map->cond);
		goto done;
	}
	for (int k = 0; k < r; k++) {
		double s = sv->a[k];
		f[k] = s / (s * s + lambda);
		g[k] = s * s / (s * s + lambda);
	}
	/* P = diag(f) U^T S (r x 61), then A = (V P)^T. */
	for (int k = 0; k < r; k++)
		for (int l = 0; l < NB; l++) {
			double v = 0;
			for (int i = 0; i < n; i++)
				v += U->a[(size_t)i * r + k] * train->spectra[i].v[l];
			P[k * NB + l] = f[k] * v;
		}
	for (int l = 0; l < NB; l++)
		for (int t = 0; t < T; t++) {
			double v = 0;
			for (int k = 0; k < r; k++)
				v += Vt->a[k * T + t] * P[k * NB + l];
			map->A[l * T + t] = v;
		}
	for (int i = 0; h && i < n; i++) {
		double v = 0;
		for (int k = 0; k < r; k++)
			v += U->a[(size_t)i * r + k] * U->a[(size_t)i * r + k] * g[k];
		h[i] = v;
	}
done:
	kg_mat_free(&X);
	kg_mat_free(&U);
	kg_mat_free(&sv);
	kg_mat_free(&Vt);
	return ret;
}

/* The PCA basis: the nk leading eigenvectors of the scatter matrix S^T S (centred:
 * of the covariance about the mean spectrum), i.e. the leading right singular
 * vectors of S, into B (61 x nk, stride nk). Signs are fixed so each vector sums to
 * a positive value. sv: singular values; energy: cumulative fraction of the trace. */
static int pca_basis(const moments *mo, int centred, int nk, double *B, double *sv,
                     double *energy, kg_err *err)
{
	kg_mat *Q = NULL, *val = NULL, *vec = NULL;
	int ret = kg_mat_from(NB, NB, mo->ss, &Q, err);
	if (ret)
		return ret;
	if (centred)
		for (int l = 0; l < NB; l++)
			for (int j = 0; j < NB; j++)
				Q->a[l * NB + j] -= mo->s[l] * mo->s[j] / mo->n;
	double trace = 0;
	for (int l = 0; l < NB; l++)
		trace += Q->a[l * NB + l];
	ret = kg_eigsym(Q, &val, &vec, err);
	if (ret == 0) {
		double cum = 0;
		for (int k = 0; k < nk; k++) {
			double sum = 0, big = 0;
			for (int l = 0; l < NB; l++) {
				double v = vec->a[l * NB + k];
				sum += v;
				if (fabs(v) > fabs(big))
					big = v;
			}
			/* A vector with no clear sum takes the sign of its largest element. */
			double sign = fabs(sum) > 1e-9 ? (sum > 0 ? 1 : -1) : (big >= 0 ? 1 : -1);
			for (int l = 0; l < NB; l++)
				B[l * nk + k] = sign * vec->a[l * NB + k];
			double ev = fmax(val->a[k], 0.0);
			cum += ev;
			if (sv)
				sv[k] = sqrt(ev);
			if (energy)
				energy[k] = trace > 0 ? cum / trace : 0;
		}
	}
	kg_mat_free(&Q);
	kg_mat_free(&val);
	kg_mat_free(&vec);
	return ret;
}

/* The linear map from RGB to spectra that the PCA model projects onto its basis:
 * uncentred, Alin = S^T rho (rho^T rho + lambda I)^-1; centred, the same on the
 * centred spectra and RGB (rbar, mu: the means). Then M = B^T Alin, since
 * W^T rho = B^T S^T rho. */
static int pca_linear(const moments *mo, int centred, double lambda, double *Alin,
                      double rbar[3], double *mu, double *cond, kg_err *err)
{
	if (!centred) {
		memset(rbar, 0, 3 * sizeof(double));
		memset(mu, 0, NB * sizeof(double));
		return regress_rgb(mo->xx, mo->xs, lambda, Alin, cond, err);
	}
	double G[9], C[3 * NB];
	for (int c = 0; c < 3; c++)
		rbar[c] = mo->x[c] / mo->n;
	for (int l = 0; l < NB; l++)
		mu[l] = mo->s[l] / mo->n;
	for (int c = 0; c < 3; c++) {
		for (int d = 0; d < 3; d++)
			G[c * 3 + d] = mo->xx[c * 3 + d] - mo->n * rbar[c] * rbar[d];
		for (int l = 0; l < NB; l++)
			C[c * NB + l] = mo->xs[c * NB + l] - mo->n * rbar[c] * mu[l];
	}
	return regress_rgb(G, C, lambda, Alin, cond, err);
}

/* The PCA model with the first K vectors of B (stride nk): M = B_K^T Alin (K x 3),
 * A = B_K M, offset = mu - A rbar. M may be NULL. */
static void pca_map(const double *B, int nk, int K, const double *Alin,
                    const double rbar[3], const double *mu, kg_spectral_map *map,
                    double *M)
{
	double Mk[KMAX * 3];
	for (int k = 0; k < K; k++)
		for (int c = 0; c < 3; c++) {
			double v = 0;
			for (int l = 0; l < NB; l++)
				v += B[l * nk + k] * Alin[l * 3 + c];
			Mk[k * 3 + c] = v;
		}
	map->method = KG_METHOD_PCA;
	map->nterms = 3;
	for (int l = 0; l < NB; l++) {
		double off = mu[l];
		for (int c = 0; c < 3; c++) {
			double v = 0;
			for (int k = 0; k < K; k++)
				v += B[l * nk + k] * Mk[k * 3 + c];
			map->A[l * 3 + c] = v;
			off -= v * rbar[c];
		}
		map->offset[l] = off;
	}
	if (M)
		memcpy(M, Mk, (size_t)K * 3 * sizeof(double));
}

/* The ridge of a method: wiener's E[rho rho^T] + sigma^2 I over the chart is
 * rho^T rho + m sigma^2 I on sums. */
static double method_lambda(kg_method m, const kg_reference_options *opt, int n)
{
	return m == KG_METHOD_WIENER ? n * opt->noise_sigma * opt->noise_sigma : opt->ridge;
}

/* Mean leave-one-out errors of the PCA model for K = 1..nK: for each patch, the
 * basis and M are refitted on the others (moments without it) and it is predicted. */
static int pca_leave_one_out(const moments *all, const kg_patchset *train, int m,
                             const kg_reference_options *opt, const calib_d65 *d65,
                             double *rmse_K, double *de_K, double (*band_K)[NB],
                             int *nK_out, kg_err *err)
{
	int nK = m - 1 < KMAX ? m - 1 : KMAX;
	double sum_r[KMAX] = {0}, sum_d[KMAX] = {0};
	for (int K = 0; K < KMAX; K++)
		for (int l = 0; l < NB; l++)
			band_K[K][l] = 0;
	moments *mo = malloc(sizeof(*mo));
	kg_spectral_map *map = malloc(sizeof(*map));
	int ok = mo && map && nK >= 1;
	if (!mo || !map) {
		free(mo);
		free(map);
		return kg_fail(err, KG_ENOMEM, "leave-one-out validation: out of memory");
	}
	for (int i = 0; ok && i < m; i++) {
		const kg_spectrum *s = &train->spectra[i];
		double B[NB * KMAX], Alin[NB * 3], rbar[3], mu[NB];
		*mo = *all;
		moments_add(mo, s, train->rgb[i], -1.0);
		if (pca_basis(mo, opt->centred, nK, B, NULL, NULL, NULL) != 0 ||
		    pca_linear(mo, opt->centred, opt->ridge, Alin, rbar, mu, NULL, NULL) != 0) {
			ok = 0;
			break;
		}
		for (int K = 1; K <= nK; K++) {
			kg_spectrum est;
			pca_map(B, nK, K, Alin, rbar, mu, map, NULL);
			kg_spectral_map_apply(map, train->rgb[i], &est);
			sum_r[K - 1] += kg_spectrum_rmse(&est, s);
			sum_d[K - 1] += calib_de00(d65, &est, s);
			for (int l = 0; l < NB; l++)
				band_K[K - 1][l] += (est.v[l] - s->v[l]) * (est.v[l] - s->v[l]);
		}
	}
	*nK_out = ok ? nK : 0;
	for (int K = 0; K < KMAX; K++) {
		rmse_K[K] = K < *nK_out ? sum_r[K] / m : NAN;
		de_K[K] = K < *nK_out ? sum_d[K] / m : NAN;
		for (int l = 0; l < NB; l++)
			band_K[K][l] = K < *nK_out ? sqrt(band_K[K][l] / m) : NAN;
	}
	free(mo);
	free(map);
	return 0;
}

double kg_spectral_map_neutral_tilt(const kg_spectral_map *map, const double white[3])
{
	if (!map || !map->available || !(white[0] > 0 && white[1] > 0 && white[2] > 0))
		return NAN;
	double worst = 0;
	const double levels[2] = {0.2, 0.8};
	for (int k = 0; k < 2; k++) {
		double rgb[3] = {levels[k] * white[0], levels[k] * white[1], levels[k] * white[2]};
		kg_spectrum est;
		kg_spectral_map_apply(map, rgb, &est);
		double mean = 0;
		for (int l = 0; l < NB; l++)
			mean += est.v[l] / NB;
		if (!(mean > 0))
			return NAN;
		for (int l = 0; l < NB; l++)
			worst = fmax(worst, fabs(est.v[l] / mean - 1));
	}
	return worst;
}

/* The camera's value of the perfect diffuser for the neutral tilt: from the chart's
 * neutral patches when it has enough (calib/flare.c's line at Y = 1), else the
 * response's reading of a flat 1. */
static int neutral_white(kg_reference *ref, const kg_patchset *train, kg_err *err)
{
	kg_flare f;
	int ret = kg_flare_estimate(train, NULL, NULL, 0, &f, err);
	if (ret)
		return ret;
	if (f.found) {
		memcpy(ref->neutral_white, f.slope, sizeof(f.slope));
		snprintf(ref->neutral_white_source, sizeof(ref->neutral_white_source), "neutrals");
		return 0;
	}
	double one[NB];
	for (int l = 0; l < NB; l++)
		one[l] = 1;
	if (ref->response.available)
		kg_response_apply(&ref->response, one, ref->neutral_white);
	else
		ref->neutral_white[0] = ref->neutral_white[1] = ref->neutral_white[2] = NAN;
	snprintf(ref->neutral_white_source, sizeof(ref->neutral_white_source), "response");
	return 0;
}

/* Fit a regression method and validate it: in-sample RMSE, and leave-one-out in
 * closed form, s_i - (s_i - est_i) / (1 - h_i), which is the refit without patch i
 * for a fixed ridge. A method the chart cannot support is marked unavailable. */
static int fit_regression(const kg_patchset *train, int m, kg_method j,
                          const kg_reference_options *opt, const calib_d65 *d65,
                          kg_spectral_map *map, kg_err *err)
{
	int rows = train->n; /* m of the chart's, then any flat greys of the neutral prior */
	map->method = j;
	map->nterms = kg_method_nterms(j);
	map->lambda = method_lambda(j, opt, m);
	map->loo_rmse = map->loo_de00 = NAN;
	for (int l = 0; l < NB; l++)
		map->loo_band[l] = NAN;
	if (m < map->nterms && map->lambda == 0) {
		snprintf(map->note, sizeof(map->note),
		         "needs at least %d patches without a ridge (the chart has %d)", map->nterms, m);
		return 0;
	}
	double *h = malloc((size_t)rows * sizeof(double));
	if (!h)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	kg_err e = {{0}};
	int ret = fit_design(train, j, map->lambda, map, h, &e);
	if (ret) {
		free(h);
		if (ret != KG_ERANGE)
			return kg_fail(err, ret, "method %s: %s", kg_method_name(j), e.msg);
		size_t n = strnlen(e.msg, sizeof(map->note) - 1);
		memcpy(map->note, e.msg, n);
		map->note[n] = '\0';
		return 0;
	}
	map->available = 1;
	double fit = 0, loo = 0, de = 0, band[NB] = {0};
	int loo_ok = 1;
	for (int i = 0; i < m; i++) {
		const kg_spectrum *s = &train->spectra[i];
		kg_spectrum est, held;
		kg_spectral_map_apply(map, train->rgb[i], &est);
		fit += kg_spectrum_rmse(&est, s);
		double d = 1 - h[i];
		if (!(d > MIN_LOO_DENOM)) {
			loo_ok = 0;
			continue;
		}
		for (int l = 0; l < NB; l++) {
			held.v[l] = s->v[l] - (s->v[l] - est.v[l]) / d;
			band[l] += (held.v[l] - s->v[l]) * (held.v[l] - s->v[l]);
		}
		loo += kg_spectrum_rmse(&held, s);
		de += calib_de00(d65, &held, s);
	}
	map->fit_rmse = fit / m;
	if (loo_ok) {
		map->loo_rmse = loo / m;
		map->loo_de00 = de / m;
		for (int l = 0; l < NB; l++)
			map->loo_band[l] = sqrt(band[l] / m);
	}
	free(h);
	return 0;
}

/* The first candidate whose error is within tolerance of the best: the simplest
 * model that validates as well (candidates are ordered simplest first). -1 if
 * none has a finite error. */
static int choose_simplest(const double *errs, int n, double rel_tol)
{
	double best = INFINITY;
	for (int i = 0; i < n; i++)
		if (isfinite(errs[i]) && errs[i] < best)
			best = errs[i];
	if (!isfinite(best))
		return -1;
	for (int i = 0; i < n; i++)
		if (isfinite(errs[i]) && errs[i] <= best * (1 + rel_tol) + CHOICE_ABS_TOL)
			return i;
	return -1;
}

void kg_reference_options_default(kg_reference_options *o)
{
	memset(o, 0, sizeof(*o));
	o->basis = 3;
	o->centred = 0;
	o->ridge = 0;
	o->noise_sigma = 0.01;
	o->method = KG_METHOD_PCA;
	o->max_cond = KG_CALIB_MAX_COND;
	o->max_flare = KG_CALIB_MAX_FLARE;
}

void kg_reference_free(kg_reference **pref)
{
	if (!pref || !*pref)
		return;
	kg_reference *ref = *pref;
	calib_strv_free(ref->ids, ref->m);
	free(ref->train_rgb);
	free(ref->rmse);
	free(ref->gfc);
	free(ref->de00);
	free(ref->projection_rmse);
	free(ref->weight_residual);
	calib_strv_free(ref->field_ids, ref->k);
	free(ref->rho0);
	calib_sources_free(&ref->sources, &ref->nsources);
	calib_strv_free(ref->flagged_ids, ref->nflagged);
	free(ref->flagged_flags);
	kg_pairing_record_free(&ref->pairing);
	free(ref);
	*pref = NULL;
}

static int check_options(const kg_reference_options *opt, kg_err *err)
{
	if (opt->basis < 0 || opt->basis > KMAX)
		return kg_fail(err, KG_EINVAL, "basis size K = %d: expected 1 to %d, or auto",
		               opt->basis, KMAX);
	if (!(opt->ridge >= 0) || !isfinite(opt->ridge))
		return kg_fail(err, KG_EINVAL, "ridge %g: expected a finite number >= 0",
		               opt->ridge);
	if (!(opt->noise_sigma > 0) || !isfinite(opt->noise_sigma))
		return kg_fail(err, KG_EINVAL, "noise sigma %g: expected a finite number > 0",
		               opt->noise_sigma);
	if (opt->method < KG_METHOD_AUTO || opt->method >= KG_METHOD_COUNT)
		return kg_fail(err, KG_EINVAL, "method %d: unknown", (int)opt->method);
	if (!(opt->max_cond >= 1))
		return kg_fail(err, KG_EINVAL, "condition-number limit %g: expected >= 1",
		               opt->max_cond);
	return 0;
}

/* The name of a patch set in messages. */
static const char *set_name(const kg_patchset *ps, const char *fallback)
{
	return ps->source ? ps->source : fallback;
}

static int check_training(const kg_patchset *train, const kg_patchset *field,
                          const kg_reference_options *opt, kg_reference *ref,
                          kg_err *err)
{
	const char *tname = set_name(train, "training chart");
	const char *fname = set_name(field, "field chart");
	if (!train->spectra || !train->rgb)
		return kg_fail(err, KG_EINVAL,
		               "%s: expected both spectra and RGB_R RGB_G RGB_B for every patch",
		               tname);
	if (!field->rgb)
		return kg_fail(err, KG_EINVAL, "%s: expected fields RGB_R RGB_G RGB_B", fname);
	int need = (opt->basis == 0 || opt->method == KG_METHOD_AUTO) ? 4 : 3;
	if (train->n < need)
		return kg_fail(err, KG_EINVAL,
		               "%s: %d patch%s with both a spectrum and RGB; expected at least %d%s",
		               tname, train->n, train->n == 1 ? "" : "es", need,
		               need == 4 ? " (leave-one-out validation refits on all but one)" : "");
	if (opt->basis > train->n)
		return kg_fail(err, KG_EINVAL,
		               "basis size K = %d: the chart has only %d patches (expected K <= %d)",
		               opt->basis, train->n, train->n);
	for (int i = 0; i < train->n; i++)
		if (!kg_spectrum_isfinite(&train->spectra[i]))
			return kg_fail(err, KG_EINVAL, "%s: patch %s: spectrum holds NaN or infinity",
			               tname, train->ids[i]);
	int stride = 0;
	const double *clip = calib_clipped_column(train, &stride);
	double *clipped = NULL;
	if (clip) {
		if (!(clipped = malloc((size_t)train->n * sizeof(double))))
			return kg_fail(err, KG_ENOMEM, "out of memory");
		for (int i = 0; i < train->n; i++)
			clipped[i] = clip[(size_t)i * stride];
	}
	int ret = calib_check_patch_values(tname, train->ids, (const double (*)[3])train->rgb,
	                                   clipped, train->n, KG_CALIB_CLIP_LEVEL, 0, err);
	free(clipped);
	clipped = NULL;
	if (ret)
		return ret;
	double cond_eq, sv[3];
	ret = calib_check_collinear(tname, train->ids, (const double (*)[3])train->rgb,
	                            train->n, opt->max_cond, &ref->cond_rho, &cond_eq, sv, err);
	if (ret)
		return ret;
	if (field->n < 3)
		return kg_fail(err, KG_EINVAL, "%s: %d patch%s with RGB; expected at least 3", fname,
		               field->n, field->n == 1 ? "" : "es");
	for (int i = 0; i < field->n; i++)
		for (int j = 0; j < i; j++)
			if (strcmp(field->ids[i], field->ids[j]) == 0)
				return kg_fail(err, KG_EINVAL, "%s: SAMPLE_ID %s appears twice", fname,
				               field->ids[i]);
	clip = calib_clipped_column(field, &stride);
	if (clip) {
		clipped = malloc((size_t)field->n * sizeof(double));
		if (!clipped)
			return kg_fail(err, KG_ENOMEM, "out of memory");
		for (int i = 0; i < field->n; i++)
			clipped[i] = clip[(size_t)i * stride];
	}
	ret = calib_check_patch_values(fname, field->ids, (const double (*)[3])field->rgb,
	                               clipped, field->n, KG_CALIB_CLIP_LEVEL,
	                               KG_CALIB_BLACK_LEVEL, err);
	free(clipped);
	if (ret)
		return ret;
	return calib_check_collinear(fname, field->ids, (const double (*)[3])field->rgb,
	                             field->n, opt->max_cond, &ref->cond_rho0, &cond_eq, sv,
	                             err);
}

/* The PCA model with the chosen K: basis (and up to 8 singular values for the
 * record), M, its map and in-sample error. */
static int fit_pca(kg_reference *ref, const moments *mo, const kg_patchset *train, int m,
                   const kg_reference_options *opt, kg_err *err)
{
	int nrec = train->n < KMAX ? train->n : KMAX;
	if (nrec < ref->K)
		nrec = ref->K;
	double Ball[NB * KMAX], Alin[NB * 3];
	kg_spectral_map *map = &ref->maps[KG_METHOD_PCA];
	int ret = pca_basis(mo, opt->centred, nrec, Ball, ref->singular_values, ref->energy, err);
	if (ret)
		return ret;
	for (int l = 0; l < NB; l++)
		for (int k = 0; k < ref->K; k++)
			ref->B[l * ref->K + k] = Ball[l * nrec + k];
	map->lambda = opt->ridge;
	ret = pca_linear(mo, opt->centred, opt->ridge, Alin, ref->rgb_mean, ref->mean, &map->cond,
	                 err);
	if (ret) {
		kg_err_prefix(err, "%s: method pca", set_name(train, "training chart"));
		return ret;
	}
	pca_map(ref->B, ref->K, ref->K, Alin, ref->rgb_mean, ref->mean, map, ref->M);
	map->available = 1;
	double sum = 0;
	for (int i = 0; i < m; i++) {
		kg_spectrum est;
		kg_spectral_map_apply(map, train->rgb[i], &est);
		sum += kg_spectrum_rmse(&est, &train->spectra[i]);
	}
	map->fit_rmse = sum / m;
	return 0;
}

/* Per-patch diagnostics: the default method's errors, and the PCA model's
 * projection error and weight residual, all in sample. */
static void patch_diagnostics(kg_reference *ref, const kg_patchset *train,
                              const calib_d65 *d65)
{
	const kg_spectral_map *map = &ref->maps[ref->method];
	for (int i = 0; i < ref->m; i++) {
		const kg_spectrum *s = &train->spectra[i];
		kg_spectrum est;
		kg_spectral_map_apply(map, train->rgb[i], &est);
		ref->rmse[i] = kg_spectrum_rmse(&est, s);
		ref->gfc[i] = kg_spectrum_gfc(&est, s);
		ref->de00[i] = calib_de00(d65, &est, s);
		/* Weights of the patch, w = B^T (s - mean), against the regression. */
		double w[KMAX], proj2 = 0, res2 = 0;
		for (int k = 0; k < ref->K; k++) {
			w[k] = 0;
			for (int l = 0; l < NB; l++)
				w[k] += ref->B[l * ref->K + k] * (s->v[l] - ref->mean[l]);
			double pred = 0;
			for (int c = 0; c < 3; c++)
				pred += ref->M[k * 3 + c] * (train->rgb[i][c] - ref->rgb_mean[c]);
			res2 += (w[k] - pred) * (w[k] - pred);
		}
		for (int l = 0; l < NB; l++) {
			double p = ref->mean[l];
			for (int k = 0; k < ref->K; k++)
				p += ref->B[l * ref->K + k] * w[k];
			proj2 += (s->v[l] - p) * (s->v[l] - p);
		}
		ref->projection_rmse[i] = sqrt(proj2 / NB);
		ref->weight_residual[i] = sqrt(res2);
	}
}

static int record_charts(kg_reference *ref, const kg_patchset *train,
                         const kg_patchset *field, kg_err *err)
{
	int m = train->n;
	ref->m = m;
	ref->ids = calib_strv_dup(train->ids, m);
	ref->train_rgb = malloc((size_t)m * sizeof(*ref->train_rgb));
	ref->rmse = malloc((size_t)m * sizeof(double));
	ref->gfc = malloc((size_t)m * sizeof(double));
	ref->de00 = malloc((size_t)m * sizeof(double));
	ref->projection_rmse = malloc((size_t)m * sizeof(double));
	ref->weight_residual = malloc((size_t)m * sizeof(double));
	ref->k = field->n;
	ref->field_ids = calib_strv_dup(field->ids, field->n);
	ref->rho0 = malloc((size_t)field->n * sizeof(*ref->rho0));
	if (!ref->ids || !ref->train_rgb || !ref->rmse || !ref->gfc || !ref->de00 ||
	    !ref->projection_rmse || !ref->weight_residual || !ref->field_ids || !ref->rho0) {
		if (!ref->ids)
			ref->m = 0;
		if (!ref->field_ids)
			ref->k = 0;
		return kg_fail(err, KG_ENOMEM, "reference calibration: out of memory");
	}
	memcpy(ref->train_rgb, train->rgb, (size_t)m * sizeof(*ref->train_rgb));
	memcpy(ref->rho0, field->rgb, (size_t)field->n * sizeof(*ref->rho0));
	return 0;
}

/* Every method fitted to set and validated by leave-one-out over its first m patches
 * (the chart's; any further ones are the neutral prior's flat greys, always fitted),
 * K and the default method chosen as the options say. */
static int fit_methods(kg_reference *ref, const kg_patchset *set, int m,
                       const kg_reference_options *opt, const calib_d65 *d65, const char *tname,
                       kg_err *err)
{
	double de_K[KMAX], band_K[KMAX][NB];
	moments *mo = calloc(1, sizeof(*mo));
	if (!mo)
		return kg_fail(err, KG_ENOMEM, "reference calibration: out of memory");
	memset(ref->maps, 0, sizeof(ref->maps));
	int ret = 0;
	/* The regression methods, validated in closed form. */
	for (int j = KG_METHOD_LINEAR; j < KG_METHOD_COUNT && !ret; j++)
		ret = fit_regression(set, m, (kg_method)j, opt, d65, &ref->maps[j], err);

	/* PCA: leave-one-out for every K, then the K and the model. */
	for (int i = 0; i < set->n && !ret; i++)
		moments_add(mo, &set->spectra[i], set->rgb[i], 1.0);
	if (!ret)
		ret = pca_leave_one_out(mo, set, m, opt, d65, ref->loo_by_K, de_K, band_K, &ref->nK,
		                        err);
	if (!ret && opt->basis == 0) {
		int best = choose_simplest(ref->loo_by_K, ref->nK, KG_CALIB_K_TOLERANCE);
		if (best < 0)
			ret = kg_fail(err, KG_EINVAL,
			              "%s: --basis auto: leave-one-out validation failed for every K "
			              "(the chart's RGB is singular without one of its patches)",
			              tname);
		ref->K = best + 1;
		ref->basis_auto = 1;
	} else if (!ret) {
		ref->K = opt->basis;
	}
	if (!ret)
		ret = fit_pca(ref, mo, set, m, opt, err);
	free(mo);
	if (ret)
		return ret;
	ref->maps[KG_METHOD_PCA].loo_rmse = ref->K <= ref->nK ? ref->loo_by_K[ref->K - 1] : NAN;
	ref->maps[KG_METHOD_PCA].loo_de00 = ref->K <= ref->nK ? de_K[ref->K - 1] : NAN;
	for (int l = 0; l < NB; l++)
		ref->maps[KG_METHOD_PCA].loo_band[l] = ref->K <= ref->nK ? band_K[ref->K - 1][l] : NAN;
	calib_reference_derive(ref);

	if (opt->method == KG_METHOD_AUTO) {
		double errs[KG_METHOD_COUNT];
		/* The colour error people judge a chart by (mean leave-one-out CIEDE2000
		 * under D65), not the spectral RMSE: the RMSE favours a smooth spectrum
		 * that misses the hue (docs/calib-camera.md, "--method auto"). */
		for (int j = 0; j < KG_METHOD_COUNT; j++)
			errs[j] = ref->maps[j].available ? ref->maps[j].loo_de00 : NAN;
		int best = choose_simplest(errs, KG_METHOD_COUNT, KG_CALIB_K_TOLERANCE);
		if (best < 0)
			return kg_fail(err, KG_EINVAL,
			               "%s: --method auto: no method could be validated by leave-one-out",
			               tname);
		ref->method = (kg_method)best;
		ref->method_auto = 1;
	} else {
		ref->method = opt->method;
		if (!ref->maps[ref->method].available)
			return kg_fail(err, KG_EINVAL, "%s: method %s: %s", tname,
			               kg_method_name(ref->method), ref->maps[ref->method].note);
	}
	for (int j = 0; j < KG_METHOD_COUNT; j++)
		ref->maps[j].neutral_tilt = kg_spectral_map_neutral_tilt(&ref->maps[j],
		                                                         ref->neutral_white);
	return 0;
}

/* The neutral prior: when the chosen method gives a flat grey more shape than
 * KG_CALIB_MAX_NEUTRAL_TILT, the chart cannot say that a grey is flat (the CIE test
 * colours hold no neutral): flat greys at KG_CALIB_NEUTRAL_LEVELS levels, read through
 * the response learned from the same chart, are added to the fit, each counted 4, 16
 * or 64 times, the least that brings the tilt within the limit. The chart's own
 * patches still validate every method. */
static int neutral_prior(kg_reference *ref, const kg_patchset *train,
                         const kg_reference_options *opt, const calib_d65 *d65,
                         const char *tname, kg_err *err)
{
	static const double levels[KG_CALIB_NEUTRAL_LEVELS] = {0.05, 0.2, 0.5, 0.9};
	static const int weights[3] = {4, 16, 64};
	double tilt = ref->maps[ref->method].neutral_tilt;
	ref->neutral_tilt_before = tilt;
	ref->neutral_loo_before = NAN;
	ref->neutral_method_before = ref->method;
	/* a chart with neutral patches says itself what a grey reads */
	if (opt->no_neutral_prior || strcmp(ref->neutral_white_source, "response") != 0 ||
	    !(tilt > KG_CALIB_MAX_NEUTRAL_TILT))
		return 0;
	double grey[KG_CALIB_NEUTRAL_LEVELS][3];
	for (int k = 0; k < KG_CALIB_NEUTRAL_LEVELS; k++)
		for (int c = 0; c < 3; c++)
			grey[k][c] = levels[k] * ref->neutral_white[c];
	ref->neutral_loo_before = ref->maps[ref->method].loo_de00;
	int m = train->n, cap = m + KG_CALIB_NEUTRAL_LEVELS * weights[2];
	kg_patchset aug = {.n = m, .source = train->source};
	aug.spectra = malloc((size_t)cap * sizeof(*aug.spectra));
	aug.rgb = malloc((size_t)cap * sizeof(*aug.rgb));
	int ret = aug.spectra && aug.rgb ? 0 : kg_fail(err, KG_ENOMEM, "out of memory");
	if (!ret) {
		memcpy(aug.spectra, train->spectra, (size_t)m * sizeof(*aug.spectra));
		memcpy(aug.rgb, train->rgb, (size_t)m * sizeof(*aug.rgb));
	}
	for (int w = 0; w < 3 && !ret; w++) {
		aug.n = m + KG_CALIB_NEUTRAL_LEVELS * weights[w];
		for (int i = m; i < aug.n; i++) {
			int k = (i - m) % KG_CALIB_NEUTRAL_LEVELS;
			for (int l = 0; l < NB; l++)
				aug.spectra[i].v[l] = levels[k];
			memcpy(aug.rgb[i], grey[k], sizeof(grey[k]));
		}
		ret = fit_methods(ref, &aug, m, opt, d65, tname, err);
		ref->neutral_prior = 1;
		ref->neutral_weight = weights[w];
		if (!ret && ref->maps[ref->method].neutral_tilt <= KG_CALIB_MAX_NEUTRAL_TILT)
			break;
	}
	free(aug.spectra);
	free(aug.rgb);
	return ret;
}

static int fit_reference(const kg_patchset *train, const kg_patchset *field,
                         const kg_reference_options *opt, kg_reference **out, kg_err *err)
{
	int ret;
	kg_reference *ref = calloc(1, sizeof(*ref));
	calib_d65 *d65 = malloc(sizeof(*d65));
	if (!ref || !d65) {
		ret = kg_fail(err, KG_ENOMEM, "reference calibration: out of memory");
		goto error;
	}
	const char *tname = set_name(train, "training chart");
	ret = check_training(train, field, opt, ref, err);
	if (!ret)
		ret = calib_d65_init(d65, err);
	if (ret)
		goto error;
	ref->centred = opt->centred;
	ref->ridge = opt->ridge;
	ref->noise_sigma = opt->noise_sigma;
	/* the response first: the neutral prior reads its greys through it */
	if ((ret = opt->camera_weights
	               ? kg_response_from_camera(opt->camera_weights, train, &ref->response, err)
	               : kg_response_fit(train, &ref->response, err)))
		kg_err_prefix(err, "%s: ", tname);
	if (!ret)
		ret = neutral_white(ref, train, err);
	if (!ret)
		ret = fit_methods(ref, train, train->n, opt, d65, tname, err);
	if (!ret)
		ret = neutral_prior(ref, train, opt, d65, tname, err);
	if (!ret)
		ret = record_charts(ref, train, field, err);
	if (ret)
		goto error;
	patch_diagnostics(ref, train, d65);
	free(d65);
	*out = ref;
	return 0;

error:
	free(d65);
	kg_reference_free(&ref);
	return ret;
}

/* The field chart's patches chart detection flagged (FLAGS != 0): *n of them, their
 * ids and flags (newly allocated, also on failure; NULL without a FLAGS column). */
static int flagged_patches(const kg_patchset *field, int *n, char ***ids, unsigned **flags,
                           kg_err *err)
{
	int col = kg_patchset_extra_index(field, "FLAGS");
	*n = 0;
	*ids = NULL;
	*flags = NULL;
	if (col < 0)
		return 0;
	size_t cap = field->n > 0 ? (size_t)field->n : 1;
	if (!(*ids = calloc(cap, sizeof(char *))) || !(*flags = calloc(cap, sizeof(unsigned))))
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (int i = 0; i < field->n; i++) {
		double f = field->extra[(size_t)i * field->nextra + col];
		if (!(f > 0) || !isfinite(f))
			continue;
		if (!((*ids)[*n] = strdup(field->ids[i])))
			return kg_fail(err, KG_ENOMEM, "out of memory");
		/* detection writes small whole numbers; anything else still counts as flagged */
		(*flags)[(*n)++] = f < 65536 ? (unsigned)f : 0xffffu;
	}
	return 0;
}

static int fit_excluding(const kg_patchset *train, const kg_patchset *field,
                         const kg_reference_options *opt, kg_reference **out, kg_err *err);

static int fit_flagged(const kg_patchset *train, const kg_patchset *field,
                       const kg_reference_options *opt, kg_reference **out, kg_err *err);

/* The chosen method's mean leave-one-out dE00. */
static double chosen_loo(const kg_reference *r)
{
	return r->maps[r->method].loo_de00;
}

/* Flare (calib/flare.c): measured on the training chart (and the field chart when it
 * is another frame); refused above opt->max_flare; the fit made with the flare kept
 * and with it removed, and the removal kept when its chosen method validates better
 * by more than KG_CALIB_K_TOLERANCE (so a frame without flare keeps its values). */
int kg_reference_fit(const kg_patchset *train, const kg_patchset *field,
                     const kg_reference_options *opt, kg_reference **out, kg_err *err)
{
	kg_check_arg(train && field && opt && out, err);
	*out = NULL;
	kg_flare fl, ffl;
	int same = field == train;
	if (!same && field->n == train->n && field->rgb && train->rgb) {
		same = 1; /* the same frame's values under the same ids (kogei process) */
		for (int i = 0; same && i < train->n; i++) {
			int j = kg_patchset_find(field, train->ids[i]);
			same = j >= 0 && !memcmp(field->rgb[j], train->rgb[i], sizeof(train->rgb[i]));
		}
	}
	int ret = kg_flare_estimate(train, same ? field : NULL, opt->exclude, opt->nexclude, &fl,
	                            err);
	if (!ret && same)
		ffl = fl;
	else if (!ret)
		ret = kg_flare_estimate(train, field, opt->exclude, opt->nexclude, &ffl, err);
	if (ret)
		return ret;
	double limit = opt->max_flare > 0 ? opt->max_flare : KG_CALIB_MAX_FLARE;
	const kg_flare *worst = kg_flare_max_fraction(&ffl) > kg_flare_max_fraction(&fl) ? &ffl : &fl;
	if (kg_flare_max_fraction(worst) > limit) {
		const kg_patchset *ps = worst == &fl ? train : field;
		return kg_fail(err, KG_EINVAL,
		               "%s: flare: the chart's %d neutral patches (%s .. %s) meet zero at "
		               "%.1f %% (R), %.1f %% (G), %.1f %% (B) of white, above the %.1f %% a "
		               "calibration can trust (light scattered in the lens: shade the lens "
		               "and the chart from the light source and the sky, or --max-flare)",
		               set_name(ps, "the chart"), worst->n, worst->ids[0],
		               worst->ids[worst->n - 1], 100 * worst->white_fraction[0],
		               100 * worst->white_fraction[1], 100 * worst->white_fraction[2],
		               100 * limit);
	}
	kg_reference *kept = NULL, *removed = NULL;
	if ((ret = fit_flagged(train, field, opt, &kept, err)))
		return ret;
	kept->flare = fl;
	kept->field_flare = ffl;
	kept->flare_loo_kept = chosen_loo(kept);
	kept->flare_loo_removed = NAN;
	if (opt->no_flare || !fl.found || !ffl.found) {
		*out = kept;
		return 0;
	}
	kg_patchset *t2 = NULL, *f2 = NULL;
	kg_err e2;
	int r2 = kg_flare_remove(train, &fl, &t2, &e2);
	if (!r2)
		r2 = kg_flare_remove(field, &ffl, &f2, &e2);
	if (!r2)
		r2 = fit_flagged(t2, f2, opt, &removed, &e2);
	kg_patchset_free(&t2);
	kg_patchset_free(&f2);
	if (r2) { /* a fit that fails without the offset leaves the one with it */
		*out = kept;
		return 0;
	}
	double lk = chosen_loo(kept), lr = chosen_loo(removed);
	if (isfinite(lr) && (!isfinite(lk) || lr < lk * (1 - KG_CALIB_K_TOLERANCE) - 1e-6)) {
		removed->flare = fl;
		removed->field_flare = ffl;
		removed->flare_removed = 1;
		removed->flare_loo_kept = lk;
		removed->flare_loo_removed = lr;
		kg_reference_free(&kept);
		*out = removed;
	} else {
		kept->flare_loo_removed = lr;
		kg_reference_free(&removed);
		*out = kept;
	}
	return 0;
}

static int fit_flagged(const kg_patchset *train, const kg_patchset *field,
                       const kg_reference_options *opt, kg_reference **out, kg_err *err)
{
	kg_check_arg(train && field && opt && out, err);
	kg_check_arg(opt->nexclude == 0 || opt->exclude, err);
	*out = NULL;
	int nflagged = 0;
	char **ids = NULL;
	unsigned *flags = NULL;
	const char **ex = NULL;
	int ret = flagged_patches(field, &nflagged, &ids, &flags, err);
	kg_reference_options o = *opt;
	if (!ret && nflagged) {
		/* opt's exclusions and the flagged patches, in one list */
		if (!(ex = calloc((size_t)(opt->nexclude + nflagged), sizeof(*ex))))
			ret = kg_fail(err, KG_ENOMEM, "out of memory");
		for (int i = 0; ex && i < opt->nexclude; i++)
			ex[i] = opt->exclude[i];
		for (int i = 0; ex && i < nflagged; i++)
			ex[opt->nexclude + i] = ids[i];
		o.exclude = ex;
		o.nexclude = opt->nexclude + nflagged;
	}
	if (!ret)
		ret = fit_excluding(train, field, &o, out, err);
	free(ex);
	if (!ret) {
		(*out)->nflagged = nflagged;
		(*out)->flagged_ids = ids;
		(*out)->flagged_flags = flags;
	} else {
		calib_strv_free(ids, nflagged);
		free(flags);
	}
	return ret;
}

static int fit_excluding(const kg_patchset *train, const kg_patchset *field,
                         const kg_reference_options *opt, kg_reference **out, kg_err *err)
{
	int ret = check_options(opt, err);
	if (ret || opt->nexclude == 0)
		return ret ? ret : fit_reference(train, field, opt, out, err);
	for (int e = 0; e < opt->nexclude; e++)
		if (kg_patchset_find(train, opt->exclude[e]) < 0 &&
		    kg_patchset_find(field, opt->exclude[e]) < 0)
			return kg_fail(err, KG_EINVAL,
			               "--exclude %s: no patch of that SAMPLE_ID in %s or in %s",
			               opt->exclude[e], set_name(train, "the training chart"),
			               set_name(field, "the field chart"));
	kg_patchset *t = NULL, *f = NULL;
	ret = calib_patchset_without(train, opt->exclude, opt->nexclude, &t, err);
	if (ret == 0)
		ret = calib_patchset_without(field, opt->exclude, opt->nexclude, &f, err);
	if (ret == 0)
		ret = fit_reference(t, f, opt, out, err);
	kg_patchset_free(&t);
	kg_patchset_free(&f);
	return ret;
}
