/* Test helper: a linear image (TIFF, PNG) to a baseline JPEG as a camera writes it:
 * sRGB-encoded 8-bit, optionally brightened by a gain before encoding.
 * usage: make_jpeg IN OUT.jpg [QUALITY] [GAIN] */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>

#include <jpeglib.h>

#include "image.h"

static unsigned char encode(float v)
{
	if (!(v > 0))
		return 0;
	if (v >= 1)
		return 255;
	double e = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
	return (unsigned char)lrint(255 * e);
}

int main(int argc, char **argv)
{
	if (argc < 3) {
		fprintf(stderr, "usage: make_jpeg IN OUT.jpg [QUALITY] [GAIN]\n");
		return 2;
	}
	int quality = argc > 3 ? atoi(argv[3]) : 95;
	double gain = argc > 4 ? atof(argv[4]) : 1.0;
	kg_image *img = NULL;
	kg_err err = {{0}};
	if (kg_image_read(argv[1], &img, &err)) {
		fprintf(stderr, "make_jpeg: %s\n", err.msg);
		return 1;
	}
	FILE *fp = fopen(argv[2], "wb");
	if (!fp) {
		perror(argv[2]);
		return 1;
	}
	struct jpeg_compress_struct c;
	struct jpeg_error_mgr jerr;
	c.err = jpeg_std_error(&jerr);
	jpeg_create_compress(&c);
	jpeg_stdio_dest(&c, fp);
	c.image_width = (JDIMENSION)img->width;
	c.image_height = (JDIMENSION)img->height;
	c.input_components = img->channels;
	c.in_color_space = img->channels == 3 ? JCS_RGB : JCS_GRAYSCALE;
	jpeg_set_defaults(&c);
	jpeg_set_quality(&c, quality, TRUE);
	jpeg_start_compress(&c, TRUE);
	size_t n = (size_t)img->width * img->channels;
	unsigned char *row = malloc(n);
	while (c.next_scanline < c.image_height) {
		const float *s = img->data + (size_t)c.next_scanline * n;
		for (size_t i = 0; i < n; i++)
			row[i] = encode((float)(s[i] * gain));
		JSAMPROW rp = row;
		jpeg_write_scanlines(&c, &rp, 1);
	}
	jpeg_finish_compress(&c);
	jpeg_destroy_compress(&c);
	fclose(fp);
	free(row);
	kg_image_free(&img);
	return 0;
}
