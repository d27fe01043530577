/*
 * plant_machine_energy.c - the machine block's energy account (plant_machine.h):
 * stored magnetic and kinetic energy and the balance of the integrals the
 * step accumulates (in = copper + stored + mechanical; pmsm_plant.h). Not in
 * the per-period path: read at reset and by the energy checks.
 *
 * Only <math.h>/<string.h>: no OS, no heap, no stdio.
 */
#include <math.h>
#include <string.h>

#include "plant_machine.h"

static double wq_energy(const plant_config_t *c, double iq_A)
{
    if (!c->sat_enable) {
        return 0.5 * c->Lq_H * iq_A * iq_A;
    }
    const double Is = c->sat_I_A, Li = c->sat_Lq_inf_H;
    const double x = iq_A / Is;
    return 0.5 * Li * iq_A * iq_A + 0.5 * (c->Lq_H - Li) * Is * Is * log1p(x * x);
}

double plant_machine_magnetic_energy_J(const plant_state_t *s, const plant_config_t *c)
{
    if (c->model == PLANT_MODEL_FLUX_MAP) {
        return s->W_mag_J; /* integrated by the step (plant_machine_fluxmap.c) */
    }
    return 1.5 * (0.5 * c->Ld_H * s->id_A * s->id_A + wq_energy(c, s->iq_A));
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
