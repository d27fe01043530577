/* linear_pmsm_model.h - the linear PMSM of the example FMUs (examples/fmu/linear_pmsm: FMI 2.0;
 * examples/fmu/linear_pmsm_fmi3: FMI 3.0, which links this file): its variables by value reference, its state,
 * its RK4 over a communication step (the model: linear_pmsm.c's head comment).  Header only: each FMU's one C
 * file includes it. */
#ifndef LINEAR_PMSM_MODEL_H
#define LINEAR_PMSM_MODEL_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

enum { V_ALPHA, V_BETA, I_A, I_B, THETA_M, OMEGA_M, N_IO };
enum { P_R = 10, P_LD, P_LQ, P_PSI, P_POLES, P_OMEGA, P_SUBSTEPS, P_FAIL_AT, P_END };

typedef struct {
    double io[N_IO];
    double par[P_END - P_R];
    double id, iq, theta_m;
    int failed;
} model_t;

static const double k_defaults[P_END - P_R] = {1.4, 4.46e-3, 4.54e-3, 0.042, 5.0, 0.0, 20.0, 0.0};

static double *ref(model_t *m, uint32_t vr)
{
    if (vr < N_IO) return &m->io[vr];
    if (vr >= P_R && vr < P_END) return &m->par[vr - P_R];
    return NULL;
}

static void outputs(model_t *m)
{
    const double te = m->par[P_POLES - P_R] * m->theta_m, c = cos(te), s = sin(te);
    const double ial = c * m->id - s * m->iq, ibe = s * m->id + c * m->iq;
    m->io[I_A] = ial;
    m->io[I_B] = -0.5 * ial + 0.5 * sqrt(3.0) * ibe;
    m->io[THETA_M] = m->theta_m;
    m->io[OMEGA_M] = m->par[P_OMEGA - P_R];
}

static void reset_state(model_t *m)
{
    m->id = m->iq = m->theta_m = 0.0;
    m->failed = 0;
    outputs(m);
}

/* d/dt (id, iq) at the angle th_m */
static void deriv(const model_t *m, double th_m, double id, double iq, double *did, double *diq)
{
    const double R = m->par[0], Ld = m->par[1], Lq = m->par[2], psi = m->par[3], p = m->par[4];
    const double w = p * m->par[P_OMEGA - P_R], te = p * th_m, c = cos(te), s = sin(te);
    const double vd = c * m->io[V_ALPHA] + s * m->io[V_BETA], vq = -s * m->io[V_ALPHA] + c * m->io[V_BETA];
    *did = (vd - R * id + w * Lq * iq) / Ld;
    *diq = (vq - R * iq - w * Ld * id - w * psi) / Lq;
}

static void advance(model_t *m, double h_total)
{
    const int n = (int)(m->par[P_SUBSTEPS - P_R] >= 1.0 ? m->par[P_SUBSTEPS - P_R] : 1.0);
    const double h = h_total / n, wm = m->par[P_OMEGA - P_R];
    for (int k = 0; k < n; ++k) {
        const double th = m->theta_m;
        double a1, b1, a2, b2, a3, b3, a4, b4;
        deriv(m, th, m->id, m->iq, &a1, &b1);
        deriv(m, th + 0.5 * h * wm, m->id + 0.5 * h * a1, m->iq + 0.5 * h * b1, &a2, &b2);
        deriv(m, th + 0.5 * h * wm, m->id + 0.5 * h * a2, m->iq + 0.5 * h * b2, &a3, &b3);
        deriv(m, th + h * wm, m->id + h * a3, m->iq + h * b3, &a4, &b4);
        m->id += h / 6.0 * (a1 + 2.0 * (a2 + a3) + a4);
        m->iq += h / 6.0 * (b1 + 2.0 * (b2 + b3) + b4);
        m->theta_m += h * wm;
    }
}

/* every variable to its start value, the state to zero */
static void model_init(model_t *m)
{
    memcpy(m->par, k_defaults, sizeof m->par);
    memset(m->io, 0, sizeof m->io);
    reset_state(m);
}

/* whether the master may set this variable (the inputs and the parameters) */
static int model_settable(uint32_t vr) { return vr == V_ALPHA || vr == V_BETA || (vr >= P_R && vr < P_END); }

/* the values of n variables: 0, or -1 at an unknown value reference */
static int model_get(model_t *m, const uint32_t vr[], size_t n, double v[])
{
    for (size_t i = 0; i < n; ++i) {
        const double *p = ref(m, vr[i]);
        if (p == NULL) return -1;
        v[i] = *p;
    }
    return 0;
}

/* n variables set: 0, or -1 at one the master may not set */
static int model_set(model_t *m, const uint32_t vr[], size_t n, const double v[])
{
    for (size_t i = 0; i < n; ++i) {
        double *p = ref(m, vr[i]);
        if (p == NULL || !model_settable(vr[i])) return -1;
        *p = v[i];
    }
    return 0;
}

/* one communication step [t, t + h]: 0, or -1 once it failed (fail_at, a test's fault: for good after that) */
static int model_do_step(model_t *m, double t, double h)
{
    const double fail_at = m->par[P_FAIL_AT - P_R];
    if (m->failed || (fail_at > 0.0 && t >= fail_at)) {
        m->failed = 1;
        return -1;
    }
    advance(m, h);
    outputs(m);
    return 0;
}

#endif
