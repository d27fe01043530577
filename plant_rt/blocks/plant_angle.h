/*
 * plant_angle.h - the rotor angle and the frames: the wrap of an angle into [0, 2 pi) with its whole turns, the
 * electrical angle's cos/sin recomputed from the mechanical angle, and the phase currents of the rotor-frame
 * currents (inverse Park, amplitude-invariant inverse Clarke).  Every machine model and the API use them.
 *
 * Only <math.h>: no OS, no heap, no stdio.
 */
#ifndef PLANT_ANGLE_H
#define PLANT_ANGLE_H

#include "plant_types.h"

/* x wrapped to [0, 2pi), the whole turns added to *revs (if not NULL). */
double plant_angle_wrap_2pi(double x, int64_t *revs);
/* cos/sin(theta_e) of the state recomputed from theta_m (theta_e = p theta_m). */
void plant_angle_resync(plant_state_t *s, const plant_config_t *c);

/* The stator-frame currents of the present state (inverse Park). */
static inline void plant_angle_alpha_beta(const plant_state_t *s, double *i_alpha_A, double *i_beta_A)
{
    *i_alpha_A = s->cos_e * s->id_A - s->sin_e * s->iq_A;
    *i_beta_A = s->sin_e * s->id_A + s->cos_e * s->iq_A;
}

/* Phase currents of stator-frame currents (amplitude-invariant inverse Clarke). */
static inline void plant_angle_abc(double i_alpha_A, double i_beta_A, double *ia_A, double *ib_A, double *ic_A)
{
    *ia_A = i_alpha_A;
    *ib_A = -0.5 * i_alpha_A + 0.5 * PLANT_SQRT3 * i_beta_A;
    *ic_A = -0.5 * i_alpha_A - 0.5 * PLANT_SQRT3 * i_beta_A;
}

/* Phase currents of the present state (inverse Park, amplitude-invariant inverse Clarke). */
static inline void plant_angle_phase_currents(const plant_state_t *s, double *ia_A, double *ib_A, double *ic_A)
{
    double ial, ibe;
    plant_angle_alpha_beta(s, &ial, &ibe);
    plant_angle_abc(ial, ibe, ia_A, ib_A, ic_A);
}

#endif
