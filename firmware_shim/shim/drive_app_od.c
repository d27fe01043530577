/* drive_app_od.c - the drive app's OD hooks (drive_app.h): pre_write checks a write on a candidate
 * copy of the OD, post_write puts it into effect, pre_read refreshes the read-only entries.  The
 * current laws' records go to drive_app_law.c, the recorders' to drive_app_trace.c.
 * Portable: no OS headers, no allocation, float32. */
#include <string.h>

#include "co_field_map.h"
#include "drive_app_internal.h"

/* The status records' read-only entries <- the app's status structs, one row per EDS entry (the
 * lists od_drive_fields.h generates; the structs' fields carry the EDS names). */
#define DRIVE_STATUS_ROW(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW(od_drive_mfr_t, drive_app_drive_status_t, record, field),
#define STEP_COST_ROW(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW(od_drive_mfr_t, drive_app_step_cost_t, record, field),
#define SAFE_STATE_ROW(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW(od_drive_mfr_t, drive_app_safe_state_t, record, field),
static const co_field_map_t drive_status_rows[] = {OD_DRIVE_DRIVE_STATUS_STATUS(DRIVE_STATUS_ROW)};
static const co_field_map_t step_cost_rows[] = {OD_DRIVE_STEP_COST_STATUS(STEP_COST_ROW)};
static const co_field_map_t safe_state_rows[] = {OD_DRIVE_SAFE_STATE_STATUS(SAFE_STATE_ROW)};
#undef DRIVE_STATUS_ROW
#undef STEP_COST_ROW
#undef SAFE_STATE_ROW
#define N_ROWS(rows) (sizeof rows / sizeof rows[0])

/* ------------------------------------------------------------------ pre_write */

/* A write to 0x6060 or 0x605A: 0 or the SDO abort code; 1 in *handled when e is one of them. */
static uint32_t cia402_pre_write(const co_od_entry_t *e, const uint8_t *data, uint32_t len, int *handled)
{
    const uint16_t idx = e->index;
    *handled = 1;
    if (idx == OD_DRIVE_MODES_OF_OPERATION_IDX && len == 1u) {
        const int8_t mode = (int8_t)data[0];
        return mode == CIA402_MODE_MANUFACTURER_CURRENT || mode == CIA402_MODE_NONE || mode == CIA402_MODE_CST
                   ? 0u
                   : CO_ABORT_INVALID_VALUE;
    }
    if (idx == OD_DRIVE_QUICK_STOP_OPTION_CODE_IDX && len == 2u) {
        const int16_t code = (int16_t)(uint16_t)(data[0] | (data[1] << 8));
        return code == 3 || code == 4 ? CO_ABORT_INVALID_VALUE : 0u; /* torque / voltage limit: not here */
    }
    *handled = 0;
    return 0;
}

uint32_t drive_app_od_pre_write(void *user, co_node_t *node, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    drive_app_t *app = (drive_app_t *)user;
    const uint16_t idx = e->index;
    int handled;
    const uint32_t cia402_abort = cia402_pre_write(e, data, len, &handled);
    if (handled) return cia402_abort;
    if ((idx < OD_DRIVE_CONTROLLER_IDX || idx > OD_DRIVE_LIVE_TRACE_IDX) && !drive_app_law_is_record(idx)) return 0;
    const uint32_t sz = co_dt_size(e->datatype);
    if (sz == 0u || len != sz) return 0; /* lengths already checked by the core */

    /* Candidate OD: the current one with the new value stored. */
    od_drive_mfr_t *m = mfr_of(node);
    od_drive_mfr_t cand;
    memcpy(&cand, m, sizeof cand);
    const size_t off = (size_t)((const uint8_t *)e->data - (const uint8_t *)m);
    if (off + sz > sizeof cand) return 0;
    co_od_entry_t tmp = *e;
    tmp.data = (uint8_t *)&cand + off;
    co_od_store(&tmp, data, len);

    uint32_t law_abort;
    if (drive_app_law_pre_write(app, m, &cand, e, data, &law_abort)) return law_abort;

    if (idx == OD_DRIVE_SAFE_STATE_IDX && e->subindex == OD_DRIVE_SAFE_STATE_CLEAR_SUB) {
        if (data[0] > 1u) return CO_ABORT_INVALID_VALUE; /* 0: no action (what a read gives back), 1: clear */
        if (data[0] == 1u && app->safe_state.reason != (uint8_t)OD_DRIVE_REASON_NONE && drive_app_heartbeat_lost(node))
            return CO_ABORT_DATA_STATE; /* the cause persists */
        return 0;
    }
    return drive_app_trace_pre_write(&cand, e, data);
}

/* ------------------------------------------------------------------ post_write */

void drive_app_od_post_write(void *user, co_node_t *node, const co_od_entry_t *e)
{
    drive_app_t *app = (drive_app_t *)user;
    od_drive_mfr_t *m = mfr_of(node);
    const uint16_t idx = e->index;
    switch (idx) {
    case OD_DRIVE_CONTROLWORD_IDX: drive_app_cia402_on_controlword(app, node); return;
    case OD_DRIVE_MODES_OF_OPERATION_IDX: /* in effect from the next step */
        m->x6061_modes_of_operation_display = m->x6060_modes_of_operation;
        drive_app_send_statusword(node);
        return;
    case OD_DRIVE_QUICK_STOP_OPTION_CODE_IDX:
        app->cia402.cfg.quick_stop_option = m->x605A_quick_stop_option_code;
        return;
    default: break;
    }
    if (drive_app_law_post_write(app, m, e)) return;
    if (idx == OD_DRIVE_SAFE_STATE_IDX && e->subindex == OD_DRIVE_SAFE_STATE_CLEAR_SUB) {
        const uint8_t v = m->x2209_safe_state.clear;
        m->x2209_safe_state.clear = 0u; /* a command, not a state */
        if (v == 1u) drive_app_leave_safe_state(app, node);
        return;
    }
    drive_app_trace_post_write(app, m, e);
}

/* ------------------------------------------------------------------ refresh (pre_read) */

/* The status records: the values the app does not count are taken now, then the generated list
 * copies the whole record's status. */
static void refresh(drive_app_t *app, od_drive_mfr_t *m, uint16_t index)
{
    const drive_t *d = &app->drv;
    if (drive_app_law_refresh(app, m, index)) return;
    switch (index) {
    case OD_DRIVE_DRIVE_STATUS_IDX: {
        drive_app_drive_status_t *s = &app->drive_status;
        s->id_A = d->st.i_d_A;
        s->iq_A = d->st.i_q_A;
        s->speed_rad_s = d->outer.omega_m_rad_s;
        s->iq_ref_active_A = d->st.iq_ref_A;
        co_field_map_to_od(drive_status_rows, N_ROWS(drive_status_rows), m, s);
        break;
    }
    case OD_DRIVE_STEP_COST_IDX: {
        drive_app_step_cost_t *c = &app->step_cost;
        c->step_cycles_mean = c->steps_measured == 0u ? 0.0f : (float)app->step_cycles_sum / (float)c->steps_measured;
        c->cycle_clock_Hz = app->cycles_fn == NULL ? 0u : app->cycle_clock_Hz;
        co_field_map_to_od(step_cost_rows, N_ROWS(step_cost_rows), m, c);
        break;
    }
    case OD_DRIVE_SAFE_STATE_IDX:
        co_field_map_to_od(safe_state_rows, N_ROWS(safe_state_rows), m, &app->safe_state);
        m->x2209_safe_state.clear = 0u; /* a command, not a state */
        break;
    default: drive_app_trace_refresh(app, m, index); break;
    }
}

void drive_app_od_pre_read(void *user, co_node_t *node, const co_od_entry_t *e)
{
    drive_app_t *app = (drive_app_t *)user;
    if (e->index < OD_DRIVE_ONLINE_TUNING_IDX) return; /* fast path: 0x2102 of TPDO1 */
    if (e->index >= OD_DRIVE_ERROR_CODE_IDX)
        drive_app_cia402_refresh(app, mfr_of(node), e->index);
    else
        refresh(app, mfr_of(node), e->index);
}
