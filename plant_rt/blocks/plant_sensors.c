/*
 * plant_sensors.c - the sensor block of the plant emulator (see
 * plant_sensors.h).
 *
 * Only <math.h>: no OS, no heap, no stdio.
 */
#include "plant_sensors.h"

#include <math.h>

static double adc_convert(plant_rng_t *rng, const plant_config_t *c, double i_true, double offset)
{
    double x = i_true + offset;
    if (c->adc_noise_std_A > 0.0) {
        x += c->adc_noise_std_A * plant_rng_gauss(rng);
    }
    if (c->adc_lsb_A > 0.0) {
        x = c->adc_lsb_A * floor(x / c->adc_lsb_A + 0.5);
    }
    if (c->adc_full_scale_A > 0.0) {
        if (x > c->adc_full_scale_A) {
            x = c->adc_full_scale_A;
        } else if (x < -c->adc_full_scale_A) {
            x = -c->adc_full_scale_A;
        }
    }
    return x;
}

void plant_sensors_sample(plant_rng_t *rng, const plant_config_t *c, double ia_A, double ib_A, double theta_m_rad,
                          plant_meas_t *m)
{
    m->i_a_A = (float)adc_convert(rng, c, ia_A, c->adc_offset_a_A);
    m->i_b_A = (float)adc_convert(rng, c, ib_A, c->adc_offset_b_A);

    if (c->encoder_lines > 0u) {
        const double cpr = 4.0 * (double)c->encoder_lines;
        double cnt = floor(theta_m_rad * (cpr / PLANT_TWO_PI));
        if (cnt >= cpr) {
            cnt = 0.0;
        }
        if (cnt < 0.0) {
            cnt = 0.0;
        }
        m->encoder_count = (int32_t)cnt;
        m->theta_m_rad = (float)(cnt * (PLANT_TWO_PI / cpr));
    } else {
        m->encoder_count = -1;
        m->theta_m_rad = (float)theta_m_rad;
    }
}
