/*
 * dq_linear_step.c - the linear dq model's step (dq_linear.h): one period Ts with the applied voltage held, on the
 * exact path (the discretization dq_linear.c prepared: expm(A Ts) and the energy integrals as quadratic forms) or
 * on the RK4 path (q-axis saturation, free mechanics: plant_rk4.h), and with the switches off (plant_bridge.h).
 * Model and integration scheme: pmsm_plant.h.
 *
 * Only <math.h>: no OS, no heap, no stdio.
 */
#include <math.h>

#include "dq_linear_step.h"
#include "plant_angle.h"
#include "plant_bridge.h"
#include "plant_rk4.h"

#define PLANT_RESYNC_PERIODS 1024u /* recompute cos/sin(theta_e) from theta_m */

/* ===================================================================== */
/* RK4 path                                                              */
/* ===================================================================== */

typedef struct {
    const plant_config_t *c;
    double va, vb;   /* applied, stator frame */
    double vd0, vq0; /* rotor-hold values */
    double p;
    bool rotor_hold;
    bool free_mech;
    double invJ;
    plant_bridge_t *bridge; /* the switches off (trip_reaction pulses_off): the diodes give the voltage */
} rk_ctx_t;

static void rk_deriv(void *ctx, const double *y, double *dy)
{
    const rk_ctx_t *k = (const rk_ctx_t *)ctx;
    const plant_config_t *c = k->c;
    const double id = y[DQ_ID], iq = y[DQ_IQ], ce = y[DQ_C], se = y[DQ_S];
    const double wm = y[DQ_W];
    const double we = k->p * wm;
    double psiq, Linc;
    if (c->sat_enable) {
        const double Is = c->sat_I_A, Li = c->sat_Lq_inf_H, x = iq / Is;
        psiq = Li * iq + (c->Lq_H - Li) * Is * atan(x);
        Linc = Li + (c->Lq_H - Li) / (1.0 + x * x);
    } else {
        psiq = c->Lq_H * iq;
        Linc = c->Lq_H;
    }
    const double psid = c->Ld_H * id + c->psi_Wb;
    double vd, vq;
    if (k->bridge != NULL) {
        const plant_bridge_lin_t l = {ce,
                                      se,
                                      we,
                                      id,
                                      iq,
                                      (-c->R_ohm * id + we * psiq) / c->Ld_H,
                                      (-c->R_ohm * iq - we * psid) / Linc,
                                      {{1.0 / c->Ld_H, 0.0}, {0.0, 1.0 / Linc}}};
        plant_bridge_voltage(k->bridge, &l, &vd, &vq);
    } else if (k->rotor_hold) {
        vd = k->vd0;
        vq = k->vq0;
    } else {
        vd = k->va * ce + k->vb * se;
        vq = -k->va * se + k->vb * ce;
    }
    dy[DQ_ID] = (vd - c->R_ohm * id + we * psiq) / c->Ld_H;
    dy[DQ_IQ] = (vq - c->R_ohm * iq - we * psid) / Linc;
    dy[DQ_C] = -we * se;
    dy[DQ_S] = we * ce;
    dy[DQ_TH] = wm;
    const double Te = 1.5 * k->p * (psid * iq - psiq * id);
    plant_rk4_mech_deriv(c, k->free_mech, k->invJ, Te, wm, &dy[DQ_W], &dy[DQ_EFR], &dy[DQ_ELD]);
    dy[DQ_EIN] = 1.5 * (vd * id + vq * iq);
    dy[DQ_ECU] = 1.5 * c->R_ohm * (id * id + iq * iq);
    dy[DQ_EME] = Te * wm;
}

/* The context, the sub-steps of the period (the stiffness bound) and the start state of the RK4 path. */
static uint32_t rk_begin(rk_ctx_t *k, double *y, plant_state_t *s, const plant_config_t *c, double va, double vb,
                         double vd0, double vq0)
{
    k->c = c;
    k->va = va;
    k->vb = vb;
    k->vd0 = vd0;
    k->vq0 = vq0;
    k->p = (double)c->pole_pairs;
    k->rotor_hold = (c->hold_frame == PLANT_HOLD_ROTOR);
    k->free_mech = (c->mech_mode == PLANT_MECH_FREE);
    k->invJ = k->free_mech ? 1.0 / c->J_kgm2 : 0.0;
    k->bridge = NULL;

    const uint32_t n = plant_rk4_clamp_substeps(c, plant_rk4_stiff_substeps(s, c, k->p));
    s->last_substeps = n;
    plant_rk4_dq_begin(s, y);
    return n;
}

static void step_rk4(plant_state_t *s, const plant_config_t *c, double va, double vb, double vd0, double vq0)
{
    rk_ctx_t k;
    double y[DQ_N];
    const uint32_t n = rk_begin(&k, y, s, c, va, vb, vd0, vq0);
    plant_rk4_run(rk_deriv, &k, y, DQ_N, n, c->Ts_s / (double)n);
    plant_rk4_dq_end(s, c, y);
}

/* ---- the switches off (plant_bridge.h): the same RK4 model, its voltage from the diodes ---- */

static void br_currents(void *ctx, const double *y, double *ia, double *ib)
{
    (void)ctx;
    *ia = y[DQ_C] * y[DQ_ID] - y[DQ_S] * y[DQ_IQ];
    *ib = y[DQ_S] * y[DQ_ID] + y[DQ_C] * y[DQ_IQ];
}

static void br_set_currents(void *ctx, double *y, double ia, double ib)
{
    (void)ctx;
    const double n2 = y[DQ_C] * y[DQ_C] + y[DQ_S] * y[DQ_S]; /* the inverse of br_currents' rotation */
    y[DQ_ID] = (y[DQ_C] * ia + y[DQ_S] * ib) / n2;
    y[DQ_IQ] = (-y[DQ_S] * ia + y[DQ_C] * ib) / n2;
}

/* The linear model (exact or RK4 path alike) for one period with the switches off: its RK4 path with the diodes'
 * voltage, each change of conduction located (plant_bridge_period).  The bridge is physical: hold_frame does not
 * apply to it. */
static void step_bridge_rk4(plant_state_t *s, const plant_config_t *c)
{
    rk_ctx_t k;
    double y[DQ_N];
    const uint32_t n = rk_begin(&k, y, s, c, 0.0, 0.0, 0.0, 0.0);
    k.bridge = &s->bridge;
    s->bridge.Vdc_V = c->Vdc_V;
    const plant_bridge_model_t m = {&k, DQ_N, rk_deriv, br_currents, br_set_currents};
    s->last_substeps = n * PLANT_BRIDGE_SUBSTEPS;
    plant_bridge_period(&s->bridge, &m, y, c->Ts_s, s->last_substeps);
    plant_rk4_dq_end(s, c, y);
}

/* ===================================================================== */
/* step                                                                   */
/* ===================================================================== */

/* The exact path: one period of x = [id iq vd vq 1] with expm(A Ts), the
 * energy integrals as quadratic forms of the start state, and the angle
 * advanced by the rotation of one period (resynchronised from theta_m every
 * PLANT_RESYNC_PERIODS periods). */
static void step_exact(plant_state_t *s, const plant_config_t *c, double vd0, double vq0)
{
    const double ce = s->cos_e, se = s->sin_e;
    const double x0 = s->id_A, x1 = s->iq_A, x2 = vd0, x3 = vq0;
    const double(*P)[5] = s->phi;
    s->id_A = P[0][0] * x0 + P[0][1] * x1 + P[0][2] * x2 + P[0][3] * x3 + P[0][4];
    s->iq_A = P[1][0] * x0 + P[1][1] * x1 + P[1][2] * x2 + P[1][3] * x3 + P[1][4];
    /* energy integrals: exact quadratic forms in the start state (m: the upper triangle, row by row) */
    /* clang-format off */
    const double m[15] = {x0 * x0, x0 * x1, x0 * x2, x0 * x3, x0,
                          x1 * x1, x1 * x2, x1 * x3, x1,
                          x2 * x2, x2 * x3, x2,
                          x3 * x3, x3,
                          1.0};
    /* clang-format on */
    double ein = 0.0, ecu = 0.0, eme = 0.0;
    for (int i = 0; i < 15; ++i) {
        ein += s->q_in[i] * m[i];
        ecu += s->q_cu[i] * m[i];
        eme += s->q_mech[i] * m[i];
    }
    s->energy.in_J += ein;
    s->energy.copper_J += ecu;
    s->energy.mech_J += eme;
    if (s->dtheta_m != 0.0) {
        double th = s->theta_m_rad + s->dtheta_m;
        if (th >= PLANT_TWO_PI) {
            th -= PLANT_TWO_PI;
            s->revolutions++;
        } else if (th < 0.0) {
            th += PLANT_TWO_PI;
            s->revolutions--;
        }
        s->theta_m_rad = plant_angle_wrap_2pi(th, &s->revolutions);
        if (++s->resync >= PLANT_RESYNC_PERIODS) {
            plant_angle_resync(s, c);
        } else {
            s->cos_e = ce * s->rot_c - se * s->rot_s;
            s->sin_e = se * s->rot_c + ce * s->rot_s;
        }
    }
}

void dq_linear_step_bridge(plant_state_t *s, const plant_config_t *c) { step_bridge_rk4(s, c); }

void dq_linear_step(plant_state_t *s, const plant_config_t *c, double va, double vb, double vd0, double vq0)
{
    if (s->exact) {
        step_exact(s, c, vd0, vq0);
    } else {
        step_rk4(s, c, va, vb, vd0, vq0);
    }
}
