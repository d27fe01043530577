/*
 * Phase-current ADC model: offset, seeded Gaussian noise, quantization,
 * full-scale clipping, determinism.
 * Statistical bounds are computed from N (5-sigma of the estimators):
 *   mean: sigma/sqrt(N);  std: sigma/sqrt(2N);  correlation: 1/sqrt(N).
 */
#include "check.h"
#include "plant_test_util.h"
#include "presets.h"

#define NS 200000

static float g_a[NS], g_b[NS], g_a2[NS], g_b2[NS];

static void collect(plant_config_t *c, float *a, float *b, int n)
{
    plant_state_t s;
    plant_init(&s, c);
    CHECK(s.status == 0, "prepare");
    for (int k = 0; k < n; ++k) {
        plant_meas_t m;
        plant_sample(&s, c, &m);
        a[k] = m.i_a_A;
        b[k] = m.i_b_A;
    }
}

int main(void)
{
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "preset");
    plant_config_ideal(&c);
    c.mech_mode = PLANT_MECH_LOCKED;

    /* ---- noise statistics with offsets ---- */
    const double sigma = 0.02, oa = 0.05, ob = -0.03;
    c.adc_noise_std_A = sigma;
    c.adc_offset_a_A = oa;
    c.adc_offset_b_A = ob;
    c.rng_seed = 1234u;
    collect(&c, g_a, g_b, NS);
    double ma = 0, mb = 0;
    for (int k = 0; k < NS; ++k) {
        ma += (double)g_a[k];
        mb += (double)g_b[k];
    }
    ma /= NS;
    mb /= NS;
    double va = 0, vb = 0, cab = 0, lag = 0;
    for (int k = 0; k < NS; ++k) {
        const double da = (double)g_a[k] - ma, db = (double)g_b[k] - mb;
        va += da * da;
        vb += db * db;
        cab += da * db;
        if (k > 0) {
            lag += da * ((double)g_a[k - 1] - ma);
        }
    }
    const double sa = sqrt(va / (NS - 1)), sb = sqrt(vb / (NS - 1));
    const double rho = cab / sqrt(va * vb), rho1 = lag / va;
    const double bm = 5.0 * sigma / sqrt((double)NS), bs = 5.0 * sigma / sqrt(2.0 * NS), br = 5.0 / sqrt((double)NS);
    printf("noise: N=%d, mean a %.6f (offset %.3f, bound +-%.2e), mean b %.6f (offset %.3f)\n", NS, ma, oa, bm, mb, ob);
    printf(
        "noise: std a %.6f, std b %.6f (sigma %.4f, bound +-%.2e); corr(a,b) %.2e, lag-1 autocorr %.2e (bound %.2e)\n",
        sa, sb, sigma, bs, rho, rho1, br);
    CHECK(fabs(ma - oa) < bm && fabs(mb - ob) < bm, "means");
    CHECK(fabs(sa - sigma) < bs && fabs(sb - sigma) < bs, "std");
    CHECK(fabs(rho) < br && fabs(rho1) < br, "independence");
    /* tail fraction beyond 3 sigma: 0.0027 */
    int tail = 0;
    for (int k = 0; k < NS; ++k) {
        if (fabs((double)g_a[k] - oa) > 3.0 * sigma) {
            tail++;
        }
    }
    const double pt = 0.0026998, ft = (double)tail / NS, bt = 5.0 * sqrt(pt * (1 - pt) / NS);
    printf("noise: fraction beyond 3 sigma %.5f (Gaussian %.5f, bound +-%.5f)\n", ft, pt, bt);
    CHECK(fabs(ft - pt) < bt, "Gaussian tail");

    /* ---- determinism ---- */
    collect(&c, g_a2, g_b2, NS);
    const int same = memcmp(g_a, g_a2, sizeof(g_a)) == 0 && memcmp(g_b, g_b2, sizeof(g_b)) == 0;
    c.rng_seed = 1235u;
    collect(&c, g_a2, g_b2, NS);
    int ndiff = 0;
    for (int k = 0; k < NS; ++k) {
        if (memcmp(&g_a[k], &g_a2[k], sizeof(float)) != 0) {
            ndiff++;
        }
    }
    printf("determinism: same seed bit-identical: %s; different seed: %d of %d samples differ\n", same ? "yes" : "NO",
           ndiff, NS);
    CHECK(same, "same seed must be bit-identical");
    CHECK(ndiff > NS * 99 / 100, "different seed must differ");

    /* ---- quantization, no noise, currents varying at speed ---- */
    plant_config_t cq = c;
    cq.adc_noise_std_A = 0.0;
    cq.adc_offset_a_A = cq.adc_offset_b_A = 0.0;
    cq.adc_lsb_A = 0.01;
    cq.mech_mode = PLANT_MECH_IMPOSED_SPEED;
    cq.omega_imposed_rad_s = 100.0;
    {
        plant_state_t s;
        plant_init(&s, &cq);
        double emax = 0.0, offgrid = 0.0;
        for (int k = 0; k < 20000; ++k) {
            plant_meas_t m;
            plant_sample(&s, &cq, &m);
            emax = fmax(emax, fabs((double)m.i_a_A - m.i_a_true_A));
            emax = fmax(emax, fabs((double)m.i_b_A - m.i_b_true_A));
            /* on the grid: the float equals the float of the nearest grid point */
            const double q = floor((double)m.i_a_A / cq.adc_lsb_A + 0.5);
            if ((float)(q * cq.adc_lsb_A) != m.i_a_A) {
                offgrid += 1.0;
            }
            plant_step(&s, &cq, 30.0, 0.0);
        }
        printf("quantization LSB %.3f A: max |meas - true| %.6f A (bound LSB/2 + float eps), samples off the LSB grid: "
               "%.0f\n",
               cq.adc_lsb_A, emax, offgrid);
        CHECK(emax <= 0.5 * cq.adc_lsb_A + 1e-6, "quantization error bound");
        CHECK(emax > 0.4 * cq.adc_lsb_A, "quantization must be visible");
        CHECK(offgrid == 0.0, "on the LSB grid");
    }
    /* noise + quantization: variance ~ sigma^2 + LSB^2/12 (sigma = LSB) */
    {
        plant_config_t cn = c;
        cn.adc_offset_a_A = cn.adc_offset_b_A = 0.0;
        cn.adc_lsb_A = 0.02;
        cn.adc_noise_std_A = 0.02;
        collect(&cn, g_a, g_b, NS);
        double v = 0.0;
        for (int k = 0; k < NS; ++k) {
            v += (double)g_a[k] * (double)g_a[k];
        }
        const double sd = sqrt(v / NS), sexp = sqrt(0.02 * 0.02 + 0.02 * 0.02 / 12.0);
        printf("noise+quantization: std %.6f A (expected sqrt(sigma^2 + LSB^2/12) = %.6f A)\n", sd, sexp);
        CHECK(fabs(sd / sexp - 1.0) < 0.01, "dithered quantization variance");
    }
    /* full-scale clipping */
    {
        plant_config_t cf = c;
        cf.adc_noise_std_A = 0.0;
        cf.adc_offset_a_A = cf.adc_offset_b_A = 0.0;
        cf.adc_full_scale_A = 2.0;
        plant_state_t s;
        plant_init(&s, &cf);
        plant_set_currents(&s, 5.0, 0.0);
        plant_meas_t m;
        plant_sample(&s, &cf, &m);
        printf("full scale 2 A: true (%.3f, %.3f) -> measured (%.3f, %.3f)\n", m.i_a_true_A, m.i_b_true_A,
               (double)m.i_a_A, (double)m.i_b_A);
        CHECK(m.i_a_A == 2.0f && m.i_b_A == -2.0f, "clipping");
    }
    /* all off: measurement equals the truth to float precision */
    {
        plant_config_t co = c;
        plant_config_ideal(&co);
        plant_state_t s;
        plant_init(&s, &co);
        plant_set_currents(&s, 1.2345678, -0.5);
        plant_meas_t m;
        plant_sample(&s, &co, &m);
        CHECK(m.i_a_A == (float)m.i_a_true_A && m.i_b_A == (float)m.i_b_true_A, "ideal ADC");
    }
    return check_finish("test_plant_adc");
}
