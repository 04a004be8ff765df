/* Camera responses: rho_c = k sum E R S_c dlambda with the exposure k set from the
 * perfect diffuser, then the noise model. */
#include <math.h>
#include <string.h>

#include "kg_sim.h"

int kg_sim_capture_init(kg_sim_capture *c, const kg_sim_camera *cam,
                        const kg_spectrum *illuminant, double white_level,
                        const kg_sim_noise *noise, kg_err *err)
{
	kg_check_arg(c && cam && illuminant, err);
	if (!(white_level > 0.0 && isfinite(white_level)))
		return kg_fail(err, KG_EINVAL, "white level %g: expected a number above 0",
		               white_level);
	memset(c, 0, sizeof(*c));
	double white[3];
	double brightest = 0.0;
	for (int ch = 0; ch < 3; ch++) {
		white[ch] = 0.0;
		for (int i = 0; i < KG_NBANDS; i++)
			white[ch] += illuminant->v[i] * cam->sens[ch].v[i] * KG_LAMBDA_STEP;
		if (!isfinite(white[ch]))
			return kg_fail(err, KG_EINVAL,
			               "camera %s: response to the perfect diffuser is not finite",
			               cam->name);
		brightest = fmax(brightest, white[ch]);
	}
	if (!(brightest > 0.0))
		return kg_fail(err, KG_EINVAL,
		               "camera %s: no response to the illuminant in 400-700 nm "
		               "(expected positive sensitivities where the illuminant has power)",
		               cam->name);
	c->exposure = white_level / brightest;
	c->white_level = white_level;
	for (int ch = 0; ch < 3; ch++)
		for (int i = 0; i < KG_NBANDS; i++) {
			c->signal_weight[ch].v[i] = c->exposure * cam->sens[ch].v[i] * KG_LAMBDA_STEP;
			c->weight[ch].v[i] =
			    c->exposure * illuminant->v[i] * cam->sens[ch].v[i] * KG_LAMBDA_STEP;
		}
	if (noise)
		c->noise = *noise;
	return 0;
}

void kg_sim_capture_mean(const kg_sim_capture *c, const kg_spectrum *reflectance,
                         double rgb[3])
{
	for (int ch = 0; ch < 3; ch++) {
		double sum = 0.0;
		for (int i = 0; i < KG_NBANDS; i++)
			sum += c->weight[ch].v[i] * reflectance->v[i];
		rgb[ch] = sum;
	}
}

void kg_sim_capture_signal_mean(const kg_sim_capture *c, const kg_spectrum *signal,
                                double rgb[3])
{
	for (int ch = 0; ch < 3; ch++)
		rgb[ch] = kg_spectrum_dot(&c->signal_weight[ch], signal);
}

void kg_sim_capture_sample(const kg_sim_capture *c, const kg_spectrum *reflectance,
                           kg_rng *rng, double rgb[3])
{
	kg_sim_capture_mean(c, reflectance, rgb);
	for (int ch = 0; ch < 3; ch++) {
		if (c->flare != 0) {
			double white = 0;
			for (int i = 0; i < KG_NBANDS; i++)
				white += c->weight[ch].v[i];
			rgb[ch] += c->flare * white;
		}
		rgb[ch] = kg_sim_noise_apply(&c->noise, rgb[ch], rng);
	}
}

void kg_sim_patches(const kg_sim_capture *c, const kg_spectrum *spectra, int n,
                    uint64_t seed, double *rgb)
{
	kg_rng rng;
	kg_rng_seed(&rng, seed);
	for (int i = 0; i < n; i++)
		kg_sim_capture_sample(c, &spectra[i], &rng, rgb + 3 * i);
}
