/* co_bindings.c - the objects bound to their owners (co_bindings.h): a table sorted by index. */
#include "co_bindings.h"

#include <stddef.h>

co_od_ext_t *co_bindings_find(const co_bindings_t *b, uint16_t index)
{
    int32_t lo = 0, hi = (int32_t)b->n - 1;
    while (lo <= hi) {
        const int32_t mid = lo + (hi - lo) / 2;
        const uint16_t k = b->items[mid].index;
        if (k == index) return b->items[mid].ext;
        if (k < index)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return NULL;
}

int co_bindings_put(co_bindings_t *b, uint16_t index, co_od_ext_t *ext)
{
    uint8_t i = 0;
    while (i < b->n && b->items[i].index < index) ++i;
    if (i < b->n && b->items[i].index == index) {
        b->items[i].ext = ext;
        return 0;
    }
    if (b->n >= CO_NODE_BINDINGS) return -1;
    for (uint8_t j = b->n; j > i; --j) b->items[j] = b->items[j - 1u];
    b->items[i].index = index;
    b->items[i].ext = ext;
    ++b->n;
    return 0;
}
