/*
 * plant_machine_external.c - the machine block on an external model (plant_config_t.model ==
 * PLANT_MODEL_EXTERNAL, plant_external_t in pmsm_plant.h; an FMU: plant_rt/fmu/): one period through the
 * caller's step, the plant's state (rotor-frame currents, angle, speed) from its stator-frame outputs.  A model
 * that fails is not stepped again: the plant latches its trip (the inverter applies 0 V) and keeps the state
 * the model last gave.
 *
 * Only <math.h>: no OS, no heap, no stdio.
 */
#include <math.h>

#include "plant_machine.h"

void plant_machine_external_take(plant_state_t *s, const plant_config_t *c, const plant_external_out_t *out)
{
    /* the model's angle may wrap or not: whole turns counted from the change of the wrapped angle */
    const double th = plant_machine_wrap_2pi(out->theta_m_rad, NULL);
    const double d = th - s->theta_m_rad;
    if (d < -0.5 * PLANT_TWO_PI) {
        ++s->revolutions;
    } else if (d > 0.5 * PLANT_TWO_PI) {
        --s->revolutions;
    }
    s->theta_m_rad = th;
    s->omega_m_rad_s = out->omega_m_rad_s;
    plant_machine_resync_angle(s, c);
    /* Park: the rotor-frame currents of the model's stator-frame ones */
    s->id_A = s->cos_e * out->i_alpha_A + s->sin_e * out->i_beta_A;
    s->iq_A = -s->sin_e * out->i_alpha_A + s->cos_e * out->i_beta_A;
}

void plant_machine_external_step(plant_state_t *s, const plant_config_t *c, double va, double vb)
{
    if (s->external_error != 0) {
        return;
    }
    if (c->external == NULL || c->external->step == NULL) { /* a model that went away (a failed reload) */
        s->external_error = -5;
        s->tripped = true;
        return;
    }
    plant_external_out_t out;
    /* the model's own time: from its (re)start */
    const int rc = c->external->step(c->external->ctx, s->t_s - s->external_t0_s, c->Ts_s, va, vb, &out);
    if (rc != 0 || !isfinite(out.i_alpha_A) || !isfinite(out.i_beta_A) || !isfinite(out.theta_m_rad) ||
        !isfinite(out.omega_m_rad_s)) {
        s->external_error = rc != 0 ? rc : -1;
        s->tripped = true;
        return;
    }
    /* the energy integrals stay 0: they are not among the model's outputs */
    plant_machine_external_take(s, c, &out);
}
