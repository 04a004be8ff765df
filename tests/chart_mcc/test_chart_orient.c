/* The tagless detector's orientation and refusals (calib/chart_detect.c).
 *
 * Orientation from the colour pattern: `kogei sim chart` renders an unframed
 * ColorChecker 24 (the real patch spectra, ../shared/reference), then the test lays a
 * light field over it that falls off across the chart towards the white patch D01
 * (exponentially along the line from A06 to D01), brightened so that the bright end
 * clips. The premise is checked on the truth (the white patch ends darker than at
 * least three colour patches, so brightness ranks read the chart upside down), and
 * the chart must then be found with every patch id where the truth puts it: the
 * orientation is right. Also with a strong falloff and no clipping, at other turns.
 *
 * Refusal with an overlay: a picture with no chart, and a chart whose patch colours
 * are shuffled (mcc finds a box, no turn fits the ColorChecker), are refused with
 * exit status 1 by `kogei chart detect --tagless --overlay O.png`, and O.png is still
 * written: the image's size, with drawn pixels (the dashed yellow frame of the
 * region searched; magenta for the rejected box) that the grey input does not have.
 * The library keeps the refusal (keep_refused): refused, the region searched, the
 * candidates with their reasons. On the tag path (two of four tags covered, four
 * asked for), each tag seen is kept as a candidate with its reason.
 *
 * Two charts side by side (the shuffled one and a relit ColorChecker): whichever of
 * mcc's boxes comes first, the ColorChecker is found with every patch in place.
 *
 * Skipped (77) when built without OpenCV mcc or without the reference spectra.
 * Argument: the kogei program. */
#include <string.h>

#include "kg_calib.h"
#include "kg_test.h"
#include "../chart_sim/chart_sim_util.h"

static const char *kogei;
static char camera[4200], spectra[4200], layout[4200];

static const char *render_width = "1200";

static int render(const char *spec, const char *tilt, const char *rotate, const char *img,
                  const char *truth)
{
	char log[8192];
	char *argv[] = {(char *)kogei, "sim", "chart", "--layout", layout, "--spectra",
	                (char *)spec, "--camera", camera, "--illuminant", "D65", "--paper",
	                "0.03", "--background", "0.3", "--width", (char *)render_width, "--height", "900",
	                "--fill", "0.7", "--tilt", (char *)tilt, "--rotate", (char *)rotate,
	                "--noise", "20000:5:12", "--blur", "0.8", "--seed", "9", "-o", (char *)img,
	                "--truth", (char *)truth, NULL};
	int rc = cs_run(argv, log, sizeof(log));
	CHECK(rc == 0, "sim chart exit %d: %s", rc, log);
	return rc;
}

static int extra_column(const kg_patchset *ps, const char *name)
{
	for (int k = 0; k < ps->nextra; k++)
		if (!strcmp(ps->extra_names[k], name))
			return k;
	return -1;
}

static void truth_centre(const kg_patchset *t, const char *id, double c[2])
{
	int k = kg_patchset_find(t, id), px = extra_column(t, "PIXEL_X"),
	    py = extra_column(t, "PIXEL_Y");
	c[0] = c[1] = NAN;
	if (k >= 0 && px >= 0 && py >= 0) {
		c[0] = t->extra[(size_t)k * t->nextra + px];
		c[1] = t->extra[(size_t)k * t->nextra + py];
	}
}

/* The light over the image: gain * ratio^t, t the position along the line from
 * D01 (t = 0) to A06 (t = 1), clamped to [-0.3, 1.3]. */
typedef struct light {
	double a[2], d[2], dd, gain, ratio;
} light;

static double light_at(const light *L, double x, double y)
{
	double t = ((x - L->a[0]) * L->d[0] + (y - L->a[1]) * L->d[1]) / L->dd;
	t = fmin(fmax(t, -0.3), 1.3);
	return L->gain * pow(L->ratio, t);
}

static int has_warning(const kg_chart_result *r, const char *text)
{
	for (int i = 0; i < r->nwarnings; i++)
		if (strstr(r->warnings[i], text))
			return 1;
	return 0;
}

/* Render, relight (and clip at full scale), detect, check the patch assignment. */
static void check_relit(const char *name, const char *tilt, const char *rotate, double gain,
                        double ratio, int want_clipped_above_white, int processed)
{
	char *img = strdup(cs_path("relit.tif")), *truth_path = strdup(cs_path("relit.cgats"));
	kg_image *im = NULL;
	kg_patchset *truth = NULL;
	kg_chart_result *r = NULL;
	kg_chart_layout *l = NULL;
	kg_err err = {{0}};
	if (render(spectra, tilt, rotate, img, truth_path))
		goto done;
	int ret = kg_image_read(img, &im, &err);
	if (!ret)
		ret = kg_patchset_read(truth_path, 0, &truth, &err);
	if (!ret)
		ret = kg_chart_layout_load(layout, &l, &err);
	CHECK(ret == 0, "%s: %s", name, err.msg);
	if (ret)
		goto done;
	light L = {.gain = gain, .ratio = ratio};
	double a6[2];
	truth_centre(truth, "D01", L.a);
	truth_centre(truth, "A06", a6);
	L.d[0] = a6[0] - L.a[0];
	L.d[1] = a6[1] - L.a[1];
	L.dd = L.d[0] * L.d[0] + L.d[1] * L.d[1];
	CHECK(L.dd > 100, "%s: no truth positions for D01 and A06", name);
	if (!(L.dd > 100))
		goto done;
	long clipped = 0;
	for (int y = 0; y < im->height; y++)
		for (int x = 0; x < im->width; x++) {
			double f = light_at(&L, x + 0.5, y + 0.5);
			float *p = im->data + ((size_t)y * im->width + x) * im->channels;
			for (int c = 0; c < im->channels; c++) {
				double v = p[c] * f;
				clipped += v >= 1;
				v = fmin(v, 1.0);
				if (processed) {
					/* as a camera's JPEG: white-balanced, then the sRGB curve */
					static const double wb[3] = {0.8, 1.0, 1.25};
					v = fmin(v * wb[c % 3], 1.0);
					v = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
				}
				p[c] = (float)v;
			}
		}
	/* the premise: by brightness the white patch is not the brightest */
	double wc[2], white = 0;
	truth_centre(truth, "D01", wc);
	int k = kg_patchset_find(truth, "D01");
	for (int c = 0; c < 3; c++)
		white += fmin(1, truth->rgb[k][c] * light_at(&L, wc[0], wc[1]));
	int brighter = 0;
	for (int i = 0; i < 18; i++) {
		char id[8];
		double pc[2], sum = 0;
		snprintf(id, sizeof(id), "%c%02d", 'A' + i / 6, i % 6 + 1);
		truth_centre(truth, id, pc);
		int j = kg_patchset_find(truth, id);
		for (int c = 0; c < 3; c++)
			sum += fmin(1, truth->rgb[j][c] * light_at(&L, pc[0], pc[1]));
		brighter += sum > white;
	}
	printf("  %s: %d colour patches brighter than the white, %.2f %% of samples clipped\n",
	       name, brighter, 100.0 * clipped / ((double)im->width * im->height * im->channels));
	CHECK(brighter >= 3, "%s: premise: only %d colour patches brighter than the white", name,
	      brighter);
	if (want_clipped_above_white)
		CHECK(clipped > 0, "%s: premise: nothing clipped", name);
	kg_chart_detect_options o;
	kg_chart_detect_options_default(&o);
	o.tagless = 1;
	/* by default a light varying this much (2-3 x its mean) is refused with that cause
	 * (the light-field correction is trusted to 100 %); the orientation is what is
	 * tested here, so the refusal is checked and then lifted */
	ret = kg_chart_detect(l, im, &o, &r, &err);
	CHECK(ret == 0 || strstr(err.msg, "the light across chart"),
	      "%s: by default found or refused for its light: %s", name, err.msg);
	kg_chart_result_free(&r);
	o.max_light_variation = 10;
	ret = kg_chart_detect(l, im, &o, &r, &err);
	CHECK(ret == 0, "%s: not found: %s", name, err.msg);
	if (ret)
		goto done;
	CHECK(r->tagless && r->npatches == 24, "%s: %d patches", name, r->npatches);
	CHECK(has_warning(r, "orientation chosen from the patches' colours"),
	      "%s: the orientation decision is not reported", name);
	for (int i = 0; i < r->nwarnings; i++)
		if (strstr(r->warnings[i], "orientation chosen"))
			printf("    %s\n", strstr(r->warnings[i], "colour misfit"));
	int right = 0;
	for (int i = 0; i < r->npatches; i++) {
		const kg_chart_sample *p = &r->patches[i];
		double cx = 0, cy = 0, t[2];
		for (int q = 0; q < 4; q++) {
			cx += p->quad[q][0] / 4;
			cy += p->quad[q][1] / 4;
		}
		double side = sqrt(fabs((p->quad[1][0] - p->quad[0][0]) * (p->quad[3][1] - p->quad[0][1]) -
		                        (p->quad[1][1] - p->quad[0][1]) * (p->quad[3][0] - p->quad[0][0])));
		truth_centre(truth, p->id, t);
		int ok = hypot(cx - t[0], cy - t[1]) < 0.25 * side;
		CHECK(ok, "%s: patch %s sampled at (%.1f, %.1f), truth centre (%.1f, %.1f)", name,
		      p->id, cx, cy, t[0], t[1]);
		right += ok;
	}
	CHECK(right == 24, "%s: %d of 24 patches where the truth puts them", name, right);
done:
	kg_chart_result_free(&r);
	kg_chart_layout_free(&l);
	kg_patchset_free(&truth);
	kg_image_free(&im);
	remove(img);
	remove(truth_path);
	free(img);
	free(truth_path);
}

/* Pixels of the overlay the grey input cannot have: saturated colour. */
static long drawn_pixels(const kg_image *ov, long *magenta)
{
	long n = 0;
	*magenta = 0;
	for (long i = 0; i < (long)ov->width * ov->height; i++) {
		const float *p = ov->data + i * ov->channels;
		if (ov->channels < 3)
			return 0;
		double mx = fmax(p[0], fmax(p[1], p[2])), mn = fmin(p[0], fmin(p[1], p[2]));
		n += mx - mn > 0.5;
		*magenta += p[0] > 0.8 && p[1] < 0.4 && p[2] > 0.8;
	}
	return n;
}

/* kogei chart detect --tagless (or --min-tags 4) --overlay on an image it must refuse. */
static void check_refusal_overlay(const char *name, const char *img, int width, int height,
                                  int want_box)
{
	char log[8192];
	char *out = strdup(cs_path("refused.cgats")), *ov = strdup(cs_path("refused.png"));
	remove(ov);
	char *argv[] = {(char *)kogei, "chart", "detect", "--layout", layout,
	                want_box == 2 ? "--min-tags=4" : "--tagless", (char *)img, "-o", out,
	                "--overlay", ov, NULL};
	int rc = cs_run(argv, log, sizeof(log));
	CHECK(rc == 1, "%s: exit %d, expected 1: %s", name, rc, log);
	CHECK(strstr(log, "not found") && strstr(log, "overlay"),
	      "%s: the message names neither the refusal nor the overlay: %s", name, log);
	CHECK(!kg_test_file_exists(out), "%s: a patch file was written", name);
	kg_image *o = NULL;
	kg_err err = {{0}};
	int ret = kg_image_read(ov, &o, &err);
	CHECK(ret == 0, "%s: no overlay: %s", name, err.msg);
	if (!ret) {
		long magenta, drawn = drawn_pixels(o, &magenta);
		printf("  %s: overlay %d x %d, %ld drawn pixels, %ld magenta\n", name, o->width,
		       o->height, drawn, magenta);
		CHECK(o->width == width && o->height == height,
		      "%s: overlay %d x %d, expected %d x %d", name, o->width, o->height, width,
		      height);
		CHECK(drawn > 2000, "%s: only %ld drawn pixels on the overlay", name, drawn);
		if (want_box)
			CHECK(magenta > 500, "%s: the rejected box is not drawn (%ld magenta pixels)",
			      name, magenta);
	}
	kg_image_free(&o);
	remove(ov);
	free(out);
	free(ov);
}

/* The same refusal through the library: what was searched is kept. */
static void check_refusal_result_at(const char *name, const kg_image *im, int want_box,
                                    int decimate)
{
	kg_chart_layout *l = NULL;
	kg_chart_result *r = NULL;
	kg_err err = {{0}};
	int ret = kg_chart_layout_load(layout, &l, &err);
	CHECK(ret == 0, "%s: %s", name, err.msg);
	if (ret)
		return;
	kg_chart_detect_options o;
	kg_chart_detect_options_default(&o);
	o.tagless = 1;
	o.keep_refused = 1;
	o.tagless_decimate = decimate;
	ret = kg_chart_detect(l, im, &o, &r, &err);
	CHECK(ret == KG_ENOENT, "%s: code %d, expected KG_ENOENT (%s)", name, ret, err.msg);
	CHECK(r && r->refused && r->has_searched && !strcmp(r->refusal, err.msg),
	      "%s: the refusal is not kept in the result", name);
	if (r && want_box) {
		CHECK(r->ncandidates == 5 && strstr(r->candidates[0].why, "mcc's box"),
		      "%s: %d candidates kept, expected mcc's box and 4 turns", name, r->ncandidates);
		CHECK(strstr(err.msg, "do not read as layout") && strstr(err.msg, "colour misfit"),
		      "%s: message: %s", name, err.msg);
	}
	printf("  %s: %s\n", name, err.msg);
	kg_chart_result_free(&r);
	/* without keep_refused, nothing comes back */
	o.keep_refused = 0;
	ret = kg_chart_detect(l, im, &o, &r, &err);
	CHECK(ret == KG_ENOENT && r == NULL, "%s: without keep_refused: code %d, result %p", name,
	      ret, (void *)r);
	kg_chart_result_free(&r);
	kg_chart_layout_free(&l);
}

/* On the full image (the default at these sizes), then on a copy reduced 2 x 2, where
 * the patch-grid finder looks first: a grid it refuses leaves nothing behind, and
 * mcc's refusal is the one reported. */
static void check_refusal_result(const char *name, const kg_image *im, int want_box)
{
	char reduced[160];
	check_refusal_result_at(name, im, want_box, 0);
	snprintf(reduced, sizeof(reduced), "%s, reduced 2 x 2", name);
	check_refusal_result_at(reduced, im, want_box, 2);
}

/* The reference spectra with the patches' spectra shuffled (ids kept in place). */
static void write_shuffled(const char *from, const char *to)
{
	FILE *in = fopen(from, "r"), *out = fopen(to, "w");
	if (!in || !out) {
		fprintf(stderr, "cannot copy %s to %s\n", from, to);
		exit(1);
	}
	static char line[25][8192];
	int n = 0;
	while (n < 25 && fgets(line[n], sizeof(line[n]), in))
		n++;
	static const int perm[24] = {5, 17, 2, 20, 11, 0, 14, 9, 22, 3, 19, 7,
	                             12, 23, 1, 16, 10, 21, 8, 4, 18, 15, 6, 13};
	fputs(line[0], out);
	for (int i = 1; i < n; i++) {
		const char *src = line[1 + perm[(i - 1) % 24]];
		/* "id,name," of row i, the spectrum of row perm */
		const char *c1 = strchr(line[i], ','), *c2 = c1 ? strchr(c1 + 1, ',') : NULL;
		const char *s1 = strchr(src, ','), *s2 = s1 ? strchr(s1 + 1, ',') : NULL;
		if (!c2 || !s2) {
			fputs(line[i], out);
			continue;
		}
		fprintf(out, "%.*s%s", (int)(c2 - line[i]), line[i], s2);
	}
	fclose(in);
	fclose(out);
}

int main(int argc, char **argv)
{
	if (argc < 2) {
		fprintf(stderr, "usage: %s KOGEI\n", argv[0]);
		return 2;
	}
	kogei = argv[1];
	snprintf(layout, sizeof(layout), "%s/fixtures/charts/colorchecker24-frame.json",
	         KG_SOURCE_ROOT);
	{
		kg_image *im = NULL;
		kg_chart_result *r = NULL;
		kg_err err = {{0}};
		kg_chart_layout *l = NULL;
		int ret = kg_image_new(64, 64, 3, &im, &err);
		if (!ret)
			ret = kg_chart_layout_load(layout, &l, &err);
		if (!ret) {
			kg_chart_detect_options o;
			kg_chart_detect_options_default(&o);
			o.tagless = 1;
			ret = kg_chart_detect(l, im, &o, &r, &err);
		}
		kg_chart_result_free(&r);
		kg_chart_layout_free(&l);
		kg_image_free(&im);
		if (ret == KG_ENOTSUP)
			kg_test_skip("built without OpenCV mcc: no tagless detection");
	}
	const char *ref = kg_test_reference_dir();
	snprintf(spectra, sizeof(spectra), "%s/charts/colorchecker24_babelcolor_avg.csv", ref);
	if (!kg_test_file_exists(spectra))
		kg_test_skip("reference ColorChecker spectra are missing");
	cs_scratch_dir("chart-orient");
	snprintf(camera, sizeof(camera), "%s", cs_path("camera.csv"));
	cs_write_camera(camera);

	/* 0.8 x at D01 rising 8 x towards A06 (6.4 x the exposure there): that end clips */
	check_relit("brightened, clipped, light falling 8 x towards D01", "10", "0", 0.8, 8, 1, 0);
	check_relit("brightened, clipped, turned 180", "15", "180", 0.8, 8, 1, 0);
	/* strong falloff, no clipping: 10 x from A06 to D01 */
	check_relit("light falling 10 x towards D01, turned 90", "20", "90", 0.09, 10, 0, 0);
	/* the same as a processed picture: white-balanced and sRGB-encoded */
	check_relit("processed (sRGB curve), light falling 4 x, turned 270", "10", "270", 0.25, 4,
	            0, 1);

	/* no chart: a grey gradient with noise */
	kg_image *im = NULL;
	kg_err err = {{0}};
	if (kg_image_new(1200, 900, 3, &im, &err) == 0) {
		unsigned s = 12345;
		for (long i = 0; i < 1200L * 900 * 3; i++) {
			s = s * 1103515245u + 12345u;
			im->data[i] = (float)(0.2 + 0.3 * (i / 3 % 1200) / 1200.0 +
			                      0.01 * ((s >> 16) & 255) / 255.0);
		}
		char *grey = strdup(cs_path("grey.tif"));
		CHECK(kg_image_write(im, grey, 16, &err) == 0, "%s", err.msg);
		check_refusal_result("no chart", im, 0);
		check_refusal_overlay("no chart", grey, 1200, 900, 0);
		free(grey);
	} else {
		CHECK(0, "%s", err.msg);
	}
	kg_image_free(&im);

	/* a chart of other colours: mcc's box is found, no turn reads as a ColorChecker */
	char *shuf = strdup(cs_path("shuffled.csv")), *img = strdup(cs_path("shuffled.tif"));
	char *truth = strdup(cs_path("shuffled.cgats"));
	write_shuffled(spectra, shuf);
	if (render(shuf, "10", "0", img, truth) == 0) {
		if (kg_image_read(img, &im, &err) == 0)
			check_refusal_result("shuffled colours", im, 1);
		else
			CHECK(0, "%s", err.msg);
		kg_image_free(&im);
		check_refusal_overlay("shuffled colours", img, 1200, 900, 1);
	}
	/* two charts side by side, the shuffled one on the left and a ColorChecker on the
	 * right: whichever box mcc ranks first, the ColorChecker is found, every patch
	 * where its truth puts it */
	render_width = "700";
	char *left = strdup(cs_path("left.tif")), *right = strdup(cs_path("right.tif"));
	char *rtruth = strdup(cs_path("right.cgats"));
	kg_image *a = NULL, *b = NULL, *both = NULL;
	kg_patchset *rt = NULL;
	kg_chart_layout *l2 = NULL;
	kg_chart_result *r2 = NULL;
	if (render(shuf, "10", "0", left, truth) == 0 && render(spectra, "10", "180", right, rtruth) == 0 &&
	    kg_image_read(left, &a, &err) == 0 && kg_image_read(right, &b, &err) == 0 &&
	    kg_patchset_read(rtruth, 0, &rt, &err) == 0 &&
	    kg_image_new(a->width + b->width, a->height, 3, &both, &err) == 0 &&
	    kg_chart_layout_load(layout, &l2, &err) == 0) {
		for (int y = 0; y < both->height; y++) {
			memcpy(both->data + (size_t)y * both->width * 3, a->data + (size_t)y * a->width * 3,
			       (size_t)a->width * 3 * sizeof(float));
			memcpy(both->data + ((size_t)y * both->width + a->width) * 3,
			       b->data + (size_t)y * b->width * 3, (size_t)b->width * 3 * sizeof(float));
		}
		both->bits = a->bits;
		/* the ColorChecker under light falling 8 x across it, its bright end at 1.6 x
		 * the exposure (clipped) */
		for (int y = 0; y < both->height; y++)
			for (int x = a->width; x < both->width; x++)
				for (int c = 0; c < 3; c++) {
					float *v = both->data + ((size_t)y * both->width + x) * 3 + c;
					double t = (double)(x - a->width) / b->width;
					*v = (float)fmin(1.0, *v * 0.2 * pow(8, 1 - t));
				}
		kg_chart_detect_options o;
		kg_chart_detect_options_default(&o);
		o.tagless = 1;
		/* on the full image (mcc), then reduced 2 x 2 (the patch-grid finder first) */
		for (int v = 0; v < 2; v++) {
			kg_chart_result_free(&r2);
			o.tagless_decimate = v ? 2 : 0;
			int ret = kg_chart_detect(l2, both, &o, &r2, &err);
			CHECK(ret == 0, "two charts%s: the ColorChecker not found: %s", v ? " (reduced)" : "",
			      err.msg);
			int right_place = 0;
			for (int i = 0; !ret && i < r2->npatches; i++) {
				const kg_chart_sample *p = &r2->patches[i];
				double cx = 0, cy = 0, t[2];
				for (int q = 0; q < 4; q++) {
					cx += p->quad[q][0] / 4;
					cy += p->quad[q][1] / 4;
				}
				truth_centre(rt, p->id, t);
				right_place += hypot(cx - (t[0] + a->width), cy - t[1]) < 15;
			}
			CHECK(ret || right_place == 24, "two charts: %d of 24 patches where the truth puts them",
			      right_place);
			printf("  two charts%s: %d of 24 patches in place%s\n", v ? ", reduced 2 x 2" : "",
			       right_place,
			       !ret && r2->tagless_grid ? " (the patch-grid finder's)"
			       : !ret && has_warning(r2, "was refused") ? " (mcc's best box refused, another taken)"
			                                               : " (mcc's best box)");
		}
	} else {
		CHECK(0, "two charts: %s", err.msg);
	}
	kg_chart_result_free(&r2);
	kg_chart_layout_free(&l2);
	kg_patchset_free(&rt);
	kg_image_free(&a);
	kg_image_free(&b);
	kg_image_free(&both);
	free(left);
	free(right);
	free(rtruth);
	render_width = "1200";

	/* the tag path: two of the frame's four tags covered, four asked for; each tag
	 * seen is kept with why it did not place the chart */
	char log[8192];
	char *argv2[] = {(char *)kogei, "sim", "chart", "--layout", layout, "--spectra", spectra,
	                 "--camera", camera, "--illuminant", "D65", "--width", "1200", "--height",
	                 "900", "--fill", "0.8",
	                 "--tilt", "10", "--occlude", "tags", "--seed", "4", "-o", img, "--truth",
	                 truth, NULL};
	int rc = cs_run(argv2, log, sizeof(log));
	CHECK(rc == 0, "sim chart --occlude tags: exit %d: %s", rc, log);
	if (rc == 0 && kg_image_read(img, &im, &err) == 0) {
		kg_chart_layout *l = NULL;
		kg_chart_result *r = NULL;
		kg_chart_detect_options o;
		kg_chart_detect_options_default(&o);
		o.min_tags = 4;
		o.keep_refused = 1;
		int ret = kg_chart_layout_load(layout, &l, &err);
		if (!ret)
			ret = kg_chart_detect(l, im, &o, &r, &err);
		if (ret == KG_ENOTSUP) {
			printf("  tags covered: %s (no tag detection in this build)\n", err.msg);
		} else {
			CHECK(ret == KG_ENOENT && r && r->refused, "tags covered: code %d (%s)", ret,
			      err.msg);
			int tagged = 0;
			for (int i = 0; r && i < r->ncandidates; i++)
				tagged += strncmp(r->candidates[i].why, "tag ", 4) == 0;
			CHECK(r && r->ntags > 0 && tagged == r->ntags,
			      "tags covered: %d tags seen, %d kept as candidates", r ? r->ntags : -1,
			      tagged);
			if (r && r->ncandidates > 0)
				printf("  tags covered: %s; %s\n", err.msg, r->candidates[0].why);
			check_refusal_overlay("tags covered", img, 1200, 900, 2);
		}
		kg_chart_result_free(&r);
		kg_chart_layout_free(&l);
	}
	kg_image_free(&im);
	free(shuf);
	free(img);
	free(truth);
	cs_scratch_remove();
	return kg_test_done("chart-orient");
}
