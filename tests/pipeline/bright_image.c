/* bright_image IN.tif OUT.tif X Y W H FACTOR: a linear RGB image with the rectangle of
 * W x H pixels at X, Y (from the top left) multiplied by FACTOR, every other pixel as
 * it was; written as 32-bit float TIFF. A region FACTOR times as bright as the surface
 * it lies on: a known set of pixels made brighter than the diffuse white. */
#include <stdio.h>
#include <stdlib.h>

#include "kg_core.h"

int main(int argc, char **argv)
{
	if (argc != 8) {
		fprintf(stderr, "usage: %s IN.tif OUT.tif X Y W H FACTOR\n", argv[0]);
		return 2;
	}
	int x0 = atoi(argv[3]), y0 = atoi(argv[4]), w = atoi(argv[5]), h = atoi(argv[6]);
	double f = atof(argv[7]);
	kg_image *img = NULL;
	kg_err err = {{0}};
	int ret = kg_image_read(argv[1], &img, &err);
	if (!ret && (img->channels != 3 || x0 < 0 || y0 < 0 || w <= 0 || h <= 0 ||
	             x0 + w > img->width || y0 + h > img->height || !(f > 0)))
		ret = kg_fail(&err, KG_EINVAL, "%s: %dx%d, %d channels: expected RGB holding the "
		              "rectangle %dx%d at %d,%d and a positive factor", argv[1], img->width,
		              img->height, img->channels, w, h, x0, y0);
	for (int y = y0; !ret && y < y0 + h; y++)
		for (int x = x0; x < x0 + w; x++)
			for (int c = 0; c < 3; c++)
				img->data[3 * ((size_t)y * img->width + x) + c] *= (float)f;
	if (!ret)
		ret = kg_image_write_tiff(img, argv[2], 32, &err);
	if (ret)
		fprintf(stderr, "bright_image: %s\n", err.msg);
	kg_image_free(&img);
	return ret ? 1 : 0;
}
