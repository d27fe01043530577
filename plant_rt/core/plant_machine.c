/*
 * plant_machine.c - the machine block of the plant emulator (see plant_machine.h; model and integration scheme:
 * pmsm_plant.h): the speed from the mechanics mode and the angle's wrap before the chosen model prepares, and the
 * step, the torque and the energy account through the model's descriptor (plant_model.h).
 *
 * Only <math.h>/<string.h>: no OS, no heap, no stdio.
 */
#include "plant_machine.h"

#include <math.h>
#include <string.h>

#include "plant_angle.h"
#include "plant_models.h"

/* The model of the state's last preparation; before one (a state the caller filled) or after a refused
 * configuration, the configuration's (NULL: not a registered model). */
static const plant_model_desc_t *model_of(const plant_state_t *s, const plant_config_t *c)
{
    return s->model != NULL ? s->model : plant_model_find(c->model);
}

double plant_machine_torque_Nm(const plant_state_t *s, const plant_config_t *c)
{
    const plant_model_desc_t *m = model_of(s, c);
    return m != NULL ? m->torque_Nm(s, c) : 0.0;
}

double plant_machine_magnetic_energy_J(const plant_state_t *s, const plant_config_t *c)
{
    const plant_model_desc_t *m = model_of(s, c);
    return m != NULL ? m->magnetic_energy_J(s, c) : 0.0;
}

double plant_machine_kinetic_energy_J(const plant_state_t *s, const plant_config_t *c)
{
    return 0.5 * c->J_kgm2 * s->omega_m_rad_s * s->omega_m_rad_s;
}

void plant_machine_energy_reset(plant_state_t *s, const plant_config_t *c)
{
    memset(&s->energy, 0, sizeof(s->energy));
    s->energy.W_mag0_J = plant_machine_magnetic_energy_J(s, c);
    s->energy.W_kin0_J = plant_machine_kinetic_energy_J(s, c);
}

double plant_machine_energy_residual_J(const plant_state_t *s, const plant_config_t *c)
{
    const plant_energy_t *e = &s->energy;
    const double dW = plant_machine_magnetic_energy_J(s, c) - e->W_mag0_J;
    return e->in_J - e->copper_J - dW - e->mech_J;
}

void plant_machine_set_mech(plant_state_t *s, const plant_config_t *c, double theta_m_rad, double omega_m_rad_s)
{
    s->theta_m_rad = plant_angle_wrap_2pi(theta_m_rad, NULL);
    if (c->mech_mode == PLANT_MECH_FREE) {
        s->omega_m_rad_s = omega_m_rad_s;
    }
    plant_angle_resync(s, c);
}

int plant_machine_prepare(plant_state_t *s, const plant_config_t *c)
{
    if (c->mech_mode == PLANT_MECH_LOCKED) {
        s->omega_m_rad_s = 0.0;
    } else if (c->mech_mode == PLANT_MECH_IMPOSED_SPEED) {
        s->omega_m_rad_s = c->omega_imposed_rad_s;
    }
    const double p = (double)c->pole_pairs;
    const double w_e = p * s->omega_m_rad_s;
    s->dtheta_m = s->omega_m_rad_s * c->Ts_s;
    s->rot_c = cos(w_e * c->Ts_s);
    s->rot_s = sin(w_e * c->Ts_s);
    s->theta_m_rad = plant_angle_wrap_2pi(s->theta_m_rad, &s->revolutions);
    plant_angle_resync(s, c);
    s->model = plant_model_find(c->model);
    return s->model != NULL ? s->model->prepare(s, c, p) : PLANT_ERR_ENUM;
}

void plant_machine_step_bridge(plant_state_t *s, const plant_config_t *c)
{
    const plant_model_desc_t *m = model_of(s, c);
    if (m == NULL || m->step_bridge == NULL) {
        return; /* refused by plant_prepare */
    }
    m->step_bridge(s, c);
    s->v_app_alpha_V = s->bridge.v_mean_alpha_V;
    s->v_app_beta_V = s->bridge.v_mean_beta_V;
}

void plant_machine_step(plant_state_t *s, const plant_config_t *c, double v_alpha_V, double v_beta_V)
{
    const double va = v_alpha_V, vb = v_beta_V;
    const double ce = s->cos_e, se = s->sin_e;
    const double vd0 = va * ce + vb * se;
    const double vq0 = -va * se + vb * ce;
    const plant_model_desc_t *m = model_of(s, c);
    if (m != NULL) {
        m->step(s, c, va, vb, vd0, vq0);
    }
}
