/* tone_image IN.tif OUT.tif GAMMA WR WG WB [NOISE SEED]: a linear RGB image given a
 * known tone response relative to the white (WR, WG, WB: the perfect diffuser's
 * values), each channel out = W (max(in, 0) / W)^GAMMA: a neutral of reflectance r is
 * written as the neutral of reflectance r^GAMMA; then, with NOISE, Gaussian noise of
 * standard deviation NOISE * W added to each sample independently (a reflectance
 * noise of NOISE in every channel). Written as 32-bit float TIFF. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "kg_core.h"

int main(int argc, char **argv)
{
	if (argc != 7 && argc != 9) {
		fprintf(stderr, "usage: %s IN.tif OUT.tif GAMMA WR WG WB [NOISE SEED]\n", argv[0]);
		return 2;
	}
	double noise = argc == 9 ? atof(argv[7]) : 0;
	unsigned long long st = argc == 9 ? strtoull(argv[8], NULL, 10) * 2654435761ULL + 1 : 1;
	double g = atof(argv[3]), w[3] = {atof(argv[4]), atof(argv[5]), atof(argv[6])};
	if (!(g > 0) || !(w[0] > 0) || !(w[1] > 0) || !(w[2] > 0)) {
		fprintf(stderr, "tone_image: GAMMA and the white must be positive\n");
		return 2;
	}
	kg_image *img = NULL;
	kg_err err = {{0}};
	int ret = kg_image_read(argv[1], &img, &err);
	if (!ret && img->channels != 3)
		ret = kg_fail(&err, KG_EINVAL, "%s: %d channels, expected RGB", argv[1], img->channels);
	if (!ret) {
		size_t n = (size_t)img->width * img->height;
		for (size_t i = 0; i < n; i++)
			for (int c = 0; c < 3; c++) {
				float *v = &img->data[3 * i + c];
				*v = (float)(w[c] * pow(*v > 0 ? *v / w[c] : 0.0, g));
				if (noise > 0) { /* Box-Muller on a 64-bit LCG's top bits */
					double u[2];
					for (int k = 0; k < 2; k++) {
						st = st * 6364136223846793005ULL + 1442695040888963407ULL;
						u[k] = ((double)(st >> 11) + 0.5) / 9007199254740992.0;
					}
					*v += (float)(noise * w[c] * sqrt(-2 * log(u[0])) *
					              cos(6.283185307179586 * u[1]));
				}
			}
		ret = kg_image_write_tiff(img, argv[2], 32, &err);
	}
	if (ret)
		fprintf(stderr, "tone_image: %s\n", err.msg);
	kg_image_free(&img);
	return ret ? 1 : 0;
}
