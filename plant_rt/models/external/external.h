/*
 * external.h - the external machine model (Motor model.model = fmu): the caller's plant_external_t (an FMU,
 * plant_rt/fmu/) replaces the machine, electrical and mechanical; the inverter and the sensors stay the plant's.
 * Its descriptor is plant_model_external (plant_model.h).
 */
#ifndef EXTERNAL_H
#define EXTERNAL_H

#include "plant_model.h"

extern const plant_model_desc_t plant_model_external;

/* The state (rotor-frame currents, angle, speed) from the model's stator-frame outputs (plant_external_restart). */
void external_take(plant_state_t *s, const plant_config_t *c, const plant_external_out_t *out);

#endif
