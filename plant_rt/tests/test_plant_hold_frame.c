/*
 * Stator-frame hold (real inverter) vs rotor-frame hold (dq command constant
 * over the period, the usual textbook discretization) on the You 2019 motor
 * at 1000 rpm.
 *
 * Averaged-model prediction: over one period the stator-held vector, seen in
 * the rotor frame, is v(t) = Rot(-w t) v0, whose mean is M v0 with
 *   M = [[ sin(phi)/phi, (1-cos(phi))/phi], [-(1-cos(phi))/phi, sin(phi)/phi]],
 *   phi = w Ts  (a rotation by -phi/2 scaled by sinc(phi/2)).
 *  A. one period from zero current, same command: |di|/|i| ~ |(M - I) v0|/|v0|
 *  B. steady state with a constant dq command converted to alpha-beta with the
 *     angle at the period start: di_ss ~ Z^-1 (M - I) V, Z = [[R, -w Lq],
 *     [w Ld, R]].
 * The measured values must fall in [0.8, 1.25] x (A) and [0.5, 2] x (B).
 */
#include "check.h"
#include "plant_test_util.h"
#include "presets.h"

int main(void)
{
    plant_config_t cs;
    CHECK(plant_preset_load("you2019", &cs) == 0, "preset");
    plant_config_ideal(&cs);
    cs.mech_mode = PLANT_MECH_IMPOSED_SPEED;
    cs.omega_imposed_rad_s = 1000.0 * 2.0 * (double)T_PI / 60.0;
    plant_config_t cr = cs;
    cr.hold_frame = PLANT_HOLD_ROTOR;

    const double p = cs.pole_pairs;
    const double w = p * cs.omega_imposed_rad_s;
    const double phi = w * cs.Ts_s;
    const double m11 = sin(phi) / phi, m12 = (1.0 - cos(phi)) / phi;
    printf("w = %.3f rad/s electrical, w*Ts = %.5f rad\n", w, phi);

    /* ---- A: one period from rest ---- */
    {
        plant_state_t ss, sr;
        plant_init(&ss, &cs);
        plant_init(&sr, &cr);
        CHECK(ss.status == 0 && sr.status == 0, "prepare");
        plant_set_mech(&ss, &cs, 0.1, 0.0);
        plant_set_mech(&sr, &cr, 0.1, 0.0);
        const double va = 30.0, vb = -10.0;
        plant_step(&ss, &cs, va, vb);
        plant_step(&sr, &cr, va, vb);
        const double di = hypot(ss.id_A - sr.id_A, ss.iq_A - sr.iq_A);
        const double rel = di / hypot(sr.id_A, sr.iq_A);
        /* voltage difference in dq (back-EMF forcing is identical in both) */
        const double th = p * 0.1, c0 = cos(th), s0 = sin(th);
        const double vd0 = va * c0 + vb * s0, vq0 = -va * s0 + vb * c0;
        const double dvd = (m11 - 1.0) * vd0 + m12 * vq0;
        const double dvq = -m12 * vd0 + (m11 - 1.0) * vq0;
        const double pred = hypot(cs.Ts_s * dvd / cs.Ld_H, cs.Ts_s * dvq / cs.Lq_H);
        printf("A. one period from rest (v = [%g, %g] V): |i_stator - i_rotor| = %.4e A (predicted %.4e A), %.3f %% of "
               "|i| = %.4f A\n",
               va, vb, di, pred, 100.0 * rel, hypot(sr.id_A, sr.iq_A));
        CHECK(di > 0.8 * pred && di < 1.25 * pred, "one-period difference %.4e vs %.4e", di, pred);
    }

    /* ---- B: steady state with a constant dq command ---- */
    {
        const double R = cs.R_ohm, Ld = cs.Ld_H, Lq = cs.Lq_H, psi = cs.psi_Wb;
        const double idr = 0.0, iqr = 1.0; /* design point of the dq command */
        const double Vd = R * idr - w * Lq * iqr;
        const double Vq = R * iqr + w * Ld * idr + w * psi;
        plant_state_t ss, sr;
        plant_init(&ss, &cs);
        plant_init(&sr, &cr);
        const int N = 4000; /* 4000 * 55 us = 69 tau */
        for (int k = 0; k < N; ++k) {
            plant_state_t *st[2] = {&ss, &sr};
            const plant_config_t *cf[2] = {&cs, &cr};
            for (int j = 0; j < 2; ++j) {
                plant_meas_t m;
                plant_sample(st[j], cf[j], &m);
                const double c = cos(m.theta_e_rad), sn = sin(m.theta_e_rad);
                plant_step(st[j], cf[j], c * Vd - sn * Vq, sn * Vd + c * Vq);
            }
        }
        printf("B. rotor-hold steady state: id %.9f A, iq %.9f A (design 0, 1)\n", sr.id_A, sr.iq_A);
        CHECK(fabs(sr.id_A - idr) < 1e-9 && fabs(sr.iq_A - iqr) < 1e-9, "rotor hold steady state");
        const double ddq_d = ss.id_A - sr.id_A, ddq_q = ss.iq_A - sr.iq_A;
        const double meas = hypot(ddq_d, ddq_q);
        /* prediction: dV = (M - I) V ; dI = Z^-1 dV */
        const double dVd = (m11 - 1.0) * Vd + m12 * Vq;
        const double dVq = -m12 * Vd + (m11 - 1.0) * Vq;
        const double a = R, b = -w * Lq, cc = w * Ld, d = R, det = a * d - b * cc;
        const double dId = (d * dVd - b * dVq) / det, dIq = (-cc * dVd + a * dVq) / det;
        const double pred = hypot(dId, dIq);
        printf("B. stator-hold steady state: id %.6f A, iq %.6f A; |difference| = %.4f A = %.2f %% of 1 A (predicted "
               "%.4f A)\n",
               ss.id_A, ss.iq_A, meas, 100.0 * meas / hypot(idr, iqr), pred);
        printf("   relative to rated 4 A: %.2f %%\n", 100.0 * meas / 4.0);
        CHECK(meas > 0.5 * pred && meas < 2.0 * pred, "steady-state difference %.4e vs %.4e", meas, pred);
    }
    return check_finish("test_plant_hold_frame");
}
