/* upscale_image IN.tif OUT.tif WIDTH HEIGHT: a recorded capture output (mean,
 * variance or RGB) resampled to WIDTH x HEIGHT by nearest sample, for tests of large
 * images. A raw mosaic keeps its CFA pattern: each output sample takes the nearest
 * input sample of its own colour (the input site of the same parity in the 2 x 2
 * repeat). Written as 32-bit float TIFF with the CFA tags. */
#include <stdio.h>
#include <stdlib.h>

#include "kg_core.h"

int main(int argc, char **argv)
{
	if (argc != 5) {
		fprintf(stderr, "usage: %s IN.tif OUT.tif WIDTH HEIGHT\n", argv[0]);
		return 2;
	}
	kg_image *in = NULL, *out = NULL;
	kg_err err = {{0}};
	int W = atoi(argv[3]), H = atoi(argv[4]);
	int ret = kg_image_read(argv[1], &in, &err);
	if (!ret)
		ret = kg_image_new(W, H, in->channels, &out, &err);
	if (!ret && in->cfa)
		ret = kg_image_set_cfa(out, in->cfa, in->cfa_rows, in->cfa_cols, &err);
	if (ret) {
		fprintf(stderr, "upscale_image: %s\n", err.msg);
		return 1;
	}
	int C = in->channels, mosaic = in->cfa && C == 1;
	for (int Y = 0; Y < H; Y++) {
		int y = (int)((long)Y * in->height / H);
		if (mosaic)
			y = (y & ~1) + (Y & 1) < in->height ? (y & ~1) + (Y & 1) : (y & ~1);
		for (int X = 0; X < W; X++) {
			int x = (int)((long)X * in->width / W);
			if (mosaic)
				x = (x & ~1) + (X & 1) < in->width ? (x & ~1) + (X & 1) : (x & ~1);
			for (int c = 0; c < C; c++)
				out->data[((size_t)Y * W + X) * C + c] = in->data[((size_t)y * in->width + x) * C + c];
		}
	}
	ret = kg_image_write_tiff(out, argv[2], 32, &err);
	if (ret)
		fprintf(stderr, "upscale_image: %s\n", err.msg);
	kg_image_free(&in);
	kg_image_free(&out);
	return ret ? 1 : 0;
}
