/* co_sdo_server.c - SDO server (CiA 301 7.2.4): expedited and segmented
 * upload/download, toggle-bit check, timeout, abort codes. Block transfer is
 * answered with "command specifier not valid" (0x05040001), which masters such
 * as python canopen take as "use segmented transfer". */
#include "co_sdo_server.h"

#include <string.h>

void co_sdo_server_init(co_sdo_server_t *s, const co_od_t *od, co_tx_t *tx, uint8_t node_id, co_sdo_write_fn write,
                        co_sdo_pre_read_fn pre_read, void *ctx)
{
    memset(s, 0, sizeof *s);
    s->od = od;
    s->tx = tx;
    s->tx_cob_id = (uint16_t)(0x580u + node_id);
    s->timeout_us = CO_SDO_SERVER_TIMEOUT_US;
    s->write = write;
    s->pre_read = pre_read;
    s->ctx = ctx;
}

void co_sdo_server_reset(co_sdo_server_t *s) { memset(&s->transfer, 0, sizeof s->transfer); }

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static void sdo_send(co_sdo_server_t *s, const uint8_t d[8]) { co_tx_send(s->tx, s->tx_cob_id, d, 8); }

static void sdo_abort(co_sdo_server_t *s, uint16_t index, uint8_t sub, uint32_t code)
{
    uint8_t d[8] = {0x80, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
    put_u32(&d[4], code);
    sdo_send(s, d);
    ++s->aborts;
    s->transfer.state = CO_SDO_IDLE;
}

static const co_od_entry_t *lookup(const co_sdo_server_t *s, uint16_t index, uint8_t sub, uint32_t *abort)
{
    int exists = 0;
    const co_od_entry_t *e = co_od_find(s->od, index, sub, &exists);
    if (!e) *abort = exists ? CO_ABORT_NO_SUB : CO_ABORT_NO_OBJECT;
    return e;
}

static void begin_transfer(co_sdo_transfer_t *t, co_sdo_state_t state, const co_od_entry_t *e, uint16_t index,
                           uint8_t sub, uint32_t size, bool size_known, int64_t now_us)
{
    t->state = state;
    t->entry = e;
    t->index = index;
    t->subindex = sub;
    t->size = size;
    t->size_known = size_known; /* read by download segments only */
    t->offset = 0;
    t->toggle = 0;
    t->last_us = now_us;
}

static void upload_initiate(co_sdo_server_t *s, uint16_t index, uint8_t sub, int64_t now_us)
{
    uint32_t abort = 0;
    const co_od_entry_t *e = lookup(s, index, sub, &abort);
    if (!e) {
        sdo_abort(s, index, sub, abort);
        return;
    }
    if (!(e->flags & CO_ODF_READ)) {
        sdo_abort(s, index, sub, CO_ABORT_WRITE_ONLY);
        return;
    }
    if (s->pre_read) s->pre_read(s->ctx, e);
    uint32_t size = co_od_value_size(e);
    uint8_t d[8] = {0, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
    if (size <= 4u && size > 0u) {
        d[0] = (uint8_t)(0x43u | ((4u - size) << 2));
        co_od_read_raw(e, 0, &d[4], 4);
        sdo_send(s, d);
        s->transfer.state = CO_SDO_IDLE;
        return;
    }
    /* Segmented (also for empty strings/domains: size 0 in one empty last segment). */
    d[0] = 0x41;
    put_u32(&d[4], size);
    sdo_send(s, d);
    begin_transfer(&s->transfer, CO_SDO_UPLOAD, e, index, sub, size, false, now_us);
}

static void upload_segment(co_sdo_server_t *s, const uint8_t *req, int64_t now_us)
{
    co_sdo_transfer_t *t = &s->transfer;
    uint8_t toggle = (uint8_t)((req[0] >> 4) & 1u);
    if (toggle != t->toggle) {
        sdo_abort(s, t->index, t->subindex, CO_ABORT_TOGGLE);
        return;
    }
    uint8_t d[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    uint32_t n = co_od_read_raw(t->entry, t->offset, &d[1], 7);
    /* A value that shrank under the transfer (domain refreshed) ends it early. */
    t->offset += n;
    uint8_t last = t->offset >= t->size || n < 7u ? 1u : 0u;
    d[0] = (uint8_t)((toggle << 4) | ((7u - n) << 1) | last);
    sdo_send(s, d);
    t->toggle ^= 1u;
    t->last_us = now_us;
    if (last) t->state = CO_SDO_IDLE;
}

static void download_initiate(co_sdo_server_t *s, const uint8_t *req, uint16_t index, uint8_t sub, int64_t now_us)
{
    uint32_t abort = 0;
    const co_od_entry_t *e = lookup(s, index, sub, &abort);
    if (!e) {
        sdo_abort(s, index, sub, abort);
        return;
    }
    if (!(e->flags & CO_ODF_WRITE)) {
        sdo_abort(s, index, sub, CO_ABORT_READ_ONLY);
        return;
    }
    uint8_t cs = req[0];
    bool expedited = (cs & 0x02u) != 0u;
    bool size_ind = (cs & 0x01u) != 0u;
    uint32_t fixed = co_dt_size(e->datatype);
    if (expedited) {
        /* Without a size indication the length is only known for fixed-size types. */
        if (!size_ind && !fixed) {
            sdo_abort(s, index, sub, CO_ABORT_TYPE_MISMATCH);
            return;
        }
        uint32_t len = size_ind ? 4u - ((cs >> 2) & 3u) : fixed;
        abort = s->write(s->ctx, e, &req[4], len);
        if (abort) {
            sdo_abort(s, index, sub, abort);
            return;
        }
        uint8_t d[8] = {0x60, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
        sdo_send(s, d);
        s->transfer.state = CO_SDO_IDLE;
        return;
    }
    uint32_t size = (uint32_t)req[4] | (uint32_t)req[5] << 8 | (uint32_t)req[6] << 16 | (uint32_t)req[7] << 24;
    uint32_t cap = CO_SDO_BUF;
    if (fixed)
        cap = fixed;
    else if (e->datatype == CO_DT_VISIBLE_STRING)
        cap = e->size;
    else if (e->datatype == CO_DT_DOMAIN)
        cap = ((const co_domain_t *)e->data)->capacity;
    if (size_ind) {
        if (size > cap) {
            sdo_abort(s, index, sub, CO_ABORT_TOO_LONG);
            return;
        }
        if (fixed && size < fixed) {
            sdo_abort(s, index, sub, CO_ABORT_TOO_SHORT);
            return;
        }
    }
    if (e->datatype == CO_DT_DOMAIN && !((const co_domain_t *)e->data)->data) {
        sdo_abort(s, index, sub, CO_ABORT_DATA_LOCAL);
        return;
    }
    begin_transfer(&s->transfer, CO_SDO_DOWNLOAD, e, index, sub, size, size_ind, now_us);
    uint8_t d[8] = {0x60, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
    sdo_send(s, d);
}

static void download_segment(co_sdo_server_t *s, const uint8_t *req, int64_t now_us)
{
    co_sdo_transfer_t *t = &s->transfer;
    uint8_t toggle = (uint8_t)((req[0] >> 4) & 1u);
    if (toggle != t->toggle) {
        sdo_abort(s, t->index, t->subindex, CO_ABORT_TOGGLE);
        return;
    }
    uint32_t n = 7u - ((req[0] >> 1) & 7u);
    bool last = (req[0] & 1u) != 0u;
    const co_od_entry_t *e = t->entry;
    bool domain = e->datatype == CO_DT_DOMAIN;
    uint32_t cap = domain ? ((const co_domain_t *)e->data)->capacity
                          : (e->datatype == CO_DT_VISIBLE_STRING ? e->size : co_dt_size(e->datatype));
    if (cap > CO_SDO_BUF && !domain) cap = CO_SDO_BUF;
    if (t->offset + n > cap || (t->size_known && t->offset + n > t->size)) {
        sdo_abort(s, t->index, t->subindex, CO_ABORT_TOO_LONG);
        return;
    }
    if (domain) {
        /* Domains are streamed straight into the application's buffer; size set at the end. */
        memcpy(((co_domain_t *)e->data)->data + t->offset, &req[1], n);
    } else {
        memcpy(&t->buf[t->offset], &req[1], n);
    }
    t->offset += n;
    t->toggle ^= 1u;
    t->last_us = now_us;
    if (last) {
        if (t->size_known && t->offset != t->size) {
            sdo_abort(s, t->index, t->subindex, t->offset < t->size ? CO_ABORT_TOO_SHORT : CO_ABORT_TOO_LONG);
            return;
        }
        uint32_t abort;
        if (domain) {
            co_domain_t *dm = (co_domain_t *)e->data;
            abort = s->write(s->ctx, e, dm->data, t->offset);
        } else {
            abort = s->write(s->ctx, e, t->buf, t->offset);
        }
        if (abort) {
            sdo_abort(s, t->index, t->subindex, abort);
            return;
        }
        t->state = CO_SDO_IDLE;
    }
    uint8_t d[8] = {(uint8_t)(0x20u | (toggle << 4)), 0, 0, 0, 0, 0, 0, 0};
    sdo_send(s, d);
}

void co_sdo_server_process(co_sdo_server_t *s, const co_frame_t *request, int64_t now_us)
{
    if (request->dlc != 8u) return; /* SDO frames are always 8 bytes; others are not SDO requests */
    const uint8_t *req = request->data;
    uint8_t ccs = (uint8_t)(req[0] >> 5);
    uint16_t index = (uint16_t)(req[1] | (req[2] << 8));
    uint8_t sub = req[3];
    co_sdo_transfer_t *t = &s->transfer;
    t->last_us = now_us;
    switch (ccs) {
    case 1: download_initiate(s, req, index, sub, now_us); break;
    case 2: upload_initiate(s, index, sub, now_us); break;
    case 0:
        if (t->state == CO_SDO_DOWNLOAD)
            download_segment(s, req, now_us);
        else
            sdo_abort(s, t->index, t->subindex, CO_ABORT_CMD);
        break;
    case 3:
        if (t->state == CO_SDO_UPLOAD)
            upload_segment(s, req, now_us);
        else
            sdo_abort(s, t->index, t->subindex, CO_ABORT_CMD);
        break;
    case 4: t->state = CO_SDO_IDLE; break;                  /* abort from the client: no answer */
    default: sdo_abort(s, index, sub, CO_ABORT_CMD); break; /* 5, 6: block transfer; 7: invalid */
    }
}

void co_sdo_server_tick(co_sdo_server_t *s, int64_t now_us)
{
    const co_sdo_transfer_t *t = &s->transfer;
    if (t->state != CO_SDO_IDLE && now_us - t->last_us > (int64_t)s->timeout_us)
        sdo_abort(s, t->index, t->subindex, CO_ABORT_TIMEOUT);
}

int64_t co_sdo_server_next_event(const co_sdo_server_t *s, int64_t next_us)
{
    if (s->transfer.state == CO_SDO_IDLE) return next_us;
    int64_t timeout = s->transfer.last_us + s->timeout_us;
    return timeout < next_us ? timeout : next_us;
}
