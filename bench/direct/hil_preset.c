/* hil_preset.c - the plant's motor presets as the plant loads them (plant_rt/core/presets.c: each value with its
 * source, every assumption marked ASSUMED), for the Python side: bench/scenario/presets.py reads a preset's values
 * here by the EDS names of plant_config_t's fields (the studies in bench/claims derive their expectations from the
 * motor the plant runs, so the numbers are the plant's own, not a copy).  Exported from libhil.so for ctypes. */
#include <stddef.h>
#include <stdint.h>

#include "co_field_map.h"
#include "od_plant_fields.h"
#include "presets.h"

typedef struct {
    const char *name;
    uint16_t offset;
    uint8_t kind, size;
} preset_field_t;

/* plant_config_t's fields that plant.eds carries (Motor model, Inverter, Sensors), named as there. */
#define FIELD_ROW(index, sub, record, field, eds_default)                                                  \
    {#field, (uint16_t)offsetof(plant_config_t, field), (uint8_t)CO_FM_KIND(((plant_config_t *)0)->field), \
     (uint8_t)sizeof(((plant_config_t *)0)->field)},
/* clang-format off */
static const preset_field_t k_fields[] = {
    OD_PLANT_MOTOR_MODEL_PARAMS(FIELD_ROW)
    OD_PLANT_INVERTER_PARAMS(FIELD_ROW)
    OD_PLANT_SENSORS_PARAMS(FIELD_ROW)};
/* clang-format on */
#undef FIELD_ROW
#define N_FIELDS ((uint32_t)(sizeof k_fields / sizeof k_fields[0]))

uint32_t hil_preset_count(void);
const char *hil_preset_name(uint32_t i);
const char *hil_preset_source(uint32_t i);
uint32_t hil_preset_field_count(void);
const char *hil_preset_field_name(uint32_t i);
int32_t hil_preset_values(const char *preset, double *out, uint32_t n);

uint32_t hil_preset_count(void) { return (uint32_t)plant_preset_count(); }
const char *hil_preset_name(uint32_t i) { return plant_preset_name(i); }
const char *hil_preset_source(uint32_t i) { return plant_preset_source(i); }
uint32_t hil_preset_field_count(void) { return N_FIELDS; }
const char *hil_preset_field_name(uint32_t i) { return i < N_FIELDS ? k_fields[i].name : NULL; }

/* Every field of the preset after plant_preset_load (its fill over the plant's defaults), in hil_preset_field_name's
 * order, into out[0..n); 0, or -1 for no such preset. */
int32_t hil_preset_values(const char *preset, double *out, uint32_t n)
{
    plant_config_t c;
    if (plant_preset_load(preset, &c) != 0) return -1;
    for (uint32_t i = 0; i < n && i < N_FIELDS; ++i)
        out[i] = co_field_map_value((const uint8_t *)&c + k_fields[i].offset, k_fields[i].kind, k_fields[i].size);
    return 0;
}
