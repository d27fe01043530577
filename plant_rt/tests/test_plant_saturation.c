/*
 * q-axis saturation (flux-linkage model, see pmsm_plant.h), integrated by the
 * RK4 path.  Checks:
 *  1. model functions: L_inc = dpsi_q/diq (central difference), W_q = int iq
 *     dpsi_q (Simpson quadrature), L_inc(0) = Lq, L_inc(I_sat) = (Lq+Lq_inf)/2;
 *  2. accuracy vs the independent long-double reference (flux states + Newton
 *     inversion, 600 sub-steps) at standstill and 1000 rpm, with the default
 *     rk4_h_rel (bound 1e-6 relative) and a coarse one (reported, to show the
 *     h^4 convergence);
 *  3. energy balance with saturation (residual < 1e-7 of the input energy);
 *  4. saturation really changes the response (> 5 % at ~3 I_sat).
 */
#include "check.h"
#include "plant_test_util.h"
#include "presets.h"

static double run_vs_ref(plant_config_t *c, double theta_m0, int nper, double *resid_rel, unsigned *substeps)
{
    plant_state_t s;
    plant_init(&s, c);
    CHECK(s.status == 0, "prepare %d", s.status);
    CHECK(!s.exact, "saturation must use the RK4 path");
    plant_set_mech(&s, c, theta_m0, 0.0);
    ref_par_t rp = ref_from_config(c);
    ref_state_t rs;
    memset(&rs, 0, sizeof(rs));
    ref_set_currents(&rp, &rs, 0.0L, 0.0L);
    rs.th_e = (long double)c->pole_pairs * (long double)theta_m0;
    rs.wm = (long double)s.omega_m_rad_s;
    unsigned long long st = 777u;
    double va = 0.0, vb = 0.0, emax = 0.0, imax = 0.0;
    for (int k = 0; k < nper; ++k) {
        if (k % 25 == 0) {
            va = 80.0 * (test_lcg_uniform(&st) - 0.5);
            vb = 80.0 * (test_lcg_uniform(&st) - 0.5);
        }
        plant_step(&s, c, va, vb);
        ref_period(&rp, &rs, va, vb, c->Ts_s, 600);
        long double id, iq;
        ref_currents(&rp, &rs, &id, &iq);
        emax = fmax(emax, hypot(s.id_A - (double)id, s.iq_A - (double)iq));
        imax = fmax(imax, (double)hypotl(id, iq));
    }
    *resid_rel = fabs(plant_energy_residual_J(&s, c)) / fabs(s.energy.in_J);
    *substeps = s.last_substeps;
    return emax / imax;
}

int main(void)
{
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "preset");
    plant_config_ideal(&c);
    c.sat_enable = true;
    c.sat_I_A = 3.0;
    c.sat_Lq_inf_H = 0.3 * c.Lq_H;
    CHECK(plant_prepare(&(plant_state_t){0}, &c) == 0, "valid saturation config");

    /* 1. model functions */
    double e_l = 0.0, e_w = 0.0;
    for (double iq = -15.0; iq <= 15.0; iq += 0.37) {
        const double h = 1e-5;
        const double num = (plant_psi_q_Wb(&c, iq + h) - plant_psi_q_Wb(&c, iq - h)) / (2.0 * h);
        e_l = fmax(e_l, fabs(num - plant_Lq_inc_H(&c, iq)) / c.Lq_H);
        /* W_q(iq) = int_0^iq x L_inc(x) dx, Simpson with 2000 intervals */
        const int n = 2000;
        double acc = 0.0;
        for (int j = 0; j <= n; ++j) {
            const double x = iq * j / n;
            const double wgt = (j == 0 || j == n) ? 1.0 : ((j % 2) ? 4.0 : 2.0);
            acc += wgt * x * plant_Lq_inc_H(&c, x);
        }
        acc *= iq / n / 3.0;
        plant_state_t tmp;
        memset(&tmp, 0, sizeof(tmp));
        tmp.iq_A = iq;
        const double W = plant_magnetic_energy_J(&tmp, &c) / 1.5;
        e_w = fmax(e_w, fabs(W - acc) / (0.5 * c.Lq_H * 225.0));
    }
    printf("model: max |dpsi/di - L_inc|/Lq = %.3e, max |W_q - int i dpsi| (rel) = %.3e\n", e_l, e_w);
    printf("model: L_inc(0) = %.6e H (Lq %.6e), L_inc(I_sat) = %.6e H (expected %.6e), L_inc(4 A) = %.4f Lq\n",
           plant_Lq_inc_H(&c, 0.0), c.Lq_H, plant_Lq_inc_H(&c, c.sat_I_A), 0.5 * (c.Lq_H + c.sat_Lq_inf_H),
           plant_Lq_inc_H(&c, 4.0) / c.Lq_H);
    CHECK(e_l < 1e-6, "L_inc vs dpsi/di");
    CHECK(e_w < 1e-9, "W_q vs quadrature");
    CHECK(fabs(plant_Lq_inc_H(&c, 0.0) - c.Lq_H) < 1e-15, "L_inc(0)");
    CHECK(fabs(plant_Lq_inc_H(&c, c.sat_I_A) - 0.5 * (c.Lq_H + c.sat_Lq_inf_H)) < 1e-15, "L_inc(Is)");

    /* 2./3. accuracy vs reference */
    double rres;
    unsigned nsub;
    c.mech_mode = PLANT_MECH_LOCKED;
    double e0 = run_vs_ref(&c, 0.08, 300, &rres, &nsub);
    printf("standstill, h_rel %.3f (%u sub-steps/period): max current error %.3e rel, energy residual %.3e of input\n",
           c.rk4_h_rel, nsub, e0, rres);
    CHECK(e0 < 1e-6, "standstill saturation error %.3e", e0);
    CHECK(rres < 1e-7, "standstill energy residual %.3e", rres);

    c.mech_mode = PLANT_MECH_IMPOSED_SPEED;
    c.omega_imposed_rad_s = 1000.0 * 2.0 * (double)T_PI / 60.0;
    double e1 = run_vs_ref(&c, 0.08, 300, &rres, &nsub);
    printf("1000 rpm,   h_rel %.3f (%u sub-steps/period): max current error %.3e rel, energy residual %.3e of input\n",
           c.rk4_h_rel, nsub, e1, rres);
    CHECK(e1 < 1e-6, "1000 rpm saturation error %.3e", e1);
    CHECK(rres < 1e-7, "1000 rpm energy residual %.3e", rres);

    plant_config_t cc = c;
    cc.rk4_h_rel = 0.2;
    double e2 = run_vs_ref(&cc, 0.08, 300, &rres, &nsub);
    printf("1000 rpm,   h_rel %.3f (%u sub-steps/period): max current error %.3e rel (coarse, reported only)\n",
           cc.rk4_h_rel, nsub, e2);
    CHECK(e2 > e1, "coarser step must be less accurate");

    /* 4. saturation matters: q-axis step to ~3 I_sat at standstill */
    {
        plant_config_t cl = c, cn;
        cl.mech_mode = PLANT_MECH_LOCKED;
        cn = cl;
        cn.sat_enable = false;
        plant_state_t a, b;
        plant_init(&a, &cl);
        plant_init(&b, &cn);
        /* theta_e = 0: q axis along beta */
        for (int k = 0; k < 10; ++k) {
            plant_step(&a, &cl, 0.0, 100.0);
            plant_step(&b, &cn, 0.0, 100.0);
        }
        const double rel = (a.iq_A - b.iq_A) / b.iq_A;
        printf("q step 100 V, 10 periods: iq saturated %.4f A vs linear %.4f A (+%.2f %%)\n", a.iq_A, b.iq_A,
               100.0 * rel);
        CHECK(rel > 0.05, "saturation should raise the current");
    }
    return check_finish("test_plant_saturation");
}
