/* shim_testbus.h - the drive node on the test bus (header only): one drive node (drive_app +
 * co_node, node-ID 0x20) on tests/c/testbus.h; the test plays the plant (SYNC + measurement
 * PDOs: sample()), the bench (RPDO3 references) and the master (NMT, SDO).  Every exchange
 * advances the bus time by the step given to setup().  The recorder holds the frames since the
 * last exchange began (sample() and the SDO helpers clear it first); find() looks among the
 * drive's frames there.  Used by firmware_shim/tests/test_shim_*.c. */
#ifndef SHIM_TESTBUS_H
#define SHIM_TESTBUS_H

#include <stdint.h>
#include <string.h>

#include "check.h"
#include "drive_app.h"
#include "drive_core.h"
#include "law_states.h"
#include "od_drive.h"
#include "testbus.h"

#define DRIVE_ID 0x20u
#define COB_CMD 0x210u   /* drive TPDO1 */
#define COB_LIVE 0x2A0u  /* drive TPDO2 */
#define COB_MEAS1 0x190u /* plant TPDO1 -> drive RPDO1 */
#define COB_MEAS2 0x290u /* plant TPDO2 -> drive RPDO2 */
#define COB_REF 0x420u   /* drive RPDO3 */
#define COB_EMCY (0x80u + DRIVE_ID)
#define COB_SDO_RX (0x600u + DRIVE_ID)
#define COB_SDO_TX (0x580u + DRIVE_ID)

static testbus_t g_tb;
static drive_app_t g_app;
static uint8_t g_sync; /* last SYNC counter (1..240) */

static inline void inject(uint16_t cob, uint8_t dlc, const uint8_t *d)
{
    CHECK_TRUE(testbus_inject(&g_tb, cob, dlc, d) == 0);
}

static inline void deliver(void) { testbus_step(&g_tb); }

static inline const co_frame_t *find(uint16_t cob, int nth) { return testbus_find(&g_tb, cob, nth); }

static inline uint32_t sdo_write_u16(uint16_t idx, uint8_t sub, uint16_t v);

/* CiA 402: SWITCH ON DISABLED -> OPERATION ENABLED by SDO (controlword 6, 7, 15), as the bench does. */
static inline void enable_drive(void)
{
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_CONTROLWORD_IDX, 0, 0x0006u) == 0);
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_CONTROLWORD_IDX, 0, 0x0007u) == 0);
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_CONTROLWORD_IDX, 0, 0x000Fu) == 0);
    CHECK_TRUE(g_app.cia.dev.state == CIA402_OPERATION_ENABLED);
    testbus_clear(&g_tb);
}

/* A fresh drive at t = 1000 us, booted and started (NMT), every exchange step_us long. */
static inline void setup(int64_t step_us)
{
    drive_app_init(&g_app);
    testbus_init(&g_tb, &od_drive, DRIVE_ID, drive_app_hooks(), &g_app, 1000, step_us);
    drive_app_bind(&g_app, &g_tb.node);
    deliver();
    CHECK_TRUE(find(0x700u + DRIVE_ID, 0) != NULL); /* boot-up */
    const uint8_t start[2] = {0x01, 0x00};          /* NMT start, all nodes */
    testbus_clear(&g_tb);
    inject(0x000, 2, start);
    deliver();
    CHECK_TRUE(g_tb.node.nmt == CO_NMT_OPERATIONAL);
    enable_drive();
}

/* ------------------------------------------------------------------ scripted plant */
static uint8_t g_meas_status = 0u; /* the plant status byte sample_ex sends (0x2100:05) */

static inline uint8_t next_sync(void)
{
    g_sync = (uint8_t)(g_sync >= 240u ? 1u : g_sync + 1u);
    return g_sync;
}

/* One sample: SYNC, TPDO1 {i_a, i_b}, TPDO2 {theta, sync, status, k} (each if sendN).
 * Returns the drive's command frame (NULL if none). */
static inline const co_frame_t *sample_ex(const drive_meas_t *m, uint16_t k, int send1, int send2)
{
    uint8_t sc = next_sync();
    uint8_t d[8];
    testbus_clear(&g_tb);
    inject(0x080, 1, &sc);
    if (send1) {
        testbus_put_f32(&d[0], m->i_a_A);
        testbus_put_f32(&d[4], m->i_b_A);
        inject(COB_MEAS1, 8, d);
    }
    if (send2) {
        testbus_put_f32(&d[0], m->theta_m_rad);
        d[4] = sc;
        d[5] = g_meas_status;
        d[6] = (uint8_t)k;
        d[7] = (uint8_t)(k >> 8);
        inject(COB_MEAS2, 8, d);
    }
    deliver();
    return find(COB_CMD, 0);
}

static inline const co_frame_t *sample(const drive_meas_t *m, uint16_t k) { return sample_ex(m, k, 1, 1); }

/* 1 if f is a command frame carrying exactly (v_alpha_V, v_beta_V). */
static inline int cmd_is(const co_frame_t *f, float v_alpha_V, float v_beta_V)
{
    return f && testbus_same_f32(testbus_get_f32(&f->data[0]), v_alpha_V) &&
           testbus_same_f32(testbus_get_f32(&f->data[4]), v_beta_V);
}

/* ------------------------------------------------------------------ SDO client */
static inline uint32_t sdo_download_raw(uint16_t idx, uint8_t sub, const uint8_t *v, uint8_t n)
{
    testbus_clear(&g_tb);
    return testbus_sdo_download(&g_tb, idx, sub, v, n);
}

static inline uint32_t sdo_write_f32(uint16_t idx, uint8_t sub, float v)
{
    uint8_t b[4];
    testbus_put_f32(b, v);
    return sdo_download_raw(idx, sub, b, 4);
}

static inline uint32_t sdo_write_u8(uint16_t idx, uint8_t sub, uint8_t v) { return sdo_download_raw(idx, sub, &v, 1); }

static inline uint32_t sdo_write_u16(uint16_t idx, uint8_t sub, uint16_t v)
{
    uint8_t b[2] = {(uint8_t)v, (uint8_t)(v >> 8)};
    return sdo_download_raw(idx, sub, b, 2);
}

static inline uint32_t sdo_write_u32(uint16_t idx, uint8_t sub, uint32_t v)
{
    uint8_t b[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    return sdo_download_raw(idx, sub, b, 4);
}

/* Expedited upload of up to 4 bytes into out[4]; returns the abort code or 0. */
static inline uint32_t sdo_read(uint16_t idx, uint8_t sub, uint8_t out[4])
{
    uint32_t len, segments;
    testbus_clear(&g_tb);
    const uint32_t a = testbus_sdo_upload(&g_tb, idx, sub, out, 4, &len, &segments);
    return (a == 0u && segments != 0u) ? TESTBUS_SDO_UNEXPECTED : a;
}

static inline float sdo_read_f32(uint16_t idx, uint8_t sub)
{
    uint8_t b[4] = {0, 0, 0, 0};
    CHECK_TRUE(sdo_read(idx, sub, b) == 0);
    return testbus_get_f32(b);
}

static inline uint32_t sdo_read_u32(uint16_t idx, uint8_t sub)
{
    uint8_t b[4] = {0, 0, 0, 0};
    CHECK_TRUE(sdo_read(idx, sub, b) == 0);
    return testbus_get_u32(b); /* upper bytes 0 for shorter types (expedited pads) */
}

/* Segmented upload into buf; returns the bytes or -1. */
static inline long sdo_upload_segmented(uint16_t idx, uint8_t sub, uint8_t *buf, uint32_t cap, uint32_t *segments)
{
    uint32_t len;
    testbus_clear(&g_tb);
    const uint32_t a = testbus_sdo_upload(&g_tb, idx, sub, buf, cap, &len, segments);
    return (a == 0u && *segments != 0u) ? (long)len : -1;
}

#endif /* SHIM_TESTBUS_H */
