/*
 * plant_rk4.c - classical RK4 over a period and its sub-steps (plant_rk4.h).
 *
 * Only <math.h>/<string.h>: no OS, no heap, no stdio.
 */
#include "plant_rk4.h"

#include <math.h>
#include <string.h>

#include "plant_angle.h"

void plant_rk4_run(plant_rk4_deriv_fn f, void *ctx, double *y, int n_y, uint32_t n, double h)
{
    double k1[PLANT_RK4_MAX_Y], k2[PLANT_RK4_MAX_Y], k3[PLANT_RK4_MAX_Y], k4[PLANT_RK4_MAX_Y], yt[PLANT_RK4_MAX_Y];
    for (uint32_t it = 0; it < n; ++it) {
        f(ctx, y, k1);
        for (int i = 0; i < n_y; ++i) {
            yt[i] = y[i] + 0.5 * h * k1[i];
        }
        f(ctx, yt, k2);
        for (int i = 0; i < n_y; ++i) {
            yt[i] = y[i] + 0.5 * h * k2[i];
        }
        f(ctx, yt, k3);
        for (int i = 0; i < n_y; ++i) {
            yt[i] = y[i] + h * k3[i];
        }
        f(ctx, yt, k4);
        for (int i = 0; i < n_y; ++i) {
            y[i] += (h / 6.0) * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
        }
    }
}

double plant_rk4_stiff_substeps(const plant_state_t *s, const plant_config_t *c, double p)
{
    const double lam = s->lam_base + p * fabs(s->omega_m_rad_s);
    return ceil(c->Ts_s * lam / c->rk4_h_rel);
}

uint32_t plant_rk4_clamp_substeps(const plant_config_t *c, double nreal)
{
    uint32_t n = !(nreal < (double)PLANT_RK4_MAX_SUBSTEPS) ? PLANT_RK4_MAX_SUBSTEPS : (uint32_t)nreal;
    if (n < c->rk4_min_substeps) {
        n = c->rk4_min_substeps;
    }
    return n < 1u ? 1u : n;
}

void plant_rk4_dq_begin(const plant_state_t *s, double *y)
{
    memset(y, 0, sizeof(double) * DQ_N);
    y[DQ_ID] = s->id_A;
    y[DQ_IQ] = s->iq_A;
    y[DQ_C] = s->cos_e;
    y[DQ_S] = s->sin_e;
    y[DQ_W] = s->omega_m_rad_s;
}

void plant_rk4_dq_end(plant_state_t *s, const plant_config_t *c, const double *y)
{
    s->id_A = y[DQ_ID];
    s->iq_A = y[DQ_IQ];
    s->omega_m_rad_s = y[DQ_W];
    s->energy.in_J += y[DQ_EIN];
    s->energy.copper_J += y[DQ_ECU];
    s->energy.mech_J += y[DQ_EME];
    s->energy.friction_J += y[DQ_EFR];
    s->energy.load_J += y[DQ_ELD];
    if (y[DQ_TH] != 0.0) {
        s->theta_m_rad = plant_angle_wrap_2pi(s->theta_m_rad + y[DQ_TH], &s->revolutions);
        /* cos/sin were integrated too (to RK4 accuracy); re-derive them from theta_m so the angle and the encoder
         * stay exactly consistent. */
        plant_angle_resync(s, c);
    }
}
