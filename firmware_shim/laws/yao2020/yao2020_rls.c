/* yao2020_rls.c - Yao 2020 Eq. 46-48 RLS baseline. */
#include "yao2020_rls.h"

#include <math.h>
#include <string.h>

#include "yao2020_model.h"

void yao2020_rls_default_config(yao2020_rls_config_t *cfg)
{
    cfg->Ts_s = 100e-6f;
    cfg->psi_hat_Wb = 0.12f;
    cfg->lambda = 0.995f;
    cfg->P0_x = 1e-2f;
    cfg->P0_y = 1e-4f;
}

void yao2020_rls_init(const yao2020_rls_config_t *cfg, yao2020_rls_state_t *st, float R0_ohm, float L0_H)
{
    memset(st, 0, sizeof(*st));
    yao2020_model_t m;
    yao2020_model_compute(R0_ohm, L0_H, 0.0f, cfg->Ts_s, &m);
    st->x_hat = m.x;
    st->y_hat = m.y;
    st->P11 = cfg->P0_x;
    st->P22 = cfg->P0_y;
    st->R_hat_ohm = R0_ohm;
    st->L_hat_H = L0_H;
}

void yao2020_rls_update(const yao2020_rls_config_t *cfg, yao2020_rls_state_t *st, float id_A, float iq_A, float vd_V,
                        float vq_V, float w_rad_s)
{
    if (st->primed != 0u) {
        const float T = cfg->Ts_s;
        const float wT = st->w * T;
        const float c = cosf(wT), s = sinf(wT);
        /* G2_hat from the current estimates (Yao 2020 Eq. 6 with Eq. 48) */
        yao2020_model_t m;
        yao2020_model_compute(st->R_hat_ohm, st->L_hat_H, st->w, T, &m);
        const float e = st->w * cfg->psi_hat_Wb;
        /* Yao 2020 Eq. 47: y = Tr^-1 i(k) - G2_hat e(k-1) */
        const float yd = (c * id_A - s * iq_A) - (-m.d2 * e);
        const float yq = (s * id_A + c * iq_A) - (m.d1 * e);
        /* phi = [[id iq],[vd vq]] (params x outputs), phi^T theta = x i + y v */
        const float a11 = st->i_d, a12 = st->i_q; /* phi row x */
        const float a21 = st->v_d, a22 = st->v_q; /* phi row y */
        /* Yao 2020 Eq. 46: eps = y - phi^T theta */
        st->eps_d = yd - (a11 * st->x_hat + a21 * st->y_hat);
        st->eps_q = yq - (a12 * st->x_hat + a22 * st->y_hat);
        /* B = P phi (2x2) */
        const float b11 = st->P11 * a11 + st->P12 * a21;
        const float b12 = st->P11 * a12 + st->P12 * a22;
        const float b21 = st->P12 * a11 + st->P22 * a21;
        const float b22 = st->P12 * a12 + st->P22 * a22;
        /* S = lambda I + phi^T P phi */
        const float s11 = cfg->lambda + a11 * b11 + a21 * b21;
        const float s12 = a11 * b12 + a21 * b22;
        const float s22 = cfg->lambda + a12 * b12 + a22 * b22;
        const float det = s11 * s22 - s12 * s12;
        if (det > 0.0f) {
            const float id = 1.0f / det;
            const float si11 = s22 * id, si12 = -s12 * id, si22 = s11 * id;
            /* K = P phi S^-1 */
            const float k11 = b11 * si11 + b12 * si12;
            const float k12 = b11 * si12 + b12 * si22;
            const float k21 = b21 * si11 + b22 * si12;
            const float k22 = b21 * si12 + b22 * si22;
            st->x_hat += k11 * st->eps_d + k12 * st->eps_q;
            st->y_hat += k21 * st->eps_d + k22 * st->eps_q;
            /* P = (I - K phi^T) P / lambda = (P - K B^T) / lambda, symmetrised */
            const float il = 1.0f / cfg->lambda;
            const float n11 = (st->P11 - (k11 * b11 + k12 * b12)) * il;
            const float n12 = (st->P12 - 0.5f * ((k11 * b21 + k12 * b22) + (k21 * b11 + k22 * b12))) * il;
            const float n22 = (st->P22 - (k21 * b21 + k22 * b22)) * il;
            st->P11 = n11;
            st->P12 = n12;
            st->P22 = n22;
        }
        /* Yao 2020 Eq. 48 */
        if (st->x_hat > 0.0f && st->x_hat < 1.0f && st->y_hat > 0.0f) {
            const float R = (1.0f - st->x_hat) / st->y_hat;
            const float L = -R * T / logf(st->x_hat);
            if (R > 0.0f && L > 0.0f) {
                st->R_hat_ohm = R;
                st->L_hat_H = L;
            }
        }
        st->n_updates++;
    }
    st->i_d = id_A;
    st->i_q = iq_A;
    st->v_d = vd_V;
    st->v_q = vq_V;
    st->w = w_rad_s;
    st->primed = 1u;
}
