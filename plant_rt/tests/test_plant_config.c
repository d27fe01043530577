/*
 * Configuration validation and presets.
 *  - defaults are valid and have every non-ideality off;
 *  - each invalid parameter is rejected by plant_prepare with its error code
 *    and plant_step is then a no-op;
 *  - all presets load by name, carry the paper values, and prepare in all
 *    three mechanical modes; unknown names are rejected.
 */
#include "check.h"
#include "plant_test_util.h"
#include "presets.h"

typedef void (*mutate_fn)(plant_config_t *c);

static void m_ts0(plant_config_t *c) { c->Ts_s = 0.0; }
static void m_tsneg(plant_config_t *c) { c->Ts_s = -1e-4; }
static void m_ld0(plant_config_t *c) { c->Ld_H = 0.0; }
static void m_lqneg(plant_config_t *c) { c->Lq_H = -1e-3; }
static void m_rneg(plant_config_t *c) { c->R_ohm = -0.1; }
static void m_rnan(plant_config_t *c) { c->R_ohm = (double)NAN; }
static void m_tsinf(plant_config_t *c) { c->Ts_s = (double)INFINITY; }
static void m_pp0(plant_config_t *c) { c->pole_pairs = 0; }
static void m_psineg(plant_config_t *c) { c->psi_Wb = -0.01; }
static void m_jfree(plant_config_t *c)
{
    c->mech_mode = PLANT_MECH_FREE;
    c->J_kgm2 = 0.0;
}
static void m_bneg(plant_config_t *c) { c->B_Nm_per_rad_s = -1.0; }
static void m_mode(plant_config_t *c) { c->mech_mode = (plant_mech_mode_t)7; }
static void m_vdc(plant_config_t *c)
{
    c->mod_limit = PLANT_MOD_CIRCLE;
    c->Vdc_V = 0.0;
}
static void m_modenum(plant_config_t *c) { c->mod_limit = (plant_mod_limit_t)9; }
static void m_dtlong(plant_config_t *c) { c->t_dead_s = 2.0 * c->Ts_s; }
static void m_dtneg(plant_config_t *c) { c->t_dead_s = -1e-6; }
static void m_sat_is(plant_config_t *c)
{
    c->sat_enable = true;
    c->sat_I_A = 0.0;
}
static void m_sat_li(plant_config_t *c)
{
    c->sat_enable = true;
    c->sat_Lq_inf_H = 2.0 * c->Lq_H;
}
static void m_adc(plant_config_t *c) { c->adc_noise_std_A = -0.1; }
static void m_lsb(plant_config_t *c) { c->adc_lsb_A = -0.1; }
static void m_trip(plant_config_t *c) { c->I_trip_A = -1.0; }
static void m_rk4(plant_config_t *c) { c->rk4_h_rel = 0.0; }
static void m_hold(plant_config_t *c) { c->hold_frame = (plant_hold_frame_t)3; }

int main(void)
{
    plant_config_t d;
    plant_config_defaults(&d);
    plant_state_t s;
    plant_init(&s, &d);
    CHECK(s.status == PLANT_OK, "defaults valid");
    CHECK(!d.sat_enable && d.mod_limit == PLANT_MOD_NONE && d.t_dead_s == 0.0 && d.adc_lsb_A == 0.0 &&
              d.adc_noise_std_A == 0.0 && d.adc_offset_a_A == 0.0 && d.adc_offset_b_A == 0.0 &&
              d.adc_full_scale_A == 0.0 && d.encoder_lines == 0u && d.I_trip_A == 0.0 &&
              d.hold_frame == PLANT_HOLD_STATOR,
          "defaults: all non-idealities off");

    struct {
        const char *name;
        mutate_fn f;
        int code;
    } cases[] = {
        {"Ts = 0", m_ts0, PLANT_ERR_TS},
        {"Ts < 0", m_tsneg, PLANT_ERR_TS},
        {"Ld = 0", m_ld0, PLANT_ERR_L},
        {"Lq < 0", m_lqneg, PLANT_ERR_L},
        {"R < 0", m_rneg, PLANT_ERR_R},
        {"R = NaN", m_rnan, PLANT_ERR_NONFINITE},
        {"Ts = inf", m_tsinf, PLANT_ERR_NONFINITE},
        {"pole pairs 0", m_pp0, PLANT_ERR_POLES},
        {"psi < 0", m_psineg, PLANT_ERR_PSI},
        {"J = 0 in FREE", m_jfree, PLANT_ERR_MECH},
        {"B < 0", m_bneg, PLANT_ERR_MECH},
        {"mech mode 7", m_mode, PLANT_ERR_MECH},
        {"limit with Vdc 0", m_vdc, PLANT_ERR_VDC},
        {"mod enum 9", m_modenum, PLANT_ERR_ENUM},
        {"t_dead >= T_pwm", m_dtlong, PLANT_ERR_DEADTIME},
        {"t_dead < 0", m_dtneg, PLANT_ERR_DEADTIME},
        {"sat I_sat 0", m_sat_is, PLANT_ERR_SAT},
        {"sat Lq_inf > Lq", m_sat_li, PLANT_ERR_SAT},
        {"noise < 0", m_adc, PLANT_ERR_SENSOR},
        {"LSB < 0", m_lsb, PLANT_ERR_SENSOR},
        {"I_trip < 0", m_trip, PLANT_ERR_TRIP},
        {"rk4_h_rel 0", m_rk4, PLANT_ERR_RK4},
        {"hold enum 3", m_hold, PLANT_ERR_ENUM},
    };
    for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); ++i) {
        plant_config_t c = d;
        cases[i].f(&c);
        plant_state_t st;
        plant_init(&st, &c);
        const int rc = plant_prepare(&st, &c);
        plant_set_currents(&st, 1.0, 2.0);
        plant_step(&st, &c, 10.0, 10.0);
        printf("invalid %-18s -> %d (expected %d), step no-op: %s\n", cases[i].name, rc, cases[i].code,
               (st.k == 0 && st.id_A == 1.0 && st.iq_A == 2.0) ? "yes" : "NO");
        CHECK(rc == cases[i].code, "%s", cases[i].name);
        CHECK(st.status == rc, "status stored");
        CHECK(st.k == 0 && st.id_A == 1.0 && st.iq_A == 2.0, "step must be a no-op");
        /* the zero-J config is fine when not FREE */
    }
    {
        plant_config_t c = d;
        c.J_kgm2 = 0.0;
        CHECK(plant_prepare(&s, &c) == PLANT_OK, "J = 0 is fine when LOCKED");
        CHECK(plant_prepare(NULL, &c) == PLANT_ERR_NULL, "NULL state");
        CHECK(plant_prepare(&s, NULL) == PLANT_ERR_NULL, "NULL config");
    }

    /* presets */
    CHECK(plant_preset_count() == 4, "4 presets");
    for (size_t i = 0; i < plant_preset_count(); ++i) {
        plant_config_t c;
        const char *n = plant_preset_name(i);
        CHECK(plant_preset_load(n, &c) == 0, "load %s", n);
        printf("preset %-13s Ts %.0f us, Vdc %.0f V, R %.4g ohm, Ld %.4g H, Lq %.4g H, psi %.5g Wb, p %d, J %.4g, "
               "t_dead %.1f us, enc %u  [%s]\n",
               n, c.Ts_s * 1e6, c.Vdc_V, c.R_ohm, c.Ld_H, c.Lq_H, c.psi_Wb, (int)c.pole_pairs, c.J_kgm2,
               c.t_dead_s * 1e6, c.encoder_lines, plant_preset_source(i));
        for (int mode = 0; mode < 3; ++mode) {
            c.mech_mode = (plant_mech_mode_t)mode;
            c.omega_imposed_rad_s = 100.0;
            plant_state_t st;
            plant_init(&st, &c);
            CHECK(st.status == 0, "preset %s mode %d prepare %d", n, mode, st.status);
            c.sat_enable = true;
            CHECK(plant_prepare(&st, &c) == 0, "preset %s with saturation", n);
            c.sat_enable = false;
        }
    }
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "you2019");
    CHECK(c.R_ohm == 1.4 && c.Ld_H == 4.46e-3 && c.Lq_H == 4.54e-3 && c.psi_Wb == 0.042 && c.pole_pairs == 5 &&
              c.Vdc_V == 300.0 && c.Ts_s == 55e-6 && c.t_dead_s == 2e-6 && c.encoder_lines == 2500u,
          "you2019 values (Tables A1/A2)");
    CHECK(plant_preset_load("yao2020_low", &c) == 0 && c.R_ohm == 2.2 && c.Ld_H == 5.5e-3 && c.Vdc_V == 300.0 &&
              c.pole_pairs == 4 && c.Ts_s == 100e-6,
          "yao2020_low values (Table I)");
    CHECK(plant_preset_load("yao2020_high", &c) == 0 && c.R_ohm == 0.045 && c.Lq_H == 24e-6 && c.Vdc_V == 48.0 &&
              c.pole_pairs == 1,
          "yao2020_high values (Table II)");
    CHECK(plant_preset_load("zhao2022", &c) == 0 && c.R_ohm == 48.9 && c.Ld_H == 14e-3 && c.Vdc_V == 28.0 &&
              c.J_kgm2 == 9.717e-5 && fabs(1.5 * c.pole_pairs * c.psi_Wb - 1.4213) < 1e-12,
          "zhao2022 values (Table 1, Kt = 1.5 p psi)");
    plant_config_t before = c;
    CHECK(plant_preset_load("nonexistent", &c) == PLANT_ERR_PRESET, "unknown name");
    CHECK(plant_preset_load(NULL, &c) == PLANT_ERR_PRESET, "NULL name");
    CHECK(memcmp(&before, &c, sizeof(c)) == 0, "config untouched on failure");
    CHECK(plant_preset_name(99) == NULL, "name out of range");
    return check_finish("test_plant_config");
}
