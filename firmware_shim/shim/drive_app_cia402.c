/* drive_app_cia402.c - the CiA 402 glue of the drive app (drive_app.h; cia402_device.h for the state
 * machine): controlword, statusword, the references of the modes, the actual values (0x6xxx).
 * Portable: no OS headers, no allocation, float32. */
#include "drive_app_internal.h"

/* ------------------------------------------------------------------ CiA 402 (drive_app.h) */

#define CIA402_INC_PER_RAD 10430.378f          /* 65536 increments per mechanical revolution / (2 pi) */
#define CIA402_STOPPED_FRACTION_OF_RATED 0.02f /* quick stop done: |iq| <= 2 % of 0x6075 */

int drive_app_pdo_maps(const co_pdo_t *p, uint16_t index)
{
    for (uint8_t i = 0; i < p->count; ++i)
        if (p->entry[i] != NULL && p->entry[i]->index == index) return 1;
    return 0;
}

/* Every valid event-driven TPDO that maps the statusword or the mode shown goes out (state and mode
 * changes, NMT start). */
void drive_app_send_statusword(co_node_t *node)
{
    for (uint8_t n = 0; n < CO_NUM_PDO; ++n) {
        const co_pdo_t *p = &node->tpdo[n];
        if (p->valid && p->trans_type >= 254u &&
            (drive_app_pdo_maps(p, OD_DRIVE_STATUSWORD_IDX) ||
             drive_app_pdo_maps(p, OD_DRIVE_MODES_OF_OPERATION_DISPLAY_IDX)))
            co_tpdo_request(node, n);
    }
}

/* The state changed: the statusword follows; a power stage switched off commands 0 V at once. */
void drive_app_cia402_changed(drive_app_t *app, co_node_t *node, int was_powered)
{
    od_drive_mfr_t *m = mfr_of(node);
    m->x6041_Statusword = cia402_device_statusword(&app->cia402);
    if (was_powered && !cia402_device_power_enabled(&app->cia402)) {
        drive_app_clear_control_memory(&app->drv);
        drive_app_zero_voltage(&app->drv);
        app->cmd.v_alpha_V = 0.0f;
        app->cmd.v_beta_V = 0.0f;
        m->x2102_voltage_command.v_alpha_V = 0.0f;
        m->x2102_voltage_command.v_beta_V = 0.0f;
        co_tpdo_request(node, 0);
    }
    drive_app_send_statusword(node);
}

/* A controlword arrived (SDO or RPDO). */
void drive_app_cia402_on_controlword(drive_app_t *app, co_node_t *node)
{
    const int was_powered = cia402_device_power_enabled(&app->cia402);
    const uint8_t before = app->cia402.state;
    if (!cia402_device_controlword(&app->cia402, mfr_of(node)->x6040_Controlword, !drive_app_heartbeat_lost(node)))
        return;
    /* transition 15 (the device is already in SWITCH ON DISABLED): the fault reset clears the safe state
     * and its EMCY first, then the statusword goes out like at any other state change */
    if (before == (uint8_t)CIA402_FAULT) drive_app_leave_safe_state(app, node);
    drive_app_cia402_changed(app, node, was_powered);
}

void drive_app_cia402_reset(drive_app_t *app, co_node_t *node)
{
    od_drive_mfr_t *m = mfr_of(node);
    const cia402_config_t cfg = {.quick_stop_option = m->x605A_quick_stop_option_code};
    cia402_device_init(&app->cia402, &cfg);
    m->x6041_Statusword = cia402_device_statusword(&app->cia402);
    m->x6061_modes_of_operation_display = m->x6060_modes_of_operation;
    m->x603F_error_code = 0u;
}

/* The references of this step in the CiA 402 modes (the manufacturer mode -1 keeps 0x2202's):
 * returns 0 when the step commands 0 V (no mode, or the power stage off). */
int drive_app_cia402_references(drive_app_t *app, const od_drive_mfr_t *m)
{
    drive_t *d = &app->drv;
    if (!cia402_device_power_enabled(&app->cia402)) return 0;
    if (app->cia402.state == (uint8_t)CIA402_QUICK_STOP_ACTIVE) {
        d->sp.mode = (uint8_t)DRIVE_MODE_CURRENT; /* quick stop: the current to zero */
        d->sp.iq_ref_A = 0.0f;
        d->sp.id_ref_A = 0.0f;
        return 1;
    }
    switch (m->x6061_modes_of_operation_display) {
    case CIA402_MODE_CST: {
        const float Kt_Nm_A = 1.5f * d->cfg.pole_pairs * d->cfg.psi_hat_Wb;
        int32_t t = m->x6071_target_torque;
        const int32_t tmax = (int32_t)m->x6072_max_torque;
        if (t > tmax) t = tmax;
        if (t < -tmax) t = -tmax;
        const float T_Nm = (float)t * 1e-3f * (float)m->x6076_motor_rated_torque * 1e-3f;
        d->sp.mode = (uint8_t)DRIVE_MODE_CURRENT;
        d->sp.iq_ref_A = Kt_Nm_A > 0.0f ? T_Nm / Kt_Nm_A : 0.0f;
        d->sp.id_ref_A = 0.0f;
        return 1;
    }
    case CIA402_MODE_MANUFACTURER_CURRENT: return 1;
    default: return 0; /* 0: no mode */
    }
}

static int16_t per_mille(float value, float rated)
{
    if (!(rated > 0.0f)) return 0;
    float x = 1000.0f * value / rated;
    if (!is_finite_f(x)) return 0;
    if (x > 32767.0f) x = 32767.0f;
    if (x < -32768.0f) x = -32768.0f;
    return (int16_t)x;
}

static int32_t increments(float rad)
{
    float x = rad * CIA402_INC_PER_RAD;
    if (!is_finite_f(x)) return 0;
    if (x > 2147483520.0f) x = 2147483520.0f; /* the largest float below 2^31 */
    if (x < -2147483648.0f) x = -2147483648.0f;
    return (int32_t)x;
}

void drive_app_cia402_refresh(const drive_app_t *app, od_drive_mfr_t *m, uint16_t index)
{
    const drive_t *d = &app->drv;
    switch (index) {
    case OD_DRIVE_STATUSWORD_IDX: m->x6041_Statusword = cia402_device_statusword(&app->cia402); break;
    case OD_DRIVE_POSITION_ACTUAL_VALUE_IDX:
        m->x6064_position_actual_value = increments(d->outer.theta_unwrapped_rad);
        break;
    case OD_DRIVE_VELOCITY_ACTUAL_VALUE_IDX: m->x606C_velocity_actual_value = increments(d->outer.omega_m_rad_s); break;
    case OD_DRIVE_TORQUE_ACTUAL_VALUE_IDX:
        m->x6077_torque_actual_value = per_mille(1.5f * d->cfg.pole_pairs * d->cfg.psi_hat_Wb * d->st.i_q_A,
                                                 (float)m->x6076_motor_rated_torque * 1e-3f);
        break;
    case OD_DRIVE_CURRENT_ACTUAL_VALUE_IDX:
        m->x6078_current_actual_value = per_mille(d->st.i_q_A, (float)m->x6075_motor_rated_current * 1e-3f);
        break;
    default: break;
    }
}

/* Quick stop with option 1, 2: stopped when the last step's iq is within the band; SWITCH ON
 * DISABLED then, before this step's command (which is 0 V). */
void drive_app_cia402_check_stopped(drive_app_t *app, co_node_t *node)
{
    if (app->cia402.state != (uint8_t)CIA402_QUICK_STOP_ACTIVE) return;
    const float band_A = CIA402_STOPPED_FRACTION_OF_RATED * (float)mfr_of(node)->x6075_motor_rated_current * 1e-3f;
    const float iq = app->drv.st.i_q_A;
    if (iq <= band_A && iq >= -band_A && cia402_device_stopped(&app->cia402)) drive_app_cia402_changed(app, node, 0);
}
