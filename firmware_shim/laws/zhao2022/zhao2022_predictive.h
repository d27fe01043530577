/* zhao2022_predictive.h - Zhao 2022 baseline: conventional one-step
 * predictive (deadbeat) current controller from the forward-Euler model
 * (Zhao et al., Machines 2022), Sec. 2.2, Eq. 3-6.
 *
 *   ud(k) = R^ id(k) + L^/Ts (id* - id(k)) - w L^ iq(k)            (Eq. 5)
 *   uq(k) = R^ iq(k) + L^/Ts (iq* - iq(k)) + w L^ id(k) + w psi^   (Eq. 6)
 *
 * As in the paper's "conventional" controller the computation/PWM delay is
 * NOT compensated: the law assumes its output acts over [k, k+1], while on
 * the bench (and in Zhao 2022 Fig. 2) the command computed at k acts over
 * [k+1, k+2].  That mismatch is what the comparison with the incremental
 * law (zhao2022_incremental.h) is about; do not "fix" it here.
 *
 * Memory-less apart from the trace; no integral action, so errors of
 * R^ and psi^ leave a steady-state current error (test_zhao2022_flux.c). */
#ifndef ZHAO2022_PREDICTIVE_H
#define ZHAO2022_PREDICTIVE_H

#include <stdint.h>

typedef struct {
    float R_hat_ohm;  /* R0 (Zhao 2022 Table 1: 48.9) */
    float L_hat_H;    /* L0 = Ld = Lq (Table 1: 14e-3) */
    float psi_hat_Wb; /* permanent-magnet flux for the w psi back-EMF term */
    float Ts_s;       /* current period (100e-6) */
    float Vmax_V;     /* radius of the dq voltage circle; <= 0: no limit */
} zhao2022_predictive_config_t;

typedef struct {
    /* copies / derived from the config */
    float R_hat_ohm, L_hat_H, psi_hat_Wb, Vmax_V;
    float G_V_A; /* L0/Ts (= B^-1 of Zhao 2022 Eq. 3/4) */
    /* trace of the last step */
    float v_d_ff_V, v_q_ff_V;   /* speed terms: -w L iq, w L id + w psi */
    float v_d_raw_V, v_q_raw_V; /* Zhao 2022 Eq. 5/6 before the limit */
    float v_d_V, v_q_V;         /* returned (limited) command */
    uint8_t limited;
    uint32_t n_steps;
} zhao2022_predictive_state_t;

/* Returns 0, or -1 when L_hat_H <= 0 or Ts_s <= 0 (state zeroed). */
int zhao2022_predictive_init(const zhao2022_predictive_config_t *cfg, zhao2022_predictive_state_t *st);
/* Clears the trace (the law itself has no memory). */
void zhao2022_predictive_reset(zhao2022_predictive_state_t *st);
/* One current period: references id*, iq* [A] (the paper's i_ref(k+1)),
 * measured id(k), iq(k) [A], electrical speed w [rad/s]; returns u(k) [V],
 * limited to Vmax (radially). */
void zhao2022_predictive_step(zhao2022_predictive_state_t *st, float id_ref_A, float iq_ref_A, float id_A, float iq_A,
                              float omega_e_rad_s, float *v_d_V, float *v_q_V);

#endif
