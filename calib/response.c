/* The reference camera's spectral response learned from the chart it photographed.
 *
 * A linear camera's reading of a reflectance s under the chart's light is
 * rho_c = sum_l F_c(l) s(l): F_c is the channel's sensitivity times the light, on the
 * 61-band grid. With m chart patches (m x 61 spectra S, m x 3 readings rho) and
 * m << 61, F is under-determined; real sensitivities and lights are smooth, so each
 * channel takes the smoothest F that fits:
 *   F_c = argmin ||S F_c - rho_c||^2 + lambda_c ||D F_c||^2,
 * D the second difference (59 x 61). It is the least-squares solution of the stacked
 * system [S; sqrt(lambda) D] F = [rho; 0], whose pseudo-inverse P gives both F = P_S
 * rho (P_S: P's first m columns) and the hat matrix H = S P_S, so the leave-one-out
 * residuals are e_i / (1 - H_ii) without refitting. lambda_c is the grid value (a
 * decade in 4 steps over 1e-8..1e2 of trace(S^T S) / trace(D^T D)) of least
 * leave-one-out error.
 *
 * What it is for: predicting, in the reference camera's space, the reading of a
 * material the chart does not hold (the library's metals), so that a site pixel
 * mapped through M2 can be matched against it. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "calib_private.h"

#define NB KG_NBANDS
#define ND (KG_NBANDS - 2) /* rows of the second difference */

void kg_response_apply(const kg_response *r, const double *spectrum, double rgb[3])
{
	for (int c = 0; c < 3; c++) {
		double s = 0;
		for (int l = 0; l < NB; l++)
			s += r->F[c][l] * spectrum[l];
		rgb[c] = s;
	}
}

int kg_response_fit(const kg_patchset *train, kg_response *out, kg_err *err)
{
	kg_check_arg(train && out, err);
	memset(out, 0, sizeof(*out));
	if (!train->spectra || !train->rgb)
		return kg_fail(err, KG_EINVAL, "response: the chart needs spectra and RGB");
	const int m = train->n;
	if (m < 3)
		return kg_fail(err, KG_EINVAL, "response: %d patches: expected 3 or more", m);
	double trace_s = 0, trace_d = 6.0 * ND; /* D^T D has 1 + 4 + 1 per row */
	for (int i = 0; i < m; i++)
		for (int l = 0; l < NB; l++)
			trace_s += train->spectra[i].v[l] * train->spectra[i].v[l];
	kg_mat *A = NULL, *P = NULL;
	int ret = kg_mat_new(m + ND, NB, &A, err);
	double best[3] = {INFINITY, INFINITY, INFINITY};
	double *h = malloc(sizeof(double) * (size_t)m);
	if (!ret && !h)
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	for (int step = 0; step <= 40 && !ret; step++) {
		double lambda = pow(10.0, -8.0 + 0.25 * step) * trace_s / trace_d;
		double root = sqrt(lambda);
		for (int i = 0; i < m; i++)
			for (int l = 0; l < NB; l++)
				A->a[(size_t)i * NB + l] = train->spectra[i].v[l];
		for (int d = 0; d < ND; d++)
			for (int l = 0; l < NB; l++)
				A->a[(size_t)(m + d) * NB + l] =
					l == d || l == d + 2 ? root : l == d + 1 ? -2.0 * root : 0.0;
		kg_mat_free(&P);
		if ((ret = kg_pinv(A, 1e-12, &P, NULL, NULL, err)))
			break;
		/* P is 61 x (m + 59); the hat matrix's diagonal H_ii = s_i . P_S[:, i] */
		for (int i = 0; i < m; i++) {
			double s = 0;
			for (int l = 0; l < NB; l++)
				s += train->spectra[i].v[l] * P->a[(size_t)l * (m + ND) + i];
			h[i] = s;
		}
		for (int c = 0; c < 3; c++) {
			double F[NB], sse = 0;
			for (int l = 0; l < NB; l++) {
				double s = 0;
				for (int i = 0; i < m; i++)
					s += P->a[(size_t)l * (m + ND) + i] * train->rgb[i][c];
				F[l] = s;
			}
			for (int i = 0; i < m; i++) {
				double fit = 0;
				for (int l = 0; l < NB; l++)
					fit += F[l] * train->spectra[i].v[l];
				double e = (train->rgb[i][c] - fit) / fmax(1.0 - h[i], 1e-9);
				sse += e * e;
			}
			if (isfinite(sse) && sse < best[c]) {
				best[c] = sse;
				memcpy(out->F[c], F, sizeof(F));
				out->lambda[c] = lambda;
			}
		}
	}
	kg_mat_free(&A);
	kg_mat_free(&P);
	free(h);
	if (ret)
		return ret;
	double num = 0, den = 0;
	for (int c = 0; c < 3; c++) {
		if (!isfinite(best[c]))
			return kg_fail(err, KG_EINVAL, "response: channel %d could not be fitted", c);
		out->loo_rmse[c] = sqrt(best[c] / m);
		num += best[c];
		for (int i = 0; i < m; i++)
			den += train->rgb[i][c] * train->rgb[i][c];
	}
	out->loo_relative = den > 0 ? sqrt(num / den) : NAN;
	out->patches = m;
	out->available = 1;
	snprintf(out->source, sizeof(out->source), "chart");
	return 0;
}

int kg_response_from_camera(const kg_spectrum weight[3], const kg_patchset *train,
                            kg_response *out, kg_err *err)
{
	kg_check_arg(weight && train && out, err);
	memset(out, 0, sizeof(*out));
	if (!train->spectra || !train->rgb)
		return kg_fail(err, KG_EINVAL, "response: the chart needs spectra and RGB");
	const int m = train->n;
	if (m < 2)
		return kg_fail(err, KG_EINVAL, "response: %d patches: expected 2 or more", m);
	double num = 0, den = 0;
	for (int c = 0; c < 3; c++) {
		/* one scale per channel (the exposure): rho_c = k_c g_c . s, least squares; its
		 * leave-one-out residuals e_i / (1 - g_i^2 / sum g^2) */
		double gg = 0, gr = 0, *g = malloc(sizeof(double) * (size_t)m);
		if (!g)
			return kg_fail(err, KG_ENOMEM, "out of memory");
		for (int i = 0; i < m; i++) {
			double s = 0;
			for (int l = 0; l < NB; l++)
				s += weight[c].v[l] * train->spectra[i].v[l];
			g[i] = s;
			gg += s * s;
			gr += s * train->rgb[i][c];
		}
		if (!(gg > 0)) {
			free(g);
			return kg_fail(err, KG_EINVAL, "response: the camera's channel %d sees nothing of "
			               "the chart under this light", c);
		}
		double k = gr / gg, sse = 0;
		for (int i = 0; i < m; i++) {
			double e = (train->rgb[i][c] - k * g[i]) / fmax(1.0 - g[i] * g[i] / gg, 1e-9);
			sse += e * e;
			den += train->rgb[i][c] * train->rgb[i][c];
		}
		free(g);
		for (int l = 0; l < NB; l++)
			out->F[c][l] = k * weight[c].v[l];
		out->loo_rmse[c] = sqrt(sse / m);
		num += sse;
	}
	out->loo_relative = den > 0 ? sqrt(num / den) : NAN;
	out->patches = m;
	out->available = 1;
	snprintf(out->source, sizeof(out->source), "camera");
	return 0;
}
