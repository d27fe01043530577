/* yao2020_common.h - shared by the test_yao2020_*.c mains (not a test executable: no test_
 * prefix).  Double precision.
 *
 * The plant: the motor of tests/c/motor_model.h (motor_t: RK4, n_sub = 40 sub-steps per period,
 * w h <= 0.021 rad for the 1.33 kHz motor, local error ~1e-11 relative; the voltage held
 * constant in the STATOR frame over each period) with the Yao 2020 presets of
 * plant_rt/core/presets.c: "yao2020_low" (Table I: R 2.2 ohm, L 5.5 mH, psi 0.12 Wb ASSUMED
 * there) and "yao2020_high" (Table II: R 0.045 ohm, L 24 uH, psi 2.0e-3 Wb ASSUMED there),
 * T = 100 us (Table III), at an imposed speed: 133.3 Hz and 1.33 kHz electrical (the rated
 * frequencies of Tables I/II).  The SPMSM's equations do not contain the pole pairs at an
 * imposed electrical speed, so the motor runs in electrical coordinates (pole_pairs 1: angle
 * and speed are electrical), starting at the angle 0.3 rad; the angle is wrapped to 2 pi
 * after every period (yplant_advance).
 *
 * Timing: yplant_advance(cmd_k) applies the command stored at the previous call over [k, k+1]
 * and stores cmd_k, so the command computed from sample k acts over [k+1, k+2]. */
#ifndef YAO2020_COMMON_H
#define YAO2020_COMMON_H

#include <math.h>

#include "motor_model.h"

#define YP_PI 3.14159265358979323846

/* The preset's motor at the electrical frequency f_e_hz, in electrical coordinates. */
static inline void yplant_init(motor_t *pl, const char *preset, double f_e_hz)
{
    motor_params_t par = motor_params_preset(preset);
    par.pole_pairs = 1.0;
    motor_init(pl, &par);
    pl->omega_m_rad_s = 2.0 * YP_PI * f_e_hz;
    pl->theta_m_rad = 0.3;
}
/* presets.c yao2020_low, at the 133.3 Hz rated electrical frequency */
static inline void yplant_low(motor_t *pl) { yplant_init(pl, "yao2020_low", 133.3); }
/* presets.c yao2020_high, at 1.33 kHz */
static inline void yplant_high(motor_t *pl) { yplant_init(pl, "yao2020_high", 1330.0); }

static inline void yplant_advance(motor_t *pl, double v_al_new, double v_be_new)
{
    motor_advance(pl, v_al_new, v_be_new);
    pl->theta_m_rad = fmod(pl->theta_m_rad, 2.0 * YP_PI);
}

/* One closed-loop period of yao2020_dpcc against the plant. */
#ifdef YAO2020_DPCC_H
static inline void yloop_step(motor_t *pl, const yao2020_dpcc_config_t *cfg, yao2020_dpcc_state_t *st, double id_ref,
                              double iq_ref, yao2020_dpcc_cmd_t *cmd)
{
    yao2020_dpcc_step(cfg, st, (float)id_ref, (float)iq_ref, (float)pl->id_A, (float)pl->iq_A, (float)motor_omega_e(pl),
                      (float)motor_theta_e(pl), cmd);
    yplant_advance(pl, (double)cmd->v_alpha_V, (double)cmd->v_beta_V);
}
#endif

/* ------------- analytic helpers (double, complex as re/im pairs) -------- */
typedef struct {
    double re, im;
} ycx;
static inline ycx ycx_mk(double a, double b)
{
    ycx z = {a, b};
    return z;
}
static inline ycx ycx_mul(ycx a, ycx b) { return ycx_mk(a.re * b.re - a.im * b.im, a.re * b.im + a.im * b.re); }
static inline ycx ycx_div(ycx a, ycx b)
{
    const double n = b.re * b.re + b.im * b.im;
    return ycx_mk((a.re * b.re + a.im * b.im) / n, (a.im * b.re - a.re * b.im) / n);
}
static inline ycx ycx_sub(ycx a, ycx b) { return ycx_mk(a.re - b.re, a.im - b.im); }

/* x, y of Yao 2020 Eq. 6 in double */
static inline void yxy(double R, double L, double T, double *x, double *y)
{
    *x = exp(-R * T / L);
    *y = -expm1(-R * T / L) / R;
}
/* Discrete steady-state impedance Zd = (exp(j w T) - x) / y: from Yao 2020 Eq. 7 in
 * steady state, dv = H^-1 (I - G) di = Zd di (Yao 2020 Eq. 29). */
static inline ycx yZd(double R, double L, double w, double T)
{
    double x, y;
    yxy(R, L, T, &x, &y);
    return ycx_mk((cos(w * T) - x) / y, sin(w * T) / y);
}
/* Exact dM (derived from Yao 2020 Eq. 26-29):
 *   dM = did * (Z_hat / Zd_hat) * (Zd - Zd_hat),  Z_hat = R_hat + j w L_hat,
 * for a pure d-axis current step did (iq unchanged). */
static inline ycx ydM_exact(double R, double L, double Rh, double Lh, double w, double T, double did)
{
    const ycx Zh = ycx_mk(Rh, w * Lh);
    const ycx Zdh = yZd(Rh, Lh, w, T);
    const ycx Zd = yZd(R, L, w, T);
    ycx r = ycx_mul(ycx_div(Zh, Zdh), ycx_sub(Zd, Zdh));
    r.re *= did;
    r.im *= did;
    return r;
}

#endif
