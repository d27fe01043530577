/* yao2020_identification.h - Yao 2020 online R/L identification (Sec. IV,
 * Eq. 22-45, Table III) for the DPCC of yao2020_dpcc.h: the
 * reconstructed characteristic vector M = F^-1 p_hat (Eq. 22-29),
 * negative d-axis current injection, integral estimators with dead zones
 * (Eq. 30-45); L first, then R.
 *
 * Its configuration and state are part of yao2020_dpcc_config_t and
 * yao2020_dpcc_state_t (the estimates R_hat/L_hat are the controller's
 * model), i.e. of yao2020_model_config_t and yao2020_model_state_t: the same
 * types, defined in yao2020_model.h so that this header does not include
 * yao2020_dpcc.h; yao2020_dpcc_step() runs yao2020_identification_update() every
 * period after the observer.  The enums below are the values of the uint8_t
 * fields gain_select, id_state, abort_reason and motor_class. */
#ifndef YAO2020_IDENTIFICATION_H
#define YAO2020_IDENTIFICATION_H

#include <stdbool.h>
#include <stdint.h>

#include "yao2020_model.h"

/* Motor class of Yao 2020 Definitions 1 and 2 (Eq. 30-31). */
typedef enum {
    YAO2020_IDENTIFICATION_MOTOR_LOW_FREQ = 0,  /* Yao 2020 Eq. 30 holds */
    YAO2020_IDENTIFICATION_MOTOR_HIGH_FREQ = 1, /* Yao 2020 Eq. 31 holds */
    YAO2020_IDENTIFICATION_MOTOR_NEITHER = 2,   /* neither definition holds */
} yao2020_identification_motor_class_t;

/* Gain-set selection of the identification. */
typedef enum {
    /* cos(wT) >= 0.98 -> low-frequency gains, else high */
    YAO2020_IDENTIFICATION_GAINS_AUTO = 0,
    YAO2020_IDENTIFICATION_GAINS_LOW = 1,
    YAO2020_IDENTIFICATION_GAINS_HIGH = 2,
} yao2020_identification_gain_select_t;

/* Identification sequence. */
typedef enum {
    YAO2020_IDENTIFICATION_IDLE = 0,
    /* base id, wait then capture M(t0) (Yao 2020 Eq. 24) */
    YAO2020_IDENTIFICATION_PRE_L = 1,
    /* id = base + inj, integrate L_hat on dM_q (Fig. 9a) */
    YAO2020_IDENTIFICATION_INJECT_L = 2,
    YAO2020_IDENTIFICATION_PRE_R = 3, /* back to base id, wait then capture M(t0) */
    /* id = base + inj, integrate R_hat on dM_d (Fig. 9b) */
    YAO2020_IDENTIFICATION_INJECT_R = 4,
    YAO2020_IDENTIFICATION_POST = 5, /* back to base id, wait */
    YAO2020_IDENTIFICATION_DONE = 6,
    YAO2020_IDENTIFICATION_ABORTED = 7,
} yao2020_identification_phase_t;

typedef enum {
    YAO2020_IDENTIFICATION_ABORT_NONE = 0,
    /* |w - w_start| > steady_tol_w_rad_s */
    YAO2020_IDENTIFICATION_ABORT_SPEED_CHANGED = 1,
    /* |iq_ref - iq_ref_start| > steady_tol_iq_A */
    YAO2020_IDENTIFICATION_ABORT_IQ_CHANGED = 2,
    /* |w| < min_speed_rad_s (dM_q ~ w dL) */
    YAO2020_IDENTIFICATION_ABORT_LOW_SPEED = 3,
    YAO2020_IDENTIFICATION_ABORT_USER = 4,
} yao2020_identification_abort_reason_t;

/* Yao 2020 Definitions 1-2 (Eq. 30-31). */
yao2020_identification_motor_class_t yao2020_identification_classify(float R_ohm, float L_H, float w_rad_s, float Ts_s);

/* Identification commands.  start: from IDLE/DONE/ABORTED, requires steady
 * speed and iq reference (checked every period while running; a change
 * aborts and restores the R_hat/L_hat held at the start). */
bool yao2020_identification_start(const yao2020_model_config_t *cfg, yao2020_model_state_t *st);
void yao2020_identification_abort(yao2020_model_state_t *st);
bool yao2020_identification_running(const yao2020_model_state_t *st);
/* 0..1: completed phases / total phases of the sequence. */
float yao2020_identification_progress(const yao2020_model_config_t *cfg, const yao2020_model_state_t *st);
/* Converged values (true when the sequence is DONE). */
bool yao2020_identification_result(const yao2020_model_state_t *st, float *R_ohm, float *L_H);

/* Identification update of one period (state machine + Yao 2020 Eq. 22-45
 * estimator), called by yao2020_dpcc_step() after the observer; public for the
 * perf tool.
 * Uses st->p_hat, st->m, st->v_app and the measured current; updates
 * R_hat/L_hat (effective from the next step) and st->id_inj_A. */
void yao2020_identification_update(const yao2020_model_config_t *cfg, yao2020_model_state_t *st, float iq_ref_A,
                                   float id_A, float iq_A, float w_rad_s);

#endif
