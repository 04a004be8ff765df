/* Slanted-edge SFR (calib/sfr.c) on edges simulated here: a step at a known slant
 * blurred by a Gaussian of known sigma, each pixel the area integral (16 x 16
 * sub-samples) of the blurred step:
 *  - MTF50 and MTF10 within 2 % of the system's analytic values (Gaussian times the
 *    square pixel's aperture projected across the edge, sinc(f cos a) sinc(f sin a)),
 *    and within 3 % of the Gaussian's own f50 = sqrt(ln 2 / 2) / (pi sigma) and f10 =
 *    sqrt(ln 10 / 2) / (pi sigma) where the pixel's share is small (sigma 2);
 *    vertical and horizontal edges, both polarities, with and without noise;
 *  - per-channel sub-pixel shifts recovered within 0.05 px (misregistration);
 *  - sampling efficiency min(MTF10 / 0.5, 1);
 *  - refusals: a flat region, pure noise, an edge square to the axis, an edge too
 *    close to the region's side, a region outside the image;
 *  - the blur against the band: a sigma 2 edge refused as too blurred in a band of
 *    6 px (under 1.6 times its 5.18 px rise), measured in one of 11 px (MTF50 within
 *    2 %, rise within 5 % of 2.563 sqrt(sigma^2 + 1/12)); the band's peak value, the
 *    clip level of an edge clipped at 0.6;
 *  - the chart edge finder: the sides of a tag slanted 5 degrees are offered with
 *    their slant, and measure to the blur they were drawn with (MTF50 within 2 %);
 *    tags square to the sensor or slanted 20 degrees give none; a layout without
 *    tags is refused. */
#include <stdlib.h>
#include <string.h>

#include "kg_test.h"
#include "sfr.h"

static unsigned long long rng_state = 12345;
static double urand(void)
{
	rng_state = rng_state * 6364136223846793005ULL + 1442695040888963407ULL;
	return ((rng_state >> 11) + 0.5) / 9007199254740992.0;
}
static double nrand(void)
{
	return sqrt(-2 * log(urand())) * cos(2 * M_PI * urand());
}

static double phi(double x)
{
	return 0.5 * erfc(-x / M_SQRT2);
}

/* Edge through (cx, cy) at angle deg from the vertical (horizontal = 1: from the
 * horizontal); channel c's edge moved by shift[c] px along the normal; dark lo,
 * bright hi on the +normal side (swapped when flip). */
static kg_image *edge_image(int W, int H, int channels, double deg, int horizontal,
                            double sigma, const double *shift, double lo, double hi,
                            double noise)
{
	kg_image *img = NULL;
	kg_err err = {{0}};
	if (kg_image_new(W, H, channels, &img, &err) != 0)
		return NULL;
	double a = deg * M_PI / 180, cx = W / 2.0, cy = H / 2.0;
	/* normal: vertical edge (cos a, -sin a); horizontal edge (sin a, cos a) */
	double nx = horizontal ? sin(a) : cos(a), ny = horizontal ? cos(a) : -sin(a);
	const int S = 16;
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++)
			for (int c = 0; c < channels; c++) {
				double s = 0;
				for (int j = 0; j < S; j++)
					for (int i = 0; i < S; i++) {
						double X = x + (i + 0.5) / S, Y = y + (j + 0.5) / S;
						double dd = (X - cx) * nx + (Y - cy) * ny - shift[c];
						s += phi(dd / sigma);
					}
				double val = lo + (hi - lo) * s / (S * S);
				if (noise > 0)
					val += noise * nrand();
				img->data[((size_t)y * W + x) * channels + c] = (float)val;
			}
	return img;
}

/* The system's MTF across an edge at angle a: Gaussian x pixel aperture. */
static double mtf_model(double f, double sigma, double a)
{
	double g = exp(-2 * M_PI * M_PI * sigma * sigma * f * f);
	double sx = f * cos(a), sy = f * sin(a);
	double s1 = sx == 0 ? 1 : sin(M_PI * sx) / (M_PI * sx);
	double s2 = sy == 0 ? 1 : sin(M_PI * sy) / (M_PI * sy);
	return g * fabs(s1 * s2);
}

static double model_crossing(double level, double sigma, double a)
{
	double lo = 0, hi = 2;
	for (int i = 0; i < 60; i++) {
		double mid = (lo + hi) / 2;
		if (mtf_model(mid, sigma, a) > level)
			lo = mid;
		else
			hi = mid;
	}
	return (lo + hi) / 2;
}

static void check_blur(double sigma, double deg, int horizontal, int flip, double noise,
                       double tol)
{
	double shift[3] = {0, 0, 0};
	kg_image *img = edge_image(96, 96, 1, deg, horizontal, sigma, shift, flip ? 0.8 : 0.1,
	                           flip ? 0.1 : 0.8, noise);
	CHECK(img != NULL, "image");
	if (!img)
		return;
	kg_sfr_roi roi = {8, 8, 80, 80, 0, {0, 0}, {0, 0}, 0};
	kg_sfr_result r;
	kg_err err = {{0}};
	int rc = kg_sfr_measure(img, &roi, &r, &err);
	CHECK(rc == 0, "sigma %g %g deg: %s", sigma, deg, err.msg);
	if (rc == 0) {
		double a = deg * M_PI / 180;
		double f50 = model_crossing(0.5, sigma, a), f10 = model_crossing(0.1, sigma, a);
		char what[128];
		snprintf(what, sizeof what, "MTF50 sigma %g %g deg %s noise %g", sigma, deg,
		         horizontal ? "horizontal" : "vertical", noise);
		CHECK_NEAR(r.mtf50, f50, tol * f50, what);
		snprintf(what, sizeof what, "MTF10 sigma %g %g deg %s noise %g", sigma, deg,
		         horizontal ? "horizontal" : "vertical", noise);
		CHECK_NEAR(r.mtf10, f10, tol * f10, what);
		CHECK(r.vertical == !horizontal, "orientation %d", r.vertical);
		CHECK_NEAR(fabs(r.angle_deg), deg, 0.1, "slant");
		CHECK_NEAR(r.efficiency, fmin(r.mtf10 / 0.5, 1), 1e-12, "efficiency");
		CHECK(r.misregistration == 0, "one channel: %g", r.misregistration);
		fprintf(stderr, "sigma %.2f %4.1f deg %s flip %d noise %.3f: MTF50 %.4f (model %.4f, "
		        "Gaussian %.4f) MTF10 %.4f (model %.4f, Gaussian %.4f) efficiency %.3f\n",
		        sigma, deg, horizontal ? "h" : "v", flip, noise, r.mtf50, f50,
		        sqrt(log(2) / 2) / (M_PI * sigma), r.mtf10, f10,
		        sqrt(log(10) / 2) / (M_PI * sigma), r.efficiency);
		if (sigma >= 2) {
			CHECK_NEAR(r.mtf50, sqrt(log(2) / 2) / (M_PI * sigma),
			           0.03 * sqrt(log(2) / 2) / (M_PI * sigma), "MTF50 vs Gaussian f50");
			CHECK_NEAR(r.mtf10, sqrt(log(10) / 2) / (M_PI * sigma),
			           0.03 * sqrt(log(10) / 2) / (M_PI * sigma), "MTF10 vs Gaussian f10");
		}
	}
	kg_image_free(&img);
}

static void check_shift(double dr, double db, double noise, int horizontal)
{
	double shift[3] = {dr, 0, db};
	kg_image *img = edge_image(96, 96, 3, 5, horizontal, 1.0, shift, 0.1, 0.7, noise);
	CHECK(img != NULL, "image");
	if (!img)
		return;
	kg_sfr_roi roi = {8, 8, 80, 80, 0, {0, 0}, {0, 0}, 0};
	kg_sfr_result r;
	kg_err err = {{0}};
	int rc = kg_sfr_measure(img, &roi, &r, &err);
	CHECK(rc == 0, "shift: %s", err.msg);
	if (rc == 0) {
		double got_r = r.ch[0].position - r.ch[1].position;
		double got_b = r.ch[2].position - r.ch[1].position;
		double want = fmax(fabs(dr - db), fmax(fabs(dr), fabs(db)));
		fprintf(stderr, "shift R %+.3f B %+.3f noise %.3f %s: measured R %+.4f B %+.4f "
		        "misregistration %.4f (true %.4f)\n", dr, db, noise, horizontal ? "h" : "v",
		        got_r, got_b, r.misregistration, want);
		CHECK_NEAR(got_r, dr, 0.05, "R shift");
		CHECK_NEAR(got_b, db, 0.05, "B shift");
		CHECK_NEAR(r.misregistration, want, 0.05, "misregistration");
		CHECK(r.channels == 3, "channels");
	}
	kg_image_free(&img);
}

static void check_refused(kg_image *img, kg_sfr_roi roi, const char *expect, const char *what)
{
	kg_sfr_result r;
	kg_err err = {{0}};
	int rc = kg_sfr_measure(img, &roi, &r, &err);
	CHECK(rc == KG_EINVAL, "%s: accepted (MTF50 %g)", what, r.mtf50);
	CHECK(strstr(err.msg, expect) != NULL, "%s: message \"%s\" lacks \"%s\"", what, err.msg,
	      expect);
	if (rc == KG_EINVAL)
		fprintf(stderr, "refused (%s): %s\n", what, err.msg);
}

/* The blur against the band and the band's peak, with known truth: a Gaussian edge of
 * sigma 2 (10-90 % rise 2.563 sqrt(sigma^2 + 1/12) = 5.18 px with the pixel's box)
 * in a band of 6 px either side (under 1.6 rises = 8.3 px) is refused as too blurred,
 * with its rise measured; in a band of 11 px it is measured, its MTF50 within 2 % of
 * the analytic one. An edge clipped at 0.6 reports a peak of 0.6 (a value the caller
 * compares with the clip level), the unclipped one its bright level 0.8. */
static void check_band(void)
{
	double zero[3] = {0, 0, 0};
	double sigma = 2.0, deg = 5, rise = 2.563 * sqrt(sigma * sigma + 1.0 / 12);
	kg_image *img = edge_image(96, 96, 1, deg, 0, sigma, zero, 0.1, 0.8, 0);
	CHECK(img != NULL, "image");
	if (!img)
		return;
	/* the edge through the centre at deg from the vertical: x = 48 + (y - 48) tan a */
	double ta = tan(deg * M_PI / 180);
	kg_sfr_roi roi = {0, 8, 96, 80, 1, {48 + (8 - 48) * ta, 8}, {48 + (88 - 48) * ta, 88}, 6};
	kg_sfr_result r;
	kg_err err = {{0}};
	int rc = kg_sfr_measure(img, &roi, &r, &err);
	CHECK(rc == KG_EINVAL && r.too_blurred, "sigma 2 in a band of 6 px: rc %d too_blurred "
	      "%d (%s)", rc, r.too_blurred, err.msg);
	CHECK(strstr(err.msg, "too blurred") != NULL, "message: %s", err.msg);
	CHECK_NEAR(r.band, 6 * cos(deg * M_PI / 180), 0.3, "band");
	fprintf(stderr, "band 6: refused: %s (known rise %.2f)\n", err.msg, rise);
	/* measured inside a band too narrow the rise reads low, never high */
	CHECK(r.rise > 0.6 * rise && r.rise < 1.02 * rise, "rise %g, known %g", r.rise, rise);
	roi.half_width = 11;
	rc = kg_sfr_measure(img, &roi, &r, &err);
	CHECK(rc == 0, "sigma 2 in a band of 11 px: %s", err.msg);
	if (rc == 0) {
		double f50 = model_crossing(0.5, sigma, deg * M_PI / 180);
		fprintf(stderr, "band 11: rise %.3f (known %.3f) MTF50 %.4f (model %.4f) peak %.4f\n",
		        r.rise, rise, r.mtf50, f50, r.peak[0]);
		CHECK(!r.too_blurred && r.band >= KG_SFR_BAND_RISE * r.rise, "band %g rise %g",
		      r.band, r.rise);
		CHECK_NEAR(r.rise, rise, 0.05 * rise, "rise");
		CHECK_NEAR(r.mtf50, f50, 0.02 * f50, "MTF50 in the band");
		CHECK_NEAR(r.peak[0], 0.8, 0.01, "peak of the unclipped edge");
	}
	/* the same edge clipped at 0.6 */
	for (int i = 0; i < 96 * 96; i++)
		img->data[i] = fminf(img->data[i], 0.6f);
	rc = kg_sfr_measure(img, &roi, &r, &err);
	CHECK(rc == 0, "clipped edge: %s", err.msg);
	CHECK(r.peak[0] == 0.6f, "peak of the clipped edge %.9g, expected 0.6", r.peak[0]);
	kg_image_free(&img);
}

/* A tag's black border ring (outer side `side` px, one cell of side / 8 wide), centred,
 * rotated deg, on white, blurred. */
static kg_image *tag_image(int W, int H, double side, double deg, double sigma,
                           double corners[4][2])
{
	kg_image *img = NULL;
	kg_err err = {{0}};
	if (kg_image_new(W, H, 1, &img, &err) != 0)
		return NULL;
	double a = deg * M_PI / 180, cx = W / 2.0, cy = H / 2.0, h = side / 2;
	double c = cos(a), s = sin(a);
	/* apriltag order: (-1,+1), (+1,+1), (+1,-1), (-1,-1) in tag coordinates, y down */
	const double tc[4][2] = {{-1, 1}, {1, 1}, {1, -1}, {-1, -1}};
	for (int k = 0; k < 4; k++) {
		corners[k][0] = cx + h * (tc[k][0] * c - tc[k][1] * s);
		corners[k][1] = cy + h * (tc[k][0] * s + tc[k][1] * c);
	}
	const int S = 8;
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			double v = 0;
			for (int j = 0; j < S; j++)
				for (int i = 0; i < S; i++) {
					double X = x + (i + 0.5) / S - cx, Y = y + (j + 0.5) / S - cy;
					double u = X * c + Y * s, w = -X * s + Y * c;
					/* inside: product of 1-D blurred boxes (separable in the tag frame) */
					double in = (phi((u + h) / sigma) - phi((u - h) / sigma)) *
					            (phi((w + h) / sigma) - phi((w - h) / sigma));
					/* a white inside one cell (side / 8) in: the border is a black
					 * ring, as tag36h11's, and its inner edge must not be measured */
					double hi = h - side / 8;
					double inner = (phi((u + hi) / sigma) - phi((u - hi) / sigma)) *
					               (phi((w + hi) / sigma) - phi((w - hi) / sigma));
					v += 0.9 - 0.85 * (in - inner);
				}
			img->data[(size_t)y * W + x] = (float)(v / (S * S));
		}
	return img;
}

static void check_finder(void)
{
	kg_chart_layout l;
	memset(&l, 0, sizeof l);
	snprintf(l.name, sizeof l.name, "test");
	snprintf(l.family, sizeof l.family, "tag36h11");
	kg_chart_tag tag;
	memset(&tag, 0, sizeof tag);
	tag.id = 7;
	tag.size_mm = 20;
	l.ntags = 1;
	l.tags = &tag;
	const double degs[3] = {5, 0, 20};
	for (int i = 0; i < 3; i++) {
		kg_chart_tag_found tf;
		memset(&tf, 0, sizeof tf);
		tf.id = 7;
		kg_image *img = tag_image(200, 200, 120, degs[i], 1.5, tf.corners);
		CHECK(img != NULL, "tag image");
		if (!img)
			return;
		kg_chart_result r;
		memset(&r, 0, sizeof r);
		r.ntags = 1;
		r.tags = &tf;
		kg_sfr_edge *e = NULL;
		int n = -1;
		kg_err err = {{0}};
		int rc = kg_sfr_find_edges(&l, &r, img, 0, &e, &n, &err);
		CHECK(rc == 0, "find edges: %s", err.msg);
		if (degs[i] == 5) {
			CHECK(n == 4, "5 degrees: %d edges", n);
			double f50 = model_crossing(0.5, 1.5, 5 * M_PI / 180);
			double f10 = model_crossing(0.1, 1.5, 5 * M_PI / 180);
			for (int k = 0; k < n; k++) {
				CHECK_NEAR(e[k].angle_deg, 5, 0.01, "edge slant");
				CHECK(e[k].length_px >= 100, "length %g", e[k].length_px);
				kg_sfr_result sr;
				rc = kg_sfr_measure(img, &e[k].roi, &sr, &err);
				CHECK(rc == 0, "tag side %d: %s", e[k].side, err.msg);
				if (rc == 0) {
					fprintf(stderr, "tag side %d: roi %d,%d,%d,%d slant %.2f MTF50 %.4f "
					        "(model %.4f) MTF10 %.4f (model %.4f)\n", e[k].side, e[k].roi.x,
					        e[k].roi.y, e[k].roi.w, e[k].roi.h, e[k].angle_deg, sr.mtf50, f50,
					        sr.mtf10, f10);
					CHECK_NEAR(sr.mtf50, f50, 0.02 * f50, "tag side MTF50");
					CHECK_NEAR(sr.mtf10, f10, 0.02 * f10, "tag side MTF10");
				}
			}
		} else {
			CHECK(n == 0, "%g degrees: %d edges offered", degs[i], n);
		}
		free(e);
		kg_image_free(&img);
	}
	/* a layout without tags */
	l.ntags = 0;
	kg_chart_result r;
	memset(&r, 0, sizeof r);
	kg_sfr_edge *e = NULL;
	int n = 0;
	kg_err err = {{0}};
	kg_image *img = NULL;
	kg_image_new(16, 16, 1, &img, &err);
	CHECK(kg_sfr_find_edges(&l, &r, img, 0, &e, &n, &err) == KG_EINVAL, "no tags accepted");
	kg_image_free(&img);
}

int main(void)
{
	/* MTF50 / MTF10 against the analytic values */
	check_blur(0.8, 5, 0, 0, 0, 0.02);
	check_blur(1.2, 5, 0, 1, 0, 0.02);
	check_blur(2.0, 5, 0, 0, 0, 0.02);
	check_blur(1.2, 3, 1, 0, 0, 0.02);
	check_blur(2.0, 7, 1, 1, 0, 0.02);
	check_blur(1.2, 5, 0, 0, 0.005, 0.03);
	check_blur(2.0, 5, 1, 0, 0.005, 0.03);

	/* a sharp edge: MTF10 beyond Nyquist, the efficiency capped at 1 */
	{
		double zero[3] = {0, 0, 0};
		kg_image *img = edge_image(96, 96, 1, 5, 0, 0.3, zero, 0.1, 0.8, 0);
		kg_sfr_roi roi = {8, 8, 80, 80, 0, {0, 0}, {0, 0}, 0};
		kg_sfr_result r;
		kg_err err = {{0}};
		int rc = kg_sfr_measure(img, &roi, &r, &err);
		CHECK(rc == 0, "sharp edge: %s", err.msg);
		double f10 = model_crossing(0.1, 0.3, 5 * M_PI / 180);
		fprintf(stderr, "sigma 0.30: MTF10 %.4f (model %.4f) efficiency %.3f\n", r.mtf10,
		        f10, r.efficiency);
		CHECK(f10 > 0.5, "model f10 %g", f10);
		CHECK_NEAR(r.mtf10, f10, 0.03 * f10, "sharp MTF10");
		CHECK(r.efficiency == 1.0, "efficiency %g, expected capped at 1", r.efficiency);
		kg_image_free(&img);
	}

	/* channel shifts */
	check_shift(0.3, -0.2, 0, 0);
	check_shift(-0.15, 0.45, 0, 1);
	check_shift(0.25, 0.1, 0.005, 0);
	check_shift(-0.1, 0.2, 0.01, 1);

	/* refusals */
	kg_err err = {{0}};
	kg_image *flat = NULL;
	kg_image_new(64, 64, 1, &flat, &err);
	for (int i = 0; i < 64 * 64; i++)
		flat->data[i] = 0.5f;
	kg_sfr_roi roi = {4, 4, 56, 56, 0, {0, 0}, {0, 0}, 0};
	check_refused(flat, roi, "no ", "flat region");
	for (int i = 0; i < 64 * 64; i++)
		flat->data[i] = (float)(0.5 + 0.01 * nrand());
	check_refused(flat, roi, "no ", "noise only");
	kg_sfr_roi outside = {40, 40, 40, 40, 0, {0, 0}, {0, 0}, 0};
	check_refused(flat, outside, "inside the", "region outside the image");
	kg_image_free(&flat);
	double zero[3] = {0, 0, 0};
	kg_image *square = edge_image(64, 64, 1, 0, 0, 1.0, zero, 0.1, 0.8, 0);
	check_refused(square, roi, "slanted", "edge square to the axis");
	kg_image_free(&square);
	kg_image *side = edge_image(64, 64, 1, 5, 0, 1.0, zero, 0.1, 0.8, 0);
	kg_sfr_roi near = {30, 4, 30, 56, 0, {0, 0}, {0, 0}, 0};
	check_refused(side, near, "side", "edge at the region's side");
	kg_image_free(&side);

	check_band();
	check_finder();
	return kg_test_done("calib-sfr");
}
