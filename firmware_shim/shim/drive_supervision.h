/* drive_supervision.h - the drive's supervision, a component of the drive app (drive_app.h tells the rules):
 * the measurements' sequence (lost, late), their non-finite values, the safe state's latch and the EMCYs of
 * all three; it owns 0x2204 Drive status and 0x2209 Safe state and binds them.  It returns verdicts (admit a
 * measurement or not, a timeout reached, a latch taken) and never runs the step: the app's root does, and acts
 * on them.  Only the cores, the stack and its own header.  Portable: no OS headers, no allocation, float32. */
#ifndef DRIVE_SUPERVISION_H
#define DRIVE_SUPERVISION_H

#include <stdint.h>

#include "co_node.h"
#include "drive_core.h"
#include "od_drive_fields.h"

/* Reasons in byte 2 of the MSEF of DRIVE_EMCY_MEAS_LATE. */
enum {
    DRIVE_LATE_RPDO1_WITHOUT_RPDO2 = 1,
    DRIVE_LATE_RPDO2_WITHOUT_RPDO1 = 2,
    DRIVE_LATE_DUPLICATE_OR_OLD = 3,
    DRIVE_LATE_SYNC_MISMATCH = 4
};

/* Fields in byte 2 of the MSEF of DRIVE_EMCY_NON_FINITE. */
enum { DRIVE_NON_FINITE_I_A = 0x01, DRIVE_NON_FINITE_I_B = 0x02, DRIVE_NON_FINITE_THETA = 0x04 };

#define DRIVE_APP_PENDING_EMCY 4u

/* The read-only entries of the status records, named as in drive.eds: the component keeps its counts in them,
 * and a read of the record copies them to the OD with the list od_drive_fields.h generates
 * (OD_DRIVE_<RECORD>_STATUS), so an entry's name is written once, in the EDS.  Values it does not count (the
 * core's currents) are taken just before the copy. */
typedef struct { /* 0x2204 Drive status */
    uint32_t current_steps;
    uint32_t lost_measurements;
    uint32_t late_measurements;
    float id_A; /* id_A .. iq_ref_active_A: the core's, at the read */
    float iq_A;
    float speed_rad_s;
    float iq_ref_active_A;
    uint16_t last_sample_index; /* also the sequencing's last sample */
} drive_app_drive_status_t;

typedef struct {    /* 0x2209 Safe state */
    uint8_t reason; /* OD_DRIVE_REASON_*: NONE = not in the safe state */
    uint32_t entries;
    uint16_t entered_at_sample;
    uint32_t non_finite_rejected;
} drive_app_safe_state_t;

typedef enum { DRIVE_SUP_STEP = 0, DRIVE_SUP_DUPLICATE } drive_sup_verdict_t;

typedef struct {
    co_node_t *node;
    const drive_t *drv; /* the core: its currents for 0x2204 */
    /* 0x2209:05 clear = 1 was written (accepted): the root leaves the safe state */
    void (*on_clear)(void *root);
    void *root;
    co_od_ext_t ext_status, ext_safe_state;

    drive_app_drive_status_t drive_status; /* 0x2204 */
    drive_app_safe_state_t safe_state;     /* 0x2209 (with non_finite_rejected) */
    uint32_t emcy_raised;                  /* EMCY 0xFF01/0xFF02 raised */

    /* measurement sequencing */
    uint8_t rpdo1_fresh; /* RPDO1 seen, waiting for its RPDO2 */
    uint8_t have_last;   /* drive_status.last_sample_index valid */
    uint8_t old_run;     /* consecutive duplicate/old sample_index */
    uint8_t sync_seen;   /* a SYNC was received since OPERATIONAL */
    uint8_t last_sync_counter;
    uint8_t meas_error_active; /* an 0xFF01/0xFF02 error is active */
    uint8_t admit_clean;       /* the measurement admitted last had no sequence error */
    uint8_t admit_was_active;  /* ... and an error was active before it */

    /* EMCYs of the measurement being handled, sent after its command */
    uint8_t defer_emcy;
    uint8_t n_pending;
    uint16_t pending_code[DRIVE_APP_PENDING_EMCY];
    uint8_t pending_msef[DRIVE_APP_PENDING_EMCY][5];

    uint16_t syncs_without_meas; /* SYNCs since the last measurement (saturates) */
    uint8_t meas_seen;           /* a measurement arrived since the NMT state changed */
    uint8_t have_good;           /* good_sample_index valid */
    uint16_t good_sample_index;  /* sample_index of the last step on finite measurement values */
    uint8_t non_finite_mask;     /* DRIVE_NON_FINITE_* replaced in the last step */
    uint8_t non_finite_active;   /* EMCY 0xFF05 active */
} drive_supervision_t;

/* Bind 0x2204 and 0x2209 to the component (co_node_init's bind hook). */
void drive_sup_bind(drive_supervision_t *s, co_node_t *node, const drive_t *drv, void (*on_clear)(void *root),
                    void *root);
/* Reset node: every count and the safe state's history; reset communication (app = 0): the sequencing. */
void drive_sup_reset(drive_supervision_t *s, int app);
void drive_sup_reset_sequencing(drive_supervision_t *s);

/* A SYNC: the late RPDO1 of the previous sample; 1 when the measurement timeout (0x2209:01) is reached. */
int drive_sup_on_sync(drive_supervision_t *s, uint8_t counter, int operational);
/* RPDO1 (the currents) arrived. */
void drive_sup_on_rpdo1(drive_supervision_t *s);
/* RPDO2 (the measurement) arrived: its sequence is judged, its EMCYs wait for the command; DUPLICATE for a second
 * copy of the sample just answered (no step: its command is out). */
drive_sup_verdict_t drive_sup_admit(drive_supervision_t *s);
/* The measurement's values: DRIVE_NON_FINITE_* replaced by their last finite value (counted), or none. */
void drive_sup_note_values(drive_supervision_t *s, uint8_t non_finite_mask, uint16_t sample_index);
/* References that were not finite (kept at their last value): counted. */
void drive_sup_note_rejected(drive_supervision_t *s, uint32_t n);
/* The command of the admitted measurement is out (or there was none): its EMCYs, then (a step ran) the step
 * counted (0x2204:01), the non-finite report and the clearing of the sequence errors. */
void drive_sup_finish(drive_supervision_t *s, drive_sup_verdict_t v, uint16_t sample_index);

/* The safe state: 1 when it is entered now (the first reason stays while it lasts); its EMCY; 0x603F's code. */
int drive_sup_latch(drive_supervision_t *s, uint8_t reason);
void drive_sup_safe_emcy(drive_supervision_t *s);
uint16_t drive_sup_safe_code(uint8_t reason);
/* Leave it: the reason it had (OD_DRIVE_REASON_NONE: was not in it); its EMCY is cleared. */
uint8_t drive_sup_release(drive_supervision_t *s);
static inline int drive_sup_safe(const drive_supervision_t *s)
{
    return s->safe_state.reason != (uint8_t)OD_DRIVE_REASON_NONE;
}

#endif /* DRIVE_SUPERVISION_H */
