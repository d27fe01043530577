/* pi_current.c - dq PI baseline with decoupling and IMC back-calculation. */
#include "pi_current.h"

#include <math.h>

#include "dq_math.h"

void pi_current_design(float pi_bandwidth_Hz, pi_current_state_t *st, float R_hat_ohm, float Ld_hat_H, float Lq_hat_H)
{
    /* IMC rule: C(s) = (w_bw / s) (L s + R)  =>  Kp = w_bw L, Ki = w_bw R. */
    const float w_bw = DQ_TWO_PI_F * pi_bandwidth_Hz;
    st->Kp_q_V_A = w_bw * Lq_hat_H;
    st->Kp_d_V_A = w_bw * Ld_hat_H;
    st->Ki_q_V_As = w_bw * R_hat_ohm;
    st->Ki_d_V_As = w_bw * R_hat_ohm;
    st->R_hat_ohm = R_hat_ohm;
}

void pi_current_reset(pi_current_state_t *st)
{
    st->integ_q_V = st->integ_d_V = 0.0f;
    st->i_q_A = st->i_d_A = 0.0f;
    st->v_q_raw_V = st->v_d_raw_V = 0.0f;
    st->e_q_A = st->e_d_A = 0.0f;
}

void pi_current_step(pi_current_state_t *st, float id_ref_A, float iq_ref_A, float id_A, float iq_A, float Ts_s,
                     float *v_d_V, float *v_q_V)
{
    st->i_q_A = iq_A;
    st->i_d_A = id_A;
    st->e_q_A = iq_ref_A - iq_A;
    st->e_d_A = id_ref_A - id_A;
    /* backward-Euler integrator */
    st->integ_q_V += st->Ki_q_V_As * Ts_s * st->e_q_A;
    st->integ_d_V += st->Ki_d_V_As * Ts_s * st->e_d_A;
    st->v_q_raw_V = st->Kp_q_V_A * st->e_q_A + st->integ_q_V;
    st->v_d_raw_V = st->Kp_d_V_A * st->e_d_A + st->integ_d_V;
    *v_q_V = st->v_q_raw_V;
    *v_d_V = st->v_d_raw_V;
}

static float pi_axis_antiwindup(float integ, float R_hat_ohm, float i_A, float raw, float applied)
{
    if (applied == raw) {
        return integ;
    }
    /* back-calculate to the IMC steady state of the present current */
    integ = R_hat_ohm * i_A;
    const float bound = fabsf(applied);
    if (integ > bound) integ = bound;
    if (integ < -bound) integ = -bound;
    return integ;
}

void pi_current_commit(pi_current_state_t *st, float v_d_applied_V, float v_q_applied_V)
{
    st->integ_q_V = pi_axis_antiwindup(st->integ_q_V, st->R_hat_ohm, st->i_q_A, st->v_q_raw_V, v_q_applied_V);
    st->integ_d_V = pi_axis_antiwindup(st->integ_d_V, st->R_hat_ohm, st->i_d_A, st->v_d_raw_V, v_d_applied_V);
}
