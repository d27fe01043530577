/* test_you2019_estimator.c - You 2019 Eq. 5-9 estimator and dead-time
 * compensation shape. */
#include <math.h>
#include <stdio.h>

#include "check.h"
#include "drive_core.h"
#include "drive_plant.h"

int main(void)
{
    const float Ts = 55e-6f;
    const double g900 = (double)you2019_estimator_loop_gain(Ts, 900.0f);
    const double gcrit = (double)you2019_estimator_loop_gain(Ts, 5000.0f);
    const double disc = sqrt(1 - 4 * g900);
    printf("[estimator design] g(900 Hz)=%.4f poles %.4f, %.4f (real, zeta>1); g clamp=%.4f"
           " (critical, double pole 0.5); ki = g R_hat/Ts = %.1f 1/s, kp = ki A Ts/(1-A) (You 2019 Eq. 8) = %.3f\n",
           g900, (1 + disc) / 2, (1 - disc) / 2, gcrit, g900 * 1.4 / 55e-6,
           g900 * 1.4 / 55e-6 * 0.98318 * 55e-6 / (1 - 0.98318));
    CHECK(fabs(g900 - 0.2003) < 1e-3, "g(900 Hz)");
    CHECK(fabs(gcrit - 0.25) < 1e-6, "critical clamp");
    /* -3 dB check of g/(z^2 - z + g) at 900 Hz */
    const double th = 2 * 3.14159265358979 * 900 * 55e-6;
    const double re = cos(2 * th) - cos(th) + g900, im = sin(2 * th) - sin(th);
    const double mag = g900 / sqrt(re * re + im * im);
    printf("[estimator design] |T(900 Hz)|=%.4f (1/sqrt2=0.7071)\n", mag);
    CHECK(fabs(mag - 0.70711) < 2e-3, "-3 dB point");

    /* closed loop: matched prediction i_hat(k) = i(k+2); mismatched converges */
    for (int c = 0; c < 2; ++c) {
        static drive_t drv;
        drive_config_t cfg;
        drive_plant_t pl;
        drive_plant_init(&pl, "you2019");
        drive_default_config(&cfg);
        if (c == 1) {
            cfg.Lq_hat_H *= 0.7f;
            cfg.R_hat_ohm *= 1.3f;
        }
        drive_init(&drv, &cfg);
        static double ih[800], ii[800];
        for (int k = 0; k < 800; ++k) {
            drive_meas_t m;
            drive_cmd_t cmd;
            drive_plant_measure(&pl, &m);
            drv.sp.iq_ref_A = (k / 200) % 2 ? 1.5f : -0.5f;
            drive_current_step(&drv, &m, &cmd);
            ih[k] = (double)YOU2019_OF(drv)->est.i_hat_q_A;
            ii[k] = (double)drv.st.i_q_A;
            drive_plant_advance(&pl, &cmd);
        }
        double maxe = 0, tail = 0;
        for (int k = 5; k < 798; ++k)
            if (fabs(ih[k] - ii[k + 2]) > maxe) maxe = fabs(ih[k] - ii[k + 2]);
        for (int k = 560; k < 598; ++k)
            if (fabs(ih[k] - ii[k + 2]) > tail) tail = fabs(ih[k] - ii[k + 2]);
        printf("[estimator %s] max|i_hat(k)-i(k+2)|=%.3g A, late in a plateau=%.3g A\n",
               c ? "L_hat=0.7L,R_hat=1.3R" : "matched", maxe, tail);
        if (c == 0)
            CHECK(maxe < 1e-4, "matched prediction");
        else
            CHECK(tail < 2e-3, "estimator integral should remove the error");
    }
    /* dead-time shape (Fig. 3): linear up to I_sat, saturated above */
    const float v1 = you2019_estimator_deadtime_shape(4.0f, 1.0f, 0.5f);
    const float v2 = you2019_estimator_deadtime_shape(4.0f, 1.0f, -3.0f);
    printf("[dead-time] V(0.5A)=%.2f V V(-3A)=%.2f V (V_dt=4, I_sat=1)\n", (double)v1, (double)v2);
    CHECK(fabsf(v1 - 2.0f) < 1e-6f && fabsf(v2 + 4.0f) < 1e-6f, "shape");
    /* compensation vector for a positive a-phase current at theta = 0 */
    you2019_estimator_state_t es;
    you2019_estimator_reset(&es);
    es.i_hat_d_A = 3.0f;
    es.i_hat_q_A = 0.0f;
    you2019_estimator_deadtime(4.0f, 1.0f, &es, 1.0f, 0.0f); /* V_dt = 4 V, I_sat = 1 A */
    printf("[dead-time] id_hat=3A at theta=0: ia=%.2f ib=%.2f ic=%.2f -> v_alpha=%.3f v_beta=%.3f"
           " (expect 4*4/3=5.333, 0)\n",
           (double)es.i_hat_a_A, (double)es.i_hat_b_A, (double)es.i_hat_c_A, (double)es.v_dt_alpha_V,
           (double)es.v_dt_beta_V);
    CHECK(fabsf(es.v_dt_alpha_V - 16.0f / 3.0f) < 1e-4f && fabsf(es.v_dt_beta_V) < 1e-5f, "dt vector");
    return check_finish("test_you2019_estimator");
}
