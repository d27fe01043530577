/* plant_testbus.h - in-process test harness for the plant node (header only).
 *
 * One plant node (plant_app + co_node, node-ID 16) on a co_membus; the test
 * plays the master and the drive by injecting frames (NMT, SDO, RPDO1) and
 * records every frame on the bus. Used by plant_rt/tests/test_node_*.c.
 */
#ifndef PLANT_TESTBUS_H
#define PLANT_TESTBUS_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "co_membus.h"
#include "od_plant.h"
#include "plant_app.h"

#define TB_NODE_ID 16u
#define TB_MAX_REC 16384u
#define TB_MAX_SAMPLES 4096u
#define TB_COB_SYNC 0x080u
#define TB_COB_EMCY (0x080u + TB_NODE_ID)
#define TB_COB_TPDO1 (0x180u + TB_NODE_ID)
#define TB_COB_TPDO2 (0x280u + TB_NODE_ID)
#define TB_COB_RPDO1 (0x200u + TB_NODE_ID)
#define TB_COB_SDO_RX (0x600u + TB_NODE_ID)
#define TB_COB_SDO_TX (0x580u + TB_NODE_ID)

typedef struct {
    co_frame_t f;
    uint8_t sender;
    int64_t t_us;
} tb_rec_t;

typedef struct {
    float ia, ib, th;
    uint8_t counter, status;
    uint16_t index;
} tb_sample_t;

typedef struct {
    co_membus_t bus;
    co_node_t node;
    plant_app_t app;
    int port;
    int64_t now_us;
    tb_rec_t rec[TB_MAX_REC];
    uint32_t n_rec;
    tb_sample_t smp[TB_MAX_SAMPLES];
    uint32_t n_smp;
    float pend_ia, pend_ib;
    uint32_t n_sync, n_emcy;
    uint8_t last_emcy[8];
    bool sdo_got;
    uint8_t sdo_resp[8];
} tb_t;

static inline float tb_f32(const uint8_t *b)
{
    uint32_t u = (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
    float f;
    memcpy(&f, &u, 4);
    return f;
}

static inline void tb_put_f32(uint8_t *b, float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    b[0] = (uint8_t)u;
    b[1] = (uint8_t)(u >> 8);
    b[2] = (uint8_t)(u >> 16);
    b[3] = (uint8_t)(u >> 24);
}

static inline void tb_sink(void *user, const co_frame_t *f, uint8_t sender, int64_t now_us)
{
    tb_t *tb = (tb_t *)user;
    if (tb->n_rec < TB_MAX_REC) {
        tb->rec[tb->n_rec].f = *f;
        tb->rec[tb->n_rec].sender = sender;
        tb->rec[tb->n_rec].t_us = now_us;
        ++tb->n_rec;
    }
    if (sender == CO_MEMBUS_EXTERNAL) return;
    uint32_t id = f->cob_id & 0x7FFu;
    if (id == TB_COB_SYNC) {
        ++tb->n_sync;
    } else if (id == TB_COB_EMCY) {
        ++tb->n_emcy;
        memcpy(tb->last_emcy, f->data, 8);
    } else if (id == TB_COB_TPDO1) {
        tb->pend_ia = tb_f32(&f->data[0]);
        tb->pend_ib = tb_f32(&f->data[4]);
    } else if (id == TB_COB_TPDO2 && tb->n_smp < TB_MAX_SAMPLES) {
        tb_sample_t *s = &tb->smp[tb->n_smp++];
        s->ia = tb->pend_ia;
        s->ib = tb->pend_ib;
        s->th = tb_f32(&f->data[0]);
        s->counter = f->data[4];
        s->status = f->data[5];
        s->index = (uint16_t)(f->data[6] | f->data[7] << 8);
    } else if (id == TB_COB_SDO_TX) {
        tb->sdo_got = true;
        memcpy(tb->sdo_resp, f->data, 8);
    }
}

static inline void tb_deliver(tb_t *tb)
{
    co_membus_deliver(&tb->bus, tb->now_us);
}

static inline void tb_init(tb_t *tb)
{
    memset(tb, 0, sizeof *tb);
    co_membus_init(&tb->bus, tb_sink, tb);
    tb->port = co_membus_port(&tb->bus);
    plant_app_init(&tb->app);
    co_node_init(&tb->node, &od_plant, TB_NODE_ID, co_membus_tx, &tb->bus.ports[tb->port], plant_app_hooks(),
                 &tb->app, tb->now_us);
    co_membus_attach(&tb->bus, tb->port, &tb->node);
    plant_app_bind(&tb->app, &tb->node);
    tb_deliver(tb);
}

static inline void tb_inject(tb_t *tb, uint32_t cob, uint8_t dlc, const uint8_t *d)
{
    co_frame_t f;
    memset(&f, 0, sizeof f);
    f.cob_id = cob;
    f.dlc = dlc;
    if (dlc) memcpy(f.data, d, dlc);
    co_membus_inject(&tb->bus, &f);
    tb_deliver(tb);
}

static inline void tb_nmt(tb_t *tb, uint8_t cs)
{
    uint8_t d[2] = {cs, (uint8_t)TB_NODE_ID};
    tb_inject(tb, 0x000u, 2, d);
}

static inline uint32_t tb_abort_of(const tb_t *tb)
{
    if (!tb->sdo_got) return 0xFFFFFFFFu;
    if (tb->sdo_resp[0] != 0x80u) return 0;
    return (uint32_t)tb->sdo_resp[4] | (uint32_t)tb->sdo_resp[5] << 8 | (uint32_t)tb->sdo_resp[6] << 16 |
           (uint32_t)tb->sdo_resp[7] << 24;
}

/* SDO download by real frames (expedited up to 4 bytes, else segmented). Returns the abort code or 0. */
static inline uint32_t tb_sdo_write(tb_t *tb, uint16_t idx, uint8_t sub, const void *data, uint32_t len)
{
    const uint8_t *p = (const uint8_t *)data;
    uint8_t d[8] = {0, (uint8_t)idx, (uint8_t)(idx >> 8), sub, 0, 0, 0, 0};
    tb->sdo_got = false;
    if (len <= 4u) {
        d[0] = (uint8_t)(0x23u | ((4u - len) << 2));
        memcpy(&d[4], p, len);
        tb_inject(tb, TB_COB_SDO_RX, 8, d);
        return tb_abort_of(tb);
    }
    d[0] = 0x21u;
    d[4] = (uint8_t)len;
    d[5] = (uint8_t)(len >> 8);
    tb_inject(tb, TB_COB_SDO_RX, 8, d);
    uint32_t a = tb_abort_of(tb);
    if (a) return a;
    uint8_t toggle = 0;
    for (uint32_t off = 0; off < len;) {
        uint32_t n = len - off > 7u ? 7u : len - off;
        uint8_t s[8] = {0};
        int last = off + n >= len;
        s[0] = (uint8_t)((toggle << 4) | ((7u - n) << 1) | (last ? 1u : 0u));
        memcpy(&s[1], p + off, n);
        tb->sdo_got = false;
        tb_inject(tb, TB_COB_SDO_RX, 8, s);
        a = tb_abort_of(tb);
        if (a) return a;
        off += n;
        toggle ^= 1u;
    }
    return 0;
}

static inline uint32_t tb_w_f32(tb_t *tb, uint16_t idx, uint8_t sub, float v)
{
    uint8_t b[4];
    tb_put_f32(b, v);
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
    tb_put_f32(&d[0], va);
    tb_put_f32(&d[4], vb);
    tb_inject(tb, TB_COB_RPDO1, 8, d);
}

/* Timers + app poll at the current time; returns the app's wait hint. */
static inline int64_t tb_poll(tb_t *tb)
{
    tb_deliver(tb);
    co_node_tick(&tb->node, tb->now_us);
    int64_t w = plant_app_poll(&tb->app, tb->now_us);
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
    tb->now_us += 10;
    tb_cmd(tb, va, vb);
    tb->now_us += 10;
    tb_poll(tb);
    return tb->n_smp ? &tb->smp[tb->n_smp - 1u] : NULL;
}

static inline int tb_f32_same(float a, float b)
{
    return memcmp(&a, &b, sizeof a) == 0;
}

#endif /* PLANT_TESTBUS_H */
