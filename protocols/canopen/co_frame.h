/* co_frame.h - the CAN frame as the portable CANopen core sees it.
 *
 * The core never touches sockets: a driver (socketcan/co_socketcan.c on Linux,
 * a CAN peripheral driver on a microcontroller) hands it received frames and
 * gives it a transmit callback (CANopenNode's CO_driver.h split).
 */
#ifndef CO_FRAME_H
#define CO_FRAME_H

#include <stdint.h>

typedef struct {
    uint32_t cob_id; /* 11-bit identifier (bits 0..10); CO_FRAME_RTR flag in bit 30 */
    uint8_t dlc;     /* 0..8 */
    uint8_t data[8];
} co_frame_t;

#define CO_FRAME_RTR 0x40000000u

/* Transmit callback: returns 0 when the frame was queued, negative on error. */
typedef int (*co_tx_fn)(void *user, const co_frame_t *frame);

#endif /* CO_FRAME_H */
