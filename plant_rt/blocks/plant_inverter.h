/*
 * plant_inverter.h - the inverter block of the plant emulator: modulation
 * limit, dead time and over-current trip.  Conventions (peak phase voltage
 * vector, SVPWM hexagon): pmsm_plant.h.
 *
 * Internal to plant_rt/core: callers use pmsm_plant.h.  The block works on
 * the inverter fields of plant_state_t (v_lim_*, v_app_*, tripped, Vdt_V) and
 * reads the inverter and protection fields of plant_config_t; its inputs are
 * the voltage command and the phase currents, its output the applied voltage
 * (v_app_alpha_V, v_app_beta_V) of the period, which plant_machine holds
 * over the period in the frame of c->hold_frame (PWM hold).
 */
#ifndef PLANT_INVERTER_H
#define PLANT_INVERTER_H

#include "plant_types.h"

/* For a validated c: the dead-time error magnitude Vdt_V. */
void plant_inverter_prepare(plant_state_t *s, const plant_config_t *c);

/* Over-current trip on any phase above c->I_trip_A (0 = level off), and,
 * whatever the level, on a non-finite phase current.  Latches s->tripped;
 * nothing to do once tripped. */
void plant_inverter_check_trip(plant_state_t *s, const plant_config_t *c, double ia_A, double ib_A, double ic_A);

/* The voltage applied over the next period for the command
 * (v_alpha_V, v_beta_V): trip on a non-finite command, modulation limit
 * (-> v_lim_*), dead time from the phase currents at the start of the period
 * (ia_A, ib_A, ic_A), zero while tripped (-> v_app_*; with trip_reaction
 * pulses_off the machine's period then follows the diodes instead, and
 * v_app_* becomes their mean voltage: plant_bridge.h). */
void plant_inverter_step(plant_state_t *s, const plant_config_t *c, double v_alpha_V, double v_beta_V, double ia_A,
                         double ib_A, double ic_A);

/* Per-phase dead-time voltage error for a phase current. */
double plant_inverter_deadtime_phase_error_V(const plant_config_t *c, double i_phase_A);
/* Apply the modulation limit of c to a command in place. */
void plant_inverter_modulation_limit(const plant_config_t *c, double *v_alpha_V, double *v_beta_V);

#endif
