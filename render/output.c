/* Writing a rendered image: an 8-bit sRGB PNG for people, a float TIFF of XYZ (or
 * camera RGB), and the truth maps as ENVI files. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

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

void kg_render_truth_free(kg_render_truth **tp)
{
	if (!tp || !*tp)
		return;
	kg_render_truth *t = *tp;
	for (int i = 0; t->class_names && i < t->nclasses; i++)
		free(t->class_names[i]);
	free(t->class_names);
	free(t->label);
	free(t->angle_deg);
	free(t);
	*tp = NULL;
}

void kg_render_result_clear(kg_render_result *r)
{
	if (!r)
		return;
	kg_image_free(&r->image);
	kg_image_free(&r->xyz);
	kg_render_truth_free(&r->truth);
}

int kg_render_truth_write_labels(const kg_render_truth *t, const char *hdr_path,
                                 kg_err *err)
{
	kg_check_arg(t && hdr_path && t->nclasses >= 1 && t->nclasses <= 256, err);
	size_t npix = (size_t)t->width * (size_t)t->height;
	float *labels = malloc(npix * sizeof(*labels));
	if (!labels)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", hdr_path);
	for (size_t p = 0; p < npix; p++)
		labels[p] = (float)t->label[p];
	/* background black, the materials in the plots' qualitative colours (as sim/'s
	 * label maps) */
	int ret = kg_envi_write_label_map(
		hdr_path, t->width, t->height, labels, t->nclasses,
		(const char *const *)t->class_names,
		"kogei render: library material of the primary hit of each pixel", err);
	free(labels);
	return ret;
}

int kg_render_truth_write_angle(const kg_render_truth *t, const char *hdr_path,
                                kg_err *err)
{
	kg_check_arg(t && hdr_path, err);
	static const char *const band_names[] = {"incidence angle (deg)"};
	kg_envi_meta meta = {
	    .samples = t->width,
	    .lines = t->height,
	    .bands = 1,
	    .data_type = KG_ENVI_F32,
	    .interleave = KG_ENVI_BSQ,
	    .description = "kogei render: incidence angle at the primary hit of each pixel, "
	                   "degrees between the surface normal and the view direction (NaN: "
	                   "background)",
	    .band_names = band_names,
	};
	return kg_envi_write(hdr_path, &meta, KG_LAYOUT_BIP, t->angle_deg, err);
}
