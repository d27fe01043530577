/* startup_mps2_an386.c - vector table and reset of the MPS2 AN386 image (Cortex-M4F).
 *
 * Reset_Handler: FPU on (CPACR CP10/CP11 full access) before any floating-point
 * instruction, .data copied from its load address, .bss zeroed, then main().
 * The exception handlers use the CMSIS names. */
#include <stdint.h>

#include "mps2_systick.h"
#include "mps2_uart.h"

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;

int main(void);
void Reset_Handler(void);
void HardFault_Handler(void);
void Default_Handler(void);
void SysTick_Handler(void);
void UART0RX_Handler(void);

#define CPACR (*(volatile uint32_t *)0xE000ED88u)

void Reset_Handler(void)
{
    CPACR |= (0xFu << 20); /* CP10, CP11: full access */
    __asm volatile("dsb\n\tisb" ::: "memory");
    const uint32_t *src = &_sidata;
    for (uint32_t *dst = &_sdata; dst < &_edata;) *dst++ = *src++;
    for (uint32_t *dst = &_sbss; dst < &_ebss;) *dst++ = 0u;
    (void)main();
    for (;;) __asm volatile("wfi");
}

void HardFault_Handler(void)
{
    mps2_uart_console("drive_mcu: HardFault\n");
    for (;;) {
    }
}

void SysTick_Handler(void) { mps2_systick_isr(); }

void UART0RX_Handler(void) { mps2_uart_rx_isr(MPS2_UART0_BASE); }

void Default_Handler(void)
{
    mps2_uart_console("drive_mcu: unexpected exception\n");
    for (;;) {
    }
}

typedef void (*vector_t)(void);

/* 16 system exceptions, then the AN386 interrupts up to UART0 RX (IRQ 0). */
__attribute__((section(".vectors"), used)) static const vector_t g_vectors[17] = {
    (vector_t)(uintptr_t)&_estack, /* initial stack pointer */
    Reset_Handler,
    Default_Handler,   /* NMI */
    HardFault_Handler, /* HardFault */
    HardFault_Handler, /* MemManage */
    HardFault_Handler, /* BusFault */
    HardFault_Handler, /* UsageFault */
    0,
    0,
    0,
    0,
    Default_Handler, /* SVCall */
    Default_Handler, /* DebugMonitor */
    0,
    Default_Handler, /* PendSV */
    SysTick_Handler,
    UART0RX_Handler, /* IRQ 0: UART0 RX */
};
