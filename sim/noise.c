/* Sensor noise: photon shot noise for a full-well capacity, read noise, clipping at
 * full scale and quantisation to a bit depth. Values are linear on a 0..1 scale, as
 * every camera value in kogei (1 = full well = the largest code). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_sim.h"

static int valid_bits(int bits)
{
	return bits == 8 || bits == 10 || bits == 12 || bits == 14 || bits == 16;
}

int kg_sim_noise_parse(const char *text, kg_sim_noise *out, kg_err *err)
{
	kg_check_arg(text && out, err);
	memset(out, 0, sizeof(*out));
	if (strcmp(text, "none") == 0)
		return 0;
	double fw, rn;
	long bits;
	char *end;
	errno = 0;
	fw = strtod(text, &end);
	if (end == text || *end != ':')
		goto bad;
	const char *p = end + 1;
	rn = strtod(p, &end);
	if (end == p || *end != ':')
		goto bad;
	p = end + 1;
	bits = strtol(p, &end, 10);
	if (end == p || *end != '\0' || errno)
		goto bad;
	if (!(fw >= 1.0 && fw <= 1e9))
		return kg_fail(err, KG_EINVAL,
		               "noise '%s': full-well capacity %g: expected 1 to 1e9 electrons", text,
		               fw);
	if (!(rn >= 0.0 && rn <= 1e6))
		return kg_fail(err, KG_EINVAL,
		               "noise '%s': read noise %g: expected 0 or more electrons rms", text, rn);
	if (!valid_bits((int)bits))
		return kg_fail(err, KG_EINVAL,
		               "noise '%s': bit depth %ld: expected 8, 10, 12, 14 or 16", text, bits);
	out->full_well = fw;
	out->read_noise = rn;
	out->bits = (int)bits;
	return 0;
bad:
	return kg_fail(err, KG_EINVAL,
	               "noise '%s': expected 'none' or FULLWELL:READ:BITS "
	               "(electrons, electrons rms, bit depth; e.g. 20000:5:12)",
	               text);
}

void kg_sim_noise_format(const kg_sim_noise *n, char *buf, size_t len)
{
	if (!kg_sim_noise_enabled(n))
		snprintf(buf, len, "none");
	else
		snprintf(buf, len, "%.17g:%.17g:%d", n->full_well, n->read_noise, n->bits);
}

int kg_sim_noise_enabled(const kg_sim_noise *n) { return n && n->full_well > 0.0; }

double kg_sim_noise_apply(const kg_sim_noise *n, double v, kg_rng *rng)
{
	if (!kg_sim_noise_enabled(n) || isnan(v))
		return v;
	double fw = n->full_well;
	/* Expected photo-electrons. Far above full well the draw is clipped anyway; the
	 * cap only keeps the sampler finite. */
	double mean_e = v > 0.0 ? fmin(v * fw, 4.0 * fw + 1e6) : 0.0;
	double e = kg_rng_poisson(rng, mean_e);
	if (n->read_noise > 0.0)
		e += n->read_noise * kg_rng_normal(rng);
	if (e < 0.0)
		e = 0.0;
	if (e > fw)
		e = fw;
	if (n->bits < 1 || n->bits > 31)
		return e / fw;
	double top = (double)((1u << n->bits) - 1u);
	return nearbyint(e / fw * top) / top;
}

void kg_sim_noise_image(const kg_sim_noise *n, kg_image *img, uint64_t seed)
{
	if (!kg_sim_noise_enabled(n) || !img)
		return;
	size_t row = (size_t)img->width * (size_t)img->channels;
	for (int y = 0; y < img->height; y++) {
		kg_rng rng;
		kg_rng_seed(&rng, seed ^ (0x9E3779B97F4A7C15ull * (uint64_t)(y + 1)));
		float *p = img->data + (size_t)y * row;
		for (size_t i = 0; i < row; i++)
			p[i] = (float)kg_sim_noise_apply(n, p[i], &rng);
	}
}
