/* plant_testbus.h - the plant node on the test bus (header only).
 *
 * One plant node (plant_app + co_node, node-ID 16) on tests/c/testbus.h; the test plays the
 * master and the drive by injecting frames (NMT, SDO, RPDO1).  On top of the bus's recorder
 * (every frame, tb->bus.rec) this keeps the plant's measurements (TPDO1 + TPDO2 = one sample),
 * the SYNCs and the EMCYs it sent.  Time is driven by hand (tb->bus.now_us; frames are
 * delivered without advancing it).  Used by plant_rt/tests/test_node_*.c.
 */
#ifndef PLANT_TESTBUS_H
#define PLANT_TESTBUS_H

#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "od_plant.h"
#include "plant_app.h"
#include "testbus.h"

#define TB_NODE_ID 16u
#define TB_MAX_SAMPLES 4096u
#define TB_COB_SYNC 0x080u
#define TB_COB_EMCY (0x080u + TB_NODE_ID)
#define TB_COB_TPDO1 (0x180u + TB_NODE_ID)
#define TB_COB_TPDO2 (0x280u + TB_NODE_ID)
#define TB_COB_RPDO1 (0x200u + TB_NODE_ID)

typedef struct {
    float ia, ib, th;
    uint8_t counter, status;
    uint16_t index;
} tb_sample_t;

typedef struct {
    testbus_t bus;
    plant_app_t app;
    tb_sample_t smp[TB_MAX_SAMPLES];
    uint32_t n_smp;
    float pend_ia, pend_ib;
    uint32_t n_sync, n_emcy;
    uint8_t last_emcy[8];
} tb_t;

static inline void tb_on_frame(void *user, const co_frame_t *f, uint8_t sender, int64_t now_us)
{
    tb_t *tb = (tb_t *)user;
    (void)now_us;
    if (sender == CO_MEMBUS_EXTERNAL) return;
    uint32_t id = f->cob_id & 0x7FFu;
    if (id == TB_COB_SYNC) {
        ++tb->n_sync;
    } else if (id == TB_COB_EMCY) {
        ++tb->n_emcy;
        memcpy(tb->last_emcy, f->data, 8);
    } else if (id == TB_COB_TPDO1) {
        tb->pend_ia = testbus_get_f32(&f->data[0]);
        tb->pend_ib = testbus_get_f32(&f->data[4]);
    } else if (id == TB_COB_TPDO2 && tb->n_smp < TB_MAX_SAMPLES) {
        tb_sample_t *s = &tb->smp[tb->n_smp++];
        s->ia = tb->pend_ia;
        s->ib = tb->pend_ib;
        s->th = testbus_get_f32(&f->data[0]);
        s->counter = f->data[4];
        s->status = f->data[5];
        s->index = (uint16_t)(f->data[6] | f->data[7] << 8);
    }
}

static inline void tb_deliver(tb_t *tb) { testbus_deliver(&tb->bus); }

static inline void tb_init(tb_t *tb)
{
    memset(tb, 0, sizeof *tb);
    plant_app_init(&tb->app);
    testbus_init(&tb->bus, &od_plant, TB_NODE_ID, plant_app_hooks(), &tb->app, 0, 0);
    tb->bus.on_frame = tb_on_frame;
    tb->bus.on_frame_user = tb;
    plant_app_bind(&tb->app, &tb->bus.node);
    tb_deliver(tb);
}

static inline void tb_inject(tb_t *tb, uint32_t cob, uint8_t dlc, const uint8_t *d)
{
    testbus_send(&tb->bus, cob, dlc, d);
}

static inline void tb_nmt(tb_t *tb, uint8_t cs)
{
    uint8_t d[2] = {cs, (uint8_t)TB_NODE_ID};
    tb_inject(tb, 0x000u, 2, d);
}

/* SDO download by real frames (expedited up to 4 bytes, else segmented). Returns the abort code or 0. */
static inline uint32_t tb_sdo_write(tb_t *tb, uint16_t idx, uint8_t sub, const void *data, uint32_t len)
{
    return testbus_sdo_download(&tb->bus, idx, sub, data, len);
}

static inline uint32_t tb_w_f32(tb_t *tb, uint16_t idx, uint8_t sub, float v)
{
    uint8_t b[4];
    testbus_put_f32(b, v);
    return tb_sdo_write(tb, idx, sub, b, 4);
}

static inline uint32_t tb_w_u32(tb_t *tb, uint16_t idx, uint8_t sub, uint32_t v)
{
    uint8_t b[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    return tb_sdo_write(tb, idx, sub, b, 4);
}

static inline uint32_t tb_w_u8(tb_t *tb, uint16_t idx, uint8_t sub, uint8_t v)
{
    return tb_sdo_write(tb, idx, sub, &v, 1);
}

/* The drive's command (RPDO1 of the plant). */
static inline void tb_cmd(tb_t *tb, float va, float vb)
{
    uint8_t d[8];
    testbus_put_f32(&d[0], va);
    testbus_put_f32(&d[4], vb);
    tb_inject(tb, TB_COB_RPDO1, 8, d);
}

/* Timers + app poll at the current time; returns the app's wait hint. */
static inline int64_t tb_poll(tb_t *tb)
{
    tb_deliver(tb);
    co_node_tick(&tb->bus.node, tb->bus.now_us);
    int64_t w = plant_app_poll(&tb->app, tb->bus.now_us);
    tb_deliver(tb);
    return w;
}

/* NMT start + run_periods, then the first poll (SYNC 0). */
static inline void tb_start(tb_t *tb, uint32_t run_periods)
{
    tb_w_u32(tb, OD_PLANT_RUN_CONTROL_IDX, OD_PLANT_RUN_CONTROL_RUN_PERIODS_SUB, run_periods);
    tb_nmt(tb, 0x01u);
    tb_poll(tb);
}

/* Lockstep period with a prompt drive: send the command for the last sample, poll -> next SYNC. */
static inline const tb_sample_t *tb_period(tb_t *tb, float va, float vb)
{
    tb->bus.now_us += 10;
    tb_cmd(tb, va, vb);
    tb->bus.now_us += 10;
    tb_poll(tb);
    return tb->n_smp ? &tb->smp[tb->n_smp - 1u] : NULL;
}

#endif /* PLANT_TESTBUS_H */
