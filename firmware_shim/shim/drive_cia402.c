/* drive_cia402.c - see drive_cia402.h. */
#include "drive_cia402.h"

#include "drive_od.h"

#define CIA402_INC_PER_RAD 10430.378f          /* 65536 increments per mechanical revolution / (2 pi) */
#define CIA402_STOPPED_FRACTION_OF_RATED 0.02f /* quick stop done: |iq| <= 2 % of 0x6075 */

void drive_cia402_send_statusword(drive_cia402_t *c)
{
    for (uint8_t n = 0; n < CO_NUM_PDO; ++n) {
        const co_pdo_t *p = &c->node->tpdo[n];
        if (p->valid && p->trans_type >= 254u &&
            (co_pdo_maps(p, OD_DRIVE_STATUSWORD_IDX) || co_pdo_maps(p, OD_DRIVE_MODES_OF_OPERATION_DISPLAY_IDX)))
            co_tpdo_request(c->node, n);
    }
}

void drive_cia402_latch_statusword(drive_cia402_t *c)
{
    mfr_of(c->node)->x6041_Statusword = cia402_device_statusword(&c->dev);
}

void drive_cia402_controlword(drive_cia402_t *c)
{
    const int was_powered = cia402_device_power_enabled(&c->dev);
    const uint8_t before = c->dev.state;
    if (!cia402_device_controlword(&c->dev, mfr_of(c->node)->x6040_Controlword, !drive_heartbeat_lost(c->node))) return;
    /* transition 15 (the device is already in SWITCH ON DISABLED): the fault reset clears the safe state
     * and its EMCY first, then the statusword goes out like at any other state change */
    if (c->on_change != NULL) c->on_change(c->root, was_powered, before == (uint8_t)CIA402_FAULT);
}

void drive_cia402_reset(drive_cia402_t *c)
{
    od_drive_mfr_t *m = mfr_of(c->node);
    const cia402_config_t cfg = {.quick_stop_option = m->x605A_quick_stop_option_code};
    cia402_device_init(&c->dev, &cfg);
    m->x6041_Statusword = cia402_device_statusword(&c->dev);
    m->x6061_modes_of_operation_display = m->x6060_modes_of_operation;
    m->x603F_error_code = 0u;
}

/* The references of this step in the modes: 0 when the step commands 0 V. */
static int references(const drive_cia402_t *c, drive_t *d, const od_drive_mfr_t *m)
{
    if (!cia402_device_power_enabled(&c->dev)) return 0;
    if (c->dev.state == (uint8_t)CIA402_QUICK_STOP_ACTIVE) {
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

static int check_stopped(drive_cia402_t *c, float iq_A)
{
    if (c->dev.state != (uint8_t)CIA402_QUICK_STOP_ACTIVE) return 0;
    const float band_A = CIA402_STOPPED_FRACTION_OF_RATED * (float)mfr_of(c->node)->x6075_motor_rated_current * 1e-3f;
    return iq_A <= band_A && iq_A >= -band_A && cia402_device_stopped(&c->dev);
}

drive_cia402_power_t drive_cia402_power(drive_cia402_t *c, drive_t *d, const od_drive_mfr_t *m)
{
    drive_cia402_power_t p;
    p.stopped = (uint8_t)check_stopped(c, d->st.i_q_A);
    p.powered = (uint8_t)references(c, d, m);
    return p;
}

int drive_cia402_disable_voltage(drive_cia402_t *c) { return cia402_device_disable_voltage(&c->dev); }

int drive_cia402_fault(drive_cia402_t *c, uint16_t code)
{
    mfr_of(c->node)->x603F_error_code = code;
    return cia402_device_fault(&c->dev);
}

int drive_cia402_fault_reset(drive_cia402_t *c)
{
    mfr_of(c->node)->x603F_error_code = 0u;
    return cia402_device_fault_reset(&c->dev);
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

/* The actual values and the statusword, when read (SDO or TPDO). */
static void cia402_read(void *object, const co_od_entry_t *e)
{
    const drive_cia402_t *c = (const drive_cia402_t *)object;
    od_drive_mfr_t *m = mfr_of(c->node);
    const drive_t *d = c->drv;
    switch (e->index) {
    case OD_DRIVE_STATUSWORD_IDX: m->x6041_Statusword = cia402_device_statusword(&c->dev); break;
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

/* 0x6060: the modes the drive has; 0x605A: not the torque or voltage limit stops (3, 4). */
static uint32_t cia402_check(void *object, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    (void)object;
    if (e->index == OD_DRIVE_MODES_OF_OPERATION_IDX && len == 1u) {
        const int8_t mode = (int8_t)data[0];
        return mode == CIA402_MODE_MANUFACTURER_CURRENT || mode == CIA402_MODE_NONE || mode == CIA402_MODE_CST
                   ? 0u
                   : CO_ABORT_INVALID_VALUE;
    }
    if (e->index == OD_DRIVE_QUICK_STOP_OPTION_CODE_IDX && len == 2u) {
        const int16_t code = (int16_t)(uint16_t)(data[0] | (data[1] << 8));
        return code == 3 || code == 4 ? CO_ABORT_INVALID_VALUE : 0u; /* torque / voltage limit: not here */
    }
    return 0;
}

static void cia402_written(void *object, const co_od_entry_t *e)
{
    drive_cia402_t *c = (drive_cia402_t *)object;
    od_drive_mfr_t *m = mfr_of(c->node);
    switch (e->index) {
    case OD_DRIVE_CONTROLWORD_IDX: drive_cia402_controlword(c); break;
    case OD_DRIVE_MODES_OF_OPERATION_IDX: /* in effect from the next step */
        m->x6061_modes_of_operation_display = m->x6060_modes_of_operation;
        drive_cia402_send_statusword(c);
        break;
    case OD_DRIVE_QUICK_STOP_OPTION_CODE_IDX: c->dev.cfg.quick_stop_option = m->x605A_quick_stop_option_code; break;
    default: break;
    }
}

void drive_cia402_bind(drive_cia402_t *c, co_node_t *node, const drive_t *drv,
                       void (*on_change)(void *root, int was_powered, int from_fault), void *root)
{
    static const uint16_t objects[] = {
        OD_DRIVE_CONTROLWORD_IDX,         OD_DRIVE_MODES_OF_OPERATION_IDX,    OD_DRIVE_QUICK_STOP_OPTION_CODE_IDX,
        OD_DRIVE_STATUSWORD_IDX,          OD_DRIVE_POSITION_ACTUAL_VALUE_IDX, OD_DRIVE_VELOCITY_ACTUAL_VALUE_IDX,
        OD_DRIVE_TORQUE_ACTUAL_VALUE_IDX, OD_DRIVE_CURRENT_ACTUAL_VALUE_IDX};
    c->node = node;
    c->drv = drv;
    c->on_change = on_change;
    c->root = root;
    c->ext = (co_od_ext_t){c, cia402_read, cia402_check, cia402_written};
    for (uint8_t i = 0; i < sizeof objects / sizeof objects[0]; ++i) (void)co_node_bind(node, objects[i], &c->ext);
}
