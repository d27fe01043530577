/*
 * plant_test_util.h - shared helpers for the plant core tests (header only); the check
 * macros are those of tests/c/check.h.
 *
 * ref_*: an INDEPENDENT reference model in long double, written in a
 * different formulation from the core:
 *   - flux linkages psi_d, psi_q are the states (the core integrates currents),
 *     iq is recovered from psi_q by Newton iteration when saturation is on;
 *   - the rotor-frame voltage is computed with cosl/sinl of the electrical
 *     angle at every RK4 stage (the core uses an augmented rotating-input
 *     state / a matrix exponential);
 *   - classical RK4 with many sub-steps (default 2000 per period).
 */
#ifndef PLANT_TEST_UTIL_H
#define PLANT_TEST_UTIL_H

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "pmsm_plant.h"

#define T_PI 3.14159265358979323846264338327950288L
#define T_TWO_PI (2.0L * T_PI)

/* deterministic command sequence for the tests (LCG, independent of the core) */
static inline double test_lcg_uniform(unsigned long long *st)
{
    *st = *st * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*st >> 11) * (1.0 / 9007199254740992.0);
}

typedef struct {
    long double R, Ld, Lq, psi, p;
    int sat;
    long double Is, Li;
    int free_mech;
    long double J, B, TL;
    int rotor_hold;
} ref_par_t;

typedef struct {
    long double psid, psiq; /* flux linkages */
    long double th_e;       /* electrical angle (unwrapped) */
    long double wm;         /* mechanical speed */
    long double e_in, e_cu, e_mech;
} ref_state_t;

static inline ref_par_t ref_from_config(const plant_config_t *c)
{
    ref_par_t r;
    r.R = (long double)c->R_ohm;
    r.Ld = (long double)c->Ld_H;
    r.Lq = (long double)c->Lq_H;
    r.psi = (long double)c->psi_Wb;
    r.p = c->pole_pairs;
    r.sat = c->sat_enable;
    r.Is = (long double)c->sat_I_A;
    r.Li = (long double)c->sat_Lq_inf_H;
    r.free_mech = (c->mech_mode == PLANT_MECH_FREE);
    r.J = (long double)c->J_kgm2;
    r.B = (long double)c->B_Nm_per_rad_s;
    r.TL = (long double)c->T_load_Nm;
    r.rotor_hold = (c->hold_frame == PLANT_HOLD_ROTOR);
    return r;
}

static inline long double ref_psiq_of_iq(const ref_par_t *r, long double iq)
{
    if (!r->sat) {
        return r->Lq * iq;
    }
    return r->Li * iq + (r->Lq - r->Li) * r->Is * atanl(iq / r->Is);
}

static inline long double ref_iq_of_psiq(const ref_par_t *r, long double psq)
{
    if (!r->sat) {
        return psq / r->Lq;
    }
    /* Newton on the monotone map; start from the unsaturated guess. */
    long double iq = psq / r->Lq;
    for (int it = 0; it < 100; ++it) {
        const long double x = iq / r->Is;
        const long double f = r->Li * iq + (r->Lq - r->Li) * r->Is * atanl(x) - psq;
        const long double df = r->Li + (r->Lq - r->Li) / (1.0L + x * x);
        const long double d = f / df;
        iq -= d;
        if (fabsl(d) <= 1e-19L * (1.0L + fabsl(iq))) {
            break;
        }
    }
    return iq;
}

static inline void ref_currents(const ref_par_t *r, const ref_state_t *s, long double *id, long double *iq)
{
    *id = (s->psid - r->psi) / r->Ld;
    *iq = ref_iq_of_psiq(r, s->psiq);
}

static inline void ref_set_currents(const ref_par_t *r, ref_state_t *s, long double id, long double iq)
{
    s->psid = r->Ld * id + r->psi;
    s->psiq = ref_psiq_of_iq(r, iq);
}

static inline void ref_deriv(const ref_par_t *r, const ref_state_t *s, long double va, long double vb, long double vd0,
                             long double vq0, ref_state_t *d)
{
    long double id, iq;
    ref_currents(r, s, &id, &iq);
    long double vd, vq;
    if (r->rotor_hold) {
        vd = vd0;
        vq = vq0;
    } else {
        const long double c = cosl(s->th_e), sn = sinl(s->th_e);
        vd = va * c + vb * sn;
        vq = -va * sn + vb * c;
    }
    const long double we = r->p * s->wm;
    d->psid = vd - r->R * id + we * s->psiq;
    d->psiq = vq - r->R * iq - we * s->psid;
    d->th_e = we;
    const long double Te = 1.5L * r->p * (s->psid * iq - s->psiq * id);
    d->wm = r->free_mech ? (Te - r->B * s->wm - r->TL) / r->J : 0.0L;
    d->e_in = 1.5L * (vd * id + vq * iq);
    d->e_cu = 1.5L * r->R * (id * id + iq * iq);
    d->e_mech = Te * s->wm;
}

static inline void ref_axpy(ref_state_t *out, const ref_state_t *y, long double h, const ref_state_t *k)
{
    out->psid = y->psid + h * k->psid;
    out->psiq = y->psiq + h * k->psiq;
    out->th_e = y->th_e + h * k->th_e;
    out->wm = y->wm + h * k->wm;
    out->e_in = y->e_in + h * k->e_in;
    out->e_cu = y->e_cu + h * k->e_cu;
    out->e_mech = y->e_mech + h * k->e_mech;
}

/* One period T with (va, vb) held in the stator frame (or, if rotor_hold, the
 * dq values at the period start held in the rotor frame). */
static inline void ref_period(const ref_par_t *r, ref_state_t *s, double va_d, double vb_d, double T_d, int nsub)
{
    const long double va = (long double)va_d, vb = (long double)vb_d, T = (long double)T_d;
    const long double c0 = cosl(s->th_e), s0 = sinl(s->th_e);
    const long double vd0 = va * c0 + vb * s0, vq0 = -va * s0 + vb * c0;
    const long double h = T / (long double)nsub;
    ref_state_t k1, k2, k3, k4, yt;
    for (int i = 0; i < nsub; ++i) {
        ref_deriv(r, s, va, vb, vd0, vq0, &k1);
        ref_axpy(&yt, s, 0.5L * h, &k1);
        ref_deriv(r, &yt, va, vb, vd0, vq0, &k2);
        ref_axpy(&yt, s, 0.5L * h, &k2);
        ref_deriv(r, &yt, va, vb, vd0, vq0, &k3);
        ref_axpy(&yt, s, h, &k3);
        ref_deriv(r, &yt, va, vb, vd0, vq0, &k4);
        s->psid += h / 6.0L * (k1.psid + 2.0L * (k2.psid + k3.psid) + k4.psid);
        s->psiq += h / 6.0L * (k1.psiq + 2.0L * (k2.psiq + k3.psiq) + k4.psiq);
        s->th_e += h / 6.0L * (k1.th_e + 2.0L * (k2.th_e + k3.th_e) + k4.th_e);
        s->wm += h / 6.0L * (k1.wm + 2.0L * (k2.wm + k3.wm) + k4.wm);
        s->e_in += h / 6.0L * (k1.e_in + 2.0L * (k2.e_in + k3.e_in) + k4.e_in);
        s->e_cu += h / 6.0L * (k1.e_cu + 2.0L * (k2.e_cu + k3.e_cu) + k4.e_cu);
        s->e_mech += h / 6.0L * (k1.e_mech + 2.0L * (k2.e_mech + k3.e_mech) + k4.e_mech);
    }
}

#endif
