/* co_fd.h - a node's CAN FD PDOs: object 0x2105 "CAN FD" of plant.eds and drive.eds.
 *
 * Sub 1 `pdo_frame_format`: 0 classic CAN, 1 CAN FD, 2 CAN FD with bit-rate switch; sub 2 `classic_tpdos`: the
 * TPDOs that stay classic frames (TPDO n in bit n-1). A manufacturer object: CANopen FD (CiA 1301) puts the whole
 * network on CAN FD instead, with no such switch; here only the PDOs change format, and SDO, NMT, SYNC, EMCY and
 * the heartbeat stay classic frames (docs/PHYSICAL_BUS.md, "CAN FD in the loop"). Portable core: no OS headers.
 */
#ifndef CO_FD_H
#define CO_FD_H

#include <stdbool.h>
#include <stdint.h>

#include "co_od.h"

#define CO_IDX_CAN_FD 0x2105u

/* The node's 0x2105 in the OD's RAM (NULL: an OD without it, classic only); the PDOs read it (co_pdo_env_t.fd). */
typedef struct {
    const uint8_t *frame_format;
    const uint8_t *classic_tpdos;
} co_fd_t;

void co_fd_attach(co_fd_t *fd, const co_od_t *od);

/* The rules of an SDO write to 0x2105: PRE-OPERATIONAL (or STOPPED) only, and CAN FD only where the frames hold more
 * than 8 bytes (CO_FRAME_MAX_DATA). Returns an abort code or 0. */
uint32_t co_fd_check_write(const co_od_entry_t *e, const uint8_t *data, bool operational);

/* The flags of PDO n's frames (a TPDO or an RPDO): 0 (classic), CO_FRAME_FDF, or CO_FRAME_FDF | CO_FRAME_BRS. */
uint8_t co_fd_flags(const co_fd_t *fd, bool is_tpdo, uint8_t n);

#endif /* CO_FD_H */
