/* mps2_systick_time.h - a SysTick reading as ticks since start: the arithmetic and the read protocol, with
 * no register address (portable; host-tested by firmware_shim/tests/test_mps2_systick.c).
 *
 * ARMv7-M (ARM DDI 0403E, B3.3 "The system timer, SysTick"): the counter counts down RELOAD-1, ..., 1, 0;
 * the step 1 -> 0 pends the SysTick exception (ICSR.PENDSTSET) and is the millisecond boundary; the next
 * clock loads RELOAD-1.  At a boundary the counter reads 0, one tick later RELOAD-1, so the ticks since the
 * last boundary are (RELOAD - CVR) mod RELOAD.  The handler counts boundaries (`ms`).  Between a boundary and
 * its handler (interrupts masked, a higher priority running, QEMU taking it at the end of the translated
 * block) the exception is pending and that boundary is not yet in `ms`: PENDSTSET adds it.
 *
 * Reading `RELOAD-1 - CVR` (as this file did before) puts the boundary one tick late: in the one tick after
 * the handler has run, with CVR still 0, the time came out one whole reload ahead, and a step cost measured
 * across it 25,000 ticks long (25,034 for 34: an overrun, the drive in its safe state, under host load). */
#ifndef MPS2_SYSTICK_TIME_H
#define MPS2_SYSTICK_TIME_H

#include <stdint.h>

typedef enum {
    MPS2_SYSTICK_REG_MS,      /* the handler's count of boundaries */
    MPS2_SYSTICK_REG_CVR,     /* SYST_CVR, the down-counter */
    MPS2_SYSTICK_REG_PENDING, /* ICSR.PENDSTSET: 1 while a boundary waits for its handler */
} mps2_systick_reg_t;

/* Reads one of the three (the hardware's registers on the target, a model in the host test). */
typedef uint32_t (*mps2_systick_read_fn)(void *ctx, mps2_systick_reg_t reg);

/* Ticks since start of one consistent reading. */
static inline uint64_t mps2_systick_compose(uint32_t ms, uint32_t cvr, uint32_t pending, uint32_t reload)
{
    const uint64_t boundaries = (uint64_t)ms + (pending != 0u ? 1u : 0u);
    const uint32_t since_boundary = cvr == 0u ? 0u : reload - cvr;
    return boundaries * reload + since_boundary;
}

/* A consistent reading: PENDSTSET the same before and after CVR (no boundary between them), the handler's
 * count the same before and after (it did not run in between); otherwise read again.  A boundary comes once
 * per RELOAD ticks, so the loop ends at its second try at most. */
static inline uint64_t mps2_systick_read(mps2_systick_read_fn rd, void *ctx, uint32_t reload)
{
    uint32_t ms, pending, cvr;
    for (;;) {
        ms = rd(ctx, MPS2_SYSTICK_REG_MS);
        pending = rd(ctx, MPS2_SYSTICK_REG_PENDING);
        cvr = rd(ctx, MPS2_SYSTICK_REG_CVR);
        if (rd(ctx, MPS2_SYSTICK_REG_PENDING) == pending && rd(ctx, MPS2_SYSTICK_REG_MS) == ms) break;
    }
    return mps2_systick_compose(ms, cvr, pending, reload);
}

#endif /* MPS2_SYSTICK_TIME_H */
