/* drive_port_mps2.h - set-up of the MPS2 AN386 port (drive_port_mps2.c). */
#ifndef DRIVE_PORT_MPS2_H
#define DRIVE_PORT_MPS2_H

#include <stdint.h>

/* UART0 (SLCAN, RX wakes WFI), UART1 (console), SysTick, the SLCAN parser. */
void drive_port_mps2_init(void);

/* SLCAN lines refused with BELL so far. */
uint32_t drive_port_mps2_slcan_errors(void);

#endif /* DRIVE_PORT_MPS2_H */
