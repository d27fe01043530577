/*
 * pmsm_plant.c - PMSM plant emulator core.  See pmsm_plant.h for the model,
 * conventions and the integration scheme.
 *
 * Only <math.h>/<string.h>/<stdint.h>/<stdbool.h>/<stddef.h>: no OS, no heap,
 * no stdio; time is the step counter k (t = k*Ts).
 */
#include "pmsm_plant.h"

#include <math.h>
#include <string.h>

#include "plant_expm.h"

#define PLANT_PI 3.141592653589793238462643383279502884
#define PLANT_TWO_PI 6.283185307179586476925286766559005768
#define PLANT_SQRT3 1.732050807568877293527446341505872367
#define PLANT_RESYNC_PERIODS 1024u   /* recompute cos/sin(theta_e) from theta_m */
#define PLANT_RK4_MAX_SUBSTEPS 100000u

/* ===================================================================== */
/* defaults                                                              */
/* ===================================================================== */

void plant_config_ideal(plant_config_t *c)
{
    c->sat_enable = false;
    c->mod_limit = PLANT_MOD_NONE;
    c->t_dead_s = 0.0;
    c->hold_frame = PLANT_HOLD_STATOR;
    c->adc_lsb_A = 0.0;
    c->adc_offset_a_A = 0.0;
    c->adc_offset_b_A = 0.0;
    c->adc_noise_std_A = 0.0;
    c->adc_full_scale_A = 0.0;
    c->encoder_lines = 0u;
    c->I_trip_A = 0.0;
}

void plant_config_defaults(plant_config_t *c)
{
    memset(c, 0, sizeof(*c));
    c->Ts_s = 100e-6;
    c->R_ohm = 1.0;
    c->Ld_H = 1e-3;
    c->Lq_H = 1e-3;
    c->psi_Wb = 0.01;
    c->pole_pairs = 1;
    c->sat_I_A = 1.0;          /* only used when sat_enable */
    c->sat_Lq_inf_H = 0.5e-3;  /* only used when sat_enable */
    c->mech_mode = PLANT_MECH_LOCKED;
    c->J_kgm2 = 1e-4;
    c->B_Nm_per_rad_s = 0.0;
    c->T_load_Nm = 0.0;
    c->omega_imposed_rad_s = 0.0;
    c->Vdc_V = 48.0;
    c->Ts_pwm_s = 0.0;
    c->deadtime_I_sat_A = 0.3;
    c->rng_seed = UINT64_C(0x5EED);
    c->rk4_h_rel = 0.02;
    c->rk4_min_substeps = 1u;
    plant_config_ideal(c);
}

/* ===================================================================== */
/* small model functions                                                 */
/* ===================================================================== */

double plant_psi_q_Wb(const plant_config_t *c, double iq_A)
{
    if (!c->sat_enable) {
        return c->Lq_H * iq_A;
    }
    const double Is = c->sat_I_A, Li = c->sat_Lq_inf_H;
    return Li * iq_A + (c->Lq_H - Li) * Is * atan(iq_A / Is);
}

double plant_Lq_inc_H(const plant_config_t *c, double iq_A)
{
    if (!c->sat_enable) {
        return c->Lq_H;
    }
    const double x = iq_A / c->sat_I_A;
    return c->sat_Lq_inf_H + (c->Lq_H - c->sat_Lq_inf_H) / (1.0 + x * x);
}

static double wq_energy(const plant_config_t *c, double iq_A)
{
    if (!c->sat_enable) {
        return 0.5 * c->Lq_H * iq_A * iq_A;
    }
    const double Is = c->sat_I_A, Li = c->sat_Lq_inf_H;
    const double x = iq_A / Is;
    return 0.5 * Li * iq_A * iq_A + 0.5 * (c->Lq_H - Li) * Is * Is * log1p(x * x);
}

double plant_magnetic_energy_J(const plant_state_t *s, const plant_config_t *c)
{
    return 1.5 * (0.5 * c->Ld_H * s->id_A * s->id_A + wq_energy(c, s->iq_A));
}

double plant_kinetic_energy_J(const plant_state_t *s, const plant_config_t *c)
{
    return 0.5 * c->J_kgm2 * s->omega_m_rad_s * s->omega_m_rad_s;
}

double plant_torque_Nm(const plant_state_t *s, const plant_config_t *c)
{
    const double id = s->id_A, iq = s->iq_A;
    return 1.5 * (double)c->pole_pairs *
           ((c->Ld_H * id + c->psi_Wb) * iq - plant_psi_q_Wb(c, iq) * id);
}

double plant_deadtime_phase_error_V(const plant_config_t *c, double i_phase_A)
{
    if (c->t_dead_s <= 0.0) {
        return 0.0;
    }
    const double Tpwm = (c->Ts_pwm_s > 0.0) ? c->Ts_pwm_s : c->Ts_s;
    const double Vdt = c->Vdc_V * c->t_dead_s / Tpwm;
    double g;
    if (c->deadtime_I_sat_A > 0.0) {
        g = tanh(i_phase_A / c->deadtime_I_sat_A);
    } else {
        g = (i_phase_A > 0.0) ? 1.0 : ((i_phase_A < 0.0) ? -1.0 : 0.0);
    }
    return -Vdt * g;
}

void plant_modulation_limit(const plant_config_t *c, double *v_alpha_V,
                            double *v_beta_V)
{
    const double va = *v_alpha_V, vb = *v_beta_V;
    const double r = c->Vdc_V / PLANT_SQRT3;  /* inscribed circle radius */
    double scale = 1.0;
    if (c->mod_limit == PLANT_MOD_CIRCLE) {
        const double m2 = va * va + vb * vb;
        if (m2 > r * r) {
            scale = r / sqrt(m2);
        }
    } else if (c->mod_limit == PLANT_MOD_SVPWM_HEX) {
        /* Hexagon = intersection of three slabs |v . n_k| <= Vdc/sqrt(3),
         * n_k at 30, 90 and 150 degrees (vertices on the phase axes). */
        const double p30 = fabs(0.5 * PLANT_SQRT3 * va + 0.5 * vb);
        const double p150 = fabs(-0.5 * PLANT_SQRT3 * va + 0.5 * vb);
        double m = fabs(vb);
        if (p30 > m) {
            m = p30;
        }
        if (p150 > m) {
            m = p150;
        }
        if (m > r) {
            scale = r / m;
        }
    }
    *v_alpha_V = va * scale;
    *v_beta_V = vb * scale;
}

/* ===================================================================== */
/* init / prepare                                                         */
/* ===================================================================== */

static void resync_angle(plant_state_t *s, const plant_config_t *c)
{
    const double th_e = fmod((double)c->pole_pairs * s->theta_m_rad, PLANT_TWO_PI);
    s->cos_e = cos(th_e);
    s->sin_e = sin(th_e);
    s->resync = 0u;
}

static double wrap_2pi(double x, int64_t *revs)
{
    if (x >= PLANT_TWO_PI || x < 0.0) {
        const double n = floor(x / PLANT_TWO_PI);
        x -= n * PLANT_TWO_PI;
        if (revs != NULL) {
            *revs += (int64_t)n;
        }
        if (x >= PLANT_TWO_PI) {   /* rounding guard */
            x -= PLANT_TWO_PI;
        }
        if (x < 0.0) {
            x = 0.0;
        }
    }
    return x;
}

void plant_init(plant_state_t *s, const plant_config_t *c)
{
    memset(s, 0, sizeof(*s));
    s->cos_e = 1.0;
    s->sin_e = 0.0;
    if (c == NULL) {
        s->status = PLANT_ERR_NULL;
        return;
    }
    plant_rng_seed(&s->rng, c->rng_seed);
    (void)plant_prepare(s, c);
    plant_energy_reset(s, c);
}

static int validate(const plant_config_t *c)
{
    const double vals[] = {
        c->Ts_s, c->R_ohm, c->Ld_H, c->Lq_H, c->psi_Wb, c->sat_I_A,
        c->sat_Lq_inf_H, c->J_kgm2, c->B_Nm_per_rad_s, c->T_load_Nm,
        c->omega_imposed_rad_s, c->Vdc_V, c->t_dead_s, c->Ts_pwm_s,
        c->deadtime_I_sat_A, c->adc_lsb_A, c->adc_offset_a_A, c->adc_offset_b_A,
        c->adc_noise_std_A, c->adc_full_scale_A, c->I_trip_A, c->rk4_h_rel};
    for (size_t i = 0; i < sizeof(vals) / sizeof(vals[0]); ++i) {
        if (!isfinite(vals[i])) {
            return PLANT_ERR_NONFINITE;
        }
    }
    if (!(c->Ts_s > 0.0)) {
        return PLANT_ERR_TS;
    }
    if (c->R_ohm < 0.0) {
        return PLANT_ERR_R;
    }
    if (!(c->Ld_H > 0.0) || !(c->Lq_H > 0.0)) {
        return PLANT_ERR_L;
    }
    if (c->pole_pairs < 1) {
        return PLANT_ERR_POLES;
    }
    if (c->psi_Wb < 0.0) {
        return PLANT_ERR_PSI;
    }
    if (c->mech_mode != PLANT_MECH_FREE && c->mech_mode != PLANT_MECH_LOCKED &&
        c->mech_mode != PLANT_MECH_IMPOSED_SPEED) {
        return PLANT_ERR_MECH;
    }
    if (c->B_Nm_per_rad_s < 0.0 || c->J_kgm2 < 0.0 ||
        (c->mech_mode == PLANT_MECH_FREE && !(c->J_kgm2 > 0.0))) {
        return PLANT_ERR_MECH;
    }
    if (c->mod_limit != PLANT_MOD_NONE && c->mod_limit != PLANT_MOD_SVPWM_HEX &&
        c->mod_limit != PLANT_MOD_CIRCLE) {
        return PLANT_ERR_ENUM;
    }
    if (c->hold_frame != PLANT_HOLD_STATOR && c->hold_frame != PLANT_HOLD_ROTOR) {
        return PLANT_ERR_ENUM;
    }
    if (c->Vdc_V < 0.0 ||
        ((c->mod_limit != PLANT_MOD_NONE || c->t_dead_s > 0.0) && !(c->Vdc_V > 0.0))) {
        return PLANT_ERR_VDC;
    }
    if (c->t_dead_s < 0.0 || c->Ts_pwm_s < 0.0 || c->deadtime_I_sat_A < 0.0) {
        return PLANT_ERR_DEADTIME;
    }
    if (c->t_dead_s > 0.0) {
        const double Tpwm = (c->Ts_pwm_s > 0.0) ? c->Ts_pwm_s : c->Ts_s;
        if (!(c->t_dead_s < Tpwm)) {
            return PLANT_ERR_DEADTIME;
        }
    }
    if (c->sat_enable &&
        (!(c->sat_I_A > 0.0) || !(c->sat_Lq_inf_H > 0.0) || c->sat_Lq_inf_H > c->Lq_H)) {
        return PLANT_ERR_SAT;
    }
    if (c->adc_lsb_A < 0.0 || c->adc_noise_std_A < 0.0 || c->adc_full_scale_A < 0.0 ||
        c->encoder_lines > 100000000u) {
        return PLANT_ERR_SENSOR;
    }
    if (c->I_trip_A < 0.0) {
        return PLANT_ERR_TRIP;
    }
    if (!(c->rk4_h_rel > 0.0) || c->rk4_h_rel > 1.0) {
        return PLANT_ERR_RK4;
    }
    return PLANT_OK;
}

/* Pack a symmetric-part quadratic form: weights for the 15 monomials
 * x_i x_j (i <= j) of x = [id iq vd vq 1]. */
static void pack_quadratic(const double *M, double *q)
{
    int n = 0;
    for (int i = 0; i < 5; ++i) {
        for (int j = i; j < 5; ++j) {
            q[n++] = (i == j) ? M[i * 5 + i] : (M[i * 5 + j] + M[j * 5 + i]);
        }
    }
}

/* M = integral_0^T expm(A' t) Q expm(A t) dt via Van Loan's block exponential:
 * expm([[-A', Q], [0, A]] T) = [[., F12], [0, F22]],  M = F22' F12. */
static int van_loan(const double *A, const double *Q, double T, double *M)
{
    double C[100], E[100];
    memset(C, 0, sizeof(C));
    for (int i = 0; i < 5; ++i) {
        for (int j = 0; j < 5; ++j) {
            C[i * 10 + j] = -A[j * 5 + i] * T;
            C[i * 10 + 5 + j] = Q[i * 5 + j] * T;
            C[(5 + i) * 10 + 5 + j] = A[i * 5 + j] * T;
        }
    }
    if (plant_expm(10, C, E) != 0) {
        return -1;
    }
    for (int i = 0; i < 5; ++i) {
        for (int j = 0; j < 5; ++j) {
            double acc = 0.0;
            for (int k = 0; k < 5; ++k) {
                acc += E[(5 + k) * 10 + 5 + i] * E[k * 10 + 5 + j];
            }
            M[i * 5 + j] = acc;
        }
    }
    return 0;
}

static int prepare_exact(plant_state_t *s, const plant_config_t *c, double w_e)
{
    const double R = c->R_ohm, Ld = c->Ld_H, Lq = c->Lq_H, psi = c->psi_Wb;
    const double Ts = c->Ts_s;
    double A[25], AT[25], PHI[25];
    memset(A, 0, sizeof(A));
    A[0 * 5 + 0] = -R / Ld;
    A[0 * 5 + 1] = w_e * Lq / Ld;
    A[0 * 5 + 2] = 1.0 / Ld;
    A[1 * 5 + 0] = -w_e * Ld / Lq;
    A[1 * 5 + 1] = -R / Lq;
    A[1 * 5 + 3] = 1.0 / Lq;
    A[1 * 5 + 4] = -w_e * psi / Lq;
    if (c->hold_frame == PLANT_HOLD_STATOR) {
        A[2 * 5 + 3] = w_e;    /* d vd/dt =  w vq */
        A[3 * 5 + 2] = -w_e;   /* d vq/dt = -w vd */
    }
    for (int i = 0; i < 25; ++i) {
        AT[i] = A[i] * Ts;
    }
    if (plant_expm(5, AT, PHI) != 0) {
        return PLANT_ERR_EXPM;
    }
    for (int i = 0; i < 2; ++i) {
        for (int j = 0; j < 5; ++j) {
            s->phi[i][j] = PHI[i * 5 + j];
        }
    }
    /* power quadratic forms p = x'Qx */
    double Qin[25], Qcu[25], Qme[25], M[25];
    memset(Qin, 0, sizeof(Qin));
    memset(Qcu, 0, sizeof(Qcu));
    memset(Qme, 0, sizeof(Qme));
    Qin[0 * 5 + 2] = Qin[2 * 5 + 0] = 0.75;    /* 1.5 vd id */
    Qin[1 * 5 + 3] = Qin[3 * 5 + 1] = 0.75;    /* 1.5 vq iq */
    Qcu[0] = Qcu[1 * 5 + 1] = 1.5 * R;
    /* Te*omega_m = 1.5 w_e (psi iq + (Ld - Lq) id iq) */
    Qme[1 * 5 + 4] = Qme[4 * 5 + 1] = 0.75 * w_e * psi;
    Qme[0 * 5 + 1] = Qme[1 * 5 + 0] = 0.75 * w_e * (Ld - Lq);
    if (van_loan(A, Qin, Ts, M) != 0) {
        return PLANT_ERR_EXPM;
    }
    pack_quadratic(M, s->q_in);
    if (van_loan(A, Qcu, Ts, M) != 0) {
        return PLANT_ERR_EXPM;
    }
    pack_quadratic(M, s->q_cu);
    if (van_loan(A, Qme, Ts, M) != 0) {
        return PLANT_ERR_EXPM;
    }
    pack_quadratic(M, s->q_mech);
    return PLANT_OK;
}

int plant_prepare(plant_state_t *s, const plant_config_t *c)
{
    if (s == NULL) {
        return PLANT_ERR_NULL;
    }
    if (c == NULL) {
        s->status = PLANT_ERR_NULL;
        return s->status;
    }
    int rc = validate(c);
    if (rc != PLANT_OK) {
        s->status = rc;
        return rc;
    }
    if (c->mech_mode == PLANT_MECH_LOCKED) {
        s->omega_m_rad_s = 0.0;
    } else if (c->mech_mode == PLANT_MECH_IMPOSED_SPEED) {
        s->omega_m_rad_s = c->omega_imposed_rad_s;
    }
    const double p = (double)c->pole_pairs;
    const double w_e = p * s->omega_m_rad_s;
    s->dtheta_m = s->omega_m_rad_s * c->Ts_s;
    s->rot_c = cos(w_e * c->Ts_s);
    s->rot_s = sin(w_e * c->Ts_s);
    s->theta_m_rad = wrap_2pi(s->theta_m_rad, &s->revolutions);
    resync_angle(s, c);

    double Lmin = (c->Ld_H < c->Lq_H) ? c->Ld_H : c->Lq_H;
    if (c->sat_enable && c->sat_Lq_inf_H < Lmin) {
        Lmin = c->sat_Lq_inf_H;
    }
    s->Lmin_H = Lmin;
    s->lam_base = c->R_ohm / Lmin;
    if (c->mech_mode == PLANT_MECH_FREE) {
        s->lam_base += sqrt(1.5 * p * p * c->psi_Wb * c->psi_Wb / (c->J_kgm2 * Lmin));
    }
    if (c->t_dead_s > 0.0) {
        const double Tpwm = (c->Ts_pwm_s > 0.0) ? c->Ts_pwm_s : c->Ts_s;
        s->Vdt_V = c->Vdc_V * c->t_dead_s / Tpwm;
    } else {
        s->Vdt_V = 0.0;
    }

    s->exact = (c->mech_mode != PLANT_MECH_FREE) && !c->sat_enable;
    if (s->exact) {
        rc = prepare_exact(s, c, w_e);
        if (rc != PLANT_OK) {
            s->status = rc;
            return rc;
        }
    }
    s->status = PLANT_OK;
    return PLANT_OK;
}

/* ===================================================================== */
/* helpers                                                                */
/* ===================================================================== */

void plant_clear_trip(plant_state_t *s)
{
    s->tripped = false;
}

void plant_set_currents(plant_state_t *s, double id_A, double iq_A)
{
    s->id_A = id_A;
    s->iq_A = iq_A;
}

void plant_set_mech(plant_state_t *s, const plant_config_t *c,
                    double theta_m_rad, double omega_m_rad_s)
{
    s->theta_m_rad = wrap_2pi(theta_m_rad, NULL);
    if (c->mech_mode == PLANT_MECH_FREE) {
        s->omega_m_rad_s = omega_m_rad_s;
    }
    resync_angle(s, c);
}

void plant_energy_reset(plant_state_t *s, const plant_config_t *c)
{
    memset(&s->energy, 0, sizeof(s->energy));
    s->energy.W_mag0_J = plant_magnetic_energy_J(s, c);
    s->energy.W_kin0_J = plant_kinetic_energy_J(s, c);
}

double plant_energy_residual_J(const plant_state_t *s, const plant_config_t *c)
{
    const plant_energy_t *e = &s->energy;
    const double dW = plant_magnetic_energy_J(s, c) - e->W_mag0_J;
    return e->in_J - e->copper_J - dW - e->mech_J;
}

static inline void phase_currents(const plant_state_t *s, double *ia, double *ib,
                                  double *ic)
{
    const double ial = s->cos_e * s->id_A - s->sin_e * s->iq_A;
    const double ibe = s->sin_e * s->id_A + s->cos_e * s->iq_A;
    *ia = ial;
    *ib = -0.5 * ial + 0.5 * PLANT_SQRT3 * ibe;
    *ic = -0.5 * ial - 0.5 * PLANT_SQRT3 * ibe;
}

/* Over-current trip on any phase above c->I_trip_A (0 = level off), and,
 * whatever the level, on a non-finite phase current: a broken model state is
 * a trip (every comparison with NaN is false, so a level alone would never
 * see it). */
static inline void check_trip(plant_state_t *s, const plant_config_t *c)
{
    if (s->tripped) {
        return;
    }
    double ia, ib, ic;
    phase_currents(s, &ia, &ib, &ic);
    if (!isfinite(ia) || !isfinite(ib) || !isfinite(ic)) {
        s->tripped = true;
    } else if (c->I_trip_A > 0.0 &&
               (fabs(ia) > c->I_trip_A || fabs(ib) > c->I_trip_A || fabs(ic) > c->I_trip_A)) {
        s->tripped = true;
    }
}

/* ===================================================================== */
/* RK4 path                                                              */
/* ===================================================================== */

enum { Y_ID, Y_IQ, Y_C, Y_S, Y_TH, Y_W, Y_EIN, Y_ECU, Y_EME, Y_EFR, Y_ELD, Y_N };

typedef struct {
    const plant_config_t *c;
    double va, vb;      /* applied, stator frame */
    double vd0, vq0;    /* rotor-hold values */
    double p;
    bool rotor_hold;
    bool free_mech;
    double invJ;
} rk_ctx_t;

static void rk_deriv(const rk_ctx_t *k, const double *y, double *dy)
{
    const plant_config_t *c = k->c;
    const double id = y[Y_ID], iq = y[Y_IQ], ce = y[Y_C], se = y[Y_S];
    const double wm = y[Y_W];
    const double we = k->p * wm;
    double vd, vq;
    if (k->rotor_hold) {
        vd = k->vd0;
        vq = k->vq0;
    } else {
        vd = k->va * ce + k->vb * se;
        vq = -k->va * se + k->vb * ce;
    }
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
    dy[Y_ID] = (vd - c->R_ohm * id + we * psiq) / c->Ld_H;
    dy[Y_IQ] = (vq - c->R_ohm * iq - we * psid) / Linc;
    dy[Y_C] = -we * se;
    dy[Y_S] = we * ce;
    dy[Y_TH] = wm;
    const double Te = 1.5 * k->p * (psid * iq - psiq * id);
    if (k->free_mech) {
        dy[Y_W] = (Te - c->B_Nm_per_rad_s * wm - c->T_load_Nm) * k->invJ;
        dy[Y_EFR] = c->B_Nm_per_rad_s * wm * wm;
        dy[Y_ELD] = c->T_load_Nm * wm;
    } else {
        dy[Y_W] = 0.0;
        dy[Y_EFR] = 0.0;
        dy[Y_ELD] = 0.0;
    }
    dy[Y_EIN] = 1.5 * (vd * id + vq * iq);
    dy[Y_ECU] = 1.5 * c->R_ohm * (id * id + iq * iq);
    dy[Y_EME] = Te * wm;
}

static void step_rk4(plant_state_t *s, const plant_config_t *c, double va, double vb,
                     double vd0, double vq0)
{
    rk_ctx_t k;
    k.c = c;
    k.va = va;
    k.vb = vb;
    k.vd0 = vd0;
    k.vq0 = vq0;
    k.p = (double)c->pole_pairs;
    k.rotor_hold = (c->hold_frame == PLANT_HOLD_ROTOR);
    k.free_mech = (c->mech_mode == PLANT_MECH_FREE);
    k.invJ = k.free_mech ? 1.0 / c->J_kgm2 : 0.0;

    const double lam = s->lam_base + k.p * fabs(s->omega_m_rad_s);
    double nreal = ceil(c->Ts_s * lam / c->rk4_h_rel);
    uint32_t n;
    if (!(nreal < (double)PLANT_RK4_MAX_SUBSTEPS)) {
        n = PLANT_RK4_MAX_SUBSTEPS;
    } else {
        n = (uint32_t)nreal;
    }
    if (n < c->rk4_min_substeps) {
        n = c->rk4_min_substeps;
    }
    if (n < 1u) {
        n = 1u;
    }
    s->last_substeps = n;
    const double h = c->Ts_s / (double)n;

    double y[Y_N], k1[Y_N], k2[Y_N], k3[Y_N], k4[Y_N], yt[Y_N];
    memset(y, 0, sizeof(y));
    y[Y_ID] = s->id_A;
    y[Y_IQ] = s->iq_A;
    y[Y_C] = s->cos_e;
    y[Y_S] = s->sin_e;
    y[Y_W] = s->omega_m_rad_s;
    for (uint32_t it = 0; it < n; ++it) {
        rk_deriv(&k, y, k1);
        for (int i = 0; i < Y_N; ++i) {
            yt[i] = y[i] + 0.5 * h * k1[i];
        }
        rk_deriv(&k, yt, k2);
        for (int i = 0; i < Y_N; ++i) {
            yt[i] = y[i] + 0.5 * h * k2[i];
        }
        rk_deriv(&k, yt, k3);
        for (int i = 0; i < Y_N; ++i) {
            yt[i] = y[i] + h * k3[i];
        }
        rk_deriv(&k, yt, k4);
        for (int i = 0; i < Y_N; ++i) {
            y[i] += (h / 6.0) * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
        }
    }
    s->id_A = y[Y_ID];
    s->iq_A = y[Y_IQ];
    s->omega_m_rad_s = y[Y_W];
    s->energy.in_J += y[Y_EIN];
    s->energy.copper_J += y[Y_ECU];
    s->energy.mech_J += y[Y_EME];
    s->energy.friction_J += y[Y_EFR];
    s->energy.load_J += y[Y_ELD];
    if (y[Y_TH] != 0.0) {
        s->theta_m_rad = wrap_2pi(s->theta_m_rad + y[Y_TH], &s->revolutions);
        /* cos/sin were integrated too (to RK4 accuracy); re-derive them from
         * theta_m so the angle and the encoder stay exactly consistent. */
        resync_angle(s, c);
    }
}

/* ===================================================================== */
/* step / sample                                                          */
/* ===================================================================== */

void plant_step(plant_state_t *s, const plant_config_t *c, double v_alpha_V,
                double v_beta_V)
{
    if (s->status != PLANT_OK) {
        return;
    }
    check_trip(s, c);
    /* An inverter cannot output a non-finite voltage: such a command (a
     * diverged controller whose float state overflowed) trips the bridge
     * before it reaches the model, so the state stays finite and the trip is
     * latched from this period on. */
    if (!isfinite(v_alpha_V) || !isfinite(v_beta_V)) {
        s->tripped = true;
    }

    double va = v_alpha_V, vb = v_beta_V;
    if (c->mod_limit != PLANT_MOD_NONE) {
        plant_modulation_limit(c, &va, &vb);
    }
    s->v_lim_alpha_V = va;
    s->v_lim_beta_V = vb;
    if (s->Vdt_V > 0.0) {
        double ia, ib, ic;
        phase_currents(s, &ia, &ib, &ic);
        const double ea = plant_deadtime_phase_error_V(c, ia);
        const double eb = plant_deadtime_phase_error_V(c, ib);
        const double ec = plant_deadtime_phase_error_V(c, ic);
        va += (2.0 / 3.0) * (ea - 0.5 * (eb + ec));
        vb += (eb - ec) / PLANT_SQRT3;
    }
    if (s->tripped) {
        va = 0.0;
        vb = 0.0;
    }
    s->v_app_alpha_V = va;
    s->v_app_beta_V = vb;

    const double ce = s->cos_e, se = s->sin_e;
    const double vd0 = va * ce + vb * se;
    const double vq0 = -va * se + vb * ce;

    if (s->exact) {
        const double x0 = s->id_A, x1 = s->iq_A, x2 = vd0, x3 = vq0;
        const double (*P)[5] = s->phi;
        s->id_A = P[0][0] * x0 + P[0][1] * x1 + P[0][2] * x2 + P[0][3] * x3 + P[0][4];
        s->iq_A = P[1][0] * x0 + P[1][1] * x1 + P[1][2] * x2 + P[1][3] * x3 + P[1][4];
        /* energy integrals: exact quadratic forms in the start state */
        const double m[15] = {x0 * x0, x0 * x1, x0 * x2, x0 * x3, x0,
                              x1 * x1, x1 * x2, x1 * x3, x1,
                              x2 * x2, x2 * x3, x2,
                              x3 * x3, x3,
                              1.0};
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
            s->theta_m_rad = wrap_2pi(th, &s->revolutions);
            if (++s->resync >= PLANT_RESYNC_PERIODS) {
                resync_angle(s, c);
            } else {
                s->cos_e = ce * s->rot_c - se * s->rot_s;
                s->sin_e = se * s->rot_c + ce * s->rot_s;
            }
        }
    } else {
        step_rk4(s, c, va, vb, vd0, vq0);
    }
    s->k++;
    s->t_s = (double)s->k * c->Ts_s;
    check_trip(s, c);
}

static double adc_convert(plant_state_t *s, const plant_config_t *c, double i_true,
                          double offset)
{
    double x = i_true + offset;
    if (c->adc_noise_std_A > 0.0) {
        x += c->adc_noise_std_A * plant_rng_gauss(&s->rng);
    }
    if (c->adc_lsb_A > 0.0) {
        x = c->adc_lsb_A * floor(x / c->adc_lsb_A + 0.5);
    }
    if (c->adc_full_scale_A > 0.0) {
        if (x > c->adc_full_scale_A) {
            x = c->adc_full_scale_A;
        } else if (x < -c->adc_full_scale_A) {
            x = -c->adc_full_scale_A;
        }
    }
    return x;
}

void plant_sample(plant_state_t *s, const plant_config_t *c, plant_meas_t *m)
{
    double ia, ib, ic;
    phase_currents(s, &ia, &ib, &ic);
    m->i_a_true_A = ia;
    m->i_b_true_A = ib;
    m->i_c_true_A = ic;
    m->i_alpha_A = s->cos_e * s->id_A - s->sin_e * s->iq_A;
    m->i_beta_A = s->sin_e * s->id_A + s->cos_e * s->iq_A;
    m->id_A = s->id_A;
    m->iq_A = s->iq_A;
    m->theta_m_true_rad = s->theta_m_rad;
    m->theta_e_rad = fmod((double)c->pole_pairs * s->theta_m_rad, PLANT_TWO_PI);
    m->omega_m_rad_s = s->omega_m_rad_s;
    m->torque_Nm = plant_torque_Nm(s, c);
    m->t_s = s->t_s;
    m->k = s->k;
    m->tripped = s->tripped;

    m->i_a_A = (float)adc_convert(s, c, ia, c->adc_offset_a_A);
    m->i_b_A = (float)adc_convert(s, c, ib, c->adc_offset_b_A);

    if (c->encoder_lines > 0u) {
        const double cpr = 4.0 * (double)c->encoder_lines;
        double cnt = floor(s->theta_m_rad * (cpr / PLANT_TWO_PI));
        if (cnt >= cpr) {
            cnt = 0.0;
        }
        if (cnt < 0.0) {
            cnt = 0.0;
        }
        m->encoder_count = (int32_t)cnt;
        m->theta_m_rad = (float)(cnt * (PLANT_TWO_PI / cpr));
    } else {
        m->encoder_count = -1;
        m->theta_m_rad = (float)s->theta_m_rad;
    }
}
