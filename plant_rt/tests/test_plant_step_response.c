/*
 * Open-loop voltage step responses vs closed-form solutions.
 *  1. standstill, d axis on phase a: i_a(t) = V/R (1 - exp(-t R/Ld))
 *  2. standstill, rotor at theta_e = 90 deg (q axis on -alpha):
 *     iq(t) = -V/R (1 - exp(-t R/Lq))
 *  3. at 1000 rpm (imposed), Ld = Lq = L, constant alpha-beta voltage:
 *     complex i(t) = v/R + ip(t) + (i0 - v/R - ip(0)) exp(-t R/L),
 *     ip(t) = -j w psi exp(j theta(t)) / (R + j w L)
 */
#include <complex.h>

#include "check.h"
#include "plant_test_util.h"
#include "presets.h"

static double run_standstill(plant_config_t *c, double theta_e, double V, int axis_q)
{
    plant_state_t s;
    plant_init(&s, c);
    CHECK(s.status == 0, "prepare %d", s.status);
    plant_set_mech(&s, c, theta_e / (double)c->pole_pairs, 0.0);
    const double L = axis_q ? c->Lq_H : c->Ld_H;
    double maxerr = 0.0, imax = 0.0;
    for (int k = 1; k <= 600; ++k) {
        plant_step(&s, c, V, 0.0);
        const double t = (double)k * c->Ts_s;
        const double ia = (double)((long double)V / (long double)c->R_ohm *
                                   (1.0L - expl(-(long double)t * (long double)c->R_ohm / (long double)L)));
        const double got = axis_q ? -s.iq_A : s.id_A;
        const double other = axis_q ? s.id_A : s.iq_A;
        const double e = fabs(got - ia) + fabs(other);
        if (e > maxerr) {
            maxerr = e;
        }
        if (fabs(ia) > imax) {
            imax = fabs(ia);
        }
    }
    return maxerr / imax;
}

int main(void)
{
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "preset");
    plant_config_ideal(&c);
    c.mech_mode = PLANT_MECH_LOCKED;

    const double V = 5.0;
    const double ed = run_standstill(&c, 0.0, V, 0);
    const double eq = run_standstill(&c, 0.5 * (double)T_PI, V, 1);
    printf("standstill d-axis RL step (600 periods, V=%g V): max rel error %.3e\n", V, ed);
    printf("standstill q-axis RL step (600 periods, V=%g V): max rel error %.3e\n", V, eq);
    CHECK(ed < 1e-9, "d-axis step error %.3e", ed);
    CHECK(eq < 1e-9, "q-axis step error %.3e", eq);

    /* Sanity of the reference: final value reached (33 time constants). */
    {
        plant_state_t s;
        plant_init(&s, &c);
        for (int k = 0; k < 20000; ++k) {
            plant_step(&s, &c, V, 0.0);
        }
        printf("standstill final current %.12f A (V/R = %.12f A)\n", s.id_A, V / c.R_ohm);
        CHECK(fabs(s.id_A - V / c.R_ohm) < 1e-9, "final value");
    }

    /* 3. at speed, Ld = Lq */
    plant_config_t c2 = c;
    c2.Ld_H = c2.Lq_H = 4.5e-3;
    c2.mech_mode = PLANT_MECH_IMPOSED_SPEED;
    c2.omega_imposed_rad_s = 1000.0 * 2.0 * (double)T_PI / 60.0;
    plant_state_t s;
    plant_init(&s, &c2);
    CHECK(s.status == 0, "prepare %d", s.status);
    const double th0 = 0.3;
    plant_set_mech(&s, &c2, th0 / 5.0, 0.0);
    const long double complex J = (long double complex)I;
    const long double complex v = 20.0L + 7.0L * J;
    const long double w = 5.0L * (long double)c2.omega_imposed_rad_s;
    const long double R = (long double)c2.R_ohm, L = (long double)c2.Lq_H, psi = (long double)c2.psi_Wb;
    const long double complex denom = R + J * w * L;
    double maxerr = 0.0, imax = 0.0;
    for (int k = 1; k <= 2000; ++k) {
        plant_step(&s, &c2, (double)creall(v), (double)cimagl(v));
        const long double t = (long double)k * (long double)c2.Ts_s;
        const long double complex ip0 = -J * w * psi * cexpl(J * (long double)th0) / denom;
        const long double complex ipt = -J * w * psi * cexpl(J * ((long double)th0 + w * t)) / denom;
        const long double complex iref = v / R + ipt + (0.0L - v / R - ip0) * expl(-t * R / L);
        plant_meas_t m;
        plant_sample(&s, &c2, &m);
        const double e = hypot(m.i_alpha_A - (double)creall(iref), m.i_beta_A - (double)cimagl(iref));
        if (e > maxerr) {
            maxerr = e;
        }
        if ((double)cabsl(iref) > imax) {
            imax = (double)cabsl(iref);
        }
    }
    printf("1000 rpm, Ld=Lq, alpha-beta step vs closed form (2000 periods): max err %.3e A, rel %.3e (peak %.3f A)\n",
           maxerr, maxerr / imax, imax);
    CHECK(maxerr / imax < 1e-9, "at-speed closed form error %.3e", maxerr / imax);
    return check_finish("test_plant_step_response");
}
