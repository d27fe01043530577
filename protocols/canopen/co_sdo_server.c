/* co_sdo_server.c - SDO server (CiA 301 7.2.4): expedited and segmented
 * upload/download, toggle-bit check, timeout, abort codes. Block transfer is
 * answered with "command specifier not valid" (0x05040001), which masters such
 * as python canopen take as "use segmented transfer". */
#include <string.h>

#include "co_node.h"

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); p[2] = (uint8_t)(v >> 16); p[3] = (uint8_t)(v >> 24);
}

static void sdo_send(co_node_t *node, const uint8_t d[8])
{
    co_node_send(node, (uint16_t)(0x580u + node->node_id), d, 8);
}

static void sdo_abort(co_node_t *node, uint16_t index, uint8_t sub, uint32_t code)
{
    uint8_t d[8] = {0x80, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
    put_u32(&d[4], code);
    sdo_send(node, d);
    ++node->sdo_aborts;
    node->sdo.state = CO_SDO_IDLE;
}

static const co_od_entry_t *lookup(co_node_t *node, uint16_t index, uint8_t sub, uint32_t *abort)
{
    int exists = 0;
    const co_od_entry_t *e = co_od_find(node->od, index, sub, &exists);
    if (!e) *abort = exists ? CO_ABORT_NO_SUB : CO_ABORT_NO_OBJECT;
    return e;
}

static void upload_initiate(co_node_t *node, uint16_t index, uint8_t sub)
{
    uint32_t abort = 0;
    const co_od_entry_t *e = lookup(node, index, sub, &abort);
    if (!e) { sdo_abort(node, index, sub, abort); return; }
    if (!(e->flags & CO_ODF_READ)) { sdo_abort(node, index, sub, CO_ABORT_WRITE_ONLY); return; }
    if (node->hooks.pre_read) node->hooks.pre_read(node->user, node, e);
    uint32_t size = co_od_value_size(e);
    uint8_t d[8] = {0, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
    if (size <= 4u && size > 0u) {
        d[0] = (uint8_t)(0x43u | ((4u - size) << 2));
        co_od_read_raw(e, 0, &d[4], 4);
        sdo_send(node, d);
        node->sdo.state = CO_SDO_IDLE;
        return;
    }
    /* Segmented (also for empty strings/domains: size 0 in one empty last segment). */
    d[0] = 0x41;
    put_u32(&d[4], size);
    sdo_send(node, d);
    node->sdo.state = CO_SDO_UPLOAD;
    node->sdo.entry = e;
    node->sdo.index = index;
    node->sdo.subindex = sub;
    node->sdo.size = size;
    node->sdo.offset = 0;
    node->sdo.toggle = 0;
    node->sdo.last_us = node->now_us;
}

static void upload_segment(co_node_t *node, const uint8_t *req)
{
    co_sdo_t *s = &node->sdo;
    uint8_t t = (uint8_t)((req[0] >> 4) & 1u);
    if (t != s->toggle) { sdo_abort(node, s->index, s->subindex, CO_ABORT_TOGGLE); return; }
    uint8_t d[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    uint32_t n = co_od_read_raw(s->entry, s->offset, &d[1], 7);
    /* A value that shrank under the transfer (domain refreshed) ends it early. */
    s->offset += n;
    uint8_t last = s->offset >= s->size || n < 7u ? 1u : 0u;
    d[0] = (uint8_t)((t << 4) | ((7u - n) << 1) | last);
    sdo_send(node, d);
    s->toggle ^= 1u;
    s->last_us = node->now_us;
    if (last) s->state = CO_SDO_IDLE;
}

static void download_initiate(co_node_t *node, const uint8_t *req, uint16_t index, uint8_t sub)
{
    uint32_t abort = 0;
    const co_od_entry_t *e = lookup(node, index, sub, &abort);
    if (!e) { sdo_abort(node, index, sub, abort); return; }
    if (!(e->flags & CO_ODF_WRITE)) { sdo_abort(node, index, sub, CO_ABORT_READ_ONLY); return; }
    uint8_t cs = req[0];
    bool expedited = (cs & 0x02u) != 0u;
    bool size_ind = (cs & 0x01u) != 0u;
    uint32_t fixed = co_dt_size(e->datatype);
    if (expedited) {
        /* Without a size indication the length is only known for fixed-size types. */
        if (!size_ind && !fixed) { sdo_abort(node, index, sub, CO_ABORT_TYPE_MISMATCH); return; }
        uint32_t len = size_ind ? 4u - ((cs >> 2) & 3u) : fixed;
        abort = co_node_sdo_write(node, e, &req[4], len);
        if (abort) { sdo_abort(node, index, sub, abort); return; }
        uint8_t d[8] = {0x60, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
        sdo_send(node, d);
        node->sdo.state = CO_SDO_IDLE;
        return;
    }
    uint32_t size = (uint32_t)req[4] | (uint32_t)req[5] << 8 | (uint32_t)req[6] << 16 | (uint32_t)req[7] << 24;
    uint32_t cap = CO_SDO_BUF;
    if (fixed) cap = fixed;
    else if (e->datatype == CO_DT_VISIBLE_STRING) cap = e->size;
    else if (e->datatype == CO_DT_DOMAIN) cap = ((const co_domain_t *)e->data)->capacity;
    if (size_ind) {
        if (size > cap) { sdo_abort(node, index, sub, CO_ABORT_TOO_LONG); return; }
        if (fixed && size < fixed) { sdo_abort(node, index, sub, CO_ABORT_TOO_SHORT); return; }
    }
    if (e->datatype == CO_DT_DOMAIN && !((const co_domain_t *)e->data)->data) {
        sdo_abort(node, index, sub, CO_ABORT_DATA_LOCAL);
        return;
    }
    co_sdo_t *s = &node->sdo;
    s->state = CO_SDO_DOWNLOAD;
    s->entry = e;
    s->index = index;
    s->subindex = sub;
    s->size = size;
    s->size_known = size_ind;
    s->offset = 0;
    s->toggle = 0;
    s->last_us = node->now_us;
    uint8_t d[8] = {0x60, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
    sdo_send(node, d);
}

static void download_segment(co_node_t *node, const uint8_t *req)
{
    co_sdo_t *s = &node->sdo;
    uint8_t t = (uint8_t)((req[0] >> 4) & 1u);
    if (t != s->toggle) { sdo_abort(node, s->index, s->subindex, CO_ABORT_TOGGLE); return; }
    uint32_t n = 7u - ((req[0] >> 1) & 7u);
    bool last = (req[0] & 1u) != 0u;
    const co_od_entry_t *e = s->entry;
    bool domain = e->datatype == CO_DT_DOMAIN;
    uint32_t cap = domain ? ((const co_domain_t *)e->data)->capacity
                          : (e->datatype == CO_DT_VISIBLE_STRING ? e->size : co_dt_size(e->datatype));
    if (cap > CO_SDO_BUF && !domain) cap = CO_SDO_BUF;
    if (s->offset + n > cap || (s->size_known && s->offset + n > s->size)) {
        sdo_abort(node, s->index, s->subindex, CO_ABORT_TOO_LONG);
        return;
    }
    if (domain) {
        /* Domains are streamed straight into the application's buffer; size set at the end. */
        memcpy(((co_domain_t *)e->data)->data + s->offset, &req[1], n);
    } else {
        memcpy(&s->buf[s->offset], &req[1], n);
    }
    s->offset += n;
    s->toggle ^= 1u;
    s->last_us = node->now_us;
    if (last) {
        if (s->size_known && s->offset != s->size) {
            sdo_abort(node, s->index, s->subindex, s->offset < s->size ? CO_ABORT_TOO_SHORT : CO_ABORT_TOO_LONG);
            return;
        }
        uint32_t abort;
        if (domain) {
            co_domain_t *dm = (co_domain_t *)e->data;
            abort = co_node_sdo_write(node, e, dm->data, s->offset);
        } else {
            abort = co_node_sdo_write(node, e, s->buf, s->offset);
        }
        if (abort) { sdo_abort(node, s->index, s->subindex, abort); return; }
        s->state = CO_SDO_IDLE;
    }
    uint8_t d[8] = {(uint8_t)(0x20u | (t << 4)), 0, 0, 0, 0, 0, 0, 0};
    sdo_send(node, d);
}

void co_sdo_process(co_node_t *node, const co_frame_t *frame)
{
    if (frame->dlc != 8u) return; /* SDO frames are always 8 bytes; others are not SDO requests */
    const uint8_t *req = frame->data;
    uint8_t ccs = (uint8_t)(req[0] >> 5);
    uint16_t index = (uint16_t)(req[1] | (req[2] << 8));
    uint8_t sub = req[3];
    node->sdo.last_us = node->now_us;
    switch (ccs) {
    case 1: download_initiate(node, req, index, sub); break;
    case 2: upload_initiate(node, index, sub); break;
    case 0:
        if (node->sdo.state == CO_SDO_DOWNLOAD) download_segment(node, req);
        else sdo_abort(node, node->sdo.index, node->sdo.subindex, CO_ABORT_CMD);
        break;
    case 3:
        if (node->sdo.state == CO_SDO_UPLOAD) upload_segment(node, req);
        else sdo_abort(node, node->sdo.index, node->sdo.subindex, CO_ABORT_CMD);
        break;
    case 4: node->sdo.state = CO_SDO_IDLE; break; /* abort from the client: no answer */
    default: sdo_abort(node, index, sub, CO_ABORT_CMD); break; /* 5, 6: block transfer; 7: invalid */
    }
}

void co_sdo_tick(co_node_t *node)
{
    co_sdo_t *s = &node->sdo;
    if (s->state != CO_SDO_IDLE && node->now_us - s->last_us > (int64_t)node->sdo_timeout_us)
        sdo_abort(node, s->index, s->subindex, CO_ABORT_TIMEOUT);
}
