/* pi_current.h - synchronous-frame dq PI current controller (baseline).
 *
 * Gain design (IMC / pole-zero cancellation, documented in pi_current.c):
 *   Kp = 2 pi f_bw L_hat   [V/A]
 *   Ki = 2 pi f_bw R_hat   [V/(A s)]
 * The PI zero Ki/Kp = R/L cancels the RL pole, the open loop is
 * 2 pi f_bw / s (times the 1.5 Ts computation + PWM delay), the closed loop is
 * first order with bandwidth f_bw.  Phase margin = 90 deg - 2 pi f_bw 1.5 Ts
 * (60 deg at 1 kHz, Ts = 55 us).
 * Anti-windup (IMC-consistent back-calculation): with Ki/Kp = R/L the
 * integrator of the unsaturated loop holds exactly R_hat * i (the resistive
 * drop of the current the loop is producing).  While the output is limited
 * by You 2019 Eq. 33 the integrator is therefore re-set to R_hat * i_measured,
 * bounded by the applied voltage; after de-saturation the loop continues
 * as the first-order IMC response without the slow L/R tail a simply
 * frozen integrator would leave, and without overshoot. */
#ifndef PI_CURRENT_H
#define PI_CURRENT_H

#include <stdint.h>

typedef struct {
    float Kp_q_V_A, Ki_q_V_As, Kp_d_V_A, Ki_d_V_As;
    float integ_q_V, integ_d_V;
    float v_q_raw_V, v_d_raw_V;
    float e_q_A, e_d_A;
    float i_q_A, i_d_A, R_hat_ohm;
} pi_current_state_t;

void pi_current_design(float pi_bandwidth_Hz, pi_current_state_t *st, float R_hat_ohm, float Ld_hat_H, float Lq_hat_H);
void pi_current_reset(pi_current_state_t *st);
/* Decoupled controller voltage (feed-forward added by the caller). */
void pi_current_step(pi_current_state_t *st, float id_ref_A, float iq_ref_A, float id_A, float iq_A, float Ts_s,
                     float *v_d_V, float *v_q_V);
/* Anti-windup: called with the decoupled voltage actually applied. */
void pi_current_commit(pi_current_state_t *st, float v_d_applied_V, float v_q_applied_V);

#endif
