/* xoshiro256** (Blackman and Vigna, 2018) seeded through splitmix64, with normal
 * deviates by Marsaglia's polar method and Poisson deviates by inversion (small
 * means) or Hormann's transformed rejection PTRS (means of 10 and more). All state
 * lives in the kg_rng the caller passes, so a seed fixes every draw. */
#include <math.h>

#include "rng.h"

static uint64_t splitmix64(uint64_t *x)
{
	uint64_t z = (*x += 0x9e3779b97f4a7c15ULL);
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
	return z ^ (z >> 31);
}

static inline uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

void kg_rng_seed(kg_rng *r, uint64_t seed)
{
	uint64_t x = seed;
	for (int i = 0; i < 4; i++)
		r->s[i] = splitmix64(&x);
	r->has_spare = 0;
	r->spare = 0.0;
}

uint64_t kg_rng_next(kg_rng *r)
{
	uint64_t *s = r->s;
	uint64_t result = rotl(s[1] * 5, 7) * 9;
	uint64_t t = s[1] << 17;
	s[2] ^= s[0];
	s[3] ^= s[1];
	s[1] ^= s[2];
	s[0] ^= s[3];
	s[2] ^= t;
	s[3] = rotl(s[3], 45);
	return result;
}

double kg_rng_uniform(kg_rng *r)
{
	/* The top 53 bits give every double in [0, 1) with spacing 2^-53. */
	return (double)(kg_rng_next(r) >> 11) * 0x1.0p-53;
}

double kg_rng_normal(kg_rng *r)
{
	if (r->has_spare) {
		r->has_spare = 0;
		return r->spare;
	}
	double u, v, s;
	do {
		u = 2.0 * kg_rng_uniform(r) - 1.0;
		v = 2.0 * kg_rng_uniform(r) - 1.0;
		s = u * u + v * v;
	} while (s >= 1.0 || s == 0.0);
	double f = sqrt(-2.0 * log(s) / s);
	r->spare = v * f;
	r->has_spare = 1;
	return u * f;
}

/* Inversion by sequential search: exact, and cheap while the mean is small. */
static double poisson_inversion(kg_rng *r, double mean)
{
	double u = kg_rng_uniform(r);
	double p = exp(-mean);
	double cdf = p;
	double k = 0.0;
	/* The 1000 cap only guards against rounding in the tail (mean < 10 here). */
	while (u > cdf && k < 1000.0) {
		k += 1.0;
		p *= mean / k;
		cdf += p;
	}
	return k;
}

/* W. Hormann, "The transformed rejection method for generating Poisson random
 * variables", Insurance: Mathematics and Economics 12 (1993) 39-45, algorithm PTRS
 * (valid for mean >= 10). */
static double poisson_ptrs(kg_rng *r, double mean)
{
	double smu = sqrt(mean);
	double log_mean = log(mean);
	double b = 0.931 + 2.53 * smu;
	double a = -0.059 + 0.02483 * b;
	double inv_alpha = 1.1239 + 1.1328 / (b - 3.4);
	double v_r = 0.9277 - 3.6224 / (b - 2.0);
	for (;;) {
		double u = kg_rng_uniform(r) - 0.5;
		double v = kg_rng_uniform(r);
		double us = 0.5 - fabs(u);
		double k = floor((2.0 * a / us + b) * u + mean + 0.43);
		if (us >= 0.07 && v <= v_r)
			return k;
		if (k < 0.0 || (us < 0.013 && v > us))
			continue;
		if (log(v) + log(inv_alpha) - log(a / (us * us) + b) <=
		    -mean + k * log_mean - lgamma(k + 1.0))
			return k;
	}
}

double kg_rng_poisson(kg_rng *r, double mean)
{
	if (!(mean > 0.0))
		return 0.0;
	return mean < 10.0 ? poisson_inversion(r, mean) : poisson_ptrs(r, mean);
}
