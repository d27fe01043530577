/* plant_rng.c - xoshiro256** + splitmix64 + Box-Muller.  See plant_rng.h. */
#include "plant_rng.h"

#include <math.h>

#define PLANT_RNG_TWO_PI 6.283185307179586476925286766559

static uint64_t splitmix64(uint64_t *x)
{
    uint64_t z = (*x += UINT64_C(0x9E3779B97F4A7C15));
    z = (z ^ (z >> 30)) * UINT64_C(0xBF58476D1CE4E5B9);
    z = (z ^ (z >> 27)) * UINT64_C(0x94D049BB133111EB);
    return z ^ (z >> 31);
}

static inline uint64_t rotl64(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

void plant_rng_seed(plant_rng_t *r, uint64_t seed)
{
    uint64_t x = seed;
    for (int i = 0; i < 4; ++i) {
        r->s[i] = splitmix64(&x);
    }
    /* splitmix64 never yields four zero words in a row, but be safe. */
    if ((r->s[0] | r->s[1] | r->s[2] | r->s[3]) == 0u) {
        r->s[0] = UINT64_C(1);
    }
    r->gauss_spare = 0.0;
    r->have_spare = false;
}

uint64_t plant_rng_next_u64(plant_rng_t *r)
{
    uint64_t *s = r->s;
    const uint64_t result = rotl64(s[1] * 5u, 7) * 9u;
    const uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl64(s[3], 45);
    return result;
}

double plant_rng_uniform(plant_rng_t *r) { return (double)(plant_rng_next_u64(r) >> 11) * 0x1.0p-53; }

double plant_rng_gauss(plant_rng_t *r)
{
    if (r->have_spare) {
        r->have_spare = false;
        return r->gauss_spare;
    }
    /* u1 in (0, 1] so log(u1) is finite; u2 in [0, 1). */
    const double u1 = ((double)(plant_rng_next_u64(r) >> 11) + 1.0) * 0x1.0p-53;
    const double u2 = plant_rng_uniform(r);
    const double rad = sqrt(-2.0 * log(u1));
    const double ang = PLANT_RNG_TWO_PI * u2;
    r->gauss_spare = rad * sin(ang);
    r->have_spare = true;
    return rad * cos(ang);
}
