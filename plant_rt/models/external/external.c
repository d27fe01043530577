/*
 * external.c - the external machine model (Motor model.model = fmu; its descriptor plant_model_external,
 * plant_model.h; plant_external_t in plant_types.h; an FMU: plant_rt/fmu/): one period through the
 * caller's step, the plant's state (rotor-frame currents, angle, speed) from its stator-frame outputs.  A model
 * that fails is not stepped again: the plant latches its trip (the inverter applies 0 V) and keeps the state
 * the model last gave.
 *
 * Only <math.h>: no OS, no heap, no stdio.
 */
#include <math.h>

#include "external.h"
#include "plant_angle.h"

void external_take(plant_state_t *s, const plant_config_t *c, const plant_external_out_t *out)
{
    /* the model's angle may wrap or not: whole turns counted from the change of the wrapped angle */
    const double th = plant_angle_wrap_2pi(out->theta_m_rad, NULL);
    const double d = th - s->theta_m_rad;
    if (d < -0.5 * PLANT_TWO_PI) {
        ++s->revolutions;
    } else if (d > 0.5 * PLANT_TWO_PI) {
        --s->revolutions;
    }
    s->theta_m_rad = th;
    s->omega_m_rad_s = out->omega_m_rad_s;
    plant_angle_resync(s, c);
    /* Park: the rotor-frame currents of the model's stator-frame ones */
    s->id_A = s->cos_e * out->i_alpha_A + s->sin_e * out->i_beta_A;
    s->iq_A = -s->sin_e * out->i_alpha_A + s->cos_e * out->i_beta_A;
}

static void external_step(plant_state_t *s, const plant_config_t *c, double va, double vb, double vd0, double vq0)
{
    (void)vd0;
    (void)vq0;
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
    external_take(s, c, &out);
}

static int external_validate(const plant_config_t *c)
{
    return (c->external == NULL || c->external->step == NULL) ? PLANT_ERR_EXTERNAL : PLANT_OK;
}

static int external_prepare(plant_state_t *s, const plant_config_t *c, double p)
{
    (void)p;
    plant_model_fixed_winding(s, c); /* 0x2005's status on a model without a thermal model */
    s->exact = false;                /* the model is the caller's: its speed and angle come from its outputs */
    return PLANT_OK;
}

static double external_zero(const plant_state_t *s, const plant_config_t *c)
{
    (void)s;
    (void)c;
    return 0.0; /* the torque and the stored energy are not among the model's outputs */
}

const plant_model_desc_t plant_model_external = {
    .id = OD_PLANT_MODEL_FMU,
    .name = "fmu",
    .thermal = false,
    .validate = external_validate,
    .prepare = external_prepare,
    .step = external_step,
    .step_bridge = NULL, /* one held voltage a period: it cannot follow the diodes */
    .torque_Nm = external_zero,
    .magnetic_energy_J = external_zero,
};
