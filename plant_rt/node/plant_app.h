/* plant_app.h - the PMSM plant as a CANopen node (portable glue: no OS headers).
 *
 * Binds plant_rt/core (pmsm_plant) to the portable CANopen slave (co_node) and
 * the generated plant OD (od_plant, from protocols/eds/plant.eds):
 *
 *   0x2000-0x2002  model parameters (every plant_config_t field), SDO-writable;
 *                  a write is validated at once (its check: a combination the
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
 * Which command answers which sample (on time, late, missed) and the real-time
 * timing (0x2006, 0x2007) are a component of their own, plant_timing.h
 * (plant_app_t.timing); the app counts what it answers in 0x2003.
 *
 * The app reaches the OD through its node (plant_mfr); plant_app_init and
 * plant_app_config_* work before the node exists, on od_plant's RAM.
 * No allocation; one instance per OD (the generated OD RAM is a global).
 *
 * The app's two halves, layered one way: plant_app_od.h/.c (below) owns the
 * state plant_app_t and the objects 0x2000-0x2004, 0x2007 (their checks, OD <->
 * config, presets, init); plant_app.c (this header's) owns the periods: the SYNC
 * hooks, plant_app_poll and plant_app_realtime_tick.  This header is the API of
 * both: it includes plant_app_od.h.
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
#include "od_plant.h"
/* plant_app_t, plant_app_init/_bind/_running/_realtime_mode/_load_preset/_config_*: the app's state and objects */
#include "plant_app_od.h"
#include "plant_timing.h"
#include "pmsm_plant.h"

/* Hooks for co_node_init (user pointer = plant_app_t *); their bind hook binds the app's objects. */
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

/* Applied Ts in nanoseconds (changes only at a SYNC). */
int64_t plant_app_period_ns(const plant_app_t *app);

#endif /* PLANT_APP_H */
