/* zero_law.c - a test fixture of the user-law folder (tests/host/test_user_law.py): a current law that
 * commands 0 V whatever the currents, counts its steps and reports its gain parameter (record 0x2400,
 * law.eds).  Not a controller: the smallest law that exercises the interface (current_law.h). */
#include "current_law.h"

typedef struct {
    uint32_t steps;
} zero_law_state_t;
CURRENT_LAW_STATE_FITS(zero_law_state_t);

static void zero_configure(void *state, const drive_config_t *cfg, const void *record, int switched)
{
    (void)cfg;
    (void)record;
    if (switched) ((zero_law_state_t *)state)->steps = 0u;
}

static void zero_step(void *state, const drive_config_t *cfg, const void *record, const current_law_in_t *in,
                      current_law_out_t *out)
{
    (void)cfg;
    (void)record;
    (void)in;
    ((zero_law_state_t *)state)->steps++;
    *out = (current_law_out_t){0};
}

static void zero_reset(void *state) { ((zero_law_state_t *)state)->steps = 0u; }

static void zero_status(const void *state, const drive_config_t *cfg, void *record)
{
    (void)cfg;
    od_drive_zero_law_t *r = (od_drive_zero_law_t *)record;
    r->steps = ((const zero_law_state_t *)state)->steps;
    r->gain_seen = r->gain;
}

const current_law_t current_law_zero_law = {
    .state_bytes = (uint32_t)sizeof(zero_law_state_t),
    .single_inductance = 0u,
    .configure = zero_configure,
    .step = zero_step,
    .reset = zero_reset,
    .status = zero_status,
};
