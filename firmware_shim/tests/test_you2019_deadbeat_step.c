/* test_you2019_deadbeat_step.c - You 2019 deadbeat controller against the exact
 * discrete standstill plant: matched step, voltage-limited step (both
 * memory readings), inductance and resistance mismatch vs analytic poles. */
#include <complex.h>
#include <math.h>
#include <stdio.h>

#include "check.h"
#include "drive_core.h"
#include "drive_plant.h"

#define NSTEP 2000
#define K0 10

typedef struct {
    double iq[NSTEP]; /* sampled iq(k) seen by the drive at step k */
    double vq[NSTEP]; /* total q command computed at step k */
    int nlim;
} run_t;

static void run_step(const drive_config_t *cfg, double iq_ref, uint8_t limited_memory, run_t *r)
{
    static drive_t drv;
    drive_plant_t pl;
    drive_plant_init(&pl, "you2019");
    drive_init(&drv, cfg);
    ((od_drive_online_tuning_t *)drive_law_record(&drv))->limited_memory = limited_memory; /* its law.eds record */
    drive_apply_config(&drv);
    r->nlim = 0;
    for (int k = 0; k < NSTEP; ++k) {
        drive_meas_t m;
        drive_cmd_t c;
        drive_plant_measure(&pl, &m);
        drv.sp.iq_ref_A = k >= K0 ? (float)iq_ref : 0.0f;
        drive_current_step(&drv, &m, &c);
        r->iq[k] = (double)drv.st.i_q_A;
        r->vq[k] = (double)drv.st.out.v_q_V;
        r->nlim += drv.st.out.v_limited;
        drive_plant_advance(&pl, &c);
    }
}

/* Closed loop with controller gains from (R_hat, L_hat) and plant (R, L):
 *   C(z) = (z^2 - Ah z) / (Bh (z^2 - 1))          (You 2019 Eq. 16)
 *   G(z) = B z^-2 / (1 - A z^-1) = B / (z (z - A)) (You 2019 Eq. 2)
 *   1 + C G = 0  <=>  P(z) = (z^2 - 1)(z - A) + beta (z - Ah) = 0, beta = B/Bh
 *   P(z) = z^3 - A z^2 + (beta - 1) z + (A - beta Ah)
 *   T(z) = beta (z - Ah) / P(z); matched (beta = 1, Ah = A): T = 1/z^2.
 * Difference equation of T:
 *   y(k) = A y(k-1) - (beta-1) y(k-2) - (A - beta Ah) y(k-3)
 *          + beta (r(k-2) - Ah r(k-3)) */
static void analytic(double R, double L, double Rh, double Lh, double complex poles[3], double *y, int n, double ref)
{
    const double Ts = motor_params_preset("you2019").Ts_s;
    const double A = exp(-Ts * R / L), B = (1 - A) / R;
    const double Ah = exp(-Ts * Rh / Lh), Bh = (1 - Ah) / Rh;
    const double beta = B / Bh;
    const double c[4] = {1.0, -A, beta - 1.0, A - beta * Ah};
    /* Durand-Kerner for the monic cubic */
    const double complex jj = (double complex)I;
    double complex z[3] = {0.4 + 0.9 * jj, -0.3 + 0.2 * jj, 0.7 - 0.5 * jj};
    for (int it = 0; it < 500; ++it) {
        for (int i = 0; i < 3; ++i) {
            double complex num = ((z[i] + c[1]) * z[i] + c[2]) * z[i] + c[3];
            double complex den = 1.0;
            for (int j = 0; j < 3; ++j)
                if (j != i) den *= (z[i] - z[j]);
            z[i] -= num / den;
        }
    }
    for (int i = 0; i < 3; ++i) poles[i] = z[i];
    for (int k = 0; k < n; ++k) {
        double r2 = (k - 2 >= K0) ? ref : 0.0, r3 = (k - 3 >= K0) ? ref : 0.0;
        double y1 = k >= 1 ? y[k - 1] : 0, y2 = k >= 2 ? y[k - 2] : 0, y3 = k >= 3 ? y[k - 3] : 0;
        y[k] = A * y1 - (beta - 1) * y2 - (A - beta * Ah) * y3 + beta * (r2 - Ah * r3);
    }
}

static int settle_periods(const double *y, double ref, double tol)
{
    int last = K0;
    for (int k = K0; k < NSTEP; ++k)
        if (fabs(y[k] - ref) > tol * fabs(ref)) last = k;
    return last + 1 - K0;
}

int main(void)
{
    static run_t r;
    drive_config_t cfg;
    const motor_params_t mp = motor_params_preset("you2019");
    const double Ts = mp.Ts_s, R = mp.R_ohm, Lq = mp.Lq_H;
    const double A = exp(-Ts * R / Lq), B = (1 - A) / R, K1 = 1 / B, K2 = A / B;
    printf("You 2019 motor: A=%.7f B=%.7f A/Vs  K1=%.4f V/A K2=%.4f V/A\n", A, B, K1, K2);

    /* ---- 1. matched 0 -> 1 A ---- */
    drive_default_config(&cfg);
    run_step(&cfg, 1.0, 0u, &r);
    double maxerr_after = 0, maxi = 0;
    for (int k = K0 + 2; k < NSTEP; ++k) {
        if (fabs(r.iq[k] - 1.0) > maxerr_after) maxerr_after = fabs(r.iq[k] - 1.0);
        if (r.iq[k] > maxi) maxi = r.iq[k];
    }
    printf("[matched 0->1A] iq(k0+1)=%.7f iq(k0+2)=%.7f max|iq-1| after k0+2=%.3g max=%.7f\n", r.iq[K0 + 1],
           r.iq[K0 + 2], maxerr_after, maxi);
    printf("[matched 0->1A] vq(k0)=%.4f V (K1*1=%.4f, paper 84.14, You 2019 Eq.20 L/Ts=%.3f)"
           " vq(k0+1)=%.4f V (K1-K2=R*1=%.4f, paper 2.1) vq(end)=%.4f\n",
           r.vq[K0], K1, Lq / Ts, r.vq[K0 + 1], K1 - K2, r.vq[NSTEP - 1]);
    CHECK(fabs(r.iq[K0 + 1]) < 1e-6, "iq(k0+1) not 0");
    CHECK(maxerr_after < 2e-5, "not deadbeat: %g", maxerr_after);
    CHECK(maxi <= 1.0 + 2e-5, "overshoot");
    CHECK(fabs(r.vq[K0] - K1) < 1e-3 * K1, "first command %g vs %g", r.vq[K0], K1);
    CHECK(fabs(r.vq[K0 + 1] - (K1 - K2)) < 2e-3, "second command %g", r.vq[K0 + 1]);

    /* ---- 2. 0 -> 4 A with Vmax = 139 V, both memory readings ---- */
    for (int mode = 0; mode < 2; ++mode) {
        drive_default_config(&cfg);
        run_step(&cfg, 4.0, (uint8_t)mode, &r);
        int reach = -1;
        double imax = 0;
        for (int k = K0; k < NSTEP; ++k) {
            if (reach < 0 && r.iq[k] >= 4.0 * 0.98) reach = k - K0;
            if (r.iq[k] > imax) imax = r.iq[k];
        }
        printf("[0->4A %s memory] periods to 98%%=%d, saturated periods=%d, max iq=%.4f A "
               "(overshoot %.2f%%), iq(k0+20)=%.4f, iq(end)=%.5f\n  vq:",
               mode == 0 ? "UNLIMITED" : "LIMITED", reach, r.nlim, imax, 100 * (imax - 4) / 4, r.iq[K0 + 20],
               r.iq[NSTEP - 1]);
        for (int k = K0; k < K0 + 9; ++k) printf(" %.1f", r.vq[k]);
        printf("\n  iq:");
        for (int k = K0; k < K0 + 9; ++k) printf(" %.3f", r.iq[k]);
        printf("\n");
        if (mode == 0) {
            CHECK(reach >= 5 && reach <= 8, "unlimited memory: %d periods", reach);
            CHECK(imax < 4.0 * 1.05, "overshoot too large");
            CHECK(fabs(r.iq[NSTEP - 1] - 4.0) < 2e-3, "no convergence");
            CHECK(r.nlim >= 2, "should saturate several times (You 2019 Eq. 17 pulse-wise)");
        } else {
            CHECK(reach > 20, "limited memory expected to crawl (open loop), got %d", reach);
        }
    }

    /* ---- 3. inductance mismatch ---- */
    static double y[NSTEP];
    const double lf[2] = {0.5, 1.2};
    for (int c = 0; c < 2; ++c) {
        drive_default_config(&cfg);
        cfg.Lq_hat_H = (float)(lf[c] * 4.54e-3);
        cfg.Ld_hat_H = (float)(lf[c] * 4.46e-3);
        run_step(&cfg, 1.0, 0u, &r);
        double complex p[3];
        analytic(R, Lq, R, lf[c] * Lq, p, y, NSTEP, 1.0);
        double maxdev = 0, imax = 0;
        for (int k = 0; k < 300; ++k) {
            if (fabs(y[k] - r.iq[k]) > maxdev) maxdev = fabs(y[k] - r.iq[k]);
            if (r.iq[k] > imax) imax = r.iq[k];
        }
        int ncomplex = 0, reach = -1;
        double rmax = 0;
        for (int k = K0; k < NSTEP; ++k)
            if (reach < 0 && r.iq[k] >= 0.98) reach = k - K0;
        for (int i = 0; i < 3; ++i) {
            if (fabs(cimag(p[i])) > 1e-9) ncomplex++;
            if (cabs(p[i]) > rmax && fabs(cabs(p[i]) - exp(-Ts * R / Lq)) > 1e-3) rmax = cabs(p[i]);
        }
        printf("[L_hat=%.1fL] poles: %.4f%+.4fj, %.4f%+.4fj, %.4f%+.4fj; sim vs T(z) max dev=%.2g;"
               " overshoot=%.2f%%; periods to 98%%=%d; 2%% settling=%d periods\n",
               lf[c], creal(p[0]), cimag(p[0]), creal(p[1]), cimag(p[1]), creal(p[2]), cimag(p[2]), maxdev,
               100 * (imax - 1), reach, settle_periods(r.iq, 1.0, 0.02));
        printf("  iq:");
        for (int k = K0; k < K0 + 12; ++k) printf(" %.3f", r.iq[k]);
        printf("\n");
        CHECK(maxdev < 1e-4, "simulation deviates from the characteristic polynomial");
        if (c == 0) {
            CHECK(ncomplex == 0, "0.5L: expected real poles (overdamped)");
            /* "overdamped" in You 2019's sense: poles on the real axis.  The
             * negative pole gives the 2-period staircase, the slow real pole near
             * A (zero at A_hat no longer cancels it) a small slow overshoot. */
            CHECK(reach >= 6 && reach <= 9, "0.5L: periods to 98%% = %d", reach);
            CHECK(imax < 1.10, "0.5L: overshoot too large");
        } else {
            CHECK(ncomplex == 2, "1.2L: expected complex pair (underdamped)");
            CHECK(imax > 1.05, "1.2L: expected overshoot");
        }
    }

    /* ---- 4. resistance mismatch ---- */
    const double rf[2] = {0.5, 1.5};
    for (int c = 0; c < 2; ++c) {
        drive_default_config(&cfg);
        cfg.R_hat_ohm = (float)(rf[c] * R);
        run_step(&cfg, 1.0, 0u, &r);
        double complex p[3];
        analytic(R, Lq, rf[c] * R, Lq, p, y, NSTEP, 1.0);
        double maxdev = 0;
        for (int k = 0; k < NSTEP; ++k)
            if (fabs(y[k] - r.iq[k]) > maxdev) maxdev = fabs(y[k] - r.iq[k]);
        double off = 0;
        for (int k = K0 + 2; k < K0 + 10; ++k) off += (r.iq[k] - 1.0) / 8.0;
        printf("[R_hat=%.1fR] poles: %.5f%+.5fj, %.5f%+.5fj, %.5f%+.5fj; iq(k0+2)=%.5f; "
               "mean offset k0+2..k0+9 = %+.3f%%; iq(k0+100)=%.5f iq(end)=%.6f; dev vs T(z)=%.2g\n",
               rf[c], creal(p[0]), cimag(p[0]), creal(p[1]), cimag(p[1]), creal(p[2]), cimag(p[2]), r.iq[K0 + 2],
               100 * off, r.iq[K0 + 100], r.iq[NSTEP - 1], maxdev);
        CHECK(fabs(off) < 0.02, "offset should be small");
        CHECK(c == 0 ? off < 0 : off > 0, "offset sign (You 2019 Fig. 11/12)");
        CHECK(fabs(r.iq[NSTEP - 1] - 1.0) < 1e-3, "integral action should remove it eventually");
        CHECK(maxdev < 1e-4, "deviation from analytic");
    }

    return check_finish("test_you2019_deadbeat_step");
}
