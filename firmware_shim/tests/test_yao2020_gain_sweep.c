/* test_yao2020_gain_sweep.c - Yao 2020: convergence time of the L and R integral
 * estimators vs their gains k_L, k_R (Yao 2020 Eq. 44-45, Fig. 14/15).
 * With the plant gain k (dM per unit parameter error, exact closed form at
 * the fixed point) the estimator is dp/dt = -k_{L,R} k (p - p_true), so the
 * time from the initial error e0 to the dead-zone edge e_dz = TH / k is
 *   t = ln(e0 / e_dz) / (k_{L,R} k)                 (derived from Eq. 44).
 * Asserts: faster gains converge faster, and each time is within 25 % of the
 * prediction.  Low-frequency motor @133.3 Hz (-2 A) for L and R; high-
 * frequency motor @1.33 kHz (-5 A) for L (dead zones 0.1 x Table III). */
#include <math.h>
#include <stdio.h>

#include "yao2020_dpcc.h"
#include "yao2020_identification.h"
#include "yao2020_common.h"

#include "check.h"

static const double T = 100e-6;

typedef struct {
    double tL, tR, eL, eR;
    int ok;
} res_t;

static res_t run(int high, double kL, double kR)
{
    motor_t pl;
    if (high)
        yplant_high(&pl);
    else
        yplant_low(&pl);
    yao2020_dpcc_config_t cfg;
    yao2020_dpcc_default_config(&cfg);
    cfg.R_hat_ohm = (float)(1.5 * pl.par.R_ohm);
    cfg.L_hat_H = (float)(1.5 * pl.par.Lq_H);
    cfg.psi_hat_Wb = (float)pl.par.psi_Wb;
    const double iq = high ? 10.0 : 4.0;
    if (high) {
        cfg.inj_id_A = -5.0f;
        cfg.kL_high_H_Vs = (float)kL;
        cfg.kR_high_ohm_Vs = (float)kR;
        cfg.th_L_V = 0.01f;
        cfg.th_R_V = 0.003f;
    } else {
        cfg.kL_low_H_Vs = (float)kL;
        cfg.kR_low_ohm_Vs = (float)kR;
    }
    static yao2020_dpcc_state_t st;
    yao2020_dpcc_init(&cfg, &st);
    yao2020_dpcc_cmd_t cmd;
    for (int k = 0; k < 3000; ++k) yloop_step(&pl, &cfg, &st, 0.0, iq, &cmd);
    yao2020_identification_start(&cfg, &st);
    for (int k = 0; k < 2000000 && yao2020_identification_running(&st); ++k) yloop_step(&pl, &cfg, &st, 0.0, iq, &cmd);
    res_t r;
    r.tL = st.t_L_conv_periods * T;
    r.tR = st.t_R_conv_periods * T;
    r.eL = (double)st.L_id_H / pl.par.Lq_H - 1.0;
    r.eR = (double)st.R_id_ohm / pl.par.R_ohm - 1.0;
    r.ok = st.id_state == YAO2020_IDENTIFICATION_DONE && st.L_converged && st.R_converged;
    return r;
}

static void sweep(int high, const double *kLs, const double *kRs, int n, int do_R)
{
    motor_t pl;
    if (high)
        yplant_high(&pl);
    else
        yplant_low(&pl);
    const double did = high ? -5.0 : -2.0;
    const double thL = high ? 0.01 : 0.1, thR = high ? 0.003 : 0.03;
    const double R = pl.par.R_ohm, L = pl.par.Lq_H, w = motor_omega_e(&pl);
    const ycx gl = ydM_exact(R, L, R, L * (1 + 1e-6), w, T, did);
    const ycx gr = ydM_exact(R, L, R * (1 + 1e-6), L, w, T, did);
    const double kpl = gl.im / (L * 1e-6), kpr = gr.re / (R * 1e-6);
    double prevL = 1e9, prevR = 1e9;
    for (int i = 0; i < n; ++i) {
        const res_t r = run(high, kLs[i], kRs[i]);
        const double tLp = log(0.5 * L / (thL / kpl)) / (kLs[i] * kpl);
        const double tRp = log(0.5 * R / (thR / kpr)) / (kRs[i] * kpr);
        printf("  %-4s kL %-8.3g t_L = %7.1f ms (pred %7.1f, tau %6.1f ms), L err %+6.2f %% | "
               "kR %-6.3g t_R = %7.1f ms (pred %7.1f, tau %6.1f ms), R err %+6.2f %%\n",
               high ? "high" : "low", kLs[i], r.tL * 1e3, tLp * 1e3, 1e3 / (kLs[i] * kpl), 100 * r.eL, kRs[i],
               r.tR * 1e3, tRp * 1e3, 1e3 / (kRs[i] * kpr), 100 * r.eR);
        CHECK(r.ok, "identification did not finish/converge (kL %g kR %g)", kLs[i], kRs[i]);
        CHECK(r.tL < prevL, "t_L must decrease with kL");
        CHECK(fabs(r.tL / tLp - 1.0) < 0.25, "t_L vs prediction (kL %g)", kLs[i]);
        if (do_R) {
            CHECK(r.tR < prevR, "t_R must decrease with kR");
            CHECK(fabs(r.tR / tRp - 1.0) < 0.25, "t_R vs prediction (kR %g)", kRs[i]);
        }
        prevL = r.tL;
        prevR = r.tR;
    }
}

int main(void)
{
    printf("convergence time (integrating periods until inside the dead zone for good)\n");
    const double kL_low[] = {0.0025, 0.005, 0.01, 0.02, 0.05};
    const double kR_low[] = {2.0, 4.0, 8.0, 16.0, 40.0};
    sweep(0, kL_low, kR_low, 5, 1);
    const double kL_high[] = {1e-5, 2e-5, 4e-5, 1e-4};
    const double kR_high[] = {0.4, 0.4, 0.4, 0.4};
    sweep(1, kL_high, kR_high, 4, 0);
    return check_finish("test_yao2020_gain_sweep");
}
