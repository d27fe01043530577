/* zhao2022_incremental.c - Zhao 2022 incremental deadbeat current controller
 * (bilinear discretisation, two-period delay), Sec. 4.1 Eq. 14-23.
 *
 * Derivation check (done by hand from Eq. 1-2, not copied from the text):
 *  Eq. 18 is the trapezoidal rule over the two periods [k, k+2] for the R i
 *  and w L i terms, while the voltage integral is exact for the
 *  zero-order-hold inverter (u(k) over [k,k+1], u(k+1) over [k+1,k+2]):
 *    L (iq(k+2) - iq(k))/Ts = -R (iq(k) + iq(k+2)) + (uq(k) + uq(k+1))
 *                             - w L (id(k) + id(k+2)) - 2 w psi
 *  Eq. 20 sets i(k+2) = i*, Eq. 21 is Eq. 18 shifted to [k-2, k]; Eq. 20
 *  minus Eq. 21 eliminates psi and id(k) (same w in both), solved for
 *  uq(k+1):
 *    uq(k+1) = L/Ts (iq* - 2 iq(k) + iq(k-2)) + R (iq* - iq(k-2))
 *              - uq(k) + uq(k-1) + uq(k-2) + w L (id* - id(k-2))
 *  and L/Ts (iq* - 2 iq(k) + iq(k-2)) = L/Ts (iq* - iq(k-2))
 *  - 2 L/Ts (iq(k) - iq(k-2)), which is the printed Eq. 22.  The d axis
 *  (did/dt = (ud - R id + w L iq)/L) gives Eq. 23 with -w L (iq* - iq(k-2)).
 *  The extracted text of Eq. 16 is garbled ("U ... q(k+1) = u_q(k)"); it is
 *  read as "the voltage is held over the period" which is what Eq. 17 uses.
 *
 * In complex form (i = id + j iq) both axes are
 *    u(k+1) = (K1 + j w L0)(i* - i(k-2)) - K2 (i(k) - i(k-2))
 *             - u(k) + u(k-1) + u(k-2),   K1 = R0 + L0/Ts, K2 = 2 L0/Ts. */
#include "zhao2022_incremental.h"

#include <string.h>

#include "dq_math.h"

int zhao2022_incremental_init(const zhao2022_incremental_config_t *cfg, zhao2022_incremental_state_t *st)
{
    memset(st, 0, sizeof(*st));
    if (!(cfg->L_hat_H > 0.0f) || !(cfg->Ts_s > 0.0f) || !(cfg->R_hat_ohm >= 0.0f)) {
        return -1;
    }
    /* Zhao 2022 Eq. 22/23: coefficients of (i* - i(k-2)) and (i(k) - i(k-2)) */
    st->K1_V_A = cfg->R_hat_ohm + cfg->L_hat_H / cfg->Ts_s;
    st->K2_V_A = 2.0f * cfg->L_hat_H / cfg->Ts_s;
    st->L_hat_H = cfg->L_hat_H;
    st->Vmax_V = cfg->Vmax_V;
    return 0;
}

void zhao2022_incremental_reset(zhao2022_incremental_state_t *st)
{
    st->i_d_hist_A[0] = st->i_d_hist_A[1] = 0.0f;
    st->i_q_hist_A[0] = st->i_q_hist_A[1] = 0.0f;
    for (int n = 0; n < 3; ++n) {
        st->u_d_hist_V[n] = 0.0f;
        st->u_q_hist_V[n] = 0.0f;
    }
    st->v_d_raw_V = st->v_q_raw_V = 0.0f;
    st->v_d_V = st->v_q_V = 0.0f;
    st->limited = 0u;
    st->n_steps = 0u;
}

void zhao2022_incremental_step(zhao2022_incremental_state_t *st, float id_ref_A, float iq_ref_A, float id_A, float iq_A,
                               float omega_e_rad_s, float *v_d_V, float *v_q_V)
{
    const float id_km2 = st->i_d_hist_A[1];
    const float iq_km2 = st->i_q_hist_A[1];
    const float wL = omega_e_rad_s * st->L_hat_H;

    /* Zhao 2022 Eq. 23 (d axis):
     * ud(k+1) = (R + L/Ts)(id* - id(k-2)) - 2L/Ts (id(k) - id(k-2))
     *           - ud(k) + ud(k-2) + ud(k-1) - w L (iq* - iq(k-2)) */
    float vd = zhao2022_incremental_law(st->K1_V_A, st->K2_V_A, id_ref_A, id_A, id_km2, st->u_d_hist_V[0],
                                        st->u_d_hist_V[1], st->u_d_hist_V[2]) -
               wL * (iq_ref_A - iq_km2);
    /* Zhao 2022 Eq. 22 (q axis):
     * uq(k+1) = (R + L/Ts)(iq* - iq(k-2)) - 2L/Ts (iq(k) - iq(k-2))
     *           - uq(k) + uq(k-2) + uq(k-1) + w L (id* - id(k-2)) */
    float vq = zhao2022_incremental_law(st->K1_V_A, st->K2_V_A, iq_ref_A, iq_A, iq_km2, st->u_q_hist_V[0],
                                        st->u_q_hist_V[1], st->u_q_hist_V[2]) +
               wL * (id_ref_A - id_km2);
    st->v_d_raw_V = vd;
    st->v_q_raw_V = vq;

    /* Zhao 2022 Sec. 5.1: the command is restricted to the inverter's
     * voltage circle (radial scaling keeps the direction). */
    st->limited = dq_limit_voltage_radial(&vd, &vq, st->Vmax_V);

    /* shift the histories: u(k+1) becomes the next step's u(k) */
    st->u_d_hist_V[2] = st->u_d_hist_V[1];
    st->u_d_hist_V[1] = st->u_d_hist_V[0];
    st->u_d_hist_V[0] = vd;
    st->u_q_hist_V[2] = st->u_q_hist_V[1];
    st->u_q_hist_V[1] = st->u_q_hist_V[0];
    st->u_q_hist_V[0] = vq;
    st->i_d_hist_A[1] = st->i_d_hist_A[0];
    st->i_d_hist_A[0] = id_A;
    st->i_q_hist_A[1] = st->i_q_hist_A[0];
    st->i_q_hist_A[0] = iq_A;

    st->v_d_V = vd;
    st->v_q_V = vq;
    st->n_steps++;
    *v_d_V = vd;
    *v_q_V = vq;
}
