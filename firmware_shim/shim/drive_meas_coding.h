/* drive_meas_coding.h - the drive's side of the compact measurement frame (drive.eds 0x2100:07-09, 0x2104):
 * when the measurement's RPDO maps the integer codes, they are decoded into 0x2100's amperes and radians
 * (protocols/coding/meas_coding.h, the plant's own expressions), and the sample index the compact frame has no
 * room for follows the SYNC counter it carries. A component of the drive app: it owns its state, and acts on
 * 0x2100 before the supervision judges the sample. Portable: no OS headers, no allocation. */
#ifndef DRIVE_MEAS_CODING_H
#define DRIVE_MEAS_CODING_H

#include <stdint.h>

#include "co_node.h"

typedef struct {
    uint8_t have_last;    /* a coded sample came since the last reset */
    uint8_t last_counter; /* its SYNC counter */
    uint16_t index;       /* the sample index given to it */
} drive_meas_coding_t;

/* Forget the sequence (an NMT state change, a reset): the next coded sample's index is its SYNC counter - 1. */
void drive_meas_coding_reset(drive_meas_coding_t *c);

/* The measurement's RPDO `pdo` wrote 0x2100: if it maps the codes, 0x2100:01-03 from them (an angle code only
 * when mapped), and 0x2100:06 from the SYNC counter when the RPDO does not map the sample index: one more per
 * counter step (0x1019's cycle; with no counter, one more per sample). Returns 1 when it decoded. */
int drive_meas_coding_take(drive_meas_coding_t *c, co_node_t *node, const co_pdo_t *pdo);

#endif /* DRIVE_MEAS_CODING_H */
