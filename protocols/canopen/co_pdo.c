/* co_pdo.c - PDOs (CiA 301 7.2.2): mapping from the OD, synchronous (1-240, and
 * acyclic 0) and event-driven (254/255) transmission with inhibit and event
 * timers, RPDO deadline monitoring, synchronous RPDOs actuated at the next SYNC,
 * and the re-mapping procedure by SDO with its abort codes. */
#include <string.h>

#include "co_node.h"

#define RPDO_COMM 0x1400u
#define RPDO_MAP 0x1600u
#define TPDO_COMM 0x1800u
#define TPDO_MAP 0x1A00u
#define COB_INVALID 0x80000000u
#define COB_EXTENDED 0x20000000u

static uint32_t le32(const uint8_t *b)
{
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}

/* Resolve one mapping entry; returns an abort code or 0. */
static uint32_t resolve(co_node_t *node, uint32_t map, bool is_tpdo, const co_od_entry_t **out)
{
    uint16_t index = (uint16_t)(map >> 16);
    uint8_t sub = (uint8_t)(map >> 8);
    uint8_t bits = (uint8_t)map;
    int exists = 0;
    const co_od_entry_t *e = co_od_find(node->od, index, sub, &exists);
    if (!e) return exists ? CO_ABORT_NO_SUB : CO_ABORT_NO_OBJECT;
    if (!(e->flags & CO_ODF_PDO)) return CO_ABORT_NO_MAP;
    if (is_tpdo ? !(e->flags & CO_ODF_READ) : !(e->flags & CO_ODF_WRITE)) return CO_ABORT_NO_MAP;
    uint32_t size = co_dt_size(e->datatype);
    if (size == 0u || bits != size * 8u) return CO_ABORT_NO_MAP;
    *out = e;
    return 0;
}

static void configure(co_node_t *node, uint8_t n, bool is_tpdo)
{
    co_pdo_t *p = is_tpdo ? &node->tpdo[n] : &node->rpdo[n];
    uint16_t comm = (uint16_t)((is_tpdo ? TPDO_COMM : RPDO_COMM) + n);
    uint16_t mapi = (uint16_t)((is_tpdo ? TPDO_MAP : RPDO_MAP) + n);
    memset(p, 0, sizeof *p);
    if (!co_od_find(node->od, comm, 1, NULL)) return; /* PDO not in this OD */
    uint32_t cob = co_od_get_u32(node->od, comm, 1);
    p->cob_id = (uint16_t)(cob & 0x7FFu);
    p->trans_type = (uint8_t)co_od_get_u32(node->od, comm, 2);
    uint32_t count = co_od_get_u32(node->od, mapi, 0);
    if (count > CO_PDO_MAX_MAPPED) count = 0;
    uint32_t bytes = 0;
    for (uint8_t i = 0; i < count; ++i) {
        const co_od_entry_t *e = NULL;
        if (resolve(node, co_od_get_u32(node->od, mapi, (uint8_t)(i + 1u)), is_tpdo, &e) != 0) {
            count = 0;
            bytes = 0;
            break;
        }
        p->entry[i] = e;
        bytes += co_dt_size(e->datatype);
    }
    if (bytes > 8u) { count = 0; bytes = 0; }
    p->count = (uint8_t)count;
    p->bytes = (uint8_t)bytes;
    p->valid = !(cob & COB_INVALID) && !(cob & COB_EXTENDED) && count > 0u;
    p->sync_start = (uint8_t)co_od_get_u32(node->od, comm, 6);
    p->event_ms = (uint16_t)co_od_get_u32(node->od, comm, 5);
    p->inhibit_100us = (uint16_t)co_od_get_u32(node->od, comm, 3);
    p->started = p->sync_start == 0u;
}

void co_pdo_configure_all(co_node_t *node)
{
    for (uint8_t i = 0; i < CO_NUM_PDO; ++i) {
        configure(node, i, false);
        configure(node, i, true);
    }
}

/* Which PDO object does this entry belong to? */
static bool pdo_object(uint16_t index, bool *is_tpdo, bool *is_map, uint8_t *n)
{
    if (index >= RPDO_COMM && index < RPDO_COMM + CO_NUM_PDO) { *is_tpdo = false; *is_map = false; *n = (uint8_t)(index - RPDO_COMM); return true; }
    if (index >= RPDO_MAP && index < RPDO_MAP + CO_NUM_PDO) { *is_tpdo = false; *is_map = true; *n = (uint8_t)(index - RPDO_MAP); return true; }
    if (index >= TPDO_COMM && index < TPDO_COMM + CO_NUM_PDO) { *is_tpdo = true; *is_map = false; *n = (uint8_t)(index - TPDO_COMM); return true; }
    if (index >= TPDO_MAP && index < TPDO_MAP + CO_NUM_PDO) { *is_tpdo = true; *is_map = true; *n = (uint8_t)(index - TPDO_MAP); return true; }
    return false;
}

uint32_t co_pdo_check_write(co_node_t *node, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    bool is_tpdo, is_map;
    uint8_t n;
    (void)len;
    if (!pdo_object(e->index, &is_tpdo, &is_map, &n)) return 0;
    uint16_t comm = (uint16_t)((is_tpdo ? TPDO_COMM : RPDO_COMM) + n);
    uint16_t mapi = (uint16_t)((is_tpdo ? TPDO_MAP : RPDO_MAP) + n);
    uint32_t cob = co_od_get_u32(node->od, comm, 1);
    bool pdo_valid = !(cob & COB_INVALID);
    if (!is_map) {
        switch (e->subindex) {
        case 1: {
            uint32_t v = le32(data);
            if (v & COB_EXTENDED) return CO_ABORT_INVALID_VALUE;
            /* While the PDO exists only the valid bit may change (CiA 301 7.5.2.35). */
            if (pdo_valid && !(v & COB_INVALID) && ((v ^ cob) & 0x7FFu)) return CO_ABORT_INVALID_VALUE;
            if (!(v & COB_INVALID)) {
                /* Restricted identifiers (CiA 301) and the SYNC identifier. */
                if (co_cob_restricted(v) || (v & 0x7FFu) == (node->c_sync_cob & 0x7FFu))
                    return CO_ABORT_INVALID_VALUE;
                if (co_od_get_u32(node->od, mapi, 0) == 0u) return 0; /* valid but empty: allowed, sends nothing */
            }
            return 0;
        }
        case 2: {
            uint8_t t = data[0];
            if (t <= 240u || t >= 254u) return 0;
            return CO_ABORT_INVALID_VALUE; /* 241-251 reserved; 252/253 (RTR-only) not supported */
        }
        case 3: /* inhibit time: only while the PDO does not exist */
            return pdo_valid ? CO_ABORT_UNSUPPORTED : 0;
        default: return 0;
        }
    }
    /* Mapping parameter: CiA 301 re-mapping procedure. */
    if (pdo_valid) return CO_ABORT_UNSUPPORTED;            /* step a) not done */
    uint32_t count = co_od_get_u32(node->od, mapi, 0);
    if (e->subindex == 0u) {
        uint8_t newc = data[0];
        if (newc > CO_PDO_MAX_MAPPED) return CO_ABORT_MAP_LEN;
        uint32_t bytes = 0;
        for (uint8_t i = 0; i < newc; ++i) {                /* step d) */
            const co_od_entry_t *m = NULL;
            uint32_t a = resolve(node, co_od_get_u32(node->od, mapi, (uint8_t)(i + 1u)), is_tpdo, &m);
            if (a) return a == CO_ABORT_NO_SUB ? CO_ABORT_NO_OBJECT : a;
            bytes += co_dt_size(m->datatype);
        }
        if (bytes > 8u) return CO_ABORT_MAP_LEN;
        return 0;
    }
    if (count != 0u) return CO_ABORT_UNSUPPORTED;           /* step b) not done */
    uint32_t v = le32(data);
    if (v == 0u) return 0;                                  /* clearing an entry */
    const co_od_entry_t *m = NULL;
    uint32_t a = resolve(node, v, is_tpdo, &m);             /* step c) */
    if (a) return a == CO_ABORT_NO_SUB ? CO_ABORT_NO_OBJECT : a;
    return 0;
}

void co_pdo_after_write(co_node_t *node, const co_od_entry_t *e)
{
    bool is_tpdo, is_map;
    uint8_t n;
    if (!pdo_object(e->index, &is_tpdo, &is_map, &n)) return;
    configure(node, n, is_tpdo);
}

static int tpdo_send(co_node_t *node, uint8_t n)
{
    co_pdo_t *p = &node->tpdo[n];
    if (!p->valid || node->nmt != CO_NMT_OPERATIONAL) return -1;
    uint8_t d[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    uint8_t off = 0;
    for (uint8_t i = 0; i < p->count; ++i) {
        if (node->hooks.pre_read) node->hooks.pre_read(node->user, node, p->entry[i]);
        off = (uint8_t)(off + co_od_read_raw(p->entry[i], 0, &d[off], (uint32_t)(8u - off)));
    }
    p->pending = false;
    p->last_tx_us = node->now_us;
    p->next_event_us = (p->trans_type >= 254u && p->event_ms) ? node->now_us + (int64_t)p->event_ms * 1000 : 0;
    return co_node_send(node, p->cob_id, d, p->bytes);
}

static bool inhibit_elapsed(co_node_t *node, uint8_t n)
{
    co_pdo_t *p = &node->tpdo[n];
    return p->last_tx_us == 0 || node->now_us - p->last_tx_us >= (int64_t)p->inhibit_100us * 100;
}

void co_tpdo_request(co_node_t *node, uint8_t pdo)
{
    if (pdo >= CO_NUM_PDO) return;
    co_pdo_t *p = &node->tpdo[pdo];
    if (!p->valid || node->nmt != CO_NMT_OPERATIONAL) return;
    if (p->trans_type >= 254u) {
        if (inhibit_elapsed(node, pdo)) tpdo_send(node, pdo);
        else p->pending = true;
    } else if (p->trans_type == 0u) {
        p->pending = true; /* acyclic synchronous: goes out at the next SYNC */
    }
}

void co_pdo_rx(co_node_t *node, const co_frame_t *frame)
{
    uint16_t id = (uint16_t)(frame->cob_id & 0x7FFu);
    for (uint8_t n = 0; n < CO_NUM_PDO; ++n) {
        co_pdo_t *p = &node->rpdo[n];
        if (!p->valid || p->cob_id != id) continue;
        if (frame->dlc < p->bytes) {
            if (!p->length_reported) {
                uint8_t msef[5] = {frame->dlc, p->bytes, (uint8_t)(n + 1u), 0, 0};
                co_emcy_raise(node, CO_EMCY_PDO_LENGTH, CO_ERR_REG_COMMUNICATION, msef);
                p->length_reported = true;
            }
            continue; /* not processed (CiA 301) */
        }
        if (frame->dlc > p->bytes && !p->length_reported) {
            uint8_t msef[5] = {frame->dlc, p->bytes, (uint8_t)(n + 1u), 0, 0};
            co_emcy_raise(node, CO_EMCY_PDO_LENGTH_EXCEEDED, CO_ERR_REG_COMMUNICATION, msef);
            p->length_reported = true;
        }
        p->last_rx_us = node->now_us;
        p->deadline_armed = true;
        if (p->deadline_reported) {
            p->deadline_reported = false;
            co_emcy_clear(node, CO_EMCY_RPDO_TIMEOUT);
        }
        if (p->trans_type <= 240u) {
            memcpy(p->rx_buf, frame->data, p->bytes); /* actuated at the next SYNC */
            p->rx_buffered = true;
        } else {
            uint8_t off = 0;
            for (uint8_t i = 0; i < p->count; ++i) {
                uint32_t sz = co_dt_size(p->entry[i]->datatype);
                co_od_store(p->entry[i], &frame->data[off], sz);
                off = (uint8_t)(off + sz);
            }
            if (node->hooks.on_rpdo) node->hooks.on_rpdo(node->user, node, n);
        }
    }
}

void co_pdo_sync(co_node_t *node, uint8_t counter)
{
    (void)counter;
    for (uint8_t n = 0; n < CO_NUM_PDO; ++n) {
        co_pdo_t *p = &node->rpdo[n];
        if (!p->valid || !p->rx_buffered) continue;
        uint8_t off = 0;
        for (uint8_t i = 0; i < p->count; ++i) {
            uint32_t sz = co_dt_size(p->entry[i]->datatype);
            co_od_store(p->entry[i], &p->rx_buf[off], sz);
            off = (uint8_t)(off + sz);
        }
        p->rx_buffered = false;
        if (node->hooks.on_rpdo) node->hooks.on_rpdo(node->user, node, n);
    }
}

void co_pdo_sync_tx(co_node_t *node, uint8_t counter)
{
    for (uint8_t n = 0; n < CO_NUM_PDO; ++n) {
        co_pdo_t *p = &node->tpdo[n];
        if (!p->valid) continue;
        if (p->trans_type == 0u) {
            if (p->pending) tpdo_send(node, n);
            continue;
        }
        if (p->trans_type > 240u) continue;
        if (!p->started) {
            if (counter != p->sync_start) continue;
            p->started = true;
            p->sync_count = 0;
        }
        if (++p->sync_count >= p->trans_type) {
            p->sync_count = 0;
            tpdo_send(node, n);
        }
    }
}

void co_pdo_tick(co_node_t *node)
{
    for (uint8_t n = 0; n < CO_NUM_PDO; ++n) {
        co_pdo_t *t = &node->tpdo[n];
        if (t->valid && t->trans_type >= 254u) {
            if (t->pending && inhibit_elapsed(node, n)) tpdo_send(node, n);
            else if (t->next_event_us && node->now_us >= t->next_event_us) tpdo_send(node, n);
            else if (!t->next_event_us && t->event_ms) {
                t->next_event_us = node->now_us + (int64_t)t->event_ms * 1000;
            }
        }
        co_pdo_t *r = &node->rpdo[n];
        if (r->valid && r->deadline_armed && !r->deadline_reported) {
            if (r->event_ms && node->now_us - r->last_rx_us > (int64_t)r->event_ms * 1000) {
                uint8_t msef[5] = {(uint8_t)(n + 1u), 0, 0, 0, 0};
                co_emcy_raise(node, CO_EMCY_RPDO_TIMEOUT, CO_ERR_REG_COMMUNICATION, msef);
                r->deadline_reported = true;
            }
        }
    }
}
