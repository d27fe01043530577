/* hil_realtime.c - direct mode in real time: the plant and the drive node apps on threads of their own over
 * the in-process bus, the plant paced by plant_pacing_loop exactly as plant_node paces itself (absolute
 * CLOCK_MONOTONIC deadlines, SCHED_FIFO, mlockall, its CPU); a frame reaches the other node's thread through
 * its inbox, stamped with the time it was sent (its arrival on a bus), and the recorder keeps that time.
 *
 * One lock (recursive, priority inheritance) guards the bus, the injector, the recorder and the nodes; each
 * thread holds it only to process its frames and timers, never while it sleeps or polls.  Time stamps: the
 * bench's time line (us) never goes back and continues across calls: at each call, now = CLOCK_MONOTONIC -
 * base, with base chosen so that it starts where the previous segment ended. */
#define _GNU_SOURCE
#include <errno.h>
#include <pthread.h>
#include <sched.h>
#include <semaphore.h>
#include <string.h>
#include <time.h>

#include "fault_injector.h"
#include "hil_internal.h"
#include "od_plant.h"
#include "plant_pacing.h"

#define INBOX 65536u                               /* frames waiting for a node's thread (a CAN controller's FIFO) */
#define STALL_NS 1000000000LL                      /* wall time without a SYNC (or the hold): the run gives up */
#define DRIVE_WAKE_NS 2000000LL                    /* the drive's thread looks at its timers at least this often */
#define DRIVE_LOCK_SPIN_NS 20000LL                 /* ... polls the lock this long before it waits for it */
#define DRIVE_PRIORITY (PLANT_PACING_PRIORITY - 1) /* the plant's SYNC comes first */

typedef struct {
    co_frame_t f;
    int64_t t_us;
} rt_item_t;

typedef struct {
    rt_item_t q[INBOX];
    uint32_t head, tail; /* tail: written under the lock, read by the drive's poll without it (atomics) */
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
    int64_t progress_ns;      /* the last SYNC (or the start) */
    int64_t next_deadline_ns; /* the plant's next deadline (atomic): the drive polls from half a period before */
    int stop_req;             /* hil_stop (atomic) */
    int drive_done;           /* atomic */
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

/* Process the frames waiting for `side` in order, each at its arrival time, and send what the node answers at
 * the time it answers (lock held). A node killed meanwhile hears nothing more; a frozen one keeps them for its
 * thaw. Returns whether the node had a SYNC among them. */
static int take_frames(uint8_t side)
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
        co_node_process(node, &it.f, it.t_us);
        advance_now(); /* what it sends goes out now, after its work */
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
        take_frames(FI_SIDE_A);
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
    take_frames(FI_SIDE_A); /* what arrived by now, in the same hold of the lock as the SYNC */
    const int64_t now_ns = plant_pacing_now_ns();
    const int64_t now_us = advance_now();
    if (hil_side_live(FI_SIDE_A) && plant_app_realtime_tick(app, now_us, now_ns - deadline_ns) >= 0)
        R.progress_ns = now_ns;
    __atomic_store_n(&R.next_deadline_ns, deadline_ns + plant_app_period_ns(app), __ATOMIC_RELEASE);
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

/* Wait for the drive's frames without the scheduler where it matters (a wake-up costs tens of us on a virtual
 * machine: most of a period): sleep until half a period before the plant's next deadline (not at all while the
 * plant catches up: its deadlines are past), then poll the inbox, then the lock. A controller on a core of its
 * own that is idle half of the period (a thread that polled all the time would be stopped by the kernel's
 * real-time throttling, sched_rt_runtime_us: 50 ms of every second). Returns with the lock held. */
static void drive_wait(void)
{
    const int64_t wake_ns =
        __atomic_load_n(&R.next_deadline_ns, __ATOMIC_ACQUIRE) - plant_app_period_ns(hil_plant_app()) / 2;
    if (plant_pacing_now_ns() < wake_ns) {
        struct timespec ts = {.tv_sec = (time_t)(wake_ns / 1000000000LL), .tv_nsec = (long)(wake_ns % 1000000000LL)};
        (void)clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL);
    }
    const int64_t end = plant_pacing_now_ns() + DRIVE_WAKE_NS;
    rt_inbox_t *b = &R.in[FI_SIDE_B];
    int got = 0;
    while (!got && plant_pacing_now_ns() < end && !__atomic_load_n(&R.drive_done, __ATOMIC_ACQUIRE))
        got = __atomic_load_n(&b->tail, __ATOMIC_ACQUIRE) != b->head;
    const int64_t lock_end = plant_pacing_now_ns() + DRIVE_LOCK_SPIN_NS;
    while (got && plant_pacing_now_ns() < lock_end)
        if (pthread_mutex_trylock(&g_lock) == 0) return;
    hil_rt_lock(); /* a holder of lower priority is lifted by priority inheritance */
}

static void *drive_main(void *arg)
{
    (void)arg;
    (void)plant_pacing_pin(R.drive_cpu); /* first: never on the plant's CPU at FIFO priority */
    struct sched_param sp = {.sched_priority = DRIVE_PRIORITY};
    (void)pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp); /* the plant's line says what is permitted */
    sem_post(&R.drive_ready);
    while (sem_wait(&R.plant_ready) != 0 && errno == EINTR) {
    }
    hil_rt_lock();
    while (!__atomic_load_n(&R.drive_done, __ATOMIC_ACQUIRE)) {
        if (R.in[FI_SIDE_B].head == R.in[FI_SIDE_B].tail) {
            hil_rt_unlock();
            drive_wait();
        }
        advance_now();
        take_frames(FI_SIDE_B);
        hil_timers(FI_SIDE_B);
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
        take_frames(FI_SIDE_B);
        take_frames(FI_SIDE_A);
        if (hil_side_live(FI_SIDE_A)) (void)plant_app_poll(app, hil_now_us());
        hil_deliver();
        if (!any) break;
    }
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
    R.next_deadline_ns = 0;
    R.drive_done = 0;
    for (int s = 0; s < 2; ++s) R.in[s].head = R.in[s].tail = 0;
    R.plant_cpu = plant_pacing_default_cpu(); /* the plant's CPU is not the drive's */
    R.drive_cpu = plant_pacing_other_cpu();
    hil_rt_active = 1;
    hil_set_running(1);
    hil_rt_unlock();

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
    hil_rt_lock();
    drain_both(app);
    hil_rt_active = 0;
    hil_set_running(0);
    __atomic_store_n(&R.stop_req, 0, __ATOMIC_RELEASE); /* a stop asked for is this run's */
    hil_rt_unlock();
    return ok_plant ? (int32_t)(app->syncs - R.syncs_at_start) : -1;
}

/* Ask a real-time run to return at its next deadline (Ctrl-C); also before it started. */
void hil_stop(void) { __atomic_store_n(&R.stop_req, 1, __ATOMIC_RELEASE); }
/* What the plant's thread got of SCHED_FIFO / mlockall / its CPU (one line), after hil_run_realtime. */
const char *hil_realtime_note(void) { return R.note; }
/* Frames a node's receive FIFO could not take (real time; since hil_open). */
uint64_t hil_rt_dropped(void) { return R.in[0].dropped + R.in[1].dropped; }
