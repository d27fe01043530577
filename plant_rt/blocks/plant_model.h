/*
 * plant_model.h - the face of a machine model, as current_law_t is a law's: a descriptor the model's folder
 * (plant_rt/models/<name>/) defines and plant_rt/core/plant_models.c registers in one line.  The plant chooses
 * the descriptor once, from Motor model.model (plant.eds), when it prepares a configuration.
 *
 * A model owns the machine's electrical part (and, for an external model, the mechanics too): it prepares its
 * discretization or its bounds from the configuration, steps one period with the applied voltage held, and gives
 * the torque and the stored magnetic energy of the present state.  It works on the machine fields of
 * plant_state_t (currents, angle, speed, the energy integrals, its status entries such as the incremental
 * inductances of 0x2005) and reads plant_config_t; the inverter, the sensors and the mechanics' wrap stay the
 * plant's.  Shared pieces below it: plant_angle.h (angle, frames), plant_rk4.h (the integrator, the sub-steps,
 * the mechanics' derivative), plant_bridge.h (the diodes, trip_reaction pulses_off).
 *
 * Only plain C: no OS, no heap, no stdio.
 */
#ifndef PLANT_MODEL_H
#define PLANT_MODEL_H

#include "plant_types.h"

typedef struct plant_model_desc {
    int32_t id;       /* its value of Motor model.model: OD_PLANT_MODEL_<NAME> (the EDS's ValueNames) */
    const char *name; /* the ValueName */
    bool thermal;     /* it runs the winding's temperature model (R_alpha_per_K, thermal_*); else those must be 0 */
    /* The model's own checks of a configuration the plant has checked (finite values, ranges, enumerations):
     * PLANT_OK or a PLANT_ERR_*.  NULL: none. */
    int (*validate)(const plant_config_t *c);
    /* For a validated c, after the plant set the speed from the mechanics mode and wrapped the angle: the
     * model's discretization, bounds and status entries.  p: the pole pairs.  PLANT_OK or a PLANT_ERR_*. */
    int (*prepare)(plant_state_t *s, const plant_config_t *c, double p);
    /* One period Ts with the applied voltage held: (va, vb) in the stator frame, (vd0, vq0) the same at the
     * period's start angle (what hold_frame rotor holds). */
    void (*step)(plant_state_t *s, const plant_config_t *c, double va, double vb, double vd0, double vq0);
    /* One period with the bridge's switches off (plant_bridge.h: the diodes give the voltage; s->bridge's mean
     * voltage is the period's).  NULL: the model holds one voltage a period and cannot follow the diodes, so
     * trip_reaction pulses_off is refused on it. */
    void (*step_bridge)(plant_state_t *s, const plant_config_t *c);
    double (*torque_Nm)(const plant_state_t *s, const plant_config_t *c);
    double (*magnetic_energy_J)(const plant_state_t *s, const plant_config_t *c);
} plant_model_desc_t;

/* The status entries of a model without a thermal model: R at its value, the winding at the ambient, and no
 * flux map the fluxes were taken from (a later switch to a flux map takes them afresh). */
static inline void plant_model_fixed_winding(plant_state_t *s, const plant_config_t *c)
{
    s->prepared_map = NULL;
    s->R_winding_ohm = c->R_ohm;
    s->T_winding_degC = c->T_amb_degC;
}

#endif
