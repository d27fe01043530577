/* drive_port_mps2.c - drive_port.h on the MPS2 AN386 image: CAN as SLCAN over
 * UART0 (the host runs slcand or python-can's slcan interface on the serial
 * line; under QEMU a TCP socket), SysTick as the clock and the cycle counter, WFI
 * as the idle hook (UART0 RX and the 1 ms SysTick wake it). */
#include <stdint.h>

#include "drive_port.h"
#include "drive_port_mps2.h"
#include "mps2_systick.h"
#include "mps2_uart.h"
#include "slcan.h"

static slcan_parser_t g_slcan;

void drive_port_mps2_init(void)
{
    mps2_uart_init(MPS2_UART0_BASE, 1);
    mps2_uart_init(MPS2_UART1_BASE, 0);
    mps2_systick_init();
    slcan_init(&g_slcan);
}

uint32_t drive_port_mps2_slcan_errors(void) { return g_slcan.errors; }

int drive_port_can_send(const co_frame_t *frame)
{
    if (!g_slcan.open) return 1; /* a closed SLCAN channel sends nothing (Lawicel) */
    char line[SLCAN_FRAME_MAX];
    const uint8_t n = slcan_encode(frame, line);
    if (n == 0u) return 1;
    mps2_uart_write(MPS2_UART0_BASE, line, n);
    return 0;
}

int drive_port_can_receive(co_frame_t *frame)
{
    for (;;) {
        const int c = mps2_uart_getc(MPS2_UART0_BASE);
        if (c < 0) return 0;
        slcan_reply_t reply;
        const int got = slcan_feed(&g_slcan, (uint8_t)c, frame, &reply);
        if (reply.len != 0u) mps2_uart_write(MPS2_UART0_BASE, reply.text, reply.len);
        if (got) return 1;
    }
}

int64_t drive_port_time_us(void) { return (int64_t)(mps2_systick_ticks() / (MPS2_SYSTICK_HZ / 1000000u)); }

uint32_t drive_port_cycles(void) { return (uint32_t)mps2_systick_ticks(); }

uint32_t drive_port_cycle_clock_Hz(void) { return MPS2_SYSTICK_HZ; }

void drive_port_idle(void)
{
    /* interrupts masked while checking: a byte arriving in between still ends the WFI */
    __asm volatile("cpsid i" ::: "memory");
    if (!mps2_uart_rx_ready(MPS2_UART0_BASE)) __asm volatile("wfi" ::: "memory");
    __asm volatile("cpsie i" ::: "memory");
}
