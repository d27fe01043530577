/*
 * The compact measurement frame's codes (protocols/coding/meas_coding.h) against the plant's own sensor models:
 *   - with the ADC model quantizing (noise and offsets on), every reading travels exactly: encoded with the ADC's
 *     LSB as current_lsb_A and decoded, it is the same float, bit for bit; the same for the encoder's angle with
 *     angle_counts = 4 x lines (the count is the encoder's own count);
 *   - with the models off, a decoded value is within half a count of the float (plus the float's rounding);
 *   - currents beyond +-32767 counts are clipped and said so, a NaN stays a NaN; a full turn wraps to count 0.
 * The readings come from plant_sample (pmsm_plant.h) over swept currents and angles, not from the coding's code.
 */
#include <math.h>
#include <string.h>

#include "check.h"
#include "meas_coding.h"
#include "plant_test_util.h"
#include "presets.h"

static uint32_t bits_of(float x)
{
    uint32_t u;
    memcpy(&u, &x, sizeof u);
    return u;
}

/* A reading of the plant at currents (id, iq) and angle theta through its sensor models. */
static plant_meas_t reading(plant_state_t *s, const plant_config_t *c, double id_A, double iq_A, double theta)
{
    plant_set_currents(s, id_A, iq_A);
    plant_set_mech(s, c, theta, 0.0);
    plant_meas_t m;
    plant_sample(s, c, &m);
    return m;
}

static void exact_with_models(float lsb_A, uint32_t lines)
{
    plant_config_t c;
    CHECK(plant_preset_load("you2019", &c) == 0, "preset");
    plant_config_ideal(&c);
    c.mech_mode = PLANT_MECH_LOCKED;
    c.adc_lsb_A = (double)lsb_A; /* the plant holds 0x2002:01, a REAL32, widened */
    c.adc_noise_std_A = 3.0 * (double)lsb_A;
    c.adc_offset_a_A = 0.37 * (double)lsb_A;
    c.encoder_lines = lines;
    c.rng_seed = 99u;
    plant_state_t s;
    plant_init(&s, &c);
    CHECK(s.status == 0, "prepare");
    const uint32_t counts = 4u * lines;
    const double span = 30000.0 * (double)lsb_A; /* inside +-32767 counts with the noise */
    unsigned long long st = 7u;
    int bad_i = 0, bad_theta = 0, bad_count = 0;
    for (int k = 0; k < 20000; ++k) {
        const double id = (2.0 * test_lcg_uniform(&st) - 1.0) * span * 0.5;
        const double iq = (2.0 * test_lcg_uniform(&st) - 1.0) * span * 0.5;
        const double th = test_lcg_uniform(&st) * (double)T_TWO_PI;
        const plant_meas_t m = reading(&s, &c, id, iq, th);
        bool clipped = false;
        const int16_t ca = meas_code_current(m.i_a_A, lsb_A, &clipped);
        const int16_t cb = meas_code_current(m.i_b_A, lsb_A, &clipped);
        const uint16_t ct = meas_code_angle(m.theta_m_rad, counts);
        bad_i += bits_of(meas_decode_current(ca, lsb_A)) != bits_of(m.i_a_A);
        bad_i += bits_of(meas_decode_current(cb, lsb_A)) != bits_of(m.i_b_A);
        bad_i += clipped;
        bad_theta += bits_of(meas_decode_angle(ct, counts)) != bits_of(m.theta_m_rad);
        bad_count += (int32_t)ct != m.encoder_count;
    }
    CHECK(bad_i == 0, "lsb %.9g A: %d of 40000 ADC readings not bit-equal after the code (or clipped)", (double)lsb_A,
          bad_i);
    CHECK(bad_theta == 0, "%u lines: %d of 20000 encoder angles not bit-equal after the code", lines, bad_theta);
    CHECK(bad_count == 0, "%u lines: %d of 20000 codes are not the encoder's count", lines, bad_count);
}

static void bounded_without_models(void)
{
    const float lsb_A = 0.001f;
    const uint32_t counts = 65536u;
    unsigned long long st = 11u;
    double worst_i = 0.0, worst_th = 0.0;
    for (int k = 0; k < 100000; ++k) {
        const float x = (float)((2.0 * test_lcg_uniform(&st) - 1.0) * 32.0);
        const float th = (float)(test_lcg_uniform(&st) * (double)T_TWO_PI);
        bool clipped = false;
        const float xd = meas_decode_current(meas_code_current(x, lsb_A, &clipped), lsb_A);
        const float thd = meas_decode_angle(meas_code_angle(th, counts), counts);
        double e_th = fabs((double)thd - (double)th);
        e_th = fmin(e_th, fabs(e_th - (double)T_TWO_PI)); /* a wrap to count 0 */
        worst_i = fmax(worst_i, fabs((double)xd - (double)x));
        worst_th = fmax(worst_th, e_th);
        CHECK(!clipped, "%.9g A clipped", (double)x);
    }
    /* half a count, and the decoded float's own rounding (half an ulp of 32 A: 2^-19 A; of 2 pi: 2^-22 rad) */
    const double bound_i = 0.5 * (double)lsb_A + ldexp(1.0, -19);
    const double bound_th = (double)T_PI / counts + ldexp(1.0, -22);
    CHECK(worst_i <= bound_i, "current: worst %.3g A > %.3g A", worst_i, bound_i);
    CHECK(worst_th <= bound_th, "angle: worst %.3g rad > %.3g rad", worst_th, bound_th);
    CHECK(worst_i > 0.4 * (double)lsb_A, "current: worst %.3g A: the sweep never met a half count", worst_i);
    printf("models off: worst %.3g A (lsb %.3g A), %.3g rad (65536 counts)\n", worst_i, (double)lsb_A, worst_th);
}

static void clipping_and_wrap(void)
{
    bool clipped = false;
    CHECK(meas_code_current(40.0f, 0.001f, &clipped) == 32767 && clipped, "+40 A at 1 mA: 32767, clipped");
    clipped = false;
    CHECK(meas_code_current(-40.0f, 0.001f, &clipped) == -32767 && clipped, "-40 A at 1 mA: -32767, clipped");
    clipped = false;
    CHECK(meas_code_current(32.767f, 0.001f, &clipped) == 32767 && !clipped, "32.767 A: 32767, not clipped");
    clipped = false;
    CHECK(meas_code_current(NAN, 0.001f, &clipped) == MEAS_CODING_NAN && !clipped, "NaN: -32768, not clipped");
    CHECK(isnan(meas_decode_current(MEAS_CODING_NAN, 0.001f)), "-32768 decodes to NaN");
    CHECK(meas_code_current(INFINITY, 0.001f, &clipped) == 32767 && clipped, "+inf: 32767, clipped");
    CHECK(meas_decode_current(-32767, 0.001f) == (float)((double)0.001f * -32767.0), "-32767 is a current: %.9g",
          (double)meas_decode_current(-32767, 0.001f));
    CHECK(meas_code_angle((float)(2.0 * M_PI) - 1e-6f, 65536u) == 0u, "just below a full turn: count 0");
    CHECK(meas_code_angle(-1e-6f, 65536u) == 0u, "just below 0: count 0");
    CHECK(meas_code_angle((float)M_PI, 4u) == 2u, "pi at 4 counts: 2");
}

int main(void)
{
    exact_with_models(0.005f, 2500u); /* You 2019's encoder, a 5 mA ADC */
    exact_with_models(0.0123f, 1024u);
    exact_with_models(20.0f / 2048.0f, 16384u); /* a 12-bit +-20 A ADC; 65536 counts */
    exact_with_models(1e-4f, 1u);
    bounded_without_models();
    clipping_and_wrap();
    return check_finish("test_meas_coding");
}
