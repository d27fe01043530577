/* drive_law_slot.h - the law slot, a component of the drive app (drive_app.h tells the rules): the drive's
 * parameter records (0x2200 Controller, 0x2202's profile, 0x2203 Outer loops) into the core's drive_config_t,
 * and every current law's record bound generically through the registry (firmware_shim/core/current_law.h):
 * its parameters reach the selected law, the law checks them, its commands act at once, its status entries are
 * the law's own.  It binds those objects and judges their writes; it never runs the step.  Only the cores, the
 * stack and its own header.  Portable: no OS headers, no allocation, float32. */
#ifndef DRIVE_LAW_SLOT_H
#define DRIVE_LAW_SLOT_H

#include <stdint.h>

#include "co_node.h"
#include "drive_core.h"
#include "od_drive.h"

typedef struct {
    drive_t *drv; /* the core whose configuration and law the records are */
    co_node_t *node;
    co_od_ext_t ext_config, ext_law;
} drive_law_slot_t;

/* Bind the parameter records and every law's record (co_node_init's bind hook). */
void drive_law_slot_bind(drive_law_slot_t *s, co_node_t *node, drive_t *drv);
/* OD -> drive_config_t.  core_ctrl: controller to keep when the OD selects the open loop (the core has no
 * open-loop controller). */
void drive_law_slot_od_to_config(const od_drive_mfr_t *m, drive_config_t *c, uint8_t core_ctrl);
/* The selected law's record, OD -> core, when its parameters differ from what the core holds: 1 then. */
int drive_law_slot_sync(drive_law_slot_t *s);

#endif /* DRIVE_LAW_SLOT_H */
