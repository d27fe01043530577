/* test_yao2020_model.c - Yao 2020 fully discretised model (Eq. 4-7) against
 * a fine RK4 integration; the characteristic-vector algebra (Eq. 26-29)
 * against the derived closed form; the low-/high-frequency simplifications
 * (Eq. 32-43) against the exact form; the Eq. 30-31 classification. */
#include <math.h>
#include <stdio.h>

#include "yao2020_dpcc.h"
#include "yao2020_identification.h"
#include "yao2020_model.h"
#include "yao2020_common.h"

#include "check.h"

/* (a) one period of Yao 2020 Eq. 7 vs RK4 */
static void check_model(const char *name, motor_t *pl, double w, double iscale, double vscale)
{
    double maxerr = 0.0;
    unsigned seed = 12345u;
    for (int t = 0; t < 200; ++t) {
        double r[5];
        for (int j = 0; j < 5; ++j) {
            seed = seed * 1103515245u + 12345u;
            r[j] = ((double)((seed >> 8) & 0xffff) / 65535.0) * 2.0 - 1.0;
        }
        pl->omega_m_rad_s = w;
        pl->id_A = iscale * r[0];
        pl->iq_A = iscale * r[1];
        pl->theta_m_rad = 3.0 * r[4];
        const double val = vscale * r[2], vbe = vscale * r[3];
        const double c = cos(pl->theta_m_rad), s = sin(pl->theta_m_rad);
        const double vd = val * c + vbe * s, vq = -val * s + vbe * c;
        const double id0 = pl->id_A, iq0 = pl->iq_A;
        pl->v_alpha_pend_V = val;
        pl->v_beta_pend_V = vbe;
        yplant_advance(pl, 0.0, 0.0);
        /* Yao 2020 Eq. 7: i(k+1) = Tr (x i + y v + G2 e), e = [0 w psi] */
        yao2020_model_t m;
        yao2020_model_compute((float)pl->par.R_ohm, (float)pl->par.Lq_H, (float)w, (float)pl->par.Ts_s, &m);
        const double e = w * pl->par.psi_Wb;
        const double ad = (double)m.x * id0 + (double)m.y * vd - (double)m.d2 * e;
        const double aq = (double)m.x * iq0 + (double)m.y * vq + (double)m.d1 * e;
        const double pd = (double)m.c * ad + (double)m.s * aq;
        const double pq = -(double)m.s * ad + (double)m.c * aq;
        const double err = hypot(pd - pl->id_A, pq - pl->iq_A);
        if (err > maxerr) maxerr = err;
    }
    printf("  Yao 2020 Eq. 4-7 vs RK4, %-5s w = %8.1f rad/s: max |i_model - i_rk4| = %.3e A"
           " (scale %.0f A)\n",
           name, w, maxerr, iscale);
    CHECK(maxerr < 2e-5 * iscale + 1e-6, "model error %s w=%g: %g", name, w, maxerr);
}

/* (b)-(d) dM for a d-axis step: Yao 2020 Eq. 27-28 + Eq. 29, closed form, Yao 2020 Eq. 35/36,
 * Eq. 42/43 */
static void check_dM(const char *name, double R, double L, double Rh, double Lh, double w, double T, double did,
                     int low)
{
    double x, y, xh, yh;
    yxy(R, L, T, &x, &y);
    yxy(Rh, Lh, T, &xh, &yh);
    const double c = cos(w * T), s = sin(w * T);
    /* Yao 2020 Eq. 6 with the estimates */
    const double den = Rh * Rh + w * w * Lh * Lh;
    const double d1 = ((xh - c) * Rh - s * w * Lh) / den;
    const double d2 = -((xh - c) * w * Lh + s * Rh) / den;
    /* Yao 2020 Eq. 29 */
    const double dvd = (c - x) * did / y, dvq = s * did / y;
    /* Yao 2020 Eq. 28, Eq. 27 */
    const double xt = xh - x, yt = yh - y;
    const double dWd = -d1 * (xt * did + yt * dvd) - d2 * yt * dvq;
    const double dWq = d2 * (xt * did + yt * dvd) - d1 * yt * dvq;
    const double n2 = d1 * d1 + d2 * d2;
    const double dMd = dWd / n2, dMq = dWq / n2;
    const ycx ex = ydM_exact(R, L, Rh, Lh, w, T, did);
    printf("  %-5s R_hat/R %.2f L_hat/L %.2f: Yao 2020 Eq.27-29 dM = (%+9.4f, %+9.4f) V,"
           " closed form (%+9.4f, %+9.4f) V\n",
           name, Rh / R, Lh / L, dMd, dMq, ex.re, ex.im);
    CHECK(fabs(dMd - ex.re) < 1e-7 * (1.0 + fabs(ex.re)) && fabs(dMq - ex.im) < 1e-7 * (1.0 + fabs(ex.im)),
          "Yao 2020 Eq. 27-29 vs closed form");
    if (low) {
        /* Yao 2020 Eq. 35/36 divided by |d_hat|^2 = (T/L_hat)^2 (Eq. 32: d1 ~ -T/L_hat,
         * d2 ~ 0; the extracted prefactor (R^2 T + wTwL)/(R^2 + w^2 L^2) reads
         * (R^2 T/L + w^2 T L)/(R^2 + w^2 L^2) = T/L_hat):
         *   dM_d ~ (R - R_hat) did,   dM_q ~ w (L - L_hat) did */
        const double ad = (R - Rh) * did, aq = w * (L - Lh) * did;
        printf("        low-frequency form Yao 2020 Eq. 35/36: (%+9.4f, %+9.4f) V"
               "   [d1 = %.4e vs -T/L_hat = %.4e, d2 = %.2e]\n",
               ad, aq, d1, -T / Lh, d2);
        const double sc = fabs(ex.re) + fabs(ex.im);
        CHECK(fabs(ad - ex.re) < 0.1 * sc && fabs(aq - ex.im) < 0.1 * sc,
              "low-frequency approximation off by more than 10 %% of |dM|");
    } else {
        /* Yao 2020 Eq. 42 and Eq. 43 divided by |d_hat|^2 ~ (s^2 + (c - x)^2)/(w L_hat)^2
         * (Eq. 37); Eq. 43 is evaluated with L_hat = L as stated there. */
        /* Yao 2020 Eq. 41: y_hat - y ~ (L - L_hat) T / (L L_hat), i.e. the extracted
         * "y~ = y_hat - y" sign is consistent with Eq. 34; Eq. 42 follows. */
        const double dWq42 = (s * s + (c - x) * (c - x)) * T / (y * w * L * Lh * Lh) * (L - Lh) * did;
        const double n2a = (s * s + (c - xh) * (c - xh)) / (w * w * Lh * Lh);
        double xL, yL;
        yxy(Rh, L, T, &xL, &yL);
        const double dWd43 = s / (w * Lh) * (yL / y) * (exp(-Rh * T / L) - exp(-R * T / L)) * did;
        printf("        high-frequency form Yao 2020 Eq. 42/43: (%+9.4f, %+9.4f) V\n", dWd43 / n2a, dWq42 / n2a);
        if (fabs(Lh - L) > 1e-12) {
            CHECK(fabs(dWq42 / n2a - ex.im) < 0.15 * fabs(ex.im), "Yao 2020 Eq. 42 vs exact (L case)");
        } else {
            CHECK(fabs(dWd43 / n2a - ex.re) < 0.15 * fabs(ex.re), "Yao 2020 Eq. 43 vs exact (R case)");
        }
    }
}

int main(void)
{
    motor_t pl;
    printf("(a) fully discretised model, one period\n");
    yplant_low(&pl);
    const double wl = motor_omega_e(&pl);
    check_model("low", &pl, 0.0, 5.0, 150.0);
    check_model("low", &pl, wl, 5.0, 150.0);
    check_model("low", &pl, -wl, 5.0, 150.0);
    yplant_high(&pl);
    const double wh = motor_omega_e(&pl);
    check_model("high", &pl, 0.0, 20.0, 24.0);
    check_model("high", &pl, wh, 20.0, 24.0);
    check_model("high", &pl, -wh, 20.0, 24.0);

    printf("(b-d) dM = M(t1) - M(t0) for a d-axis injection (Fig. 7/8 cases)\n");
    const double T = 100e-6;
    const motor_params_t lo = motor_params_preset("yao2020_low");
    const motor_params_t hi = motor_params_preset("yao2020_high");
    const double R_lo = lo.R_ohm, L_lo = lo.Lq_H, R_hi = hi.R_ohm, L_hi = hi.Lq_H;
    check_dM("low", R_lo, L_lo, R_lo, 1.5 * L_lo, wl, T, -2.0, 1);
    check_dM("low", R_lo, L_lo, 1.5 * R_lo, L_lo, wl, T, -2.0, 1);
    check_dM("low", R_lo, L_lo, 1.5 * R_lo, 1.5 * L_lo, wl, T, -2.0, 1);
    check_dM("high", R_hi, L_hi, R_hi, 1.5 * L_hi, wh, T, -5.0, 0);
    check_dM("high", R_hi, L_hi, 1.5 * R_hi, L_hi, wh, T, -5.0, 0);
    /* Fig. 7/8 qualitative statement: L error -> M_q responds, R error -> M_d */
    {
        const ycx a = ydM_exact(R_lo, L_lo, R_lo, 1.5 * L_lo, wl, T, -2.0);
        const ycx b = ydM_exact(R_lo, L_lo, 1.5 * R_lo, L_lo, wl, T, -2.0);
        const ycx c = ydM_exact(R_hi, L_hi, R_hi, 1.5 * L_hi, wh, T, -5.0);
        const ycx d = ydM_exact(R_hi, L_hi, 1.5 * R_hi, L_hi, wh, T, -5.0);
        printf("  |dM_q/dM_d|: low 1.5L %.1f, high 1.5L %.1f;  |dM_d/dM_q|: low 1.5R %.1f,"
               " high 1.5R %.2f\n",
               fabs(a.im / a.re), fabs(c.im / c.re), fabs(b.re / b.im), fabs(d.re / d.im));
        CHECK(a.im > 0 && fabs(a.im) > 10 * fabs(a.re), "Fig. 7(a,b): M_q must rise");
        CHECK(b.re > 0 && fabs(b.re) > 10 * fabs(b.im), "Fig. 7(c,d): M_d must rise");
        CHECK(c.im > 0 && fabs(c.im) > 3 * fabs(c.re), "Fig. 8(a,b)");
        CHECK(d.re > 0, "Fig. 8(c,d): M_d must rise");
        /* fixed point: dM = 0 iff Zd_hat = Zd iff (x_hat, y_hat) = (x, y) */
        const ycx z = ydM_exact(R_lo, L_lo, R_lo, L_lo, wl, T, -2.0);
        CHECK(fabs(z.re) + fabs(z.im) < 1e-9, "dM at matched parameters");
        /* local loop gains at the fixed point (used by Yao 2020 Eq. 44) */
        const double hL = 1e-8, hR = 1e-5;
        const ycx gl = ydM_exact(R_lo, L_lo, R_lo, L_lo + hL, wl, T, -2.0);
        const ycx gr = ydM_exact(R_lo, L_lo, R_lo + hR, L_lo, wl, T, -2.0);
        const ycx ghl = ydM_exact(R_hi, L_hi, R_hi, L_hi + 1e-11, wh, T, -5.0);
        const ycx ghr = ydM_exact(R_hi, L_hi, R_hi + 1e-7, L_hi, wh, T, -5.0);
        printf("  exact loop gains k = d(dM_q)/dL_hat, d(dM_d)/dR_hat at the fixed point:\n"
               "    low : %.1f V/H (w|did| = %.1f), %.4f V/ohm (|did| = 2)\n"
               "    high: %.1f V/H (w|did| = %.1f), %.4f V/ohm (|did| = 5)\n",
               gl.im / hL, wl * 2.0, gr.re / hR, ghl.im / 1e-11, wh * 5.0, ghr.re / 1e-7);
    }

    printf("(e) Yao 2020 Eq. 30-31 classification\n");
    const yao2020_identification_motor_class_t cl =
        yao2020_identification_classify((float)R_lo, (float)L_lo, (float)wl, 1e-4f);
    const yao2020_identification_motor_class_t ch =
        yao2020_identification_classify((float)R_hi, (float)L_hi, (float)wh, 1e-4f);
    const yao2020_identification_motor_class_t ch15 =
        yao2020_identification_classify((float)(1.5 * R_hi), (float)(1.5 * L_hi), (float)wh, 1e-4f);
    printf("  Table I @133.3 Hz: class %d (cos wT = %.4f, |e^-a - (1-a)| = %.2e)\n", (int)cl, cos(wl * T),
           fabs(exp(-0.04) - 0.96));
    printf("  Table II @1.33 kHz: class %d (cos wT = %.4f, R = %.4f vs 0.2 w L = %.4f);"
           " with 1.5R,1.5L: class %d\n",
           (int)ch, cos(wh * T), R_hi, 0.2 * wh * L_hi, (int)ch15);
    CHECK(cl == YAO2020_IDENTIFICATION_MOTOR_LOW_FREQ, "Table I must be low-frequency");
    CHECK(ch == YAO2020_IDENTIFICATION_MOTOR_NEITHER, "Table II misses R < 0.2 w L (0.045 > 0.0401)");
    return check_finish("test_yao2020_model");
}
