/* hil_frame.h - the bench's frame record, shared by the direct-mode recorder
 * (hil_master.c) and the candump log formatter/parser (hil_log.c).
 * numpy dtype: FRAME_DTYPE in bench/run/bus/frames.py (must stay 24 bytes, same layout). */
#ifndef HIL_FRAME_H
#define HIL_FRAME_H

#include <stdint.h>

typedef struct {
    uint64_t t_us;   /* simulated time (direct mode) or absolute µs since the epoch (a log) */
    uint32_t seq;    /* bus order */
    uint16_t cob_id; /* 11-bit identifier */
    uint8_t dlc;     /* data bytes, 0..8 */
    uint8_t sender;  /* 0 plant, 1 drive, 255 master or unknown (a log) */
    uint8_t data[8]; /* bytes past dlc are 0 */
} hil_frame_t;

_Static_assert(sizeof(hil_frame_t) == 24, "hil_frame_t must match FRAME_DTYPE (24 bytes)");

/* The record of a run whose PDOs travel in CAN FD frames (0x2105): the same fields at the same offsets, the data
 * 64 bytes, and the frame's flags. numpy dtype: FRAME_FD_DTYPE (88 bytes). A classic run keeps the 24-byte record:
 * its memory and speed do not change. */
#define HIL_FRAME_FDF 0x01u /* a CAN FD frame */
#define HIL_FRAME_BRS 0x02u /* with bit-rate switch */

typedef struct {
    uint64_t t_us;
    uint32_t seq;
    uint16_t cob_id;
    uint8_t dlc; /* data bytes: 0..8, and for a CAN FD frame 12, 16, 20, 24, 32, 48 or 64 */
    uint8_t sender;
    uint8_t data[64]; /* bytes past dlc are 0 */
    uint8_t flags;    /* HIL_FRAME_FDF, HIL_FRAME_BRS */
    uint8_t pad[7];
} hil_frame_fd_t;

_Static_assert(sizeof(hil_frame_fd_t) == 88, "hil_frame_fd_t must match FRAME_FD_DTYPE (88 bytes)");

#endif
