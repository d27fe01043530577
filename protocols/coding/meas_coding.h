/* meas_coding.h - the compact measurement frame's integer codes (plant.eds / drive.eds 0x2100:07-09, scaled by
 * 0x2104 Measurement coding), encoded by the plant and decoded by the drive with the same expressions.
 *
 * A current travels as a signed 16-bit count of current_lsb_A, the angle as an unsigned 16-bit count of
 * 1/angle_counts of a mechanical revolution. Why exact with the plant's sensor models on (plant_sensors.c):
 *  - the ADC model's reading is (float)(lsb * k), k an integer, lsb the REAL32 0x2002:01 widened to double;
 *    with current_lsb_A = that lsb the encoder recovers k (|value / lsb - k| <= 2^-24 |k| < 0.5 for |k| < 2^23)
 *    and the decoder computes (float)(lsb * k) again, the same double product, rounded once: the same float;
 *  - the encoder model's angle is (float)(count * (2 pi / cpr)), cpr = 4 x lines; with angle_counts = cpr the
 *    same holds for the count.
 * Anything else is quantized: at most half a count (current_lsb_A / 2, pi / angle_counts rad) plus the float's
 * own rounding; currents beyond +-32767 counts are clipped (the encoder says so). A clipped ADC full scale that
 * is not a whole number of LSBs is one such value. A NaN current travels as -32768 and stays NaN; the angle has no
 * spare code (65536 counts take them all): a NaN angle travels as count 0.
 *
 * Header only, pure C11 with <math.h>: no OS headers, no allocation (the plant and the drive firmware, the MCU
 * image included, compile it as it is). */
#ifndef MEAS_CODING_H
#define MEAS_CODING_H

#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#define MEAS_CODING_TWO_PI 6.283185307179586476925286766559005768
#define MEAS_CODING_CURRENT_MAX 32767
#define MEAS_CODING_NAN ((int16_t)-32768) /* a current that is not a number */

/* A current's count; *clipped is set when it had to be limited to +-32767 (an infinity too). A NaN travels as
 * MEAS_CODING_NAN (-32768, which no clipped value takes) and decodes to NaN: the drive's non-finite path runs. */
static inline int16_t meas_code_current(float value_A, float lsb_A, bool *clipped)
{
    const double c = floor((double)value_A / (double)lsb_A + 0.5);
    if (c != c) return MEAS_CODING_NAN;
    if (!(c <= (double)MEAS_CODING_CURRENT_MAX && c >= -(double)MEAS_CODING_CURRENT_MAX)) {
        *clipped = true;
        return c < 0.0 ? (int16_t)-MEAS_CODING_CURRENT_MAX : (int16_t)MEAS_CODING_CURRENT_MAX;
    }
    return (int16_t)c;
}

static inline float meas_decode_current(int16_t code, float lsb_A)
{
    return code == MEAS_CODING_NAN ? (float)NAN : (float)((double)lsb_A * (double)code);
}

/* The angle's count in [0, counts): the nearest count, a full turn wrapping to 0. */
static inline uint16_t meas_code_angle(float theta_rad, uint32_t counts)
{
    const double step = MEAS_CODING_TWO_PI / (double)counts;
    double c = floor((double)theta_rad / step + 0.5);
    c -= (double)counts * floor(c / (double)counts);
    return (c >= 0.0 && c < (double)counts) ? (uint16_t)c : 0u;
}

static inline float meas_decode_angle(uint16_t code, uint32_t counts)
{
    return (float)((double)code * (MEAS_CODING_TWO_PI / (double)counts));
}

#endif /* MEAS_CODING_H */
