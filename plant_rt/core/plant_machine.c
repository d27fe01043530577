/*
 * plant_machine.c - the machine block of the plant emulator (see
 * plant_machine.h; model and integration scheme: pmsm_plant.h): the model
 * functions (q-axis saturation, torque), the angle (its wrap and the cached
 * cos/sin of theta_e) and the preparation for a configuration: the speed
 * from the mechanics mode, the RK4 stiffness bound and the exact path's
 * discretization (expm(A Ts), Van Loan's energy integrals).  The step
 * itself, exact or RK4, is plant_machine_step.c's; it uses the angle from
 * here.
 *
 * Only <math.h>/<string.h>: no OS, no heap, no stdio.
 */
#include "plant_machine.h"

#include <math.h>
#include <string.h>

#include "plant_expm.h"

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
    if (c->model == PLANT_MODEL_EXTERNAL) {
        return 0.0; /* not an output of the external model */
    }
    if (c->model == PLANT_MODEL_FLUX_MAP) {
        return plant_machine_flux_torque_Nm(s, c);
    }
    const double id = s->id_A, iq = s->iq_A;
    return 1.5 * (double)c->pole_pairs * ((c->Ld_H * id + c->psi_Wb) * iq - plant_machine_psi_q_Wb(c, iq) * id);
}

/* ===================================================================== */
/* angle                                                                  */
/* ===================================================================== */

/* cos/sin(theta_e) recomputed from theta_m.  The angle's two helpers are shared with plant_machine_step.c
 * (plant_machine.h). */
void plant_machine_resync_angle(plant_state_t *s, const plant_config_t *c)
{
    const double th_e = fmod((double)c->pole_pairs * s->theta_m_rad, PLANT_TWO_PI);
    s->cos_e = cos(th_e);
    s->sin_e = sin(th_e);
    s->resync = 0u;
}

/* x wrapped to [0, 2pi), the whole turns added to *revs (if not NULL). */
double plant_machine_wrap_2pi(double x, int64_t *revs)
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
    s->theta_m_rad = plant_machine_wrap_2pi(theta_m_rad, NULL);
    if (c->mech_mode == PLANT_MECH_FREE) {
        s->omega_m_rad_s = omega_m_rad_s;
    }
    plant_machine_resync_angle(s, c);
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
    s->theta_m_rad = plant_machine_wrap_2pi(s->theta_m_rad, &s->revolutions);
    plant_machine_resync_angle(s, c);

    if (c->model == PLANT_MODEL_FLUX_MAP) {
        return plant_machine_flux_prepare(s, c, p);
    }
    s->prepared_map = NULL;      /* a later switch to a flux map takes its fluxes afresh */
    s->R_winding_ohm = c->R_ohm; /* 0x2005's status on the models without a thermal model */
    s->T_winding_degC = c->T_amb_degC;
    if (c->model == PLANT_MODEL_EXTERNAL) {
        s->exact = false; /* the model is the caller's: its speed and angle come from its outputs */
        return PLANT_OK;
    }
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
