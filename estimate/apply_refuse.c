/* Images to files: the refusal stage of a classification (unknown and background). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "apply_private.h"

/* Pixel i of a block whose input planes are pl (raw: the image's values, before pre;
 * kin: what the kernel saw; var and mask when given). */
void ap_refuse_pixel(const refusal *r, const planes *pl, size_t i, uint8_t *label,
                         float *conf)
{
	const float *px = pl->raw + 3 * i;
	if (pl->mask && pl->mask[i] == 0.0f) {
		*label = r->background;
		*conf = NAN;
		return;
	}
	if (*label == KG_EST_LABEL_NONE)
		return;
	if (fmaxf(px[0], fmaxf(px[1], px[2])) < r->background_level) {
		*label = r->background;
		*conf = NAN;
		return;
	}
	if (isinf(r->threshold))
		return;
	const int k = r->cls->k;
	float w[KG_EST_MAX_K];
	kg_est_kernel_eval(r->k, pl->kin + 3 * i, INFINITY, 1, w);
	double var[3];
	for (int c = 0; c < 3; c++) {
		double rho = px[c] > 0.0f ? px[c] : 0.0;
		double noise = pl->var ? pl->var[3 * i + c] * r->inv_frames
		                      : r->noise_floor2 + r->noise_rel2 * rho * rho;
		var[c] = noise + r->resid2 * rho * rho;
	}
	double sigma[KG_EST_MAX_K * KG_EST_MAX_K];
	for (int a = 0; a < k; a++)
		for (int b = 0; b < k; b++)
			sigma[a * k + b] = r->g[a * 3] * r->g[b * 3] * var[0] +
			                   r->g[a * 3 + 1] * r->g[b * 3 + 1] * var[1] +
			                   r->g[a * 3 + 2] * r->g[b * 3 + 2] * var[2];
	if (kg_est_classifier_chi2(r->cls, *label - 1, w, sigma) > r->threshold) {
		*label = r->unknown;
		*conf = NAN;
	}
}

/* The refusal stage's constants; dof and threshold also go to the result. */
int ap_refusal_init(refusal *r, const kg_est_kernel *k, const kg_est_classifier *cls,
                        const kg_est_material_set *set, const kg_apply_options *opt,
                        const kg_classify_options *o, kg_classify_result *res, kg_err *err)
{
	memset(r, 0, sizeof(*r));
	r->k = k;
	r->cls = cls;
	r->inv_frames = 1.0 / o->frames;
	r->noise_rel2 = o->noise_relative * o->noise_relative;
	r->noise_floor2 = o->noise_floor * o->noise_floor;
	r->resid2 = o->residual_relative * o->residual_relative;
	r->background_level = (float)o->background_level;
	r->unknown = (uint8_t)ap_label_unknown(set);
	r->background = (uint8_t)ap_label_background(set);
	res->dof = kg_est_classifier_dof(cls);
	r->threshold = o->unknown_threshold > 0 ? o->unknown_threshold
	                                        : kg_chi2_quantile(0.999, res->dof);
	res->unknown_threshold = r->threshold;
	if (isinf(r->threshold))
		return 0;
	if (k->method != KG_EST_LINEAR)
		return kg_fail(err, KG_EINVAL,
		               "classify: the unknown test propagates the noise through the kernel's "
		               "weight matrix: expected the linear pca kernel, not a %s one (or no "
		               "unknown test)",
		               k->method == KG_EST_LUT ? "lookup-table" : "root-polynomial");
	const double ident[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
	const double *P = opt->pre ? opt->pre : ident;
	for (int a = 0; a < k->k; a++)
		for (int c = 0; c < 3; c++) {
			double g = 0;
			for (int t = 0; t < 3; t++)
				g += (double)k->wts.a[a * 3 + t] * P[3 * t + c];
			r->g[a * 3 + c] = g;
		}
	return 0;
}
