/* test_shim_safe_state.c - the safe states of the drive node (0x2209, drive_app.h
 * "Safe states" and "Non-finite values") in-process on co_membus, frame by frame:
 *
 *   (a) measurement timeout: entered at exactly meas_timeout_periods SYNCs
 *       without a measurement, not one earlier; zero-voltage command at once,
 *       then EMCY 0xFF03 with its MSEF; latched (no second entry); every later
 *       measurement still runs a step whose command, state voltages and trace
 *       are zero while the core keeps running (bit-identical to a reference
 *       core whose controller memory is cleared the same way); in speed mode
 *       the speed loop's integrator and iq reference stay 0 (no wind-up)
 *   (b) clear by SDO (0x2209:05 = 1): EMCY 0x0000, reason 0, the next command
 *       is non-zero and bit-identical to the reference core restarting from
 *       cleared memories; 0 is no action, values above 1 abort 0x06090030; the timeout
 *       re-arms; NMT pre-operational -> operational keeps the state, reset
 *       communication leaves it
 *   (c) meas_timeout_periods = 0 disables the timeout
 *   (d) heartbeat consumer timeout (0x1016): reason 2, EMCY 0x8130 then the
 *       zero command then EMCY 0xFF04; clear refused with 0x08000022 while the
 *       heartbeat is still lost, accepted once it is back; a timeout in
 *       pre-operational enters at NMT start
 *   (e) non-finite measurement values: the step uses the last finite value of
 *       the field (command bit-identical to the core fed with it), counted in
 *       0x2209:06, EMCY 0xFF05 {sample_index, field mask} after the command,
 *       cleared by the next finite measurement; entered_at_sample skips it;
 *       non-finite references by RPDO3 are counted once per step and field
 *   (f) a normal run: no EMCY, one command frame per measurement, 0x2209 idle
 *
 * Link: test + drive_app.c + libfw.a + libplant.a + libco.a (-lm). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "co_node.h"
#include "drive_app.h"
#include "drive_core.h"
#include "od_drive.h"
#include "shim_testbus.h"

#define STEP_US 55 /* bus time of one exchange */
#define PLANT_ID 0x10u
#define HB_MS 100u

/* ------------------------------------------------------------------ helpers */

/* Number of EMCYs of the drive with this code among the recorded frames; the MSEF of the
 * last one in msef_out, its error register in reg_out (either may be NULL). */
static int count_emcy(uint16_t code, uint8_t *msef_out, uint8_t *reg_out)
{
    int n = 0;
    for (int i = 0;; ++i) {
        const co_frame_t *e = find(COB_EMCY, i);
        if (!e) break;
        if ((uint16_t)(e->data[0] | e->data[1] << 8) == code) {
            ++n;
            if (msef_out) memcpy(msef_out, &e->data[3], 5);
            if (reg_out) *reg_out = e->data[2];
        }
    }
    return n;
}

/* The first recorded EMCY of the drive with this code, or NULL. */
static const co_frame_t *find_emcy(uint16_t code)
{
    for (int i = 0;; ++i) {
        const co_frame_t *e = find(COB_EMCY, i);
        if (!e || (uint16_t)(e->data[0] | e->data[1] << 8) == code) return e;
    }
}

/* A SYNC alone (its sample's PDOs lost); returns the number of frames the drive sent. */
static uint32_t sync_only(void)
{
    uint8_t sc = next_sync();
    testbus_clear(&g_tb);
    inject(0x080, 1, &sc);
    deliver();
    return testbus_node_frames(&g_tb);
}

/* The measurement of sample k (varying, so that the observers and the speed estimate move). */
static drive_meas_t meas_of(int k)
{
    const drive_meas_t m = {0.5f + 0.01f * (float)k, -0.2f + 0.005f * (float)k, 0.02f * (float)k};
    return m;
}

static uint32_t read_safe(uint8_t sub) { return sdo_read_u32(OD_DRIVE_SAFE_STATE_IDX, sub); }

static uint32_t write_clear(uint8_t v)
{
    return sdo_write_u8(OD_DRIVE_SAFE_STATE_IDX, OD_DRIVE_SAFE_STATE_CLEAR_SUB, v);
}

/* After a fault reset: FAULT -> SWITCH ON DISABLED (transition 15, 0x603F = 0), then enabled
 * again as a master does. */
static void reenable(void)
{
    CHECK_TRUE(g_app.cia.dev.state == CIA402_SWITCH_ON_DISABLED);
    CHECK_TRUE((sdo_read_u32(OD_DRIVE_STATUSWORD_IDX, 0) & 0x4Fu) == 0x40u);
    CHECK_TRUE(sdo_read_u32(OD_DRIVE_ERROR_CODE_IDX, 0) == 0u);
    enable_drive();
}

/* The reference core: a fresh drive with the node's defaults and iq_ref_A. */
static void ref_init(drive_t *ref, float iq_ref_A)
{
    drive_config_t cfg;
    drive_default_config(&cfg);
    drive_init(ref, &cfg);
    ref->sp.iq_ref_A = iq_ref_A;
}

/* What entering the safe state and every step in it do to the core, for the
 * reference: the controller memories and the outer loops' integrator and
 * profile are cleared. */
static void ref_clear(drive_t *ref)
{
    drive_reset_controller_memory(ref);
    ref->outer.integ_A = 0.0f;
    ref->outer.iq_ref_A = 0.0f;
    ref->outer.pos_ref_rad = ref->outer.theta_unwrapped_rad;
    ref->outer.vel_ref_rad_s = 0.0f;
}

/* A step in the safe state, for the reference: the core runs, its output is discarded. */
static void ref_safe_step(drive_t *ref, const drive_meas_t *m)
{
    drive_cmd_t c;
    drive_current_step(ref, m, &c);
    ref_clear(ref);
}

static int zero_f(float v) { return testbus_same_f32(v, 0.0f); }

/* ------------------------------------------------------------------ (a), (b) */

static void test_meas_timeout_and_clear(void)
{
    setup(STEP_US);
    drive_t ref;
    ref_init(&ref, 1.0f);
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_IQ_REF_A_SUB, 1.0f) == 0);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_MEAS_TIMEOUT_PERIODS_SUB) == 3u); /* EDS default */
    /* trace: V_ALPHA and IQ, immediate trigger (EDS trigger_edge 0) */
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_SIGNAL_COUNT_SUB, 2) == 0);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_SIGNAL_1_SUB, TRACE_SIG_V_ALPHA) == 0);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_SIGNAL_2_SUB, TRACE_SIG_IQ) == 0);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_TRACE_IDX, OD_DRIVE_TRACE_STATE_SUB, 1) == 0);

    /* samples 0x0100..0x0109: normal closed loop (the index tests the MSEF's byte order) */
    const uint16_t k0 = 0x0100u;
    int identical = 0;
    uint16_t k = k0;
    for (; k < k0 + 10u; ++k) {
        const drive_meas_t m = meas_of(k - k0);
        const co_frame_t *f = sample(&m, k);
        drive_cmd_t c;
        drive_current_step(&ref, &m, &c);
        identical += cmd_is(f, c.v_alpha_V, c.v_beta_V) && !(zero_f(c.v_alpha_V) && zero_f(c.v_beta_V));
        CHECK_TRUE(find(COB_EMCY, 0) == NULL);
    }
    CHECK_TRUE(identical == 10);
    const uint16_t k_last = (uint16_t)(k - 1u); /* 0x0109 */

    /* SYNCs without their measurement: nothing at the 1st and 2nd (not one earlier) */
    CHECK_TRUE(sync_only() == 0u);
    CHECK_TRUE(g_app.sup.safe_state.reason == 0u && g_app.sup.syncs_without_meas == 1u);
    CHECK_TRUE(sync_only() == 0u);
    CHECK_TRUE(g_app.sup.safe_state.reason == 0u && g_app.sup.syncs_without_meas == 2u);
    /* the 3rd: zero-voltage command at once, then EMCY 0xFF03 */
    CHECK_TRUE(sync_only() == 2u);
    const co_frame_t *cmd = find(COB_CMD, 0);
    const co_frame_t *em = find_emcy(DRIVE_EMCY_SAFE_MEAS_TIMEOUT);
    CHECK_TRUE(cmd_is(cmd, 0.0f, 0.0f));
    CHECK_TRUE(em != NULL && cmd != NULL && cmd < em);
    uint8_t msef[5], reg = 0;
    CHECK_TRUE(count_emcy(DRIVE_EMCY_SAFE_MEAS_TIMEOUT, msef, &reg) == 1);
    CHECK_TRUE(msef[0] == 0x09 && msef[1] == 0x01 && msef[2] == OD_DRIVE_REASON_MEAS_TIMEOUT && msef[3] == 0 &&
               msef[4] == 0);
    CHECK_TRUE(reg == 0x91u); /* generic + communication + manufacturer, as 0xFF01 */
    CHECK_TRUE(zero_f(OD_DRIVE.mfr.x2102_voltage_command.v_alpha_V) &&
               zero_f(OD_DRIVE.mfr.x2102_voltage_command.v_beta_V));
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_REASON_SUB) == OD_DRIVE_REASON_MEAS_TIMEOUT);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_ENTRIES_SUB) == 1u);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_ENTERED_AT_SAMPLE_SUB) == k_last);
    CHECK_TRUE(sdo_read_u32(0x1001, 0) == 0x91u);
    CHECK_TRUE(sdo_read_u32(0x1003, 1) == DRIVE_EMCY_SAFE_MEAS_TIMEOUT);
    /* latched: more SYNCs send nothing more */
    CHECK_TRUE(sync_only() == 0u);
    CHECK_TRUE(g_app.sup.safe_state.entries == 1u);
    /* the reference saw the same: no steps for the lost samples */
    ref_clear(&ref); /* (the entry clears the memories too) */
    k = (uint16_t)(k + 4u);

    /* (a) in the safe state: every measurement runs a step, the command is zero */
    const uint32_t steps0 = g_app.sup.drive_status.current_steps;
    const uint32_t rows0 = g_app.rec.trace.rows_written;
    int zero_cmds = 0, same_core = 0;
    for (int i = 0; i < 12; ++i, ++k) {
        const drive_meas_t m = meas_of(k - k0);
        const co_frame_t *f = sample(&m, k);
        ref_safe_step(&ref, &m);
        zero_cmds += cmd_is(f, 0.0f, 0.0f);
        const drive_state_t *s = &g_app.drv.st;
        same_core += testbus_same_f32(s->i_q_A, ref.st.i_q_A) && testbus_same_f32(s->theta_e_rad, ref.st.theta_e_rad) &&
                     testbus_same_f32(g_app.drv.outer.omega_m_rad_s, ref.outer.omega_m_rad_s) &&
                     testbus_same_f32(YOU2019_OF(g_app.drv)->est.i_hat_q_A, YOU2019_OF(ref)->est.i_hat_q_A);
        CHECK_TRUE(zero_f(s->out.v_alpha_V) && zero_f(s->out.v_beta_V) && zero_f(s->out.v_d_V) &&
                   zero_f(s->out.v_q_V) && zero_f(s->out.v_d_star_V) && zero_f(s->out.v_q_star_V));
        CHECK_TRUE(zero_f(drive_signal(&g_app.drv, TRACE_SIG_V_ALPHA)) &&
                   zero_f(drive_signal(&g_app.drv, TRACE_SIG_V_BETA)) &&
                   zero_f(drive_signal(&g_app.drv, TRACE_SIG_VQ)) && zero_f(drive_signal(&g_app.drv, TRACE_SIG_VD)));
        const trace_recorder_t *tr = &g_app.rec.trace;
        const uint32_t row = (tr->head + tr->depth - 1u) % tr->depth; /* the row this step wrote */
        CHECK_TRUE(zero_f(tr->buffer[row * 2u]) && testbus_same_f32(tr->buffer[row * 2u + 1u], ref.st.i_q_A));
        CHECK_TRUE(find(COB_EMCY, 0) == NULL || i == 0); /* only the lost samples' 0xFF01 at the first */
    }
    CHECK_TRUE(zero_cmds == 12 && same_core == 12);
    CHECK_TRUE(g_app.sup.drive_status.current_steps - steps0 == 12u && g_app.rec.trace.rows_written - rows0 == 12u);
    CHECK_TRUE(g_app.sup.safe_state.entries == 1u && g_app.sup.safe_state.reason == OD_DRIVE_REASON_MEAS_TIMEOUT);

    /* NMT pre-operational -> operational does not leave it */
    const uint8_t preop[2] = {0x80, 0x00}, start[2] = {0x01, 0x00};
    testbus_clear(&g_tb);
    inject(0x000, 2, preop);
    deliver();
    inject(0x000, 2, start);
    deliver();
    CHECK_TRUE(g_tb.node.nmt == CO_NMT_OPERATIONAL && g_app.sup.safe_state.reason == OD_DRIVE_REASON_MEAS_TIMEOUT);

    /* (b) clear: 0 is no action (a read value written back), values above 1 abort, 1 leaves (EMCY 0x0000:
     * nothing else active) */
    CHECK_TRUE(write_clear(0) == 0);
    CHECK_TRUE(write_clear(2) == CO_ABORT_INVALID_VALUE);
    CHECK_TRUE(g_app.sup.safe_state.reason == OD_DRIVE_REASON_MEAS_TIMEOUT);
    CHECK_TRUE(write_clear(1) == 0);
    CHECK_TRUE(count_emcy(0x0000, NULL, &reg) == 1 && reg == 0u);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_REASON_SUB) == 0u);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_CLEAR_SUB) == 0u);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_ENTRIES_SUB) == 1u);
    CHECK_TRUE(sdo_read_u32(0x1001, 0) == 0u);
    reenable(); /* CiA 402: the fault reset left FAULT for SWITCH ON DISABLED */
    /* the next step commands again: non-zero, the core restarting from cleared memories
     * (a lost sample gap, counted by 0xFF01, after the NMT transitions: none here) */
    identical = 0;
    for (int i = 0; i < 5; ++i, ++k) {
        const drive_meas_t m = meas_of(k - k0);
        const co_frame_t *f = sample(&m, k);
        drive_cmd_t c;
        drive_current_step(&ref, &m, &c);
        identical += cmd_is(f, c.v_alpha_V, c.v_beta_V) && !(zero_f(c.v_alpha_V) && zero_f(c.v_beta_V));
        CHECK_TRUE(find(COB_EMCY, 0) == NULL);
    }
    CHECK_TRUE(identical == 5);

    /* the timeout re-arms after the clear: a second entry */
    CHECK_TRUE(sync_only() == 0u);
    CHECK_TRUE(sync_only() == 0u);
    CHECK_TRUE(sync_only() == 2u && count_emcy(DRIVE_EMCY_SAFE_MEAS_TIMEOUT, msef, NULL) == 1);
    CHECK_TRUE(msef[0] == (uint8_t)(k - 1u) && msef[1] == (uint8_t)((k - 1u) >> 8));
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_ENTRIES_SUB) == 2u);

    /* NMT reset communication leaves it (entries kept), reset node clears the counters */
    const uint8_t reset_comm[2] = {0x82, 0x00}, reset_node[2] = {0x81, 0x00};
    testbus_clear(&g_tb);
    inject(0x000, 2, reset_comm);
    deliver();
    CHECK_TRUE(g_tb.node.nmt == CO_NMT_PRE_OPERATIONAL && g_app.sup.safe_state.reason == 0u);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_REASON_SUB) == 0u && read_safe(OD_DRIVE_SAFE_STATE_ENTRIES_SUB) == 2u);
    testbus_clear(&g_tb);
    inject(0x000, 2, reset_node);
    deliver();
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_ENTRIES_SUB) == 0u &&
               read_safe(OD_DRIVE_SAFE_STATE_ENTERED_AT_SAMPLE_SUB) == 0u);
    printf("(a) timeout at the 3rd SYNC without a measurement: 0 V at once, EMCY 0xFF03 {%02X %02X %u 0 0}; "
           "12 safe steps at 0 V with the core running\n"
           "(b) clear: EMCY 0x0000, next 5 commands = the core restarted (non-zero); re-armed, second entry; "
           "resets leave it\n",
           0x09, 0x01, 1u);
}

/* (a) with the speed loop: its integrator and reference do not wind up in the safe state */
static void test_speed_mode_no_windup(void)
{
    setup(STEP_US);
    drive_t ref;
    ref_init(&ref, 0.0f);
    ref.sp.mode = (uint8_t)DRIVE_MODE_SPEED;
    ref.sp.speed_ref_rad_s = 5.0f;
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_MODE_SUB, DRIVE_MODE_SPEED) == 0);
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_SPEED_REF_RAD_S_SUB, 5.0f) == 0);
    const drive_meas_t m = {0.1f, -0.05f, 0.3f}; /* standing still: the speed error integrates */
    uint16_t k = 0;
    drive_cmd_t c;
    for (; k < 40; ++k) {
        drive_current_step(&ref, &m, &c);
        CHECK_TRUE(cmd_is(sample(&m, k), c.v_alpha_V, c.v_beta_V));
    }
    CHECK_TRUE(g_app.drv.outer.integ_A > 0.0f && g_app.drv.outer.iq_ref_A > 0.0f);
    for (int i = 0; i < 3; ++i) sync_only();
    CHECK_TRUE(g_app.sup.safe_state.reason == OD_DRIVE_REASON_MEAS_TIMEOUT);
    ref_clear(&ref);
    k = (uint16_t)(k + 3u);
    int clean = 0;
    for (int i = 0; i < 40; ++i, ++k) { /* 5 executions of the speed loop */
        CHECK_TRUE(cmd_is(sample(&m, k), 0.0f, 0.0f));
        ref_safe_step(&ref, &m);
        clean += zero_f(g_app.drv.outer.integ_A) && zero_f(g_app.drv.outer.iq_ref_A) &&
                 testbus_same_f32(g_app.drv.outer.pos_ref_rad, g_app.drv.outer.theta_unwrapped_rad);
    }
    CHECK_TRUE(clean == 40);
    CHECK_TRUE(write_clear(1) == 0);
    reenable(); /* CiA 402: the fault reset left FAULT for SWITCH ON DISABLED */
    int identical = 0;
    for (int i = 0; i < 16; ++i, ++k) {
        drive_current_step(&ref, &m, &c);
        identical += cmd_is(sample(&m, k), c.v_alpha_V, c.v_beta_V);
    }
    CHECK_TRUE(identical == 16);
    printf("(a) speed mode: integrator and iq reference held at 0 through 40 safe steps; after the clear "
           "16/16 commands = the core restarted from them\n");
}

/* ------------------------------------------------------------------ (c) */

static void test_timeout_disabled(void)
{
    setup(STEP_US);
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_SAFE_STATE_IDX, OD_DRIVE_SAFE_STATE_MEAS_TIMEOUT_PERIODS_SUB, 1001) ==
               CO_ABORT_VALUE_HIGH);
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_SAFE_STATE_IDX, OD_DRIVE_SAFE_STATE_MEAS_TIMEOUT_PERIODS_SUB, 0) == 0);
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_IQ_REF_A_SUB, 1.0f) == 0);
    for (uint16_t k = 0; k < 3; ++k) {
        const drive_meas_t m = meas_of(k);
        CHECK_TRUE(sample(&m, k) != NULL);
    }
    uint32_t sent = 0;
    for (int i = 0; i < 50; ++i) sent += sync_only();
    CHECK_TRUE(sent == 0u && g_app.sup.safe_state.reason == 0u && g_app.sup.safe_state.entries == 0u);
    const drive_meas_t m = meas_of(53);
    const co_frame_t *f = sample(&m, 53);
    CHECK_TRUE(f != NULL && !cmd_is(f, 0.0f, 0.0f));
    CHECK_TRUE(count_emcy(DRIVE_EMCY_MEAS_LOST, NULL, NULL) == 1 &&
               count_emcy(DRIVE_EMCY_SAFE_MEAS_TIMEOUT, NULL, NULL) == 0);
    /* and 2: entered at the 2nd SYNC (one measurement missing) */
    CHECK_TRUE(sdo_write_u16(OD_DRIVE_SAFE_STATE_IDX, OD_DRIVE_SAFE_STATE_MEAS_TIMEOUT_PERIODS_SUB, 2) == 0);
    CHECK_TRUE(sync_only() == 0u);
    CHECK_TRUE(sync_only() == 2u && count_emcy(DRIVE_EMCY_SAFE_MEAS_TIMEOUT, NULL, NULL) == 1);
    printf("(c) meas_timeout_periods 0: 50 SYNCs without a measurement, no safe state; 2: entered at the 2nd\n");
}

/* the plant holds (status bit 1 in its last sample): SYNCs after it (another producer's) arm nothing */
static void test_holding_disarms(void)
{
    setup(STEP_US);
    for (uint16_t k = 0; k < 3; ++k) {
        const drive_meas_t m = meas_of(k);
        g_meas_status = k == 2u ? 0x02u : 0u; /* the last sample of the segment: holding */
        CHECK_TRUE(sample(&m, k) != NULL);
    }
    g_meas_status = 0u;
    uint32_t sent = 0;
    for (int i = 0; i < 10; ++i) sent += sync_only();
    CHECK_TRUE(sent == 0u && g_app.sup.safe_state.reason == 0u);
    const drive_meas_t m = meas_of(3);
    CHECK_TRUE(sample(&m, 3) != NULL); /* the next segment: armed again */
    CHECK_TRUE(sync_only() == 0u && sync_only() == 0u);
    CHECK_TRUE(sync_only() == 2u && g_app.sup.safe_state.reason == OD_DRIVE_REASON_MEAS_TIMEOUT);
    printf("(c2) after a sample that says the plant holds: 10 SYNCs, no safe state; armed again by the next sample\n");
}

/* ------------------------------------------------------------------ (d) */

static void heartbeat(void)
{
    const uint8_t st = 0x05; /* OPERATIONAL */
    testbus_clear(&g_tb);
    inject(0x700u + PLANT_ID, 1, &st);
    deliver();
}

/* Let dt_us pass and run the node's timers (the heartbeat consumer). */
static void tick(int64_t dt_us)
{
    testbus_clear(&g_tb);
    g_tb.now_us += dt_us;
    co_node_tick(&g_tb.node, g_tb.now_us);
    testbus_deliver(&g_tb);
}

static void test_heartbeat_lost(void)
{
    setup(STEP_US);
    drive_t ref;
    ref_init(&ref, 1.0f);
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_IQ_REF_A_SUB, 1.0f) == 0);
    CHECK_TRUE(sdo_write_u32(0x1016, 1, (PLANT_ID << 16) | HB_MS) == 0);
    heartbeat(); /* monitoring starts at the first heartbeat */
    uint16_t k = 0;
    for (; k < 6; ++k) {
        const drive_meas_t m = meas_of(k);
        drive_cmd_t c;
        drive_current_step(&ref, &m, &c);
        CHECK_TRUE(cmd_is(sample(&m, k), c.v_alpha_V, c.v_beta_V));
    }
    tick(50000); /* within the consumer time */
    CHECK_TRUE(testbus_node_frames(&g_tb) == 0u);
    tick(60000); /* 110 ms since the heartbeat: lost */
    const co_frame_t *hb = find_emcy(CO_EMCY_HEARTBEAT);
    const co_frame_t *cmd = find(COB_CMD, 0);
    const co_frame_t *em = find_emcy(DRIVE_EMCY_SAFE_HEARTBEAT);
    CHECK_TRUE(hb != NULL && hb->data[3] == PLANT_ID);
    CHECK_TRUE(cmd_is(cmd, 0.0f, 0.0f));
    CHECK_TRUE(hb < cmd && cmd < em); /* the stack's EMCY, the zero command, the drive's reaction */
    uint8_t msef[5], reg = 0;
    CHECK_TRUE(count_emcy(DRIVE_EMCY_SAFE_HEARTBEAT, msef, &reg) == 1);
    CHECK_TRUE(msef[0] == 5 && msef[1] == 0 && msef[2] == OD_DRIVE_REASON_HEARTBEAT_LOST && msef[3] == 0 &&
               msef[4] == 0);
    CHECK_TRUE(reg == 0x91u);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_REASON_SUB) == OD_DRIVE_REASON_HEARTBEAT_LOST);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_ENTRIES_SUB) == 1u);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_ENTERED_AT_SAMPLE_SUB) == 5u);
    ref_clear(&ref);

    /* a plant still producing periods gets 0 V; a measurement timeout does not replace the reason */
    for (int i = 0; i < 3; ++i, ++k) {
        const drive_meas_t m = meas_of(k);
        CHECK_TRUE(cmd_is(sample(&m, k), 0.0f, 0.0f));
        ref_safe_step(&ref, &m);
    }
    for (int i = 0; i < 5; ++i) CHECK_TRUE(sync_only() == 0u);
    CHECK_TRUE(g_app.sup.safe_state.reason == OD_DRIVE_REASON_HEARTBEAT_LOST && g_app.sup.safe_state.entries == 1u);

    /* clear refused while the heartbeat is lost */
    CHECK_TRUE(write_clear(1) == CO_ABORT_DATA_STATE);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_REASON_SUB) == OD_DRIVE_REASON_HEARTBEAT_LOST);
    /* the heartbeat returns: the stack clears 0x8130, 0xFF04 stays active (no EMCY 0x0000) */
    heartbeat();
    CHECK_TRUE(find(COB_EMCY, 0) == NULL);
    CHECK_TRUE(sdo_read_u32(0x1001, 0) != 0u);
    CHECK_TRUE(write_clear(1) == 0);
    CHECK_TRUE(count_emcy(0x0000, NULL, NULL) == 1);
    CHECK_TRUE(sdo_read_u32(0x1001, 0) == 0u);
    reenable(); /* CiA 402: the fault reset left FAULT for SWITCH ON DISABLED */
    /* running again (the lost SYNCs above make the next sample a gap: 0xFF01, not a safe state) */
    k = (uint16_t)(k + 5u);
    for (int i = 0; i < 3; ++i, ++k) {
        const drive_meas_t m = meas_of(k);
        drive_cmd_t c;
        drive_current_step(&ref, &m, &c);
        const co_frame_t *f = sample(&m, k);
        CHECK_TRUE(cmd_is(f, c.v_alpha_V, c.v_beta_V) && !cmd_is(f, 0.0f, 0.0f));
    }

    /* lost in pre-operational: no safe state there, entered at NMT start */
    const uint8_t preop[2] = {0x80, 0x00}, start[2] = {0x01, 0x00};
    testbus_clear(&g_tb);
    inject(0x000, 2, preop);
    deliver();
    tick(150000);
    CHECK_TRUE(count_emcy(CO_EMCY_HEARTBEAT, NULL, NULL) == 1 && g_app.sup.safe_state.reason == 0u);
    testbus_clear(&g_tb);
    inject(0x000, 2, start);
    deliver();
    CHECK_TRUE(g_app.sup.safe_state.reason == OD_DRIVE_REASON_HEARTBEAT_LOST && g_app.sup.safe_state.entries == 2u);
    CHECK_TRUE(cmd_is(find(COB_CMD, 0), 0.0f, 0.0f) && count_emcy(DRIVE_EMCY_SAFE_HEARTBEAT, NULL, NULL) == 1);
    CHECK_TRUE(write_clear(1) == CO_ABORT_DATA_STATE);
    printf("(d) heartbeat lost: EMCY 0x8130, 0 V, EMCY 0xFF04 {05 00 2 0 0}; clear refused (0x08000022) until "
           "the heartbeat is back; lost in pre-operational -> entered at NMT start\n");
}

/* ------------------------------------------------------------------ (e) */

static void test_non_finite(void)
{
    setup(STEP_US);
    drive_t ref;
    ref_init(&ref, 1.0f);
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_IQ_REF_A_SUB, 1.0f) == 0);
    uint16_t k = 0;
    drive_cmd_t c;
    for (; k < 5; ++k) {
        const drive_meas_t m = meas_of(k);
        drive_current_step(&ref, &m, &c);
        CHECK_TRUE(cmd_is(sample(&m, k), c.v_alpha_V, c.v_beta_V));
    }
    /* sample 5: i_a_A NaN -> the step runs on the last finite i_a_A (sample 4's) with the new i_b/theta */
    drive_meas_t bad = meas_of(k);
    bad.i_a_A = NAN;
    const co_frame_t *f = sample(&bad, k);
    drive_meas_t used = bad;
    used.i_a_A = meas_of(k - 1).i_a_A;
    drive_current_step(&ref, &used, &c);
    CHECK_TRUE(cmd_is(f, c.v_alpha_V, c.v_beta_V));
    CHECK_TRUE(isfinite(c.v_alpha_V) && isfinite(c.v_beta_V));
    const co_frame_t *em = find_emcy(DRIVE_EMCY_NON_FINITE);
    CHECK_TRUE(em != NULL && f != NULL && f < em); /* after the command */
    uint8_t msef[5], reg = 0;
    CHECK_TRUE(count_emcy(DRIVE_EMCY_NON_FINITE, msef, &reg) == 1);
    CHECK_TRUE(msef[0] == 5 && msef[1] == 0 && msef[2] == DRIVE_NON_FINITE_I_A && msef[3] == 0 && msef[4] == 0);
    CHECK_TRUE(reg == 0x91u);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_NON_FINITE_REJECTED_SUB) == 1u);
    ++k;
    /* sample 6: i_b_A +inf and theta -inf -> mask 0x06, two more; i_a_A is finite again */
    bad = meas_of(k);
    bad.i_b_A = INFINITY;
    bad.theta_m_rad = -INFINITY;
    f = sample(&bad, k);
    used = bad;
    used.i_b_A = meas_of(k - 1).i_b_A;
    used.theta_m_rad = meas_of(k - 1).theta_m_rad;
    drive_current_step(&ref, &used, &c);
    CHECK_TRUE(cmd_is(f, c.v_alpha_V, c.v_beta_V));
    CHECK_TRUE(count_emcy(DRIVE_EMCY_NON_FINITE, msef, NULL) == 1 &&
               msef[2] == (DRIVE_NON_FINITE_I_B | DRIVE_NON_FINITE_THETA) && msef[0] == 6);
    CHECK_TRUE(count_emcy(0x0000, NULL, NULL) == 0);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_NON_FINITE_REJECTED_SUB) == 3u);
    ++k;
    /* sample 7: finite -> EMCY 0x0000 after the command, no 0xFF05 */
    const drive_meas_t good = meas_of(k);
    f = sample(&good, k);
    drive_current_step(&ref, &good, &c);
    CHECK_TRUE(cmd_is(f, c.v_alpha_V, c.v_beta_V));
    const co_frame_t *reset = find_emcy(0x0000);
    CHECK_TRUE(reset != NULL && f < reset && count_emcy(DRIVE_EMCY_NON_FINITE, NULL, NULL) == 0);
    CHECK_TRUE(sdo_read_u32(0x1001, 0) == 0u);
    ++k;
    /* sample 8 NaN, then a timeout: entered_at_sample is the last finite one (7) */
    bad = meas_of(k);
    bad.i_a_A = NAN;
    CHECK_TRUE(sample(&bad, k) != NULL && count_emcy(DRIVE_EMCY_NON_FINITE, NULL, NULL) == 1);
    sync_only();
    sync_only();
    CHECK_TRUE(sync_only() == 2u && count_emcy(DRIVE_EMCY_SAFE_MEAS_TIMEOUT, msef, NULL) == 1 && msef[0] == 7);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_ENTERED_AT_SAMPLE_SUB) == 7u);
    CHECK_TRUE(write_clear(1) == 0);
    CHECK_TRUE(count_emcy(0x0000, NULL, NULL) == 0); /* 0xFF05 of sample 8 is still active */
    reenable();                                      /* CiA 402: the fault reset left FAULT for SWITCH ON DISABLED */
    k = (uint16_t)(k + 4u);

    /* references by RPDO3: a NaN iq_ref_A is ignored and counted at every step it is read */
    const uint32_t n0 = read_safe(OD_DRIVE_SAFE_STATE_NON_FINITE_REJECTED_SUB);
    uint8_t d[8];
    testbus_put_f32(&d[0], NAN);
    testbus_put_f32(&d[4], INFINITY);
    testbus_clear(&g_tb);
    inject(COB_REF, 8, d);
    deliver();
    for (int i = 0; i < 3; ++i, ++k) {
        const drive_meas_t m = meas_of(k);
        CHECK_TRUE(sample(&m, k) != NULL);
        CHECK_TRUE(count_emcy(DRIVE_EMCY_NON_FINITE, NULL, NULL) == 0);
        CHECK_TRUE(testbus_same_f32(g_app.drv.st.iq_ref_A, 1.0f) && testbus_same_f32(g_app.drv.st.id_ref_A, 0.0f));
    }
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_NON_FINITE_REJECTED_SUB) == n0 + 6u); /* 3 steps x 2 fields */
    printf("(e) NaN i_a_A: command = the core on the last finite i_a_A, EMCY 0xFF05 {05 00 01 0 0} after it; "
           "inf i_b/theta: mask 0x06; cleared by a finite sample; RPDO3 NaN/inf refs: +6 in 3 steps\n");
}

/* ------------------------------------------------------------------ (f) */

static void test_normal_run_unchanged(void)
{
    setup(STEP_US);
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_IQ_REF_A_SUB, 2.0f) == 0);
    CHECK_TRUE(sdo_write_u32(0x1016, 1, (PLANT_ID << 16) | HB_MS) == 0);
    heartbeat();
    int one_frame = 0;
    const int N = 1000;
    for (int k = 0; k < N; ++k) {
        if (k % 500 == 0) heartbeat();
        const drive_meas_t m = meas_of(k % 100);
        const co_frame_t *f = sample(&m, (uint16_t)k);
        one_frame += f != NULL && testbus_node_frames(&g_tb) == 1u;
    }
    CHECK_TRUE(one_frame == N);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_REASON_SUB) == 0u && read_safe(OD_DRIVE_SAFE_STATE_ENTRIES_SUB) == 0u &&
               read_safe(OD_DRIVE_SAFE_STATE_NON_FINITE_REJECTED_SUB) == 0u);
    CHECK_TRUE(sdo_read_u32(0x1001, 0) == 0u && sdo_read_u32(0x1003, 0) == 0u);
    printf("(f) normal run: %d measurements, exactly one frame (the command) each, no EMCY\n", N);
}

/* ------------------------------------------------------------------ (g), (h) */

/* (g) A law whose command is not finite (here: a NaN model, a law's bug): the drive applies 0 V at that
 * step, enters its safe state (reason law_output, EMCY 0xFF06) and stays there. */
static void test_law_output(void)
{
    setup(STEP_US);
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_IQ_REF_A_SUB, 1.0f) == 0);
    for (uint16_t k = 0; k < 5; ++k) {
        const drive_meas_t m = meas_of(k);
        const co_frame_t *f = sample(&m, k);
        CHECK_TRUE(f != NULL && !cmd_is(f, 0.0f, 0.0f));
    }
    g_app.drv.cfg.R_hat_ohm = (float)NAN; /* what no SDO write can do (the EDS range): a broken law */
    drive_apply_config(&g_app.drv);
    const drive_meas_t m = meas_of(5);
    const co_frame_t *f = sample(&m, 5);
    CHECK_TRUE(f != NULL && cmd_is(f, 0.0f, 0.0f));
    uint8_t msef[5] = {0};
    CHECK_TRUE(count_emcy(DRIVE_EMCY_SAFE_LAW_OUTPUT, msef, NULL) == 1 && msef[2] == OD_DRIVE_REASON_LAW_OUTPUT);
    CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_REASON_SUB) == OD_DRIVE_REASON_LAW_OUTPUT);
    for (uint16_t k = 6; k < 10; ++k) {
        const drive_meas_t mk = meas_of(k);
        const co_frame_t *fk = sample(&mk, k);
        CHECK_TRUE(fk != NULL && cmd_is(fk, 0.0f, 0.0f));
    }
    printf("(g) a law's non-finite command: 0 V at once, safe state law_output, EMCY 0xFF06\n");
}

static uint32_t g_fake_cycles;
static uint32_t fake_cycles(void *user)
{
    (void)user;
    g_fake_cycles += 40000u; /* per call: two calls a step, 40 000 cycles apart */
    return g_fake_cycles;
}

/* (h) A step longer than the current period by a bare-metal counter (overrun check on): safe state,
 * reason overrun, EMCY 0xFF07; the same counter without the check (a Linux process) is only counted. */
static void test_overrun(void)
{
    for (int on = 0; on <= 1; ++on) {
        setup(STEP_US);
        drive_app_set_cycle_counter(&g_app, fake_cycles, NULL, 1000000000u); /* 40 us a step at 1 GHz */
        drive_app_set_overrun_check(&g_app, (uint8_t)on);
        const float Ts = g_app.drv.cfg.Ts_s; /* You 2019: 55 us, above 40 */
        for (uint16_t k = 0; k < 3; ++k) {
            const drive_meas_t m = meas_of(k);
            CHECK_TRUE(sample(&m, k) != NULL);
        }
        CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_REASON_SUB) == 0u);
        g_app.drv.cfg.Ts_s = 30e-6f; /* now 40 us is longer than the period */
        const drive_meas_t m = meas_of(3);
        CHECK_TRUE(sample(&m, 3) != NULL);
        CHECK_TRUE(count_emcy(DRIVE_EMCY_SAFE_OVERRUN, NULL, NULL) == on); /* this exchange's frames */
        const uint32_t want = on ? (uint32_t)OD_DRIVE_REASON_OVERRUN : 0u;
        CHECK_TRUE(read_safe(OD_DRIVE_SAFE_STATE_REASON_SUB) == want);
        g_app.drv.cfg.Ts_s = Ts;
    }
    printf("(h) a step of 40 us in a 30 us period: overrun (EMCY 0xFF07) with the check on, counted only without\n");
}

int main(void)
{
    test_meas_timeout_and_clear();
    test_speed_mode_no_windup();
    test_timeout_disabled();
    test_holding_disarms();
    test_heartbeat_lost();
    test_non_finite();
    test_normal_run_unchanged();
    test_law_output();
    test_overrun();
    return check_finish("test_shim_safe_state");
}
