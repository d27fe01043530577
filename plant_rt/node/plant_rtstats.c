/* plant_rtstats.c - see plant_rtstats.h. */
#include "plant_rtstats.h"

#include <string.h>

void plant_rtstats_init(plant_rtstats_t *s, uint8_t *bytes)
{
    memset(s, 0, sizeof *s);
    s->bytes = bytes;
    if (bytes) memset(bytes, 0, PLANT_RTSTATS_BINS * 4u);
}

uint32_t plant_rtstats_bin(int64_t value_us)
{
    if (value_us < (int64_t)PLANT_RTSTATS_LINEAR_BINS) return value_us < 0 ? 0u : (uint32_t)value_us;
    uint32_t e = 0;
    while (e < 62u && (value_us >> (e + 1u)) != 0) ++e; /* 2^e <= value < 2^(e+1) */
    if (e >= 6u + PLANT_RTSTATS_OCTAVES) return PLANT_RTSTATS_BINS - 1u;
    uint32_t sub = (uint32_t)((value_us >> (e - 4u)) & (PLANT_RTSTATS_SUB_BINS - 1u));
    return PLANT_RTSTATS_LINEAR_BINS + (e - 6u) * PLANT_RTSTATS_SUB_BINS + sub;
}

/* The upper edge of bin b, us. */
static double bin_upper_us(uint32_t b)
{
    if (b < PLANT_RTSTATS_LINEAR_BINS) return (double)(b + 1u);
    uint32_t e = 6u + (b - PLANT_RTSTATS_LINEAR_BINS) / PLANT_RTSTATS_SUB_BINS;
    uint32_t sub = (b - PLANT_RTSTATS_LINEAR_BINS) % PLANT_RTSTATS_SUB_BINS;
    return (double)((1ull << e) + (uint64_t)(sub + 1u) * (1ull << (e - 4u)));
}

void plant_rtstats_add(plant_rtstats_t *s, int64_t value_ns, uint64_t at)
{
    if (value_ns < 0) value_ns = 0;
    if (s->n == 0u || value_ns < s->min_ns) s->min_ns = value_ns;
    if (s->n == 0u || value_ns > s->max_ns) {
        s->max_ns = value_ns;
        s->max_at = at;
    }
    ++s->n;
    s->sum_ns += value_ns;
    uint32_t b = plant_rtstats_bin(value_ns / 1000);
    uint32_t v = ++s->bins[b];
    if (s->bytes) {
        uint8_t *p = &s->bytes[b * 4u];
        p[0] = (uint8_t)v;
        p[1] = (uint8_t)(v >> 8);
        p[2] = (uint8_t)(v >> 16);
        p[3] = (uint8_t)(v >> 24);
    }
}

double plant_rtstats_quantile_us(const plant_rtstats_t *s, double q)
{
    if (s->n == 0u) return 0.0;
    double max_us = (double)s->max_ns * 1e-3;
    uint64_t rank = (uint64_t)(q * (double)s->n);
    if ((double)rank < q * (double)s->n) ++rank; /* ceil */
    if (rank == 0u) rank = 1u;
    uint64_t cum = 0;
    for (uint32_t b = 0; b < PLANT_RTSTATS_BINS; ++b) {
        cum += s->bins[b];
        if (cum >= rank) {
            double up = bin_upper_us(b);
            return up < max_us ? up : max_us;
        }
    }
    return max_us;
}

double plant_rtstats_mean_us(const plant_rtstats_t *s)
{
    return s->n == 0u ? 0.0 : (double)s->sum_ns * 1e-3 / (double)s->n;
}
