/* test_yao2020_rls.c - Yao 2020 Sec. VI-B: the RLS baseline (Eq. 46-48)
 * needs psi_hat in its output vector (Eq. 47) and converges to biased R, L
 * when psi_hat = 0.8 psi or 1.2 psi; the proposed identification does not
 * use psi_hat (nor depend on the plant's psi).
 * The RLS observes the closed loop of the proposed controller (matched R, L)
 * at a fixed operating point (low-frequency motor, 133.3 Hz, iq = 4 A,
 * id = 0, ASSUMED).  Its fixed point eps = 0 of Eq. 46-47,
 *   exp(jwT) i - G2(x_hat, y_hat) j w psi_hat = x_hat i + y_hat v,
 * is solved independently here (Newton, double) and compared. */
#include <math.h>
#include <stdio.h>

#include "yao2020_dpcc.h"
#include "yao2020_identification.h"
#include "yao2020_rls.h"
#include "yao2020_common.h"

#include "check.h"

static const double T = 100e-6;

/* residual of the RLS fixed point for theta = (x_hat, y_hat) */
static void resid(double xh, double yh, double w, double psih, ycx i, ycx v, double *r)
{
    const double Rh = (1 - xh) / yh, Lh = -Rh * T / log(xh);
    const ycx G2 = ycx_div(ycx_mk(xh - cos(w * T), -sin(w * T)), ycx_mk(Rh, w * Lh));
    const ycx lhs = ycx_sub(ycx_mul(ycx_mk(cos(w * T), sin(w * T)), i), ycx_mul(G2, ycx_mk(0.0, w * psih)));
    r[0] = lhs.re - (xh * i.re + yh * v.re);
    r[1] = lhs.im - (xh * i.im + yh * v.im);
}

static void predict(double w, double psih, ycx i, ycx v, double *R, double *L)
{
    const motor_params_t mp = motor_params_preset("yao2020_low");
    double x, y;
    yxy(mp.R_ohm, mp.Lq_H, T, &x, &y);
    for (int it = 0; it < 50; ++it) {
        double r[2], rx[2], ry[2];
        const double hx = 1e-9, hy = 1e-9 * y;
        resid(x, y, w, psih, i, v, r);
        resid(x + hx, y, w, psih, i, v, rx);
        resid(x, y + hy, w, psih, i, v, ry);
        const double a = (rx[0] - r[0]) / hx, b = (ry[0] - r[0]) / hy;
        const double c = (rx[1] - r[1]) / hx, d = (ry[1] - r[1]) / hy;
        const double det = a * d - b * c;
        x -= (d * r[0] - b * r[1]) / det;
        y -= (-c * r[0] + a * r[1]) / det;
    }
    *R = (1 - x) / y;
    *L = -*R * T / log(x);
}

int main(void)
{
    const motor_params_t mp = motor_params_preset("yao2020_low");
    const double R = mp.R_ohm, L = mp.Lq_H, iq = 4.0;
    const double ratios[3] = {0.8, 1.0, 1.2};
    printf("RLS (Yao 2020 Eq. 46-48), lambda 0.995, start R_hat = 1.5 R, L_hat = 1.5 L, 1 s of data\n");
    for (int j = 0; j < 3; ++j) {
        motor_t pl;
        yplant_low(&pl);
        yao2020_dpcc_config_t cfg;
        yao2020_dpcc_default_config(&cfg);
        cfg.R_hat_ohm = (float)R;
        cfg.L_hat_H = (float)L;
        static yao2020_dpcc_state_t st;
        yao2020_dpcc_init(&cfg, &st);
        yao2020_rls_config_t rc;
        yao2020_rls_default_config(&rc);
        rc.psi_hat_Wb = (float)(ratios[j] * pl.par.psi_Wb);
        yao2020_rls_state_t rs;
        yao2020_rls_init(&rc, &rs, (float)(1.5 * R), (float)(1.5 * L));
        yao2020_dpcc_cmd_t cmd;
        /* i(k) measured before the controller step; v(k) = v_app (over [k, k+1]) */
        double vd_avg = 0, vq_avg = 0;
        for (int k = 0; k < 10000; ++k) {
            const float id_m = (float)pl.id_A, iq_m = (float)pl.iq_A;
            yloop_step(&pl, &cfg, &st, 0.0, iq, &cmd);
            if (k >= 10)
                yao2020_rls_update(&rc, &rs, id_m, iq_m, st.v_app_d_V, st.v_app_q_V, (float)motor_omega_e(&pl));
            if (k >= 9000) {
                vd_avg += (double)st.v_app_d_V / 1000.0;
                vq_avg += (double)st.v_app_q_V / 1000.0;
            }
        }
        double Rp, Lp;
        predict(motor_omega_e(&pl), ratios[j] * pl.par.psi_Wb, ycx_mk(0.0, iq), ycx_mk(vd_avg, vq_avg), &Rp, &Lp);
        const double eR = (double)rs.R_hat_ohm / R - 1, eL = (double)rs.L_hat_H / L - 1;
        printf("  psi_hat = %.1f psi: x_hat = %.6f, y_hat = %.6f A/V -> R_hat = %.4f ohm (%+7.2f %%),"
               " L_hat = %.4f mH (%+7.2f %%); derived fixed point R %.4f ohm, L %.4f mH\n",
               ratios[j], (double)rs.x_hat, (double)rs.y_hat, (double)rs.R_hat_ohm, 100 * eR, (double)rs.L_hat_H * 1e3,
               100 * eL, Rp, Lp * 1e3);
        if (Rp > 0.0) {
            CHECK(fabs((double)rs.R_hat_ohm / Rp - 1) < 0.02 && fabs((double)rs.L_hat_H / Lp - 1) < 0.02,
                  "RLS vs derived fixed point (psi_hat %.1f psi)", ratios[j]);
        } else {
            /* no physical fixed point: x_hat -> > 1, Yao 2020 Eq. 48 rejected (R_hat held) */
            printf("    (fixed point has R < 0: Yao 2020 Eq. 48 guard keeps the last physical R_hat, L_hat)\n");
            CHECK(rs.x_hat > 1.0f, "x_hat must run past 1 when the fixed point has R < 0");
        }
        if (j == 1)
            CHECK(fabs(eR) < 0.01 && fabs(eL) < 0.01, "RLS with the true psi must be unbiased");
        else
            CHECK(fabs(eR) > 0.05 || fabs(eL) > 0.05, "RLS with a wrong psi_hat must be biased");
    }

    printf("proposed identification (L_hat = 1.5 L, R_hat = 1.5 R, -2 A, Table III)\n");
    double Lref = 0, Rref = 0;
    for (int j = 0; j < 5; ++j) {
        /* j 0..2: controller psi_hat 0.8/1.0/1.2 psi; j 3..4: plant psi 0.8/1.2 */
        motor_t pl;
        yplant_low(&pl);
        const double psi_true = pl.par.psi_Wb;
        yao2020_dpcc_config_t cfg;
        yao2020_dpcc_default_config(&cfg);
        cfg.R_hat_ohm = (float)(1.5 * R);
        cfg.L_hat_H = (float)(1.5 * L);
        cfg.psi_hat_Wb = (float)((j < 3 ? ratios[j] : 1.0) * psi_true);
        if (j >= 3) pl.par.psi_Wb = ratios[j == 3 ? 0 : 2] * psi_true;
        static yao2020_dpcc_state_t st;
        yao2020_dpcc_init(&cfg, &st);
        yao2020_dpcc_cmd_t cmd;
        for (int k = 0; k < 3000; ++k) yloop_step(&pl, &cfg, &st, 0.0, iq, &cmd);
        yao2020_identification_start(&cfg, &st);
        for (int k = 0; k < 300000 && yao2020_identification_running(&st); ++k)
            yloop_step(&pl, &cfg, &st, 0.0, iq, &cmd);
        float Ri, Li;
        const bool done = yao2020_identification_result(&st, &Ri, &Li);
        printf("  %s = %.1f psi: done %d, R_hat = %.4f ohm (%+.3f %%), L_hat = %.4f mH (%+.3f %%)\n",
               j < 3 ? "controller psi_hat" : "plant psi        ", j < 3 ? ratios[j] : ratios[j == 3 ? 0 : 2], done,
               (double)Ri, 100 * ((double)Ri / R - 1), (double)Li * 1e3, 100 * ((double)Li / L - 1));
        CHECK(done, "identification must finish");
        if (j == 1) {
            Lref = (double)Li;
            Rref = (double)Ri;
        }
        CHECK(fabs((double)Li / L - 1) < 0.015 && fabs((double)Ri / R - 1) < 0.01,
              "proposed method must not depend on psi (case %d)", j);
        if (j == 2)
            CHECK(fabs((double)Li - Lref) < 1e-4 * L && fabs((double)Ri - Rref) < 1e-4 * R,
                  "psi_hat must not change the result");
    }
    return check_finish("test_yao2020_rls");
}
