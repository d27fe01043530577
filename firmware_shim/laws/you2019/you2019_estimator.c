/* you2019_estimator.c - You 2019 Eq. 5-9 and dead-time compensation.
 *
 * Derivation of the estimator loop (per axis):
 *   model (Eq. 5):  i_hat = B_hat z / (z - A_hat) (v* + u)
 *   PI:             u = (kp + ki Ts z/(z-1)) e
 *                     = (kp + ki Ts) (z - kp/(kp + ki Ts)) / (z - 1) e
 *   Pole-zero cancellation kp/(kp + ki Ts) = A_hat gives
 *                   kp = ki A_hat Ts / (1 - A_hat)          (Eq. 8 / Eq. 9)
 *   so the backward-Euler integrator is the one consistent with Eq. 8.
 *   Feedback e = i - z^-2 i_hat; loop gain
 *     L(z) = (kp + ki Ts) B_hat z/(z-1) z^-2 = g / (z (z - 1)),
 *     g = (kp + ki Ts) B_hat = ki Ts B_hat / (1 - A_hat) = ki Ts / R_hat.
 *   Characteristic polynomial: z^2 - z + g.  Real double pole (critical
 *   damping) for 1 - 4 g = 0 -> g = 1/4.  Tracking TF g / (z^2 - z + g);
 *   |.|^2 = 1/2 at z = e^{j theta} leads to
 *     g^2 - b g - 2 (1 - c) = 0,  c = cos theta, b = 2 (2c + 1)(c - 1). */
#include "you2019_estimator.h"

#include <math.h>

#include "dq_math.h"

void you2019_estimator_reset(you2019_estimator_state_t *st)
{
    st->i_hat_q_A = st->i_hat_d_A = 0.0f;
    st->i_hat_q_hist_A[0] = st->i_hat_q_hist_A[1] = 0.0f;
    st->i_hat_d_hist_A[0] = st->i_hat_d_hist_A[1] = 0.0f;
    st->integ_q_V = st->integ_d_V = 0.0f;
    st->err_q_A = st->err_d_A = 0.0f;
    st->i_hat_a_A = st->i_hat_b_A = st->i_hat_c_A = 0.0f;
    st->v_dt_alpha_V = st->v_dt_beta_V = 0.0f;
}

float you2019_estimator_loop_gain(float Ts_s, float bandwidth_Hz)
{
    const float theta = DQ_TWO_PI_F * bandwidth_Hz * Ts_s;
    if (!(theta > 0.0f) || theta >= DQ_PI_F) {
        return 0.25f;
    }
    const float c = cosf(theta);
    const float b = 2.0f * (2.0f * c + 1.0f) * (c - 1.0f);
    float g = 0.5f * (b + sqrtf(b * b + 8.0f * (1.0f - c)));
    if (g > 0.25f) {
        g = 0.25f; /* critical damping: never let the estimator ring */
    }
    return g;
}

void you2019_estimator_set_model(you2019_estimator_state_t *st, uint8_t axis, float A, float B_A_Vs)
{
    if (axis == 0u) {
        st->A_q = A;
        st->B_q_A_Vs = B_A_Vs;
    } else {
        st->A_d = A;
        st->B_d_A_Vs = B_A_Vs;
    }
}

void you2019_estimator_design_pi(float estimator_bandwidth_Hz, you2019_estimator_state_t *st, uint8_t axis, float Ts_s)
{
    const float g = you2019_estimator_loop_gain(Ts_s, estimator_bandwidth_Hz);
    const float A = axis == 0u ? st->A_q : st->A_d;
    const float B = axis == 0u ? st->B_q_A_Vs : st->B_d_A_Vs;
    const float one_minus_a = 1.0f - A;
    /* g = ki Ts B_hat / (1 - A_hat)  ->  ki */
    const float ki = g * one_minus_a / (B * Ts_s);
    /* You 2019 Eq. 8 (q) / Eq. 9 (d): kp = ki A_hat Ts / (1 - A_hat) */
    const float kp = ki * A * Ts_s / one_minus_a;
    st->g_loop = g;
    if (axis == 0u) {
        st->kp_q = kp;
        st->ki_q_1_s = ki;
    } else {
        st->kp_d = kp;
        st->ki_d_1_s = ki;
    }
}

static float estimator_axis(float i_A, float v_V, float A, float B, float kp, float ki, float Ts_s, float hist[2],
                            float *integ, float *err)
{
    /* feedback through z^-2: compare i(k) with the prediction made at k-2 */
    const float e = i_A - hist[1];
    *integ += ki * Ts_s * e;
    const float u = kp * e + *integ;
    /* You 2019 Eq. 5 (q) / Eq. 6 (d), PI correction added to the voltage */
    const float i_hat = B * (v_V + u) + A * hist[0];
    hist[1] = hist[0];
    hist[0] = i_hat;
    *err = e;
    return i_hat;
}

void you2019_estimator_step(you2019_estimator_state_t *st, float id_A, float iq_A, float v_d_V, float v_q_V, float Ts_s)
{
    st->i_hat_q_A = estimator_axis(iq_A, v_q_V, st->A_q, st->B_q_A_Vs, st->kp_q, st->ki_q_1_s, Ts_s, st->i_hat_q_hist_A,
                                   &st->integ_q_V, &st->err_q_A);
    st->i_hat_d_A = estimator_axis(id_A, v_d_V, st->A_d, st->B_d_A_Vs, st->kp_d, st->ki_d_1_s, Ts_s, st->i_hat_d_hist_A,
                                   &st->integ_d_V, &st->err_d_A);
}

float you2019_estimator_deadtime_shape(float V_dt_V, float I_sat_A, float i_A)
{
    /* You 2019 Fig. 3: the dead-time voltage error grows with |i| and
     * saturates above about 1 A; modelled as a linear ramp clamped at I_sat. */
    float x = I_sat_A > 1e-6f ? i_A / I_sat_A : (i_A > 0.0f ? 1.0f : -1.0f);
    if (x > 1.0f) x = 1.0f;
    if (x < -1.0f) x = -1.0f;
    return V_dt_V * x;
}

void you2019_estimator_deadtime(float deadtime_comp_V, float deadtime_comp_I_sat_A, you2019_estimator_state_t *st,
                                float cos_th, float sin_th)
{
    float i_al, i_be;
    /* You 2019 Eq. 7: estimated dq currents -> estimated phase currents */
    dq_inv_park(st->i_hat_d_A, st->i_hat_q_A, cos_th, sin_th, &i_al, &i_be);
    dq_inv_clarke(i_al, i_be, &st->i_hat_a_A, &st->i_hat_b_A, &st->i_hat_c_A);
    const float va = you2019_estimator_deadtime_shape(deadtime_comp_V, deadtime_comp_I_sat_A, st->i_hat_a_A);
    const float vb = you2019_estimator_deadtime_shape(deadtime_comp_V, deadtime_comp_I_sat_A, st->i_hat_b_A);
    const float vc = you2019_estimator_deadtime_shape(deadtime_comp_V, deadtime_comp_I_sat_A, st->i_hat_c_A);
    dq_clarke3(va, vb, vc, &st->v_dt_alpha_V, &st->v_dt_beta_V);
}
