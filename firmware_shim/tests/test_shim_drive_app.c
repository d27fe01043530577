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

#include "check.h"
#include "co_node.h"
#include "drive_app.h"
#include "drive_core.h"
#include "drive_plant.h"
#include "dq_math.h"
#include "od_drive.h"
#include "shim_testbus.h"

#define STEP_US 55 /* bus time of one exchange */

/* ------------------------------------------------------------------ (a) */

static void test_bit_identical(void)
{
    setup(STEP_US);
    drive_t ref;
    drive_config_t cfg;
    drive_default_config(&cfg);
    drive_init(&ref, &cfg);
    ref.sp.iq_ref_A = 2.0f;
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_IQ_REF_A_SUB, 2.0f) == 0);

    drive_plant_t pl;
    drive_plant_init(&pl, "you2019");
    pl.rotating = 1;
    pl.rk4.omega_m_rad_s = 100.0; /* rad/s mechanical, fixed */
    int frames = 0, identical = 0;
    const int N = 400;
    for (int k = 0; k < N; ++k) {
        drive_meas_t m;
        drive_plant_measure(&pl, &m);
        if (k == 200) { /* step of the reference by SDO, mirrored in the reference drive */
            ref.sp.iq_ref_A = -1.5f;
            CHECK_TRUE(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_IQ_REF_A_SUB, -1.5f) == 0);
        }
        const co_frame_t *f = sample(&m, (uint16_t)k);
        drive_cmd_t c;
        drive_current_step(&ref, &m, &c);
        if (f) {
            ++frames;
            CHECK_TRUE(f->dlc == 8);
            if (cmd_is(f, c.v_alpha_V, c.v_beta_V)) ++identical;
        }
        CHECK_TRUE(find(COB_EMCY, 0) == NULL);
        drive_cmd_t applied = {testbus_get_f32(f ? &f->data[0] : (const uint8_t *)"\0\0\0\0\0\0\0\0"),
                               testbus_get_f32(f ? &f->data[4] : (const uint8_t *)"\0\0\0\0\0\0\0\0")};
        drive_plant_advance(&pl, &applied);
    }
    CHECK_TRUE(frames == N);
    CHECK_TRUE(identical == N);
    CHECK_TRUE(g_app.sup.drive_status.current_steps == (uint32_t)N);
    CHECK_TRUE(g_app.sup.drive_status.lost_measurements == 0u && g_app.sup.drive_status.late_measurements == 0u);
    CHECK_TRUE(sdo_read_u32(OD_DRIVE_DRIVE_STATUS_IDX, OD_DRIVE_DRIVE_STATUS_CURRENT_STEPS_SUB) == (uint32_t)N);
    float iq = sdo_read_f32(OD_DRIVE_DRIVE_STATUS_IDX, OD_DRIVE_DRIVE_STATUS_IQ_A_SUB);
    CHECK_TRUE(testbus_same_f32(iq, ref.st.i_q_A));
    CHECK_TRUE(fabsf(iq - (-1.5f)) < 0.1f); /* deadbeat settled on the step */
    CHECK_TRUE(ref.st.step_count == (uint32_t)N && g_app.drv.st.step_count == (uint32_t)N);
    printf("(a) %d measurements -> %d command frames, %d bit-identical to drive_current_step; iq = %.4f A (ref -1.5)\n",
           N, frames, identical, (double)iq);
}

/* ------------------------------------------------------------------ (b) */

static int count_emcy(uint16_t code, uint8_t *msef_out)
{
    int n = 0;
    for (int i = 0;; ++i) {
        const co_frame_t *e = find(COB_EMCY, i);
        if (!e) break;
        uint16_t c = (uint16_t)(e->data[0] | e->data[1] << 8);
        if (c == code) {
            ++n;
            if (msef_out) memcpy(msef_out, &e->data[3], 5);
        }
    }
    return n;
}

static void test_lost_late(void)
{
    setup(STEP_US);
    drive_meas_t m = {0.1f, -0.05f, 0.3f};
    for (uint16_t k = 0; k < 10; ++k) CHECK_TRUE(sample(&m, k) != NULL);
    CHECK_TRUE(g_app.sup.drive_status.lost_measurements == 0u && g_app.sup.drive_status.late_measurements == 0u);

    /* sample 10 (SYNC + both PDOs) never arrives: only its SYNC */
    next_sync();
    uint8_t sc = g_sync;
    testbus_clear(&g_tb);
    inject(0x080, 1, &sc);
    deliver();
    CHECK_TRUE(find(COB_CMD, 0) == NULL);
    /* sample 11 */
    const co_frame_t *f = sample(&m, 11);
    CHECK_TRUE(f != NULL); /* still answered */
    uint8_t msef[5];
    CHECK_TRUE(count_emcy(DRIVE_EMCY_MEAS_LOST, msef) == 1);
    CHECK_TRUE(find(COB_EMCY, 0) > f); /* the command goes out first */
    CHECK_TRUE(msef[0] == 11 && msef[1] == 0 && msef[2] == 1 && msef[3] == 0);
    CHECK_TRUE(g_app.sup.drive_status.lost_measurements == 1u);
    CHECK_TRUE(sdo_read_u32(OD_DRIVE_DRIVE_STATUS_IDX, OD_DRIVE_DRIVE_STATUS_LOST_MEASUREMENTS_SUB) == 1u);
    uint8_t reg[4];
    CHECK_TRUE(sdo_read(0x1001, 0, reg) == 0 && (reg[0] & 0x91u) == 0x91u); /* generic+communication+manufacturer */
    CHECK_TRUE(sdo_read_u32(0x1003, 1) == DRIVE_EMCY_MEAS_LOST);
    /* a gap of 5 (12..16 missing) in one go */
    CHECK_TRUE(sample(&m, 17) != NULL);
    CHECK_TRUE(count_emcy(DRIVE_EMCY_MEAS_LOST, msef) == 1 && msef[2] == 5);
    CHECK_TRUE(g_app.sup.drive_status.lost_measurements == 6u);
    /* next good one clears the error: EMCY 0x0000 */
    CHECK_TRUE(sample(&m, 18) != NULL);
    CHECK_TRUE(count_emcy(0x0000, NULL) == 1);
    CHECK_TRUE(sdo_read(0x1001, 0, reg) == 0 && reg[0] == 0u);

    /* RPDO1 without its RPDO2 (sample 19), detected at the next SYNC */
    CHECK_TRUE(sample_ex(&m, 19, 1, 0) == NULL);
    f = sample(&m, 20);
    CHECK_TRUE(f != NULL);
    CHECK_TRUE(count_emcy(DRIVE_EMCY_MEAS_LATE, msef) == 1 && msef[2] == DRIVE_LATE_RPDO1_WITHOUT_RPDO2);
    CHECK_TRUE(count_emcy(DRIVE_EMCY_MEAS_LOST, NULL) == 1); /* and 19 is missing from the sequence */
    CHECK_TRUE(g_app.sup.drive_status.late_measurements == 1u && g_app.sup.drive_status.lost_measurements == 7u);
    /* RPDO2 without a fresh RPDO1: still a step (command), counted late */
    f = sample_ex(&m, 21, 0, 1);
    CHECK_TRUE(f != NULL);
    CHECK_TRUE(count_emcy(DRIVE_EMCY_MEAS_LATE, msef) == 1 && msef[2] == DRIVE_LATE_RPDO2_WITHOUT_RPDO1);
    CHECK_TRUE(g_app.sup.drive_status.late_measurements == 2u);
    /* duplicate sample_index: counted late, no second step (its command is out) */
    CHECK_TRUE(sample(&m, 21) == NULL);
    CHECK_TRUE(count_emcy(DRIVE_EMCY_MEAS_LATE, msef) == 1 && msef[2] == DRIVE_LATE_DUPLICATE_OR_OLD);
    CHECK_TRUE(g_app.sup.drive_status.late_measurements == 3u && g_app.sup.drive_status.lost_measurements == 7u);
    CHECK_TRUE(sample(&m, 22) != NULL);
    CHECK_TRUE(count_emcy(0x0000, NULL) == 1);
    CHECK_TRUE(sdo_read_u32(OD_DRIVE_DRIVE_STATUS_IDX, OD_DRIVE_DRIVE_STATUS_LATE_MEASUREMENTS_SUB) == 3u);
    /* sample_index wraps 65535 -> 0 without loss */
    CHECK_TRUE(sample(&m, 23) != NULL);
    g_app.sup.drive_status.last_sample_index = 65535u; /* jump the sequence there */
    CHECK_TRUE(sample(&m, 0) != NULL);
    CHECK_TRUE(g_app.sup.drive_status.lost_measurements == 7u && g_app.sup.drive_status.late_measurements == 3u);
    printf(
        "(b) lost = %u (gaps 1 + 5 + 1), late = %u (RPDO1 alone, RPDO2 alone, duplicate), EMCY 0xFF01/0xFF02 + reset\n",
        (unsigned)g_app.sup.drive_status.lost_measurements, (unsigned)g_app.sup.drive_status.late_measurements);
}

/* ------------------------------------------------------------------ (c) */

static void test_sdo_gains(void)
{
    setup(STEP_US);
    drive_t ref;
    drive_config_t cfg;
    drive_default_config(&cfg);
    drive_init(&ref, &cfg);
    drive_meas_t m = {0.5f, -0.2f, 1.0f};
    drive_cmd_t c;
    ref.sp.iq_ref_A = 1.0f;
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_IQ_REF_A_SUB, 1.0f) == 0);
    for (uint16_t k = 0; k < 5; ++k) {
        CHECK_TRUE(sample(&m, k) != NULL);
        drive_current_step(&ref, &m, &c);
    }
    const float K1_before = sdo_read_f32(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_K1_ACTIVE_V_A_SUB);
    CHECK_TRUE(testbus_same_f32(K1_before, YOU2019_OF(ref)->db.K1q_V_A));

    /* the real frame: 23 00 22 06 <REAL32 LE> (expedited download, 4 bytes) */
    const float Lq_new = 2.27e-3f; /* 50 % of the motor's Lq */
    uint8_t d[8] = {0x23, 0x00, 0x22, 0x06, 0, 0, 0, 0};
    testbus_put_f32(&d[4], Lq_new);
    testbus_clear(&g_tb);
    inject(COB_SDO_RX, 8, d);
    deliver();
    const co_frame_t *r = find(COB_SDO_TX, 0);
    CHECK_TRUE(r && r->data[0] == 0x60 && r->data[1] == 0x00 && r->data[2] == 0x22 && r->data[3] == 0x06);
    CHECK_TRUE(testbus_same_f32(OD_DRIVE.mfr.x2200_Controller.Lq_hat_H, Lq_new));
    CHECK_TRUE(testbus_same_f32(YOU2019_OF(g_app.drv)->db.K1q_V_A, K1_before)); /* not before the next step */

    ref.cfg.Lq_hat_H = Lq_new; /* the same mismatch knob, written directly ... */
    drive_apply_config(&ref);  /* ... through the one config-change path */
    const co_frame_t *f = sample(&m, 5);
    drive_current_step(&ref, &m, &c);
    CHECK_TRUE(cmd_is(f, c.v_alpha_V, c.v_beta_V));
    const float K1_after = sdo_read_f32(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_K1_ACTIVE_V_A_SUB);
    float A, B, K1e, K2e;
    you2019_deadbeat_model_gains(55e-6f, 1.4f, Lq_new, &A, &B);
    you2019_deadbeat_controller_gains(A, B, &K1e, &K2e);
    CHECK_TRUE(testbus_same_f32(K1_after, K1e) && testbus_same_f32(K1_after, YOU2019_OF(ref)->db.K1q_V_A));
    CHECK_TRUE(K1_after < 0.6f * K1_before);

    /* aborts: range, unimplemented controller, invalid combinations */
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_LQ_HAT_H_SUB, 20.0f) == CO_ABORT_VALUE_HIGH);
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_LQ_HAT_H_SUB, NAN) == CO_ABORT_INVALID_VALUE);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 5) == CO_ABORT_INVALID_VALUE);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_DEADTIME_COMP_ENABLE_SUB, 1) == 0);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_ESTIMATOR_ENABLE_SUB, 0) ==
               CO_ABORT_PARAM_INCOMPAT);
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_PI_BANDWIDTH_HZ_SUB, 5000.0f) ==
               CO_ABORT_PARAM_INCOMPAT);
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_OUTER_LOOPS_IDX, OD_DRIVE_OUTER_LOOPS_POSITION_BANDWIDTH_HZ_SUB, 200.0f) ==
               CO_ABORT_PARAM_INCOMPAT);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 1) == 0); /* PI */
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_ENABLE_SUB, 1) ==
               CO_ABORT_PARAM_INCOMPAT);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 2) == 0); /* deadbeat */
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_ENABLE_SUB, 1) == 0);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 1) == CO_ABORT_PARAM_INCOMPAT);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_AVERAGE_M_SUB, 17) ==
               CO_ABORT_VALUE_HIGH);

    /* a setting of the law's record (memory reading) reaches the law through drive_apply_config */
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_LIMITED_MEMORY_SUB, 1) == 0);
    const od_drive_online_tuning_t *held = (const od_drive_online_tuning_t *)drive_law_record(&g_app.drv);
    CHECK_TRUE(held->limited_memory == 1u && g_app.drv.st.dirty == 1u);
    CHECK_TRUE(held->deadtime_comp_enable == 1u && held->enable == 1u);
    CHECK_TRUE(sample(&m, 6) != NULL);
    CHECK_TRUE(g_app.drv.st.dirty == 0u);
    printf("(c) SDO 23 00 22 06 Lq_hat = %.3g H: K1 %.3f -> %.3f V/A at the next step (bit-identical to the core); "
           "aborts OK\n",
           (double)Lq_new, (double)K1_before, (double)K1_after);
}

/* ------------------------------------------------------------------ (d) */

#define TR_CH 4
#define TR_STEPS 6000
static float g_sig[TR_STEPS][TR_CH];
static uint8_t g_up[TRACE_BUFFER_SAMPLES * 4 + 16];

static void test_trace(void)
{
    setup(STEP_US);
    const uint8_t sigs[TR_CH] = {TRACE_SIG_I_A, TRACE_SIG_IQ, TRACE_SIG_V_ALPHA, TRACE_SIG_THETA};
    const uint16_t pre = 100;
    const float level = 0.5f;
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_SIGNAL_COUNT_SUB, TR_CH) == 0);
    for (uint8_t i = 0; i < TR_CH; ++i)
        CHECK_TRUE(sdo_write_u8(OD_DRIVE_TRACE_IDX, (uint8_t)(OD_DRIVE_TRACE_SIGNAL_1_SUB + i), sigs[i]) == 0);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_TRIGGER_SIGNAL_SUB, TRACE_SIG_I_A) == 0);
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_TRIGGER_LEVEL_SUB, level) == 0);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_TRIGGER_EDGE_SUB, 1) == 0); /* rising */
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_PRETRIGGER_SAMPLES_SUB, pre) == 0);
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_DECIMATION_SUB, 1) == 0);
    /* invalid combination: pre-trigger >= depth (8192 / 4) */
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_PRETRIGGER_SAMPLES_SUB, 2048) == 0);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB, 1) == CO_ABORT_PARAM_INCOMPAT);
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_PRETRIGGER_SAMPLES_SUB, pre) == 0);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_SIGNAL_2_SUB, 200) == CO_ABORT_VALUE_HIGH);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB, 3) == CO_ABORT_INVALID_VALUE);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB, 1) == 0); /* arm */
    CHECK_TRUE(sdo_read_u32(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB) == 1u);

    const int trig_step = 3000; /* i_a crosses 0.5 A there: the ring has wrapped */
    const uint32_t depth = TRACE_BUFFER_SAMPLES / TR_CH;
    int steps = 0;
    for (int k = 0; k < TR_STEPS; ++k) {
        const float t = (float)k * 55e-6f;
        drive_meas_t m = {k < trig_step ? 0.2f * sinf(300.0f * t) : 1.0f + 0.1f * sinf(700.0f * t),
                          -0.3f * cosf(300.0f * t), 0.001f * (float)k};
        CHECK_TRUE(sample(&m, (uint16_t)k) != NULL);
        for (int c = 0; c < TR_CH; ++c) g_sig[k][c] = drive_signal(&g_app.drv, (trace_signal_t)sigs[c]);
        ++steps;
        if (g_app.rec.trace.status == TRACE_DONE) break;
    }
    CHECK_TRUE(steps == trig_step + (int)(depth - pre)); /* rows after the trigger incl. itself */
    CHECK_TRUE(sdo_read_u32(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB) == 3u);
    const uint32_t bytes = sdo_read_u32(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_CAPTURED_BYTES_SUB);
    CHECK_TRUE(bytes == depth * TR_CH * 4u);
    CHECK_TRUE(sdo_read_u32(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_TRIGGER_ROW_SUB) == pre);

    uint32_t segs = 0;
    long n = sdo_upload_segmented(OD_DRIVE_TRACE_BUFFER_IDX, 0, g_up, sizeof g_up, &segs);
    CHECK_TRUE(n == (long)bytes);
    int mism = 0;
    const int first = trig_step - pre;
    for (uint32_t row = 0; n > 0 && row < depth; ++row)
        for (int c = 0; c < TR_CH; ++c)
            if (!testbus_same_f32(testbus_get_f32(&g_up[(row * TR_CH + (uint32_t)c) * 4u]), g_sig[first + (int)row][c]))
                ++mism;
    CHECK_TRUE(mism == 0);
    CHECK_TRUE(testbus_get_f32(&g_up[(pre * TR_CH) * 4u]) >= level &&
               testbus_get_f32(&g_up[((pre - 1u) * TR_CH) * 4u]) < level);
    /* a second upload gives the same bytes (linearised once, in place) */
    static uint8_t again[TRACE_BUFFER_SAMPLES * 4 + 16];
    uint32_t segs2 = 0;
    CHECK_TRUE(sdo_upload_segmented(OD_DRIVE_TRACE_BUFFER_IDX, 0, again, sizeof again, &segs2) == n &&
               memcmp(again, g_up, (size_t)bytes) == 0);
    /* re-arm: buffer empty until done again */
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB, 1) == 0);
    CHECK_TRUE(sdo_read_u32(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_CAPTURED_BYTES_SUB) == 0u);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB, 0) == 0);
    CHECK_TRUE(sdo_read_u32(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB) == 0u);
    printf("(d) trace %d ch x %u rows, trigger at step %d (pre %u): %ld bytes in %u SDO segments, %d mismatches\n",
           TR_CH, (unsigned)depth, trig_step, (unsigned)pre, n, (unsigned)segs, mism);
}

/* ------------------------------------------------------------------ (e) */

static void test_rpdo3_refs(void)
{
    setup(STEP_US);
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
            testbus_put_f32(&d[0], iq_refs[k / 10]);
            testbus_put_f32(&d[4], id_refs[k / 10]);
            testbus_clear(&g_tb);
            inject(COB_REF, 8, d); /* bench RPDO3 {iq_ref_A, id_ref_A} */
            deliver();
            CHECK_TRUE(testbus_node_frames(&g_tb) == 0); /* no step, no frame for a reference */
            ref.sp.iq_ref_A = iq_refs[k / 10];
            ref.sp.id_ref_A = id_refs[k / 10];
        }
        const co_frame_t *f = sample(&m, (uint16_t)k);
        drive_current_step(&ref, &m, &c);
        if (cmd_is(f, c.v_alpha_V, c.v_beta_V)) ++identical;
        CHECK_TRUE(testbus_same_f32(g_app.drv.st.iq_ref_A, iq_refs[k / 10]) &&
                   testbus_same_f32(g_app.drv.st.id_ref_A, id_refs[k / 10]));
    }
    CHECK_TRUE(identical == 40);
    CHECK_TRUE(
        testbus_same_f32(sdo_read_f32(OD_DRIVE_DRIVE_STATUS_IDX, OD_DRIVE_DRIVE_STATUS_IQ_REF_ACTIVE_A_SUB), 0.5f));
    /* a NaN by PDO (no range check on PDOs) is ignored */
    uint8_t d[8];
    testbus_put_f32(&d[0], NAN);
    testbus_put_f32(&d[4], 0.0f);
    inject(COB_REF, 8, d);
    deliver();
    CHECK_TRUE(sample(&m, 40) != NULL);
    CHECK_TRUE(testbus_same_f32(g_app.drv.st.iq_ref_A, 0.5f));
    printf("(e) RPDO3 references: 4 steps of iq/id_ref, %d/40 commands bit-identical\n", identical);
}

/* ------------------------------------------------------------------ (f) */

static void test_open_loop_and_live(void)
{
    setup(STEP_US);
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_V_D_OPEN_V_SUB, 3.0f) == 0);
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_V_Q_OPEN_V_SUB, 12.0f) == 0);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_MODE_SUB, 3) == 0);
    int ok = 0;
    for (int k = 0; k < 20; ++k) {
        drive_meas_t m = {0.1f, 0.2f, 0.05f * (float)k};
        const co_frame_t *f = sample(&m, (uint16_t)k);
        const float th = dq_wrap_pi(5.0f * m.theta_m_rad);
        float va, vb;
        dq_inv_park(3.0f, 12.0f, cosf(th), sinf(th), &va, &vb);
        if (cmd_is(f, va, vb)) ++ok;
    }
    CHECK_TRUE(ok == 20);
    /* controller 0 is the same open loop */
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_MODE_SUB, 0) == 0);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 0) == 0);
    drive_meas_t m = {0.1f, 0.2f, 1.0f};
    const co_frame_t *f = sample(&m, 20);
    float va, vb;
    const float th = dq_wrap_pi(5.0f * 1.0f);
    dq_inv_park(3.0f, 12.0f, cosf(th), sinf(th), &va, &vb);
    CHECK_TRUE(cmd_is(f, va, vb));
    CHECK_TRUE(g_app.open_loop == 1u);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_CONTROLLER_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 2) == 0);

    /* live trace TPDO2: disabled by default, enabled by clearing bit 31 of 0x1801:01 */
    int live = 0;
    for (int k = 21; k < 37; ++k) {
        sample(&m, (uint16_t)k);
        live += find(COB_LIVE, 0) != NULL;
    }
    CHECK_TRUE(live == 0);
    CHECK_TRUE(sdo_write_u32(0x1801, 1, COB_LIVE) == 0);
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_LIVE_TRACE_IDX, OD_DRIVE_LIVE_TRACE_DECIMATION_SUB, 4) == 0);
    int order_ok = 1;
    for (int k = 37; k < 53; ++k) {
        const co_frame_t *c = sample(&m, (uint16_t)k);
        const co_frame_t *l = find(COB_LIVE, 0);
        if (l) {
            ++live;
            order_ok &= c != NULL && c < l; /* command first */
            order_ok &= testbus_same_f32(testbus_get_f32(&l->data[0]), g_app.drv.st.i_q_A) &&
                        testbus_same_f32(testbus_get_f32(&l->data[4]), g_app.drv.st.iq_ref_A);
        }
    }
    CHECK_TRUE(live == 4 && order_ok);
    printf(
        "(f) open loop: 21/21 commands = inverse Park of (3, 12) V; live TPDO2: %d frames in 16 steps (decimation 4)\n",
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
    return check_finish("test_shim_drive_app");
}
