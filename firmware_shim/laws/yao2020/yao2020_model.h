/* yao2020_model.h - Yao 2020 fully discretised (zero-order hold) motor model
 * of one current period, with the rotation over the period, Eq. 4-7: x, y,
 * d1, d2, G = x Tr, H = y Tr, F = Tr G2 (Yao, Huang, Peng, Dong, Zhang, "An
 * Improved Deadbeat Predictive Current Control With Online Parameter
 * Identification for Surface-Mounted PMSMs", IEEE TIE 67(12), 2020,
 * "Yao 2020"), and its complex-number helpers (Tr, Tr^-1, G2^-1).
 *
 * The unit below the DPCC (yao2020_dpcc.h) and its R/L identification
 * (yao2020_identification.h), which both compute with the model and both
 * read and write the controller's configuration and state: these are
 * defined here (yao2020_model_config_t, yao2020_model_state_t) and are the
 * DPCC's yao2020_dpcc_config_t and yao2020_dpcc_state_t (same types,
 * typedef'd in yao2020_dpcc.h), so that the include graph is a tree:
 * model <- identification <- dpcc, model <- rls.
 * Fields, timing, frames and units: see yao2020_dpcc.h. */
#ifndef YAO2020_MODEL_H
#define YAO2020_MODEL_H

#include <stdint.h>

/* The DPCC's configuration (yao2020_dpcc_config_t). */
typedef struct {
    float Ts_s; /* current period T, default 100e-6 (Table III) */
    /* controller's motor model; R_hat/L_hat are the initial values, copied to
     * the state by init/reset; the identification updates the state copies */
    float R_hat_ohm;         /* default 2.2 (Table I) */
    float L_hat_H;           /* default 5.5e-3 (Table I) */
    float psi_hat_Wb;        /* only for observer_enable = 0 and the first step */
    float Vmax_V;            /* radial voltage limit, 0 = off (default 0) */
    uint8_t observer_enable; /* 1 (default): SMO, Yao 2020 Eq. 13-18;
                              * 0: p = F e(psi_hat) */
    float Q_d, Q_q;          /* Yao 2020 Eq. 16 reaching-law matrix, default 0.4, 0.4 */
    /* identification (Sec. IV-E, Table III) */
    float inj_id_A;             /* d-axis injection step, default -2 (low-freq test) */
    uint8_t gain_select;        /* yao2020_identification_gain_select_t, default AUTO */
    float kL_low_H_Vs;          /* default 0.005 */
    float kR_low_ohm_Vs;        /* default 4 */
    float kL_high_H_Vs;         /* default 2e-5 */
    float kR_high_ohm_Vs;       /* default 0.04 */
    float th_L_V;               /* dead zone on dM_q, default 0.1 (TH_L) */
    float th_R_V;               /* dead zone on dM_d, default 0.03 (TH_R) */
    uint32_t n_settle;          /* periods to wait after each id change, default 200 */
    uint32_t n_avg;             /* periods averaged for M(t0), default 50 */
    uint32_t n_hold;            /* periods inside the dead zone = converged, default 200 */
    uint32_t n_timeout;         /* max integrating periods per injection, default 300000 */
    uint8_t n_rounds;           /* L then R repeated n times, default 1 (paper) */
    uint8_t rereference;        /* 1 (default): re-evaluate M(t0) with the current
                                 * R_hat/L_hat; 0: stale M(t0) (literal reading) */
    float steady_tol_w_rad_s;   /* default 5 */
    float steady_tol_iq_A;      /* default 0.05 */
    float min_speed_rad_s;      /* default 50 */
    float R_min_ohm, R_max_ohm; /* estimate clamps, default 1e-4, 1e3 */
    float L_min_H, L_max_H;     /* default 1e-7, 1 */
    /* the other parameters of the drive's Yao 2020 DPCC record (0x2501, law.eds), not
     * read by the DPCC: the drive's RLS baseline (Yao 2020 Sec. VI-B) beside it,
     * and the identification command the drive app acts on */
    uint8_t rls_enable;
    float rls_lambda; /* RLS forgetting factor */
    uint8_t ident_command;
} yao2020_model_config_t;

/* Estimated-parameter model of one period (Yao 2020 Eq. 5-6). */
typedef struct {
    float x, y;   /* x = exp(-R T / L), y = (1 - x) / R (A/V) */
    float c, s;   /* cos(w T), sin(w T) */
    float d1, d2; /* G2 = [d1 -d2; d2 d1] (A/V) */
} yao2020_model_t;

/* The DPCC's state (yao2020_dpcc_state_t). */
typedef struct {
    /* active estimated parameters (controller model) */
    float R_hat_ohm, L_hat_H;
    yao2020_model_t m;      /* model of this step */
    float Gp_x, Gp_c, Gp_s; /* G_hat of the previous step (x, cos, sin) */
    /* observer (Yao 2020 Eq. 13-18) */
    float i_pred_d_A, i_pred_q_A; /* i_hat(k+1) predicted at k */
    float i_err_d_A, i_err_q_A;   /* i_tilde(k) = i_hat(k) - i(k) */
    float p_prev_d_A, p_prev_q_A; /* p(k-1), Yao 2020 Eq. 18 */
    float p_hat_d_A, p_hat_q_A;   /* p_hat(k), Yao 2020 Eq. 17 */
    /* reconstructed characteristic vector (Yao 2020 Eq. 22) */
    float M_d_V, M_q_V;
    float dM_d_V, dM_q_V; /* M(k) - M(t0) (identification phases) */
    /* voltages */
    float v_app_d_V, v_app_q_V;   /* v(k) = v*(k-1): acts over [k, k+1] */
    float v_star_d_V, v_star_q_V; /* last command v*(k) */
    float r_prev_d_A, r_prev_q_A; /* i_ref(k+1) for the next step */
    float w_rad_s, iq_ref_A;      /* speed and iq reference of the last step */
    uint8_t primed;
    uint32_t step_count;
    /* identification */
    uint8_t id_state;                 /* yao2020_identification_phase_t */
    uint8_t abort_reason;             /* yao2020_identification_abort_reason_t */
    uint8_t motor_class;              /* yao2020_identification_motor_class_t
                                       * (Yao 2020 Eq. 30-31, from R_hat/L_hat) */
    uint8_t gains_high;               /* 1: high-frequency gain set in use */
    uint8_t round;                    /* current round (0-based) */
    uint8_t L_converged, R_converged; /* last injection ended in the dead zone */
    uint32_t phase_count;             /* periods spent in the current phase */
    uint32_t hold_count;              /* consecutive periods inside the dead zone */
    uint32_t phases_done;
    float id_inj_A; /* injection currently added to id_ref */
    float w_start_rad_s, iq_ref_start_A;
    float R_start_ohm, L_start_H;                         /* restored on abort */
    float N0_d, N0_q, i0_d, i0_q, v0_d, v0_q, M0_d, M0_q; /* M(t0) reference */
    float acc[8];
    float kL_H_Vs, kR_ohm_Vs;                    /* gains in use */
    float tau_L_pred_s, tau_R_pred_s;            /* Yao 2020 Eq. 44 with the k of
                                                  * Eq. 35/36 or 42/43 */
    uint32_t t_L_conv_periods, t_R_conv_periods; /* integrating periods to converge */
    float L_id_H, R_id_ohm;                      /* converged values */
} yao2020_model_state_t;

/* Yao 2020 Eq. 5-6 for (R, L, w, T). */
void yao2020_model_compute(float R_ohm, float L_H, float w_rad_s, float Ts_s, yao2020_model_t *m);

/* Complex-number helpers of the step and the identification (a dq 2-vector
 * [a b] is a + j b, see yao2020_model.c). */
/* Tr [a b] = exp(-j w T)(a + j b) */
static inline void yao2020_model_rot_fwd(const yao2020_model_t *m, float a, float b, float *oa, float *ob)
{
    *oa = m->c * a + m->s * b;
    *ob = -m->s * a + m->c * b;
}
/* Tr^-1 [a b] = exp(+j w T)(a + j b) */
static inline void yao2020_model_rot_inv(const yao2020_model_t *m, float a, float b, float *oa, float *ob)
{
    *oa = m->c * a - m->s * b;
    *ob = m->s * a + m->c * b;
}
/* G2^-1 [a b] = (a + j b) / (d1 + j d2) */
static inline void yao2020_model_g2_solve(const yao2020_model_t *m, float a, float b, float *oa, float *ob)
{
    const float n2 = m->d1 * m->d1 + m->d2 * m->d2;
    const float inv = n2 > 0.0f ? 1.0f / n2 : 0.0f;
    *oa = (m->d1 * a + m->d2 * b) * inv;
    *ob = (m->d1 * b - m->d2 * a) * inv;
}

#endif
