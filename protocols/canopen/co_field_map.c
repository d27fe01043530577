/* co_field_map.c - see co_field_map.h. */
#include "co_field_map.h"

#include <string.h>

/* A value on its way: real types through a double, integer types (bool, enums) through 64 bits, so a
 * 64-bit seed or a wrapped narrowing behaves as the C cast between the two types would. */
typedef struct {
    double d;
    uint64_t u;
    bool real;
} value_t;

static value_t get(const void *p, uint8_t kind, uint8_t size)
{
    value_t v = {0.0, 0u, false};
    if (kind == CO_FM_FLOAT) {
        float f;
        memcpy(&f, p, sizeof f);
        v.d = (double)f;
        v.real = true;
    } else if (kind == CO_FM_DOUBLE) {
        memcpy(&v.d, p, sizeof v.d);
        v.real = true;
    } else if (kind == CO_FM_BOOL) {
        bool b;
        memcpy(&b, p, sizeof b);
        v.u = b ? 1u : 0u;
    } else if (kind == CO_FM_SINT) {
        int64_t s = 0;
        if (size == 1) {
            int8_t x;
            memcpy(&x, p, 1);
            s = x;
        } else if (size == 2) {
            int16_t x;
            memcpy(&x, p, 2);
            s = x;
        } else if (size == 4) {
            int32_t x;
            memcpy(&x, p, 4);
            s = x;
        } else
            memcpy(&s, p, 8);
        v.u = (uint64_t)s;
    } else {
        if (size == 1) {
            uint8_t x;
            memcpy(&x, p, 1);
            v.u = x;
        } else if (size == 2) {
            uint16_t x;
            memcpy(&x, p, 2);
            v.u = x;
        } else if (size == 4) {
            uint32_t x;
            memcpy(&x, p, 4);
            v.u = x;
        } else
            memcpy(&v.u, p, 8);
    }
    if (!v.real) v.d = kind == CO_FM_SINT ? (double)(int64_t)v.u : (double)v.u;
    return v;
}

double co_field_map_value(const void *p, uint8_t kind, uint8_t size) { return get(p, kind, size).d; }

static void put(void *p, uint8_t kind, uint8_t size, value_t v)
{
    if (kind == CO_FM_FLOAT) {
        const float f = (float)v.d;
        memcpy(p, &f, sizeof f);
        return;
    }
    if (kind == CO_FM_DOUBLE) {
        memcpy(p, &v.d, sizeof v.d);
        return;
    }
    const uint64_t u = v.real ? (uint64_t)(int64_t)v.d : v.u;
    if (kind == CO_FM_BOOL) {
        const bool b = v.real ? v.d != 0.0 : u != 0u;
        memcpy(p, &b, sizeof b);
    } else if (size == 1) {
        const uint8_t x = (uint8_t)u;
        memcpy(p, &x, 1);
    } else if (size == 2) {
        const uint16_t x = (uint16_t)u;
        memcpy(p, &x, 2);
    } else if (size == 4) {
        const uint32_t x = (uint32_t)u;
        memcpy(p, &x, 4);
    } else {
        memcpy(p, &u, 8);
    }
}

/* One value from src to dst: a plain copy when both sides have the same kind and size (what the double would
 * give back exactly), else through value_t. */
static void move(void *dst, uint8_t dst_kind, uint8_t dst_size, const void *src, uint8_t src_kind, uint8_t src_size)
{
    if (dst_kind == src_kind && dst_size == src_size) {
        memcpy(dst, src, dst_size);
        return;
    }
    put(dst, dst_kind, dst_size, get(src, src_kind, src_size));
}

void co_field_map_to_core(const co_field_map_t *rows, size_t n, const void *od, void *core)
{
    for (size_t i = 0; i < n; ++i) {
        const co_field_map_t *r = &rows[i];
        move((uint8_t *)core + r->core_offset, r->core_kind, r->core_size, (const uint8_t *)od + r->od_offset,
             r->od_kind, r->od_size);
    }
}

void co_field_map_to_od(const co_field_map_t *rows, size_t n, void *od, const void *core)
{
    for (size_t i = 0; i < n; ++i) {
        const co_field_map_t *r = &rows[i];
        move((uint8_t *)od + r->od_offset, r->od_kind, r->od_size, (const uint8_t *)core + r->core_offset, r->core_kind,
             r->core_size);
    }
}
