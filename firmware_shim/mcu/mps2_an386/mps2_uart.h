/* mps2_uart.h - CMSDK APB UART of the MPS2 AN386 image (QEMU mps2-an386: UART0 at
 * 0x40004000 carries SLCAN, UART1 at 0x40005000 a text console).  Polled; the RX
 * interrupt of UART0 only wakes the core from WFI. */
#ifndef MPS2_UART_H
#define MPS2_UART_H

#include <stdint.h>

#define MPS2_SYSCLK_HZ 25000000u /* SYSCLK of the FPGA image (QEMU: SYSCLK_FRQ) */
#define MPS2_UART0_BASE 0x40004000u
#define MPS2_UART1_BASE 0x40005000u

void mps2_uart_init(uint32_t base, int rx_wakeup);
/* Received byte waiting? (STATE.RXFULL) */
int mps2_uart_rx_ready(uint32_t base);
/* One received byte, -1 when none. */
int mps2_uart_getc(uint32_t base);
void mps2_uart_putc(uint32_t base, uint8_t c);
void mps2_uart_write(uint32_t base, const char *s, uint32_t n);
/* UART0 RX interrupt: clears it (the byte stays for mps2_uart_getc). */
void mps2_uart_rx_isr(uint32_t base);

/* Text on the console (UART1). */
void mps2_uart_console(const char *s);
void mps2_uart_console_u32(uint32_t v);

#endif /* MPS2_UART_H */
