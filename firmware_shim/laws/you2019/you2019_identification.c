/* you2019_identification.c - You 2019 Eq. 22-32. */
#include "you2019_identification.h"

#include <math.h>
#include <string.h>

void you2019_identification_reset_axis(you2019_identification_axis_state_t *ax) { memset(ax, 0, sizeof(*ax)); }

void you2019_identification_reset(you2019_identification_state_t *st)
{
    you2019_identification_reset_axis(&st->q);
    you2019_identification_reset_axis(&st->d);
}

float you2019_identification_solve(float i_k, float i_km1, float i_km2, float v_km2, float v_km3, float *K1, float *K2)
{
    /* You 2019 Eq. 22: i(k)   = B v(k-2) + A i(k-1)
     *                  i(k-1) = B v(k-3) + A i(k-2)
     * Eq. 23: [ i(k)   -i(k-1) ] [K1]   [v(k-2)]
     *         [ i(k-1) -i(k-2) ] [K2] = [v(k-3)]
     * Eq. 25: det = i(k-1)^2 - i(k) i(k-2)  (determinant of the Eq. 23 matrix)
     * Eq. 24: inverse of the 2x2 matrix:
     *   K1 = (-i(k-2) v(k-2) + i(k-1) v(k-3)) / det
     *   K2 = (-i(k-1) v(k-2) + i(k)   v(k-3)) / det */
    const float det = i_km1 * i_km1 - i_k * i_km2;
    if (det != 0.0f) {
        const float inv = 1.0f / det;
        *K1 = (i_km1 * v_km3 - i_km2 * v_km2) * inv;
        *K2 = (i_k * v_km3 - i_km1 * v_km2) * inv;
    } else {
        *K1 = 0.0f;
        *K2 = 0.0f;
    }
    return det;
}

void you2019_identification_sample(const you2019_identification_config_t *cfg, you2019_identification_axis_state_t *ax,
                                   float i_A, float v_applied_V)
{
    ax->accepted = 0u;
    if (ax->primed >= 3u) {
        float K1, K2;
        /* at sample k: v_hist[0] = v(k-1) (unused), v_hist[1] = v(k-2),
         * v_km3 = v(k-3) */
        const float det =
            you2019_identification_solve(i_A, ax->i_hist_A[0], ax->i_hist_A[1], ax->v_hist_V[1], ax->v_km3_V, &K1, &K2);
        ax->det_A2 = det;
        ax->K1_hat_V_A = K1;
        ax->K2_hat_V_A = K2;
        /* You 2019 Eq. 27: identify only when |det| > det_thres */
        if (fabsf(det) > cfg->det_threshold_A2) {
            uint8_t m = cfg->average_m;
            if (m < 1u) m = 1u;
            if (m > YOU2019_IDENTIFICATION_MAX_WINDOW) m = (uint8_t)YOU2019_IDENTIFICATION_MAX_WINDOW;
            if (ax->win_head >= m) ax->win_head = 0u;
            ax->win_K1[ax->win_head] = K1;
            ax->win_K2[ax->win_head] = K2;
            ax->win_absdet[ax->win_head] = fabsf(det);
            ax->win_head = (uint8_t)(ax->win_head + 1u);
            if (ax->win_count < m) ax->win_count = (uint8_t)(ax->win_count + 1u);
            ax->accepted = 1u;
            ax->n_identified++;
        }
    } else {
        ax->primed = (uint8_t)(ax->primed + 1u);
    }
    ax->v_km3_V = ax->v_hist_V[1];
    ax->v_hist_V[1] = ax->v_hist_V[0];
    ax->v_hist_V[0] = v_applied_V;
    ax->i_hist_A[1] = ax->i_hist_A[0];
    ax->i_hist_A[0] = i_A;
}

bool you2019_identification_average(const you2019_identification_config_t *cfg, you2019_identification_axis_state_t *ax,
                                    float Ts_s, float R_hat_ohm)
{
    (void)cfg;
    if (ax->win_count == 0u) {
        return false;
    }
    float s1 = 0.0f, s2 = 0.0f, sw = 0.0f;
    for (uint8_t y = 0u; y < ax->win_count; ++y) {
        s1 += ax->win_K1[y] * ax->win_absdet[y];
        s2 += ax->win_K2[y] * ax->win_absdet[y];
        sw += ax->win_absdet[y];
    }
    ax->win_count = 0u;
    ax->win_head = 0u;
    if (!(sw > 0.0f)) {
        return false;
    }
    /* You 2019 Eq. 28: K1_bar = sum K1_y |det_y| / sum |det_y| */
    const float K1b = s1 / sw;
    /* You 2019 Eq. 29: K2_bar = sum K2_y |det_y| / sum |det_y| */
    const float K2b = s2 / sw;
    if (!(K1b > 0.0f) || !(K2b > 0.0f)) {
        return false;
    }
    /* You 2019 Eq. 30: A_hat = K2_bar / K1_bar */
    const float A = K2b / K1b;
    if (!(A > 0.0f && A < 1.0f)) {
        return false;
    }
    ax->K1_bar_V_A = K1b;
    ax->K2_bar_V_A = K2b;
    ax->A_hat = A;
    /* You 2019 Eq. 31, corrected: B_hat = 1 / K1_bar (printed 1/K2_bar is
     * inconsistent with K1 = 1/B of Eq. 17/23). */
    ax->B_hat_A_Vs = 1.0f / K1b;
    /* You 2019 Eq. 32: L_hat = -Ts r_s / ln(A_hat), r_s = configured R_hat */
    ax->L_hat_H = -Ts_s * R_hat_ohm / logf(A);
    /* for tracing only: resistance implied by the identified gains,
     * R = (1 - A)/B = K1_bar - K2_bar */
    ax->R_id_ohm = K1b - K2b;
    ax->n_updates++;
    return true;
}
