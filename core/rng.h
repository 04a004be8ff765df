/* Random numbers for simulations and Monte Carlo: xoshiro256** seeded through
 * splitmix64. A plain value with no global state, so output is deterministic for a
 * seed whatever the thread count. */
#ifndef KG_RNG_H
#define KG_RNG_H

#include <stdint.h>

/* xoshiro256** seeded through splitmix64. Plain value; no global state. */
typedef struct kg_rng {
	uint64_t s[4];
	double spare; /* second normal deviate of the polar method */
	int has_spare;
} kg_rng;

void kg_rng_seed(kg_rng *r, uint64_t seed);
uint64_t kg_rng_next(kg_rng *r);
/* Uniform on [0, 1), 53 random bits. */
double kg_rng_uniform(kg_rng *r);
/* Standard normal deviate. */
double kg_rng_normal(kg_rng *r);
/* Poisson deviate (a whole number, returned as double); 0 for mean <= 0 or NaN. */
double kg_rng_poisson(kg_rng *r, double mean);

#endif
