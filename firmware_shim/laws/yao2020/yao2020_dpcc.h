/* yao2020_dpcc.h - Yao 2020: improved deadbeat predictive current control
 * (DPCC) with sliding-mode disturbance observer and online R/L
 * identification for surface-mounted PMSMs, after Yao, Huang, Peng, Dong,
 * Zhang, "An Improved Deadbeat Predictive Current Control With Online
 * Parameter Identification for Surface-Mounted PMSMs", IEEE TIE 67(12), 2020
 * ("Yao 2020").
 *
 * Blocks (equation numbers of Yao 2020):
 *   - fully discretised (zero-order hold) model with the rotation over one
 *     period, Eq. 4-7: x, y, d1, d2, G = x Tr, H = y Tr, F = Tr G2
 *     (yao2020_model.h, shared with the identification and the RLS);
 *   - deadbeat law with one-period delay compensation, Eq. 9-12;
 *   - sliding-mode disturbance observer, Eq. 13-18 (switchable; when off the
 *     disturbance is the conventional back-EMF term F [0, w psi_hat]);
 *   - reconstructed characteristic vector M = F^-1 p_hat, Eq. 22-29, and the
 *     R/L identification by negative d-axis current injection with integral
 *     estimators and dead zones, Eq. 30-45, Table III; L first, then R
 *     (yao2020_identification.h; its configuration and state are part of
 *     the DPCC's, defined in yao2020_model.h).
 *
 * Timing (same as drive_core.h): the command returned by yao2020_dpcc_step()
 * at sample k is applied by the PWM over [k+1, k+2], held constant in the
 * STATOR frame, and first shows in the current sampled at k+2.  The
 * reference passed at sample k is therefore the target of i(k+2)
 * (i_ref(k+2) of Eq. 12); the previous one is i_ref(k+1).
 *
 * Output frames.  v_star_{d,q} is v*(k) of Eq. 9: the command expressed in
 * the dq frame of theta(k+1) = theta(k) + w T (the frame at the start of the
 * interval over which it acts).  v_ref_{d,q} = Tr^-1 v*(k) is the same
 * vector in the frame of theta(k) (v_dq_ref of Eq. 9).  v_alpha/v_beta is
 * the stator-frame vector: the caller must NOT add any angle advance.
 *
 * Units: SI throughout (A, V, ohm, H, Wb, s, rad/s electrical).  M and dM
 * have the unit of a voltage (M = G2_hat^-1 Tr^-1 p_hat, p in A, G2 in A/V).
 * Integral estimator gains: k_L in H/(V s), k_R in ohm/(V s)
 * (dL_hat/dt = -k_L dM_q, dR_hat/dt = -k_R dM_d for a negative injection,
 * Eq. 44, discretised with forward Euler at the current period). */
#ifndef YAO2020_DPCC_H
#define YAO2020_DPCC_H

#include <stdint.h>

#include "yao2020_model.h"

/* Configuration and state of the DPCC, its observer and its identification
 * (fields: yao2020_model.h, where they are defined so that the
 * identification does not include this header). */
typedef yao2020_model_config_t yao2020_dpcc_config_t;
typedef yao2020_model_state_t yao2020_dpcc_state_t;

typedef struct {
    float v_star_d_V, v_star_q_V; /* v*(k), frame theta(k) + w T (Yao 2020 Eq. 9) */
    float v_ref_d_V, v_ref_q_V;   /* Tr^-1 v*(k), frame theta(k) */
    float v_alpha_V, v_beta_V;    /* stator frame, held over [k+1, k+2] */
    float id_ref_eff_A;           /* d reference incl. injection */
    uint8_t limited;              /* Vmax_V limit active */
} yao2020_dpcc_cmd_t;

void yao2020_dpcc_default_config(yao2020_dpcc_config_t *cfg);
/* init = reset (takes R_hat/L_hat from the config). */
void yao2020_dpcc_init(const yao2020_dpcc_config_t *cfg, yao2020_dpcc_state_t *st);
void yao2020_dpcc_reset(const yao2020_dpcc_config_t *cfg, yao2020_dpcc_state_t *st);

/* One current period.  id_ref/iq_ref: targets of i(k+2); id/iq: measured
 * currents at sample k (frame of theta_e); w: electrical speed; theta_e:
 * electrical angle at sample k. */
void yao2020_dpcc_step(const yao2020_dpcc_config_t *cfg, yao2020_dpcc_state_t *st, float id_ref_A, float iq_ref_A,
                       float id_A, float iq_A, float w_rad_s, float theta_e_rad, yao2020_dpcc_cmd_t *cmd);

#endif
