/* plant_fmu.h - a co-simulation FMU (FMI 2.0 or 3.0, a Linux x86-64 binary) as the plant's external machine model
 * (plant_external_t, pmsm_plant.h): host glue, loaded with dlopen through the standard's C interface, declared by
 * plant_fmi_api.h (the project's own, no external FMI header: the loader is always built).  The bench checks the
 * FMU against its modelDescription.xml and extracts it (bench/motor/fmu.py); the plant gets what it needs as the
 * text of its object 0x2009 "FMU" (plant.eds):
 *
 *     fmi 2                       2 or 3
 *     library /x/binaries/linux64/linear_pmsm.so
 *     identifier linear_pmsm      the model identifier (the functions' prefix of FMI 2 is none: plain names)
 *     token {8c4e810f-...}        fmi2 guid / fmi3 instantiationToken
 *     resources file:///x/resources/   fmi2: a URI; fmi3: a path
 *     inputs alpha_beta           alpha_beta (v_alpha_V, v_beta_V) or dq (vd_V, vq_V, at the model's last angle)
 *     in0 1                       value references of the two inputs
 *     in1 2
 *     outputs phase               phase (i_a_A, i_b_A), alpha_beta or dq (at the model's angle)
 *     out0 3
 *     out1 4
 *     theta 5                     the mechanical angle (rad)
 *     omega 6                     the mechanical speed (rad/s); optional
 *     pole_pairs 5                theta_e = pole_pairs theta_m (dq inputs and outputs)
 *     substeps 1                  doStep calls a period
 *     param 7 1.4                 a parameter's value reference and value, set before initialization (repeated)
 */
#ifndef PLANT_FMU_H
#define PLANT_FMU_H

#include <stddef.h>
#include <stdint.h>

#include "pmsm_plant.h"

#include "plant_fmu_text.h"

/* Load the library, instantiate, set the parameters, initialize (start time 0); the external model in *ext.
 * Closes a model loaded before.  0, or -1 with the reason in err (the plant's log line). */
int plant_fmu_load(const plant_fmu_spec_t *spec, const plant_external_t **ext, char *err, size_t err_len);
/* Terminate, free and unload the loaded model (none: no-op). */
void plant_fmu_unload(void);
/* The plant app's loader (plant_app_set_fmu_loader): parse and load a 0x2009 text; 0, or the SDO abort code
 * 0x06090030 (a bad text or an FMU that does not load); the reason on stderr, the plant's log. */
uint32_t plant_fmu_load_text(const uint8_t *text, uint32_t len, const plant_external_t **ext);

#endif
