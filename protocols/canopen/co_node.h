/* co_node.h - portable CANopen slave (CiA 301): NMT, heartbeat, SYNC, PDO, SDO server, EMCY.
 *
 * Portable core: no OS headers, no allocation, time passed in (microseconds).
 * A driver feeds received frames to co_node_process() and calls co_node_tick()
 * periodically; frames go out through the co_tx_fn given at init
 * (protocols/socketcan/ on Linux).
 *
 * The node owns NMT, the heartbeat producer and consumers and SYNC, and composes the
 * services, each in its own module that knows nothing of the node (CANopenNode's
 * split): co_emcy.h, co_pdo.h, co_sdo_server.h, all over co_od.h and co_tx.h.
 */
#ifndef CO_NODE_H
#define CO_NODE_H

#include <stdbool.h>
#include <stdint.h>

#include "co_bindings.h"
#include "co_emcy.h"
#include "co_frame.h"
#include "co_hb.h"
#include "co_od.h"
#include "co_pdo.h"
#include "co_sdo_server.h"
#include "co_tx.h"

#define CO_NUM_PDO 4u

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

typedef struct co_node co_node_t;

/* Application hooks (all optional): the node's events. Access to an object goes to the object's owner through its
 * binding (co_od_ext_t, co_node_bind), not through a hook. */
typedef struct {
    /* Once, in co_node_init before the first reset: the application binds its objects (co_node_bind). */
    void (*bind)(void *user, co_node_t *node);
    /* SYNC: synchronous RPDOs are already actuated; synchronous TPDOs go out after this returns. */
    void (*on_sync)(void *user, co_node_t *node, uint8_t counter);
    /* An RPDO wrote the OD (event-driven types at reception, synchronous ones at the SYNC). */
    void (*on_rpdo)(void *user, co_node_t *node, uint8_t pdo);
    /* An RPDO frame was received and accepted (each frame, when it came; a synchronous one is then buffered, and a
     * second before the SYNC replaces the first: this tells the owner of every arrival). */
    void (*on_rpdo_received)(void *user, co_node_t *node, uint8_t pdo);
    /* NMT state changed. */
    void (*on_nmt)(void *user, co_node_t *node, co_nmt_state_t state);
    /* The OD was restored to its defaults (reset node: communication_only = 0). */
    void (*on_reset)(void *user, co_node_t *node, int communication_only);
    /* A monitored node's heartbeat was not seen in time. */
    void (*on_hb_timeout)(void *user, co_node_t *node, uint8_t node_id);
} co_hooks_t;

struct co_node {
    const co_od_t *od;
    uint8_t node_id;
    co_nmt_state_t nmt;
    co_tx_t tx; /* the driver's transmit callback and the frame counters */
    co_hooks_t hooks;
    void *user;
    int64_t now_us;

    /* Communication parameters read on every frame, cached from the OD after a reset and
     * after every SDO write (the OD stays the single place they are stored). */
    uint32_t c_sync_cob;     /* 0x1005 */
    uint8_t c_sync_overflow; /* 0x1019 */
    uint16_t c_hb_ms;        /* 0x1017 */
    uint32_t c_cycle_us;     /* 0x1006 */

    /* Heartbeat producer */
    int64_t hb_next_us;
    co_hb_consumer_t hb[CO_HB_CONSUMERS];

    /* SYNC */
    uint8_t sync_counter;    /* last counter produced or consumed */
    bool sync_timer_enabled; /* produce SYNC from 0x1006 in co_node_tick (real-time mode) */
    int64_t sync_next_us;
    uint32_t syncs; /* SYNC events processed */

    /* Objects bound to their owners (co_node_bind). */
    co_bindings_t bindings;

    /* Services, wired to this node by co_node_init. */
    co_emcy_t emcy;
    co_pdo_env_t pdo_env; /* what the PDOs share: OD, tx, EMCY, the hooks' adapters */
    co_pdo_t rpdo[CO_NUM_PDO];
    co_pdo_t tpdo[CO_NUM_PDO];
    uint16_t rpdo_cob[CO_NUM_PDO]; /* each RPDO's COB-ID while valid, else 0xFFFF (no 11-bit frame has it) */
    co_sdo_server_t sdo;

    /* Statistics (frames received; sent: tx.frames, tx.errors; SDO aborts: sdo.aborts) */
    uint32_t rx_frames;
};

/* Initialise: restore the OD defaults, send the boot-up message and enter
 * pre-operational (CiA 301 NMT slave start-up). The node must not be moved or
 * copied afterwards (its services point into it). */
void co_node_init(co_node_t *node, const co_od_t *od, uint8_t node_id, co_tx_fn tx, void *tx_user,
                  const co_hooks_t *hooks, void *user, int64_t now_us);

/* Bind object `index` to its owner's handlers (co_od_ext_t, kept by the owner; binding an index again replaces
 * the binding). Returns 0, or -1 when the OD has no such object or the table (CO_NODE_BINDINGS) is full. The PDOs
 * that map the object learn it at once. */
int co_node_bind(co_node_t *node, uint16_t index, co_od_ext_t *ext);
/* The binding of object `index`, or NULL. */
co_od_ext_t *co_node_ext(const co_node_t *node, uint16_t index);

/* Handle one received frame. */
void co_node_process(co_node_t *node, const co_frame_t *frame, int64_t now_us);

/* Timers: heartbeat, consumers, SDO timeout, TPDO event/inhibit, RPDO deadline, SYNC producer. */
void co_node_tick(co_node_t *node, int64_t now_us);
/* This node was not running for `stall_us` (its process, or the whole machine or VM, descheduled: its loop
 * woke that much later than it asked): the silence of the heartbeats it consumes over that time is its own,
 * not the producers', and is not counted against them (a producer silent on its own is still timed out). */
void co_node_excuse_us(co_node_t *node, int64_t stall_us);

/* Microseconds until the next timer event (for poll timeouts); capped at max_us. */
int64_t co_node_next_event_us(const co_node_t *node, int64_t now_us, int64_t max_us);

/* Produce one SYNC now (SYNC producer only; lockstep calls this explicitly).
 * Returns the counter sent (0 when the counter is disabled), or -1 if not producer/not allowed. */
int co_sync_produce(co_node_t *node, int64_t now_us);
/* The producer's SYNC without its frame: the counter advances, the synchronous RPDOs are actuated, the hooks run
 * and the synchronous TPDOs go out as at co_sync_produce, but no SYNC frame is sent (the period is marked on the
 * bus by another frame: the plant's measurement TPDO with the counter inside, issue 54). Not CiA 301: its
 * synchronous PDOs follow a SYNC that only this node sees. Same returns as co_sync_produce. */
int co_sync_produce_local(co_node_t *node, int64_t now_us);

/* Request an event-driven (or type-0) TPDO. pdo is 0-based. */
void co_tpdo_request(co_node_t *node, uint8_t pdo);

/* Local NMT transition (as if commanded by the master). */
void co_nmt_command(co_node_t *node, uint8_t cs);

/* EMCY of this node (co_emcy_report_error / co_emcy_clear_error on node->emcy). */
void co_emcy_raise(co_node_t *node, uint16_t code, uint8_t err_reg_bits, const uint8_t msef[5]);
void co_emcy_clear(co_node_t *node, uint16_t code);

#endif /* CO_NODE_H */
