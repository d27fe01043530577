/* test_yao2020_ident_high.c - Yao 2020 Fig. 11 scenario: Table II motor at
 * 1.33 kHz (w T = 0.84 rad), L_hat = 1.5 L, R_hat = 1.5 R, -5 A d-axis
 * injection, Table III high-frequency gains.  Asserts that L_hat converges
 * (inside the dead-zone bound derived from the exact loop gain) and that the
 * response becomes deadbeat; reports what R_hat does.  Runs twice: with the
 * Table III dead zones and with dead zones 10x smaller.
 * Operating point (ASSUMED, not in the paper): iq = 10 A, id = 0. */
#include <math.h>
#include <stdio.h>

#include "yao2020_dpcc.h"
#include "yao2020_identification.h"
#include "yao2020_common.h"

#include "check.h"

#define IQ0 10.0
static const double T = 100e-6;

static void settle(motor_t *pl, const yao2020_dpcc_config_t *cfg, yao2020_dpcc_state_t *st, int n, double idr,
                   double iqr)
{
    yao2020_dpcc_cmd_t cmd;
    for (int k = 0; k < n; ++k) yloop_step(pl, cfg, st, idr, iqr, &cmd);
}

static void run(double th_scale)
{
    motor_t pl;
    yplant_high(&pl);
    const double R = pl.par.R_ohm, L = pl.par.Lq_H;
    yao2020_dpcc_config_t cfg;
    yao2020_dpcc_default_config(&cfg);
    cfg.R_hat_ohm = (float)(1.5 * R);
    cfg.L_hat_H = (float)(1.5 * L);
    cfg.psi_hat_Wb = (float)pl.par.psi_Wb;
    cfg.Vmax_V = (float)(pl.par.Vdc_V / sqrt(3.0));
    cfg.inj_id_A = -5.0f;
    cfg.th_L_V = (float)(0.1 * th_scale);
    cfg.th_R_V = (float)(0.03 * th_scale);
    cfg.n_timeout = 400000u;
    static yao2020_dpcc_state_t st;
    yao2020_dpcc_init(&cfg, &st);
    settle(&pl, &cfg, &st, 3000, 0.0, IQ0);
    const double ss = hypot(pl.id_A, pl.iq_A - IQ0);
    yao2020_dpcc_cmd_t cmd;
    CHECK(yao2020_identification_start(&cfg, &st), "start");
    int k;
    for (k = 0; k < 1000000 && yao2020_identification_running(&st); ++k) yloop_step(&pl, &cfg, &st, 0.0, IQ0, &cmd);
    float Rid, Lid;
    const bool done = yao2020_identification_result(&st, &Rid, &Lid);
    const double eL = (double)Lid / L - 1.0, eR = (double)Rid / R - 1.0;
    /* exact loop gains at the fixed point (closed form of dM, derived) */
    const ycx gl = ydM_exact(R, L, R, L * (1 + 1e-6), motor_omega_e(&pl), T, -5.0);
    const ycx gr = ydM_exact(R, L, R * (1 + 1e-6), L, motor_omega_e(&pl), T, -5.0);
    const double kL = gl.im / (L * 1e-6), kR = gr.re / (R * 1e-6);
    const double dL_bound = (double)cfg.th_L_V / kL * 1.2, dR_bound = (double)cfg.th_R_V / kR * 1.2;
    printf("dead zones TH_L %.3g V, TH_R %.3g V (x%.2g of Table III); steady error before ID %.2e A\n"
           "  class %d (Yao 2020 Eq. 30-31), high gains %d: kL %.2g H/(V s), kR %.2g ohm/(V s); exact loop gains"
           " %.0f V/H, %.3f V/ohm\n  predicted tau_L %.3f s (exact %.3f s), tau_R %.2f s (exact %.2f s)\n"
           "  done %d after %.2f s; L_hat = %.3f uH (error %+.2f %%, bound %.2f %%, converged %d after"
           " %.2f s integrating)\n  R_hat = %.2f mohm (error %+.2f %%, bound %.2f %%, converged %d after"
           " %.2f s)\n",
           (double)cfg.th_L_V, (double)cfg.th_R_V, th_scale, ss, st.motor_class, st.gains_high, (double)st.kL_H_Vs,
           (double)st.kR_ohm_Vs, kL, kR, (double)st.tau_L_pred_s, 1.0 / (kL * (double)st.kL_H_Vs),
           (double)st.tau_R_pred_s, 1.0 / (kR * (double)st.kR_ohm_Vs), done, k * T, (double)Lid * 1e6, 100 * eL,
           100 * dL_bound / L, st.L_converged, st.t_L_conv_periods * T, (double)Rid * 1e3, 100 * eR, 100 * dR_bound / R,
           st.R_converged, st.t_R_conv_periods * T);
    CHECK(ss < 1e-3, "observer: steady-state error");
    CHECK(done && st.L_converged, "L identification must converge");
    CHECK(fabs((double)Lid - L) <= dL_bound, "L_hat outside its dead-zone bound");
    CHECK(st.gains_high == 1u, "AUTO must pick the high-frequency gains (cos wT < 0.98)");
    /* deadbeat check after identification: first-sample error = y/y_hat - 1 */
    settle(&pl, &cfg, &st, 2000, 0.0, IQ0);
    double x, y, xh, yh;
    yxy(R, L, T, &x, &y);
    yxy((double)st.R_hat_ohm, (double)st.L_hat_H, T, &xh, &yh);
    double e2 = 0, emax = 0, cross = 0;
    for (int j = 0; j < 300; ++j) {
        if (j >= 2) {
            const double e = (pl.iq_A - 12.0) / 2.0;
            if (j == 2) e2 = e;
            emax = fmax(emax, fabs(e));
            cross = fmax(cross, fabs(pl.id_A) / 2.0);
        }
        yloop_step(&pl, &cfg, &st, 0.0, 12.0, &cmd);
    }
    printf("  after ID: iq 10->12 A: e(k0+2)/dr = %+.4f (derived y/y_hat - 1 = %+.4f), max|e|/dr"
           " from k0+2 = %.4f, cross %.4f\n",
           e2, y / yh - 1.0, emax, cross);
    CHECK(fabs(e2 - (y / yh - 1.0)) < 3e-3, "first-sample error vs y/y_hat - 1");
    CHECK(emax < fabs(y / yh - 1.0) + 0.02, "deadbeat after identification");
}

int main(void)
{
    run(1.0);
    run(0.1);
    return check_finish("test_yao2020_ident_high");
}
