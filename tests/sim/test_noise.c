/* The random number generator and the sensor noise model against their stated
 * distributions: sample moments of many draws must match the model within a few
 * standard errors (the tolerances below are 4-5 standard errors or a few per cent). */
#include <math.h>
#include <string.h>

#include "kg_sim.h"
#include "kg_test.h"

#define N 400000

static void moments(const double *x, int n, double *mean, double *var)
{
	long double s = 0.0L, ss = 0.0L;
	for (int i = 0; i < n; i++)
		s += x[i];
	long double m = s / n;
	for (int i = 0; i < n; i++)
		ss += (x[i] - m) * (x[i] - m);
	*mean = (double)m;
	*var = (double)(ss / (n - 1));
}

static double buf[N];

static void test_determinism(void)
{
	kg_rng a, b, c;
	kg_rng_seed(&a, 42);
	kg_rng_seed(&b, 42);
	kg_rng_seed(&c, 43);
	int same = 1, differ = 0;
	for (int i = 0; i < 1000; i++) {
		uint64_t x = kg_rng_next(&a), y = kg_rng_next(&b), z = kg_rng_next(&c);
		same &= x == y;
		differ += x != z;
	}
	CHECK(same, "same seed gave different sequences");
	CHECK(differ > 990, "seeds 42 and 43 agree in %d of 1000 draws", 1000 - differ);
	/* Seed 0 must not give the all-zero state of xoshiro (a constant stream). */
	kg_rng z;
	kg_rng_seed(&z, 0);
	CHECK(kg_rng_next(&z) != kg_rng_next(&z), "seed 0 gives a constant stream");
}

static void test_uniform_normal(void)
{
	kg_rng r;
	kg_rng_seed(&r, 7);
	double mean, var;
	for (int i = 0; i < N; i++) {
		buf[i] = kg_rng_uniform(&r);
		CHECK(buf[i] >= 0.0 && buf[i] < 1.0, "uniform %g outside [0, 1)", buf[i]);
	}
	moments(buf, N, &mean, &var);
	CHECK_NEAR(mean, 0.5, 5 * sqrt(1.0 / 12 / N), "uniform mean");
	CHECK_NEAR(var, 1.0 / 12, 0.02 / 12, "uniform variance");

	int within1 = 0;
	for (int i = 0; i < N; i++) {
		buf[i] = kg_rng_normal(&r);
		within1 += fabs(buf[i]) < 1.0;
	}
	moments(buf, N, &mean, &var);
	CHECK_NEAR(mean, 0.0, 5 / sqrt(N), "normal mean");
	CHECK_NEAR(var, 1.0, 5 * sqrt(2.0 / N), "normal variance");
	double p1 = 0.682689492137;
	CHECK_NEAR((double)within1 / N, p1, 5 * sqrt(p1 * (1 - p1) / N), "P(|z| < 1)");
}

static void test_poisson(void)
{
	/* Both samplers (inversion below 10, PTRS from 10) and the switch-over. */
	static const double means[] = {0.3, 2.0, 9.5, 10.0, 37.0, 1000.0, 1e5};
	kg_rng r;
	kg_rng_seed(&r, 11);
	for (size_t m = 0; m < sizeof(means) / sizeof(means[0]); m++) {
		double mu = means[m];
		int zeros = 0, whole = 1;
		for (int i = 0; i < N; i++) {
			buf[i] = kg_rng_poisson(&r, mu);
			whole &= buf[i] >= 0.0 && buf[i] == floor(buf[i]);
			zeros += buf[i] == 0.0;
		}
		double mean, var;
		moments(buf, N, &mean, &var);
		char what[64];
		snprintf(what, sizeof(what), "Poisson(%g) mean", mu);
		CHECK_NEAR(mean, mu, 5 * sqrt(mu / N), what);
		/* sd of the sample variance ~ sqrt((2 mu^2 + mu) / N) */
		snprintf(what, sizeof(what), "Poisson(%g) variance", mu);
		CHECK_NEAR(var, mu, 5 * sqrt((2 * mu * mu + mu) / N), what);
		CHECK(whole, "Poisson(%g) gave a negative or fractional count", mu);
		double p0 = exp(-mu);
		snprintf(what, sizeof(what), "Poisson(%g) P(0)", mu);
		CHECK_NEAR((double)zeros / N, p0, 5 * sqrt(p0 * (1 - p0) / N) + 1e-9, what);
	}
	CHECK(kg_rng_poisson(&r, 0.0) == 0.0, "Poisson(0) is not 0");
	CHECK(kg_rng_poisson(&r, -3.0) == 0.0, "Poisson(-3) is not 0");
	CHECK(kg_rng_poisson(&r, NAN) == 0.0, "Poisson(NaN) is not 0");
}

/* A flat patch read many times: mean and variance against the stated model. */
static void check_flat(double v, const char *spec, double tol_rel)
{
	kg_sim_noise n;
	kg_err err = {{0}};
	CHECK(kg_sim_noise_parse(spec, &n, &err) == 0, "%s", err.msg);
	kg_rng r;
	kg_rng_seed(&r, 2024);
	double top = (double)((1u << n.bits) - 1u);
	int on_grid = 1, in_range = 1;
	for (int i = 0; i < N; i++) {
		buf[i] = kg_sim_noise_apply(&n, v, &r);
		on_grid &= fabs(buf[i] * top - nearbyint(buf[i] * top)) < 1e-9;
		in_range &= buf[i] >= 0.0 && buf[i] <= 1.0;
	}
	double mean, var;
	moments(buf, N, &mean, &var);
	double fw = n.full_well, q = 1.0 / top;
	double model_var = (v * fw + n.read_noise * n.read_noise) / (fw * fw) + q * q / 12.0;
	char what[128];
	snprintf(what, sizeof(what), "noise %s at %g: mean", spec, v);
	CHECK_NEAR(mean, v, 5 * sqrt(model_var / N) + 1e-12, what);
	snprintf(what, sizeof(what), "noise %s at %g: variance (model %.4g)", spec, v, model_var);
	CHECK_NEAR(var, model_var, tol_rel * model_var, what);
	CHECK(on_grid, "noise %s: values not multiples of 1/%g", spec, top);
	CHECK(in_range, "noise %s: values outside [0, 1]", spec);
	printf("noise %-14s v=%.3f: mean %.6f var %.4e model %.4e (%+.2f %%)\n", spec, v, mean,
	       var, model_var, 100.0 * (var / model_var - 1.0));
}

static void test_noise_model(void)
{
	/* Shot noise dominant, 12 bits. */
	check_flat(0.5, "20000:10:12", 0.03);
	/* Quantisation about 5 % of the variance at 8 bits. */
	check_flat(0.5, "20000:10:8", 0.03);
	/* Read noise dominant at a low level. */
	check_flat(0.05, "10000:30:16", 0.03);
	/* Small full well: means below 10 electrons (inversion sampler). */
	check_flat(0.2, "40:0:16", 0.03);
	/* 14 bits, bright. */
	check_flat(0.85, "60000:3:14", 0.03);
}

static void test_clipping(void)
{
	kg_sim_noise n;
	CHECK(kg_sim_noise_parse("5000:5:12", &n, NULL) == 0, "parse");
	kg_rng r;
	kg_rng_seed(&r, 5);
	int all_one = 1, negative = 0, zeros = 0, max_one = 0, above = 0;
	for (int i = 0; i < 20000; i++) {
		all_one &= kg_sim_noise_apply(&n, 1.5, &r) == 1.0;
		/* Below black only read noise remains; the negative half clips to 0. */
		double b = kg_sim_noise_apply(&n, -0.2, &r);
		negative += b < 0.0;
		zeros += b == 0.0;
		double x = kg_sim_noise_apply(&n, 1.0, &r);
		max_one += x == 1.0;
		above += x > 1.0;
	}
	CHECK(all_one, "a value above full scale is not clipped to exactly 1");
	CHECK(negative == 0 && zeros > 9000,
	      "below black: %d of 20000 negative, %d at 0 (expected none and about half)",
	      negative, zeros);
	/* At exactly full scale half the draws exceed the well and clip. */
	CHECK(max_one > 8000 && above == 0, "at full scale: %d of 20000 at 1, %d above",
	      max_one, above);
	/* Noise-free values pass through unchanged, even out of range. */
	kg_sim_noise none;
	CHECK(kg_sim_noise_parse("none", &none, NULL) == 0, "parse none");
	CHECK(kg_sim_noise_apply(&none, 1.25, &r) == 1.25, "none changed a value");
	CHECK(!kg_sim_noise_enabled(&none), "none reported as enabled");
}

static void test_parse(void)
{
	static const char *const bad[] = {"",       "20000",      "20000:5",    "20000:5:13",
	                                  "0:5:12", "-1:2:8",     "abc",        "20000:x:12",
	                                  "1e3:-1:8", "20000:5:12:1", "20000:5:12x", "nan:1:8"};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		kg_sim_noise n;
		kg_err err = {{0}};
		CHECK(kg_sim_noise_parse(bad[i], &n, &err) == KG_EINVAL, "'%s' accepted", bad[i]);
		CHECK(strstr(err.msg, "noise") != NULL, "'%s': message '%s' does not say noise",
		      bad[i], err.msg);
	}
	kg_sim_noise n, back;
	CHECK(kg_sim_noise_parse("12345.5:2.25:14", &n, NULL) == 0, "parse");
	CHECK(n.full_well == 12345.5 && n.read_noise == 2.25 && n.bits == 14, "fields");
	char text[128];
	kg_sim_noise_format(&n, text, sizeof(text));
	CHECK(kg_sim_noise_parse(text, &back, NULL) == 0 && memcmp(&n, &back, sizeof(n)) == 0,
	      "'%s' does not round-trip", text);
}

int main(void)
{
	test_determinism();
	test_uniform_normal();
	test_poisson();
	test_noise_model();
	test_clipping();
	test_parse();
	return kg_test_done("sim/noise");
}
