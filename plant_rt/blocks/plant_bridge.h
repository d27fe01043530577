/*
 * plant_bridge.h - the inverter's bridge with its six switches off (plant_config_t.trip_reaction ==
 * PLANT_TRIP_PULSES_OFF, after a trip): a three-phase diode bridge between the motor's terminals and a stiff DC
 * link of Vdc_V.  Internal to plant_rt/core (the machine models call it; callers use pmsm_plant.h).
 *
 * The physics, per phase x (motor convention, i_x > 0 flows into the motor; u_x the terminal's voltage against
 * the DC link's midpoint):
 *   i_x > 0: the lower diode conducts, u_x = -Vdc/2;   i_x < 0: the upper diode, u_x = +Vdc/2;
 *   i_x = 0: the phase is off, u_x is whatever the machine makes it, and it stays off while
 *            -Vdc/2 <= u_x <= Vdc/2 (outside, the diode on that side starts to conduct).
 * The star point floats: the three currents sum to zero, so one phase alone cannot conduct.  The bridge has
 * three conduction states: all three phases conduct (the applied voltage is fixed by the currents' signs:
 * v = (2/3) sum u_x n_x, amplitude-invariant Clarke), one phase off (its voltage is the one that keeps its
 * current at zero, from the machine's own equations), all off (the currents stay zero while the back-EMF's
 * spread between phases, max e_x - min e_x, is below Vdc; above it the highest and the lowest phase conduct:
 * uncontrolled rectification).
 *
 * The machine models give, at each RK4 stage, their state's linearization in the applied voltage
 * (plant_bridge_lin_t: d i/dt = a + B v in the rotor frame, exact for these models since their derivatives are
 * affine in the voltage), and take the bridge's voltage from plant_bridge_voltage.  plant_bridge_period
 * integrates a period in the model's RK4 sub-steps and locates each change of conduction state inside a sub-step
 * (a current reaching zero, an off phase's voltage reaching a rail, the back-EMF's spread reaching Vdc) by
 * regula falsi (Illinois) on the step length, each trial a full RK4 step from the sub-step's start; the state
 * changes there and the integration goes on from that instant, so RK4 keeps its order across the kinks.
 *
 * Only <stdint.h>/<stdbool.h>: no OS, no heap, no stdio.
 */
#ifndef PLANT_BRIDGE_H
#define PLANT_BRIDGE_H

#include <stdbool.h>
#include <stdint.h>

#define PLANT_BRIDGE_MAX_Y 12      /* the longest model state (models/flux_map/flux_map.c) */
#define PLANT_BRIDGE_MAX_EVENTS 64 /* conduction changes located a period (more: the rest of it is not located) */
/* The bridge's period takes this many times the model's RK4 sub-steps: the diodes drive the current with up to
 * 2/3 Vdc, far beyond what the current's own scale suggests, and RK4's error scales with that forcing (Vdc / R);
 * 4 times the steps is 1/1024 of the error (plant_bridge.c), at a cost paid only while tripped. */
#define PLANT_BRIDGE_SUBSTEPS 4u

typedef struct {
    int8_t phase[3];    /* +1 conducts i > 0 (u = -Vdc/2), -1 conducts i < 0 (u = +Vdc/2), 0 off (i = 0) */
    bool active;        /* phase[] holds the conduction state (set at the first period with the pulses off) */
    uint32_t events;    /* conduction changes since the pulses went off */
    uint32_t unlocated; /* periods that had more than PLANT_BRIDGE_MAX_EVENTS changes */
    /* the last plant_bridge_voltage: its voltage (stator frame), the state's margin (> 0 while the conduction
     * state holds: Vdc/2 - |u| of the off phase, Vdc - the back-EMF's spread with all off, +inf with all on),
     * the off phase's terminal voltage, the phases of the highest and lowest back-EMF (all off) */
    double Vdc_V;
    double v_alpha_V, v_beta_V;
    double margin_V;
    double u_off_V;
    int8_t emf_max, emf_min;
    /* plant_bridge_period: the mean voltage the bridge applied over the period */
    double v_mean_alpha_V, v_mean_beta_V;
} plant_bridge_t;

/* A model's state at one RK4 stage: the angle, the speed, the currents and d(id, iq)/dt = a + B (vd, vq). */
typedef struct {
    double cos_e, sin_e, w_e; /* electrical angle (cos, sin) and speed, rad/s */
    double id_A, iq_A;
    double a_d_A_s, a_q_A_s; /* d(id, iq)/dt at zero applied voltage */
    double B_per_H[2][2];    /* d(d id/dt, d iq/dt) / d(vd, vq): the inverse incremental inductance */
} plant_bridge_lin_t;

/* The rotor-frame voltage the bridge applies in its conduction state at this stage (and b's margin). */
void plant_bridge_voltage(plant_bridge_t *b, const plant_bridge_lin_t *l, double *vd_V, double *vq_V);

/* A machine model as the bridge's integrator sees it: its state y (n_y values: currents or fluxes, the angle's
 * cos and sin, the mechanics, the energy integrals), its derivative (which takes its voltage from
 * plant_bridge_voltage on the same bridge), its stator-frame currents, and a state with its currents set. */
typedef struct {
    void *ctx;
    int n_y;
    void (*deriv)(void *ctx, const double *y, double *dy);
    void (*currents)(void *ctx, const double *y, double *i_alpha_A, double *i_beta_A);
    void (*set_currents)(void *ctx, double *y, double i_alpha_A, double i_beta_A);
} plant_bridge_model_t;

/* One period Ts_s of the model with the switches off, in n RK4 sub-steps (the model's own count), each change of
 * conduction state located.  y: the state at the period's start, on return at its end. */
void plant_bridge_period(plant_bridge_t *b, const plant_bridge_model_t *m, double *y, double Ts_s, uint32_t n);

#endif
