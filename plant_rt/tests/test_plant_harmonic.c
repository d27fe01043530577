/*
 * The harmonic PMSM (plant_rt/models/harmonic/): checked against an independent calculation written here, in the
 * STATOR frame with complex numbers (the model integrates the rotor frame with RK4):
 *   - Ld = Lq = L, imposed speed: L di/dt = v - R i - d psi_pm/dt, psi_pm = psi e^(j th) + psi_5 e^(-j5 th)
 *     + psi_7 e^(j7 th), th = th0 + w t, v held over each period.  Linear with constant coefficients and
 *     exponential forcing: one period is closed form, i(T) = e^(-aT) i0 + (1 - e^(-aT)) v / R
 *     - sum_k (j k w c_k / L) e^(j k th0) (e^(j k w T) - e^(-aT)) / (a + j k w), a = R / L;
 *   - the torque, 1.5 p Re(conj(d psi_pm / d th) i) (the co-energy's derivative in the stator frame), plus the
 *     cogging torque; the energy balance of the windings;
 *   - every harmonic 0: the dq_linear model bit for bit (its exact path);
 *   - a free rotor at zero current with cogging only: the energy 1/2 J w^2 + (T_c / n) cos(n theta) kept, and
 *     the rotor pulled back towards the stable point theta = pi / n.
 */
#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "plant_test_util.h"
#include "pmsm_plant.h"

#define J1 CMPLX(0.0, 1.0) /* the imaginary unit as a double complex */
#define HARM_PSI5 0.004
#define HARM_PSI7 -0.002

static plant_config_t base_config(double w_m)
{
    plant_config_t c;
    plant_config_defaults(&c);
    c.R_ohm = 1.4;
    c.Ld_H = 4.5e-3;
    c.Lq_H = 4.5e-3;
    c.psi_Wb = 0.042;
    c.pole_pairs = 5;
    c.mech_mode = PLANT_MECH_IMPOSED_SPEED;
    c.omega_imposed_rad_s = w_m;
    c.model = (plant_model_t)OD_PLANT_MODEL_HARMONIC;
    c.params.x200A_model_harmonic.psi_5_Wb = (float)HARM_PSI5;
    c.params.x200A_model_harmonic.psi_7_Wb = (float)HARM_PSI7;
    return c;
}

/* One period of the closed form from i0 at angle th0, v held. */
static double complex closed_period(const plant_config_t *c, double complex i0, double th0, double complex v)
{
    const double L = c->Ld_H, R = c->R_ohm, w = (double)c->pole_pairs * c->omega_imposed_rad_s, T = c->Ts_s;
    const double a = R / L, ea = exp(-a * T);
    const double psi5 = (double)c->params.x200A_model_harmonic.psi_5_Wb;
    const double psi7 = (double)c->params.x200A_model_harmonic.psi_7_Wb;
    const struct {
        double k, ck;
    } terms[] = {{1.0, c->psi_Wb}, {-5.0, psi5}, {7.0, psi7}};
    double complex i = ea * i0 + (1.0 - ea) * v / R;
    for (int n = 0; n < 3; ++n) {
        const double k = terms[n].k, ck = terms[n].ck;
        const double complex f = J1 * k * w * ck / L * cexp(J1 * k * th0);
        i -= f * (cexp(J1 * k * w * T) - ea) / (a + J1 * k * w);
    }
    return i;
}

static void test_closed_form(void)
{
    plant_config_t c = base_config(150.0);
    plant_state_t s;
    plant_init(&s, &c);
    CHECK(s.status == PLANT_OK, "prepare %d", s.status);
    unsigned long long seed = 42ULL;
    double complex ref = 0.0;
    double err = 0.0, peak = 0.0, terr = 0.0, tpeak = 0.0;
    const double w = 5.0 * 150.0;
    for (int k = 0; k < 400; ++k) {
        const double va = 40.0 * (test_lcg_uniform(&seed) - 0.5), vb = 40.0 * (test_lcg_uniform(&seed) - 0.5);
        const double th0 = w * c.Ts_s * (double)k;
        ref = closed_period(&c, ref, th0, va + J1 * vb);
        plant_step(&s, &c, va, vb);
        plant_meas_t m;
        plant_sample(&s, &c, &m);
        const double complex i = m.i_alpha_A + J1 * m.i_beta_A;
        err = fmax(err, cabs(i - ref));
        peak = fmax(peak, cabs(ref));
        /* the torque: 1.5 p Re(conj(d psi_pm/d th) i), d psi_pm/d th = j psi e^(j th) - 5j psi_5 e^(-j5 th) + ... */
        const double th = w * c.Ts_s * (double)(k + 1);
        const double complex dpsi = J1 * c.psi_Wb * cexp(J1 * th) - 5.0 * J1 * HARM_PSI5 * cexp(-5.0 * J1 * th) +
                                    7.0 * J1 * HARM_PSI7 * cexp(7.0 * J1 * th);
        const double Tref = 1.5 * 5.0 * creal(conj(dpsi) * ref);
        terr = fmax(terr, fabs(m.torque_Nm - Tref));
        tpeak = fmax(tpeak, fabs(Tref));
    }
    const double resid = plant_energy_residual_J(&s, &c) / s.energy.in_J;
    printf("closed form, 150 rad/s, 400 periods of random voltage: max |i - i_ref| = %.3g A of %.3g A, torque %.3g "
           "of %.3g N m, energy residual %.3g of the input (%u sub-steps a period)\n",
           err, peak, terr, tpeak, resid, s.last_substeps);
    CHECK(err < 1e-7 * peak, "the currents differ from the closed form by %.3g A", err);
    CHECK(terr < 1e-6 * tpeak, "the torque differs from the stator-frame formula by %.3g N m", terr);
    CHECK(fabs(resid) < 1e-6, "the windings' energy balance is off by %.3g of the input", resid);
    /* the harmonics matter: the same run on the linear model is far off */
    plant_config_t lin = base_config(150.0);
    lin.model = PLANT_MODEL_DQ_LINEAR;
    plant_state_t sl;
    plant_init(&sl, &lin);
    seed = 42ULL;
    double apart = 0.0;
    ref = 0.0;
    for (int k = 0; k < 400; ++k) {
        const double va = 40.0 * (test_lcg_uniform(&seed) - 0.5), vb = 40.0 * (test_lcg_uniform(&seed) - 0.5);
        ref = closed_period(&c, ref, w * c.Ts_s * (double)k, va + J1 * vb);
        plant_step(&sl, &lin, va, vb);
        plant_meas_t m;
        plant_sample(&sl, &lin, &m);
        apart = fmax(apart, cabs(m.i_alpha_A + J1 * m.i_beta_A - ref));
    }
    CHECK(apart > 1000.0 * err && apart > 1e-3, "the linear model is only %.3g A from the harmonic closed form", apart);
}

static void test_zero_harmonics_is_the_linear_model(void)
{
    for (int mode = 0; mode < 2; ++mode) { /* exact path (imposed speed), RK4 path (free) */
        plant_config_t h = base_config(120.0), lin;
        h.Lq_H = 5.2e-3;
        h.params.x200A_model_harmonic.psi_5_Wb = 0.0f;
        h.params.x200A_model_harmonic.psi_7_Wb = 0.0f;
        h.params.x200A_model_harmonic.cogging_Nm = 0.3f; /* without periods: no cogging */
        if (mode == 1) {
            h.mech_mode = PLANT_MECH_FREE;
            h.J_kgm2 = 1e-4;
        }
        lin = h;
        lin.model = PLANT_MODEL_DQ_LINEAR;
        plant_state_t a, b;
        plant_init(&a, &h);
        plant_init(&b, &lin);
        unsigned long long seed = 7ULL;
        int same = 1;
        for (int k = 0; k < 300; ++k) {
            const double va = 30.0 * (test_lcg_uniform(&seed) - 0.5), vb = 30.0 * (test_lcg_uniform(&seed) - 0.5);
            plant_step(&a, &h, va, vb);
            plant_step(&b, &lin, va, vb);
            same &= a.id_A == b.id_A && a.iq_A == b.iq_A && a.theta_m_rad == b.theta_m_rad &&
                    a.omega_m_rad_s == b.omega_m_rad_s && plant_torque_Nm(&a, &h) == plant_torque_Nm(&b, &lin);
        }
        CHECK(same, "%s: zero harmonics differ from the dq_linear model", mode ? "free" : "imposed");
        CHECK(a.exact == (mode == 0), "the exact path is the linear model's");
    }
}

static void test_cogging_pendulum(void)
{
    plant_config_t c = base_config(0.0);
    const double Tc = 0.05, n = 12.0, J = 2e-5;
    c.psi_Wb = 0.0; /* no back-EMF: the windings carry no current at 0 V */
    c.params.x200A_model_harmonic.psi_5_Wb = 0.0f;
    c.params.x200A_model_harmonic.psi_7_Wb = 0.0f;
    c.params.x200A_model_harmonic.cogging_Nm = (float)Tc;
    c.params.x200A_model_harmonic.cogging_periods = (uint16_t)n;
    c.mech_mode = PLANT_MECH_FREE;
    c.J_kgm2 = J;
    plant_state_t s;
    plant_init(&s, &c);
    const double th0 = 3.14159265358979 / n + 0.1; /* past the stable point */
    plant_set_mech(&s, &c, th0, 0.0);
    const double Tcf = (double)(float)Tc;
    const double E0 = Tcf / n * cos(n * th0);
    double drift = 0.0, wmin = 0.0;
    for (int k = 0; k < 2000; ++k) {
        plant_step(&s, &c, 0.0, 0.0);
        const double E = 0.5 * J * s.omega_m_rad_s * s.omega_m_rad_s + Tcf / n * cos(n * s.theta_m_rad);
        drift = fmax(drift, fabs(E - E0));
        wmin = fmin(wmin, s.omega_m_rad_s);
    }
    printf("cogging pendulum: energy drift %.3g J of %.3g J, lowest speed %.3g rad/s\n", drift, fabs(E0), wmin);
    CHECK(s.status == PLANT_OK && fabs(s.id_A) < 1e-12 && fabs(s.iq_A) < 1e-12, "no current flows");
    CHECK(drift < 1e-9 * fabs(E0) + 1e-15, "the pendulum's energy drifts by %.3g J", drift);
    CHECK(wmin < -1.0, "the cogging torque did not pull the rotor back (lowest speed %.3g rad/s)", wmin);
}

static void test_pulses_off_is_refused(void)
{
    plant_config_t c = base_config(100.0);
    c.trip_reaction = PLANT_TRIP_PULSES_OFF;
    plant_state_t s;
    plant_init(&s, &c);
    CHECK(s.status == PLANT_ERR_REACTION, "pulses_off on the harmonic model: status %d", s.status);
}

int main(void)
{
    test_closed_form();
    test_zero_harmonics_is_the_linear_model();
    test_cogging_pendulum();
    test_pulses_off_is_refused();
    return check_finish("test_plant_harmonic");
}
