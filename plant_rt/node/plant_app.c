/* plant_app.c - the PMSM plant as a CANopen node (see plant_app.h). Portable: no OS headers. */
#include "plant_app.h"

#include <math.h>
#include <string.h>

#include "co_field_map.h"
#include "od_plant.h"
#include "plant_app_internal.h"
#include "presets.h"

#define RUN_FOREVER 0xFFFFFFFFu

/* ------------------------------------------------------------------ OD <-> config */

/* Motor model, Inverter and Sensors (0x2000-0x2002) <-> plant_config_t: the rows are the EDS's
 * own lists (od_plant.h), the fields of plant_config_t carry the EDS names. */
#define PLANT_ROW(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW(od_plant_mfr_t, plant_config_t, record, field),
/* one list a line (clang-format would run the macro lists together) */
/* clang-format off */
static const co_field_map_t config_rows[] = {
    OD_PLANT_MOTOR_MODEL_PARAMS(PLANT_ROW)
    OD_PLANT_INVERTER_PARAMS(PLANT_ROW)
    OD_PLANT_SENSORS_PARAMS(PLANT_ROW)};
/* clang-format on */
#undef PLANT_ROW
#define N_CONFIG_ROWS (sizeof config_rows / sizeof config_rows[0])

void plant_app_config_from_od(plant_config_t *c)
{
    plant_config_defaults(c); /* the fields the OD does not carry */
    co_field_map_to_core(config_rows, N_CONFIG_ROWS, &M, c);
}

void plant_app_config_to_od(const plant_config_t *c) { co_field_map_to_od(config_rows, N_CONFIG_ROWS, &M, c); }

/* ------------------------------------------------------------------ helpers */

static bool is_model_entry(const co_od_entry_t *e)
{
    return e->index >= OD_PLANT_MOTOR_MODEL_IDX && e->index <= OD_PLANT_SENSORS_IDX && e->subindex != 0u;
}

static void attach_domain(plant_app_t *app)
{
    M.x2006_timing_histograms.data = app->hist_bytes;
    M.x2006_timing_histograms.size = (uint32_t)sizeof app->hist_bytes;
    M.x2006_timing_histograms.capacity = 0u; /* read-only */
}

static void reset_tracking(plant_app_t *app)
{
    app->cmd_ready = false;
    app->cmd_seen = false;
    app->cmd_seen_rx_us = 0;
    app->late_in_period = false;
    app->owed = 0;
    app->late_timeout_streak = 0;
    app->miss_flag = false;
}

static void model_reset(plant_app_t *app)
{
    plant_app_config_from_od(&app->cfg);
    plant_init(&app->state, &app->cfg);
    memset(&app->meas, 0, sizeof app->meas);
    app->cfg_dirty = false;
    app->reseed = false;
    app->started = false;
    app->k = 0;
    app->v_held_alpha_V = 0.0;
    app->v_held_beta_V = 0.0;
    app->paused = true;
    app->drive_lost = false;
    app->trip_emcy = 0u;
    reset_tracking(app);
    plant_app_timing_reset(app);
    attach_domain(app);
}

void plant_app_init(plant_app_t *app)
{
    memset(app, 0, sizeof *app);
    co_od_reset(&od_plant, OD_PLANT_DEFAULT_NODE_ID, 0);
    model_reset(app);
}

void plant_app_bind(plant_app_t *app, co_node_t *node) { app->node = node; }

bool plant_app_running(const plant_app_t *app)
{
    return app->node && app->node->nmt == CO_NMT_OPERATIONAL && M.x2003_run_control.run_periods > 0u;
}

bool plant_app_realtime_mode(const plant_app_t *app)
{
    (void)app;
    return M.x2003_run_control.mode == OD_PLANT_MODE_REALTIME;
}

int64_t plant_app_period_ns(const plant_app_t *app) { return (int64_t)llround(app->cfg.Ts_s * 1e9); }

static void apply_pending_config(plant_app_t *app)
{
    plant_config_t *c = &app->scratch_cfg;
    plant_app_config_from_od(c);
    if (plant_prepare(&app->state, c) == PLANT_OK) {
        app->cfg = *c;
        if (app->reseed) plant_rng_seed(&app->state.rng, app->cfg.rng_seed);
        ++app->config_applies;
    } else {
        ++app->config_errors;
        (void)plant_prepare(&app->state, &app->cfg);
    }
    app->cfg_dirty = false;
    app->reseed = false;
}

/* ------------------------------------------------------------------ status */

/* 0x2100's and 0x2005's entries <- plant_app_t.measurement / .plant_state (their names: plant.eds). */
#define MEASUREMENT_ROW(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW(od_plant_mfr_t, plant_app_measurement_t, record, field),
#define PLANT_STATE_ROW(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW(od_plant_mfr_t, plant_app_plant_state_t, record, field),
static const co_field_map_t measurement_rows[] = {OD_PLANT_MEASUREMENT_STATUS(MEASUREMENT_ROW)};
static const co_field_map_t plant_state_rows[] = {OD_PLANT_PLANT_STATE_STATUS(PLANT_STATE_ROW)};
#undef MEASUREMENT_ROW
#undef PLANT_STATE_ROW

/* The sample of this SYNC -> 0x2100 (the TPDOs) and 0x2005. */
static void publish_sample(plant_app_t *app, uint8_t sync_counter, uint8_t status)
{
    plant_app_measurement_t *x = &app->measurement;
    x->i_a_A = app->meas.i_a_A;
    x->i_b_A = app->meas.i_b_A;
    x->theta_m_rad = app->meas.theta_m_rad;
    x->sync_counter = sync_counter;
    x->status = status;
    x->sample_index = (uint16_t)app->k;
    plant_app_plant_state_t *p = &app->plant_state;
    p->id_A = app->meas.id_A;
    p->iq_A = app->meas.iq_A;
    p->omega_m_rad_s = app->meas.omega_m_rad_s;
    p->theta_m_rad = app->meas.theta_m_true_rad;
    p->torque_Nm = app->meas.torque_Nm;
    p->energy_in_J = app->state.energy.in_J;
    co_field_map_to_od(measurement_rows, sizeof measurement_rows / sizeof measurement_rows[0], &M, x);
    co_field_map_to_od(plant_state_rows, sizeof plant_state_rows / sizeof plant_state_rows[0], &M, p);
}

/* ------------------------------------------------------------------ hooks */

static plant_app_t *user_app(void *user, co_node_t *node)
{
    plant_app_t *app = (plant_app_t *)user;
    if (!app->node) app->node = node;
    return app;
}

/* Validate a write to 0x2000-0x2002 against the whole configuration: store it
 * temporarily, read the config back, restore, try plant_prepare on a copy. */
static uint32_t validate_model_write(plant_app_t *app, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    uint8_t saved[8];
    uint32_t n = e->size <= sizeof saved ? e->size : (uint32_t)sizeof saved;
    memcpy(saved, e->data, n);
    co_od_store(e, data, len);
    plant_app_config_from_od(&app->scratch_cfg);
    memcpy(e->data, saved, n);
    app->scratch_state = app->state;
    return plant_prepare(&app->scratch_state, &app->scratch_cfg) == PLANT_OK ? 0u : CO_ABORT_PARAM_INCOMPAT;
}

static uint32_t hook_pre_write(void *user, co_node_t *node, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    plant_app_t *app = user_app(user, node);
    if (is_model_entry(e)) return validate_model_write(app, e, data, len);
    if (e->index == OD_PLANT_MOTOR_PRESET_IDX) {
        char name[40];
        if (len >= sizeof name) return CO_ABORT_INVALID_VALUE;
        memcpy(name, data, len);
        name[len] = '\0';
        if (plant_preset_load(name, &app->scratch_cfg) != 0) return CO_ABORT_INVALID_VALUE;
        app->scratch_state = app->state;
        if (plant_prepare(&app->scratch_state, &app->scratch_cfg) != PLANT_OK) return CO_ABORT_PARAM_INCOMPAT;
        return 0;
    }
    return 0;
}

int plant_app_load_preset(plant_app_t *app, const char *name)
{
    if (plant_preset_load(name, &app->scratch_cfg) != 0) return PLANT_ERR_PRESET;
    plant_app_config_to_od(&app->scratch_cfg);
    app->cfg_dirty = true;
    app->reseed = true;
    return 0;
}

static void hook_post_write(void *user, co_node_t *node, const co_od_entry_t *e)
{
    plant_app_t *app = user_app(user, node);
    if (is_model_entry(e)) {
        app->cfg_dirty = true;
        if (e->index == OD_PLANT_SENSORS_IDX && e->subindex == OD_PLANT_SENSORS_RNG_SEED_SUB) app->reseed = true;
        return;
    }
    if (e->index == OD_PLANT_MOTOR_PRESET_IDX) {
        (void)plant_app_load_preset(app, M.x2004_motor_preset);
        return;
    }
    if (e->index == OD_PLANT_RUN_CONTROL_IDX) {
        switch (e->subindex) {
        case OD_PLANT_RUN_CONTROL_TRIP_CLEAR_SUB:
            if (M.x2003_run_control.trip_clear == 1u) {
                plant_clear_trip(&app->state);
                if (M.x2003_run_control.trip_active) {
                    M.x2003_run_control.trip_active = 0u;
                    co_emcy_clear(node, app->trip_emcy);
                }
                app->drive_lost = false;
            }
            M.x2003_run_control.trip_clear = 0u;
            break;
        case OD_PLANT_RUN_CONTROL_MODE_SUB:
            app->paused = true; /* restart the timing of the current period */
            app->owed = 0;      /* start the command accounting afresh */
            app->late_timeout_streak = 0;
            break;
        case OD_PLANT_RUN_CONTROL_RUN_PERIODS_SUB: M.x2003_run_control.state = plant_app_running(app) ? 1u : 0u; break;
        default: break;
        }
    }
    if (e->index == OD_PLANT_REALTIME_TIMING_IDX && e->subindex == OD_PLANT_REALTIME_TIMING_RESET_SUB) {
        if (M.x2007_realtime_timing.reset == 1u) plant_app_timing_reset(app);
        M.x2007_realtime_timing.reset = 0u;
    }
}

/* 0x2007 is read: its figures from the statistics (the percentiles are computed here, not per period). */
static void hook_pre_read(void *user, co_node_t *node, const co_od_entry_t *e)
{
    if (e->index == OD_PLANT_REALTIME_TIMING_IDX) plant_app_timing_publish(user_app(user, node));
}

static void hook_on_rpdo(void *user, co_node_t *node, uint8_t pdo)
{
    plant_app_t *app = user_app(user, node);
    /* Synchronous RPDO actuated at this SYNC: account for it if poll did not see it yet. */
    const co_pdo_t *p = plant_app_cmd_rpdo(app);
    if (p && p == &node->rpdo[pdo] && !(app->cmd_seen && p->last_rx_us == app->cmd_seen_rx_us))
        plant_app_note_arrival(app, p->last_rx_us);
    app->cmd_seen = false;
}

static void hook_on_sync(void *user, co_node_t *node, uint8_t counter)
{
    plant_app_t *app = user_app(user, node);
    if (node->nmt != CO_NMT_OPERATIONAL || M.x2003_run_control.run_periods == 0u) return;
    int64_t now = node->now_us;

    /* 1. integrate [k-1, k] with the command held over it */
    const bool k_was_started = app->started;
    if (app->started) {
        plant_step(&app->state, &app->cfg, app->v_held_alpha_V, app->v_held_beta_V);
        ++app->k;
    } else {
        app->started = true;
        app->k = 0;
    }
    /* 2. parameter changes take effect at the period boundary */
    if (app->cfg_dirty) apply_pending_config(app);
    if (app->state.tripped && !M.x2003_run_control.trip_active) {
        M.x2003_run_control.trip_active = 1u;
        uint8_t msef[5] = {(uint8_t)app->k, (uint8_t)(app->k >> 8), 0, 0, 0};
        app->trip_emcy = app->drive_lost ? PLANT_EMCY_DRIVE_LOST : PLANT_EMCY_OVERCURRENT;
        co_emcy_raise(node, app->trip_emcy, app->drive_lost ? CO_ERR_REG_COMMUNICATION : CO_ERR_REG_CURRENT, msef);
    }
    /* a held period: no command frame since the previous SYNC (the first sample has none to hold) */
    const bool held = k_was_started && app->commands == app->commands_at_sync;
    app->commands_at_sync = app->commands;
    /* 3. actuate the received command: held in the stator frame over [k, k+1] */
    app->v_held_alpha_V = (double)M.x2102_voltage_command.v_alpha_V;
    app->v_held_beta_V = (double)M.x2102_voltage_command.v_beta_V;

    /* period bookkeeping */
    uint32_t *rp = &M.x2003_run_control.run_periods;
    if (*rp != RUN_FOREVER) --*rp;
    ++app->syncs;
    app->last_sync_us = now;
    app->wait_start_us = now;
    app->cmd_ready = false;
    app->cmd_seen = false;
    app->late_in_period = false;

    /* 4. sample */
    plant_sample(&app->state, &app->cfg, &app->meas);
    uint8_t status = 0;
    if (M.x2003_run_control.trip_active) status |= PLANT_STATUS_TRIP;
    if (*rp == 0u) status |= PLANT_STATUS_HOLDING;
    if (app->miss_flag) status |= PLANT_STATUS_MISSED;
    if (held) status |= PLANT_STATUS_HELD;
    app->miss_flag = false;

    publish_sample(app, counter, status);

    M.x2003_run_control.period_index = (uint32_t)app->k;
    /* Still running until the command for this sample is in (see plant_app_poll). */
    M.x2003_run_control.state = 1u;
}

static void hook_on_nmt(void *user, co_node_t *node, co_nmt_state_t st)
{
    plant_app_t *app = user_app(user, node);
    if (st != CO_NMT_OPERATIONAL) {
        app->cmd_seen = false; /* the core dropped the buffered RPDOs */
        app->cmd_ready = false;
    }
    app->paused = true;
    M.x2003_run_control.state = plant_app_running(app) ? 1u : 0u;
}

static void hook_on_reset(void *user, co_node_t *node, int communication_only)
{
    plant_app_t *app = user_app(user, node);
    if (communication_only) {
        reset_tracking(app); /* PDO buffers are gone */
        app->paused = true;
        return;
    }
    model_reset(app);
}

/* The drive's heartbeat (0x1016) timed out: the drive is dead or silent; the stack has sent EMCY
 * 0x8130 with the drive's node-ID.
 * Real time: what a real inverter does when its controller is gone: it switches to zero voltage at
 * once (the trip latch: all phases on one rail, an active short circuit, the usual safe state of a
 * PMSM inverter: at speed it keeps the back-EMF from charging the DC link through the diodes) and
 * time goes on, the machine coasting or braking; EMCY 0xFF10, status TRIP, latched until
 * 0x2003:07 trip_clear. The SYNCs go on, so the bench sees the currents decay.
 * Lockstep: simulated time advances only with commands, so a silent drive stops it: the plant keeps
 * waiting (with 0x2003:04 command_timeout_us it holds the last command instead); a drive starved of
 * CPU for a while (its heartbeat then comes back and the EMCY is reset) leaves the run unchanged,
 * and the master judges the drive. */
static void hook_on_hb_timeout(void *user, co_node_t *node, uint8_t node_id)
{
    plant_app_t *app = user_app(user, node);
    (void)node_id;
    if (M.x2003_run_control.mode != OD_PLANT_MODE_REALTIME || !app->started) return;
    app->drive_lost = true;
    app->state.tripped = true;
}

static const co_hooks_t k_hooks = {
    .pre_write = hook_pre_write,
    .post_write = hook_post_write,
    .pre_read = hook_pre_read,
    .on_sync = hook_on_sync,
    .on_rpdo = hook_on_rpdo,
    .on_nmt = hook_on_nmt,
    .on_reset = hook_on_reset,
    .on_hb_timeout = hook_on_hb_timeout,
};

const co_hooks_t *plant_app_hooks(void) { return &k_hooks; }
