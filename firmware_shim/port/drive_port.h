/* drive_port.h - what a target provides to run the drive firmware (the port layer).
 *
 * Modelled on CANopenNode's CO_driver.h: the portable firmware (protocols/canopen,
 * firmware_shim/core, firmware_shim/shim/drive_app.c, drive_firmware.c) calls only
 * these functions; a target implements them once, in its own directory
 * (firmware_shim/mcu/<board>/drive_port_<board>.c).  They are resolved at link
 * time: no function pointers, no OS, no allocation.
 *
 * All are called from the main loop only (drive_firmware_run), never from an
 * interrupt: a target that receives or sends in interrupts puts a queue between
 * its ISR and these functions.
 */
#ifndef DRIVE_PORT_H
#define DRIVE_PORT_H

#include <stdint.h>

#include "co_frame.h"

/* Send one 11-bit CAN frame (frame->cob_id bits 0..10, CO_FRAME_RTR for a remote
 * frame, dlc 0..8).  Returns 0 when the frame was queued or sent, non-zero when it
 * was refused (bus off, queue full, channel closed): the CANopen node counts it in
 * node.tx.errors and goes on. */
int drive_port_can_send(const co_frame_t *frame);

/* Take one received frame if there is one (never blocks): returns 1 and fills
 * *frame, or 0 when nothing is waiting. */
int drive_port_can_receive(co_frame_t *frame);

/* Monotonic time in microseconds since start (heartbeat, SDO timeout, PDO timers). */
int64_t drive_port_time_us(void);

/* A free-running cycle counter (wraps modulo 2^32) and its frequency in Hz, read
 * around every current step for 0x2208 Step cost (DWT->CYCCNT at the core clock on
 * most Cortex-M, SysTick on the QEMU image).  A target without one returns 0 Hz. */
uint32_t drive_port_cycles(void);
uint32_t drive_port_cycle_clock_Hz(void);

/* Nothing to do: called by the main loop when no frame was waiting.  May sleep
 * (WFI) until the next interrupt, provided a received frame and the timer both
 * wake the core. */
void drive_port_idle(void);

#endif /* DRIVE_PORT_H */
