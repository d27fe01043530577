/* hil_realtime.c - direct mode in real time: the plant and the drive node apps on threads of their own over
 * the in-process bus, the plant paced by plant_pacing_loop exactly as plant_node paces itself (absolute
 * CLOCK_MONOTONIC deadlines, SCHED_FIFO, mlockall, its CPU); a frame reaches the other node's thread through
 * its inbox, stamped with the time it was sent (its arrival on a bus), and the recorder keeps that time.
 * Placement (docs/REALTIME.md, "Where the lateness came from"): the plant, the drive (one priority below, woken
 * by its frames) and a SCHED_IDLE thread that keeps the CPU out of its halt share the plant's CPU; every other
 * thread of the process leaves that CPU for the run.
 *
 * One lock (recursive, priority inheritance) guards the bus, the injector, the recorder and the plant; each
 * thread holds it only to process its frames and timers, never while it sleeps. The drive's work on a frame
 * (its law's step) runs outside it: what the drive sends goes to an outbox of its own and onto the bus when
 * its work is done, so a law slower than the period makes the drive late, never the plant's SYNC (the plant
 * waits for its clock and its frames, nothing else).  Time stamps: the
 * bench's time line (us) never goes back and continues across calls: at each call, now = CLOCK_MONOTONIC -
 * base, with base chosen so that it starts where the previous segment ended. */
#define _GNU_SOURCE
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <sched.h>
#include <semaphore.h>
#include <string.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include "fault_injector.h"
#include "hil_internal.h"
#include "od_plant.h"
#include "plant_pacing.h"

#define INBOX 65536u                               /* frames waiting for a node's thread (a CAN controller's FIFO) */
#define STALL_NS 1000000000LL                      /* wall time without a SYNC (or the hold): the run gives up */
#define DRIVE_WAKE_NS 2000000LL                    /* the drive's thread looks at its timers at least this often */
#define DRIVE_PRIORITY (PLANT_PACING_PRIORITY - 1) /* the plant's SYNC comes first */

typedef struct {
    co_frame_t f;
    int64_t t_us;
} rt_item_t;

typedef struct {
    rt_item_t q[INBOX];
    uint32_t head, tail; /* written under the lock */
    uint64_t dropped;
    pthread_cond_t cv;
} rt_inbox_t;

static pthread_mutex_t g_lock;
static pthread_once_t g_once = PTHREAD_ONCE_INIT;
volatile int hil_rt_active;

#define OUTBOX 256u /* frames the drive sends while it works on one frame (a CAN controller's transmit FIFO) */

static struct {
    rt_inbox_t in[2];
    co_frame_t out[OUTBOX]; /* the drive's frames during its work, written by its thread alone */
    uint32_t out_n;
    uint64_t out_dropped;
    co_tx_t drive_tx; /* the drive node's own transmit path, restored after the run */
    int64_t base_ns;
    uint32_t syncs_at_start, max_periods;
    int64_t progress_ns; /* the last SYNC (or the start) */
    int stop_req;        /* hil_stop (atomic) */
    int drive_done;      /* atomic */
    sem_t plant_ready, drive_ready;
    int plant_cpu, drive_cpu;
    char note[512];
} R;

static void init_once(void)
{
    pthread_mutexattr_t ma;
    pthread_mutexattr_init(&ma);
    pthread_mutexattr_settype(&ma, PTHREAD_MUTEX_RECURSIVE);
    pthread_mutexattr_setprotocol(&ma, PTHREAD_PRIO_INHERIT);
    pthread_mutex_init(&g_lock, &ma);
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    for (int s = 0; s < 2; ++s) pthread_cond_init(&R.in[s].cv, &ca);
    sem_init(&R.plant_ready, 0, 0);
    sem_init(&R.drive_ready, 0, 0);
}

void hil_rt_lock(void)
{
    pthread_once(&g_once, init_once);
    pthread_mutex_lock(&g_lock);
}
void hil_rt_unlock(void) { pthread_mutex_unlock(&g_lock); }

void hil_rt_reset(void)
{
    hil_rt_lock();
    __atomic_store_n(&R.stop_req, 0, __ATOMIC_RELEASE);
    for (int s = 0; s < 2; ++s) R.in[s].head = R.in[s].tail = 0, R.in[s].dropped = 0;
    R.out_dropped = 0;
    hil_rt_unlock();
}

/* The bench's time now, never before a time already given (lock held). */
static int64_t advance_now(void)
{
    int64_t t = (plant_pacing_now_ns() - R.base_ns) / 1000;
    if (t > hil_now_us()) hil_set_now_us(t);
    return hil_now_us();
}

void hil_rt_push(uint8_t side, const co_frame_t *f, int64_t t_us)
{
    rt_inbox_t *b = &R.in[side];
    if (b->tail - b->head >= INBOX) { /* the node's receive FIFO overflowed: the frame is lost to it */
        ++b->dropped;
        return;
    }
    b->q[b->tail % INBOX] = (rt_item_t){.f = *f, .t_us = t_us};
    __atomic_store_n(&b->tail, b->tail + 1u, __ATOMIC_RELEASE);
    pthread_cond_signal(&b->cv);
}

/* ---- the drive's outbox: its transmit path for the run ---- */

static int drive_outbox_tx(void *user, const co_frame_t *f)
{
    (void)user;
    if (R.out_n >= OUTBOX) {
        ++R.out_dropped;
        return -1; /* the node counts it as a transmit error */
    }
    R.out[R.out_n++] = *f;
    return 0;
}

/* What the drive sent, onto the bus now, in order (lock held). */
static void drive_flush(void)
{
    advance_now();
    for (uint32_t i = 0; i < R.out_n; ++i) (void)R.drive_tx.fn(R.drive_tx.user, &R.out[i]);
    R.out_n = 0;
    hil_deliver();
}

/* Process the frames waiting for `side` in order, each at its arrival time, and send what the node answers at
 * the time it answers (lock held on entry and on return). A node killed meanwhile hears nothing more; a frozen
 * one keeps them for its thaw. `unlocked` (the drive's thread in the run): each frame is processed with the lock
 * released, so that the plant's thread never waits for the drive's law; what it sent waits in its outbox
 * (drive_flush). Returns whether the node had a SYNC among them. */
static int take_frames(uint8_t side, int unlocked)
{
    rt_inbox_t *b = &R.in[side];
    co_node_t *node = hil_node_of(side);
    const uint32_t syncs = node->syncs;
    while (b->head != b->tail) {
        rt_item_t it = b->q[b->head++ % INBOX];
        if (hil_side_killed(side)) continue;
        if (!hil_side_live(side)) {
            hil_frozen_frame(&it.f);
            continue;
        }
        if (unlocked) hil_rt_unlock();
        co_node_process(node, &it.f, it.t_us);
        if (unlocked) {
            hil_rt_lock();
            drive_flush(); /* what it answers goes out now, after its work */
        } else {
            advance_now(); /* what it sends goes out now, after its work */
            hil_deliver();
        }
    }
    return node->syncs != syncs;
}

static void wait_frames(uint8_t side, int64_t until_ns)
{
    if (R.in[side].head != R.in[side].tail) return;
    struct timespec ts = {.tv_sec = (time_t)(until_ns / 1000000000LL), .tv_nsec = (long)(until_ns % 1000000000LL)};
    (void)pthread_cond_timedwait(&R.in[side].cv, &g_lock, &ts);
}

static int stop_requested(void) { return __atomic_load_n(&R.stop_req, __ATOMIC_ACQUIRE); }

/* ---- the plant's thread: the transport of plant_pacing_loop ---- */

static void plant_serve_until(void *user, int64_t until_ns)
{
    plant_app_t *app = (plant_app_t *)user;
    hil_rt_lock();
    while (!stop_requested()) {
        if (plant_pacing_now_ns() >= until_ns) break;
        wait_frames(FI_SIDE_A, until_ns);
        advance_now();
        take_frames(FI_SIDE_A, 0);
        hil_timers(FI_SIDE_A);
        hil_fi_tick();
        if (hil_side_live(FI_SIDE_A)) (void)plant_app_poll(app, hil_now_us()); /* arrivals; the hold */
        hil_deliver();
        if (!plant_app_realtime_mode(app) || !plant_app_running(app)) break;
    }
    hil_rt_unlock();
}

static int64_t plant_tick(void *user, int64_t deadline_ns)
{
    plant_app_t *app = (plant_app_t *)user;
    hil_rt_lock();
    take_frames(FI_SIDE_A, 0); /* what arrived by now, in the same hold of the lock as the SYNC */
    const int64_t now_ns = plant_pacing_now_ns();
    const int64_t now_us = advance_now();
    if (hil_side_live(FI_SIDE_A) && plant_app_realtime_tick(app, now_us, now_ns - deadline_ns) >= 0)
        R.progress_ns = now_ns;
    hil_timers(FI_SIDE_A);
    hil_fi_tick();
    hil_rt_unlock();
    return now_ns;
}

static int plant_stop(void *user)
{
    plant_app_t *app = (plant_app_t *)user;
    if (stop_requested()) return 1;
    hil_rt_lock();
    int stop = hil_nodes_down() != 0u || app->syncs - R.syncs_at_start >= R.max_periods ||
               (!plant_app_running(app) && OD_PLANT.mfr.x2003_run_control.state == 0u) ||
               plant_pacing_now_ns() - R.progress_ns > STALL_NS;
    hil_rt_unlock();
    return stop;
}

static void *plant_main(void *arg)
{
    plant_app_t *app = (plant_app_t *)arg;
    (void)pthread_setname_np(pthread_self(), "hil-plant"); /* named in top, perf sched and ftrace */
    strncpy(R.note, plant_pacing_priority(PLANT_PACING_PRIORITY, R.plant_cpu), sizeof R.note - 1u);
    sem_post(&R.plant_ready);
    while (sem_wait(&R.drive_ready) != 0 && errno == EINTR) { /* the drive listens before the first SYNC */
    }
    hil_rt_lock();
    R.progress_ns = plant_pacing_now_ns();
    hil_rt_unlock();
    const plant_pacing_io_t io = {
        .user = app, .serve_until = plant_serve_until, .tick = plant_tick, .stop = plant_stop};
    plant_pacing_loop(app, &io);
    return NULL;
}

/* ---- the drive's thread: it answers what arrives, as drive_node does on its socket ---- */

/* The drive's thread sleeps until a frame comes (the plant's SYNC and measurements wake it, as a CAN controller's
 * receive interrupt wakes a drive's firmware) or its next timer is due; it shares the plant's CPU one priority
 * below the plant, so it runs while the plant sleeps, and no other CPU spins for it (docs/REALTIME.md). */
static void drive_wait(void) { wait_frames(FI_SIDE_B, plant_pacing_now_ns() + DRIVE_WAKE_NS); }

static void *drive_main(void *arg)
{
    (void)arg;
    (void)pthread_setname_np(pthread_self(), "hil-drive");
    (void)plant_pacing_pin(R.drive_cpu); /* the plant's CPU, below the plant */
    struct sched_param sp = {.sched_priority = DRIVE_PRIORITY};
    (void)pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp); /* the plant's line says what is permitted */
    sem_post(&R.drive_ready);
    while (sem_wait(&R.plant_ready) != 0 && errno == EINTR) {
    }
    hil_rt_lock();
    while (!__atomic_load_n(&R.drive_done, __ATOMIC_ACQUIRE)) {
        if (R.in[FI_SIDE_B].head == R.in[FI_SIDE_B].tail) drive_wait();
        advance_now();
        take_frames(FI_SIDE_B, 1);
        hil_timers(FI_SIDE_B); /* heartbeats, EMCYs: into the outbox, then onto the bus */
        drive_flush();
        hil_fi_tick();
    }
    hil_rt_unlock();
    return NULL;
}

/* After the threads: what is still queued, in order (the drive's answers to the last SYNCs, the plant's taking
 * of them, its hold), until both inboxes are empty (lock held). */
static void drain_both(plant_app_t *app)
{
    for (int round = 0; round < 64; ++round) {
        advance_now();
        int any = R.in[FI_SIDE_A].head != R.in[FI_SIDE_A].tail || R.in[FI_SIDE_B].head != R.in[FI_SIDE_B].tail;
        take_frames(FI_SIDE_B, 0);
        take_frames(FI_SIDE_A, 0);
        if (hil_side_live(FI_SIDE_A)) (void)plant_app_poll(app, hil_now_us());
        hil_deliver();
        if (!any) break;
    }
}

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
 * loop stalls (STALL_NS without a SYNC), hil_stop(), or max_periods SYNCs were produced. Returns the SYNCs
 * produced (-1: a thread could not be started). */
int32_t hil_run_realtime(uint32_t max_periods)
{
    plant_app_t *app = hil_plant_app();
    hil_rt_lock();
    R.base_ns = plant_pacing_now_ns() - hil_now_us() * 1000;
    R.syncs_at_start = app->syncs;
    R.max_periods = max_periods;
    R.progress_ns = plant_pacing_now_ns();
    R.drive_done = 0;
    for (int s = 0; s < 2; ++s) R.in[s].head = R.in[s].tail = 0;
    co_node_t *drive_node = hil_node_of(FI_SIDE_B);
    R.drive_tx = drive_node->tx;
    R.out_n = 0;
    drive_node->tx.fn = drive_outbox_tx; /* the drive's frames wait for the end of its work (drive_flush) */
    drive_node->tx.user = NULL;
    R.plant_cpu = plant_pacing_default_cpu(); /* the plant, the drive and the awake thread share it */
    R.drive_cpu = R.plant_cpu;
    hil_rt_active = 1;
    hil_set_running(1);
    hil_rt_unlock();

    reserve_cpu(R.plant_cpu);
    (void)plant_pacing_awake_start(R.plant_cpu); /* the CPU never halts while the plant sleeps */
    pthread_t plant, drive;
    int ok_drive = pthread_create(&drive, NULL, drive_main, NULL) == 0;
    int ok_plant = ok_drive && pthread_create(&plant, NULL, plant_main, app) == 0;
    if (ok_plant) {
        pthread_join(plant, NULL);
    } else if (ok_drive) {
        sem_post(&R.plant_ready); /* release the drive's thread */
    }
    __atomic_store_n(&R.drive_done, 1, __ATOMIC_RELEASE);
    if (ok_drive) pthread_join(drive, NULL);
    while (sem_trywait(&R.plant_ready) == 0 || sem_trywait(&R.drive_ready) == 0) { /* leave both at zero */
    }
    plant_pacing_awake_stop();
    release_cpu(R.plant_cpu);
    hil_rt_lock();
    drive_node->tx.fn = R.drive_tx.fn; /* its own transmit path back (its counters kept) */
    drive_node->tx.user = R.drive_tx.user;
    drain_both(app);
    hil_rt_active = 0;
    hil_set_running(0);
    __atomic_store_n(&R.stop_req, 0, __ATOMIC_RELEASE); /* a stop asked for is this run's */
    hil_rt_unlock();
    return ok_plant ? (int32_t)(app->syncs - R.syncs_at_start) : -1;
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

/* Ask a real-time run to return at its next deadline (Ctrl-C); also before it started. */
void hil_stop(void) { __atomic_store_n(&R.stop_req, 1, __ATOMIC_RELEASE); }
/* What the plant's thread got of SCHED_FIFO / mlockall / its CPU (one line), after hil_run_realtime. */
const char *hil_realtime_note(void) { return R.note; }
/* Frames a node's receive FIFO could not take (real time; since hil_open). */
uint64_t hil_rt_dropped(void) { return R.in[0].dropped + R.in[1].dropped + R.out_dropped; }
