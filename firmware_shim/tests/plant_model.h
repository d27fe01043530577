/* plant_model.h - small test-only PMSM plant (double precision).
 * Not a test executable (no test_ prefix); included by the tests.
 *
 * Timing (You 2019 Fig. 1): plant_advance(cmd_k) applies the command stored
 * at the previous call (cmd_{k-1}) over [k, k+1] and stores cmd_k, so the
 * command computed at sample k acts over [k+1, k+2] and first shows in i(k+2).
 *
 * Standstill (omega fixed at 0): exact discretisation per dq axis,
 *   i(k+1) = A i(k) + B v(k-1),  A = exp(-Ts R/L), B = (1-A)/R.
 * Rotating: RK4 with n_sub sub-steps of the rotor-frame model (You 2019
 * Eq. 1) with the voltage held constant in the STATOR frame. */
#ifndef PLANT_MODEL_H
#define PLANT_MODEL_H

#include <math.h>

#include "drive_core.h"

typedef struct {
  double R, Ld, Lq, psi, p, Ts;
  double J, b_visc, T_load;
  double id, iq, theta_m, omega_m;
  double v_al_pend, v_be_pend;   /* command waiting for its interval */
  int rotating;                  /* 0: exact standstill model */
  int free_speed;                /* 1: integrate mechanics, 0: omega fixed */
  int n_sub;
} plant_t;

static inline void plant_init_you2019(plant_t *pl) {
  pl->R = 1.4; pl->Ld = 4.46e-3; pl->Lq = 4.54e-3; pl->psi = 0.042;
  pl->p = 5.0; pl->Ts = 55e-6; pl->J = 3.0e-5; pl->b_visc = 0.0; pl->T_load = 0.0;
  pl->id = pl->iq = 0.0; pl->theta_m = 0.0; pl->omega_m = 0.0;
  pl->v_al_pend = pl->v_be_pend = 0.0;
  pl->rotating = 0; pl->free_speed = 0; pl->n_sub = 40;
}

static inline void plant_measure(const plant_t *pl, drive_meas_t *m) {
  const double th = pl->p * pl->theta_m;
  const double c = cos(th), s = sin(th);
  const double ial = pl->id * c - pl->iq * s;
  const double ibe = pl->id * s + pl->iq * c;
  m->i_a_A = (float)ial;
  m->i_b_A = (float)(-0.5 * ial + 0.5 * sqrt(3.0) * ibe);
  double tm = fmod(pl->theta_m, 2.0 * 3.14159265358979323846);
  if (tm < 0) tm += 2.0 * 3.14159265358979323846;
  m->theta_m_rad = (float)tm;
}

static inline void plant_deriv(const plant_t *pl, double th_m, double w_m,
                               double id, double iq, double *did, double *diq,
                               double *dw) {
  const double th = pl->p * th_m, we = pl->p * w_m;
  const double c = cos(th), s = sin(th);
  const double vd = pl->v_al_pend * c + pl->v_be_pend * s;
  const double vq = -pl->v_al_pend * s + pl->v_be_pend * c;
  *did = (vd - pl->R * id + we * pl->Lq * iq) / pl->Ld;
  *diq = (vq - pl->R * iq - we * pl->Ld * id - we * pl->psi) / pl->Lq;
  const double Te = 1.5 * pl->p * (pl->psi * iq + (pl->Ld - pl->Lq) * id * iq);
  *dw = pl->free_speed ? (Te - pl->T_load - pl->b_visc * w_m) / pl->J : 0.0;
}

static inline void plant_advance(plant_t *pl, const drive_cmd_t *cmd) {
  if (!pl->rotating) {
    const double th = pl->p * pl->theta_m;
    const double c = cos(th), s = sin(th);
    const double vd = pl->v_al_pend * c + pl->v_be_pend * s;
    const double vq = -pl->v_al_pend * s + pl->v_be_pend * c;
    const double Aq = exp(-pl->Ts * pl->R / pl->Lq), Bq = (1.0 - Aq) / pl->R;
    const double Ad = exp(-pl->Ts * pl->R / pl->Ld), Bd = (1.0 - Ad) / pl->R;
    pl->iq = Aq * pl->iq + Bq * vq;
    pl->id = Ad * pl->id + Bd * vd;
  } else {
    const double h = pl->Ts / pl->n_sub;
    for (int n = 0; n < pl->n_sub; ++n) {
      double k1d, k1q, k1w, k2d, k2q, k2w, k3d, k3q, k3w, k4d, k4q, k4w;
      const double t0 = pl->theta_m, w0 = pl->omega_m, d0 = pl->id, q0 = pl->iq;
      plant_deriv(pl, t0, w0, d0, q0, &k1d, &k1q, &k1w);
      plant_deriv(pl, t0 + 0.5 * h * w0, w0 + 0.5 * h * k1w, d0 + 0.5 * h * k1d,
                  q0 + 0.5 * h * k1q, &k2d, &k2q, &k2w);
      plant_deriv(pl, t0 + 0.5 * h * (w0 + 0.5 * h * k1w), w0 + 0.5 * h * k2w,
                  d0 + 0.5 * h * k2d, q0 + 0.5 * h * k2q, &k3d, &k3q, &k3w);
      plant_deriv(pl, t0 + h * (w0 + 0.5 * h * k2w), w0 + h * k3w, d0 + h * k3d,
                  q0 + h * k3q, &k4d, &k4q, &k4w);
      pl->id = d0 + h / 6.0 * (k1d + 2 * k2d + 2 * k3d + k4d);
      pl->iq = q0 + h / 6.0 * (k1q + 2 * k2q + 2 * k3q + k4q);
      pl->omega_m = w0 + h / 6.0 * (k1w + 2 * k2w + 2 * k3w + k4w);
      pl->theta_m = t0 + h * (w0 + pl->omega_m) * 0.5;
    }
  }
  pl->v_al_pend = (double)cmd->v_alpha_V;
  pl->v_be_pend = (double)cmd->v_beta_V;
}

#define CHECK(cond, ...)                                   \
  do {                                                     \
    if (!(cond)) {                                         \
      printf("FAIL %s:%d: ", __FILE__, __LINE__);          \
      printf(__VA_ARGS__);                                 \
      printf("\n");                                        \
      g_fail++;                                            \
    }                                                      \
  } while (0)

#endif
