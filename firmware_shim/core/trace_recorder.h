/* trace_recorder.h - oscilloscope-style capture of the drive's own signals at
 * the current-loop rate into a fixed RAM buffer (no allocation).
 *
 * The signals are the drive's, whichever law runs: its measurements,
 * references and the law's command as current_law_out_t gives it.  A law's
 * own quantities are the status entries of its EDS record, traced by PDO
 * (its record's Trace= entries, a scenario's [trace]) like any entry. */
#ifndef TRACE_RECORDER_H
#define TRACE_RECORDER_H

#include <stddef.h>
#include <stdint.h>

#define TRACE_MAX_CHANNELS 8u
#define TRACE_BUFFER_SAMPLES 8192u /* floats, shared by all channels */

typedef enum {
    TRACE_SIG_NONE = 0,
    TRACE_SIG_IQ_REF,
    TRACE_SIG_IQ,
    TRACE_SIG_ID_REF,
    TRACE_SIG_ID,
    TRACE_SIG_VQ, /* total q voltage after limit (incl. feed-forward) */
    TRACE_SIG_VD,
    TRACE_SIG_VQ_STAR, /* decoupled q command actually applied (the law's v_q_star_V) */
    TRACE_SIG_VD_STAR,
    TRACE_SIG_V_ALPHA,
    TRACE_SIG_V_BETA,
    TRACE_SIG_OMEGA, /* estimated mechanical speed */
    TRACE_SIG_OMEGA_REF,
    TRACE_SIG_THETA, /* mechanical angle */
    TRACE_SIG_THETA_E,
    TRACE_SIG_POS_REF,
    TRACE_SIG_I_A,
    TRACE_SIG_I_B,
    TRACE_SIG_V_LIMITED, /* 1 when the law limited the vector to Vmax_V */
    TRACE_SIG_COUNT
} trace_signal_t;

typedef enum {
    TRACE_IDLE = 0,
    TRACE_ARMED = 1,
    TRACE_TRIGGERED = 2,
    TRACE_DONE = 3,
} trace_status_t;

typedef enum {
    TRACE_EDGE_RISING = 0,
    TRACE_EDGE_FALLING = 1,
    TRACE_EDGE_EITHER = 2,
    TRACE_EDGE_IMMEDIATE = 3, /* trigger on the first sample after arming */
} trace_edge_t;

typedef struct {
    uint8_t signal_0, signal_1, signal_2, signal_3; /* trace_signal_t; NONE ends */
    uint8_t signal_4, signal_5, signal_6, signal_7;
    uint8_t trigger_signal; /* trace_signal_t */
    uint8_t trigger_edge;   /* trace_edge_t */
    float trigger_level;
    uint16_t pretrigger_samples; /* per channel */
    uint16_t decimation;         /* record every N-th call, >= 1 */
} trace_config_t;

typedef struct {
    trace_config_t cfg_active; /* latched at arm time */
    uint8_t channels[TRACE_MAX_CHANNELS];
    uint8_t n_channels;
    uint8_t status;        /* trace_status_t */
    uint32_t depth;        /* samples per channel */
    uint32_t head;         /* next write row */
    uint32_t rows_written; /* total rows since arming */
    uint32_t rows_after_trigger;
    uint32_t trigger_row; /* row index (in ring) of the trigger sample */
    uint32_t start_row;   /* first row of the linearised capture */
    uint32_t rows_captured;
    uint16_t decim_count;
    float prev_trigger_value;
    uint8_t have_prev;
    float buffer[TRACE_BUFFER_SAMPLES];
} trace_recorder_t;

void trace_init(trace_recorder_t *rec);
/* Latch the config, clear the buffer, state -> ARMED. Returns 0 on success. */
int trace_arm(trace_recorder_t *rec, const trace_config_t *cfg);
void trace_stop(trace_recorder_t *rec);
/* Called once per current period with all signal values (indexed by id). */
void trace_sample(trace_recorder_t *rec, const float signals[TRACE_SIG_COUNT]);
/* Captured size in bytes (rows * channels * 4), valid in DONE. */
uint32_t trace_size_bytes(const trace_recorder_t *rec);
/* Copy captured data as little-endian float32, rows in time order, channels
 * interleaved, starting at byte offset. Returns number of bytes copied. */
size_t trace_read_bytes(const trace_recorder_t *rec, uint32_t offset, uint8_t *dst, size_t len);
/* Row index (0-based, in the linearised capture) of the trigger sample. */
uint32_t trace_trigger_index(const trace_recorder_t *rec);

#endif
