/* co_node.h - portable CANopen slave (CiA 301): NMT, heartbeat, SYNC, PDO, SDO server, EMCY.
 *
 * Portable core: no OS headers, no allocation, time passed in (microseconds).
 * A driver feeds received frames to co_node_process() and calls co_node_tick()
 * periodically; frames go out through the co_tx_fn given at init
 * (protocols/socketcan/ on Linux).
 */
#ifndef CO_NODE_H
#define CO_NODE_H

#include <stdbool.h>
#include <stdint.h>

#include "co_frame.h"
#include "co_od.h"

#define CO_NUM_PDO 4u
#define CO_PDO_MAX_MAPPED 8u
#define CO_HB_CONSUMERS 4u
#define CO_SDO_BUF 64u

typedef enum {
    CO_NMT_INITIALIZING = 0x00,
    CO_NMT_STOPPED = 0x04,
    CO_NMT_OPERATIONAL = 0x05,
    CO_NMT_PRE_OPERATIONAL = 0x7F
} co_nmt_state_t;

/* NMT command specifiers (CiA 301 7.2.8.3.1). */
enum {
    CO_NMT_CS_START = 0x01,
    CO_NMT_CS_STOP = 0x02,
    CO_NMT_CS_PREOP = 0x80,
    CO_NMT_CS_RESET_NODE = 0x81,
    CO_NMT_CS_RESET_COMM = 0x82
};

/* EMCY error codes used by the slave itself (CiA 301 table 21). */
#define CO_EMCY_NO_ERROR 0x0000u
#define CO_EMCY_HEARTBEAT 0x8130u
#define CO_EMCY_PDO_LENGTH 0x8210u
#define CO_EMCY_PDO_LENGTH_EXCEEDED 0x8220u
#define CO_EMCY_SYNC_LENGTH 0x8240u
#define CO_EMCY_RPDO_TIMEOUT 0x8250u

/* Error register bits (0x1001). */
#define CO_ERR_REG_GENERIC 0x01u
#define CO_ERR_REG_CURRENT 0x02u
#define CO_ERR_REG_VOLTAGE 0x04u
#define CO_ERR_REG_TEMPERATURE 0x08u
#define CO_ERR_REG_COMMUNICATION 0x10u
#define CO_ERR_REG_PROFILE 0x20u
#define CO_ERR_REG_MANUFACTURER 0x80u

typedef struct co_node co_node_t;

/* Application hooks (all optional). */
typedef struct {
    /* Veto or accept an SDO write after the generic checks; return an abort code or 0. */
    uint32_t (*pre_write)(void *user, co_node_t *node, const co_od_entry_t *e, const uint8_t *data, uint32_t len);
    /* A value was written by SDO (the OD holds the new value). */
    void (*post_write)(void *user, co_node_t *node, const co_od_entry_t *e);
    /* About to be uploaded: refresh the value. */
    void (*pre_read)(void *user, co_node_t *node, const co_od_entry_t *e);
    /* SYNC: synchronous RPDOs are already actuated; synchronous TPDOs go out after this returns. */
    void (*on_sync)(void *user, co_node_t *node, uint8_t counter);
    /* An RPDO wrote the OD (event-driven types at reception, synchronous ones at the SYNC). */
    void (*on_rpdo)(void *user, co_node_t *node, uint8_t pdo);
    /* NMT state changed. */
    void (*on_nmt)(void *user, co_node_t *node, co_nmt_state_t state);
    /* The OD was restored to its defaults (reset node: communication_only = 0). */
    void (*on_reset)(void *user, co_node_t *node, int communication_only);
    /* A monitored node's heartbeat was not seen in time. */
    void (*on_hb_timeout)(void *user, co_node_t *node, uint8_t node_id);
} co_hooks_t;

typedef struct {
    const co_od_entry_t *entry[CO_PDO_MAX_MAPPED];
    uint8_t count;
    uint8_t bytes;
    bool valid;            /* COB-ID valid and mapping resolved */
    uint16_t cob_id;
    uint8_t trans_type;
    uint8_t sync_start;    /* cached from the communication parameter (sub 6) */
    uint16_t event_ms;     /* cached sub 5 */
    uint16_t inhibit_100us;/* cached sub 3 */
    /* TPDO */
    uint8_t sync_count;
    bool pending;          /* event requested (or type 0 waiting for SYNC) */
    bool started;          /* SYNC start value reached */
    int64_t last_tx_us;
    int64_t next_event_us;
    /* RPDO */
    uint8_t rx_buf[8];
    bool rx_buffered;      /* synchronous RPDO waiting for the next SYNC */
    int64_t last_rx_us;
    bool deadline_armed;
    bool deadline_reported;
    bool length_reported;
} co_pdo_t;

typedef enum {
    CO_SDO_IDLE = 0,
    CO_SDO_DOWNLOAD,
    CO_SDO_UPLOAD
} co_sdo_state_t;

typedef struct {
    co_sdo_state_t state;
    const co_od_entry_t *entry;
    uint16_t index;
    uint8_t subindex;
    uint8_t toggle;
    uint32_t size;      /* total bytes (indicated or known) */
    bool size_known;
    uint32_t offset;
    uint8_t buf[CO_SDO_BUF];
    int64_t last_us;
} co_sdo_t;

typedef struct {
    uint8_t node_id;
    uint16_t time_ms;
    bool active;
    bool timed_out;
    bool seen;
    int64_t last_us;
    uint8_t state;
} co_hb_consumer_t;

struct co_node {
    const co_od_t *od;
    uint8_t node_id;
    co_nmt_state_t nmt;
    co_tx_fn tx;
    void *tx_user;
    co_hooks_t hooks;
    void *user;
    int64_t now_us;

    /* Communication parameters read on every frame, cached from the OD after a reset and
     * after every SDO write (the OD stays the single place they are stored). */
    uint32_t c_sync_cob;       /* 0x1005 */
    uint8_t c_sync_overflow;   /* 0x1019 */
    uint16_t c_hb_ms;          /* 0x1017 */
    uint32_t c_cycle_us;       /* 0x1006 */

    /* Heartbeat producer */
    int64_t hb_next_us;
    co_hb_consumer_t hb[CO_HB_CONSUMERS];

    /* SYNC */
    uint8_t sync_counter;      /* last counter produced or consumed */
    bool sync_timer_enabled;   /* produce SYNC from 0x1006 in co_node_tick (real-time mode) */
    int64_t sync_next_us;
    uint32_t syncs;            /* SYNC events processed */

    co_pdo_t rpdo[CO_NUM_PDO];
    co_pdo_t tpdo[CO_NUM_PDO];
    co_sdo_t sdo;
    uint32_t sdo_timeout_us;

    /* EMCY bookkeeping */
    uint16_t active_errors[8];
    uint8_t n_active_errors;

    /* Statistics (frames) */
    uint32_t rx_frames, tx_frames, tx_errors, sdo_aborts;
};

/* Initialise: restore the OD defaults, send the boot-up message and enter
 * pre-operational (CiA 301 NMT slave start-up). */
void co_node_init(co_node_t *node, const co_od_t *od, uint8_t node_id, co_tx_fn tx, void *tx_user,
                  const co_hooks_t *hooks, void *user, int64_t now_us);

/* Handle one received frame. */
void co_node_process(co_node_t *node, const co_frame_t *frame, int64_t now_us);

/* Timers: heartbeat, consumers, SDO timeout, TPDO event/inhibit, RPDO deadline, SYNC producer. */
void co_node_tick(co_node_t *node, int64_t now_us);

/* Microseconds until the next timer event (for poll timeouts); capped at max_us. */
int64_t co_node_next_event_us(const co_node_t *node, int64_t now_us, int64_t max_us);

/* Produce one SYNC now (SYNC producer only; lockstep calls this explicitly).
 * Returns the counter sent (0 when the counter is disabled), or -1 if not producer/not allowed. */
int co_sync_produce(co_node_t *node, int64_t now_us);

/* Request an event-driven (or type-0) TPDO. pdo is 0-based. */
void co_tpdo_request(co_node_t *node, uint8_t pdo);

/* Local NMT transition (as if commanded by the master). */
void co_nmt_command(co_node_t *node, uint8_t cs);

/* EMCY: raise an error (adds to 0x1003, sets 0x1001 bits, sends the EMCY frame). */
void co_emcy_raise(co_node_t *node, uint16_t code, uint8_t err_reg_bits, const uint8_t msef[5]);
/* Clear an active error; when none is left, send the "error reset" EMCY and clear 0x1001. */
void co_emcy_clear(co_node_t *node, uint16_t code);

/* Internal: apply a validated SDO write (used by the SDO server). */
uint32_t co_node_sdo_write(co_node_t *node, const co_od_entry_t *e, const uint8_t *data, uint32_t len);
void co_sdo_process(co_node_t *node, const co_frame_t *frame);
void co_sdo_tick(co_node_t *node);
void co_pdo_configure_all(co_node_t *node);
uint32_t co_pdo_check_write(co_node_t *node, const co_od_entry_t *e, const uint8_t *data, uint32_t len);
void co_pdo_after_write(co_node_t *node, const co_od_entry_t *e);
void co_pdo_rx(co_node_t *node, const co_frame_t *frame);
void co_pdo_sync(co_node_t *node, uint8_t counter);
void co_pdo_sync_tx(co_node_t *node, uint8_t counter);
void co_pdo_tick(co_node_t *node);
int co_node_send(co_node_t *node, uint16_t cob_id, const uint8_t *data, uint8_t dlc);

#endif /* CO_NODE_H */
