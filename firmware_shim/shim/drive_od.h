/* drive_od.h - what the drive app's components share of the drive's OD, below all of them: the manufacturer
 * part of a node's OD, the finite test of a float that a PDO wrote, the plant's heartbeat, and the candidate OD a
 * check judges a write on.  Portable: no OS headers, no allocation, float32. */
#ifndef DRIVE_OD_H
#define DRIVE_OD_H

#include <stdint.h>

#include "co_node.h"
#include "od_drive.h"

static inline od_drive_mfr_t *mfr_of(const co_node_t *node) { return &((od_drive_ram_t *)node->od->ram)->mfr; }

static inline int is_finite_f(float x) { return (x - x) == 0.0f; /* false for NaN and +-inf */ }

/* A heartbeat consumer of the node (the plant) timed out. */
static inline int drive_heartbeat_lost(const co_node_t *node)
{
    for (uint8_t i = 0; i < CO_HB_CONSUMERS; ++i)
        if (node->hb[i].active && node->hb[i].timed_out) return 1;
    return 0;
}

/* A check's candidate OD: the node's manufacturer part with e's new value stored in it. 0 when e is not a
 * fixed-size entry of that part (nothing to check against). */
int drive_od_candidate(const co_node_t *node, const co_od_entry_t *e, const uint8_t *data, uint32_t len,
                       od_drive_mfr_t *cand);

#endif /* DRIVE_OD_H */
