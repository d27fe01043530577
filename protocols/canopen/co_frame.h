/* co_frame.h - the CAN frame as the portable CANopen core sees it.
 *
 * The core never touches sockets: a driver (socketcan/co_socketcan.c on Linux,
 * a CAN peripheral driver on a microcontroller) hands it received frames and
 * gives it a transmit callback (CANopenNode's CO_driver.h split).
 */
#ifndef CO_FRAME_H
#define CO_FRAME_H

#include <stdint.h>

/* The largest payload a frame holds: 64 (CAN FD, ISO 11898-1:2015); a build for a classic-only controller (the
 * Cortex-M4F image) sets 8, and its nodes refuse CAN FD (0x2105 PDO frame format). */
#ifndef CO_FRAME_MAX_DATA
#define CO_FRAME_MAX_DATA 64u
#endif

typedef struct {
    uint32_t cob_id; /* 11-bit identifier (bits 0..10); CO_FRAME_RTR flag in bit 30 */
    uint8_t dlc;     /* the payload's length in bytes (SocketCAN's len, not the 4-bit code): 0..8, and on CAN FD
                      * also 12, 16, 20, 24, 32, 48, 64 */
    uint8_t flags;   /* CO_FRAME_FDF, CO_FRAME_BRS; 0: a classic frame */
    uint8_t data[CO_FRAME_MAX_DATA]; /* the first 8 bytes past dlc are 0; beyond 8 only dlc bytes are defined */
} co_frame_t;

#define CO_FRAME_RTR 0x40000000u
#define CO_FRAME_FDF 0x01u /* a CAN FD frame (FD format) */
#define CO_FRAME_BRS 0x02u /* its data phase at the data bit rate (bit-rate switch) */

/* The CAN FD payload length that holds n bytes: n up to 8, then the next of 12, 16, 20, 24, 32, 48, 64 (a
 * DLC code per length: ISO 11898-1 table 5); 0 when n > 64. */
static inline uint8_t co_frame_fd_len(uint32_t n)
{
    if (n <= 8u) return (uint8_t)n;
    if (n <= 24u) return (uint8_t)((n + 3u) & ~3u);
    if (n <= 32u) return 32u;
    if (n <= 48u) return 48u;
    return n <= 64u ? 64u : 0u;
}

/* Transmit callback: returns 0 when the frame was queued, negative on error. */
typedef int (*co_tx_fn)(void *user, const co_frame_t *frame);

#endif /* CO_FRAME_H */
