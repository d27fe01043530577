/* co_node_bind.c - the objects bound to their owners (co_node.h: co_node_bind, co_node_ext): a table sorted by
 * index, searched by the SDO paths; a PDO that maps a bound object learns it at once. */
#include "co_node.h"

co_od_ext_t *co_node_ext(const co_node_t *node, uint16_t index)
{
    int32_t lo = 0, hi = (int32_t)node->n_bindings - 1;
    while (lo <= hi) {
        const int32_t mid = lo + (hi - lo) / 2;
        const uint16_t k = node->bindings[mid].index;
        if (k == index) return node->bindings[mid].ext;
        if (k < index)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return NULL;
}

int co_node_bind(co_node_t *node, uint16_t index, co_od_ext_t *ext)
{
    int exists = 0;
    (void)co_od_find(node->od, index, 0, &exists);
    if (!exists) return -1;
    uint8_t i = 0;
    while (i < node->n_bindings && node->bindings[i].index < index) ++i;
    if (i < node->n_bindings && node->bindings[i].index == index) {
        node->bindings[i].ext = ext;
    } else {
        if (node->n_bindings >= CO_NODE_BINDINGS) return -1;
        for (uint8_t j = node->n_bindings; j > i; --j) node->bindings[j] = node->bindings[j - 1u];
        node->bindings[i].index = index;
        node->bindings[i].ext = ext;
        ++node->n_bindings;
    }
    for (uint8_t n = 0; n < CO_NUM_PDO; ++n) {
        co_pdo_bind(&node->rpdo[n]);
        co_pdo_bind(&node->tpdo[n]);
    }
    return 0;
}
