/*
 * plant_perf.c - throughput of the plant core (one core, no threads).
 * Prints ns/period and periods/s for several configurations and the resident
 * memory before/after 10^6 periods (from /proc/self/statm).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "pmsm_plant.h"
#include "presets.h"

#define TWO_PI 6.283185307179586

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static long rss_pages(void)
{
    FILE *f = fopen("/proc/self/statm", "r");
    long size = 0, res = -1;
    if (f != NULL) {
        if (fscanf(f, "%ld %ld", &size, &res) != 2) {
            res = -1;
        }
        fclose(f);
    }
    return res;
}

static volatile double g_sink;

/* The example motor's map (examples/motors/saturating_you2019, bench/motor/example.py's co-energy model) on its
 * 33 x 33 grid of 1 A steps; `saturating` 0 tabulates the linear model instead. */
#define NG 33
static double g_grid[NG], g_pd[NG * NG], g_pq[NG * NG];
static plant_flux_map_t g_map = {NG, NG, g_grid, g_grid, g_pd, g_pq};

static void tabulate(const plant_config_t *c, int saturating)
{
    const double a = 0.55, Id = 8.0, b = 0.4, Iq = 5.0, kappa = 2.5e-4, Ix = 5.0;
    for (int i = 0; i < NG; ++i) g_grid[i] = -16.0 + (double)i;
    for (int i = 0; i < NG; ++i)
        for (int j = 0; j < NG; ++j) {
            const double id = g_grid[i], iq = g_grid[j], x = iq / Ix;
            if (saturating) {
                g_pd[i * NG + j] =
                    c->psi_Wb + c->Ld_H * (a * id + (1 - a) * Id * atan(id / Id)) - kappa * Ix * log1p(x * x);
                g_pq[i * NG + j] = c->Lq_H * (b * iq + (1 - b) * Iq * atan(iq / Iq)) - 2 * kappa * id * x / (1 + x * x);
            } else {
                g_pd[i * NG + j] = c->psi_Wb + c->Ld_H * id;
                g_pq[i * NG + j] = c->Lq_H * iq;
            }
        }
}

/* Runs n periods of sample+step with a rotating command; returns ns/period. */
static double run(plant_state_t *s, const plant_config_t *c, long n, int with_sample)
{
    plant_meas_t m;
    double acc = 0.0;
    const double V = 10.0;
    double ca = 1.0, sa = 0.0;
    const double dc = 0.9999998, ds = 0.00063245553; /* slow rotation, |.|~1 */
    const double t0 = now_s();
    for (long k = 0; k < n; ++k) {
        if (with_sample) {
            plant_sample(s, c, &m);
            acc += (double)m.i_a_A + (double)m.theta_m_rad;
        }
        plant_step(s, c, V * ca, V * sa);
        const double nc = ca * dc - sa * ds;
        sa = sa * dc + ca * ds;
        ca = nc;
    }
    const double t1 = now_s();
    g_sink = acc + s->id_A;
    return 1e9 * (t1 - t0) / (double)n;
}

static void bench(const char *label, plant_config_t *c, long n)
{
    plant_state_t s;
    plant_init(&s, c);
    if (s.status != 0) {
        printf("%-44s prepare failed (%d)\n", label, s.status);
        return;
    }
    (void)run(&s, c, n / 10, 1); /* warm-up */
    const double ns_step = run(&s, c, n, 0);
    const double ns_both = run(&s, c, n, 1);
    printf("%-44s step: %7.1f ns/period (%6.2f M/s)   sample+step: %7.1f ns (%6.2f M/s)  [rk4 substeps %u]\n", label,
           ns_step, 1e3 / ns_step, ns_both, 1e3 / ns_both, s.exact ? 0u : s.last_substeps);
}

int main(int argc, char **argv)
{
    long n = 10000000L;
    if (argc > 1) {
        n = atol(argv[1]);
        if (n < 1000) {
            n = 1000;
        }
    }
    plant_config_t c;
    if (plant_preset_load("you2019", &c) != 0) {
        return 1;
    }
    printf("plant_perf: You 2019 motor, %ld periods per measurement\n", n);

    plant_config_ideal(&c);
    c.mech_mode = PLANT_MECH_LOCKED;
    bench("locked rotor, all off", &c, n);

    c.mech_mode = PLANT_MECH_IMPOSED_SPEED;
    c.omega_imposed_rad_s = 1000.0 * TWO_PI / 60.0;
    bench("imposed 1000 rpm, all off", &c, n);

    plant_config_t cn = c;
    cn.t_dead_s = 2e-6;
    cn.adc_noise_std_A = 0.01;
    cn.adc_lsb_A = 0.005;
    cn.encoder_lines = 2500u;
    cn.mod_limit = PLANT_MOD_SVPWM_HEX;
    cn.I_trip_A = 1e6;
    bench("imposed 1000 rpm, DT+noise+enc+hex+trip", &cn, n);

    plant_config_t cf = c;
    cf.mech_mode = PLANT_MECH_FREE;
    cf.B_Nm_per_rad_s = 1e-4;
    bench("free mechanics (RK4)", &cf, n / 4);

    plant_config_t cs = c;
    cs.sat_enable = true;
    bench("imposed 1000 rpm, saturation (RK4)", &cs, n / 4);

    plant_config_t cm = c;
    cm.model = PLANT_MODEL_FLUX_MAP;
    cm.flux_map = &g_map;
    tabulate(&c, 0);
    cm.mech_mode = PLANT_MECH_LOCKED;
    bench("locked rotor, flux map 33x33 (linear)", &cm, n / 4);
    cm.mech_mode = PLANT_MECH_IMPOSED_SPEED;
    bench("imposed 1000 rpm, flux map 33x33 (linear)", &cm, n / 4);
    tabulate(&c, 1);
    bench("imposed 1000 rpm, flux map 33x33 (saturating)", &cm, n / 4);

    /* memory: everything on; a short warm-up first so that lazily mapped
     * libm/libc pages are already resident, then 2 x 10^6 periods. */
    plant_state_t s;
    plant_init(&s, &cn);
    (void)run(&s, &cn, 100000L, 1);
    const long rss0 = rss_pages();
    (void)run(&s, &cn, 1000000L, 1);
    const long rss1 = rss_pages();
    (void)run(&s, &cn, 1000000L, 1);
    const long rss2 = rss_pages();
    printf(
        "resident memory (pages): after warm-up %ld, after 10^6 periods %ld, after 2*10^6 periods %ld (growth %ld)\n",
        rss0, rss1, rss2, rss2 - rss0);
    printf("sizeof(plant_state_t) = %zu bytes, sizeof(plant_config_t) = %zu bytes\n", sizeof(plant_state_t),
           sizeof(plant_config_t));
    return 0;
}
