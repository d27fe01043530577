/*
 * plant_machine.h - the machine block of the plant emulator: the chosen machine model (plant_model.h; the models'
 * folders: plant_rt/models/, registered in plant_models.c), the mechanics' modes around it and the energy account.
 * Model, conventions and integration scheme: pmsm_plant.h.
 *
 * Internal to plant_rt/core: callers use pmsm_plant.h.  The block works on the machine fields of plant_state_t
 * (currents, angle, speed, energy and the model's cache) and reads the motor, mechanics, hold-frame and RK4
 * fields of plant_config_t; its input is the voltage the inverter applies.
 */
#ifndef PLANT_MACHINE_H
#define PLANT_MACHINE_H

#include "plant_model.h"

double plant_machine_torque_Nm(const plant_state_t *s, const plant_config_t *c);
double plant_machine_magnetic_energy_J(const plant_state_t *s, const plant_config_t *c);
double plant_machine_kinetic_energy_J(const plant_state_t *s, const plant_config_t *c);
void plant_machine_energy_reset(plant_state_t *s, const plant_config_t *c);
double plant_machine_energy_residual_J(const plant_state_t *s, const plant_config_t *c);

/* theta_m is wrapped to [0, 2pi); omega only matters in FREE mode. */
void plant_machine_set_mech(plant_state_t *s, const plant_config_t *c, double theta_m_rad, double omega_m_rad_s);

/* For a validated c: speed from the mechanics mode, angle wrap, then the model's preparation.  Returns
 * PLANT_OK or the model's PLANT_ERR_*. */
int plant_machine_prepare(plant_state_t *s, const plant_config_t *c);

/* Advance the machine one period Ts with the applied voltage (v_alpha_V, v_beta_V) held in the frame of
 * c->hold_frame. */
void plant_machine_step(plant_state_t *s, const plant_config_t *c, double v_alpha_V, double v_beta_V);
/* Advance the machine one period Ts with the bridge's switches off (trip_reaction pulses_off): the diodes give
 * the voltage (plant_bridge.h, s->bridge); v_app_* become its mean over the period.  A model without a bridge step
 * is refused pulses_off by plant_prepare. */
void plant_machine_step_bridge(plant_state_t *s, const plant_config_t *c);

#endif
