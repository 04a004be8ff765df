/* `kogei sim patches`: one simulated reading per spectrum, written as a patch file
 * (SAMPLE_ID RGB_R RGB_G RGB_B, linear, 0..1; docs/formats.md). */
#include "kg_sim.h"

int kg_sim_write_patches(const char *path, const kg_patchset *spectra,
                         const kg_sim_capture *c, uint64_t seed,
                         const char *const *keywords, kg_err *err)
{
	kg_check_arg(path && spectra && spectra->spectra && c, err);
	kg_patchset *out = NULL;
	int ret = kg_patchset_new(spectra->n, KG_PATCH_RGB, &out, err);
	if (ret)
		return ret;
	for (int i = 0; i < spectra->n && !ret; i++)
		ret = kg_patchset_set_id(out, i, spectra->ids[i], err);
	if (!ret) {
		kg_sim_patches(c, spectra->spectra, spectra->n, seed, &out->rgb[0][0]);
		ret = kg_patchset_write(path, out, KG_PATCH_RGB, keywords, err);
	}
	kg_patchset_free(&out);
	return ret;
}
