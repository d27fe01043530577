/* you2019_law.h - You 2019's current control as plug-ins of the drive
 * (current_law.h): the deadbeat law (Sec. 4, Eq. 16-19) and the PI baseline,
 * both inside You 2019's drive pipeline:
 *   - Eq. 4 decoupling feed-forward with the model in use (Eq. 32 when tuned),
 *   - Eq. 33 voltage limit (Eq. 34 d priority or radial), Eq. 35 decoupled
 *     command actually applied (what the law's memory and the identification
 *     see),
 *   - Fig. 1 timing: the stator-frame command held over [k+1, k+2], rotated by
 *     the drive's angle advance,
 *   - Sec. 3.2 estimator (Eq. 5-9) and Eq. 7 dead-time compensation from the
 *     estimated currents,
 *   - Sec. 6 online tuning (Eq. 22-32) and the Fig. 16 gain pipeline: gains
 *     averaged at the speed-loop execution are loaded into the deadbeat law and
 *     the estimator model at the next current period, the estimator PI two
 *     current periods after that (deadbeat law only; its EDS record 0x2500
 *     Online tuning).
 * Registered as current_law_deadbeat_you2019 and current_law_pi. */
#ifndef YOU2019_LAW_H
#define YOU2019_LAW_H

#include <stdint.h>

#include "current_law.h"
#include "pi_current.h"
#include "you2019_deadbeat.h"
#include "you2019_estimator.h"
#include "you2019_identification.h"

typedef struct {
    uint8_t deadbeat; /* 1: the deadbeat law, 0: the PI */
    you2019_deadbeat_state_t db;
    pi_current_state_t pi;
    you2019_estimator_state_t est;
    you2019_identification_config_t ident_cfg; /* from its record (law.eds; enable 0 for the PI) */
    you2019_identification_state_t ident;
    /* active model used for feed-forward (config or identified, You 2019 Eq. 32) */
    float Lq_active_H, Ld_active_H;
    /* Fig. 16 pipeline */
    uint8_t pending_q, pending_d;
    uint8_t est_pi_countdown;
    uint32_t n_gain_updates;
    float cos_cmd, sin_cmd; /* rotation of this step's command (dead-time compensation) */
} you2019_law_state_t;

extern const current_law_t current_law_deadbeat_you2019;
extern const current_law_t current_law_pi;

#endif
