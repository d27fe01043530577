/* test_you2019_identification.c - You 2019 Sec. 6 online tuning against the
 * exact discrete standstill plant, starting from L_hat = 0.5 L and 1.2 L. */
#include <math.h>
#include <stdio.h>

#include "check.h"
#include "drive_core.h"
#include "drive_plant.h"

static void run_case(double lf, int d_axis)
{
    static drive_t drv;
    drive_config_t cfg;
    drive_plant_t pl;
    drive_plant_init(&pl, "you2019");
    const double Ts = pl.zoh.par.Ts_s, R = pl.zoh.par.R_ohm;
    const double L = d_axis ? pl.zoh.par.Ld_H : pl.zoh.par.Lq_H;
    const double A = exp(-Ts * R / L), B = (1 - A) / R, K1 = 1 / B, K2 = A / B;
    drive_default_config(&cfg);
    cfg.Lq_hat_H = (float)(lf * 4.54e-3);
    cfg.Ld_hat_H = (float)(lf * 4.46e-3);
    drive_init(&drv, &cfg);
    od_drive_online_tuning_t *tuning = (od_drive_online_tuning_t *)drive_law_record(&drv);
    tuning->enable = 1u;
    tuning->separate_d_axis = (uint8_t)d_axis;
    drive_apply_config(&drv);
    const int k0 = 13, k1 = 400;
    int n_acc = 0, first_acc = -1, upd_step = -1, est_pi_step = -1;
    double max_e1 = 0, max_e2 = 0, min_absdet_acc = 1e9;
    float kp_before = 0;
    double i_hist[600];
    const you2019_identification_axis_state_t *ax = d_axis ? &YOU2019_OF(drv)->ident.d : &YOU2019_OF(drv)->ident.q;
    for (int k = 0; k < 600; ++k) {
        drive_meas_t m;
        drive_cmd_t c;
        drive_plant_measure(&pl, &m);
        const float ref = k >= k1 ? 2.0f : (k >= k0 ? 1.0f : 0.0f);
        if (d_axis)
            drv.sp.id_ref_A = ref;
        else
            drv.sp.iq_ref_A = ref;
        const uint32_t nupd = YOU2019_OF(drv)->n_gain_updates;
        kp_before = d_axis ? YOU2019_OF(drv)->est.kp_d : YOU2019_OF(drv)->est.kp_q;
        drive_current_step(&drv, &m, &c);
        i_hist[k] = (double)(d_axis ? drv.st.i_d_A : drv.st.i_q_A);
        if (ax->accepted) {
            const double e1 = fabs((double)ax->K1_hat_V_A - K1) / K1, e2 = fabs((double)ax->K2_hat_V_A - K2) / K2;
            if (e1 > max_e1) max_e1 = e1;
            if (e2 > max_e2) max_e2 = e2;
            if (fabs((double)ax->det_A2) < min_absdet_acc) min_absdet_acc = fabs((double)ax->det_A2);
            if (first_acc < 0) first_acc = k;
            n_acc++;
        }
        if (upd_step < 0 && YOU2019_OF(drv)->n_gain_updates != nupd) upd_step = k;
        if (upd_step >= 0 && est_pi_step < 0 &&
            (d_axis ? YOU2019_OF(drv)->est.kp_d : YOU2019_OF(drv)->est.kp_q) != kp_before)
            est_pi_step = k;
        drive_plant_advance(&pl, &c);
    }
    const float K1a = d_axis ? YOU2019_OF(drv)->db.K1d_V_A : YOU2019_OF(drv)->db.K1q_V_A;
    const float K2a = d_axis ? YOU2019_OF(drv)->db.K2d_V_A : YOU2019_OF(drv)->db.K2q_V_A;
    printf("[%s L_hat=%.1fL] accepted ids=%d (min |det| %.3f A^2), max err K1_hat=%.2e K2_hat=%.2e;"
           " first accepted k=%d, gains loaded k=%d (%d periods after), est PI k=%d\n",
           d_axis ? "d-axis" : "q-axis", lf, n_acc, min_absdet_acc, max_e1, max_e2, first_acc, upd_step,
           upd_step - first_acc, est_pi_step);
    printf("  K1_bar=%.4f (true %.4f) K2_bar=%.4f (true %.4f) A_hat=%.7f (true %.7f) L_hat=%.4f mH"
           " (true %.4f) active K1=%.4f K2=%.4f; q->d copy K1d=%.4f\n",
           (double)ax->K1_bar_V_A, K1, (double)ax->K2_bar_V_A, K2, (double)ax->A_hat, A, 1e3 * (double)ax->L_hat_H,
           1e3 * L, (double)K1a, (double)K2a, (double)YOU2019_OF(drv)->db.K1d_V_A);
    printf("  i after first step:");
    for (int k = k0; k < k0 + 14; ++k) printf(" %.3f", i_hist[k]);
    printf("\n  i after second step:");
    for (int k = k1; k < k1 + 6; ++k) printf(" %.4f", i_hist[k]);
    printf("\n");
    double maxdev2 = 0;
    for (int k = k1 + 2; k < 600; ++k)
        if (fabs(i_hist[k] - 2.0) > maxdev2) maxdev2 = fabs(i_hist[k] - 2.0);
    printf("  second step: i(k1+1)=%.4f i(k1+2)=%.5f max|i-2| after k1+2 = %.2e\n", i_hist[k1 + 1], i_hist[k1 + 2],
           maxdev2);
    CHECK(n_acc >= 2, "too few identifications");
    CHECK(max_e1 < 0.01 && max_e2 < 0.01, "identified gains not within 1%%");
    CHECK(upd_step > 0 && upd_step - first_acc <= 9, "update later than one speed period");
    CHECK(est_pi_step == upd_step + 2, "estimator PI not 2 periods after model update");
    CHECK(fabs((double)K1a - K1) / K1 < 0.01 && fabs((double)K2a - K2) / K2 < 0.01, "active gains");
    CHECK(fabs((double)ax->L_hat_H - L) / L < 0.01, "L_hat (You 2019 Eq. 32)");
    CHECK(fabs(i_hist[k1 + 1] - 1.0) < 0.01 && maxdev2 < 0.01 * 2.0, "not back to the 2-period deadbeat response");
    if (!d_axis) CHECK(fabs((double)YOU2019_OF(drv)->db.K1d_V_A - K1) / K1 < 0.01, "q->d copy");
}

int main(void)
{
    /* pure You 2019 Eq. 24 solve check with a hand example: A=0.9, B=0.01 */
    float K1, K2;
    const float det = you2019_identification_solve(0.9f * 0.5f + 0.01f * 30.0f, 0.5f, 0.0f, 30.0f, 50.0f, &K1, &K2);
    printf("[You 2019 Eq.24 unit] det=%.4f K1=%.3f (100) K2=%.3f (90)\n", (double)det, (double)K1, (double)K2);
    CHECK(fabsf(K1 - 100.0f) < 1e-3f && fabsf(K2 - 90.0f) < 1e-3f, "You 2019 Eq. 24 solve");
    run_case(0.5, 0);
    run_case(1.2, 0);
    run_case(0.5, 1);
    run_case(1.2, 1);
    return check_finish("test_you2019_identification");
}
