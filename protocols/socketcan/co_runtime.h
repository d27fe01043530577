/* co_runtime.h - the Linux main loop of a CANopen node process: one raw
 * SocketCAN socket, the portable co_node_t, and an application poll hook.
 *
 *   for (;;) { wait for a frame or the next timer; co_node_process() the burst; co_node_tick(); app->poll(); }
 *
 * A burst is bounded (CO_RUNTIME_BURST_MAX frames), so under any receive load the heartbeat
 * and the other timers keep their time (a flood of frames once held them for seconds).
 *
 * SIGINT/SIGTERM end the loop cleanly (co_runtime_run returns 0).
 */
#ifndef CO_RUNTIME_H
#define CO_RUNTIME_H

#include <stdint.h>

#include "co_node.h"

typedef struct co_runtime co_runtime_t;

typedef struct {
    /* Called after every received frame and every timeout; returns the longest
     * time in microseconds the loop may wait before calling it again
     * (negative: no wish). Return CO_RUNTIME_EXIT to stop the loop. */
    int64_t (*poll)(void *user, co_runtime_t *rt, int64_t now_us);
} co_runtime_app_t;

#define CO_RUNTIME_EXIT (-1000000000LL)

struct co_runtime {
    int fd;
    co_node_t node;
    const co_runtime_app_t *app;
    void *user;
    volatile int stop;
    uint32_t frames_in;
    int rx_stamps; /* non-zero: a frame is processed at its kernel receive time (real-time pacing), else now */
};

/* Parse the common options: --iface NAME (default vcan0), --node-id N (1..127).
 * Unknown options are left for the caller (returns the index of the first one or argc).
 * On a bad value prints a message naming the option and the allowed range, returns -1. */
int co_runtime_parse_args(int argc, char **argv, const char **iface, uint8_t *node_id);

/* Open the socket and initialise the node (boot-up is sent). Returns 0 or -1. */
int co_runtime_open(co_runtime_t *rt, const char *iface, const co_od_t *od, uint8_t node_id, const co_hooks_t *hooks,
                    const co_runtime_app_t *app, void *user);

/* Run until stopped by a signal or by the app. Returns 0 on a clean stop, 1 on a bus error. */
int co_runtime_run(co_runtime_t *rt);

/* Frames processed back to back before the node's timers get their turn (co_runtime_run, co_runtime_drain):
 * a flood of received frames must not hold the heartbeat, whose time is the bus's liveness. */
#define CO_RUNTIME_BURST_MAX 64u
/* A wake-up this much later than asked is a stall of the node's own (co_node_excuse_us). */
#define CO_RUNTIME_STALL_US 50000

/* Process the frames already queued on the socket without waiting (for tight loops), at most
 * CO_RUNTIME_BURST_MAX: the caller runs its timers (co_node_tick) and comes back for the rest.
 * Returns how many were processed. */
uint32_t co_runtime_drain(co_runtime_t *rt);

/* Block up to timeout_us for one frame and process it; returns 1 if a frame was processed. */
int co_runtime_wait_one(co_runtime_t *rt, int64_t timeout_us);

void co_runtime_close(co_runtime_t *rt);

/* True once SIGINT or SIGTERM was received. */
int co_runtime_stop_requested(void);

#endif /* CO_RUNTIME_H */
