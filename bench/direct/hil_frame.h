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

#endif
