/* Frame averaging against a direct computation: per-sample mean and unbiased variance
 * by two passes in long double over the same frames, for 8- and 16-bit formats with
 * padded rows, values close to full scale (where a single-pass float sum of squares
 * loses everything to cancellation), the clipped fraction counted directly, and the
 * refusals (format change, MJPEG, YUYV unless forced); a 12-bit Bayer sensor that
 * saturates at 4092 of 4095: the saturation found from the data and the clipped
 * fraction counted at it, per CFA position. */
#include <stdint.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "kg_acquire.h"
#include "kg_test.h"

#define NFRAMES 60

typedef struct case_ {
	const char *name;
	kg_pixfmt pixfmt;
	int bits;
	const char *cfa;
	int width, height, pad; /* pad: extra bytes per row */
	double base, spread;    /* values: base + spread * noise, in DN */
} case_;

static unsigned fullscale(const case_ *c) { return (1u << c->bits) - 1u; }

static void run_case(const case_ *c, uint64_t seed)
{
	kg_frame_format fmt = {.pixfmt = c->pixfmt, .width = c->width, .height = c->height,
	                       .bits = c->bits};
	snprintf(fmt.cfa, sizeof(fmt.cfa), "%s", c->cfa);
	kg_frame_format_fill(&fmt);
	fmt.stride += (size_t)c->pad;
	fmt.size = fmt.stride * (size_t)fmt.height;
	int ch = kg_pixfmt_channels(c->pixfmt);
	int wide = kg_pixfmt_bytes_per_pixel(c->pixfmt) / ch == 2;
	size_t ns = (size_t)c->width * (size_t)c->height * (size_t)ch;
	unsigned max = fullscale(c);

	uint16_t *values = malloc(sizeof(uint16_t) * ns * NFRAMES);
	uint8_t *buf = calloc(1, fmt.size);
	kg_rng rng;
	kg_rng_seed(&rng, seed);
	for (size_t k = 0; k < ns * NFRAMES; k++) {
		double v = c->base + c->spread * kg_rng_normal(&rng);
		/* a few samples far off, some of them at full scale */
		if (kg_rng_uniform(&rng) < 0.001)
			v = max;
		v = floor(v + 0.5);
		values[k] = (uint16_t)(v < 0 ? 0 : v > max ? max : v);
	}
	kg_frame_accum *acc = NULL;
	kg_err err = {{0}};
	int ret = kg_frame_accum_new(&fmt, 0, &acc, &err);
	CHECK(ret == 0, "%s: accum_new: %s", c->name, err.msg);
	if (ret)
		goto out;
	for (int f = 0; f < NFRAMES; f++) {
		memset(buf, 0xA5, fmt.size); /* padding bytes must be ignored */
		for (int y = 0; y < c->height; y++)
			for (size_t x = 0; x < (size_t)c->width * (size_t)ch; x++) {
				uint16_t v = values[(size_t)f * ns + (size_t)y * (size_t)c->width * (size_t)ch + x];
				uint8_t *p = buf + fmt.stride * (size_t)y;
				if (wide) {
					p[2 * x] = (uint8_t)(v & 0xff);
					p[2 * x + 1] = (uint8_t)(v >> 8);
				} else {
					p[x] = (uint8_t)v;
				}
			}
		kg_frame fr = {.fmt = fmt, .data = buf, .size = fmt.size, .sequence = (uint64_t)f + 1};
		ret = kg_frame_accum_add(acc, &fr, &err);
		CHECK(ret == 0, "%s: add frame %d: %s", c->name, f, err.msg);
	}
	CHECK(kg_frame_accum_count(acc) == NFRAMES, "%s: count %ld", c->name,
	      kg_frame_accum_count(acc));
	kg_image *mean = NULL, *var = NULL;
	ret = kg_frame_accum_result(acc, &mean, &var, &err);
	CHECK(ret == 0, "%s: result: %s", c->name, err.msg);
	if (ret)
		goto out;
	CHECK(mean->width == c->width && mean->height == c->height && mean->channels == ch,
	      "%s: mean is %dx%dx%d", c->name, mean->width, mean->height, mean->channels);
	if (c->cfa[0])
		CHECK(mean->cfa && !strcmp(mean->cfa, c->cfa), "%s: CFA %s lost", c->name, c->cfa);
	double worst_m = 0, worst_v = 0;
	size_t clipped = 0;
	for (size_t i = 0; i < ns; i++) {
		long double s = 0, ss = 0;
		int clip = 0;
		for (int f = 0; f < NFRAMES; f++)
			s += values[(size_t)f * ns + i];
		long double m = s / NFRAMES;
		for (int f = 0; f < NFRAMES; f++) {
			long double d = values[(size_t)f * ns + i] - m;
			ss += d * d;
			clip |= values[(size_t)f * ns + i] == max;
		}
		clipped += (size_t)clip;
		double mref = (double)(m / max), vref = (double)(ss / (NFRAMES - 1) / max / max);
		/* float32 outputs: half an ulp relative, plus a tiny absolute floor */
		double em = fabs(mean->data[i] - mref) / (mref * 6e-8 + 1e-30);
		double ev = fabs(var->data[i] - vref) / (vref * 6e-8 + 1e-20);
		if (em > worst_m)
			worst_m = em;
		if (ev > worst_v)
			worst_v = ev;
	}
	CHECK(worst_m <= 1.05, "%s: mean off by %.3g float half-ulps", c->name, worst_m);
	CHECK(worst_v <= 1.05, "%s: variance off by %.3g float half-ulps", c->name, worst_v);
	CHECK_NEAR(kg_frame_accum_clipped_fraction(acc), (double)clipped / (double)ns, 0,
	           "clipped fraction");
	CHECK(clipped > 0, "%s: the data should have clipped samples", c->name);
	printf("%s: mean within %.2f, variance within %.2f float half-ulps; clipped %.4f\n",
	       c->name, worst_m, worst_v, (double)clipped / (double)ns);

	/* a frame of another format is refused */
	kg_frame_format other = fmt;
	other.width -= 1;
	kg_frame fr = {.fmt = other, .data = buf, .size = fmt.size};
	CHECK(kg_frame_accum_add(acc, &fr, &err) == KG_EINVAL, "%s: other format accepted",
	      c->name);
	CHECK(strstr(err.msg, "differs"), "%s: message '%s'", c->name, err.msg);
	kg_image_free(&mean);
	kg_image_free(&var);
out:
	kg_frame_accum_free(&acc);
	free(values);
	free(buf);
}

/* A 12-bit RGGB sensor whose ADC stops at 4092: a smooth scene with shot noise whose
 * brightest part saturates the R sites (and a little of G). */
static void test_saturating_sensor(void)
{
	enum { SW = 120, SH = 80, NF = 4 };
	kg_frame_format fmt = {.pixfmt = KG_PIX_BAYER16, .width = SW, .height = SH, .bits = 12};
	snprintf(fmt.cfa, sizeof(fmt.cfa), "RGGB");
	kg_frame_format_fill(&fmt);
	kg_frame_accum *acc = NULL;
	kg_err err = {{0}};
	CHECK(kg_frame_accum_new(&fmt, 0, &acc, &err) == 0, "%s", err.msg);
	if (!acc)
		return;
	uint8_t *buf = calloc(1, fmt.size);
	unsigned char *hit = calloc((size_t)SW * SH, 1);
	kg_rng rng;
	kg_rng_seed(&rng, 34);
	for (int f = 0; f < NF; f++) {
		for (int y = 0; y < SH; y++)
			for (int x = 0; x < SW; x++) {
				int site = (y & 1) * 2 + (x & 1);
				double gain = site == 0 ? 1.0 : site == 3 ? 0.5 : 0.75;
				double mean = 4800.0 * gain * (0.1 + 0.9 * x / (double)SW) *
				              (1 - 0.2 * (y - SH / 2.0) * (y - SH / 2.0) / (SH * SH / 4.0));
				double v = floor(mean + sqrt(mean + 9) * kg_rng_normal(&rng) + 0.5);
				v = v < 0 ? 0 : v > 4092 ? 4092 : v;
				hit[y * SW + x] |= v >= 4092;
				uint8_t *p = buf + fmt.stride * (size_t)y + 2 * (size_t)x;
				p[0] = (uint8_t)((unsigned)v & 0xff);
				p[1] = (uint8_t)((unsigned)v >> 8);
			}
		kg_frame fr = {.fmt = fmt, .data = buf, .size = fmt.size, .sequence = (uint64_t)f + 1};
		CHECK(kg_frame_accum_add(acc, &fr, &err) == 0, "%s", err.msg);
	}
	size_t n = 0, nr = 0;
	for (int i = 0; i < SW * SH; i++) {
		n += hit[i];
		nr += hit[i] && (i / SW % 2 == 0) && (i % SW % 2 == 0);
	}
	double want = (double)n / (SW * SH);
	kg_saturation s;
	CHECK(kg_frame_accum_saturation(acc, &s) == 0 && s.channels == 4, "no saturation result");
	CHECK(s.found[0] && fabs(s.level[0] * 4095 - 4092) < 1e-6,
	      "R site: saturation at 4092 of 4095 not found (level %g)", s.level[0] * 4095);
	CHECK(!s.found[3], "B site never reaches 4092, yet found at %g", s.level[3] * 4095);
	CHECK(fabs(s.fraction[0] - (double)nr / (SW * SH / 4)) < 1e-12, "R fraction %g, want %g",
	      s.fraction[0], (double)nr / (SW * SH / 4));
	CHECK(want > 0.01, "the scene should clip more than 1 %% (%g)", want);
	CHECK_NEAR(kg_frame_accum_clipped_fraction(acc), want, 1e-12,
	           "clipped fraction at the sensor's saturation (4092 of 4095)");
	printf("bayer16/12 saturating at 4092: clipped %.4f %% (R site %.3f %%)\n",
	       100 * kg_frame_accum_clipped_fraction(acc), 100 * s.fraction[0]);
	free(buf);
	free(hit);
	kg_frame_accum_free(&acc);
}

int main(void)
{
	static const case_ cases[] = {
		{"mono16/12 padded", KG_PIX_MONO16, 12, "", 37, 23, 6, 4090, 2.5},
		{"mono16/16 near full scale", KG_PIX_MONO16, 16, "", 32, 16, 0, 65530, 1.5},
		{"bayer16/14 rggb", KG_PIX_BAYER16, 14, "RGGB", 30, 20, 4, 12000, 40},
		{"rgb8 padded", KG_PIX_RGB8, 8, "", 21, 13, 3, 250, 2},
		{"mono8", KG_PIX_MONO8, 8, "", 40, 10, 0, 30, 5},
	};
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++)
		run_case(&cases[i], 100 + i);
	test_saturating_sensor();

	/* one frame: variance 0 */
	kg_frame_format fmt = {.pixfmt = KG_PIX_MONO8, .width = 4, .height = 2, .bits = 8};
	kg_frame_format_fill(&fmt);
	uint8_t px[8] = {0, 1, 2, 3, 255, 128, 64, 32};
	kg_frame fr = {.fmt = fmt, .data = px, .size = sizeof(px)};
	kg_frame_accum *acc = NULL;
	kg_err err = {{0}};
	CHECK(kg_frame_accum_new(&fmt, 0, &acc, &err) == 0, "%s", err.msg);
	kg_image *mean = NULL, *var = NULL;
	CHECK(kg_frame_accum_result(acc, &mean, &var, &err) == KG_EINVAL,
	      "a result of no frames must be refused");
	CHECK(kg_frame_accum_add(acc, &fr, &err) == 0, "%s", err.msg);
	CHECK(kg_frame_accum_result(acc, &mean, &var, &err) == 0, "%s", err.msg);
	for (int i = 0; mean && var && i < 8; i++) {
		CHECK_NEAR(mean->data[i], px[i] / 255.0, 1e-7, "single-frame mean");
		CHECK(var->data[i] == 0, "single-frame variance %g", var->data[i]);
	}
	CHECK_NEAR(kg_frame_accum_clipped_fraction(acc), 1.0 / 8, 0, "single-frame clipped");
	kg_image_free(&mean);
	kg_image_free(&var);
	kg_frame_accum_free(&acc);

	/* formats that are not linear */
	fmt.pixfmt = KG_PIX_MJPEG;
	kg_frame_format_fill(&fmt);
	CHECK(kg_frame_accum_new(&fmt, 0, &acc, &err) == KG_EINVAL &&
	          strstr(err.msg, "--force-nonlinear"),
	      "MJPEG accepted unforced: %s", err.msg);
	CHECK(kg_frame_accum_new(&fmt, 1, &acc, &err) == 0, "MJPEG refused when forced: %s",
	      err.msg);
	kg_frame_accum_free(&acc);
	fmt.pixfmt = KG_PIX_YUYV;
	kg_frame_format_fill(&fmt);
	CHECK(kg_frame_accum_new(&fmt, 0, &acc, &err) == KG_EINVAL, "YUYV accepted unforced");
	CHECK(strstr(err.msg, "--force-nonlinear"), "message '%s'", err.msg);
	CHECK(kg_frame_accum_new(&fmt, 1, &acc, &err) == 0, "YUYV refused when forced: %s",
	      err.msg);
	kg_frame_accum_free(&acc);
	return kg_test_done("acquire-accum");
}
