/* outer_loops.c - You 2019 Sec. 3.1 P-PI servo loops. */
#include "outer_loops.h"

#include <math.h>

#include "dq_math.h"

void outer_loops_design(const outer_loops_config_t *cfg, outer_loops_state_t *st, float pole_pairs, float psi_hat_Wb,
                        float J_hat_kgm2)
{
    /* torque constant for id = 0: T = 1.5 p psi iq */
    st->Kt_Nm_A = 1.5f * pole_pairs * psi_hat_Wb;
    const float ww = DQ_TWO_PI_F * cfg->speed_bandwidth_Hz;
    st->Kp_w_A_s_rad = st->Kt_Nm_A > 0.0f ? ww * J_hat_kgm2 / st->Kt_Nm_A : 0.0f;
    st->Ki_w_A_rad = st->Kp_w_A_s_rad * ww * cfg->speed_pi_zero_ratio;
    st->Kp_p_1_s = DQ_TWO_PI_F * cfg->position_bandwidth_Hz;
}

void outer_loops_reset(outer_loops_state_t *st)
{
    st->theta_prev_rad = 0.0f;
    st->theta_unwrapped_rad = 0.0f;
    st->omega_m_rad_s = 0.0f;
    st->omega_ref_rad_s = 0.0f;
    st->integ_A = 0.0f;
    st->iq_ref_A = 0.0f;
    st->pos_ref_rad = 0.0f;
    st->vel_ref_rad_s = 0.0f;
    st->initialised = 0u;
}

void outer_loops_measure(outer_loops_state_t *st, float theta_m_rad, float T_s)
{
    if (st->initialised == 0u) {
        st->theta_prev_rad = theta_m_rad;
        st->theta_unwrapped_rad = theta_m_rad;
        st->pos_ref_rad = theta_m_rad;
        st->initialised = 1u;
        st->omega_m_rad_s = 0.0f;
        return;
    }
    const float d = dq_wrap_pi(theta_m_rad - st->theta_prev_rad);
    st->theta_prev_rad = theta_m_rad;
    st->theta_unwrapped_rad += d;
    st->omega_m_rad_s = d / T_s;
}

void outer_loops_profile(const outer_loops_config_t *cfg, outer_loops_state_t *st, float target_rad, float T_s)
{
    const float a = cfg->profile_accel_rad_s2;
    const float vmax = cfg->profile_speed_rad_s;
    const float dist = target_rad - st->pos_ref_rad;
    const float sgn = dist >= 0.0f ? 1.0f : -1.0f;
    /* fastest speed from which we can still stop at the target */
    float v_stop = sqrtf(2.0f * a * fabsf(dist));
    float v_des = sgn * (v_stop < vmax ? v_stop : vmax);
    float dv = v_des - st->vel_ref_rad_s;
    const float dv_max = a * T_s;
    if (dv > dv_max) dv = dv_max;
    if (dv < -dv_max) dv = -dv_max;
    float v = st->vel_ref_rad_s + dv;
    float step = v * T_s;
    if (fabsf(step) >= fabsf(dist) && fabsf(v) <= dv_max * 1.5f) {
        st->pos_ref_rad = target_rad; /* arrived */
        st->vel_ref_rad_s = 0.0f;
        return;
    }
    st->vel_ref_rad_s = v;
    st->pos_ref_rad += step;
}

float outer_loops_position(outer_loops_state_t *st)
{
    /* proportional position loop + profile velocity feed-forward */
    return st->Kp_p_1_s * (st->pos_ref_rad - st->theta_unwrapped_rad) + st->vel_ref_rad_s;
}

float outer_loops_speed(const outer_loops_config_t *cfg, outer_loops_state_t *st, float omega_ref_rad_s, float T_s)
{
    st->omega_ref_rad_s = omega_ref_rad_s;
    const float e = omega_ref_rad_s - st->omega_m_rad_s;
    const float integ_prev = st->integ_A;
    st->integ_A += st->Ki_w_A_rad * T_s * e;
    float iq = st->Kp_w_A_s_rad * e + st->integ_A;
    const float lim = cfg->iq_limit_A;
    if (iq > lim || iq < -lim) {
        /* clamping anti-windup */
        if ((iq > lim && e > 0.0f) || (iq < -lim && e < 0.0f)) {
            st->integ_A = integ_prev;
        }
        iq = iq > lim ? lim : -lim;
    }
    st->iq_ref_A = iq;
    return iq;
}
