/*
 * dq_linear_step.h - the linear dq model's step (dq_linear_step.c): one period, on the exact path dq_linear.c
 * prepared or on the RK4 path, and one period with the bridge's switches off.
 */
#ifndef DQ_LINEAR_STEP_H
#define DQ_LINEAR_STEP_H

#include "plant_types.h"

void dq_linear_step(plant_state_t *s, const plant_config_t *c, double va, double vb, double vd0, double vq0);
void dq_linear_step_bridge(plant_state_t *s, const plant_config_t *c);

#endif
