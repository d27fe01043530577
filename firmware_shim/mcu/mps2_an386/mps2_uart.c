/* mps2_uart.c - CMSDK APB UART driver, polled (see mps2_uart.h). */
#include "mps2_uart.h"

#include <string.h>

#define REG(base, off) (*(volatile uint32_t *)((base) + (off)))
#define UART_DATA 0x00u
#define UART_STATE 0x04u
#define UART_CTRL 0x08u
#define UART_INTCLEAR 0x0Cu
#define UART_BAUDDIV 0x10u

#define STATE_TXFULL 0x1u
#define STATE_RXFULL 0x2u
#define CTRL_TX_EN 0x1u
#define CTRL_RX_EN 0x2u
#define CTRL_RX_INT_EN 0x8u
#define INT_RX 0x2u

#define NVIC_ISER0 (*(volatile uint32_t *)0xE000E100u)

void mps2_uart_init(uint32_t base, int rx_wakeup)
{
    REG(base, UART_BAUDDIV) = 16u; /* the smallest divider the CMSDK UART allows */
    REG(base, UART_CTRL) = CTRL_TX_EN | CTRL_RX_EN | (rx_wakeup ? CTRL_RX_INT_EN : 0u);
    if (rx_wakeup && base == MPS2_UART0_BASE) NVIC_ISER0 = 1u << 0; /* IRQ 0: UART0 RX */
}

int mps2_uart_rx_ready(uint32_t base) { return (REG(base, UART_STATE) & STATE_RXFULL) != 0u; }

int mps2_uart_getc(uint32_t base)
{
    if (!mps2_uart_rx_ready(base)) return -1;
    return (int)(REG(base, UART_DATA) & 0xFFu);
}

void mps2_uart_putc(uint32_t base, uint8_t c)
{
    while (REG(base, UART_STATE) & STATE_TXFULL) {
    }
    REG(base, UART_DATA) = c;
}

void mps2_uart_write(uint32_t base, const char *s, uint32_t n)
{
    for (uint32_t i = 0; i < n; ++i) mps2_uart_putc(base, (uint8_t)s[i]);
}

void mps2_uart_rx_isr(uint32_t base) { REG(base, UART_INTCLEAR) = INT_RX; }

void mps2_uart_console(const char *s) { mps2_uart_write(MPS2_UART1_BASE, s, (uint32_t)strlen(s)); }

void mps2_uart_console_u32(uint32_t v)
{
    char buf[10];
    uint32_t n = 0u;
    do {
        buf[n++] = (char)('0' + v % 10u);
        v /= 10u;
    } while (v != 0u);
    while (n > 0u) mps2_uart_putc(MPS2_UART1_BASE, (uint8_t)buf[--n]);
}
