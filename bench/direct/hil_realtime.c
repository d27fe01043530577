/* hil_realtime.c - direct mode in real time: the plant and the drive node apps on threads of their own over
 * the in-process bus, the plant paced by plant_pacing_loop exactly as plant_node paces itself (absolute
 * CLOCK_MONOTONIC deadlines, SCHED_FIFO, mlockall); a frame reaches the other node's thread through its inbox,
 * stamped with the time it was sent (its arrival on a bus), and the recorder keeps that time.
 *
 * One lock (priority inheritance) guards the bus, the injector, the recorder and the nodes; each thread holds
 * it only to process its frames and timers, never while it sleeps.  Time stamps: the bench's time line (us)
 * continues across calls: at each call, now = (CLOCK_MONOTONIC - base) with base chosen so that it starts at
 * the time the previous segment ended. */
#define _GNU_SOURCE
#include <errno.h>
#include <pthread.h>
#include <sched.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "fault_injector.h"
#include "hil_internal.h"
#include "od_plant.h"
#include "plant_pacing.h"

#define INBOX 8192u             /* frames waiting for a node's thread */
#define STALL_NS 1000000000LL   /* wall time without a SYNC (or the hold) after which the run gives up */
#define DRIVE_WAKE_NS 2000000LL /* the drive's thread looks at its timers at least this often */
#define DRIVE_PRIORITY (PLANT_PACING_PRIORITY - 1) /* the plant's SYNC comes first */

typedef struct {
    co_frame_t f;
    int64_t t_us;
} rt_item_t;

typedef struct {
    rt_item_t q[INBOX];
    uint32_t head, tail;
    uint64_t dropped;
    pthread_cond_t cv;
} rt_inbox_t;

static pthread_mutex_t g_lock;
static pthread_once_t g_once = PTHREAD_ONCE_INIT;
volatile int hil_rt_active;

static struct {
    rt_inbox_t in[2];
    int64_t base_ns;
    uint32_t syncs_at_start, max_periods;
    int64_t progress_ns; /* the last SYNC (or the start) */
    volatile int stop_req;
    int drive_done;
    int drive_ready; /* the drive's thread is waiting for frames: the first SYNC may go */
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
}

void hil_rt_lock(void)
{
    pthread_once(&g_once, init_once);
    pthread_mutex_lock(&g_lock);
}
void hil_rt_unlock(void) { pthread_mutex_unlock(&g_lock); }

static int64_t now_us_of(int64_t mono_ns) { return (mono_ns - R.base_ns) / 1000; }

void hil_rt_push(uint8_t side, const co_frame_t *f, int64_t t_us)
{
    rt_inbox_t *b = &R.in[side];
    if (b->tail - b->head >= INBOX) {
        ++b->dropped;
        return;
    }
    b->q[b->tail % INBOX] = (rt_item_t){.f = *f, .t_us = t_us};
    __atomic_store_n(&b->tail, b->tail + 1u, __ATOMIC_RELEASE);
    pthread_cond_signal(&b->cv);
}

/* Process the frames waiting for `side`, each at its arrival time (lock held); returns whether the node had
 * a SYNC among them. */
static int take_frames(uint8_t side)
{
    rt_inbox_t *b = &R.in[side];
    co_node_t *node = hil_node_of(side);
    const uint32_t syncs = node->syncs;
    while (b->head != b->tail) {
        rt_item_t it = b->q[b->head++ % INBOX];
        co_node_process(node, &it.f, it.t_us);
        hil_deliver();
    }
    return node->syncs != syncs;
}

static void wait_frames(uint8_t side, int64_t until_ns)
{
    if (R.in[side].head != R.in[side].tail) return;
    struct timespec ts = {.tv_sec = (time_t)(until_ns / 1000000000LL), .tv_nsec = (long)(until_ns % 1000000000LL)};
    (void)pthread_cond_timedwait(&R.in[side].cv, &g_lock, &ts);
}

/* ---- the plant's thread: the transport of plant_pacing_loop ---- */

static void plant_serve_until(void *user, int64_t until_ns)
{
    plant_app_t *app = (plant_app_t *)user;
    hil_rt_lock();
    while (!R.stop_req) {
        int64_t now_ns = plant_pacing_now_ns();
        if (now_ns >= until_ns) break;
        wait_frames(FI_SIDE_A, until_ns);
        int64_t now_us = now_us_of(plant_pacing_now_ns());
        hil_set_now_us(now_us);
        take_frames(FI_SIDE_A);
        hil_timers(FI_SIDE_A);
        hil_fi_tick();
        (void)plant_app_poll(app, now_us); /* arrivals; the hold's announcement */
        hil_deliver();
        if (!plant_app_realtime_mode(app) || !plant_app_running(app)) break;
    }
    hil_rt_unlock();
}

static void plant_drain(void *user)
{
    (void)user;
    hil_rt_lock();
    hil_set_now_us(now_us_of(plant_pacing_now_ns()));
    take_frames(FI_SIDE_A);
    hil_rt_unlock();
}

static void plant_tick(void *user, int64_t now_ns, int64_t lateness_ns)
{
    plant_app_t *app = (plant_app_t *)user;
    hil_rt_lock();
    int64_t now_us = now_us_of(now_ns);
    hil_set_now_us(now_us);
    if (hil_side_live(FI_SIDE_A) && plant_app_realtime_tick(app, now_us, lateness_ns) >= 0) R.progress_ns = now_ns;
    hil_timers(FI_SIDE_A);
    hil_fi_tick();
    hil_rt_unlock();
}

static int plant_stop(void *user)
{
    plant_app_t *app = (plant_app_t *)user;
    if (R.stop_req) return 1;
    hil_rt_lock();
    int stop = hil_nodes_down() != 0u || app->syncs - R.syncs_at_start > R.max_periods ||
               (!plant_app_running(app) && OD_PLANT.mfr.x2003_run_control.state == 0u) ||
               plant_pacing_now_ns() - R.progress_ns > STALL_NS;
    hil_rt_unlock();
    return stop;
}

static void *plant_main(void *arg)
{
    plant_app_t *app = (plant_app_t *)arg;
    strncpy(R.note, plant_pacing_priority(PLANT_PACING_PRIORITY, R.plant_cpu), sizeof R.note - 1u);
    while (!__atomic_load_n(&R.drive_ready, __ATOMIC_ACQUIRE)) sched_yield(); /* the drive listens first */
    hil_rt_lock();
    R.progress_ns = plant_pacing_now_ns();
    hil_rt_unlock();
    const plant_pacing_io_t io = {
        .user = app, .serve_until = plant_serve_until, .drain = plant_drain, .tick = plant_tick, .stop = plant_stop};
    plant_pacing_loop(app, &io);
    return NULL;
}

/* ---- the drive's thread: it answers what arrives, as drive_node does on its socket ---- */

/* Wait for the drive's frames without the scheduler (a wake-up costs tens of us on a virtual machine: most
 * of a period): after answering a SYNC, sleep until half a period before the next one is due, then poll the
 * inbox, and take the lock by polling it too. A controller on a core of its own, which is idle for half of
 * the period (a thread that polled all the time would be stopped by the kernel's real-time throttling,
 * sched_rt_runtime_us: 50 ms every second). Returns with the lock held. */
static void drive_wait(int64_t answered_ns)
{
    const int64_t period_ns = plant_app_period_ns(hil_plant_app());
    const int64_t wake_ns = answered_ns + period_ns / 2;
    if (answered_ns > 0 && plant_pacing_now_ns() < wake_ns) {
        struct timespec ts = {.tv_sec = (time_t)(wake_ns / 1000000000LL), .tv_nsec = (long)(wake_ns % 1000000000LL)};
        (void)clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL);
    }
    const int64_t end = plant_pacing_now_ns() + DRIVE_WAKE_NS;
    rt_inbox_t *b = &R.in[FI_SIDE_B];
    int got = 0;
    while (!got && plant_pacing_now_ns() < end) {
        if (__atomic_load_n(&b->tail, __ATOMIC_ACQUIRE) != b->head) got = 1;
        if (__atomic_load_n(&R.drive_done, __ATOMIC_ACQUIRE)) break;
    }
    while (got && plant_pacing_now_ns() < end)
        if (pthread_mutex_trylock(&g_lock) == 0) return;
    hil_rt_lock();
}

static void *drive_main(void *arg)
{
    (void)arg;
    struct sched_param sp = {.sched_priority = DRIVE_PRIORITY};
    (void)pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp); /* the plant's line says what is permitted */
    (void)plant_pacing_pin(R.drive_cpu);
    __atomic_store_n(&R.drive_ready, 1, __ATOMIC_RELEASE);
    hil_rt_lock();
    int64_t answered_ns = 0;
    while (!R.drive_done) {
        if (R.in[FI_SIDE_B].head == R.in[FI_SIDE_B].tail) {
            hil_rt_unlock();
            drive_wait(answered_ns);
        }
        int64_t now_ns = plant_pacing_now_ns();
        hil_set_now_us(now_us_of(now_ns));
        answered_ns = take_frames(FI_SIDE_B) ? now_ns : 0;
        hil_timers(FI_SIDE_B);
        hil_fi_tick();
    }
    hil_rt_unlock();
    return NULL;
}

/* Run in real time until the plant holds (run_periods exhausted, the last command in), a node is lost, the
 * loop stalls (STALL_NS without a SYNC) or hil_stop(); at most max_periods SYNCs. Returns the SYNCs produced
 * (-1: a thread could not be started). */
int32_t hil_run_realtime(uint32_t max_periods)
{
    plant_app_t *app = hil_plant_app();
    hil_rt_lock();
    R.base_ns = plant_pacing_now_ns() - hil_now_us() * 1000;
    R.syncs_at_start = app->syncs;
    R.max_periods = max_periods;
    R.progress_ns = plant_pacing_now_ns();
    R.stop_req = 0;
    R.drive_done = 0;
    R.drive_ready = 0;
    long ncpu = sysconf(_SC_NPROCESSORS_ONLN);
    R.plant_cpu = plant_pacing_default_cpu();
    R.drive_cpu = R.plant_cpu >= 0 ? (int)ncpu - 1 : -1; /* the plant's CPU is not the drive's */
    for (int s = 0; s < 2; ++s) R.in[s].head = R.in[s].tail = 0;
    hil_rt_active = 1;
    hil_set_running(1);
    hil_rt_unlock();

    pthread_t plant, drive;
    int ok_drive = pthread_create(&drive, NULL, drive_main, NULL) == 0;
    int ok_plant = ok_drive && pthread_create(&plant, NULL, plant_main, app) == 0;
    if (ok_plant) pthread_join(plant, NULL);
    hil_rt_lock();
    __atomic_store_n(&R.drive_done, 1, __ATOMIC_RELEASE);
    pthread_cond_signal(&R.in[FI_SIDE_B].cv);
    hil_rt_unlock();
    if (ok_drive) pthread_join(drive, NULL);
    hil_rt_lock();
    hil_rt_active = 0;
    hil_set_running(0);
    /* what is still queued for a node is heard as in lockstep (at once) */
    for (uint8_t s = 0; s < 2u; ++s) take_frames(s);
    hil_rt_unlock();
    return ok_plant ? (int32_t)(app->syncs - R.syncs_at_start) : -1;
}

void hil_stop(void) { R.stop_req = 1; }
/* What the plant's thread got of SCHED_FIFO / mlockall (one line), after hil_run_realtime. */
const char *hil_realtime_note(void) { return R.note; }
/* Frames a node's inbox could not take (real time). */
uint64_t hil_rt_dropped(void) { return R.in[0].dropped + R.in[1].dropped; }
