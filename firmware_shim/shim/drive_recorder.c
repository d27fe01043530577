/* drive_recorder.c - the recorders, a component of the drive app (drive_recorder.h): the trace recorder (0x2300 config,
 * arm, 0x2301 the buffer linearised for its upload), the live trace (0x2302) and the step cost
 * (0x2208 statistics).  Portable: no OS headers, no allocation, float32. */
#include <string.h>

#include "co_field_map.h"
#include "drive_od.h"
#include "drive_recorder.h"

/* 0x2300's read-only entries <- drive_recorder_t.trace_status (their names: drive.eds). */
#define TRACE_STATUS_ROW(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW(od_drive_mfr_t, drive_app_trace_status_t, record, field),
#define STEP_COST_ROW(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW(od_drive_mfr_t, drive_app_step_cost_t, record, field),
static const co_field_map_t trace_status_rows[] = {OD_DRIVE_TRACE_STATUS(TRACE_STATUS_ROW)};
static const co_field_map_t step_cost_rows[] = {OD_DRIVE_STEP_COST_STATUS(STEP_COST_ROW)};
#undef TRACE_STATUS_ROW
#undef STEP_COST_ROW

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
static void trace_linearise(drive_recorder_t *rec)
{
    trace_recorder_t *r = &rec->trace;
    if (rec->linear || r->status != (uint8_t)TRACE_DONE) return;
    const uint32_t n = r->rows_captured * r->n_channels;
    const uint32_t k = r->start_row * r->n_channels;
    if (k != 0u && k < n) {
        reverse_f(r->buffer, 0u, k);
        reverse_f(r->buffer, k, n);
        reverse_f(r->buffer, 0u, n);
    }
    r->start_row = 0u;
    if (!co_host_is_little()) {
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
    rec->linear = 1u;
}

/* A write to 0x2300 or 0x2302: 0 or the SDO abort code (arming is judged on the OD with the value stored). */
static uint32_t trace_check(void *object, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    const drive_recorder_t *rec = (const drive_recorder_t *)object;
    const uint16_t idx = e->index;
    if (idx == OD_DRIVE_TRACE_IDX) {
        const uint8_t v = data[0];
        switch (e->subindex) {
        case OD_DRIVE_TRACE_STATE_SUB: {
            if (v == (uint8_t)TRACE_IDLE) return 0;
            if (v != (uint8_t)TRACE_ARMED) return CO_ABORT_INVALID_VALUE; /* 2, 3 are read-only states */
            od_drive_mfr_t cand;
            if (!drive_od_candidate(rec->node, e, data, len, &cand)) return 0;
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

/* After a write to 0x2300 (state: arm, stop) or 0x2302 (decimation). */
static void trace_written(void *object, const co_od_entry_t *e)
{
    drive_recorder_t *rec = (drive_recorder_t *)object;
    od_drive_mfr_t *m = mfr_of(rec->node);
    const uint16_t idx = e->index;
    if (idx == OD_DRIVE_TRACE_IDX && e->subindex == OD_DRIVE_TRACE_STATE_SUB) {
        if (m->x2300_Trace.state == (uint8_t)TRACE_ARMED) {
            trace_config_t tc;
            if (trace_config_from_od(m, &tc) == 0u && trace_arm(&rec->trace, &tc) == 0) {
                rec->linear = 0u;
            }
        } else {
            trace_stop(&rec->trace);
            rec->linear = 0u;
        }
        m->x2300_Trace.state = rec->trace.status;
        return;
    }
    if (idx == OD_DRIVE_LIVE_TRACE_IDX && e->subindex == OD_DRIVE_LIVE_TRACE_DECIMATION_SUB) rec->live_count = 0u;
}

/* A read of 0x2300, 0x2301 or 0x2302 (0x2302 by TPDO2 too: the live values). */
static void trace_read(void *object, const co_od_entry_t *e)
{
    drive_recorder_t *rec = (drive_recorder_t *)object;
    od_drive_mfr_t *m = mfr_of(rec->node);
    switch (e->index) {
    case OD_DRIVE_TRACE_IDX:
        m->x2300_Trace.state = rec->trace.status;
        rec->trace_status.captured_bytes = trace_size_bytes(&rec->trace);
        rec->trace_status.trigger_row =
            rec->trace.status == (uint8_t)TRACE_DONE ? trace_trigger_index(&rec->trace) : 0u;
        co_field_map_to_od(trace_status_rows, sizeof trace_status_rows / sizeof trace_status_rows[0], m,
                           &rec->trace_status);
        break;
    case OD_DRIVE_TRACE_BUFFER_IDX: {
        co_domain_t *dm = &m->x2301_trace_buffer;
        trace_linearise(rec);
        dm->data = (uint8_t *)rec->trace.buffer;
        dm->size = trace_size_bytes(&rec->trace);
        dm->capacity = 0u;
        break;
    }
    case OD_DRIVE_LIVE_TRACE_IDX:
        m->x2302_live_trace.value_1 = drive_signal(rec->drv, (trace_signal_t)m->x2302_live_trace.live_signal_1);
        m->x2302_live_trace.value_2 = drive_signal(rec->drv, (trace_signal_t)m->x2302_live_trace.live_signal_2);
        break;
    default: break;
    }
}

/* 0x2208 is read: the mean of the steps measured, the counter's clock (0 without a counter). */
static void cost_read(void *object, const co_od_entry_t *e)
{
    drive_recorder_t *rec = (drive_recorder_t *)object;
    drive_app_step_cost_t *c = &rec->step_cost;
    (void)e;
    c->step_cycles_mean = c->steps_measured == 0u ? 0.0f : (float)rec->step_cycles_sum / (float)c->steps_measured;
    c->cycle_clock_Hz = rec->cycles_fn == NULL ? 0u : rec->cycle_clock_Hz;
    co_field_map_to_od(step_cost_rows, sizeof step_cost_rows / sizeof step_cost_rows[0], mfr_of(rec->node), c);
}

void drive_recorder_bind(drive_recorder_t *rec, co_node_t *node)
{
    rec->node = node;
    rec->ext_trace = (co_od_ext_t){rec, trace_read, trace_check, trace_written};
    rec->ext_cost = (co_od_ext_t){rec, cost_read, NULL, NULL};
    (void)co_node_bind(node, OD_DRIVE_TRACE_IDX, &rec->ext_trace);
    (void)co_node_bind(node, OD_DRIVE_TRACE_BUFFER_IDX, &rec->ext_trace);
    (void)co_node_bind(node, OD_DRIVE_LIVE_TRACE_IDX, &rec->ext_trace);
    (void)co_node_bind(node, OD_DRIVE_STEP_COST_IDX, &rec->ext_cost);
}

void drive_recorder_init(drive_recorder_t *rec, drive_t *drv)
{
    rec->drv = drv;
    trace_init(&rec->trace);
    drive_attach_trace(drv, &rec->trace);
}

void drive_recorder_reset(drive_recorder_t *rec)
{
    trace_init(&rec->trace);
    drive_attach_trace(rec->drv, &rec->trace);
    rec->linear = 0u;
    rec->live_count = 0u;
    drive_recorder_reset_cost(rec);
}

void drive_recorder_publish_buffer(drive_recorder_t *rec)
{
    od_drive_mfr_t *m = mfr_of(rec->node);
    m->x2301_trace_buffer.data = (uint8_t *)rec->trace.buffer;
    m->x2301_trace_buffer.size = 0u;
    m->x2301_trace_buffer.capacity = 0u;
}

static int live_due(drive_recorder_t *rec)
{
    if (!rec->node->tpdo[1].valid) return 0;
    uint16_t dec = mfr_of(rec->node)->x2302_live_trace.decimation;
    if (dec == 0u) dec = 1u;
    if (++rec->live_count < dec) return 0;
    rec->live_count = 0u;
    return 1;
}

/* ------------------------------------------------------------------ step cost */

void drive_recorder_set_cycle_counter(drive_recorder_t *rec, drive_app_cycles_fn fn, void *user, uint32_t clock_Hz)
{
    rec->cycles_fn = fn;
    rec->cycles_user = user;
    rec->cycle_clock_Hz = clock_Hz;
    drive_recorder_reset_cost(rec);
}

void drive_recorder_begin(drive_recorder_t *rec, uint8_t controller)
{
    if (controller == rec->cost_controller) return;
    drive_recorder_reset_cost(rec);
    rec->cost_controller = controller;
}

void drive_recorder_reset_cost(drive_recorder_t *rec)
{
    rec->step_cost.step_cycles_last = rec->step_cost.step_cycles_max = rec->step_cost.steps_measured = 0u;
    rec->step_cycles_sum = 0u;
}

drive_recorder_step_t drive_recorder_end(drive_recorder_t *rec, uint32_t cycles)
{
    drive_recorder_step_t out = {0u, 0u, 0u};
    if (rec->cycles_fn != NULL) {
        rec->step_cost.step_cycles_last = cycles;
        if (cycles > rec->step_cost.step_cycles_max) rec->step_cost.step_cycles_max = cycles;
        rec->step_cycles_sum += cycles;
        ++rec->step_cost.steps_measured;
        out.counted = 1u;
        out.cycles = cycles;
    }
    out.live_due = (uint8_t)live_due(rec);
    return out;
}
