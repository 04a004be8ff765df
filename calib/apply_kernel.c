/* A site camera's kernel, ready for estimate/'s image functions: the method's
 * description, the pre-transform of the root-polynomial methods and an optional
 * lookup table over the values the pixels can take. */
#include <math.h>
#include <string.h>

#include "kg_calib.h"

int kg_camera_kernel(const kg_camera_calib *cam, kg_method m, int lut_size, kg_est_kernel **out,
                     double pre[9], int *pre_needed, kg_err *err)
{
	kg_check_arg(cam && out && pre, err);
	if (lut_size && (lut_size < 2 || lut_size > KG_EST_LUT_MAX_N))
		return kg_fail(err, KG_EINVAL, "lookup table size %d: expected 2 to %d", lut_size,
		               KG_EST_LUT_MAX_N);
	kg_est_desc desc;
	int rc = kg_camera_kernel_desc(cam, m, &desc, pre, err);
	if (rc)
		return rc;
	kg_est_kernel *k = NULL;
	if ((rc = kg_est_kernel_new(&desc, &k, err)))
		return rc;
	int identity = 1;
	for (int i = 0; i < 9; i++)
		identity &= pre[i] == (i % 4 == 0 ? 1.0 : 0.0);
	if (pre_needed)
		*pre_needed = !identity;
	if (lut_size) {
		/* Pixels in [0, 1]^3 reach the kernel as pre rho: each channel between the
		 * sums of pre's negative and of its positive entries in its row. */
		double lo = 0, hi = 1;
		for (int r = 0; r < 3; r++) {
			double neg = 0, pos = 0;
			for (int c = 0; c < 3; c++)
				*(pre[3 * r + c] < 0 ? &neg : &pos) += pre[3 * r + c];
			lo = fmin(lo, neg);
			hi = fmax(hi, pos);
		}
		kg_est_kernel *lut = NULL;
		rc = kg_est_kernel_new_lut(k, lut_size, (float)lo, (float)hi, &lut, err);
		kg_est_kernel_free(&k);
		if (rc)
			return rc;
		k = lut;
	}
	*out = k;
	return 0;
}
