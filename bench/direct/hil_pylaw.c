/* hil_pylaw.c - a current law prototyped in Python, in the direct loop: the registry row of a registered law
 * (its Controller.controller value, its EDS record and its check) with the law's functions replaced by the
 * caller's callbacks (bench/law_py.py makes them from a Python class with the C interface's face).
 *
 * The drive finds the row through current_law_override (current_law.h), so everything around the law is the
 * drive's own: its record's defaults and SDO writes, the check of a configuration, the limit and finiteness check
 * of the command (law_fault), the trace.  The law's state is the Python object's: the drive's law_state is not
 * used.  A record's command entries (current_law_t.command) and the outer loops' speed_step are not forwarded.
 * One law at a time, as one drive per process (hil_direct.c). */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "current_law.h"
#include "hil_internal.h"

typedef struct {
    void (*configure)(const drive_config_t *cfg, const void *record, int32_t switched);
    void (*step)(const drive_config_t *cfg, const void *record, const current_law_in_t *in, current_law_out_t *out);
    /* optional (NULL: none) */
    void (*commit)(const drive_config_t *cfg, const void *record, const current_law_in_t *in,
                   const current_law_out_t *applied);
    void (*reset)(void);
    void (*status)(const drive_config_t *cfg, void *record);
} hil_pylaw_t;

int32_t hil_pylaw_install(uint8_t value, const hil_pylaw_t *cb);
void hil_pylaw_uninstall(void);
uint32_t hil_pylaw_layout(uint32_t *out, uint32_t max);
uint32_t hil_pylaw_record_bytes(uint8_t value);
void hil_pylaw_interrupt(void);

static hil_pylaw_t g_cb;
static current_law_t g_law;
static current_law_entry_t g_row;
static volatile int32_t g_stop; /* a Ctrl-C in one of the law's methods: the loop returns (hil_pylaw_stopping) */

/* Whether the law is still the one installed: after hil_pylaw_uninstall the drive may hold the row until its next
 * configuration, and the callbacks (the caller's) are gone. */
static int installed(void) { return current_law_override == &g_row; }

static void py_configure(void *state, const drive_config_t *cfg, const void *record, int switched)
{
    (void)state;
    if (installed()) g_cb.configure(cfg, record, (int32_t)switched);
}

static void py_step(void *state, const drive_config_t *cfg, const void *record, const current_law_in_t *in,
                    current_law_out_t *out)
{
    (void)state;
    if (installed())
        g_cb.step(cfg, record, in, out);
    else
        memset(out, 0, sizeof *out); /* 0 V until the drive takes its registered law again */
}

static void py_commit(void *state, const drive_config_t *cfg, const void *record, const current_law_in_t *in,
                      const current_law_out_t *applied)
{
    (void)state;
    if (installed()) g_cb.commit(cfg, record, in, applied);
}

static void py_reset(void *state)
{
    (void)state;
    if (installed()) g_cb.reset();
}

static void py_status(const void *state, const drive_config_t *cfg, void *record)
{
    (void)state;
    if (installed()) g_cb.status(cfg, record);
}

/* The law of Controller.controller value `value` from now on: 0, or -1 when no registered law has that value
 * or a required callback is missing. */
int32_t hil_pylaw_install(uint8_t value, const hil_pylaw_t *cb)
{
    if (cb == NULL || cb->configure == NULL || cb->step == NULL) return -1;
    const current_law_entry_t *row = NULL;
    for (uint8_t i = 0u; i < current_law_count; ++i)
        if (current_law_table[i].value == value) row = &current_law_table[i];
    if (row == NULL) return -1;
    current_law_override = NULL;
    g_stop = 0;
    g_cb = *cb;
    g_law = (current_law_t){
        .state_bytes = 0u,
        .single_inductance = row->law->single_inductance,
        .configure = py_configure,
        .step = py_step,
        .commit = cb->commit != NULL ? py_commit : NULL,
        .speed_step = NULL,
        .reset = cb->reset != NULL ? py_reset : NULL,
        .status = cb->status != NULL ? py_status : NULL,
        .check = row->law->check,
        .command = NULL,
    };
    g_row = *row;
    g_row.law = &g_law;
    current_law_override = &g_row;
    return 0;
}

void hil_pylaw_uninstall(void)
{
    current_law_override = NULL;
    g_stop = 0;
    memset(&g_cb, 0, sizeof g_cb);
}

/* A Ctrl-C during one of the law's methods: the lockstep loop returns at its next step (a real-time run is asked by
 * the caller through hil_stop), and the caller raises it. */
void hil_pylaw_interrupt(void) { g_stop = 1; }

int hil_pylaw_stopping(void) { return g_stop; }

/* The layout bench/law_py.py mirrors with ctypes, checked before a law is installed: sizes and offsets in the
 * order of its LAYOUT. */
uint32_t hil_pylaw_layout(uint32_t *out, uint32_t max)
{
    const uint32_t v[] = {
        (uint32_t)sizeof(current_law_in_t),
        (uint32_t)offsetof(current_law_in_t, omega_e_rad_s),
        (uint32_t)sizeof(current_law_out_t),
        (uint32_t)offsetof(current_law_out_t, v_beta_V),
        (uint32_t)offsetof(current_law_out_t, v_limited),
        (uint32_t)offsetof(current_law_out_t, v_after_limit_V),
        (uint32_t)offsetof(drive_config_t, Ts_s),
        (uint32_t)offsetof(drive_config_t, speed_loop_divider),
        (uint32_t)offsetof(drive_config_t, R_hat_ohm),
        (uint32_t)offsetof(drive_config_t, Ld_hat_H),
        (uint32_t)offsetof(drive_config_t, Lq_hat_H),
        (uint32_t)offsetof(drive_config_t, psi_hat_Wb),
        (uint32_t)offsetof(drive_config_t, pole_pairs),
        (uint32_t)offsetof(drive_config_t, Vmax_V),
        (uint32_t)offsetof(drive_config_t, J_hat_kgm2),
        (uint32_t)offsetof(drive_config_t, vlimit_radial),
        (uint32_t)offsetof(drive_config_t, angle_advance_periods),
    };
    const uint32_t n = (uint32_t)(sizeof v / sizeof v[0]);
    for (uint32_t i = 0u; i < n && i < max; ++i) out[i] = v[i];
    return n;
}

/* The size of the record of Controller.controller value `value` (its generated struct), 0: none or no such law. */
uint32_t hil_pylaw_record_bytes(uint8_t value)
{
    for (uint8_t i = 0u; i < current_law_count; ++i)
        if (current_law_table[i].value == value) return current_law_table[i].record_bytes;
    return 0u;
}
