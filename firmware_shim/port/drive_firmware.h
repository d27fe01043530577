/* drive_firmware.h - the drive node's portable main loop over the port layer (drive_port.h).
 *
 *   static drive_firmware_t fw;           // ~36 KiB (trace buffer): static, never on the stack
 *   drive_firmware_init(&fw, OD_DRIVE_DEFAULT_NODE_ID);
 *   drive_firmware_run(&fw);              // never returns
 *
 * init: drive_app_init, co_node_init with drive_app_hooks (restores the OD
 * defaults, sends the boot-up, enters NMT pre-operational), drive_app_bind, and the
 * port's cycle counter for 0x2208 Step cost.
 * run:  for (;;) { every received frame -> co_node_process; co_node_tick; idle when
 * nothing came }.
 *
 * The step trigger is the measurement PDO, exactly as in the Linux node
 * (drive_node_main.c): the plant's TPDO2 {theta, sync_counter, status,
 * sample_index} arrives as RPDO2, whose hook (drive_app.c) runs one current step
 * and sends the voltage command (TPDO1) before co_node_process returns.  There is
 * no timer-driven control loop: the firmware runs when the plant's frames arrive.
 * Around each current step drive_app reads drive_port_cycles(); last, max and mean
 * are SDO-readable in 0x2208 (per controller: a new 0x2200:01 restarts them).
 */
#ifndef DRIVE_FIRMWARE_H
#define DRIVE_FIRMWARE_H

#include <stdint.h>

#include "co_node.h"
#include "drive_app.h"

typedef struct {
    drive_app_t app;
    co_node_t node;
    uint32_t frames_in; /* frames handed to co_node_process */
} drive_firmware_t;

/* Initialise the app and the node (boot-up frame sent). */
void drive_firmware_init(drive_firmware_t *fw, uint8_t node_id);

/* One pass of the loop: every waiting frame, then the timers.  Returns the number
 * of frames processed (0: the caller may idle). */
uint32_t drive_firmware_poll(drive_firmware_t *fw);

/* drive_firmware_poll forever, drive_port_idle when nothing came. */
void drive_firmware_run(drive_firmware_t *fw);

#endif /* DRIVE_FIRMWARE_H */
