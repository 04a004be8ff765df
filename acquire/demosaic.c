/* Bayer demosaicing of a float mosaic. OpenCV demosaics 8- and 16-bit mosaics only, so
 * the mosaic is scaled to 16 bits over its own range (the step is reported), demosaiced
 * bilinearly (a linear filter, so the scaling commutes with it up to that step) and
 * scaled back. Without OpenCV: KG_ENOTSUP, and the session keeps the raw mosaic. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "kg_acquire.h"
#if KG_HAVE_DEMOSAIC
#include "demosaic_cv.h"
#endif

const char *kg_demosaic_algorithm(void)
{
#if KG_HAVE_DEMOSAIC
	return kg_cv_demosaic_name();
#else
	return NULL;
#endif
}

int kg_demosaic(const kg_image *mosaic, kg_image **rgb, double *step, kg_err *err)
{
	kg_check_arg(mosaic && rgb, err);
	*rgb = NULL;
	size_t n = (size_t)mosaic->width * (size_t)mosaic->height;
	double lo = INFINITY, hi = -INFINITY;
	for (size_t i = 0; mosaic->data && i < n; i++)
		if (isfinite(mosaic->data[i])) {
			lo = fmin(lo, mosaic->data[i]);
			hi = fmax(hi, mosaic->data[i]);
		}
	if (!(lo <= hi))
		lo = hi = 0;
	return kg_demosaic_range(mosaic, lo, hi, rgb, step, err);
}

int kg_demosaic_range(const kg_image *mosaic, double lo, double hi, kg_image **rgb,
                      double *step, kg_err *err)
{
	kg_check_arg(mosaic && rgb, err);
	*rgb = NULL;
	if (mosaic->channels != 1 || !mosaic->cfa || mosaic->cfa_rows != 2 ||
	    mosaic->cfa_cols != 2)
		return kg_fail(err, KG_EINVAL,
		               "demosaic: expected a 1-channel mosaic with a 2x2 CFA pattern");
#if KG_HAVE_DEMOSAIC
	size_t n = (size_t)mosaic->width * (size_t)mosaic->height;
	double range = hi > lo ? hi - lo : 1.0;
	uint16_t *in = malloc(n * sizeof(uint16_t));
	uint16_t *out = malloc(3 * n * sizeof(uint16_t));
	kg_image *img = NULL;
	int ret = in && out ? kg_image_new(mosaic->width, mosaic->height, 3, &img, err)
	                    : kg_fail(err, KG_ENOMEM, "demosaic: out of memory");
	if (!ret) {
		for (size_t i = 0; i < n; i++) {
			float v = mosaic->data[i];
			double q = isfinite(v) ? (v - lo) / range * 65535.0 : 0.0;
			in[i] = (uint16_t)lrint(fmin(fmax(q, 0.0), 65535.0));
		}
		ret = kg_cv_demosaic_u16(in, mosaic->width, mosaic->height, mosaic->cfa, out, err);
	}
	if (!ret) {
		for (size_t i = 0; i < n; i++)
			for (int c = 0; c < 3; c++)
				img->data[3 * i + (size_t)c] =
					isfinite(mosaic->data[i])
						? (float)(lo + (double)out[3 * i + (size_t)c] / 65535.0 * range)
						: NAN;
		if (step)
			*step = range / 65535.0;
		*rgb = img;
		img = NULL;
	}
	kg_image_free(&img);
	free(in);
	free(out);
	return ret;
#else
	(void)lo;
	(void)hi;
	(void)step;
	return kg_fail(err, KG_ENOTSUP,
	               "demosaic: kogei was built without OpenCV; the raw mosaic is kept");
#endif
}
