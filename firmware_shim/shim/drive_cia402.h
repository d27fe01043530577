/* drive_cia402.h - CiA 402 as a component of the drive app (drive_app.h tells the rules; cia402_device.h is the
 * state machine): it owns the device's state and its objects (0x603F-0x6078: controlword, statusword, modes,
 * quick stop, the actual values) and binds them; it gives the step its references and tells whether the power
 * stage acts.  A state change goes to the root through on_change (the root sends 0 V when the power stage goes
 * off, leaves the safe state at a fault reset); it never runs the step.  Only the cores, the stack and its own
 * header.  Portable: no OS headers, no allocation, float32. */
#ifndef DRIVE_CIA402_H
#define DRIVE_CIA402_H

#include <stdint.h>

#include "cia402_device.h"
#include "co_node.h"
#include "drive_core.h"
#include "od_drive.h"

typedef struct {
    cia402_device_t dev;
    co_node_t *node;
    const drive_t *drv; /* the core: its cfg (torque constant) and state (the actual values) */
    /* The state changed (by a controlword): was_powered, the power stage before; from_fault, a fault reset left
     * FAULT (transition 15: the root leaves the safe state first). */
    void (*on_change)(void *root, int was_powered, int from_fault);
    void *root;
    co_od_ext_t ext;
} drive_cia402_t;

void drive_cia402_bind(drive_cia402_t *c, co_node_t *node, const drive_t *drv,
                       void (*on_change)(void *root, int was_powered, int from_fault), void *root);
/* Reset node or communication: SWITCH ON DISABLED, the quick stop option of 0x605A, 0x6041/0x6061/0x603F. */
void drive_cia402_reset(drive_cia402_t *c);
/* A controlword arrived (SDO or an RPDO that maps 0x6040). */
void drive_cia402_controlword(drive_cia402_t *c);
/* What CiA 402 gives a step. */
typedef struct {
    uint8_t powered; /* the power stage acts: the mode's references are in the core's set-points */
    uint8_t stopped; /* a quick stop ended before this step (SWITCH ON DISABLED now): the statusword follows */
} drive_cia402_power_t;

/* Once a step, before the law: a quick stop with option 1, 2 has ended when the last step's iq is within 2 % of
 * 0x6075 (SWITCH ON DISABLED); then the references of this step in the CiA 402 modes (the manufacturer mode -1
 * keeps 0x2202's) into the core's set-points.  Not powered: the step commands 0 V (no mode, power stage off). */
drive_cia402_power_t drive_cia402_power(drive_cia402_t *c, drive_t *d, const od_drive_mfr_t *m);
/* NMT left OPERATIONAL: the "disable voltage" reaction of 0x6007; 1 when the state changed. */
int drive_cia402_disable_voltage(drive_cia402_t *c);
/* The fault reaction is done (0 V): FAULT with 0x603F = code; 1 when the state changed. */
int drive_cia402_fault(drive_cia402_t *c, uint16_t code);
/* The fault is reset: 0x603F = 0; 1 when the state changed (it was in FAULT). */
int drive_cia402_fault_reset(drive_cia402_t *c);
/* 0x6041 <- the state. */
void drive_cia402_latch_statusword(drive_cia402_t *c);
/* Every valid event-driven TPDO that maps the statusword or the mode shown goes out. */
void drive_cia402_send_statusword(drive_cia402_t *c);

static inline int drive_cia402_powered(const drive_cia402_t *c) { return cia402_device_power_enabled(&c->dev); }
static inline int drive_cia402_quick_stopping(const drive_cia402_t *c)
{
    return c->dev.state == (uint8_t)CIA402_QUICK_STOP_ACTIVE;
}

#endif /* DRIVE_CIA402_H */
