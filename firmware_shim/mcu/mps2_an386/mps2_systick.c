/* mps2_systick.c - SysTick time base (see mps2_systick.h). */
#include "mps2_systick.h"

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define CSR_ENABLE 0x1u
#define CSR_TICKINT 0x2u
#define CSR_CLKSOURCE 0x4u

static volatile uint32_t g_ms; /* reloads since init */
static uint64_t g_last;        /* the last value returned */

void mps2_systick_init(void)
{
    g_ms = 0u;
    g_last = 0u;
    SYST_RVR = MPS2_SYSTICK_RELOAD - 1u;
    SYST_CVR = 0u;
    SYST_CSR = CSR_ENABLE | CSR_TICKINT | CSR_CLKSOURCE;
}

void mps2_systick_isr(void) { g_ms = g_ms + 1u; }

uint64_t mps2_systick_ticks(void)
{
    uint32_t ms, val;
    do { /* a reload between the two reads of g_ms: read again */
        ms = g_ms;
        val = SYST_CVR;
    } while (ms != g_ms);
    uint64_t t = (uint64_t)ms * MPS2_SYSTICK_RELOAD + (MPS2_SYSTICK_RELOAD - 1u - val);
    /* The counter can reload before its exception has run (QEMU raises it at the end of the translated block;
     * on silicon a masked or lower-priority exception waits too): CVR has wrapped, g_ms has not, and t is one
     * reload behind. Time never runs backwards, so a t below the last one counts that reload. Without this a
     * step cost measured across such a reload came out 1 ms long (25033 ticks for 33: an overrun under load). */
    if (t < g_last) t += MPS2_SYSTICK_RELOAD;
    g_last = t;
    return t;
}
