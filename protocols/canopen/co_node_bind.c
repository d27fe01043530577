/* co_node_bind.c - the node's objects bound to their owners (co_node.h: co_node_bind, co_node_ext): the table
 * (co_bindings.h) and, at each binding, the PDOs that map the object learning it. */
#include "co_bindings.h"
#include "co_node.h"

co_od_ext_t *co_node_ext(const co_node_t *node, uint16_t index) { return co_bindings_find(&node->bindings, index); }

int co_node_bind(co_node_t *node, uint16_t index, co_od_ext_t *ext)
{
    int exists = 0;
    (void)co_od_find(node->od, index, 0, &exists);
    if (!exists || co_bindings_put(&node->bindings, index, ext) != 0) return -1;
    for (uint8_t n = 0; n < CO_NUM_PDO; ++n) {
        co_pdo_bind(&node->rpdo[n]);
        co_pdo_bind(&node->tpdo[n]);
    }
    return 0;
}
