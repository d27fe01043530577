/* test_zhao2022_common.h - shared by the test_zhao2022_*.c mains (not a test
 * executable itself: the Makefile only builds test_*.c).  Double precision.
 *
 *  1. Zhao 2022 Table 1 motor: the "zhao2022" preset of
 *     plant_rt/core/presets.c (R 48.9 ohm, Ld = Lq = 14 mH, 5 pole pairs,
 *     psi = 1.4213 / (1.5 * 5) Wb, Ts = 100 us (10 kHz current control),
 *     Udc = 28 V, rated speed 367.72 deg/s), read once by zh_motor().
 *  2. The plant: the exact discrete model of tests/c/motor_model.h
 *     (motor_zoh_t): w constant over the period, voltage held (in the rotor
 *     frame) over the period, complex notation i = id + j iq:
 *        di/dt = -(R/L + j w) i + (u - j w psi)/L
 *        i(k+1) = Phi i(k) + Gam (u(k) - j w psi),
 *        Phi = exp(-(R/L + j w) Ts), Gam = (1 - Phi)/(R + j w L)
 *     One-period command delay: the command computed from sample k acts
 *     over [k+1, k+2] (motor_zoh_advance stores it and applies it at the
 *     next call), as in Zhao 2022 Fig. 2 and drive_core.h.
 *  3. Closed-loop characteristic polynomials and a root finder
 *     (Durand-Kerner) -> spectral radius -> stability boundary in L/L0.
 *
 * Closed loop of the Zhao 2022 incremental law (Eq. 22/23) with this plant
 * (derived here, the paper has no such derivation):
 *   controller, v(k) = command computed at k = paper u(k+1):
 *     v(k) = K1c (r - i(k-2)) - K2 (i(k) - i(k-2)) - v(k-1) + v(k-2) + v(k-3)
 *     K1c = R0 + L0/Ts + j w L0, K2 = 2 L0/Ts
 *   z-domain: V (z+1)^2 (z-1) = K1c z^3 R - (K1c z + K2 (z^3 - z)) I
 *   plant:    z (z - Phi) I = Gam V          (delay: u(k) = v(k-1))
 *   =>  Q(z) I = Gam K1c z^2 R,
 *       Q(z) = (z - Phi)(z - 1)(z + 1)^2 + Gam K2 z^2 + Gam (K1c - K2)
 *   (a common factor z was cancelled).  Q(1) = Gam K1c, so T(1) = 1 for any
 *   parameter error (integral action of the incremental form).
 *   Paper's approximation (Zhao 2022 Eq. 28-34): R = R0 = w = 0 in the limit
 *   Ts -> 0 gives Phi = 1, Gam = Ts/L and Q = (L0/L) [lam (z^2-1)^2
 *   + 2 (z^2 - 1) + 1] with lam = L/L0, i.e. exactly Zhao 2022 Eq. 34's denominator.
 *   The exact plant therefore reproduces the paper's polynomial when
 *   R Ts / L -> 0; for the Table 1 motor R Ts / L = 0.349, which moves the
 *   boundary (test_zhao2022_stability.c).
 *
 * Closed loop of the conventional law (Zhao 2022 Eq. 5/6) with the same plant:
 *   v(k) = (R0 - L0/Ts + j w L0) i(k) + (L0/Ts) r(k) + j w psi0
 *   =>  (z^2 - Phi z - Gam (R0 - L0/Ts + j w L0)) I = Gam (L0/Ts) R + dist. */
#ifndef TEST_ZHAO2022_COMMON_H
#define TEST_ZHAO2022_COMMON_H

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "motor_model.h"
#include "zhao2022_incremental.h"
#include "zhao2022_predictive.h"

#define ZH_PI MOTOR_PI
#define ZH_IM MOTOR_IM

/* ---------------------------------------------------------------- motor */
static inline const motor_params_t *zh_motor(void)
{
    static motor_params_t par;
    static int loaded = 0;
    if (!loaded) {
        par = motor_params_preset("zhao2022");
        loaded = 1;
    }
    return &par;
}
#define ZH_R (zh_motor()->R_ohm)
#define ZH_L (zh_motor()->Lq_H) /* = Ld */
#define ZH_TS (zh_motor()->Ts_s)
#define ZH_P (zh_motor()->pole_pairs)
#define ZH_PSI (zh_motor()->psi_Wb)
#define ZH_UDC (zh_motor()->Vdc_V)
#define ZH_VMAX (ZH_UDC / 1.7320508075688772)         /* linear SVPWM circle */
#define ZH_WM_RATED (zh_motor()->omega_m_rated_rad_s) /* mechanical rad/s */
#define ZH_WE_RATED (ZH_P * ZH_WM_RATED)              /* 32.09 rad/s electrical */

/* The plant: the Table 1 motor with the test's R, L (= Ld = Lq) and psi (the
 * mismatch and flux sweeps), at the constant electrical speed w. */
static inline void zh_plant_init(motor_zoh_t *pl, double R, double L, double psi, double w)
{
    motor_params_t par = *zh_motor();
    par.R_ohm = R;
    par.Ld_H = L;
    par.Lq_H = L;
    par.psi_Wb = psi;
    motor_zoh_init(pl, &par, w);
}

/* --------------------------------------------------------- controllers */
typedef enum { ZH_INC = 0, ZH_EUL = 1 } zh_law_t;
static const char *const zh_law_name[2] = {"incremental(bilinear)", "conventional(Euler)"};

typedef struct {
    zh_law_t law;
    zhao2022_incremental_state_t inc;
    zhao2022_predictive_state_t eul;
} zh_ctrl_t;

static inline int zh_ctrl_init(zh_ctrl_t *c, zh_law_t law, double R0, double L0, double psi0, double Vmax)
{
    c->law = law;
    if (law == ZH_INC) {
        const zhao2022_incremental_config_t cfg = {(float)R0, (float)L0, (float)ZH_TS, (float)Vmax};
        return zhao2022_incremental_init(&cfg, &c->inc);
    }
    const zhao2022_predictive_config_t cfg = {(float)R0, (float)L0, (float)psi0, (float)ZH_TS, (float)Vmax};
    return zhao2022_predictive_init(&cfg, &c->eul);
}

static inline void zh_ctrl_step(zh_ctrl_t *c, double complex i, double w, double complex r, double *vd, double *vq)
{
    float fd, fq;
    if (c->law == ZH_INC) {
        zhao2022_incremental_step(&c->inc, (float)creal(r), (float)cimag(r), (float)creal(i), (float)cimag(i), (float)w,
                                  &fd, &fq);
    } else {
        zhao2022_predictive_step(&c->eul, (float)creal(r), (float)cimag(r), (float)creal(i), (float)cimag(i), (float)w,
                                 &fd, &fq);
    }
    *vd = (double)fd;
    *vq = (double)fq;
}

static inline int zh_ctrl_limited(const zh_ctrl_t *c) { return c->law == ZH_INC ? c->inc.limited : c->eul.limited; }

/* ------------------------------------------------ polynomials and roots */
#define ZH_MAXDEG 6

/* Durand-Kerner on a polynomial c[0] z^n + ... + c[n] (c[0] != 0). */
static inline void zh_roots(const double complex *c, int n, double complex *z)
{
    double complex a[ZH_MAXDEG + 1];
    for (int m = 0; m <= n; ++m) a[m] = c[m] / c[0];
    for (int m = 0; m < n; ++m) z[m] = cpow(0.4 + 0.9 * ZH_IM, m) * 0.9;
    for (int it = 0; it < 4000; ++it) {
        double delta = 0.0;
        for (int m = 0; m < n; ++m) {
            double complex p = 1.0;
            for (int q = 1; q <= n; ++q) p = p * z[m] + a[q];
            double complex den = 1.0;
            for (int q = 0; q < n; ++q)
                if (q != m) den *= (z[m] - z[q]);
            if (cabs(den) < 1e-300) den = 1e-300;
            const double complex dz = p / den;
            z[m] -= dz;
            if (cabs(dz) > delta) delta = cabs(dz);
        }
        if (delta < 1e-15) break;
    }
}

static inline double zh_spectral_radius(const double complex *c, int n)
{
    double complex z[ZH_MAXDEG];
    zh_roots(c, n, z);
    double r = 0.0;
    for (int m = 0; m < n; ++m)
        if (cabs(z[m]) > r) r = cabs(z[m]);
    return r;
}

/* Plant and controller parameters of one closed loop. */
typedef struct {
    double R, L;   /* plant */
    double R0, L0; /* controller */
    double w;      /* electrical rad/s */
} zh_loop_t;

/* Exact ZOH plant + one-period delay + Zhao 2022 Eq. 22/23: Q(z), deg 4. */
static inline int zh_poly_incremental(const zh_loop_t *lp, double complex *c)
{
    double complex Phi, Gam;
    motor_zoh_coeffs(lp->R, lp->L, ZH_TS, lp->w, &Phi, &Gam);
    const double complex K1c = lp->R0 + lp->L0 / ZH_TS + ZH_IM * lp->w * lp->L0;
    const double K2 = 2.0 * lp->L0 / ZH_TS;
    /* (z - Phi)(z - 1) = z^2 - (Phi + 1) z + Phi; times (z^2 + 2 z + 1) */
    const double complex p0 = 1.0, p1 = -(Phi + 1.0), p2 = Phi;
    c[0] = p0;
    c[1] = 2.0 * p0 + p1;
    c[2] = p0 + 2.0 * p1 + p2 + Gam * K2;
    c[3] = p1 + 2.0 * p2;
    c[4] = p2 + Gam * (K1c - K2);
    return 4;
}

/* Numerator of T(z) = N z^2 / Q(z) for the incremental law. */
static inline double complex zh_num_incremental(const zh_loop_t *lp)
{
    double complex Phi, Gam;
    motor_zoh_coeffs(lp->R, lp->L, ZH_TS, lp->w, &Phi, &Gam);
    return Gam * (lp->R0 + lp->L0 / ZH_TS + ZH_IM * lp->w * lp->L0);
}

/* Exact ZOH plant + delay + conventional Zhao 2022 Eq. 5/6, deg 2. */
static inline int zh_poly_euler(const zh_loop_t *lp, double complex *c)
{
    double complex Phi, Gam;
    motor_zoh_coeffs(lp->R, lp->L, ZH_TS, lp->w, &Phi, &Gam);
    c[0] = 1.0;
    c[1] = -Phi;
    c[2] = -Gam * (lp->R0 - lp->L0 / ZH_TS + ZH_IM * lp->w * lp->L0);
    return 2;
}
static inline double complex zh_num_euler(const zh_loop_t *lp)
{
    double complex Phi, Gam;
    motor_zoh_coeffs(lp->R, lp->L, ZH_TS, lp->w, &Phi, &Gam);
    return Gam * lp->L0 / ZH_TS;
}

/* Zhao 2022 Eq. 34 denominator (the Ts -> 0 approximation):
 *   lam (z^2 - 1)^2 + 2 (z^2 - 1) + 1 = lam z^4 - 2 (lam - 1) z^2 + lam - 1 */
static inline int zh_poly_paper_eq34(const zh_loop_t *lp, double complex *c)
{
    const double lam = lp->L / lp->L0;
    c[0] = lam;
    c[1] = 0.0;
    c[2] = -2.0 * (lam - 1.0);
    c[3] = 0.0;
    c[4] = lam - 1.0;
    return 4;
}

/* Zhao 2022 Eq. 28/29 with w = 0 but WITHOUT letting Ts -> 0 (the paper's
 * own two-period bilinear "plant" model, multiplied by Ts):
 *   (R Ts + L) z^4 - 2 (L - L0) z^2 + (L - L0) - (R - R0) Ts */
static inline int zh_poly_paper_eq28(const zh_loop_t *lp, double complex *c)
{
    c[0] = lp->R * ZH_TS + lp->L;
    c[1] = 0.0;
    c[2] = -2.0 * (lp->L - lp->L0);
    c[3] = 0.0;
    c[4] = (lp->L - lp->L0) - (lp->R - lp->R0) * ZH_TS;
    return 4;
}

typedef int (*zh_poly_fn)(const zh_loop_t *lp, double complex *c);

/* How the ratio lam = L/L0 is produced from a base loop. */
typedef enum {
    ZH_VARY_CONTROLLER = 0, /* plant fixed (Table 1), L0 = L / lam */
    ZH_VARY_PLANT = 1,      /* controller fixed (Table 1), L = lam L0 */
} zh_vary_t;

static inline zh_loop_t zh_loop_at(const zh_loop_t *base, zh_vary_t vary, double lam)
{
    zh_loop_t lp = *base;
    if (vary == ZH_VARY_CONTROLLER)
        lp.L0 = base->L / lam;
    else
        lp.L = lam * base->L0;
    return lp;
}

static inline double zh_radius_at(zh_poly_fn f, const zh_loop_t *base, zh_vary_t vary, double lam)
{
    double complex c[ZH_MAXDEG + 1];
    const zh_loop_t lp = zh_loop_at(base, vary, lam);
    const int n = f(&lp, c);
    return zh_spectral_radius(c, n);
}

/* Smallest stable L/L0: walks from lam_start (must be stable, e.g. 1 or
 * slightly below 1 where the paper's polynomial is degenerate) in steps of
 * -step until the spectral radius reaches 1 (or lam_min), then bisects.
 * Returns the boundary lam* (radius(lam*) = 1) or lam_min if none. */
static inline double zh_boundary(zh_poly_fn f, const zh_loop_t *base, zh_vary_t vary, double lam_start, double lam_stop,
                                 double step)
{
    double good = lam_start, bad = lam_start;
    const double dir = lam_stop < lam_start ? -1.0 : 1.0;
    int found = 0;
    for (double lam = lam_start; dir * (lam_stop - lam) >= 0.0; lam += dir * step) {
        if (zh_radius_at(f, base, vary, lam) >= 1.0) {
            bad = lam;
            found = 1;
            break;
        }
        good = lam;
    }
    if (!found) return lam_stop;
    for (int it = 0; it < 60; ++it) {
        const double mid = 0.5 * (good + bad);
        if (zh_radius_at(f, base, vary, mid) >= 1.0)
            bad = mid;
        else
            good = mid;
    }
    return 0.5 * (good + bad);
}

/* Response of T(z) = num z^(n - rel) / den(z) (den monic of degree n,
 * relative degree rel) to the input r[], by its difference equation. */
static inline void zh_filter(const double complex *den, int n, int rel, double complex num, const double complex *r,
                             double complex *y, int N)
{
    for (int k = 0; k < N; ++k) {
        double complex acc = (k - rel >= 0) ? num * r[k - rel] : 0.0;
        for (int m = 1; m <= n; ++m)
            if (k - m >= 0) acc -= den[m] / den[0] * y[k - m];
        y[k] = acc;
    }
}

/* Frequency response of the closed loop at f [Hz]. */
static inline double complex zh_freq_incremental(const zh_loop_t *lp, double f)
{
    double complex c[ZH_MAXDEG + 1];
    zh_poly_incremental(lp, c);
    const double complex z = cexp(ZH_IM * 2.0 * ZH_PI * f * ZH_TS);
    const double complex Q = (((c[0] * z + c[1]) * z + c[2]) * z + c[3]) * z + c[4];
    return zh_num_incremental(lp) * z * z / Q;
}
static inline double complex zh_freq_euler(const zh_loop_t *lp, double f)
{
    double complex c[ZH_MAXDEG + 1];
    zh_poly_euler(lp, c);
    const double complex z = cexp(ZH_IM * 2.0 * ZH_PI * f * ZH_TS);
    return zh_num_euler(lp) / ((c[0] * z + c[1]) * z + c[2]);
}

/* Step metrics of a sampled response y[k] to a step of height h applied at
 * k0 (final value r_end): overshoot in % of h, and settling = number of
 * periods after k0 from which |y - r_end| <= band * |h| for good. */
static inline void zh_step_metrics(const double *y, int N, int k0, double r_end, double h, double band,
                                   double *overshoot_pct, int *settle)
{
    double ymax = -1e300;
    for (int k = k0; k < N; ++k) {
        const double v = (h > 0 ? y[k] : -y[k]);
        if (v > ymax) ymax = v;
    }
    *overshoot_pct = 100.0 * (ymax - (h > 0 ? r_end : -r_end)) / fabs(h);
    int last_out = k0 - 1;
    for (int k = k0; k < N; ++k)
        if (fabs(y[k] - r_end) > band * fabs(h)) last_out = k;
    *settle = last_out + 1 - k0;
}

#endif
