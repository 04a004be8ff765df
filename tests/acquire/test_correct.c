/* Corrections and statistics against direct computations:
 * - dark and flat on a synthetic Bayer scene with vignetting, per-colour gains and a
 *   dark offset: the corrected image must be scene x gain x (mean vignetting of that
 *   colour), the variance divided by the squared normalised flat, unusable flat
 *   samples NaN and counted;
 * - the flat low-passed (kg_flat_smooth): a textured, noisy flat corrects a uniform
 *   target to a lower pixel spread than the raw flat; a clipped and a too uneven flat
 *   are refused naming it and the value;
 * - the illuminance non-uniformity of a flat (kg_flat_nonuniformity): a Bayer flat
 *   with per-colour gains and a 20 % ramp across the frame departs from its mean by
 *   the ramp's value at the outer blocks' centres (8.9 %), a flat frame by about 0,
 *   a quadratic falloff by its analytic block extreme;
 * - percentiles and the under-exposed fraction against a sorted copy;
 * - the bright level against a brute-force same-colour box mean and a sorted copy;
 * - demosaicing (when built with OpenCV): uniform colours and a ramp come back for each
 *   of the four CFA patterns (a swapped pattern fails). */
#include <string.h>

#include "kg_acquire.h"
#include "kg_test.h"

static int cmp_float(const void *a, const void *b)
{
	float x = *(const float *)a, y = *(const float *)b;
	return x < y ? -1 : x > y;
}

/* numpy's default percentile (linear between order statistics) on a sorted array */
static double ref_percentile(const float *sorted, size_t n, double p)
{
	double pos = p / 100 * (double)(n - 1);
	size_t k = (size_t)floor(pos);
	if (k >= n - 1)
		return sorted[n - 1];
	return sorted[k] + (pos - (double)k) * ((double)sorted[k + 1] - sorted[k]);
}

static int colour_of(const char *cfa, int x, int y)
{
	char l = cfa[(y & 1) * 2 + (x & 1)];
	return l == 'R' ? 0 : l == 'G' ? 1 : 2;
}

static void test_dark_flat(void)
{
	const int W = 64, H = 48;
	const char *cfa = "GRBG";
	const double gain[3] = {0.8, 1.0, 0.6};
	kg_image *scene, *obj, *var, *flat, *dark;
	kg_err err = {{0}};
	kg_image_new(W, H, 1, &scene, &err);
	kg_image_new(W, H, 1, &obj, &err);
	kg_image_new(W, H, 1, &var, &err);
	kg_image_new(W, H, 1, &flat, &err);
	kg_image_new(W, H, 1, &dark, &err);
	kg_image_set_cfa(obj, cfa, 2, 2, &err);
	kg_image_set_cfa(var, cfa, 2, 2, &err);
	kg_image_set_cfa(flat, cfa, 2, 2, &err);
	kg_rng rng;
	kg_rng_seed(&rng, 7);
	double fsum[4] = {0}, fn[4] = {0};
	double *vign = malloc(sizeof(double) * (size_t)(W * H));
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			int i = y * W + x, c = colour_of(cfa, x, y);
			double dx = (x - W / 2.0) / W, dy = (y - H / 2.0) / H;
			double F = 1 - 0.6 * (dx * dx + dy * dy);
			double D = 0.01 + 0.02 * kg_rng_uniform(&rng);
			vign[i] = F;
			scene->data[i] = (float)(0.1 + 0.5 * kg_rng_uniform(&rng));
			obj->data[i] = (float)(scene->data[i] * F * gain[c] + D);
			var->data[i] = (float)(1e-4 * F);
			dark->data[i] = (float)D;
			flat->data[i] = (float)(0.7 * F * gain[c]); /* a flat, dark already taken off */
		}
	/* two dead flat samples (left out of the low-passed flat: their pixels are corrected
	 * by their neighbours' light) and an unlit strip x < 8 (not valid: NaN) */
	flat->data[5 * W + 7 + 10] = 0;
	flat->data[9 * W + 11 + 10] = NAN;
	for (int y = 0; y < H; y++)
		for (int x = 0; x < 8; x++)
			flat->data[y * W + x] = 0;
	CHECK(kg_correct_dark(obj, dark, &err) == 0, "dark: %s", err.msg);
	float *obj0 = malloc(sizeof(float) * (size_t)(W * H));
	memcpy(obj0, obj->data, sizeof(float) * (size_t)(W * H));
	/* what kg_correct_flat must divide by: the flat low-passed, over its colour's mean
	 * of the valid samples */
	kg_flat_smooth sm;
	CHECK(kg_flat_smooth_init(&sm, W, H, 1, cfa, 2, 2, &err) == 0, "smooth: %s", err.msg);
	kg_flat_smooth_add(&sm, flat->data, 0, H);
	kg_flat_smooth_finish(&sm);
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			float v = flat->data[y * W + x];
			if (isfinite(v) && v > 0) {
				fsum[colour_of(cfa, x, y)] += v;
				fn[colour_of(cfa, x, y)]++;
			}
		}
	long invalid = -1;
	CHECK(kg_correct_flat(obj, var, flat, &invalid, &err) == 0, "flat: %s", err.msg);
	double worst = 0, worst_v = 0, worst_truth = 0;
	long nan = 0;
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			int i = y * W + x, c = colour_of(cfa, x, y);
			double sf = kg_flat_smooth_at(&sm, 0, x, y);
			if (x < 8) {
				CHECK(isnan(obj->data[i]) && isnan(var->data[i]), "unlit flat at %d,%d: %g",
				      x, y, obj->data[i]);
				nan++;
				continue;
			}
			if (isnan(obj->data[i])) { /* within half a block of the unlit strip */
				CHECK(x < 8 + sm.block && !isfinite(sf), "NaN at %d,%d", x, y);
				nan++;
				continue;
			}
			double mf = fsum[c] / fn[c];
			double g = sf / mf;
			double want = obj0[i] / g;
			double want_v = 1e-4 * vign[i] / (g * g);
			worst = fmax(worst, fabs(obj->data[i] - want) / want);
			worst_v = fmax(worst_v, fabs(var->data[i] - want_v) / want_v);
			/* against the truth: the scene times the colour's gain and mean light */
			double truth = scene->data[i] * gain[c] * mf / (0.7 * gain[c]);
			if (x >= 8 + sm.block)
				worst_truth = fmax(worst_truth, fabs(obj->data[i] - truth) / truth);
		}
	CHECK(invalid == nan, "invalid flat samples %ld, NaN %ld", invalid, nan);
	CHECK(worst < 2e-6, "flat-corrected image off by %.3g (relative)", worst);
	CHECK(worst_v < 2e-6, "flat-corrected variance off by %.3g (relative)", worst_v);
	/* the low-pass follows the vignetting (0.7..1) within a small bias */
	CHECK(worst_truth < 0.005, "flat-corrected image off the truth by %.3g", worst_truth);
	printf("dark+flat: largest relative error %.2g (image), %.2g (variance); against the "
	       "truth %.2g (the low-pass's bias); %ld invalid\n", worst, worst_v, worst_truth,
	       invalid);
	kg_flat_smooth_free(&sm);
	free(obj0);

	/* size and pattern mismatches */
	kg_image *small;
	kg_image_new(W - 2, H, 1, &small, &err);
	CHECK(kg_correct_dark(obj, small, &err) == KG_EINVAL, "a smaller dark was accepted");
	CHECK(strstr(err.msg, "the dark is 62x48"), "message '%s'", err.msg);
	kg_image_set_cfa(dark, "RGGB", 2, 2, &err);
	CHECK(kg_correct_dark(obj, dark, &err) == KG_EINVAL, "another CFA was accepted");
	kg_image_free(&small);
	kg_image_free(&scene);
	kg_image_free(&obj);
	kg_image_free(&var);
	kg_image_free(&flat);
	kg_image_free(&dark);
	free(vign);
}

/* A flat of a textured board (a fine random texture of 3 % and the flat's own noise of
 * 1 %, per pixel) under a smooth fall-off to 0.55 at the corners, and a uniform target
 * (reflectance 0.5, noise 0.2 %) under the same light: divided by the low-passed flat
 * the target comes out flatter than divided by the raw one (whose texture and noise go
 * straight into every pixel), close to its own noise. Then the refusals: a clipped flat
 * (its clipped fraction above KG_FLAT_MAX_CLIPPED) and one more uneven than
 * KG_FLAT_MIN_RATIO, each naming the flat and the measured value. */
static void test_flat_lowpass(void)
{
	const int W = 240, H = 160;
	kg_image *flat, *obj, *raw;
	kg_err err = {{0}};
	kg_image_new(W, H, 1, &flat, &err);
	kg_image_new(W, H, 1, &obj, &err);
	kg_image_new(W, H, 1, &raw, &err);
	kg_rng rng;
	kg_rng_seed(&rng, 11);
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			int i = y * W + x;
			double dx = (x - W / 2.0) / W, dy = (y - H / 2.0) / H;
			double L = 1 - 0.9 * (dx * dx + dy * dy);
			double texture = 1 + 0.03 * (2 * kg_rng_uniform(&rng) - 1) * 1.7320508;
			flat->data[i] = (float)(0.6 * L * texture + 0.006 * kg_rng_normal(&rng));
			obj->data[i] = (float)(0.5 * L + 0.001 * kg_rng_normal(&rng));
			raw->data[i] = obj->data[i];
		}
	long invalid = -1;
	CHECK(kg_correct_flat(obj, NULL, flat, &invalid, &err) == 0, "flat: %s", err.msg);
	CHECK(invalid == 0, "invalid %ld", invalid);
	/* the raw flat, as kogei divided before: by the flat over its mean */
	double fm = 0;
	for (int i = 0; i < W * H; i++)
		fm += flat->data[i];
	fm /= W * H;
	for (int i = 0; i < W * H; i++)
		raw->data[i] = (float)(raw->data[i] / (flat->data[i] / fm));
	double sd[2];
	for (int k = 0; k < 2; k++) {
		const kg_image *im = k ? raw : obj;
		double m = 0, m2 = 0;
		for (int i = 0; i < W * H; i++)
			m += im->data[i];
		m /= W * H;
		for (int i = 0; i < W * H; i++)
			m2 += (im->data[i] - m) * (im->data[i] - m);
		sd[k] = sqrt(m2 / (W * H - 1)) / m;
	}
	printf("uniform target through a textured, noisy flat: relative pixel std %.4f with the "
	       "low-passed flat, %.4f with the raw one (the target's own noise ~%.4f)\n",
	       sd[0], sd[1], 0.001 / 0.5 / 0.85);
	CHECK(sd[0] < sd[1] / 3, "low-passed %.4f is not well below raw %.4f", sd[0], sd[1]);
	CHECK(sd[0] < 0.006, "low-passed std %.4f: more than the target's noise and a small bias",
	      sd[0]);

	/* refusals, naming the flat and the measured value */
	double ratio = NAN;
	CHECK(kg_flat_check_image(flat, 0, "flat-0001", &ratio, &err) == 0, "even flat: %s",
	      err.msg);
	CHECK(ratio > KG_FLAT_MIN_RATIO && ratio < 0.7, "ratio %.3f", ratio);
	CHECK(kg_flat_check_image(flat, 0.023, "flat-0001", NULL, &err) == KG_EINVAL,
	      "a clipped flat was accepted");
	CHECK(strstr(err.msg, "flat flat-0001 is clipped: 2.3 % of its samples"), "message '%s'",
	      err.msg);
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++)
			flat->data[y * W + x] = (float)(0.8 * (0.25 + 0.75 * x / (W - 1.0)));
	CHECK(kg_flat_check_image(flat, 0, "flat-0002", &ratio, &err) == KG_EINVAL,
	      "an uneven flat (ratio %.3f) was accepted", ratio);
	CHECK(fabs(ratio - 0.25) < 0.03, "ramp 0.25..1: ratio %.3f", ratio);
	CHECK(strstr(err.msg, "flat flat-0002 is too uneven: its dimmest part gets 2") &&
	      strstr(err.msg, "limit 40 %"), "message '%s'", err.msg);
	printf("refused: %s\n", err.msg);
	kg_image_free(&flat);
	kg_image_free(&obj);
	kg_image_free(&raw);
}

static void test_stats(void)
{
	kg_image *img;
	kg_err err = {{0}};
	kg_image_new(101, 37, 3, &img, &err);
	size_t n = 101 * 37 * 3;
	kg_rng rng;
	kg_rng_seed(&rng, 11);
	for (size_t i = 0; i < n; i++)
		img->data[i] = (float)(kg_rng_uniform(&rng) * kg_rng_uniform(&rng));
	img->data[17] = NAN;
	img->data[18] = INFINITY;
	float *sorted = malloc(sizeof(float) * n);
	size_t m = 0, under = 0;
	for (size_t i = 0; i < n; i++)
		if (isfinite(img->data[i])) {
			sorted[m++] = img->data[i];
			under += img->data[i] < KG_UNDEREXPOSED_LEVEL;
		}
	qsort(sorted, m, sizeof(float), cmp_float);
	kg_image_stats st;
	CHECK(kg_image_stats_compute(img, &st, &err) == 0, "%s", err.msg);
	CHECK(st.nonfinite == 2, "nonfinite %ld", st.nonfinite);
	CHECK_NEAR(st.min, sorted[0], 0, "min");
	CHECK_NEAR(st.max, sorted[m - 1], 0, "max");
	CHECK_NEAR(st.p01, ref_percentile(sorted, m, 1), 1e-7, "p1");
	CHECK_NEAR(st.p50, ref_percentile(sorted, m, 50), 1e-7, "p50");
	CHECK_NEAR(st.p99, ref_percentile(sorted, m, 99), 1e-7, "p99");
	CHECK_NEAR(st.p999, ref_percentile(sorted, m, 99.9), 1e-7, "p99.9");
	CHECK_NEAR(st.underexposed_fraction, (double)under / (double)m, 1e-12, "under-exposed");
	free(sorted);
	kg_image_free(&img);
}

/* Brute force: same-colour neighbours within radius r (in same-colour steps). */
static double ref_bright(const kg_image *img, int r, double p)
{
	int step = img->cfa ? 2 : 1, ch = img->channels;
	size_t n = (size_t)img->width * (size_t)img->height * (size_t)ch;
	float *v = malloc(sizeof(float) * n);
	size_t m = 0;
	for (int y = 0; y < img->height; y++)
		for (int x = 0; x < img->width; x++)
			for (int c = 0; c < ch; c++) {
				double s = 0;
				int k = 0;
				for (int dy = -r; dy <= r; dy++)
					for (int dx = -r; dx <= r; dx++) {
						int X = x + dx * step, Y = y + dy * step;
						if (X < 0 || Y < 0 || X >= img->width || Y >= img->height)
							continue;
						s += img->data[((size_t)Y * (size_t)img->width + (size_t)X) * (size_t)ch + (size_t)c];
						k++;
					}
				v[m++] = (float)(s / k);
			}
	qsort(v, m, sizeof(float), cmp_float);
	double out = ref_percentile(v, m, p);
	free(v);
	return out;
}

static void test_bright_level(void)
{
	kg_err err = {{0}};
	for (int mosaic = 0; mosaic < 2; mosaic++) {
		int ch = mosaic ? 1 : 3;
		kg_image *img;
		kg_image_new(120, 90, ch, &img, &err);
		if (mosaic)
			kg_image_set_cfa(img, "BGGR", 2, 2, &err);
		kg_rng rng;
		kg_rng_seed(&rng, 5 + (uint64_t)mosaic);
		size_t n = (size_t)120 * 90 * (size_t)ch;
		for (size_t i = 0; i < n; i++)
			img->data[i] = (float)(0.2 + 0.05 * kg_rng_uniform(&rng));
		/* a bright 14 x 14 patch (1.8 % of the image) and isolated hot pixels */
		for (int y = 30; y < 44; y++)
			for (int x = 50; x < 64; x++)
				for (int c = 0; c < ch; c++)
					img->data[((size_t)y * 120 + (size_t)x) * (size_t)ch + (size_t)c] = 0.9f;
		for (int k = 0; k < 40; k++)
			img->data[(size_t)(kg_rng_uniform(&rng) * (double)n)] = 1.0f;
		double level = -1;
		CHECK(kg_bright_level(img, KG_BRIGHT_RADIUS, KG_BRIGHT_PERCENTILE, &level, &err) == 0,
		      "%s", err.msg);
		double want = ref_bright(img, KG_BRIGHT_RADIUS, KG_BRIGHT_PERCENTILE);
		CHECK_NEAR(level, want, 1e-6, mosaic ? "bright level (mosaic)" : "bright level (rgb)");
		/* the hot pixels do not decide it: the patch does */
		CHECK(level > 0.6 && level < 0.95, "bright level %g should be near the patch", level);
		printf("bright level (%s): %.6f (brute force %.6f)\n", mosaic ? "mosaic" : "rgb", level,
		       want);
		kg_image_free(&img);
	}
}

static void test_demosaic(void)
{
	if (!kg_demosaic_algorithm()) {
		printf("demosaic: built without OpenCV, not tested\n");
		kg_image *m;
		kg_err err = {{0}};
		kg_image_new(8, 8, 1, &m, &err);
		kg_image_set_cfa(m, "RGGB", 2, 2, &err);
		kg_image *rgb = NULL;
		CHECK(kg_demosaic(m, &rgb, NULL, &err) == KG_ENOTSUP, "demosaic without OpenCV");
		kg_image_free(&m);
		return;
	}
	static const char *const pats[] = {"RGGB", "GRBG", "GBRG", "BGGR"};
	const double colour[3] = {0.2, 0.5, 0.7};
	for (int p = 0; p < 4; p++) {
		const int W = 40, H = 30;
		kg_image *m, *rgb = NULL;
		kg_err err = {{0}};
		kg_image_new(W, H, 1, &m, &err);
		kg_image_set_cfa(m, pats[p], 2, 2, &err);
		/* each colour is a ramp across x: bilinear interpolation keeps it exactly */
		for (int y = 0; y < H; y++)
			for (int x = 0; x < W; x++)
				m->data[y * W + x] = (float)(colour[colour_of(pats[p], x, y)] * (1 + 0.01 * x));
		double step = 0;
		int ret = kg_demosaic(m, &rgb, &step, &err);
		CHECK(ret == 0, "%s: %s", pats[p], err.msg);
		if (ret) {
			kg_image_free(&m);
			continue;
		}
		double worst = 0;
		for (int y = 2; y < H - 2; y++)
			for (int x = 2; x < W - 2; x++)
				for (int c = 0; c < 3; c++)
					worst = fmax(worst, fabs(rgb->data[(y * W + x) * 3 + c] -
					                         colour[c] * (1 + 0.01 * x)));
		CHECK(worst <= 2 * step + 1e-6, "%s: interior off by %.3g (step %.3g)", pats[p], worst,
		      step);
		printf("demosaic %s: interior within %.3g (16-bit step %.3g)\n", pats[p], worst, step);
		kg_image_free(&m);
		kg_image_free(&rgb);
	}
}

/* Bands of a mosaic, demosaiced over the whole mosaic's range and cut 4 rows inside
 * (as kogei process reads a capture, pipeline/capture_rows.c), give the whole mosaic's
 * values bit for bit, NaN samples included, for bands of many heights. */
static void test_demosaic_bands(void)
{
	if (!kg_demosaic_algorithm())
		return;
	const int W = 37, H = 53, M = 4;
	kg_image *m = NULL, *whole = NULL;
	kg_err err = {{0}};
	kg_image_new(W, H, 1, &m, &err);
	kg_image_set_cfa(m, "GRBG", 2, 2, &err);
	uint64_t st = 12345;
	for (int i = 0; i < W * H; i++) {
		st = st * 6364136223846793005ULL + 1442695040888963407ULL;
		m->data[i] = (float)((st >> 11) * (1.0 / 9007199254740992.0)) * 0.8f + 0.05f;
	}
	m->data[5 * W + 7] = NAN;
	CHECK(kg_demosaic(m, &whole, NULL, &err) == 0, "whole: %s", err.msg);
	double lo = INFINITY, hi = -INFINITY;
	for (int i = 0; i < W * H; i++)
		if (isfinite(m->data[i]))
			lo = fmin(lo, m->data[i]), hi = fmax(hi, m->data[i]);
	int differ = 0, bands = 0;
	for (int rows = 1; rows <= 9 && whole; rows++)
		for (int y0 = 0; y0 < H; y0 += rows, bands++) {
			int n = H - y0 < rows ? H - y0 : rows;
			int a = y0 - M < 0 ? 0 : y0 - M;
			a -= a % 2;
			int b = y0 + n + M > H ? H : y0 + n + M;
			kg_image band = *m;
			band.height = b - a;
			band.data = m->data + (size_t)a * W;
			kg_image *rgb = NULL;
			CHECK(kg_demosaic_range(&band, lo, hi, &rgb, NULL, &err) == 0, "band: %s", err.msg);
			for (int i = 0; rgb && i < n * W * 3; i++) {
				float x = rgb->data[(size_t)(y0 - a) * W * 3 + i];
				float y = whole->data[(size_t)y0 * W * 3 + i];
				differ += !(x == y || (isnan(x) && isnan(y)));
			}
			kg_image_free(&rgb);
		}
	CHECK(differ == 0, "%d samples of %d bands differ from the whole mosaic's", differ, bands);
	printf("demosaic in bands: %d bands of 1 to 9 rows, %d samples differ\n", bands, differ);
	kg_image_free(&m);
	kg_image_free(&whole);
}

static void test_flat_nonuniformity(void)
{
	const int W = 64, H = 48;
	const char *cfa = "GRBG";
	const double gain[3] = {0.8, 1.0, 0.6};
	kg_err err = {{0}};
	kg_image *flat = NULL;
	CHECK(kg_image_new(W, H, 1, &flat, &err) == 0, "image: %s", err.msg);
	kg_image_set_cfa(flat, cfa, 2, 2, &err);
	kg_rng rng;
	kg_rng_seed(&rng, 11);
	for (int kind = 0; kind < 3; kind++) {
		for (int y = 0; y < H; y++)
			for (int x = 0; x < W; x++) {
				double dx = (x - (W - 1) / 2.0) / (W - 1); /* the light varies along x */
				double F = kind == 0 ? 1 + 0.2 * dx : kind == 1 ? 1 : 1 - 0.4 * dx * dx;
				double noise = 1 + 0.002 * (kg_rng_uniform(&rng) - 0.5);
				flat->data[y * W + x] = (float)(0.6 * F * gain[colour_of(cfa, x, y)] * noise);
			}
		flat->data[3 * W + 3] = NAN; /* a dead sample is left out */
		double nu = -1;
		CHECK(kg_flat_nonuniformity(flat, &nu, &err) == 0, "non-uniformity: %s", err.msg);
		/* the outer blocks' centres: x = 3.5 and 59.5 of 0..63 */
		double edge = (3.5 - 31.5) / 63;
		double want = kind == 0 ? 0.2 * -edge : kind == 1 ? 0 : NAN;
		if (kind == 2) {
			/* block means of 1 - 0.4 dx^2 over 8 columns; the mean of all blocks is the
			 * mean over the frame */
			double mean = 0, bmin = INFINITY, bmax = -INFINITY;
			for (int b = 0; b < 8; b++) {
				double s = 0;
				for (int x = 8 * b; x < 8 * b + 8; x++) {
					double dx = (x - 31.5) / 63;
					s += 1 - 0.4 * dx * dx;
				}
				s /= 8;
				mean += s / 8;
				bmin = fmin(bmin, s);
				bmax = fmax(bmax, s);
			}
			want = fmax(bmax - mean, mean - bmin) / mean;
		}
		printf("flat non-uniformity (%s): %.4f, expected %.4f\n",
		       kind == 0 ? "20 % ramp" : kind == 1 ? "even" : "falloff", nu, want);
		CHECK(fabs(nu - want) < 0.003, "flat %d: non-uniformity %.4f, expected %.4f", kind, nu,
		      want);
	}
	kg_image_free(&flat);
}

int main(void)
{
	test_dark_flat();
	test_flat_lowpass();
	test_flat_nonuniformity();
	test_stats();
	test_bright_level();
	test_demosaic();
	test_demosaic_bands();
	return kg_test_done("acquire-correct");
}
