/* drive_core.h - top-level PMSM current-control drive (glue).
 *
 * Timing model: the stator-frame command returned by drive_current_step() at
 * sample k is applied by the PWM over [k+1, k+2] and first shows in the
 * current sampled at k+2.
 *
 * The drive knows no control law: it measures (Clarke, Park, the electrical
 * angle), runs the outer loops, and calls the law Controller.controller selects
 * through its registry row (current_law.h).  A new law is a registry row, not
 * a case here.
 *
 * Configuration: every field of drive_config_t is an EDS entry of the same
 * name (defaults and ranges in protocols/eds/drive.eds); the selected law's own
 * parameters are its EDS record (drive_law_record).  One path for a change:
 * write the fields, drive_config_check() them, drive_apply_config(); the change
 * takes effect at the next step. */
#ifndef DRIVE_CORE_H
#define DRIVE_CORE_H

#include <stdbool.h>
#include <stdint.h>

#include "current_law.h"
#include "drive_config.h"
#include "outer_loops.h"
#include "trace_recorder.h"

typedef struct {
    uint32_t step_count;
    uint16_t speed_div_count;
    float theta_e_rad, omega_e_rad_s;
    float i_d_A, i_q_A;
    float iq_ref_A, id_ref_A; /* references used in this step */
    current_law_out_t out;    /* the law's command of this step */
    uint8_t law_fault;        /* drive_law_fault_t of the last step */
    uint8_t controller_cache; /* the law of the last recompute (0xFF: none yet) */
    uint8_t dirty;
    float signals[TRACE_SIG_COUNT];
} drive_state_t;

/* What the drive found wrong with the law's command (the command is then 0 V). */
typedef enum {
    DRIVE_LAW_FAULT_NONE = 0,
    DRIVE_LAW_FAULT_NON_FINITE,   /* a NaN or infinite voltage */
    DRIVE_LAW_FAULT_OUT_OF_LIMIT, /* |v| beyond Vmax_V (+ the dead-time compensation's share) */
} drive_law_fault_t;

typedef struct {
    drive_config_t cfg;
    drive_setpoint_t sp;
    drive_state_t st;
    outer_loops_state_t outer;
    const current_law_entry_t *law; /* the selected law's registry row, NULL: none */
    uint16_t law_record_index;      /* the record law_record holds (0: none) */
    _Alignas(8) uint8_t law_state[CURRENT_LAW_STATE_BYTES];
    _Alignas(8) uint8_t law_record[CURRENT_LAW_RECORD_BYTES];
    trace_recorder_t *trace; /* optional, NULL = no tracing */
} drive_t;

/* Defaults: the EDS's. */
void drive_default_config(drive_config_t *cfg);
void drive_init(drive_t *drv, const drive_config_t *cfg);
/* Mark the configuration changed; derived gains are recomputed at the start
 * of the next drive_current_step(). */
void drive_apply_config(drive_t *drv);
/* Recompute now what drive_apply_config() marked (the next step would): a
 * status read of a law just selected sees that law configured. */
void drive_update_config(drive_t *drv);

/* The selected law's EDS record as the drive holds it (its parameters; its
 * status after drive_law_status), NULL when the law has none.  A change of its
 * parameters takes effect through drive_apply_config(). */
void *drive_law_record(drive_t *drv);
/* Copy a record (the node's OD) into the drive for the selected law. */
void drive_set_law_record(drive_t *drv, const void *record, uint32_t bytes);
/* The selected law writes its status entries into `record` (its record's C struct). */
void drive_law_status(const drive_t *drv, void *record);

/* Verdict on a configuration: the cross-field rules (a single field's range is
 * the EDS's).  c->controller may be 0, the drive app's open loop; mode is the
 * reference mode (OD_DRIVE_MODE_*).  Every registered law checks its record
 * against it: record_of gives a law's record by index (NULL: the EDS defaults). */
typedef enum {
    DRIVE_CONFIG_OK = 0,
    DRIVE_CONFIG_NO_SUCH_CONTROLLER, /* a controller value no registered law has */
    DRIVE_CONFIG_INCOMPATIBLE,       /* fields that contradict each other */
} drive_config_verdict_t;
typedef const void *(*drive_record_of_fn)(uint16_t index, void *user);
drive_config_verdict_t drive_config_check(const drive_config_t *c, uint8_t mode, drive_record_of_fn record_of,
                                          void *user);
/* Selecting a surface-mounted law (one inductance, Lq_hat_H) needs a
 * non-salient model: |Ld_hat_H - Lq_hat_H| <= 5 % of Lq_hat_H. */
drive_config_verdict_t drive_config_check_selection(const drive_config_t *c);
void drive_attach_trace(drive_t *drv, trace_recorder_t *rec);

/* Current-period "ISR". */
void drive_current_step(drive_t *drv, const drive_meas_t *meas, drive_cmd_t *cmd);

float drive_signal(const drive_t *drv, trace_signal_t id);

/* Clear the law's memories (open loop: the command is not the law's). */
void drive_reset_controller_memory(drive_t *drv);

/* A write to an entry of law e's record: is it a command, and may it (apply = 0) / does it (apply = 1) act
 * (current_law_t.command)?  The law runs when it is the selected one and the drive is not in open loop; its
 * state is given once the drive has configured it (at the step after the selection). */
current_law_verdict_t drive_law_command(drive_t *drv, const current_law_entry_t *e, void *record, uint8_t subindex,
                                        int open_loop, int apply);

#endif
