/* drive_od.c - see drive_od.h. */
#include "drive_od.h"

#include <string.h>

int drive_od_candidate(const co_node_t *node, const co_od_entry_t *e, const uint8_t *data, uint32_t len,
                       od_drive_mfr_t *cand)
{
    const uint32_t sz = co_dt_size(e->datatype);
    if (sz == 0u || len != sz) return 0; /* lengths already checked by the node */
    const od_drive_mfr_t *m = mfr_of(node);
    const size_t off = (size_t)((const uint8_t *)e->data - (const uint8_t *)m);
    if ((const uint8_t *)e->data < (const uint8_t *)m || off + sz > sizeof *cand) return 0;
    memcpy(cand, m, sizeof *cand);
    co_od_entry_t tmp = *e;
    tmp.data = (uint8_t *)cand + off;
    co_od_store(&tmp, data, len);
    return 1;
}
