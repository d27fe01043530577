/*
 * plant_rng.h - deterministic PRNG for the plant emulator.
 *
 * xoshiro256** (Blackman & Vigna, public domain reference algorithm) seeded
 * through splitmix64, plus a Box-Muller Gaussian generator that caches the
 * second variate of each pair.  Same seed -> bit-identical sequence on any
 * platform whose libm returns the same log/sqrt/cos/sin (IEEE double).
 */
#ifndef PLANT_RNG_H
#define PLANT_RNG_H

#include <stdbool.h>
#include <stdint.h>

typedef struct {
    uint64_t s[4];
    double gauss_spare;
    bool have_spare;
} plant_rng_t;

/* Seed with splitmix64(seed); any seed (including 0) gives a valid state. */
void plant_rng_seed(plant_rng_t *r, uint64_t seed);
/* Next raw 64-bit output. */
uint64_t plant_rng_next_u64(plant_rng_t *r);
/* Uniform in [0, 1) with 53 random bits. */
double plant_rng_uniform(plant_rng_t *r);
/* Standard normal N(0, 1) via Box-Muller (pairs, second value cached). */
double plant_rng_gauss(plant_rng_t *r);

#endif
