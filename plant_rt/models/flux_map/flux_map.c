/*
 * flux_map.c - the flux-map machine model (Motor model.model = flux_map; its descriptor plant_model_flux_map,
 * plant_model.h; the tables and their inversion: plant_fluxmap.h).
 *
 * States: the flux linkages in the rotor frame, motor convention,
 *     d psi_d/dt = vd - R id + w psi_q
 *     d psi_q/dt = vq - R iq - w psi_d           (w = p omega_m)
 * with (id, iq) the inverse of the map at (psi_d, psi_q), the torque
 * Te = 1.5 p (psi_d iq - psi_q id) and the magnetic energy as the integral of
 * 1.5 (id dpsi_d + iq dpsi_q).  Classical RK4 with the fixed sub-steps of the
 * RK4 path (plant_rk4.h): N = max(rk4_min_substeps, ceil(Ts lambda /
 * rk4_h_rel)), lambda = R / L_min + |w| (+ the electromechanical frequency in
 * FREE mode), L_min the map's smallest incremental inductance.  Each stage
 * inverts the map by Newton's method from the previous stage's currents.
 *
 * The winding's temperature: one exact first-order step a period with the
 * period's mean copper loss; R for the next period follows it.
 *
 * Only <math.h>/<string.h>: no OS, no heap, no stdio.
 */
#include <math.h>
#include <string.h>

#include "plant_angle.h"
#include "plant_bridge.h"
#include "plant_fluxmap.h"
#include "plant_model.h"
#include "plant_rk4.h"

enum { F_PD, F_PQ, F_C, F_S, F_TH, F_W, F_EIN, F_ECU, F_EME, F_EFR, F_ELD, F_EMAG, F_N };

typedef struct {
    const plant_config_t *c;
    plant_state_t *s;
    double va, vb, vd0, vq0;
    double p, R, invJ;
    bool rotor_hold, free_mech;
    double id, iq;          /* the last inversion: the next one's start */
    plant_bridge_t *bridge; /* the switches off (trip_reaction pulses_off): the diodes give the voltage */
} flux_ctx_t;

/* (id, iq) at (psi_d, psi_q), from the last solution. */
static void invert(flux_ctx_t *k, double psi_d, double psi_q)
{
    const int n = plant_flux_map_currents(k->c->flux_map, psi_d, psi_q, &k->id, &k->iq);
    if (n < 0) {
        ++k->s->newton_failures;
    } else if (n > k->s->newton_evals_max) {
        k->s->newton_evals_max = n;
    }
}

static void flux_deriv(void *ctx, const double *y, double *dy)
{
    flux_ctx_t *k = (flux_ctx_t *)ctx;
    const plant_config_t *c = k->c;
    invert(k, y[F_PD], y[F_PQ]);
    const double id = k->id, iq = k->iq, wm = y[F_W], we = k->p * wm;
    double vd, vq;
    if (k->bridge != NULL) {
        /* d i/dt = L^-1 d psi/dt with L the interpolant's incremental inductance at the currents */
        plant_flux_eval_t e;
        plant_flux_map_eval(c->flux_map, id, iq, &e);
        const double det = e.Ldd_H * e.Lqq_H - e.Ldq_H * e.Lqd_H; /* > 0: a checked map */
        const double Bdd = e.Lqq_H / det, Bdq = -e.Ldq_H / det, Bqd = -e.Lqd_H / det, Bqq = e.Ldd_H / det;
        const double fd = -k->R * id + we * y[F_PQ], fq = -k->R * iq - we * y[F_PD];
        const plant_bridge_lin_t l = {
            y[F_C], y[F_S], we, id, iq, Bdd * fd + Bdq * fq, Bqd * fd + Bqq * fq, {{Bdd, Bdq}, {Bqd, Bqq}}};
        plant_bridge_voltage(k->bridge, &l, &vd, &vq);
    } else if (k->rotor_hold) {
        vd = k->vd0;
        vq = k->vq0;
    } else {
        vd = k->va * y[F_C] + k->vb * y[F_S];
        vq = -k->va * y[F_S] + k->vb * y[F_C];
    }
    dy[F_PD] = vd - k->R * id + we * y[F_PQ];
    dy[F_PQ] = vq - k->R * iq - we * y[F_PD];
    dy[F_C] = -we * y[F_S];
    dy[F_S] = we * y[F_C];
    dy[F_TH] = wm;
    const double Te = 1.5 * k->p * (y[F_PD] * iq - y[F_PQ] * id);
    plant_rk4_mech_deriv(c, k->free_mech, k->invJ, Te, wm, &dy[F_W], &dy[F_EFR], &dy[F_ELD]);
    dy[F_EIN] = 1.5 * (vd * id + vq * iq);
    dy[F_ECU] = 1.5 * k->R * (id * id + iq * iq);
    dy[F_EME] = Te * wm;
    dy[F_EMAG] = 1.5 * (id * dy[F_PD] + iq * dy[F_PQ]);
}

/* The magnetic energy 1.5 * integral of i . dpsi along the straight path from zero current to the present one
 * (64 midpoint steps): the reference when the currents are set from outside. */
static double path_energy_J(const plant_flux_map_t *m, double id_A, double iq_A)
{
    plant_flux_eval_t a, b;
    plant_flux_map_eval(m, 0.0, 0.0, &a);
    double W = 0.0;
    for (int n = 1; n <= 64; ++n) {
        const double f = (double)n / 64.0, fm = ((double)n - 0.5) / 64.0;
        plant_flux_map_eval(m, f * id_A, f * iq_A, &b);
        W += fm * id_A * (b.psi_d_Wb - a.psi_d_Wb) + fm * iq_A * (b.psi_q_Wb - a.psi_q_Wb);
        a = b;
    }
    return 1.5 * W;
}

/* The fluxes, the incremental inductances and the resistance from the present currents and temperature. */
static void refresh(plant_state_t *s, const plant_config_t *c, bool fluxes)
{
    plant_flux_eval_t e;
    plant_flux_map_eval(c->flux_map, s->id_A, s->iq_A, &e);
    if (fluxes) {
        s->psi_d_Wb = e.psi_d_Wb;
        s->psi_q_Wb = e.psi_q_Wb;
        s->W_mag_J = path_energy_J(c->flux_map, s->id_A, s->iq_A);
        s->psi_stale = false;
    }
    s->Ldd_H = e.Ldd_H;
    s->Ldq_H = e.Ldq_H;
    s->Lqd_H = e.Lqd_H;
    s->Lqq_H = e.Lqq_H;
    s->R_winding_ohm = c->R_ohm * (1.0 + c->R_alpha_per_K * (s->T_winding_degC - c->T_ref_degC));
}

static int flux_prepare(plant_state_t *s, const plant_config_t *c, double p)
{
    const double Lmin = plant_flux_map_Lmin_H(c->flux_map);
    plant_flux_eval_t e0;
    plant_flux_map_eval(c->flux_map, 0.0, 0.0, &e0);
    s->Lmin_H = Lmin;
    s->cell_min_A = plant_flux_map_cell_min_A(c->flux_map);
    if (!(c->thermal_C_J_per_K > 0.0) || s->k == 0u) {
        s->T_winding_degC = c->T_amb_degC; /* the winding starts at the ambient; without a thermal model it stays */
    }
    /* the fluxes from the currents (and the magnetic energy's reference) before the run and after a switch of
     * model or map; a mid-run change of another parameter keeps them, and the energy account with them */
    const bool fresh = s->k == 0u || s->psi_stale || s->prepared_map != c->flux_map;
    refresh(s, c, fresh);
    s->prepared_map = c->flux_map;
    const double Rmax = s->R_winding_ohm > c->R_ohm ? s->R_winding_ohm : c->R_ohm;
    s->lam_base = Rmax / Lmin;
    if (c->mech_mode == PLANT_MECH_FREE) {
        const double psi0 = e0.psi_d_Wb;
        s->lam_base += sqrt(1.5 * p * p * psi0 * psi0 / (c->J_kgm2 * Lmin));
    }
    s->exact = false;
    return PLANT_OK;
}

static double flux_torque_Nm(const plant_state_t *s, const plant_config_t *c)
{
    return 1.5 * (double)c->pole_pairs * (s->psi_d_Wb * s->iq_A - s->psi_q_Wb * s->id_A);
}

/* The winding's temperature over one period (exact for the period's mean loss) and the resistance it gives. */
static void thermal_step(plant_state_t *s, const plant_config_t *c, double copper_J)
{
    if (c->thermal_C_J_per_K > 0.0) {
        const double P = copper_J / c->Ts_s;
        const double Rth = c->thermal_R_K_per_W, Cth = c->thermal_C_J_per_K;
        if (Rth > 0.0) {
            const double a = exp(-c->Ts_s / (Rth * Cth));
            const double T_inf = c->T_amb_degC + Rth * P;
            s->T_winding_degC = T_inf + (s->T_winding_degC - T_inf) * a;
        } else { /* no path to the ambient: adiabatic heating */
            s->T_winding_degC += copper_J / Cth;
        }
    }
    s->R_winding_ohm = c->R_ohm * (1.0 + c->R_alpha_per_K * (s->T_winding_degC - c->T_ref_degC));
}

/* The sub-steps of a period: the stiffness bound of the RK4 path, and a bound on the cells crossed: the
 * interpolant's slopes jump on the grid lines, where RK4 falls to low order, so a sub-step may move the current
 * by at most FLUX_CELL_FRACTION of the narrowest cell (the current's change estimated from the voltage and the
 * back-EMF over L_min). */
#define FLUX_CELL_FRACTION 0.0625
static double cell_substeps(const plant_state_t *s, const plant_config_t *c, double p, double va, double vb)
{
    const double w = p * fabs(s->omega_m_rad_s);
    const double dpsi = c->Ts_s * (sqrt(va * va + vb * vb) + w * hypot(s->psi_d_Wb, s->psi_q_Wb) +
                                   s->R_winding_ohm * hypot(s->id_A, s->iq_A));
    return dpsi / (s->Lmin_H * s->cell_min_A * FLUX_CELL_FRACTION);
}

static uint32_t substeps(const plant_state_t *s, const plant_config_t *c, double p, double va, double vb)
{
    double nreal = plant_rk4_stiff_substeps(s, c, p);
    const double cells = cell_substeps(s, c, p, va, vb);
    if (cells > nreal) nreal = ceil(cells);
    return plant_rk4_clamp_substeps(c, nreal);
}

/* The context and the start state of a period. */
static void flux_begin(flux_ctx_t *k, double *y, plant_state_t *s, const plant_config_t *c, double va, double vb,
                       double vd0, double vq0)
{
    if (s->psi_stale) refresh(s, c, true);
    k->c = c;
    k->s = s;
    k->va = va;
    k->vb = vb;
    k->vd0 = vd0;
    k->vq0 = vq0;
    k->p = (double)c->pole_pairs;
    k->R = s->R_winding_ohm;
    k->rotor_hold = (c->hold_frame == PLANT_HOLD_ROTOR);
    k->free_mech = (c->mech_mode == PLANT_MECH_FREE);
    k->invJ = k->free_mech ? 1.0 / c->J_kgm2 : 0.0;
    k->id = s->id_A;
    k->iq = s->iq_A;
    k->bridge = NULL;
    memset(y, 0, sizeof(double) * F_N);
    y[F_PD] = s->psi_d_Wb;
    y[F_PQ] = s->psi_q_Wb;
    y[F_C] = s->cos_e;
    y[F_S] = s->sin_e;
    y[F_W] = s->omega_m_rad_s;
}

/* The state from a period's end state. */
static void flux_end(flux_ctx_t *k, plant_state_t *s, const plant_config_t *c, const double *y)
{
    s->psi_d_Wb = y[F_PD];
    s->psi_q_Wb = y[F_PQ];
    invert(k, s->psi_d_Wb, s->psi_q_Wb);
    s->id_A = k->id;
    s->iq_A = k->iq;
    s->omega_m_rad_s = y[F_W];
    s->energy.in_J += y[F_EIN];
    s->energy.copper_J += y[F_ECU];
    s->energy.mech_J += y[F_EME];
    s->energy.friction_J += y[F_EFR];
    s->energy.load_J += y[F_ELD];
    s->W_mag_J += y[F_EMAG];
    if (y[F_TH] != 0.0) {
        s->theta_m_rad = plant_angle_wrap_2pi(s->theta_m_rad + y[F_TH], &s->revolutions);
        plant_angle_resync(s, c);
    }
    if (!plant_flux_map_inside(c->flux_map, s->id_A, s->iq_A)) ++s->outside_map_periods;
    thermal_step(s, c, y[F_ECU]);
    refresh(s, c, false);
}

static void flux_step(plant_state_t *s, const plant_config_t *c, double va, double vb, double vd0, double vq0)
{
    flux_ctx_t k;
    double y[F_N];
    flux_begin(&k, y, s, c, va, vb, vd0, vq0);
    const uint32_t n = substeps(s, c, k.p, va, vb);
    s->last_substeps = n;
    plant_rk4_run(flux_deriv, &k, y, F_N, n, c->Ts_s / (double)n);
    flux_end(&k, s, c, y);
}

/* ---- the switches off (plant_bridge.h): the flux states with the diodes' voltage ---- */

static void br_currents(void *ctx, const double *y, double *ia, double *ib)
{
    flux_ctx_t *k = (flux_ctx_t *)ctx;
    invert(k, y[F_PD], y[F_PQ]);
    *ia = y[F_C] * k->id - y[F_S] * k->iq;
    *ib = y[F_S] * k->id + y[F_C] * k->iq;
}

/* the fluxes of the map at the given currents (a projection moves the currents by rounding errors only) */
static void br_set_currents(void *ctx, double *y, double ia, double ib)
{
    flux_ctx_t *k = (flux_ctx_t *)ctx;
    const double n2 = y[F_C] * y[F_C] + y[F_S] * y[F_S];
    k->id = (y[F_C] * ia + y[F_S] * ib) / n2;
    k->iq = (-y[F_S] * ia + y[F_C] * ib) / n2;
    plant_flux_eval_t e;
    plant_flux_map_eval(k->c->flux_map, k->id, k->iq, &e);
    y[F_PD] = e.psi_d_Wb;
    y[F_PQ] = e.psi_q_Wb;
}

static void flux_step_bridge(plant_state_t *s, const plant_config_t *c)
{
    flux_ctx_t k;
    double y[F_N];
    flux_begin(&k, y, s, c, 0.0, 0.0, 0.0, 0.0);
    k.bridge = &s->bridge;
    s->bridge.Vdc_V = c->Vdc_V;
    /* the sub-steps: the stiffness bound's, PLANT_BRIDGE_SUBSTEPS times; while a phase conducts, at least those of
     * a period with the largest voltage the diodes apply (2/3 Vdc on a phase); all off, the currents stay zero and
     * the fluxes still (the diodes hold the back-EMF), so the cells crossed do not count */
    const plant_bridge_t *b = &s->bridge;
    double nreal = plant_rk4_stiff_substeps(s, c, k.p) * (double)PLANT_BRIDGE_SUBSTEPS;
    if (!(b->active && b->phase[0] == 0 && b->phase[1] == 0 && b->phase[2] == 0)) {
        const double cells = cell_substeps(s, c, k.p, (2.0 / 3.0) * c->Vdc_V, 0.0);
        if (cells > nreal) nreal = ceil(cells);
    }
    s->last_substeps = plant_rk4_clamp_substeps(c, nreal);
    const plant_bridge_model_t m = {&k, F_N, flux_deriv, br_currents, br_set_currents};
    plant_bridge_period(&s->bridge, &m, y, c->Ts_s, s->last_substeps);
    flux_end(&k, s, c, y);
}

static double flux_magnetic_energy_J(const plant_state_t *s, const plant_config_t *c)
{
    (void)c;
    return s->W_mag_J; /* integrated by the step */
}

static int flux_validate(const plant_config_t *c)
{
    return plant_flux_map_check(c->flux_map) != 0 ? PLANT_ERR_FLUXMAP : PLANT_OK;
}

const plant_model_desc_t plant_model_flux_map = {
    .id = OD_PLANT_MODEL_FLUX_MAP,
    .name = "flux_map",
    .thermal = true,
    .validate = flux_validate,
    .prepare = flux_prepare,
    .step = flux_step,
    .step_bridge = flux_step_bridge,
    .torque_Nm = flux_torque_Nm,
    .magnetic_energy_J = flux_magnetic_energy_J,
};
