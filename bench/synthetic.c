/* Synthetic spectra and camera: inputs that need no reference data, for the unit
 * test and for the speed part when ../shared/reference is absent. */
#include <math.h>
#include <stdio.h>

#include "kg_bench.h"

int kg_bench_synthetic_spectra(int n, uint64_t seed, kg_patchset **out, kg_err *err)
{
	kg_check_arg(n > 0 && out, err);
	int ret = kg_patchset_new(n, KG_PATCH_SPECTRA, out, err);
	if (ret)
		return ret;
	kg_rng rng;
	kg_rng_seed(&rng, seed);
	for (int i = 0; i < n && !ret; i++) {
		char id[32];
		snprintf(id, sizeof(id), "S%d", i + 1);
		ret = kg_patchset_set_id(*out, i, id, err);
		/* A base level plus two or three bumps, like the broad reflectances of
		 * pigments and dyes. */
		kg_spectrum *s = &(*out)->spectra[i];
		double base = 0.03 + 0.3 * kg_rng_uniform(&rng);
		int bumps = 2 + (int)(2 * kg_rng_uniform(&rng));
		double centre[3], width[3], height[3];
		for (int j = 0; j < bumps; j++) {
			centre[j] = 380 + 340 * kg_rng_uniform(&rng);
			width[j] = 25 + 80 * kg_rng_uniform(&rng);
			height[j] = 0.6 * kg_rng_uniform(&rng);
		}
		for (int b = 0; b < KG_NBANDS; b++) {
			double v = base, nm = kg_band_nm(b);
			for (int j = 0; j < bumps; j++) {
				double z = (nm - centre[j]) / width[j];
				v += height[j] * exp(-0.5 * z * z);
			}
			s->v[b] = fmin(fmax(v, 0.02), 0.95);
		}
	}
	if (ret)
		kg_patchset_free(out);
	return ret;
}

void kg_bench_synthetic_camera(kg_sim_camera *cam)
{
	static const double peak[3] = {600, 540, 450}, width[3] = {30, 35, 25};
	snprintf(cam->name, sizeof(cam->name), "synthetic");
	for (int c = 0; c < 3; c++)
		for (int b = 0; b < KG_NBANDS; b++) {
			double z = (kg_band_nm(b) - peak[c]) / width[c];
			cam->sens[c].v[b] = exp(-0.5 * z * z);
		}
}
