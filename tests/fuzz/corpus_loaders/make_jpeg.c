/* Encodes a 16-bit RGB TIFF's top 8 bits as a baseline JPEG (libjpeg, quality 90): the
 * seed of fuzz-mjpeg. Not built by meson; see README.md.
 *   cc make_jpeg.c -ltiff -ljpeg -o make_jpeg && ./make_jpeg IN.tif OUT.jpg */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <tiffio.h>

#include <jpeglib.h> /* after stdio.h: it uses FILE and size_t */

int main(int argc, char **argv)
{
	if (argc != 3) {
		fprintf(stderr, "usage: %s IN.tif OUT.jpg\n", argv[0]);
		return 2;
	}
	TIFF *tif = TIFFOpen(argv[1], "r");
	if (!tif)
		return 1;
	uint32_t w, h;
	uint16_t spp, bits;
	TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &w);
	TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &h);
	TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLESPERPIXEL, &spp);
	TIFFGetFieldDefaulted(tif, TIFFTAG_BITSPERSAMPLE, &bits);
	if (bits != 16 || spp < 3) {
		fprintf(stderr, "%s: expected 16-bit RGB\n", argv[1]);
		return 1;
	}
	uint16_t *row = malloc((size_t)TIFFScanlineSize(tif));
	unsigned char *rgb = malloc((size_t)w * h * 3);
	if (!row || !rgb)
		return 1;
	for (uint32_t y = 0; y < h; y++) {
		TIFFReadScanline(tif, row, y, 0);
		for (uint32_t x = 0; x < w; x++)
			for (int k = 0; k < 3; k++)
				rgb[((size_t)y * w + x) * 3 + k] = (unsigned char)(row[x * spp + k] >> 8);
	}
	TIFFClose(tif);

	struct jpeg_compress_struct ci;
	struct jpeg_error_mgr jerr;
	ci.err = jpeg_std_error(&jerr);
	jpeg_create_compress(&ci);
	FILE *out = fopen(argv[2], "wb");
	if (!out)
		return 1;
	jpeg_stdio_dest(&ci, out);
	ci.image_width = w;
	ci.image_height = h;
	ci.input_components = 3;
	ci.in_color_space = JCS_RGB;
	jpeg_set_defaults(&ci);
	jpeg_set_quality(&ci, 90, TRUE);
	jpeg_start_compress(&ci, TRUE);
	for (uint32_t y = 0; y < h; y++) {
		JSAMPROW r = rgb + (size_t)y * w * 3;
		jpeg_write_scanlines(&ci, &r, 1);
	}
	jpeg_finish_compress(&ci);
	jpeg_destroy_compress(&ci);
	fclose(out);
	free(row);
	free(rgb);
	return 0;
}
