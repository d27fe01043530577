/*
 * plant_models.c - the machine models the plant knows: one line each, the descriptor its folder defines
 * (plant_rt/models/<name>/, plant_model.h).  Motor model.model's ValueNames in plant.eds name the same models;
 * tests/host/test_plant_models.py holds the two lists against each other.
 *
 * Plain C: no OS, no heap, no stdio.
 */
#include "plant_models.h"

/* clang-format off */
#define PLANT_MODELS(X) \
    X(plant_model_dq_linear) \
    X(plant_model_flux_map) \
    X(plant_model_external) \
    X(plant_model_harmonic)
/* clang-format on */

#define PLANT_MODEL_DECLARE(d) extern const plant_model_desc_t d;
PLANT_MODELS(PLANT_MODEL_DECLARE)
#undef PLANT_MODEL_DECLARE

#define PLANT_MODEL_ENTRY(d) &d,
static const plant_model_desc_t *const MODELS[] = {PLANT_MODELS(PLANT_MODEL_ENTRY)};
#undef PLANT_MODEL_ENTRY

const plant_model_desc_t *plant_model_find(int32_t id)
{
    for (size_t i = 0; i < sizeof MODELS / sizeof MODELS[0]; ++i) {
        if (MODELS[i]->id == id) {
            return MODELS[i];
        }
    }
    return NULL;
}
