/* drive_app.h - the drive firmware (firmware_shim/core) as a CANopen node.
 *
 * PORTABLE glue (no OS headers, no allocation, float32): the same code runs in
 * the Linux process (drive_node_main.c over SocketCAN), in-process on
 * co_membus (bench direct mode, tests) and on a microcontroller.
 *
 *   drive_app_t app;
 *   drive_app_init(&app);                                   // before co_node_init
 *   co_node_init(&node, &od_drive, id, tx, tx_user, drive_app_hooks(), &app, now);  // binds the objects
 *   drive_app_bind(&app, &node);                            // after (optional: the bind hook did it)
 *   drive_app_set_cycle_counter(&app, fn, user, clock_Hz);  // optional, any time
 *
 * Data flow (docs/ARCHITECTURE.md):
 *   plant TPDO1 {i_a_A, i_b_A}            -> RPDO1 -> 0x2100:01/02
 *   plant TPDO2 {theta, sync, status, k}  -> RPDO2 -> 0x2100:03..06 -> current step
 *   current step -> 0x2102 -> TPDO1 {v_alpha_V, v_beta_V} sent at once
 *   bench RPDO3 {iq_ref_A, id_ref_A} or SDO -> 0x2202 (read at every step)
 *
 * The app is a root of components (docs/ARCHITECTURE.md), each owning its state and binding its own objects
 * (co_od_ext_t, co_node_bind) at init, none running the step:
 *   drive_supervision.h  measurement sequence, non-finite values, safe-state latch, EMCYs (0x2204, 0x2209)
 *   drive_cia402.h       CiA 402 state machine and objects (0x603F-0x6078)
 *   drive_law_slot.h     the parameter records and every current law's record (0x2200-0x2203, the laws')
 *   drive_recorder.h     trace recorder, live trace, step cost (0x2300-0x2302, 0x2208)
 * One period reads top to bottom in drive_app.c (drive_app_period): admit the measurement -> CiA 402 power ->
 * law step, 0 V or open loop -> guard (law output, overrun) -> fault transition -> TPDO -> deferred EMCYs.
 *
 * Configuration: the OD (0x2200-0x2203) is the source of truth.  An accepted
 * SDO write is copied into drive_t.cfg when it is written (the law slot); the mismatch
 * knobs (R_hat, Ld_hat, Lq_hat, psi_hat), the controller and the tuning
 * switch are watched by the core and take effect at the next step, any other
 * field through drive_apply_config() (also at the next step).  Invalid
 * combinations are refused by the check of the write with SDO abort 0x06040043.
 *
 * Controllers (0x2200:01): 0 is the app's open loop; every other value is a
 *   current law of the registry (firmware_shim/core/current_law.h, generated
 *   from the EDS's value names), n the row of value n; a value without a row
 *   aborts with 0x06090030, and so does selecting a surface-mounted law
 *   (single_inductance) while |Ld_hat_H - Lq_hat_H| > 5 % of Lq_hat_H.
 *
 * A law's EDS record (CurrentLaws key of its section): its parameters reach
 *   the law like the drive's (when written, next step); the law checks them
 *   (abort 0x06040043); its commands (entries that read back 0) act
 *   at once (current_law_t.command); its status entries are written by the
 *   law on every read.
 *
 * Measurement supervision (counted in 0x2204, never silently skipped):
 *   lost (0x2204:02)  gap in sample_index (modulo 65536): every missing sample
 *                     is counted; EMCY 0xFF01 (manufacturer specific,
 *                     error register bits generic + communication +
 *                     manufacturer), MSEF = {sample_index LE16, missing LE16
 *                     (saturated), sync_counter}.
 *   late  (0x2204:03) RPDO1 not followed by its RPDO2, RPDO2 without a fresh
 *                     RPDO1, duplicate / out-of-order sample_index, or a
 *                     measurement whose sync_counter is not that of the last
 *                     SYNC the drive received; EMCY 0xFF02, MSEF = {sample_index
 *                     LE16, reason, sync_counter, last SYNC counter}.
 *   These EMCYs go out right after the command of the same measurement.
 *   The first good measurement afterwards clears the error (EMCY 0x0000 when
 *   no other error is active).  A step still runs for an RPDO2 without a fresh
 *   RPDO1 (with the last currents), so the plant always gets a command; not for
 *   a second copy of the sample just answered (same sample_index): its command
 *   is out, and a second step would advance the controller twice and send the
 *   plant two commands for one sample (its EMCY 0xFF02 still goes out).
 *
 * Non-finite values (0x2209:06 non_finite_rejected, counted once per step and
 * field): PDOs bypass the EDS limits, so a NaN or +-inf can arrive.
 *   measurement   i_a_A, i_b_A, theta_m_rad of 0x2100: the step runs with the
 *                 last finite value of that field (0 before the first one);
 *                 EMCY 0xFF05 after the command, error register bits generic +
 *                 communication + manufacturer, MSEF = {sample_index LE16,
 *                 fields (bit0 i_a_A, bit1 i_b_A, bit2 theta_m_rad), 0, 0};
 *                 the next measurement with finite values clears it.
 *   references    iq_ref_A, id_ref_A, speed_ref_rad_s, position_ref_rad of
 *                 0x2202 keep their last finite value, v_d_open_V/v_q_open_V
 *                 read 0 in the open loop (counted only there); no EMCY.
 *
 * CiA 402 (0x603F-0x6502; cia402_device.h for the state machine): the node is
 * a servo drive (0x1000 = 0x00020192).  It starts in SWITCH ON DISABLED and
 * the power stage acts only in OPERATION ENABLED (and QUICK STOP ACTIVE, where
 * the control takes iq to 0, id to 0); every other state commands 0 V, sent at
 * once when the state is left while OPERATIONAL, and clears the controllers'
 * memories at every step (a clean start at enable).  The bench's lockstep runs
 * enable the drive by SDO (controlword 6, 7, 15) before NMT start.
 *   0x6040 controlword   by SDO or by any RPDO that maps it (RPDO4 by default,
 *                        not valid until a master enables it)
 *   0x6041 statusword    every valid event-driven TPDO that maps it (TPDO3 by
 *                        default) goes out at each state change and at NMT start
 *   0x6060 modes          -1 manufacturer current mode (default: the id/iq
 *                        references of 0x2202, the papers' runs), 10 cyclic
 *                        synchronous torque (iq_ref = 0x6071 / 1000 x 0x6076 [mNm]
 *                        / 1000 / (1.5 p psi_hat), clamped to +-0x6072, id_ref = 0),
 *                        0 no mode (0 V); 0x6061 shows it
 *   0x605A quick stop     0 -> SWITCH ON DISABLED at once; 1, 2 -> iq to 0, then
 *                        SWITCH ON DISABLED before the command of the step that
 *                        finds |iq| <= 2 % of 0x6075 (0 V in it); 5, 6 stay
 *   actual values        0x6064/0x606C position/velocity (65536 increments per
 *                        mechanical revolution), 0x6077 torque (1.5 p psi_hat iq per
 *                        mille of 0x6076), 0x6078 iq per mille of 0x6075; refreshed
 *                        on every read
 *   faults               the safe states below are the 402 FAULT (transitions 13,
 *                        14) with 0x603F = their EMCY code; a fault reset (rising
 *                        edge of controlword bit 7, or 0x2209:05) is refused while
 *                        the plant's heartbeat is still lost (a refused edge is
 *                        consumed: bit 7 held at 1 never resets later); a reset
 *                        sends the statusword TPDOs like any state change
 *   NMT                  leaving OPERATIONAL while enabled: SWITCH ON DISABLED
 *                        (the "disable voltage" reaction of 0x6007); a reset node
 *                        or reset communication: SWITCH ON DISABLED
 *
 * Safe states (0x2209): a real drive's reaction to losing its communication.
 * Without measurements or a live plant the drive cannot control the current,
 * so it commands zero voltage and stays there until told otherwise (latched:
 * a fault, not a glitch that heals itself).  This is the communication-loss
 * reaction a CiA 402 drive configures in 0x6007 (abort connection option
 * code); it is the CiA 402 FAULT state (above), 0x2209:05 a fault reset
 * like the controlword's bit 7; the codes and entries here stay as its
 * manufacturer detail.
 *   measurement timeout (reason 1)  0x2209:01 meas_timeout_periods SYNCs in a
 *                     row without a measurement (RPDO2) in between, counted
 *                     while OPERATIONAL from the first measurement of the run
 *                     (the NMT state changing re-arms it); 0 off.  The SYNC
 *                     comes before the measurement of its sample, so n SYNCs
 *                     are n - 1 missing measurements (1 would enter at the
 *                     first SYNC after every measurement).
 *                     EMCY 0xFF03.
 *   heartbeat lost    (reason 2)  a heartbeat consumer of 0x1016 (the plant)
 *                     timed out while OPERATIONAL, or is still timed out when
 *                     the node enters OPERATIONAL; the stack has sent EMCY
 *                     0x8130 for the heartbeat itself, EMCY 0xFF04 is the
 *                     drive's reaction.
 *   Entering (the first reason is kept while the state lasts: a second cause
 *   sends no EMCY of its own, the stack's 0x8130 still goes out): 0x2209:03
 *   entries + 1, 0x2209:04 entered_at_sample = sample_index of the last
 *   measurement with finite values (0 if none), 0x2102 = 0 V sent at once
 *   (TPDO1: a plant still running applies zero volts), then the EMCY: error
 *   register bits generic + communication + manufacturer (as 0xFF01), MSEF =
 *   {entered_at_sample LE16, reason, 0, 0}.
 *   In the safe state every measurement still runs a step (observers, speed
 *   estimate, trace, one command per measurement for a plant in lockstep) but
 *   the command is 0 V, and so are the voltages of the state and the trace
 *   (v_d/q_V, v_d/q_star_V, v_alpha/beta_V, the feed-forward); the controller
 *   memories (drive_reset_controller_memory) and the outer loops' integrator
 *   and position profile (restarted at the measured position) are cleared at
 *   entry and at every step, so leaving restarts the control without wind-up.
 *   Leaving: 0x2209:05 clear = 1 (fault reset, reads back 0; abort 0x08000022
 *   while a heartbeat consumer is still timed out, 0x06090030 for a value
 *   other than 1), NMT reset node or reset communication.  NMT pre-operational
 *   -> operational does not leave it.  Leaving clears the EMCY (EMCY 0x0000
 *   when no other error is active), 0x2209:02 reason and the SYNC count.
 */
#ifndef DRIVE_APP_H
#define DRIVE_APP_H

#include <stdint.h>

#include "co_node.h"
#include "drive_cia402.h"
#include "drive_core.h"
#include "drive_law_slot.h"
#include "drive_meas_coding.h"
#include "drive_recorder.h"
/* The drive's manufacturer-specific EMCY codes (CiA 301 0xFF00-0xFFFF), DRIVE_EMCY_*: generated from the
 * [EmergencyCodes] of drive.eds by protocols/gen_od.py; the late reasons and non-finite fields of their MSEFs,
 * DRIVE_LATE_* and DRIVE_NON_FINITE_*: drive_supervision.h. */
#include "drive_supervision.h"
#include "od_drive_fields.h"

/* The reasons of 0x2209:02 (and byte 2 of the MSEF of 0xFF03/0xFF04) are
 * OD_DRIVE_REASON_NONE, _MEAS_TIMEOUT, _HEARTBEAT_LOST (od_drive_fields.h). */

typedef struct {
    drive_t drv;     /* firmware core */
    co_node_t *node; /* set when co_node_init binds the app (hooks.bind) */

    /* the components, each with its state and its objects */
    drive_supervision_t sup;
    drive_cia402_t cia;
    drive_law_slot_t law;
    drive_recorder_t rec;
    drive_meas_coding_t coding; /* the compact measurement frame's codes */

    /* last inputs / output of the current step */
    drive_meas_t meas;
    drive_cmd_t cmd;
    drive_meas_t meas_good; /* last finite value of each measurement field */

    /* open loop active in the last step (0x2200:01 = 0 or 0x2202:01 = 3) */
    uint8_t open_loop;
    uint8_t overrun_check; /* 1: a step longer than Ts_s by the counter enters the safe state (overrun) */
} drive_app_t;

/* Hooks for co_node_init (user = drive_app_t *); their bind hook binds the components' objects. */
const co_hooks_t *drive_app_hooks(void);

/* Before co_node_init: core defaults, trace recorder. */
void drive_app_init(drive_app_t *app);

/* After co_node_init: remembers the node (co_node_init's bind hook already did, and bound the objects). */
void drive_app_bind(drive_app_t *app, co_node_t *node);

/* The target's cycle counter and its frequency for 0x2208 Step cost (fn NULL:
 * none, the entries read 0).  The statistics restart with it, at an NMT reset
 * node and when 0x2200:01 selects another controller. */
void drive_app_set_cycle_counter(drive_app_t *app, drive_app_cycles_fn fn, void *user, uint32_t clock_Hz);

/* On a target whose counter measures the step alone (a bare-metal MCU: no preemption, cycles are the
 * step's), a step that takes longer than the current period Ts_s is an overrun: the law is too slow for
 * the target.  The drive enters its safe state (reason overrun, EMCY 0xFF07).  Off by default: a Linux
 * process's clock counts the time it was preempted too. */
void drive_app_set_overrun_check(drive_app_t *app, uint8_t on);

/* Run one current step on the measurement held in 0x2100 (what RPDO2 does, without the measurement's
 * supervision; public for drivers that receive the measurement otherwise). */
void drive_app_current_step(drive_app_t *app);

/* Load the whole drive configuration from the OD into app->drv.cfg and mark
 * it for drive_apply_config (normally done when the records are written). */
void drive_app_load_config(drive_app_t *app);

#endif /* DRIVE_APP_H */
