/*
 * pmsm_plant.c - PMSM plant emulator core: the public API (pmsm_plant.h) as
 * glue of its three blocks, machine (plant_machine.c), inverter
 * (plant_inverter.c) and sensors (plant_sensors.c), plus the defaults and
 * the validation of the configuration.
 *
 * Only <math.h>/<string.h>/<stdint.h>/<stdbool.h>/<stddef.h>: no OS, no heap,
 * no stdio; time is the step counter k (t = k*Ts).
 */
#include "pmsm_plant.h"

#include <math.h>
#include <string.h>

#include "dq_linear/dq_linear.h"
#include "external/external.h"
#include "plant_angle.h"
#include "plant_inverter.h"
#include "plant_machine.h"
#include "plant_models.h"
#include "plant_sensors.h"

/* ===================================================================== */
/* defaults                                                              */
/* ===================================================================== */

void plant_config_ideal(plant_config_t *c)
{
    c->sat_enable = false;
    c->mod_limit = PLANT_MOD_NONE;
    c->t_dead_s = 0.0;
    c->hold_frame = PLANT_HOLD_STATOR;
    c->adc_lsb_A = 0.0;
    c->adc_offset_a_A = 0.0;
    c->adc_offset_b_A = 0.0;
    c->adc_noise_std_A = 0.0;
    c->adc_full_scale_A = 0.0;
    c->encoder_lines = 0u;
    c->I_trip_A = 0.0;
}

void plant_config_defaults(plant_config_t *c)
{
    memset(c, 0, sizeof(*c));
    c->Ts_s = 100e-6;
    c->R_ohm = 1.0;
    c->Ld_H = 1e-3;
    c->Lq_H = 1e-3;
    c->psi_Wb = 0.01;
    c->pole_pairs = 1;
    c->sat_I_A = 1.0;         /* only used when sat_enable */
    c->sat_Lq_inf_H = 0.5e-3; /* only used when sat_enable */
    c->mech_mode = PLANT_MECH_LOCKED;
    c->J_kgm2 = 1e-4;
    c->B_Nm_per_rad_s = 0.0;
    c->T_load_Nm = 0.0;
    c->omega_imposed_rad_s = 0.0;
    c->Vdc_V = 48.0;
    c->Ts_pwm_s = 0.0;
    c->deadtime_I_sat_A = 0.3;
    c->rng_seed = UINT64_C(0x5EED);
    c->rk4_h_rel = 0.02;
    c->rk4_min_substeps = 1u;
    c->model = PLANT_MODEL_DQ_LINEAR;
    c->flux_map = NULL;
    c->T_ref_degC = 20.0;
    c->T_amb_degC = 20.0;
    /* the machine models' own records at the EDS's defaults */
#define PLANT_MODEL_DEFAULT(index, sub, record, field, eds_default) c->params.record.field = eds_default;
#define PLANT_MODEL_DEFAULTS(name, type, record, index, fields) fields(PLANT_MODEL_DEFAULT)
    OD_PLANT_MODEL_RECORDS(PLANT_MODEL_DEFAULTS)
#undef PLANT_MODEL_DEFAULTS
#undef PLANT_MODEL_DEFAULT
    plant_config_ideal(c);
}

/* ===================================================================== */
/* init / prepare                                                         */
/* ===================================================================== */

void plant_init(plant_state_t *s, const plant_config_t *c)
{
    memset(s, 0, sizeof(*s));
    s->cos_e = 1.0;
    s->sin_e = 0.0;
    if (c != NULL) {
        s->T_winding_degC = c->T_amb_degC;
        s->R_winding_ohm = c->R_ohm;
    }
    if (c == NULL) {
        s->status = PLANT_ERR_NULL;
        return;
    }
    plant_rng_seed(&s->rng, c->rng_seed);
    (void)plant_prepare(s, c);
    plant_energy_reset(s, c);
}

static int validate_inverter(const plant_config_t *c);
static int validate_model(const plant_config_t *c);

/* Every value finite, the timing, the motor and the mechanics, then the inverter's (validate_inverter). */
static int validate(const plant_config_t *c)
{
    const double vals[] = {c->Ts_s,
                           c->R_ohm,
                           c->Ld_H,
                           c->Lq_H,
                           c->psi_Wb,
                           c->sat_I_A,
                           c->sat_Lq_inf_H,
                           c->J_kgm2,
                           c->B_Nm_per_rad_s,
                           c->T_load_Nm,
                           c->omega_imposed_rad_s,
                           c->Vdc_V,
                           c->t_dead_s,
                           c->Ts_pwm_s,
                           c->deadtime_I_sat_A,
                           c->adc_lsb_A,
                           c->adc_offset_a_A,
                           c->adc_offset_b_A,
                           c->adc_noise_std_A,
                           c->adc_full_scale_A,
                           c->I_trip_A,
                           c->rk4_h_rel,
                           c->R_alpha_per_K,
                           c->T_ref_degC,
                           c->T_amb_degC,
                           c->thermal_R_K_per_W,
                           c->thermal_C_J_per_K};
    for (size_t i = 0; i < sizeof(vals) / sizeof(vals[0]); ++i) {
        if (!isfinite(vals[i])) {
            return PLANT_ERR_NONFINITE;
        }
    }
    if (!(c->Ts_s > 0.0)) {
        return PLANT_ERR_TS;
    }
    if (c->R_ohm < 0.0) {
        return PLANT_ERR_R;
    }
    if (!(c->Ld_H > 0.0) || !(c->Lq_H > 0.0)) {
        return PLANT_ERR_L;
    }
    if (c->pole_pairs < 1) {
        return PLANT_ERR_POLES;
    }
    if (c->psi_Wb < 0.0) {
        return PLANT_ERR_PSI;
    }
    if (c->mech_mode != PLANT_MECH_FREE && c->mech_mode != PLANT_MECH_LOCKED &&
        c->mech_mode != PLANT_MECH_IMPOSED_SPEED) {
        return PLANT_ERR_MECH;
    }
    if (c->B_Nm_per_rad_s < 0.0 || c->J_kgm2 < 0.0 || (c->mech_mode == PLANT_MECH_FREE && !(c->J_kgm2 > 0.0))) {
        return PLANT_ERR_MECH;
    }
    return validate_inverter(c);
}

/* The inverter's and the sensors' settings, then the model's (validate_model). */
static int validate_inverter(const plant_config_t *c)
{
    if (c->mod_limit != PLANT_MOD_NONE && c->mod_limit != PLANT_MOD_SVPWM_HEX && c->mod_limit != PLANT_MOD_CIRCLE) {
        return PLANT_ERR_ENUM;
    }
    if (c->hold_frame != PLANT_HOLD_STATOR && c->hold_frame != PLANT_HOLD_ROTOR) {
        return PLANT_ERR_ENUM;
    }
    if (c->Vdc_V < 0.0 || ((c->mod_limit != PLANT_MOD_NONE || c->t_dead_s > 0.0) && !(c->Vdc_V > 0.0))) {
        return PLANT_ERR_VDC;
    }
    if (c->t_dead_s < 0.0 || c->Ts_pwm_s < 0.0 || c->deadtime_I_sat_A < 0.0) {
        return PLANT_ERR_DEADTIME;
    }
    if (c->t_dead_s > 0.0) {
        const double Tpwm = (c->Ts_pwm_s > 0.0) ? c->Ts_pwm_s : c->Ts_s;
        if (!(c->t_dead_s < Tpwm)) {
            return PLANT_ERR_DEADTIME;
        }
    }
    if (c->sat_enable && (!(c->sat_I_A > 0.0) || !(c->sat_Lq_inf_H > 0.0) || c->sat_Lq_inf_H > c->Lq_H)) {
        return PLANT_ERR_SAT;
    }
    if (c->adc_lsb_A < 0.0 || c->adc_noise_std_A < 0.0 || c->adc_full_scale_A < 0.0 || c->encoder_lines > 100000000u) {
        return PLANT_ERR_SENSOR;
    }
    if (c->I_trip_A < 0.0) {
        return PLANT_ERR_TRIP;
    }
    return validate_model(c);
}

/* The trip reaction, the numerics and the chosen model: registered, its own checks, the thermal model's. */
static int validate_model(const plant_config_t *c)
{
    const plant_model_desc_t *model = plant_model_find(c->model);
    if (c->trip_reaction != PLANT_TRIP_ACTIVE_SHORT_CIRCUIT &&
        (c->trip_reaction != PLANT_TRIP_PULSES_OFF || !(c->Vdc_V > 0.0) ||
         (model != NULL && model->step_bridge == NULL))) {
        return PLANT_ERR_REACTION; /* the diodes clamp to Vdc; a model holding one voltage a period cannot follow */
    }
    if (!(c->rk4_h_rel > 0.0) || c->rk4_h_rel > 1.0) {
        return PLANT_ERR_RK4;
    }
    if (model == NULL) {
        return PLANT_ERR_ENUM; /* not a registered model (plant_models.c) */
    }
    if (model->validate != NULL) {
        const int rc = model->validate(c);
        if (rc != PLANT_OK) {
            return rc;
        }
    }
    if (c->R_alpha_per_K < 0.0 || c->thermal_R_K_per_W < 0.0 || c->thermal_C_J_per_K < 0.0) {
        return PLANT_ERR_THERMAL;
    }
    if (!(1.0 + c->R_alpha_per_K * (c->T_amb_degC - c->T_ref_degC) > 0.0)) {
        return PLANT_ERR_THERMAL; /* R would not be positive at the ambient */
    }
    if (!model->thermal && (c->R_alpha_per_K != 0.0 || c->thermal_C_J_per_K != 0.0)) {
        return PLANT_ERR_THERMAL; /* the model keeps R constant (dq_linear's exact path): no thermal model */
    }
    return PLANT_OK;
}

int plant_prepare(plant_state_t *s, const plant_config_t *c)
{
    if (s == NULL) {
        return PLANT_ERR_NULL;
    }
    if (c == NULL) {
        s->status = PLANT_ERR_NULL;
        return s->status;
    }
    int rc = validate(c);
    if (rc == PLANT_OK) {
        plant_inverter_prepare(s, c);
        rc = plant_machine_prepare(s, c);
    }
    if (rc != PLANT_OK) {
        s->model = NULL; /* a refused configuration has no model: nothing steps (status) */
    }
    s->status = rc;
    return rc;
}

/* ===================================================================== */
/* helpers                                                                */
/* ===================================================================== */

void plant_clear_trip(plant_state_t *s)
{
    if (s->external_error == 0) { /* a failed external model is not stepped again: its trip stays */
        s->tripped = false;
        s->bridge.active = false; /* the next trip takes its diodes' state from the currents again */
    }
}

int plant_external_restart(plant_state_t *s, const plant_config_t *c)
{
    if (c->model != PLANT_MODEL_EXTERNAL || c->external == NULL || c->external->restart == NULL) {
        return 0;
    }
    plant_external_out_t out;
    const int rc = c->external->restart(c->external->ctx, &out);
    s->external_error = rc;
    s->external_t0_s = s->t_s;
    if (rc == 0) {
        external_take(s, c, &out);
    } else {
        s->tripped = true;
    }
    return rc;
}

void plant_set_currents(plant_state_t *s, double id_A, double iq_A)
{
    s->id_A = id_A;
    s->iq_A = iq_A;
    s->psi_stale = true;      /* the flux-map model takes its fluxes from these currents */
    s->bridge.active = false; /* and a bridge with its pulses off its diodes' state */
}

void plant_set_mech(plant_state_t *s, const plant_config_t *c, double theta_m_rad, double omega_m_rad_s)
{
    plant_machine_set_mech(s, c, theta_m_rad, omega_m_rad_s);
}

double plant_torque_Nm(const plant_state_t *s, const plant_config_t *c) { return plant_machine_torque_Nm(s, c); }

double plant_psi_q_Wb(const plant_config_t *c, double iq_A) { return dq_linear_psi_q_Wb(c, iq_A); }

double plant_Lq_inc_H(const plant_config_t *c, double iq_A) { return dq_linear_Lq_inc_H(c, iq_A); }

double plant_magnetic_energy_J(const plant_state_t *s, const plant_config_t *c)
{
    return plant_machine_magnetic_energy_J(s, c);
}

double plant_kinetic_energy_J(const plant_state_t *s, const plant_config_t *c)
{
    return plant_machine_kinetic_energy_J(s, c);
}

void plant_energy_reset(plant_state_t *s, const plant_config_t *c) { plant_machine_energy_reset(s, c); }

double plant_energy_residual_J(const plant_state_t *s, const plant_config_t *c)
{
    return plant_machine_energy_residual_J(s, c);
}

double plant_deadtime_phase_error_V(const plant_config_t *c, double i_phase_A)
{
    return plant_inverter_deadtime_phase_error_V(c, i_phase_A);
}

void plant_modulation_limit(const plant_config_t *c, double *v_alpha_V, double *v_beta_V)
{
    plant_inverter_modulation_limit(c, v_alpha_V, v_beta_V);
}

/* ===================================================================== */
/* step / sample                                                          */
/* ===================================================================== */

void plant_step(plant_state_t *s, const plant_config_t *c, double v_alpha_V, double v_beta_V)
{
    if (s->status != PLANT_OK) {
        return;
    }
    double ia, ib, ic;
    plant_angle_phase_currents(s, &ia, &ib, &ic); /* at the start of the period */
    plant_inverter_check_trip(s, c, ia, ib, ic);
    plant_inverter_step(s, c, v_alpha_V, v_beta_V, ia, ib, ic);
    if (s->tripped && c->trip_reaction == PLANT_TRIP_PULSES_OFF) {
        plant_machine_step_bridge(s, c); /* the diodes' voltage; v_app_* its mean over the period */
    } else {
        s->bridge.active = false;
        plant_machine_step(s, c, s->v_app_alpha_V, s->v_app_beta_V);
    }
    s->k++;
    s->t_s = (double)s->k * c->Ts_s;
    plant_angle_phase_currents(s, &ia, &ib, &ic); /* at its end */
    plant_inverter_check_trip(s, c, ia, ib, ic);
}

void plant_sample(plant_state_t *s, const plant_config_t *c, plant_meas_t *m)
{
    double ial, ibe, ia, ib, ic;
    plant_angle_alpha_beta(s, &ial, &ibe);
    plant_angle_abc(ial, ibe, &ia, &ib, &ic);
    m->i_a_true_A = ia;
    m->i_b_true_A = ib;
    m->i_c_true_A = ic;
    m->i_alpha_A = ial;
    m->i_beta_A = ibe;
    m->id_A = s->id_A;
    m->iq_A = s->iq_A;
    m->theta_m_true_rad = s->theta_m_rad;
    m->theta_e_rad = fmod((double)c->pole_pairs * s->theta_m_rad, PLANT_TWO_PI);
    m->omega_m_rad_s = s->omega_m_rad_s;
    m->torque_Nm = plant_machine_torque_Nm(s, c);
    m->t_s = s->t_s;
    m->k = s->k;
    m->tripped = s->tripped;

    plant_sensors_sample(&s->rng, c, ia, ib, s->theta_m_rad, m);
}
