/*
 * pmsm_plant.h - portable PMSM plant emulator core (the "hardware" side of the
 * hardware-in-the-loop bench).
 *
 * Timing contract (CANopen loop): at SYNC k the bench calls plant_sample() to
 * get the ADC phase currents and the encoder angle at instant k, then calls
 * plant_step() once per period with the voltage that the inverter outputs
 * during [k, k+1).  The one-period computation delay of the drive (command of
 * period k applied from k+1 to k+2) is handled by the bench, not here.
 *
 * Conventions
 *  - SI units everywhere, encoded in the names.
 *  - Clarke transform is amplitude invariant: v_alpha = phase-a voltage, a
 *    balanced set of phase currents with peak I gives |i_alphabeta| = I.
 *    The voltage command (v_alpha_V, v_beta_V) is therefore the PEAK
 *    phase-to-neutral voltage vector; the SVPWM hexagon has its vertices at
 *    2/3*Vdc and its inscribed circle has radius Vdc/sqrt(3).
 *  - Power/torque carry the 3/2 factor of the amplitude-invariant transform:
 *    P = 1.5 (vd id + vq iq), Te = 1.5 p (psi iq + (Ld - Lq) id iq).
 *  - Rotor dq frame, d axis on the magnet, motor convention (You 2019 Eq. 1):
 *      Ld did/dt = vd - R id + w Lq iq
 *      Lq diq/dt = vq - R iq - w Ld id - w psi          (w = p * omega_m)
 *  - theta_e = p * theta_m (d axis aligned with phase a at theta_m = 0).
 *
 * Integration
 *  - LOCKED / IMPOSED_SPEED without saturation: exact.  The command is held
 *    constant in the STATOR frame, so in the rotor frame it rotates:
 *    d/dt [vd vq] = w [vq -vd].  The augmented state x = [id iq vd vq 1] obeys
 *    dx/dt = A x with constant A; one period is x+ = expm(A Ts) x, computed
 *    once in plant_prepare.  Energy integrals over the period are exact
 *    quadratic forms x'Mx obtained with Van Loan's block exponential.
 *  - FREE mechanics or saturation on: classical RK4 on
 *    [id iq cos(th_e) sin(th_e) theta_m omega_m + 5 energy integrals] with
 *    N sub-steps per period, N = max(rk4_min_substeps,
 *    ceil(Ts*lambda/rk4_h_rel)), lambda = R/Lmin + |w| (+ the electromechanical
 *    frequency sqrt(1.5 p^2 psi^2/(J Lmin)) in FREE mode).  See the tests for
 *    the measured error.
 *
 * All functions take the config by const pointer; after any change of the
 * config call plant_prepare() again (it keeps the electrical/mechanical
 * state, recomputes the discretization and validates the parameters).
 *
 * Blocks (internal headers of plant_rt/core; the API below is their glue in
 * pmsm_plant.c).  They share plant_config_t and plant_state_t, whose fields
 * the callers use by flat names; the comments there say which block owns
 * which fields:
 *  - plant_machine: electrical model, mechanics, energy (exact / RK4 paths);
 *  - plant_inverter: modulation limit, dead time, over-current trip, the
 *    applied voltage the machine holds over the period;
 *  - plant_bridge: once tripped with trip_reaction pulses_off, the bridge
 *    as six diodes against Vdc (the machine's RK4 with each change of the
 *    diodes' conduction located);
 *  - plant_sensors: ADC of the phase currents, encoder.
 */
#ifndef PMSM_PLANT_H
#define PMSM_PLANT_H

#include "plant_types.h" /* the configuration, state and measurement; the EDS's enumerations */

/* Fill defaults: generic 1 ohm / 1 mH / 10 mWb motor, Ts = 100 us, LOCKED,
 * every non-ideality off (no saturation, modulation limit, dead time, ADC
 * noise/quantization/offset, encoder, trip). */
void plant_config_defaults(plant_config_t *c);
/* Turn every non-ideality off, keep motor/mechanics/timing parameters. */
void plant_config_ideal(plant_config_t *c);

/* Zero currents/angle/speed/energy, seed the RNG from c->rng_seed, and call
 * plant_prepare(); the result is in s->status (plant_step is a no-op while
 * s->status != 0). */
void plant_init(plant_state_t *s, const plant_config_t *c);
/* Validate c and (re)compute the discretization.  Returns PLANT_OK or a
 * negative PLANT_ERR_*.  Keeps currents and angle; sets omega_m to 0 (LOCKED)
 * or omega_imposed_rad_s (IMPOSED_SPEED). */
int plant_prepare(plant_state_t *s, const plant_config_t *c);
/* Measurement at the current instant (consumes RNG draws when noise is on). */
void plant_sample(plant_state_t *s, const plant_config_t *c, plant_meas_t *m);
/* Advance one period Ts with (v_alpha_V, v_beta_V) held in the stator frame
 * (peak phase voltage vector, amplitude-invariant Clarke). */
void plant_step(plant_state_t *s, const plant_config_t *c, double v_alpha_V, double v_beta_V);
void plant_clear_trip(plant_state_t *s);
/* The external model back to its initial state and the plant's state from its outputs (no-op for the other
 * models); returns the model's error (0: none). */
int plant_external_restart(plant_state_t *s, const plant_config_t *c);

/* Helpers for tests / bench set-up. */
void plant_set_currents(plant_state_t *s, double id_A, double iq_A);
/* theta_m is wrapped to [0, 2pi); omega only matters in FREE mode. */
void plant_set_mech(plant_state_t *s, const plant_config_t *c, double theta_m_rad, double omega_m_rad_s);
double plant_torque_Nm(const plant_state_t *s, const plant_config_t *c);
double plant_psi_q_Wb(const plant_config_t *c, double iq_A);
double plant_Lq_inc_H(const plant_config_t *c, double iq_A);
double plant_magnetic_energy_J(const plant_state_t *s, const plant_config_t *c);
double plant_kinetic_energy_J(const plant_state_t *s, const plant_config_t *c);
/* Zero the energy integrals and take the present stored energies as reference. */
void plant_energy_reset(plant_state_t *s, const plant_config_t *c);
/* in - copper - (W_mag - W_mag0) - mech  (0 up to integration error). */
double plant_energy_residual_J(const plant_state_t *s, const plant_config_t *c);
/* Per-phase dead-time voltage error for a phase current (exposed for tests). */
double plant_deadtime_phase_error_V(const plant_config_t *c, double i_phase_A);
/* Apply the modulation limit of c to a command in place. */
void plant_modulation_limit(const plant_config_t *c, double *v_alpha_V, double *v_beta_V);

#endif
