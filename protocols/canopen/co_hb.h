/* co_hb.h - heartbeat consumers (CiA 301 7.2.8.3.2, object 0x1016): which nodes a node watches, a heartbeat seen,
 * a consumer timed out (EMCY 0x8130), a stall excused. The node (co_node.c) owns the array and calls these. */
#ifndef CO_HB_H
#define CO_HB_H

#include <stdbool.h>
#include <stdint.h>

#include "co_emcy.h"
#include "co_od.h"

#define CO_HB_CONSUMERS 4u

typedef struct {
    uint8_t node_id;
    uint16_t time_ms;
    bool active;
    bool timed_out;
    bool seen;
    int64_t last_us;
    uint8_t state;
} co_hb_consumer_t;

/* The consumers from 0x1016 (after a reset or a write to it). */
void co_hb_configure(co_hb_consumer_t hb[CO_HB_CONSUMERS], const co_od_t *od);
/* A heartbeat of node `id` (0x700 + id) in NMT state `state` at now_us; a consumer that had timed out clears
 * its EMCY. */
void co_hb_consume(co_hb_consumer_t hb[CO_HB_CONSUMERS], co_emcy_t *emcy, uint16_t id, uint8_t state, int64_t now_us);
/* A consumer whose heartbeat is late, once: EMCY 0x8130; returns true then (the node calls its hook). */
bool co_hb_check(co_hb_consumer_t *c, co_emcy_t *emcy, int64_t now_us);
/* A stall of the whole process (stall_us) is not the producers' fault: their deadlines move by it. */
void co_hb_excuse(co_hb_consumer_t hb[CO_HB_CONSUMERS], int64_t stall_us);
/* The earliest consumer deadline before next_us (or next_us). */
int64_t co_hb_next_event(const co_hb_consumer_t hb[CO_HB_CONSUMERS], int64_t next_us);

#endif /* CO_HB_H */
