/* The sfr and colour_misregistration records (kg_conformance_edges) on a synthetic
 * chart of known blur and clipping: four tag36h11-like tags (a black ring one cell
 * wide, white inside and around; 80 px square, cell 10 px) turned 5 degrees on an RGB
 * image, each pixel the mean of 4 x 4 samples of the edges blurred by a Gaussian of
 * sigma (the system MTF across a side slanted a: exp(-2 pi^2 sigma^2 f^2) x
 * |sinc(f cos a) sinc(f sin a)|; the 10-90 % rise 2.563 sqrt(sigma^2 + 1/12)):
 *  - sigma 1 (rise 2.67 px, band 0.8 cell = 7.97 px across, needing 4.3): all 16
 *    sides used, MTF50 within 3 % of the analytic value, misregistration (channels
 *    alike: truly 0) under 0.01 px, nothing left out;
 *  - sigma 3 (rise 7.8 px, needing 12.5 px): every side left out as too blurred, the
 *    records "not measured" with the reason;
 *  - sigma 1 with the white around tag 0 brighter in G and clipped there at 0.9375 (the
 *    clip level given as the chart result's; the other tags' white, 0.9, below it):
 *    tag 0's four sides left out as clipped, naming channel G, the 12 others used as
 *    before;
 *  - the whole image clipped at 0.75: every side left out as clipped, not measured.
 * Without the clipping check, tag 0's sides clipped in G read a misregistration of
 * 0.23 px that is not in the scene. */
#include <math.h>
#include <string.h>

#include "kg_pipeline.h"
#include "kg_test.h"
#include "sfr.h"

#define W 400
#define SIDE 80.0
#define DEG 5.0

static const double centre[4][2] = {{100, 100}, {300, 100}, {100, 300}, {300, 300}};

static double phi(double x)
{
	return 0.5 * erfc(-x / M_SQRT2);
}

/* The chart blurred by sigma; within 70 px of tag 0's centre G brighter by 1.2 and
 * clipped at clip_g (0: not); clipped at clip_all everywhere (0: not); the tags'
 * corners into tf. */
static kg_image *chart(double sigma, double clip_g, double clip_all, kg_chart_tag_found *tf)
{
	kg_image *img = NULL;
	kg_err err = {{0}};
	if (kg_image_new(W, W, 3, &img, &err) != 0)
		return NULL;
	double a = DEG * M_PI / 180, c = cos(a), s = sin(a), h = SIDE / 2, hi = h - SIDE / 8;
	const double tc[4][2] = {{-1, 1}, {1, 1}, {1, -1}, {-1, -1}}; /* apriltag order */
	for (int k = 0; k < 4; k++) {
		tf[k].id = k;
		for (int j = 0; j < 4; j++) {
			tf[k].corners[j][0] = centre[k][0] + h * (tc[j][0] * c - tc[j][1] * s);
			tf[k].corners[j][1] = centre[k][1] + h * (tc[j][0] * s + tc[j][1] * c);
		}
	}
	const int S = 4;
	for (int y = 0; y < W; y++)
		for (int x = 0; x < W; x++) {
			int k = (x >= W / 2) + 2 * (y >= W / 2); /* the quadrant's tag */
			double v = 0;
			for (int j = 0; j < S; j++)
				for (int i = 0; i < S; i++) {
					double X = x + (i + 0.5) / S - centre[k][0];
					double Y = y + (j + 0.5) / S - centre[k][1];
					double u = X * c + Y * s, w = -X * s + Y * c;
					double in = (phi((u + h) / sigma) - phi((u - h) / sigma)) *
					            (phi((w + h) / sigma) - phi((w - h) / sigma));
					double inner = (phi((u + hi) / sigma) - phi((u - hi) / sigma)) *
					               (phi((w + hi) / sigma) - phi((w - hi) / sigma));
					v += 0.9 - 0.85 * (in - inner);
				}
			v /= S * S;
			for (int ch = 0; ch < 3; ch++) {
				double o = v;
				if (clip_all > 0 && o > clip_all)
					o = clip_all;
				if (ch == 1 && k == 0 && clip_g > 0 &&
				    hypot(x + 0.5 - centre[0][0], y + 0.5 - centre[0][1]) < 70)
					o = fmin(1.2 * o, clip_g);
				img->data[((size_t)y * W + x) * 3 + ch] = (float)o;
			}
		}
	return img;
}

static double model_f50(double sigma, double a)
{
	double lo = 0, hi = 1;
	for (int i = 0; i < 60; i++) {
		double f = (lo + hi) / 2, sx = f * cos(a), sy = f * sin(a);
		double m = exp(-2 * M_PI * M_PI * sigma * sigma * f * f) *
		           fabs(sin(M_PI * sx) / (M_PI * sx) * (sy > 0 ? sin(M_PI * sy) / (M_PI * sy) : 1));
		if (m > 0.5)
			lo = f;
		else
			hi = f;
	}
	return (lo + hi) / 2;
}

static const json_t *rec(const json_t *list, const char *id)
{
	size_t i;
	const json_t *e;
	json_array_foreach(list, i, e)
		if (!strcmp(json_string_value(json_object_get(e, "id")), id))
			return e;
	return NULL;
}

/* Run kg_conformance_edges; returns the list (json_decref it). */
static json_t *run(double sigma, double clip_g, double clip_all, const double clip[3])
{
	kg_chart_layout l;
	memset(&l, 0, sizeof l);
	snprintf(l.name, sizeof l.name, "four-tags");
	snprintf(l.family, sizeof l.family, "tag36h11");
	kg_chart_tag tags[4];
	memset(tags, 0, sizeof tags);
	for (int k = 0; k < 4; k++) {
		tags[k].id = k;
		tags[k].size_mm = 20;
	}
	l.ntags = 4;
	l.tags = tags;
	kg_chart_tag_found tf[4];
	memset(tf, 0, sizeof tf);
	kg_image *img = chart(sigma, clip_g, clip_all, tf);
	CHECK(img != NULL, "image");
	kg_chart_result r;
	memset(&r, 0, sizeof r);
	r.ntags = 4;
	r.tags = tf;
	memcpy(r.clip, clip, sizeof r.clip);
	json_t *patches = json_array();
	json_t *list = kg_conformance(patches, NAN);
	json_decref(patches);
	if (img && list)
		kg_conformance_edges(list, &l, &r, img, 1);
	kg_image_free(&img);
	return list;
}

/* The left_out entries whose why starts with prefix; every entry has an id and why. */
static int count_left(const json_t *r, const char *prefix, const char *also)
{
	const json_t *lo = json_object_get(r, "left_out");
	int n = 0;
	size_t i;
	const json_t *e;
	CHECK(json_is_array(lo), "no left_out");
	json_array_foreach(lo, i, e) {
		const char *id = json_string_value(json_object_get(e, "id"));
		const char *why = json_string_value(json_object_get(e, "why"));
		CHECK(id && why && why[0], "left_out entry without id or why");
		if (why && !strncmp(why, prefix, strlen(prefix)) && (!also || strstr(why, also)))
			n++;
	}
	return n;
}

int main(void)
{
	const double noclip[3] = {1, 1, 1};
	/* sigma 1: every side used, MTF50 against the analytic value */
	json_t *list = run(1.0, 0, 0, noclip);
	const json_t *s = list ? rec(list, "sfr") : NULL;
	const json_t *m = list ? rec(list, "colour_misregistration") : NULL;
	CHECK(s && json_is_true(json_object_get(s, "measured")), "sigma 1: sfr not measured: %s",
	      s ? json_string_value(json_object_get(s, "note")) : "-");
	if (s) {
		double f50 = model_f50(1.0, DEG * M_PI / 180);
		double got = json_number_value(json_object_get(s, "mtf50"));
		fprintf(stderr, "sigma 1: %zu sides used, MTF50 %.4f (analytic %.4f), misregistration "
		        "%.4f px\n", json_array_size(json_object_get(s, "used")), got, f50,
		        json_number_value(json_object_get(m, "value")));
		CHECK(json_array_size(json_object_get(s, "used")) == 16, "sigma 1: %zu sides used",
		      json_array_size(json_object_get(s, "used")));
		CHECK_NEAR(got, f50, 0.03 * f50, "sigma 1 MTF50");
		CHECK(json_array_size(json_object_get(s, "left_out")) == 0, "sigma 1: sides left out");
		CHECK(json_is_true(json_object_get(m, "measured")) &&
		          json_number_value(json_object_get(m, "value")) < 0.01,
		      "sigma 1: misregistration");
	}
	json_decref(list);

	/* sigma 3: too blurred for the tag's cells */
	list = run(3.0, 0, 0, noclip);
	s = list ? rec(list, "sfr") : NULL;
	m = list ? rec(list, "colour_misregistration") : NULL;
	CHECK(s && !json_is_true(json_object_get(s, "measured")) &&
	          json_is_null(json_object_get(s, "value")), "sigma 3: sfr measured");
	CHECK(m && !json_is_true(json_object_get(m, "measured")), "sigma 3: misregistration measured");
	if (s) {
		const char *note = json_string_value(json_object_get(s, "note"));
		fprintf(stderr, "sigma 3: %s\n", note);
		CHECK(count_left(s, "too blurred", NULL) == 16, "sigma 3: %d of 16 too blurred",
		      count_left(s, "too blurred", NULL));
		CHECK(strstr(note, "not measured") == note && strstr(note, "at least 3"), "note %s",
		      note);
	}
	json_decref(list);

	/* sigma 1, the white around tag 0 brighter in G (1.08) and clipped at 0.9375 (a
	 * float exactly), the others' white (0.9) below that */
	const double clip_g[3] = {1, 0.9375, 1};
	list = run(1.0, 0.9375, 0, clip_g);
	s = list ? rec(list, "sfr") : NULL;
	m = list ? rec(list, "colour_misregistration") : NULL;
	CHECK(s && json_is_true(json_object_get(s, "measured")), "tag 0 clipped: not measured");
	if (s) {
		int n = count_left(s, "clipped: channel G", NULL);
		CHECK(n == 4 && json_array_size(json_object_get(s, "left_out")) == 4,
		      "tag 0 clipped: %d sides left out as clipped in G", n);
		const json_t *lo = json_object_get(s, "left_out");
		for (size_t i = 0; i < json_array_size(lo); i++) {
			const char *id = json_string_value(json_object_get(json_array_get(lo, i), "id"));
			CHECK(id && !strncmp(id, "tag0.", 5), "left out %s, expected tag 0's sides", id);
		}
		CHECK(json_array_size(json_object_get(s, "used")) == 12, "tag 0 clipped: %zu used",
		      json_array_size(json_object_get(s, "used")));
		double f50 = model_f50(1.0, DEG * M_PI / 180);
		CHECK_NEAR(json_number_value(json_object_get(s, "mtf50")), f50, 0.03 * f50,
		           "tag 0 clipped: MTF50 of the others");
		CHECK(json_equal(json_object_get(m, "left_out"), lo), "misregistration's left_out");
		CHECK(json_number_value(json_object_get(m, "value")) < 0.01,
		      "tag 0 clipped: misregistration %g",
		      json_number_value(json_object_get(m, "value")));
		fprintf(stderr, "tag 0 clipped in G: %s\n",
		        json_string_value(json_object_get(json_array_get(lo, 0), "why")));
	}
	json_decref(list);

	/* all clipped at 0.75 */
	const double clip8[3] = {0.75, 0.75, 0.75};
	list = run(1.0, 0, 0.75, clip8);
	s = list ? rec(list, "sfr") : NULL;
	m = list ? rec(list, "colour_misregistration") : NULL;
	CHECK(s && !json_is_true(json_object_get(s, "measured")), "all clipped: sfr measured");
	CHECK(m && !json_is_true(json_object_get(m, "measured")), "all clipped: misregistration");
	if (s) {
		CHECK(count_left(s, "clipped", NULL) == 16, "all clipped: %d of 16",
		      count_left(s, "clipped", NULL));
		CHECK(strstr(json_string_value(json_object_get(s, "note")), "16 clipped") != NULL,
		      "note %s", json_string_value(json_object_get(s, "note")));
	}
	json_decref(list);
	return kg_test_done("conformance-edges");
}
