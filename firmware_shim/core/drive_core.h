/* drive_core.h - top-level PMSM current-control drive (glue).
 *
 * Timing model (You 2019 Fig. 1): the stator-frame command returned by
 * drive_current_step() at sample k is applied by the PWM over [k+1, k+2] and
 * first shows in the current sampled at k+2.
 *
 * Configuration: every field of drive_config_t is an EDS entry of the same
 * name (defaults and ranges in protocols/eds/drive.eds).  One path for a
 * change: write the fields, drive_config_check() them, drive_apply_config();
 * the change takes effect at the next step. */
#ifndef DRIVE_CORE_H
#define DRIVE_CORE_H

#include <stdbool.h>
#include <stdint.h>

#include "outer_loops.h"
#include "pi_current.h"
#include "trace_recorder.h"
#include "od_drive_fields.h"
#include "yao2020_dpcc.h"
#include "yao2020_identification.h"
#include "yao2020_rls.h"
#include "you2019_deadbeat.h"
#include "you2019_estimator.h"
#include "you2019_identification.h"
#include "zhao2022_incremental.h"
#include "zhao2022_predictive.h"

/* Controller kinds: the values of Controller.controller (0x2200:01), named in
 * the EDS (ValueNames) and generated into od_drive_fields.h; 0 is the drive
 * app's open loop, which the core does not run. */
typedef enum {
    DRIVE_CTRL_PI = OD_DRIVE_CONTROLLER_PI,
    DRIVE_CTRL_DEADBEAT_YOU2019 = OD_DRIVE_CONTROLLER_DEADBEAT_YOU2019,
    /* surface-mounted (single-inductance) controllers: L_hat = Lq_hat_H,
     * no You 2019 Eq. 4 decoupling / You 2019 estimator / dead-time compensation /
     * You 2019 Eq. 33 limiter of the drive (each limits its own command radially to
     * Vmax_V); see drive_step_spm() in drive_core.c */
    DRIVE_CTRL_DPCC_YAO2020 = OD_DRIVE_CONTROLLER_DPCC_YAO2020,                 /* Yao 2020 DPCC + SMO + R/L ident */
    DRIVE_CTRL_INCREMENTAL_ZHAO2022 = OD_DRIVE_CONTROLLER_INCREMENTAL_ZHAO2022, /* Zhao 2022 Eq. 22/23 */
    DRIVE_CTRL_PREDICTIVE_ZHAO2022 = OD_DRIVE_CONTROLLER_PREDICTIVE_ZHAO2022,   /* Zhao 2022 Eq. 5/6 (baseline) */
    /* further current controllers: a value in the EDS, a case in drive_core.c */
} drive_controller_t;

/* 1 for a controller the core runs. */
int drive_controller_exists(uint8_t controller);

/* Reference modes: References.mode (0x2202:01), named in the EDS; the drive
 * app plays OD_DRIVE_MODE_OPEN_LOOP itself. */
typedef enum {
    DRIVE_MODE_CURRENT = OD_DRIVE_MODE_CURRENT,
    DRIVE_MODE_SPEED = OD_DRIVE_MODE_SPEED,
    DRIVE_MODE_POSITION = OD_DRIVE_MODE_POSITION,
} drive_mode_t;

/* The drive's configuration: every field carries the name of its EDS entry
 * (protocols/eds/drive.eds), which is also where its default and range are
 * written (drive_default_config takes the defaults from od_drive_fields.h).
 * The node app copies the EDS records onto it with one table per record. */
typedef struct {
    /* 0x2200 Controller, its parameters in EDS order */
    uint8_t controller; /* drive_controller_t */
    float Ts_s;         /* current period */
    uint16_t speed_loop_divider;
    /* controller's motor model (mismatch knobs) */
    float R_hat_ohm;
    float Ld_hat_H;
    float Lq_hat_H;
    float psi_hat_Wb;
    float pole_pairs;
    float Vmax_V;                 /* You 2019 Eq. 33 radius */
    float pi_bandwidth_Hz;        /* PI baseline */
    uint8_t limited_memory;       /* you2019_deadbeat_memory_t */
    uint8_t deadtime_comp_enable; /* You 2019 Eq. 7, on the estimated currents */
    float deadtime_comp_V;
    float deadtime_comp_I_sat_A;
    float estimator_bandwidth_Hz; /* You 2019 Sec. 3.2 */
    float J_hat_kgm2;             /* outer loops */
    uint8_t vlimit_radial;        /* 0: d priority (You 2019 Eq. 34), 1: radial */
    uint8_t decoupling_enable;    /* You 2019 Eq. 4 feed-forward */
    float angle_advance_periods;  /* inverse-Park angle advance in Ts */
    uint8_t estimator_enable;
    you2019_identification_config_t ident; /* 0x2201 Online tuning (enable = tuning switch) */
    outer_loops_config_t outer;            /* 0x2203 Outer loops, and the profile of 0x2202 */
    /* 0x2206 Yao 2020 DPCC (controller DRIVE_CTRL_DPCC_YAO2020).  Its Ts_s,
     * R_hat_ohm, L_hat_H, psi_hat_Wb and Vmax_V are NOT read: the drive's
     * Ts_s, R_hat_ohm, Lq_hat_H, psi_hat_Wb and Vmax_V above are used (the
     * identification then moves the controller's own R_hat/L_hat, readable
     * in drive_t.yao). */
    yao2020_dpcc_config_t yao;
} drive_config_t;

typedef struct {
    uint8_t mode;           /* drive_mode_t */
    float iq_ref_A;         /* current mode */
    float id_ref_A;         /* all modes */
    float speed_ref_rad_s;  /* speed mode (mechanical) */
    float position_ref_rad; /* position mode (mechanical, multi-turn) */
} drive_setpoint_t;

typedef struct {
    float i_a_A, i_b_A; /* phase currents from the ADC */
    float theta_m_rad;  /* encoder mechanical angle */
} drive_meas_t;

typedef struct {
    float v_alpha_V, v_beta_V; /* stator-frame command, held over [k+1,k+2] */
} drive_cmd_t;

typedef struct {
    uint32_t step_count;
    uint16_t speed_div_count;
    float theta_e_rad, omega_e_rad_s;
    float i_d_A, i_q_A;
    float iq_ref_A, id_ref_A;     /* references used in this step */
    float v_q_ff_V, v_d_ff_V;     /* You 2019 Eq. 4 */
    float v_q_V, v_d_V;           /* total dq command after You 2019 Eq. 33 */
    float v_q_star_V, v_d_star_V; /* decoupled applied command (You 2019 Eq. 35) */
    float v_alpha_V, v_beta_V;
    uint8_t v_limited;
    /* active model used for feed-forward (config or identified, You 2019 Eq. 32) */
    float Lq_active_H, Ld_active_H;
    /* Fig. 16 pipeline */
    uint8_t pending_q, pending_d;
    uint8_t est_pi_countdown;
    uint32_t n_gain_updates;
    /* cached watched config values */
    /* values of the last recompute (what a new configuration changes) */
    float R_hat_cache, Lq_hat_cache;
    uint8_t controller_cache;
    uint8_t rls_cache; /* yao_rls_enable of the last recompute */
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
    yao2020_dpcc_cmd_t yao_cmd; /* last Yao 2020 command */
    yao2020_rls_config_t rls_cfg;
    yao2020_rls_state_t rls;
    zhao2022_incremental_state_t inc;
    zhao2022_predictive_state_t eul;
    trace_recorder_t *trace; /* optional, NULL = no tracing */
} drive_t;

/* Defaults: You 2019 Table A1/A2 drive and motor. */
void drive_default_config(drive_config_t *cfg);
void drive_init(drive_t *drv, const drive_config_t *cfg);
/* Mark the configuration changed; derived gains are recomputed at the start
 * of the next drive_current_step(). */
void drive_apply_config(drive_t *drv);

/* Verdict on a configuration: the cross-field rules (a single field's range is
 * the EDS's).  c->controller may be 0, the drive app's open loop; mode is the
 * reference mode (OD_DRIVE_MODE_*). */
typedef enum {
    DRIVE_CONFIG_OK = 0,
    DRIVE_CONFIG_NO_SUCH_CONTROLLER, /* a controller value the core does not run */
    DRIVE_CONFIG_INCOMPATIBLE,       /* fields that contradict each other */
} drive_config_verdict_t;
drive_config_verdict_t drive_config_check(const drive_config_t *c, uint8_t mode);
/* Selecting a surface-mounted law (one inductance, Lq_hat_H) needs a
 * non-salient model: |Ld_hat_H - Lq_hat_H| <= 5 % of Lq_hat_H. */
drive_config_verdict_t drive_config_check_selection(const drive_config_t *c);
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
