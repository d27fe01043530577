/* core_loop_perf.c - the bare closed loop, no CANopen: plant_sample ->
 * drive_current_step -> plant_step, You 2019 preset (ideal: every non-ideality
 * off, locked rotor), deadbeat controller with matched parameters, iq* = 1 A.
 * Same timing as the lockstep loop (docs/ARCHITECTURE.md): the command computed
 * from sample k is actuated at SYNC k+1 and held over [k+1, k+2].
 *
 * Exported for bench/tools/perf/cores.py (ctypes): hil_core_loop_ns(periods) returns the
 * wall time per period in ns; hil_core_loop_iq_A() returns the plant's true iq at
 * the end of the last run (a sanity check that the loop really regulated).
 * Compiled into build/libhil.so (which links the plant and firmware cores).
 */
#define _POSIX_C_SOURCE 199309L
#include <stdint.h>
#include <string.h>
#include <time.h>

#include "drive_core.h"
#include "pmsm_plant.h"
#include "presets.h"

static double g_last_iq_A;

static double core_now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

double hil_core_loop_ns(uint32_t periods);
double hil_core_loop_iq_A(void);

double hil_core_loop_ns(uint32_t periods)
{
    static plant_config_t pc;
    static plant_state_t ps;
    static drive_t drv;
    drive_config_t dc;
    plant_meas_t pm;
    drive_meas_t dm;
    drive_cmd_t cmd = {0.0f, 0.0f};

    if (periods == 0u) return 0.0;
    if (plant_preset_load("you2019", &pc) != 0) return -1.0;
    plant_config_ideal(&pc);
    pc.mech_mode = PLANT_MECH_LOCKED;
    plant_init(&ps, &pc);
    if (ps.status != 0) return -1.0;

    drive_default_config(&dc); /* You 2019 Tables A1/A2: matches the preset */
    dc.controller = (uint8_t)OD_DRIVE_CONTROLLER_DEADBEAT_YOU2019;
    drive_init(&drv, &dc);
    drv.sp.mode = (uint8_t)DRIVE_MODE_CURRENT;
    drv.sp.iq_ref_A = 1.0f;
    drv.sp.id_ref_A = 0.0f;

    double va = 0.0, vb = 0.0; /* held over the current period */
    const double t0 = core_now_ns();
    for (uint32_t k = 0; k < periods; ++k) {
        plant_sample(&ps, &pc, &pm);
        dm.i_a_A = pm.i_a_A;
        dm.i_b_A = pm.i_b_A;
        dm.theta_m_rad = pm.theta_m_rad;
        drive_current_step(&drv, &dm, &cmd);
        plant_step(&ps, &pc, va, vb); /* [k, k+1] with v*(k-1) */
        va = (double)cmd.v_alpha_V;   /* v*(k), actuated at SYNC k+1 */
        vb = (double)cmd.v_beta_V;
    }
    const double t1 = core_now_ns();
    g_last_iq_A = ps.iq_A;
    return (t1 - t0) / (double)periods;
}

double hil_core_loop_iq_A(void) { return g_last_iq_A; }
