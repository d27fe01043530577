/* outer_loops.h - P-PI position/speed loops (You 2019 Sec. 3.1: proportional
 * position, PI velocity, 10 Hz / 100 Hz bandwidths) and a trapezoidal
 * position profile generator.  Executed every speed_loop_divider current
 * periods (You 2019 Table A1: 440 us = 8 x 55 us).
 *
 * Design (rigid body J dw/dt = Kt iq, Kt = 1.5 p psi_hat):
 *   Kp_w = 2 pi f_w J / Kt         [A/(rad/s)]  -> crossover at f_w
 *   Ki_w = Kp_w 2 pi f_w r_z       [A/rad]      PI zero at r_z f_w (r_z = 0.25)
 *   Kp_p = 2 pi f_p                [1/s]        position loop crossover f_p
 * Speed is estimated from the encoder angle difference over one speed
 * period: w_m = wrap(theta(k) - theta(k-N)) / (N Ts). */
#ifndef OUTER_LOOPS_H
#define OUTER_LOOPS_H

#include <stdint.h>

typedef struct {
    /* the drive's Outer loops parameters (0x2203), EDS names */
    float speed_bandwidth_Hz;
    float position_bandwidth_Hz;
    float iq_limit_A;          /* current reference limit */
    float speed_pi_zero_ratio; /* PI zero / speed bandwidth */
    /* the profile of References (0x2202) */
    float profile_speed_rad_s;
    float profile_accel_rad_s2;
} outer_loops_config_t;

typedef struct {
    float Kp_w_A_s_rad, Ki_w_A_rad, Kp_p_1_s, Kt_Nm_A;
    float theta_prev_rad;      /* last encoder angle (wrapped) */
    float theta_unwrapped_rad; /* multi-turn position */
    float omega_m_rad_s;       /* estimated mechanical speed */
    float omega_ref_rad_s;
    float integ_A;
    float iq_ref_A;
    float pos_ref_rad, vel_ref_rad_s; /* profile generator output */
    uint8_t initialised;
} outer_loops_state_t;

void outer_loops_design(const outer_loops_config_t *cfg, outer_loops_state_t *st, float pole_pairs, float psi_hat_Wb,
                        float J_hat_kgm2);
void outer_loops_reset(outer_loops_state_t *st);
/* Speed estimate from the encoder; T_s is the speed-loop period. */
void outer_loops_measure(outer_loops_state_t *st, float theta_m_rad, float T_s);
/* Trapezoidal profile toward target (one speed period). */
void outer_loops_profile(const outer_loops_config_t *cfg, outer_loops_state_t *st, float target_rad, float T_s);
/* Position P: returns speed reference (with profile velocity feed-forward). */
float outer_loops_position(outer_loops_state_t *st);
/* Speed PI with clamping anti-windup: returns iq reference. */
float outer_loops_speed(const outer_loops_config_t *cfg, outer_loops_state_t *st, float omega_ref_rad_s, float T_s);

#endif
