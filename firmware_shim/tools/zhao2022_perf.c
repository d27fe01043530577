/* zhao2022_perf.c - Zhao 2022: ns per current step of its laws:
 * zhao2022_incremental_step (Eq. 22/23) and zhao2022_predictive_step (Eq. 5/6),
 * with a crude first-order plant in the loop so the data are realistic.
 * Usage: zhao2022_perf [steps]   (default 2000000) */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "zhao2022_incremental.h"
#include "zhao2022_predictive.h"

static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

static volatile float sink;

static double bench(int which, long n)
{
    static zhao2022_incremental_state_t inc;
    static zhao2022_predictive_state_t eul;
    const zhao2022_incremental_config_t ci = {48.9f, 14e-3f, 100e-6f, 16.17f};
    const zhao2022_predictive_config_t ce = {48.9f, 14e-3f, 0.18951f, 100e-6f, 16.17f};
    zhao2022_incremental_init(&ci, &inc);
    zhao2022_predictive_init(&ce, &eul);
    float id = 0.0f, iq = 0.0f, vd = 0.0f, vq = 0.0f;
    const float w = 32.09f;
    const double t0 = now_ns();
    for (long k = 0; k < n; ++k) {
        const float iq_ref = (k & 256) ? 0.05f : -0.05f;
        float nd, nq;
        if (which == 0) {
            zhao2022_incremental_step(&inc, 0.0f, iq_ref, id, iq, w, &nd, &nq);
        } else {
            zhao2022_predictive_step(&eul, 0.0f, iq_ref, id, iq, w, &nd, &nq);
        }
        /* previous command acts now (one-period delay), A = 0.705, B = 6.03e-3 */
        id = 0.705f * id + 6.03e-3f * vd;
        iq = 0.705f * iq + 6.03e-3f * (vq - 6.08f);
        vd = nd;
        vq = nq;
        sink = nq;
    }
    return (now_ns() - t0) / (double)n;
}

int main(int argc, char **argv)
{
    long n = argc > 1 ? atol(argv[1]) : 2000000L;
    if (n <= 0) n = 2000000L;
    (void)bench(0, n / 10); /* warm-up */
    (void)bench(1, n / 10);
    const double t_inc = bench(0, n);
    const double t_eul = bench(1, n);
    printf("zhao2022_perf: %ld steps each (host, incl. a 2-line plant)\n", n);
    printf("  zhao2022_incremental_step (Zhao 2022 Eq. 22/23): %.1f ns/step\n", t_inc);
    printf("  zhao2022_predictive_step  (Zhao 2022 Eq. 5/6):   %.1f ns/step\n", t_eul);
    return 0;
}
