/* kg_chart_detect on synthetic photographs (chart_synth.h): patch values against
 * truth, occluded tags, no chart, foreign tags, two charts, 8/16 bit, grey, Bayer,
 * clipping; and the homography fit itself. */
#include <string.h>

#include "chart_synth.h"
#include "kg_test.h"

static const double view[4][2] = {{90, 70}, {850, 110}, {820, 600}, {120, 640}};

static int has_warning(const kg_chart_result *r, const char *text)
{
	for (int i = 0; i < r->nwarnings; i++)
		if (strstr(r->warnings[i], text))
			return 1;
	return 0;
}

static void check_values(const kg_chart_result *r, int grey, double tol, const char *what)
{
	CHECK(r->npatches == SYN_ROWS * SYN_COLS, "%s: %d patches", what, r->npatches);
	double worst = 0;
	for (int i = 0; i < r->npatches; i++) {
		const kg_chart_sample *p = &r->patches[i];
		CHECK(p->flags == 0, "%s: patch %s flagged: %s", what, p->id, p->warning);
		for (int c = 0; c < 3; c++) {
			double truth = syn_value(i, grey ? 1 : c);
			double rel = fabs(p->rgb[c] - truth) / truth;
			worst = fmax(worst, rel);
			CHECK(rel <= tol, "%s: patch %s channel %d: %.5f vs truth %.5f (%.2f %%)", what,
			      p->id, c, p->rgb[c], truth, 100 * rel);
		}
	}
	printf("%s: %d tags used, RMS %.3f px, worst patch error %.3f %%, tags %.1f ms, "
	       "total %.1f ms\n", what, r->ntags_used, r->rms_px, 100 * worst,
	       1e3 * r->tag_seconds, 1e3 * r->total_seconds);
}

static kg_chart_result *detect(const kg_chart_layout *l, const kg_image *img, int expect,
                               const char *what, kg_err *err)
{
	kg_chart_result *r = NULL;
	int ret = kg_chart_detect(l, img, NULL, &r, err);
	CHECK(ret == expect, "%s: returned %d, expected %d: %s", what, ret, expect, err->msg);
	for (int i = 0; r && i < r->nwarnings; i++)
		printf("  %s: warning: %s\n", what, r->warnings[i]);
	return r;
}

static void test_homography(void)
{
	double H[9] = {1.9, 0.3, 40, -0.2, 2.1, 55, 2e-4, -3e-4, 1}, src[12][2], dst[12][2];
	for (int i = 0; i < 12; i++) {
		src[i][0] = 10 + 17 * (i % 4);
		src[i][1] = 5 + 23 * (i / 4);
		kg_homography_map(H, src[i][0], src[i][1], dst[i]);
		dst[i][0] += 0.01 * ((i * 7) % 3 - 1);
	}
	double G[9], rms;
	kg_err err = {{0}};
	CHECK(kg_homography_fit((const double (*)[2])src, (const double (*)[2])dst, 12, 1, G, &rms,
	                        &err) == 0, "fit: %s", err.msg);
	for (int k = 0; k < 9; k++)
		CHECK_NEAR(G[k], H[k], 1e-2 * fabs(H[k]) + 1e-6, "homography entry");
	CHECK(rms < 0.01, "rms %g", rms);
	double Hi[9], p[2], q[2];
	CHECK(kg_homography_invert(H, Hi) == 0, "invert");
	kg_homography_map(H, 3, 4, p);
	kg_homography_map(Hi, p[0], p[1], q);
	CHECK_NEAR(q[0], 3, 1e-9, "inverse x");
	CHECK_NEAR(q[1], 4, 1e-9, "inverse y");
	CHECK(kg_homography_fit((const double (*)[2])src, (const double (*)[2])dst, 3, 1, G, NULL,
	                        &err) == KG_EINVAL, "3 points refused");
}

int main(void)
{
	test_homography();
	kg_err err = {{0}};
	kg_chart_layout *l = syn_layout("synthetic-24", 0);
	double H[9];
	syn_homography(l, view, H);

	/* 8-bit and 16-bit RGB with noise */
	for (int bits = 8; bits <= 16; bits += 8) {
		kg_image *img = syn_image(960, 720, 3, 0.3f);
		syn_draw(img, l, H);
		syn_finish(img, 0.004, bits, 1);
		char what[32];
		snprintf(what, sizeof(what), "rgb %d-bit", bits);
		kg_chart_result *r = detect(l, img, 0, what, &err);
		if (r) {
			check_values(r, 0, 0.005, what);
			CHECK(r->ntags_used == 4, "%s: %d tags used", what, r->ntags_used);
			CHECK(r->rms_px < 0.5, "%s: rms %.3f px", what, r->rms_px);
			CHECK(r->nwarnings == 0, "%s: %d warnings", what, r->nwarnings);
			kg_patchset *ps = NULL;
			CHECK(kg_chart_result_patchset(r, &ps, &err) == 0, "patchset: %s", err.msg);
			if (ps) {
				CHECK(ps->n == 24 && kg_patchset_extra_index(ps, "CLIPPED_FRACTION") >= 0,
				      "patch set of %d", ps->n);
				CHECK(strcmp(ps->ids[0], "A1") == 0, "first id %s", ps->ids[0]);
			}
			kg_patchset_free(&ps);
			if (bits == 8) {
				CHECK(kg_chart_overlay_write(r, img, "test-chart-detect-overlay.png", 800,
				                             &err) == 0, "overlay: %s", err.msg);
				CHECK(kg_test_file_exists("test-chart-detect-overlay.png"), "overlay written");
			}
		}
		kg_chart_result_free(&r);
		kg_image_free(&img);
	}

	/* grey image: grey patch values */
	{
		kg_image *img = syn_image(960, 720, 1, 0.3f);
		syn_draw(img, l, H);
		syn_finish(img, 0.002, 16, 2);
		kg_chart_result *r = detect(l, img, 0, "grey 16-bit", &err);
		if (r)
			check_values(r, 1, 0.005, "grey 16-bit");
		kg_chart_result_free(&r);
		kg_image_free(&img);
	}

	/* Bayer RGGB, demosaiced */
	{
		kg_image *rgb = syn_image(960, 720, 3, 0.3f);
		syn_draw(rgb, l, H);
		kg_image *raw = syn_mosaic(rgb, "RGGB");
		syn_finish(raw, 0.002, 16, 3);
		kg_chart_result *r = detect(l, raw, 0, "bayer RGGB", &err);
		if (r)
			check_values(r, 0, 0.005, "bayer RGGB");
		kg_chart_result_free(&r);
		kg_image_free(&raw);
		kg_image_free(&rgb);
	}

	/* two tags occluded: still found, and it says so */
	{
		kg_image *img = syn_image(960, 720, 3, 0.3f);
		syn_draw(img, l, H);
		for (int t = 1; t <= 2; t++) {
			double c[2];
			kg_homography_map(H, l->tags[t].center_mm[0], l->tags[t].center_mm[1], c);
			for (int y = (int)c[1] - 30; y < (int)c[1] + 30; y++)
				for (int x = (int)c[0] - 30; x < (int)c[0] + 30; x++)
					if (x >= 0 && y >= 0 && x < 960 && y < 720)
						for (int k = 0; k < 3; k++)
							img->data[((size_t)y * 960 + x) * 3 + k] = 0.15f;
		}
		syn_finish(img, 0.004, 8, 4);
		kg_chart_result *r = detect(l, img, 0, "two tags occluded", &err);
		if (r) {
			check_values(r, 0, 0.005, "two tags occluded");
			CHECK(r->ntags_used == 2, "%d tags used", r->ntags_used);
			CHECK(has_warning(r, "homography determined from 2 tags' corners"),
			      "warning about 2 tags");
		}
		kg_chart_result_free(&r);
		kg_image_free(&img);
	}

	/* no chart at all */
	{
		kg_image *img = syn_image(640, 480, 3, 0.4f);
		syn_finish(img, 0.01, 8, 5);
		kg_chart_result *r = detect(l, img, KG_ENOENT, "no chart", &err);
		CHECK(!r, "no result");
		CHECK(strstr(err.msg, "no tag36h11 tags found"), "message: %s", err.msg);
		kg_image_free(&img);
	}

	/* tags of another layout only: refused, naming what was seen */
	{
		kg_chart_layout *other = syn_layout("other", 10);
		kg_image *img = syn_image(960, 720, 3, 0.3f);
		syn_draw(img, other, H);
		syn_finish(img, 0.004, 8, 6);
		kg_chart_result *r = detect(l, img, KG_ENOENT, "foreign tags", &err);
		CHECK(!r, "no result");
		CHECK(strstr(err.msg, "found 4 other tags: 10, 11, 12, 13") ||
		      strstr(err.msg, "other tags"), "message: %s", err.msg);
		kg_image_free(&img);
		syn_layout_free(other);
	}

	/* two charts in one frame: the one whose ids match the layout */
	{
		kg_chart_layout *other = syn_layout("other", 20);
		double left[4][2] = {{20, 60}, {470, 80}, {460, 420}, {30, 400}};
		double right[4][2] = {{500, 70}, {940, 60}, {950, 400}, {490, 420}};
		double HL[9], HR[9];
		syn_homography(l, left, HL);
		syn_homography(other, right, HR);
		kg_image *img = syn_image(960, 720, 3, 0.3f);
		syn_draw(img, other, HR);
		syn_draw(img, l, HL);
		syn_finish(img, 0.003, 16, 7);
		kg_chart_result *r = detect(l, img, 0, "two charts", &err);
		if (r) {
			check_values(r, 0, 0.005, "two charts");
			CHECK(has_warning(r, "ignored 4 tags not in layout"), "foreign tags noted");
			double c[2];
			kg_homography_map(r->H, 105, 80, c);
			CHECK(c[0] < 480, "chart found at x %.0f: the left one", c[0]);
		}
		kg_chart_result_free(&r);
		kg_image_free(&img);
		syn_layout_free(other);
	}

	/* a clipped patch is flagged, the others are not */
	{
		kg_image *img = syn_image(960, 720, 3, 0.3f);
		syn_draw(img, l, H);
		syn_finish(img, 0.003, 8, 8);
		double q0[2], q1[2];
		kg_homography_map(H, l->patches[5].center_mm[0] - 10, l->patches[5].center_mm[1] - 10, q0);
		kg_homography_map(H, l->patches[5].center_mm[0] + 10, l->patches[5].center_mm[1] + 10, q1);
		for (int y = (int)q0[1] + 8; y < (int)q1[1] - 8; y++)
			for (int x = (int)q0[0] + 8; x < (int)q1[0] - 8; x++)
				img->data[((size_t)y * 960 + x) * 3 + 0] = 1.0f;
		kg_chart_result *r = detect(l, img, 0, "clipped", &err);
		if (r) {
			CHECK(r->patches[5].flags & KG_CHART_FLAG_CLIPPED, "patch %s not flagged clipped",
			      r->patches[5].id);
			CHECK(r->patches[5].clipped_fraction > 0.5, "clipped fraction %g",
			      r->patches[5].clipped_fraction);
			CHECK(r->patches[0].flags == 0, "patch A1 flagged: %s", r->patches[0].warning);
			CHECK(has_warning(r, "1 patch flagged"), "warning about the clipped patch");
		}
		kg_chart_result_free(&r);
		kg_image_free(&img);
	}

	syn_layout_free(l);
	return kg_test_done("chart-detect");
}
