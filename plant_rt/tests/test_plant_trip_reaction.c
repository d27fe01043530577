/*
 * What the bridge does once tripped (plant_config_t.trip_reaction, plant.eds Inverter.trip_reaction), each
 * reaction against a calculation written here, independent of the plant's integration (closed forms in long
 * double; the plant integrates by its matrix exponential or RK4 with the diodes' changes located):
 *
 *  1. active_short_circuit (0 V): at an imposed speed, the linear PMSM's transient i(t) = i_ss + expm(A t)
 *     (i0 - i_ss) with A's 2 x 2 exponential in closed form, and its steady state id = -psi w^2 Lq / (R^2 +
 *     w^2 Ld Lq), iq = -psi w R / (R^2 + w^2 Ld Lq); locked: id0 e^(-R t/Ld), iq0 e^(-R t/Lq).  Linear model
 *     (exact path) and a flux map tabulating it (RK4 path).
 *  2. pulses_off (all switches off, the currents through the diodes against Vdc): a piecewise solution
 *     written from the circuit, each segment in closed form and its end (a current reaching zero, an off phase's
 *     voltage reaching a rail, the back-EMF's spread reaching Vdc) found by bisection on the closed form:
 *       - locked rotor, Ld != Lq: three phases conduct (v fixed by the signs: each axis an RL step response),
 *         then the phase whose current reaches zero is off and the other two carry one current along their
 *         line (L_eff = d' L d, a scalar RL decay against the line's diode voltage), which reaches zero in a
 *         finite time: all off, for good;
 *       - turning rotor (Ld = Lq, so that the stator-frame model stays time-invariant: L di/dt = -R i + v - e(t),
 *         e a rotating phasor: each segment a constant and a sinusoidal particular solution and one
 *         exponential), with the line back-EMF sqrt(3) psi w below Vdc: the currents reach zero and stay there;
 *         above it: the uncontrolled rectification, its pulses compared sample by sample.
 *     Linear model and the flux map tabulating it.
 *     And You 2019's own motor (Ld != Lq) turning and rectifying, against a brute force that knows no rule of
 *     when a diode turns on or off: implicit Euler in the rotor frame at 10 ns with, at every step, the one of
 *     the 27 states of the three legs whose solution is consistent (a conducting leg's current of its sign, an
 *     off leg's voltage within the rails, all off: the back-EMF's spread within Vdc).  First order: 6e-5 A at
 *     10 ns, 6e-6 A at 1 ns.
 *  3. the diodes let no more current through than the short circuit from the same trip state (what the bench's
 *     motor-folder check assumes: bench/motor/trip.py), the energy account closes with the diodes (free rotor), the
 * trip clears back to the command, the default is active_short_circuit, and a run that never trips is the same bit for
 * bit under either reaction; pulses_off is refused without Vdc or on the external (FMU) model, and an unknown value.
 */
#include <complex.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "plant_test_util.h"
#include "presets.h"

typedef long double ld;
typedef long double complex ldc;

static const ld NXL[3] = {1.0L, -0.5L, -0.5L};
static const ld NYL[3] = {0.0L, 0.86602540378443864676372317075293618L, -0.86602540378443864676372317075293618L};

/* ------------------------------------------------------------------ the flux map tabulating the linear model */
#define NG 9
static double g_grid[NG], g_pd[NG * NG], g_pq[NG * NG];
static plant_flux_map_t g_map = {NG, NG, g_grid, g_grid, g_pd, g_pq};

static void tabulate(const plant_config_t *c, double imax)
{
    for (int i = 0; i < NG; ++i) g_grid[i] = -imax + 2.0 * imax * i / (NG - 1);
    for (int i = 0; i < NG; ++i)
        for (int j = 0; j < NG; ++j) {
            g_pd[i * NG + j] = c->Ld_H * g_grid[i] + c->psi_Wb;
            g_pq[i * NG + j] = c->Lq_H * g_grid[j];
        }
}

/* ------------------------------------------------------------------ the reference of pulses_off */
typedef struct {
    ld R, Ld, Lq, psi, w, th0, V; /* locked (w = 0) with any Ld, Lq; turning with Ld == Lq */
    ld t0, ia0, ib0;              /* the segment's start and currents (alpha-beta) */
    int ph[3];                    /* +1 / -1 conducting with i > 0 / < 0, 0 off */
    int events;
} ref_t;

static int ref_off(const ref_t *r, int *z)
{
    int n = 0;
    for (int x = 0; x < 3; ++x)
        if (r->ph[x] == 0) {
            ++n;
            *z = x;
        }
    return n;
}

/* the conducting terminals' voltage, (2/3) sum u_x n_x with u_x = -sign(i_x) V/2 */
static void ref_v0(const ref_t *r, ld *va, ld *vb)
{
    *va = *vb = 0.0L;
    for (int x = 0; x < 3; ++x) {
        *va += (2.0L / 3.0L) * (-(ld)r->ph[x] * r->V / 2.0L) * NXL[x];
        *vb += (2.0L / 3.0L) * (-(ld)r->ph[x] * r->V / 2.0L) * NYL[x];
    }
}

/* the particular solution of L di/dt = -R i - e(t), e = j w psi e^(j theta): P = -j w psi e^(j theta) / (R + j w L) */
static ldc ref_P(const ref_t *r, ld t)
{
    return -I * r->w * r->psi * cexpl(I * (r->th0 + r->w * t)) / (r->R + I * r->w * r->Ld);
}

static ldc ref_emf(const ref_t *r, ld t) { return I * r->w * r->psi * cexpl(I * (r->th0 + r->w * t)); }

/* one phase z off: the pair's current s along d (perpendicular to n_z) at t, and z's terminal voltage u_z */
static void ref_pair(const ref_t *r, int z, ld t, ld *sc, ld *uz)
{
    ld va, vb;
    ref_v0(r, &va, &vb);
    const ld tau = t - r->t0, c = cosl(r->th0), s = sinl(r->th0);
    const ld da = -NYL[z], db = NXL[z];
    const ld dv0 = da * va + db * vb, s0 = da * r->ia0 + db * r->ib0, nv0 = NXL[z] * va + NYL[z] * vb;
    if (r->w == 0.0L) {
        /* L d s' = -R s d + v0 + (2/3) u_z n_z: along d, L_eff s' = -R s + d.v0 (L_eff = d' L d); along n_z, u_z */
        const ld dd = c * da + s * db, dq = -s * da + c * db; /* d in the rotor frame */
        const ld Leff = r->Ld * dd * dd + r->Lq * dq * dq;
        *sc = dv0 / r->R + (s0 - dv0 / r->R) * expl(-r->R * tau / Leff);
        const ld sdot = (-r->R * *sc + dv0) / Leff;
        const ld nd = c * NXL[z] + s * NYL[z], nq = -s * NXL[z] + c * NYL[z]; /* n_z' L d */
        *uz = 1.5L * ((nd * r->Ld * dd + nq * r->Lq * dq) * sdot - nv0);
    } else {
        /* L s' = -R s + d.(v0 - e(t)); u_z = 1.5 (e_z - n_z.v0) */
        const ldc dc = da + I * db;
        const ld p0 = creall(conjl(dc) * ref_P(r, r->t0)), pt = creall(conjl(dc) * ref_P(r, t));
        *sc = dv0 / r->R + pt + (s0 - dv0 / r->R - p0) * expl(-r->R * tau / r->Ld);
        const ldc e = ref_emf(r, t);
        *uz = 1.5L * (NXL[z] * creall(e) + NYL[z] * cimagl(e) - nv0);
    }
}

/* all off: the back-EMF's spread between phases, and the phases of its extremes */
static ld ref_spread(const ref_t *r, ld t, int *xmax, int *xmin)
{
    const ldc e = ref_emf(r, t);
    ld emax = -INFINITY, emin = INFINITY;
    for (int x = 0; x < 3; ++x) {
        const ld ex = NXL[x] * creall(e) + NYL[x] * cimagl(e);
        if (ex > emax) {
            emax = ex;
            *xmax = x;
        }
        if (ex < emin) {
            emin = ex;
            *xmin = x;
        }
    }
    return emax - emin;
}

/* the segment's currents at t, and its margin (> 0 while the bridge's state holds; *which the phase whose current
 * is smallest, 3 the voltage) */
static void ref_eval(const ref_t *r, ld t, ld *ia, ld *ib, ld *g, int *which)
{
    ld va, vb;
    ref_v0(r, &va, &vb);
    const ld tau = t - r->t0, c = cosl(r->th0), s = sinl(r->th0);
    int z = 0;
    const int off = ref_off(r, &z);
    ld margin = INFINITY;
    if (off == 0) {
        if (r->w == 0.0L) { /* dq axes decoupled: an RL step response each */
            const ld vd = c * va + s * vb, vq = -s * va + c * vb;
            const ld id0 = c * r->ia0 + s * r->ib0, iq0 = -s * r->ia0 + c * r->ib0;
            const ld id = vd / r->R + (id0 - vd / r->R) * expl(-r->R * tau / r->Ld);
            const ld iq = vq / r->R + (iq0 - vq / r->R) * expl(-r->R * tau / r->Lq);
            *ia = c * id - s * iq;
            *ib = s * id + c * iq;
        } else {
            const ldc v0 = va + I * vb, i0 = r->ia0 + I * r->ib0;
            const ldc i = v0 / r->R + ref_P(r, t) + (i0 - v0 / r->R - ref_P(r, r->t0)) * expl(-r->R * tau / r->Ld);
            *ia = creall(i);
            *ib = cimagl(i);
        }
    } else if (off == 1) {
        ld sc, uz;
        ref_pair(r, z, t, &sc, &uz);
        *ia = -sc * NYL[z];
        *ib = sc * NXL[z];
        margin = r->V / 2.0L - fabsl(uz);
    } else {
        *ia = *ib = 0.0L;
        int xa, xb;
        margin = r->V - ref_spread(r, t, &xa, &xb);
    }
    *g = margin / r->V;
    *which = 3;
    for (int x = 0; x < 3; ++x) {
        if (r->ph[x] != 0) {
            const ld v = (ld)r->ph[x] * (NXL[x] * *ia + NYL[x] * *ib);
            if (v < *g) {
                *g = v;
                *which = x;
            }
        }
    }
}

/* a change of the bridge's state at t: a phase's current reached zero (which < 3: it stops; if it was one of a
 * pair, both stop) or the voltage margin (an off phase beyond a rail conducts on that side; all off, the highest
 * and lowest back-EMF conduct); then, while the new state's margin is negative, the same rules */
static void ref_change(ref_t *r, ld t, int which)
{
    ld ia, ib, g;
    int w, z = 0;
    ref_eval(r, t, &ia, &ib, &g, &w);
    if (which < 3) {
        if (ref_off(r, &z) == 0) {
            const ld ix = NXL[which] * ia + NYL[which] * ib;
            r->ph[which] = 0;
            ia -= ix * NXL[which];
            ib -= ix * NYL[which];
        } else {
            r->ph[0] = r->ph[1] = r->ph[2] = 0;
            ia = ib = 0.0L;
        }
    }
    r->t0 = t;
    r->ia0 = ia;
    r->ib0 = ib;
    for (int it = 0; it < 4; ++it) {
        ref_eval(r, t, &ia, &ib, &g, &w);
        if (!(g < 0.0L) && !(it == 0 && which == 3)) break;
        const int off = ref_off(r, &z);
        if (off == 1) {
            ld sc, uz;
            ref_pair(r, z, t, &sc, &uz);
            r->ph[z] = uz > 0.0L ? -1 : 1;
        } else if (off == 3) {
            int xmax = 0, xmin = 0;
            (void)ref_spread(r, t, &xmax, &xmin);
            r->ph[xmax] = -1;
            r->ph[xmin] = 1;
        } else {
            break;
        }
    }
    ++r->events;
}

/* the reference from its segment's start to t (changes found by a scan of 1/20 period and bisection) */
static void ref_advance(ref_t *r, ld t, ld scan, ld *ia, ld *ib)
{
    ld tc = r->t0, g, a, b;
    int w;
    while (tc < t) {
        const ld tn = fminl(tc + scan, t);
        ref_eval(r, tn, &a, &b, &g, &w);
        if (g > 0.0L) {
            tc = tn;
            continue;
        }
        ld lo = tc, hi = tn;
        for (int it = 0; it < 200 && hi - lo > 1e-19L; ++it) {
            const ld mid = 0.5L * (lo + hi);
            ref_eval(r, mid, &a, &b, &g, &w);
            if (g > 0.0L)
                lo = mid;
            else
                hi = mid;
        }
        ref_eval(r, hi, &a, &b, &g, &w);
        ref_change(r, hi, w);
        tc = hi;
    }
    ref_eval(r, t, ia, ib, &g, &w);
}

/* ------------------------------------------------------------------ the plant against it */
static plant_config_t base_config(double Vdc)
{
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "preset");
    plant_config_ideal(&c);
    c.Vdc_V = Vdc;
    return c;
}

/* The plant from (id0, iq0) at theta_e (tripped at t = 0), n periods, against the reference: the largest
 * error of the phase currents, the first period with all currents zero (-1: none), the largest current after it. */
typedef struct {
    double err_A, after_zero_A, peak_A;
    int zero_k;
    int events;
} cmp_t;

static cmp_t run_pulses_off(plant_config_t c, bool flux, double th_e, double id0, double iq0, int n)
{
    cmp_t out = {0.0, 0.0, 0.0, -1, 0};
    c.trip_reaction = PLANT_TRIP_PULSES_OFF;
    if (flux) {
        tabulate(&c, 16.0);
        c.model = PLANT_MODEL_FLUX_MAP;
        c.flux_map = &g_map;
    }
    plant_state_t s;
    plant_init(&s, &c);
    CHECK(s.status == PLANT_OK, "prepare %d", s.status);
    plant_set_mech(&s, &c, th_e / (double)c.pole_pairs, 0.0);
    plant_set_currents(&s, id0, iq0);
    s.tripped = true;
    ref_t r = {(ld)c.R_ohm, (ld)c.Ld_H, (ld)c.Lq_H, (ld)c.psi_Wb, 0.0L, 0.0L, (ld)c.Vdc_V, 0.0L, 0.0L, 0.0L, {0}, 0};
    r.w = c.mech_mode == PLANT_MECH_IMPOSED_SPEED ? (ld)c.pole_pairs * (ld)c.omega_imposed_rad_s : 0.0L;
    r.th0 = (ld)c.pole_pairs * (ld)s.theta_m_rad;
    const ld cs = cosl(r.th0), sn = sinl(r.th0);
    r.ia0 = cs * id0 - sn * iq0;
    r.ib0 = sn * id0 + cs * iq0;
    for (int x = 0; x < 3; ++x) {
        const ld ix = NXL[x] * r.ia0 + NYL[x] * r.ib0;
        r.ph[x] = ix > 0 ? 1 : (ix < 0 ? -1 : 0);
    }
    for (int k = 1; k <= n; ++k) {
        plant_step(&s, &c, 50.0, -20.0); /* a command: the bridge is off, it does not act */
        plant_meas_t m;
        plant_sample(&s, &c, &m);
        ld ia, ib;
        ref_advance(&r, (ld)k * (ld)c.Ts_s, (ld)c.Ts_s / 20.0L, &ia, &ib);
        const double ra = (double)ia, rb = (double)(-0.5L * ia + NYL[1] * ib);
        out.err_A = fmax(out.err_A, fmax(fabs(m.i_a_true_A - ra), fabs(m.i_b_true_A - rb)));
        const double mag = fmax(fabs(m.i_a_true_A), fmax(fabs(m.i_b_true_A), fabs(m.i_c_true_A)));
        out.peak_A = fmax(out.peak_A, mag);
        if (out.zero_k < 0 && ia == 0.0L && ib == 0.0L) out.zero_k = k;
        if (out.zero_k >= 0) out.after_zero_A = fmax(out.after_zero_A, mag);
    }
    out.events = r.events;
    CHECK(s.bridge.unlocated == 0u, "periods with unlocated changes: %u", s.bridge.unlocated);
    CHECK(s.bridge.events == (uint32_t)r.events, "the plant changed its bridge's state %u times, the reference %d",
          s.bridge.events, r.events);
    return out;
}

/* 2 x 2 exponential in closed form: expm(A t) for A = [[a, b], [c, d]] with complex eigenvalues or real ones */
static void expm2(ld a, ld b, ld c, ld d, ld t, ld E[2][2])
{
    const ld m = 0.5L * (a + d), q = 0.25L * (a - d) * (a - d) + b * c;
    ld f0, f1; /* expm = e^(m t) (f0 I + f1 (A - m I)) */
    if (q < 0.0L) {
        const ld mu = sqrtl(-q);
        f0 = cosl(mu * t);
        f1 = sinl(mu * t) / mu;
    } else if (q > 0.0L) {
        const ld mu = sqrtl(q);
        f0 = coshl(mu * t);
        f1 = sinhl(mu * t) / mu;
    } else {
        f0 = 1.0L;
        f1 = t;
    }
    const ld em = expl(m * t);
    E[0][0] = em * (f0 + f1 * (a - m));
    E[0][1] = em * f1 * b;
    E[1][0] = em * f1 * c;
    E[1][1] = em * (f0 + f1 * (d - m));
}

/* active short circuit from (id0, iq0) at an imposed speed (w_m = 0: locked): the rotor-frame currents against
 * i_ss + expm(A t)(i0 - i_ss); returns the largest error, and the end's error from the steady-state formula */
static double run_asc(plant_config_t c, bool flux, double w_m, double id0, double iq0, int n, double *ss_err,
                      double *peak)
{
    c.trip_reaction = PLANT_TRIP_ACTIVE_SHORT_CIRCUIT;
    c.mech_mode = w_m != 0.0 ? PLANT_MECH_IMPOSED_SPEED : PLANT_MECH_LOCKED;
    c.omega_imposed_rad_s = w_m;
    if (flux) {
        tabulate(&c, 40.0);
        c.model = PLANT_MODEL_FLUX_MAP;
        c.flux_map = &g_map;
    }
    plant_state_t s;
    plant_init(&s, &c);
    CHECK(s.status == PLANT_OK, "prepare %d", s.status);
    plant_set_mech(&s, &c, 0.7 / (double)c.pole_pairs, 0.0);
    plant_set_currents(&s, id0, iq0);
    s.tripped = true;
    const ld R = c.R_ohm, Ld = c.Ld_H, Lq = c.Lq_H, psi = c.psi_Wb, w = (ld)c.pole_pairs * (ld)w_m;
    const ld den = R * R + w * w * Ld * Lq;
    const ld idss = -psi * w * w * Lq / den, iqss = -psi * w * R / den;
    double err = 0.0;
    *peak = 0.0;
    for (int k = 1; k <= n; ++k) {
        plant_step(&s, &c, 30.0, 10.0);
        CHECK(s.v_app_alpha_V == 0.0 && s.v_app_beta_V == 0.0, "the short circuit applies 0 V");
        ld E[2][2];
        expm2(-R / Ld, w * Lq / Ld, -w * Ld / Lq, -R / Lq, (ld)k * (ld)c.Ts_s, E);
        const ld id = idss + E[0][0] * (id0 - idss) + E[0][1] * (iq0 - iqss);
        const ld iq = iqss + E[1][0] * (id0 - idss) + E[1][1] * (iq0 - iqss);
        err = fmax(err, (double)fmaxl(fabsl(s.id_A - id), fabsl(s.iq_A - iq)));
        *peak = fmax(*peak, hypot(s.id_A, s.iq_A));
    }
    *ss_err = (double)fmaxl(fabsl(s.id_A - idss), fabsl(s.iq_A - iqss));
    return err;
}

static void test_active_short_circuit(void)
{
    const plant_config_t c = base_config(300.0);
    const char *model[2] = {"linear (exact path)", "flux map (RK4)"};
    for (int f = 0; f < 2; ++f) {
        double ss, peak;
        /* 100 rad/s mechanical: w_e 500 rad/s; 2000 periods = 34 L/R: the end is the steady state */
        const double e = run_asc(c, f == 1, 100.0, -2.0, 10.0, 2000, &ss, &peak);
        const double w = 5.0 * 100.0, den = 1.4 * 1.4 + w * w * c.Ld_H * c.Lq_H;
        printf("active short circuit at 500 rad/s el., %-20s from (-2, 10) A: transient error %.3g A, steady state "
               "(%.6f, %.6f) A err %.3g A, peak |i_dq| %.4g A\n",
               model[f], e, -c.psi_Wb * w * w * c.Lq_H / den, -c.psi_Wb * w * 1.4 / den, ss, peak);
        CHECK(e < (f == 0 ? 1e-12 : 1e-8), "%s: the short circuit's transient is off by %.3g A", model[f], e);
        CHECK(ss < 1e-12, "%s: the steady short-circuit current is off by %.3g A", model[f], ss);
        const double el = run_asc(c, f == 1, 0.0, 3.0, -7.0, 400, &ss, &peak);
        printf("active short circuit, locked, %-29s: decay error %.3g A\n", model[f], el);
        CHECK(el < (f == 0 ? 1e-12 : 1e-8), "%s: locked decay off by %.3g A", model[f], el);
    }
}

static void report(const char *what, cmp_t r, double Ts)
{
    printf("%-60s error %.3g A, %d changes of the bridge's state, peak %.4g A, ", what, r.err_A, r.events, r.peak_A);
    if (r.zero_k > 0) {
        printf("all zero from period %d (%.4g ms) on (then |i| <= %.3g A)\n", r.zero_k, r.zero_k * Ts * 1e3,
               r.after_zero_A);
    } else {
        printf("never all zero\n");
    }
}

/* ------------------------------------------------------------------ the brute force (implicit Euler + enumeration) */
/* One implicit-Euler step of dt at the angle th (its end) of the rotor-frame model with the diode bridge: the first
 * of the 27 states of the legs (each conducting with i > 0, with i < 0, or off) whose solution is consistent.
 * Returns 0, or -1 when none is. */
static int lcp_step(const plant_config_t *c, double w, double th, double dt, double *id, double *iq)
{
    const double R = c->R_ohm, Ld = c->Ld_H, Lq = c->Lq_H, V = c->Vdc_V, cs = cos(th), sn = sin(th);
    const double a00 = Ld / dt + R, a01 = -w * Lq, a10 = w * Ld, a11 = Lq / dt + R; /* M i' = r + v */
    const double r0 = Ld * *id / dt, r1 = Lq * *iq / dt - w * c->psi_Wb;
    for (int m = 0; m < 27; ++m) {
        const int sg[3] = {m % 3 - 1, (m / 3) % 3 - 1, m / 9 - 1};
        int nc = 0, z = 0;
        for (int x = 0; x < 3; ++x) {
            if (sg[x])
                ++nc;
            else
                z = x;
        }
        if (nc == 1) continue;
        double va = 0.0, vb = 0.0;
        for (int x = 0; x < 3; ++x) {
            va += (2.0 / 3.0) * (-sg[x] * V / 2.0) * (double)NXL[x];
            vb += (2.0 / 3.0) * (-sg[x] * V / 2.0) * (double)NYL[x];
        }
        const double vd = cs * va + sn * vb, vq = -sn * va + cs * vb;
        double nid, niq;
        if (nc == 3) {
            const double b0 = r0 + vd, b1 = r1 + vq, det = a00 * a11 - a01 * a10;
            nid = (b0 * a11 - a01 * b1) / det;
            niq = (a00 * b1 - a10 * b0) / det;
        } else if (nc == 2) { /* unknowns id', iq', u_z: M i' - (2/3) u_z n_z(dq) = r + v0, n_z . i' = 0 */
            const double nd = cs * (double)NXL[z] + sn * (double)NYL[z],
                         nq = -sn * (double)NXL[z] + cs * (double)NYL[z];
            double A[3][4] = {
                {a00, a01, -2.0 / 3.0 * nd, r0 + vd}, {a10, a11, -2.0 / 3.0 * nq, r1 + vq}, {nd, nq, 0, 0}};
            for (int p = 0; p < 3; ++p) {
                int piv = p;
                for (int q = p + 1; q < 3; ++q)
                    if (fabs(A[q][p]) > fabs(A[piv][p])) piv = q;
                for (int k = 0; k < 4; ++k) {
                    const double tmp = A[p][k];
                    A[p][k] = A[piv][k];
                    A[piv][k] = tmp;
                }
                for (int q = 0; q < 3; ++q)
                    if (q != p) {
                        const double f = A[q][p] / A[p][p];
                        for (int k = 0; k < 4; ++k) A[q][k] -= f * A[p][k];
                    }
            }
            nid = A[0][3] / A[0][0];
            niq = A[1][3] / A[1][1];
            if (fabs(A[2][3] / A[2][2]) > V / 2.0) continue; /* the off leg's voltage beyond a rail */
        } else { /* all off: the voltage that holds i' = 0 must fit between the rails */
            const double vdn = -Ld * *id / dt, vqn = -Lq * *iq / dt + w * c->psi_Wb;
            const double a = cs * vdn - sn * vqn, b = sn * vdn + cs * vqn;
            double mx = -INFINITY, mn = INFINITY;
            for (int x = 0; x < 3; ++x) {
                const double e = (double)NXL[x] * a + (double)NYL[x] * b;
                mx = fmax(mx, e);
                mn = fmin(mn, e);
            }
            if (mx - mn > V) continue;
            nid = niq = 0.0;
        }
        const double ia = cs * nid - sn * niq, ib = sn * nid + cs * niq;
        int ok = 1;
        for (int x = 0; x < 3; ++x)
            if (sg[x] && sg[x] * ((double)NXL[x] * ia + (double)NYL[x] * ib) < 0.0) ok = 0;
        if (ok) {
            *id = nid;
            *iq = niq;
            return 0;
        }
    }
    return -1;
}

/* You 2019's motor (Ld != Lq) at 1000 rad/s el. into 48 V, rectifying: the plant against the brute force */
static void test_rectifier_brute_force(void)
{
    plant_config_t c = base_config(48.0);
    c.mech_mode = PLANT_MECH_IMPOSED_SPEED;
    c.omega_imposed_rad_s = 200.0;
    c.trip_reaction = PLANT_TRIP_PULSES_OFF;
    plant_state_t s;
    plant_init(&s, &c);
    plant_set_mech(&s, &c, 1.1 / 5.0, 0.0);
    plant_set_currents(&s, -4.0, 9.0);
    s.tripped = true;
    const double dt = 1e-8, w = 1000.0;
    const long per = lround(c.Ts_s / dt);
    double id = -4.0, iq = 9.0, err = 0.0, peak = 0.0;
    long steps = 0;
    int none = 0;
    for (int k = 1; k <= 200; ++k) {
        for (long q = 0; q < per; ++q) {
            ++steps;
            none |= lcp_step(&c, w, 1.1 + w * (double)steps * dt, dt, &id, &iq);
        }
        plant_step(&s, &c, 0.0, 0.0);
        err = fmax(err, hypot(s.id_A - id, s.iq_A - iq));
        peak = fmax(peak, hypot(id, iq));
    }
    printf("pulses off, You 2019's motor (Ld != Lq) at 1000 rad/s el. into 48 V against the brute force at 10 ns: "
           "largest |i_dq| difference %.3g A (peak %.3g A, %u changes)\n",
           err, peak, s.bridge.events);
    CHECK(!none, "the brute force found no consistent state of the legs");
    CHECK(err < 1.5e-4, "the rectifier differs from the brute force by %.3g A", err);
}

static void test_pulses_off(void)
{
    const char *model[2] = {"linear", "flux map"};
    for (int f = 0; f < 2; ++f) {
        char what[120];
        /* locked, You 2019's Ld != Lq, 300 V */
        plant_config_t c = base_config(300.0);
        c.mech_mode = PLANT_MECH_LOCKED;
        cmp_t r = run_pulses_off(c, f == 1, 0.3, 3.0, 8.0, 120);
        snprintf(what, sizeof what, "pulses off, locked, Ld != Lq, 300 V, %s:", model[f]);
        report(what, r, c.Ts_s);
        CHECK(r.err_A < 1e-10, "%s: off by %.3g A", what, r.err_A);
        CHECK(r.zero_k > 0 && r.after_zero_A == 0.0, "%s: the currents do not stay at zero", what);
        CHECK(r.events == 2, "%s: %d changes (three phases, two, none)", what, r.events);

        /* turning, Ld = Lq, 48 V: line back-EMF sqrt(3) psi w = 29 V below Vdc, then 73 V above */
        c = base_config(48.0);
        c.Lq_H = c.Ld_H;
        c.mech_mode = PLANT_MECH_IMPOSED_SPEED;
        c.omega_imposed_rad_s = 80.0; /* 400 rad/s el. */
        r = run_pulses_off(c, f == 1, 1.1, -4.0, 9.0, 200);
        snprintf(what, sizeof what, "pulses off, 400 rad/s el. (line EMF 29 V < 48 V), %s:", model[f]);
        report(what, r, c.Ts_s);
        CHECK(r.err_A < 1e-10, "%s: off by %.3g A", what, r.err_A);
        CHECK(r.zero_k > 0 && r.after_zero_A == 0.0, "%s: the currents do not stay at zero", what);

        c.omega_imposed_rad_s = 200.0; /* 1000 rad/s el. */
        r = run_pulses_off(c, f == 1, 1.1, -4.0, 9.0, 800);
        snprintf(what, sizeof what, "pulses off, 1000 rad/s el. (line EMF 73 V > 48 V), %s:", model[f]);
        report(what, r, c.Ts_s);
        CHECK(r.err_A < 3e-10, "%s: off by %.3g A", what, r.err_A);
        CHECK(r.zero_k < 0 && r.events > 20 && r.peak_A > 1.0, "%s: no rectified current", what);
    }
}

/* What the bench's motor-folder check assumes (bench/motor/trip.py): the diodes let through no more than the short
 * circuit would, from the same trip state at the same speed (their voltage opposes every current they carry).  The
 * largest |id| and |iq| over 600 periods, trip states on the circle of 13.86 A, speeds below and far above the line
 * back-EMF's Vdc. */
static double axis_peak(plant_config_t c, plant_trip_reaction_t r, double w_m, double id0, double iq0)
{
    c.mech_mode = PLANT_MECH_IMPOSED_SPEED;
    c.omega_imposed_rad_s = w_m;
    c.trip_reaction = r;
    plant_state_t s;
    plant_init(&s, &c);
    plant_set_currents(&s, id0, iq0);
    s.tripped = true;
    double pk = 0.0;
    for (int k = 0; k < 600; ++k) {
        plant_step(&s, &c, 0.0, 0.0);
        pk = fmax(pk, fmax(fabs(s.id_A), fabs(s.iq_A)));
    }
    return pk;
}

static void test_rectifier_below_short_circuit(void)
{
    double worst = 0.0;
    for (int v = 0; v < 2; ++v) {
        const plant_config_t c = base_config(v ? 300.0 : 48.0);
        for (int sp = 0; sp < 3; ++sp) {
            const double w_m = 100.0 * pow(4.0, sp); /* 500, 2000, 8000 rad/s el. */
            for (int a = 0; a < 6; ++a) {
                const double th = 2.0 * (double)T_PI * a / 6.0 + 0.3;
                const double po = axis_peak(c, PLANT_TRIP_PULSES_OFF, w_m, 13.86 * cos(th), 13.86 * sin(th));
                const double asc = axis_peak(c, PLANT_TRIP_ACTIVE_SHORT_CIRCUIT, w_m, 13.86 * cos(th), 13.86 * sin(th));
                worst = fmax(worst, po / asc);
                CHECK(po <= asc,
                      "Vdc %g, %g rad/s el., trip state at %.2f rad: the diodes %.4g A > the short circuit %.4g A",
                      c.Vdc_V, 5.0 * w_m, th, po, asc);
            }
        }
    }
    printf("pulses off against the short circuit from the same trip state (48 V and 300 V, 500 .. 8000 rad/s el.): the "
           "largest axis current at most %.3f of the short circuit's\n",
           worst);
}

/* the diodes with a free rotor: in = copper + magnetic + mechanical still closes */
static void test_energy_free(void)
{
    plant_config_t c = base_config(48.0);
    c.mech_mode = PLANT_MECH_FREE;
    c.J_kgm2 = 2e-5;
    c.trip_reaction = PLANT_TRIP_PULSES_OFF;
    plant_state_t s;
    plant_init(&s, &c);
    plant_set_mech(&s, &c, 0.2, 250.0); /* 1250 rad/s el.: it rectifies and brakes */
    plant_set_currents(&s, 2.0, 5.0);
    plant_energy_reset(&s, &c);
    s.tripped = true;
    const double w0 = s.omega_m_rad_s;
    for (int k = 0; k < 2000; ++k) plant_step(&s, &c, 0.0, 0.0);
    const double res = plant_energy_residual_J(&s, &c);
    const double kin = plant_kinetic_energy_J(&s, &c) - s.energy.W_kin0_J;
    printf("pulses off, free rotor from 250 rad/s: %.2f rad/s after 2000 periods, energy to the DC link %.4g J, "
           "kinetic change %.4g J, residual %.3g J, %u changes\n",
           s.omega_m_rad_s, -s.energy.in_J, kin, res, s.bridge.events);
    CHECK(fabs(res) < 1e-9 * fabs(s.energy.in_J) + 1e-12, "the energy account does not close: %.3g J", res);
    CHECK(fabs(kin - s.energy.mech_J) < 1e-6 * fabs(kin), "the shaft power is not the kinetic energy's change");
    CHECK(s.omega_m_rad_s < w0 && s.energy.in_J < 0.0, "the rectifier does not brake");
}

static void test_settings(void)
{
    plant_config_t d;
    plant_config_defaults(&d);
    CHECK(d.trip_reaction == PLANT_TRIP_ACTIVE_SHORT_CIRCUIT, "the default is not active_short_circuit");
    CHECK(OD_PLANT_INVERTER_TRIP_REACTION_DEFAULT == PLANT_TRIP_ACTIVE_SHORT_CIRCUIT, "the EDS default");
    plant_state_t s;
    plant_config_t c = base_config(300.0);
    c.trip_reaction = PLANT_TRIP_PULSES_OFF;
    CHECK(plant_prepare(&s, &c) == PLANT_OK, "pulses_off refused");
    c.Vdc_V = 0.0;
    CHECK(plant_prepare(&s, &c) == PLANT_ERR_REACTION, "pulses_off without Vdc accepted");
    c = base_config(300.0);
    c.trip_reaction = (plant_trip_reaction_t)2;
    CHECK(plant_prepare(&s, &c) == PLANT_ERR_REACTION, "an unknown reaction accepted");
    plant_external_t ext = {NULL, NULL, NULL};
    c = base_config(300.0);
    c.model = PLANT_MODEL_EXTERNAL;
    c.external = &ext;
    c.trip_reaction = PLANT_TRIP_PULSES_OFF;
    CHECK(plant_prepare(&s, &c) != PLANT_OK, "pulses_off on an external model accepted");

    /* a run that never trips is the same bit for bit under either reaction; one that trips is not */
    for (int tr = 0; tr < 2; ++tr) {
        plant_config_t a = base_config(300.0), b = a;
        a.mech_mode = b.mech_mode = PLANT_MECH_IMPOSED_SPEED;
        a.omega_imposed_rad_s = b.omega_imposed_rad_s = 120.0;
        a.I_trip_A = b.I_trip_A = tr ? 5.0 : 0.0;
        b.trip_reaction = PLANT_TRIP_PULSES_OFF;
        plant_state_t sa, sb;
        plant_init(&sa, &a);
        plant_init(&sb, &b);
        int same = 1;
        for (int k = 0; k < 300; ++k) {
            plant_step(&sa, &a, 40.0 * cos(0.01 * k), 40.0 * sin(0.01 * k));
            plant_step(&sb, &b, 40.0 * cos(0.01 * k), 40.0 * sin(0.01 * k));
            same &= sa.id_A == sb.id_A && sa.iq_A == sb.iq_A;
        }
        printf("%s: tripped %d, the two reactions' runs %s\n", tr ? "a run that trips" : "a run that never trips",
               (int)sa.tripped, same ? "identical" : "differ");
        CHECK(tr ? (sa.tripped && !same) : (!sa.tripped && same), "the reaction acts %s a trip",
              tr ? "without" : "only with");
        /* cleared: the command is applied again */
        if (tr) {
            while (hypot(sb.id_A, sb.iq_A) > 1.0) plant_step(&sb, &b, 0.0, 0.0);
            plant_clear_trip(&sb);
            plant_step(&sb, &b, 20.0, 0.0);
            CHECK(!sb.tripped && sb.v_app_alpha_V == 20.0 && !sb.bridge.active, "cleared: the command is not applied");
        }
    }
}

int main(void)
{
    test_active_short_circuit();
    test_pulses_off();
    test_rectifier_brute_force();
    test_rectifier_below_short_circuit();
    test_energy_free();
    test_settings();
    return check_finish("test_plant_trip_reaction");
}
