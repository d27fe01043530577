/* zhao2022_incremental.h - Zhao 2022 incremental deadbeat current controller
 * from the bilinear (trapezoidal) discretisation with the two-period delay
 * (Zhao, Chen, Wang, Li, Mao, Li, Zhang, Wu, "An Improved Deadbeat Current
 * Controller of PMSM Based on Bilinear Discretization", Machines 2022),
 * Sec. 4.1, Eq. 14-23.
 *
 * Timing (Zhao 2022 Fig. 2, same as drive_core.h): the command returned by
 * zhao2022_incremental_step() at sample k is the paper's u(k+1); it is
 * applied over [k+1, k+2] and first shows in the current sampled at k+2.
 * The paper's u(k) (applied over [k, k+1]) is the command returned at k-1.
 *
 * Control law (Eq. 22 / Eq. 23), complex notation i = id + j iq:
 *   u(k+1) = (R^ + L^/Ts + j w L^) (i* - i(k-2))
 *            - (2 L^/Ts) (i(k) - i(k-2))
 *            - u(k) + u(k-1) + u(k-2)
 * Only R^ and L^ are used: the permanent-magnet flux cancels between Eq. 20
 * and Eq. 21 (constant speed over [k-2, k+2]), so this controller has no
 * psi_hat parameter at all.
 *
 * Voltage memory: u(k), u(k-1), u(k-2) are the voltages ACTUALLY APPLIED
 * (after the Vmax limit), because Eq. 21 is the motor equation over
 * [k-2, k] and holds for the applied voltages; this also makes the law
 * wind-up free.
 *
 * Closed-loop analysis (exact ZOH plant, not the paper's Ts -> 0 limit):
 * see firmware_shim/tests/test_zhao2022_stability.c and
 * docs/analysis/zhao2022_stability.py. */
#ifndef ZHAO2022_INCREMENTAL_H
#define ZHAO2022_INCREMENTAL_H

#include <stdint.h>

typedef struct {
    float R_hat_ohm; /* controller resistance R0 (Zhao 2022 Table 1: 48.9) */
    float L_hat_H;   /* controller inductance L0 = Ld = Lq (Table 1: 14e-3) */
    float Ts_s;      /* current-control period (Zhao 2022 Sec. 5: 100e-6) */
    float Vmax_V;    /* radius of the dq voltage circle; <= 0: no limit */
} zhao2022_incremental_config_t;

typedef struct {
    /* gains derived from the config by zhao2022_incremental_init() */
    float K1_V_A;  /* R0 + L0/Ts   (Zhao 2022 Eq. 22/23, first term) */
    float K2_V_A;  /* 2 L0/Ts      (Zhao 2022 Eq. 22/23, second term) */
    float L_hat_H; /* L0 for the w L0 cross term */
    float Vmax_V;
    /* current history: [0] = i(k-1), [1] = i(k-2) */
    float i_d_hist_A[2], i_q_hist_A[2];
    /* applied-voltage history: [0] = u(k), [1] = u(k-1), [2] = u(k-2)
     * (= commands returned at k-1, k-2, k-3) */
    float u_d_hist_V[3], u_q_hist_V[3];
    /* trace of the last step */
    float v_d_raw_V, v_q_raw_V; /* Zhao 2022 Eq. 22/23 before the limit */
    float v_d_V, v_q_V;         /* returned (limited) command u(k+1) */
    uint8_t limited;            /* 1 when the last command was limited */
    uint32_t n_steps;
} zhao2022_incremental_state_t;

/* Zhao 2022 Eq. 22 (one axis, no cross term), exposed for tests:
 *   u(k+1) = K1 (i* - i(k-2)) - K2 (i(k) - i(k-2)) - u(k) + u(k-1) + u(k-2) */
static inline float zhao2022_incremental_law(float K1_V_A, float K2_V_A, float i_ref_A, float i_k_A, float i_km2_A,
                                             float u_k_V, float u_km1_V, float u_km2_V)
{
    return K1_V_A * (i_ref_A - i_km2_A) - K2_V_A * (i_k_A - i_km2_A) - u_k_V + u_km1_V + u_km2_V;
}

/* Computes the gains and resets the history.  Returns 0, or -1 when
 * L_hat_H <= 0, Ts_s <= 0 or R_hat_ohm < 0 (state then zeroed, gains 0). */
int zhao2022_incremental_init(const zhao2022_incremental_config_t *cfg, zhao2022_incremental_state_t *st);

/* Clears the current and voltage histories (keeps the gains). */
void zhao2022_incremental_reset(zhao2022_incremental_state_t *st);

/* One current period.  Inputs: references id*, iq* [A] (the paper's
 * i_dref/i_qref, wanted at k+2), measured id(k), iq(k) [A], electrical speed
 * w [rad/s].  Output: dq command u(k+1) [V], limited to Vmax (radially). */
void zhao2022_incremental_step(zhao2022_incremental_state_t *st, float id_ref_A, float iq_ref_A, float id_A, float iq_A,
                               float omega_e_rad_s, float *v_d_V, float *v_q_V);

#endif
