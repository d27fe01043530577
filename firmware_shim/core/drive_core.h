/* drive_core.h - top-level PMSM current-control drive (glue).
 *
 * Timing model (You 2019 Fig. 1): the stator-frame command returned by
 * drive_current_step() at sample k is applied by the PWM over [k+1, k+2] and
 * first shows in the current sampled at k+2.
 *
 * Configuration: every field of drive_config_t (and of the nested per-block
 * configs) is a flat scalar intended to become a CANopen OD entry.  The
 * mismatch parameters R_hat_ohm, Ld_hat_H, Lq_hat_H, psi_hat_Wb, the
 * controller selection and ident.enable (tuning switch) are watched every
 * step and take effect at the next step when written; any other change
 * requires drive_apply_config() (also effective at the next step). */
#ifndef DRIVE_CORE_H
#define DRIVE_CORE_H

#include <stdbool.h>
#include <stdint.h>

#include "outer_loops.h"
#include "pi_current.h"
#include "trace_recorder.h"
#include "yao2020_dpcc.h"
#include "yao2020_identification.h"
#include "yao2020_rls.h"
#include "you2019_deadbeat.h"
#include "you2019_estimator.h"
#include "you2019_identification.h"
#include "zhao2022_incremental.h"
#include "zhao2022_predictive.h"

typedef enum {
  DRIVE_CTRL_PI = 0,
  DRIVE_CTRL_DEADBEAT_YOU2019 = 1,
  /* surface-mounted (single-inductance) controllers: L_hat = Lq_hat_H,
   * no You 2019 Eq. 4 decoupling / You 2019 estimator / dead-time compensation /
   * Eq. 33 limiter of the drive (each limits its own command radially to
   * Vmax_V); see drive_step_spm() in drive_core.c */
  DRIVE_CTRL_DPCC_YAO2020 = 2,         /* Yao 2020 DPCC + SMO + R/L ident */
  DRIVE_CTRL_INCREMENTAL_ZHAO2022 = 3, /* Zhao 2022 Eq. 22/23 */
  DRIVE_CTRL_PREDICTIVE_ZHAO2022 = 4,  /* Zhao 2022 Eq. 5/6 (baseline) */
  /* further current controllers are added here (switch in drive_core.c) */
  DRIVE_CTRL_COUNT
} drive_controller_t;

typedef enum {
  DRIVE_MODE_CURRENT = 0,
  DRIVE_MODE_SPEED = 1,
  DRIVE_MODE_POSITION = 2,
} drive_mode_t;

typedef struct {
  float Ts_s;                 /* current period, default 55e-6 */
  float pole_pairs;           /* default 5 */
  uint16_t speed_loop_divider;/* default 8 */
  uint8_t controller;         /* drive_controller_t, default DEADBEAT */
  /* controller's motor model (mismatch knobs) */
  float R_hat_ohm;            /* default 1.4 */
  float Ld_hat_H;             /* default 4.46e-3 */
  float Lq_hat_H;             /* default 4.54e-3 */
  float psi_hat_Wb;           /* default 0.042 */
  float Vmax_V;               /* You 2019 Eq. 33 radius, default 139 */
  uint8_t vlimit_radial;      /* 0: d priority (You 2019 Eq. 34), 1: radial */
  uint8_t decoupling_enable;  /* You 2019 Eq. 4 feed-forward, default 1 */
  float angle_advance_periods;/* inverse-Park angle advance in Ts, default 1.5 */
  you2019_deadbeat_config_t deadbeat;
  pi_current_config_t pi;
  you2019_estimator_config_t estimator;
  you2019_identification_config_t ident; /* ident.enable = tuning switch */
  outer_loops_config_t outer;
  /* Yao 2020 DPCC (controller DRIVE_CTRL_DPCC_YAO2020).  Its Ts_s,
   * R_hat_ohm, L_hat_H, psi_hat_Wb and Vmax_V are NOT read: the drive's
   * Ts_s, R_hat_ohm, Lq_hat_H, psi_hat_Wb and Vmax_V above are used (the
   * identification then moves the controller's own R_hat/L_hat, readable
   * in drive_t.yao). */
  yao2020_dpcc_config_t yao;
  uint8_t yao_rls_enable;     /* Yao 2020 Sec. VI-B RLS baseline beside the DPCC */
  float yao_rls_lambda;       /* RLS forgetting factor, default 0.995 */
} drive_config_t;

typedef struct {
  uint8_t mode;               /* drive_mode_t */
  float iq_ref_A;             /* current mode */
  float id_ref_A;             /* all modes */
  float speed_ref_rad_s;      /* speed mode (mechanical) */
  float position_target_rad;  /* position mode (mechanical, multi-turn) */
} drive_setpoint_t;

typedef struct {
  float i_a_A, i_b_A;         /* phase currents from the ADC */
  float theta_m_rad;          /* encoder mechanical angle */
} drive_meas_t;

typedef struct {
  float v_alpha_V, v_beta_V;  /* stator-frame command, held over [k+1,k+2] */
} drive_cmd_t;

typedef struct {
  uint32_t step_count;
  uint16_t speed_div_count;
  float theta_e_rad, omega_e_rad_s;
  float i_d_A, i_q_A;
  float iq_ref_A, id_ref_A;   /* references used in this step */
  float v_q_ff_V, v_d_ff_V;   /* You 2019 Eq. 4 */
  float v_q_V, v_d_V;         /* total dq command after You 2019 Eq. 33 */
  float v_q_star_V, v_d_star_V;/* decoupled applied command (You 2019 Eq. 35) */
  float v_alpha_V, v_beta_V;
  uint8_t v_limited;
  /* active model used for feed-forward (config or identified, You 2019 Eq. 32) */
  float Lq_active_H, Ld_active_H;
  /* Fig. 16 pipeline */
  uint8_t pending_q, pending_d;
  uint8_t est_pi_countdown;
  uint32_t n_gain_updates;
  /* cached watched config values */
  float R_hat_cache, Ld_hat_cache, Lq_hat_cache, psi_hat_cache;
  uint8_t controller_cache, tuning_cache;
  uint8_t rls_cache;          /* yao_rls_enable of the last recompute */
  uint8_t dirty;
  float signals[TRACE_SIG_COUNT];
} drive_state_t;

typedef struct {
  drive_config_t cfg;
  drive_setpoint_t sp;
  drive_state_t st;
  you2019_deadbeat_state_t db;
  pi_current_state_t pi;
  you2019_estimator_state_t est;
  you2019_identification_state_t ident;
  outer_loops_state_t outer;
  /* surface-mounted controllers (derived configs rebuilt by the recompute) */
  yao2020_dpcc_config_t yao_cfg;
  yao2020_dpcc_state_t yao;
  yao2020_dpcc_cmd_t yao_cmd;     /* last Yao 2020 command */
  yao2020_rls_config_t rls_cfg;
  yao2020_rls_state_t rls;
  zhao2022_incremental_state_t inc;
  zhao2022_predictive_state_t eul;
  trace_recorder_t *trace;    /* optional, NULL = no tracing */
} drive_t;

/* Defaults: You 2019 Table A1/A2 drive and motor. */
void drive_default_config(drive_config_t *cfg);
void drive_init(drive_t *drv, const drive_config_t *cfg);
/* Mark the configuration changed; derived gains are recomputed at the start
 * of the next drive_current_step(). */
void drive_apply_config(drive_t *drv);
void drive_attach_trace(drive_t *drv, trace_recorder_t *rec);

/* Current-period "ISR". */
void drive_current_step(drive_t *drv, const drive_meas_t *meas, drive_cmd_t *cmd);

float drive_signal(const drive_t *drv, trace_signal_t id);

/* 1 for the surface-mounted controllers (Yao 2020, Zhao 2022). */
int drive_controller_is_spm(uint8_t controller);

/* Clear the controllers' memories (open loop: the command is not theirs).
 * The Yao 2020 estimates R_hat/L_hat are kept; its observer restarts. */
void drive_reset_controller_memory(drive_t *drv);

/* Yao 2020 R/L identification (Sec. IV-E): start requires the Yao 2020
 * controller, the observer on and at least one step run with it (the speed
 * and iq reference of the last step are latched as the steady state).
 * Returns false when refused. */
bool drive_yao_ident_start(drive_t *drv);
void drive_yao_ident_abort(drive_t *drv);

#endif
