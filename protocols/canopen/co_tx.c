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
    co_frame_t f = {(uint32_t)(cob_id & 0x7FFu), dlc, {0, 0, 0, 0, 0, 0, 0, 0}};
    if (dlc == 8u)
        memcpy(f.data, data, 8); /* a PDO's usual size: a copy of a constant size, no call */
    else if (dlc)
        memcpy(f.data, data, dlc);
    int r = tx->fn ? tx->fn(tx->user, &f) : -1;
    if (r == 0)
        ++tx->frames;
    else
        ++tx->errors;
    return r;
}
