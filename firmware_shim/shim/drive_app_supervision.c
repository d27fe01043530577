/* drive_app_supervision.c - the drive app's supervision (drive_app.h): the measurements' sequence
 * (lost, late), non-finite values, the safe states and their EMCYs.
 * Portable: no OS headers, no allocation, float32. */
#include <string.h>

#include "drive_app_internal.h"

/* ------------------------------------------------------------------ measurement supervision */

static void emcy_send(drive_app_t *app, uint16_t code, const uint8_t msef[5])
{
    if (app->node) co_emcy_raise(app->node, code, (uint8_t)(CO_ERR_REG_COMMUNICATION | CO_ERR_REG_MANUFACTURER), msef);
}

/* While a measurement is being handled the EMCYs wait until the command
 * (TPDO1) is out: supervision never delays the voltage command. */
static void meas_error(drive_app_t *app, uint16_t code, const uint8_t msef[5])
{
    ++app->emcy_raised;
    app->meas_error_active = 1u;
    if (app->defer_emcy) {
        if (app->n_pending < DRIVE_APP_PENDING_EMCY) {
            app->pending_code[app->n_pending] = code;
            memcpy(app->pending_msef[app->n_pending], msef, 5);
            ++app->n_pending;
        }
        return;
    }
    emcy_send(app, code, msef);
}

static void flush_emcy(drive_app_t *app)
{
    app->defer_emcy = 0u;
    for (uint8_t i = 0; i < app->n_pending; ++i) emcy_send(app, app->pending_code[i], app->pending_msef[i]);
    app->n_pending = 0u;
}

void drive_app_count_late(drive_app_t *app, uint8_t reason, uint16_t sample_index, uint8_t sync_counter)
{
    ++app->drive_status.late_measurements;
    const uint8_t msef[5] = {(uint8_t)sample_index, (uint8_t)(sample_index >> 8), reason, sync_counter,
                             app->last_sync_counter};
    meas_error(app, DRIVE_EMCY_MEAS_LATE, msef);
}

static void count_lost(drive_app_t *app, uint32_t missing, uint16_t sample_index, uint8_t sync_counter)
{
    app->drive_status.lost_measurements += missing;
    const uint16_t m16 = missing > 0xFFFFu ? 0xFFFFu : (uint16_t)missing;
    const uint8_t msef[5] = {(uint8_t)sample_index, (uint8_t)(sample_index >> 8), (uint8_t)m16, (uint8_t)(m16 >> 8),
                             sync_counter};
    meas_error(app, DRIVE_EMCY_MEAS_LOST, msef);
}

void drive_app_reset_sequencing(drive_app_t *app)
{
    app->rpdo1_fresh = 0u;
    app->have_last = 0u;
    app->sync_seen = 0u;
    app->meas_seen = 0u; /* the measurement timeout re-arms at the next measurement */
    app->syncs_without_meas = 0u;
}

/* Non-finite measurement values of the step just run: EMCY 0xFF05 (after the
 * command and the deferred EMCYs), cleared by the next step without any. */
void drive_app_report_non_finite(drive_app_t *app, uint16_t sample_index)
{
    if (app->node == NULL) return;
    if (app->non_finite_mask != 0u) {
        const uint8_t msef[5] = {(uint8_t)sample_index, (uint8_t)(sample_index >> 8), app->non_finite_mask, 0, 0};
        app->non_finite_active = 1u;
        emcy_send(app, DRIVE_EMCY_NON_FINITE, msef);
    } else if (app->non_finite_active) {
        app->non_finite_active = 0u;
        co_emcy_clear(app->node, DRIVE_EMCY_NON_FINITE);
    }
}

/* A measurement (RPDO2) arrived: check its sequence, then the step. */
void drive_app_on_measurement(drive_app_t *app, co_node_t *node)
{
    od_drive_mfr_t *m = mfr_of(node);
    const uint16_t si = m->x2100_Measurement.sample_index;
    const uint8_t sc = m->x2100_Measurement.sync_counter;
    const uint32_t late0 = app->drive_status.late_measurements, lost0 = app->drive_status.lost_measurements;
    const uint8_t was_active = app->meas_error_active;
    app->defer_emcy = 1u;
    app->n_pending = 0u;
    /* the measurement timeout is armed by a measurement, and disarmed by one whose status says the plant
     * holds (plant.eds 0x2100:05 bit 1, end of a run segment): SYNCs after that are not the plant's */
    app->meas_seen = (m->x2100_Measurement.status & PLANT_STATUS_HOLDING) ? 0u : 1u;
    app->syncs_without_meas = 0u;

    if (!app->rpdo1_fresh) drive_app_count_late(app, DRIVE_LATE_RPDO2_WITHOUT_RPDO1, si, sc);
    app->rpdo1_fresh = 0u;

    int duplicate = 0;
    if (app->have_last) {
        const uint16_t delta = (uint16_t)(si - app->drive_status.last_sample_index);
        duplicate = delta == 0u && app->old_run == 0u;
        if (delta == 0u || delta >= 0x8000u) {
            drive_app_count_late(app, DRIVE_LATE_DUPLICATE_OR_OLD, si, sc);
            /* stay on the newest index; a restarted plant is followed after
             * three consecutive "old" samples */
            if (++app->old_run >= 3u) {
                app->drive_status.last_sample_index = si;
                app->old_run = 0u;
            }
        } else {
            if (delta > 1u) count_lost(app, (uint32_t)delta - 1u, si, sc);
            app->drive_status.last_sample_index = si;
            app->old_run = 0u;
        }
    } else {
        app->have_last = 1u;
        app->drive_status.last_sample_index = si;
        app->old_run = 0u;
    }
    const uint8_t sync_ov = node->c_sync_overflow; /* 0x1019, kept current by the node */
    if (app->sync_seen && sync_ov >= 2u && sc != app->last_sync_counter)
        drive_app_count_late(app, DRIVE_LATE_SYNC_MISMATCH, si, sc);

    const int clean = app->drive_status.late_measurements == late0 && app->drive_status.lost_measurements == lost0;
    if (clean) app->meas_error_active = 0u;
    if (duplicate) { /* the sample just answered, again: its command is out; a second step would advance the
                      * controller's state twice and send the plant a second command */
        flush_emcy(app);
        return;
    }
    drive_app_step(app); /* command out first */
    flush_emcy(app);
    drive_app_report_non_finite(app, si);
    if (clean && was_active) {
        co_emcy_clear(node, DRIVE_EMCY_MEAS_LOST);
        co_emcy_clear(node, DRIVE_EMCY_MEAS_LATE);
    }
}

/* ------------------------------------------------------------------ safe state */

/* Zero voltage in the state and its trace signals: they show what the drive commanded. */
void drive_app_zero_voltage(drive_t *d)
{
    drive_state_t *s = &d->st;
    s->out.v_d_V = s->out.v_q_V = 0.0f;
    s->out.v_d_star_V = s->out.v_q_star_V = 0.0f;
    s->out.v_d_ff_V = s->out.v_q_ff_V = 0.0f;
    s->out.v_alpha_V = s->out.v_beta_V = 0.0f;
    s->out.v_limited = 0u;
    s->signals[TRACE_SIG_VQ] = 0.0f;
    s->signals[TRACE_SIG_VD] = 0.0f;
    s->signals[TRACE_SIG_VQ_STAR] = 0.0f;
    s->signals[TRACE_SIG_VD_STAR] = 0.0f;
    s->signals[TRACE_SIG_V_ALPHA] = 0.0f;
    s->signals[TRACE_SIG_V_BETA] = 0.0f;
    s->signals[TRACE_SIG_V_LIMITED] = 0.0f;
}

/* Forget what the control built up while it did not act: the current
 * controllers' memories and the outer loops' integrator and profile (restarted
 * at the measured position), so that leaving the safe state starts cleanly. */
void drive_app_clear_control_memory(drive_t *d)
{
    drive_reset_controller_memory(d);
    d->outer.integ_A = 0.0f;
    d->outer.iq_ref_A = 0.0f;
    d->outer.pos_ref_rad = d->outer.theta_unwrapped_rad;
    d->outer.vel_ref_rad_s = 0.0f;
    d->st.signals[TRACE_SIG_POS_REF] = d->outer.pos_ref_rad;
}

/* A step in the safe state: the core runs (observers, speed estimate), the
 * command is zero. */
void drive_app_safe_step(drive_app_t *app)
{
    drive_t *d = &app->drv;
    trace_recorder_t *rec = drive_app_core_step_without_output(app);
    drive_app_clear_control_memory(d);
    drive_app_zero_voltage(d);
    if (rec != NULL) trace_sample(rec, d->st.signals);
    app->cmd.v_alpha_V = 0.0f;
    app->cmd.v_beta_V = 0.0f;
}

int drive_app_heartbeat_lost(const co_node_t *node)
{
    for (uint8_t i = 0; i < CO_HB_CONSUMERS; ++i)
        if (node->hb[i].active && node->hb[i].timed_out) return 1;
    return 0;
}

static uint16_t safe_emcy_code(uint8_t reason)
{
    switch (reason) {
    case OD_DRIVE_REASON_HEARTBEAT_LOST: return DRIVE_EMCY_SAFE_HEARTBEAT;
    case OD_DRIVE_REASON_LAW_OUTPUT: return DRIVE_EMCY_SAFE_LAW_OUTPUT;
    case OD_DRIVE_REASON_OVERRUN: return DRIVE_EMCY_SAFE_OVERRUN;
    default: return DRIVE_EMCY_SAFE_MEAS_TIMEOUT;
    }
}

static void enter_safe_state(drive_app_t *app, co_node_t *node, uint8_t reason, int send_now)
{
    if (app->safe_state.reason != (uint8_t)OD_DRIVE_REASON_NONE) return; /* latched: the first reason stays */
    app->safe_state.reason = reason;
    ++app->safe_state.entries;
    const uint16_t si = app->have_good ? app->good_sample_index : 0u;
    app->safe_state.entered_at_sample = si;
    /* zero volts now: a plant still producing periods applies them at its next SYNC */
    drive_app_clear_control_memory(&app->drv);
    drive_app_zero_voltage(&app->drv);
    app->cmd.v_alpha_V = 0.0f;
    app->cmd.v_beta_V = 0.0f;
    od_drive_mfr_t *m = mfr_of(node);
    m->x2102_voltage_command.v_alpha_V = 0.0f;
    m->x2102_voltage_command.v_beta_V = 0.0f;
    if (send_now) co_tpdo_request(node, 0);
    const uint8_t msef[5] = {(uint8_t)si, (uint8_t)(si >> 8), reason, 0, 0};
    emcy_send(app, safe_emcy_code(reason), msef);
    /* CiA 402: the fault reaction (0 V, above) is done: FAULT, with the EMCY code as the error code */
    m->x603F_error_code = safe_emcy_code(reason);
    if (cia402_device_fault(&app->cia402)) drive_app_cia402_changed(app, node, 0);
}

void drive_app_enter_safe_state(drive_app_t *app, co_node_t *node, uint8_t reason)
{
    enter_safe_state(app, node, reason, 1);
}

void drive_app_enter_safe_state_in_step(drive_app_t *app, co_node_t *node, uint8_t reason)
{
    enter_safe_state(app, node, reason, 0);
}

void drive_app_leave_safe_state(drive_app_t *app, co_node_t *node)
{
    const uint8_t reason = app->safe_state.reason;
    if (reason == (uint8_t)OD_DRIVE_REASON_NONE) return;
    app->safe_state.reason = (uint8_t)OD_DRIVE_REASON_NONE;
    app->syncs_without_meas = 0u;
    co_emcy_clear(node, safe_emcy_code(reason));
    mfr_of(node)->x603F_error_code = 0u;
    if (cia402_device_fault_reset(&app->cia402)) drive_app_cia402_changed(app, node, 0);
}
