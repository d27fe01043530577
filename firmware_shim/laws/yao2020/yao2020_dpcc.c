/* yao2020_dpcc.c - Yao 2020 improved DPCC: deadbeat law (Eq. 12) on the
 * fully discretised model (Eq. 4-7, yao2020_model.c), sliding-mode
 * disturbance observer (Eq. 13-18); the R/L identification (Eq. 22-45) it
 * runs every period is in yao2020_identification.c.  See yao2020_dpcc.h
 * for timing, frames and units.
 *
 * Complex notation used in the comments: a dq (or alpha-beta) 2-vector
 * [a b] is the complex number a + j b.  Then Tr = exp(-j w T), Tr^-1 =
 * exp(+j w T), G1 = x, H1 = y, G2 = d1 + j d2, G = x Tr, H = y Tr,
 * F = Tr G2. */
#include "yao2020_dpcc.h"

#include <math.h>
#include <string.h>

#include "dq_math.h"

#include "yao2020_identification.h"

void yao2020_dpcc_default_config(yao2020_dpcc_config_t *cfg)
{
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
    cfg->gain_select = (uint8_t)YAO2020_IDENTIFICATION_GAINS_AUTO;
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

void yao2020_dpcc_reset(const yao2020_dpcc_config_t *cfg, yao2020_dpcc_state_t *st)
{
    memset(st, 0, sizeof(*st));
    st->R_hat_ohm = cfg->R_hat_ohm;
    st->L_hat_H = cfg->L_hat_H;
    st->id_state = (uint8_t)YAO2020_IDENTIFICATION_IDLE;
    st->L_id_H = cfg->L_hat_H;
    st->R_id_ohm = cfg->R_hat_ohm;
}

void yao2020_dpcc_init(const yao2020_dpcc_config_t *cfg, yao2020_dpcc_state_t *st) { yao2020_dpcc_reset(cfg, st); }

/* ----------------------------------------------------------------- step */

void yao2020_dpcc_step(const yao2020_dpcc_config_t *cfg, yao2020_dpcc_state_t *st, float id_ref_A, float iq_ref_A,
                       float id_A, float iq_A, float w_rad_s, float theta_e_rad, yao2020_dpcc_cmd_t *cmd)
{
    yao2020_model_t *m = &st->m;
    /* Yao 2020 Eq. 5-7 with the current estimates R_hat, L_hat and w(k) */
    yao2020_model_compute(st->R_hat_ohm, st->L_hat_H, w_rad_s, cfg->Ts_s, m);

    /* v(k): voltage acting over [k, k+1], frame theta(k): v(k) = v*(k-1)
     * (Yao 2020 Eq. 9) */
    st->v_app_d_V = st->v_star_d_V;
    st->v_app_q_V = st->v_star_q_V;

    /* back-EMF term F e_dq(psi_hat), e_dq = [0, w psi_hat] (Yao 2020 Eq. 7):
     * F e = Tr G2 [0, w psi] */
    float fe_d, fe_q;
    {
        const float e = w_rad_s * cfg->psi_hat_Wb;
        yao2020_model_rot_fwd(m, -m->d2 * e, m->d1 * e, &fe_d, &fe_q);
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
        /* Yao 2020 Eq. 14-15: i_tilde(k) = i_hat(k) - i(k) */
        const float e1d = st->i_err_d_A, e1q = st->i_err_q_A; /* i_tilde(k-1) */
        const float ekd = st->i_pred_d_A - id_A;
        const float ekq = st->i_pred_q_A - iq_A;
        /* Yao 2020 Eq. 18: p(k-1) = G(k-1) i_tilde(k-1) + p_hat(k-1) - i_tilde(k) */
        const float gd = st->Gp_x * (st->Gp_c * e1d + st->Gp_s * e1q);
        const float gq = st->Gp_x * (-st->Gp_s * e1d + st->Gp_c * e1q);
        st->p_prev_d_A = gd + st->p_hat_d_A - ekd;
        st->p_prev_q_A = gq + st->p_hat_q_A - ekq;
        /* Yao 2020 Eq. 17: p_hat(k) = C^-1 Q s(k) - G i_tilde(k) + p(k-1); with C and Q
         * diagonal C^-1 Q C = Q, so C drops out: p_hat = (Q - G) i_tilde + p(k-1).
         * Reading: Eq. 17 and Eq. 19 correspond to the reaching law
         *   s(k+1) = Q s(k) + C (p(k-1) - p(k));
         * Eq. 16 as extracted has the opposite sign of the last term, which would
         * give p_hat = ... + 2 p(k) - p(k-1) instead.  Observer error dynamics
         * (derived, tested): i_tilde(k+1) = Q i_tilde(k) + p(k-1) - p(k). */
        float Gd, Gq;
        yao2020_model_rot_fwd(m, ekd, ekq, &Gd, &Gq);
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

    /* Yao 2020 Eq. 22: M(k) = F_hat^-1 p_hat(k) = G2_hat^-1 Tr^-1 p_hat(k) (trace) */
    {
        float a, b;
        yao2020_model_rot_inv(m, st->p_hat_d_A, st->p_hat_q_A, &a, &b);
        yao2020_model_g2_solve(m, a, b, &st->M_d_V, &st->M_q_V);
    }

    /* identification (may change the injection now and R_hat/L_hat for the
     * next step) */
    if (st->primed != 0u) {
        yao2020_identification_update(cfg, st, iq_ref_A, id_A, iq_A, w_rad_s);
    }

    /* Yao 2020 Eq. 12: v*(k) = H^-1 (i_ref(k+2) - G i_ref(k+1) - p_hat(k))
     *              = (1/y) (Tr^-1 (i_ref(k+2) - p_hat(k)) - x i_ref(k+1)) */
    const float r2d = id_ref_A + st->id_inj_A;
    const float r2q = iq_ref_A;
    float vd, vq;
    {
        float a, b;
        yao2020_model_rot_inv(m, r2d - st->p_hat_d_A, r2q - st->p_hat_q_A, &a, &b);
        const float iy = 1.0f / m->y;
        vd = (a - m->x * st->r_prev_d_A) * iy;
        vq = (b - m->x * st->r_prev_q_A) * iy;
    }
    const uint8_t limited = dq_limit_voltage_radial(&vd, &vq, cfg->Vmax_V);

    /* Yao 2020 Eq. 13: i_hat(k+1) = G i_hat(k) + H v(k) + p_hat(k) */
    {
        float a, b, c2, d2;
        yao2020_model_rot_fwd(m, st->i_pred_d_A, st->i_pred_q_A, &a, &b);
        yao2020_model_rot_fwd(m, st->v_app_d_V, st->v_app_q_V, &c2, &d2);
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

    /* Yao 2020 Eq. 9: v_ref(k) = Tr^-1 v*(k) in the frame of theta(k); stator frame =
     * exp(j theta(k)) v_ref(k) = exp(j (theta(k) + w T)) v*(k) */
    float rd, rq;
    yao2020_model_rot_inv(m, vd, vq, &rd, &rq);
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
