/* A helper of the real-photograph tests (tests/real): what kogei's commands do not
 * do themselves with a fixture, done without changing its pixels.
 *   real_tool cfa IN.tif OUT.tif PATTERN   IN's samples as they are, with a 2 x 2 CFA
 *                                          pattern (TIFF/EP tags) attached: the
 *                                          fixtures' mosaics carry none
 *   real_tool stats IN                     per CFA colour (or channel): mean, maximum
 *                                          and the fraction of samples at the maximum
 *   real_tool compose OUT.tif R.tif G.tif B.tif
 *                                          an RGB image whose channel c is, in every
 *                                          2 x 2 block, the c sample(s) of the GBRG
 *                                          mosaic given for c (the two G averaged):
 *                                          narrowband frames of one chart, each
 *                                          read in the channel its light falls on
 *   real_tool compare A B                  B against A sample by sample: the slope of
 *                                          B = k A (least squares) and the largest
 *                                          |B - k A|, over samples A < 0.999 (a raw
 *                                          import keeps a fixture's values linear)
 *   real_tool raw IN OUT.tif W H PATTERN BLACK WHITE
 *                                          a headerless 8-bit mosaic (W x H, a 2 x 2
 *                                          CFA PATTERN) as a 16-bit TIFF carrying its
 *                                          pattern, (code - BLACK) / (WHITE - BLACK)
 *                                          clamped to 0..1 */
#include "image.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int usage(void)
{
	fprintf(stderr, "usage: real_tool cfa IN OUT PATTERN | stats IN | compose OUT R G B | "
	                "compare A B | raw IN OUT W H PATTERN BLACK WHITE\n");
	return 2;
}

static int compose(int argc, char **argv)
{
	static const char pat[] = "GBRG";
	kg_err err = {0};
	kg_image *in[3] = {NULL, NULL, NULL}, *out = NULL;
	int ret = 1;
	if (argc != 6)
		return usage();
	for (int c = 0; c < 3; c++)
		if (kg_image_read(argv[3 + c], &in[c], &err)) {
			fprintf(stderr, "real_tool: %s\n", err.msg);
			goto done;
		}
	int w = in[0]->width, h = in[0]->height;
	for (int c = 0; c < 3; c++)
		if (in[c]->width != w || in[c]->height != h || in[c]->channels != 1 || w % 2 ||
		    h % 2) {
			fprintf(stderr, "real_tool: %s: expected a one-channel mosaic of even size "
			        "%d x %d like %s\n", argv[3 + c], w, h, argv[3]);
			goto done;
		}
	if (kg_image_new(w, h, 3, &out, &err)) {
		fprintf(stderr, "real_tool: %s\n", err.msg);
		goto done;
	}
	for (int y = 0; y < h; y += 2)
		for (int x = 0; x < w; x += 2)
			for (int c = 0; c < 3; c++) {
				double sum = 0;
				int n = 0;
				for (int k = 0; k < 4; k++)
					if (pat[k] == "RGB"[c]) {
						sum += in[c]->data[(size_t)(y + k / 2) * w + x + k % 2];
						n++;
					}
				for (int k = 0; k < 4; k++)
					out->data[((size_t)(y + k / 2) * w + x + k % 2) * 3 + c] =
						(float)(sum / n);
			}
	if (kg_image_write_tiff(out, argv[2], 16, &err)) {
		fprintf(stderr, "real_tool: %s\n", err.msg);
		goto done;
	}
	ret = 0;
done:
	for (int c = 0; c < 3; c++)
		kg_image_free(&in[c]);
	kg_image_free(&out);
	return ret;
}

static int compare(int argc, char **argv)
{
	kg_err err = {0};
	kg_image *a = NULL, *b = NULL;
	int ret = 1;
	if (argc != 4)
		return usage();
	if (kg_image_read(argv[2], &a, &err) || kg_image_read(argv[3], &b, &err)) {
		fprintf(stderr, "real_tool: %s\n", err.msg);
		goto done;
	}
	if (a->width != b->width || a->height != b->height || a->channels != b->channels) {
		fprintf(stderr, "real_tool: %s is %d x %d x %d, %s %d x %d x %d: expected the "
		        "same size\n", argv[2], a->width, a->height, a->channels, argv[3],
		        b->width, b->height, b->channels);
		goto done;
	}
	size_t n = (size_t)a->width * a->height * a->channels, used = 0;
	double sab = 0, saa = 0, worst = 0;
	for (size_t i = 0; i < n; i++)
		if (a->data[i] < 0.999f) {
			sab += (double)a->data[i] * b->data[i];
			saa += (double)a->data[i] * a->data[i];
			used++;
		}
	double k = saa > 0 ? sab / saa : 0;
	for (size_t i = 0; i < n; i++)
		if (a->data[i] < 0.999f) {
			double d = fabs(b->data[i] - k * a->data[i]);
			if (d > worst)
				worst = d;
		}
	printf("slope %.7f max_dev %.3g samples %zu\n", k, worst, used);
	ret = 0;
done:
	kg_image_free(&a);
	kg_image_free(&b);
	return ret;
}

static int raw8(int argc, char **argv)
{
	if (argc != 9)
		return usage();
	int w = atoi(argv[4]), h = atoi(argv[5]);
	double black = atof(argv[7]), white = atof(argv[8]);
	kg_err err = {0};
	kg_image *img = NULL;
	FILE *f = fopen(argv[2], "rb");
	unsigned char *codes = w > 0 && h > 0 ? malloc((size_t)w * h) : NULL;
	int ret = 1;
	if (!f || !codes || fread(codes, 1, (size_t)w * h, f) != (size_t)w * h ||
	    !(white > black)) {
		fprintf(stderr, "real_tool: %s: expected %d x %d 8-bit samples and BLACK < WHITE\n",
		        argv[2], w, h);
		goto done;
	}
	if (kg_image_new(w, h, 1, &img, &err) || kg_image_set_cfa(img, argv[6], 2, 2, &err))
		goto fail;
	for (size_t i = 0; i < (size_t)w * h; i++)
		img->data[i] = (float)fmin(1, fmax(0, (codes[i] - black) / (white - black)));
	if (kg_image_write_tiff(img, argv[3], 16, &err))
		goto fail;
	ret = 0;
	goto done;
fail:
	fprintf(stderr, "real_tool: %s\n", err.msg);
done:
	if (f)
		fclose(f);
	free(codes);
	kg_image_free(&img);
	return ret;
}

int main(int argc, char **argv)
{
	kg_err err = {0};
	kg_image *img = NULL;
	if (argc < 3)
		return usage();
	if (!strcmp(argv[1], "compose"))
		return compose(argc, argv);
	if (!strcmp(argv[1], "compare"))
		return compare(argc, argv);
	if (!strcmp(argv[1], "raw"))
		return raw8(argc, argv);
	if (kg_image_read(argv[2], &img, &err)) {
		fprintf(stderr, "real_tool: %s\n", err.msg);
		return 1;
	}
	int ret = 0;
	if (!strcmp(argv[1], "cfa") && argc == 5) {
		if (img->channels != 1 || strlen(argv[4]) != 4) {
			fprintf(stderr, "real_tool: %s: expected one channel and a 2 x 2 pattern\n",
			        argv[2]);
			ret = 1;
		} else if (kg_image_set_cfa(img, argv[4], 2, 2, &err) ||
		           kg_image_write_tiff(img, argv[3], img->bits <= 8 ? 8 : 16, &err)) {
			fprintf(stderr, "real_tool: %s\n", err.msg);
			ret = 1;
		}
	} else if (!strcmp(argv[1], "stats") && argc == 3) {
		const char *cfa = img->cfa ? img->cfa : NULL;
		const char *names = cfa || img->channels == 3 ? "RGB" : "Y";
		for (int c = 0; names[c]; c++) {
			double sum = 0, max = -1;
			long n = 0, at_max = 0;
			for (int y = 0; y < img->height; y++)
				for (int x = 0; x < img->width; x++)
					for (int k = 0; k < img->channels; k++) {
						if (cfa && cfa[(y % img->cfa_rows) * img->cfa_cols +
						               x % img->cfa_cols] != names[c])
							continue;
						if (!cfa && img->channels == 3 && k != c)
							continue;
						double v = img->data[((size_t)y * img->width + x) *
						                     img->channels + k];
						sum += v;
						n++;
						if (v > max) {
							max = v;
							at_max = 0;
						}
						if (v == max)
							at_max++;
					}
			if (n)
				printf("%c mean %.6f max %.6f at_max %.6f n %ld\n", names[c], sum / n,
				       max, (double)at_max / n, n);
		}
	} else {
		ret = usage();
	}
	kg_image_free(&img);
	return ret;
}
