/*
 * dq_linear.c - the linear dq model (dq_linear.h): its model functions (q-axis saturation, torque, stored energy),
 * its preparation for a configuration (the RK4 stiffness bound and the exact path's discretization: expm(A Ts),
 * Van Loan's energy integrals) and its descriptor.  The step, exact or RK4, is dq_linear_step.c's.
 *
 * Only <math.h>/<string.h>: no OS, no heap, no stdio.
 */
#include "dq_linear.h"

#include <math.h>
#include <string.h>

#include "dq_linear_step.h"
#include "plant_expm.h"

/* ===================================================================== */
/* model functions                                                        */
/* ===================================================================== */

double dq_linear_psi_q_Wb(const plant_config_t *c, double iq_A)
{
    if (!c->sat_enable) {
        return c->Lq_H * iq_A;
    }
    const double Is = c->sat_I_A, Li = c->sat_Lq_inf_H;
    return Li * iq_A + (c->Lq_H - Li) * Is * atan(iq_A / Is);
}

double dq_linear_Lq_inc_H(const plant_config_t *c, double iq_A)
{
    if (!c->sat_enable) {
        return c->Lq_H;
    }
    const double x = iq_A / c->sat_I_A;
    return c->sat_Lq_inf_H + (c->Lq_H - c->sat_Lq_inf_H) / (1.0 + x * x);
}

static double torque_Nm(const plant_state_t *s, const plant_config_t *c)
{
    const double id = s->id_A, iq = s->iq_A;
    return 1.5 * (double)c->pole_pairs * ((c->Ld_H * id + c->psi_Wb) * iq - dq_linear_psi_q_Wb(c, iq) * id);
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

static double magnetic_energy_J(const plant_state_t *s, const plant_config_t *c)
{
    return 1.5 * (0.5 * c->Ld_H * s->id_A * s->id_A + wq_energy(c, s->iq_A));
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

void dq_linear_prepare_bound(plant_state_t *s, const plant_config_t *c, double p)
{
    double Lmin = (c->Ld_H < c->Lq_H) ? c->Ld_H : c->Lq_H;
    if (c->sat_enable && c->sat_Lq_inf_H < Lmin) {
        Lmin = c->sat_Lq_inf_H;
    }
    s->Lmin_H = Lmin;
    s->lam_base = c->R_ohm / Lmin;
    if (c->mech_mode == PLANT_MECH_FREE) {
        s->lam_base += sqrt(1.5 * p * p * c->psi_Wb * c->psi_Wb / (c->J_kgm2 * Lmin));
    }
}

int dq_linear_prepare(plant_state_t *s, const plant_config_t *c, double p)
{
    plant_model_fixed_winding(s, c); /* 0x2005's status on a model without a thermal model */
    dq_linear_prepare_bound(s, c, p);
    s->exact = (c->mech_mode != PLANT_MECH_FREE) && !c->sat_enable;
    if (s->exact) {
        return prepare_exact(s, c, p * s->omega_m_rad_s);
    }
    return PLANT_OK;
}

const plant_model_desc_t plant_model_dq_linear = {
    .id = OD_PLANT_MODEL_DQ_LINEAR,
    .name = "dq_linear",
    .thermal = false, /* the exact path keeps R constant: the thermal model is the flux map's */
    .validate = NULL,
    .prepare = dq_linear_prepare,
    .step = dq_linear_step,
    .step_bridge = dq_linear_step_bridge,
    .torque_Nm = torque_Nm,
    .magnetic_energy_J = magnetic_energy_J,
};
