/*
 * presets.h - motor/drive parameter sets taken from the three papers the
 * bench reproduces (see /work/shared/papers/README.md).  Each preset starts
 * from plant_config_defaults() (all non-idealities off), then sets the
 * paper's motor, timing and inverter values; the hardware non-idealities the
 * paper states (You 2019: 2 us dead time, 2500-line encoder) are filled in,
 * and every preset sets an over-current trip level derived from the motor
 * (I_trip_A, ASSUMED, see presets.c); call plant_config_ideal() afterwards
 * to switch them off.
 * Fields the paper does not give are documented assumptions in presets.c.
 */
#ifndef PLANT_PRESETS_H
#define PLANT_PRESETS_H

#include <stddef.h>

#include "pmsm_plant.h"

#define PLANT_ERR_PRESET (-100)

/* Fill *c from the preset called name ("you2019", "yao2020_low",
 * "yao2020_high", "zhao2022").  Returns 0 or PLANT_ERR_PRESET (c untouched). */
int plant_preset_load(const char *name, plant_config_t *c);
size_t plant_preset_count(void);
/* Name of preset i (NULL if out of range). */
const char *plant_preset_name(size_t i);
/* One-line description with the source table (NULL if out of range). */
const char *plant_preset_source(size_t i);

#endif
