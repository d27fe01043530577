/* co_tx.c - sending a frame through the driver (see co_tx.h). */
#include "co_tx.h"

#include <string.h>

void co_tx_init(co_tx_t *tx, co_tx_fn fn, void *user)
{
    memset(tx, 0, sizeof *tx);
    tx->fn = fn;
    tx->user = user;
}

int co_tx_send(co_tx_t *tx, uint16_t cob_id, const uint8_t *data, uint8_t dlc)
{
    return co_tx_send_fd(tx, cob_id, data, dlc, 0u);
}

int co_tx_send_fd(co_tx_t *tx, uint16_t cob_id, const uint8_t *data, uint8_t dlc, uint8_t flags)
{
    co_frame_t f;
    f.cob_id = (uint32_t)(cob_id & 0x7FFu);
    f.flags = flags;
    memset(f.data, 0, 8);
    if (dlc == 8u) {
        memcpy(f.data, data, 8); /* a PDO's usual size: a copy of a constant size, no call */
        f.dlc = 8u;
    } else if (dlc <= 8u) {
        if (dlc) memcpy(f.data, data, dlc);
        f.dlc = dlc;
    } else {
        /* CAN FD: the payload padded with zeros to the next length a DLC code gives */
        uint8_t len = co_frame_fd_len(dlc);
        if (len == 0u || len > CO_FRAME_MAX_DATA || !(flags & CO_FRAME_FDF)) {
            ++tx->errors;
            return -1;
        }
        memcpy(f.data, data, dlc);
        memset(&f.data[dlc], 0, (size_t)(len - dlc));
        f.dlc = len;
    }
    int r = tx->fn ? tx->fn(tx->user, &f) : -1;
    if (r == 0)
        ++tx->frames;
    else
        ++tx->errors;
    return r;
}
