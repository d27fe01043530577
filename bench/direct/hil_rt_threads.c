/* hil_rt_threads.c - the nodes' threads of a real-time run in direct mode (see hil_rt_threads.h): the plant paced by
 * plant_pacing_loop exactly as plant_node paces itself, the drive answering what arrives; a frame reaches the other
 * node's thread through its inbox (the run's delivery sink: hil_direct.c knows nothing else of real time), stamped
 * with the time it was sent (its arrival on a bus), and the recorder keeps that time. One lock (hil_lock) guards the
 * bus, the injector, the recorder and the plant; each thread holds it only to process its frames and timers, never
 * while it sleeps. The drive's work on a frame (its law's step) runs outside it: what the drive sends goes to an
 * outbox of its own and onto the bus when its work is done, so a law slower than the period makes the drive late,
 * never the plant's SYNC (the plant waits for its clock and its frames, nothing else).  Time stamps: the bench's time
 * line (us) never goes back and continues across calls: at each call, now = CLOCK_MONOTONIC - base, with base chosen
 * so that it starts where the previous segment ended. */
#define _GNU_SOURCE
#include "hil_rt_threads.h"

#include <errno.h>
#include <pthread.h>
#include <sched.h>
#include <semaphore.h>
#include <string.h>
#include <time.h>

#include "fault_injector.h"
#include "hil_internal.h"
#include "hil_lock.h"
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

static pthread_once_t g_once = PTHREAD_ONCE_INIT;

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
    uint32_t stop_req;   /* hil_stop (atomic): the opening (hil_opens) it was asked in, 0 none */
    uint32_t opened;     /* the opening the drop counters belong to */
    int drive_done;      /* atomic */
    sem_t plant_ready, drive_ready;
    int plant_cpu, drive_cpu;
    char note[512];
} R;

static void init_once(void)
{
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    for (int s = 0; s < 2; ++s) pthread_cond_init(&R.in[s].cv, &ca);
    sem_init(&R.plant_ready, 0, 0);
    sem_init(&R.drive_ready, 0, 0);
}

/* A stop asked for and the drop counters belong to one opening of direct mode (hil_open): a new one forgets them
 * (lock held). */
static void follow_open(void)
{
    if (R.opened == hil_opens()) return;
    R.opened = hil_opens();
    for (int s = 0; s < 2; ++s) R.in[s].dropped = 0;
    R.out_dropped = 0;
}

/* The bench's time now, never before a time already given (lock held). */
static int64_t advance_now(void)
{
    int64_t t = (plant_pacing_now_ns() - R.base_ns) / 1000;
    if (t > hil_now_us()) hil_set_now_us(t);
    return hil_now_us();
}

/* The run's delivery sink (hil_sink_t): a frame for a node goes to its thread's inbox. */
static void rt_push(void *user, uint8_t side, const co_frame_t *f, int64_t t_us)
{
    (void)user;
    rt_inbox_t *b = &R.in[side];
    if (b->tail - b->head >= INBOX) { /* the node's receive FIFO overflowed: the frame is lost to it */
        ++b->dropped;
        return;
    }
    b->q[b->tail % INBOX] = (rt_item_t){.f = *f, .t_us = t_us};
    __atomic_store_n(&b->tail, b->tail + 1u, __ATOMIC_RELEASE);
    pthread_cond_signal(&b->cv);
}

/* The drive works on its own thread alone (outside the lock): a thawed drive's backlog goes there too. */
static const hil_sink_t k_sink = {.push = rt_push, .user = NULL, .own_thread = 1u << FI_SIDE_B};

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
        if (unlocked) hil_unlock();
        co_node_process(node, &it.f, it.t_us);
        if (unlocked) {
            hil_lock();
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
    hil_wait(&R.in[side].cv, &ts);
}

static int stop_requested(void)
{
    const uint32_t asked = __atomic_load_n(&R.stop_req, __ATOMIC_ACQUIRE);
    return asked != 0u && asked == hil_opens();
}

/* ---- the plant's thread: the transport of plant_pacing_loop ---- */

static void plant_serve_until(void *user, int64_t until_ns)
{
    plant_app_t *app = (plant_app_t *)user;
    hil_lock();
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
    hil_unlock();
}

static int64_t plant_tick(void *user, int64_t deadline_ns)
{
    plant_app_t *app = (plant_app_t *)user;
    hil_lock();
    take_frames(FI_SIDE_A, 0); /* what arrived by now, in the same hold of the lock as the SYNC */
    const int64_t now_ns = plant_pacing_now_ns();
    const int64_t now_us = advance_now();
    if (hil_side_live(FI_SIDE_A) && plant_app_realtime_tick(app, now_us, now_ns - deadline_ns) >= 0)
        R.progress_ns = now_ns;
    hil_timers(FI_SIDE_A);
    hil_fi_tick();
    hil_unlock();
    return now_ns;
}

static int plant_stop(void *user)
{
    plant_app_t *app = (plant_app_t *)user;
    if (stop_requested()) return 1;
    hil_lock();
    int stop = hil_nodes_down() != 0u || app->syncs - R.syncs_at_start >= R.max_periods ||
               (!plant_app_running(app) && OD_PLANT.mfr.x2003_run_control.state == 0u) ||
               plant_pacing_now_ns() - R.progress_ns > STALL_NS;
    hil_unlock();
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
    hil_lock();
    R.progress_ns = plant_pacing_now_ns();
    hil_unlock();
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
    hil_lock();
    while (!__atomic_load_n(&R.drive_done, __ATOMIC_ACQUIRE)) {
        if (R.in[FI_SIDE_B].head == R.in[FI_SIDE_B].tail) drive_wait();
        advance_now();
        take_frames(FI_SIDE_B, 1);
        hil_timers(FI_SIDE_B); /* heartbeats, EMCYs: into the outbox, then onto the bus */
        drive_flush();
        hil_fi_tick();
    }
    hil_unlock();
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

/* ---- the run ---- */

int hil_rt_threads_begin(plant_app_t *app, uint32_t max_periods)
{
    pthread_once(&g_once, init_once);
    hil_lock();
    follow_open();
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
    hil_set_sink(&k_sink); /* the nodes' frames to their threads */
    hil_set_running(1);
    hil_unlock();
    return R.plant_cpu;
}

int hil_rt_threads_run(plant_app_t *app)
{
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
    return ok_plant;
}

void hil_rt_threads_end(plant_app_t *app)
{
    hil_lock();
    co_node_t *drive_node = hil_node_of(FI_SIDE_B);
    drive_node->tx.fn = R.drive_tx.fn; /* its own transmit path back (its counters kept) */
    drive_node->tx.user = R.drive_tx.user;
    drain_both(app);
    hil_set_sink(NULL); /* lockstep again */
    hil_set_running(0);
    __atomic_store_n(&R.stop_req, 0u, __ATOMIC_RELEASE); /* a stop asked for is this run's */
    hil_unlock();
}

uint32_t hil_rt_threads_syncs(const plant_app_t *app) { return app->syncs - R.syncs_at_start; }

/* ---- libhil.so's API (ctypes) on the threads' state ---- */

void hil_stop(void) { __atomic_store_n(&R.stop_req, hil_opens(), __ATOMIC_RELEASE); }
const char *hil_realtime_note(void) { return R.note; }
uint64_t hil_rt_dropped(void)
{
    return R.opened == hil_opens() ? R.in[0].dropped + R.in[1].dropped + R.out_dropped : 0u;
}
