/* you2019_identification.h - You 2019 Sec. 6: online deadbeat gain
 * identification (Eq. 22-32, Eq. 34-35), per axis.
 *
 * Eq. 31 correction: the paper prints B_hat = 1 / K2_bar, which contradicts
 * its own definitions K1 = 1/B and K2 = A/B (Eq. 17/23).  We use
 *   A_hat = K2_bar / K1_bar   (Eq. 30)
 *   B_hat = 1 / K1_bar        (Eq. 31 corrected)
 *   L_hat = -Ts R_hat / ln(A_hat)   (Eq. 32)
 *
 * Identification voltage: v(k-2), v(k-3) are the DECOUPLED voltages that
 * were actually applied, v* = v_limited - v_ff (Eq. 35 generalised to both
 * axes).  At speed the rotor-frame plant is
 *   L di/dt = v - R i - e,   e_q = w L_d i_d + w psi,  e_d = -w L_q i_q,
 * and with e constant over a period the exact discretisation is
 *   i(k) = A i(k-1) + B (v(k-2) - e),
 * so Eq. 22 holds for v - e; subtracting the feed-forward of Eq. 4 is the
 * right thing to do and leaves only the feed-forward error (psi_hat, L_hat
 * mismatch, and the w Ts rotation of the stator-frame-held vector) as a bias
 * term in Eq. 23. */
#ifndef YOU2019_IDENTIFICATION_H
#define YOU2019_IDENTIFICATION_H

#include <stdbool.h>
#include <stdint.h>

#define YOU2019_IDENTIFICATION_MAX_WINDOW 16u

typedef struct {
    uint8_t enable;          /* tuning switch (default 0) */
    float det_threshold_A2;  /* You 2019 Eq. 27 threshold, default 0.2 A^2
                              * (Sec. 7) */
    uint8_t average_m;       /* You 2019 Eq. 28-29 m, default 8, max 16 */
    uint8_t separate_d_axis; /* 0 (default, paper): copy q gains to d */
} you2019_identification_config_t;

typedef struct {
    /* history: i(k-1), i(k-2); v(k-1), v(k-2) (decoupled applied voltage) */
    float i_hist_A[2];
    float v_hist_V[2];
    float v_km3_V; /* v(k-3) at the next sample */
    /* latest You 2019 Eq. 24/25 result */
    float det_A2;
    float K1_hat_V_A, K2_hat_V_A;
    uint8_t accepted; /* latest identification passed You 2019 Eq. 27 */
    uint8_t primed;   /* number of valid history samples (max 3) */
    /* window of accepted identifications (ring) */
    float win_K1[YOU2019_IDENTIFICATION_MAX_WINDOW];
    float win_K2[YOU2019_IDENTIFICATION_MAX_WINDOW];
    float win_absdet[YOU2019_IDENTIFICATION_MAX_WINDOW];
    uint8_t win_count, win_head;
    /* You 2019 Eq. 28-32 results */
    float K1_bar_V_A, K2_bar_V_A;
    float A_hat, B_hat_A_Vs, L_hat_H, R_id_ohm;
    uint32_t n_identified, n_updates;
} you2019_identification_axis_state_t;

typedef struct {
    you2019_identification_axis_state_t q;
    you2019_identification_axis_state_t d;
} you2019_identification_state_t;

void you2019_identification_reset_axis(you2019_identification_axis_state_t *ax);
void you2019_identification_reset(you2019_identification_state_t *st);

/* Pure You 2019 Eq. 24/25 solve.  Returns det(i) (Eq. 25). */
float you2019_identification_solve(float i_k, float i_km1, float i_km2, float v_km2, float v_km3, float *K1, float *K2);

/* One current period: sampled current i(k) and the decoupled voltage v*(k)
 * actually applied (computed at k, acting over [k+1, k+2]). Identifies with
 * i(k), i(k-1), i(k-2), v(k-2), v(k-3), then pushes i(k), v(k). */
void you2019_identification_sample(const you2019_identification_config_t *cfg, you2019_identification_axis_state_t *ax,
                                   float i_A, float v_applied_V);

/* Speed-loop rate: det-weighted averages You 2019 Eq. 28-29 and Eq. 30-32.  Returns
 * true when a new, physically valid (K1 > 0, 0 < A < 1) set is available in
 * ax->K1_bar..L_hat.  Clears the window. */
bool you2019_identification_average(const you2019_identification_config_t *cfg, you2019_identification_axis_state_t *ax,
                                    float Ts_s, float R_hat_ohm);

#endif
