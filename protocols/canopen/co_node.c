/* co_node.c - NMT slave, heartbeat producer (its consumers: co_hb.c), SYNC, the SDO write path and
 * frame dispatch to the services (EMCY, PDO, SDO server) (CiA 301). */
#include "co_node.h"

#include <string.h>

#define IDX_SYNC_COBID 0x1005u
#define IDX_CYCLE_PERIOD 0x1006u
#define IDX_HB_PRODUCER 0x1017u
#define IDX_SYNC_OVERFLOW 0x1019u

static void refresh_cache(co_node_t *node)
{
    node->c_sync_cob = co_od_get_u32(node->od, IDX_SYNC_COBID, 0);
    node->c_sync_overflow = (uint8_t)co_od_get_u32(node->od, IDX_SYNC_OVERFLOW, 0);
    node->c_hb_ms = (uint16_t)co_od_get_u32(node->od, IDX_HB_PRODUCER, 0);
    node->c_cycle_us = co_od_get_u32(node->od, IDX_CYCLE_PERIOD, 0);
}

static bool operational(const co_node_t *node) { return node->nmt == CO_NMT_OPERATIONAL; }

/* Every change of node->nmt goes through here: the services that depend on it learn it. */
static void enter_nmt_state(co_node_t *node, co_nmt_state_t s)
{
    node->nmt = s;
    co_emcy_set_sending(&node->emcy, s == CO_NMT_OPERATIONAL || s == CO_NMT_PRE_OPERATIONAL);
}

static void set_state(co_node_t *node, co_nmt_state_t s)
{
    if (node->nmt == s) return;
    enter_nmt_state(node, s);
    if (s != CO_NMT_OPERATIONAL) {
        for (uint8_t i = 0; i < CO_NUM_PDO; ++i) {
            co_pdo_stop(&node->rpdo[i]);
            co_pdo_stop(&node->tpdo[i]);
        }
    }
    if (node->hooks.on_nmt) node->hooks.on_nmt(node->user, node, s);
}

/* The RPDOs' COB-IDs as a frame is dispatched by them (after every configuration of a PDO). */
static void cache_rpdo_cobs(co_node_t *node)
{
    for (uint8_t i = 0; i < CO_NUM_PDO; ++i) node->rpdo_cob[i] = node->rpdo[i].valid ? node->rpdo[i].cob_id : 0xFFFFu;
}

static void configure_pdos(co_node_t *node)
{
    for (uint8_t i = 0; i < CO_NUM_PDO; ++i) {
        co_pdo_configure(&node->rpdo[i]);
        co_pdo_configure(&node->tpdo[i]);
    }
    cache_rpdo_cobs(node);
}

static void reset(co_node_t *node, int communication_only)
{
    co_od_reset(node->od, node->node_id, communication_only);
    co_sdo_server_reset(&node->sdo);
    node->sync_counter = 0;
    co_emcy_forget_active(&node->emcy);
    if (node->hooks.on_reset) node->hooks.on_reset(node->user, node, communication_only);
    refresh_cache(node);
    configure_pdos(node);
    co_hb_configure(node->hb, node->od);
    enter_nmt_state(node, CO_NMT_INITIALIZING);
    /* Boot-up message: COB-ID 0x700 + node-ID, one byte 0x00. */
    uint8_t zero = 0;
    co_tx_send(&node->tx, (uint16_t)(0x700u + node->node_id), &zero, 1);
    node->hb_next_us = node->now_us + (int64_t)node->c_hb_ms * 1000;
    node->sync_next_us = node->now_us;
    set_state(node, CO_NMT_PRE_OPERATIONAL);
}

/* ------------------------------------------------------------------ hooks as the services see them */

static co_od_ext_t *service_ext_of(void *ctx, uint16_t index)
{
    return co_bindings_find(&((const co_node_t *)ctx)->bindings, index);
}

static void service_pre_read(void *ctx, const co_od_entry_t *e)
{
    co_od_ext_t *x = co_bindings_find(&((const co_node_t *)ctx)->bindings, e->index);
    if (x != NULL && x->read != NULL) x->read(x->object, e);
}

static void service_on_rpdo(void *ctx, uint8_t pdo)
{
    co_node_t *node = (co_node_t *)ctx;
    if (node->hooks.on_rpdo) node->hooks.on_rpdo(node->user, node, pdo);
}

static void service_on_rpdo_rx(void *ctx, uint8_t pdo)
{
    co_node_t *node = (co_node_t *)ctx;
    if (node->hooks.on_rpdo_received) node->hooks.on_rpdo_received(node->user, node, pdo);
}

static uint32_t sdo_write(void *ctx, const co_od_entry_t *e, const uint8_t *data, uint32_t len);

void co_node_init(co_node_t *node, const co_od_t *od, uint8_t node_id, co_tx_fn tx, void *tx_user,
                  const co_hooks_t *hooks, void *user, int64_t now_us)
{
    memset(node, 0, sizeof *node);
    node->od = od;
    node->node_id = node_id;
    co_tx_init(&node->tx, tx, tx_user);
    if (hooks) node->hooks = *hooks;
    node->user = user;
    node->now_us = now_us;
    co_emcy_init(&node->emcy, od, &node->tx);
    node->pdo_env.od = od;
    node->pdo_env.tx = &node->tx;
    node->pdo_env.emcy = &node->emcy;
    node->pdo_env.ext_of = service_ext_of;
    node->pdo_env.on_rpdo = service_on_rpdo;
    node->pdo_env.on_rpdo_rx = service_on_rpdo_rx;
    node->pdo_env.ctx = node;
    co_fd_attach(&node->pdo_env.fd, od); /* 0x2105 CAN FD */
    for (uint8_t i = 0; i < CO_NUM_PDO; ++i) {
        co_rpdo_init(&node->rpdo[i], i, &node->pdo_env);
        co_tpdo_init(&node->tpdo[i], i, &node->pdo_env);
    }
    co_sdo_server_init(&node->sdo, od, &node->tx, node_id, sdo_write, service_pre_read, node);
    enter_nmt_state(node, CO_NMT_INITIALIZING);
    if (node->hooks.bind) node->hooks.bind(user, node);
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

/* ------------------------------------------------------------------ the node's services, by node */

void co_emcy_raise(co_node_t *node, uint16_t code, uint8_t err_reg_bits, const uint8_t msef[5])
{
    co_emcy_report_error(&node->emcy, code, err_reg_bits, msef);
}

void co_emcy_clear(co_node_t *node, uint16_t code) { co_emcy_clear_error(&node->emcy, code); }

void co_tpdo_request(co_node_t *node, uint8_t pdo)
{
    if (pdo >= CO_NUM_PDO) return;
    co_tpdo_request_event(&node->tpdo[pdo], operational(node), node->now_us);
}

/* ------------------------------------------------------------------ SYNC */

static void sync_event(co_node_t *node, uint8_t counter)
{
    if (node->nmt != CO_NMT_OPERATIONAL && node->nmt != CO_NMT_PRE_OPERATIONAL) return;
    node->sync_counter = counter;
    ++node->syncs;
    if (operational(node)) { /* actuate synchronous RPDOs (a PDO that is not valid does nothing: not called) */
        for (uint8_t n = 0; n < CO_NUM_PDO; ++n)
            if (node->rpdo[n].valid) co_rpdo_actuate(&node->rpdo[n]);
    }
    if (node->hooks.on_sync) node->hooks.on_sync(node->user, node, counter);
    if (operational(node)) {
        for (uint8_t n = 0; n < CO_NUM_PDO; ++n)
            if (node->tpdo[n].valid) co_tpdo_on_sync(&node->tpdo[n], counter, true, node->now_us);
    }
}

/* A SYNC of the producer: its frame on the bus (send) or not (co_sync_produce_local), then its event. */
static int sync_produce(co_node_t *node, int64_t now_us, bool send)
{
    node->now_us = now_us;
    uint32_t cob = node->c_sync_cob;
    if (!(cob & 0x40000000u)) return -1;
    if (node->nmt != CO_NMT_OPERATIONAL && node->nmt != CO_NMT_PRE_OPERATIONAL) return -1;
    uint8_t ov = node->c_sync_overflow;
    uint8_t counter = 0;
    if (ov >= 2u) counter = (uint8_t)(node->sync_counter >= ov ? 1u : node->sync_counter + 1u);
    if (send) co_tx_send(&node->tx, (uint16_t)(cob & 0x7FFu), ov >= 2u ? &counter : NULL, ov >= 2u ? 1u : 0u);
    sync_event(node, counter);
    return counter;
}

int co_sync_produce(co_node_t *node, int64_t now_us) { return sync_produce(node, now_us, true); }

int co_sync_produce_local(co_node_t *node, int64_t now_us) { return sync_produce(node, now_us, false); }

/* CiA 301 rules of an SDO write to the SYNC objects (0x1005, 0x1019). */
static uint32_t sync_check_write(const co_node_t *node, const co_od_entry_t *e, const uint8_t *data)
{
    if (e->index == IDX_SYNC_OVERFLOW) {
        if (co_od_get_u32(node->od, IDX_CYCLE_PERIOD, 0) != 0u) return CO_ABORT_DATA_STATE;
        if (data[0] == 1u) return CO_ABORT_INVALID_VALUE;
    }
    if (e->index == IDX_SYNC_COBID) {
        uint32_t v = (uint32_t)data[0] | (uint32_t)data[1] << 8 | (uint32_t)data[2] << 16 | (uint32_t)data[3] << 24;
        if (v & 0x20000000u) return CO_ABORT_INVALID_VALUE;      /* 29-bit identifiers not supported */
        if (co_cob_restricted(v)) return CO_ABORT_INVALID_VALUE; /* bit 30 = producer; always in use */
    }
    return 0;
}

/* ------------------------------------------------------------------ SDO writes */

/* Whether the PDOs that are valid still fit their frames after 0x2105:sub = v (CiA 301: a PDO is made invalid
 * before what it depends on changes; one mapped beyond 8 bytes is refused classic frames while it is valid). */
static bool fd_write_keeps_pdos(const co_node_t *node, uint8_t sub, uint8_t v)
{
    for (uint8_t i = 0; i < CO_NUM_PDO; ++i) {
        const co_pdo_t *t = &node->tpdo[i], *r = &node->rpdo[i];
        bool classic = (sub == 1u && v == 0u) || (sub == 2u && ((v >> i) & 1u));
        if (classic && t->valid && t->bytes > 8u) return false;
        if (sub == 1u && v == 0u && r->valid && r->bytes > 8u) return false;
    }
    return true;
}

static co_pdo_t *pdo_owning(co_node_t *node, uint16_t index)
{
    for (uint8_t i = 0; i < CO_NUM_PDO; ++i) {
        if (co_pdo_owns(&node->rpdo[i], index)) return &node->rpdo[i];
        if (co_pdo_owns(&node->tpdo[i], index)) return &node->tpdo[i];
    }
    return NULL;
}

/* The SDO server's write path: generic checks, the communication-area rules of the
 * services, the application's veto, then store and re-configure what depends on it. */
static uint32_t sdo_write(void *ctx, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    co_node_t *node = (co_node_t *)ctx;
    uint32_t abort = co_od_check_write(e, data, len);
    if (abort) return abort;
    abort = co_emcy_check_write(&node->emcy, e, data);
    if (abort) return abort;
    abort = sync_check_write(node, e, data);
    if (abort) return abort;
    abort = co_fd_check_write(e, data, operational(node));
    if (abort) return abort;
    if (e->index == CO_IDX_CAN_FD && !fd_write_keeps_pdos(node, e->subindex, data[0])) return CO_ABORT_PARAM_INCOMPAT;
    co_pdo_t *pdo = pdo_owning(node, e->index);
    if (pdo) {
        abort = co_pdo_check_write(pdo, e, data, node->c_sync_cob);
        if (abort) return abort;
    }
    co_od_ext_t *x = co_bindings_find(&node->bindings, e->index);
    if (x != NULL && x->check != NULL) {
        abort = x->check(x->object, e, data, len);
        if (abort) return abort;
    }
    co_emcy_before_store(&node->emcy, e);
    co_od_store(e, data, len);
    if (e->index < 0x2000u) refresh_cache(node);
    if (e->index == 0x1016u) co_hb_configure(node->hb, node->od); /* the heartbeat consumers */
    if (e->index == IDX_HB_PRODUCER) node->hb_next_us = node->now_us + (int64_t)node->c_hb_ms * 1000;
    if (e->index == IDX_CYCLE_PERIOD) node->sync_next_us = node->now_us;
    if (pdo) {
        co_pdo_configure(pdo);
        cache_rpdo_cobs(node);
    }
    if (e->index == CO_IDX_CAN_FD) configure_pdos(node); /* beyond 8 bytes a PDO is valid only with CAN FD */
    if (x != NULL && x->written != NULL) x->written(x->object, e);
    return 0;
}

/* ------------------------------------------------------------------ dispatch */

void co_node_process(co_node_t *node, const co_frame_t *frame, int64_t now_us)
{
    node->now_us = now_us;
    ++node->rx_frames;
    if (frame->cob_id & CO_FRAME_RTR) return; /* remote frames are not used (CiA recommends against) */
    uint16_t id = (uint16_t)(frame->cob_id & 0x7FFu);
    if (frame->dlc > CO_FRAME_MAX_DATA) return;

    /* An RPDO first (the frames of every period): its COB-ID is never one of the ids below (co_cob_restricted;
     * the SYNC's keeps its precedence should 0x1005 be set to an RPDO's later), so the order changes nothing. */
    if (operational(node) && id != (node->c_sync_cob & 0x7FFu)) {
        int matched = 0;
        for (uint8_t n = 0; n < CO_NUM_PDO; ++n) {
            if (node->rpdo_cob[n] != id) continue;
            co_rpdo_receive(&node->rpdo[n], frame, node->now_us);
            matched = 1;
        }
        if (matched) return;
    }
    if (id == 0x000u) { /* NMT */
        if (frame->dlc == 2u && (frame->data[1] == 0u || frame->data[1] == node->node_id))
            co_nmt_command(node, frame->data[0]);
        return;
    }
    if (node->nmt == CO_NMT_INITIALIZING) return;

    /* Heartbeat consumer (also in STOPPED). */
    if (id > 0x700u && id <= 0x77Fu && frame->dlc == 1u) {
        co_hb_consume(node->hb, &node->emcy, id, frame->data[0], now_us);
        return;
    }
    if (node->nmt == CO_NMT_STOPPED) return;

    uint32_t sync_cob = node->c_sync_cob;
    if (id == (sync_cob & 0x7FFu) && !(sync_cob & 0x40000000u)) { /* SYNC consumer */
        uint8_t ov = node->c_sync_overflow;
        uint8_t expect = ov >= 2u ? 1u : 0u;
        if (frame->dlc != expect) {
            uint8_t msef[5] = {frame->dlc, 0, 0, 0, 0};
            co_emcy_report_error(&node->emcy, CO_EMCY_SYNC_LENGTH, CO_ERR_REG_COMMUNICATION, msef);
            return;
        }
        sync_event(node, expect ? frame->data[0] : 0u);
        return;
    }
    if (id == 0x600u + node->node_id) co_sdo_server_process(&node->sdo, frame, node->now_us);
}

void co_node_tick(co_node_t *node, int64_t now_us)
{
    node->now_us = now_us;
    if (node->nmt == CO_NMT_INITIALIZING) return;
    uint16_t hb_ms = node->c_hb_ms;
    if (hb_ms && now_us >= node->hb_next_us) {
        uint8_t st = (uint8_t)node->nmt;
        co_tx_send(&node->tx, (uint16_t)(0x700u + node->node_id), &st, 1);
        node->hb_next_us += (int64_t)hb_ms * 1000;
        if (node->hb_next_us <= now_us) node->hb_next_us = now_us + (int64_t)hb_ms * 1000;
    }
    for (uint8_t i = 0; i < CO_HB_CONSUMERS; ++i) /* each late consumer: its EMCY, then the hook */
        if (co_hb_check(&node->hb[i], &node->emcy, now_us) && node->hooks.on_hb_timeout)
            node->hooks.on_hb_timeout(node->user, node, node->hb[i].node_id);
    if (node->sync_timer_enabled) {
        uint32_t period = node->c_cycle_us;
        if (period && now_us >= node->sync_next_us) {
            co_sync_produce(node, now_us);
            node->sync_next_us += period;
            if (node->sync_next_us <= now_us) node->sync_next_us = now_us + period;
        }
    }
    co_sdo_server_tick(&node->sdo, node->now_us);
    if (operational(node)) {
        for (uint8_t n = 0; n < CO_NUM_PDO; ++n) {
            co_tpdo_tick(&node->tpdo[n], operational(node), node->now_us);
            co_rpdo_check_deadline(&node->rpdo[n], node->now_us);
        }
    }
}

void co_node_excuse_us(co_node_t *node, int64_t stall_us) { co_hb_excuse(node->hb, stall_us); }

int64_t co_node_next_event_us(const co_node_t *node, int64_t now_us, int64_t max_us)
{
    int64_t next = now_us + max_us;
    if (node->c_hb_ms && node->hb_next_us < next) next = node->hb_next_us;
    if (node->sync_timer_enabled && node->c_cycle_us && node->sync_next_us < next) next = node->sync_next_us;
    for (uint8_t i = 0; i < CO_NUM_PDO; ++i) next = co_tpdo_next_event(&node->tpdo[i], next);
    next = co_sdo_server_next_event(&node->sdo, next);
    next = co_hb_next_event(node->hb, next);
    int64_t d = next - now_us;
    return d < 0 ? 0 : d;
}
