/* co_od.c - object dictionary access: lookup, length and range checks, reset. */
#include "co_od.h"

#include <string.h>

int co_cob_restricted(uint32_t cob_id)
{
    uint32_t id = cob_id & 0x7FFu;
    return id == 0u || (id >= 0x001u && id <= 0x07Fu) || (id >= 0x101u && id <= 0x180u) ||
           (id >= 0x581u && id <= 0x5FFu) || (id >= 0x601u && id <= 0x67Fu) || (id >= 0x6E0u && id <= 0x6FFu) ||
           (id >= 0x701u && id <= 0x77Fu) || (id >= 0x780u && id <= 0x7FFu);
}

uint32_t co_dt_size(uint8_t datatype)
{
    switch (datatype) {
    case CO_DT_BOOLEAN:
    case CO_DT_INTEGER8:
    case CO_DT_UNSIGNED8: return 1u;
    case CO_DT_INTEGER16:
    case CO_DT_UNSIGNED16: return 2u;
    case CO_DT_INTEGER32:
    case CO_DT_UNSIGNED32:
    case CO_DT_REAL32: return 4u;
    default: return 0u;
    }
}

const co_od_entry_t *co_od_find(const co_od_t *od, uint16_t index, uint8_t subindex, int *index_exists)
{
    uint32_t key = ((uint32_t)index << 8) | subindex;
    int32_t lo = 0, hi = (int32_t)od->count - 1;
    if (index_exists) *index_exists = 0;
    while (lo <= hi) {
        int32_t mid = lo + (hi - lo) / 2;
        const co_od_entry_t *e = &od->entries[mid];
        uint32_t k = ((uint32_t)e->index << 8) | e->subindex;
        if (e->index == index && index_exists) *index_exists = 1;
        if (k == key) return e;
        if (k < key)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    if (index_exists && !*index_exists) {
        /* The binary search may not have touched the index: look at the insertion point. */
        int32_t p = lo;
        if (p < (int32_t)od->count && od->entries[p].index == index) *index_exists = 1;
        if (p > 0 && od->entries[p - 1].index == index) *index_exists = 1;
    }
    return NULL;
}

uint32_t co_od_value_size(const co_od_entry_t *e)
{
    if (e->datatype == CO_DT_VISIBLE_STRING) {
        const char *s = (const char *)e->data;
        uint32_t n = 0;
        while (n < e->size && s[n] != '\0') ++n;
        return n;
    }
    if (e->datatype == CO_DT_DOMAIN) {
        const co_domain_t *d = (const co_domain_t *)e->data;
        return d->data ? d->size : 0u;
    }
    return e->size;
}

static const uint8_t *value_ptr(const co_od_entry_t *e)
{
    if (e->datatype == CO_DT_DOMAIN) return ((const co_domain_t *)e->data)->data;
    return (const uint8_t *)e->data;
}

/* Values are stored in host order; CANopen is little-endian. */
int co_host_is_little(void)
{
    const uint16_t one = 1u;
    return *(const uint8_t *)&one == 1u;
}

uint32_t co_od_read_raw(const co_od_entry_t *e, uint32_t offset, uint8_t *buf, uint32_t cap)
{
    uint32_t size = co_od_value_size(e);
    if (offset >= size) return 0;
    uint32_t n = size - offset;
    if (n > cap) n = cap;
    const uint8_t *src = value_ptr(e);
    if (!src) return 0;
    uint32_t fixed = co_dt_size(e->datatype);
    if (fixed > 1u && !co_host_is_little()) {
        for (uint32_t i = 0; i < n; ++i) buf[i] = src[fixed - 1u - (offset + i)];
    } else {
        memcpy(buf, src + offset, n);
    }
    return n;
}

static int64_t load_int(uint8_t dt, const uint8_t *b)
{
    switch (dt) {
    case CO_DT_BOOLEAN:
    case CO_DT_UNSIGNED8: return b[0];
    case CO_DT_INTEGER8: return (int8_t)b[0];
    case CO_DT_UNSIGNED16: return (uint16_t)(b[0] | (b[1] << 8));
    case CO_DT_INTEGER16: return (int16_t)(uint16_t)(b[0] | (b[1] << 8));
    case CO_DT_UNSIGNED32:
        return (int64_t)((uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24);
    case CO_DT_INTEGER32:
        return (int32_t)((uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24);
    default: return 0;
    }
}

static float load_f32(const uint8_t *b)
{
    uint32_t u = (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

uint32_t co_od_check_write(const co_od_entry_t *e, const uint8_t *buf, uint32_t len)
{
    uint32_t fixed = co_dt_size(e->datatype);
    if (fixed) {
        if (len > fixed) return CO_ABORT_TOO_LONG;
        if (len < fixed) return CO_ABORT_TOO_SHORT;
        if (e->datatype == CO_DT_BOOLEAN && buf[0] > 1u) return CO_ABORT_INVALID_VALUE;
        if (e->datatype == CO_DT_REAL32) {
            float v = load_f32(buf);
            if (v != v) return CO_ABORT_INVALID_VALUE; /* NaN is never a parameter */
            if (e->flags & CO_ODF_LIMITS) {
                if (v > e->high.f) return CO_ABORT_VALUE_HIGH;
                if (v < e->low.f) return CO_ABORT_VALUE_LOW;
            }
        } else if (e->flags & CO_ODF_LIMITS) {
            int64_t v = load_int(e->datatype, buf);
            if (v > e->high.i) return CO_ABORT_VALUE_HIGH;
            if (v < e->low.i) return CO_ABORT_VALUE_LOW;
        }
        return 0;
    }
    if (e->datatype == CO_DT_VISIBLE_STRING) {
        if (len > e->size) return CO_ABORT_TOO_LONG;
        for (uint32_t i = 0; i < len; ++i)
            if (buf[i] == 0u) return CO_ABORT_INVALID_VALUE;
        return 0;
    }
    if (e->datatype == CO_DT_DOMAIN) {
        const co_domain_t *d = (const co_domain_t *)e->data;
        if (!d->data || len > d->capacity) return CO_ABORT_TOO_LONG;
        return 0;
    }
    return CO_ABORT_TYPE_MISMATCH;
}

void co_od_store(const co_od_entry_t *e, const uint8_t *buf, uint32_t len)
{
    uint32_t fixed = co_dt_size(e->datatype);
    if (fixed) {
        uint8_t *dst = (uint8_t *)e->data;
        if (fixed > 1u && !co_host_is_little()) {
            for (uint32_t i = 0; i < fixed; ++i) dst[i] = buf[fixed - 1u - i];
        } else {
            memcpy(dst, buf, fixed);
        }
    } else if (e->datatype == CO_DT_VISIBLE_STRING) {
        char *s = (char *)e->data;
        memcpy(s, buf, len);
        s[len] = '\0'; /* storage is size + 1 bytes */
    } else if (e->datatype == CO_DT_DOMAIN) {
        co_domain_t *d = (co_domain_t *)e->data;
        if (d->data != buf) memmove(d->data, buf, len); /* a segmented download streamed in place already */
        d->size = len;
    }
}

uint32_t co_od_get_u32(const co_od_t *od, uint16_t index, uint8_t sub)
{
    const co_od_entry_t *e = co_od_find(od, index, sub, NULL);
    if (!e) return 0;
    uint8_t b[4] = {0, 0, 0, 0};
    uint32_t n = co_od_read_raw(e, 0, b, 4);
    if (n == 0) return 0;
    return (uint32_t)load_int(e->datatype == CO_DT_REAL32 ? CO_DT_UNSIGNED32 : e->datatype, b);
}

void co_od_set_u32(const co_od_t *od, uint16_t index, uint8_t sub, uint32_t value)
{
    const co_od_entry_t *e = co_od_find(od, index, sub, NULL);
    if (!e) return;
    uint8_t b[4] = {(uint8_t)value, (uint8_t)(value >> 8), (uint8_t)(value >> 16), (uint8_t)(value >> 24)};
    uint32_t n = co_dt_size(e->datatype);
    if (n) co_od_store(e, b, n);
}

void co_od_reset(const co_od_t *od, uint8_t node_id, int communication_only)
{
    size_t n = communication_only ? od->comm_size : od->total_size;
    memcpy(od->ram, od->defaults, n);
    for (uint16_t i = 0; i < od->count; ++i) {
        const co_od_entry_t *e = &od->entries[i];
        if (!(e->flags & CO_ODF_NODEID)) continue;
        if (communication_only && e->index >= 0x2000u) continue;
        co_od_set_u32(od, e->index, e->subindex, co_od_get_u32(od, e->index, e->subindex) + node_id);
    }
}
