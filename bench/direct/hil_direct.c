/* hil_direct.c - the bench's direct mode: the plant and drive node apps on an
 * in-process co_membus (no kernel, no sockets), driven from Python by ctypes.
 *
 * Same code as the node processes (plant_app.c, drive_app.c, the CANopen slave),
 * same frames in the same order: a lockstep run over vcan and a direct run of the
 * same scenario decode to identical traces. Simulated time advances by Ts per SYNC.
 *
 * The Python side talks to the nodes as a CANopen master through hil_send/hil_recv
 * (bench/direct.py wraps them as a python-can bus, so `canopen` works unchanged).
 */
#include <stdint.h>
#include <string.h>

#include "co_membus.h"
#include "co_node.h"
#include "drive_app.h"
#include "od_drive.h"
#include "od_plant.h"
#include "plant_app.h"

#include "hil_frame.h" /* hil_frame_t, 24 bytes; numpy dtype FRAME_DTYPE */

#define MASTER_Q 1024u

static struct {
    co_membus_t bus;
    co_node_t plant_node, drive_node;
    plant_app_t plant;
    drive_app_t drive;
    int plant_port, drive_port;
    int64_t now_us;
    uint32_t seq;
    hil_frame_t *rec;
    uint32_t rec_cap, rec_n;
    uint64_t rec_dropped;
    hil_frame_t mq[MASTER_Q];
    uint32_t mq_head, mq_tail;
    uint64_t mq_dropped;
    int running;
} H;

static void sink(void *user, const co_frame_t *f, uint8_t sender, int64_t now_us)
{
    (void)user;
    hil_frame_t r;
    memset(&r, 0, sizeof r);
    r.t_us = (uint64_t)now_us;
    r.seq = H.seq++;
    r.cob_id = (uint16_t)(f->cob_id & 0x7FFu);
    r.dlc = f->dlc;
    r.sender = sender;
    memcpy(r.data, f->data, f->dlc);
    if (H.rec) {
        if (H.rec_n < H.rec_cap)
            H.rec[H.rec_n++] = r;
        else
            ++H.rec_dropped;
    }
    /* The master sees every frame of the nodes, like a CAN controller would, except the
     * PDO stream of a run (it reads the recorder instead). */
    if (sender != CO_MEMBUS_EXTERNAL && !H.running) {
        if (H.mq_tail - H.mq_head < MASTER_Q)
            H.mq[H.mq_tail++ % MASTER_Q] = r;
        else
            ++H.mq_dropped;
    }
}

int hil_open(uint8_t plant_id, uint8_t drive_id)
{
    memset(&H, 0, sizeof H);
    H.now_us = 0;
    co_membus_init(&H.bus, sink, NULL);
    H.plant_port = co_membus_port(&H.bus);
    H.drive_port = co_membus_port(&H.bus);
    plant_app_init(&H.plant);
    co_node_init(&H.plant_node, &od_plant, plant_id, co_membus_tx, &H.bus.ports[H.plant_port], plant_app_hooks(),
                 &H.plant, H.now_us);
    plant_app_bind(&H.plant, &H.plant_node);
    co_membus_attach(&H.bus, H.plant_port, &H.plant_node);
    drive_app_init(&H.drive);
    co_node_init(&H.drive_node, &od_drive, drive_id, co_membus_tx, &H.bus.ports[H.drive_port], drive_app_hooks(),
                 &H.drive, H.now_us);
    drive_app_bind(&H.drive, &H.drive_node);
    co_membus_attach(&H.bus, H.drive_port, &H.drive_node);
    co_membus_deliver(&H.bus, H.now_us);
    return 0;
}

/* Recorder: every frame on the bus goes into the caller's buffer (no allocation here). */
void hil_set_recorder(hil_frame_t *buf, uint32_t capacity)
{
    H.rec = buf;
    H.rec_cap = capacity;
    H.rec_n = 0;
    H.rec_dropped = 0;
}

uint32_t hil_recorded(void) { return H.rec_n; }
uint64_t hil_record_dropped(void) { return H.rec_dropped; }

/* A frame from the master: queue it and deliver it (and everything it causes). */
int hil_send(uint16_t cob_id, const uint8_t *data, uint8_t dlc)
{
    co_frame_t f;
    memset(&f, 0, sizeof f);
    f.cob_id = cob_id & 0x7FFu;
    f.dlc = dlc > 8 ? 8 : dlc;
    memcpy(f.data, data, f.dlc);
    if (co_membus_inject(&H.bus, &f) != 0) return -1;
    co_membus_deliver(&H.bus, H.now_us);
    return 0;
}

/* Next frame of the nodes for the master; returns 1 when one was copied. */
int hil_recv(hil_frame_t *out)
{
    if (H.mq_head == H.mq_tail) return 0;
    *out = H.mq[H.mq_head++ % MASTER_Q];
    return 1;
}

/* Run the lockstep loop until the plant holds (run_periods exhausted) or max_periods
 * SYNCs were produced. Returns the SYNCs produced. */
uint32_t hil_run(uint32_t max_periods)
{
    uint32_t n = 0;
    H.running = 1;
    while (n < max_periods) {
        uint32_t before = H.plant.syncs;
        plant_app_poll(&H.plant, H.now_us);
        co_membus_deliver(&H.bus, H.now_us);
        if (H.plant.syncs == before) break; /* holding, stopped, or waiting (cannot happen in-process) */
        ++n;
        H.now_us += plant_app_period_ns(&H.plant) / 1000;
    }
    H.running = 0;
    return n;
}

/* Simulated time (us) and the plant's period index, for the Python side. */
int64_t hil_now_us(void) { return H.now_us; }
uint64_t hil_plant_period(void) { return H.plant.k; }
uint32_t hil_frame_size(void) { return (uint32_t)sizeof(hil_frame_t); }
