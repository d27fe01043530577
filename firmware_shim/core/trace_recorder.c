/* trace_recorder.c - triggered capture into a static buffer. */
#include "trace_recorder.h"

#include <string.h>

void trace_init(trace_recorder_t *rec)
{
    memset(rec, 0, sizeof(*rec));
    rec->status = (uint8_t)TRACE_IDLE;
}

int trace_arm(trace_recorder_t *rec, const trace_config_t *cfg)
{
    const uint8_t sig[TRACE_MAX_CHANNELS] = {cfg->signal_0, cfg->signal_1, cfg->signal_2, cfg->signal_3,
                                             cfg->signal_4, cfg->signal_5, cfg->signal_6, cfg->signal_7};
    uint8_t n = 0u;
    for (uint8_t c = 0u; c < TRACE_MAX_CHANNELS; ++c) {
        if (sig[c] == (uint8_t)TRACE_SIG_NONE) break;
        if (sig[c] >= (uint8_t)TRACE_SIG_COUNT) return -1;
        rec->channels[c] = sig[c];
        n++;
    }
    if (n == 0u || cfg->trigger_signal >= (uint8_t)TRACE_SIG_COUNT) return -1;
    const uint32_t depth = TRACE_BUFFER_SAMPLES / n;
    if (cfg->pretrigger_samples >= depth) return -1;
    rec->cfg_active = *cfg;
    if (rec->cfg_active.decimation == 0u) rec->cfg_active.decimation = 1u;
    rec->n_channels = n;
    rec->depth = depth;
    rec->head = 0u;
    rec->rows_written = 0u;
    rec->rows_after_trigger = 0u;
    rec->trigger_row = 0u;
    rec->start_row = 0u;
    rec->rows_captured = 0u;
    rec->decim_count = 0u;
    rec->have_prev = 0u;
    rec->status = (uint8_t)TRACE_ARMED;
    return 0;
}

void trace_stop(trace_recorder_t *rec) { rec->status = (uint8_t)TRACE_IDLE; }

static int trace_trigger_hit(trace_recorder_t *rec, float v)
{
    const trace_config_t *c = &rec->cfg_active;
    int hit = 0;
    if (c->trigger_edge == (uint8_t)TRACE_EDGE_IMMEDIATE) {
        hit = 1;
    } else if (rec->have_prev != 0u) {
        const float p = rec->prev_trigger_value;
        const int rise = (p < c->trigger_level) && (v >= c->trigger_level);
        const int fall = (p > c->trigger_level) && (v <= c->trigger_level);
        if (c->trigger_edge == (uint8_t)TRACE_EDGE_RISING)
            hit = rise;
        else if (c->trigger_edge == (uint8_t)TRACE_EDGE_FALLING)
            hit = fall;
        else
            hit = rise || fall;
    }
    rec->prev_trigger_value = v;
    rec->have_prev = 1u;
    return hit;
}

void trace_sample(trace_recorder_t *rec, const float signals[TRACE_SIG_COUNT])
{
    const uint8_t status = rec->status;
    if (status != (uint8_t)TRACE_ARMED && status != (uint8_t)TRACE_TRIGGERED) {
        return;
    }
    rec->decim_count++;
    if (rec->decim_count < rec->cfg_active.decimation) {
        return;
    }
    rec->decim_count = 0u;
    /* write one row */
    const uint32_t row = rec->head;
    float *dst = &rec->buffer[row * rec->n_channels];
    for (uint8_t c = 0u; c < rec->n_channels; ++c) {
        dst[c] = signals[rec->channels[c]];
    }
    rec->head = (row + 1u == rec->depth) ? 0u : row + 1u;
    rec->rows_written++;
    if (status == (uint8_t)TRACE_ARMED) {
        const float tv = signals[rec->cfg_active.trigger_signal];
        const int hit = trace_trigger_hit(rec, tv);
        /* the trigger is only accepted once the pre-trigger history is full */
        if (hit && rec->rows_written > rec->cfg_active.pretrigger_samples) {
            rec->status = (uint8_t)TRACE_TRIGGERED;
            rec->trigger_row = row;
            rec->rows_after_trigger = 1u;
        }
    } else {
        rec->rows_after_trigger++;
    }
    if (rec->status == (uint8_t)TRACE_TRIGGERED &&
        rec->rows_after_trigger >= rec->depth - rec->cfg_active.pretrigger_samples) {
        rec->start_row = (rec->trigger_row + rec->depth - rec->cfg_active.pretrigger_samples) % rec->depth;
        rec->rows_captured = rec->depth;
        rec->status = (uint8_t)TRACE_DONE;
    }
}

uint32_t trace_size_bytes(const trace_recorder_t *rec)
{
    if (rec->status != (uint8_t)TRACE_DONE) return 0u;
    return rec->rows_captured * rec->n_channels * 4u;
}

uint32_t trace_trigger_index(const trace_recorder_t *rec) { return rec->cfg_active.pretrigger_samples; }

size_t trace_read_bytes(const trace_recorder_t *rec, uint32_t offset, uint8_t *dst, size_t len)
{
    const uint32_t total = trace_size_bytes(rec);
    size_t n = 0u;
    while (n < len && offset < total) {
        const uint32_t fidx = offset / 4u; /* float index, linearised */
        const uint32_t lrow = fidx / rec->n_channels;
        const uint32_t ch = fidx % rec->n_channels;
        const uint32_t prow = (rec->start_row + lrow) % rec->depth;
        uint32_t bits;
        memcpy(&bits, &rec->buffer[prow * rec->n_channels + ch], sizeof(bits));
        dst[n] = (uint8_t)(bits >> (8u * (offset % 4u))); /* little-endian */
        n++;
        offset++;
    }
    return n;
}
