/*
 * plant_angle.c - the rotor angle (plant_angle.h): its wrap with the whole turns, and the electrical angle's
 * cos/sin from the mechanical angle.
 *
 * Only <math.h>: no OS, no heap, no stdio.
 */
#include "plant_angle.h"

#include <math.h>

void plant_angle_resync(plant_state_t *s, const plant_config_t *c)
{
    const double th_e = fmod((double)c->pole_pairs * s->theta_m_rad, PLANT_TWO_PI);
    s->cos_e = cos(th_e);
    s->sin_e = sin(th_e);
    s->resync = 0u;
}

double plant_angle_wrap_2pi(double x, int64_t *revs)
{
    if (x >= PLANT_TWO_PI || x < 0.0) {
        const double n = floor(x / PLANT_TWO_PI);
        x -= n * PLANT_TWO_PI;
        if (revs != NULL) {
            *revs += (int64_t)n;
        }
        if (x >= PLANT_TWO_PI) { /* rounding guard */
            x -= PLANT_TWO_PI;
        }
        if (x < 0.0) {
            x = 0.0;
        }
    }
    return x;
}
