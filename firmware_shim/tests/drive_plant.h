/* drive_plant.h - the motor of tests/c/motor_model.h behind the drive core's interface
 * (drive_meas_t in, drive_cmd_t out), for the tests that run drive_current_step() in closed loop.
 * Not a test executable (no test_ prefix).
 *
 *   rotating = 0  exact standstill model (motor_zoh_t, per axis for the salient You 2019 motor),
 *                 rotor at angle 0; the stator-frame command is the rotor-frame one there
 *   rotating = 1  RK4 model (motor_t): the command held in the stator frame, speed fixed
 *                 (rk4.omega_m_rad_s) or free (rk4.free_speed)
 * The measurement is exact: phase currents a, b and the mechanical angle in [0, 2 pi). */
#ifndef DRIVE_PLANT_H
#define DRIVE_PLANT_H

#include <math.h>

#include "drive_core.h"
#include "law_states.h"
#include "motor_model.h"

typedef struct {
    int rotating;
    motor_zoh_t zoh;
    motor_t rk4;
} drive_plant_t;

static inline void drive_plant_init(drive_plant_t *pl, const char *preset)
{
    const motor_params_t par = motor_params_preset(preset);
    pl->rotating = 0;
    motor_init(&pl->rk4, &par);
    motor_zoh_init(&pl->zoh, &par, 0.0);
}

static inline void drive_plant_measure(const drive_plant_t *pl, drive_meas_t *m)
{
    const double id = pl->rotating ? pl->rk4.id_A : creal(pl->zoh.i_A);
    const double iq = pl->rotating ? pl->rk4.iq_A : cimag(pl->zoh.i_A);
    const double theta_m = pl->rotating ? pl->rk4.theta_m_rad : 0.0;
    const double th = pl->rk4.par.pole_pairs * theta_m;
    const double c = cos(th), s = sin(th);
    const double ial = id * c - iq * s;
    const double ibe = id * s + iq * c;
    m->i_a_A = (float)ial;
    m->i_b_A = (float)(-0.5 * ial + 0.5 * sqrt(3.0) * ibe);
    double tm = fmod(theta_m, 2.0 * MOTOR_PI);
    if (tm < 0) tm += 2.0 * MOTOR_PI;
    m->theta_m_rad = (float)tm;
}

static inline void drive_plant_advance(drive_plant_t *pl, const drive_cmd_t *cmd)
{
    const double va = (double)cmd->v_alpha_V, vb = (double)cmd->v_beta_V;
    if (pl->rotating) {
        motor_advance(&pl->rk4, va, vb);
    } else {
        const double c = 1.0, s = 0.0; /* cos, sin of the rotor angle 0 */
        motor_zoh_advance(&pl->zoh, va * c + vb * s, -va * s + vb * c);
    }
}

#endif /* DRIVE_PLANT_H */
