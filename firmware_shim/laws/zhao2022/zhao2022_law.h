/* zhao2022_law.h - Zhao 2022's two laws as current laws of the drive
 * (current_law.h): the incremental deadbeat law (Eq. 22/23) and the
 * conventional predictive baseline (Eq. 5/6).  Surface-mounted laws
 * (L_hat = Lq_hat_H), each limits its own command radially to Vmax_V; their
 * dq command is held in the stator frame, rotated by the drive's angle advance.
 * Their EDS record 0x2502 Zhao 2022 (law.eds) carries their status.  Registered as
 * current_law_incremental_zhao2022 and current_law_predictive_zhao2022. */
#ifndef ZHAO2022_LAW_H
#define ZHAO2022_LAW_H

#include "current_law.h"
#include "zhao2022_incremental.h"
#include "zhao2022_predictive.h"

extern const current_law_t current_law_incremental_zhao2022;
extern const current_law_t current_law_predictive_zhao2022;

#endif
