/* The chart scene renderer on its own (no detection): the noise-free image holds
 * each patch's truth at its centre; the true homography maps the patch centre to
 * the reported pixel; supersampling gives partial coverage at an edge; vignetting
 * follows the cos^4 law; the image is the same for 1 and 3 threads, and for the
 * same seed; bad descriptions are refused with a message. */
#include <string.h>

#include "kg_sim.h"
#include "kg_test.h"

static unsigned char bits[8 * 8];

static void describe(kg_sim_chart_card *card, kg_sim_chart_patch *patches,
                     kg_sim_chart_tag *tag)
{
	memset(card, 0, sizeof(*card));
	for (int i = 0; i < 64; i++)
		bits[i] = (i / 8 == 0 || i / 8 == 7 || i % 8 == 0 || i % 8 == 7) ? 1 : ((i * 5) % 3 == 0);
	*tag = (kg_sim_chart_tag){{{10, 10}, {50, 10}, {50, 50}, {10, 50}}, 8, bits};
	for (int p = 0; p < 4; p++) {
		patches[p] = (kg_sim_chart_patch){NULL, {80.0 + 40 * p, 60}, {30, 30}, NULL,
		                                  {0.1 + 0.2 * p, 0.5, 0.8 - 0.15 * p}};
	}
	card->size_mm[0] = 260;
	card->size_mm[1] = 120;
	card->paper = 0.8;
	card->ink = 0.05;
	card->tags = tag;
	card->ntags = 1;
	card->patches = patches;
	card->npatches = 4;
}

int main(void)
{
	kg_err err = {{0}};
	kg_sim_camera cam;
	memset(&cam, 0, sizeof(cam));
	for (int i = 0; i < KG_NBANDS; i++) {
		double wl = kg_band_nm(i);
		cam.sens[0].v[i] = exp(-0.5 * pow((wl - 600) / 30.0, 2));
		cam.sens[1].v[i] = exp(-0.5 * pow((wl - 540) / 35.0, 2));
		cam.sens[2].v[i] = exp(-0.5 * pow((wl - 460) / 25.0, 2));
	}
	kg_spectrum flat = kg_spectrum_const(1.0);
	kg_sim_capture cap;
	CHECK(kg_sim_capture_init(&cap, &cam, &flat, 0.9, NULL, &err) == 0, "capture: %s", err.msg);

	kg_sim_chart_card card;
	kg_sim_chart_patch patches[4];
	kg_sim_chart_tag tag;
	describe(&card, patches, &tag);
	card.pose = (kg_sim_chart_pose){.rotate_deg = 12, .tilt_deg = 35, .tilt_axis_deg = 50};
	kg_sim_chart_desc d = {.width = 640, .height = 480, .cards = &card, .ncards = 1,
	                       .background = 0.2, .supersample = 4, .vignetting = 0.3,
	                       .threads = 1, .seed = 3};
	d.focal_px = kg_sim_chart_focal_px(d.width, 40);
	double box[4] = {0, 0, 640, 480};
	CHECK(kg_sim_chart_pose_fit(&card.pose, card.size_mm, d.focal_px, 640, 480, box, 0.9,
	                            &err) == 0, "pose fit: %s", err.msg);
	kg_sim_chart_result *r = NULL;
	CHECK(kg_sim_chart_render(&d, &cap, &r, &err) == 0, "render: %s", err.msg);
	if (!r)
		return kg_test_done("chart-sim-render");

	/* The card corners land inside the box with the fill asked for. */
	double lo[2] = {1e9, 1e9}, hi[2] = {-1e9, -1e9};
	for (int k = 0; k < 4; k++) {
		double mm[2] = {k == 1 || k == 2 ? 260 : 0, k >= 2 ? 120 : 0}, px[2];
		kg_sim_chart_project(r->homography[0], mm, px);
		for (int a = 0; a < 2; a++) {
			lo[a] = fmin(lo[a], px[a]);
			hi[a] = fmax(hi[a], px[a]);
		}
	}
	CHECK(lo[0] >= 0 && lo[1] >= 0 && hi[0] <= 640 && hi[1] <= 480, "card outside the image");
	CHECK(fabs(fmax((hi[0] - lo[0]) / 640, (hi[1] - lo[1]) / 480) - 0.9) < 1e-6,
	      "fill %.6f", fmax((hi[0] - lo[0]) / 640, (hi[1] - lo[1]) / 480));

	for (int p = 0; p < 4; p++) {
		const kg_sim_chart_truth *t = &r->truth[p];
		double px[2];
		kg_sim_chart_project(r->homography[0], patches[p].centre_mm, px);
		CHECK_NEAR(px[0], t->centre_px[0], 1e-9, "centre x");
		/* The pixel containing the centre holds truth up to the vignetting's
		 * variation over half a pixel. */
		int x = (int)floor(px[0]), y = (int)floor(px[1]);
		const float *v = r->image->data + ((size_t)y * 640 + x) * 3;
		for (int c = 0; c < 3; c++)
			CHECK_NEAR(v[c], t->rgb[c], 2e-3 * t->rgb[c] + 1e-6, "centre value");
		for (int c = 0; c < 3; c++)
			CHECK_NEAR(t->flat_rgb[c], patches[p].rgb[c], 1e-12, "flat value");
		double du = px[0] - 320, dv = px[1] - 240;
		double a = 1 / sqrt(0.7) - 1, s = 1 + a * (du * du + dv * dv) / (320.0 * 320 + 240 * 240);
		CHECK_NEAR(t->vignetting, 1 / (s * s), 1e-12, "vignetting");
		CHECK(t->visible && !t->occluded && !t->glare, "patch %d flags", p);
	}
	/* Anti-aliasing: some pixel on a patch edge lies strictly between patch and
	 * paper. */
	{
		double a[2] = {patches[0].centre_mm[0] - 15, 60}, px[2];
		kg_sim_chart_project(r->homography[0], a, px);
		int y = (int)px[1], x0 = (int)px[0] - 2, mixed = 0;
		for (int x = x0; x < x0 + 5; x++) {
			float g = r->image->data[((size_t)y * 640 + x) * 3 + 1];
			double vg = 0.5 * r->truth[0].vignetting;
			double paper_g = r->truth[0].vignetting * 0.8 * 0.9; /* flat 0.8 under E */
			if (g > fmin(vg, paper_g) * 1.02 && g < fmax(vg, paper_g) * 0.98)
				mixed = 1;
		}
		CHECK(mixed, "no partially covered pixel at a patch edge");
	}

	/* Threads and seeds: same image bit for bit. */
	kg_sim_noise noise = {20000, 5, 12};
	cap.noise = noise;
	d.blur_sigma = 1.2;
	kg_sim_chart_result *r1 = NULL, *r3 = NULL, *r3b = NULL;
	CHECK(kg_sim_chart_render(&d, &cap, &r1, &err) == 0, "render 1: %s", err.msg);
	d.threads = 3;
	CHECK(kg_sim_chart_render(&d, &cap, &r3, &err) == 0, "render 3: %s", err.msg);
	CHECK(kg_sim_chart_render(&d, &cap, &r3b, &err) == 0, "render 3b: %s", err.msg);
	if (r1 && r3 && r3b) {
		size_t n = sizeof(float) * 640 * 480 * 3;
		CHECK(memcmp(r1->image->data, r3->image->data, n) == 0, "1 and 3 threads differ");
		CHECK(memcmp(r3->image->data, r3b->image->data, n) == 0, "same seed differs");
	}
	/* A Bayer mosaic: one sample per pixel with the CFA attached. */
	d.cfa = "GRBG";
	kg_sim_chart_result *rb = NULL;
	CHECK(kg_sim_chart_render(&d, &cap, &rb, &err) == 0, "render mosaic: %s", err.msg);
	if (rb)
		CHECK(rb->image->channels == 1 && rb->image->cfa && !strcmp(rb->image->cfa, "GRBG"),
		      "mosaic: %d channels", rb->image->channels);
	kg_sim_chart_result_free(&rb);
	kg_sim_chart_result_free(&r1);
	kg_sim_chart_result_free(&r3);
	kg_sim_chart_result_free(&r3b);

	/* Refusals. */
	d.cfa = "RGBG";
	CHECK(kg_sim_chart_render(&d, &cap, &rb, &err) == KG_EINVAL && strstr(err.msg, "RGBG"),
	      "bad CFA accepted: %s", err.msg);
	d.cfa = NULL;
	d.vignetting = 1.0;
	CHECK(kg_sim_chart_render(&d, &cap, &rb, &err) == KG_EINVAL && strstr(err.msg, "vignetting"),
	      "vignetting 1 accepted: %s", err.msg);
	d.vignetting = 0;
	card.pose.distance_mm = 0;
	CHECK(kg_sim_chart_render(&d, &cap, &rb, &err) == KG_EINVAL && strstr(err.msg, "distance"),
	      "distance 0 accepted: %s", err.msg);
	kg_sim_chart_pose p = {.tilt_deg = 85};
	CHECK(kg_sim_chart_pose_fit(&p, card.size_mm, d.focal_px, 640, 480, box, 0.9, &err) ==
	          KG_EINVAL, "tilt 85 accepted");
	kg_sim_chart_result_free(&r);
	return kg_test_done("chart-sim-render");
}
