/* you2019_estimator.h - You 2019 Sec. 3.2: predictive current estimator
 * (Eq. 5-9, Fig. 4) and dead-time compensation from the estimated phase
 * currents (Eq. 7, Fig. 3).
 *
 * Estimator per axis (x = q or d):
 *   e(k)    = i_x(k) - i_hat_x(k-2)                 (z^-2 in the feedback path)
 *   u(k)    = kp e(k) + integ(k),  integ(k) = integ(k-1) + ki Ts e(k)
 *   i_hat(k)= B_hat (v*(k) + u(k)) + A_hat i_hat(k-1)  (Eq. 5/6 + PI)
 * i_hat(k) predicts the current sampled at k+2.
 *
 * Integral gain derivation (see you2019_estimator.c for the algebra):
 *   with kp from Eq. 8 the PI zero cancels the model pole A_hat, the loop
 *   gain is g / (z (z - 1)) with g = ki Ts B_hat / (1 - A_hat) (= ki Ts / R_hat),
 *   characteristic polynomial z^2 - z + g, tracking transfer function
 *   i_hat(k-2)/i(k) = g / (z^2 - z + g).
 *   Critical damping <=> g = 1/4 (double pole z = 0.5, -3 dB at 0.0732 fs =
 *   1331 Hz for Ts = 55 us).  For a requested -3 dB bandwidth f_bw:
 *     c = cos(2 pi f_bw Ts), b = 2 (2c + 1)(c - 1),
 *     g = (b + sqrt(b^2 + 8 (1 - c))) / 2,
 *   clamped to g <= 1/4 (never underdamped).  900 Hz gives g = 0.2003,
 *   poles 0.724 / 0.276 (zeta > 1).  ki = g (1 - A_hat) / (B_hat Ts). */
#ifndef YOU2019_ESTIMATOR_H
#define YOU2019_ESTIMATOR_H

#include <stdint.h>

typedef struct {
    /* model gains used by You 2019 Eq. 5/6 */
    float A_q, B_q_A_Vs, A_d, B_d_A_Vs;
    /* PI gains (You 2019 Eq. 8/9) */
    float kp_q, ki_q_1_s, kp_d, ki_d_1_s;
    float g_loop; /* loop gain g of the design, for tracing */
    /* predictions and histories: [0] = i_hat(k-1), [1] = i_hat(k-2) */
    float i_hat_q_A, i_hat_d_A;
    float i_hat_q_hist_A[2], i_hat_d_hist_A[2];
    float integ_q_V, integ_d_V;
    float err_q_A, err_d_A;
    /* dead-time compensation output (stator frame) and phase currents */
    float i_hat_a_A, i_hat_b_A, i_hat_c_A;
    float v_dt_alpha_V, v_dt_beta_V;
} you2019_estimator_state_t;

void you2019_estimator_reset(you2019_estimator_state_t *st);

/* Loop gain g for a requested bandwidth (clamped to 1/4, see above). */
float you2019_estimator_loop_gain(float Ts_s, float bandwidth_Hz);

/* Set the model (You 2019 Eq. 5/6) gains of one axis (axis 0 = q, 1 = d). */
void you2019_estimator_set_model(you2019_estimator_state_t *st, uint8_t axis, float A, float B_A_Vs);
/* Design the PI of one axis from its current model gains (You 2019 Eq. 8/9). */
void you2019_estimator_design_pi(float estimator_bandwidth_Hz, you2019_estimator_state_t *st, uint8_t axis, float Ts_s);

/* One current period: measured i(k), decoupled voltage command v*(k), d
 * before q. */
void you2019_estimator_step(you2019_estimator_state_t *st, float id_A, float iq_A, float v_d_V, float v_q_V,
                            float Ts_s);

/* Per-phase dead-time voltage shape: V_dt * sat(i / I_sat). */
float you2019_estimator_deadtime_shape(float V_dt_V, float I_sat_A, float i_A);

/* Dead-time compensation in the stator frame from the estimated dq currents
 * rotated with (cos_th, sin_th) to phases (You 2019 Eq. 7). */
void you2019_estimator_deadtime(float deadtime_comp_V, float deadtime_comp_I_sat_A, you2019_estimator_state_t *st,
                                float cos_th, float sin_th);

#endif
