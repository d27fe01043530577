/* yao2020_rls.h - Yao 2020 baseline: recursive-least-squares R/L
 * identification (Sec. VI-B, Eq. 46-48, after Underwood & Husain
 * 2010), on the fully discretised model of Eq. 7.
 *
 * Regression (Eq. 47, derived from Eq. 7 rotated back by Tr^-1):
 *   y(k) = Tr^-1 i(k) - G2_hat e(k-1)            output, 2 x 1
 *   phi^T(k) = [ i(k-1)  v(k-1) ]                 2 x 2 (rows d, q)
 *   theta = [x y]^T,  y(k) = phi^T(k) theta
 * with e = [0, w psi_hat] and G2_hat (Eq. 6) computed from the current
 * estimates via Eq. 48.  The output contains psi_hat, so a wrong psi_hat
 * biases R_hat and L_hat (the point of the comparison).
 * Eq. 48 as extracted prints L = -R T / ln x; read as L_hat = -R_hat T /
 * ln x_hat (R_hat = (1 - x_hat) / y_hat). */
#ifndef YAO2020_RLS_H
#define YAO2020_RLS_H

#include <stdint.h>

typedef struct {
    float Ts_s;       /* default 100e-6 */
    float psi_hat_Wb; /* flux linkage used in the output vector */
    float lambda;     /* forgetting factor, default 0.995 */
    float P0_x, P0_y; /* initial covariance diagonal, default 1e-2, 1e-4 */
} yao2020_rls_config_t;

typedef struct {
    float x_hat, y_hat;          /* theta_est */
    float P11, P12, P22;         /* symmetric covariance */
    float R_hat_ohm, L_hat_H;    /* Yao 2020 Eq. 48 */
    float eps_d, eps_q;          /* Yao 2020 Eq. 46 estimation error */
    float i_d, i_q, v_d, v_q, w; /* previous sample (k-1) */
    uint8_t primed;
    uint32_t n_updates;
} yao2020_rls_state_t;

void yao2020_rls_default_config(yao2020_rls_config_t *cfg);
/* Starts from R0/L0 (theta = [x(R0,L0) y(R0,L0)]). */
void yao2020_rls_init(const yao2020_rls_config_t *cfg, yao2020_rls_state_t *st, float R0_ohm, float L0_H);
/* Sample k: measured i(k), the voltage v(k) applied over [k, k+1] (frame of
 * theta(k)) and w(k). Runs Yao 2020 Eq. 46 with i(k), i(k-1), v(k-1), w(k-1). */
void yao2020_rls_update(const yao2020_rls_config_t *cfg, yao2020_rls_state_t *st, float id_A, float iq_A, float vd_V,
                        float vq_V, float w_rad_s);

#endif
