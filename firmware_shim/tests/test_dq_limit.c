/* test_dq_limit.c - the two voltage limiters of dq_math.h: the radial limit
 * of the surface-mounted laws (dq_limit_voltage_radial: off for Vmax <= 0, a
 * NaN magnitude passes) and its agreement, bit for bit, with the radial mode
 * of the You 2019 limiter (dq_limit_voltage(.., 1)) wherever both apply. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "dq_math.h"
#include "check.h"

static uint32_t bits(float x)
{
    uint32_t u;
    memcpy(&u, &x, sizeof(u));
    return u;
}

int main(void)
{
    float vd = 30.0f, vq = 40.0f; /* |v| = 50 */
    CHECK(dq_limit_voltage_radial(&vd, &vq, 60.0f) == 0u && vd == 30.0f && vq == 40.0f,
          "inside the circle the command is unchanged");

    vd = 30.0f, vq = 40.0f;
    CHECK(dq_limit_voltage_radial(&vd, &vq, 25.0f) == 1u, "outside the circle the command is limited");
    CHECK(fabsf(sqrtf(vd * vd + vq * vq) - 25.0f) < 1e-5f && fabsf(vd * 40.0f - vq * 30.0f) < 1e-4f,
          "scaled onto the circle, direction kept: %g %g", (double)vd, (double)vq);

    const float off[] = {0.0f, -1.0f, NAN};
    for (int k = 0; k < 3; ++k) {
        vd = 300.0f, vq = -400.0f;
        CHECK(dq_limit_voltage_radial(&vd, &vq, off[k]) == 0u && vd == 300.0f && vq == -400.0f,
              "Vmax = %g means no limit", (double)off[k]);
    }

    vd = NAN, vq = 5.0f;
    CHECK(dq_limit_voltage_radial(&vd, &vq, 1.0f) == 0u && isnan(vd) && vq == 5.0f,
          "a NaN magnitude passes unlimited (the other axis is kept)");

    /* same scaling as dq_limit_voltage(.., radial = 1) for finite commands and
     * Vmax > 0, bit for bit */
    long n = 0, diff = 0;
    for (int i = -40; i <= 40; ++i) {
        for (int j = -40; j <= 40; ++j) {
            for (int m = 1; m <= 5; ++m) {
                const float d0 = 3.7f * (float)i, q0 = 2.9f * (float)j;
                const float vmax = 19.3f * (float)m;
                float d1 = d0, q1 = q0, d2 = d0, q2 = q0;
                const uint8_t l1 = dq_limit_voltage_radial(&d1, &q1, vmax);
                const uint8_t l2 = dq_limit_voltage(&d2, &q2, vmax, 1u);
                diff += l1 != l2 || bits(d1) != bits(d2) || bits(q1) != bits(q2);
                ++n;
            }
        }
    }
    CHECK(diff == 0, "%ld of %ld commands differ from dq_limit_voltage(.., 1)", diff, n);
    printf("dq limiters: %ld commands compared, %ld differ\n", n, diff);
    return check_finish("test_dq_limit");
}
