/* mps2_systick.c - SysTick time base (see mps2_systick.h). */
#include "mps2_systick.h"

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define CSR_ENABLE 0x1u
#define CSR_TICKINT 0x2u
#define CSR_CLKSOURCE 0x4u

static volatile uint32_t g_ms; /* reloads since init */

void mps2_systick_init(void)
{
    g_ms = 0u;
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
    return (uint64_t)ms * MPS2_SYSTICK_RELOAD + (MPS2_SYSTICK_RELOAD - 1u - val);
}
