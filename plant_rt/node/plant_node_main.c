/* plant_node_main.c - the PMSM plant as a Linux CANopen node process.
 *
 *   plant_node [--iface vcan0] [--node-id N] [--realtime] [--help]
 *
 * Lockstep (0x2003:01 = 0): co_runtime_run() with plant_app_poll() as the app
 * poll: a SYNC goes out as soon as the command for the current period arrived
 * (or after 0x2003:04 command_timeout_us).
 * Real time (0x2003:01 = 1): plant_pacing_loop (plant_pacing.h), SYNC every Ts_s
 * at absolute deadlines, frames drained between deadlines. Tries SCHED_FIFO and
 * mlockall (one line says if not permitted and how to grant them); the timing
 * statistics in 0x2007 (and 0x2006).
 * SIGINT/SIGTERM: clean exit (status 0).
 */
#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "co_runtime.h"
#include "od_plant.h"
#include "plant_app.h"
#include "plant_fmu.h"
#include "plant_pacing.h"

#define EXIT_USAGE 64

static plant_app_t g_app;
static co_runtime_t g_rt;
static int g_cpu = -2;   /* --cpu: -2 the default (plant_pacing_default_cpu), -1 anywhere */
static int g_keep_awake; /* --keep-awake: the pacing CPU never halts during real time */

static void usage(FILE *f)
{
    fprintf(f,
            "usage: plant_node [--iface NAME] [--node-id N] [--realtime] [--cpu N] [--keep-awake] [--help]\n"
            "\n"
            "PMSM plant emulator as a CANopen slave (OD: protocols/eds/plant.eds).\n"
            "It is the SYNC producer: SYNC k -> TPDO1 {i_a_A, i_b_A}, TPDO2 {theta_m_rad,\n"
            "sync_counter, status, sample_index}; the voltage command comes in the\n"
            "synchronous RPDO1 (0x2102) and is actuated at the next SYNC.\n"
            "\n"
            "  --iface NAME   SocketCAN interface (default vcan0)\n"
            "  --node-id N    CANopen node-ID, 1..127 (default %u)\n"
            "  --realtime     start in real-time mode (same as SDO 0x2003:01 = 1)\n"
            "  --cpu N        real time: keep the pacing on CPU N (-1: anywhere; default the\n"
            "                 first CPU the process may use, when it may use two or more)\n"
            "  --keep-awake   real time: a SCHED_IDLE busy loop on that CPU keeps it out of its\n"
            "                 halt while the plant sleeps (a halted virtual CPU wakes late;\n"
            "                 docs/REALTIME.md); costs the CPU whole during real time\n"
            "  --help         this text\n"
            "\n"
            "Nothing runs until the master sends NMT start and writes 0x2003:02\n"
            "run_periods (> 0; 0xFFFFFFFF = without end). Lockstep mode (default) waits\n"
            "for each command (timeout 0x2003:04); real-time mode sends SYNC at absolute\n"
            "deadlines every Ts_s (0x2001:01), with SCHED_FIFO when permitted.\n",
            (unsigned)OD_PLANT_DEFAULT_NODE_ID);
}

/* Lockstep app poll; leaves co_runtime_run when real-time mode is selected. */
static int64_t lockstep_poll(void *user, co_runtime_t *rt, int64_t now_us)
{
    (void)rt;
    plant_app_t *app = (plant_app_t *)user;
    if (plant_app_realtime_mode(app)) return CO_RUNTIME_EXIT;
    return plant_app_poll(app, now_us);
}

/* ---- real time over SocketCAN: the transport of plant_pacing_loop ---- */

/* Serve frames until until_ns. co_runtime_wait_one() waits in whole milliseconds (poll()), far too
 * coarse for a 55 us period, so wait on the socket with ppoll() (ns timeout) and drain what arrived
 * (each frame with its kernel receive time: a command's arrival is timed as the bus delivered it). */
static void rt_serve_until(void *user, int64_t until_ns)
{
    co_runtime_t *rt = (co_runtime_t *)user;
    for (;;) {
        int64_t rem_ns = until_ns - plant_pacing_now_ns();
        if (rem_ns <= 0 || co_runtime_stop_requested()) break;
        struct pollfd p = {.fd = rt->fd, .events = POLLIN, .revents = 0};
        struct timespec to = {.tv_sec = (time_t)(rem_ns / 1000000000LL), .tv_nsec = (long)(rem_ns % 1000000000LL)};
        int r = ppoll(&p, 1, &to, NULL);
        if (r < 0 && errno != EINTR) break;
        if (r > 0) co_runtime_drain(rt);
        int64_t now_us = plant_pacing_now_ns() / 1000;
        co_node_tick(&rt->node, now_us);
        (void)plant_app_poll(&g_app, now_us); /* arrival bookkeeping only in real-time mode */
        if (!plant_app_realtime_mode(&g_app)) break;
    }
}

/* The deadline: the frames queued by then (a burst is bounded for co_runtime_run's timers; here the tick follows
 * at once: a backlog after a deschedule, 1,024 frames or ~10 ms of a full bus, is caught up in this period, not
 * spread over many; a flood beyond it still leaves the SYNC its turn), then the SYNC. */
static int64_t rt_tick(void *user, int64_t deadline_ns)
{
    co_runtime_t *rt = (co_runtime_t *)user;
    for (int burst = 0; burst < 16 && co_runtime_drain(rt) == CO_RUNTIME_BURST_MAX; ++burst) {
    }
    int64_t now_ns = plant_pacing_now_ns();
    plant_app_realtime_tick(&g_app, now_ns / 1000, now_ns - deadline_ns);
    co_node_tick(&rt->node, now_ns / 1000);
    return now_ns;
}

static int rt_stop(void *user)
{
    (void)user;
    return co_runtime_stop_requested();
}

static void realtime_loop(co_runtime_t *rt)
{
    static int announced;
    const int cpu = g_cpu == -2 ? plant_pacing_default_cpu() : g_cpu;
    const char *line = announced ? NULL : plant_pacing_priority(PLANT_PACING_PRIORITY, cpu);
    const int awake = g_keep_awake && plant_pacing_awake_start(cpu);
    if (line != NULL) {
        printf("plant_node: real-time mode: %s%s\n", line,
               awake ? ", its CPU kept out of halt" : (g_keep_awake ? ", --keep-awake needs a CPU (--cpu N)" : ""));
        fflush(stdout);
        announced = 1;
    }
    rt->rx_stamps = 1;
    const plant_pacing_io_t io = {.user = rt, .serve_until = rt_serve_until, .tick = rt_tick, .stop = rt_stop};
    plant_pacing_loop(&g_app, &io);
    rt->rx_stamps = 0;
    plant_pacing_awake_stop();
}

int main(int argc, char **argv)
{
    const char *iface = "vcan0";
    uint8_t node_id = (uint8_t)OD_PLANT_DEFAULT_NODE_ID;
    int realtime = 0;
    for (int i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            usage(stdout);
            return 0;
        }
    }
    int i = co_runtime_parse_args(argc, argv, &iface, &node_id);
    if (i < 0) return EXIT_USAGE;
    for (; i < argc; ++i) {
        if (strcmp(argv[i], "--realtime") == 0) {
            realtime = 1;
        } else if (strcmp(argv[i], "--keep-awake") == 0) {
            g_keep_awake = 1;
        } else if (strcmp(argv[i], "--cpu") == 0 && i + 1 < argc) {
            char *end = NULL;
            long cpu = strtol(argv[++i], &end, 10);
            if (end == argv[i] || *end != '\0' || cpu < -1 || cpu >= 1024) {
                fprintf(stderr, "plant_node: --cpu '%s': a CPU number 0..1023, or -1 for any\n", argv[i]);
                return EXIT_USAGE;
            }
            g_cpu = (int)cpu;
        } else if (strcmp(argv[i], "--iface") == 0 || strcmp(argv[i], "--node-id") == 0) {
            fprintf(stderr, "plant_node: %s needs a value (%s)\n", argv[i],
                    strcmp(argv[i], "--iface") == 0 ? "a SocketCAN interface name, e.g. vcan0" : "1..127");
            return EXIT_USAGE;
        } else {
            fprintf(stderr,
                    "plant_node: unknown option '%s' (allowed: --iface NAME, --node-id 1..127, --realtime, --cpu N, "
                    "--keep-awake, --help)\n",
                    argv[i]);
            return EXIT_USAGE;
        }
    }

    static const co_runtime_app_t app_poll = {.poll = lockstep_poll};
    plant_app_init(&g_app);
    plant_app_set_fmu_loader(&g_app, plant_fmu_load_text);
    if (co_runtime_open(&g_rt, iface, &od_plant, node_id, plant_app_hooks(), &app_poll, &g_app) != 0) {
        fprintf(stderr, "plant_node: cannot open CAN interface '%s'\n", iface);
        return 1;
    }
    plant_app_bind(&g_app, &g_rt.node);
    if (realtime) OD_PLANT.mfr.x2003_run_control.mode = OD_PLANT_MODE_REALTIME;
    printf("plant_node: node-ID %u on %s, %s mode, Ts = %.1f us\n", (unsigned)node_id, iface,
           realtime ? "real-time" : "lockstep", (double)plant_app_period_ns(&g_app) / 1000.0);
    fflush(stdout);

    int rc = 0;
    while (!co_runtime_stop_requested()) {
        if (plant_app_realtime_mode(&g_app)) {
            realtime_loop(&g_rt);
        } else {
            rc = co_runtime_run(&g_rt);
            if (rc != 0) break;
        }
    }
    co_runtime_close(&g_rt);
    printf("plant_node: stopped after %u SYNCs (missed %u, late %u commands)\n", (unsigned)g_app.syncs,
           (unsigned)OD_PLANT.mfr.x2003_run_control.missed_commands,
           (unsigned)OD_PLANT.mfr.x2003_run_control.late_commands);
    return rc;
}
