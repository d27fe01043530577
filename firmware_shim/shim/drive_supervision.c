/* drive_supervision.c - see drive_supervision.h. */
#include "drive_supervision.h"

#include <string.h>

#include "co_field_map.h"
#include "drive_od.h"
#include "od_plant_fields.h" /* PLANT_STATUS_HOLDING: plant.eds 0x2100:05 BitNames (the plant holds at this sample) */

/* The status records' read-only entries <- the component's structs, one row per EDS entry. */
#define DRIVE_STATUS_ROW(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW(od_drive_mfr_t, drive_app_drive_status_t, record, field),
#define SAFE_STATE_ROW(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW(od_drive_mfr_t, drive_app_safe_state_t, record, field),
static const co_field_map_t drive_status_rows[] = {OD_DRIVE_DRIVE_STATUS_STATUS(DRIVE_STATUS_ROW)};
static const co_field_map_t safe_state_rows[] = {OD_DRIVE_SAFE_STATE_STATUS(SAFE_STATE_ROW)};
#undef DRIVE_STATUS_ROW
#undef SAFE_STATE_ROW
#define N_ROWS(rows) (sizeof rows / sizeof rows[0])

/* ------------------------------------------------------------------ EMCYs */

static void emcy_send(drive_supervision_t *s, uint16_t code, const uint8_t msef[5])
{
    if (s->node) co_emcy_raise(s->node, code, (uint8_t)(CO_ERR_REG_COMMUNICATION | CO_ERR_REG_MANUFACTURER), msef);
}

/* While a measurement is being handled the EMCYs wait until the command (TPDO1) is out: supervision never
 * delays the voltage command. */
static void meas_error(drive_supervision_t *s, uint16_t code, const uint8_t msef[5])
{
    ++s->emcy_raised;
    s->meas_error_active = 1u;
    if (s->defer_emcy) {
        if (s->n_pending < DRIVE_APP_PENDING_EMCY) {
            s->pending_code[s->n_pending] = code;
            memcpy(s->pending_msef[s->n_pending], msef, 5);
            ++s->n_pending;
        }
        return;
    }
    emcy_send(s, code, msef);
}

static void flush_emcy(drive_supervision_t *s)
{
    s->defer_emcy = 0u;
    for (uint8_t i = 0; i < s->n_pending; ++i) emcy_send(s, s->pending_code[i], s->pending_msef[i]);
    s->n_pending = 0u;
}

static void count_late(drive_supervision_t *s, uint8_t reason, uint16_t sample_index, uint8_t sync_counter)
{
    ++s->drive_status.late_measurements;
    const uint8_t msef[5] = {(uint8_t)sample_index, (uint8_t)(sample_index >> 8), reason, sync_counter,
                             s->last_sync_counter};
    meas_error(s, DRIVE_EMCY_MEAS_LATE, msef);
}

static void count_lost(drive_supervision_t *s, uint32_t missing, uint16_t sample_index, uint8_t sync_counter)
{
    s->drive_status.lost_measurements += missing;
    const uint16_t m16 = missing > 0xFFFFu ? 0xFFFFu : (uint16_t)missing;
    const uint8_t msef[5] = {(uint8_t)sample_index, (uint8_t)(sample_index >> 8), (uint8_t)m16, (uint8_t)(m16 >> 8),
                             sync_counter};
    meas_error(s, DRIVE_EMCY_MEAS_LOST, msef);
}

/* ------------------------------------------------------------------ the measurements' sequence */

void drive_sup_reset_sequencing(drive_supervision_t *s)
{
    s->rpdo1_fresh = 0u;
    s->have_last = 0u;
    s->sync_seen = 0u;
    s->meas_seen = 0u; /* the measurement timeout re-arms at the next measurement */
    s->syncs_without_meas = 0u;
}

void drive_sup_reset(drive_supervision_t *s, int app)
{
    if (app) {
        s->drive_status.current_steps = s->drive_status.lost_measurements = s->drive_status.late_measurements =
            s->emcy_raised = 0u;
        s->meas_error_active = 0u;
        s->safe_state.entries = 0u;
        s->safe_state.entered_at_sample = 0u;
        s->have_good = 0u;
        s->good_sample_index = 0u;
        s->safe_state.non_finite_rejected = 0u;
    }
    drive_sup_reset_sequencing(s);
    /* both resets leave the safe state (the stack has forgotten the active EMCYs) */
    s->safe_state.reason = (uint8_t)OD_DRIVE_REASON_NONE;
    s->non_finite_mask = 0u;
    s->non_finite_active = 0u;
}

int drive_sup_on_sync(drive_supervision_t *s, uint8_t counter, int operational)
{
    if (s->rpdo1_fresh) {
        /* the currents of the previous sample never got their RPDO2 */
        s->rpdo1_fresh = 0u;
        count_late(s, DRIVE_LATE_RPDO1_WITHOUT_RPDO2, s->drive_status.last_sample_index, counter);
    }
    s->sync_seen = 1u;
    s->last_sync_counter = counter;
    /* measurement timeout: SYNCs since the last measurement */
    if (!operational || !s->meas_seen) return 0;
    if (s->syncs_without_meas < 0xFFFFu) ++s->syncs_without_meas;
    const uint16_t n = mfr_of(s->node)->x2209_safe_state.meas_timeout_periods;
    return n != 0u && s->syncs_without_meas >= n;
}

void drive_sup_on_rpdo1(drive_supervision_t *s)
{
    if (s->rpdo1_fresh) {
        const od_drive_mfr_t *m = mfr_of(s->node);
        count_late(s, DRIVE_LATE_RPDO1_WITHOUT_RPDO2, m->x2100_Measurement.sample_index,
                   m->x2100_Measurement.sync_counter);
    }
    s->rpdo1_fresh = 1u;
}

/* The sample index against the last one: lost samples, duplicates and old ones; 1 for a duplicate. */
static int judge_index(drive_supervision_t *s, uint16_t si, uint8_t sc)
{
    if (!s->have_last) {
        s->have_last = 1u;
        s->drive_status.last_sample_index = si;
        s->old_run = 0u;
        return 0;
    }
    const uint16_t delta = (uint16_t)(si - s->drive_status.last_sample_index);
    const int duplicate = delta == 0u && s->old_run == 0u;
    if (delta == 0u || delta >= 0x8000u) {
        count_late(s, DRIVE_LATE_DUPLICATE_OR_OLD, si, sc);
        /* stay on the newest index; a restarted plant is followed after three consecutive "old" samples */
        if (++s->old_run >= 3u) {
            s->drive_status.last_sample_index = si;
            s->old_run = 0u;
        }
    } else {
        if (delta > 1u) count_lost(s, (uint32_t)delta - 1u, si, sc);
        s->drive_status.last_sample_index = si;
        s->old_run = 0u;
    }
    return duplicate;
}

drive_sup_verdict_t drive_sup_admit(drive_supervision_t *s)
{
    const od_drive_mfr_t *m = mfr_of(s->node);
    const uint16_t si = m->x2100_Measurement.sample_index;
    const uint8_t sc = m->x2100_Measurement.sync_counter;
    const uint32_t late0 = s->drive_status.late_measurements, lost0 = s->drive_status.lost_measurements;
    s->admit_was_active = s->meas_error_active;
    s->defer_emcy = 1u;
    s->n_pending = 0u;
    /* the measurement timeout is armed by a measurement, and disarmed by one whose status says the plant
     * holds (plant.eds 0x2100:05 bit 1, end of a run segment): SYNCs after that are not the plant's */
    s->meas_seen = (m->x2100_Measurement.status & PLANT_STATUS_HOLDING) ? 0u : 1u;
    s->syncs_without_meas = 0u;

    if (!s->rpdo1_fresh) count_late(s, DRIVE_LATE_RPDO2_WITHOUT_RPDO1, si, sc);
    s->rpdo1_fresh = 0u;
    const int duplicate = judge_index(s, si, sc);
    const uint8_t sync_ov = s->node->c_sync_overflow; /* 0x1019, kept current by the node */
    if (s->sync_seen && sync_ov >= 2u && sc != s->last_sync_counter) count_late(s, DRIVE_LATE_SYNC_MISMATCH, si, sc);

    s->admit_clean = s->drive_status.late_measurements == late0 && s->drive_status.lost_measurements == lost0;
    if (s->admit_clean) s->meas_error_active = 0u;
    /* a duplicate: the sample just answered, again: its command is out; a second step would advance the
     * controller's state twice and send the plant a second command */
    return duplicate ? DRIVE_SUP_DUPLICATE : DRIVE_SUP_STEP;
}

void drive_sup_note_values(drive_supervision_t *s, uint8_t non_finite_mask, uint16_t sample_index)
{
    s->non_finite_mask = non_finite_mask;
    if (non_finite_mask == 0u) {
        s->have_good = 1u;
        s->good_sample_index = sample_index;
    } else {
        s->safe_state.non_finite_rejected +=
            (uint32_t)((non_finite_mask & 1u) + ((non_finite_mask >> 1) & 1u) + ((non_finite_mask >> 2) & 1u));
    }
}

void drive_sup_note_rejected(drive_supervision_t *s, uint32_t n) { s->safe_state.non_finite_rejected += n; }

/* Non-finite measurement values of the step just run: EMCY 0xFF05 (after the command and the deferred EMCYs),
 * cleared by the next step without any. */
static void report_non_finite(drive_supervision_t *s, uint16_t sample_index)
{
    if (s->node == NULL) return;
    if (s->non_finite_mask != 0u) {
        const uint8_t msef[5] = {(uint8_t)sample_index, (uint8_t)(sample_index >> 8), s->non_finite_mask, 0, 0};
        s->non_finite_active = 1u;
        emcy_send(s, DRIVE_EMCY_NON_FINITE, msef);
    } else if (s->non_finite_active) {
        s->non_finite_active = 0u;
        co_emcy_clear(s->node, DRIVE_EMCY_NON_FINITE);
    }
}

void drive_sup_finish(drive_supervision_t *s, drive_sup_verdict_t v, uint16_t sample_index)
{
    flush_emcy(s);
    if (v == DRIVE_SUP_DUPLICATE) return;
    ++s->drive_status.current_steps;
    report_non_finite(s, sample_index);
    if (s->admit_clean && s->admit_was_active) {
        co_emcy_clear(s->node, DRIVE_EMCY_MEAS_LOST);
        co_emcy_clear(s->node, DRIVE_EMCY_MEAS_LATE);
    }
    s->admit_was_active = 0u; /* cleared once */
}

/* ------------------------------------------------------------------ safe state */

uint16_t drive_sup_safe_code(uint8_t reason)
{
    switch (reason) {
    case OD_DRIVE_REASON_HEARTBEAT_LOST: return DRIVE_EMCY_SAFE_HEARTBEAT;
    case OD_DRIVE_REASON_LAW_OUTPUT: return DRIVE_EMCY_SAFE_LAW_OUTPUT;
    case OD_DRIVE_REASON_OVERRUN: return DRIVE_EMCY_SAFE_OVERRUN;
    default: return DRIVE_EMCY_SAFE_MEAS_TIMEOUT;
    }
}

int drive_sup_latch(drive_supervision_t *s, uint8_t reason)
{
    if (drive_sup_safe(s)) return 0; /* latched: the first reason stays */
    s->safe_state.reason = reason;
    ++s->safe_state.entries;
    s->safe_state.entered_at_sample = s->have_good ? s->good_sample_index : 0u;
    return 1;
}

void drive_sup_safe_emcy(drive_supervision_t *s)
{
    const uint16_t si = s->safe_state.entered_at_sample;
    const uint8_t msef[5] = {(uint8_t)si, (uint8_t)(si >> 8), s->safe_state.reason, 0, 0};
    emcy_send(s, drive_sup_safe_code(s->safe_state.reason), msef);
}

uint8_t drive_sup_release(drive_supervision_t *s)
{
    const uint8_t reason = s->safe_state.reason;
    if (reason == (uint8_t)OD_DRIVE_REASON_NONE) return reason;
    s->safe_state.reason = (uint8_t)OD_DRIVE_REASON_NONE;
    s->syncs_without_meas = 0u;
    co_emcy_clear(s->node, drive_sup_safe_code(reason));
    return reason;
}

/* ------------------------------------------------------------------ 0x2204, 0x2209: the bindings */

static void status_read(void *object, const co_od_entry_t *e)
{
    drive_supervision_t *s = (drive_supervision_t *)object;
    const drive_t *d = s->drv;
    drive_app_drive_status_t *st = &s->drive_status;
    (void)e;
    st->id_A = d->st.i_d_A;
    st->iq_A = d->st.i_q_A;
    st->speed_rad_s = d->outer.omega_m_rad_s;
    st->iq_ref_active_A = d->st.iq_ref_A;
    co_field_map_to_od(drive_status_rows, N_ROWS(drive_status_rows), mfr_of(s->node), st);
}

static void safe_state_read(void *object, const co_od_entry_t *e)
{
    drive_supervision_t *s = (drive_supervision_t *)object;
    od_drive_mfr_t *m = mfr_of(s->node);
    (void)e;
    co_field_map_to_od(safe_state_rows, N_ROWS(safe_state_rows), m, &s->safe_state);
    m->x2209_safe_state.clear = 0u; /* a command, not a state */
}

/* :clear takes 0 (no action: what a read gives back) or 1 (leave the safe state, refused while its cause
 * persists); the other entries any value their range allows. */
static uint32_t safe_state_check(void *object, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    const drive_supervision_t *s = (const drive_supervision_t *)object;
    (void)len;
    if (e->subindex != OD_DRIVE_SAFE_STATE_CLEAR_SUB) return 0;
    if (data[0] > 1u) return CO_ABORT_INVALID_VALUE;
    if (data[0] == 1u && drive_sup_safe(s) && drive_heartbeat_lost(s->node))
        return CO_ABORT_DATA_STATE; /* the cause persists */
    return 0;
}

static void safe_state_written(void *object, const co_od_entry_t *e)
{
    drive_supervision_t *s = (drive_supervision_t *)object;
    od_drive_mfr_t *m = mfr_of(s->node);
    if (e->subindex != OD_DRIVE_SAFE_STATE_CLEAR_SUB) return;
    const uint8_t v = m->x2209_safe_state.clear;
    m->x2209_safe_state.clear = 0u; /* a command, not a state */
    if (v == 1u && s->on_clear != NULL) s->on_clear(s->root);
}

void drive_sup_bind(drive_supervision_t *s, co_node_t *node, const drive_t *drv, void (*on_clear)(void *root),
                    void *root)
{
    s->node = node;
    s->drv = drv;
    s->on_clear = on_clear;
    s->root = root;
    s->ext_status = (co_od_ext_t){s, status_read, NULL, NULL};
    s->ext_safe_state = (co_od_ext_t){s, safe_state_read, safe_state_check, safe_state_written};
    (void)co_node_bind(node, OD_DRIVE_DRIVE_STATUS_IDX, &s->ext_status);
    (void)co_node_bind(node, OD_DRIVE_SAFE_STATE_IDX, &s->ext_safe_state);
}
