/* drive_config.h - the drive's configuration and its per-period inputs and
 * output, as every current law sees them (current_law.h).
 *
 * Every field of drive_config_t is an EDS entry of the same name (defaults and
 * ranges in protocols/eds/drive.eds).  A law's own parameters are not here:
 * they are its EDS record (current_law.h). */
#ifndef DRIVE_CONFIG_H
#define DRIVE_CONFIG_H

#include <stdint.h>

#include "od_drive_fields.h"
#include "outer_loops.h"

/* Reference modes: References.mode (0x2202:01), named in the EDS; the drive
 * app plays OD_DRIVE_MODE_OPEN_LOOP itself. */
typedef enum {
    DRIVE_MODE_CURRENT = OD_DRIVE_MODE_CURRENT,
    DRIVE_MODE_SPEED = OD_DRIVE_MODE_SPEED,
    DRIVE_MODE_POSITION = OD_DRIVE_MODE_POSITION,
} drive_mode_t;

/* The drive's configuration: 0x2200 Controller (its parameters in EDS order),
 * 0x2203 Outer loops and the profile of 0x2202 References.  The node app copies
 * the EDS records onto it with one table per record. */
typedef struct {
    uint8_t controller; /* Controller.controller: the law (current_law_find) */
    float Ts_s;         /* current period */
    uint16_t speed_loop_divider;
    /* controller's motor model (mismatch knobs) */
    float R_hat_ohm;
    float Ld_hat_H;
    float Lq_hat_H;
    float psi_hat_Wb;
    float pole_pairs;
    float Vmax_V;                /* radius of the voltage limit */
    float J_hat_kgm2;            /* outer loops */
    uint8_t vlimit_radial;       /* 0: d priority, 1: radial */
    float angle_advance_periods; /* inverse-Park angle advance in Ts */
    outer_loops_config_t outer;  /* 0x2203 Outer loops, and the profile of 0x2202 */
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

#endif
