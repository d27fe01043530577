/* plant_app_od.c - the plant app's state and its objects: OD <-> config, the model, preset, run-control and timing
 * objects with their checks, the model's reset (see plant_app_od.h). Portable: no OS headers. */
#include "plant_app_od.h"

#include <string.h>

#include "co_field_map.h"
#include "presets.h"

/* ------------------------------------------------------------------ OD <-> config */

/* Motor model, Inverter and Sensors (0x2000-0x2002) <-> plant_config_t: the rows are the EDS's
 * own lists (od_plant.h), the fields of plant_config_t carry the EDS names. */
#define PLANT_ROW(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW(od_plant_mfr_t, plant_config_t, record, field),
/* one list a line (clang-format would run the macro lists together) */
/* the machine models' own records (plant_types.h: plant_model_params_t, by the record's member) */
#define MODEL_ROW(index, sub, record, field, eds_default) \
    CO_FIELD_MAP_ROW_IN(od_plant_mfr_t, plant_config_t, params.record, record, field),
#define MODEL_ROWS(name, type, record, index, fields) fields(MODEL_ROW)
/* clang-format off */
static const co_field_map_t config_rows[] = {
    OD_PLANT_MOTOR_MODEL_PARAMS(PLANT_ROW)
    OD_PLANT_INVERTER_PARAMS(PLANT_ROW)
    OD_PLANT_SENSORS_PARAMS(PLANT_ROW)
    OD_PLANT_MODEL_RECORDS(MODEL_ROWS)};
/* clang-format on */
#undef PLANT_ROW
#undef MODEL_ROWS
#undef MODEL_ROW
#define N_CONFIG_ROWS (sizeof config_rows / sizeof config_rows[0])

static void config_from(const od_plant_mfr_t *m, plant_config_t *c)
{
    plant_config_defaults(c); /* the fields the OD does not carry */
    co_field_map_to_core(config_rows, N_CONFIG_ROWS, m, c);
}

/* The app's configuration: the OD's values and the app's own flux map. */
static void config_of(const plant_app_t *app, const od_plant_mfr_t *m, plant_config_t *c)
{
    config_from(m, c);
    c->flux_map = plant_fluxmap_obj_map(&app->fluxmap);
    c->external = app->external;
}

void plant_app_config_from_od(plant_config_t *c) { config_from(plant_od_mfr(&od_plant), c); }

static void config_to(od_plant_mfr_t *m, const plant_config_t *c)
{
    co_field_map_to_od(config_rows, N_CONFIG_ROWS, m, c);
}

void plant_app_config_to_od(const plant_config_t *c) { config_to(plant_od_mfr(&od_plant), c); }

/* ------------------------------------------------------------------ state */

/* The app's OD: its node's; od_plant's (the same RAM) before co_node_init bound the node. */
static od_plant_mfr_t *od_of(const plant_app_t *app)
{
    return app->node ? plant_mfr(app->node) : plant_od_mfr(&od_plant);
}

void plant_app_model_reset(plant_app_t *app, od_plant_mfr_t *m)
{
    plant_fluxmap_obj_init(&app->fluxmap, &m->x2008_flux_map); /* a reset forgets the map, as the OD's values */
    app->external = NULL;                                      /* ... and the FMU (written again to be used) */
    app->external_restart = false;
    m->x2009_FMU = (co_domain_t){app->fmu_text, 0u, (uint32_t)sizeof app->fmu_text};
    config_of(app, m, &app->cfg);
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
    plant_timing_forget(&app->timing);
    plant_timing_reset_stats(&app->timing, &m->x2007_realtime_timing);
    plant_timing_attach(&app->timing, &m->x2006_timing_histograms);
}

void plant_app_init(plant_app_t *app)
{
    memset(app, 0, sizeof *app);
    co_od_reset(&od_plant, OD_PLANT_DEFAULT_NODE_ID, 0);
    plant_app_model_reset(app, plant_od_mfr(&od_plant));
}

void plant_app_bind(plant_app_t *app, co_node_t *node) { app->node = node; }

bool plant_app_running(const plant_app_t *app)
{
    return app->node && app->node->nmt == CO_NMT_OPERATIONAL &&
           plant_mfr(app->node)->x2003_run_control.run_periods > 0u;
}

bool plant_app_realtime_mode(const plant_app_t *app) { return plant_od_realtime(od_of(app)); }

void plant_app_apply_pending(plant_app_t *app)
{
    plant_config_t *c = &app->scratch_cfg;
    config_of(app, plant_mfr(app->node), c);
    if (plant_prepare(&app->state, c) == PLANT_OK) {
        app->cfg = *c;
        if (app->reseed) plant_rng_seed(&app->state.rng, app->cfg.rng_seed);
        if (app->external_restart && app->cfg.model == PLANT_MODEL_EXTERNAL) {
            (void)plant_external_restart(&app->state, &app->cfg); /* its initial state; a failure trips */
            app->external_restart = false;
        }
        ++app->config_applies;
    } else {
        ++app->config_errors;
        (void)plant_prepare(&app->state, &app->cfg);
    }
    app->cfg_dirty = false;
    app->reseed = false;
}

/* ------------------------------------------------------------------ the objects */

/* 0x2000-0x2002 and the models' records: validate a write against the whole configuration: store it temporarily, read
 * the config back, restore, try plant_prepare on a copy. Sub-index 0 (the entry count) is the node's own. */
static uint32_t model_check(void *object, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    plant_app_t *app = (plant_app_t *)object;
    if (e->subindex == 0u) return 0;
    uint8_t saved[8];
    uint32_t n = e->size <= sizeof saved ? e->size : (uint32_t)sizeof saved;
    memcpy(saved, e->data, n);
    co_od_store(e, data, len);
    config_of(app, plant_mfr(app->node), &app->scratch_cfg);
    memcpy(e->data, saved, n);
    app->scratch_state = app->state;
    return plant_prepare(&app->scratch_state, &app->scratch_cfg) == PLANT_OK ? 0u : CO_ABORT_PARAM_INCOMPAT;
}

static void model_written(void *object, const co_od_entry_t *e)
{
    plant_app_t *app = (plant_app_t *)object;
    if (e->subindex == 0u) return;
    app->cfg_dirty = true;
    if (e->index == OD_PLANT_SENSORS_IDX && e->subindex == OD_PLANT_SENSORS_RNG_SEED_SUB) app->reseed = true;
}

/* 0x2004: a preset's name, checked by loading it. */
static uint32_t preset_check(void *object, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    plant_app_t *app = (plant_app_t *)object;
    (void)e;
    char name[40];
    if (len >= sizeof name) return CO_ABORT_INVALID_VALUE;
    memcpy(name, data, len);
    name[len] = '\0';
    if (plant_preset_load(name, &app->scratch_cfg) != 0) return CO_ABORT_INVALID_VALUE;
    app->scratch_state = app->state;
    if (plant_prepare(&app->scratch_state, &app->scratch_cfg) != PLANT_OK) return CO_ABORT_PARAM_INCOMPAT;
    return 0;
}

int plant_app_load_preset(plant_app_t *app, const char *name)
{
    if (plant_preset_load(name, &app->scratch_cfg) != 0) return PLANT_ERR_PRESET;
    config_to(od_of(app), &app->scratch_cfg);
    app->cfg_dirty = true;
    app->reseed = true;
    return 0;
}

static void preset_written(void *object, const co_od_entry_t *e)
{
    (void)e;
    plant_app_t *app = (plant_app_t *)object;
    (void)plant_app_load_preset(app, plant_mfr(app->node)->x2004_motor_preset);
}

/* 0x2003: trip clear (a command: reads back 0), the mode (restarts the period's timing), run_periods. */
static void run_written(void *object, const co_od_entry_t *e)
{
    plant_app_t *app = (plant_app_t *)object;
    od_plant_run_control_t *rc = &plant_mfr(app->node)->x2003_run_control;
    switch (e->subindex) {
    case OD_PLANT_RUN_CONTROL_TRIP_CLEAR_SUB:
        if (rc->trip_clear == 1u) {
            plant_clear_trip(&app->state);
            if (rc->trip_active) {
                rc->trip_active = 0u;
                co_emcy_clear(app->node, app->trip_emcy);
            }
            app->drive_lost = false;
        }
        rc->trip_clear = 0u;
        break;
    case OD_PLANT_RUN_CONTROL_MODE_SUB:
        app->paused = true;                /* restart the timing of the current period */
        plant_timing_resync(&app->timing); /* start the command accounting afresh */
        break;
    case OD_PLANT_RUN_CONTROL_RUN_PERIODS_SUB: rc->state = plant_app_running(app) ? 1u : 0u; break;
    default: break;
    }
}

/* 0x2008 and 0x2009 are written before a run: in PRE-OPERATIONAL, before the first SYNC after a reset (the model
 * in use reads the tables and steps the FMU from the first period on; a mid-run change would step one period with
 * the new model and the old state). */
static bool model_object_writable(const plant_app_t *app)
{
    return app->node->nmt != CO_NMT_OPERATIONAL && !app->started;
}

/* 0x2008: a download is checked whole and replaces the live map only when it passes; the model is prepared again
 * at the next SYNC.  An upload reads the live map. */
static uint32_t fluxmap_check(void *object, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    (void)e;
    plant_app_t *app = (plant_app_t *)object;
    if (!model_object_writable(app)) return CO_ABORT_DATA_STATE;
    return plant_fluxmap_obj_accept(&app->fluxmap, data, len);
}

static void fluxmap_written(void *object, const co_od_entry_t *e)
{
    (void)e;
    ((plant_app_t *)object)->cfg_dirty = true;
}

static void fluxmap_read(void *object, const co_od_entry_t *e)
{
    (void)e;
    plant_app_t *app = (plant_app_t *)object;
    plant_fluxmap_obj_publish(&app->fluxmap, &plant_mfr(app->node)->x2008_flux_map);
}

/* 0x2009: the host's loader loads the FMU the text names; the model starts from its initial state at the next
 * SYNC.  A refused text leaves the plant without an FMU (the loader unloads the one before first). */
static uint32_t fmu_check(void *object, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    (void)e;
    plant_app_t *app = (plant_app_t *)object;
    if (!model_object_writable(app)) return CO_ABORT_DATA_STATE;
    if (app->fmu_load == NULL) return CO_ABORT_UNSUPPORTED;
    const plant_external_t *ext = NULL;
    const uint32_t abort = app->fmu_load(data, len, &ext);
    if (abort != 0u) {
        /* the loader let the FMU loaded before go: the plant has no external model any more */
        app->external = NULL;
        app->cfg.external = NULL;
        app->cfg_dirty = true;
        return abort;
    }
    app->external = ext;
    app->external_restart = true;
    return 0u;
}

static void fmu_written(void *object, const co_od_entry_t *e)
{
    (void)e;
    ((plant_app_t *)object)->cfg_dirty = true;
}

/* 0x2007 is read: its figures from the statistics (the percentiles are computed here, not per period); :12 reset
 * (a command: reads back 0). */
static void timing_read(void *object, const co_od_entry_t *e)
{
    (void)e;
    plant_app_t *app = (plant_app_t *)object;
    plant_timing_publish(&app->timing, &plant_mfr(app->node)->x2007_realtime_timing);
}

static void timing_written(void *object, const co_od_entry_t *e)
{
    if (e->subindex != OD_PLANT_REALTIME_TIMING_RESET_SUB) return;
    plant_app_t *app = (plant_app_t *)object;
    od_plant_realtime_timing_t *fig = &plant_mfr(app->node)->x2007_realtime_timing;
    if (fig->reset == 1u) plant_timing_reset_stats(&app->timing, fig);
    fig->reset = 0u;
}

void plant_app_bind_objects(plant_app_t *app, co_node_t *node)
{
    app->node = node;
    app->ext_model = (co_od_ext_t){app, NULL, model_check, model_written};
    app->ext_preset = (co_od_ext_t){app, NULL, preset_check, preset_written};
    app->ext_run = (co_od_ext_t){app, NULL, NULL, run_written};
    app->ext_timing = (co_od_ext_t){app, timing_read, NULL, timing_written};
    app->ext_fluxmap = (co_od_ext_t){app, fluxmap_read, fluxmap_check, fluxmap_written};
    app->ext_fmu = (co_od_ext_t){app, NULL, fmu_check, fmu_written};
    /* which object owns which index (the model's three records share one) */
    const struct {
        uint16_t index;
        co_od_ext_t *ext;
    } objects[] = {
        {OD_PLANT_MOTOR_MODEL_IDX, &app->ext_model}, {OD_PLANT_INVERTER_IDX, &app->ext_model},
        {OD_PLANT_SENSORS_IDX, &app->ext_model},     {OD_PLANT_MOTOR_PRESET_IDX, &app->ext_preset},
        {OD_PLANT_RUN_CONTROL_IDX, &app->ext_run},   {OD_PLANT_REALTIME_TIMING_IDX, &app->ext_timing},
        {OD_PLANT_FLUX_MAP_IDX, &app->ext_fluxmap},  {OD_PLANT_FMU_IDX, &app->ext_fmu},
    };
    for (size_t i = 0; i < sizeof objects / sizeof objects[0]; ++i)
        (void)co_node_bind(node, objects[i].index, objects[i].ext);
        /* each machine model's own record is checked against the whole configuration, as the motor model's */
#define MODEL_RECORD_BIND(name, type, record, index, fields) (void)co_node_bind(node, index, &app->ext_model);
    OD_PLANT_MODEL_RECORDS(MODEL_RECORD_BIND)
#undef MODEL_RECORD_BIND
}
