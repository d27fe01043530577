/*
 * Exactness of the matrix-exponential discretization (You 2019 motor,
 * Ld != Lq) against the independent long-double RK4 reference
 * (plant_test_util.h, 2000 sub-steps per period, flux-linkage states, trig
 * evaluated at every stage), at standstill and at 1000 rpm, with a random
 * sequence of stator-frame voltage commands.  Also compares the exact
 * per-period energy integrals (Van Loan) with the reference quadratures.
 */
#include "check.h"
#include "plant_test_util.h"
#include "presets.h"

static void run_case(const char *label, plant_config_t *c, double theta_m0, int nper, double vmax, double *err_i,
                     double *err_e)
{
    plant_state_t s;
    plant_init(&s, c);
    CHECK(s.status == 0, "prepare %d", s.status);
    CHECK(s.exact, "expected the exact path");
    plant_set_mech(&s, c, theta_m0, 0.0);
    ref_par_t rp = ref_from_config(c);
    ref_state_t rs;
    memset(&rs, 0, sizeof(rs));
    ref_set_currents(&rp, &rs, 0.0L, 0.0L);
    rs.th_e = (long double)c->pole_pairs * (long double)theta_m0;
    rs.wm = (long double)s.omega_m_rad_s;

    unsigned long long st = 12345u;
    double emax = 0.0, imax = 0.0;
    double va = 0.0, vb = 0.0;
    for (int k = 0; k < nper; ++k) {
        /* new random command every 20 periods, components in [-vmax, vmax] */
        if (k % 20 == 0) {
            va = 2.0 * vmax * (test_lcg_uniform(&st) - 0.5);
            vb = 2.0 * vmax * (test_lcg_uniform(&st) - 0.5);
        }
        plant_step(&s, c, va, vb);
        ref_period(&rp, &rs, va, vb, c->Ts_s, 2000);
        long double id, iq;
        ref_currents(&rp, &rs, &id, &iq);
        const double e = hypot(s.id_A - (double)id, s.iq_A - (double)iq);
        if (e > emax) {
            emax = e;
        }
        const double mag = (double)hypotl(id, iq);
        if (mag > imax) {
            imax = mag;
        }
    }
    *err_i = emax / imax;
    const double ein = fabs(s.energy.in_J - (double)rs.e_in) / fabs((double)rs.e_in);
    const double ecu = fabs(s.energy.copper_J - (double)rs.e_cu) / fabs((double)rs.e_cu);
    double eme = 0.0;
    if (rs.e_mech != 0.0L) {
        eme = fabs(s.energy.mech_J - (double)rs.e_mech) / (double)fabsl(rs.e_mech);
    } else {
        eme = fabs(s.energy.mech_J);
    }
    *err_e = fmax(ein, fmax(ecu, eme));
    printf("%s: %d periods, peak |i| %.3f A, max current error %.3e (relative)\n", label, nper, imax, *err_i);
    printf("%s: energy in %.6e J (ref %.6e), copper %.6e J (ref %.6e), mech %.6e J (ref %.6e); max rel err %.3e\n",
           label, s.energy.in_J, (double)rs.e_in, s.energy.copper_J, (double)rs.e_cu, s.energy.mech_J,
           (double)rs.e_mech, *err_e);
}

int main(void)
{
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "preset");
    plant_config_ideal(&c);

    double ei, ee;
    c.mech_mode = PLANT_MECH_LOCKED;
    run_case("standstill (theta_m=0.37 rad)", &c, 0.37, 400, 60.0, &ei, &ee);
    CHECK(ei < 1e-6, "standstill current error %.3e", ei);
    CHECK(ee < 1e-6, "standstill energy error %.3e", ee);

    c.mech_mode = PLANT_MECH_IMPOSED_SPEED;
    c.omega_imposed_rad_s = 1000.0 * 2.0 * (double)T_PI / 60.0;
    run_case("1000 rpm", &c, 0.37, 400, 60.0, &ei, &ee);
    CHECK(ei < 1e-6, "1000 rpm current error %.3e", ei);
    CHECK(ee < 1e-6, "1000 rpm energy error %.3e", ee);

    c.omega_imposed_rad_s = -3000.0 * 2.0 * (double)T_PI / 60.0;
    run_case("-3000 rpm", &c, 1.1, 400, 60.0, &ei, &ee);
    CHECK(ei < 1e-6, "-3000 rpm current error %.3e", ei);
    CHECK(ee < 1e-6, "-3000 rpm energy error %.3e", ee);

    /* High-frequency motor of Yao 2020: w*T = 0.84 rad per period. */
    plant_config_t ch;
    CHECK(plant_preset_load("yao2020_high", &ch) == 0, "preset");
    ch.mech_mode = PLANT_MECH_IMPOSED_SPEED;
    ch.omega_imposed_rad_s = 2.0 * (double)T_PI * 1330.0;
    run_case("yao2020_high 1.33 kHz", &ch, 0.2, 300, 3.0, &ei, &ee);
    CHECK(ei < 1e-6, "yao high current error %.3e", ei);
    CHECK(ee < 1e-6, "yao high energy error %.3e", ee);
    return check_finish("test_plant_exactness");
}
