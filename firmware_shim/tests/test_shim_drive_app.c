/* test_shim_drive_app.c - the drive node app (firmware_shim/shim/drive_app.c)
 * in-process on co_membus with a scripted plant: real CAN frames in (NMT,
 * SYNC, measurement PDOs, reference RPDO3, SDO), the drive's frames out.
 *
 *   (a) one command frame per measurement, bit-identical to drive_current_step
 *       driven directly with the same inputs (closed loop on a PMSM model)
 *   (b) a skipped sample_index is counted as lost and raises EMCY 0xFF01;
 *       an RPDO1 without its RPDO2 / an RPDO2 without RPDO1 count as late (0xFF02)
 *   (c) an expedited SDO download of a REAL32 into Lq_hat changes the next
 *       step's gains (bit-identical to the core with the same change); invalid
 *       values / combinations abort
 *   (d) trace: arm by SDO, run, segmented SDO upload of the DOMAIN, compare
 *       with the signals of every step (ring wrapped, pre-trigger)
 *   (e) references by RPDO3
 *   (f) open loop (mode 3) and the live-trace TPDO2
 *
 * Link: test + drive_app.c + libfw.a + libco.a (-lm). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "co_membus.h"
#include "co_node.h"
#include "drive_app.h"
#include "drive_core.h"
#include "dq_math.h"
#include "od_drive.h"
#include "plant_model.h"

static int g_fail;
#define EXPECT(c)                                                                  \
    do {                                                                          \
        if (!(c)) {                                                               \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #c); \
            ++g_fail;                                                             \
        }                                                                         \
    } while (0)

#define DRIVE_ID 0x20u
#define COB_CMD 0x210u   /* drive TPDO1 */
#define COB_LIVE 0x2A0u  /* drive TPDO2 */
#define COB_MEAS1 0x190u /* plant TPDO1 -> drive RPDO1 */
#define COB_MEAS2 0x290u /* plant TPDO2 -> drive RPDO2 */
#define COB_REF 0x420u   /* drive RPDO3 */
#define COB_EMCY (0x80u + DRIVE_ID)
#define COB_SDO_RX (0x600u + DRIVE_ID)
#define COB_SDO_TX (0x580u + DRIVE_ID)

/* ------------------------------------------------------------------ bus + capture */

#include "shim_testbus.h"

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void inject(uint16_t cob, uint8_t dlc, const uint8_t *d)
{
    co_frame_t f;
    memset(&f, 0, sizeof f);
    f.cob_id = cob;
    f.dlc = dlc;
    if (dlc) memcpy(f.data, d, dlc);
    EXPECT(co_membus_inject(&g_bus, &f) == 0);
}

static void deliver(void)
{
    g_now += 55;
    co_membus_deliver(&g_bus, g_now);
}

static const co_frame_t *find(uint16_t cob, int nth)
{
    for (int i = 0; i < g_ncap; ++i)
        if ((g_cap[i].cob_id & 0x7FFu) == cob && nth-- == 0) return &g_cap[i];
    return NULL;
}

static void setup(void)
{
    co_membus_init(&g_bus, sink, NULL);
    int port = co_membus_port(&g_bus);
    drive_app_init(&g_app);
    g_now = 1000;
    co_node_init(&g_node, &od_drive, DRIVE_ID, co_membus_tx, &g_bus.ports[port], drive_app_hooks(), &g_app, g_now);
    co_membus_attach(&g_bus, port, &g_node);
    drive_app_bind(&g_app, &g_node);
    g_ncap = 0;
    deliver();
    EXPECT(find(0x700u + DRIVE_ID, 0) != NULL); /* boot-up */
    const uint8_t start[2] = {0x01, 0x00};     /* NMT start, all nodes */
    g_ncap = 0;
    inject(0x000, 2, start);
    deliver();
    EXPECT(g_node.nmt == CO_NMT_OPERATIONAL);
}

/* ------------------------------------------------------------------ scripted plant */

static uint8_t g_sync; /* last SYNC counter (1..240) */

static uint8_t next_sync(void)
{
    g_sync = (uint8_t)(g_sync >= 240u ? 1u : g_sync + 1u);
    return g_sync;
}

/* One sample: SYNC, TPDO1 {i_a, i_b}, TPDO2 {theta, sync, status, k}.
 * Returns the drive's command frame (NULL if none). */
static const co_frame_t *sample_ex(const drive_meas_t *m, uint16_t k, int send1, int send2)
{
    uint8_t sc = next_sync();
    uint8_t d[8];
    g_ncap = 0;
    inject(0x080, 1, &sc);
    if (send1) {
        put_f32(&d[0], m->i_a_A);
        put_f32(&d[4], m->i_b_A);
        inject(COB_MEAS1, 8, d);
    }
    if (send2) {
        put_f32(&d[0], m->theta_m_rad);
        d[4] = sc;
        d[5] = 0;
        d[6] = (uint8_t)k;
        d[7] = (uint8_t)(k >> 8);
        inject(COB_MEAS2, 8, d);
    }
    deliver();
    return find(COB_CMD, 0);
}

static const co_frame_t *sample(const drive_meas_t *m, uint16_t k) { return sample_ex(m, k, 1, 1); }

/* ------------------------------------------------------------------ SDO client */

static uint32_t sdo_download_raw(uint16_t idx, uint8_t sub, const uint8_t *v, uint8_t n)
{
    uint8_t d[8] = {(uint8_t)(0x23u | ((4u - n) << 2)), (uint8_t)idx, (uint8_t)(idx >> 8), sub, 0, 0, 0, 0};
    memcpy(&d[4], v, n);
    g_ncap = 0;
    inject(COB_SDO_RX, 8, d);
    deliver();
    const co_frame_t *r = find(COB_SDO_TX, 0);
    if (!r) return 0xFFFFFFFFu;
    if (r->data[0] == 0x60) return 0;
    if (r->data[0] == 0x80) return get_u32(&r->data[4]);
    return 0xFFFFFFFEu;
}

static uint32_t sdo_write_f32(uint16_t idx, uint8_t sub, float v)
{
    uint8_t b[4];
    put_f32(b, v);
    return sdo_download_raw(idx, sub, b, 4);
}

static uint32_t sdo_write_u8(uint16_t idx, uint8_t sub, uint8_t v) { return sdo_download_raw(idx, sub, &v, 1); }

static uint32_t sdo_write_u16(uint16_t idx, uint8_t sub, uint16_t v)
{
    uint8_t b[2] = {(uint8_t)v, (uint8_t)(v >> 8)};
    return sdo_download_raw(idx, sub, b, 2);
}

static uint32_t sdo_write_u32(uint16_t idx, uint8_t sub, uint32_t v)
{
    uint8_t b[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    return sdo_download_raw(idx, sub, b, 4);
}

/* Expedited upload of up to 4 bytes into out[4]; returns the abort code or 0. */
static uint32_t sdo_read(uint16_t idx, uint8_t sub, uint8_t out[4])
{
    uint8_t d[8] = {0x40, (uint8_t)idx, (uint8_t)(idx >> 8), sub, 0, 0, 0, 0};
    g_ncap = 0;
    inject(COB_SDO_RX, 8, d);
    deliver();
    const co_frame_t *r = find(COB_SDO_TX, 0);
    if (!r) return 0xFFFFFFFFu;
    if (r->data[0] == 0x80) return get_u32(&r->data[4]);
    if ((r->data[0] & 0xE3u) != 0x43u) return 0xFFFFFFFEu;
    memcpy(out, &r->data[4], 4);
    return 0;
}

static float sdo_read_f32(uint16_t idx, uint8_t sub)
{
    uint8_t b[4] = {0, 0, 0, 0};
    EXPECT(sdo_read(idx, sub, b) == 0);
    return get_f32(b);
}

static uint32_t sdo_read_u32(uint16_t idx, uint8_t sub)
{
    uint8_t b[4] = {0, 0, 0, 0};
    EXPECT(sdo_read(idx, sub, b) == 0);
    return get_u32(b); /* upper bytes 0 for shorter types (expedited pads) */
}

/* Segmented upload (initiate 0x40, segments 0x60/0x70) into buf; returns bytes or -1. */
static long sdo_upload_segmented(uint16_t idx, uint8_t sub, uint8_t *buf, uint32_t cap, uint32_t *segments)
{
    uint8_t d[8] = {0x40, (uint8_t)idx, (uint8_t)(idx >> 8), sub, 0, 0, 0, 0};
    g_ncap = 0;
    inject(COB_SDO_RX, 8, d);
    deliver();
    const co_frame_t *r = find(COB_SDO_TX, 0);
    if (!r || r->data[0] != 0x41) return -1;
    uint32_t size = get_u32(&r->data[4]);
    uint32_t got = 0;
    uint8_t toggle = 0;
    *segments = 0;
    for (;;) {
        uint8_t q[8] = {(uint8_t)(0x60u | (toggle << 4)), 0, 0, 0, 0, 0, 0, 0};
        g_ncap = 0;
        inject(COB_SDO_RX, 8, q);
        deliver();
        r = find(COB_SDO_TX, 0);
        if (!r || (r->data[0] & 0xE0u) != 0x00u) return -1;
        if (((r->data[0] >> 4) & 1u) != toggle) return -1;
        uint32_t n = 7u - ((r->data[0] >> 1) & 7u);
        if (got + n > cap) return -1;
        memcpy(buf + got, &r->data[1], n);
        got += n;
        ++*segments;
        toggle ^= 1u;
        if (r->data[0] & 1u) break;
    }
    return got == size ? (long)got : -1;
}

/* ------------------------------------------------------------------ (a) */

static void test_bit_identical(void)
{
    setup();
    drive_t ref;
    drive_config_t cfg;
    drive_default_config(&cfg);
    drive_init(&ref, &cfg);
    ref.sp.iq_ref_A = 2.0f;
    EXPECT(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_IQ_REF_A_SUB, 2.0f) == 0);

    plant_t pl;
    plant_init_you2019(&pl);
    pl.rotating = 1;
    pl.omega_m = 100.0; /* rad/s mechanical, fixed */
    int frames = 0, identical = 0;
    const int N = 400;
    for (int k = 0; k < N; ++k) {
        drive_meas_t m;
        plant_measure(&pl, &m);
        if (k == 200) { /* step of the reference by SDO, mirrored in the reference drive */
            ref.sp.iq_ref_A = -1.5f;
            EXPECT(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_IQ_REF_A_SUB, -1.5f) == 0);
        }
        const co_frame_t *f = sample(&m, (uint16_t)k);
        drive_cmd_t c;
        drive_current_step(&ref, &m, &c);
        if (f) {
            ++frames;
            EXPECT(f->dlc == 8);
            if (same_bits(get_f32(&f->data[0]), c.v_alpha_V) && same_bits(get_f32(&f->data[4]), c.v_beta_V))
                ++identical;
        }
        EXPECT(find(COB_EMCY, 0) == NULL);
        drive_cmd_t applied = {get_f32(f ? &f->data[0] : (const uint8_t *)"\0\0\0\0\0\0\0\0"),
                               get_f32(f ? &f->data[4] : (const uint8_t *)"\0\0\0\0\0\0\0\0")};
        plant_advance(&pl, &applied);
    }
    EXPECT(frames == N);
    EXPECT(identical == N);
    EXPECT(g_app.current_steps == (uint32_t)N);
    EXPECT(g_app.lost == 0u && g_app.late == 0u);
    EXPECT(sdo_read_u32(OD_DRIVE_DRIVE_STATUS_IDX, OD_DRIVE_DRIVE_STATUS_CURRENT_STEPS_SUB) == (uint32_t)N);
    float iq = sdo_read_f32(OD_DRIVE_DRIVE_STATUS_IDX, OD_DRIVE_DRIVE_STATUS_IQ_A_SUB);
    EXPECT(same_bits(iq, ref.st.i_q_A));
    EXPECT(fabsf(iq - (-1.5f)) < 0.1f); /* deadbeat settled on the step */
    EXPECT(ref.st.step_count == (uint32_t)N && g_app.drv.st.step_count == (uint32_t)N);
    printf("(a) %d measurements -> %d command frames, %d bit-identical to drive_current_step; iq = %.4f A (ref -1.5)\n",
           N, frames, identical, (double)iq);
}

/* ------------------------------------------------------------------ (b) */

static int count_emcy(uint16_t code, uint8_t *msef_out)
{
    int n = 0;
    for (int i = 0; i < g_ncap; ++i) {
        if ((g_cap[i].cob_id & 0x7FFu) != COB_EMCY) continue;
        uint16_t c = (uint16_t)(g_cap[i].data[0] | g_cap[i].data[1] << 8);
        if (c == code) {
            ++n;
            if (msef_out) memcpy(msef_out, &g_cap[i].data[3], 5);
        }
    }
    return n;
}

static void test_lost_late(void)
{
    setup();
    drive_meas_t m = {0.1f, -0.05f, 0.3f};
    for (uint16_t k = 0; k < 10; ++k) EXPECT(sample(&m, k) != NULL);
    EXPECT(g_app.lost == 0u && g_app.late == 0u);

    /* sample 10 (SYNC + both PDOs) never arrives: only its SYNC */
    next_sync();
    uint8_t sc = g_sync;
    g_ncap = 0;
    inject(0x080, 1, &sc);
    deliver();
    EXPECT(find(COB_CMD, 0) == NULL);
    /* sample 11 */
    const co_frame_t *f = sample(&m, 11);
    EXPECT(f != NULL); /* still answered */
    uint8_t msef[5];
    EXPECT(count_emcy(DRIVE_EMCY_MEAS_LOST, msef) == 1);
    EXPECT(find(COB_EMCY, 0) > f); /* the command goes out first */
    EXPECT(msef[0] == 11 && msef[1] == 0 && msef[2] == 1 && msef[3] == 0);
    EXPECT(g_app.lost == 1u);
    EXPECT(sdo_read_u32(OD_DRIVE_DRIVE_STATUS_IDX, OD_DRIVE_DRIVE_STATUS_LOST_MEASUREMENTS_SUB) == 1u);
    uint8_t reg[4];
    EXPECT(sdo_read(0x1001, 0, reg) == 0 && (reg[0] & 0x91u) == 0x91u); /* generic+communication+manufacturer */
    EXPECT(sdo_read_u32(0x1003, 1) == DRIVE_EMCY_MEAS_LOST);
    /* a gap of 5 (12..16 missing) in one go */
    EXPECT(sample(&m, 17) != NULL);
    EXPECT(count_emcy(DRIVE_EMCY_MEAS_LOST, msef) == 1 && msef[2] == 5);
    EXPECT(g_app.lost == 6u);
    /* next good one clears the error: EMCY 0x0000 */
    EXPECT(sample(&m, 18) != NULL);
    EXPECT(count_emcy(0x0000, NULL) == 1);
    EXPECT(sdo_read(0x1001, 0, reg) == 0 && reg[0] == 0u);

    /* RPDO1 without its RPDO2 (sample 19), detected at the next SYNC */
    EXPECT(sample_ex(&m, 19, 1, 0) == NULL);
    f = sample(&m, 20);
    EXPECT(f != NULL);
    EXPECT(count_emcy(DRIVE_EMCY_MEAS_LATE, msef) == 1 && msef[2] == DRIVE_LATE_RPDO1_WITHOUT_RPDO2);
    EXPECT(count_emcy(DRIVE_EMCY_MEAS_LOST, NULL) == 1); /* and 19 is missing from the sequence */
    EXPECT(g_app.late == 1u && g_app.lost == 7u);
    /* RPDO2 without a fresh RPDO1: still a step (command), counted late */
    f = sample_ex(&m, 21, 0, 1);
    EXPECT(f != NULL);
    EXPECT(count_emcy(DRIVE_EMCY_MEAS_LATE, msef) == 1 && msef[2] == DRIVE_LATE_RPDO2_WITHOUT_RPDO1);
    EXPECT(g_app.late == 2u);
    /* duplicate sample_index */
    EXPECT(sample(&m, 21) != NULL);
    EXPECT(count_emcy(DRIVE_EMCY_MEAS_LATE, msef) == 1 && msef[2] == DRIVE_LATE_DUPLICATE_OR_OLD);
    EXPECT(g_app.late == 3u && g_app.lost == 7u);
    EXPECT(sample(&m, 22) != NULL);
    EXPECT(count_emcy(0x0000, NULL) == 1);
    EXPECT(sdo_read_u32(OD_DRIVE_DRIVE_STATUS_IDX, OD_DRIVE_DRIVE_STATUS_LATE_MEASUREMENTS_SUB) == 3u);
    /* sample_index wraps 65535 -> 0 without loss */
    EXPECT(sample(&m, 23) != NULL);
    g_app.last_sample_index = 65535u; /* jump the sequence there */
    EXPECT(sample(&m, 0) != NULL);
    EXPECT(g_app.lost == 7u && g_app.late == 3u);
    printf("(b) lost = %u (gaps 1 + 5 + 1), late = %u (RPDO1 alone, RPDO2 alone, duplicate), EMCY 0xFF01/0xFF02 + reset\n",
           (unsigned)g_app.lost, (unsigned)g_app.late);
}

/* ------------------------------------------------------------------ (c) */

static void test_sdo_gains(void)
{
    setup();
    drive_t ref;
    drive_config_t cfg;
    drive_default_config(&cfg);
    drive_init(&ref, &cfg);
    drive_meas_t m = {0.5f, -0.2f, 1.0f};
    drive_cmd_t c;
    ref.sp.iq_ref_A = 1.0f;
    EXPECT(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_IQ_REF_A_SUB, 1.0f) == 0);
    for (uint16_t k = 0; k < 5; ++k) {
        EXPECT(sample(&m, k) != NULL);
        drive_current_step(&ref, &m, &c);
    }
    const float K1_before = sdo_read_f32(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_K1_ACTIVE_V_A_SUB);
    EXPECT(same_bits(K1_before, ref.db.K1q_V_A));

    /* the real frame: 23 00 22 06 <REAL32 LE> (expedited download, 4 bytes) */
    const float Lq_new = 2.27e-3f; /* 50 % of the motor's Lq */
    uint8_t d[8] = {0x23, 0x00, 0x22, 0x06, 0, 0, 0, 0};
    put_f32(&d[4], Lq_new);
    g_ncap = 0;
    inject(COB_SDO_RX, 8, d);
    deliver();
    const co_frame_t *r = find(COB_SDO_TX, 0);
    EXPECT(r && r->data[0] == 0x60 && r->data[1] == 0x00 && r->data[2] == 0x22 && r->data[3] == 0x06);
    EXPECT(same_bits(OD_DRIVE.mfr.x2200_Controller.Lq_hat_H, Lq_new));
    EXPECT(same_bits(g_app.drv.db.K1q_V_A, K1_before)); /* not before the next step */

    ref.cfg.Lq_hat_H = Lq_new; /* the same mismatch knob, written directly ... */
    drive_apply_config(&ref); /* ... through the one config-change path */
    const co_frame_t *f = sample(&m, 5);
    drive_current_step(&ref, &m, &c);
    EXPECT(f && same_bits(get_f32(&f->data[0]), c.v_alpha_V) && same_bits(get_f32(&f->data[4]), c.v_beta_V));
    const float K1_after = sdo_read_f32(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_K1_ACTIVE_V_A_SUB);
    float A, B, K1e, K2e;
    you2019_deadbeat_model_gains(55e-6f, 1.4f, Lq_new, &A, &B);
    you2019_deadbeat_controller_gains(A, B, &K1e, &K2e);
    EXPECT(same_bits(K1_after, K1e) && same_bits(K1_after, ref.db.K1q_V_A));
    EXPECT(K1_after < 0.6f * K1_before);

    /* aborts: range, unimplemented controller, invalid combinations */
    EXPECT(sdo_write_f32(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_LQ_HAT_H_SUB, 20.0f) == CO_ABORT_VALUE_HIGH);
    EXPECT(sdo_write_f32(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_LQ_HAT_H_SUB, NAN) == CO_ABORT_INVALID_VALUE);
    EXPECT(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 5) == CO_ABORT_INVALID_VALUE);
    EXPECT(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_DEADTIME_COMP_ENABLE_SUB, 1) == 0);
    EXPECT(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_ESTIMATOR_ENABLE_SUB, 0) == CO_ABORT_PARAM_INCOMPAT);
    EXPECT(sdo_write_f32(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_PI_BANDWIDTH_HZ_SUB, 5000.0f) == CO_ABORT_PARAM_INCOMPAT);
    EXPECT(sdo_write_f32(OD_DRIVE_OUTER_LOOPS_IDX, OD_DRIVE_OUTER_LOOPS_POSITION_BANDWIDTH_HZ_SUB, 200.0f) == CO_ABORT_PARAM_INCOMPAT);
    EXPECT(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 1) == 0); /* PI */
    EXPECT(sdo_write_u8(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_ENABLE_SUB, 1) == CO_ABORT_PARAM_INCOMPAT);
    EXPECT(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 2) == 0); /* deadbeat */
    EXPECT(sdo_write_u8(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_ENABLE_SUB, 1) == 0);
    EXPECT(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 1) == CO_ABORT_PARAM_INCOMPAT);
    EXPECT(sdo_write_u8(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_AVERAGE_M_SUB, 17) == CO_ABORT_VALUE_HIGH);

    /* a non-watched field (memory reading) reaches the core through drive_apply_config */
    EXPECT(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_LIMITED_MEMORY_SUB, 1) == 0);
    EXPECT(g_app.drv.cfg.limited_memory == 1u && g_app.drv.st.dirty == 1u);
    EXPECT(g_app.drv.cfg.deadtime_comp_enable == 1u && g_app.drv.cfg.ident.enable == 1u);
    EXPECT(sample(&m, 6) != NULL);
    EXPECT(g_app.drv.st.dirty == 0u);
    printf("(c) SDO 23 00 22 06 Lq_hat = %.3g H: K1 %.3f -> %.3f V/A at the next step (bit-identical to the core); aborts OK\n",
           (double)Lq_new, (double)K1_before, (double)K1_after);
}

/* ------------------------------------------------------------------ (d) */

#define TR_CH 4
#define TR_STEPS 6000
static float g_sig[TR_STEPS][TR_CH];
static uint8_t g_up[TRACE_BUFFER_SAMPLES * 4 + 16];

static void test_trace(void)
{
    setup();
    const uint8_t sigs[TR_CH] = {TRACE_SIG_I_A, TRACE_SIG_IQ, TRACE_SIG_V_ALPHA, TRACE_SIG_THETA};
    const uint16_t pre = 100;
    const float level = 0.5f;
    EXPECT(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_SIGNAL_COUNT_SUB, TR_CH) == 0);
    for (uint8_t i = 0; i < TR_CH; ++i) EXPECT(sdo_write_u8(OD_DRIVE_TRACE_IDX, (uint8_t)(OD_DRIVE_TRACE_SIGNAL_1_SUB + i), sigs[i]) == 0);
    EXPECT(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_TRIGGER_SIGNAL_SUB, TRACE_SIG_I_A) == 0);
    EXPECT(sdo_write_f32(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_TRIGGER_LEVEL_SUB, level) == 0);
    EXPECT(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_TRIGGER_EDGE_SUB, 1) == 0); /* rising */
    EXPECT(sdo_write_u16(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_PRETRIGGER_SAMPLES_SUB, pre) == 0);
    EXPECT(sdo_write_u16(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_DECIMATION_SUB, 1) == 0);
    /* invalid combination: pre-trigger >= depth (8192 / 4) */
    EXPECT(sdo_write_u16(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_PRETRIGGER_SAMPLES_SUB, 2048) == 0);
    EXPECT(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB, 1) == CO_ABORT_PARAM_INCOMPAT);
    EXPECT(sdo_write_u16(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_PRETRIGGER_SAMPLES_SUB, pre) == 0);
    EXPECT(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_SIGNAL_2_SUB, 200) == CO_ABORT_VALUE_HIGH);
    EXPECT(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB, 3) == CO_ABORT_INVALID_VALUE);
    EXPECT(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB, 1) == 0); /* arm */
    EXPECT(sdo_read_u32(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB) == 1u);

    const int trig_step = 3000; /* i_a crosses 0.5 A there: the ring has wrapped */
    const uint32_t depth = TRACE_BUFFER_SAMPLES / TR_CH;
    int steps = 0;
    for (int k = 0; k < TR_STEPS; ++k) {
        const float t = (float)k * 55e-6f;
        drive_meas_t m = {k < trig_step ? 0.2f * sinf(300.0f * t) : 1.0f + 0.1f * sinf(700.0f * t),
                          -0.3f * cosf(300.0f * t), 0.001f * (float)k};
        EXPECT(sample(&m, (uint16_t)k) != NULL);
        for (int c = 0; c < TR_CH; ++c) g_sig[k][c] = drive_signal(&g_app.drv, (trace_signal_t)sigs[c]);
        ++steps;
        if (g_app.trace.status == TRACE_DONE) break;
    }
    EXPECT(steps == trig_step + (int)(depth - pre)); /* rows after the trigger incl. itself */
    EXPECT(sdo_read_u32(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB) == 3u);
    const uint32_t bytes = sdo_read_u32(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_CAPTURED_BYTES_SUB);
    EXPECT(bytes == depth * TR_CH * 4u);
    EXPECT(sdo_read_u32(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_TRIGGER_ROW_SUB) == pre);

    uint32_t segs = 0;
    long n = sdo_upload_segmented(OD_DRIVE_TRACE_BUFFER_IDX, 0, g_up, sizeof g_up, &segs);
    EXPECT(n == (long)bytes);
    int mism = 0;
    const int first = trig_step - pre;
    for (uint32_t row = 0; n > 0 && row < depth; ++row)
        for (int c = 0; c < TR_CH; ++c)
            if (!same_bits(get_f32(&g_up[(row * TR_CH + (uint32_t)c) * 4u]), g_sig[first + (int)row][c])) ++mism;
    EXPECT(mism == 0);
    EXPECT(get_f32(&g_up[(pre * TR_CH) * 4u]) >= level && get_f32(&g_up[((pre - 1u) * TR_CH) * 4u]) < level);
    /* a second upload gives the same bytes (linearised once, in place) */
    static uint8_t again[TRACE_BUFFER_SAMPLES * 4 + 16];
    uint32_t segs2 = 0;
    EXPECT(sdo_upload_segmented(OD_DRIVE_TRACE_BUFFER_IDX, 0, again, sizeof again, &segs2) == n &&
          memcmp(again, g_up, (size_t)bytes) == 0);
    /* re-arm: buffer empty until done again */
    EXPECT(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB, 1) == 0);
    EXPECT(sdo_read_u32(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_CAPTURED_BYTES_SUB) == 0u);
    EXPECT(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB, 0) == 0);
    EXPECT(sdo_read_u32(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB) == 0u);
    printf("(d) trace %d ch x %u rows, trigger at step %d (pre %u): %ld bytes in %u SDO segments, %d mismatches\n", TR_CH,
           (unsigned)depth, trig_step, (unsigned)pre, n, (unsigned)segs, mism);
}

/* ------------------------------------------------------------------ (e) */

static void test_rpdo3_refs(void)
{
    setup();
    drive_t ref;
    drive_config_t cfg;
    drive_default_config(&cfg);
    drive_init(&ref, &cfg);
    drive_meas_t m = {0.3f, 0.1f, 0.7f};
    drive_cmd_t c;
    int identical = 0;
    const float iq_refs[4] = {1.0f, 3.0f, -2.0f, 0.5f};
    const float id_refs[4] = {0.0f, -0.5f, 0.25f, 0.0f};
    for (int k = 0; k < 40; ++k) {
        if (k % 10 == 0) {
            uint8_t d[8];
            put_f32(&d[0], iq_refs[k / 10]);
            put_f32(&d[4], id_refs[k / 10]);
            g_ncap = 0;
            inject(COB_REF, 8, d); /* bench RPDO3 {iq_ref_A, id_ref_A} */
            deliver();
            EXPECT(g_ncap == 0); /* no step, no frame for a reference */
            ref.sp.iq_ref_A = iq_refs[k / 10];
            ref.sp.id_ref_A = id_refs[k / 10];
        }
        const co_frame_t *f = sample(&m, (uint16_t)k);
        drive_current_step(&ref, &m, &c);
        if (f && same_bits(get_f32(&f->data[0]), c.v_alpha_V) && same_bits(get_f32(&f->data[4]), c.v_beta_V))
            ++identical;
        EXPECT(same_bits(g_app.drv.st.iq_ref_A, iq_refs[k / 10]) && same_bits(g_app.drv.st.id_ref_A, id_refs[k / 10]));
    }
    EXPECT(identical == 40);
    EXPECT(same_bits(sdo_read_f32(OD_DRIVE_DRIVE_STATUS_IDX, OD_DRIVE_DRIVE_STATUS_IQ_REF_ACTIVE_A_SUB), 0.5f));
    /* a NaN by PDO (no range check on PDOs) is ignored */
    uint8_t d[8];
    put_f32(&d[0], NAN);
    put_f32(&d[4], 0.0f);
    inject(COB_REF, 8, d);
    deliver();
    EXPECT(sample(&m, 40) != NULL);
    EXPECT(same_bits(g_app.drv.st.iq_ref_A, 0.5f));
    printf("(e) RPDO3 references: 4 steps of iq/id_ref, %d/40 commands bit-identical\n", identical);
}

/* ------------------------------------------------------------------ (f) */

static void test_open_loop_and_live(void)
{
    setup();
    EXPECT(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_V_D_OPEN_V_SUB, 3.0f) == 0);
    EXPECT(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_V_Q_OPEN_V_SUB, 12.0f) == 0);
    EXPECT(sdo_write_u8(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_MODE_SUB, 3) == 0);
    int ok = 0;
    for (int k = 0; k < 20; ++k) {
        drive_meas_t m = {0.1f, 0.2f, 0.05f * (float)k};
        const co_frame_t *f = sample(&m, (uint16_t)k);
        const float th = dq_wrap_pi(5.0f * m.theta_m_rad);
        float va, vb;
        dq_inv_park(3.0f, 12.0f, cosf(th), sinf(th), &va, &vb);
        if (f && same_bits(get_f32(&f->data[0]), va) && same_bits(get_f32(&f->data[4]), vb)) ++ok;
    }
    EXPECT(ok == 20);
    /* controller 0 is the same open loop */
    EXPECT(sdo_write_u8(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_MODE_SUB, 0) == 0);
    EXPECT(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 0) == 0);
    drive_meas_t m = {0.1f, 0.2f, 1.0f};
    const co_frame_t *f = sample(&m, 20);
    float va, vb;
    const float th = dq_wrap_pi(5.0f * 1.0f);
    dq_inv_park(3.0f, 12.0f, cosf(th), sinf(th), &va, &vb);
    EXPECT(f && same_bits(get_f32(&f->data[0]), va) && same_bits(get_f32(&f->data[4]), vb));
    EXPECT(g_app.open_loop == 1u);
    EXPECT(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 2) == 0);

    /* live trace TPDO2: disabled by default, enabled by clearing bit 31 of 0x1801:01 */
    int live = 0;
    for (int k = 21; k < 37; ++k) { sample(&m, (uint16_t)k); live += find(COB_LIVE, 0) != NULL; }
    EXPECT(live == 0);
    EXPECT(sdo_write_u32(0x1801, 1, COB_LIVE) == 0);
    EXPECT(sdo_write_u16(OD_DRIVE_LIVE_TRACE_IDX, OD_DRIVE_LIVE_TRACE_DECIMATION_SUB, 4) == 0);
    int order_ok = 1;
    for (int k = 37; k < 53; ++k) {
        const co_frame_t *c = sample(&m, (uint16_t)k);
        const co_frame_t *l = find(COB_LIVE, 0);
        if (l) {
            ++live;
            order_ok &= c != NULL && c < l; /* command first */
            order_ok &= same_bits(get_f32(&l->data[0]), g_app.drv.st.i_q_A) &&
                        same_bits(get_f32(&l->data[4]), g_app.drv.st.iq_ref_A);
        }
    }
    EXPECT(live == 4 && order_ok);
    printf("(f) open loop: 21/21 commands = inverse Park of (3, 12) V; live TPDO2: %d frames in 16 steps (decimation 4)\n",
           live);
}

int main(void)
{
    test_bit_identical();
    test_lost_late();
    test_sdo_gains();
    test_trace();
    test_rpdo3_refs();
    test_open_loop_and_live();
    if (g_fail) {
        fprintf(stderr, "test_shim_drive_app: %d check(s) failed\n", g_fail);
        return 1;
    }
    printf("test_shim_drive_app: all checks passed\n");
    return 0;
}
