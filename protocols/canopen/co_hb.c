/* co_hb.c - heartbeat consumers (see co_hb.h). */
#include "co_hb.h"

#include <string.h>

#define IDX_HB_CONSUMER 0x1016u

void co_hb_configure(co_hb_consumer_t hb[CO_HB_CONSUMERS], const co_od_t *od)
{
    uint32_t n = co_od_get_u32(od, IDX_HB_CONSUMER, 0);
    for (uint8_t i = 0; i < CO_HB_CONSUMERS; ++i) {
        co_hb_consumer_t *c = &hb[i];
        memset(c, 0, sizeof *c);
        if (i + 1u > n) continue;
        uint32_t v = co_od_get_u32(od, IDX_HB_CONSUMER, (uint8_t)(i + 1u));
        c->node_id = (uint8_t)(v >> 16);
        c->time_ms = (uint16_t)v;
        c->active = c->node_id >= 1u && c->node_id <= 127u && c->time_ms > 0u;
    }
}

void co_hb_consume(co_hb_consumer_t hb[CO_HB_CONSUMERS], co_emcy_t *emcy, uint16_t id, uint8_t state, int64_t now_us)
{
    for (uint8_t i = 0; i < CO_HB_CONSUMERS; ++i) {
        co_hb_consumer_t *c = &hb[i];
        if (c->active && id == 0x700u + c->node_id) {
            if (c->timed_out) {
                c->timed_out = false;
                co_emcy_clear_error(emcy, CO_EMCY_HEARTBEAT);
            }
            c->seen = true;
            c->last_us = now_us;
            c->state = state;
        }
    }
}

bool co_hb_check(co_hb_consumer_t *c, co_emcy_t *emcy, int64_t now_us)
{
    if (!c->active || c->timed_out || !c->seen) return false; /* monitoring starts at the first heartbeat */
    if (now_us - c->last_us <= (int64_t)c->time_ms * 1000) return false;
    c->timed_out = true;
    uint8_t msef[5] = {c->node_id, 0, 0, 0, 0};
    co_emcy_report_error(emcy, CO_EMCY_HEARTBEAT, CO_ERR_REG_COMMUNICATION, msef);
    return true;
}

void co_hb_excuse(co_hb_consumer_t hb[CO_HB_CONSUMERS], int64_t stall_us)
{
    if (stall_us <= 0) return;
    for (uint8_t i = 0; i < CO_HB_CONSUMERS; ++i) {
        co_hb_consumer_t *c = &hb[i];
        if (c->active && c->seen && !c->timed_out) c->last_us += stall_us;
    }
}

int64_t co_hb_next_event(const co_hb_consumer_t hb[CO_HB_CONSUMERS], int64_t next_us)
{
    for (uint8_t i = 0; i < CO_HB_CONSUMERS; ++i) {
        const co_hb_consumer_t *c = &hb[i];
        if (c->active && !c->timed_out && c->seen) {
            int64_t to = c->last_us + (int64_t)c->time_ms * 1000 + 1;
            if (to < next_us) next_us = to;
        }
    }
    return next_us;
}
