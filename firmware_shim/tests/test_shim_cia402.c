/* test_shim_cia402.c - the drive node as a CiA 402 device, frame by frame on the
 * in-process bus (shim_testbus.h): the drive_app glue and cia402_device.c.
 *
 *   (a) every transition 0..16 with its statusword (SDO and RPDO4), 0 V in
 *       every state but OPERATION ENABLED, the statusword TPDO3 at each change
 *   (b) CST (0x6060 = 10): the commands equal a reference core's with iq_ref =
 *       0x6071 / 1000 x 0x6076 / (1.5 p psi_hat), clamped to 0x6072; actual values
 *   (c) quick stop option codes 0, 2, 6; the step that ends a quick stop commands 0 V
 *   (d) faults: measurement timeout -> FAULT, 0x603F = 0xFF03; fault reset only on
 *       a rising edge of bit 7, the event-driven statusword TPDO3 at it; refused while
 *       the plant's heartbeat is lost, and a refused edge is consumed
 *   (e) NMT pre-operational while enabled -> SWITCH ON DISABLED; modes refused
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "cia402_device.h"
#include "co_node.h"
#include "drive_app.h"
#include "drive_core.h"
#include "od_drive.h"
#include "shim_testbus.h"

#define STEP_US 55
#define COB_RPDO4 (0x500u + DRIVE_ID)
#define COB_TPDO3 (0x380u + DRIVE_ID)
#define SW_MASK 0x6Fu

static uint16_t statusword(void) { return (uint16_t)sdo_read_u32(OD_DRIVE_STATUSWORD_IDX, 0); }

static int state_is(uint16_t mask, uint16_t value) { return (statusword() & mask) == value; }

/* RPDO4 {controlword, target torque} and TPDO3 {statusword, mode, torque, current} made valid (event-driven). */
static void enable_pdos(void)
{
    CHECK_TRUE(sdo_write_u32(0x1403, 1, COB_RPDO4) == 0);
    CHECK_TRUE(sdo_write_u32(0x1802, 1, COB_TPDO3) == 0);
    testbus_clear(&g_tb);
}

static void rpdo4(uint16_t cw, int16_t torque)
{
    const uint8_t d[4] = {(uint8_t)cw, (uint8_t)(cw >> 8), (uint8_t)torque, (uint8_t)((uint16_t)torque >> 8)};
    testbus_clear(&g_tb);
    inject(COB_RPDO4, 4, d);
    deliver();
}

/* The statusword of the last TPDO3 sent since the bus was cleared (-1: none). */
static int tpdo3_statusword(void)
{
    const co_frame_t *last = NULL;
    for (int i = 0;; ++i) {
        const co_frame_t *f = find(COB_TPDO3, i);
        if (f == NULL) break;
        last = f;
    }
    return last == NULL ? -1 : (int)(last->data[0] | (last->data[1] << 8));
}

static const drive_meas_t k_meas = {0.5f, -0.2f, 0.3f};

/* One sample; returns 1 if the command is 0 V. */
static int zero_cmd(uint16_t k)
{
    const co_frame_t *f = sample(&k_meas, k);
    CHECK_TRUE(f != NULL);
    return f != NULL && cmd_is(f, 0.0f, 0.0f);
}

/* ------------------------------------------------------------------ (a) */
static void test_transitions(void)
{
    setup(STEP_US); /* enabled by SDO (6, 7, 15) */
    enable_pdos();
    uint16_t k = 0;
    CHECK_TRUE(!zero_cmd(k++)); /* OPERATION ENABLED: the control acts */

    struct {
        uint16_t cw;
        uint16_t mask, sw; /* statusword expected (CiA 402-2 Table 30) */
        int zero_v;
        const char *what;
    } steps[] = {
        {0x0007u, SW_MASK, 0x23u, 1, "5 disable operation -> SWITCHED ON"},
        {0x000Fu, SW_MASK, 0x27u, 0, "4 enable operation -> OPERATION ENABLED"},
        {0x0006u, SW_MASK, 0x21u, 1, "8 shutdown -> READY TO SWITCH ON"},
        {0x0007u, SW_MASK, 0x23u, 1, "3 switch on -> SWITCHED ON"},
        {0x0006u, SW_MASK, 0x21u, 1, "6 shutdown -> READY TO SWITCH ON"},
        {0x0000u, 0x4Fu, 0x40u, 1, "7 disable voltage -> SWITCH ON DISABLED"},
        {0x0006u, SW_MASK, 0x21u, 1, "2 shutdown -> READY TO SWITCH ON"},
        {0x000Fu, SW_MASK, 0x27u, 0, "3+4 -> OPERATION ENABLED"},
        {0x0000u, 0x4Fu, 0x40u, 1, "9 disable voltage -> SWITCH ON DISABLED"},
        {0x0006u, SW_MASK, 0x21u, 1, "2"},
        {0x0007u, SW_MASK, 0x23u, 1, "3"},
        {0x0002u, 0x4Fu, 0x40u, 1, "10 quick stop -> SWITCH ON DISABLED"},
        {0x0006u, SW_MASK, 0x21u, 1, "2"},
        {0x0002u, 0x4Fu, 0x40u, 1, "7 quick stop -> SWITCH ON DISABLED"},
        {0x000Fu, 0x4Fu, 0x40u, 1, "no transition from SWITCH ON DISABLED on enable"},
    };
    int ok = 0;
    for (size_t i = 0; i < sizeof steps / sizeof steps[0]; ++i) {
        const int by_pdo = (i % 2u) == 0u; /* half by RPDO4, half by SDO */
        if (by_pdo) {
            rpdo4(steps[i].cw, 0);
        } else {
            CHECK_TRUE(sdo_write_u16(OD_DRIVE_CONTROLWORD_IDX, 0, steps[i].cw) == 0);
        }
        const int sent = tpdo3_statusword();
        const int good = state_is(steps[i].mask, steps[i].sw) && zero_cmd(k++) == steps[i].zero_v &&
                         (i == 14u ? sent == -1 : sent >= 0 && ((uint16_t)sent & steps[i].mask) == steps[i].sw);
        if (!good) printf("  transition step %zu failed: %s (statusword 0x%04X)\n", i, steps[i].what, statusword());
        ok += good;
    }
    CHECK_TRUE(ok == (int)(sizeof steps / sizeof steps[0]));
    CHECK_TRUE(sdo_read_u32(0x1000, 0) == 0x00020192u);
    printf("(a) %d controlwords (half by RPDO4, half by SDO): transitions 2-10 with their statuswords, 0 V outside "
           "OPERATION ENABLED, TPDO3 at each change\n",
           ok);
}

/* ------------------------------------------------------------------ (b) */
static void test_cst(void)
{
    setup(STEP_US);
    enable_pdos();
    const float T_rated_Nm = 1.26f, I_rated_A = 4.0f; /* the EDS defaults of 0x6076, 0x6075 */
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_MODES_OF_OPERATION_IDX, 0, (uint8_t)CIA402_MODE_CST) == 0);
    CHECK_TRUE(sdo_read_u32(OD_DRIVE_MODES_OF_OPERATION_DISPLAY_IDX, 0) == (uint8_t)CIA402_MODE_CST);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_MODES_OF_OPERATION_IDX, 0, 9u) == CO_ABORT_INVALID_VALUE); /* CSV: no */
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_MAX_TORQUE_IDX, 0, 600u) == 0);

    drive_t ref;
    drive_config_t cfg;
    drive_default_config(&cfg);
    drive_init(&ref, &cfg);
    const float Kt = 1.5f * cfg.pole_pairs * cfg.psi_hat_Wb;
    const int16_t targets[3] = {250, -400, 900}; /* 900 is clamped to 600 */
    int same = 0, n = 0;
    uint16_t k = 0;
    for (int t = 0; t < 3; ++t) {
        rpdo4(0x000Fu, targets[t]);
        const float tq = (float)(targets[t] > 600 ? 600 : targets[t]);
        ref.sp.iq_ref_A = tq * 1e-3f * 1260.0f * 1e-3f / Kt; /* as the drive computes it */
        ref.sp.id_ref_A = 0.0f;
        for (int i = 0; i < 30; ++i, ++k, ++n) {
            const co_frame_t *f = sample(&k_meas, k);
            drive_cmd_t c;
            drive_current_step(&ref, &k_meas, &c);
            same += f != NULL && cmd_is(f, c.v_alpha_V, c.v_beta_V);
        }
    }
    CHECK_TRUE(same == n);
    /* actual values: iq per mille of 0x6075, torque per mille of 0x6076, position in 65536 inc/rev */
    const int16_t i_pm = (int16_t)sdo_read_u32(OD_DRIVE_CURRENT_ACTUAL_VALUE_IDX, 0);
    const int16_t t_pm = (int16_t)sdo_read_u32(OD_DRIVE_TORQUE_ACTUAL_VALUE_IDX, 0);
    const int32_t pos = (int32_t)sdo_read_u32(OD_DRIVE_POSITION_ACTUAL_VALUE_IDX, 0);
    CHECK_TRUE(fabsf((float)i_pm - 1000.0f * g_app.drv.st.i_q_A / I_rated_A) <= 1.0f);
    CHECK_TRUE(fabsf((float)t_pm - 1000.0f * Kt * g_app.drv.st.i_q_A / T_rated_Nm) <= 1.0f);
    CHECK_TRUE(fabsf((float)pos - g_app.drv.outer.theta_unwrapped_rad * 65536.0f / 6.2831853f) <= 1.0f);
    printf("(b) CST: %d/%d commands = the reference core's at iq_ref = T/Kt (targets 250, -400, 900 -> 600 per "
           "mille); actual iq %d, torque %d per mille, position %ld inc\n",
           same, n, i_pm, t_pm, (long)pos);
}

/* ------------------------------------------------------------------ (c) */
static void test_quick_stop(void)
{
    uint16_t k = 0;
    /* option 0: SWITCH ON DISABLED at once */
    setup(STEP_US);
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_QUICK_STOP_OPTION_CODE_IDX, 0, 0u) == 0);
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_QUICK_STOP_OPTION_CODE_IDX, 0, 3u) == CO_ABORT_INVALID_VALUE);
    CHECK_TRUE(!zero_cmd(k++));
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_CONTROLWORD_IDX, 0, 0x0002u) == 0);
    CHECK_TRUE(state_is(0x4Fu, 0x40u) && zero_cmd(k++));

    /* option 2 (default): QUICK STOP ACTIVE, the current controlled to 0, then SWITCH ON DISABLED */
    setup(STEP_US);
    k = 0;
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_IQ_REF_A_SUB, 2.0f) == 0);
    drive_meas_t m = {0.0f, 1.0f, 0.0f}; /* theta 0: iq = i_beta = 2 i_b / sqrt(3) = 1.15 A */
    for (int i = 0; i < 5; ++i) CHECK_TRUE(!cmd_is(sample(&m, k++), 0.0f, 0.0f));
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_CONTROLWORD_IDX, 0, 0x000Bu) == 0); /* bit 2 = 0: quick stop */
    CHECK_TRUE(state_is(SW_MASK, 0x07u));
    /* the control acts with iq_ref = 0 */
    const co_frame_t *f = sample(&m, k++);
    CHECK_TRUE(f != NULL && !cmd_is(f, 0.0f, 0.0f) && testbus_get_f32(&f->data[4]) < 0.0f); /* pulls iq down */
    CHECK_TRUE(g_app.drv.sp.iq_ref_A == 0.0f && state_is(SW_MASK, 0x07u));
    m.i_b_A = 0.05f; /* iq = 0.058 A, within 2 % of 4 A: stopped */
    CHECK_TRUE(!cmd_is(sample(&m, k++), 0.0f, 0.0f) && state_is(SW_MASK, 0x07u)); /* measured now, seen next */
    CHECK_TRUE(zero_cmd(k++));                                                    /* the step that ends it: 0 V */
    CHECK_TRUE(state_is(0x4Fu, 0x40u));

    /* option 6: stays in QUICK STOP ACTIVE, enable operation returns (transition 16) */
    setup(STEP_US);
    k = 0;
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_QUICK_STOP_OPTION_CODE_IDX, 0, 6u) == 0);
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_CONTROLWORD_IDX, 0, 0x0002u) == 0);
    for (int i = 0; i < 5; ++i) sample(&k_meas, k++);
    CHECK_TRUE(state_is(SW_MASK, 0x07u));
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_CONTROLWORD_IDX, 0, 0x000Fu) == 0);
    CHECK_TRUE(state_is(SW_MASK, 0x27u));
    printf("(c) quick stop: option 0 -> SWITCH ON DISABLED at once; 2 -> iq controlled to 0, SWITCH ON DISABLED "
           "with 0 V in the step that finds it stopped; 6 stays, 16 back to OPERATION ENABLED\n");
}

/* ------------------------------------------------------------------ (d) */
static void test_faults(void)
{
    setup(STEP_US);
    enable_pdos();
    uint16_t k = 0;
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_SAFE_STATE_IDX, OD_DRIVE_SAFE_STATE_MEAS_TIMEOUT_PERIODS_SUB, 3u) == 0);
    for (int i = 0; i < 3; ++i) CHECK_TRUE(!zero_cmd(k++));
    testbus_clear(&g_tb);
    for (int i = 0; i < 3; ++i) {
        uint8_t sc = next_sync();
        inject(0x080, 1, &sc);
        deliver();
    }
    CHECK_TRUE(tpdo3_statusword() >= 0 && ((uint16_t)tpdo3_statusword() & 0x4Fu) == 0x08u);
    CHECK_TRUE(state_is(0x4Fu, 0x08u) && sdo_read_u32(OD_DRIVE_ERROR_CODE_IDX, 0) == DRIVE_EMCY_SAFE_MEAS_TIMEOUT);
    k = (uint16_t)(k + 3u);
    CHECK_TRUE(zero_cmd(k++));
    /* fault reset by RPDO4: bit 7 after a controlword without it; the event-driven TPDO3 tells it (a master
     * such as canopen's BaseNode402 waits for it) */
    rpdo4(0x0080u, 0);
    CHECK_TRUE(tpdo3_statusword() >= 0 && ((uint16_t)tpdo3_statusword() & 0x4Fu) == 0x40u);
    CHECK_TRUE(state_is(0x4Fu, 0x40u)); /* the first 0x80 after 0: a rising edge */
    CHECK_TRUE(sdo_read_u32(OD_DRIVE_ERROR_CODE_IDX, 0) == 0u && g_app.sup.safe_state.reason == 0u);
    enable_drive();
    CHECK_TRUE(!zero_cmd(k++));
    /* a second fault with bit 7 still high in the last controlword: 0x80 again is not an edge */
    rpdo4(0x0080u, 0); /* OPERATION ENABLED ignores a controlword with bit 7 */
    CHECK_TRUE(state_is(SW_MASK, 0x27u));
    testbus_clear(&g_tb);
    for (int i = 0; i < 3; ++i) {
        uint8_t sc = next_sync();
        inject(0x080, 1, &sc);
        deliver();
    }
    k = (uint16_t)(k + 3u);
    CHECK_TRUE(state_is(0x4Fu, 0x08u));
    rpdo4(0x0080u, 0);
    CHECK_TRUE(state_is(0x4Fu, 0x08u)); /* held: no edge */
    rpdo4(0x0000u, 0);
    rpdo4(0x0080u, 0);
    CHECK_TRUE(state_is(0x4Fu, 0x40u)); /* 0 -> 1: reset */

    /* heartbeat lost: FAULT with 0xFF04; a reset is refused while it is lost, and the refusal consumes the
     * edge: bit 7 held at 1 does not reset once the heartbeat is back (CiA 402: the rising edge only) */
    setup(STEP_US);
    enable_pdos();
    CHECK_TRUE(sdo_write_u32(0x1016, 1, (0x10u << 16) | 50u) == 0); /* plant 0x10, 50 ms */
    const uint8_t hb = 0x05;
    testbus_clear(&g_tb);
    inject(0x710, 1, &hb);
    deliver();
    g_tb.now_us += 60000; /* 60 ms later: the consumer time (50 ms) is over */
    co_node_tick(&g_tb.node, g_tb.now_us);
    testbus_deliver(&g_tb);
    CHECK_TRUE(g_app.sup.safe_state.reason == OD_DRIVE_REASON_HEARTBEAT_LOST);
    CHECK_TRUE(state_is(0x4Fu, 0x08u) && sdo_read_u32(OD_DRIVE_ERROR_CODE_IDX, 0) == DRIVE_EMCY_SAFE_HEARTBEAT);
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_CONTROLWORD_IDX, 0, 0x0000u) == 0);
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_CONTROLWORD_IDX, 0, 0x0080u) == 0);
    CHECK_TRUE(state_is(0x4Fu, 0x08u)); /* refused: the plant is still silent */
    testbus_clear(&g_tb);
    inject(0x710, 1, &hb);
    deliver();
    CHECK_TRUE(g_app.sup.safe_state.reason == OD_DRIVE_REASON_HEARTBEAT_LOST); /* the cause is gone, the fault stays */
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_CONTROLWORD_IDX, 0, 0x0080u) == 0);
    CHECK_TRUE(tpdo3_statusword() == -1);
    CHECK_TRUE(state_is(0x4Fu, 0x08u)); /* bit 7 held: no edge, no reset (the refused one consumed it) */
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_CONTROLWORD_IDX, 0, 0x0000u) == 0);
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_CONTROLWORD_IDX, 0, 0x0080u) == 0);
    CHECK_TRUE(tpdo3_statusword() >= 0 && ((uint16_t)tpdo3_statusword() & 0x4Fu) == 0x40u); /* by SDO too */
    CHECK_TRUE(state_is(0x4Fu, 0x40u) && sdo_read_u32(OD_DRIVE_ERROR_CODE_IDX, 0) == 0u);
    printf("(d) measurement timeout -> FAULT (TPDO3), 0x603F = 0xFF03, reset on a rising bit 7 only, statusword "
           "TPDO3 at the reset; heartbeat lost -> 0xFF04, reset refused until the heartbeat is back, the refused "
           "edge consumed (bit 7 held does not reset)\n");
}

/* ------------------------------------------------------------------ (e) */
static void test_nmt(void)
{
    setup(STEP_US);
    uint16_t k = 0;
    CHECK_TRUE(!zero_cmd(k++));
    const uint8_t preop[2] = {0x80, 0x00}, start[2] = {0x01, 0x00};
    testbus_clear(&g_tb);
    inject(0x000, 2, preop);
    deliver();
    CHECK_TRUE(g_app.cia.dev.state == CIA402_SWITCH_ON_DISABLED);
    inject(0x000, 2, start);
    deliver();
    CHECK_TRUE(state_is(0x4Fu, 0x40u) && zero_cmd(k++)); /* stays disabled after NMT start */
    const uint8_t reset_node[2] = {0x81, 0x00};
    enable_drive();
    inject(0x000, 2, reset_node);
    deliver();
    CHECK_TRUE(g_app.cia.dev.state == CIA402_SWITCH_ON_DISABLED);
    CHECK_TRUE(sdo_read_u32(OD_DRIVE_MODES_OF_OPERATION_DISPLAY_IDX, 0) == 0xFFu); /* -1 */
    printf("(e) NMT pre-operational while enabled -> SWITCH ON DISABLED (0 V after restart); reset node -> "
           "SWITCH ON DISABLED, mode -1\n");
}

int main(void)
{
    test_transitions();
    test_cst();
    test_quick_stop();
    test_faults();
    test_nmt();
    return check_finish("test_shim_cia402");
}
