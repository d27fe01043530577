/* you2019_deadbeat.h - You 2019 z-domain deadbeat current controller, Sec. 4
 * (Eq. 2-3 model gains, Eq. 16-19 control law). */
#ifndef YOU2019_DEADBEAT_H
#define YOU2019_DEADBEAT_H

#include <stdint.h>

/* What the controller memory v*(k-2) of You 2019 Eq. 17/19 holds.
 * UNLIMITED (default): the raw controller output.  This is the reading that
 *   reproduces You 2019 Fig. 9/18b/19b (0->4 A in about 6 periods, the
 *   command "saturates several times", "pulse-wise voltage").
 * LIMITED: the decoupled part of the voltage actually applied (You 2019
 *   Eq. 35).  The law then degenerates to e(k) = A e(k-1) after one saturated
 *   period and the current crawls with the open-loop time constant L/R (~59
 *   periods here).
 * See tests/test_you2019_deadbeat_step.c for the simulation of both readings. */
typedef enum {
    YOU2019_DEADBEAT_MEMORY_UNLIMITED = 0,
    YOU2019_DEADBEAT_MEMORY_LIMITED = 1,
} you2019_deadbeat_memory_t;

typedef struct {
    /* active gains (from R_hat/L_hat or from the online identification) */
    float K1q_V_A, K2q_V_A, K1d_V_A, K2d_V_A;
    /* errors e(k-1) = i*(k-1) - i(k-1) */
    float e_q_prev_A, e_d_prev_A;
    /* controller output memory v*(k-1), v*(k-2) (decoupled part, no feed-forward) */
    float v_q_mem_V[2], v_d_mem_V[2];
    /* last raw output of You 2019 Eq. 17 / Eq. 19 */
    float v_q_raw_V, v_d_raw_V;
} you2019_deadbeat_state_t;

/* You 2019 Eq. 2-3: A = exp(-Ts R/L), B = (1 - A)/R. */
void you2019_deadbeat_model_gains(float Ts_s, float R_ohm, float L_H, float *A, float *B_A_Vs);

/* You 2019 Eq. 17: K1 = 1/B, K2 = A/B. */
void you2019_deadbeat_controller_gains(float A, float B_A_Vs, float *K1_V_A, float *K2_V_A);

/* Pure control law, You 2019 Eq. 17/19. */
static inline float you2019_deadbeat_law(float v_km2_V, float K1_V_A, float K2_V_A, float e_k_A, float e_km1_A)
{
    return v_km2_V + K1_V_A * e_k_A - K2_V_A * e_km1_A;
}

void you2019_deadbeat_reset(you2019_deadbeat_state_t *st);

/* Computes the decoupled controller voltages (You 2019 Eq. 17 and Eq. 19)
 * into st->v_d_raw_V / st->v_q_raw_V and returns them.  Call
 * you2019_deadbeat_commit() afterwards with the decoupled voltage actually
 * applied (after You 2019 Eq. 33). */
void you2019_deadbeat_step(you2019_deadbeat_state_t *st, float id_ref_A, float iq_ref_A, float id_A, float iq_A,
                           float *v_d_V, float *v_q_V);

/* Updates the v*(k-1), v*(k-2) memory according to limited_memory
 * (you2019_deadbeat_memory_t). */
void you2019_deadbeat_commit(uint8_t limited_memory, you2019_deadbeat_state_t *st, float v_d_applied_V,
                             float v_q_applied_V);

#endif
