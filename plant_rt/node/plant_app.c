/* plant_app.c - the plant app's periods (see plant_app.h): the SYNC hooks (integrate, apply the pending
 * configuration, latch the command, sample and publish), the lockstep poll and the real-time tick that produce the
 * SYNCs, the trip and the drive's loss. The objects and the state are plant_app_od.c's. Portable: no OS headers. */
#include "plant_app.h"

#include <math.h>

#include "co_field_map.h"
#include "meas_coding.h"

#define RUN_FOREVER 0xFFFFFFFFu

/* ------------------------------------------------------------------ status */

/* 0x2100's and 0x2005's entries <- plant_app_t.measurement / .plant_state (their names: plant.eds), every SYNC:
 * one assignment per entry of the generated lists (float <- float, float <- double, integers). */
#define MEASUREMENT_SET(index, sub, record, field, eds_default) CO_FIELD_SET_OD(*m, x, record, field);
#define PLANT_STATE_SET(index, sub, record, field, eds_default) CO_FIELD_SET_OD(*m, p, record, field);

/* A valid TPDO maps the compact frame's current codes (0x2100:07): only then are they computed (and bit 4 of the
 * status, a clipped code, said), so that the default frame set's status is what it always was. */
static bool codes_mapped(const co_node_t *node)
{
    for (uint8_t n = 0; n < CO_NUM_PDO; ++n)
        if (node->tpdo[n].valid &&
            co_pdo_maps_entry(&node->tpdo[n], OD_PLANT_MEASUREMENT_IDX, OD_PLANT_MEASUREMENT_I_A_CODE_SUB))
            return true;
    return false;
}

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
    od_plant_mfr_t *m = plant_mfr(app->node);
    if (codes_mapped(app->node)) { /* the compact frame: its codes, and the status says a clipped current */
        const od_plant_measurement_coding_t *coding = &m->x2104_measurement_coding;
        bool clipped = false;
        x->i_a_code = meas_code_current(x->i_a_A, coding->current_lsb_A, &clipped);
        x->i_b_code = meas_code_current(x->i_b_A, coding->current_lsb_A, &clipped);
        x->theta_code = meas_code_angle(x->theta_m_rad, coding->angle_counts);
        if (clipped) x->status |= PLANT_STATUS_CLIPPED;
    }
    plant_app_plant_state_t *p = &app->plant_state;
    p->id_A = app->meas.id_A;
    p->iq_A = app->meas.iq_A;
    p->omega_m_rad_s = app->meas.omega_m_rad_s;
    p->theta_m_rad = app->meas.theta_m_true_rad;
    p->torque_Nm = app->meas.torque_Nm;
    p->energy_in_J = app->state.energy.in_J;
    p->Ldd_H = app->state.Ldd_H;
    p->Ldq_H = app->state.Ldq_H;
    p->Lqd_H = app->state.Lqd_H;
    p->Lqq_H = app->state.Lqq_H;
    p->T_winding_degC = app->state.T_winding_degC;
    p->R_winding_ohm = app->state.R_winding_ohm;
    OD_PLANT_MEASUREMENT_STATUS(MEASUREMENT_SET)
    OD_PLANT_PLANT_STATE_STATUS(PLANT_STATE_SET)
}

/* ------------------------------------------------------------------ periods (plant_timing.h) */

/* An arrival's turnaround is timed: real time, a period under way. */
static bool timed(const plant_app_t *app) { return app->started && plant_od_realtime(plant_mfr(app->node)); }

/* What a command frame was taken for: a late one is counted (0x2003:06). */
static void take_command(plant_app_t *app, plant_cmd_t got)
{
    if (got == PLANT_CMD_LATE) ++plant_mfr(app->node)->x2003_run_control.late_commands;
}

static void scan_arrivals(plant_app_t *app)
{
    take_command(app, plant_timing_scan(&app->timing, app->node, timed(app), app->k));
}

/* The current period ends without its command (0x2003:05). */
static void handle_miss(plant_app_t *app)
{
    od_plant_mfr_t *m = plant_mfr(app->node);
    ++m->x2003_run_control.missed_commands;
    plant_timing_miss(&app->timing, plant_od_realtime(m));
}

int64_t plant_app_period_ns(const plant_app_t *app) { return (int64_t)llround(app->cfg.Ts_s * 1e9); }

static int64_t period_us(const plant_app_t *app) { return (int64_t)llround(app->cfg.Ts_s * 1e6); }

/* Lockstep: how long the command of the current period may still be waited for (us); 0 when the
 * wait is over; -1 (no wish) when command_timeout_us = 0, which waits for the command as long as
 * the drive is alive (its heartbeat, hook_on_hb_timeout): load then never turns into a held command. */
static int64_t command_wait_left_us(const plant_app_t *app, int64_t now_us)
{
    int64_t timeout = (int64_t)plant_mfr(app->node)->x2003_run_control.command_timeout_us;
    if (timeout == 0) return -1;
    int64_t left = timeout - (now_us - app->wait_start_us);
    return left > 0 ? left : 0;
}

/* The period's SYNC: on the bus, or (0x2003:0B period_mark = measurement) seen by the plant alone, the measurement
 * TPDO with its counter marking the period (co_sync_produce_local). */
static int produce(plant_app_t *app, int64_t now_us)
{
    app->paused = false;
    if (plant_mfr(app->node)->x2003_run_control.period_mark == OD_PLANT_PERIOD_MARK_MEASUREMENT)
        return co_sync_produce_local(app->node, now_us);
    return co_sync_produce(app->node, now_us);
}

int64_t plant_app_poll(plant_app_t *app, int64_t now_us)
{
    if (!app->node) return -1;
    scan_arrivals(app);
    od_plant_mfr_t *m = plant_mfr(app->node);
    bool run = plant_app_running(app);
    if (!run) {
        /* Holding (run_periods exhausted) or not operational. The hold is announced only once the
         * command for the last sample is in (or timed out): a master that changes parameters on the
         * hold then changes them exactly between two periods. The announcement: 0x2003:09 = 0 and
         * every event-driven TPDO is sent once (map 0x2003 period_index/state into one to be told). */
        int64_t left = command_wait_left_us(app, now_us);
        bool settled = app->node->nmt != CO_NMT_OPERATIONAL || !app->started || plant_timing_command_in(&app->timing) ||
                       app->paused || left == 0;
        app->paused = settled;
        if (!settled) return left;
        if (m->x2003_run_control.state != 0u) {
            m->x2003_run_control.state = 0u;
            for (uint8_t n = 0; n < CO_NUM_PDO; ++n) co_tpdo_request(app->node, n);
        }
        return -1;
    }
    if (plant_od_realtime(m)) return -1; /* real time: the transport ticks */
    if (app->paused) {
        app->paused = false;
        app->wait_start_us = now_us; /* the timeout counts from the resume */
    }
    if (!app->started || plant_timing_command_in(&app->timing)) {
        produce(app, now_us);
        return command_wait_left_us(app, now_us);
    }
    int64_t left = command_wait_left_us(app, now_us);
    if (left == 0) {
        handle_miss(app);
        produce(app, now_us);
        return command_wait_left_us(app, now_us);
    }
    return left;
}

int plant_app_realtime_tick(plant_app_t *app, int64_t now_us, int64_t lateness_ns)
{
    if (!app->node) return -1;
    scan_arrivals(app);
    od_plant_mfr_t *m = plant_mfr(app->node);
    if (!plant_app_running(app) || !plant_od_realtime(m)) {
        app->paused = true;
        return -1;
    }
    const bool was_timed = app->started && !app->paused;
    const uint64_t k_sync = app->started ? app->k + 1u : 0u; /* k of this SYNC */
    if (plant_timing_deadline(&app->timing, &m->x2007_realtime_timing, was_timed, now_us, lateness_ns, k_sync,
                              period_us(app)))
        handle_miss(app);
    return produce(app, now_us);
}

/* ------------------------------------------------------------------ hooks */

static plant_app_t *user_app(void *user, co_node_t *node)
{
    plant_app_t *app = (plant_app_t *)user;
    if (!app->node) app->node = node;
    return app;
}

/* The app's objects (plant_app_od.c) bound on the node. */
static void hook_bind(void *user, co_node_t *node) { plant_app_bind_objects((plant_app_t *)user, node); }

static void hook_on_rpdo(void *user, co_node_t *node, uint8_t pdo)
{
    plant_app_t *app = user_app(user, node);
    /* Synchronous RPDO actuated at this SYNC: account for it if poll did not see it yet. */
    take_command(app, plant_timing_actuated(&app->timing, node, pdo, timed(app), app->k));
}

static void hook_on_rpdo_received(void *user, co_node_t *node, uint8_t pdo)
{
    plant_app_t *app = user_app(user, node);
    const co_pdo_t *p = &node->rpdo[pdo];
    if (p == plant_timing_cmd_rpdo(node)) take_command(app, plant_timing_received(&app->timing, p, timed(app), app->k));
}

static void hook_on_sync(void *user, co_node_t *node, uint8_t counter)
{
    plant_app_t *app = user_app(user, node);
    od_plant_mfr_t *m = plant_mfr(node);
    od_plant_run_control_t *rc = &m->x2003_run_control;
    if (node->nmt != CO_NMT_OPERATIONAL || rc->run_periods == 0u) return;
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
    if (app->cfg_dirty) plant_app_apply_pending(app);
    if (app->state.tripped && !rc->trip_active) {
        rc->trip_active = 1u;
        uint8_t msef[5] = {(uint8_t)app->k, (uint8_t)(app->k >> 8), 0, 0, 0};
        app->trip_emcy = app->drive_lost                  ? PLANT_EMCY_DRIVE_LOST
                         : app->state.external_error != 0 ? PLANT_EMCY_MODEL_FAULT
                                                          : PLANT_EMCY_OVERCURRENT;
        co_emcy_raise(node, app->trip_emcy, app->drive_lost ? CO_ERR_REG_COMMUNICATION : CO_ERR_REG_CURRENT, msef);
    }
    /* the next period's commands; the sample's command status: a period missed since the previous sample, a held
     * period (no command frame since the previous SYNC) */
    const uint8_t command_status = plant_timing_sync(&app->timing, now, !k_was_started);
    /* 3. actuate the received command: held in the stator frame over [k, k+1] */
    app->v_held_alpha_V = (double)m->x2102_voltage_command.v_alpha_V;
    app->v_held_beta_V = (double)m->x2102_voltage_command.v_beta_V;

    /* period bookkeeping */
    uint32_t *rp = &rc->run_periods;
    if (*rp != RUN_FOREVER) --*rp;
    ++app->syncs;
    app->wait_start_us = now;

    /* 4. sample */
    plant_sample(&app->state, &app->cfg, &app->meas);
    uint8_t status = command_status;
    if (rc->trip_active) status |= PLANT_STATUS_TRIP;
    if (*rp == 0u) status |= PLANT_STATUS_HOLDING;

    publish_sample(app, counter, status);

    rc->period_index = (uint32_t)app->k;
    rc->outside_map_periods = app->state.outside_map_periods;
    /* Still running until the command for this sample is in (see plant_app_poll). */
    rc->state = 1u;
}

static void hook_on_nmt(void *user, co_node_t *node, co_nmt_state_t st)
{
    plant_app_t *app = user_app(user, node);
    if (st != CO_NMT_OPERATIONAL) plant_timing_drop_buffered(&app->timing); /* the core dropped the buffered RPDOs */
    app->paused = true;
    plant_mfr(node)->x2003_run_control.state = plant_app_running(app) ? 1u : 0u;
}

static void hook_on_reset(void *user, co_node_t *node, int communication_only)
{
    plant_app_t *app = user_app(user, node);
    if (communication_only) {
        plant_timing_forget(&app->timing); /* PDO buffers are gone */
        app->paused = true;
        return;
    }
    plant_app_model_reset(app, plant_mfr(node));
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
    if (!plant_od_realtime(plant_mfr(node)) || !app->started) return;
    app->drive_lost = true;
    app->state.tripped = true;
}

static const co_hooks_t k_hooks = {
    .bind = hook_bind,
    .on_sync = hook_on_sync,
    .on_rpdo = hook_on_rpdo,
    .on_rpdo_received = hook_on_rpdo_received,
    .on_nmt = hook_on_nmt,
    .on_reset = hook_on_reset,
    .on_hb_timeout = hook_on_hb_timeout,
};

const co_hooks_t *plant_app_hooks(void) { return &k_hooks; }
