/* plant_rtstats.h - one real-time timing quantity of the plant (SYNC lateness, turnaround): exact count,
 * min, max (and the period it happened in), mean, and a log-linear histogram from which percentiles are
 * read. The histogram's counts are also kept as little-endian bytes, the layout of the DOMAIN 0x2006
 * (plant.eds: its Description gives the bins). Portable: no OS headers, no allocation. */
#ifndef PLANT_RTSTATS_H
#define PLANT_RTSTATS_H

#include <stdint.h>

/* Bins: [b, b+1) us for b < 64; then 16 per octave, 2^e us .. 2^(e+1) us for e = 6..19; the last bin
 * also holds later values (above ~1 s). */
#define PLANT_RTSTATS_LINEAR_BINS 64u
#define PLANT_RTSTATS_SUB_BINS 16u
#define PLANT_RTSTATS_OCTAVES 14u
#define PLANT_RTSTATS_BINS (PLANT_RTSTATS_LINEAR_BINS + PLANT_RTSTATS_SUB_BINS * PLANT_RTSTATS_OCTAVES)

typedef struct {
    uint64_t n;
    int64_t min_ns;
    int64_t max_ns;
    int64_t sum_ns;
    uint64_t max_at; /* the caller's index (period) of the largest value */
    uint32_t bins[PLANT_RTSTATS_BINS];
    uint8_t *bytes; /* PLANT_RTSTATS_BINS x UNSIGNED32 LE, kept equal to bins (NULL: none) */
} plant_rtstats_t;

/* Zero the statistics; bytes (may be NULL) is their DOMAIN image of PLANT_RTSTATS_BINS * 4 bytes. */
void plant_rtstats_init(plant_rtstats_t *s, uint8_t *bytes);
/* One value (negative values count as 0), taken at index `at`. */
void plant_rtstats_add(plant_rtstats_t *s, int64_t value_ns, uint64_t at);
/* The bin of a value in us (>= 0). */
uint32_t plant_rtstats_bin(int64_t value_us);
/* The q-quantile (0 < q <= 1) in us: the upper edge of the bin holding the ceil(q n)-th value, at most the
 * maximum (0 when empty). */
double plant_rtstats_quantile_us(const plant_rtstats_t *s, double q);
double plant_rtstats_mean_us(const plant_rtstats_t *s);

#endif /* PLANT_RTSTATS_H */
