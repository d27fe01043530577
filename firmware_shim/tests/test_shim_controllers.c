/* test_shim_controllers.c - controller selection of the drive node app
 * (firmware_shim/shim/drive_app.c) by real SDO frames on co_membus.
 *
 * For each OD controller value 3 (Yao 2020 DPCC), 4 (Zhao 2022 incremental)
 * and 5 (Zhao 2022 forward Euler), selected by an expedited SDO download of
 * 0x2200:01, every command frame of the drive is bit-identical to
 *   (1) drive_current_step() on a drive_t configured the same way, and
 *   (2) the controller's own core called directly with the drive's dq
 *       currents and speed (Yao 2020: its stator-frame output, no angle
 *       advance; Zhao 2022: its dq output, rotated by the drive's advance).
 * Also: the Yao 2020 identification started by SDO (0x2501:15 = 1) follows
 * yao2020_identification_start() on the direct core; the RLS baseline (0x2501:25)
 * equals yao2020_rls_update() on the same data; refusals (salient model,
 * identification without the DPCC); switching back to 2 keeps You 2019.
 *
 * Link: test + drive_app.c + libfw.a + libco.a (-lm). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "co_node.h"
#include "dq_math.h"
#include "drive_app.h"
#include "drive_core.h"
#include "motor_model.h"
#include "od_drive.h"
#include "shim_testbus.h"

#define STEP_US 100 /* bus time of one exchange */

static void setup_drive(void)
{
    setup(STEP_US);
    g_sync = 0;
}

/* ------------------------------------------------------------------ model */

#define C_IDX OD_DRIVE_CONTROLLER_IDX
#define Y_IDX OD_DRIVE_YAO_2020_DPCC_IDX
/* The drive's model: the yao2020_low motor of plant_rt/core/presets.c (load_motor); Vmax a
 * round number under Vdc/sqrt(3) = 173.205 V. */
static float kTs, kR, kL, kPsi;
static uint8_t kPp;
static const float kVmax = 173.2f;

static void load_motor(void)
{
    const motor_params_t mp = motor_params_preset("yao2020_low");
    kTs = (float)mp.Ts_s;
    kR = (float)mp.R_ohm;
    kL = (float)mp.Lq_H;
    kPsi = (float)mp.psi_Wb;
    kPp = (uint8_t)mp.pole_pairs;
}

static void configure_by_sdo(void)
{
    CHECK_TRUE(sdo_write_f32(C_IDX, OD_DRIVE_CONTROLLER_TS_S_SUB, kTs) == 0);
    CHECK_TRUE(sdo_write_u8(C_IDX, OD_DRIVE_CONTROLLER_POLE_PAIRS_SUB, kPp) == 0);
    CHECK_TRUE(sdo_write_f32(C_IDX, OD_DRIVE_CONTROLLER_R_HAT_OHM_SUB, kR) == 0);
    CHECK_TRUE(sdo_write_f32(C_IDX, OD_DRIVE_CONTROLLER_LD_HAT_H_SUB, kL) == 0);
    CHECK_TRUE(sdo_write_f32(C_IDX, OD_DRIVE_CONTROLLER_LQ_HAT_H_SUB, kL) == 0);
    CHECK_TRUE(sdo_write_f32(C_IDX, OD_DRIVE_CONTROLLER_PSI_HAT_WB_SUB, kPsi) == 0);
    CHECK_TRUE(sdo_write_f32(C_IDX, OD_DRIVE_CONTROLLER_VMAX_V_SUB, kVmax) == 0);
    CHECK_TRUE(sdo_write_u8(C_IDX, OD_DRIVE_CONTROLLER_SPEED_LOOP_DIVIDER_SUB, 1u) == 0);
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_REFERENCES_IDX, OD_DRIVE_REFERENCES_IQ_REF_A_SUB, 2.0f) == 0);
}

static void configure_ref(drive_t *ref, uint8_t core_ctrl)
{
    drive_config_t cfg;
    drive_default_config(&cfg);
    cfg.Ts_s = kTs;
    cfg.pole_pairs = (float)kPp;
    cfg.R_hat_ohm = kR;
    cfg.Ld_hat_H = kL;
    cfg.Lq_hat_H = kL;
    cfg.psi_hat_Wb = kPsi;
    cfg.Vmax_V = kVmax;
    cfg.speed_loop_divider = 1u;
    cfg.controller = core_ctrl;
    drive_init(ref, &cfg);
    ref->sp.iq_ref_A = 2.0f;
}

/* measurement of step k: rotor at 150 rad/s mechanical (600 rad/s electrical) */
static drive_meas_t meas_of(uint16_t k)
{
    drive_meas_t m;
    const float th = 0.015f * (float)k;
    m.theta_m_rad = dq_wrap_pi(th);
    m.i_a_A = 2.0f * sinf(4.0f * th) + 0.1f * sinf(0.37f * (float)k);
    m.i_b_A = 2.0f * sinf(4.0f * th - 2.0943951f) + 0.05f * cosf(0.23f * (float)k);
    return m;
}

static void run_controller(uint8_t od_ctrl)
{
    setup_drive();
    configure_by_sdo();
    const uint8_t core_ctrl = od_ctrl; /* the core runs the OD's controller values */
    if (od_ctrl == 3u) CHECK_TRUE(sdo_write_u8(Y_IDX, OD_DRIVE_YAO_2020_DPCC_RLS_ENABLE_SUB, 1u) == 0);
    CHECK_TRUE(sdo_write_u8(C_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, od_ctrl) == 0);
    if (od_ctrl != 3u)
        CHECK_TRUE(sdo_write_u8(Y_IDX, OD_DRIVE_YAO_2020_DPCC_IDENT_COMMAND_SUB, 1u) == CO_ABORT_PARAM_INCOMPAT);
    else /* not run yet: the observer has no steady state to latch */
        CHECK_TRUE(sdo_write_u8(Y_IDX, OD_DRIVE_YAO_2020_DPCC_IDENT_COMMAND_SUB, 1u) == CO_ABORT_DATA_STATE);

    static drive_t ref;
    configure_ref(&ref, core_ctrl);
    if (drive_law_record(&ref) != NULL) /* the surface-mounted laws: Yao 2020's record (0x2501) only */
        ((od_drive_yao_2020_dpcc_t *)drive_law_record(&ref))->rls_enable = od_ctrl == 3u ? 1u : 0u;
    drive_apply_config(&ref);

    /* direct cores, configured from the same values */
    yao2020_dpcc_config_t ycfg;
    yao2020_dpcc_default_config(&ycfg);
    ycfg.Ts_s = kTs;
    ycfg.R_hat_ohm = kR;
    ycfg.L_hat_H = kL;
    ycfg.psi_hat_Wb = kPsi;
    ycfg.Vmax_V = kVmax;
    static yao2020_dpcc_state_t yst;
    yao2020_dpcc_init(&ycfg, &yst);
    yao2020_rls_config_t rcfg;
    yao2020_rls_default_config(&rcfg);
    rcfg.Ts_s = kTs;
    rcfg.psi_hat_Wb = kPsi;
    rcfg.lambda = 0.995f;
    yao2020_rls_state_t rls;
    yao2020_rls_init(&rcfg, &rls, kR, kL);
    zhao2022_incremental_config_t icfg = {kR, kL, kTs, kVmax};
    zhao2022_incremental_state_t ist;
    CHECK_TRUE(zhao2022_incremental_init(&icfg, &ist) == 0);
    zhao2022_predictive_config_t ecfg = {kR, kL, kPsi, kTs, kVmax};
    zhao2022_predictive_state_t est;
    CHECK_TRUE(zhao2022_predictive_init(&ecfg, &est) == 0);

    int n_same_drive = 0, n_same_core = 0, n = 0;
    const int N = 400, K_ID = 120;
    for (uint16_t k = 0; k < (uint16_t)N; ++k) {
        if (od_ctrl == 3u && k == K_ID) {
            CHECK_TRUE(sdo_write_u8(Y_IDX, OD_DRIVE_YAO_2020_DPCC_IDENT_COMMAND_SUB, 1u) == 0);
            od_drive_yao_2020_dpcc_t *yrec = (od_drive_yao_2020_dpcc_t *)drive_law_record(&ref);
            yrec->ident_command = 1u;
            CHECK_TRUE(drive_law_command(&ref, ref.law, yrec, OD_DRIVE_YAO_2020_DPCC_IDENT_COMMAND_SUB, 0, 0) ==
                       CURRENT_LAW_OK);
            (void)drive_law_command(&ref, ref.law, yrec, OD_DRIVE_YAO_2020_DPCC_IDENT_COMMAND_SUB, 0, 1);
            CHECK_TRUE(yao2020_identification_running(&YAO2020_OF(ref)->st));
            CHECK_TRUE(yao2020_identification_start(&ycfg, &yst));
            CHECK_TRUE(yao2020_identification_running(&YAO2020_OF(g_app.drv)->st));
        }
        const drive_meas_t m = meas_of(k);
        const co_frame_t *f = sample(&m, k);
        /* (1) the same drive core driven directly */
        const float w = ref.st.omega_e_rad_s; /* speed used by this step */
        drive_cmd_t c;
        drive_current_step(&ref, &m, &c);
        ++n;
        if (cmd_is(f, c.v_alpha_V, c.v_beta_V)) ++n_same_drive;
        /* (2) the controller's own core */
        const float th = dq_wrap_pi((float)kPp * m.theta_m_rad);
        const float cs = cosf(th), sn = sinf(th);
        float ial, ibe, id, iq;
        dq_clarke(m.i_a_A, m.i_b_A, &ial, &ibe);
        dq_park(ial, ibe, cs, sn, &id, &iq);
        float va, vb;
        if (od_ctrl == 3u) {
            yao2020_dpcc_cmd_t yc;
            yao2020_dpcc_step(&ycfg, &yst, 0.0f, 2.0f, id, iq, w, th, &yc);
            yao2020_rls_update(&rcfg, &rls, id, iq, yst.v_app_d_V, yst.v_app_q_V, w);
            va = yc.v_alpha_V;
            vb = yc.v_beta_V;
        } else {
            float vd, vq;
            if (od_ctrl == 4u)
                zhao2022_incremental_step(&ist, 0.0f, 2.0f, id, iq, w, &vd, &vq);
            else
                zhao2022_predictive_step(&est, 0.0f, 2.0f, id, iq, w, &vd, &vq);
            const float thc = th + 1.5f * w * kTs;
            dq_inv_park(vd, vq, cosf(thc), sinf(thc), &va, &vb);
        }
        if (cmd_is(f, va, vb)) ++n_same_core;
    }
    CHECK_TRUE(n_same_drive == N);
    CHECK_TRUE(n_same_core == N);
    if (od_ctrl == 3u) {
        CHECK_TRUE(YAO2020_OF(g_app.drv)->st.id_state == yst.id_state &&
                   yst.id_state != (uint8_t)YAO2020_IDENTIFICATION_IDLE);
        CHECK_TRUE(testbus_same_f32(sdo_read_f32(Y_IDX, OD_DRIVE_YAO_2020_DPCC_L_HAT_H_SUB), yst.L_hat_H));
        CHECK_TRUE(testbus_same_f32(sdo_read_f32(Y_IDX, OD_DRIVE_YAO_2020_DPCC_RLS_R_HAT_OHM_SUB), rls.R_hat_ohm));
        CHECK_TRUE(testbus_same_f32(sdo_read_f32(Y_IDX, OD_DRIVE_YAO_2020_DPCC_RLS_L_HAT_H_SUB), rls.L_hat_H));
        CHECK_TRUE(sdo_write_u8(Y_IDX, OD_DRIVE_YAO_2020_DPCC_IDENT_COMMAND_SUB, 2u) == 0); /* abort */
        CHECK_TRUE(YAO2020_OF(g_app.drv)->st.id_state == (uint8_t)YAO2020_IDENTIFICATION_ABORTED);
        CHECK_TRUE(OD_DRIVE.mfr.x2501_yao_2020_dpcc.ident_command == 0u);
    }
    if (od_ctrl == 4u) {
        CHECK_TRUE(testbus_same_f32(sdo_read_f32(OD_DRIVE_ZHAO_2022_IDX, OD_DRIVE_ZHAO_2022_K1_V_A_SUB), ist.K1_V_A));
        CHECK_TRUE(testbus_same_f32(sdo_read_f32(OD_DRIVE_ZHAO_2022_IDX, OD_DRIVE_ZHAO_2022_K2_V_A_SUB), ist.K2_V_A));
    }
    printf("controller %u: %d/%d commands = drive_current_step, %d/%d = the core called directly%s\n",
           (unsigned)od_ctrl, n_same_drive, N, n_same_core, N,
           od_ctrl == 3u ? " (identification started by SDO at step 120, RLS beside)" : "");
}

/* Refusals and the switch back to You 2019. */
static void test_selection_rules(void)
{
    setup_drive();
    /* default You 2019 model is nearly round (4.46 / 4.54 mH): accepted */
    CHECK_TRUE(sdo_write_u8(C_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 4u) == 0);
    CHECK_TRUE(sdo_write_u8(C_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 2u) == 0);
    /* salient model: the single-inductance laws are refused */
    CHECK_TRUE(sdo_write_f32(C_IDX, OD_DRIVE_CONTROLLER_LQ_HAT_H_SUB, 2.27e-3f) == 0);
    for (uint8_t c = 3u; c <= 5u; ++c)
        CHECK_TRUE(sdo_write_u8(C_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, c) == CO_ABORT_INVALID_VALUE);
    CHECK_TRUE(sdo_write_u8(C_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 6u) == CO_ABORT_VALUE_HIGH);
    /* online tuning (You 2019) stays reserved to controller 2 */
    CHECK_TRUE(sdo_write_f32(C_IDX, OD_DRIVE_CONTROLLER_LQ_HAT_H_SUB, 4.46e-3f) == 0);
    CHECK_TRUE(sdo_write_u8(C_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 5u) == 0);
    CHECK_TRUE(sdo_write_u8(OD_DRIVE_ONLINE_TUNING_IDX, OD_DRIVE_ONLINE_TUNING_ENABLE_SUB, 1u) ==
               CO_ABORT_PARAM_INCOMPAT);

    /* back to You 2019: commands bit-identical to a fresh You 2019 drive */
    CHECK_TRUE(sdo_write_u8(C_IDX, OD_DRIVE_CONTROLLER_CONTROLLER_SUB, 2u) == 0);
    static drive_t ref;
    drive_config_t cfg;
    drive_default_config(&cfg);
    cfg.Lq_hat_H = 4.46e-3f;
    drive_init(&ref, &cfg);
    int same = 0;
    for (uint16_t k = 0; k < 50u; ++k) {
        const drive_meas_t m = meas_of(k);
        const co_frame_t *f = sample(&m, k);
        drive_cmd_t c;
        drive_current_step(&ref, &m, &c);
        if (cmd_is(f, c.v_alpha_V, c.v_beta_V)) ++same;
    }
    CHECK_TRUE(same == 50);
    printf("selection rules: salient model refused (0x06090030) for 3-5, 6 above range; back to You 2019: %d/50 "
           "bit-identical\n",
           same);
}

int main(void)
{
    load_motor();
    run_controller(3u);
    run_controller(4u);
    run_controller(5u);
    test_selection_rules();
    return check_finish("test_shim_controllers");
}
