/* A camera simulated from published sensitivities for tests on real data: each
 * channel's weight is its sensitivity (../shared/reference/cameras/NAME.csv) times the
 * light, scaled so the perfect diffuser gives 0.9 in the brightest channel; a
 * reflectance's reading is the weight's dot product with it. And a fixed stream of
 * uniform and normal deviates (xorshift64, Box-Muller) for noise. */
#ifndef KG_TEST_CAMERA_H
#define KG_TEST_CAMERA_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>

#include "kg_core.h"

/* The exposure: scales three channel weights so the perfect diffuser (reflectance 1)
 * gives 0.9 in the brightest channel. */
static inline void kg_test_expose(kg_spectrum w[3])
{
	kg_spectrum one = kg_spectrum_const(1.0);
	double top = 0;
	for (int c = 0; c < 3; c++)
		top = fmax(top, kg_spectrum_dot(&w[c], &one));
	for (int c = 0; c < 3; c++)
		w[c] = kg_spectrum_scale(&w[c], 0.9 / top);
}

static inline int kg_test_camera_weights(const char *reference_dir, const char *camera,
                                         const char *light, kg_spectrum w[3], kg_err *err)
{
	static const char *const cols[3] = {"r", "g", "b"};
	char path[4200];
	snprintf(path, sizeof(path), "%s/%s", reference_dir, camera);
	kg_spectrum sens[3];
	kg_illuminant *ill = NULL;
	int ret = kg_csv_read_column_spectra(path, cols, 3, 0, sens, err);
	if (!ret)
		ret = kg_illuminant_by_name(light, &ill, err);
	if (ret)
		return ret;
	for (int c = 0; c < 3; c++)
		w[c] = kg_spectrum_mul(&sens[c], &ill->spd);
	kg_test_expose(w);
	kg_illuminant_free(&ill);
	return 0;
}

static inline double kg_test_uniform(uint64_t *st)
{
	*st ^= *st << 13;
	*st ^= *st >> 7;
	*st ^= *st << 17;
	return ((*st >> 11) + 0.5) / 9007199254740992.0;
}

static inline double kg_test_gauss(uint64_t *st)
{
	double u = kg_test_uniform(st), v = kg_test_uniform(st);
	return sqrt(-2 * log(u)) * cos(2 * M_PI * v);
}

#endif
