/* co_pdo.c - PDOs (CiA 301 7.2.2): mapping from the OD, synchronous (1-240, and acyclic 0) and event-driven
 * (254/255) transmission with inhibit and event timers, RPDO deadline monitoring, synchronous RPDOs actuated at the
 * next SYNC, the re-mapping procedure by SDO with its abort codes, and CAN FD frames (co_fd.h, 0x2105).
 * SYNC start value (TPDO sub 6, types 1-240; CiA 301 7.5.2.37): with a SYNC counter (0x1019 >= 2) and a start value
 * S != 0, the first PDO goes out at the SYNC whose counter is S, then every transmission type-th SYNC (S + n,
 * S + 2n, ...: as CANopenNode's CO_TPDO_process); without a counter S is ignored.  Start value 0: the first PDO at
 * the n-th SYNC.  Sub 6 may be written only while the PDO is not valid. */
#include "co_pdo.h"

#include <string.h>

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

static void wire(co_pdo_t *p, uint8_t n, const co_pdo_env_t *env, bool is_tpdo)
{
    memset(p, 0, sizeof *p);
    p->link.env = env;
    p->link.comm_index = (uint16_t)((is_tpdo ? TPDO_COMM : RPDO_COMM) + n);
    p->link.map_index = (uint16_t)((is_tpdo ? TPDO_MAP : RPDO_MAP) + n);
    p->link.number = n;
    p->link.is_tpdo = is_tpdo;
}

void co_rpdo_init(co_pdo_t *p, uint8_t n, const co_pdo_env_t *env) { wire(p, n, env, false); }
void co_tpdo_init(co_pdo_t *p, uint8_t n, const co_pdo_env_t *env) { wire(p, n, env, true); }

void co_pdo_bind(co_pdo_t *p)
{
    const co_pdo_env_t *env = p->link.env;
    p->n_refresh = 0;
    if (!p->link.is_tpdo || env->ext_of == NULL) return;
    for (uint8_t i = 0; i < p->count; ++i) {
        if (i != 0u && p->entry[i]->index == p->entry[i - 1u]->index) continue;
        co_od_ext_t *x = env->ext_of(env->ctx, p->entry[i]->index);
        if (x == NULL || x->read == NULL) continue;
        p->refresh[p->n_refresh] = x;
        p->refresh_entry[p->n_refresh] = p->entry[i];
        ++p->n_refresh;
    }
}

static uint8_t pdo_flags(const co_pdo_t *p) { return co_fd_flags(&p->link.env->fd, p->link.is_tpdo, p->link.number); }

uint8_t co_pdo_max_bytes(const co_pdo_t *p) { return pdo_flags(p) ? (uint8_t)CO_FRAME_MAX_DATA : 8u; }

bool co_pdo_maps(const co_pdo_t *p, uint16_t index)
{
    for (uint8_t i = 0; i < p->count; ++i)
        if (p->entry[i]->index == index) return true;
    return false;
}

bool co_pdo_maps_entry(const co_pdo_t *p, uint16_t index, uint8_t subindex)
{
    for (uint8_t i = 0; i < p->count; ++i)
        if (p->entry[i]->index == index && p->entry[i]->subindex == subindex) return true;
    return false;
}

bool co_pdo_owns(const co_pdo_t *p, uint16_t index)
{
    return index == p->link.comm_index || index == p->link.map_index;
}

/* Resolve one mapping entry; returns an abort code or 0. */
static uint32_t resolve(const co_od_t *od, uint32_t map, bool is_tpdo, const co_od_entry_t **out)
{
    uint16_t index = (uint16_t)(map >> 16);
    uint8_t sub = (uint8_t)(map >> 8);
    uint8_t bits = (uint8_t)map;
    int exists = 0;
    const co_od_entry_t *e = co_od_find(od, index, sub, &exists);
    if (!e) return exists ? CO_ABORT_NO_SUB : CO_ABORT_NO_OBJECT;
    if (!(e->flags & CO_ODF_PDO)) return CO_ABORT_NO_MAP;
    if (is_tpdo ? !(e->flags & CO_ODF_READ) : !(e->flags & CO_ODF_WRITE)) return CO_ABORT_NO_MAP;
    uint32_t size = co_dt_size(e->datatype);
    if (size == 0u || bits != size * 8u) return CO_ABORT_NO_MAP;
    *out = e;
    return 0;
}

void co_pdo_configure(co_pdo_t *p)
{
    const co_pdo_link_t link = p->link;
    const co_od_t *od = link.env->od;
    uint16_t comm = link.comm_index;
    uint16_t mapi = link.map_index;
    memset(p, 0, sizeof *p);
    p->link = link;
    if (!co_od_find(od, comm, 1, NULL)) return; /* PDO not in this OD */
    uint32_t cob = co_od_get_u32(od, comm, 1);
    p->cob_id = (uint16_t)(cob & 0x7FFu);
    p->trans_type = (uint8_t)co_od_get_u32(od, comm, 2);
    uint32_t count = co_od_get_u32(od, mapi, 0);
    if (count > CO_PDO_MAX_MAPPED) count = 0;
    uint32_t bytes = 0;
    for (uint8_t i = 0; i < count; ++i) {
        const co_od_entry_t *e = NULL;
        if (resolve(od, co_od_get_u32(od, mapi, (uint8_t)(i + 1u)), link.is_tpdo, &e) != 0) {
            count = 0;
            bytes = 0;
            break;
        }
        p->entry[i] = e;
        bytes += co_dt_size(e->datatype);
    }
    if (bytes > co_pdo_max_bytes(p)) { /* mapped for CAN FD, and the node went back to classic frames */
        count = 0;
        bytes = 0;
    }
    p->count = (uint8_t)count;
    p->bytes = (uint8_t)bytes;
    p->native = co_host_is_little() != 0;
    bool contiguous = p->native && p->count > 0u;
    for (uint8_t i = 0; i < p->count; ++i) {
        p->field[i].data = (uint8_t *)p->entry[i]->data;
        p->field[i].size = (uint8_t)co_dt_size(p->entry[i]->datatype);
        if (i > 0u && p->field[i].data != p->field[i - 1u].data + p->field[i - 1u].size) contiguous = false;
    }
    p->block = contiguous ? p->field[0].data : NULL;
    co_pdo_bind(p);
    p->valid = !(cob & COB_INVALID) && !(cob & COB_EXTENDED) && count > 0u;
    p->sync_start = (uint8_t)co_od_get_u32(od, comm, 6);
    p->event_ms = (uint16_t)co_od_get_u32(od, comm, 5);
    p->inhibit_100us = (uint16_t)co_od_get_u32(od, comm, 3);
    p->started = p->sync_start == 0u;
}

static uint32_t check_comm_write(const co_pdo_t *p, const co_od_entry_t *e, const uint8_t *data, uint32_t sync_cob_id,
                                 uint32_t cob)
{
    const co_od_t *od = p->link.env->od;
    bool pdo_valid = !(cob & COB_INVALID);
    switch (e->subindex) {
    case 1: {
        uint32_t v = le32(data);
        if (v & COB_EXTENDED) return CO_ABORT_INVALID_VALUE;
        /* While the PDO exists only the valid bit may change (CiA 301 7.5.2.35). */
        if (pdo_valid && !(v & COB_INVALID) && ((v ^ cob) & 0x7FFu)) return CO_ABORT_INVALID_VALUE;
        if (!(v & COB_INVALID)) {
            /* Restricted identifiers (CiA 301) and the SYNC identifier. */
            if (co_cob_restricted(v) || (v & 0x7FFu) == (sync_cob_id & 0x7FFu)) return CO_ABORT_INVALID_VALUE;
            if (co_od_get_u32(od, p->link.map_index, 0) == 0u) return 0; /* valid but empty: allowed, sends nothing */
        }
        return 0;
    }
    case 2: {
        uint8_t t = data[0];
        if (t <= 240u || t >= 254u) return 0;
        return CO_ABORT_INVALID_VALUE; /* 241-251 reserved; 252/253 (RTR-only) not supported */
    }
    case 3: /* inhibit time: only while the PDO does not exist */ return pdo_valid ? CO_ABORT_UNSUPPORTED : 0;
    case 6: /* TPDO SYNC start value: only while the PDO does not exist (CiA 301 7.5.2.37, as CANopenNode) */
        if (!p->link.is_tpdo) return 0;
        return pdo_valid || data[0] > 240u ? CO_ABORT_INVALID_VALUE : 0;
    default: return 0;
    }
}

/* CiA 301 re-mapping procedure. */
static uint32_t check_map_write(const co_pdo_t *p, const co_od_entry_t *e, const uint8_t *data, uint32_t cob)
{
    const co_od_t *od = p->link.env->od;
    uint16_t mapi = p->link.map_index;
    bool is_tpdo = p->link.is_tpdo;
    if (!(cob & COB_INVALID)) return CO_ABORT_UNSUPPORTED; /* step a) not done */
    uint32_t count = co_od_get_u32(od, mapi, 0);
    if (e->subindex == 0u) {
        uint8_t newc = data[0];
        if (newc > CO_PDO_MAX_MAPPED) return CO_ABORT_MAP_LEN;
        uint32_t bytes = 0;
        for (uint8_t i = 0; i < newc; ++i) { /* step d) */
            const co_od_entry_t *m = NULL;
            uint32_t a = resolve(od, co_od_get_u32(od, mapi, (uint8_t)(i + 1u)), is_tpdo, &m);
            if (a) return a == CO_ABORT_NO_SUB ? CO_ABORT_NO_OBJECT : a;
            bytes += co_dt_size(m->datatype);
        }
        if (bytes > co_pdo_max_bytes(p)) return CO_ABORT_MAP_LEN;
        return 0;
    }
    if (count != 0u) return CO_ABORT_UNSUPPORTED; /* step b) not done */
    uint32_t v = le32(data);
    if (v == 0u) return 0; /* clearing an entry */
    const co_od_entry_t *m = NULL;
    uint32_t a = resolve(od, v, is_tpdo, &m); /* step c) */
    if (a) return a == CO_ABORT_NO_SUB ? CO_ABORT_NO_OBJECT : a;
    return 0;
}

uint32_t co_pdo_check_write(const co_pdo_t *p, const co_od_entry_t *e, const uint8_t *data, uint32_t sync_cob_id)
{
    if (!co_pdo_owns(p, e->index)) return 0;
    uint32_t cob = co_od_get_u32(p->link.env->od, p->link.comm_index, 1);
    if (e->index == p->link.comm_index) return check_comm_write(p, e, data, sync_cob_id, cob);
    return check_map_write(p, e, data, cob);
}

void co_pdo_stop(co_pdo_t *p)
{
    p->rx_buffered = false;
    p->deadline_armed = false;
    p->pending = false;
    if (p->sync_start != 0u) p->started = false; /* back in OPERATIONAL: wait for the start value again */
}

/* ------------------------------------------------------------------ RPDO */

/* n bytes (a field, or a whole frame of contiguous fields), the size a constant in the usual cases: the compiler
 * moves them without a call. */
static inline void copy_bytes(uint8_t *dst, const uint8_t *src, uint8_t n)
{
    switch (n) {
    case 8: memcpy(dst, src, 8); break;
    case 4: memcpy(dst, src, 4); break;
    case 2: memcpy(dst, src, 2); break;
    case 1: dst[0] = src[0]; break;
    default: memcpy(dst, src, n); break;
    }
}

static void store_mapped(co_pdo_t *p, const uint8_t *data)
{
    if (p->block != NULL) {
        copy_bytes(p->block, data, p->bytes);
        return;
    }
    uint8_t off = 0;
    for (uint8_t i = 0; i < p->count; ++i) {
        const co_pdo_field_t *f = &p->field[i];
        if (p->native)
            copy_bytes(f->data, &data[off], f->size);
        else
            co_od_store(p->entry[i], &data[off], f->size);
        off = (uint8_t)(off + f->size);
    }
}

static void notify_rpdo(const co_pdo_t *p)
{
    const co_pdo_env_t *env = p->link.env;
    if (env->on_rpdo) env->on_rpdo(env->ctx, p->link.number);
}

static void notify_rx(const co_pdo_t *p)
{
    const co_pdo_env_t *env = p->link.env;
    if (env->on_rpdo_rx) env->on_rpdo_rx(env->ctx, p->link.number);
}

void co_rpdo_receive(co_pdo_t *p, const co_frame_t *frame, int64_t now_us)
{
    uint16_t id = (uint16_t)(frame->cob_id & 0x7FFu);
    if (!p->valid || p->cob_id != id) return;
    co_emcy_t *emcy = p->link.env->emcy;
    uint8_t msef[5] = {frame->dlc, p->bytes, (uint8_t)(p->link.number + 1u), 0, 0};
    if (frame->dlc < p->bytes) {
        if (!p->length_reported) {
            co_emcy_report_error(emcy, CO_EMCY_PDO_LENGTH, CO_ERR_REG_COMMUNICATION, msef);
            p->length_reported = true;
        }
        return; /* not processed (CiA 301) */
    }
    uint8_t wire = (frame->flags & CO_FRAME_FDF) ? co_frame_fd_len(p->bytes) : p->bytes; /* CAN FD: padded */
    if (frame->dlc > wire && !p->length_reported) {
        co_emcy_report_error(emcy, CO_EMCY_PDO_LENGTH_EXCEEDED, CO_ERR_REG_COMMUNICATION, msef);
        p->length_reported = true;
    }
    p->last_rx_us = now_us;
    p->deadline_armed = true;
    if (p->deadline_reported) {
        p->deadline_reported = false;
        co_emcy_clear_error(emcy, CO_EMCY_RPDO_TIMEOUT);
    }
    if (p->trans_type <= 240u) {
        memcpy(p->rx_buf, frame->data, p->bytes); /* actuated at the next SYNC */
        p->rx_buffered = true;
        notify_rx(p); /* each frame, also of a burst that overwrites the buffer before the SYNC */
    } else {
        store_mapped(p, frame->data);
        notify_rx(p);
        notify_rpdo(p);
    }
}

void co_rpdo_actuate(co_pdo_t *p)
{
    if (!p->valid || !p->rx_buffered) return;
    store_mapped(p, p->rx_buf);
    p->rx_buffered = false;
    notify_rpdo(p);
}

void co_rpdo_check_deadline(co_pdo_t *p, int64_t now_us)
{
    if (!p->valid || !p->deadline_armed || p->deadline_reported) return;
    if (p->event_ms && now_us - p->last_rx_us > (int64_t)p->event_ms * 1000) {
        uint8_t msef[5] = {(uint8_t)(p->link.number + 1u), 0, 0, 0, 0};
        co_emcy_report_error(p->link.env->emcy, CO_EMCY_RPDO_TIMEOUT, CO_ERR_REG_COMMUNICATION, msef);
        p->deadline_reported = true;
    }
}

/* ------------------------------------------------------------------ TPDO */

static int tpdo_send(co_pdo_t *p, bool operational, int64_t now_us)
{
    const co_pdo_env_t *env = p->link.env;
    if (!p->valid || !operational) return -1;
    for (uint8_t r = 0; r < p->n_refresh; ++r) p->refresh[r]->read(p->refresh[r]->object, p->refresh_entry[r]);
    uint8_t d[CO_FRAME_MAX_DATA];
    memset(d, 0, 8);
    uint8_t off = 0;
    if (p->block != NULL) {
        copy_bytes(d, p->block, p->bytes);
    } else {
        for (uint8_t i = 0; i < p->count; ++i) {
            const co_pdo_field_t *f = &p->field[i];
            if (p->native)
                copy_bytes(&d[off], f->data, f->size);
            else
                (void)co_od_read_raw(p->entry[i], 0, &d[off], f->size);
            off = (uint8_t)(off + f->size);
        }
    }
    p->pending = false;
    p->last_tx_us = now_us;
    p->next_event_us = (p->trans_type >= 254u && p->event_ms) ? now_us + (int64_t)p->event_ms * 1000 : 0;
    return co_tx_send_fd(env->tx, p->cob_id, d, p->bytes, pdo_flags(p));
}

static bool inhibit_elapsed(const co_pdo_t *p, int64_t now_us)
{
    return p->last_tx_us == 0 || now_us - p->last_tx_us >= (int64_t)p->inhibit_100us * 100;
}

void co_tpdo_request_event(co_pdo_t *p, bool operational, int64_t now_us)
{
    if (!p->valid || !operational) return;
    if (p->trans_type >= 254u) {
        if (inhibit_elapsed(p, now_us))
            tpdo_send(p, operational, now_us);
        else
            p->pending = true;
    } else if (p->trans_type == 0u) {
        p->pending = true; /* acyclic synchronous: goes out at the next SYNC */
    }
}

void co_tpdo_on_sync(co_pdo_t *p, uint8_t counter, bool operational, int64_t now_us)
{
    if (!p->valid) return;
    if (p->trans_type == 0u) {
        if (p->pending) tpdo_send(p, operational, now_us);
        return;
    }
    if (p->trans_type > 240u) return;
    if (!p->started) {
        if (!operational) return; /* counting starts at the start value seen while OPERATIONAL */
        p->started = true;
        p->sync_count = 0;
        if (counter != 0u) { /* a SYNC counter (0x1019 >= 2): the start value is in use */
            if (counter != p->sync_start) {
                p->started = false;
                return;
            }
            p->sync_count = (uint8_t)(p->trans_type - 1u); /* the SYNC equal to the start value sends the first */
        }
    }
    if (++p->sync_count >= p->trans_type) {
        p->sync_count = 0;
        tpdo_send(p, operational, now_us);
    }
}

void co_tpdo_tick(co_pdo_t *p, bool operational, int64_t now_us)
{
    if (!p->valid || p->trans_type < 254u) return;
    if (p->pending && inhibit_elapsed(p, now_us))
        tpdo_send(p, operational, now_us);
    else if (p->next_event_us && now_us >= p->next_event_us)
        tpdo_send(p, operational, now_us);
    else if (!p->next_event_us && p->event_ms)
        p->next_event_us = now_us + (int64_t)p->event_ms * 1000;
}

int64_t co_tpdo_next_event(const co_pdo_t *p, int64_t next_us)
{
    if (p->valid && p->next_event_us && p->next_event_us < next_us) return p->next_event_us;
    return next_us;
}
