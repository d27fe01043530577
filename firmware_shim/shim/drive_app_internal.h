/* drive_app_internal.h - what the files of the drive app share (not an API: drive_app.h is).
 *
 *   drive_app.c             init, bind, the hooks table, NMT/SYNC/RPDO/reset hooks, the current step
 *   drive_app_od.c          pre_write / post_write / pre_read: the OD binding, the status copies
 *   drive_app_law.c         the current laws' records: config rows, their checks and status
 *   drive_app_supervision.c measurement supervision, non-finite values, safe states, EMCYs
 *   drive_app_cia402.c      CiA 402 glue: controlword, statusword, references, 0x6xxx
 *   drive_app_trace.c       trace recorder (0x2300/0x2301), live trace (0x2302), step cost
 *
 * Portable: no OS headers, no allocation, float32. */
#ifndef DRIVE_APP_INTERNAL_H
#define DRIVE_APP_INTERNAL_H

#include "drive_app.h"
#include "od_drive.h"
#include "od_plant_fields.h" /* PLANT_STATUS_HOLDING: plant.eds 0x2100:05 BitNames (the plant holds at this sample) */

static inline od_drive_mfr_t *mfr_of(const co_node_t *node) { return &((od_drive_ram_t *)node->od->ram)->mfr; }

static inline int is_finite_f(float x) { return (x - x) == 0.0f; /* false for NaN and +-inf */ }

/* drive_app.c */
void drive_app_step(drive_app_t *app);
trace_recorder_t *drive_app_core_step_without_output(drive_app_t *app);

/* drive_app_od.c: the OD hooks */
uint32_t drive_app_od_pre_write(void *user, co_node_t *node, const co_od_entry_t *e, const uint8_t *data, uint32_t len);
void drive_app_od_post_write(void *user, co_node_t *node, const co_od_entry_t *e);
void drive_app_od_pre_read(void *user, co_node_t *node, const co_od_entry_t *e);

/* drive_app_law.c: the parameter records (0x2200-0x2203) and the current laws' records */
void drive_app_law_od_to_config(const od_drive_mfr_t *m, drive_config_t *c, uint8_t core_ctrl);
int drive_app_law_is_record(uint16_t index); /* 1 for a law's record (CurrentLaws) */
/* The selected law's record, OD -> drive, when its parameters differ from what the drive holds: 1 then. */
int drive_app_law_sync(drive_app_t *app);
/* 1 when e is the app's parameter records or a law's (*abort: 0 or the SDO abort code). */
int drive_app_law_pre_write(drive_app_t *app, const od_drive_mfr_t *m, const od_drive_mfr_t *cand,
                            const co_od_entry_t *e, const uint8_t *data, uint32_t *abort);
int drive_app_law_post_write(drive_app_t *app, od_drive_mfr_t *m, const co_od_entry_t *e);
int drive_app_law_refresh(drive_app_t *app, od_drive_mfr_t *m, uint16_t index);

/* drive_app_supervision.c */
void drive_app_count_late(drive_app_t *app, uint8_t reason, uint16_t sample_index, uint8_t sync_counter);
void drive_app_reset_sequencing(drive_app_t *app);
void drive_app_report_non_finite(drive_app_t *app, uint16_t sample_index);
void drive_app_on_measurement(drive_app_t *app, co_node_t *node);
void drive_app_zero_voltage(drive_t *d);
void drive_app_clear_control_memory(drive_t *d);
void drive_app_safe_step(drive_app_t *app);
int drive_app_heartbeat_lost(const co_node_t *node);
void drive_app_enter_safe_state(drive_app_t *app, co_node_t *node, uint8_t reason);
/* The same from inside the current step, whose own command (now 0 V) goes out at its end: one command a
 * period on the bus, never a second frame. */
void drive_app_enter_safe_state_in_step(drive_app_t *app, co_node_t *node, uint8_t reason);
void drive_app_leave_safe_state(drive_app_t *app, co_node_t *node);

/* drive_app_cia402.c */
int drive_app_pdo_maps(const co_pdo_t *p, uint16_t index);
void drive_app_send_statusword(co_node_t *node);
void drive_app_cia402_changed(drive_app_t *app, co_node_t *node, int was_powered);
void drive_app_cia402_on_controlword(drive_app_t *app, co_node_t *node);
void drive_app_cia402_reset(drive_app_t *app, co_node_t *node);
int drive_app_cia402_references(drive_app_t *app, const od_drive_mfr_t *m);
void drive_app_cia402_refresh(const drive_app_t *app, od_drive_mfr_t *m, uint16_t index);
void drive_app_cia402_check_stopped(drive_app_t *app, co_node_t *node);

/* drive_app_trace.c */
uint32_t drive_app_trace_pre_write(const od_drive_mfr_t *cand, const co_od_entry_t *e, const uint8_t *data);
void drive_app_trace_post_write(drive_app_t *app, od_drive_mfr_t *m, const co_od_entry_t *e);
void drive_app_trace_refresh(drive_app_t *app, od_drive_mfr_t *m, uint16_t index);
void drive_app_reset_step_cost(drive_app_t *app);
void drive_app_count_step_cost(drive_app_t *app, uint32_t cycles);

#endif /* DRIVE_APP_INTERNAL_H */
