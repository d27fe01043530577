/* dq_math.h - Clarke/Park transforms and the stator voltage limit.
 * Header-only (static inline), float32, no allocation. */
#ifndef DQ_MATH_H
#define DQ_MATH_H

#include <math.h>
#include <stdint.h>

#define DQ_PI_F 3.14159265358979f
#define DQ_TWO_PI_F 6.28318530717959f
#define DQ_SQRT3_F 1.73205080756888f
#define DQ_INV_SQRT3_F 0.577350269189626f

/* Wrap an angle to [-pi, pi). */
static inline float dq_wrap_pi(float x_rad)
{
    if (x_rad >= DQ_PI_F || x_rad < -DQ_PI_F) {
        x_rad = x_rad - DQ_TWO_PI_F * floorf((x_rad + DQ_PI_F) / DQ_TWO_PI_F);
    }
    return x_rad;
}

/* Amplitude-invariant Clarke from two phase currents (i_a + i_b + i_c = 0). */
static inline void dq_clarke(float i_a_A, float i_b_A, float *i_alpha_A, float *i_beta_A)
{
    *i_alpha_A = i_a_A;
    *i_beta_A = (i_a_A + 2.0f * i_b_A) * DQ_INV_SQRT3_F;
}

/* Amplitude-invariant Clarke from three phase quantities. */
static inline void dq_clarke3(float x_a, float x_b, float x_c, float *x_alpha, float *x_beta)
{
    *x_alpha = (2.0f * x_a - x_b - x_c) * (1.0f / 3.0f);
    *x_beta = (x_b - x_c) * DQ_INV_SQRT3_F;
}

/* Convention: d axis on phase a at theta_e = 0; q leads d by 90 deg. */
static inline void dq_park(float x_alpha, float x_beta, float cos_th, float sin_th, float *x_d, float *x_q)
{
    *x_d = x_alpha * cos_th + x_beta * sin_th;
    *x_q = -x_alpha * sin_th + x_beta * cos_th;
}

static inline void dq_inv_park(float x_d, float x_q, float cos_th, float sin_th, float *x_alpha, float *x_beta)
{
    *x_alpha = x_d * cos_th - x_q * sin_th;
    *x_beta = x_d * sin_th + x_q * cos_th;
}

/* Inverse Clarke to three phases (You 2019 Eq. 7, left matrix, written for our
 * d-on-phase-a convention instead of the paper's q-first ordering). */
static inline void dq_inv_clarke(float x_alpha, float x_beta, float *x_a, float *x_b, float *x_c)
{
    *x_a = x_alpha;
    *x_b = -0.5f * x_alpha + 0.5f * DQ_SQRT3_F * x_beta;
    *x_c = -0.5f * x_alpha - 0.5f * DQ_SQRT3_F * x_beta;
}

/* Scale (v_d, v_q), whose squared magnitude is mag2_V2, to the radius
 * vmax_V (direction kept).  The one radial scaling of both limiters below. */
static inline void dq_scale_to_radius(float *v_d_V, float *v_q_V, float mag2_V2, float vmax_V)
{
    const float s = vmax_V / sqrtf(mag2_V2);
    *v_d_V = *v_d_V * s;
    *v_q_V = *v_q_V * s;
}

/* You 2019 Eq. 33: sqrt(vq^2 + vd^2) <= Vmax.  The paper's You 2019 Eq. 34
 * keeps the d-axis voltage and gives the q axis what remains (d priority);
 * the radial variant scales both.  Returns 1 when the vector was limited. */
static inline uint8_t dq_limit_voltage(float *v_d_V, float *v_q_V, float vmax_V, uint8_t radial)
{
    const float vd = *v_d_V;
    const float vq = *v_q_V;
    const float mag2 = vd * vd + vq * vq;
    if (mag2 <= vmax_V * vmax_V) {
        return 0u;
    }
    if (radial != 0u) {
        dq_scale_to_radius(v_d_V, v_q_V, mag2, vmax_V);
        return 1u;
    }
    /* d priority (You 2019 Eq. 34): clamp d to the circle, q gets
     * +-sqrt(Vmax^2 - vd^2) */
    float vd_l = vd;
    if (vd_l > vmax_V) vd_l = vmax_V;
    if (vd_l < -vmax_V) vd_l = -vmax_V;
    const float rem2 = vmax_V * vmax_V - vd_l * vd_l;
    const float vq_max = rem2 > 0.0f ? sqrtf(rem2) : 0.0f;
    float vq_l = vq;
    if (vq_l > vq_max) vq_l = vq_max;
    if (vq_l < -vq_max) vq_l = -vq_max;
    *v_d_V = vd_l;
    *v_q_V = vq_l;
    return 1u;
}

/* Radial limit of the surface-mounted laws (Yao 2020 DPCC, Zhao 2022
 * incremental and predictive): the command is scaled onto the voltage circle
 * of radius vmax_V.  It differs from dq_limit_voltage(.., radial = 1) in two
 * cases only: vmax_V <= 0 (or NaN) means no limit, and a NaN magnitude passes
 * unlimited (the comparison is "mag2 > Vmax^2", not "!(mag2 <= Vmax^2)").
 * Returns 1 when the vector was scaled. */
static inline uint8_t dq_limit_voltage_radial(float *v_d_V, float *v_q_V, float vmax_V)
{
    if (!(vmax_V > 0.0f)) {
        return 0u;
    }
    const float mag2 = *v_d_V * *v_d_V + *v_q_V * *v_q_V;
    if (!(mag2 > vmax_V * vmax_V)) {
        return 0u;
    }
    dq_scale_to_radius(v_d_V, v_q_V, mag2, vmax_V);
    return 1u;
}

#endif
