/* hil_master.h - what the bench's master sees of the in-process bus: the recorder (every frame on the plant's side
 * of the bus, into the caller's buffer) and the master's receive queue (the nodes' frames outside a run: hil_recv,
 * an SDO's answer). The bus (hil_direct.c) hands it each frame (hil_master_record); it knows nothing of the bus. */
#ifndef HIL_MASTER_H
#define HIL_MASTER_H

#include <stdint.h>

#include "co_frame.h"
#include "hil_frame.h" /* hil_frame_t, 24 bytes; numpy dtype FRAME_DTYPE */

/* ---- libhil.so's API (ctypes: bench/run/bus/direct.py) */

/* Recorder: every frame on the bus goes into the caller's buffer (no allocation here): hil_frame_t records, or
 * hil_frame_fd_t after hil_set_recorder_fd(1) (a run whose PDOs are CAN FD; a classic record cannot hold a frame
 * of more than 8 bytes: it counts as dropped). */
void hil_set_recorder(void *buf, uint32_t capacity);
void hil_set_recorder_fd(int wide);
/* The frames recorded so far (their count, returned) and a fresh buffer for the next ones, in one step under
 * the bus lock (real time: the nodes' threads record while the caller takes). */
uint32_t hil_take(void *buf, uint32_t capacity);
uint32_t hil_recorded(void);
uint64_t hil_record_dropped(void);
/* Next frame of the nodes for the master; returns 1 when one was copied. */
int hil_recv(hil_frame_t *out);

/* ---- for the bus (hil_direct.c) */

/* hil_open: no recorder, the master's queue empty, the bus order from 0. */
void hil_master_reset(void);
/* A frame on the plant's side of the bus, from `sender` (a bus port, CO_MEMBUS_EXTERNAL: the master's or the
 * injector's) at t_us: recorded, and queued for the master when a node sent it outside a run (`running`: the
 * master reads the loop's frames from the recorder). */
void hil_master_record(const co_frame_t *f, uint8_t sender, int64_t t_us, int running);
/* Where the master's queue ends now (for hil_master_answer). */
uint32_t hil_master_mark(void);
/* The first frame on resp_cob of 8 bytes queued since `mark`: taken out of the queue into resp (the others stay
 * queued); returns 1 when there was one, else 0. */
int hil_master_answer(uint32_t mark, uint16_t resp_cob, uint8_t resp[8]);

#endif /* HIL_MASTER_H */
