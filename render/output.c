/* Writing a rendered XYZ image: an 8-bit sRGB PNG for people, a float TIFF of XYZ. */
#include <stdlib.h>

#include "kg_render.h"

int kg_render_write_png(const kg_image *xyz, kg_xyz white, const char *path, kg_err *err)
{
	kg_check_arg(xyz && xyz->channels == 3 && path, err);
	size_t n = (size_t)xyz->width * (size_t)xyz->height;
	unsigned char *rgb = malloc(3 * n);
	if (!rgb)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	/* kg_xyz_to_linear_srgb works on the Y = 100 scale */
	kg_xyz w100 = {100.0 * white.X, 100.0 * white.Y, 100.0 * white.Z};
	for (size_t i = 0; i < n; i++) {
		const float *p = xyz->data + 3 * i;
		kg_xyz c = {100.0 * p[0], 100.0 * p[1], 100.0 * p[2]};
		kg_rgb lin = kg_xyz_to_linear_srgb(c, w100);
		lin.r = lin.r < 0.0 ? 0.0 : lin.r;
		lin.g = lin.g < 0.0 ? 0.0 : lin.g;
		lin.b = lin.b < 0.0 ? 0.0 : lin.b;
		kg_rgb_to_u8(kg_srgb_encode(lin), rgb + 3 * i);
	}
	int ret = kg_png_write_rgb8(path, rgb, xyz->width, xyz->height, err);
	free(rgb);
	return ret;
}

int kg_render_write_xyz_tiff(const kg_image *xyz, const char *path, kg_err *err)
{
	kg_check_arg(xyz && xyz->channels == 3 && path, err);
	return kg_image_write_tiff(xyz, path, 32, err);
}
