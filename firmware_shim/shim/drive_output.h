/* drive_output.h - the drive's output when the control does not act (the safe state, a power stage off, the
 * open loop): zero voltage in the core's state and its trace signals, and the control's memory forgotten.
 * Only the core (drive_core.h) below it.  Portable: no OS headers, no allocation, float32. */
#ifndef DRIVE_OUTPUT_H
#define DRIVE_OUTPUT_H

#include "drive_core.h"

/* Zero voltage in the state and its trace signals: they show what the drive commanded. */
void drive_output_zero(drive_t *d);

/* Forget what the control built up while it did not act: the current controllers' memories and the outer
 * loops' integrator and profile (restarted at the measured position), so that acting again starts cleanly. */
void drive_output_clear_memory(drive_t *d);

/* The core runs for the angle, the dq currents, the speed estimate and its bookkeeping; its controller output
 * is discarded and its memory cleared (no wind-up, clean restart when the loop is closed again).  Returns the
 * trace recorder, detached meanwhile: the caller samples it with its own voltages. */
trace_recorder_t *drive_output_step_without_output(drive_t *d, const drive_meas_t *meas, drive_cmd_t *cmd);

#endif /* DRIVE_OUTPUT_H */
