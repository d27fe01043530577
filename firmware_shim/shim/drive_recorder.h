/* drive_recorder.h - the recorders, a component of the drive app (drive_app.h tells the rules): the trace
 * recorder (0x2300 its configuration and arming, 0x2301 the captured buffer, linearised for its upload), the
 * live trace (0x2302, TPDO2's values and decimation) and the step cost (0x2208: the cycles of the current step
 * by the target's counter).  It owns those objects and binds them; it never runs the step.  Only the cores,
 * the stack and its own header.  Portable: no OS headers, no allocation, float32. */
#ifndef DRIVE_RECORDER_H
#define DRIVE_RECORDER_H

#include <stdint.h>

#include "co_node.h"
#include "drive_core.h"
#include "trace_recorder.h"

/* A free-running cycle counter of the target (wraps modulo 2^32): DWT CYCCNT, SysTick, clock_gettime in ns.
 * Read before and after every current step; the difference is published in 0x2208 Step cost. */
typedef uint32_t (*drive_app_cycles_fn)(void *user);

typedef struct {               /* 0x2208 Step cost, named as in drive.eds */
    uint32_t step_cycles_last; /* REAL32 in the OD */
    uint32_t step_cycles_max;  /* REAL32 in the OD */
    float step_cycles_mean;    /* at the read: sum / steps_measured */
    uint32_t cycle_clock_Hz;   /* at the read: 0 without a counter */
    uint32_t steps_measured;
} drive_app_step_cost_t;

typedef struct { /* 0x2300 Trace, at the read */
    uint32_t captured_bytes;
    uint32_t trigger_row;
} drive_app_trace_status_t;

typedef struct {
    trace_recorder_t trace; /* oscilloscope buffer, exposed as 0x2301 */
    drive_t *drv;           /* the core it samples (its signals, the live trace's values) */
    co_node_t *node;
    co_od_ext_t ext_trace, ext_cost;
    uint8_t linear; /* the buffer linearised in place for the DOMAIN upload */
    drive_app_trace_status_t trace_status;
    uint16_t live_count; /* live trace (TPDO2) decimation counter */

    /* step cost (0x2208): NULL counter -> all 0 */
    drive_app_cycles_fn cycles_fn;
    void *cycles_user;
    uint32_t cycle_clock_Hz;
    drive_app_step_cost_t step_cost;
    uint64_t step_cycles_sum;
    uint8_t cost_controller; /* 0x2200:01 of the steps measured (a new one resets the statistics) */
} drive_recorder_t;

/* Before the node: an empty recorder attached to the core. */
void drive_recorder_init(drive_recorder_t *r, drive_t *drv);
/* Bind 0x2300-0x2302 and 0x2208 (co_node_init's bind hook). */
void drive_recorder_bind(drive_recorder_t *r, co_node_t *node);
/* Reset node: an empty recorder, the statistics restart. */
void drive_recorder_reset(drive_recorder_t *r);
/* 0x2301 points at the buffer (nothing captured yet). */
void drive_recorder_publish_buffer(drive_recorder_t *r);

void drive_recorder_set_cycle_counter(drive_recorder_t *r, drive_app_cycles_fn fn, void *user, uint32_t clock_Hz);
void drive_recorder_reset_cost(drive_recorder_t *r);

/* A step begins with this controller: another one restarts the statistics. */
void drive_recorder_begin(drive_recorder_t *r, uint8_t controller);
/* The target's counter now (0 without one): read by the root right around the law's step, so that nothing but the
 * step is in the window (inline: no call in it either). */
static inline uint32_t drive_recorder_now(const drive_recorder_t *r)
{
    return r->cycles_fn != NULL ? r->cycles_fn(r->cycles_user) : 0u;
}
/* What the recorders make of a step that has ended. */
typedef struct {
    uint8_t counted;  /* a counter is there: cycles is the step's */
    uint8_t live_due; /* the live trace's TPDO2 goes out after the command */
    uint32_t cycles;
} drive_recorder_step_t;
/* The step has ended, `cycles` long by the counter (drive_recorder_now after minus before): its cost counted, the
 * live trace's decimation. */
drive_recorder_step_t drive_recorder_end(drive_recorder_t *r, uint32_t cycles);

#endif /* DRIVE_RECORDER_H */
