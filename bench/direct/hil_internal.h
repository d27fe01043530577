/* hil_internal.h - what hil_direct.c (the bus, the nodes, the injector, the lockstep loop) gives the real-time
 * files (not an API: the hil_* functions Python calls are):
 *   hil_rt_threads.c  the nodes' threads of a real-time run: the plant paced, the drive answering what arrives
 *   hil_realtime.c    the real-time run (hil_run_realtime) and the host under it
 * The dependency runs one way: the real-time files use hil_direct.c; for a run they install a delivery sink
 * (hil_sink_t), through which hil_direct.c hands the nodes' frames to them without knowing them. The lock is
 * hil_lock.h's, the recorder and the master's queue hil_master.h's. */
#ifndef HIL_INTERNAL_H
#define HIL_INTERNAL_H

#include <stdint.h>

#include "co_node.h"
#include "plant_app.h"

/* Where the frames for the nodes go while a sink is installed: push(user, side, f, t_us) takes a frame for side
 * `side` (FI_SIDE_A plant, FI_SIDE_B drive) delivered at t_us (the bus lock held), instead of the delivering thread
 * processing it at once (co_node_process). own_thread: a bit per side whose node works on a thread of its own
 * alone; a thawed node's backlog goes through push too (the other side's is processed at once, under the lock). */
typedef struct {
    void (*push)(void *user, uint8_t side, const co_frame_t *f, int64_t t_us);
    void *user;
    uint8_t own_thread;
} hil_sink_t;

/* hil_direct.c (callers hold the bus lock in real time) */

/* The delivery sink; NULL (hil_open's): the lockstep path, every frame processed at once by the delivering thread. */
void hil_set_sink(const hil_sink_t *sink);
/* How many times hil_open ran: what another layer keeps for one opening (a stop asked for, counters) is stale
 * once this changed. */
uint32_t hil_opens(void);

co_node_t *hil_node_of(uint8_t side);
plant_app_t *hil_plant_app(void);
void hil_deliver(void);
void hil_timers(uint8_t side);
void hil_fi_tick(void);
void hil_set_now_us(int64_t t_us);
int hil_side_live(uint8_t side);
int hil_side_killed(uint8_t side);
void hil_frozen_frame(const co_frame_t *f);
void hil_set_running(int on);
uint32_t hil_nodes_down(void);
int64_t hil_now_us(void);

/* hil_pylaw.c: a Ctrl-C in a Python law's method asked the loop to return (hil_run checks it each period). */
int hil_pylaw_stopping(void);
#endif /* HIL_INTERNAL_H */
