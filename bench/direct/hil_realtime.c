/* hil_realtime.c - direct mode in real time: the run (hil_run_realtime) and the host under it. The run readies the
 * nodes' threads (hil_rt_threads.c: the plant paced as plant_node paces itself, the drive answering what arrives,
 * each frame through its inbox), reserves the plant's CPU, keeps it awake, runs the threads and puts everything back.
 * Placement (docs/REALTIME.md, "Where the lateness came from"): the plant, the drive (one priority below, woken by its
 * frames) and a SCHED_IDLE thread that keeps the CPU out of its halt share the plant's CPU; every other thread of the
 * process leaves that CPU for the run. Also the host's floor (hil_probe_floor: what any real-time loop gets here) and
 * the period a run will pace (hil_rt_period_ns). */
#define _GNU_SOURCE
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <sched.h>
#include <string.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include "hil_internal.h"
#include "hil_rt_threads.h"
#include "od_plant.h"
#include "plant_pacing.h"

/* ---- the plant's CPU, reserved for the run ----
 * Every other thread of the process (the caller's Python threads: decoding, writing, the live view; numpy's and
 * the viewer's threads) leaves the plant's CPU for the run and comes back after: on a kernel without PREEMPT_RT
 * a thread inside a system call or a page fault is not preempted, however high the waking thread's priority,
 * and it delayed the plant's wake-ups by up to hundreds of us (docs/REALTIME.md, "Where the lateness comes
 * from"). Threads started during the run inherit the reduced set from the thread that starts them. */
#define RESERVE_MAX 512
static struct {
    pid_t tid[RESERVE_MAX];
    cpu_set_t was[RESERVE_MAX];
    int n, moved;
} V;

static int reserve_cpu(int cpu)
{
    V.n = V.moved = 0;
    if (cpu < 0) return 0;
    DIR *d = opendir("/proc/self/task");
    if (!d) return 0;
    for (struct dirent *e; (e = readdir(d)) != NULL && V.n < RESERVE_MAX;) {
        pid_t tid = (pid_t)atoi(e->d_name);
        if (tid <= 0) continue;
        cpu_set_t set;
        if (sched_getaffinity(tid, sizeof set, &set) != 0 || !CPU_ISSET(cpu, &set) || CPU_COUNT(&set) < 2) continue;
        V.tid[V.n] = tid;
        V.was[V.n] = set;
        CPU_CLR(cpu, &set);
        if (sched_setaffinity(tid, sizeof set, &set) == 0) ++V.moved;
        ++V.n;
    }
    closedir(d);
    return V.moved;
}

/* Back where they were; a thread started during the run gets the caller's former set. */
static void release_cpu(int cpu)
{
    if (cpu < 0 || V.n == 0) return;
    const pid_t self = (pid_t)syscall(SYS_gettid);
    cpu_set_t mine;
    int have_mine = 0;
    for (int i = 0; i < V.n; ++i) {
        (void)sched_setaffinity(V.tid[i], sizeof V.was[i], &V.was[i]);
        if (V.tid[i] == self) mine = V.was[i], have_mine = 1;
    }
    if (!have_mine) return;
    DIR *d = opendir("/proc/self/task");
    if (!d) return;
    for (struct dirent *e; (e = readdir(d)) != NULL;) {
        pid_t tid = (pid_t)atoi(e->d_name);
        cpu_set_t set;
        if (tid <= 0 || sched_getaffinity(tid, sizeof set, &set) != 0 || CPU_ISSET(cpu, &set)) continue;
        int known = 0;
        for (int i = 0; i < V.n && !known; ++i) known = V.tid[i] == tid;
        if (!known) (void)sched_setaffinity(tid, sizeof mine, &mine);
    }
    closedir(d);
    V.n = 0;
}

/* Run in real time until the plant holds (run_periods exhausted, the last command in), a node is lost, the
 * loop stalls (hil_rt_threads.c: STALL_NS without a SYNC), hil_stop(), or max_periods SYNCs were produced. Returns the
 * SYNCs produced (-1: a thread could not be started). */
int32_t hil_run_realtime(uint32_t max_periods)
{
    plant_app_t *app = hil_plant_app();
    const int cpu = hil_rt_threads_begin(app, max_periods);
    reserve_cpu(cpu);
    (void)plant_pacing_awake_start(cpu); /* the CPU never halts while the plant sleeps */
    const int ok = hil_rt_threads_run(app);
    plant_pacing_awake_stop();
    release_cpu(cpu);
    hil_rt_threads_end(app);
    return ok ? (int32_t)hil_rt_threads_syncs(app) : -1;
}

/* ---- the host's floor: a plain timer loop, as cyclictest's ----
 * n absolute CLOCK_MONOTONIC deadlines period_ns apart, on a thread at the plant's priority and CPU, nothing else
 * done: its wake-up lateness is what the host gives any real-time loop (the bench warns when it makes the period
 * impossible). Fills out_us with p50, p99, p99.9 (upper edges of 1 us bins) and the max; returns the wake-ups
 * timed (-1: no thread). */
#define FLOOR_BINS 4096u
static struct {
    uint32_t period_ns, n, bins[FLOOR_BINS], over;
    int64_t max_ns;
    int cpu;
} F;

static void *floor_main(void *arg)
{
    (void)arg;
    (void)pthread_setname_np(pthread_self(), "hil-floor");
    (void)plant_pacing_pin(F.cpu);
    struct sched_param sp = {.sched_priority = PLANT_PACING_PRIORITY};
    (void)pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    int64_t deadline = plant_pacing_now_ns() + F.period_ns;
    for (uint32_t i = 0; i < F.n; ++i, deadline += F.period_ns) {
        struct timespec ts = {.tv_sec = (time_t)(deadline / 1000000000LL), .tv_nsec = (long)(deadline % 1000000000LL)};
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR) {
        }
        const int64_t late = plant_pacing_now_ns() - deadline;
        const uint64_t bin = late > 0 ? (uint64_t)late / 1000u : 0u;
        if (bin < FLOOR_BINS)
            ++F.bins[bin];
        else
            ++F.over;
        if (late > F.max_ns) F.max_ns = late;
    }
    return NULL;
}

static float floor_quantile(double q)
{
    const double want = q * F.n;
    uint64_t c = 0;
    for (uint32_t b = 0; b < FLOOR_BINS; ++b)
        if ((double)(c += F.bins[b]) >= want) return (float)(b + 1u);
    return (float)((double)F.max_ns * 1e-3);
}

/* The plant's period (ns) as its object dictionary has it now (applied at the next SYNC): what a run will pace. */
uint64_t hil_rt_period_ns(void) { return (uint64_t)llround((double)OD_PLANT.mfr.x2001_Inverter.Ts_s * 1e9); }

int32_t hil_probe_floor(uint32_t period_ns, uint32_t n, float out_us[4])
{
    memset(&F, 0, sizeof F);
    F.period_ns = period_ns ? period_ns : 1u;
    F.n = n;
    F.cpu = plant_pacing_default_cpu();
    pthread_t th;
    if (pthread_create(&th, NULL, floor_main, NULL) != 0) return -1;
    pthread_join(th, NULL);
    out_us[0] = floor_quantile(0.5);
    out_us[1] = floor_quantile(0.99);
    out_us[2] = floor_quantile(0.999);
    out_us[3] = (float)((double)F.max_ns * 1e-3);
    return (int32_t)n;
}
