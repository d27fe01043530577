/* test_shim_meas_coding.c - the drive with the compact measurement frame (drive_meas_coding.c), mapped by SDO as
 * the bench maps it (RPDO1 {i_a_code, i_b_code, theta_code, sync_counter, status}, RPDO2 off, 0x2104 coding):
 *   - one frame is one period: the command comes, and 0x2100's amperes and radians are the codes times the coding's
 *     steps (computed here from the codes sent, in double, rounded once);
 *   - the sample index follows the SYNC counter the frame carries: a frame missing is one lost measurement, a frame
 *     behind the last one (reordered) is one late measurement, never a cycle of 239 lost;
 *   - a current code of -32768 is NaN: the drive's non-finite path counts it (0x2209:06) and keeps the last value;
 *   - with the default mapping the RPDO that carries the SYNC counter (RPDO2) still runs the period (the other
 *     shim tests). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "drive_od.h"
#include "shim_testbus.h"

#define LSB_A 0.005f
#define COUNTS 10000u

static void remap_compact(void)
{
    CHECK_TRUE(sdo_write_u32(0x1400u, 1, 0x80000000u | COB_MEAS1) == 0); /* RPDO1 off while mapped */
    CHECK_TRUE(sdo_write_u8(0x1600u, 0, 0) == 0);
    const uint32_t map[5] = {0x21000710u, 0x21000810u, 0x21000910u, 0x21000408u, 0x21000508u};
    for (uint8_t i = 0; i < 5u; ++i) CHECK_TRUE(sdo_write_u32(0x1600u, (uint8_t)(i + 1u), map[i]) == 0);
    CHECK_TRUE(sdo_write_u8(0x1600u, 0, 5) == 0);
    CHECK_TRUE(sdo_write_u32(0x1400u, 1, COB_MEAS1) == 0);
    CHECK_TRUE(sdo_write_u32(0x1401u, 1, 0x80000000u | COB_MEAS2) == 0); /* RPDO2 off */
    CHECK_TRUE(sdo_write_f32(OD_DRIVE_MEASUREMENT_CODING_IDX, 1, LSB_A) == 0);
    CHECK_TRUE(sdo_write_u32(OD_DRIVE_MEASUREMENT_CODING_IDX, 2, COUNTS) == 0);
}

/* The compact frame with SYNC counter sc (no SYNC frame: the frame marks the period); the command frame or NULL. */
static const co_frame_t *compact(int16_t ia, int16_t ib, uint16_t th, uint8_t sc)
{
    const uint8_t d[8] = {(uint8_t)ia, (uint8_t)((uint16_t)ia >> 8), (uint8_t)ib, (uint8_t)((uint16_t)ib >> 8),
                          (uint8_t)th, (uint8_t)(th >> 8),           sc,          0u};
    testbus_clear(&g_tb);
    inject(COB_MEAS1, 8, d);
    deliver();
    return find(COB_CMD, 0);
}

static uint32_t lost(void) { return sdo_read_u32(0x2204u, 2); } /* read: the supervision's counts */
static uint32_t late(void) { return sdo_read_u32(0x2204u, 3); }

int main(void)
{
    setup(100);
    remap_compact();
    const od_drive_measurement_t *x = &mfr_of(&g_tb.node)->x2100_Measurement;

    CHECK(compact(200, -123, 2500, 1) != NULL, "a compact frame is a period: the command comes");
    const float ia = (float)((double)LSB_A * 200.0), ib = (float)((double)LSB_A * -123.0);
    const float th = (float)(2500.0 * (6.283185307179586 / 10000.0));
    CHECK(x->i_a_A == ia && x->i_b_A == ib, "currents %.9g %.9g, want %.9g %.9g", (double)x->i_a_A, (double)x->i_b_A,
          (double)ia, (double)ib);
    CHECK(x->theta_m_rad == th, "angle %.9g, want %.9g", (double)x->theta_m_rad, (double)th);
    CHECK(x->sample_index == 0u, "the first sample's index is its counter - 1: %u", (unsigned)x->sample_index);

    for (uint8_t sc = 2; sc <= 5u; ++sc) CHECK(compact(10, 10, 0, sc) != NULL, "sample %u", (unsigned)sc);
    CHECK(lost() == 0u && late() == 0u, "in order: lost %u late %u", (unsigned)lost(), (unsigned)late());
    CHECK(x->sample_index == 4u, "index %u after counters 1..5", (unsigned)x->sample_index);

    compact(10, 10, 0, 7); /* 6 never comes */
    CHECK(lost() == 1u && late() == 0u, "one frame missing: lost %u late %u", (unsigned)lost(), (unsigned)late());
    compact(10, 10, 0, 9); /* 8 comes after 9 */
    compact(10, 10, 0, 8);
    CHECK(lost() == 2u && late() == 1u, "reordered: lost %u (8 missing when 9 came) late %u (8 behind 9)",
          (unsigned)lost(), (unsigned)late());
    compact(10, 10, 0, 10);
    CHECK(lost() == 2u && x->sample_index == 9u, "back in order: lost %u index %u", (unsigned)lost(),
          (unsigned)x->sample_index);

    /* the counter's cycle: 240 -> 1 is one step */
    for (unsigned sc = 11; sc <= 240u; ++sc) compact(10, 10, 0, (uint8_t)sc);
    compact(10, 10, 0, 1);
    CHECK(lost() == 2u && x->sample_index == 240u, "across the cycle: lost %u index %u", (unsigned)lost(),
          (unsigned)x->sample_index);

    const uint32_t nf0 = sdo_read_u32(0x2209u, 6);
    CHECK(compact((int16_t)-32768, 10, 0, 2) != NULL, "a NaN current is still a period");
    CHECK(isnan(x->i_a_A), "-32768 decodes to NaN: %.9g", (double)x->i_a_A);
    CHECK(sdo_read_u32(0x2209u, 6) == nf0 + 1u, "the drive rejected the NaN");
    return check_finish("test_shim_meas_coding");
}
