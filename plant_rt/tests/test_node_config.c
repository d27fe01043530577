/* test_node_config.c - model parameters by SDO: effective at the next period
 * boundary, presets (0x2004), rejected values leave the model unchanged. */
#include <math.h>
#include <stdio.h>

#include "check.h"
#include "plant_testbus.h"
#include "presets.h"

static tb_t g_tb;

#define MM (OD_PLANT.mfr.x2000_motor_model)
#define INV (OD_PLANT.mfr.x2001_Inverter)

static void test_defaults_are_you2019(void)
{
    plant_config_t p, od;
    plant_preset_load("you2019", &p);
    plant_app_config_to_od(&p); /* rounds to REAL32 */
    plant_config_t pr;
    plant_app_config_from_od(&pr);
    tb_init(&g_tb); /* OD back to the EDS defaults */
    plant_app_config_from_od(&od);
    int same = memcmp(&pr, &od, sizeof od) == 0;
    printf("EDS defaults == preset you2019 (REAL32): %s\n", same ? "yes" : "no");
    CHECK(same, "EDS defaults differ from the you2019 preset");
    CHECK(strcmp(OD_PLANT.mfr.x2004_motor_preset, "you2019") == 0, "0x2004 default");
}

static void test_boundary(void)
{
    tb_t *tb = &g_tb;
    tb_init(tb);
    tb_start(tb, 0xFFFFFFFFu);
    const int K = 8, N = 20;
    for (int j = 0; j < N; ++j) {
        if (j == K) {
            /* written during [K, K+1]: the OD has it at once, the model from SYNC K+1 */
            CHECK(tb_w_f32(tb, 0x2000, OD_PLANT_MOTOR_MODEL_R_OHM_SUB, 5.0f) == 0, "R write");
            CHECK(MM.R_ohm == 5.0f && tb->app.cfg.R_ohm != 5.0, "R applied before the boundary");
        }
        tb_period(tb, 10.0f, -4.0f);
        if (j == K) CHECK(tb->app.cfg.R_ohm == 5.0, "R not applied at the boundary");
    }
    /* reference: the core with R changed after integrating [K, K+1] */
    plant_config_t c;
    tb_init(tb); /* defaults */
    plant_app_config_from_od(&c);
    plant_state_t s;
    plant_meas_t m;
    plant_init(&s, &c);
    static float ia[64];
    for (int j = 0; j <= N; ++j) {
        if (j > 0) plant_step(&s, &c, j >= 2 ? 10.0 : 0.0, j >= 2 ? -4.0 : 0.0);
        if (j == K + 1) {
            c.R_ohm = 5.0;
            plant_prepare(&s, &c);
        }
        plant_sample(&s, &c, &m);
        ia[j] = m.i_a_A;
    }
    /* rerun the node to compare (the first tb was reset above) */
    tb_init(tb);
    tb_start(tb, 0xFFFFFFFFu);
    for (int j = 0; j < N; ++j) {
        if (j == K) tb_w_f32(tb, 0x2000, OD_PLANT_MOTOR_MODEL_R_OHM_SUB, 5.0f);
        tb_period(tb, 10.0f, -4.0f);
    }
    int mism = 0;
    for (int j = 0; j <= N; ++j) mism += !testbus_same_f32(ia[j], tb->smp[j].ia);
    printf("R 1.4 -> 5 ohm written after sample %d: node vs core (change at SYNC %d): %d of %d samples differ\n", K,
           K + 1, mism, N + 1);
    printf("  i_a(K+1) %.6f, i_a(K+2) %.6f, i_a(N) %.6f A\n", (double)tb->smp[K + 1].ia, (double)tb->smp[K + 2].ia,
           (double)tb->smp[N].ia);
    CHECK(mism == 0, "boundary semantics");
}

static void test_rejects_and_presets(void)
{
    tb_t *tb = &g_tb;
    tb_init(tb);
    tb_start(tb, 0xFFFFFFFFu);
    plant_config_t before = tb->app.cfg;
    uint32_t a;
    a = tb_w_f32(tb, 0x2000, OD_PLANT_MOTOR_MODEL_LD_H_SUB, 50.0f);
    printf("Ld_H = 50 H: abort 0x%08X\n", (unsigned)a);
    CHECK(a == CO_ABORT_VALUE_HIGH, "range check");
    a = tb_w_f32(tb, 0x2001, OD_PLANT_INVERTER_T_DEAD_S_SUB, 9e-5f); /* >= Ts_pwm 55 us */
    printf("t_dead_s = 90 us with Ts_pwm 55 us: abort 0x%08X\n", (unsigned)a);
    CHECK(a == CO_ABORT_PARAM_INCOMPAT, "dead time >= PWM period accepted");
    CHECK(INV.t_dead_s == 2e-6f, "OD changed by a rejected write");
    CHECK(tb_w_f32(tb, 0x2000, OD_PLANT_MOTOR_MODEL_J_KGM2_SUB, 0.0f) == 0, "J = 0 in locked mode");
    a = tb_w_u8(tb, 0x2000, OD_PLANT_MOTOR_MODEL_MECH_MODE_SUB, 0);
    printf("mech_mode = free with J = 0: abort 0x%08X\n", (unsigned)a);
    CHECK(a == CO_ABORT_PARAM_INCOMPAT, "free with J = 0 accepted");
    CHECK(tb_w_u8(tb, 0x2000, OD_PLANT_MOTOR_MODEL_SAT_ENABLE_SUB, 1) == 0, "sat on");
    a = tb_w_f32(tb, 0x2000, OD_PLANT_MOTOR_MODEL_SAT_LQ_INF_H_SUB, 0.01f); /* > Lq */
    printf("sat_Lq_inf_H = 10 mH > Lq = 4.54 mH: abort 0x%08X\n", (unsigned)a);
    CHECK(a == CO_ABORT_PARAM_INCOMPAT, "Lq_inf > Lq accepted");
    tb_w_u8(tb, 0x2000, OD_PLANT_MOTOR_MODEL_SAT_ENABLE_SUB, 0);
    tb_w_f32(tb, 0x2000, OD_PLANT_MOTOR_MODEL_J_KGM2_SUB, 2.77e-5f);
    tb_period(tb, 0, 0);
    before.sat_enable = false;
    CHECK(memcmp(&before, &tb->app.cfg, sizeof before) == 0, "model changed by rejected writes");

    const char *bad = "nosuchmotor";
    a = tb_sdo_write(tb, 0x2004, 0, bad, (uint32_t)strlen(bad));
    printf("preset '%s': abort 0x%08X\n", bad, (unsigned)a);
    CHECK(a == CO_ABORT_INVALID_VALUE, "unknown preset accepted");
    CHECK(strcmp(OD_PLANT.mfr.x2004_motor_preset, "you2019") == 0, "0x2004 changed");

    const char *name = "yao2020_low";
    a = tb_sdo_write(tb, 0x2004, 0, name, (uint32_t)strlen(name));
    CHECK(a == 0, "preset write abort 0x%08X", (unsigned)a);
    CHECK(MM.R_ohm == 2.2f && MM.pole_pairs == 4 && INV.Ts_s == 100e-6f, "preset not in the OD");
    CHECK(tb->app.cfg.R_ohm != (double)2.2f, "preset applied before the boundary");
    int64_t ts_before = plant_app_period_ns(&tb->app);
    tb_period(tb, 0, 0);
    plant_config_t p;
    plant_preset_load(name, &p);
    printf("preset %s: R %.3g ohm, p %d, Ts %lld -> %lld ns at the next SYNC, psi %.3g Wb\n", name, tb->app.cfg.R_ohm,
           (int)tb->app.cfg.pole_pairs, (long long)ts_before, (long long)plant_app_period_ns(&tb->app),
           tb->app.cfg.psi_Wb);
    CHECK(tb->app.cfg.R_ohm == (double)(float)p.R_ohm && tb->app.cfg.Ts_s == (double)(float)p.Ts_s &&
              tb->app.cfg.encoder_lines == p.encoder_lines && tb->app.cfg.t_dead_s == 0.0,
          "preset not applied");
    CHECK(plant_app_period_ns(&tb->app) == 100000, "Ts");
    CHECK(tb->app.config_errors == 0, "config errors %u", (unsigned)tb->app.config_errors);
}

int main(void)
{
    test_defaults_are_you2019();
    test_boundary();
    test_rejects_and_presets();
    return check_finish("test_node_config");
}
