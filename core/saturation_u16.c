/* The saturation scan of a mapped 16-bit image (kg_image_map): the same results as
 * of its floats, counted on the codes themselves. A code k reads as the float
 * kg_image_u16_lut()[k], which the 65535-step histogram puts in bin k; a comparison
 * with a clip level is one with the least code at or above it. */
#include <stdlib.h>

#include "saturation.h"

int kg_saturation_of_u16(const kg_image *img, double nominal_clip, kg_saturation *out,
                         kg_err *err)
{
	kg_check_arg(img && img->u16 && out && kg_saturation_steps(img) == 65535, err);
	int C = img->channels;
	if (C != 1 && C != 3)
		return kg_fail(err, KG_EINVAL, "saturation: %d channels: expected 1 or 3", C);
	const float *lut = kg_image_u16_lut();
	const uint16_t *d = img->u16;
	size_t n = (size_t)img->width * (size_t)img->height;
	kg_sat_hist h;
	int ret = kg_sat_hist_init(&h, C, 65535, err);
	if (ret)
		return ret;
	uint64_t *b0 = h.bins[0], *b1 = C == 3 ? h.bins[1] : NULL, *b2 = C == 3 ? h.bins[2] : NULL;
	if (C == 3)
		for (size_t i = 0; i < n; i++) {
			b0[d[3 * i]]++;
			b1[d[3 * i + 1]]++;
			b2[d[3 * i + 2]]++;
		}
	else
		for (size_t i = 0; i < n; i++)
			b0[d[i]]++;
	for (int c = 0; c < C; c++)
		h.total[c] = n;
	kg_sat_hist_result(&h, nominal_clip, out);
	kg_sat_hist_free(&h);
	if (C == 3 && kg_saturation_below(out, nominal_clip)) {
		kg_sat_flat f;
		kg_sat_flat_init(&f, out);
		enum { BAND = 4096 };
		float *px = malloc(BAND * 3 * sizeof(float));
		if (!px)
			return kg_fail(err, KG_ENOMEM, "saturation: out of memory");
		for (size_t i = 0; i < n; i += BAND) {
			size_t m = n - i < BAND ? n - i : BAND;
			for (size_t k = 0; k < 3 * m; k++)
				px[k] = lut[d[3 * i + k]];
			kg_sat_flat_add(&f, px, m);
		}
		free(px);
		kg_sat_flat_result(&f, out);
	}
	/* the least code that reads at or above each channel's clip level */
	long least[3];
	for (int c = 0; c < C; c++) {
		long k = 0;
		while (k < 65536 && !(lut[k] >= out->clip[c]))
			k++;
		least[c] = k;
	}
	size_t any = 0;
	if (C == 3)
		for (size_t i = 0; i < n; i++)
			any += (d[3 * i] >= least[0]) | (d[3 * i + 1] >= least[1]) | (d[3 * i + 2] >= least[2]);
	else
		for (size_t i = 0; i < n; i++)
			any += d[i] >= least[0];
	out->fraction_any = n ? (double)any / (double)n : 0;
	return 0;
}
