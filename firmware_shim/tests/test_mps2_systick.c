/* test_mps2_systick.c - the MPS2 image's SysTick time base (firmware_shim/mcu/mps2_an386/mps2_systick_time.h)
 * against a model of the ARMv7-M SysTick (ARM DDI 0403E, B3.3): a counter that counts RELOAD-1 ... 0, pends its
 * exception on 1 -> 0, and a handler that runs a chosen number of ticks after it (0: at once; more: masked,
 * or QEMU taking it at the end of its translated block).
 *  (a) every moment of three reloads, every handler delay: one reading's ticks = the model's time, exactly
 *      (the boundary's own tick, CVR = 0 after the handler, is where the old arithmetic was a reload ahead);
 *  (b) the read protocol with time advancing at every register read, so a boundary or the handler falls
 *      between any two of its reads: the ticks are the time of its CVR read, in at most three tries;
 *  (c) a step cost measured across a boundary: the step's own ticks, never a reload more. */
#include <stdint.h>
#include <stdio.h>

#include "../mcu/mps2_an386/mps2_systick_time.h"
#include "check.h"

#define RELOAD 25000u

typedef struct {
    uint64_t k;         /* ticks since the counter started */
    uint64_t delay;     /* ticks from a boundary to its handler */
    uint64_t per_read;  /* ticks one register read takes */
    uint64_t k_at_cvr;  /* the time of the last CVR read */
    unsigned cvr_reads; /* CVR reads of one mps2_systick_read (its tries) */
} systick_model_t;

static uint32_t model_ms(const systick_model_t *m)
{ /* boundaries j >= 1 at j*RELOAD whose handler has run */
    return m->k < m->delay ? 0u : (uint32_t)((m->k - m->delay) / RELOAD);
}

static uint32_t model_pending(const systick_model_t *m) { return (uint32_t)(m->k / RELOAD) - model_ms(m); }

static uint32_t model_cvr(const systick_model_t *m) { return (uint32_t)((RELOAD - m->k % RELOAD) % RELOAD); }

static uint32_t model_read(void *ctx, mps2_systick_reg_t reg)
{
    systick_model_t *m = ctx;
    m->k += m->per_read;
    switch (reg) {
    case MPS2_SYSTICK_REG_MS: return model_ms(m);
    case MPS2_SYSTICK_REG_PENDING: return model_pending(m);
    case MPS2_SYSTICK_REG_CVR:
        m->k_at_cvr = m->k;
        ++m->cvr_reads;
        return model_cvr(m);
    }
    return 0u;
}

static const uint64_t DELAYS[] = {0u, 1u, 2u, 3u, 7u, 40u, 1000u};
#define N_DELAYS (sizeof DELAYS / sizeof DELAYS[0])

int main(void)
{
    unsigned wrong = 0u;
    for (size_t d = 0; d < N_DELAYS; ++d) {
        systick_model_t m = {.delay = DELAYS[d]};
        for (m.k = 0u; m.k < 3u * RELOAD + 100u; ++m.k) {
            const uint64_t t = mps2_systick_compose(model_ms(&m), model_cvr(&m), model_pending(&m), RELOAD);
            if (t != m.k && wrong++ < 5u)
                printf("(a) delay %llu, tick %llu: read %llu\n", (unsigned long long)m.delay, (unsigned long long)m.k,
                       (unsigned long long)t);
        }
    }
    CHECK(wrong == 0u, "(a) %u moments read wrong", wrong);
    printf("(a) every tick of 3 reloads, handler delays 0..1000 ticks: the reading is the time\n");

    unsigned bad = 0u, most_tries = 0u;
    for (size_t d = 0; d < N_DELAYS; ++d) {
        for (uint64_t per_read = 1u; per_read <= 3u; ++per_read) {
            for (uint64_t j = 1u; j <= 2u; ++j) {
                for (uint64_t start = j * RELOAD - 20u; start < j * RELOAD + DELAYS[d] + 20u; ++start) {
                    systick_model_t m = {.k = start, .delay = DELAYS[d], .per_read = per_read};
                    const uint64_t t = mps2_systick_read(model_read, &m, RELOAD);
                    if (m.cvr_reads > most_tries) most_tries = m.cvr_reads;
                    if (t != m.k_at_cvr && bad++ < 5u)
                        printf("(b) delay %llu, %llu ticks a read, from %llu: read %llu at %llu\n",
                               (unsigned long long)m.delay, (unsigned long long)per_read, (unsigned long long)start,
                               (unsigned long long)t, (unsigned long long)m.k_at_cvr);
                }
            }
        }
    }
    CHECK(bad == 0u, "(b) %u readings not the time of their CVR read", bad);
    CHECK(most_tries <= 3u, "(b) a reading took %u tries", most_tries);
    printf("(b) boundary and handler between any two reads: exact, at most %u tries\n", most_tries);

    unsigned long_steps = 0u;
    for (size_t d = 0; d < N_DELAYS; ++d) {
        for (uint64_t start = RELOAD - 60u; start < RELOAD + DELAYS[d] + 60u; ++start) {
            systick_model_t m = {.k = start, .delay = DELAYS[d], .per_read = 1u};
            const uint64_t c0 = mps2_systick_read(model_read, &m, RELOAD);
            const uint64_t k0 = m.k_at_cvr;
            m.k += 34u; /* the step */
            const uint64_t c1 = mps2_systick_read(model_read, &m, RELOAD);
            if (c1 - c0 != m.k_at_cvr - k0 || c1 - c0 >= RELOAD) ++long_steps;
        }
    }
    CHECK(long_steps == 0u, "(c) %u step costs not the step's ticks", long_steps);
    printf("(c) a 34-tick step across a boundary costs its own ticks\n");
    return check_finish("test_mps2_systick");
}
