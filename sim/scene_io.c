/* Writing a scene: the camera image (TIFF) and its ground truth (ENVI reflectance
 * cube and ENVI classification map). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "kg_sim.h"

/* Lines per block when streaming the truth cube: bounded memory for any scene. */
#define TRUTH_BLOCK_LINES 64

int kg_sim_depth_parse(const char *text, enum kg_sim_depth *out, kg_err *err)
{
	kg_check_arg(text && out, err);
	if (strcmp(text, "8") == 0)
		*out = KG_SIM_DEPTH_U8;
	else if (strcmp(text, "16") == 0)
		*out = KG_SIM_DEPTH_U16;
	else if (strcmp(text, "float") == 0 || strcmp(text, "32") == 0)
		*out = KG_SIM_DEPTH_F32;
	else
		return kg_fail(err, KG_EINVAL, "depth '%s': expected 8, 16 or float", text);
	return 0;
}

int kg_sim_scene_write_image(const kg_sim_scene *s, const char *path,
                             enum kg_sim_depth depth, kg_err *err)
{
	kg_check_arg(s && path, err);
	kg_image *img = NULL;
	int ret = kg_image_new(s->width, s->height, 3, &img, err);
	if (ret)
		return ret;
	memcpy(img->data, s->rgb, (size_t)s->width * (size_t)s->height * 3 * sizeof(float));
	ret = kg_image_write(img, path, (int)depth, err);
	kg_image_free(&img);
	return ret;
}

int kg_sim_scene_write_truth_cube(const kg_sim_scene *s, const char *hdr_path, kg_err *err)
{
	kg_check_arg(s && hdr_path, err);
	double wavelength[KG_NBANDS];
	for (int i = 0; i < KG_NBANDS; i++)
		wavelength[i] = kg_band_nm(i);
	kg_envi_meta meta = {
	    .samples = s->width,
	    .lines = s->height,
	    .bands = KG_NBANDS,
	    .data_type = KG_ENVI_F32,
	    .interleave = KG_ENVI_BSQ,
	    .description = "kogei sim: true reflectance of each pixel",
	    .wavelength = wavelength,
	};
	kg_envi_writer *w = NULL;
	int ret = kg_envi_writer_open(hdr_path, &meta, &w, err);
	if (ret)
		return ret;
	size_t block_px = (size_t)s->width * TRUTH_BLOCK_LINES;
	float *block = malloc(block_px * KG_NBANDS * sizeof(*block));
	if (!block) {
		kg_envi_writer_abort(&w);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", hdr_path);
	}
	for (int y0 = 0; y0 < s->height && !ret; y0 += TRUTH_BLOCK_LINES) {
		int y1 = y0 + TRUTH_BLOCK_LINES < s->height ? y0 + TRUTH_BLOCK_LINES : s->height;
		size_t first = (size_t)y0 * (size_t)s->width;
		size_t count = (size_t)(y1 - y0) * (size_t)s->width;
		for (size_t p = 0; p < count; p++) {
			int32_t k = s->sample[first + p];
			const kg_spectrum *r = k < 0 ? &s->background : &s->truth[k];
			for (int i = 0; i < KG_NBANDS; i++)
				block[p * KG_NBANDS + (size_t)i] = (float)r->v[i];
		}
		ret = kg_envi_writer_put(w, y0, y1, KG_LAYOUT_BIP, block, err);
	}
	free(block);
	if (ret) {
		kg_envi_writer_abort(&w);
		return ret;
	}
	return kg_envi_writer_finish(&w, err);
}

int kg_sim_scene_write_labels(const kg_sim_scene *s, const char *hdr_path, kg_err *err)
{
	kg_check_arg(s && hdr_path, err);
	if (s->nclasses > 256)
		return kg_fail(err, KG_ERANGE,
		               "%s: %d classes: an ENVI classification map holds at most 256",
		               hdr_path, s->nclasses);
	size_t npix = (size_t)s->width * (size_t)s->height;
	float *labels = malloc(npix * sizeof(*labels));
	if (!labels)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", hdr_path);
	for (size_t p = 0; p < npix; p++)
		labels[p] = (float)s->label[p];
	/* Unclassified black, the rest in the plots' qualitative colours. */
	int ret = kg_envi_write_label_map(hdr_path, s->width, s->height, labels, s->nclasses,
	                                  (const char *const *)s->class_names,
	                                  "kogei sim: true material of each pixel", err);
	free(labels);
	return ret;
}

int kg_sim_scene_write(const kg_sim_scene *s, const char *image_path,
                       enum kg_sim_depth depth, const char *truth_cube_path,
                       const char *labels_path, kg_err *err)
{
	kg_check_arg(s && image_path, err);
	int ret = kg_sim_scene_write_image(s, image_path, depth, err);
	if (ret)
		return ret;
	if (truth_cube_path) {
		ret = kg_sim_scene_write_truth_cube(s, truth_cube_path, err);
		if (ret) {
			kg_envi_remove_output(image_path, 0);
			return ret;
		}
	}
	if (labels_path) {
		ret = kg_sim_scene_write_labels(s, labels_path, err);
		if (ret) {
			kg_envi_remove_output(image_path, 0);
			if (truth_cube_path)
				kg_envi_remove_output(truth_cube_path, 1);
			return ret;
		}
	}
	return 0;
}
