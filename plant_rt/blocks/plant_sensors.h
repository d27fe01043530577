/*
 * plant_sensors.h - the sensor block of the plant emulator: ADC of the phase
 * currents a and b (offset, Gaussian noise, quantization, full-scale
 * clipping) and the quadrature encoder (4*lines counts per revolution).
 *
 * Internal to plant_rt/core: callers use pmsm_plant.h.  The block's state is
 * the noise generator (plant_state_t.rng); it reads the sensor fields of
 * plant_config_t.
 */
#ifndef PLANT_SENSORS_H
#define PLANT_SENSORS_H

#include "plant_types.h"

/* The measured fields of *m (i_a_A, i_b_A, theta_m_rad, encoder_count) from
 * the true phase currents and mechanical angle ([0, 2pi)); consumes two
 * draws of rng when the noise is on (phase a first). */
void plant_sensors_sample(plant_rng_t *rng, const plant_config_t *c, double ia_A, double ib_A, double theta_m_rad,
                          plant_meas_t *m);

#endif
