/* zhao2022_predictive.c - Zhao 2022 conventional forward-Euler predictive
 * current controller (Sec. 2.2, Eq. 3-6), the baseline of the comparison. */
#include "zhao2022_predictive.h"

#include <string.h>

#include "dq_math.h"

int zhao2022_predictive_init(const zhao2022_predictive_config_t *cfg, zhao2022_predictive_state_t *st)
{
    memset(st, 0, sizeof(*st));
    if (!(cfg->L_hat_H > 0.0f) || !(cfg->Ts_s > 0.0f)) {
        return -1;
    }
    st->R_hat_ohm = cfg->R_hat_ohm;
    st->L_hat_H = cfg->L_hat_H;
    st->psi_hat_Wb = cfg->psi_hat_Wb;
    st->Vmax_V = cfg->Vmax_V;
    /* Zhao 2022 Eq. 3: B = diag(Ts/Ls) -> B^-1 = Ls/Ts (Eq. 4) */
    st->G_V_A = cfg->L_hat_H / cfg->Ts_s;
    return 0;
}

void zhao2022_predictive_reset(zhao2022_predictive_state_t *st)
{
    st->v_d_ff_V = st->v_q_ff_V = 0.0f;
    st->v_d_raw_V = st->v_q_raw_V = 0.0f;
    st->v_d_V = st->v_q_V = 0.0f;
    st->limited = 0u;
    st->n_steps = 0u;
}

void zhao2022_predictive_step(zhao2022_predictive_state_t *st, float id_ref_A, float iq_ref_A, float id_A, float iq_A,
                              float omega_e_rad_s, float *v_d_V, float *v_q_V)
{
    const float wL = omega_e_rad_s * st->L_hat_H;
    /* Zhao 2022 Eq. 4 = B^-1 (X_ref(k+1) - A(k) X(k) - d(k)) with Eq. 3's
     * A = [1 - Ts R/L, Ts w; -Ts w, 1 - Ts R/L], d = [0; -Ts psi w / L]:
     * speed-dependent part first (Eq. 5: -w L iq; Eq. 6: +w L id + w psi) */
    st->v_d_ff_V = -wL * iq_A;
    st->v_q_ff_V = wL * id_A + omega_e_rad_s * st->psi_hat_Wb;
    /* Zhao 2022 Eq. 5: ud(k) = R id(k) + L/Ts (id*(k+1) - id(k)) - w L iq(k) */
    float vd = st->R_hat_ohm * id_A + st->G_V_A * (id_ref_A - id_A) + st->v_d_ff_V;
    /* Zhao 2022 Eq. 6: uq(k) = R iq(k) + L/Ts (iq*(k+1) - iq(k)) + w L id(k)
     *                          + w psi */
    float vq = st->R_hat_ohm * iq_A + st->G_V_A * (iq_ref_A - iq_A) + st->v_q_ff_V;
    st->v_d_raw_V = vd;
    st->v_q_raw_V = vq;
    /* Zhao 2022 Sec. 5.1: command restricted to the voltage circle */
    st->limited = dq_limit_voltage_radial(&vd, &vq, st->Vmax_V);
    st->v_d_V = vd;
    st->v_q_V = vq;
    st->n_steps++;
    *v_d_V = vd;
    *v_q_V = vq;
}
