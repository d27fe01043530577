/* mps2_systick.h - SysTick as the time base of the MPS2 AN386 image: it counts
 * the 25 MHz core clock (CLKSOURCE = processor) and interrupts every millisecond;
 * the interrupt extends it to 64 bits.
 *
 * Under QEMU with -icount shift=0 one guest instruction takes 1 ns of virtual time,
 * and SysTick counts that virtual clock at 25 MHz: one tick = 40 ns = 40
 * instructions.  A step cost in ticks times 40 is the instruction count (to +-40). */
#ifndef MPS2_SYSTICK_H
#define MPS2_SYSTICK_H

#include <stdint.h>

#define MPS2_SYSTICK_HZ 25000000u
#define MPS2_SYSTICK_RELOAD 25000u /* ticks per millisecond */

void mps2_systick_init(void);
/* Ticks since mps2_systick_init (64-bit, monotonic). */
uint64_t mps2_systick_ticks(void);
/* The SysTick exception: one more millisecond. */
void mps2_systick_isr(void);

#endif /* MPS2_SYSTICK_H */
