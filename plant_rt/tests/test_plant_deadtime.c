/*
 * Dead-time voltage error (You 2019 drive: Vdc 300 V, t_dead 2 us, PWM
 * period 55 us -> V_dt = 10.909 V; shape -V_dt tanh(i/I_sat), I_sat = 1/3 A).
 *  1. shape: sign opposite to the current, odd, ~linear for |i| << I_sat with
 *     slope -V_dt/I_sat, saturated (>= 99 % of V_dt) at |i| >= 1 A;
 *  2. in the plant: applied alpha-beta voltage = limited command + Clarke of
 *     the three phase errors evaluated from the phase currents at the period
 *     start (phase currents recomputed independently here);
 *  3. effect: locked rotor, constant v_alpha -> steady state satisfies
 *     R I = V - (2/3) V_dt (tanh(I/Is) + tanh(I/(2 Is))) (solved by bisection).
 */
#include "check.h"
#include "plant_test_util.h"
#include "presets.h"

int main(void)
{
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "preset");
    plant_config_ideal(&c);
    c.t_dead_s = 2e-6; /* only dead time on */
    c.mech_mode = PLANT_MECH_LOCKED;
    const double Vdt = c.Vdc_V * c.t_dead_s / c.Ts_pwm_s;
    const double Is = c.deadtime_I_sat_A;
    printf("V_dt = Vdc*t_dead/T_pwm = %.4f V, I_sat = %.4f A\n", Vdt, Is);

    /* 1. shape */
    printf("   i [A]   dv [V]   dv/V_dt\n");
    double prev = 1e300;
    for (double i = -2.0; i <= 2.0001; i += 0.25) {
        const double dv = plant_deadtime_phase_error_V(&c, i);
        printf("  %6.2f  %8.4f  %7.4f\n", i, dv, dv / Vdt);
        CHECK(dv <= prev, "monotone non-increasing");
        prev = dv;
        if (i > 1e-9) {
            CHECK(dv < 0.0, "sign for i>0");
        }
        if (i < -1e-9) {
            CHECK(dv > 0.0, "sign for i<0");
        }
        CHECK(fabs(dv + plant_deadtime_phase_error_V(&c, -i)) < 1e-12, "odd");
    }
    const double slope = plant_deadtime_phase_error_V(&c, 1e-3) / 1e-3;
    printf("small-signal slope %.4f V/A (expected -V_dt/I_sat = %.4f), |dv(1 A)|/V_dt = %.5f, |dv(3 A)|/V_dt = %.9f\n",
           slope, -Vdt / Is, -plant_deadtime_phase_error_V(&c, 1.0) / Vdt,
           -plant_deadtime_phase_error_V(&c, 3.0) / Vdt);
    CHECK(fabs(slope / (-Vdt / Is) - 1.0) < 1e-4, "slope");
    CHECK(-plant_deadtime_phase_error_V(&c, 1.0) / Vdt > 0.99, "saturated at 1 A");
    CHECK(fabs(-plant_deadtime_phase_error_V(&c, 3.0) / Vdt - 1.0) < 1e-6, "saturated at 3 A");
    CHECK(plant_deadtime_phase_error_V(&c, 0.0) == 0.0, "zero at zero current");

    /* 2. applied voltage in the plant, random currents and angles */
    {
        unsigned long long st = 5u;
        double emax = 0.0;
        for (int n = 0; n < 200; ++n) {
            plant_state_t s;
            plant_init(&s, &c);
            const double th_m = 2.0 * (double)T_PI * test_lcg_uniform(&st);
            const double id = 6.0 * (test_lcg_uniform(&st) - 0.5), iq = 6.0 * (test_lcg_uniform(&st) - 0.5);
            plant_set_mech(&s, &c, th_m, 0.0);
            plant_set_currents(&s, id, iq);
            const double th = fmod(5.0 * th_m, 2.0 * (double)T_PI);
            const double ial = cos(th) * id - sin(th) * iq, ibe = sin(th) * id + cos(th) * iq;
            const double ph[3] = {ial, -0.5 * ial + 0.5 * sqrt(3.0) * ibe, -0.5 * ial - 0.5 * sqrt(3.0) * ibe};
            double e[3];
            for (int j = 0; j < 3; ++j) {
                e[j] = -Vdt * tanh(ph[j] / Is);
            }
            const double dva = (2.0 * e[0] - e[1] - e[2]) / 3.0, dvb = (e[1] - e[2]) / sqrt(3.0);
            plant_step(&s, &c, 7.0, -3.0);
            emax = fmax(emax, hypot(s.v_app_alpha_V - (7.0 + dva), s.v_app_beta_V - (-3.0 + dvb)));
        }
        printf("applied voltage vs independent Clarke of phase errors (200 cases): max err %.3e V\n", emax);
        CHECK(emax < 1e-9, "applied voltage");
        /* saturated balanced pattern ia = 2, ib = ic = -1 -> dv_alpha = -(2/3)(tanh(6)+tanh(3)) V_dt */
        plant_state_t s;
        plant_init(&s, &c);
        plant_set_currents(&s, 2.0, 0.0);
        plant_step(&s, &c, 0.0, 0.0);
        printf("ia=2, ib=ic=-1 A: dv = (%.4f, %.2e) V, |dv| = %.4f V = %.4f V_dt (4/3 = 1.3333 when fully saturated)\n",
               s.v_app_alpha_V, s.v_app_beta_V, hypot(s.v_app_alpha_V, s.v_app_beta_V),
               hypot(s.v_app_alpha_V, s.v_app_beta_V) / Vdt);
        CHECK(s.v_app_alpha_V < 0.0 && fabs(s.v_app_beta_V) < 1e-12, "opposes the current vector");
        CHECK(fabs(-s.v_app_alpha_V / Vdt - 2.0 / 3.0 * (tanh(6.0) + tanh(3.0))) < 1e-12, "magnitude");
    }

    /* 3. steady-state effect */
    {
        const double V = 10.0, R = c.R_ohm;
        double lo = 0.0, hi = V / R;
        for (int it = 0; it < 200; ++it) {
            const double I = 0.5 * (lo + hi);
            const double f = R * I - V + (2.0 / 3.0) * Vdt * (tanh(I / Is) + tanh(I / (2.0 * Is)));
            if (f > 0.0) {
                hi = I;
            } else {
                lo = I;
            }
        }
        const double Iexp = 0.5 * (lo + hi);
        plant_state_t s;
        plant_init(&s, &c);
        for (int k = 0; k < 20000; ++k) {
            plant_step(&s, &c, V, 0.0);
        }
        printf("locked rotor, v_alpha = %.1f V: steady i_a = %.9f A (expected %.9f A; without dead time %.4f A)\n", V,
               s.id_A, Iexp, V / R);
        CHECK(fabs(s.id_A - Iexp) < 1e-9, "steady state with dead time");
        CHECK(fabs(s.iq_A) < 1e-9, "no q current");
    }
    return check_finish("test_plant_deadtime");
}
