/* write_jpeg PATH: a 64x48 RGB JPEG (quality 95) of a fixed pattern, the live-view
 * image the PTP replay's preview scenario serves (make_ptp_replay.py). */
#include <stdio.h>

#include <jpeglib.h>

#define W 64
#define H 48

int main(int argc, char **argv)
{
	if (argc != 2) {
		fprintf(stderr, "usage: write_jpeg PATH\n");
		return 2;
	}
	FILE *f = fopen(argv[1], "wb");
	if (!f) {
		perror(argv[1]);
		return 1;
	}
	struct jpeg_compress_struct j;
	struct jpeg_error_mgr e;
	j.err = jpeg_std_error(&e);
	jpeg_create_compress(&j);
	jpeg_stdio_dest(&j, f);
	j.image_width = W;
	j.image_height = H;
	j.input_components = 3;
	j.in_color_space = JCS_RGB;
	jpeg_set_defaults(&j);
	jpeg_set_quality(&j, 95, TRUE);
	for (int c = 0; c < 3; c++) /* no chroma subsampling: the test compares pixels */
		j.comp_info[c].h_samp_factor = j.comp_info[c].v_samp_factor = 1;
	jpeg_start_compress(&j, TRUE);
	unsigned char row[W * 3];
	while (j.next_scanline < H) {
		int y = (int)j.next_scanline;
		for (int x = 0; x < W; x++) {
			row[3 * x] = (unsigned char)(x * 4);     /* red ramp across */
			row[3 * x + 1] = (unsigned char)(y * 5); /* green ramp down */
			row[3 * x + 2] = (unsigned char)(x < W / 2 ? 40 : 200);
		}
		JSAMPROW r = row;
		jpeg_write_scanlines(&j, &r, 1);
	}
	jpeg_finish_compress(&j);
	jpeg_destroy_compress(&j);
	return fclose(f) ? 1 : 0;
}
