/* plant_app_od.h - the plant app's state and its objects (portable glue: no OS headers).
 *
 * The lower half of the plant app (plant_app.h, the API's header, includes this one; plant_app.c, the periods and
 * the SYNC hooks, calls it, never the other way). It owns:
 *   - plant_app_t, the app's state, and the views of the OD's manufacturer part (plant_mfr);
 *   - OD 0x2000-0x2002 <-> plant_config_t (the rows are the EDS's own lists, od_plant_fields.h);
 *   - the objects the app binds on its node (co_node_bind) and what a read or a write of them does:
 *       0x2000-0x2002  model parameters: a write is checked against the whole configuration at once
 *                      (a combination the core rejects -> abort 0x06040043, the model is unchanged)
 *                      and takes effect at the next SYNC (plant_app_apply_pending);
 *       0x2003         run control: trip clear, the mode (restarts the period's timing), run_periods;
 *       0x2004         motor preset: writing a name loads it into 0x2000-0x2002
 *                      (unknown name -> abort 0x06090030);
 *       0x2007         real-time timing: computed when read, :12 reset;
 *       0x2008         flux map: a download checked whole (plant_fluxmap_obj.h), in PRE-OPERATIONAL only;
 *       0x2009         FMU: a text the host's loader (plant_rt/fmu/) loads, in PRE-OPERATIONAL only;
 *   - the model's reset (init, NMT reset node) and the pending configuration applied at a SYNC. */
#ifndef PLANT_APP_OD_H
#define PLANT_APP_OD_H

#include <stdbool.h>
#include <stdint.h>

#include "co_node.h"
#include "od_plant_fields.h"
#include "od_plant.h"
#include "plant_fluxmap_obj.h"
#include "plant_timing.h"
#include "pmsm_plant.h"

/* The plant's OD RAM (its manufacturer part, 0x2000-0x2FFF) through the OD's table: a node's (plant_mfr), or
 * od_plant's itself before the node exists (plant_app_init, plant_app_config_*). */
static inline od_plant_mfr_t *plant_od_mfr(const co_od_t *od) { return &((od_plant_ram_t *)od->ram)->mfr; }
static inline od_plant_mfr_t *plant_mfr(const co_node_t *node) { return plant_od_mfr(node->od); }
/* 0x2003:01 == 1 in the OD `m`. */
static inline bool plant_od_realtime(const od_plant_mfr_t *m)
{
    return m->x2003_run_control.mode == OD_PLANT_MODE_REALTIME;
}

/* The read-only entries of 0x2100 Measurement and 0x2005 Plant state, named as in plant.eds: the
 * SYNC fills them and the list od_plant_fields.h generates (OD_PLANT_<RECORD>_STATUS) copies them
 * to the OD, so an entry's name is written once, in the EDS.  (0x2003 Run control's status stays
 * in the OD: the plant counts and tests it there.) */
typedef struct { /* 0x2100 Measurement (TPDO1, TPDO2; or the compact frame) */
    float i_a_A;
    float i_b_A;
    float theta_m_rad;
    uint8_t sync_counter;
    uint8_t status; /* PLANT_STATUS_* */
    uint16_t sample_index;
    int16_t i_a_code; /* the compact frame's codes (protocols/coding/meas_coding.h, 0x2104) */
    int16_t i_b_code;
    uint16_t theta_code;
} plant_app_measurement_t;

typedef struct { /* 0x2005 Plant state: the model's truth, REAL32 in the OD */
    double id_A;
    double iq_A;
    double omega_m_rad_s;
    double theta_m_rad;
    double torque_Nm;
    double energy_in_J;
    double Ldd_H; /* the flux_map model's incremental inductances at the present currents */
    double Ldq_H;
    double Lqd_H;
    double Lqq_H;
    double T_winding_degC;
    double R_winding_ohm;
} plant_app_plant_state_t;

/* Loads the external model a 0x2009 "FMU" text describes (host glue, plant_rt/fmu/: the node's main or the direct
 * mode sets it): 0 and *ext, or an SDO abort code. */
typedef uint32_t (*plant_app_fmu_load_t)(const uint8_t *text, uint32_t len, const plant_external_t **ext);

#define PLANT_APP_FMU_TEXT_BYTES 4096u

typedef struct {
    co_node_t *node;
    /* The objects the app owns, bound at init (co_node_bind, hooks.bind): the model records and the preset
     * (0x2000-0x2002, 0x2004: checked against the whole configuration, in effect at the next SYNC), run control
     * (0x2003) and the real-time timing (0x2007: computed when read). */
    co_od_ext_t ext_model, ext_preset, ext_run, ext_timing, ext_fluxmap, ext_fmu;
    /* 0x2009 FMU: its text (a download lands here), the loader the host gave, the model it loaded
     * (plant_config_t.external) and whether the model starts afresh at the next SYNC */
    uint8_t fmu_text[PLANT_APP_FMU_TEXT_BYTES];
    plant_app_fmu_load_t fmu_load;
    const plant_external_t *external;
    bool external_restart;
    /* 0x2008 Flux map: the tables of the flux_map model (plant_config_t.flux_map points into them) */
    plant_fluxmap_obj_t fluxmap;

    /* model */
    plant_config_t cfg; /* applied configuration */
    plant_state_t state;
    plant_meas_t meas;                   /* sample of the last SYNC */
    plant_app_measurement_t measurement; /* 0x2100 of the last SYNC */
    plant_app_plant_state_t plant_state; /* 0x2005 of the last SYNC */
    plant_config_t scratch_cfg;          /* SDO validation (not in the per-period path) */
    plant_state_t scratch_state;
    bool cfg_dirty; /* OD 0x2000-0x2002 changed: apply at the next SYNC */
    bool reseed;    /* rng_seed written: re-seed at the next SYNC */
    uint32_t config_applies;
    uint32_t config_errors; /* pending change rejected by plant_prepare at the SYNC (should stay 0) */

    /* periods */
    bool started;                         /* SYNC 0 happened */
    uint64_t k;                           /* index of the last sample */
    double v_held_alpha_V, v_held_beta_V; /* command held over [k, k+1] */
    int64_t wait_start_us;                /* lockstep: command timeout counts from here */
    bool paused;                          /* not running at the last poll (holding / not operational) */
    uint32_t syncs;
    bool drive_lost;    /* the trip latched because the drive's heartbeat was lost (EMCY 0xFF10) */
    uint16_t trip_emcy; /* the EMCY code the active trip raised (cleared with it) */

    /* the commands' accounting (late, missed) and the real-time timing (0x2006, 0x2007) */
    plant_timing_t timing;
} plant_app_t;

/* Zero the app and load the OD defaults into the model (callable before co_node_init). */
void plant_app_init(plant_app_t *app);
/* The host's FMU loader (after plant_app_init; none: 0x2009 refuses every FMU). */
static inline void plant_app_set_fmu_loader(plant_app_t *app, plant_app_fmu_load_t load) { app->fmu_load = load; }
/* Remember the node (co_node_init's bind hook does it, and binds the app's objects). */
void plant_app_bind(plant_app_t *app, co_node_t *node);

/* NMT OPERATIONAL and run_periods > 0. */
bool plant_app_running(const plant_app_t *app);
/* 0x2003:01 == 1. */
bool plant_app_realtime_mode(const plant_app_t *app);

/* Load the named preset into the OD entries 0x2000-0x2002 (as the 0x2004 write does);
 * effective at the next SYNC. Returns 0 or PLANT_ERR_PRESET. */
int plant_app_load_preset(plant_app_t *app, const char *name);

/* OD 0x2000-0x2002 -> config (exact float -> double). */
void plant_app_config_from_od(plant_config_t *c);
/* config -> OD 0x2000-0x2002 (rounded to REAL32). */
void plant_app_config_to_od(const plant_config_t *c);

/* ---- for the periods (plant_app.c) */

/* Remember the node and bind the app's objects on it (the hooks' bind). */
void plant_app_bind_objects(plant_app_t *app, co_node_t *node);
/* The model from the OD `m`, the periods and the timing from the start. */
void plant_app_model_reset(plant_app_t *app, od_plant_mfr_t *m);
/* At a SYNC: the changed configuration of 0x2000-0x2002 takes effect (a rejected one is counted, the applied
 * one kept). */
void plant_app_apply_pending(plant_app_t *app);

#endif /* PLANT_APP_OD_H */
