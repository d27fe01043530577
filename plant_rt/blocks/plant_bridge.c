/*
 * plant_bridge.c - the bridge with its switches off (plant_bridge.h): the voltage of each conduction state and
 * the period's integration with the changes of state located.
 *
 * Accuracy.  Between changes of conduction state the model is smooth and RK4 keeps its order: a local error of
 * about (h lambda)^5 / 120 relative a sub-step, with h lambda <= rk4_h_rel (0.02 by default) from the model's
 * own stiffness bound, i.e. <= 3e-11 relative a sub-step.  A change inside a sub-step is located by regula falsi
 * (Illinois) on the sub-step's length until the bracket is a few ULPs of the sub-step: every trial is a full RK4
 * step from the sub-step's start, so the state at the change carries RK4's error and no interpolation's; the
 * crossing current is then set to exactly zero (the state projected on the phase's off line), and an off phase's
 * current is projected back to zero after every sub-step (RK4 keeps it there only to its own error when the
 * rotor turns).  A test checks it against the closed-form solutions (plant_rt/tests/test_plant_trip_reaction.c).
 *
 * Only <math.h>/<float.h>: no OS, no heap, no stdio.
 */
#include "plant_bridge.h"

#include <float.h>
#include <math.h>

#define BR_SQRT3 1.732050807568877293527446341505872367

/* the phases' unit vectors in the alpha-beta plane (amplitude-invariant Clarke: i_x = n_x . i_alphabeta) */
static const double NX[3] = {1.0, -0.5, -0.5};
static const double NY[3] = {0.0, 0.5 * BR_SQRT3, -0.5 * BR_SQRT3};

static int off_count(const plant_bridge_t *b, int *z)
{
    int n = 0;
    for (int x = 0; x < 3; ++x) {
        if (b->phase[x] == 0) {
            ++n;
            *z = x;
        }
    }
    return n;
}

void plant_bridge_voltage(plant_bridge_t *b, const plant_bridge_lin_t *l, double *vd_V, double *vq_V)
{
    const double c = l->cos_e, s = l->sin_e, w = l->w_e;
    /* d i_alphabeta/dt = R(theta) (w J i_dq + a + B R(theta)' v) = as + Bs v */
    const double ad = l->a_d_A_s - w * l->iq_A, aq = l->a_q_A_s + w * l->id_A;
    const double asa = c * ad - s * aq, asb = s * ad + c * aq;
    const double(*B)[2] = l->B_per_H;
    const double m00 = c * B[0][0] - s * B[1][0], m01 = c * B[0][1] - s * B[1][1]; /* R B */
    const double m10 = s * B[0][0] + c * B[1][0], m11 = s * B[0][1] + c * B[1][1];
    const double b00 = m00 * c - m01 * s, b01 = m00 * s + m01 * c; /* (R B) R' */
    const double b10 = m10 * c - m11 * s, b11 = m10 * s + m11 * c;
    const double half = 0.5 * b->Vdc_V;
    int z = 0;
    const int off = off_count(b, &z);
    double va = 0.0, vb = 0.0;
    for (int x = 0; x < 3; ++x) { /* the conducting phases' terminals on their rails */
        const double u = -(double)b->phase[x] * half;
        va += (2.0 / 3.0) * u * NX[x];
        vb += (2.0 / 3.0) * u * NY[x];
    }
    if (off == 0) {
        b->margin_V = INFINITY;
    } else if (off == 1) {
        /* the off phase's voltage u keeps its current at zero: n_z . (as + Bs (v0 + (2/3) u n_z)) = 0 */
        const double ga = (2.0 / 3.0) * NX[z], gb = (2.0 / 3.0) * NY[z];
        const double num = NX[z] * (asa + b00 * va + b01 * vb) + NY[z] * (asb + b10 * va + b11 * vb);
        const double den = NX[z] * (b00 * ga + b01 * gb) + NY[z] * (b10 * ga + b11 * gb);
        const double u = den > 0.0 ? -num / den : 0.0; /* den > 0 for a positive-definite inductance */
        va += u * ga;
        vb += u * gb;
        b->u_off_V = u;
        b->margin_V = half - fabs(u);
    } else {
        /* all off: the voltage that keeps the currents at zero is the back-EMF, -Bs^-1 as */
        const double det = b00 * b11 - b01 * b10;
        va = det != 0.0 ? -(b11 * asa - b01 * asb) / det : 0.0;
        vb = det != 0.0 ? -(b00 * asb - b10 * asa) / det : 0.0;
        double emax = -INFINITY, emin = INFINITY;
        for (int x = 0; x < 3; ++x) {
            const double e = NX[x] * va + NY[x] * vb;
            if (e > emax) {
                emax = e;
                b->emf_max = (int8_t)x;
            }
            if (e < emin) {
                emin = e;
                b->emf_min = (int8_t)x;
            }
        }
        b->margin_V = b->Vdc_V - (emax - emin);
    }
    b->v_alpha_V = va;
    b->v_beta_V = vb;
    *vd_V = c * va + s * vb;
    *vq_V = -s * va + c * vb;
}

/* ------------------------------------------------------------------ the period */

/* The state's currents projected on the conduction state: an off phase's current to zero, all off to zero. */
static void project(const plant_bridge_t *b, const plant_bridge_model_t *m, double *y)
{
    int z = 0;
    const int off = off_count(b, &z);
    if (off == 0) return;
    if (off > 1) {
        m->set_currents(m->ctx, y, 0.0, 0.0);
        return;
    }
    double ia, ib;
    m->currents(m->ctx, y, &ia, &ib);
    const double iz = NX[z] * ia + NY[z] * ib;
    if (iz != 0.0) m->set_currents(m->ctx, y, ia - iz * NX[z], ib - iz * NY[z]);
}

/* The margin of the conduction state (> 0 while it holds) from the last plant_bridge_voltage and the phase
 * currents: each conducting phase's sigma i in A (the scale does not matter: only the first crossing of zero
 * counts) and the voltage margin over Vdc; the phases in skip (their current zero at the sub-step's start: they
 * begin to conduct) are left out.  *which: the phase whose current is the smallest, or 3 for the voltage margin. */
static double combine(const plant_bridge_t *b, const double i_ph[3], unsigned skip, int *which)
{
    double g = b->margin_V / b->Vdc_V;
    *which = 3;
    for (int x = 0; x < 3; ++x) {
        if (b->phase[x] != 0 && !((skip >> x) & 1u)) {
            const double v = (double)b->phase[x] * i_ph[x];
            if (v < g) {
                g = v;
                *which = x;
            }
        }
    }
    return g;
}

/* The margin at y (combine), its phase currents, and the derivative there (dy). */
static double margin_at(plant_bridge_t *b, const plant_bridge_model_t *m, const double *y, double *dy, unsigned skip,
                        int *which, double i_ph[3])
{
    m->deriv(m->ctx, y, dy); /* the state's voltage and margin_V */
    double ia, ib;
    m->currents(m->ctx, y, &ia, &ib);
    for (int x = 0; x < 3; ++x) i_ph[x] = NX[x] * ia + NY[x] * ib;
    return combine(b, i_ph, skip, which);
}

/* One RK4 step of length h from y0 (k1: the derivative there, va1/vb1 its voltage) into y; *wa, *wb: the
 * integral of the applied voltage over the step (the same quadrature). */
static void rk4(plant_bridge_t *b, const plant_bridge_model_t *m, const double *y0, const double *k1, double va1,
                double vb1, double h, double *y, double *wa, double *wb)
{
    double k2[PLANT_BRIDGE_MAX_Y] = {0}, k3[PLANT_BRIDGE_MAX_Y] = {0}, k4[PLANT_BRIDGE_MAX_Y] = {0};
    double yt[PLANT_BRIDGE_MAX_Y] = {0};
    const int n = m->n_y < PLANT_BRIDGE_MAX_Y ? m->n_y : PLANT_BRIDGE_MAX_Y;
    for (int i = 0; i < n; ++i) yt[i] = y0[i] + 0.5 * h * k1[i];
    m->deriv(m->ctx, yt, k2);
    const double va2 = b->v_alpha_V, vb2 = b->v_beta_V;
    for (int i = 0; i < n; ++i) yt[i] = y0[i] + 0.5 * h * k2[i];
    m->deriv(m->ctx, yt, k3);
    const double va3 = b->v_alpha_V, vb3 = b->v_beta_V;
    for (int i = 0; i < n; ++i) yt[i] = y0[i] + h * k3[i];
    m->deriv(m->ctx, yt, k4);
    for (int i = 0; i < n; ++i) y[i] = y0[i] + (h / 6.0) * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
    *wa = (h / 6.0) * (va1 + 2.0 * (va2 + va3) + b->v_alpha_V);
    *wb = (h / 6.0) * (vb1 + 2.0 * (vb2 + vb3) + b->v_beta_V);
}

/* After a change: while the state's margin is negative, the phase it names starts to conduct (an off phase
 * whose voltage is beyond a rail conducts on that rail's side; with all off, the phases of the highest and
 * lowest back-EMF conduct). */
static void settle(plant_bridge_t *b, const plant_bridge_model_t *m, const double *y)
{
    double dy[PLANT_BRIDGE_MAX_Y] = {0};
    for (int it = 0; it < 3; ++it) {
        m->deriv(m->ctx, y, dy);
        int z = 0;
        const int off = off_count(b, &z);
        if (off == 0 || !(b->margin_V < 0.0)) return;
        if (off == 1) {
            b->phase[z] = (int8_t)(b->u_off_V > 0.0 ? -1 : 1);
        } else {
            b->phase[b->emf_max] = -1; /* its current flows out of the motor into the upper rail */
            b->phase[b->emf_min] = 1;
        }
    }
}

/* The change named by which (a phase's current reached zero, or the voltage margin), at y. */
static void change(plant_bridge_t *b, const plant_bridge_model_t *m, double *y, int which)
{
    int z = 0;
    const int off = off_count(b, &z);
    if (which < 3) {
        if (off == 0) {
            b->phase[which] = 0; /* one of three stops: the other two go on */
        } else {
            b->phase[0] = b->phase[1] = b->phase[2] = 0; /* the pair's current reached zero: all off */
        }
        project(b, m, y);
    } else if (off == 1) {
        b->phase[z] = (int8_t)(b->u_off_V > 0.0 ? -1 : 1);
    } else if (off == 3) {
        b->phase[b->emf_max] = -1;
        b->phase[b->emf_min] = 1;
    }
    settle(b, m, y);
    ++b->events;
}

/* The conduction state from the currents' signs (the first period with the pulses off). */
static void select_state(plant_bridge_t *b, const plant_bridge_model_t *m, double *y)
{
    double ia, ib;
    m->currents(m->ctx, y, &ia, &ib);
    int zeros = 0;
    for (int x = 0; x < 3; ++x) {
        const double i = NX[x] * ia + NY[x] * ib;
        b->phase[x] = (int8_t)(i > 0.0 ? 1 : (i < 0.0 ? -1 : 0));
        zeros += b->phase[x] == 0;
    }
    if (zeros > 1) b->phase[0] = b->phase[1] = b->phase[2] = 0;
    b->active = true;
    project(b, m, y);
    settle(b, m, y);
}

void plant_bridge_period(plant_bridge_t *b, const plant_bridge_model_t *m, double *y, double Ts_s, uint32_t n)
{
    if (!b->active) select_state(b, m, y);
    project(b, m, y); /* the model re-derived its angle at the last period's end */
    const double h0 = Ts_s / (double)(n > 0u ? n : 1u);
    double t = 0.0, wsum_a = 0.0, wsum_b = 0.0;
    uint32_t events = 0u;
    double k1[PLANT_BRIDGE_MAX_Y] = {0}, y1[PLANT_BRIDGE_MAX_Y] = {0}, dy[PLANT_BRIDGE_MAX_Y] = {0};
    double i0[3], i1[3];
    bool last = false;
    while (!last) {
        double h = h0;
        if (Ts_s - t <= h0 * (1.0 + 1e-9)) {
            h = Ts_s - t;
            last = true;
        }
        if (!(h > 0.0)) break;
        int w0 = 3, w1 = 3;
        (void)margin_at(b, m, y, k1, 0u, &w0, i0);
        const double va1 = b->v_alpha_V, vb1 = b->v_beta_V;
        unsigned skip = 0u; /* phases that begin to conduct from zero here */
        for (int x = 0; x < 3; ++x) {
            if (b->phase[x] != 0 && !((double)b->phase[x] * i0[x] > 0.0)) skip |= 1u << x;
        }
        const double g0 = combine(b, i0, skip, &w0);
        double wa, wb;
        rk4(b, m, y, k1, va1, vb1, h, y1, &wa, &wb);
        const double g1 = margin_at(b, m, y1, dy, skip, &w1, i1);
        int started_wrong = -1; /* a phase that began to conduct and whose current went the wrong way */
        for (int x = 0; x < 3; ++x) {
            if (((skip >> x) & 1u) && (double)b->phase[x] * i1[x] < 0.0) started_wrong = x;
        }
        if (events >= PLANT_BRIDGE_MAX_EVENTS || (g1 > 0.0 && started_wrong < 0)) {
            if (events >= PLANT_BRIDGE_MAX_EVENTS && !(g1 > 0.0)) ++b->unlocated;
            for (int i = 0; i < m->n_y && i < PLANT_BRIDGE_MAX_Y; ++i) y[i] = y1[i];
            t += h;
            wsum_a += wa;
            wsum_b += wb;
            project(b, m, y);
            continue;
        }
        last = false;
        ++events;
        if (started_wrong >= 0 || !(g0 > 0.0)) { /* the conduction cannot begin (or the margin is gone): at once */
            change(b, m, y, started_wrong >= 0 ? started_wrong : w0);
            continue;
        }
        /* regula falsi (Illinois) on the step's length: g(lo) > 0 >= g(hi) */
        double lo = 0.0, glo = g0, hi = h, ghi = g1;
        int side = 0, which = w1;
        for (int it = 0; it < 200 && hi - lo > 4.0 * DBL_EPSILON * hi; ++it) {
            double c = (lo * ghi - hi * glo) / (ghi - glo);
            if (!(c > lo && c < hi)) c = 0.5 * (lo + hi);
            int wc = 3;
            double ca, cb;
            rk4(b, m, y, k1, va1, vb1, c, y1, &ca, &cb);
            const double gc = margin_at(b, m, y1, dy, skip, &wc, i1);
            if (gc > 0.0) {
                lo = c;
                glo = gc;
                if (side == 1) ghi *= 0.5;
                side = 1;
            } else {
                hi = c;
                ghi = gc;
                which = wc;
                if (side == -1) glo *= 0.5;
                side = -1;
            }
        }
        rk4(b, m, y, k1, va1, vb1, hi, y1, &wa, &wb); /* the state just past the change */
        for (int i = 0; i < m->n_y && i < PLANT_BRIDGE_MAX_Y; ++i) y[i] = y1[i];
        t += hi;
        wsum_a += wa;
        wsum_b += wb;
        change(b, m, y, which);
    }
    b->v_mean_alpha_V = wsum_a / Ts_s;
    b->v_mean_beta_V = wsum_b / Ts_s;
}
