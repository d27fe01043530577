/* co_pdo.h - one PDO (CiA 301 7.2.2), receive or transmit (CANopenNode's CO_PDO.h).
 *
 * A PDO is wired once (co_rpdo_init / co_tpdo_init) to its OD objects and to what it
 * talks to (co_pdo_env_t: the OD, the transmit side, the EMCY producer, the
 * application callbacks); co_pdo_configure reads its communication and mapping
 * parameters. The owner of the NMT state calls the rest, passing the time and, where
 * a TPDO may send, whether the node is operational.
 */
#ifndef CO_PDO_H
#define CO_PDO_H

#include <stdbool.h>
#include <stdint.h>

#include "co_emcy.h"
#include "co_fd.h"
#include "co_frame.h"
#include "co_od.h"
#include "co_tx.h"

#define CO_PDO_MAX_MAPPED 8u

/* What the PDOs of one node share. */
typedef struct {
    const co_od_t *od;
    co_tx_t *tx;     /* TPDOs are sent through it */
    co_emcy_t *emcy; /* RPDO length errors and deadline misses are reported to it */
    /* The owner's callbacks (optional), given ctx back. */
    co_od_ext_t *(*ext_of)(void *ctx, uint16_t index); /* the object's binding (co_od.h), or NULL */
    void (*on_rpdo)(void *ctx, uint8_t pdo);           /* an RPDO wrote the OD */
    void (*on_rpdo_rx)(void *ctx, uint8_t pdo);        /* an RPDO frame was accepted (each one, when it came) */
    void *ctx;
    co_fd_t fd; /* the node's CAN FD PDOs (0x2105): a CAN FD PDO maps up to CO_FRAME_MAX_DATA bytes */
} co_pdo_env_t;

/* Where a PDO sits; kept when it is re-configured. */
typedef struct {
    const co_pdo_env_t *env;
    uint16_t comm_index; /* 0x1400 + n (RPDO) or 0x1800 + n (TPDO) */
    uint16_t map_index;  /* 0x1600 + n or 0x1A00 + n */
    uint8_t number;      /* n, 0-based */
    bool is_tpdo;
} co_pdo_link_t;

/* A mapped entry as the frame sees it, resolved once (when the PDO is configured): where its value lives in the
 * OD's RAM and how many bytes it takes in the frame. The frame is packed and unpacked from these, with no OD
 * look-up per field. */
typedef struct {
    uint8_t *data;
    uint8_t size;
} co_pdo_field_t;

typedef struct {
    co_pdo_link_t link;
    const co_od_entry_t *entry[CO_PDO_MAX_MAPPED];
    co_pdo_field_t field[CO_PDO_MAX_MAPPED];
    /* TPDO: the bound objects to refresh before sending (co_od_ext_t.read), once per run of consecutive
     * entries of one object; resolved with the mapping and again when an object is bound (co_pdo_bind). */
    co_od_ext_t *refresh[CO_PDO_MAX_MAPPED];
    const co_od_entry_t *refresh_entry[CO_PDO_MAX_MAPPED];
    uint8_t n_refresh;
    bool native;    /* little-endian host: a field is a plain copy */
    uint8_t *block; /* native, and the mapped entries lie one after the other in RAM in the frame's order (a
                     * record's fields usually do): the frame is one copy of `bytes` from or to here */
    uint8_t count;
    uint8_t bytes;
    bool valid; /* COB-ID valid and mapping resolved */
    uint16_t cob_id;
    uint8_t trans_type;
    uint8_t sync_start;     /* cached from the communication parameter (sub 6) */
    uint16_t event_ms;      /* cached sub 5 */
    uint16_t inhibit_100us; /* cached sub 3 */
    /* TPDO */
    uint8_t sync_count;
    bool pending; /* event requested (or type 0 waiting for SYNC) */
    bool started; /* SYNC start value reached */
    int64_t last_tx_us;
    int64_t next_event_us;
    /* RPDO */
    uint8_t rx_buf[CO_FRAME_MAX_DATA];
    bool rx_buffered; /* synchronous RPDO waiting for the next SYNC */
    int64_t last_rx_us;
    bool deadline_armed;
    bool deadline_reported;
    bool length_reported;
} co_pdo_t;

/* Wire PDO n (0-based) to its OD objects and env; co_pdo_configure reads them. */
void co_rpdo_init(co_pdo_t *p, uint8_t n, const co_pdo_env_t *env);
void co_tpdo_init(co_pdo_t *p, uint8_t n, const co_pdo_env_t *env);

/* (Re)read the communication and mapping parameters from the OD; clears the run-time state. */
void co_pdo_configure(co_pdo_t *p);

/* The mapped objects' bindings changed (co_node_bind): resolve the TPDO's refresh list again. */
void co_pdo_bind(co_pdo_t *p);

/* Does this PDO map an entry of object `index`? */
/* The most bytes this PDO may map: 8, or CO_FRAME_MAX_DATA when it travels in CAN FD frames (0x2105). */
uint8_t co_pdo_max_bytes(const co_pdo_t *p);

bool co_pdo_maps(const co_pdo_t *p, uint16_t index);
/* Whether the PDO maps this entry (index and sub-index). */
bool co_pdo_maps_entry(const co_pdo_t *p, uint16_t index, uint8_t subindex);

/* Is `index` this PDO's communication or mapping parameter? */
bool co_pdo_owns(const co_pdo_t *p, uint16_t index);

/* CiA 301 rules of an SDO write to this PDO's parameters (COB-ID, transmission type,
 * inhibit time, SYNC start value, re-mapping procedure); an abort code or 0. sync_cob_id: 0x1005. */
uint32_t co_pdo_check_write(const co_pdo_t *p, const co_od_entry_t *e, const uint8_t *data, uint32_t sync_cob_id);

/* Leaving operational: a buffered RPDO, the deadline watch and a pending TPDO are dropped;
 * a TPDO with a SYNC start value waits for it again. */
void co_pdo_stop(co_pdo_t *p);

/* RPDO: a frame arrived (any COB-ID; others are ignored). */
void co_rpdo_receive(co_pdo_t *p, const co_frame_t *frame, int64_t now_us);
/* RPDO: SYNC - a buffered synchronous RPDO writes the OD. */
void co_rpdo_actuate(co_pdo_t *p);
/* RPDO: event-timer deadline monitoring. */
void co_rpdo_check_deadline(co_pdo_t *p, int64_t now_us);

/* TPDO: the application requests an event-driven (or type-0) transmission. */
void co_tpdo_request_event(co_pdo_t *p, bool operational, int64_t now_us);
/* TPDO: SYNC with this counter (0: counter disabled); the start value rules are in co_pdo.c. */
void co_tpdo_on_sync(co_pdo_t *p, uint8_t counter, bool operational, int64_t now_us);
/* TPDO: inhibit and event timers. */
void co_tpdo_tick(co_pdo_t *p, bool operational, int64_t now_us);
/* TPDO: the earlier of next_us and this PDO's next timer event. */
int64_t co_tpdo_next_event(const co_pdo_t *p, int64_t next_us);

#endif /* CO_PDO_H */
