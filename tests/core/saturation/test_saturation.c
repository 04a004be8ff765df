/* Saturation from the data (core/saturation.h):
 *   - a 12-bit sensor that saturates at 4092 of 4095: the pile-up found at 4092 in the
 *     channels that reach it, the clipped fraction the count the test made, the others
 *     not flagged; the same on a Bayer mosaic per CFA position;
 *   - no false positives: natural histograms (smooth scenes with shot noise, 8, 12 and
 *     16 bits, float), a noise-free synthetic chart whose brightest patch is a spike,
 *     an 8-bit image whose top is a thin tail; and the project's own fixture images;
 *   - clipping at the nominal white found too (level 1), a user's lower clip level kept;
 *   - a row source gives what the image gives;
 *   - the scan's shortcuts (single-precision binning, blocks skipped when they cannot
 *     hold a clipped sample) give what the search sample by sample in double precision
 *     gives, field for field, on values chosen to trip them. */
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
static kg_image *scene_gains(int channels, int bits, double peak, double sat_counts, double e,
                             unsigned seed, long *clipped_per_channel, const double gains[3])
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
				double gain = gains[c < 3 ? c : 1];
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

static kg_image *scene(int channels, int bits, double peak, double sat_counts, double e,
                       unsigned seed, long *clipped_per_channel)
{
	static const double gains[3] = {1.0, 0.8, 0.55};
	return scene_gains(channels, bits, peak, sat_counts, e, seed, clipped_per_channel, gains);
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

/* The reference the scan must match: the search as first written, sample by sample in
 * double precision, with a second full pass for the pixels with any channel clipped. */
static int ref_bin(double v, int steps)
{
	double x = v * steps + 0.5;
	if (!(x > 0))
		return 0;
	if (x >= steps)
		return steps;
	return (int)x;
}

static int ref_channel(const kg_image *img, size_t x, size_t y, int c, int *mosaic)
{
	*mosaic = img->channels == 1 && img->cfa && img->cfa_rows == 2 && img->cfa_cols == 2;
	return *mosaic ? (int)((y & 1) * 2 + (x & 1)) : c;
}

/* The flat-object guard's sums, pixel by pixel. */
static void ref_flat_add(kg_sat_flat *f, const float *px, size_t n)
{
	const kg_saturation *s = &f->sat;
	if (s->channels != 3)
		return;
	for (size_t i = 0; i < n; i++) {
		const float *p = px + 3 * i;
		for (int c = 0; c < 3; c++) {
			if (!s->found[c] || !(p[c] >= s->clip[c]))
				continue;
			f->piled[c]++;
			for (int d = 0; d < 3; d++) {
				if (d == c || !(p[d] < s->clip[d]) || !isfinite(p[d]))
					continue;
				if (!f->n[c][d])
					f->ref[c][d] = p[d];
				f->n[c][d]++;
				double dv = p[d] - f->ref[c][d];
				f->sum[c][d] += dv;
				f->sumsq[c][d] += dv * dv;
			}
		}
	}
}

static int ref_saturation(const kg_image *img, double nominal, kg_saturation *out)
{
	kg_err err = {{0}};
	int mosaic = img->channels == 1 && img->cfa && img->cfa_rows == 2 && img->cfa_cols == 2;
	int C = mosaic ? 4 : img->channels;
	kg_sat_hist h;
	if (kg_sat_hist_init(&h, C, kg_saturation_steps(img), &err))
		return -1;
	size_t nx = (size_t)img->width, ny = (size_t)img->height, ch = (size_t)img->channels;
	for (size_t y = 0; y < ny; y++)
		for (size_t x = 0; x < nx; x++)
			for (size_t c = 0; c < ch; c++) {
				float v = img->data[(y * nx + x) * ch + c];
				int m, k = ref_channel(img, x, y, (int)c, &m);
				if (isfinite(v)) {
					h.bins[k][ref_bin(v, h.steps)]++;
					h.total[k]++;
				}
			}
	kg_sat_hist_result(&h, nominal, out);
	kg_sat_hist_free(&h);
	if (!mosaic && C == 3 && kg_saturation_below(out, nominal)) {
		kg_sat_flat f;
		kg_sat_flat_init(&f, out);
		ref_flat_add(&f, img->data, nx * ny);
		kg_sat_flat_result(&f, out);
	}
	size_t any = 0;
	for (size_t y = 0; y < ny; y++)
		for (size_t x = 0; x < nx; x++) {
			int hit = 0;
			for (size_t c = 0; c < ch; c++) {
				int m, k = ref_channel(img, x, y, (int)c, &m);
				hit |= img->data[(y * nx + x) * ch + c] >= out->clip[k];
			}
			any += (size_t)hit;
		}
	out->fraction_any = nx && ny ? (double)any / (double)(nx * ny) : 0;
	return 0;
}

/* Bit for bit, NaN equal to NaN. */
static int same(double a, double b)
{
	return memcmp(&a, &b, sizeof(a)) == 0 || (isnan(a) && isnan(b));
}

/* kg_saturation_of_image against the reference, every field; returns 1 when equal. */
static int matches_reference(const char *what, const kg_image *img, double nominal)
{
	kg_saturation s, r;
	kg_err err = {{0}};
	memset(&s, 0x55, sizeof(s));
	CHECK(kg_saturation_of_image(img, nominal, &s, &err) == 0, "%s: %s", what, err.msg);
	CHECK(ref_saturation(img, nominal, &r) == 0, "%s: reference failed", what);
	int ok = s.channels == r.channels && s.steps == r.steps && same(s.nominal, r.nominal) &&
	         same(s.fraction_any, r.fraction_any);
	for (int c = 0; c < r.channels && c < KG_SAT_MAX_CHANNELS; c++)
		ok = ok && s.found[c] == r.found[c] && same(s.level[c], r.level[c]) &&
		     same(s.clip[c], r.clip[c]) && same(s.fraction[c], r.fraction[c]);
	CHECK(ok, "%s, nominal clip %.9g: fraction_any %.17g (reference %.17g), channel 0 "
	      "found %d/%d clip %.17g/%.17g fraction %.17g/%.17g", what, nominal,
	      s.fraction_any, r.fraction_any, s.found[0], r.found[0], s.clip[0], r.clip[0],
	      s.fraction[0], r.fraction[0]);
	return ok;
}

/* kg_sat_flat_add against the reference, over the whole image in bands of uneven
 * sizes, every sum bit for bit. */
static void flat_matches_reference(const char *what, const kg_image *img, double nominal)
{
	kg_saturation s;
	kg_err err = {{0}};
	CHECK(kg_saturation_of_image(img, nominal, &s, &err) == 0, "%s", err.msg);
	for (int c = 0; c < 3; c++) /* the guard over every channel, found or not */
		if (!s.found[c]) {
			s.found[c] = 1;
			s.clip[c] = 0.9;
		}
	kg_sat_flat f, r;
	kg_sat_flat_init(&f, &s);
	kg_sat_flat_init(&r, &s);
	size_t n = (size_t)img->width * (size_t)img->height;
	for (size_t i = 0, m = 1; i < n; i += m, m = m * 7 % 1001 + 1)
		kg_sat_flat_add(&f, img->data + 3 * i, n - i < m ? n - i : m);
	ref_flat_add(&r, img->data, n);
	CHECK(!memcmp(f.piled, r.piled, sizeof(f.piled)) && !memcmp(f.n, r.n, sizeof(f.n)) &&
	          !memcmp(f.ref, r.ref, sizeof(f.ref)) && !memcmp(f.sum, r.sum, sizeof(f.sum)) &&
	          !memcmp(f.sumsq, r.sumsq, sizeof(f.sumsq)),
	      "%s: the flat-object guard's sums differ from the reference (red over green: "
	      "%llu %.17g %.17g, reference %llu %.17g %.17g)", what,
	      (unsigned long long)f.n[0][1], f.sum[0][1], f.sumsq[0][1],
	      (unsigned long long)r.n[0][1], r.sum[0][1], r.sumsq[0][1]);
}

/* kg_sat_hist_add against the reference binning, bin by bin. */
static void hist_matches_reference(const char *what, const float *v, size_t n, int C,
                                   int steps)
{
	kg_sat_hist h;
	kg_err err = {{0}};
	CHECK(kg_sat_hist_init(&h, C, steps, &err) == 0, "%s", err.msg);
	/* in uneven pieces, so that every remainder of the fast path is run */
	for (size_t i = 0, m = 1; i < n; i += m, m = m * 3 % 17 + 1)
		kg_sat_hist_add(&h, v + i * (size_t)C, n - i < m ? n - i : m);
	uint64_t *ref = calloc((size_t)steps + 1, sizeof(uint64_t));
	int bad = 0;
	for (int c = 0; c < C && !bad; c++) {
		uint64_t total = 0;
		memset(ref, 0, ((size_t)steps + 1) * sizeof(uint64_t));
		for (size_t i = 0; i < n; i++) {
			float x = v[i * (size_t)C + (size_t)c];
			if (isfinite(x)) {
				ref[ref_bin(x, steps)]++;
				total++;
			}
		}
		for (int k = 0; k <= steps && !bad; k++)
			if (h.bins[c][k] != ref[k]) {
				bad = 1;
				CHECK(0, "%s, %d steps: channel %d bin %d holds %llu, the reference %llu",
				      what, steps, c, k, (unsigned long long)h.bins[c][k],
				      (unsigned long long)ref[k]);
			}
		CHECK(h.total[c] == total, "%s: channel %d total %llu, the reference %llu", what, c,
		      (unsigned long long)h.total[c], (unsigned long long)total);
	}
	free(ref);
	kg_sat_hist_free(&h);
}

/* Values that a single-precision shortcut could bin wrongly: random values over and
 * beyond 0..1, and values at, just below and just above the boundaries between bins
 * (count - 0.5) / steps; 0, -0, 1, above 1, negative, tiny, huge, NaN and infinities. */
static float awkward(kg_rng *rng, int steps)
{
	static const float special[] = {0.0f, -0.0f, 1.0f, 1.0000001f, 0.99999994f, 1.5f,
	                                2.0f, 1e30f, -1e30f, -0.5f, -1e-30f, 1e-40f, 3.4e38f,
	                                NAN, INFINITY, -INFINITY};
	uint64_t r = kg_rng_next(rng);
	switch (r % 8) {
	case 0:
		return special[(r >> 8) % (sizeof(special) / sizeof(special[0]))];
	case 1:
	case 2:
		return (float)(kg_rng_uniform(rng) * 1.4 - 0.2);
	default: {
		double k = (double)((r >> 8) % ((uint64_t)steps + 2));
		float b = (float)((k - 0.5) / steps);
		int ulps = (int)((r >> 32) % 7) - 3;
		for (; ulps < 0; ulps++)
			b = nextafterf(b, -INFINITY);
		for (; ulps > 0; ulps--)
			b = nextafterf(b, INFINITY);
		return b;
	}
	}
}

static void test_fast_paths(void)
{
	kg_rng rng;
	kg_rng_seed(&rng, 2024);
	kg_err err = {{0}};
	static const int depths[] = {8, 12, 16, 32};
	int ok = 1;
	/* awkward values in a float image and in images said to come from integers */
	for (size_t d = 0; d < sizeof(depths) / sizeof(depths[0]); d++) {
		kg_image *img = NULL;
		CHECK(kg_image_new(W + 3, 37, 3, &img, &err) == 0, "%s", err.msg);
		img->bits = depths[d];
		img->is_float = depths[d] == 32;
		int steps = kg_saturation_steps(img);
		size_t n = (size_t)img->width * (size_t)img->height;
		for (size_t i = 0; i < 3 * n; i++)
			img->data[i] = awkward(&rng, steps);
		char what[64];
		snprintf(what, sizeof(what), "awkward values, %d bits", depths[d]);
		hist_matches_reference(what, img->data, n, 3, steps);
		hist_matches_reference(what, img->data, 3 * n, 1, steps);
		static const double nominal[] = {1.0, 0.9, 0.5, 0.0, -1.0, 1.0 - 0.5 / 65535};
		for (size_t k = 0; k < sizeof(nominal) / sizeof(nominal[0]); k++)
			ok &= matches_reference(what, img, nominal[k]);
		kg_image_free(&img);
	}
	/* every float from 1/4 to 1 and a little above (the binades where a float's
	 * rounding comes closest to a bin's width), for each resolution */
	{
		float lo = 0.25f, hi = 1.0625f;
		uint32_t ulo, uhi;
		memcpy(&ulo, &lo, sizeof(ulo));
		memcpy(&uhi, &hi, sizeof(uhi));
		size_t n = (size_t)(uhi - ulo);
		float *v = malloc(n * sizeof(float));
		CHECK(v != NULL, "out of memory");
		for (size_t i = 0; v && i < n; i++) {
			uint32_t u = ulo + (uint32_t)i;
			memcpy(&v[i], &u, sizeof(u));
		}
		static const int steps[] = {255, 4095, 65535};
		for (size_t k = 0; v && k < sizeof(steps) / sizeof(steps[0]); k++)
			hist_matches_reference("every float in 0.25 .. 1.0625", v, n, 1, steps[k]);
		free(v);
	}
	/* every count of 8, 12 and 16 bits, divided as the readers do and in double */
	for (int bits = 8; bits <= 16; bits += 4) {
		int steps = (1 << bits) - 1;
		size_t n = (size_t)steps + 1;
		float *v = malloc(2 * n * sizeof(float));
		for (size_t u = 0; u < n; u++) {
			v[u] = (float)u / (float)steps;
			v[n + u] = (float)((double)u / steps);
		}
		char what[64];
		snprintf(what, sizeof(what), "every %d-bit count", bits);
		hist_matches_reference(what, v, 2 * n, 1, steps);
		hist_matches_reference(what, v, 2 * n, 1, 65535);
		free(v);
	}
	/* natural integer scenes clipping below full scale in 1, 2 and 3 channels; then with
	 * NaN, infinities and negative samples strewn over them; as a 1-channel image and a
	 * Bayer mosaic */
	static const double gains[3][3] = {{1.0, 0.55, 0.5}, {1.0, 1.0, 0.5}, {1.0, 1.0, 1.0}};
	for (int bits = 8; bits <= 16; bits += 4)
		for (int g = 0; g < 3; g++) {
			long clipped[3];
			double fs = (double)((1 << bits) - 1);
			kg_image *img = scene_gains(3, bits, 1.3, fs - 3, bits == 8 ? 50.0 : 1.0,
			                            (unsigned)(20 + g + bits), clipped, gains[g]);
			CHECK(img != NULL, "no image");
			if (!img)
				continue;
			char what[96];
			snprintf(what, sizeof(what), "%d-bit scene, %d channel(s) clipped", bits, g + 1);
			kg_saturation s;
			CHECK(kg_saturation_of_image(img, 1.0, &s, &err) == 0, "%s", err.msg);
			int found = s.found[0] + s.found[1] + s.found[2];
			CHECK(found == g + 1, "%s: found in %d channels", what, found);
			ok &= matches_reference(what, img, 1.0);
			ok &= matches_reference(what, img, 1.0 - 0.5 / fs);
			ok &= matches_reference(what, img, 0.95);
			size_t n = (size_t)W * H * 3;
			for (int k = 0; k < 200; k++) {
				static const float odd[] = {NAN, INFINITY, -INFINITY, -0.25f, 1.25f};
				img->data[kg_rng_next(&rng) % n] = odd[k % 5];
			}
			snprintf(what, sizeof(what), "%d-bit scene, %d channel(s) clipped, with NaN and "
			         "infinities", bits, g + 1);
			ok &= matches_reference(what, img, 1.0);
			flat_matches_reference(what, img, 1.0);
			ok &= matches_reference(what, img, 1.0 - 0.5 / fs);
			/* the same samples as one channel and as a mosaic */
			kg_image *one = NULL;
			CHECK(kg_image_new(W * 3, H, 1, &one, &err) == 0, "%s", err.msg);
			if (!one) {
				kg_image_free(&img);
				continue;
			}
			one->bits = bits;
			one->is_float = 0;
			memcpy(one->data, img->data, n * sizeof(float));
			snprintf(what, sizeof(what), "%d-bit samples as 1 channel", bits);
			ok &= matches_reference(what, one, 1.0);
			ok &= matches_reference(what, one, 1.0 - 0.5 / fs);
			CHECK(kg_image_set_cfa(one, "RGGB", 2, 2, &err) == 0, "%s", err.msg);
			snprintf(what, sizeof(what), "%d-bit samples as a mosaic", bits);
			ok &= matches_reference(what, one, 1.0);
			ok &= matches_reference(what, one, 1.0 - 0.5 / fs);
			kg_image_free(&one);
			kg_image_free(&img);
		}
	/* lone samples at the level of the one channel found clipped, scattered where the
	 * other channels are far from their own (higher) clip levels: each pixel counts in
	 * fraction_any only if the scan keeps its channels apart */
	for (int bits = 12; bits <= 16; bits += 4) {
		double fs = (double)((1 << bits) - 1);
		kg_image *img = scene_gains(3, bits, 1.3, fs - 3, 1.0, (unsigned)(60 + bits), NULL,
		                            gains[0]);
		CHECK(img != NULL, "no image");
		if (!img)
			continue;
		kg_saturation s;
		CHECK(kg_saturation_of_image(img, 1.0, &s, &err) == 0, "%s", err.msg);
		CHECK(s.found[0] && !s.found[1] && !s.found[2], "%d bits: red alone not found",
		      bits);
		/* at the level, and the least float at or above the clip level (next to a bin
		 * boundary, where the single-precision binning defers to the exact one) */
		float edge = (float)s.clip[0];
		if (edge < s.clip[0])
			edge = nextafterf(edge, INFINITY);
		for (int k = 0; k < 600; k++) {
			size_t px = kg_rng_next(&rng) % ((size_t)W * H);
			img->data[3 * px] = k & 1 ? edge : (float)s.level[0];
		}
		char what[96];
		snprintf(what, sizeof(what), "%d-bit scene, lone samples at red's clip level", bits);
		ok &= matches_reference(what, img, 1.0);
		/* three columns fewer: rows that end part-way through the scan's groups */
		kg_image *narrow = NULL;
		CHECK(kg_image_new(W - 3, H, 3, &narrow, &err) == 0, "%s", err.msg);
		if (narrow) {
			narrow->bits = bits;
			narrow->is_float = 0;
			for (size_t y = 0; y < H; y++) {
				memcpy(narrow->data + y * (W - 3) * 3, img->data + y * W * 3,
				       (W - 3) * 3 * sizeof(float));
				if (y % 5 == 0) /* and in the last pixel of a row */
					narrow->data[(y * (W - 3) + W - 4) * 3] = (float)s.level[0];
			}
			ok &= matches_reference(what, narrow, 1.0);
			kg_image_free(&narrow);
		}
		kg_image_free(&img);
	}
	/* a user's clip level just past a bin boundary, and lone samples on either side of
	 * it in a dull image: a sample at or above that level shares the level's bin */
	{
		kg_image *img = NULL;
		CHECK(kg_image_new(W - 1, 50, 3, &img, &err) == 0, "%s", err.msg);
		if (img) {
			img->bits = 16;
			img->is_float = 0;
			size_t n = (size_t)img->width * (size_t)img->height;
			for (size_t i = 0; i < 3 * n; i++)
				img->data[i] = 0.25f;
			float b = (float)((50000 - 0.5) / 65535), near[7];
			near[3] = b;
			for (int k = 1; k <= 3; k++) {
				near[3 + k] = nextafterf(near[2 + k], INFINITY);
				near[3 - k] = nextafterf(near[4 - k], -INFINITY);
			}
			for (int k = 0; k < 200; k++)
				img->data[kg_rng_next(&rng) % (3 * n)] = near[k % 7];
			for (int k = 0; k < 7; k++) {
				ok &= matches_reference("lone samples by a bin boundary", img, near[k]);
				ok &= matches_reference("lone samples by a bin boundary", img,
				                        near[k] + 1e-12);
			}
			kg_image_free(&img);
		}
	}
	/* clipped at full scale: samples at exactly 1, the clip level's own bin */
	for (int bits = 8; bits <= 16; bits += 8)
		for (int g = 0; g < 3; g++) {
			double fs = (double)((1 << bits) - 1);
			kg_image *img = scene_gains(3, bits, 1.3, fs, bits == 8 ? 50.0 : 1.0,
			                            (unsigned)(40 + g + bits), NULL, gains[g]);
			CHECK(img != NULL, "no image");
			if (!img)
				continue;
			char what[96];
			snprintf(what, sizeof(what), "%d-bit scene, %d channel(s) clipped at full scale",
			         bits, g + 1);
			ok &= matches_reference(what, img, 1.0);
			ok &= matches_reference(what, img, 1.0 - 0.5 / fs);
			kg_image *one = NULL;
			CHECK(kg_image_new(W * 3, H, 1, &one, &err) == 0, "%s", err.msg);
			if (one) {
				one->bits = bits;
				one->is_float = 0;
				memcpy(one->data, img->data, (size_t)W * H * 3 * sizeof(float));
				CHECK(kg_image_set_cfa(one, "RGGB", 2, 2, &err) == 0, "%s", err.msg);
				ok &= matches_reference(what, one, 1.0);
				kg_image_free(&one);
			}
			kg_image_free(&img);
		}
	/* a flat bright object in an otherwise noisy image: found, then dropped as an object */
	kg_image *img = scene(3, 16, 0.9, 1e9, 1.0, 5, NULL);
	for (int y = 100; y < 140; y++)
		for (int x = 200; x < 260; x++)
			for (int c = 0; c < 3; c++)
				img->data[((size_t)y * W + x) * 3 + (size_t)c] = c == 0 ? 0.97f : 0.4f;
	ok &= matches_reference("a flat bright object", img, 1.0);
	kg_image_free(&img);
	if (ok)
		printf("  the scan matches the reference sample by sample: awkward floats, every "
		       "8/12/16-bit count, 1-3 channels clipped, NaN/infinities, mosaic\n");
}

int main(int argc, char **argv)
{
	test_pileup_12bit();
	test_natural();
	test_nominal();
	test_sparse_codes();
	test_fast_paths();
	if (argc > 1)
		test_fixtures(argv[1]);
	return kg_test_done("saturation");
}
