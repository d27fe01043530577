/* hil_internal.h - what the direct mode's files share (not an API: the hil_* functions Python calls are).
 *   hil_direct.c    the in-process bus, the nodes, the injector, the recorder, the lockstep loop
 *   hil_realtime.c  the real-time loop: the plant and the drive on threads of their own */
#ifndef HIL_INTERNAL_H
#define HIL_INTERNAL_H

#include <stdint.h>

#include "co_node.h"
#include "plant_app.h"

/* hil_direct.c (callers hold the bus lock in real time) */
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

/* hil_realtime.c */
extern volatile int hil_rt_active;
/* A frame for side `side` (FI_SIDE_A plant, FI_SIDE_B drive), delivered at t_us: queued for its thread. */
void hil_rt_push(uint8_t side, const co_frame_t *f, int64_t t_us);
/* The one lock of direct mode (recursive, priority inheritance): every hil_* entry point Python calls takes it,
 * so that Python's threads never meet the nodes' threads of a real-time run in the middle of a frame. */
void hil_rt_lock(void);
void hil_rt_unlock(void);
/* Forget a previous run's stop request and counters (hil_open). */
void hil_rt_reset(void);

#endif /* HIL_INTERNAL_H */
