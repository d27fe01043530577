/* plant_app.h - the PMSM plant as a CANopen node (portable glue: no OS headers).
 *
 * Binds plant_rt/core (pmsm_plant) to the portable CANopen slave (co_node) and
 * the generated plant OD (od_plant, from protocols/eds/plant.eds):
 *
 *   0x2000-0x2002  model parameters (every plant_config_t field), SDO-writable;
 *                  a write is validated at once (pre_write: a combination the
 *                  core rejects -> abort 0x06040043, the model is unchanged)
 *                  and takes effect at the next SYNC (period boundary).
 *   0x2003         run control: mode (0 lockstep, 1 real time), run_periods,
 *                  counters, trip clear/active, state.
 *   0x2004         motor preset: writing a name loads it into 0x2000-0x2002
 *                  (unknown name -> abort 0x06090030).
 *   0x2005         true state after the last SYNC.
 *   0x2006         DOMAIN: the real-time timing histograms (plant_rtstats.h).
 *   0x2007         real-time timing: SYNC lateness and turnaround (min, mean,
 *                  p50, p99, p99.9, max; the percentiles computed when read),
 *                  overruns, the worst period; write 1 to :12 reset.
 *   0x2100         the sample taken at the last SYNC (TPDO1/TPDO2).
 *   0x2102         the voltage command (synchronous RPDO1).
 *
 * SYNC k (on_sync hook, after the core actuated the synchronous RPDO):
 *   1. integrate [k-1, k] with the command held over it (nothing at k = 0),
 *   2. apply pending parameter changes (plant_prepare),
 *   3. latch OD 0x2102 as the stator-frame command held over [k, k+1],
 *   4. sample i(k), theta(k) into 0x2100 / 0x2005; the synchronous TPDOs
 *      go out after the hook returns.
 *
 * Usage (any transport):
 *   plant_app_init(&app);
 *   co_node_init(&node, &od_plant, id, tx, tx_user, plant_app_hooks(), &app, now);
 *   plant_app_bind(&app, &node);
 *   loop: feed frames to co_node_process(), co_node_tick(), then
 *         plant_app_poll(&app, now)           (lockstep: produces the SYNCs)
 *         plant_app_realtime_tick(&app, ...)  (real time: at each deadline)
 *
 * The synchronous RPDO only calls on_rpdo at the SYNC, so the arrival of a
 * command is detected by plant_app_poll() from the RPDO's receive buffer
 * (co_pdo_t.rx_buffered / last_rx_us): call it after every received frame
 * (co_runtime does) or at least after every batch (co_membus_deliver).
 *
 * No allocation; one instance per OD (the generated OD RAM is a global).
 */
#ifndef PLANT_APP_H
#define PLANT_APP_H

#include <stdbool.h>
#include <stdint.h>

#include "co_node.h"
/* od_plant_fields.h: the plant's EMCY codes PLANT_EMCY_* ([EmergencyCodes] of plant.eds) and the bits of
 * 0x2100:05 Measurement.status, PLANT_STATUS_TRIP, _HOLDING, _MISSED, _HELD (its BitNames in plant.eds;
 * what each means: its Description there). */
#include "od_plant_fields.h"
#include "plant_rtstats.h"
#include "pmsm_plant.h"

/* Command accounting: the n-th command frame answers sample n, so after a
 * missed period the next arrival is taken as that late command (0x2003:06)
 * and does not release the next SYNC. Resynchronisation: after this many
 * consecutive periods that ended without an on-time command although a
 * (presumed late) one arrived in them, the owed count is reset (the drive is
 * assumed to have dropped a command). Real-time mode uses 1. */
#define PLANT_APP_RESYNC_PERIODS 3u
#define PLANT_APP_SCHED_RING 16u

/* The read-only entries of 0x2100 Measurement and 0x2005 Plant state, named as in plant.eds: the
 * SYNC fills them and the list od_plant_fields.h generates (OD_PLANT_<RECORD>_STATUS) copies them
 * to the OD, so an entry's name is written once, in the EDS.  (0x2003 Run control's status stays
 * in the OD: the plant counts and tests it there.) */
typedef struct { /* 0x2100 Measurement (TPDO1, TPDO2) */
    float i_a_A;
    float i_b_A;
    float theta_m_rad;
    uint8_t sync_counter;
    uint8_t status; /* PLANT_STATUS_* */
    uint16_t sample_index;
} plant_app_measurement_t;

typedef struct { /* 0x2005 Plant state: the model's truth, REAL32 in the OD */
    double id_A;
    double iq_A;
    double omega_m_rad_s;
    double theta_m_rad;
    double torque_Nm;
    double energy_in_J;
} plant_app_plant_state_t;

typedef struct {
    co_node_t *node;

    /* model */
    plant_config_t cfg; /* applied configuration */
    plant_state_t state;
    plant_meas_t meas;                   /* sample of the last SYNC */
    plant_app_measurement_t measurement; /* 0x2100 of the last SYNC */
    plant_app_plant_state_t plant_state; /* 0x2005 of the last SYNC */
    plant_config_t scratch_cfg;          /* SDO validation (not in the per-period path) */
    plant_state_t scratch_state;
    bool cfg_dirty; /* OD 0x2000-0x2002 changed: apply at the next SYNC */
    bool reseed;    /* rng_seed written: re-seed at the next SYNC */
    uint32_t config_applies;
    uint32_t config_errors; /* pending change rejected by plant_prepare at the SYNC (should stay 0) */

    /* periods */
    bool started;                         /* SYNC 0 happened */
    uint64_t k;                           /* index of the last sample */
    double v_held_alpha_V, v_held_beta_V; /* command held over [k, k+1] */
    int64_t last_sync_us;
    int64_t wait_start_us; /* lockstep: command timeout counts from here */
    bool paused;           /* not running at the last poll (holding / not operational) */
    uint32_t syncs;

    /* command tracking (lockstep and real time) */
    bool cmd_ready;         /* the command for the current period arrived */
    bool cmd_seen;          /* the buffered RPDO has been accounted for */
    int64_t cmd_seen_rx_us; /* its reception time */
    int64_t cmd_arrival_us; /* when the command of the current period arrived (real time: overrun if late) */
    bool late_in_period;    /* a command classified late arrived in this period */
    uint32_t owed;          /* commands of missed periods that may still arrive */
    uint32_t late_timeout_streak;
    bool miss_flag;            /* status bit2 of the next sample */
    uint32_t commands;         /* command frames seen */
    uint32_t commands_at_sync; /* ... at the last SYNC (PLANT_STATUS_HELD) */
    bool drive_lost;           /* the trip latched because the drive's heartbeat was lost (EMCY 0xFF10) */
    uint16_t trip_emcy;        /* the EMCY code the active trip raised (cleared with it) */

    /* real time */
    plant_rtstats_t lateness;                         /* SYNC: its time minus its deadline */
    plant_rtstats_t turnaround;                       /* command arrival minus its period's SYNC */
    uint8_t hist_bytes[2u * PLANT_RTSTATS_BINS * 4u]; /* the DOMAIN 0x2006: lateness, then turnaround */
} plant_app_t;

/* Zero the app and load the OD defaults into the model (callable before co_node_init). */
void plant_app_init(plant_app_t *app);
/* Remember the node (also learnt from the first hook call). */
void plant_app_bind(plant_app_t *app, co_node_t *node);
/* Hooks for co_node_init (user pointer = plant_app_t *). */
const co_hooks_t *plant_app_hooks(void);

/* Lockstep driver: detects command arrival, produces the next SYNC when it is
 * due (NMT OPERATIONAL, run_periods > 0, mode 0, command arrived or timed out).
 * Returns the longest wait (us) before the next call is needed; -1: no wish
 * (holding, or real-time mode where the transport calls realtime_tick). */
int64_t plant_app_poll(plant_app_t *app, int64_t now_us);

/* Real-time mode: the transport calls this at each absolute deadline (every
 * plant_app_period_ns), after taking the frames that arrived; lateness_ns = now -
 * deadline. Counts an overrun if the command was not in by the deadline (a miss
 * if it is not in at all), times the SYNC (0x2007), produces it. Returns the SYNC
 * counter or -1 (not running / not in real-time mode). */
int plant_app_realtime_tick(plant_app_t *app, int64_t now_us, int64_t lateness_ns);

/* NMT OPERATIONAL and run_periods > 0. */
bool plant_app_running(const plant_app_t *app);
/* 0x2003:01 == 1. */
bool plant_app_realtime_mode(const plant_app_t *app);
/* Applied Ts in nanoseconds (changes only at a SYNC). */
int64_t plant_app_period_ns(const plant_app_t *app);

/* Load the named preset into the OD entries 0x2000-0x2002 (as the 0x2004 write does);
 * effective at the next SYNC. Returns 0 or PLANT_ERR_PRESET. */
int plant_app_load_preset(plant_app_t *app, const char *name);

/* OD 0x2000-0x2002 -> config (exact float -> double). */
void plant_app_config_from_od(plant_config_t *c);
/* config -> OD 0x2000-0x2002 (rounded to REAL32). */
void plant_app_config_to_od(const plant_config_t *c);

#endif /* PLANT_APP_H */
