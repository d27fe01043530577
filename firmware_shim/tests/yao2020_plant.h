/* yao2020_plant.h - test-only exact-enough SPMSM plant for the Yao 2020
 * tests (double precision).  Not a test executable (no test_ prefix).
 *
 * Rotor-frame SPMSM (Ld = Lq = L):
 *   L did/dt = vd - R id + w L iq
 *   L diq/dt = vq - R iq - w L id - w psi
 * with the voltage held constant in the STATOR frame over each period,
 * vd + j vq = exp(-j theta(t)) (v_alpha + j v_beta), theta(t) = theta_k + w t.
 * Integrated with RK4, n_sub sub-steps per period (default 40: w h <= 0.021
 * rad for the 1.33 kHz motor, local error ~1e-11 relative).
 *
 * Timing: yplant_advance(cmd_k) applies the command stored at the previous
 * call over [k, k+1] and stores cmd_k, so the command computed from sample k
 * acts over [k+1, k+2].
 *
 * Motor data transcribed from plant_rt/core/presets.c (fill_yao2020_low,
 * fill_yao2020_high): Table I R 2.2 ohm, L 5.5 mH, 4 pole pairs, psi 0.12 Wb
 * (ASSUMED there); Table II R 0.045 ohm, L 24 uH, 1 pole pair, psi 2.0e-3 Wb
 * (ASSUMED there); T = 100 us (Table III).  Speeds: 133.3 Hz and 1.33 kHz
 * electrical (rated frequencies of Tables I/II). */
#ifndef YAO2020_PLANT_H
#define YAO2020_PLANT_H

#include <math.h>

#define YP_PI 3.14159265358979323846

typedef struct {
  double R, L, psi, w, Ts;
  double id, iq, th;          /* state at the current sample */
  double val_pend, vbe_pend;  /* command waiting for its interval */
  int n_sub;
} yplant_t;

static inline void yplant_init(yplant_t *pl, double R, double L, double psi,
                               double f_e_hz) {
  pl->R = R; pl->L = L; pl->psi = psi;
  pl->w = 2.0 * YP_PI * f_e_hz; pl->Ts = 100e-6;
  pl->id = pl->iq = 0.0; pl->th = 0.3;
  pl->val_pend = pl->vbe_pend = 0.0;
  pl->n_sub = 40;
}
/* presets.c fill_yao2020_low, at the 133.3 Hz rated electrical frequency */
static inline void yplant_low(yplant_t *pl) { yplant_init(pl, 2.2, 5.5e-3, 0.12, 133.3); }
/* presets.c fill_yao2020_high, at 1.33 kHz */
static inline void yplant_high(yplant_t *pl) { yplant_init(pl, 0.045, 24e-6, 2.0e-3, 1330.0); }

static inline void yplant_deriv(const yplant_t *pl, double th, double id,
                                double iq, double *did, double *diq) {
  const double c = cos(th), s = sin(th);
  const double vd = pl->val_pend * c + pl->vbe_pend * s;
  const double vq = -pl->val_pend * s + pl->vbe_pend * c;
  *did = (vd - pl->R * id + pl->w * pl->L * iq) / pl->L;
  *diq = (vq - pl->R * iq - pl->w * pl->L * id - pl->w * pl->psi) / pl->L;
}

static inline void yplant_advance(yplant_t *pl, double v_al_new, double v_be_new) {
  const double h = pl->Ts / pl->n_sub;
  for (int n = 0; n < pl->n_sub; ++n) {
    const double t0 = pl->th, d0 = pl->id, q0 = pl->iq;
    double k1d, k1q, k2d, k2q, k3d, k3q, k4d, k4q;
    yplant_deriv(pl, t0, d0, q0, &k1d, &k1q);
    yplant_deriv(pl, t0 + 0.5 * h * pl->w, d0 + 0.5 * h * k1d, q0 + 0.5 * h * k1q, &k2d, &k2q);
    yplant_deriv(pl, t0 + 0.5 * h * pl->w, d0 + 0.5 * h * k2d, q0 + 0.5 * h * k2q, &k3d, &k3q);
    yplant_deriv(pl, t0 + h * pl->w, d0 + h * k3d, q0 + h * k3q, &k4d, &k4q);
    pl->id = d0 + h / 6.0 * (k1d + 2 * k2d + 2 * k3d + k4d);
    pl->iq = q0 + h / 6.0 * (k1q + 2 * k2q + 2 * k3q + k4q);
    pl->th = t0 + h * pl->w;
  }
  pl->th = fmod(pl->th, 2.0 * YP_PI);
  pl->val_pend = v_al_new;
  pl->vbe_pend = v_be_new;
}

/* One closed-loop period of yao2020_dpcc against the plant. */
#ifdef YAO2020_DPCC_H
static inline void yloop_step(yplant_t *pl, const yao2020_dpcc_config_t *cfg,
                              yao2020_dpcc_state_t *st, double id_ref, double iq_ref,
                              yao2020_dpcc_cmd_t *cmd) {
  yao2020_dpcc_step(cfg, st, (float)id_ref, (float)iq_ref, (float)pl->id,
                    (float)pl->iq, (float)pl->w, (float)pl->th, cmd);
  yplant_advance(pl, (double)cmd->v_alpha_V, (double)cmd->v_beta_V);
}
#endif

/* ------------- analytic helpers (double, complex as re/im pairs) -------- */
typedef struct { double re, im; } ycx;
static inline ycx ycx_mk(double a, double b) { ycx z = {a, b}; return z; }
static inline ycx ycx_mul(ycx a, ycx b) { return ycx_mk(a.re * b.re - a.im * b.im, a.re * b.im + a.im * b.re); }
static inline ycx ycx_div(ycx a, ycx b) {
  const double n = b.re * b.re + b.im * b.im;
  return ycx_mk((a.re * b.re + a.im * b.im) / n, (a.im * b.re - a.re * b.im) / n);
}
static inline ycx ycx_sub(ycx a, ycx b) { return ycx_mk(a.re - b.re, a.im - b.im); }

/* x, y of Yao 2020 Eq. 6 in double */
static inline void yxy(double R, double L, double T, double *x, double *y) {
  *x = exp(-R * T / L);
  *y = -expm1(-R * T / L) / R;
}
/* Discrete steady-state impedance Zd = (exp(j w T) - x) / y: from Yao 2020 Eq. 7 in
 * steady state, dv = H^-1 (I - G) di = Zd di (Yao 2020 Eq. 29). */
static inline ycx yZd(double R, double L, double w, double T) {
  double x, y;
  yxy(R, L, T, &x, &y);
  return ycx_mk((cos(w * T) - x) / y, sin(w * T) / y);
}
/* Exact dM (derived from Yao 2020 Eq. 26-29):
 *   dM = did * (Z_hat / Zd_hat) * (Zd - Zd_hat),  Z_hat = R_hat + j w L_hat,
 * for a pure d-axis current step did (iq unchanged). */
static inline ycx ydM_exact(double R, double L, double Rh, double Lh, double w,
                            double T, double did) {
  const ycx Zh = ycx_mk(Rh, w * Lh);
  const ycx Zdh = yZd(Rh, Lh, w, T);
  const ycx Zd = yZd(R, L, w, T);
  ycx r = ycx_mul(ycx_div(Zh, Zdh), ycx_sub(Zd, Zdh));
  r.re *= did;
  r.im *= did;
  return r;
}

#endif
