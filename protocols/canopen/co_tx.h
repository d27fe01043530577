/* co_tx.h - the transmit side of the CAN driver as every CANopen service sees it
 * (CANopenNode's CO_CANmodule_t, reduced to sending): the driver's callback and
 * the node's frame counters. The node owns one; its services send through it.
 */
#ifndef CO_TX_H
#define CO_TX_H

#include <stdint.h>

#include "co_frame.h"

typedef struct {
    co_tx_fn fn; /* NULL: every send fails */
    void *user;
    uint32_t frames; /* frames the driver accepted */
    uint32_t errors; /* frames it refused */
} co_tx_t;

void co_tx_init(co_tx_t *tx, co_tx_fn fn, void *user);

/* Send an 11-bit frame of dlc bytes; returns the driver's result (0 = queued). */
int co_tx_send(co_tx_t *tx, uint16_t cob_id, const uint8_t *data, uint8_t dlc);
/* The same with the frame's flags (CO_FRAME_FDF, CO_FRAME_BRS): more than 8 bytes need CO_FRAME_FDF and go out
 * padded with zeros to the next CAN FD length (co_frame_fd_len); a length the frame cannot hold is refused. */
int co_tx_send_fd(co_tx_t *tx, uint16_t cob_id, const uint8_t *data, uint8_t dlc, uint8_t flags);

#endif /* CO_TX_H */
