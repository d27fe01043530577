/* test_yao2020_ident_low.c - Yao 2020 Sec. V / Fig. 10 scenario on the
 * Table I motor at 133.3 Hz, controller started with L_hat = 1.5 L,
 * R_hat = 1.5 R:
 *   1. steady-state iq error without / with the sliding-mode observer;
 *   2. an iq step before identification: first-sample error equals the
 *      derived (y/y_hat - 1) dr (Eq. 20 with p_hat(k0) = p(k0));
 *   3. the injection sequence (-2 A, L first then R, Table III gains and dead
 *      zones) drives L_hat, R_hat to the plant values; the first dM seen by
 *      the firmware equals the derived closed form;
 *   4. iq and id steps after identification are deadbeat;
 *   5. the literal "stale M(t0)" reading, for comparison (reported).
 * Operating point (ASSUMED, not in the paper): iq = 4 A, id = 0. */
#include <math.h>
#include <stdio.h>

#include "yao2020_dpcc.h"
#include "yao2020_identification.h"
#include "yao2020_common.h"

#include "check.h"

#define IQ0 4.0
/* step sizes small enough that Vmax = 300/sqrt(3) V is never reached (the
 * deadbeat step needs dv = dr / y_hat ~ 55 V/A with L_hat = 1.5 L) */
#define IQ1 4.5
#define ID1 (-1.0)
static const double T = 100e-6;

static void settle(motor_t *pl, const yao2020_dpcc_config_t *cfg, yao2020_dpcc_state_t *st, int n, double idr,
                   double iqr)
{
    yao2020_dpcc_cmd_t cmd;
    for (int k = 0; k < n; ++k) yloop_step(pl, cfg, st, idr, iqr, &cmd);
}

/* Step response: returns e(k0+2)/dr, and the max |e|/dr over k0+2..k0+n of
 * the stepped axis and of the other axis; settle periods to 2 %. */
typedef struct {
    double e2, emax, cross, over;
    int settle2, nlim;
} step_t;
static step_t step_test(motor_t *pl, const yao2020_dpcc_config_t *cfg, yao2020_dpcc_state_t *st, int axis_q,
                        double from, double to, int n)
{
    step_t r = {0, 0, 0, 0, 0, 0};
    yao2020_dpcc_cmd_t cmd;
    const double dr = to - from;
    int last_out = 1; /* settle2 = first k >= 2 after which |e| <= 2 % */
    for (int k = 0; k <= n; ++k) {
        const double i_ax = axis_q ? pl->iq_A : pl->id_A;
        const double i_ot = axis_q ? pl->id_A : pl->iq_A;
        const double ot_ref = axis_q ? 0.0 : IQ0;
        if (k >= 2) {
            const double e = (i_ax - to) / dr;
            if (k == 2) r.e2 = e;
            r.emax = fmax(r.emax, fabs(e));
            r.over = fmax(r.over, e);
            r.cross = fmax(r.cross, fabs(i_ot - ot_ref) / fabs(dr));
            if (fabs(e) > 0.02) last_out = k;
        }
        const double ref = to;
        if (axis_q)
            yloop_step(pl, cfg, st, 0.0, ref, &cmd);
        else
            yloop_step(pl, cfg, st, ref, IQ0, &cmd);
        r.nlim += cmd.limited;
    }
    r.settle2 = last_out + 1;
    return r;
}

typedef struct {
    float L, R;
    int state, Lconv, Rconv;
    unsigned tL, tR;
    double t_done_s;
    double dM_first_d, dM_first_q;
    double max_id_dev_l, tauL, tauR;
} ident_t;

static ident_t identify(motor_t *pl, const yao2020_dpcc_config_t *cfg, yao2020_dpcc_state_t *st, int max_steps)
{
    ident_t r = {0};
    yao2020_dpcc_cmd_t cmd;
    CHECK(yao2020_identification_start(cfg, st), "ident_start refused");
    int k, got_first = 0;
    for (k = 0; k < max_steps && yao2020_identification_running(st); ++k) {
        yloop_step(pl, cfg, st, 0.0, IQ0, &cmd);
        if (!got_first && st->id_state == YAO2020_IDENTIFICATION_INJECT_L && st->phase_count == cfg->n_settle + 1u) {
            r.dM_first_d = st->dM_d_V;
            r.dM_first_q = st->dM_q_V;
            got_first = 1;
        }
    }
    r.t_done_s = k * T;
    r.state = st->id_state;
    yao2020_identification_result(st, &r.R, &r.L);
    r.Lconv = st->L_converged;
    r.Rconv = st->R_converged;
    r.tL = st->t_L_conv_periods;
    r.tR = st->t_R_conv_periods;
    r.tauL = st->tau_L_pred_s;
    r.tauR = st->tau_R_pred_s;
    return r;
}

int main(void)
{
    motor_t pl;
    yao2020_dpcc_config_t cfg;
    static yao2020_dpcc_state_t st;
    const motor_params_t mp = motor_params_preset("yao2020_low");
    const double R = mp.R_ohm, L = mp.Lq_H;

    /* ---- 1. steady-state error, observer off vs on */
    printf("1. steady-state error with R_hat = 1.5 R, L_hat = 1.5 L, iq* = %.0f A @ 133.3 Hz\n", IQ0);
    double ss[2];
    for (int obs = 0; obs < 2; ++obs) {
        yplant_low(&pl);
        yao2020_dpcc_default_config(&cfg);
        cfg.R_hat_ohm = (float)(1.5 * R);
        cfg.L_hat_H = (float)(1.5 * L);
        cfg.psi_hat_Wb = (float)pl.par.psi_Wb;
        cfg.Vmax_V = (float)(mp.Vdc_V / sqrt(3.0));
        cfg.observer_enable = (uint8_t)obs;
        yao2020_dpcc_init(&cfg, &st);
        settle(&pl, &cfg, &st, 3000, 0.0, IQ0);
        ss[obs] = hypot(pl.id_A, pl.iq_A - IQ0);
        printf("   observer %s: |i - i*| = %.4e A (id = %+.4f, iq = %.4f)\n", obs ? "on " : "off", ss[obs], pl.id_A,
               pl.iq_A);
    }
    CHECK(ss[0] > 0.05, "without observer a steady-state error is expected");
    CHECK(ss[1] < 1e-3, "observer must remove the steady-state error");

    /* ---- 2. step before identification */
    const double Rh = 1.5 * R, Lh = 1.5 * L;
    double x, y, xh, yh;
    yxy(R, L, T, &x, &y);
    yxy(Rh, Lh, T, &xh, &yh);
    const double pred_before = y / yh - 1.0;
    step_t sb = step_test(&pl, &cfg, &st, 1, IQ0, IQ1, 300);
    settle(&pl, &cfg, &st, 1000, 0.0, IQ0);
    printf("2. iq 4->4.5 A before identification: e(k0+2)/dr = %+.4f (derived y/y_hat - 1 ="
           " %+.4f), max overshoot %.3f, cross %.3f, settles (2 %%) in %d periods, limited %d\n",
           sb.e2, pred_before, sb.over, sb.cross, sb.settle2, sb.nlim);
    CHECK(fabs(sb.e2 - pred_before) < 2e-3, "first-sample error must match y/y_hat - 1");

    /* ---- 3. identification */
    ident_t id = identify(&pl, &cfg, &st, 200000);
    const double eL = (double)id.L / L - 1.0, eR = (double)id.R / R - 1.0;
    const ycx dM_pred = ydM_exact(R, L, Rh, Lh, motor_omega_e(&pl), T, (double)cfg.inj_id_A);
    printf("3. identification (inj %.1f A, kL %.3g, kR %.3g, TH_L %.2g V, TH_R %.2g V):\n"
           "   first dM (firmware) = (%+.4f, %+.4f) V, derived closed form (%+.4f, %+.4f) V\n"
           "   state %d, L_hat = %.4f mH (error %+.3f %%, converged %d after %.1f ms integrating,"
           " predicted tau %.1f ms)\n   R_hat = %.4f ohm (error %+.3f %%, converged %d after %.1f ms,"
           " predicted tau %.1f ms); whole sequence %.3f s\n",
           (double)cfg.inj_id_A, (double)cfg.kL_low_H_Vs, (double)cfg.kR_low_ohm_Vs, (double)cfg.th_L_V,
           (double)cfg.th_R_V, id.dM_first_d, id.dM_first_q, dM_pred.re, dM_pred.im, id.state, (double)id.L * 1e3,
           100 * eL, id.Lconv, id.tL * T * 1e3, id.tauL * 1e3, (double)id.R, 100 * eR, id.Rconv, id.tR * T * 1e3,
           id.tauR * 1e3, id.t_done_s);
    CHECK(fabs(id.dM_first_d - dM_pred.re) < 0.01 * fabs(dM_pred.re) + 2e-3 &&
              fabs(id.dM_first_q - dM_pred.im) < 0.01 * fabs(dM_pred.im) + 2e-3,
          "firmware dM vs closed form");
    CHECK(id.state == YAO2020_IDENTIFICATION_DONE && id.Lconv && id.Rconv, "identification must finish");
    /* dead zones: |dM_q| <= TH_L ~ w |did| |dL| , |dM_d| <= TH_R ~ |did| |dR|
     * (Yao 2020 Eq. 35/36), plus margin for the per-step increment */
    const double dL_bound = (double)cfg.th_L_V / (motor_omega_e(&pl) * 2.0) * 1.2;
    const double dR_bound = (double)cfg.th_R_V / 2.0 * 1.2 + 2e-3;
    printf("   dead-zone bounds (Yao 2020 Eq. 35/36): |dL| <= %.4f mH (%.2f %%), |dR| <= %.4f ohm (%.2f %%)\n",
           dL_bound * 1e3, 100 * dL_bound / L, dR_bound, 100 * dR_bound / R);
    CHECK(fabs((double)id.L - L) <= dL_bound, "L_hat outside the dead-zone bound");
    CHECK(fabs((double)id.R - R) <= dR_bound, "R_hat outside the dead-zone bound");

    /* ---- 4. deadbeat after identification */
    settle(&pl, &cfg, &st, 1000, 0.0, IQ0);
    yxy((double)st.R_hat_ohm, (double)st.L_hat_H, T, &xh, &yh);
    const double pred_after = y / yh - 1.0;
    step_t sq = step_test(&pl, &cfg, &st, 1, IQ0, IQ1, 300);
    settle(&pl, &cfg, &st, 1000, 0.0, IQ0);
    step_t sd = step_test(&pl, &cfg, &st, 0, 0.0, ID1, 300);
    printf("4. after identification: iq 4->4.5 A: e(k0+2)/dr = %+.4f (derived %+.4f), max|e|/dr"
           " from k0+2 = %.4f, cross %.4f, settles (2 %%) in %d periods, limited %d\n"
           "   id 0->-1 A: e(k0+2)/dr = %+.4f, max|e|/dr = %.4f, cross %.4f, settles in %d periods,"
           " limited %d\n",
           sq.e2, pred_after, sq.emax, sq.cross, sq.settle2, sq.nlim, sd.e2, sd.emax, sd.cross, sd.settle2, sd.nlim);
    CHECK(sb.nlim == 0 && sq.nlim == 0 && sd.nlim == 0, "voltage limit reached in a step test");
    CHECK(fabs(sq.e2 - pred_after) < 2e-3, "first-sample error after ID must match y/y_hat - 1");
    CHECK(sq.settle2 <= 2 && sd.settle2 <= 2, "deadbeat (within 2 %%) after identification");
    CHECK(sb.settle2 > 2, "not deadbeat before identification");

    /* ---- 5. variants (reported) */
    for (int variant = 0; variant < 2; ++variant) {
        yplant_low(&pl);
        yao2020_dpcc_config_t c2 = cfg;
        c2.R_hat_ohm = (float)Rh;
        c2.L_hat_H = (float)Lh;
        if (variant == 0)
            c2.rereference = 0u;
        else
            c2.n_rounds = 2u;
        yao2020_dpcc_init(&c2, &st);
        settle(&pl, &c2, &st, 3000, 0.0, IQ0);
        ident_t v = identify(&pl, &c2, &st, 300000);
        printf("5.%d %s: state %d, L_hat error %+.3f %% (conv %d), R_hat error %+.3f %% (conv %d),"
               " %.3f s\n",
               variant, variant == 0 ? "stale M(t0) (rereference = 0)" : "two rounds L,R,L,R          ", v.state,
               100 * ((double)v.L / L - 1), v.Lconv, 100 * ((double)v.R / R - 1), v.Rconv, v.t_done_s);
    }
    return check_finish("test_yao2020_ident_low");
}
