/*
 * Encoder: N lines -> 4N counts/rev, count = floor(theta_m * 4N / 2pi),
 * theta_meas = count * 2pi / 4N.  Over one revolution at constant speed every
 * count must appear, 0 <= theta_true - theta_meas < 2pi/4N, and theta_meas is
 * on the grid.  lines = 0 gives the (float) true angle.
 */
#include <stdlib.h>

#include "check.h"
#include "plant_test_util.h"
#include "presets.h"

static int run(double omega, uint32_t lines)
{
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "preset");
    plant_config_ideal(&c);
    c.encoder_lines = lines;
    c.mech_mode = PLANT_MECH_IMPOSED_SPEED;
    c.omega_imposed_rad_s = omega;
    plant_state_t s;
    plant_init(&s, &c);
    CHECK(s.status == 0, "prepare");
    const uint32_t cpr = 4u * lines;
    const double q = 2.0 * (double)T_PI / cpr;
    unsigned char *seen = calloc(cpr, 1);
    const long nper = (long)(1.02 * 2.0 * (double)T_PI / (fabs(omega) * c.Ts_s));
    double emin = 1e9, emax = -1e9, offgrid = 0.0;
    for (long k = 0; k < nper; ++k) {
        plant_meas_t m;
        plant_sample(&s, &c, &m);
        CHECK(m.encoder_count >= 0 && (uint32_t)m.encoder_count < cpr, "count range");
        if (m.encoder_count >= 0 && (uint32_t)m.encoder_count < cpr) {
            seen[m.encoder_count] = 1;
        }
        const double e = m.theta_m_true_rad - (double)m.theta_m_rad;
        emin = fmin(emin, e);
        emax = fmax(emax, e);
        offgrid = fmax(offgrid, fabs((double)m.theta_m_rad - m.encoder_count * q));
        plant_step(&s, &c, 0.0, 0.0);
    }
    uint32_t nseen = 0;
    for (uint32_t i = 0; i < cpr; ++i) {
        nseen += seen[i];
    }
    free(seen);
    printf("encoder %u lines, omega %.2f rad/s: %u of %u counts seen, theta_true - theta_meas in [%.3e, %.3e] rad "
           "(quantum %.3e), off-grid %.2e\n",
           lines, omega, nseen, cpr, emin, emax, q, offgrid);
    CHECK(nseen == cpr, "all counts");
    CHECK(emin > -1e-6 && emax < q + 1e-6, "quantization error bound");
    CHECK(emax > 0.9 * q, "quantization visible");
    CHECK(offgrid < 1e-6, "on grid");
    return 0;
}

int main(void)
{
    run(1.0, 2500u);
    run(-1.3, 2500u);
    run(50.0, 64u);
    /* ideal */
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "preset");
    plant_config_ideal(&c);
    c.mech_mode = PLANT_MECH_IMPOSED_SPEED;
    c.omega_imposed_rad_s = 7.0;
    plant_state_t s;
    plant_init(&s, &c);
    double e = 0.0;
    for (int k = 0; k < 100000; ++k) {
        plant_meas_t m;
        plant_sample(&s, &c, &m);
        CHECK(m.encoder_count == -1, "ideal count");
        e = fmax(e, fabs((double)m.theta_m_rad - m.theta_m_true_rad));
        plant_step(&s, &c, 0.0, 0.0);
    }
    /* angle after 100000 periods vs omega*t (mod 2 pi) */
    const double th = fmod(7.0 * 100000 * c.Ts_s, 2.0 * (double)T_PI);
    printf("ideal encoder: max |theta_meas - theta_true| %.3e rad (float rounding); theta after 1e5 periods %.12f vs "
           "omega*t mod 2pi %.12f\n",
           e, s.theta_m_rad, th);
    CHECK(e < 1e-6, "ideal angle");
    CHECK(fabs(s.theta_m_rad - th) < 1e-9, "angle integration");
    return check_finish("test_plant_encoder");
}
