/* co_socketcan.h - thin Linux SocketCAN driver for the portable CANopen core. */
#ifndef CO_SOCKETCAN_H
#define CO_SOCKETCAN_H

#include <stdint.h>
#include "co_frame.h"

/* Opens a raw CAN socket bound to `ifname` (e.g. "vcan0", "can0").
 * rcvbuf_bytes > 0 enlarges the kernel receive buffer (recorders use this).
 * Returns the socket fd, or -1 with a message on stderr. */
int co_socketcan_open(const char *ifname, int rcvbuf_bytes);

/* co_tx_fn-compatible transmit; `user` points to the int fd. */
int co_socketcan_send(void *user, const co_frame_t *frame);

/* Waits up to timeout_us (negative: forever) for one frame.
 * Returns 1 with *frame filled, 0 on timeout, -1 on error. If ts_ns is not NULL
 * it receives the kernel receive time stamp (CLOCK_REALTIME, ns). */
int co_socketcan_recv(int fd, co_frame_t *frame, int64_t timeout_us, int64_t *ts_ns);

/* Monotonic clock in microseconds. */
int64_t co_socketcan_now_us(void);

#endif /* CO_SOCKETCAN_H */
