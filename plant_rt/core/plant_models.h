/*
 * plant_models.h - the machine models the plant knows (plant_models.c: one line each) and the lookup of the one
 * Motor model.model names.
 */
#ifndef PLANT_MODELS_H
#define PLANT_MODELS_H

#include "plant_model.h"

/* The registered model whose id is Motor model.model's value, or NULL. */
const plant_model_desc_t *plant_model_find(int32_t id);

#endif
