/* co_bindings.h - the objects bound to their owners (co_od_ext_t), a table sorted by index: the node's
 * (co_node_bind, co_node_ext) and the SDO paths search it.  Portable C, no OS headers. */
#ifndef CO_BINDINGS_H
#define CO_BINDINGS_H

#include <stdint.h>

#include "co_od.h"

#define CO_NODE_BINDINGS 48u
typedef struct {
    uint16_t index;
    co_od_ext_t *ext;
} co_binding_t;

typedef struct {
    co_binding_t items[CO_NODE_BINDINGS];
    uint8_t n;
} co_bindings_t;

/* The binding of object `index`, or NULL (a binary search). */
co_od_ext_t *co_bindings_find(const co_bindings_t *b, uint16_t index);
/* Bind `index` to `ext`, in order; binding an index again replaces the binding. Returns 0, or -1 when full. */
int co_bindings_put(co_bindings_t *b, uint16_t index, co_od_ext_t *ext);

#endif
