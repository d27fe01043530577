/* hil_direct.c - the bench's direct mode: the plant and drive node apps on an
 * in-process co_membus (no kernel, no sockets), driven from Python by ctypes.
 *
 * Same code as the node processes (plant_app.c, drive_app.c, the CANopen slave),
 * same frames in the same order: a lockstep run over vcan and a direct run of the
 * same scenario decode to identical traces. Simulated time advances by Ts per SYNC.
 *
 * This file owns the bus and what is on it: the nodes, the fault injector between them (frozen and killed
 * nodes), the master's frames onto the bus (hil_send, hil_sdo), the nodes' timers, simulated time and the
 * lockstep loop (hil_run, hil_linger). Below it: what the master sees of the bus, the recorder and the master's
 * receive queue (hil_master.c: hil_recv, hil_take), and the lock (hil_lock.c).
 *
 * The Python side talks to the nodes as a CANopen master through hil_send/hil_recv
 * (bench/run/bus/direct.py wraps them as a python-can bus, so `canopen` works unchanged).
 *
 * Real time (hil_realtime.c) runs the same nodes on threads of its own: for the run it installs a delivery sink
 * (hil_set_sink) that takes the nodes' frames for their threads; this file knows nothing else of it.
 */
#include <stdint.h>
#include <string.h>

#include "co_membus.h"
#include "co_node.h"
#include "drive_app.h"
#include "fault_injector.h"
#include "fault_rules.h"
#include "od_drive.h"
#include "od_plant.h"
#include "plant_app.h"
#include "plant_fmu.h"

#include "hil_internal.h"
#include "hil_lock.h"
#include "hil_master.h"

#define FROZEN_Q 4096u    /* frames waiting for a frozen node (a socket buffer's worth) */
#define STALL_US 10000000 /* simulated time without a SYNC after which hil_run gives up */
#define TICK_MAX_US 10000 /* node timers are looked at least this often (simulated) */
#define SIDE_OF(port) ((port) == H.drive_port ? FI_SIDE_B : FI_SIDE_A)

/* The two sides of the fault injector (fault_injector.h): side A = the plant, the master and the
 * recorder; side B = the drive. Without fault rules every frame passes at once, in order: the
 * frames and their order are those of one bus. */
static struct {
    co_membus_t bus;
    co_node_t plant_node, drive_node;
    plant_app_t plant;
    drive_app_t drive;
    int plant_port, drive_port;
    int64_t now_us;
    int running;
    fi_t fi;
    uint8_t cur_side;        /* side of the frame being passed through the injector */
    uint8_t frozen[2];       /* per side: the node neither runs nor hears (frames queue) */
    uint8_t killed[2];       /* per side: the node is gone */
    co_frame_t fz[FROZEN_Q]; /* frames for the frozen node */
    uint32_t fz_n;
    uint64_t fz_dropped;
    int64_t next_tick_us[2]; /* when the nodes' timers next need a look */
    const hil_sink_t *sink;  /* NULL: lockstep (the frames processed at once) */
} H;

static uint32_t g_opens; /* hil_open's count (atomic) */

uint32_t hil_opens(void) { return __atomic_load_n(&g_opens, __ATOMIC_ACQUIRE); }

void hil_set_sink(const hil_sink_t *sink)
{
    hil_lock();
    H.sink = sink;
    hil_unlock();
}

static co_node_t *node_of(uint8_t side) { return side == FI_SIDE_B ? &H.drive_node : &H.plant_node; }

/* A frame for the frozen node: it waits for the thaw (a socket buffer's worth). */
static void freeze(const co_frame_t *f)
{
    if (H.fz_n < FROZEN_Q)
        H.fz[H.fz_n++] = *f;
    else
        ++H.fz_dropped;
}

static void hear(uint8_t side, const co_frame_t *f)
{
    if (H.killed[side]) return;
    if (H.frozen[side]) {
        freeze(f);
        return;
    }
    if (H.sink) {
        H.sink->push(H.sink->user, side, f, H.now_us); /* real time: the node's own thread takes it */
        return;
    }
    co_node_process(node_of(side), f, H.now_us);
}

/* The injector's output: a frame arrives on side `to`. */
static void emit(void *user, const co_frame_t *f, uint8_t to, uint8_t from)
{
    (void)user;
    if (to == FI_SIDE_A) {
        /* from the drive (also when released late), or made by the injector (an NMT reset) */
        hil_master_record(f, from == FI_SIDE_B ? (uint8_t)H.drive_port : CO_MEMBUS_EXTERNAL, H.now_us, H.running);
        hear(FI_SIDE_A, f);
    } else {
        hear(FI_SIDE_B, f);
    }
}

static void node_fault(void *user, uint8_t side, uint8_t kind, int on)
{
    (void)user;
    if (kind == FI_KILL) {
        H.killed[side] = 1u;
        return;
    }
    H.frozen[side] = (uint8_t)on;
    if (!on) { /* thawed: what it was sent meanwhile, in order, before anything new (in real time a node that
                * works on its own thread alone, the drive, takes them there) */
        const hil_sink_t *to = H.sink && (H.sink->own_thread >> side & 1u) ? H.sink : NULL;
        for (uint32_t i = 0; i < H.fz_n && !H.killed[side]; ++i) {
            if (to)
                to->push(to->user, side, &H.fz[i], H.now_us);
            else
                co_node_process(node_of(side), &H.fz[i], H.now_us);
        }
        H.fz_n = 0;
        H.next_tick_us[side] = H.now_us;
    }
}

/* One frame straight to the other side, where the injector has no rule and no sink is installed: what fi_frame,
 * emit and hear do with it then (recorded, heard, in the same order), without copying it or calling back. No rule
 * means no node is ever frozen or killed. */
static void pass(const co_frame_t *f, uint8_t sender)
{
    if (sender == H.drive_port) {
        fi_pass(&H.fi, f, FI_SIDE_B);
        hil_master_record(f, sender, H.now_us, H.running);
        co_node_process(&H.plant_node, f, H.now_us);
        return;
    }
    hil_master_record(f, sender, H.now_us, H.running);
    if (sender == CO_MEMBUS_EXTERNAL) co_node_process(&H.plant_node, f, H.now_us); /* the master's frame */
    fi_pass(&H.fi, f, FI_SIDE_A);
    co_node_process(&H.drive_node, f, H.now_us);
}

/* Every frame queued on the in-process bus, through the injector to the other side. */
static void deliver(void)
{
    co_membus_t *b = &H.bus;
    if (fi_passes_all(&H.fi) && H.sink == NULL) {
        while (b->head != b->tail) { /* in its slot: the slot is taken back once the frame was heard */
            const uint32_t slot = b->head % CO_MEMBUS_QUEUE;
            ++b->frames;
            pass(&b->queue[slot], b->sender[slot]);
            ++b->head;
        }
        return;
    }
    while (b->head != b->tail) {
        uint32_t slot = b->head % CO_MEMBUS_QUEUE;
        co_frame_t f = b->queue[slot];
        uint8_t sender = b->sender[slot];
        ++b->head;
        ++b->frames;
        uint8_t side = sender == CO_MEMBUS_EXTERNAL ? FI_SIDE_A : (uint8_t)SIDE_OF(sender);
        if (side == FI_SIDE_A) {
            hil_master_record(&f, sender, H.now_us, H.running);
            if (sender == CO_MEMBUS_EXTERNAL) hear(FI_SIDE_A, &f); /* the master's frame reaches the plant */
        }
        fi_frame(&H.fi, &f, side, H.now_us);
    }
}

/* One node's timers (heartbeats, consumers, SDO timeouts), when due. */
void hil_timers(uint8_t s)
{
    if (H.killed[s] || H.frozen[s] || H.now_us < H.next_tick_us[s]) return;
    co_node_tick(node_of(s), H.now_us);
    H.next_tick_us[s] = H.now_us + co_node_next_event_us(node_of(s), H.now_us, TICK_MAX_US);
}

/* The injector's held frames that are due, and every frame queued on the bus. */
void hil_fi_tick(void)
{
    fi_tick(&H.fi, H.now_us);
    deliver();
}

/* The nodes' timers on simulated time, when due. */
static void tick(void)
{
    for (uint8_t s = 0; s < 2u; ++s) hil_timers(s);
    hil_fi_tick();
}

co_node_t *hil_node_of(uint8_t side) { return node_of(side); }
plant_app_t *hil_plant_app(void) { return &H.plant; }
void hil_deliver(void) { deliver(); }
void hil_set_now_us(int64_t t_us) { H.now_us = t_us; }
int hil_side_live(uint8_t side) { return !H.killed[side] && !H.frozen[side]; }
int hil_side_killed(uint8_t side) { return H.killed[side]; }
/* A frame that reached a node's inbox before the node froze: it waits with the frames sent to it since. */
void hil_frozen_frame(const co_frame_t *f) { freeze(f); }
void hil_set_running(int on) { H.running = on; }

int hil_open(uint8_t plant_id, uint8_t drive_id)
{
    __atomic_add_fetch(&g_opens, 1u, __ATOMIC_RELEASE); /* a previous opening's stop request and counters are stale */
    memset(&H, 0, sizeof H);                            /* no sink: lockstep */
    hil_master_reset();
    H.now_us = 0;
    co_membus_init(&H.bus, NULL, NULL);
    fi_init(&H.fi, emit, node_fault, NULL);
    H.plant_port = co_membus_port(&H.bus);
    H.drive_port = co_membus_port(&H.bus);
    plant_app_init(&H.plant);
    plant_app_set_fmu_loader(&H.plant, plant_fmu_load_text);
    co_node_init(&H.plant_node, &od_plant, plant_id, co_membus_tx, &H.bus.ports[H.plant_port], plant_app_hooks(),
                 &H.plant, H.now_us);
    plant_app_bind(&H.plant, &H.plant_node);
    co_membus_attach(&H.bus, H.plant_port, &H.plant_node);
    drive_app_init(&H.drive);
    co_node_init(&H.drive_node, &od_drive, drive_id, co_membus_tx, &H.bus.ports[H.drive_port], drive_app_hooks(),
                 &H.drive, H.now_us);
    drive_app_bind(&H.drive, &H.drive_node);
    co_membus_attach(&H.bus, H.drive_port, &H.drive_node);
    deliver();
    return 0;
}

/* Fault rules (fault_rules.h text); before the run. Returns the rules added or -1 (message in err). */
int hil_faults(const char *text, char *err, uint32_t err_len) { return fi_parse_rules(&H.fi, text, err, err_len); }

/* The injector's log: copies up to max events, returns how many there are in all. */
uint32_t hil_fault_log(fi_event_t *out, uint32_t max)
{
    hil_lock();
    uint32_t n = H.fi.n_log < max ? H.fi.n_log : max;
    if (out != NULL && n != 0u) memcpy(out, H.fi.log, n * sizeof *out);
    uint32_t all = H.fi.n_log;
    hil_unlock();
    return all;
}
uint32_t hil_fault_event_size(void) { return (uint32_t)sizeof(fi_event_t); }
uint64_t hil_fault_overflows(void) { return H.fi.log_overflow + H.fi.held_overflow + H.fz_dropped; }

/* A frame from the master: queue it and deliver it (and everything it causes). */
int hil_send(uint16_t cob_id, const uint8_t *data, uint8_t dlc)
{
    co_frame_t f;
    memset(&f, 0, sizeof f);
    f.cob_id = cob_id & 0x7FFu;
    f.dlc = dlc > 8 ? 8 : dlc;
    memcpy(f.data, data, f.dlc);
    hil_lock();
    int rc = co_membus_inject(&H.bus, &f) != 0 ? -1 : 0;
    if (rc == 0) deliver();
    hil_unlock();
    return rc;
}

/* One SDO transfer of the master, whole (bench/run/bus/direct_sdo.py): the request goes on the bus as
 * hil_send sends it (recorded, heard by the nodes), and the server's answer - the first frame on resp_cob
 * since, of 8 bytes as CiA 301 has every SDO frame - is taken out of the master's queue into resp; the nodes'
 * other frames stay queued for the master.
 * Returns 1 when answered, 0 when no answer came (a killed or frozen node), -1 when the bus queue was full. */
int hil_sdo(uint16_t req_cob, const uint8_t req[8], uint16_t resp_cob, uint8_t resp[8])
{
    hil_lock();
    const uint32_t from = hil_master_mark();
    int rc = hil_send(req_cob, req, 8u);
    if (rc == 0) rc = hil_master_answer(from, resp_cob, resp);
    hil_unlock();
    return rc;
}

/* Nodes that are no longer in the loop: bit 0 the plant, bit 1 the drive (killed by a fault, or out
 * of OPERATIONAL: reset, stopped). */
static uint32_t nodes_down(void)
{
    uint32_t down = 0;
    for (uint8_t s = 0; s < 2u; ++s)
        if (H.killed[s] || node_of(s)->nmt != CO_NMT_OPERATIONAL) down |= 1u << s;
    return down;
}
uint32_t hil_nodes_down(void)
{
    hil_lock();
    const uint32_t down = nodes_down();
    hil_unlock();
    return down;
}

/* The node's state: 0xFF killed, else its NMT state (co_nmt_state_t). */
uint32_t hil_node_state(uint32_t side)
{
    hil_lock();
    uint32_t st = H.killed[side & 1u] ? 0xFFu : (uint32_t)node_of((uint8_t)(side & 1u))->nmt;
    hil_unlock();
    return st;
}

/* After a node was lost: simulated time goes on for `us` with the nodes' timers only (no new period),
 * so that the survivor's reaction (its heartbeat consumer) is recorded as on a bus. */
void hil_linger(int64_t us)
{
    hil_lock();
    const int64_t end = H.now_us + us;
    H.running = 1;
    while (H.now_us < end) {
        int64_t next = end;
        for (uint8_t s = 0; s < 2u; ++s)
            if (!H.killed[s] && !H.frozen[s] && H.next_tick_us[s] < next)
                next = H.next_tick_us[s] > H.now_us ? H.next_tick_us[s] : H.now_us + 1;
        H.now_us = next;
        tick();
    }
    H.running = 0;
    hil_unlock();
}

/* Run the lockstep loop until the plant holds (run_periods exhausted) or max_periods
 * SYNCs were produced. Returns the SYNCs produced. Simulated time advances by Ts per SYNC, and
 * while the plant waits (a command that did not come: its timeout 0x2003:04, the nodes'
 * heartbeat consumers, frames the injector holds) to the next thing that can happen; after
 * STALL_US of simulated time without a SYNC the loop gives up (the caller names the stall). */
uint32_t hil_run(uint32_t max_periods)
{
    hil_lock();
    uint32_t n = 0;
    int64_t idle_since = H.now_us;
    H.running = 1;
    while (n < max_periods && !hil_pylaw_stopping()) {
        const uint32_t before = H.plant.syncs;
        const int plant_up = !H.killed[FI_SIDE_A] && !H.frozen[FI_SIDE_A];
        const int64_t wish = plant_up ? plant_app_poll(&H.plant, H.now_us) : -1;
        deliver();
        if (nodes_down() != 0u) break; /* a node killed, reset or stopped: the caller names it */
        if (H.plant.syncs != before) {
            ++n;
            H.now_us += plant_app_period_ns(&H.plant) / 1000;
            idle_since = H.now_us;
            tick();
            continue;
        }
        if (plant_up && wish < 0 && !plant_app_running(&H.plant)) break; /* holding: the segment is over */
        /* waiting: on to the next event */
        int64_t next = wish > 0 ? H.now_us + wish : INT64_MAX;
        for (uint8_t s = 0; s < 2u; ++s)
            if (!H.killed[s] && !H.frozen[s] && H.next_tick_us[s] < next)
                next = H.next_tick_us[s] > H.now_us ? H.next_tick_us[s] : H.now_us + 1;
        const int64_t rel = fi_next_release_us(&H.fi);
        if (rel >= 0 && rel < next) next = rel > H.now_us ? rel : H.now_us + 1;
        if (next == INT64_MAX || next - idle_since > STALL_US) break;
        H.now_us = next;
        tick();
    }
    H.running = 0;
    hil_unlock();
    return n;
}

/* Simulated time (us) and the plant's period index, for the Python side. */
int64_t hil_now_us(void) { return H.now_us; }
uint64_t hil_plant_period(void) { return H.plant.k; }
uint64_t hil_bus_frames(void) { return H.bus.frames; }
uint32_t hil_frame_size(void) { return (uint32_t)sizeof(hil_frame_t); }
uint32_t hil_frame_fd_size(void) { return (uint32_t)sizeof(hil_frame_fd_t); }
