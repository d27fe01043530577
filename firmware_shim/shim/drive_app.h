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
 * OD controller numbering (0x2200:01) vs the core's drive_controller_t:
 *   0 open loop (shim), n >= 1 -> core controller n - 1 (1 PI, 2 deadbeat
 *   You 2019, 3 DPCC Yao 2020, 4 incremental deadbeat Zhao 2022, 5
 *   forward-Euler predictive Zhao 2022); values whose core controller does
 *   not exist (>= DRIVE_CTRL_COUNT) abort with 0x06090030.  3-5 are
 *   surface-mounted laws (L = Lq_hat_H): selecting one while |Ld_hat_H -
 *   Lq_hat_H| > 5 % of Lq_hat_H aborts with 0x06090030 too.
 *
 * Yao 2020 (0x2206): its settings reach the core like the others (next
 * step); 0x2206:15 ident_command = 1 starts the R/L identification at once
 * (abort 0x06040043 without controller 3 and its observer, 0x08000022
 * before the first step or while running), 2 aborts it; it reads back 0.
 * The read-only entries (state, progress, R_hat/L_hat, RLS estimates) are
 * refreshed on every read (SDO or TPDO).
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
 *   RPDO1 (with the last currents), so the plant always gets a command.
 */
#ifndef DRIVE_APP_H
#define DRIVE_APP_H

#include <stdint.h>

#include "co_node.h"
#include "drive_core.h"
#include "trace_recorder.h"

/* Manufacturer-specific EMCY codes (CiA 301 0xFF00-0xFFFF). */
#define DRIVE_EMCY_MEAS_LOST 0xFF01u
#define DRIVE_EMCY_MEAS_LATE 0xFF02u

/* Reasons in byte 2 of the MSEF of DRIVE_EMCY_MEAS_LATE. */
enum {
    DRIVE_LATE_RPDO1_WITHOUT_RPDO2 = 1,
    DRIVE_LATE_RPDO2_WITHOUT_RPDO1 = 2,
    DRIVE_LATE_DUPLICATE_OR_OLD = 3,
    DRIVE_LATE_SYNC_MISMATCH = 4
};

#define DRIVE_APP_PENDING_EMCY 4u

/* A free-running cycle counter of the target (wraps modulo 2^32): DWT CYCCNT,
 * SysTick, clock_gettime in ns.  Read before and after every current step; the
 * difference is published in 0x2208 Step cost. */
typedef uint32_t (*drive_app_cycles_fn)(void *user);

typedef struct {
    drive_t drv;            /* firmware core */
    trace_recorder_t trace; /* oscilloscope buffer, exposed as 0x2301 */
    co_node_t *node;        /* set by drive_app_bind */

    /* last inputs / output of the current step */
    drive_meas_t meas;
    drive_cmd_t cmd;

    /* counters (mirrored in 0x2204) */
    uint32_t current_steps;
    uint32_t lost;
    uint32_t late;
    uint32_t emcy_raised; /* EMCY 0xFF01/0xFF02 raised */

    /* measurement sequencing */
    uint8_t rpdo1_fresh; /* RPDO1 seen, waiting for its RPDO2 */
    uint8_t have_last;   /* last_sample_index valid */
    uint16_t last_sample_index;
    uint8_t old_run;   /* consecutive duplicate/old sample_index */
    uint8_t sync_seen; /* a SYNC was received since OPERATIONAL */
    uint8_t last_sync_counter;
    uint8_t meas_error_active; /* an 0xFF01/0xFF02 error is active */

    /* EMCYs of the measurement being handled, sent after its command */
    uint8_t defer_emcy;
    uint8_t n_pending;
    uint16_t pending_code[DRIVE_APP_PENDING_EMCY];
    uint8_t pending_msef[DRIVE_APP_PENDING_EMCY][5];

    /* open loop active in the last step (0x2200:01 = 0 or 0x2202:01 = 3) */
    uint8_t open_loop;

    /* trace buffer linearised in place for the DOMAIN upload */
    uint8_t trace_linear;

    /* live trace (TPDO2) decimation counter */
    uint16_t live_count;

    /* step cost (0x2208): NULL counter -> all 0 */
    drive_app_cycles_fn cycles_fn;
    void *cycles_user;
    uint32_t cycle_clock_Hz;
    uint32_t step_cycles_last;
    uint32_t step_cycles_max;
    uint64_t step_cycles_sum;
    uint32_t steps_measured;
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

/* Run one current step on the measurement held in 0x2100 (what the RPDO2 hook
 * does; public for drivers that receive the measurement otherwise). */
void drive_app_current_step(drive_app_t *app);

/* Load the whole drive configuration from the OD into app->drv.cfg and mark
 * it for drive_apply_config (normally done by the hooks). */
void drive_app_load_config(drive_app_t *app);

#endif /* DRIVE_APP_H */
