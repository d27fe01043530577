/* yao2020_dpcc.c - Yao 2020 improved DPCC: fully discretised model
 * (Eq. 4-7), deadbeat law (Eq. 12), sliding-mode disturbance observer
 * (Eq. 13-18), R/L identification from the reconstructed characteristic
 * vector (Eq. 22-45).  See yao2020_dpcc.h for timing, frames and units.
 *
 * Complex notation used in the comments: a dq (or alpha-beta) 2-vector
 * [a b] is the complex number a + j b.  Then Tr = exp(-j w T), Tr^-1 =
 * exp(+j w T), G1 = x, H1 = y, G2 = d1 + j d2, G = x Tr, H = y Tr,
 * F = Tr G2. */
#include "yao2020_dpcc.h"

#include <math.h>
#include <string.h>

void yao_dpcc_default_config(yao_dpcc_config_t *cfg) {
  memset(cfg, 0, sizeof(*cfg));
  cfg->Ts_s = 100e-6f;
  cfg->R_hat_ohm = 2.2f;
  cfg->L_hat_H = 5.5e-3f;
  cfg->psi_hat_Wb = 0.12f;
  cfg->Vmax_V = 0.0f;
  cfg->observer_enable = 1u;
  cfg->Q_d = 0.4f;
  cfg->Q_q = 0.4f;
  cfg->inj_id_A = -2.0f;
  cfg->gain_select = (uint8_t)YAO_GAINS_AUTO;
  cfg->kL_low_H_Vs = 0.005f;
  cfg->kR_low_ohm_Vs = 4.0f;
  cfg->kL_high_H_Vs = 2e-5f;
  cfg->kR_high_ohm_Vs = 0.04f;
  cfg->th_L_V = 0.1f;
  cfg->th_R_V = 0.03f;
  cfg->n_settle = 200u;
  cfg->n_avg = 50u;
  cfg->n_hold = 200u;
  cfg->n_timeout = 300000u;
  cfg->n_rounds = 1u;
  cfg->rereference = 1u;
  cfg->steady_tol_w_rad_s = 5.0f;
  cfg->steady_tol_iq_A = 0.05f;
  cfg->min_speed_rad_s = 50.0f;
  cfg->R_min_ohm = 1e-4f;
  cfg->R_max_ohm = 1e3f;
  cfg->L_min_H = 1e-7f;
  cfg->L_max_H = 1.0f;
}

void yao_dpcc_reset(const yao_dpcc_config_t *cfg, yao_dpcc_state_t *st) {
  memset(st, 0, sizeof(*st));
  st->R_hat_ohm = cfg->R_hat_ohm;
  st->L_hat_H = cfg->L_hat_H;
  st->id_state = (uint8_t)YAO_ID_IDLE;
  st->L_id_H = cfg->L_hat_H;
  st->R_id_ohm = cfg->R_hat_ohm;
}

void yao_dpcc_init(const yao_dpcc_config_t *cfg, yao_dpcc_state_t *st) {
  yao_dpcc_reset(cfg, st);
}

/* Yao 2020 Eq. 5-6 (ZOH of the augmented alpha-beta model Eq. 3):
 *   x  = exp(-R T / L),  y = (1 - x) / R
 *   d1 = ((x - cos wT) R - sin wT  w L) / (R^2 + w^2 L^2)
 *   d2 = -((x - cos wT) w L + sin wT R) / (R^2 + w^2 L^2)
 * i.e. G2 = d1 + j d2 = (x - exp(j w T)) / (R + j w L)   (derived: the
 * integral -1/L int_0^T exp(-R/L (T - t)) exp(j w t) dt; it reproduces
 * Eq. 6 exactly).  y uses expm1f so that it stays accurate for small R T/L,
 * and tends to T/L for R -> 0. */
void yao_dpcc_model(float R_ohm, float L_H, float w_rad_s, float Ts_s,
                    yao_dpcc_model_t *m) {
  const float a = Ts_s * R_ohm / L_H;
  const float one_minus_x = -expm1f(-a);
  m->x = 1.0f - one_minus_x;
  m->y = (R_ohm > 1e-9f) ? one_minus_x / R_ohm : Ts_s / L_H;
  const float wT = w_rad_s * Ts_s;
  m->c = cosf(wT);
  m->s = sinf(wT);
  const float wL = w_rad_s * L_H;
  const float den = R_ohm * R_ohm + wL * wL;
  const float xc = m->x - m->c;
  if (den > 0.0f) {
    const float inv = 1.0f / den;
    m->d1 = (xc * R_ohm - m->s * wL) * inv;
    m->d2 = -(xc * wL + m->s * R_ohm) * inv;
  } else {
    m->d1 = -m->y; /* R = w = 0 limit: G2 = -T/L */
    m->d2 = 0.0f;
  }
}

/* Yao 2020 Definition 1 (Eq. 30) and Definition 2 (Eq. 31). */
yao_motor_class_t yao_dpcc_classify(float R_ohm, float L_H, float w_rad_s,
                                    float Ts_s) {
  const float cwT = cosf(w_rad_s * Ts_s);
  const float a = R_ohm * Ts_s / L_H;
  if (cwT >= 0.98f && fabsf(expf(-a) - (1.0f - a)) < 0.05f) {
    return YAO_MOTOR_LOW_FREQ;
  }
  if (cwT < 0.98f && R_ohm < 0.2f * fabsf(w_rad_s) * L_H) {
    return YAO_MOTOR_HIGH_FREQ;
  }
  return YAO_MOTOR_NEITHER;
}

/* Tr [a b] = exp(-j w T)(a + j b) */
static inline void rot_fwd(const yao_dpcc_model_t *m, float a, float b,
                           float *oa, float *ob) {
  *oa = m->c * a + m->s * b;
  *ob = -m->s * a + m->c * b;
}
/* Tr^-1 [a b] = exp(+j w T)(a + j b) */
static inline void rot_inv(const yao_dpcc_model_t *m, float a, float b,
                           float *oa, float *ob) {
  *oa = m->c * a - m->s * b;
  *ob = m->s * a + m->c * b;
}
/* G2^-1 [a b] = (a + j b) / (d1 + j d2) */
static inline void g2_solve(const yao_dpcc_model_t *m, float a, float b,
                            float *oa, float *ob) {
  const float n2 = m->d1 * m->d1 + m->d2 * m->d2;
  const float inv = n2 > 0.0f ? 1.0f / n2 : 0.0f;
  *oa = (m->d1 * a + m->d2 * b) * inv;
  *ob = (m->d1 * b - m->d2 * a) * inv;
}

static float clampf(float v, float lo, float hi) {
  if (v < lo) return lo;
  if (v > hi) return hi;
  return v;
}

/* ---------------------------------------------------------------- ident */

static uint32_t ident_total_phases(const yao_dpcc_config_t *cfg) {
  const uint32_t r = cfg->n_rounds > 0u ? cfg->n_rounds : 1u;
  return 4u * r + 1u;
}

bool yao_dpcc_ident_running(const yao_dpcc_state_t *st) {
  return st->id_state != (uint8_t)YAO_ID_IDLE &&
         st->id_state != (uint8_t)YAO_ID_DONE &&
         st->id_state != (uint8_t)YAO_ID_ABORTED;
}

bool yao_dpcc_ident_start(const yao_dpcc_config_t *cfg, yao_dpcc_state_t *st) {
  if (yao_dpcc_ident_running(st) || st->primed == 0u) {
    return false;
  }
  st->id_state = (uint8_t)YAO_ID_PRE_L;
  st->abort_reason = (uint8_t)YAO_ABORT_NONE;
  st->round = 0u;
  st->phase_count = 0u;
  st->hold_count = 0u;
  st->phases_done = 0u;
  st->L_converged = 0u;
  st->R_converged = 0u;
  st->t_L_conv_periods = 0u;
  st->t_R_conv_periods = 0u;
  st->id_inj_A = 0.0f;
  st->R_start_ohm = st->R_hat_ohm;
  st->L_start_H = st->L_hat_H;
  /* w_start / iq_ref_start are latched from the last step */
  st->w_start_rad_s = st->w_rad_s;
  st->iq_ref_start_A = st->iq_ref_A;
  memset(st->acc, 0, sizeof(st->acc));
  /* Eq. 30-31 with the controller's (estimated) parameters */
  st->motor_class = (uint8_t)yao_dpcc_classify(st->R_hat_ohm, st->L_hat_H,
                                               st->w_start_rad_s, cfg->Ts_s);
  if (cfg->gain_select == (uint8_t)YAO_GAINS_LOW) {
    st->gains_high = 0u;
  } else if (cfg->gain_select == (uint8_t)YAO_GAINS_HIGH) {
    st->gains_high = 1u;
  } else {
    /* AUTO: the cos(wT) test common to Eq. 30 and Eq. 31 selects the
     * simplification.  (The Table II motor misses the second condition of
     * Eq. 31, R < 0.2 w L: 0.045 vs 0.040 ohm, yet the paper treats it as
     * high-frequency; motor_class still reports NEITHER in that case.) */
    st->gains_high = cosf(st->w_start_rad_s * cfg->Ts_s) < 0.98f ? 1u : 0u;
  }
  st->kL_H_Vs = st->gains_high ? cfg->kL_high_H_Vs : cfg->kL_low_H_Vs;
  st->kR_ohm_Vs = st->gains_high ? cfg->kR_high_ohm_Vs : cfg->kR_low_ohm_Vs;
  /* Eq. 44: closed-loop rate k_{L,R} k with the positive plant gain k
   * (dM per unit parameter error) from the chosen simplification:
   *   low  (Eq. 35/36 divided by |d_hat|^2 = (T/L)^2, Eq. 27):
   *        dM_q = w (L - L_hat) did,   dM_d = (R - R_hat) did
   *   high (Eq. 42/43 divided by |d_hat|^2 = (s^2 + (c - x)^2)/(w L)^2,
   *        Eq. 37, and exp(-R_hat T/L) - exp(-R T/L) ~ -x T/L (R_hat - R)):
   *        dM_q = w T/(y L) (L - L_hat) did
   *        dM_d = s w T x/(s^2 + (c - x)^2) (R - R_hat) did */
  {
    yao_dpcc_model_t m0;
    yao_dpcc_model(st->R_hat_ohm, st->L_hat_H, st->w_start_rad_s, cfg->Ts_s, &m0);
    const float ai = fabsf(cfg->inj_id_A);
    const float aw = fabsf(st->w_start_rad_s);
    float kq, kd;
    if (st->gains_high) {
      const float wT = aw * cfg->Ts_s;
      const float cx = m0.c - m0.x;
      kq = aw * ai * cfg->Ts_s / (m0.y * st->L_hat_H);
      kd = ai * fabsf(m0.s) * wT * m0.x / (m0.s * m0.s + cx * cx);
    } else {
      kq = aw * ai;
      kd = ai;
    }
    st->tau_L_pred_s = (kq * st->kL_H_Vs > 0.0f) ? 1.0f / (kq * st->kL_H_Vs) : 0.0f;
    st->tau_R_pred_s = (kd * st->kR_ohm_Vs > 0.0f) ? 1.0f / (kd * st->kR_ohm_Vs) : 0.0f;
  }
  return true;
}

static void ident_abort(yao_dpcc_state_t *st, yao_abort_reason_t why) {
  st->id_state = (uint8_t)YAO_ID_ABORTED;
  st->abort_reason = (uint8_t)why;
  st->id_inj_A = 0.0f;
  st->R_hat_ohm = st->R_start_ohm;
  st->L_hat_H = st->L_start_H;
}

void yao_dpcc_ident_abort(yao_dpcc_state_t *st) {
  if (yao_dpcc_ident_running(st)) {
    ident_abort(st, YAO_ABORT_USER);
  }
}

float yao_dpcc_ident_progress(const yao_dpcc_config_t *cfg,
                              const yao_dpcc_state_t *st) {
  if (st->id_state == (uint8_t)YAO_ID_DONE) return 1.0f;
  return (float)st->phases_done / (float)ident_total_phases(cfg);
}

bool yao_dpcc_ident_result(const yao_dpcc_state_t *st, float *R_ohm, float *L_H) {
  *R_ohm = st->R_id_ohm;
  *L_H = st->L_id_H;
  return st->id_state == (uint8_t)YAO_ID_DONE;
}

static void next_phase(yao_dpcc_state_t *st, yao_id_state_t s) {
  st->id_state = (uint8_t)s;
  st->phase_count = 0u;
  st->hold_count = 0u;
  st->phases_done++;
  memset(st->acc, 0, sizeof(st->acc));
}

void yao_dpcc_ident_update(const yao_dpcc_config_t *cfg, yao_dpcc_state_t *st,
                           float id_A, float iq_A, float w_rad_s,
                           float iq_ref_A) {
  if (!yao_dpcc_ident_running(st)) {
    st->id_inj_A = 0.0f;
    return;
  }
  /* Sec. III: identification only in steady state (w and iq unchanged) */
  if (fabsf(w_rad_s - st->w_start_rad_s) > cfg->steady_tol_w_rad_s) {
    ident_abort(st, YAO_ABORT_SPEED_CHANGED);
    return;
  }
  if (fabsf(iq_ref_A - st->iq_ref_start_A) > cfg->steady_tol_iq_A) {
    ident_abort(st, YAO_ABORT_IQ_CHANGED);
    return;
  }
  if (fabsf(w_rad_s) < cfg->min_speed_rad_s) {
    ident_abort(st, YAO_ABORT_LOW_SPEED);
    return;
  }
  const yao_dpcc_model_t *m = &st->m;
  /* Tr^-1 p_hat(k); M(k) = F^-1 p_hat = G2^-1 Tr^-1 p_hat (Eq. 22) */
  float tp_d, tp_q;
  rot_inv(m, st->p_hat_d_A, st->p_hat_q_A, &tp_d, &tp_q);
  st->phase_count++;
  const yao_id_state_t s = (yao_id_state_t)st->id_state;
  switch (s) {
    case YAO_ID_PRE_L:
    case YAO_ID_PRE_R: {
      st->id_inj_A = 0.0f;
      const uint32_t navg = cfg->n_avg > 0u ? cfg->n_avg : 1u;
      const uint32_t nset = cfg->n_settle > navg ? cfg->n_settle : navg;
      if (st->phase_count + navg > nset) {
        /* Eq. 24: M(t0).  Stored as the estimate-independent
         *   N = Tr^-1 p_hat + x_hat i + y_hat v   (= Tr^-1 i(k+1), Eq. 7-8)
         * together with i(t0), v(t0), so that M(t0) can be re-evaluated with
         * the current R_hat/L_hat (see the INJECT phase). */
        st->acc[0] += tp_d + m->x * id_A + m->y * st->v_app_d_V;
        st->acc[1] += tp_q + m->x * iq_A + m->y * st->v_app_q_V;
        st->acc[2] += id_A;
        st->acc[3] += iq_A;
        st->acc[4] += st->v_app_d_V;
        st->acc[5] += st->v_app_q_V;
        st->acc[6] += st->M_d_V;
        st->acc[7] += st->M_q_V;
      }
      if (st->phase_count >= nset) {
        const float inv = 1.0f / (float)navg;
        st->N0_d = st->acc[0] * inv;
        st->N0_q = st->acc[1] * inv;
        st->i0_d = st->acc[2] * inv;
        st->i0_q = st->acc[3] * inv;
        st->v0_d = st->acc[4] * inv;
        st->v0_q = st->acc[5] * inv;
        st->M0_d = st->acc[6] * inv;
        st->M0_q = st->acc[7] * inv;
        next_phase(st, s == YAO_ID_PRE_L ? YAO_ID_INJECT_L : YAO_ID_INJECT_R);
        st->id_inj_A = cfg->inj_id_A; /* negative step into the d axis */
      }
      break;
    }
    case YAO_ID_INJECT_L:
    case YAO_ID_INJECT_R: {
      st->id_inj_A = cfg->inj_id_A;
      if (st->phase_count <= cfg->n_settle) {
        break; /* Sec. IV-E: wait for the observer/current transient */
      }
      /* Eq. 26: dM = M(k) - M(t0).
       * rereference = 1 (derived): M(t0) re-evaluated with the current
       *   estimates, M0 = G2^-1 (N0 - x i0 - y v0); Eq. 22 shows M depends
       *   on R_hat/L_hat through G2_hat, x_hat, y_hat, so a stale M(t0) would
       *   make the integrator converge where M(t1; L_hat) = M(t0; L_start).
       * rereference = 0: literal reading, stale M(t0). */
      if (cfg->rereference != 0u) {
        const float ad = tp_d - (st->N0_d - m->x * st->i0_d - m->y * st->v0_d);
        const float aq = tp_q - (st->N0_q - m->x * st->i0_q - m->y * st->v0_q);
        g2_solve(m, ad, aq, &st->dM_d_V, &st->dM_q_V);
      } else {
        st->dM_d_V = st->M_d_V - st->M0_d;
        st->dM_q_V = st->M_q_V - st->M0_q;
      }
      const float sgn_i = cfg->inj_id_A < 0.0f ? -1.0f : 1.0f;
      const float T = cfg->Ts_s;
      bool inside;
      if (s == YAO_ID_INJECT_L) {
        /* Fig. 9(a), Eq. 36/42/44: dM_q ~ k' w (L - L_hat) did; integral
         * estimator driving dM_q to 0, dead zone TH_L. */
        inside = fabsf(st->dM_q_V) <= cfg->th_L_V;
        if (!inside) {
          const float sgn = (w_rad_s < 0.0f) ? -sgn_i : sgn_i;
          st->L_hat_H = clampf(st->L_hat_H + sgn * st->kL_H_Vs * T * st->dM_q_V,
                               cfg->L_min_H, cfg->L_max_H);
        }
      } else {
        /* Fig. 9(b), Eq. 35/43/44: dM_d ~ k' (R - R_hat) did, dead zone TH_R */
        inside = fabsf(st->dM_d_V) <= cfg->th_R_V;
        if (!inside) {
          st->R_hat_ohm = clampf(st->R_hat_ohm + sgn_i * st->kR_ohm_Vs * T * st->dM_d_V,
                                 cfg->R_min_ohm, cfg->R_max_ohm);
        }
      }
      st->hold_count = inside ? st->hold_count + 1u : 0u;
      const uint32_t n_int = st->phase_count - cfg->n_settle;
      const bool conv = st->hold_count >= (cfg->n_hold > 0u ? cfg->n_hold : 1u);
      if (conv || n_int >= cfg->n_timeout) {
        const uint32_t t_conv = conv ? n_int - st->hold_count : n_int;
        if (s == YAO_ID_INJECT_L) {
          st->L_converged = conv ? 1u : 0u;
          st->t_L_conv_periods = t_conv;
          st->L_id_H = st->L_hat_H;
          next_phase(st, YAO_ID_PRE_R);
        } else {
          st->R_converged = conv ? 1u : 0u;
          st->t_R_conv_periods = t_conv;
          st->R_id_ohm = st->R_hat_ohm;
          const uint8_t nr = cfg->n_rounds > 0u ? cfg->n_rounds : 1u;
          st->round++;
          next_phase(st, st->round < nr ? YAO_ID_PRE_L : YAO_ID_POST);
        }
        st->id_inj_A = 0.0f;
      }
      break;
    }
    case YAO_ID_POST:
      st->id_inj_A = 0.0f;
      if (st->phase_count >= cfg->n_settle) {
        next_phase(st, YAO_ID_DONE);
        st->L_id_H = st->L_hat_H;
        st->R_id_ohm = st->R_hat_ohm;
      }
      break;
    default:
      break;
  }
}

/* ----------------------------------------------------------------- step */

void yao_dpcc_step(const yao_dpcc_config_t *cfg, yao_dpcc_state_t *st,
                   float id_A, float iq_A, float w_rad_s, float theta_e_rad,
                   float id_ref_A, float iq_ref_A, yao_dpcc_cmd_t *cmd) {
  yao_dpcc_model_t *m = &st->m;
  /* Eq. 5-7 with the current estimates R_hat, L_hat and w(k) */
  yao_dpcc_model(st->R_hat_ohm, st->L_hat_H, w_rad_s, cfg->Ts_s, m);

  /* v(k): voltage acting over [k, k+1], frame theta(k): v(k) = v*(k-1) (Eq. 9) */
  st->v_app_d_V = st->v_star_d_V;
  st->v_app_q_V = st->v_star_q_V;

  /* back-EMF term F e_dq(psi_hat), e_dq = [0, w psi_hat] (Eq. 7):
   * F e = Tr G2 [0, w psi] */
  float fe_d, fe_q;
  {
    const float e = w_rad_s * cfg->psi_hat_Wb;
    rot_fwd(m, -m->d2 * e, m->d1 * e, &fe_d, &fe_q);
  }

  if (st->primed == 0u) {
    /* bumpless start: p_hat(0) = F e(psi_hat), i_tilde = 0 */
    st->p_hat_d_A = fe_d;
    st->p_hat_q_A = fe_q;
    st->p_prev_d_A = fe_d;
    st->p_prev_q_A = fe_q;
    st->i_err_d_A = 0.0f;
    st->i_err_q_A = 0.0f;
    st->i_pred_d_A = id_A;
    st->i_pred_q_A = iq_A;
    st->r_prev_d_A = id_ref_A;
    st->r_prev_q_A = iq_ref_A;
  } else if (cfg->observer_enable != 0u) {
    /* Eq. 14-15: i_tilde(k) = i_hat(k) - i(k) */
    const float e1d = st->i_err_d_A, e1q = st->i_err_q_A; /* i_tilde(k-1) */
    const float ekd = st->i_pred_d_A - id_A;
    const float ekq = st->i_pred_q_A - iq_A;
    /* Eq. 18: p(k-1) = G(k-1) i_tilde(k-1) + p_hat(k-1) - i_tilde(k) */
    const float gd = st->Gp_x * (st->Gp_c * e1d + st->Gp_s * e1q);
    const float gq = st->Gp_x * (-st->Gp_s * e1d + st->Gp_c * e1q);
    st->p_prev_d_A = gd + st->p_hat_d_A - ekd;
    st->p_prev_q_A = gq + st->p_hat_q_A - ekq;
    /* Eq. 17: p_hat(k) = C^-1 Q s(k) - G i_tilde(k) + p(k-1); with C and Q
     * diagonal C^-1 Q C = Q, so C drops out: p_hat = (Q - G) i_tilde + p(k-1).
     * Reading: Eq. 17 and Eq. 19 correspond to the reaching law
     *   s(k+1) = Q s(k) + C (p(k-1) - p(k));
     * Eq. 16 as extracted has the opposite sign of the last term, which would
     * give p_hat = ... + 2 p(k) - p(k-1) instead.  Observer error dynamics
     * (derived, tested): i_tilde(k+1) = Q i_tilde(k) + p(k-1) - p(k). */
    float Gd, Gq;
    rot_fwd(m, ekd, ekq, &Gd, &Gq);
    st->p_hat_d_A = cfg->Q_d * ekd - m->x * Gd + st->p_prev_d_A;
    st->p_hat_q_A = cfg->Q_q * ekq - m->x * Gq + st->p_prev_q_A;
    st->i_err_d_A = ekd;
    st->i_err_q_A = ekq;
  } else {
    /* observer off: conventional DPCC disturbance p = F e(psi_hat) */
    st->p_hat_d_A = fe_d;
    st->p_hat_q_A = fe_q;
    st->i_err_d_A = st->i_pred_d_A - id_A;
    st->i_err_q_A = st->i_pred_q_A - iq_A;
  }

  /* Eq. 22: M(k) = F_hat^-1 p_hat(k) = G2_hat^-1 Tr^-1 p_hat(k) (trace) */
  {
    float a, b;
    rot_inv(m, st->p_hat_d_A, st->p_hat_q_A, &a, &b);
    g2_solve(m, a, b, &st->M_d_V, &st->M_q_V);
  }

  /* identification (may change the injection now and R_hat/L_hat for the
   * next step) */
  if (st->primed != 0u) {
    yao_dpcc_ident_update(cfg, st, id_A, iq_A, w_rad_s, iq_ref_A);
  }

  /* Eq. 12: v*(k) = H^-1 (i_ref(k+2) - G i_ref(k+1) - p_hat(k))
   *              = (1/y) (Tr^-1 (i_ref(k+2) - p_hat(k)) - x i_ref(k+1)) */
  const float r2d = id_ref_A + st->id_inj_A;
  const float r2q = iq_ref_A;
  float vd, vq;
  {
    float a, b;
    rot_inv(m, r2d - st->p_hat_d_A, r2q - st->p_hat_q_A, &a, &b);
    const float iy = 1.0f / m->y;
    vd = (a - m->x * st->r_prev_d_A) * iy;
    vq = (b - m->x * st->r_prev_q_A) * iy;
  }
  uint8_t limited = 0u;
  if (cfg->Vmax_V > 0.0f) {
    const float mag2 = vd * vd + vq * vq;
    if (mag2 > cfg->Vmax_V * cfg->Vmax_V) {
      const float sc = cfg->Vmax_V / sqrtf(mag2);
      vd *= sc;
      vq *= sc;
      limited = 1u;
    }
  }

  /* Eq. 13: i_hat(k+1) = G i_hat(k) + H v(k) + p_hat(k) */
  {
    float a, b, c2, d2;
    rot_fwd(m, st->i_pred_d_A, st->i_pred_q_A, &a, &b);
    rot_fwd(m, st->v_app_d_V, st->v_app_q_V, &c2, &d2);
    st->i_pred_d_A = m->x * a + m->y * c2 + st->p_hat_d_A;
    st->i_pred_q_A = m->x * b + m->y * d2 + st->p_hat_q_A;
  }
  st->Gp_x = m->x;
  st->Gp_c = m->c;
  st->Gp_s = m->s;

  st->v_star_d_V = vd;
  st->v_star_q_V = vq;
  st->r_prev_d_A = r2d;
  st->r_prev_q_A = r2q;
  st->w_rad_s = w_rad_s;
  st->iq_ref_A = iq_ref_A;
  st->primed = 1u;
  st->step_count++;

  /* Eq. 9: v_ref(k) = Tr^-1 v*(k) in the frame of theta(k); stator frame =
   * exp(j theta(k)) v_ref(k) = exp(j (theta(k) + w T)) v*(k) */
  float rd, rq;
  rot_inv(m, vd, vq, &rd, &rq);
  const float ct = cosf(theta_e_rad), sn = sinf(theta_e_rad);
  cmd->v_star_d_V = vd;
  cmd->v_star_q_V = vq;
  cmd->v_ref_d_V = rd;
  cmd->v_ref_q_V = rq;
  cmd->v_alpha_V = rd * ct - rq * sn;
  cmd->v_beta_V = rd * sn + rq * ct;
  cmd->id_ref_eff_A = r2d;
  cmd->limited = limited;
}
