/* What estimate/ needs from a calibration: kernel descriptions. */
#include <string.h>

#include "calib_private.h"

void calib_reference_derive(kg_reference *ref)
{
	for (int k = 0; k < ref->K; k++)
		ref->weight_offset[k] = -(ref->M[k * 3] * ref->rgb_mean[0] +
		                          ref->M[k * 3 + 1] * ref->rgb_mean[1] +
		                          ref->M[k * 3 + 2] * ref->rgb_mean[2]);
}

void calib_camera_derive(kg_camera_calib *cam)
{
	for (int k = 0; k < cam->K; k++) {
		for (int c = 0; c < 3; c++)
			cam->weight_matrix[k * 3 + c] = cam->M[k * 3] * cam->M2[c] +
			                                cam->M[k * 3 + 1] * cam->M2[3 + c] +
			                                cam->M[k * 3 + 2] * cam->M2[6 + c];
		cam->weight_offset[k] = -(cam->M[k * 3] * cam->rgb_mean[0] +
		                          cam->M[k * 3 + 1] * cam->rgb_mean[1] +
		                          cam->M[k * 3 + 2] * cam->rgb_mean[2]);
	}
}

void kg_camera_weights(const kg_camera_calib *cam, const double rgb[3], double *w)
{
	for (int k = 0; k < cam->K; k++)
		w[k] = cam->weight_matrix[k * 3] * rgb[0] + cam->weight_matrix[k * 3 + 1] * rgb[1] +
		       cam->weight_matrix[k * 3 + 2] * rgb[2] + cam->weight_offset[k];
}

/* KG_METHOD_AUTO means the calibration's default method. */
static int resolve(kg_method *m, kg_method dflt, kg_err *err)
{
	if (*m == KG_METHOD_AUTO)
		*m = dflt;
	if (*m < 0 || *m >= KG_METHOD_COUNT)
		return kg_fail(err, KG_EINVAL, "method %d: unknown", (int)*m);
	return 0;
}

int kg_reference_kernel_desc(const kg_reference *ref, kg_method m, kg_est_desc *desc,
                             kg_err *err)
{
	kg_check_arg(ref && desc, err);
	int ret = resolve(&m, ref->method, err);
	if (ret)
		return ret;
	const kg_spectral_map *map = &ref->maps[m];
	if (!map->available)
		return kg_fail(err, KG_EINVAL, "method %s is not available in this reference: %s",
		               kg_method_name(m), map->note);
	memset(desc, 0, sizeof(*desc));
	desc->method = kg_method_est(m);
	if (m == KG_METHOD_PCA) {
		desc->k = ref->K;
		desc->matrix = ref->M;
		desc->offset = ref->weight_offset;
		desc->basis = ref->B;
		desc->mean = ref->centred ? ref->mean : NULL;
	} else {
		desc->matrix = map->A;
		desc->offset = map->offset;
	}
	return 0;
}

int kg_camera_kernel_desc(const kg_camera_calib *cam, kg_method m, kg_est_desc *desc,
                          double pre[9], kg_err *err)
{
	kg_check_arg(cam && desc, err);
	int ret = resolve(&m, cam->method, err);
	if (ret)
		return ret;
	const kg_site_map *map = &cam->maps[m];
	if (!map->available)
		return kg_fail(err, KG_EINVAL, "method %s was not available on the reference chart",
		               kg_method_name(m));
	if (map->nterms != 3 && !pre)
		return kg_fail(err, KG_EINVAL,
		               "method %s: its kernel needs the site's M2 applied to the pixels first, "
		               "and no place for it was given",
		               kg_method_name(m));
	memset(desc, 0, sizeof(*desc));
	desc->method = kg_method_est(m);
	if (m == KG_METHOD_PCA) {
		desc->k = cam->K;
		desc->matrix = cam->weight_matrix;
		desc->offset = cam->weight_offset;
		desc->basis = cam->B;
		desc->mean = cam->centred ? cam->mean : NULL;
	} else {
		desc->matrix = map->A;
		desc->offset = map->offset;
	}
	if (pre)
		memcpy(pre, map->pre, 9 * sizeof(double));
	return 0;
}
