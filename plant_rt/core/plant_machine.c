/*
 * plant_machine.c - the machine block of the plant emulator (see
 * plant_machine.h; model and integration scheme: pmsm_plant.h).
 *
 * Only <math.h>/<string.h>: no OS, no heap, no stdio.
 */
#include "plant_machine.h"

#include <math.h>
#include <string.h>

#include "plant_expm.h"

#define PLANT_RESYNC_PERIODS 1024u /* recompute cos/sin(theta_e) from theta_m */
#define PLANT_RK4_MAX_SUBSTEPS 100000u

/* ===================================================================== */
/* model functions                                                        */
/* ===================================================================== */

double plant_machine_psi_q_Wb(const plant_config_t *c, double iq_A)
{
    if (!c->sat_enable) {
        return c->Lq_H * iq_A;
    }
    const double Is = c->sat_I_A, Li = c->sat_Lq_inf_H;
    return Li * iq_A + (c->Lq_H - Li) * Is * atan(iq_A / Is);
}

double plant_machine_Lq_inc_H(const plant_config_t *c, double iq_A)
{
    if (!c->sat_enable) {
        return c->Lq_H;
    }
    const double x = iq_A / c->sat_I_A;
    return c->sat_Lq_inf_H + (c->Lq_H - c->sat_Lq_inf_H) / (1.0 + x * x);
}

double plant_machine_torque_Nm(const plant_state_t *s, const plant_config_t *c)
{
    const double id = s->id_A, iq = s->iq_A;
    return 1.5 * (double)c->pole_pairs * ((c->Ld_H * id + c->psi_Wb) * iq - plant_machine_psi_q_Wb(c, iq) * id);
}

/* ===================================================================== */
/* angle                                                                  */
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
        if (x >= PLANT_TWO_PI) { /* rounding guard */
            x -= PLANT_TWO_PI;
        }
        if (x < 0.0) {
            x = 0.0;
        }
    }
    return x;
}

void plant_machine_set_mech(plant_state_t *s, const plant_config_t *c, double theta_m_rad, double omega_m_rad_s)
{
    s->theta_m_rad = wrap_2pi(theta_m_rad, NULL);
    if (c->mech_mode == PLANT_MECH_FREE) {
        s->omega_m_rad_s = omega_m_rad_s;
    }
    resync_angle(s, c);
}

/* ===================================================================== */
/* discretization                                                         */
/* ===================================================================== */

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
        A[2 * 5 + 3] = w_e;  /* d vd/dt =  w vq */
        A[3 * 5 + 2] = -w_e; /* d vq/dt = -w vd */
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
    Qin[0 * 5 + 2] = Qin[2 * 5 + 0] = 0.75; /* 1.5 vd id */
    Qin[1 * 5 + 3] = Qin[3 * 5 + 1] = 0.75; /* 1.5 vq iq */
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

int plant_machine_prepare(plant_state_t *s, const plant_config_t *c)
{
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

    s->exact = (c->mech_mode != PLANT_MECH_FREE) && !c->sat_enable;
    if (s->exact) {
        return prepare_exact(s, c, w_e);
    }
    return PLANT_OK;
}

/* ===================================================================== */
/* RK4 path                                                              */
/* ===================================================================== */

enum { Y_ID, Y_IQ, Y_C, Y_S, Y_TH, Y_W, Y_EIN, Y_ECU, Y_EME, Y_EFR, Y_ELD, Y_N };

typedef struct {
    const plant_config_t *c;
    double va, vb;   /* applied, stator frame */
    double vd0, vq0; /* rotor-hold values */
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

static void step_rk4(plant_state_t *s, const plant_config_t *c, double va, double vb, double vd0, double vq0)
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
        s->theta_m_rad = wrap_2pi(th, &s->revolutions);
        if (++s->resync >= PLANT_RESYNC_PERIODS) {
            resync_angle(s, c);
        } else {
            s->cos_e = ce * s->rot_c - se * s->rot_s;
            s->sin_e = se * s->rot_c + ce * s->rot_s;
        }
    }
}

void plant_machine_step(plant_state_t *s, const plant_config_t *c, double v_alpha_V, double v_beta_V)
{
    const double va = v_alpha_V, vb = v_beta_V;
    const double ce = s->cos_e, se = s->sin_e;
    const double vd0 = va * ce + vb * se;
    const double vq0 = -va * se + vb * ce;

    if (s->exact) {
        step_exact(s, c, vd0, vq0);
    } else {
        step_rk4(s, c, va, vb, vd0, vq0);
    }
}
