/* Saturation from the data (core/saturation.h):
 *   - a 12-bit sensor that saturates at 4092 of 4095: the pile-up found at 4092 in the
 *     channels that reach it, the clipped fraction the count the test made, the others
 *     not flagged; the same on a Bayer mosaic per CFA position;
 *   - no false positives: natural histograms (smooth scenes with shot noise, 8, 12 and
 *     16 bits, float), a noise-free synthetic chart whose brightest patch is a spike,
 *     an 8-bit image whose top is a thin tail; and the project's own fixture images;
 *   - clipping at the nominal white found too (level 1), a user's lower clip level kept;
 *   - a row source gives what the image gives. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_core.h"
#include "kg_test.h"

#define W 400
#define H 300

/* A smooth scene: a horizontal gradient, a vignetted light and bright patches, values
 * up to peak (0..1 of full scale before clipping), with shot noise of a sensor of
 * gain e electrons per count, quantised to 2^bits - 1 and clamped at sat counts. */
static kg_image *scene(int channels, int bits, double peak, double sat_counts, double e,
                       unsigned seed, long *clipped_per_channel)
{
	kg_image *img = NULL;
	kg_err err = {{0}};
	if (kg_image_new(W, H, channels, &img, &err))
		return NULL;
	img->bits = bits;
	img->is_float = 0;
	double fs = (double)((1 << bits) - 1);
	kg_rng rng;
	kg_rng_seed(&rng, seed);
	for (int c = 0; c < 3; c++)
		if (clipped_per_channel)
			clipped_per_channel[c] = 0;
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++)
			for (int c = 0; c < channels; c++) {
				double gain = (c == 0 ? 1.0 : c == 1 ? 0.8 : 0.55);
				double r2 = ((x - W / 2.0) * (x - W / 2.0) + (y - H / 2.0) * (y - H / 2.0)) /
				            (double)(W * W / 4);
				double light = 1.0 - 0.35 * r2;
				double refl = 0.05 + 0.9 * x / (double)W;
				if (x > 40 && x < 120 && y > 40 && y < 120)
					refl = 0.97; /* a white patch */
				double mean = peak * gain * light * refl * fs;
				double sd = sqrt(mean / e + 4.0);
				double v = round(mean + sd * kg_rng_normal(&rng));
				if (v < 0)
					v = 0;
				if (v >= sat_counts) {
					v = sat_counts;
					if (clipped_per_channel)
						clipped_per_channel[c]++;
				}
				if (v > fs)
					v = fs;
				img->data[((size_t)y * W + x) * (size_t)channels + (size_t)c] = (float)(v / fs);
			}
	return img;
}

static void test_pileup_12bit(void)
{
	long clipped[3];
	kg_image *img = scene(3, 12, 1.3, 4092, 1.0, 7, clipped);
	kg_saturation s;
	kg_err err = {{0}};
	CHECK(kg_saturation_of_image(img, 1.0, &s, &err) == 0, "%s", err.msg);
	CHECK(clipped[0] > 1000, "the scene clips red (%ld samples)", clipped[0]);
	for (int c = 0; c < 3; c++) {
		if (clipped[c] > 100) {
			CHECK(s.found[c], "channel %d: %ld clipped at 4092 of 4095 not found", c, clipped[c]);
			CHECK_NEAR(s.level[c] * 4095, 4092, 0.01, "saturation level (counts)");
			CHECK(fabs(s.fraction[c] * W * H - clipped[c]) < 0.5,
			      "channel %d: fraction %.5f, the scene clipped %ld of %d", c, s.fraction[c],
			      clipped[c], W * H);
		} else {
			CHECK(!s.found[c], "channel %d: %ld clipped, yet a pile-up at %.5f", c,
			      clipped[c], s.level[c]);
		}
	}
	char line[256];
	kg_saturation_format(&s, "RGB", line, sizeof(line));
	CHECK(strstr(line, "R at 0.99927 (4092 of 4095"), "summary: %s", line);
	printf("  12-bit, saturating at 4092: %s; any channel %.3f %%\n", line,
	       100 * s.fraction_any);
	/* a user's clip level below the pile-up stays */
	CHECK(kg_saturation_of_image(img, 0.9, &s, &err) == 0, "%s", err.msg);
	CHECK(!kg_saturation_below(&s, 0.9) && s.clip[0] == 0.9, "clip 0.9 kept (%g)", s.clip[0]);
	kg_image_free(&img);

	/* per CFA position of a mosaic: R site saturates, the others do not */
	kg_image *rgb = scene(3, 12, 1.3, 4092, 1.0, 8, clipped), *mos = NULL;
	CHECK(kg_image_new(W, H, 1, &mos, &err) == 0 && kg_image_set_cfa(mos, "RGGB", 2, 2, &err) == 0,
	      "%s", err.msg);
	mos->bits = 12;
	mos->is_float = 0;
	long want = 0;
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			int site = (y & 1) * 2 + (x & 1), c = site == 0 ? 0 : site == 3 ? 2 : 1;
			float v = rgb->data[((size_t)y * W + x) * 3 + (size_t)c];
			mos->data[(size_t)y * W + x] = v;
			want += site == 0 && v * 4095.0f > 4091.5f;
		}
	CHECK(kg_saturation_of_image(mos, 1.0, &s, &err) == 0, "%s", err.msg);
	CHECK(s.channels == 4 && s.found[0], "mosaic: R site pile-up not found");
	CHECK(fabs(s.fraction[0] * (W * H / 4) - want) < 0.5, "R site fraction %.5f, want %ld",
	      s.fraction[0], want);
	CHECK(!s.found[3], "B site flagged at %.5f", s.level[3]);
	kg_image_free(&rgb);
	kg_image_free(&mos);
}

static void no_pileup(const char *what, kg_image *img)
{
	kg_saturation s;
	kg_err err = {{0}};
	CHECK(img != NULL, "%s: no image", what);
	if (!img)
		return;
	CHECK(kg_saturation_of_image(img, 1.0, &s, &err) == 0, "%s: %s", what, err.msg);
	char line[256];
	kg_saturation_format(&s, "RGBG", line, sizeof(line));
	CHECK(!kg_saturation_below(&s, 1.0), "%s: false pile-up: %s", what, line);
}

static void test_natural(void)
{
	for (int bits = 8; bits <= 16; bits += 4)
		for (unsigned seed = 1; seed <= 3; seed++) {
			char what[64];
			snprintf(what, sizeof(what), "%d-bit natural scene, seed %u", bits, seed);
			/* peak 0.95: the white patch's top tail reaches near full scale */
			kg_image *img = scene(3, bits, 0.95, 1e9, bits == 8 ? 50.0 : 1.0, seed, NULL);
			no_pileup(what, img);
			kg_image_free(&img);
		}
	/* float */
	kg_image *f = scene(3, 16, 0.9, 1e9, 1.0, 4, NULL);
	f->is_float = 1;
	f->bits = 32;
	no_pileup("float scene", f);
	kg_image_free(&f);
	/* noise-free synthetic chart: 24 flat patches, the brightest at 0.9, soft edges */
	kg_image *c = NULL;
	kg_err err = {{0}};
	CHECK(kg_image_new(W, H, 3, &c, &err) == 0, "%s", err.msg);
	c->bits = 16;
	c->is_float = 0;
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			int px = x / (W / 6), py = y / (H / 4);
			double v = round((0.03 + 0.87 * (py * 6 + px) / 23.0) * 65535) / 65535;
			if (x % (W / 6) < 2 || y % (H / 4) < 2)
				v *= 0.5;
			for (int k = 0; k < 3; k++)
				c->data[((size_t)y * W + x) * 3 + (size_t)k] = (float)v;
		}
	no_pileup("noise-free synthetic chart", c);
	/* a noise-free render of coloured patches with soft edges: each channel's brightest
	 * patch is a spike with edge pixels of every value below it */
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			int px = x / (W / 6), py = y / (H / 4), ex = x % (W / 6), ey = y % (H / 4);
			double edge = fmin(1.0, fmin(ex, ey) / 12.0);
			int k = py * 6 + px;
			double rgb[3] = {0.05 + 0.3 * (k % 5) / 4.0, 0.05 + 0.75 * (k % 7) / 6.0,
			                 0.05 + 0.6 * (k % 3) / 2.0};
			for (int q = 0; q < 3; q++)
				c->data[((size_t)y * W + x) * 3 + (size_t)q] =
					(float)(round(rgb[q] * (0.2 + 0.8 * edge) * 65535) / 65535);
		}
	no_pileup("noise-free coloured chart with soft edges", c);
	kg_image_free(&c);
	printf("  no pile-up on natural 8/12/16-bit and float scenes or a noise-free chart\n");
}

static void test_nominal(void)
{
	long clipped[3];
	kg_image *img = scene(3, 8, 1.3, 255, 50.0, 9, clipped);
	kg_saturation s;
	kg_err err = {{0}};
	CHECK(kg_saturation_of_image(img, 1.0, &s, &err) == 0, "%s", err.msg);
	CHECK(s.found[0] && s.level[0] == 1.0, "8-bit clipped at 255: level %g", s.level[0]);
	CHECK(fabs(s.fraction[0] * W * H - clipped[0]) < 0.5, "fraction %.5f, want %ld",
	      s.fraction[0], clipped[0]);
	/* a row source says the same */
	kg_row_source src;
	kg_row_source_of_image(img, &src);
	kg_saturation r;
	CHECK(kg_saturation_of_rows(&src, 255, 1.0, &r, &err) == 0, "%s", err.msg);
	for (int c = 0; c < 3; c++)
		CHECK(r.found[c] == s.found[c] && r.fraction[c] == s.fraction[c],
		      "rows and image differ in channel %d", c);
	kg_image_free(&img);
	/* too small a histogram, empty histograms: nothing */
	uint64_t h[64] = {0};
	CHECK(kg_saturation_detect(h, 64) == -1, "empty histogram");
	h[63] = 1000;
	CHECK(kg_saturation_detect(h, 64) == -1, "a lone spike with nothing below it");
	CHECK(kg_saturation_detect(h, 8) == -1, "8 bins");
	printf("  clipping at full scale found (level 1), rows = image\n");
}

static void test_fixtures(const char *root)
{
	static const char *const files[] = {"fixtures/demo/studio.png",
	                                    "fixtures/demo/object_truth_angle.png"};
	for (size_t i = 0; i < sizeof(files) / sizeof(files[0]); i++) {
		char p[1024];
		snprintf(p, sizeof(p), "%s/%s", root, files[i]);
		kg_image *img = NULL;
		kg_err err = {{0}};
		if (kg_image_read(p, &img, &err)) {
			CHECK(0, "%s: %s", p, err.msg);
			continue;
		}
		if (img->channels == 3)
			no_pileup(files[i], img);
		kg_image_free(&img);
	}
}

/* Coarser codes in a finer histogram: a 12-bit raw with black 256, scaled to 16 bits
 * as the files: backend serves it (codes ~17 bins apart), saturating at 4092; and a
 * natural 8-bit scene scaled to 16 bits (codes 257 apart) with no pile-up. */
static void test_sparse_codes(void)
{
	long clipped[3];
	kg_image *img = scene(3, 12, 1.3, 4092, 1.0, 11, clipped);
	for (size_t i = 0; i < (size_t)W * H * 3; i++) {
		double dn = round(img->data[i] * 4095);
		img->data[i] = (float)(round((dn - 256) / (4095 - 256) * 65535) / 65535);
	}
	img->bits = 16;
	kg_saturation s;
	kg_err err = {{0}};
	CHECK(kg_saturation_of_image(img, 1.0, &s, &err) == 0, "%s", err.msg);
	double want = round((4092.0 - 256) / (4095 - 256) * 65535) / 65535;
	CHECK(s.found[0] && fabs(s.level[0] - want) < 1e-9,
	      "12-bit codes in 16 bits: saturation at %.6f not found (level %g)", want, s.level[0]);
	CHECK(fabs(s.fraction[0] * W * H - clipped[0]) < 0.5, "fraction %.5f, want %ld",
	      s.fraction[0], clipped[0]);
	kg_image_free(&img);
	for (unsigned seed = 1; seed <= 3; seed++) {
		kg_image *e = scene(3, 8, 0.95, 1e9, 50.0, seed, NULL);
		e->bits = 16;
		no_pileup("8-bit scene scaled to 16 bits", e);
		kg_image_free(&e);
	}
	printf("  codes coarser than the histogram: 12-bit raw in 16 bits found, 8-bit in 16 "
	       "clean\n");
}

int main(int argc, char **argv)
{
	test_pileup_12bit();
	test_natural();
	test_nominal();
	test_sparse_codes();
	if (argc > 1)
		test_fixtures(argv[1]);
	return kg_test_done("saturation");
}
