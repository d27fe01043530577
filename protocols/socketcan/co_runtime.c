/* co_runtime.c - Linux main loop of a CANopen node process (see co_runtime.h). */
#include "co_runtime.h"

#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "co_socketcan.h"

static volatile sig_atomic_t g_stop;

static void on_signal(int sig)
{
    (void)sig;
    g_stop = 1;
}

int co_runtime_parse_args(int argc, char **argv, const char **iface, uint8_t *node_id)
{
    int i = 1;
    for (; i < argc; ++i) {
        if (strcmp(argv[i], "--iface") == 0 && i + 1 < argc) {
            *iface = argv[++i];
        } else if (strcmp(argv[i], "--node-id") == 0 && i + 1 < argc) {
            char *end = NULL;
            long v = strtol(argv[++i], &end, 0);
            if (!end || *end || v < 1 || v > 127) {
                fprintf(stderr, "--node-id must be an integer in 1..127, got '%s'\n", argv[i]);
                return -1;
            }
            *node_id = (uint8_t)v;
        } else {
            break;
        }
    }
    return i;
}

int co_runtime_open(co_runtime_t *rt, const char *iface, const co_od_t *od, uint8_t node_id, const co_hooks_t *hooks,
                    const co_runtime_app_t *app, void *user)
{
    memset(rt, 0, sizeof *rt);
    rt->fd = co_socketcan_open(iface, 4 << 20);
    if (rt->fd < 0) return -1;
    rt->app = app;
    rt->user = user;
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    co_node_init(&rt->node, od, node_id, co_socketcan_send, &rt->fd, hooks, user, co_socketcan_now_us());
    return 0;
}

int co_runtime_wait_one(co_runtime_t *rt, int64_t timeout_us)
{
    co_frame_t f;
    int64_t rx_ns = 0;
    int r = co_socketcan_recv(rt->fd, &f, timeout_us, &rx_ns);
    if (r < 0) return -1;
    if (r == 1) {
        ++rt->frames_in;
        /* the frame's time: now, or with rx_stamps the kernel's receive time stamp (CLOCK_REALTIME) on the
         * monotonic clock, when there is one and it is neither in the future nor a second old (a clock step) */
        int64_t now = co_socketcan_now_us();
        int64_t at = now;
        if (rt->rx_stamps && rx_ns > 0) {
            struct timespec wall;
            clock_gettime(CLOCK_REALTIME, &wall);
            int64_t age_us = ((int64_t)wall.tv_sec * 1000000000LL + wall.tv_nsec - rx_ns) / 1000;
            if (age_us >= 0 && age_us < 1000000) at = now - age_us;
        }
        co_node_process(&rt->node, &f, at);
    }
    return r;
}

uint32_t co_runtime_drain(co_runtime_t *rt)
{
    uint32_t n = 0;
    while (n < CO_RUNTIME_BURST_MAX && co_runtime_wait_one(rt, 0) == 1) ++n;
    return n;
}

int co_runtime_run(co_runtime_t *rt)
{
    int64_t app_wait = 1000000;
    while (!g_stop && !rt->stop) {
        int64_t now = co_socketcan_now_us();
        int64_t wait = co_node_next_event_us(&rt->node, now, 100000);
        if (app_wait >= 0 && app_wait < wait) wait = app_wait;
        int r = co_runtime_wait_one(rt, wait);
        if (r < 0) {
            fprintf(stderr, "CAN receive failed\n");
            return 1;
        }
        /* woken far later than asked: this process (or its machine, its VM) did not run meanwhile, and the
         * heartbeats it consumes are not to blame for that time (a loaded host stalled a CI VM for ~2 s) */
        int64_t late_us = co_socketcan_now_us() - (now + wait);
        if (late_us > CO_RUNTIME_STALL_US) co_node_excuse_us(&rt->node, late_us);
        /* the rest of the burst, without waiting, but bounded: under any receive load the node's timers
         * (heartbeat produced and consumed, TPDO event timers, SDO timeout) and the app's poll run at
         * least every CO_RUNTIME_BURST_MAX + 1 frames; the frames left are served next time round */
        if (r == 1) (void)co_runtime_drain(rt);
        now = co_socketcan_now_us();
        co_node_tick(&rt->node, now);
        if (rt->app && rt->app->poll) {
            app_wait = rt->app->poll(rt->user, rt, now);
            if (app_wait == CO_RUNTIME_EXIT) break;
        }
    }
    return 0;
}

void co_runtime_close(co_runtime_t *rt)
{
    if (rt->fd >= 0) close(rt->fd);
    rt->fd = -1;
}

int co_runtime_stop_requested(void) { return g_stop; }
