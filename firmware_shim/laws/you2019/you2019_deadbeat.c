/* you2019_deadbeat.c - You 2019 deadbeat current controller (Sec. 4). */
#include "you2019_deadbeat.h"

#include <math.h>
#include <string.h>

void you2019_deadbeat_model_gains(float Ts_s, float R_ohm, float L_H, float *A, float *B_A_Vs)
{
    /* You 2019 Eq. 2-3: A_m = exp(-Ts r_s / L), B_m = (1 - A_m) / r_s.
     * Written with expm1f so that B stays accurate for small Ts R / L and the
     * R -> 0 limit B -> Ts / L is handled. */
    const float x = Ts_s * R_ohm / L_H;
    const float one_minus_a = -expm1f(-x);
    *A = 1.0f - one_minus_a;
    if (R_ohm > 1e-9f) {
        *B_A_Vs = one_minus_a / R_ohm;
    } else {
        *B_A_Vs = Ts_s / L_H;
    }
}

void you2019_deadbeat_controller_gains(float A, float B_A_Vs, float *K1_V_A, float *K2_V_A)
{
    /* You 2019 Eq. 17 (and Eq. 19 for d): K1 = 1/B_m, K2 = A_m/B_m. */
    *K1_V_A = 1.0f / B_A_Vs;
    *K2_V_A = A / B_A_Vs;
}

void you2019_deadbeat_reset(you2019_deadbeat_state_t *st)
{
    st->e_q_prev_A = 0.0f;
    st->e_d_prev_A = 0.0f;
    st->v_q_mem_V[0] = st->v_q_mem_V[1] = 0.0f;
    st->v_d_mem_V[0] = st->v_d_mem_V[1] = 0.0f;
    st->v_q_raw_V = 0.0f;
    st->v_d_raw_V = 0.0f;
}

void you2019_deadbeat_step(you2019_deadbeat_state_t *st, float id_ref_A, float iq_ref_A, float id_A, float iq_A,
                           float *v_d_V, float *v_q_V)
{
    const float e_q = iq_ref_A - iq_A;
    const float e_d = id_ref_A - id_A;
    /* You 2019 Eq. 17:
     * v*q(k) = v*q(k-2) + K1q (i*q(k) - iq(k)) - K2q (i*q(k-1) - iq(k-1)) */
    st->v_q_raw_V = you2019_deadbeat_law(st->v_q_mem_V[1], st->K1q_V_A, st->K2q_V_A, e_q, st->e_q_prev_A);
    /* You 2019 Eq. 19 (d axis, same structure) */
    st->v_d_raw_V = you2019_deadbeat_law(st->v_d_mem_V[1], st->K1d_V_A, st->K2d_V_A, e_d, st->e_d_prev_A);
    st->e_q_prev_A = e_q;
    st->e_d_prev_A = e_d;
    *v_q_V = st->v_q_raw_V;
    *v_d_V = st->v_d_raw_V;
}

void you2019_deadbeat_commit(uint8_t limited_memory, you2019_deadbeat_state_t *st, float v_d_applied_V,
                             float v_q_applied_V)
{
    float vq = st->v_q_raw_V;
    float vd = st->v_d_raw_V;
    if (limited_memory == (uint8_t)YOU2019_DEADBEAT_MEMORY_LIMITED) {
        /* memory = decoupled voltage really applied (You 2019 Eq. 33 then Eq. 35) */
        vq = v_q_applied_V;
        vd = v_d_applied_V;
    }
    st->v_q_mem_V[1] = st->v_q_mem_V[0];
    st->v_q_mem_V[0] = vq;
    st->v_d_mem_V[1] = st->v_d_mem_V[0];
    st->v_d_mem_V[0] = vd;
}
