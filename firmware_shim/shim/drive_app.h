/* drive_app.h - the drive firmware (firmware_shim/core) as a CANopen node.
 *
 * PORTABLE glue (no OS headers, no allocation, float32): the same code runs in
 * the Linux process (drive_node_main.c over SocketCAN), in-process on
 * co_membus (bench direct mode, tests) and on a microcontroller.
 *
 *   drive_app_t app;
 *   drive_app_init(&app);                                   // before co_node_init
 *   co_node_init(&node, &od_drive, id, tx, tx_user, drive_app_hooks(), &app, now);
 *   drive_app_bind(&app, &node);                            // after
 *   drive_app_set_cycle_counter(&app, fn, user, clock_Hz);  // optional, any time
 *
 * Data flow (docs/ARCHITECTURE.md):
 *   plant TPDO1 {i_a_A, i_b_A}            -> RPDO1 -> 0x2100:01/02
 *   plant TPDO2 {theta, sync, status, k}  -> RPDO2 -> 0x2100:03..06 -> current step
 *   current step -> 0x2102 -> TPDO1 {v_alpha_V, v_beta_V} sent at once
 *   bench RPDO3 {iq_ref_A, id_ref_A} or SDO -> 0x2202 (read at every step)
 *
 * Configuration: the OD (0x2200-0x2203) is the source of truth.  An accepted
 * SDO write is copied into drive_t.cfg in the post_write hook; the mismatch
 * knobs (R_hat, Ld_hat, Lq_hat, psi_hat), the controller and the tuning
 * switch are watched by the core and take effect at the next step, any other
 * field through drive_apply_config() (also at the next step).  Invalid
 * combinations are refused in pre_write with SDO abort 0x06040043.
 *
 * Controllers (0x2200:01): 0 is the app's open loop; every other value is a
 *   current law of the registry (firmware_shim/core/current_law.h, generated
 *   from the EDS's value names), n the row of value n; a value without a row
 *   aborts with 0x06090030, and so does selecting a surface-mounted law
 *   (single_inductance) while |Ld_hat_H - Lq_hat_H| > 5 % of Lq_hat_H.
 *
 * A law's EDS record (CurrentLaws key of its section): its parameters reach
 *   the law like the drive's (post_write, next step); the law checks them
 *   (pre_write, abort 0x06040043); its commands (entries that read back 0) act
 *   at once (current_law_t.command); its status entries are written by the
 *   law on every read (pre_read).
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

#include "cia402_device.h"
#include "co_node.h"
#include "drive_core.h"
/* The drive's manufacturer-specific EMCY codes (CiA 301 0xFF00-0xFFFF), DRIVE_EMCY_*: generated from the
 * [EmergencyCodes] of drive.eds by protocols/gen_od.py. */
#include "od_drive_fields.h"
#include "trace_recorder.h"

/* Reasons in byte 2 of the MSEF of DRIVE_EMCY_MEAS_LATE. */
enum {
    DRIVE_LATE_RPDO1_WITHOUT_RPDO2 = 1,
    DRIVE_LATE_RPDO2_WITHOUT_RPDO1 = 2,
    DRIVE_LATE_DUPLICATE_OR_OLD = 3,
    DRIVE_LATE_SYNC_MISMATCH = 4
};

/* Fields in byte 2 of the MSEF of DRIVE_EMCY_NON_FINITE. */
enum { DRIVE_NON_FINITE_I_A = 0x01, DRIVE_NON_FINITE_I_B = 0x02, DRIVE_NON_FINITE_THETA = 0x04 };

/* The reasons of 0x2209:02 (and byte 2 of the MSEF of 0xFF03/0xFF04) are
 * OD_DRIVE_REASON_NONE, _MEAS_TIMEOUT, _HEARTBEAT_LOST (od_drive_fields.h). */

#define DRIVE_APP_PENDING_EMCY 4u

/* A free-running cycle counter of the target (wraps modulo 2^32): DWT CYCCNT,
 * SysTick, clock_gettime in ns.  Read before and after every current step; the
 * difference is published in 0x2208 Step cost. */
typedef uint32_t (*drive_app_cycles_fn)(void *user);

/* The read-only entries of the status records, named as in drive.eds: the app keeps its counts in
 * them, and a read of the record copies them to the OD with the list od_drive_fields.h generates
 * (OD_DRIVE_<RECORD>_STATUS), so an entry's name is written once, in the EDS.  Values the app does
 * not count (the core's currents, the mean, the trace's size) are taken just before the copy. */
typedef struct { /* 0x2204 Drive status */
    uint32_t current_steps;
    uint32_t lost_measurements;
    uint32_t late_measurements;
    float id_A; /* id_A .. iq_ref_active_A: the core's, at the read */
    float iq_A;
    float speed_rad_s;
    float iq_ref_active_A;
    uint16_t last_sample_index; /* also the sequencing's last sample */
} drive_app_drive_status_t;

typedef struct {               /* 0x2208 Step cost */
    uint32_t step_cycles_last; /* REAL32 in the OD */
    uint32_t step_cycles_max;  /* REAL32 in the OD */
    float step_cycles_mean;    /* at the read: sum / steps_measured */
    uint32_t cycle_clock_Hz;   /* at the read: 0 without a counter */
    uint32_t steps_measured;
} drive_app_step_cost_t;

typedef struct {    /* 0x2209 Safe state */
    uint8_t reason; /* OD_DRIVE_REASON_*: NONE = not in the safe state */
    uint32_t entries;
    uint16_t entered_at_sample;
    uint32_t non_finite_rejected;
} drive_app_safe_state_t;

typedef struct { /* 0x2300 Trace, at the read */
    uint32_t captured_bytes;
    uint32_t trigger_row;
} drive_app_trace_status_t;

typedef struct {
    drive_t drv;            /* firmware core */
    trace_recorder_t trace; /* oscilloscope buffer, exposed as 0x2301 */
    co_node_t *node;        /* set by drive_app_bind */

    /* last inputs / output of the current step */
    drive_meas_t meas;
    drive_cmd_t cmd;

    /* counters (0x2204; last_sample_index: valid with have_last) */
    drive_app_drive_status_t drive_status;
    uint32_t emcy_raised; /* EMCY 0xFF01/0xFF02 raised */

    /* measurement sequencing */
    uint8_t rpdo1_fresh; /* RPDO1 seen, waiting for its RPDO2 */
    uint8_t have_last;   /* drive_status.last_sample_index valid */
    uint8_t old_run;     /* consecutive duplicate/old sample_index */
    uint8_t sync_seen;   /* a SYNC was received since OPERATIONAL */
    uint8_t last_sync_counter;
    uint8_t meas_error_active; /* an 0xFF01/0xFF02 error is active */

    /* EMCYs of the measurement being handled, sent after its command */
    uint8_t defer_emcy;
    uint8_t n_pending;
    uint16_t pending_code[DRIVE_APP_PENDING_EMCY];
    uint8_t pending_msef[DRIVE_APP_PENDING_EMCY][5];

    /* safe state (0x2209; with non_finite_rejected below) */
    drive_app_safe_state_t safe_state;
    uint16_t syncs_without_meas; /* SYNCs since the last measurement (saturates) */
    uint8_t meas_seen;           /* a measurement arrived since the NMT state changed */
    uint8_t have_good;           /* good_sample_index valid */
    uint16_t good_sample_index;  /* sample_index of the last step on finite measurement values */

    /* non-finite values received by PDO */
    drive_meas_t meas_good;    /* last finite value of each measurement field */
    uint8_t non_finite_mask;   /* DRIVE_NON_FINITE_* replaced in the last step */
    uint8_t non_finite_active; /* EMCY 0xFF05 active */

    /* open loop active in the last step (0x2200:01 = 0 or 0x2202:01 = 3) */
    uint8_t open_loop;

    /* CiA 402 power drive system (0x6040/0x6041): only OPERATION ENABLED and QUICK STOP ACTIVE let
     * the control act on the motor */
    cia402_device_t cia402;

    /* trace buffer linearised in place for the DOMAIN upload */
    uint8_t trace_linear;
    drive_app_trace_status_t trace_status;

    /* live trace (TPDO2) decimation counter */
    uint16_t live_count;

    /* step cost (0x2208): NULL counter -> all 0 */
    drive_app_cycles_fn cycles_fn;
    void *cycles_user;
    uint32_t cycle_clock_Hz;
    uint8_t overrun_check; /* 1: a step longer than Ts_s by the counter enters the safe state (overrun) */
    drive_app_step_cost_t step_cost;
    uint64_t step_cycles_sum;
    uint8_t cost_controller; /* 0x2200:01 of the steps measured (a new one resets the statistics) */
} drive_app_t;

/* Hooks for co_node_init (user = drive_app_t *). */
const co_hooks_t *drive_app_hooks(void);

/* Before co_node_init: core defaults, trace recorder. */
void drive_app_init(drive_app_t *app);

/* After co_node_init: remembers the node. */
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

/* Run one current step on the measurement held in 0x2100 (what the RPDO2 hook
 * does; public for drivers that receive the measurement otherwise). */
void drive_app_current_step(drive_app_t *app);

/* Load the whole drive configuration from the OD into app->drv.cfg and mark
 * it for drive_apply_config (normally done by the hooks). */
void drive_app_load_config(drive_app_t *app);

#endif /* DRIVE_APP_H */
