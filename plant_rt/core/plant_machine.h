/*
 * plant_machine.h - the machine block of the plant emulator: PMSM electrical
 * model in the rotor frame (exact discretization with Van Loan's energy
 * integrals, or RK4 with q-axis saturation), mechanics and energy accounting.
 * Model, conventions and integration scheme: pmsm_plant.h.
 *
 * Internal to plant_rt/core: callers use pmsm_plant.h.  The block works on
 * the machine fields of plant_state_t (currents, angle, speed, energy and the
 * discretization cache) and reads the motor, mechanics, hold-frame and RK4
 * fields of plant_config_t; its input is the voltage the inverter applies.
 */
#ifndef PLANT_MACHINE_H
#define PLANT_MACHINE_H

#include "pmsm_plant.h"

/* Phase currents of the present state (inverse Park, amplitude-invariant
 * inverse Clarke). */
static inline void plant_machine_phase_currents(const plant_state_t *s, double *ia_A, double *ib_A, double *ic_A)
{
    const double ial = s->cos_e * s->id_A - s->sin_e * s->iq_A;
    const double ibe = s->sin_e * s->id_A + s->cos_e * s->iq_A;
    *ia_A = ial;
    *ib_A = -0.5 * ial + 0.5 * PLANT_SQRT3 * ibe;
    *ic_A = -0.5 * ial - 0.5 * PLANT_SQRT3 * ibe;
}

/* q-axis flux linkage and incremental inductance (saturation model of
 * plant_config_t). */
double plant_machine_psi_q_Wb(const plant_config_t *c, double iq_A);
double plant_machine_Lq_inc_H(const plant_config_t *c, double iq_A);
double plant_machine_torque_Nm(const plant_state_t *s, const plant_config_t *c);
double plant_machine_magnetic_energy_J(const plant_state_t *s, const plant_config_t *c);
double plant_machine_kinetic_energy_J(const plant_state_t *s, const plant_config_t *c);
void plant_machine_energy_reset(plant_state_t *s, const plant_config_t *c);
double plant_machine_energy_residual_J(const plant_state_t *s, const plant_config_t *c);

/* theta_m is wrapped to [0, 2pi); omega only matters in FREE mode. */
void plant_machine_set_mech(plant_state_t *s, const plant_config_t *c, double theta_m_rad, double omega_m_rad_s);

/* For a validated c: speed from the mechanics mode, angle wrap and the
 * discretization cache.  Returns PLANT_OK or PLANT_ERR_EXPM. */
int plant_machine_prepare(plant_state_t *s, const plant_config_t *c);

/* Advance the machine one period Ts with the applied voltage
 * (v_alpha_V, v_beta_V) held in the frame of c->hold_frame. */
void plant_machine_step(plant_state_t *s, const plant_config_t *c, double v_alpha_V, double v_beta_V);
/* Advance the machine one period Ts with the bridge's switches off (trip_reaction pulses_off): the diodes give
 * the voltage (plant_bridge.h, s->bridge); v_app_* become its mean over the period.  Built-in models only. */
void plant_machine_step_bridge(plant_state_t *s, const plant_config_t *c);

/* The mechanics' part of an RK4 derivative, shared by the current (plant_machine_step.c) and the flux
 * (plant_machine_fluxmap.c) paths: the speed's derivative and the friction and load powers (0 unless FREE). */
static inline void plant_machine_mech_deriv(const plant_config_t *c, bool free_mech, double invJ, double Te, double wm,
                                            double *dw, double *p_fric, double *p_load)
{
    if (free_mech) {
        *dw = (Te - c->B_Nm_per_rad_s * wm - c->T_load_Nm) * invJ;
        *p_fric = c->B_Nm_per_rad_s * wm * wm;
        *p_load = c->T_load_Nm * wm;
    } else {
        *dw = 0.0;
        *p_fric = 0.0;
        *p_load = 0.0;
    }
}

/* The flux-map model (plant_machine_fluxmap.c): its preparation (the stiffness bound, the fluxes from the present
 * currents, the temperature), its step and its torque. */
int plant_machine_flux_prepare(plant_state_t *s, const plant_config_t *c, double p);
void plant_machine_flux_step(plant_state_t *s, const plant_config_t *c, double va, double vb, double vd0, double vq0);
double plant_machine_flux_torque_Nm(const plant_state_t *s, const plant_config_t *c);
void plant_machine_flux_step_bridge(plant_state_t *s, const plant_config_t *c);

/* The external model (plant_machine_external.c): one period through the caller's plant_external_t, the state
 * (currents, angle, speed) from its outputs; and the state from its initial outputs (plant_external_restart). */
void plant_machine_external_step(plant_state_t *s, const plant_config_t *c, double va, double vb);
void plant_machine_external_take(plant_state_t *s, const plant_config_t *c, const plant_external_out_t *out);

/* Shared by plant_machine.c and plant_machine_step.c: an angle into [0, 2 pi) (whole turns counted in *revs when
 * not NULL), and the electrical angle and its sine/cosine recomputed from the mechanical one. */
double plant_machine_wrap_2pi(double x, int64_t *revs);
void plant_machine_resync_angle(plant_state_t *s, const plant_config_t *c);

#endif
