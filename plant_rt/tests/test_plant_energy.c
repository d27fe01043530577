/*
 * Energy accounting: input = copper + delta(stored magnetic) + mechanical.
 *  - exact path (IMPOSED 1000 rpm, Ld != Lq, random commands, with SVPWM
 *    limit and dead time so the applied voltage differs from the command):
 *    residual bound 1e-10 of the input energy;
 *  - exact path locked rotor: mech must be exactly 0, residual 1e-10;
 *  - independent check of the integrals themselves (Ld = Lq, where the
 *    stator-frame current has a closed form): copper and input energy over
 *    200 periods vs Simpson quadrature (400 points per period, long double)
 *    of 1.5 R |i(t)|^2 and 1.5 v . i(t); bound 1e-9 relative.
 */
#include <complex.h>

#include "check.h"
#include "plant_test_util.h"
#include "presets.h"

int main(void)
{
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "preset");
    plant_config_ideal(&c);
    c.mech_mode = PLANT_MECH_IMPOSED_SPEED;
    c.omega_imposed_rad_s = 1000.0 * 2.0 * (double)T_PI / 60.0;
    c.mod_limit = PLANT_MOD_SVPWM_HEX;
    c.t_dead_s = 2e-6;

    for (int pass = 0; pass < 2; ++pass) {
        plant_config_t cc = c;
        if (pass == 1) {
            cc.mech_mode = PLANT_MECH_LOCKED;
        }
        plant_state_t s;
        plant_init(&s, &cc);
        CHECK(s.status == 0, "prepare %d", s.status);
        unsigned long long st = 4242u;
        double va = 0.0, vb = 0.0;
        for (int k = 0; k < 5000; ++k) {
            if (k % 40 == 0) {
                va = 400.0 * (test_lcg_uniform(&st) - 0.5);
                vb = 400.0 * (test_lcg_uniform(&st) - 0.5);
            }
            plant_step(&s, &cc, va, vb);
        }
        const plant_energy_t *e = &s.energy;
        const double dW = plant_magnetic_energy_J(&s, &cc) - e->W_mag0_J;
        const double r = plant_energy_residual_J(&s, &cc);
        printf("%s: in %.9f J, copper %.9f J, dW_mag %.3e J, mech %.9f J, residual %.3e J (%.3e of input)\n",
               pass ? "locked" : "1000 rpm", e->in_J, e->copper_J, dW, e->mech_J, r, fabs(r) / e->in_J);
        CHECK(e->in_J > 0.0 && e->copper_J > 0.0, "positive input/copper");
        CHECK(fabs(r) / e->in_J < 1e-10, "energy balance residual");
        if (pass == 1) {
            CHECK(e->mech_J == 0.0, "locked rotor does no mechanical work");
        } else {
            CHECK(fabs(e->mech_J) > 1e-3 * e->in_J, "mechanical work should be significant");
        }
    }

    /* Independent copper-energy check, Ld = Lq closed form (see
     * test_plant_step_response for the formula), 200 periods, Simpson. */
    {
        plant_config_t c2 = c;
        plant_config_ideal(&c2);
        c2.Ld_H = c2.Lq_H = 4.5e-3;
        plant_state_t s;
        plant_init(&s, &c2);
        const long double complex J = (long double complex)I;
        const long double w = 5.0L * (long double)c2.omega_imposed_rad_s;
        const long double R = (long double)c2.R_ohm, L = (long double)c2.Lq_H, psi = (long double)c2.psi_Wb;
        const long double complex v = 20.0L - 9.0L * J;
        const long double complex denom = R + J * w * L;
        const long double complex ip0 = -J * w * psi / denom;
        long double ecu = 0.0L, ein = 0.0L;
        const int N = 200, M = 400;
        const long double T = (long double)N * (long double)c2.Ts_s;
        for (int j = 0; j <= N * M; ++j) {
            const long double t = T * j / (N * M);
            const long double complex i_t =
                v / R - J * w * psi * cexpl(J * w * t) / denom + (-v / R - ip0) * expl(-t * R / L);
            const long double wgt = (j == 0 || j == N * M) ? 1.0L : ((j % 2) ? 4.0L : 2.0L);
            ecu += wgt * 1.5L * R * (creall(i_t) * creall(i_t) + cimagl(i_t) * cimagl(i_t));
            ein += wgt * 1.5L * (creall(v) * creall(i_t) + cimagl(v) * cimagl(i_t));
        }
        ecu *= T / (N * M) / 3.0L;
        ein *= T / (N * M) / 3.0L;
        for (int k = 0; k < N; ++k) {
            plant_step(&s, &c2, (double)creall(v), (double)cimagl(v));
        }
        const double rc = fabs(s.energy.copper_J - (double)ecu) / (double)ecu;
        const double ri = fabs(s.energy.in_J - (double)ein) / (double)ein;
        printf("Ld=Lq closed form + Simpson: copper %.12f J (plant %.12f, rel %.2e), input %.12f J (plant %.12f, rel "
               "%.2e)\n",
               (double)ecu, s.energy.copper_J, rc, (double)ein, s.energy.in_J, ri);
        CHECK(rc < 1e-9 && ri < 1e-9, "energy integrals vs closed form");
    }
    return check_finish("test_plant_energy");
}
