/* yao2020_model.c - Yao 2020 fully discretised model (Eq. 4-7); see
 * yao2020_model.h.
 *
 * Complex notation used in the comments: a dq (or alpha-beta) 2-vector
 * [a b] is the complex number a + j b.  Then Tr = exp(-j w T), Tr^-1 =
 * exp(+j w T), G1 = x, H1 = y, G2 = d1 + j d2, G = x Tr, H = y Tr,
 * F = Tr G2. */
#include "yao2020_model.h"

#include <math.h>

/* Yao 2020 Eq. 5-6 (ZOH of the augmented alpha-beta model Eq. 3):
 *   x  = exp(-R T / L),  y = (1 - x) / R
 *   d1 = ((x - cos wT) R - sin wT  w L) / (R^2 + w^2 L^2)
 *   d2 = -((x - cos wT) w L + sin wT R) / (R^2 + w^2 L^2)
 * i.e. G2 = d1 + j d2 = (x - exp(j w T)) / (R + j w L)   (derived: the
 * integral -1/L int_0^T exp(-R/L (T - t)) exp(j w t) dt; it reproduces
 * Eq. 6 exactly).  y uses expm1f so that it stays accurate for small R T/L,
 * and tends to T/L for R -> 0. */
void yao2020_model_compute(float R_ohm, float L_H, float w_rad_s, float Ts_s, yao2020_model_t *m)
{
    const float a = Ts_s * R_ohm / L_H;
    const float one_minus_x = -expm1f(-a);
    m->x = 1.0f - one_minus_x;
    m->y = (R_ohm > 1e-9f) ? one_minus_x / R_ohm : Ts_s / L_H;
    const float wT = w_rad_s * Ts_s;
    m->c = cosf(wT);
    m->s = sinf(wT);
    const float wL = w_rad_s * L_H;
    const float den = R_ohm * R_ohm + wL * wL;
    const float xc = m->x - m->c;
    if (den > 0.0f) {
        const float inv = 1.0f / den;
        m->d1 = (xc * R_ohm - m->s * wL) * inv;
        m->d2 = -(xc * wL + m->s * R_ohm) * inv;
    } else {
        m->d1 = -m->y; /* R = w = 0 limit: G2 = -T/L */
        m->d2 = 0.0f;
    }
}
