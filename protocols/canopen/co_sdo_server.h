/* co_sdo_server.h - SDO server (CiA 301 7.2.4): expedited and segmented upload and
 * download, toggle bit, timeout, abort codes (CANopenNode's CO_SDOserver.h).
 *
 * Initialised with the OD, the transmit side, the node-ID (answers go to 0x580 + ID)
 * and the write path of the node: every download ends in `write`, which applies the
 * node's checks and stores the value. The owner hands it the requests to 0x600 + ID.
 */
#ifndef CO_SDO_SERVER_H
#define CO_SDO_SERVER_H

#include <stdbool.h>
#include <stdint.h>

#include "co_frame.h"
#include "co_od.h"
#include "co_tx.h"

#define CO_SDO_BUF 64u
#define CO_SDO_SERVER_TIMEOUT_US 1000000u

typedef enum { CO_SDO_IDLE = 0, CO_SDO_DOWNLOAD, CO_SDO_UPLOAD } co_sdo_state_t;

/* The transfer in progress. */
typedef struct {
    co_sdo_state_t state;
    const co_od_entry_t *entry;
    uint16_t index;
    uint8_t subindex;
    uint8_t toggle;
    uint32_t size; /* total bytes (indicated or known) */
    bool size_known;
    uint32_t offset;
    uint8_t buf[CO_SDO_BUF];
    int64_t last_us;
} co_sdo_transfer_t;

/* Check and store a downloaded value; returns an abort code or 0. */
typedef uint32_t (*co_sdo_write_fn)(void *ctx, const co_od_entry_t *e, const uint8_t *data, uint32_t len);
/* About to be uploaded: refresh the value (optional). */
typedef void (*co_sdo_pre_read_fn)(void *ctx, const co_od_entry_t *e);

typedef struct {
    const co_od_t *od;
    co_tx_t *tx;
    uint16_t tx_cob_id; /* 0x580 + node-ID */
    uint32_t timeout_us;
    co_sdo_write_fn write;
    co_sdo_pre_read_fn pre_read;
    void *ctx;
    co_sdo_transfer_t transfer;
    uint32_t aborts; /* abort frames sent */
} co_sdo_server_t;

void co_sdo_server_init(co_sdo_server_t *s, const co_od_t *od, co_tx_t *tx, uint8_t node_id, co_sdo_write_fn write,
                        co_sdo_pre_read_fn pre_read, void *ctx);

/* Reset: a transfer in progress is dropped without an answer. */
void co_sdo_server_reset(co_sdo_server_t *s);

/* A request to this server (COB-ID 0x600 + node-ID). */
void co_sdo_server_process(co_sdo_server_t *s, const co_frame_t *request, int64_t now_us);

/* Timeout of a segmented transfer. */
void co_sdo_server_tick(co_sdo_server_t *s, int64_t now_us);

/* The earlier of next_us and the timeout of the transfer in progress. */
int64_t co_sdo_server_next_event(const co_sdo_server_t *s, int64_t next_us);

#endif /* CO_SDO_SERVER_H */
