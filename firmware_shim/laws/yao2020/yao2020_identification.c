/* yao2020_identification.c - Yao 2020 R/L identification (Eq. 22-45,
 * Definitions 1-2); see yao2020_identification.h. */
#include "yao2020_identification.h"

#include <math.h>
#include <string.h>

/* Yao 2020 Definition 1 (Eq. 30) and Definition 2 (Eq. 31). */
yao2020_identification_motor_class_t yao2020_identification_classify(float R_ohm, float L_H, float w_rad_s, float Ts_s)
{
    const float cwT = cosf(w_rad_s * Ts_s);
    const float a = R_ohm * Ts_s / L_H;
    if (cwT >= 0.98f && fabsf(expf(-a) - (1.0f - a)) < 0.05f) {
        return YAO2020_IDENTIFICATION_MOTOR_LOW_FREQ;
    }
    if (cwT < 0.98f && R_ohm < 0.2f * fabsf(w_rad_s) * L_H) {
        return YAO2020_IDENTIFICATION_MOTOR_HIGH_FREQ;
    }
    return YAO2020_IDENTIFICATION_MOTOR_NEITHER;
}

static float clampf(float v, float lo, float hi)
{
    if (v < lo) return lo;
    if (v > hi) return hi;
    return v;
}

static uint32_t ident_total_phases(const yao2020_model_config_t *cfg)
{
    const uint32_t r = cfg->n_rounds > 0u ? cfg->n_rounds : 1u;
    return 4u * r + 1u;
}

bool yao2020_identification_running(const yao2020_model_state_t *st)
{
    return st->id_state != (uint8_t)YAO2020_IDENTIFICATION_IDLE &&
           st->id_state != (uint8_t)YAO2020_IDENTIFICATION_DONE &&
           st->id_state != (uint8_t)YAO2020_IDENTIFICATION_ABORTED;
}

bool yao2020_identification_start(const yao2020_model_config_t *cfg, yao2020_model_state_t *st)
{
    if (yao2020_identification_running(st) || st->primed == 0u) {
        return false;
    }
    st->id_state = (uint8_t)YAO2020_IDENTIFICATION_PRE_L;
    st->abort_reason = (uint8_t)YAO2020_IDENTIFICATION_ABORT_NONE;
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
    /* Yao 2020 Eq. 30-31 with the controller's (estimated) parameters */
    st->motor_class =
        (uint8_t)yao2020_identification_classify(st->R_hat_ohm, st->L_hat_H, st->w_start_rad_s, cfg->Ts_s);
    if (cfg->gain_select == (uint8_t)YAO2020_IDENTIFICATION_GAINS_LOW) {
        st->gains_high = 0u;
    } else if (cfg->gain_select == (uint8_t)YAO2020_IDENTIFICATION_GAINS_HIGH) {
        st->gains_high = 1u;
    } else {
        /* AUTO: the cos(wT) test common to Yao 2020 Eq. 30 and Eq. 31 selects the
         * simplification.  (The Table II motor misses the second condition of
         * Yao 2020 Eq. 31, R < 0.2 w L: 0.045 vs 0.040 ohm, yet the paper treats it as
         * high-frequency; motor_class still reports NEITHER in that case.) */
        st->gains_high = cosf(st->w_start_rad_s * cfg->Ts_s) < 0.98f ? 1u : 0u;
    }
    st->kL_H_Vs = st->gains_high ? cfg->kL_high_H_Vs : cfg->kL_low_H_Vs;
    st->kR_ohm_Vs = st->gains_high ? cfg->kR_high_ohm_Vs : cfg->kR_low_ohm_Vs;
    /* Yao 2020 Eq. 44: closed-loop rate k_{L,R} k with the positive plant gain k
     * (dM per unit parameter error) from the chosen simplification:
     *   low  (Eq. 35/36 divided by |d_hat|^2 = (T/L)^2, Eq. 27):
     *        dM_q = w (L - L_hat) did,   dM_d = (R - R_hat) did
     *   high (Eq. 42/43 divided by |d_hat|^2 = (s^2 + (c - x)^2)/(w L)^2,
     *        Eq. 37, and exp(-R_hat T/L) - exp(-R T/L) ~ -x T/L (R_hat - R)):
     *        dM_q = w T/(y L) (L - L_hat) did
     *        dM_d = s w T x/(s^2 + (c - x)^2) (R - R_hat) did */
    {
        yao2020_model_t m0;
        yao2020_model_compute(st->R_hat_ohm, st->L_hat_H, st->w_start_rad_s, cfg->Ts_s, &m0);
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

static void ident_abort(yao2020_model_state_t *st, yao2020_identification_abort_reason_t why)
{
    st->id_state = (uint8_t)YAO2020_IDENTIFICATION_ABORTED;
    st->abort_reason = (uint8_t)why;
    st->id_inj_A = 0.0f;
    st->R_hat_ohm = st->R_start_ohm;
    st->L_hat_H = st->L_start_H;
}

void yao2020_identification_abort(yao2020_model_state_t *st)
{
    if (yao2020_identification_running(st)) {
        ident_abort(st, YAO2020_IDENTIFICATION_ABORT_USER);
    }
}

float yao2020_identification_progress(const yao2020_model_config_t *cfg, const yao2020_model_state_t *st)
{
    if (st->id_state == (uint8_t)YAO2020_IDENTIFICATION_DONE) return 1.0f;
    return (float)st->phases_done / (float)ident_total_phases(cfg);
}

bool yao2020_identification_result(const yao2020_model_state_t *st, float *R_ohm, float *L_H)
{
    *R_ohm = st->R_id_ohm;
    *L_H = st->L_id_H;
    return st->id_state == (uint8_t)YAO2020_IDENTIFICATION_DONE;
}

static void next_phase(yao2020_model_state_t *st, yao2020_identification_phase_t s)
{
    st->id_state = (uint8_t)s;
    st->phase_count = 0u;
    st->hold_count = 0u;
    st->phases_done++;
    memset(st->acc, 0, sizeof(st->acc));
}

void yao2020_identification_update(const yao2020_model_config_t *cfg, yao2020_model_state_t *st, float iq_ref_A,
                                   float id_A, float iq_A, float w_rad_s)
{
    if (!yao2020_identification_running(st)) {
        st->id_inj_A = 0.0f;
        return;
    }
    /* Sec. III: identification only in steady state (w and iq unchanged) */
    if (fabsf(w_rad_s - st->w_start_rad_s) > cfg->steady_tol_w_rad_s) {
        ident_abort(st, YAO2020_IDENTIFICATION_ABORT_SPEED_CHANGED);
        return;
    }
    if (fabsf(iq_ref_A - st->iq_ref_start_A) > cfg->steady_tol_iq_A) {
        ident_abort(st, YAO2020_IDENTIFICATION_ABORT_IQ_CHANGED);
        return;
    }
    if (fabsf(w_rad_s) < cfg->min_speed_rad_s) {
        ident_abort(st, YAO2020_IDENTIFICATION_ABORT_LOW_SPEED);
        return;
    }
    const yao2020_model_t *m = &st->m;
    /* Tr^-1 p_hat(k); M(k) = F^-1 p_hat = G2^-1 Tr^-1 p_hat (Yao 2020 Eq. 22) */
    float tp_d, tp_q;
    yao2020_model_rot_inv(m, st->p_hat_d_A, st->p_hat_q_A, &tp_d, &tp_q);
    st->phase_count++;
    const yao2020_identification_phase_t s = (yao2020_identification_phase_t)st->id_state;
    switch (s) {
    case YAO2020_IDENTIFICATION_PRE_L:
    case YAO2020_IDENTIFICATION_PRE_R: {
        st->id_inj_A = 0.0f;
        const uint32_t navg = cfg->n_avg > 0u ? cfg->n_avg : 1u;
        const uint32_t nset = cfg->n_settle > navg ? cfg->n_settle : navg;
        if (st->phase_count + navg > nset) {
            /* Yao 2020 Eq. 24: M(t0).  Stored as the estimate-independent
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
            next_phase(st, s == YAO2020_IDENTIFICATION_PRE_L ? YAO2020_IDENTIFICATION_INJECT_L
                                                             : YAO2020_IDENTIFICATION_INJECT_R);
            st->id_inj_A = cfg->inj_id_A; /* negative step into the d axis */
        }
        break;
    }
    case YAO2020_IDENTIFICATION_INJECT_L:
    case YAO2020_IDENTIFICATION_INJECT_R: {
        st->id_inj_A = cfg->inj_id_A;
        if (st->phase_count <= cfg->n_settle) {
            break; /* Sec. IV-E: wait for the observer/current transient */
        }
        /* Yao 2020 Eq. 26: dM = M(k) - M(t0).
         * rereference = 1 (derived): M(t0) re-evaluated with the current
         *   estimates, M0 = G2^-1 (N0 - x i0 - y v0); Eq. 22 shows M depends
         *   on R_hat/L_hat through G2_hat, x_hat, y_hat, so a stale M(t0) would
         *   make the integrator converge where M(t1; L_hat) = M(t0; L_start).
         * rereference = 0: literal reading, stale M(t0). */
        if (cfg->rereference != 0u) {
            const float ad = tp_d - (st->N0_d - m->x * st->i0_d - m->y * st->v0_d);
            const float aq = tp_q - (st->N0_q - m->x * st->i0_q - m->y * st->v0_q);
            yao2020_model_g2_solve(m, ad, aq, &st->dM_d_V, &st->dM_q_V);
        } else {
            st->dM_d_V = st->M_d_V - st->M0_d;
            st->dM_q_V = st->M_q_V - st->M0_q;
        }
        const float sgn_i = cfg->inj_id_A < 0.0f ? -1.0f : 1.0f;
        const float T = cfg->Ts_s;
        bool inside;
        if (s == YAO2020_IDENTIFICATION_INJECT_L) {
            /* Fig. 9(a), Yao 2020 Eq. 36/42/44: dM_q ~ k' w (L - L_hat) did; integral
             * estimator driving dM_q to 0, dead zone TH_L. */
            inside = fabsf(st->dM_q_V) <= cfg->th_L_V;
            if (!inside) {
                const float sgn = (w_rad_s < 0.0f) ? -sgn_i : sgn_i;
                st->L_hat_H = clampf(st->L_hat_H + sgn * st->kL_H_Vs * T * st->dM_q_V, cfg->L_min_H, cfg->L_max_H);
            }
        } else {
            /* Fig. 9(b), Yao 2020 Eq. 35/43/44: dM_d ~ k' (R - R_hat) did, dead
             * zone TH_R */
            inside = fabsf(st->dM_d_V) <= cfg->th_R_V;
            if (!inside) {
                st->R_hat_ohm =
                    clampf(st->R_hat_ohm + sgn_i * st->kR_ohm_Vs * T * st->dM_d_V, cfg->R_min_ohm, cfg->R_max_ohm);
            }
        }
        st->hold_count = inside ? st->hold_count + 1u : 0u;
        const uint32_t n_int = st->phase_count - cfg->n_settle;
        const bool conv = st->hold_count >= (cfg->n_hold > 0u ? cfg->n_hold : 1u);
        if (conv || n_int >= cfg->n_timeout) {
            const uint32_t t_conv = conv ? n_int - st->hold_count : n_int;
            if (s == YAO2020_IDENTIFICATION_INJECT_L) {
                st->L_converged = conv ? 1u : 0u;
                st->t_L_conv_periods = t_conv;
                st->L_id_H = st->L_hat_H;
                next_phase(st, YAO2020_IDENTIFICATION_PRE_R);
            } else {
                st->R_converged = conv ? 1u : 0u;
                st->t_R_conv_periods = t_conv;
                st->R_id_ohm = st->R_hat_ohm;
                const uint8_t nr = cfg->n_rounds > 0u ? cfg->n_rounds : 1u;
                st->round++;
                next_phase(st, st->round < nr ? YAO2020_IDENTIFICATION_PRE_L : YAO2020_IDENTIFICATION_POST);
            }
            st->id_inj_A = 0.0f;
        }
        break;
    }
    case YAO2020_IDENTIFICATION_POST:
        st->id_inj_A = 0.0f;
        if (st->phase_count >= cfg->n_settle) {
            next_phase(st, YAO2020_IDENTIFICATION_DONE);
            st->L_id_H = st->L_hat_H;
            st->R_id_ohm = st->R_hat_ohm;
        }
        break;
    default: break;
    }
}
