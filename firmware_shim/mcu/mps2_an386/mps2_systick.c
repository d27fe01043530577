/* mps2_systick.c - SysTick time base (see mps2_systick.h; the arithmetic in mps2_systick_time.h). */
#include "mps2_systick.h"

#include <stddef.h>

#include "mps2_systick_time.h"

#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SCB_ICSR (*(volatile uint32_t *)0xE000ED04u)
#define CSR_ENABLE 0x1u
#define CSR_TICKINT 0x2u
#define CSR_CLKSOURCE 0x4u
#define ICSR_PENDSTSET_SHIFT 26u

static volatile uint32_t g_ms; /* boundaries whose handler has run */

void mps2_systick_init(void)
{
    g_ms = 0u;
    SYST_RVR = MPS2_SYSTICK_RELOAD - 1u;
    SYST_CVR = 0u;
    SYST_CSR = CSR_ENABLE | CSR_TICKINT | CSR_CLKSOURCE;
}

void mps2_systick_isr(void) { g_ms = g_ms + 1u; }

static uint32_t read_register(void *ctx, mps2_systick_reg_t reg)
{
    (void)ctx;
    switch (reg) {
    case MPS2_SYSTICK_REG_MS: return g_ms;
    case MPS2_SYSTICK_REG_CVR: return SYST_CVR;
    case MPS2_SYSTICK_REG_PENDING: return (SCB_ICSR >> ICSR_PENDSTSET_SHIFT) & 1u;
    }
    return 0u;
}

uint64_t mps2_systick_ticks(void) { return mps2_systick_read(read_register, NULL, MPS2_SYSTICK_RELOAD); }
