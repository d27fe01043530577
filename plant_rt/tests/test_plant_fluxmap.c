/*
 * The flux-map model (plant_fluxmap.h, models/flux_map/flux_map.c).  Checks:
 *  1. the inversion: random points of a saturating, cross-coupled map are
 *     found again from their fluxes (<= 1e-10 A), inside and outside the grid;
 *  2. a map that tabulates the linear model (psi_d = Ld id + psi, psi_q =
 *     Lq iq) reproduces the built-in linear plant (exact path: locked and at
 *     imposed speed, both hold frames; RK4 path: free mechanics) to <= 1e-6 A
 *     over a random command sequence, and its incremental inductances are Ld
 *     and Lq;
 *  3. bad maps are refused by plant_prepare (PLANT_ERR_FLUXMAP): a grid not
 *     increasing, a non-finite value, a flux that falls with its current, a
 *     NULL map; thermal parameters on the linear model (PLANT_ERR_THERMAL);
 *  4. energy: in = copper + magnetic + mechanical on a saturating map
 *     (residual < 1e-6 of the input).  The magnetic energy is integrated
 *     from the same derivatives, so this checks that the torque, power and
 *     flux terms are one consistent model (a wrong factor or sign in one
 *     fails it), not the integration's accuracy (checks 2 and the host
 *     test's independent integration do that);
 *  5. the winding's temperature: with a constant current held by its steady
 *     voltage, T settles where T - T_amb = R_th * 1.5 R(T) i^2.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "plant_test_util.h"
#include "presets.h"

#define ND 25
#define NQ 31
static double g_id[ND], g_iq[NQ], g_pd[ND * NQ], g_pq[ND * NQ];
static plant_flux_map_t g_map = {ND, NQ, g_id, g_iq, g_pd, g_pq};

static void grid(double imax)
{
    for (int i = 0; i < ND; ++i) g_id[i] = -imax + 2.0 * imax * i / (ND - 1);
    for (int j = 0; j < NQ; ++j) g_iq[j] = -imax + 2.0 * imax * j / (NQ - 1);
}

static void tabulate_linear(const plant_config_t *c)
{
    for (int i = 0; i < ND; ++i)
        for (int j = 0; j < NQ; ++j) {
            g_pd[i * NQ + j] = c->Ld_H * g_id[i] + c->psi_Wb;
            g_pq[i * NQ + j] = c->Lq_H * g_iq[j];
        }
}

/* a saturating, cross-coupled map (the example motor's form, docs/YOUR_MOTOR.md) */
static void tabulate_saturating(double Ld, double Lq, double psi, double Is)
{
    for (int i = 0; i < ND; ++i)
        for (int j = 0; j < NQ; ++j) {
            const double id = g_id[i], iq = g_iq[j];
            const double x = iq / Is, y = id / Is;
            g_pd[i * NQ + j] = psi + 0.6 * Ld * id + 0.4 * Ld * Is * atan(y) - 0.05 * Ld * Is * log1p(x * x) / 2.0;
            g_pq[i * NQ + j] = 0.3 * Lq * iq + 0.7 * Lq * Is * atan(x) - 0.05 * Lq * iq * y / sqrt(1.0 + y * y);
        }
}

static void check_inversion(void)
{
    grid(30.0);
    tabulate_saturating(2e-3, 4e-3, 0.05, 8.0);
    CHECK(plant_flux_map_check(&g_map) == 0, "the saturating map is refused: %d", plant_flux_map_check(&g_map));
    unsigned long long st = 5u;
    double emax = 0.0;
    int evals_max = 0;
    for (int n = 0; n < 2000; ++n) {
        const double id = 70.0 * (test_lcg_uniform(&st) - 0.5), iq = 70.0 * (test_lcg_uniform(&st) - 0.5);
        plant_flux_eval_t e;
        plant_flux_map_eval(&g_map, id, iq, &e);
        double gd = id + 3.0 * (test_lcg_uniform(&st) - 0.5), gq = iq + 3.0 * (test_lcg_uniform(&st) - 0.5);
        const int k = plant_flux_map_currents(&g_map, e.psi_d_Wb, e.psi_q_Wb, &gd, &gq);
        CHECK(k > 0, "no convergence at (%g, %g)", id, iq);
        if (k > evals_max) evals_max = k;
        emax = fmax(emax, hypot(gd - id, gq - iq));
    }
    CHECK(emax <= 1e-10, "inversion error %.3g A", emax);
    printf("  inversion: max error %.3g A, at most %d evaluations from a start 1.5 A away\n", emax, evals_max);
}

static double run_pair(plant_config_t *lin, int nper, double *Ldd, double *Lqq)
{
    plant_config_t fm = *lin;
    fm.model = PLANT_MODEL_FLUX_MAP;
    fm.flux_map = &g_map;
    plant_state_t a, b;
    plant_init(&a, lin);
    plant_init(&b, &fm);
    CHECK(a.status == 0 && b.status == 0, "prepare %d %d", a.status, b.status);
    plant_set_mech(&a, lin, 0.3, lin->mech_mode == PLANT_MECH_FREE ? 50.0 : 0.0);
    plant_set_mech(&b, &fm, 0.3, lin->mech_mode == PLANT_MECH_FREE ? 50.0 : 0.0);
    unsigned long long st = 99u;
    double va = 0.0, vb = 0.0, emax = 0.0;
    for (int k = 0; k < nper; ++k) {
        if (k % 20 == 0) {
            va = 60.0 * (test_lcg_uniform(&st) - 0.5);
            vb = 60.0 * (test_lcg_uniform(&st) - 0.5);
        }
        plant_step(&a, lin, va, vb);
        plant_step(&b, &fm, va, vb);
        emax = fmax(emax, hypot(a.id_A - b.id_A, a.iq_A - b.iq_A));
    }
    emax = fmax(emax, fabs(a.omega_m_rad_s - b.omega_m_rad_s) * 1e-3); /* speed in the same check, rad/s / 1000 */
    *Ldd = b.Ldd_H;
    *Lqq = b.Lqq_H;
    CHECK(b.newton_failures == 0u, "%u inversions failed", b.newton_failures);
    return emax;
}

static void check_linear_map(void)
{
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "preset");
    plant_config_ideal(&c);
    grid(40.0);
    tabulate_linear(&c);
    const struct {
        plant_mech_mode_t mech;
        plant_hold_frame_t hold;
        double w;
        const char *what;
    } cases[] = {
        {PLANT_MECH_LOCKED, PLANT_HOLD_STATOR, 0.0, "locked"},
        {PLANT_MECH_IMPOSED_SPEED, PLANT_HOLD_STATOR, 150.0, "imposed speed, stator hold"},
        {PLANT_MECH_IMPOSED_SPEED, PLANT_HOLD_ROTOR, 150.0, "imposed speed, rotor hold"},
        {PLANT_MECH_FREE, PLANT_HOLD_STATOR, 0.0, "free mechanics"},
    };
    for (size_t n = 0; n < sizeof cases / sizeof cases[0]; ++n) {
        c.mech_mode = cases[n].mech;
        c.hold_frame = cases[n].hold;
        c.omega_imposed_rad_s = cases[n].w;
        c.J_kgm2 = 2e-3;
        double Ldd, Lqq;
        const double e = run_pair(&c, 600, &Ldd, &Lqq);
        CHECK(e <= 1e-6, "%s: the tabulated linear map differs from the linear plant by %.3g A", cases[n].what, e);
        CHECK(fabs(Ldd - c.Ld_H) <= 1e-12 && fabs(Lqq - c.Lq_H) <= 1e-12, "%s: L_inc %g %g", cases[n].what, Ldd, Lqq);
        printf("  linear map vs linear plant, %s: max |di| %.3g A\n", cases[n].what, e);
    }
}

static void check_refusals(void)
{
    plant_config_t c;
    plant_config_defaults(&c);
    grid(10.0);
    tabulate_linear(&c);
    c.model = PLANT_MODEL_FLUX_MAP;
    c.flux_map = &g_map;
    plant_state_t s;
    CHECK(plant_prepare(&s, &c) == PLANT_OK, "the linear map");
    g_id[3] = g_id[2];
    CHECK(plant_prepare(&s, &c) == PLANT_ERR_FLUXMAP, "a grid not increasing");
    grid(10.0);
    g_pq[40] = NAN;
    CHECK(plant_prepare(&s, &c) == PLANT_ERR_FLUXMAP, "a NaN");
    tabulate_linear(&c);
    g_pd[5 * NQ + 7] = g_pd[4 * NQ + 7] - 1e-4; /* psi_d falls as id rises */
    CHECK(plant_prepare(&s, &c) == PLANT_ERR_FLUXMAP, "a map that cannot be inverted");
    tabulate_linear(&c);
    c.flux_map = NULL;
    CHECK(plant_prepare(&s, &c) == PLANT_ERR_FLUXMAP, "no map");
    plant_config_defaults(&c);
    c.R_alpha_per_K = 0.00393;
    CHECK(plant_prepare(&s, &c) == PLANT_ERR_THERMAL, "a thermal coefficient on the linear model");
}

static void check_energy_and_heat(void)
{
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "preset");
    plant_config_ideal(&c);
    grid(30.0);
    tabulate_saturating(c.Ld_H, c.Lq_H, c.psi_Wb, 6.0);
    c.model = PLANT_MODEL_FLUX_MAP;
    c.flux_map = &g_map;
    c.mech_mode = PLANT_MECH_FREE;
    c.J_kgm2 = 1e-3;
    plant_state_t s;
    plant_init(&s, &c);
    CHECK(s.status == 0, "prepare %d", s.status);
    unsigned long long st = 3u;
    double va = 0.0, vb = 0.0;
    for (int k = 0; k < 800; ++k) {
        if (k % 40 == 0) {
            va = 40.0 * (test_lcg_uniform(&st) - 0.5);
            vb = 40.0 * (test_lcg_uniform(&st) - 0.5);
        }
        plant_step(&s, &c, va, vb);
    }
    const double rel = fabs(plant_energy_residual_J(&s, &c)) / fabs(s.energy.in_J);
    CHECK(rel < 1e-6, "energy residual %.3g of the input", rel);
    printf("  saturating map, free mechanics: energy residual %.3g of the input, %u sub-steps\n", rel, s.last_substeps);

    /* heat: iq held at 10 A by its steady voltage (locked rotor), R follows T */
    c.mech_mode = PLANT_MECH_LOCKED;
    c.R_alpha_per_K = 0.00393;
    c.T_ref_degC = 20.0;
    c.T_amb_degC = 40.0;
    c.thermal_R_K_per_W = 0.5;
    c.thermal_C_J_per_K = 0.02; /* tau = 10 ms: 20 tau in 2000 periods of 100 us */
    plant_init(&s, &c);
    CHECK(s.status == 0, "prepare %d", s.status);
    const double iq = 10.0;
    for (int k = 0; k < 4000; ++k) {
        /* the voltage holding iq at the present R (the drive would close this loop) */
        const double vq = s.R_winding_ohm * iq;
        plant_set_currents(&s, 0.0, iq);
        plant_step(&s, &c, -vq * s.sin_e, vq * s.cos_e);
    }
    const double T = s.T_winding_degC;
    const double R = c.R_ohm * (1.0 + c.R_alpha_per_K * (T - c.T_ref_degC));
    const double T_fix = c.T_amb_degC + c.thermal_R_K_per_W * 1.5 * R * iq * iq;
    CHECK(fabs(T - T_fix) < 1e-3, "winding at %.6f degC, the fixed point is %.6f degC", T, T_fix);
    CHECK(fabs(s.R_winding_ohm - R) < 1e-12, "R %g != %g", s.R_winding_ohm, R);
    printf("  thermal: %.4f degC (fixed point %.4f), R %.6f ohm\n", T, T_fix, s.R_winding_ohm);
}

int main(void)
{
    check_inversion();
    check_linear_map();
    check_refusals();
    check_energy_and_heat();
    return check_finish("test_plant_fluxmap");
}
