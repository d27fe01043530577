/* co_node.c - NMT slave, heartbeat producer/consumer, SYNC, EMCY and frame dispatch (CiA 301). */
#include "co_node.h"

#include <string.h>

#define IDX_ERROR_REGISTER 0x1001u
#define IDX_ERROR_FIELD 0x1003u
#define IDX_SYNC_COBID 0x1005u
#define IDX_CYCLE_PERIOD 0x1006u
#define IDX_EMCY_COBID 0x1014u
#define IDX_HB_CONSUMER 0x1016u
#define IDX_HB_PRODUCER 0x1017u
#define IDX_SYNC_OVERFLOW 0x1019u

int co_node_send(co_node_t *node, uint16_t cob_id, const uint8_t *data, uint8_t dlc)
{
    co_frame_t f;
    memset(&f, 0, sizeof f);
    f.cob_id = cob_id & 0x7FFu;
    f.dlc = dlc;
    if (dlc) memcpy(f.data, data, dlc);
    int r = node->tx ? node->tx(node->tx_user, &f) : -1;
    if (r == 0) ++node->tx_frames; else ++node->tx_errors;
    return r;
}

static void configure_hb_consumers(co_node_t *node)
{
    uint32_t n = co_od_get_u32(node->od, IDX_HB_CONSUMER, 0);
    for (uint8_t i = 0; i < CO_HB_CONSUMERS; ++i) {
        co_hb_consumer_t *c = &node->hb[i];
        memset(c, 0, sizeof *c);
        if (i + 1u > n) continue;
        uint32_t v = co_od_get_u32(node->od, IDX_HB_CONSUMER, (uint8_t)(i + 1u));
        c->node_id = (uint8_t)(v >> 16);
        c->time_ms = (uint16_t)v;
        c->active = c->node_id >= 1u && c->node_id <= 127u && c->time_ms > 0u;
    }
}

static void refresh_cache(co_node_t *node)
{
    node->c_sync_cob = co_od_get_u32(node->od, IDX_SYNC_COBID, 0);
    node->c_sync_overflow = (uint8_t)co_od_get_u32(node->od, IDX_SYNC_OVERFLOW, 0);
    node->c_hb_ms = (uint16_t)co_od_get_u32(node->od, IDX_HB_PRODUCER, 0);
    node->c_cycle_us = co_od_get_u32(node->od, IDX_CYCLE_PERIOD, 0);
}

static void set_state(co_node_t *node, co_nmt_state_t s)
{
    if (node->nmt == s) return;
    node->nmt = s;
    if (s != CO_NMT_OPERATIONAL) {
        for (uint8_t i = 0; i < CO_NUM_PDO; ++i) {
            node->rpdo[i].rx_buffered = false;
            node->rpdo[i].deadline_armed = false;
            node->tpdo[i].pending = false;
        }
    }
    if (node->hooks.on_nmt) node->hooks.on_nmt(node->user, node, s);
}

static void reset(co_node_t *node, int communication_only)
{
    co_od_reset(node->od, node->node_id, communication_only);
    memset(&node->sdo, 0, sizeof node->sdo);
    node->sync_counter = 0;
    node->n_active_errors = 0;
    if (node->hooks.on_reset) node->hooks.on_reset(node->user, node, communication_only);
    refresh_cache(node);
    co_pdo_configure_all(node);
    configure_hb_consumers(node);
    node->nmt = CO_NMT_INITIALIZING;
    /* Boot-up message: COB-ID 0x700 + node-ID, one byte 0x00. */
    uint8_t zero = 0;
    co_node_send(node, (uint16_t)(0x700u + node->node_id), &zero, 1);
    node->hb_next_us = node->now_us + (int64_t)node->c_hb_ms * 1000;
    node->sync_next_us = node->now_us;
    set_state(node, CO_NMT_PRE_OPERATIONAL);
}

void co_node_init(co_node_t *node, const co_od_t *od, uint8_t node_id, co_tx_fn tx, void *tx_user,
                  const co_hooks_t *hooks, void *user, int64_t now_us)
{
    memset(node, 0, sizeof *node);
    node->od = od;
    node->node_id = node_id;
    node->tx = tx;
    node->tx_user = tx_user;
    if (hooks) node->hooks = *hooks;
    node->user = user;
    node->now_us = now_us;
    node->sdo_timeout_us = 1000000u;
    node->nmt = CO_NMT_INITIALIZING;
    reset(node, 0);
}

void co_nmt_command(co_node_t *node, uint8_t cs)
{
    switch (cs) {
    case CO_NMT_CS_START: set_state(node, CO_NMT_OPERATIONAL); break;
    case CO_NMT_CS_STOP: set_state(node, CO_NMT_STOPPED); break;
    case CO_NMT_CS_PREOP: set_state(node, CO_NMT_PRE_OPERATIONAL); break;
    case CO_NMT_CS_RESET_NODE: reset(node, 0); break;
    case CO_NMT_CS_RESET_COMM: reset(node, 1); break;
    default: break; /* unknown command specifier: ignored (CiA 301) */
    }
}

/* ------------------------------------------------------------------ EMCY */

static void emcy_send(co_node_t *node, uint16_t code, const uint8_t msef[5])
{
    uint32_t cob = co_od_get_u32(node->od, IDX_EMCY_COBID, 0);
    if ((cob & 0x80000000u) || node->nmt == CO_NMT_STOPPED || node->nmt == CO_NMT_INITIALIZING) return;
    uint8_t d[8] = {(uint8_t)code, (uint8_t)(code >> 8), (uint8_t)co_od_get_u32(node->od, IDX_ERROR_REGISTER, 0),
                    0, 0, 0, 0, 0};
    if (msef) memcpy(&d[3], msef, 5);
    co_node_send(node, (uint16_t)(cob & 0x7FFu), d, 8);
}

void co_emcy_raise(co_node_t *node, uint16_t code, uint8_t err_reg_bits, const uint8_t msef[5])
{
    uint8_t reg = (uint8_t)co_od_get_u32(node->od, IDX_ERROR_REGISTER, 0);
    reg |= (uint8_t)(err_reg_bits | CO_ERR_REG_GENERIC);
    co_od_set_u32(node->od, IDX_ERROR_REGISTER, 0, reg);
    /* Pre-defined error field: newest at sub-index 1, at most 8 kept. */
    uint32_t n = co_od_get_u32(node->od, IDX_ERROR_FIELD, 0);
    for (uint32_t i = (n < 8u ? n : 7u); i >= 1u; --i)
        co_od_set_u32(node->od, IDX_ERROR_FIELD, (uint8_t)(i + 1u), co_od_get_u32(node->od, IDX_ERROR_FIELD, (uint8_t)i));
    co_od_set_u32(node->od, IDX_ERROR_FIELD, 1, code);
    co_od_set_u32(node->od, IDX_ERROR_FIELD, 0, n < 8u ? n + 1u : 8u);
    bool known = false;
    for (uint8_t i = 0; i < node->n_active_errors; ++i) known |= node->active_errors[i] == code;
    if (!known && node->n_active_errors < 8u) node->active_errors[node->n_active_errors++] = code;
    emcy_send(node, code, msef);
}

void co_emcy_clear(co_node_t *node, uint16_t code)
{
    uint8_t j = 0;
    for (uint8_t i = 0; i < node->n_active_errors; ++i)
        if (node->active_errors[i] != code) node->active_errors[j++] = node->active_errors[i];
    if (j == node->n_active_errors) return;
    node->n_active_errors = j;
    if (j == 0) {
        co_od_set_u32(node->od, IDX_ERROR_REGISTER, 0, 0);
        emcy_send(node, CO_EMCY_NO_ERROR, NULL);
    }
}

/* ------------------------------------------------------------------ SYNC */

static void sync_event(co_node_t *node, uint8_t counter)
{
    if (node->nmt != CO_NMT_OPERATIONAL && node->nmt != CO_NMT_PRE_OPERATIONAL) return;
    node->sync_counter = counter;
    ++node->syncs;
    if (node->nmt == CO_NMT_OPERATIONAL) co_pdo_sync(node, counter); /* actuate synchronous RPDOs */
    if (node->hooks.on_sync) node->hooks.on_sync(node->user, node, counter);
    if (node->nmt == CO_NMT_OPERATIONAL) co_pdo_sync_tx(node, counter);
}

int co_sync_produce(co_node_t *node, int64_t now_us)
{
    node->now_us = now_us;
    uint32_t cob = node->c_sync_cob;
    if (!(cob & 0x40000000u)) return -1;
    if (node->nmt != CO_NMT_OPERATIONAL && node->nmt != CO_NMT_PRE_OPERATIONAL) return -1;
    uint8_t ov = node->c_sync_overflow;
    uint8_t counter = 0;
    if (ov >= 2u) {
        counter = (uint8_t)(node->sync_counter >= ov ? 1u : node->sync_counter + 1u);
        co_node_send(node, (uint16_t)(cob & 0x7FFu), &counter, 1);
    } else {
        co_node_send(node, (uint16_t)(cob & 0x7FFu), NULL, 0);
    }
    sync_event(node, counter);
    return counter;
}

/* ------------------------------------------------------------------ writes */

uint32_t co_node_sdo_write(co_node_t *node, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    uint32_t abort = co_od_check_write(e, data, len);
    if (abort) return abort;
    /* Communication-area rules of CiA 301. */
    if (e->index == IDX_ERROR_FIELD && e->subindex == 0u && data[0] != 0u) return CO_ABORT_INVALID_VALUE;
    if (e->index == IDX_SYNC_OVERFLOW) {
        if (co_od_get_u32(node->od, IDX_CYCLE_PERIOD, 0) != 0u) return CO_ABORT_DATA_STATE;
        if (data[0] == 1u) return CO_ABORT_INVALID_VALUE;
    }
    if (e->index == IDX_SYNC_COBID || e->index == IDX_EMCY_COBID) {
        uint32_t v = (uint32_t)data[0] | (uint32_t)data[1] << 8 | (uint32_t)data[2] << 16 | (uint32_t)data[3] << 24;
        if (v & 0x20000000u) return CO_ABORT_INVALID_VALUE; /* 29-bit identifiers not supported */
        /* EMCY: bit 31 = not valid; SYNC: bit 30 = producer. A used identifier must not be restricted. */
        int used = e->index == IDX_SYNC_COBID ? 1 : !(v & 0x80000000u);
        if (used && co_cob_restricted(v)) return CO_ABORT_INVALID_VALUE;
    }
    abort = co_pdo_check_write(node, e, data, len);
    if (abort) return abort;
    if (node->hooks.pre_write) {
        abort = node->hooks.pre_write(node->user, node, e, data, len);
        if (abort) return abort;
    }
    if (e->index == IDX_ERROR_FIELD && e->subindex == 0u) {
        for (uint8_t s = 1; s <= 8u; ++s) co_od_set_u32(node->od, IDX_ERROR_FIELD, s, 0);
    }
    co_od_store(e, data, len);
    if (e->index < 0x2000u) refresh_cache(node);
    if (e->index == IDX_HB_CONSUMER) configure_hb_consumers(node);
    if (e->index == IDX_HB_PRODUCER) node->hb_next_us = node->now_us + (int64_t)node->c_hb_ms * 1000;
    if (e->index == IDX_CYCLE_PERIOD) node->sync_next_us = node->now_us;
    co_pdo_after_write(node, e);
    if (node->hooks.post_write) node->hooks.post_write(node->user, node, e);
    return 0;
}

/* ------------------------------------------------------------------ dispatch */

void co_node_process(co_node_t *node, const co_frame_t *frame, int64_t now_us)
{
    node->now_us = now_us;
    ++node->rx_frames;
    if (frame->cob_id & CO_FRAME_RTR) return; /* remote frames are not used (CiA recommends against) */
    uint16_t id = (uint16_t)(frame->cob_id & 0x7FFu);
    if (frame->dlc > 8u) return;

    if (id == 0x000u) { /* NMT */
        if (frame->dlc == 2u && (frame->data[1] == 0u || frame->data[1] == node->node_id))
            co_nmt_command(node, frame->data[0]);
        return;
    }
    if (node->nmt == CO_NMT_INITIALIZING) return;

    /* Heartbeat consumer (also in STOPPED). */
    if (id > 0x700u && id <= 0x77Fu && frame->dlc == 1u) {
        for (uint8_t i = 0; i < CO_HB_CONSUMERS; ++i) {
            co_hb_consumer_t *c = &node->hb[i];
            if (c->active && id == 0x700u + c->node_id) {
                if (c->timed_out) {
                    c->timed_out = false;
                    co_emcy_clear(node, CO_EMCY_HEARTBEAT);
                }
                c->seen = true;
                c->last_us = now_us;
                c->state = frame->data[0];
            }
        }
        return;
    }
    if (node->nmt == CO_NMT_STOPPED) return;

    uint32_t sync_cob = node->c_sync_cob;
    if (id == (sync_cob & 0x7FFu) && !(sync_cob & 0x40000000u)) { /* SYNC consumer */
        uint8_t ov = node->c_sync_overflow;
        uint8_t expect = ov >= 2u ? 1u : 0u;
        if (frame->dlc != expect) {
            uint8_t msef[5] = {frame->dlc, 0, 0, 0, 0};
            co_emcy_raise(node, CO_EMCY_SYNC_LENGTH, CO_ERR_REG_COMMUNICATION, msef);
            return;
        }
        sync_event(node, expect ? frame->data[0] : 0u);
        return;
    }
    if (id == 0x600u + node->node_id) {
        co_sdo_process(node, frame);
        return;
    }
    if (node->nmt == CO_NMT_OPERATIONAL) co_pdo_rx(node, frame);
}

void co_node_tick(co_node_t *node, int64_t now_us)
{
    node->now_us = now_us;
    if (node->nmt == CO_NMT_INITIALIZING) return;
    uint16_t hb_ms = node->c_hb_ms;
    if (hb_ms && now_us >= node->hb_next_us) {
        uint8_t st = (uint8_t)node->nmt;
        co_node_send(node, (uint16_t)(0x700u + node->node_id), &st, 1);
        node->hb_next_us += (int64_t)hb_ms * 1000;
        if (node->hb_next_us <= now_us) node->hb_next_us = now_us + (int64_t)hb_ms * 1000;
    }
    for (uint8_t i = 0; i < CO_HB_CONSUMERS; ++i) {
        co_hb_consumer_t *c = &node->hb[i];
        if (!c->active || c->timed_out || !c->seen) continue; /* monitoring starts at the first heartbeat */
        if (now_us - c->last_us > (int64_t)c->time_ms * 1000) {
            c->timed_out = true;
            uint8_t msef[5] = {c->node_id, 0, 0, 0, 0};
            co_emcy_raise(node, CO_EMCY_HEARTBEAT, CO_ERR_REG_COMMUNICATION, msef);
            if (node->hooks.on_hb_timeout) node->hooks.on_hb_timeout(node->user, node, c->node_id);
        }
    }
    if (node->sync_timer_enabled) {
        uint32_t period = node->c_cycle_us;
        if (period && now_us >= node->sync_next_us) {
            co_sync_produce(node, now_us);
            node->sync_next_us += period;
            if (node->sync_next_us <= now_us) node->sync_next_us = now_us + period;
        }
    }
    co_sdo_tick(node);
    if (node->nmt == CO_NMT_OPERATIONAL) co_pdo_tick(node);
}

int64_t co_node_next_event_us(const co_node_t *node, int64_t now_us, int64_t max_us)
{
    int64_t next = now_us + max_us;
    if (node->c_hb_ms && node->hb_next_us < next) next = node->hb_next_us;
    if (node->sync_timer_enabled && node->c_cycle_us && node->sync_next_us < next)
        next = node->sync_next_us;
    for (uint8_t i = 0; i < CO_NUM_PDO; ++i) {
        const co_pdo_t *t = &node->tpdo[i];
        if (t->valid && t->next_event_us && t->next_event_us < next) next = t->next_event_us;
    }
    if (node->sdo.state != CO_SDO_IDLE) {
        int64_t to = node->sdo.last_us + node->sdo_timeout_us;
        if (to < next) next = to;
    }
    for (uint8_t i = 0; i < CO_HB_CONSUMERS; ++i) {
        const co_hb_consumer_t *c = &node->hb[i];
        if (c->active && !c->timed_out && c->seen) {
            int64_t to = c->last_us + (int64_t)c->time_ms * 1000 + 1;
            if (to < next) next = to;
        }
    }
    int64_t d = next - now_us;
    return d < 0 ? 0 : d;
}
