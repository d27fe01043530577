/* plant_pacing.h - the plant's real-time pacing, shared by every transport (plant_node over SocketCAN,
 * the bench's direct mode on threads): SYNC at absolute CLOCK_MONOTONIC deadlines every Ts, frames served
 * between deadlines, SCHED_FIFO and mlockall when permitted.  POSIX (the one file of the plant app with OS
 * headers: the pacing is the operating system's part). */
#ifndef PLANT_PACING_H
#define PLANT_PACING_H

#include <stdint.h>

#include "plant_app.h"

#define PLANT_PACING_PRIORITY 80 /* SCHED_FIFO priority of the plant's pacing thread */

/* What the transport does for the loop (user: its own pointer). */
typedef struct {
    void *user;
    /* Take and process frames until until_ns (CLOCK_MONOTONIC) or until real-time mode ends; the node's timers
     * and plant_app_poll() after each batch. */
    void (*serve_until)(void *user, int64_t until_ns);
    /* The deadline has passed: take the frames that arrived, read the clock, plant_app_realtime_tick(app, now,
     * now - deadline_ns) and the node's timers; returns now (CLOCK_MONOTONIC ns). */
    int64_t (*tick)(void *user, int64_t deadline_ns);
    /* Non-zero: leave the loop (a signal, the end of a segment). */
    int (*stop)(void *user);
} plant_pacing_io_t;

int64_t plant_pacing_now_ns(void);
/* The CPU the plant's pacing thread is kept on: the first of those the process may use (taskset, cpusets) when
 * it may use two or more, else -1 (anywhere): the scheduler does not move it mid-run. */
int plant_pacing_default_cpu(void);
/* The CPU for the drive beside it (direct mode): the last of those, -1 when there is one. */
int plant_pacing_other_cpu(void);
/* For the calling thread: SCHED_FIFO at `priority`, kept on `cpu` (-1: anywhere) and, once per process,
 * mlockall(MCL_CURRENT | MCL_FUTURE) and CPU idle states held off (/dev/cpu_dma_latency = 0, as cyclictest
 * does); returns one line saying what was got, and for what was not, why and the command that grants it (a
 * static buffer). */
const char *plant_pacing_priority(int priority, int cpu);
/* Keep the calling thread on one CPU (-1: anywhere); 0 or an errno. */
int plant_pacing_pin(int cpu);
/* Keep `cpu` out of its halt while the plant sleeps (-1: nothing done): a thread at SCHED_IDLE busy-loops there
 * until plant_pacing_awake_stop(). On a virtual machine a halted virtual CPU is woken by the hypervisor, late
 * (docs/REALTIME.md); the plant's timer interrupt preempts the loop at once (user space, nothing held). It
 * costs that CPU whole for the run. Returns 1 when the thread runs. */
int plant_pacing_awake_start(int cpu);
void plant_pacing_awake_stop(void);
/* The absolute-deadline loop: returns when real-time mode ends or io->stop() says so. */
void plant_pacing_loop(plant_app_t *app, const plant_pacing_io_t *io);

#endif /* PLANT_PACING_H */
