#include <stdio.h>
#include <stdlib.h>
#include <stdint.h>
#include <tiffio.h>
#include <jpeglib.h>
int main(int c, char **v) {
	TIFF *t = TIFFOpen(v[1], "r"); uint32_t w, h; uint16_t spp, bits;
	TIFFGetField(t, TIFFTAG_IMAGEWIDTH, &w); TIFFGetField(t, TIFFTAG_IMAGELENGTH, &h);
	TIFFGetFieldDefaulted(t, TIFFTAG_SAMPLESPERPIXEL, &spp); TIFFGetFieldDefaulted(t, TIFFTAG_BITSPERSAMPLE, &bits);
	fprintf(stderr, "%u %u %u %u\n", w, h, spp, bits);
	uint16_t *row = malloc(TIFFScanlineSize(t)); unsigned char *rgb = malloc(w*h*3);
	for (uint32_t y = 0; y < h; y++) { TIFFReadScanline(t, row, y, 0);
		for (uint32_t x = 0; x < w; x++) for (int k = 0; k < 3; k++) rgb[(y*w+x)*3+k] = row[x*spp + (spp>=3?k:0)] >> 8; }
	struct jpeg_compress_struct ci; struct jpeg_error_mgr je; ci.err = jpeg_std_error(&je);
	jpeg_create_compress(&ci); FILE *f = fopen(v[2], "wb"); jpeg_stdio_dest(&ci, f);
	ci.image_width = w; ci.image_height = h; ci.input_components = 3; ci.in_color_space = JCS_RGB;
	jpeg_set_defaults(&ci); jpeg_set_quality(&ci, 90, TRUE); jpeg_start_compress(&ci, TRUE);
	for (uint32_t y = 0; y < h; y++) { JSAMPROW r = rgb + y*w*3; jpeg_write_scanlines(&ci, &r, 1); }
	jpeg_finish_compress(&ci); fclose(f); return 0; }
