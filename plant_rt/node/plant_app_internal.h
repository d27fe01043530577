/* plant_app_internal.h - what the files of the plant app share (not an API: plant_app.h is).
 *   plant_app.c         init, config <-> OD, the hooks, the sample's status copies
 *   plant_app_timing.c  command accounting (late, missed), real-time timing (0x2006, 0x2007), poll / tick
 * Portable: no OS headers. */
#ifndef PLANT_APP_INTERNAL_H
#define PLANT_APP_INTERNAL_H

#include "od_plant.h"
#include "plant_app.h"

#define M (OD_PLANT.mfr)

/* The RPDO that carries the voltage command (maps 0x2102), NULL if none. */
const co_pdo_t *plant_app_cmd_rpdo(const plant_app_t *app);
/* A command frame was received at t_us (on time or late). */
void plant_app_note_arrival(plant_app_t *app, int64_t t_us);
/* Clear the real-time timing (0x2007 and the histograms 0x2006). */
void plant_app_timing_reset(plant_app_t *app);
/* Copy the timing statistics into 0x2007. */
void plant_app_timing_publish(plant_app_t *app);

#endif /* PLANT_APP_INTERNAL_H */
