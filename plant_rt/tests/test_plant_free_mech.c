/*
 * FREE mechanics (RK4 path).
 *  1. Mechanical closed form: no magnet flux and no current -> Te = 0,
 *     J dw/dt = -B w - TL:  w(t) = (w0 + TL/B) e^{-t B/J} - TL/B,
 *     theta(t) = theta0 + (w0 + TL/B)(J/B)(1 - e^{-t B/J}) - (TL/B) t.
 *  2. Coupled electro-mechanical run (You 2019 motor, random voltage
 *     commands) vs the independent long-double reference (500 sub-steps per
 *     period): currents, speed and angle, default rk4_h_rel and a coarse one.
 *  3. Energy balances: in = copper + dW_mag + mech (bound 1e-7 of input) and
 *     mech = dKE + friction + load (bound 1e-6 of mech; limited by the RK4
 *     speed error, since KE = J w^2/2 is evaluated from the integrated w).
 */
#include "check.h"
#include "plant_test_util.h"
#include "presets.h"

int main(void)
{
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "preset");
    plant_config_ideal(&c);
    c.mech_mode = PLANT_MECH_FREE;

    /* 1. closed form */
    {
        plant_config_t cm = c;
        cm.psi_Wb = 0.0;
        cm.B_Nm_per_rad_s = 2e-4;
        cm.T_load_Nm = 0.01;
        plant_state_t s;
        plant_init(&s, &cm);
        CHECK(s.status == 0, "prepare %d", s.status);
        const double w0 = 300.0, th0 = 0.2;
        plant_set_mech(&s, &cm, th0, w0);
        const double J = cm.J_kgm2, B = cm.B_Nm_per_rad_s, TL = cm.T_load_Nm;
        double ew = 0.0, eth = 0.0;
        for (int k = 1; k <= 5000; ++k) {
            plant_step(&s, &cm, 0.0, 0.0);
            const double t = k * cm.Ts_s;
            const double e = exp(-t * B / J);
            const double w = (w0 + TL / B) * e - TL / B;
            const double th = th0 + (w0 + TL / B) * (J / B) * (1.0 - e) - TL / B * t;
            const double th_p = s.theta_m_rad + 2.0 * (double)T_PI * (double)s.revolutions;
            ew = fmax(ew, fabs(s.omega_m_rad_s - w) / w0);
            eth = fmax(eth, fabs(th_p - th) / fabs(th));
        }
        printf("closed-form coast-down (5000 periods, w %.1f -> %.3f rad/s): max rel speed err %.3e, angle err %.3e, "
               "revolutions %lld\n",
               w0, s.omega_m_rad_s, ew, eth, (long long)s.revolutions);
        CHECK(ew < 1e-9, "speed closed form");
        CHECK(eth < 1e-9, "angle closed form");
    }

    /* 2. coupled vs reference */
    c.B_Nm_per_rad_s = 1e-4;
    c.T_load_Nm = 0.05;
    const double hrel[2] = {c.rk4_h_rel, 0.2};
    double err_def = 0.0;
    for (int pass = 0; pass < 2; ++pass) {
        plant_config_t cc = c;
        cc.rk4_h_rel = hrel[pass];
        plant_state_t s;
        plant_init(&s, &cc);
        plant_set_mech(&s, &cc, 0.3, 20.0);
        plant_energy_reset(&s, &cc);
        ref_par_t rp = ref_from_config(&cc);
        ref_state_t rs;
        memset(&rs, 0, sizeof(rs));
        ref_set_currents(&rp, &rs, 0.0L, 0.0L);
        rs.th_e = 5.0L * 0.3L;
        rs.wm = 20.0L;
        unsigned long long st = 99u;
        double va = 0.0, vb = 0.0, ei = 0.0, imax = 0.0, ew = 0.0, wmax = 0.0, eth = 0.0;
        unsigned maxsub = 0;
        for (int k = 0; k < 1500; ++k) {
            if (k % 30 == 0) {
                va = 60.0 * (test_lcg_uniform(&st) - 0.5);
                vb = 60.0 * (test_lcg_uniform(&st) - 0.5);
            }
            plant_step(&s, &cc, va, vb);
            if (s.last_substeps > maxsub) {
                maxsub = s.last_substeps;
            }
            ref_period(&rp, &rs, va, vb, cc.Ts_s, 500);
            long double id, iq;
            ref_currents(&rp, &rs, &id, &iq);
            ei = fmax(ei, hypot(s.id_A - (double)id, s.iq_A - (double)iq));
            imax = fmax(imax, (double)hypotl(id, iq));
            ew = fmax(ew, fabs(s.omega_m_rad_s - (double)rs.wm));
            wmax = fmax(wmax, fabs((double)rs.wm));
            const double th_p = s.theta_m_rad + 2.0 * (double)T_PI * (double)s.revolutions;
            eth = fmax(eth, fabs(th_p - (double)(rs.th_e / 5.0L)));
        }
        printf("coupled FREE run, h_rel %.3f (<= %u sub-steps): current err %.3e rel (peak %.2f A), speed err %.3e rel "
               "(peak %.1f rad/s), angle err %.3e rad\n",
               cc.rk4_h_rel, maxsub, ei / imax, imax, ew / wmax, wmax, eth);
        if (pass == 0) {
            err_def = fmax(ei / imax, ew / wmax);
            CHECK(ei / imax < 1e-6, "free current error");
            CHECK(ew / wmax < 1e-6, "free speed error");
            CHECK(eth < 1e-6, "free angle error");
            /* 3. energy balances */
            const plant_energy_t *e = &s.energy;
            const double el = plant_energy_residual_J(&s, &cc);
            const double dke = plant_kinetic_energy_J(&s, &cc) - e->W_kin0_J;
            const double em = e->mech_J - dke - e->friction_J - e->load_J;
            printf("energy: in %.6f J, copper %.6f J, mech %.6f J, dKE %.6f J, friction %.6f J, load %.6f J\n", e->in_J,
                   e->copper_J, e->mech_J, dke, e->friction_J, e->load_J);
            printf("energy: electrical residual %.3e J (%.3e of input), mechanical residual %.3e J (%.3e of |mech|)\n",
                   el, fabs(el) / e->in_J, em, fabs(em) / fabs(e->mech_J));
            CHECK(fabs(el) / e->in_J < 1e-7, "electrical balance");
            CHECK(fabs(em) / fabs(e->mech_J) < 1e-6, "mechanical balance");
        } else {
            CHECK(fmax(ei / imax, ew / wmax) > err_def, "coarse must be worse");
        }
    }
    return check_finish("test_plant_free_mech");
}
