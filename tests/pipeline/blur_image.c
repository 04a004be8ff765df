/* blur_image IN.tif OUT.tif SIGMA: a linear image blurred by a Gaussian of standard
 * deviation SIGMA pixels (a known point spread function: its MTF is
 * exp(-2 pi^2 SIGMA^2 f^2)), separable, the kernel sampled at the pixel centres out to
 * 5 SIGMA and normalised to 1, the image's border pixels repeated outside it. Every
 * channel alike. Written as 32-bit float TIFF. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "kg_core.h"

/* One pass along x (dir 0) or y (dir 1) from src to dst. */
static void pass(const float *src, float *dst, int w, int h, int ch, const double *k, int r,
                 int dir)
{
	for (int y = 0; y < h; y++)
		for (int x = 0; x < w; x++)
			for (int c = 0; c < ch; c++) {
				double s = 0;
				for (int d = -r; d <= r; d++) {
					int xx = dir ? x : x + d, yy = dir ? y + d : y;
					xx = xx < 0 ? 0 : xx >= w ? w - 1 : xx;
					yy = yy < 0 ? 0 : yy >= h ? h - 1 : yy;
					s += k[d + r] * src[((size_t)yy * w + xx) * ch + c];
				}
				dst[((size_t)y * w + x) * ch + c] = (float)s;
			}
}

int main(int argc, char **argv)
{
	if (argc != 4) {
		fprintf(stderr, "usage: %s IN.tif OUT.tif SIGMA\n", argv[0]);
		return 2;
	}
	double sigma = atof(argv[3]);
	if (!(sigma > 0 && sigma <= 50)) {
		fprintf(stderr, "blur_image: SIGMA %s: expected 0 to 50 px\n", argv[3]);
		return 2;
	}
	kg_image *img = NULL;
	kg_err err = {{0}};
	int ret = kg_image_read(argv[1], &img, &err);
	if (!ret) {
		int r = (int)ceil(5 * sigma), w = img->width, h = img->height, ch = img->channels;
		double *k = malloc(sizeof(double) * (size_t)(2 * r + 1)), sum = 0;
		float *tmp = malloc(sizeof(float) * (size_t)w * h * ch);
		if (!k || !tmp) {
			ret = kg_fail(&err, KG_ENOMEM, "out of memory");
		} else {
			for (int d = -r; d <= r; d++)
				sum += k[d + r] = exp(-0.5 * d * d / (sigma * sigma));
			for (int d = 0; d <= 2 * r; d++)
				k[d] /= sum;
			pass(img->data, tmp, w, h, ch, k, r, 0);
			pass(tmp, img->data, w, h, ch, k, r, 1);
			ret = kg_image_write_tiff(img, argv[2], 32, &err);
		}
		free(k);
		free(tmp);
	}
	if (ret)
		fprintf(stderr, "blur_image: %s\n", err.msg);
	kg_image_free(&img);
	return ret ? 1 : 0;
}
