/* The patch sampler's optimised path (scanline spans of each region, radix selection,
 * patches over threads) against its reference (every pixel of each region's bounding
 * box through the inverse homography, quickselect) on synthetic photographs
 * (chart_synth.h): the same pixels and the same numbers, bit for bit, for 8- and
 * 16-bit, grey, float and Bayer images (and the Bayer frame demosaiced pixel by pixel
 * here, sampled by the reference), both statistics, a patch half out of the
 * frame, glare, a clipped patch, steep perspective and an axis-aligned view whose
 * region sides fall on pixel centres. kg_chart_detect must also give the same
 * patches at 1, 2 and 3 threads. */
#include <string.h>

#include "calib_private.h"
#include "chart_synth.h"
#include "kg_test.h"

static int same_double(double a, double b)
{
	return a == b || (isnan(a) && isnan(b));
}

static void compare(const kg_chart_result *a, const kg_chart_result *b, const char *what,
                    const char *how)
{
	CHECK(a->npatches == b->npatches, "%s, %s: %d vs %d patches", what, how, a->npatches,
	      b->npatches);
	for (int i = 0; i < a->npatches && i < b->npatches; i++) {
		const kg_chart_sample *p = &a->patches[i], *q = &b->patches[i];
		int same = p->pixels == q->pixels && p->flags == q->flags &&
		           same_double(p->clipped_fraction, q->clipped_fraction) &&
		           same_double(p->nonuniformity, q->nonuniformity) &&
		           !strcmp(p->warning, q->warning) && !strcmp(p->id, q->id);
		for (int c = 0; c < 3; c++)
			same = same && same_double(p->rgb[c], q->rgb[c]) && same_double(p->sd[c], q->sd[c]);
		CHECK(same, "%s, %s: patch %s differs: %ld vs %ld px, rgb %.9g %.9g %.9g vs %.9g "
		      "%.9g %.9g, sd %.9g vs %.9g, flags %u vs %u", what, how, p->id, p->pixels,
		      q->pixels, p->rgb[0], p->rgb[1], p->rgb[2], q->rgb[0], q->rgb[1], q->rgb[2],
		      p->sd[0], q->sd[0], p->flags, q->flags);
	}
}

/* The bilinear demosaic written out pixel by pixel, independently of the sampler's:
 * each missing colour the mean of the 3 x 3 neighbours (edges clamped) that carry it,
 * summed in raster order in double. */
static kg_image *demosaic_reference(const kg_image *raw)
{
	int W = raw->width, H = raw->height;
	kg_image *rgb = syn_image(W, H, 3, 0);
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			double sum[3] = {0, 0, 0};
			int cnt[3] = {0, 0, 0};
			for (int dy = -1; dy <= 1; dy++)
				for (int dx = -1; dx <= 1; dx++) {
					int yy = y + dy < 0 ? 0 : y + dy >= H ? H - 1 : y + dy;
					int xx = x + dx < 0 ? 0 : x + dx >= W ? W - 1 : x + dx;
					int c = (int)(strchr("RGB", raw->cfa[(yy % 2) * 2 + xx % 2]) - "RGB");
					sum[c] += raw->data[(size_t)yy * W + xx];
					cnt[c]++;
				}
			int own = (int)(strchr("RGB", raw->cfa[(y % 2) * 2 + x % 2]) - "RGB");
			for (int c = 0; c < 3; c++)
				rgb->data[((size_t)y * W + x) * 3 + c] =
				    c == own ? raw->data[(size_t)y * W + x] : (float)(sum[c] / cnt[c]);
		}
	return rgb;
}

/* Reference against the optimised sampler at 1, 2 and 3 threads. */
static void check_sampler(const kg_chart_layout *l, const kg_image *img, const double H[9],
                          kg_chart_statistic statistic, const char *what)
{
	kg_chart_detect_options o;
	kg_chart_detect_options_default(&o);
	o.statistic = statistic;
	o.threads = 1;
	kg_err err = {{0}};
	kg_chart_result *ref = NULL;
	int ret = calib_chart_sample(l, img, H, &o, 1, &ref, &err);
	CHECK(ret == 0, "%s: reference sampler: %s", what, err.msg);
	long pixels = 0;
	unsigned flags = 0;
	for (int t = 1; t <= 3 && ref; t++) {
		kg_chart_result *fast = NULL;
		o.threads = t;
		ret = calib_chart_sample(l, img, H, &o, 0, &fast, &err);
		CHECK(ret == 0, "%s: sampler: %s", what, err.msg);
		char how[32];
		snprintf(how, sizeof(how), "%d thread%s", t, t > 1 ? "s" : "");
		if (fast)
			compare(ref, fast, what, how);
		kg_chart_result_free(&fast);
	}
	for (int i = 0; ref && i < ref->npatches; i++) {
		pixels += ref->patches[i].pixels;
		flags |= ref->patches[i].flags;
	}
	printf("%s: %ld pixels sampled, flags seen %#x\n", what, pixels, flags);
	kg_chart_result_free(&ref);
}

static kg_image *photo(const kg_chart_layout *l, const double H[9], int channels, int bits,
                       unsigned seed)
{
	kg_image *img = syn_image(960, 720, 3, 0.3f);
	syn_draw(img, l, H);
	if (channels == 1) {
		kg_image *grey = syn_image(960, 720, 1, 0);
		for (size_t i = 0; i < (size_t)960 * 720; i++)
			grey->data[i] = img->data[i * 3 + 1];
		kg_image_free(&img);
		img = grey;
	}
	syn_finish(img, 0.004, bits, seed);
	return img;
}

int main(void)
{
	kg_chart_layout *l = syn_layout("synthetic-24", 0);
	static const double tilted[4][2] = {{90, 70}, {850, 110}, {820, 600}, {120, 640}};
	static const double steep[4][2] = {{300, 60}, {660, 90}, {950, 700}, {10, 690}};
	/* 4 px per mm from the origin: region sides of whole or half mm on pixel edges and
	 * centres */
	static const double aligned[4][2] = {{0, 0}, {840, 0}, {840, 640}, {0, 640}};
	/* the right-hand columns of patches across and past the image's edge */
	static const double cut[4][2] = {{420, 100}, {1280, 100}, {1280, 700}, {420, 700}};
	double H[9];

	syn_homography(l, tilted, H);
	for (int bits = 8; bits <= 16; bits += 8) {
		kg_image *img = photo(l, H, 3, bits, 1);
		char what[64];
		snprintf(what, sizeof(what), "%d-bit RGB, tilted", bits);
		check_sampler(l, img, H, KG_CHART_MEDIAN, what);
		snprintf(what, sizeof(what), "%d-bit RGB, tilted, trimmed mean", bits);
		check_sampler(l, img, H, KG_CHART_TRIMMED_MEAN, what);
		kg_image_free(&img);
	}
	{
		kg_image *img = photo(l, H, 1, 16, 2);
		check_sampler(l, img, H, KG_CHART_MEDIAN, "16-bit grey, tilted");
		kg_image_free(&img);
		img = photo(l, H, 3, 32, 3);
		check_sampler(l, img, H, KG_CHART_MEDIAN, "float RGB, tilted");
		kg_image_free(&img);
	}
	/* Bayer RGGB: demosaiced only where sampled, against the whole frame demosaiced */
	{
		kg_image *rgb = photo(l, H, 3, 32, 4);
		kg_image *raw = syn_mosaic(rgb, "RGGB");
		syn_finish(raw, 0.0, 16, 5);
		check_sampler(l, raw, H, KG_CHART_MEDIAN, "Bayer RGGB 16-bit, tilted");
		/* the frame demosaiced here, sampled by the reference: the same patches as the
		 * optimised sampler's on the raw frame (one clip level for both) */
		kg_image *dem = demosaic_reference(raw);
		kg_chart_detect_options o;
		kg_chart_detect_options_default(&o);
		o.clip_level = 0.999;
		o.threads = 2;
		kg_err err = {{0}};
		kg_chart_result *a = NULL, *b = NULL;
		CHECK(calib_chart_sample(l, dem, H, &o, 1, &a, &err) == 0, "demosaiced: %s", err.msg);
		CHECK(calib_chart_sample(l, raw, H, &o, 0, &b, &err) == 0, "raw: %s", err.msg);
		if (a && b)
			compare(a, b, "Bayer RGGB 16-bit, demosaiced here vs by the sampler", "2 threads");
		kg_chart_result_free(&a);
		kg_chart_result_free(&b);
		kg_image_free(&dem);
		kg_image_free(&raw);
		kg_image_free(&rgb);
	}
	/* glare over one patch, another clipped */
	{
		kg_image *img = syn_image(960, 720, 3, 0.3f);
		syn_draw(img, l, H);
		double c[2];
		kg_homography_map(H, l->patches[3].center_mm[0], l->patches[3].center_mm[1], c);
		for (int y = (int)c[1] - 6; y < (int)c[1] + 6; y++)
			for (int x = (int)c[0] - 6; x < (int)c[0] + 6; x++)
				for (int k = 0; k < 3; k++)
					img->data[((size_t)y * 960 + x) * 3 + k] = 0.98f;
		kg_homography_map(H, l->patches[9].center_mm[0], l->patches[9].center_mm[1], c);
		for (int y = (int)c[1] - 30; y < (int)c[1] + 30; y++)
			for (int x = (int)c[0] - 30; x < (int)c[0] + 30; x++)
				img->data[((size_t)y * 960 + x) * 3] = 1.0f;
		syn_finish(img, 0.002, 16, 6);
		check_sampler(l, img, H, KG_CHART_MEDIAN, "16-bit RGB, glare and clipping");
		kg_image_free(&img);
	}
	/* other poses: steep, axis-aligned, partly out of frame */
	const struct {
		const double (*q)[2];
		int bits;
		const char *what;
	} poses[] = {{steep, 16, "16-bit RGB, steep perspective"},
	             {aligned, 8, "8-bit RGB, axis-aligned 4 px/mm"},
	             {cut, 16, "16-bit RGB, partly out of frame"}};
	for (int i = 0; i < 3; i++) {
		syn_homography(l, poses[i].q, H);
		kg_image *img = photo(l, H, 3, poses[i].bits, 7 + (unsigned)i);
		check_sampler(l, img, H, KG_CHART_MEDIAN, poses[i].what);
		kg_image_free(&img);
	}

	/* the whole detector at 1, 2 and 3 threads */
	syn_homography(l, tilted, H);
	{
		kg_image *img = photo(l, H, 3, 16, 10);
		kg_chart_result *r[3] = {NULL, NULL, NULL};
		for (int t = 0; t < 3; t++) {
			kg_chart_detect_options o;
			kg_chart_detect_options_default(&o);
			o.threads = t + 1;
			kg_err err = {{0}};
			int ret = kg_chart_detect(l, img, &o, &r[t], &err);
			CHECK(ret == 0, "detect at %d threads: %s", t + 1, err.msg);
		}
		for (int t = 1; t < 3; t++)
			if (r[0] && r[t]) {
				char how[32];
				snprintf(how, sizeof(how), "detect at %d threads", t + 1);
				CHECK(!memcmp(r[0]->H, r[t]->H, sizeof(r[0]->H)), "%s: another homography",
				      how);
				compare(r[0], r[t], "detect at 1 thread", how);
			}
		for (int t = 0; t < 3; t++)
			kg_chart_result_free(&r[t]);
		kg_image_free(&img);
	}
	syn_layout_free(l);
	return kg_test_done("chart-detect-sampler");
}
