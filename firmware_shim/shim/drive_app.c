/* drive_app.c - the drive firmware as a CANopen node (see drive_app.h).
 * Portable: no OS headers, no allocation, float32. */
#include "drive_app.h"

#include <string.h>

#include "co_field_map.h"
#include "dq_math.h"
#include "od_drive.h"

/* ------------------------------------------------------------------ OD access */

static od_drive_mfr_t *mfr_of(const co_node_t *node) { return &((od_drive_ram_t *)node->od->ram)->mfr; }

/* plant.eds 0x2100:05 status, bit 1: run_periods reached 0 at this sample, the plant holds */
#define PLANT_STATUS_HOLDING_BIT 0x02u

static int is_finite_f(float x) { return (x - x) == 0.0f; /* false for NaN and +-inf */ }

/* The drive's parameter records -> drive_config_t, one row per EDS entry (the
 * lists od_drive_fields.h generates; the config's fields carry the EDS names). */
#define AT_ROOT(index, sub, record, field, eds_default) CO_FIELD_MAP_ROW(od_drive_mfr_t, drive_config_t, record, field),
#define IN_OUTER(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW_IN(od_drive_mfr_t, drive_config_t, outer, record, field),
/* one list a line (clang-format would run the macro lists together) */
/* clang-format off */
static const co_field_map_t config_rows[] = {
    OD_DRIVE_CONTROLLER_PARAMS(AT_ROOT)
    OD_DRIVE_OUTER_LOOPS_PARAMS(IN_OUTER)
    /* the profile of References belongs to the outer loops */
    CO_FIELD_MAP_ROW_IN(od_drive_mfr_t, drive_config_t, outer, x2202_References, profile_speed_rad_s),
    CO_FIELD_MAP_ROW_IN(od_drive_mfr_t, drive_config_t, outer, x2202_References, profile_accel_rad_s2)};
/* clang-format on */
#undef AT_ROOT
#undef IN_OUTER

/* OD -> drive_config_t.  core_ctrl: controller to keep when the OD selects the
 * open loop (the core has no open-loop controller). */
static void od_to_config(const od_drive_mfr_t *m, drive_config_t *c, uint8_t core_ctrl)
{
    co_field_map_to_core(config_rows, sizeof config_rows / sizeof config_rows[0], m, c);
    if (c->controller == (uint8_t)OD_DRIVE_CONTROLLER_OPEN_LOOP) c->controller = core_ctrl;
}

/* ------------------------------------------------------------------ the laws' records */

/* The C struct of a manufacturer record in the OD at m (its sub-index 0 is its first member), NULL for none. */
static void *od_record(const co_node_t *node, od_drive_mfr_t *m, uint16_t index)
{
    const co_od_entry_t *e = node != NULL ? co_od_find(node->od, index, 0u, NULL) : NULL;
    if (e == NULL) return NULL;
    const size_t off = (size_t)((const uint8_t *)e->data - (const uint8_t *)mfr_of(node));
    return (uint8_t *)m + off;
}

typedef struct {
    const co_node_t *node;
    od_drive_mfr_t *m;
} record_ctx_t;

static const void *record_in(uint16_t index, void *user)
{
    const record_ctx_t *x = (const record_ctx_t *)user;
    return od_record(x->node, x->m, index);
}

/* 1 when a law's record at `index` (0x2201, 0x2206, ..., a user law's 0x24xx). */
static int is_law_record(uint16_t index)
{
    for (uint8_t i = 0u; i < current_law_count; ++i)
        if (current_law_table[i].record_index == index && index != 0u) return 1;
    return 0;
}

/* The law that takes commands on the record at `index`, NULL for none. */
static const current_law_entry_t *commanded_law(uint16_t index)
{
    for (uint8_t i = 0u; i < current_law_count; ++i)
        if (current_law_table[i].record_index == index && current_law_table[i].law->command != NULL)
            return &current_law_table[i];
    return NULL;
}

/* The selected law's record, OD -> drive, when its parameters (its writable entries) differ from what
 * the drive holds; returns 1 then.  Status entries (written by pre_read) are not a change. */
static int sync_law_record(drive_app_t *app)
{
    co_node_t *node = app->node;
    drive_t *d = &app->drv;
    const current_law_entry_t *e = current_law_find(d->cfg.controller);
    if (node == NULL || e == NULL || e->record_index == 0u) return 0;
    const uint8_t *rec = (const uint8_t *)od_record(node, mfr_of(node), e->record_index);
    if (rec == NULL) return 0;
    int differ = d->law_record_index != e->record_index;
    for (uint16_t sub = 1u; !differ && sub <= 0xFFu; ++sub) {
        const co_od_entry_t *x = co_od_find(node->od, e->record_index, (uint8_t)sub, NULL);
        if (x == NULL) break;
        if ((x->flags & CO_ODF_WRITE) == 0u) continue;
        const size_t off = (size_t)((const uint8_t *)x->data - rec);
        differ = memcmp(d->law_record + off, x->data, co_od_value_size(x)) != 0;
    }
    if (differ) drive_set_law_record(d, rec, e->record_bytes);
    return differ;
}

static uint32_t abort_of(current_law_verdict_t v)
{
    switch (v) {
    case CURRENT_LAW_OK:
    case CURRENT_LAW_NOT_COMMAND: return 0u;
    case CURRENT_LAW_INCOMPATIBLE: return CO_ABORT_PARAM_INCOMPAT;
    case CURRENT_LAW_NOT_NOW: return CO_ABORT_DATA_STATE;
    default: return CO_ABORT_INVALID_VALUE;
    }
}

/* Would the core accept the parameter records of m (a candidate OD)?  (Its rules: drive_config_check,
 * and every law's on its record.) */
static uint32_t check_config(const drive_app_t *app, od_drive_mfr_t *m, int controller_written)
{
    drive_config_t c = app->drv.cfg;
    co_field_map_to_core(config_rows, sizeof config_rows / sizeof config_rows[0], m, &c); /* 0 = open loop */
    if (controller_written && drive_config_check_selection(&c) != DRIVE_CONFIG_OK)
        return CO_ABORT_INVALID_VALUE; /* a surface-mounted law with a salient model */
    record_ctx_t ctx = {app->node, m};
    switch (drive_config_check(&c, m->x2202_References.mode, record_in, &ctx)) {
    case DRIVE_CONFIG_OK: return 0;
    case DRIVE_CONFIG_NO_SUCH_CONTROLLER: return CO_ABORT_INVALID_VALUE;
    default: return CO_ABORT_PARAM_INCOMPAT;
    }
}

/* EDS trigger_edge (0 immediate, 1 rising, 2 falling, 3 either) -> trace_edge_t. */
static uint8_t edge_from_od(uint8_t v)
{
    switch (v) {
    case 1: return (uint8_t)TRACE_EDGE_RISING;
    case 2: return (uint8_t)TRACE_EDGE_FALLING;
    case 3: return (uint8_t)TRACE_EDGE_EITHER;
    default: return (uint8_t)TRACE_EDGE_IMMEDIATE;
    }
}

/* 0x2300 -> trace_config_t; returns 0 or an abort code for invalid combinations. */
static uint32_t trace_config_from_od(const od_drive_mfr_t *m, trace_config_t *tc)
{
#define t (&m->x2300_Trace)
    const uint8_t sig[TRACE_MAX_CHANNELS] = {t->signal_1, t->signal_2, t->signal_3, t->signal_4,
                                             t->signal_5, t->signal_6, t->signal_7, t->signal_8};
    uint8_t s[TRACE_MAX_CHANNELS] = {0, 0, 0, 0, 0, 0, 0, 0};
    const uint8_t n = t->signal_count;
    if (n == 0u || n > TRACE_MAX_CHANNELS) return CO_ABORT_PARAM_INCOMPAT;
    for (uint8_t i = 0; i < n; ++i) {
        if (sig[i] == (uint8_t)TRACE_SIG_NONE || sig[i] >= (uint8_t)TRACE_SIG_COUNT) return CO_ABORT_PARAM_INCOMPAT;
        s[i] = sig[i];
    }
    if (t->trigger_signal >= (uint8_t)TRACE_SIG_COUNT) return CO_ABORT_PARAM_INCOMPAT;
    if ((uint32_t)t->pretrigger_samples >= TRACE_BUFFER_SAMPLES / n) return CO_ABORT_PARAM_INCOMPAT;
    memset(tc, 0, sizeof *tc);
    tc->signal_0 = s[0];
    tc->signal_1 = s[1];
    tc->signal_2 = s[2];
    tc->signal_3 = s[3];
    tc->signal_4 = s[4];
    tc->signal_5 = s[5];
    tc->signal_6 = s[6];
    tc->signal_7 = s[7];
    tc->trigger_signal = t->trigger_signal;
    tc->trigger_edge = edge_from_od(t->trigger_edge);
    tc->trigger_level = t->trigger_level;
    tc->pretrigger_samples = t->pretrigger_samples;
    tc->decimation = t->decimation == 0u ? 1u : t->decimation;
#undef t
    return 0;
}

static int host_is_little(void)
{
    const uint16_t one = 1u;
    return *(const uint8_t *)&one == 1u;
}

static void reverse_f(float *a, uint32_t lo, uint32_t hi) /* [lo, hi) */
{
    while (hi > lo + 1u) {
        --hi;
        const float t = a[lo];
        a[lo] = a[hi];
        a[hi] = t;
        ++lo;
    }
}

/* Make the captured ring contiguous (oldest row first) in place, so the DOMAIN
 * can point straight at it: no second 32 KiB buffer. */
static void trace_linearise(drive_app_t *app)
{
    trace_recorder_t *r = &app->trace;
    if (app->trace_linear || r->status != (uint8_t)TRACE_DONE) return;
    const uint32_t n = r->rows_captured * r->n_channels;
    const uint32_t k = r->start_row * r->n_channels;
    if (k != 0u && k < n) {
        reverse_f(r->buffer, 0u, k);
        reverse_f(r->buffer, k, n);
        reverse_f(r->buffer, 0u, n);
    }
    r->start_row = 0u;
    if (!host_is_little()) {
        for (uint32_t i = 0; i < n; ++i) {
            uint8_t b[4];
            memcpy(b, &r->buffer[i], 4);
            const uint8_t s0 = b[0], s1 = b[1];
            b[0] = b[3];
            b[1] = b[2];
            b[2] = s1;
            b[3] = s0;
            memcpy(&r->buffer[i], b, 4);
        }
    }
    app->trace_linear = 1u;
}

/* ------------------------------------------------------------------ refresh (pre_read) */

static void refresh(drive_app_t *app, od_drive_mfr_t *m, uint16_t index)
{
    drive_t *d = &app->drv;
    const current_law_entry_t *selected = current_law_find(d->cfg.controller);
    if (selected != NULL && selected->record_index == index) drive_update_config(d); /* selected, not yet run */
    if (d->law != NULL && d->law->record_index == index && d->law->record_index != 0u) {
        drive_law_status(d, od_record(app->node, m, index)); /* the selected law's status entries */
        return;
    }
    switch (index) {
    case OD_DRIVE_DRIVE_STATUS_IDX: {
#define s (&m->x2204_drive_status)
        s->current_steps = app->current_steps;
        s->lost_measurements = app->lost;
        s->late_measurements = app->late;
        s->id_A = d->st.i_d_A;
        s->iq_A = d->st.i_q_A;
        s->speed_rad_s = d->outer.omega_m_rad_s;
        s->iq_ref_active_A = d->st.iq_ref_A;
        s->last_sample_index = app->last_sample_index;
#undef s
        break;
    }
    case OD_DRIVE_STEP_COST_IDX: {
#define c (&m->x2208_step_cost)
        c->step_cycles_last = (float)app->step_cycles_last;
        c->step_cycles_max = (float)app->step_cycles_max;
        c->step_cycles_mean =
            app->steps_measured == 0u ? 0.0f : (float)app->step_cycles_sum / (float)app->steps_measured;
        c->cycle_clock_Hz = app->cycles_fn == NULL ? 0u : app->cycle_clock_Hz;
        c->steps_measured = app->steps_measured;
#undef c
        break;
    }
    case OD_DRIVE_SAFE_STATE_IDX: {
#define z (&m->x2209_safe_state)
        z->reason = app->safe_reason;
        z->entries = app->safe_entries;
        z->entered_at_sample = app->safe_entered_at_sample;
        z->clear = 0u; /* a command, not a state */
        z->non_finite_rejected = app->non_finite_rejected;
#undef z
        break;
    }
    case OD_DRIVE_TRACE_IDX:
        m->x2300_Trace.state = app->trace.status;
        m->x2300_Trace.captured_bytes = trace_size_bytes(&app->trace);
        m->x2300_Trace.trigger_row = app->trace.status == (uint8_t)TRACE_DONE ? trace_trigger_index(&app->trace) : 0u;
        break;
    case OD_DRIVE_TRACE_BUFFER_IDX: {
        co_domain_t *dm = &m->x2301_trace_buffer;
        trace_linearise(app);
        dm->data = (uint8_t *)app->trace.buffer;
        dm->size = trace_size_bytes(&app->trace);
        dm->capacity = 0u;
        break;
    }
    case OD_DRIVE_LIVE_TRACE_IDX:
        m->x2302_live_trace.value_1 = drive_signal(d, (trace_signal_t)m->x2302_live_trace.live_signal_1);
        m->x2302_live_trace.value_2 = drive_signal(d, (trace_signal_t)m->x2302_live_trace.live_signal_2);
        break;
    default: break;
    }
}

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

static void count_late(drive_app_t *app, uint8_t reason, uint16_t sample_index, uint8_t sync_counter)
{
    ++app->late;
    const uint8_t msef[5] = {(uint8_t)sample_index, (uint8_t)(sample_index >> 8), reason, sync_counter,
                             app->last_sync_counter};
    meas_error(app, DRIVE_EMCY_MEAS_LATE, msef);
}

static void count_lost(drive_app_t *app, uint32_t missing, uint16_t sample_index, uint8_t sync_counter)
{
    app->lost += missing;
    const uint16_t m16 = missing > 0xFFFFu ? 0xFFFFu : (uint16_t)missing;
    const uint8_t msef[5] = {(uint8_t)sample_index, (uint8_t)(sample_index >> 8), (uint8_t)m16, (uint8_t)(m16 >> 8),
                             sync_counter};
    meas_error(app, DRIVE_EMCY_MEAS_LOST, msef);
}

static void reset_sequencing(drive_app_t *app)
{
    app->rpdo1_fresh = 0u;
    app->have_last = 0u;
    app->sync_seen = 0u;
    app->meas_seen = 0u; /* the measurement timeout re-arms at the next measurement */
    app->syncs_without_meas = 0u;
}

/* Non-finite measurement values of the step just run: EMCY 0xFF05 (after the
 * command and the deferred EMCYs), cleared by the next step without any. */
static void report_non_finite(drive_app_t *app, uint16_t sample_index)
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

/* ------------------------------------------------------------------ step cost */

static void reset_step_cost(drive_app_t *app)
{
    app->step_cycles_last = app->step_cycles_max = app->steps_measured = 0u;
    app->step_cycles_sum = 0u;
}

static void count_step_cost(drive_app_t *app, uint32_t cycles)
{
    app->step_cycles_last = cycles;
    if (cycles > app->step_cycles_max) app->step_cycles_max = cycles;
    app->step_cycles_sum += cycles;
    ++app->steps_measured;
}

/* ------------------------------------------------------------------ current step */

/* The core runs for the angle, the dq currents, the speed estimate and its
 * bookkeeping; its controller output is discarded and its memory cleared (no
 * wind-up, clean restart when the loop is closed again).  Returns the trace
 * recorder, detached meanwhile: the caller samples it with its own voltages. */
static trace_recorder_t *core_step_without_output(drive_app_t *app)
{
    drive_t *d = &app->drv;
    trace_recorder_t *rec = d->trace;
    d->trace = NULL;
    drive_current_step(d, &app->meas, &app->cmd);
    d->trace = rec;
    drive_reset_controller_memory(d);
    return rec;
}

static void open_loop_step(drive_app_t *app, const od_drive_mfr_t *m)
{
    drive_t *d = &app->drv;
    drive_state_t *s = &d->st;
    trace_recorder_t *rec = core_step_without_output(app);

    float vd = m->x2202_References.v_d_open_V;
    float vq = m->x2202_References.v_q_open_V;
    if (!is_finite_f(vd)) {
        vd = 0.0f;
        ++app->non_finite_rejected;
    }
    if (!is_finite_f(vq)) {
        vq = 0.0f;
        ++app->non_finite_rejected;
    }
    s->out.v_limited = dq_limit_voltage(&vd, &vq, d->cfg.Vmax_V, d->cfg.vlimit_radial);
    const float cs = cosf(s->theta_e_rad);
    const float sn = sinf(s->theta_e_rad);
    s->out.v_d_V = s->out.v_d_star_V = vd;
    s->out.v_q_V = s->out.v_q_star_V = vq;
    s->out.v_d_ff_V = s->out.v_q_ff_V = 0.0f;
    dq_inv_park(vd, vq, cs, sn, &s->out.v_alpha_V, &s->out.v_beta_V);
    s->signals[TRACE_SIG_VQ] = vq;
    s->signals[TRACE_SIG_VD] = vd;
    s->signals[TRACE_SIG_VQ_STAR] = vq;
    s->signals[TRACE_SIG_VD_STAR] = vd;
    s->signals[TRACE_SIG_V_ALPHA] = s->out.v_alpha_V;
    s->signals[TRACE_SIG_V_BETA] = s->out.v_beta_V;
    s->signals[TRACE_SIG_V_LIMITED] = (float)s->out.v_limited;
    if (rec != NULL) trace_sample(rec, s->signals);
    app->cmd.v_alpha_V = s->out.v_alpha_V;
    app->cmd.v_beta_V = s->out.v_beta_V;
}

/* ------------------------------------------------------------------ CiA 402 (drive_app.h) */

#define CIA402_INC_PER_RAD 10430.378f          /* 65536 increments per mechanical revolution / (2 pi) */
#define CIA402_STOPPED_FRACTION_OF_RATED 0.02f /* quick stop done: |iq| <= 2 % of 0x6075 */

static void zero_voltage(drive_t *d);
static void clear_control_memory(drive_t *d);

static int pdo_maps(const co_pdo_t *p, uint16_t index)
{
    for (uint8_t i = 0; i < p->count; ++i)
        if (p->entry[i] != NULL && p->entry[i]->index == index) return 1;
    return 0;
}

/* Every valid event-driven TPDO that maps the statusword or the mode shown goes out (state and mode
 * changes, NMT start). */
static void send_statusword(co_node_t *node)
{
    for (uint8_t n = 0; n < CO_NUM_PDO; ++n) {
        const co_pdo_t *p = &node->tpdo[n];
        if (p->valid && p->trans_type >= 254u &&
            (pdo_maps(p, OD_DRIVE_STATUSWORD_IDX) || pdo_maps(p, OD_DRIVE_MODES_OF_OPERATION_DISPLAY_IDX)))
            co_tpdo_request(node, n);
    }
}

/* The state changed: the statusword follows; a power stage switched off commands 0 V at once. */
static void cia402_changed(drive_app_t *app, co_node_t *node, int was_powered)
{
    od_drive_mfr_t *m = mfr_of(node);
    m->x6041_Statusword = cia402_device_statusword(&app->cia402);
    if (was_powered && !cia402_device_power_enabled(&app->cia402)) {
        clear_control_memory(&app->drv);
        zero_voltage(&app->drv);
        app->cmd.v_alpha_V = 0.0f;
        app->cmd.v_beta_V = 0.0f;
        m->x2102_voltage_command.v_alpha_V = 0.0f;
        m->x2102_voltage_command.v_beta_V = 0.0f;
        co_tpdo_request(node, 0);
    }
    send_statusword(node);
}

static int heartbeat_lost(const co_node_t *node);
static void leave_safe_state(drive_app_t *app, co_node_t *node);

/* A controlword arrived (SDO or RPDO). */
static void cia402_on_controlword(drive_app_t *app, co_node_t *node)
{
    const int was_powered = cia402_device_power_enabled(&app->cia402);
    const uint8_t before = app->cia402.state;
    if (!cia402_device_controlword(&app->cia402, mfr_of(node)->x6040_Controlword, !heartbeat_lost(node))) return;
    /* transition 15 (the device is already in SWITCH ON DISABLED): the fault reset clears the safe state
     * and its EMCY first, then the statusword goes out like at any other state change */
    if (before == (uint8_t)CIA402_FAULT) leave_safe_state(app, node);
    cia402_changed(app, node, was_powered);
}

static void cia402_reset(drive_app_t *app, co_node_t *node)
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
static int cia402_references(drive_app_t *app, const od_drive_mfr_t *m)
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

static void cia402_refresh(const drive_app_t *app, od_drive_mfr_t *m, uint16_t index)
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
static void cia402_check_stopped(drive_app_t *app, co_node_t *node)
{
    if (app->cia402.state != (uint8_t)CIA402_QUICK_STOP_ACTIVE) return;
    const float band_A = CIA402_STOPPED_FRACTION_OF_RATED * (float)mfr_of(node)->x6075_motor_rated_current * 1e-3f;
    const float iq = app->drv.st.i_q_A;
    if (iq <= band_A && iq >= -band_A && cia402_device_stopped(&app->cia402)) cia402_changed(app, node, 0);
}

/* ------------------------------------------------------------------ safe state */

/* Zero voltage in the state and its trace signals: they show what the drive commanded. */
static void zero_voltage(drive_t *d)
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
static void clear_control_memory(drive_t *d)
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
static void safe_step(drive_app_t *app)
{
    drive_t *d = &app->drv;
    trace_recorder_t *rec = core_step_without_output(app);
    clear_control_memory(d);
    zero_voltage(d);
    if (rec != NULL) trace_sample(rec, d->st.signals);
    app->cmd.v_alpha_V = 0.0f;
    app->cmd.v_beta_V = 0.0f;
}

static int heartbeat_lost(const co_node_t *node)
{
    for (uint8_t i = 0; i < CO_HB_CONSUMERS; ++i)
        if (node->hb[i].active && node->hb[i].timed_out) return 1;
    return 0;
}

static uint16_t safe_emcy_code(uint8_t reason)
{
    return reason == (uint8_t)OD_DRIVE_REASON_HEARTBEAT_LOST ? DRIVE_EMCY_SAFE_HEARTBEAT : DRIVE_EMCY_SAFE_MEAS_TIMEOUT;
}

static void enter_safe_state(drive_app_t *app, co_node_t *node, uint8_t reason)
{
    if (app->safe_reason != (uint8_t)OD_DRIVE_REASON_NONE) return; /* latched: the first reason stays */
    app->safe_reason = reason;
    ++app->safe_entries;
    const uint16_t si = app->have_good ? app->good_sample_index : 0u;
    app->safe_entered_at_sample = si;
    /* zero volts now: a plant still producing periods applies them at its next SYNC */
    clear_control_memory(&app->drv);
    zero_voltage(&app->drv);
    app->cmd.v_alpha_V = 0.0f;
    app->cmd.v_beta_V = 0.0f;
    od_drive_mfr_t *m = mfr_of(node);
    m->x2102_voltage_command.v_alpha_V = 0.0f;
    m->x2102_voltage_command.v_beta_V = 0.0f;
    co_tpdo_request(node, 0);
    const uint8_t msef[5] = {(uint8_t)si, (uint8_t)(si >> 8), reason, 0, 0};
    emcy_send(app, safe_emcy_code(reason), msef);
    /* CiA 402: the fault reaction (0 V, above) is done: FAULT, with the EMCY code as the error code */
    m->x603F_error_code = safe_emcy_code(reason);
    if (cia402_device_fault(&app->cia402)) cia402_changed(app, node, 0);
}

static void leave_safe_state(drive_app_t *app, co_node_t *node)
{
    const uint8_t reason = app->safe_reason;
    if (reason == (uint8_t)OD_DRIVE_REASON_NONE) return;
    app->safe_reason = (uint8_t)OD_DRIVE_REASON_NONE;
    app->syncs_without_meas = 0u;
    co_emcy_clear(node, safe_emcy_code(reason));
    mfr_of(node)->x603F_error_code = 0u;
    if (cia402_device_fault_reset(&app->cia402)) cia402_changed(app, node, 0);
}

/* ------------------------------------------------------------------ current step (continued) */

static void current_step(drive_app_t *app)
{
    co_node_t *node = app->node;
    if (node == NULL) return;
    od_drive_mfr_t *m = mfr_of(node);
    drive_t *d = &app->drv;

    /* measurement: a non-finite field (PDOs bypass the EDS limits) is replaced
     * by its last finite value */
    uint8_t bad = 0u;
#define x (&m->x2100_Measurement)
    if (is_finite_f(x->i_a_A))
        app->meas_good.i_a_A = x->i_a_A;
    else
        bad |= (uint8_t)DRIVE_NON_FINITE_I_A;
    if (is_finite_f(x->i_b_A))
        app->meas_good.i_b_A = x->i_b_A;
    else
        bad |= (uint8_t)DRIVE_NON_FINITE_I_B;
    if (is_finite_f(x->theta_m_rad))
        app->meas_good.theta_m_rad = x->theta_m_rad;
    else
        bad |= (uint8_t)DRIVE_NON_FINITE_THETA;
    app->meas = app->meas_good;
    app->non_finite_mask = bad;
    if (bad == 0u) {
        app->have_good = 1u;
        app->good_sample_index = x->sample_index;
    } else {
        app->non_finite_rejected += (uint32_t)((bad & 1u) + ((bad >> 1) & 1u) + ((bad >> 2) & 1u));
    }
#undef x

    /* references (SDO or RPDO3 wrote them; PDO writes bypass the EDS limits:
     * non-finite values are ignored, and counted) */
#define r (&m->x2202_References)
    const uint8_t mode = r->mode;
    d->sp.mode = mode <= (uint8_t)DRIVE_MODE_POSITION ? mode : (uint8_t)DRIVE_MODE_CURRENT;
    uint32_t refs_bad = 0u;
    if (is_finite_f(r->iq_ref_A))
        d->sp.iq_ref_A = r->iq_ref_A;
    else
        ++refs_bad;
    if (is_finite_f(r->id_ref_A))
        d->sp.id_ref_A = r->id_ref_A;
    else
        ++refs_bad;
    if (is_finite_f(r->speed_ref_rad_s))
        d->sp.speed_ref_rad_s = r->speed_ref_rad_s;
    else
        ++refs_bad;
    if (is_finite_f(r->position_ref_rad))
        d->sp.position_ref_rad = r->position_ref_rad;
    else
        ++refs_bad;
    app->non_finite_rejected += refs_bad;

#undef r
    app->open_loop =
        (uint8_t)(m->x2200_Controller.controller == OD_DRIVE_CONTROLLER_OPEN_LOOP || mode == OD_DRIVE_MODE_OPEN_LOOP);
    if (m->x2200_Controller.controller != app->cost_controller) {
        reset_step_cost(app);
        app->cost_controller = m->x2200_Controller.controller;
    }
    /* CiA 402: a quick stop that has ended leaves before this command; then the mode's references */
    cia402_check_stopped(app, node);
    const int powered = cia402_references(app, m);
    const uint32_t c0 = app->cycles_fn != NULL ? app->cycles_fn(app->cycles_user) : 0u;
    if (app->safe_reason != (uint8_t)OD_DRIVE_REASON_NONE || !powered ||
        (app->open_loop && app->cia402.state == (uint8_t)CIA402_QUICK_STOP_ACTIVE)) {
        safe_step(app); /* 0 V */
    } else if (app->open_loop) {
        open_loop_step(app, m);
    } else {
        drive_current_step(d, &app->meas, &app->cmd);
    }
    if (app->cycles_fn != NULL) count_step_cost(app, app->cycles_fn(app->cycles_user) - c0);
    ++app->current_steps;

    m->x2102_voltage_command.v_alpha_V = app->cmd.v_alpha_V;
    m->x2102_voltage_command.v_beta_V = app->cmd.v_beta_V;
    co_tpdo_request(node, 0); /* event-driven: goes out now */

    if (node->tpdo[1].valid) {
        uint16_t dec = m->x2302_live_trace.decimation;
        if (dec == 0u) dec = 1u;
        if (++app->live_count >= dec) {
            app->live_count = 0u;
            co_tpdo_request(node, 1); /* values refreshed by pre_read */
        }
    }
}

void drive_app_current_step(drive_app_t *app)
{
    if (app->node == NULL) return;
    current_step(app);
    report_non_finite(app, mfr_of(app->node)->x2100_Measurement.sample_index);
}

static void on_measurement(drive_app_t *app, co_node_t *node)
{
    od_drive_mfr_t *m = mfr_of(node);
    const uint16_t si = m->x2100_Measurement.sample_index;
    const uint8_t sc = m->x2100_Measurement.sync_counter;
    const uint32_t late0 = app->late, lost0 = app->lost;
    const uint8_t was_active = app->meas_error_active;
    app->defer_emcy = 1u;
    app->n_pending = 0u;
    /* the measurement timeout is armed by a measurement, and disarmed by one whose status says the plant
     * holds (plant.eds 0x2100:05 bit 1, end of a run segment): SYNCs after that are not the plant's */
    app->meas_seen = (m->x2100_Measurement.status & PLANT_STATUS_HOLDING_BIT) ? 0u : 1u;
    app->syncs_without_meas = 0u;

    if (!app->rpdo1_fresh) count_late(app, DRIVE_LATE_RPDO2_WITHOUT_RPDO1, si, sc);
    app->rpdo1_fresh = 0u;

    int duplicate = 0;
    if (app->have_last) {
        const uint16_t delta = (uint16_t)(si - app->last_sample_index);
        duplicate = delta == 0u && app->old_run == 0u;
        if (delta == 0u || delta >= 0x8000u) {
            count_late(app, DRIVE_LATE_DUPLICATE_OR_OLD, si, sc);
            /* stay on the newest index; a restarted plant is followed after
             * three consecutive "old" samples */
            if (++app->old_run >= 3u) {
                app->last_sample_index = si;
                app->old_run = 0u;
            }
        } else {
            if (delta > 1u) count_lost(app, (uint32_t)delta - 1u, si, sc);
            app->last_sample_index = si;
            app->old_run = 0u;
        }
    } else {
        app->have_last = 1u;
        app->last_sample_index = si;
        app->old_run = 0u;
    }
    const uint8_t sync_ov = (uint8_t)co_od_get_u32(node->od, OD_DRIVE_SYNCHRONOUS_COUNTER_OVERFLOW_VALUE_IDX, 0);
    if (app->sync_seen && sync_ov >= 2u && sc != app->last_sync_counter)
        count_late(app, DRIVE_LATE_SYNC_MISMATCH, si, sc);

    const int clean = app->late == late0 && app->lost == lost0;
    if (clean) app->meas_error_active = 0u;
    if (duplicate) { /* the sample just answered, again: its command is out; a second step would advance the
                      * controller's state twice and send the plant a second command */
        flush_emcy(app);
        return;
    }
    current_step(app); /* command out first */
    flush_emcy(app);
    report_non_finite(app, si);
    if (clean && was_active) {
        co_emcy_clear(node, DRIVE_EMCY_MEAS_LOST);
        co_emcy_clear(node, DRIVE_EMCY_MEAS_LATE);
    }
}

/* ------------------------------------------------------------------ hooks */

static uint32_t hk_pre_write(void *user, co_node_t *node, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    drive_app_t *app = (drive_app_t *)user;
    const uint16_t idx = e->index;
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
    if ((idx < OD_DRIVE_CONTROLLER_IDX || idx > OD_DRIVE_LIVE_TRACE_IDX) && !is_law_record(idx)) return 0;
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

    if (is_law_record(idx)) { /* a law's command, or its parameters */
        const current_law_entry_t *law = commanded_law(idx);
        if (law != NULL) {
            const int open_loop = m->x2200_Controller.controller == OD_DRIVE_CONTROLLER_OPEN_LOOP;
            const current_law_verdict_t v =
                drive_law_command(&app->drv, law, od_record(node, &cand, idx), e->subindex, open_loop, 0);
            if (v != CURRENT_LAW_NOT_COMMAND) return abort_of(v);
        }
        return check_config(app, &cand, 0);
    }
    if (idx >= OD_DRIVE_CONTROLLER_IDX && idx <= OD_DRIVE_OUTER_LOOPS_IDX)
        return check_config(app, &cand,
                            idx == OD_DRIVE_CONTROLLER_IDX && e->subindex == OD_DRIVE_CONTROLLER_CONTROLLER_SUB);

    if (idx == OD_DRIVE_SAFE_STATE_IDX && e->subindex == OD_DRIVE_SAFE_STATE_CLEAR_SUB) {
        if (data[0] > 1u) return CO_ABORT_INVALID_VALUE; /* 0: no action (what a read gives back), 1: clear */
        if (data[0] == 1u && app->safe_reason != (uint8_t)OD_DRIVE_REASON_NONE && heartbeat_lost(node))
            return CO_ABORT_DATA_STATE; /* the cause persists */
        return 0;
    }

    if (idx == OD_DRIVE_TRACE_IDX) {
        const uint8_t v = data[0];
        switch (e->subindex) {
        case OD_DRIVE_TRACE_STATE_SUB: {
            if (v == (uint8_t)TRACE_IDLE) return 0;
            if (v != (uint8_t)TRACE_ARMED) return CO_ABORT_INVALID_VALUE; /* 2, 3 are read-only states */
            trace_config_t tc;
            return trace_config_from_od(&cand, &tc);
        }
        case OD_DRIVE_TRACE_TRIGGER_SIGNAL_SUB:
        case OD_DRIVE_TRACE_SIGNAL_1_SUB:
        case OD_DRIVE_TRACE_SIGNAL_2_SUB:
        case OD_DRIVE_TRACE_SIGNAL_3_SUB:
        case OD_DRIVE_TRACE_SIGNAL_4_SUB:
        case OD_DRIVE_TRACE_SIGNAL_5_SUB:
        case OD_DRIVE_TRACE_SIGNAL_6_SUB:
        case OD_DRIVE_TRACE_SIGNAL_7_SUB:
        case OD_DRIVE_TRACE_SIGNAL_8_SUB: return v >= (uint8_t)TRACE_SIG_COUNT ? CO_ABORT_VALUE_HIGH : 0u;
        default: return 0;
        }
    }
    if (idx == OD_DRIVE_LIVE_TRACE_IDX &&
        (e->subindex == OD_DRIVE_LIVE_TRACE_LIVE_SIGNAL_1_SUB || e->subindex == OD_DRIVE_LIVE_TRACE_LIVE_SIGNAL_2_SUB))
        return data[0] >= (uint8_t)TRACE_SIG_COUNT ? CO_ABORT_VALUE_HIGH : 0u;
    return 0;
}

static void hk_post_write(void *user, co_node_t *node, const co_od_entry_t *e)
{
    drive_app_t *app = (drive_app_t *)user;
    od_drive_mfr_t *m = mfr_of(node);
    const uint16_t idx = e->index;
    switch (idx) {
    case OD_DRIVE_CONTROLWORD_IDX: cia402_on_controlword(app, node); return;
    case OD_DRIVE_MODES_OF_OPERATION_IDX: /* in effect from the next step */
        m->x6061_modes_of_operation_display = m->x6060_modes_of_operation;
        send_statusword(node);
        return;
    case OD_DRIVE_QUICK_STOP_OPTION_CODE_IDX:
        app->cia402.cfg.quick_stop_option = m->x605A_quick_stop_option_code;
        return;
    default: break;
    }
    const current_law_entry_t *law = commanded_law(idx);
    if (law != NULL) {
        const int open_loop = m->x2200_Controller.controller == OD_DRIVE_CONTROLLER_OPEN_LOOP;
        if (drive_law_command(&app->drv, law, od_record(node, m, idx), e->subindex, open_loop, 1) !=
            CURRENT_LAW_NOT_COMMAND)
            return;
    }
    if (idx == OD_DRIVE_SAFE_STATE_IDX && e->subindex == OD_DRIVE_SAFE_STATE_CLEAR_SUB) {
        const uint8_t v = m->x2209_safe_state.clear;
        m->x2209_safe_state.clear = 0u; /* a command, not a state */
        if (v == 1u) leave_safe_state(app, node);
        return;
    }
    const int is_config =
        idx == OD_DRIVE_CONTROLLER_IDX || idx == OD_DRIVE_OUTER_LOOPS_IDX || is_law_record(idx) ||
        (idx == OD_DRIVE_REFERENCES_IDX && (e->subindex == OD_DRIVE_REFERENCES_PROFILE_SPEED_RAD_S_SUB ||
                                            e->subindex == OD_DRIVE_REFERENCES_PROFILE_ACCEL_RAD_S2_SUB));
    if (is_config) { /* the one config-change path: copy, and recompute at the next step if it changed */
        drive_config_t c = app->drv.cfg;
        od_to_config(m, &c, c.controller);
        int changed = memcmp(&c, &app->drv.cfg, sizeof c) != 0;
        if (changed) app->drv.cfg = c;
        changed |= sync_law_record(app); /* the selected law's record (also when the selection changed) */
        if (changed) drive_apply_config(&app->drv);
        return;
    }
    if (idx == OD_DRIVE_TRACE_IDX && e->subindex == OD_DRIVE_TRACE_STATE_SUB) {
        if (m->x2300_Trace.state == (uint8_t)TRACE_ARMED) {
            trace_config_t tc;
            if (trace_config_from_od(m, &tc) == 0u && trace_arm(&app->trace, &tc) == 0) {
                app->trace_linear = 0u;
            }
        } else {
            trace_stop(&app->trace);
            app->trace_linear = 0u;
        }
        m->x2300_Trace.state = app->trace.status;
        return;
    }
    if (idx == OD_DRIVE_LIVE_TRACE_IDX && e->subindex == OD_DRIVE_LIVE_TRACE_DECIMATION_SUB) app->live_count = 0u;
}

static void hk_pre_read(void *user, co_node_t *node, const co_od_entry_t *e)
{
    drive_app_t *app = (drive_app_t *)user;
    if (e->index < OD_DRIVE_ONLINE_TUNING_IDX) return; /* fast path: 0x2102 of TPDO1 */
    if (e->index >= OD_DRIVE_ERROR_CODE_IDX)
        cia402_refresh(app, mfr_of(node), e->index);
    else
        refresh(app, mfr_of(node), e->index);
}

static void hk_on_sync(void *user, co_node_t *node, uint8_t counter)
{
    drive_app_t *app = (drive_app_t *)user;
    if (app->rpdo1_fresh) {
        /* the currents of the previous sample never got their RPDO2 */
        app->rpdo1_fresh = 0u;
        count_late(app, DRIVE_LATE_RPDO1_WITHOUT_RPDO2, app->last_sample_index, counter);
    }
    app->sync_seen = 1u;
    app->last_sync_counter = counter;
    /* measurement timeout: SYNCs since the last measurement */
    if (node->nmt == CO_NMT_OPERATIONAL && app->meas_seen) {
        if (app->syncs_without_meas < 0xFFFFu) ++app->syncs_without_meas;
        const uint16_t n = mfr_of(node)->x2209_safe_state.meas_timeout_periods;
        if (n != 0u && app->syncs_without_meas >= n) enter_safe_state(app, node, (uint8_t)OD_DRIVE_REASON_MEAS_TIMEOUT);
    }
}

static void hk_on_rpdo(void *user, co_node_t *node, uint8_t pdo)
{
    drive_app_t *app = (drive_app_t *)user;
    app->node = node;
    if (pdo == 0u) {
        if (app->rpdo1_fresh) {
            od_drive_mfr_t *m = mfr_of(node);
            count_late(app, DRIVE_LATE_RPDO1_WITHOUT_RPDO2, m->x2100_Measurement.sample_index,
                       m->x2100_Measurement.sync_counter);
        }
        app->rpdo1_fresh = 1u;
    } else if (pdo == 1u) {
        on_measurement(app, node);
    } else if (pdo_maps(&node->rpdo[pdo], OD_DRIVE_CONTROLWORD_IDX)) {
        cia402_on_controlword(app, node); /* RPDO4 by default; the target torque is read by the next step */
    }
    /* pdo 2 (references): read by the next step */
}

static void hk_on_nmt(void *user, co_node_t *node, co_nmt_state_t state)
{
    drive_app_t *app = (drive_app_t *)user;
    reset_sequencing(app);
    /* CiA 402: leaving OPERATIONAL disables the power stage (the "disable voltage" reaction of 0x6007) */
    if (state != CO_NMT_OPERATIONAL) {
        const int was_powered = cia402_device_power_enabled(&app->cia402);
        if (cia402_device_disable_voltage(&app->cia402)) cia402_changed(app, node, was_powered);
    }
    /* started while the plant's heartbeat is still lost: not a state to run in */
    if (state == CO_NMT_OPERATIONAL && heartbeat_lost(node))
        enter_safe_state(app, node, (uint8_t)OD_DRIVE_REASON_HEARTBEAT_LOST);
    if (state == CO_NMT_OPERATIONAL) send_statusword(node);
}

static void hk_on_hb_timeout(void *user, co_node_t *node, uint8_t node_id)
{
    drive_app_t *app = (drive_app_t *)user;
    (void)node_id; /* the stack's EMCY 0x8130 names it */
    if (node->nmt == CO_NMT_OPERATIONAL) enter_safe_state(app, node, (uint8_t)OD_DRIVE_REASON_HEARTBEAT_LOST);
}

static void hk_on_reset(void *user, co_node_t *node, int communication_only)
{
    drive_app_t *app = (drive_app_t *)user;
    od_drive_mfr_t *m = mfr_of(node);
    app->node = node;
    if (!communication_only) {
        /* reset application: OD defaults -> fresh firmware core */
        drive_config_t cfg;
        drive_default_config(&cfg);
        od_to_config(m, &cfg, cfg.controller);
        drive_init(&app->drv, &cfg);
        if (sync_law_record(app)) drive_apply_config(&app->drv);
        trace_init(&app->trace);
        drive_attach_trace(&app->drv, &app->trace);
        app->current_steps = app->lost = app->late = app->emcy_raised = 0u;
        app->meas_error_active = 0u;
        app->safe_entries = 0u;
        app->safe_entered_at_sample = 0u;
        app->have_good = 0u;
        app->good_sample_index = 0u;
        app->non_finite_rejected = 0u;
        memset(&app->meas_good, 0, sizeof app->meas_good);
        app->open_loop = 0u;
        app->trace_linear = 0u;
        app->live_count = 0u;
        reset_step_cost(app);
        memset(&app->meas, 0, sizeof app->meas);
        memset(&app->cmd, 0, sizeof app->cmd);
    }
    reset_sequencing(app);
    /* both resets leave the safe state (the stack has forgotten the active EMCYs), and the
     * CiA 402 state machine starts again in SWITCH ON DISABLED */
    app->safe_reason = (uint8_t)OD_DRIVE_REASON_NONE;
    cia402_reset(app, node);
    app->non_finite_mask = 0u;
    app->non_finite_active = 0u;
    m->x2301_trace_buffer.data = (uint8_t *)app->trace.buffer;
    m->x2301_trace_buffer.size = 0u;
    m->x2301_trace_buffer.capacity = 0u;
}

static const co_hooks_t g_hooks = {
    .pre_write = hk_pre_write,
    .post_write = hk_post_write,
    .pre_read = hk_pre_read,
    .on_sync = hk_on_sync,
    .on_rpdo = hk_on_rpdo,
    .on_nmt = hk_on_nmt,
    .on_reset = hk_on_reset,
    .on_hb_timeout = hk_on_hb_timeout,
};

const co_hooks_t *drive_app_hooks(void) { return &g_hooks; }

/* ------------------------------------------------------------------ API */

void drive_app_init(drive_app_t *app)
{
    memset(app, 0, sizeof *app);
    drive_config_t cfg;
    drive_default_config(&cfg);
    drive_init(&app->drv, &cfg);
    trace_init(&app->trace);
    drive_attach_trace(&app->drv, &app->trace);
}

void drive_app_bind(drive_app_t *app, co_node_t *node) { app->node = node; }

void drive_app_set_cycle_counter(drive_app_t *app, drive_app_cycles_fn fn, void *user, uint32_t clock_Hz)
{
    app->cycles_fn = fn;
    app->cycles_user = user;
    app->cycle_clock_Hz = clock_Hz;
    reset_step_cost(app);
}

void drive_app_load_config(drive_app_t *app)
{
    if (app->node == NULL) return;
    od_to_config(mfr_of(app->node), &app->drv.cfg, app->drv.cfg.controller);
    (void)sync_law_record(app);
    drive_apply_config(&app->drv);
}
