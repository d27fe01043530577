/* test_yao2020_deadbeat.c - Yao 2020 DPCC (Eq. 12) with the sliding-mode
 * observer (Eq. 13-18) and matched R, L against the RK4 plant: the current
 * reaches an iq / id step exactly two periods after the reference changes
 * (one period computation delay + one period of action, Eq. 9-10), with no
 * cross-coupling, on the Table I motor at 133.3 Hz and the Table II motor at
 * 1.33 kHz (w T = 0.84 rad).  Also: the observer error contracts by Q = 0.4
 * per period (derived error dynamics i~(k+1) = Q i~(k) + p(k-1) - p(k)). */
#include <math.h>
#include <stdio.h>

#include "yao2020_dpcc.h"
#include "yao2020_common.h"

#include "check.h"

#define N 800
#define K1 300 /* iq step */
#define K2 500 /* id step */

static void run(const char *name, int high, int observer, double iq_step, double id_step)
{
    motor_t pl;
    if (high)
        yplant_high(&pl);
    else
        yplant_low(&pl);
    yao2020_dpcc_config_t cfg;
    yao2020_dpcc_default_config(&cfg);
    cfg.R_hat_ohm = (float)pl.par.R_ohm;
    cfg.L_hat_H = (float)pl.par.Lq_H;
    cfg.psi_hat_Wb = observer ? 0.0f : (float)pl.par.psi_Wb; /* observer: psi unused */
    cfg.observer_enable = (uint8_t)observer;
    static yao2020_dpcc_state_t st;
    yao2020_dpcc_init(&cfg, &st);
    static double iq[N], id[N], eq[N];
    yao2020_dpcc_cmd_t cmd;
    for (int k = 0; k < N; ++k) {
        const double iqr = k >= K1 ? iq_step : 0.0;
        const double idr = k >= K2 ? id_step : 0.0;
        iq[k] = pl.iq_A;
        id[k] = pl.id_A;
        yloop_step(&pl, &cfg, &st, idr, iqr, &cmd);
        eq[k] = hypot((double)st.i_err_d_A, (double)st.i_err_q_A);
    }
    /* observer contraction (psi_hat = 0 seeds p_hat(0) = 0 != p) */
    if (observer) {
        double worst = 0.0;
        for (int k = 2; k < 8; ++k) {
            const double r = eq[k] / eq[k - 1];
            if (fabs(r - 0.4) > worst) worst = fabs(r - 0.4);
        }
        printf("  %-5s observer |i~(k)|: %.3e %.3e %.3e %.3e A, max |ratio - Q| = %.2e\n", name, eq[1], eq[2], eq[3],
               eq[4], worst);
        CHECK(eq[1] > 1e-2 && worst < 1e-3, "%s: observer contraction", name);
    }
    const double tol = 2e-3 * fabs(iq_step);
    double ss_before = 0.0;
    for (int k = K1 - 50; k < K1; ++k) ss_before = fmax(ss_before, fabs(iq[k]) + fabs(id[k]));
    double err_after_q = 0.0, cross_d = 0.0;
    for (int k = K1 + 2; k < K2; ++k) {
        err_after_q = fmax(err_after_q, fabs(iq[k] - iq_step));
        cross_d = fmax(cross_d, fabs(id[k]));
    }
    int reach = -1;
    for (int k = K1; k < K2; ++k)
        if (fabs(iq[k] - iq_step) < tol) {
            reach = k - K1;
            break;
        }
    double err_after_d = 0.0, cross_q = 0.0;
    for (int k = K2 + 2; k < N; ++k) {
        err_after_d = fmax(err_after_d, fabs(id[k] - id_step));
        cross_q = fmax(cross_q, fabs(iq[k] - iq_step));
    }
    int reach_d = -1;
    for (int k = K2; k < N; ++k)
        if (fabs(id[k] - id_step) < 2e-3 * fabs(id_step)) {
            reach_d = k - K2;
            break;
        }
    printf("  %-5s obs=%d: before step |i| <= %.1e A; iq 0->%.0f A: iq(k0+1) = %.4f, "
           "iq(k0+2) = %.5f, reached in %d periods, max|iq - ref| after = %.2e, max|id| = %.2e\n",
           name, observer, ss_before, iq_step, iq[K1 + 1], iq[K1 + 2], reach, err_after_q, cross_d);
    printf("  %-5s obs=%d: id 0->%.0f A: id(k0+2) = %.5f, reached in %d periods, max|id - ref|"
           " after = %.2e, max|iq - ref| = %.2e\n",
           name, observer, id_step, id[K2 + 2], reach_d, err_after_d, cross_q);
    CHECK(ss_before < tol, "%s: steady state before the step", name);
    CHECK(fabs(iq[K1 + 1]) < tol, "%s: iq must not move before k0+2", name);
    CHECK(reach == 2, "%s: deadbeat iq in 2 periods (got %d)", name, reach);
    CHECK(err_after_q < tol && cross_d < tol, "%s: iq step error/cross-coupling", name);
    CHECK(reach_d == 2, "%s: deadbeat id in 2 periods (got %d)", name, reach_d);
    CHECK(err_after_d < tol && cross_q < tol, "%s: id step error/cross-coupling", name);
}

int main(void)
{
    printf("matched parameters, deadbeat steps (T = 100 us)\n");
    run("low", 0, 1, 4.0, -2.0);
    run("high", 1, 1, 10.0, -5.0);
    run("low", 0, 0, 4.0, -2.0);
    run("high", 1, 0, 10.0, -5.0);
    return check_finish("test_yao2020_deadbeat");
}
