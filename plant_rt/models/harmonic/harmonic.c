/*
 * harmonic.c - the harmonic PMSM (Motor model.model = harmonic; its record 0x200A Model harmonic): the linear dq
 * model (R, Ld, Lq, psi and its q-axis saturation knob) whose magnets' flux linkage carries the 5th and 7th
 * space harmonics, and a cogging torque on the rotor.  Its descriptor is plant_model_harmonic (plant_model.h).
 *
 * Phase a's magnet flux linkage is psi cos(th) + psi_5 cos(5 th) + psi_7 cos(7 th) (th = theta_e; the 5th is a
 * negative-sequence set, the 7th a positive one), so in the stator frame psi_pm = psi e^(j th) + psi_5 e^(-j5 th)
 * + psi_7 e^(j7 th) and in the rotor frame (times e^(-j th)):
 *     psi_pm_d = psi + (psi_5 + psi_7) cos 6 th,     psi_pm_q = (psi_7 - psi_5) sin 6 th.
 * Motor convention, w = p omega_m, psi_d = Ld id + psi_pm_d, psi_q = psi_q(iq) + psi_pm_q:
 *     Ld did/dt      = vd - R id + w psi_q - w dpsi_pm_d/dth
 *     L_inc diq/dt   = vq - R iq - w psi_d - w dpsi_pm_q/dth
 *     Te = 1.5 p (psi_d iq - psi_q id + id dpsi_pm_d/dth + iq dpsi_pm_q/dth)     (from the co-energy)
 *     T_cog = cogging_Nm sin(cogging_periods theta_m)                             (on the rotor, beside Te)
 * The energy account stays the windings': in = copper + d(W_mag)/dt + Te omega_m, W_mag the linear model's.
 * The torque of a sample (plant_torque_Nm) is Te + T_cog.
 *
 * With every harmonic 0 it is the dq_linear model itself (its exact path too): bit for bit.  Otherwise always
 * RK4 (plant_rk4.h), the sub-steps bounded by the 6th harmonic's frequency too.  The bridge with its pulses off
 * is not followed (step_bridge NULL: trip_reaction pulses_off is refused on this model).
 *
 * Only <math.h>: no OS, no heap, no stdio.
 */
#include <math.h>

#include "dq_linear/dq_linear.h"
#include "plant_model.h"
#include "plant_rk4.h"

typedef struct {
    const plant_config_t *c;
    double va, vb, vd0, vq0; /* the applied voltage: stator frame; the rotor-hold values */
    double p, invJ, theta0;  /* theta0: theta_m at the period's start (y[DQ_TH] counts from it) */
    bool rotor_hold, free_mech;
    double psi5, psi7, cog_Nm, cog_n;
} hm_ctx_t;

static const od_plant_model_harmonic_t *params(const plant_config_t *c) { return &c->params.x200A_model_harmonic; }

static bool harmonics_off(const plant_config_t *c)
{
    const od_plant_model_harmonic_t *h = params(c);
    return h->psi_5_Wb == 0.0f && h->psi_7_Wb == 0.0f && (h->cogging_Nm == 0.0f || h->cogging_periods == 0u);
}

/* The magnets' rotor-frame flux linkage and its derivative in theta_e, from cos/sin(theta_e). */
static void magnet_flux(const plant_config_t *c, double psi5, double psi7, double ce, double se, double *pd, double *pq,
                        double *dpd, double *dpq)
{
    const double c2 = ce * ce - se * se, s2 = 2.0 * ce * se;
    const double c3 = c2 * ce - s2 * se, s3 = s2 * ce + c2 * se;
    const double c6 = c3 * c3 - s3 * s3, s6 = 2.0 * c3 * s3;
    *pd = c->psi_Wb + (psi5 + psi7) * c6;
    *pq = (psi7 - psi5) * s6;
    *dpd = -6.0 * (psi5 + psi7) * s6;
    *dpq = 6.0 * (psi7 - psi5) * c6;
}

static double cogging_Nm(double amp_Nm, double n, double theta_m_rad) { return amp_Nm * sin(n * theta_m_rad); }

static void deriv(void *ctx, const double *y, double *dy)
{
    const hm_ctx_t *k = (const hm_ctx_t *)ctx;
    const plant_config_t *c = k->c;
    const double id = y[DQ_ID], iq = y[DQ_IQ], ce = y[DQ_C], se = y[DQ_S], wm = y[DQ_W];
    const double we = k->p * wm;
    double pd, pq, dpd, dpq;
    magnet_flux(c, k->psi5, k->psi7, ce, se, &pd, &pq, &dpd, &dpq);
    const double psiq = dq_linear_psi_q_Wb(c, iq) + pq, Linc = dq_linear_Lq_inc_H(c, iq);
    const double psid = c->Ld_H * id + pd;
    double vd, vq;
    if (k->rotor_hold) {
        vd = k->vd0;
        vq = k->vq0;
    } else {
        vd = k->va * ce + k->vb * se;
        vq = -k->va * se + k->vb * ce;
    }
    dy[DQ_ID] = (vd - c->R_ohm * id + we * psiq - we * dpd) / c->Ld_H;
    dy[DQ_IQ] = (vq - c->R_ohm * iq - we * psid - we * dpq) / Linc;
    dy[DQ_C] = -we * se;
    dy[DQ_S] = we * ce;
    dy[DQ_TH] = wm;
    const double Te = 1.5 * k->p * (psid * iq - psiq * id + id * dpd + iq * dpq);
    const double Tc = cogging_Nm(k->cog_Nm, k->cog_n, k->theta0 + y[DQ_TH]);
    plant_rk4_mech_deriv(c, k->free_mech, k->invJ, Te + Tc, wm, &dy[DQ_W], &dy[DQ_EFR], &dy[DQ_ELD]);
    dy[DQ_EIN] = 1.5 * (vd * id + vq * iq);
    dy[DQ_ECU] = 1.5 * c->R_ohm * (id * id + iq * iq);
    dy[DQ_EME] = Te * wm; /* the windings' account: the cogging torque's power is the rotor's */
}

static void begin(hm_ctx_t *k, double *y, const plant_state_t *s, const plant_config_t *c)
{
    const od_plant_model_harmonic_t *h = params(c);
    k->c = c;
    k->p = (double)c->pole_pairs;
    k->rotor_hold = (c->hold_frame == PLANT_HOLD_ROTOR);
    k->free_mech = (c->mech_mode == PLANT_MECH_FREE);
    k->invJ = k->free_mech ? 1.0 / c->J_kgm2 : 0.0;
    k->theta0 = s->theta_m_rad;
    k->psi5 = (double)h->psi_5_Wb;
    k->psi7 = (double)h->psi_7_Wb;
    k->cog_Nm = (double)h->cogging_Nm;
    k->cog_n = (double)h->cogging_periods;
    plant_rk4_dq_begin(s, y);
}

static void step(plant_state_t *s, const plant_config_t *c, double va, double vb, double vd0, double vq0)
{
    if (harmonics_off(c)) {
        plant_model_dq_linear.step(s, c, va, vb, vd0, vq0);
        return;
    }
    hm_ctx_t k;
    double y[DQ_N];
    begin(&k, y, s, c);
    k.va = va;
    k.vb = vb;
    k.vd0 = vd0;
    k.vq0 = vq0;
    /* the stiffness bound, with the fastest forcing: the 6th harmonic in the rotor frame (6 w), the rotation
     * (w) and the cogging (cogging_periods omega_m) */
    const double wm = fabs(s->omega_m_rad_s);
    const double lam = s->lam_base + 7.0 * k.p * wm + k.cog_n * wm;
    const uint32_t n = plant_rk4_clamp_substeps(c, ceil(c->Ts_s * lam / c->rk4_h_rel));
    s->last_substeps = n;
    plant_rk4_run(deriv, &k, y, DQ_N, n, c->Ts_s / (double)n);
    plant_rk4_dq_end(s, c, y);
}

static int prepare(plant_state_t *s, const plant_config_t *c, double p)
{
    if (harmonics_off(c)) {
        return plant_model_dq_linear.prepare(s, c, p);
    }
    plant_model_fixed_winding(s, c);
    dq_linear_prepare_bound(s, c, p);
    const od_plant_model_harmonic_t *h = params(c);
    if (c->mech_mode == PLANT_MECH_FREE && h->cogging_periods > 0u) {
        /* the cogging's stiffness: small oscillations at sqrt(|T_cog| n / J) */
        s->lam_base += sqrt(fabs((double)h->cogging_Nm) * (double)h->cogging_periods / c->J_kgm2);
    }
    s->exact = false;
    return PLANT_OK;
}

static double torque(const plant_state_t *s, const plant_config_t *c)
{
    const double Te = plant_model_dq_linear.torque_Nm(s, c);
    if (harmonics_off(c)) {
        return Te;
    }
    const od_plant_model_harmonic_t *h = params(c);
    double pd, pq, dpd, dpq;
    magnet_flux(c, (double)h->psi_5_Wb, (double)h->psi_7_Wb, s->cos_e, s->sin_e, &pd, &pq, &dpd, &dpq);
    /* the linear model's torque with psi, plus the harmonics' share: psi_pm_d - psi and psi_pm_q in the flux form
     * and the derivative terms */
    const double p15 = 1.5 * (double)c->pole_pairs, id = s->id_A, iq = s->iq_A;
    const double Th = p15 * ((pd - c->psi_Wb) * iq - pq * id + id * dpd + iq * dpq);
    return Te + Th + cogging_Nm((double)h->cogging_Nm, (double)h->cogging_periods, s->theta_m_rad);
}

static double magnetic_energy(const plant_state_t *s, const plant_config_t *c)
{
    return plant_model_dq_linear.magnetic_energy_J(s, c); /* the windings' own: the linear model's */
}

const plant_model_desc_t plant_model_harmonic = {
    .id = OD_PLANT_MODEL_HARMONIC,
    .name = "harmonic",
    .thermal = false,
    .validate = NULL,
    .prepare = prepare,
    .step = step,
    .step_bridge = NULL,
    .torque_Nm = torque,
    .magnetic_energy_J = magnetic_energy,
};
