/* motor_model.h - the one motor the drive tests close their loops on (double precision).
 *
 * Parameters: the presets of plant_rt/core/presets.c ("you2019", "yao2020_low",
 * "yao2020_high", "zhao2022"), read with plant_preset_load() by motor_params_preset(); a test
 * changes a value only on purpose (a mismatch, a flux ratio) and says why.
 *
 * One PMSM in the rotor frame (You 2019 Eq. 1; Ld = Lq is the surface-mounted motor of Yao 2020
 * and Zhao 2022):
 *   L_d did/dt = vd - R id + w_e L_q iq
 *   L_q diq/dt = vq - R iq - w_e L_d id - w_e psi
 *   Te = 1.5 p (psi iq + (L_d - L_q) id iq),  J dw_m/dt = Te - T_load - B w_m  (free speed)
 * in two discretisations, both with the one-period command delay of the drives: advance(cmd_k)
 * applies the command stored by the previous call over [k, k+1] and stores cmd_k, so the command
 * computed from sample k acts over [k+1, k+2] and first shows in i(k+2) (You 2019 Fig. 1):
 *
 *   motor_t      RK4 with n_sub sub-steps per period, the voltage held constant in the STATOR
 *                frame (what an inverter applies), speed fixed or integrated (free_speed).
 *   motor_zoh_t  the exact discrete model the papers' equations assume: the voltage held in the
 *                ROTOR frame, constant electrical speed w_e,
 *                  i(k+1) = Phi i(k) + Gam (u(k) - j w_e psi),  i = id + j iq,
 *                  Phi = exp(-(R/L + j w_e) Ts),  Gam = (1 - Phi) / (R + j w_e L)
 *                (Ld = Lq = L); a salient motor (Ld != Lq) only at standstill, per axis:
 *                  i_x(k+1) = A_x i_x(k) + B_x u_x(k),  A_x = exp(-Ts R/L_x),  B_x = (1 - A_x)/R.
 *
 * Header only; a test that includes it links libplant (the presets and the plant core: Makefile). */
#ifndef TESTS_C_MOTOR_MODEL_H
#define TESTS_C_MOTOR_MODEL_H

#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "presets.h"

#define MOTOR_PI 3.14159265358979323846
#define MOTOR_IM CMPLX(0.0, 1.0) /* double imaginary unit (I is complex float) */

/* ------------------------------------------------------------------ parameters */
typedef struct {
    double R_ohm, Ld_H, Lq_H, psi_Wb;
    double pole_pairs;
    double Ts_s; /* current-loop period */
    double J_kgm2, B_Nm_s_rad, T_load_Nm;
    double Vdc_V;
    double omega_m_rated_rad_s; /* the preset's imposed (rated) mechanical speed, 0 if none */
} motor_params_t;

/* The motor of a preset; an unknown name ends the test (exit status 1). */
static inline motor_params_t motor_params_preset(const char *name)
{
    plant_config_t c;
    if (plant_preset_load(name, &c) != 0) {
        printf("FAIL %s:%d: no preset \"%s\" in plant_rt/core/presets.c\n", __FILE__, __LINE__, name);
        exit(1);
    }
    motor_params_t p;
    p.R_ohm = c.R_ohm;
    p.Ld_H = c.Ld_H;
    p.Lq_H = c.Lq_H;
    p.psi_Wb = c.psi_Wb;
    p.pole_pairs = (double)c.pole_pairs;
    p.Ts_s = c.Ts_s;
    p.J_kgm2 = c.J_kgm2;
    p.B_Nm_s_rad = c.B_Nm_per_rad_s;
    p.T_load_Nm = c.T_load_Nm;
    p.Vdc_V = c.Vdc_V;
    p.omega_m_rated_rad_s = c.omega_imposed_rad_s;
    return p;
}

/* ------------------------------------------------------------------ continuous (RK4) */
typedef struct {
    motor_params_t par;
    double id_A, iq_A;
    double theta_m_rad; /* not wrapped */
    double omega_m_rad_s;
    double v_alpha_pend_V, v_beta_pend_V; /* command waiting for its interval (stator frame) */
    int free_speed;                       /* 1: integrate the mechanics, 0: omega_m fixed */
    int n_sub;                            /* RK4 sub-steps per period */
} motor_t;

static inline void motor_init(motor_t *m, const motor_params_t *par)
{
    m->par = *par;
    m->id_A = m->iq_A = 0.0;
    m->theta_m_rad = 0.0;
    m->omega_m_rad_s = 0.0;
    m->v_alpha_pend_V = m->v_beta_pend_V = 0.0;
    m->free_speed = 0;
    m->n_sub = 40;
}

static inline double motor_theta_e(const motor_t *m) { return m->par.pole_pairs * m->theta_m_rad; }
static inline double motor_omega_e(const motor_t *m) { return m->par.pole_pairs * m->omega_m_rad_s; }

static inline void motor_deriv(const motor_t *m, double th_m, double w_m, double id, double iq, double *did,
                               double *diq, double *dw)
{
    const motor_params_t *p = &m->par;
    const double th = p->pole_pairs * th_m, we = p->pole_pairs * w_m;
    const double c = cos(th), s = sin(th);
    const double vd = m->v_alpha_pend_V * c + m->v_beta_pend_V * s;
    const double vq = -m->v_alpha_pend_V * s + m->v_beta_pend_V * c;
    *did = (vd - p->R_ohm * id + we * p->Lq_H * iq) / p->Ld_H;
    *diq = (vq - p->R_ohm * iq - we * p->Ld_H * id - we * p->psi_Wb) / p->Lq_H;
    const double Te = 1.5 * p->pole_pairs * (p->psi_Wb * iq + (p->Ld_H - p->Lq_H) * id * iq);
    *dw = m->free_speed ? (Te - p->T_load_Nm - p->B_Nm_s_rad * w_m) / p->J_kgm2 : 0.0;
}

/* One period: the stored command over [k, k+1], then (v_alpha_V, v_beta_V) is stored. */
static inline void motor_advance(motor_t *m, double v_alpha_V, double v_beta_V)
{
    const double h = m->par.Ts_s / m->n_sub;
    for (int n = 0; n < m->n_sub; ++n) {
        double k1d, k1q, k1w, k2d, k2q, k2w, k3d, k3q, k3w, k4d, k4q, k4w;
        const double t0 = m->theta_m_rad, w0 = m->omega_m_rad_s, d0 = m->id_A, q0 = m->iq_A;
        motor_deriv(m, t0, w0, d0, q0, &k1d, &k1q, &k1w);
        motor_deriv(m, t0 + 0.5 * h * w0, w0 + 0.5 * h * k1w, d0 + 0.5 * h * k1d, q0 + 0.5 * h * k1q, &k2d, &k2q, &k2w);
        motor_deriv(m, t0 + 0.5 * h * (w0 + 0.5 * h * k1w), w0 + 0.5 * h * k2w, d0 + 0.5 * h * k2d, q0 + 0.5 * h * k2q,
                    &k3d, &k3q, &k3w);
        motor_deriv(m, t0 + h * (w0 + 0.5 * h * k2w), w0 + h * k3w, d0 + h * k3d, q0 + h * k3q, &k4d, &k4q, &k4w);
        m->id_A = d0 + h / 6.0 * (k1d + 2 * k2d + 2 * k3d + k4d);
        m->iq_A = q0 + h / 6.0 * (k1q + 2 * k2q + 2 * k3q + k4q);
        m->omega_m_rad_s = w0 + h / 6.0 * (k1w + 2 * k2w + 2 * k3w + k4w);
        m->theta_m_rad = t0 + h * (w0 + m->omega_m_rad_s) * 0.5;
    }
    m->v_alpha_pend_V = v_alpha_V;
    m->v_beta_pend_V = v_beta_V;
}

/* ------------------------------------------------------------------ exact discrete (ZOH) */
/* Phi, Gam of the round-rotor model for (R, L, Ts, w_e); Gam = Ts/L in the limit a Ts -> 0. */
static inline void motor_zoh_coeffs(double R_ohm, double L_H, double Ts_s, double omega_e_rad_s, double complex *Phi,
                                    double complex *Gam)
{
    const double complex a = R_ohm / L_H + MOTOR_IM * omega_e_rad_s;
    *Phi = cexp(-a * Ts_s);
    if (cabs(a * Ts_s) > 1e-8) {
        *Gam = (1.0 - *Phi) / (L_H * a);
    } else {
        *Gam = Ts_s / L_H;
    }
}

typedef struct {
    motor_params_t par;
    double omega_e_rad_s;        /* constant */
    double complex i_A;          /* id + j iq */
    double vd_pend_V, vq_pend_V; /* command waiting for its interval (rotor frame) */
    int salient;                 /* Ld != Lq: per-axis coefficients (standstill only) */
    double complex Phi, Gam;     /* round rotor */
    double Ad, Bd, Aq, Bq;       /* salient rotor at standstill */
} motor_zoh_t;

/* Returns 0, or -1 for a salient motor at a speed (no exact per-axis model there). */
static inline int motor_zoh_init(motor_zoh_t *m, const motor_params_t *par, double omega_e_rad_s)
{
    m->par = *par;
    m->omega_e_rad_s = omega_e_rad_s;
    m->i_A = 0.0;
    m->vd_pend_V = m->vq_pend_V = 0.0;
    m->salient = par->Ld_H != par->Lq_H;
    m->Phi = m->Gam = 0.0;
    m->Ad = m->Bd = m->Aq = m->Bq = 0.0;
    if (m->salient) {
        if (omega_e_rad_s != 0.0) return -1;
        m->Aq = exp(-par->Ts_s * par->R_ohm / par->Lq_H);
        m->Bq = (1.0 - m->Aq) / par->R_ohm;
        m->Ad = exp(-par->Ts_s * par->R_ohm / par->Ld_H);
        m->Bd = (1.0 - m->Ad) / par->R_ohm;
    } else {
        motor_zoh_coeffs(par->R_ohm, par->Lq_H, par->Ts_s, omega_e_rad_s, &m->Phi, &m->Gam);
    }
    return 0;
}

/* One period: the stored command over [k, k+1], then (vd_V, vq_V) is stored. */
static inline void motor_zoh_advance(motor_zoh_t *m, double vd_V, double vq_V)
{
    if (m->salient) {
        const double iq = m->Aq * cimag(m->i_A) + m->Bq * m->vq_pend_V;
        const double id = m->Ad * creal(m->i_A) + m->Bd * m->vd_pend_V;
        m->i_A = CMPLX(id, iq);
    } else {
        const double complex u = m->vd_pend_V + MOTOR_IM * m->vq_pend_V;
        m->i_A = m->Phi * m->i_A + m->Gam * (u - MOTOR_IM * m->omega_e_rad_s * m->par.psi_Wb);
    }
    m->vd_pend_V = vd_V;
    m->vq_pend_V = vq_V;
}

#endif /* TESTS_C_MOTOR_MODEL_H */
