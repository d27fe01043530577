/* hil_rt_threads.h - the nodes' threads of a real-time run in direct mode: the plant's (plant_pacing_loop over the
 * in-process bus), the drive's (it answers what arrives, its frames through an outbox), their inboxes (the run's
 * delivery sink) and, after them, the draining of what is still queued. The run (hil_realtime.c) calls it in this
 * order: begin, run, end. It owns the run's state that outlives a call too: a stop asked for (hil_stop), the plant
 * thread's note (hil_realtime_note), the frames the inboxes could not take (hil_rt_dropped). */
#ifndef HIL_RT_THREADS_H
#define HIL_RT_THREADS_H

#include <stdint.h>

#include "plant_app.h"

/* Ready a run of at most max_periods SYNCs (the lock taken here): the time line continued, the inboxes emptied,
 * the drive's frames through its outbox, the delivery sink installed. Returns the plant's CPU (-1: anywhere),
 * which the plant, the drive and the awake thread share. */
int hil_rt_threads_begin(plant_app_t *app, uint32_t max_periods);
/* The drive's and the plant's threads, until the plant's loop ends (the hold, a node lost, a stall, hil_stop,
 * max_periods); returns once both are done: 1, or 0 when a thread could not be started. */
int hil_rt_threads_run(plant_app_t *app);
/* After the threads (the lock taken here): the drive's own transmit path back, what is still queued processed
 * in order, the sink removed (lockstep again), a stop asked for forgotten. */
void hil_rt_threads_end(plant_app_t *app);
/* The SYNCs the plant produced since begin. */
uint32_t hil_rt_threads_syncs(const plant_app_t *app);

/* ---- libhil.so's API (ctypes: bench/run/bus/direct.py) */

/* Ask a real-time run to return at its next deadline (Ctrl-C); also before it started. */
void hil_stop(void);
/* What the plant's thread got of SCHED_FIFO / mlockall / its CPU (one line), after hil_run_realtime. */
const char *hil_realtime_note(void);
/* Frames a node's receive FIFO could not take (real time; since hil_open). */
uint64_t hil_rt_dropped(void);

#endif /* HIL_RT_THREADS_H */
