/* plant_app_timing.c - the plant app's periods (see plant_app.h): which command answers which
 * sample (late, missed), the real-time timing (0x2006 histograms, 0x2007 figures), and the drivers
 * that produce the SYNCs (lockstep poll, real-time tick).  Portable: no OS headers. */
#include <math.h>
#include <string.h>

#include "plant_app.h"
#include "plant_app_internal.h"

void plant_app_timing_reset(plant_app_t *app)
{
    plant_rtstats_init(&app->lateness, app->hist_bytes);
    plant_rtstats_init(&app->turnaround, app->hist_bytes + PLANT_RTSTATS_BINS * 4u);
    od_plant_realtime_timing_t *t = &M.x2007_realtime_timing;
    memset(t, 0, sizeof *t);
}

void plant_app_timing_publish(plant_app_t *app)
{
    od_plant_realtime_timing_t *t = &M.x2007_realtime_timing;
    const plant_rtstats_t *l = &app->lateness, *r = &app->turnaround;
    t->periods = (uint32_t)l->n;
    t->sync_lateness_min_us = (float)((double)l->min_ns * 1e-3);
    t->sync_lateness_mean_us = (float)plant_rtstats_mean_us(l);
    t->sync_lateness_p50_us = (float)plant_rtstats_quantile_us(l, 0.5);
    t->sync_lateness_p99_us = (float)plant_rtstats_quantile_us(l, 0.99);
    t->sync_lateness_p99_9_us = (float)plant_rtstats_quantile_us(l, 0.999);
    t->sync_lateness_max_us = (float)((double)l->max_ns * 1e-3);
    t->worst_period = (uint32_t)l->max_at;
    t->commands_timed = (uint32_t)r->n;
    t->turnaround_min_us = (float)((double)r->min_ns * 1e-3);
    t->turnaround_mean_us = (float)plant_rtstats_mean_us(r);
    t->turnaround_p50_us = (float)plant_rtstats_quantile_us(r, 0.5);
    t->turnaround_p99_us = (float)plant_rtstats_quantile_us(r, 0.99);
    t->turnaround_p99_9_us = (float)plant_rtstats_quantile_us(r, 0.999);
    t->turnaround_max_us = (float)((double)r->max_ns * 1e-3);
}

static int64_t period_us(const plant_app_t *app) { return (int64_t)llround(app->cfg.Ts_s * 1e6); }

/* The RPDO that carries the voltage command (maps 0x2102). */
const co_pdo_t *plant_app_cmd_rpdo(const plant_app_t *app)
{
    for (uint8_t n = 0; n < CO_NUM_PDO; ++n) {
        const co_pdo_t *p = &app->node->rpdo[n];
        if (!p->valid) continue;
        for (uint8_t i = 0; i < p->count; ++i)
            if (p->entry[i]->index == OD_PLANT_VOLTAGE_COMMAND_IDX) return p;
    }
    return NULL;
}

/* A command frame was received at t_us. The n-th command answers sample n:
 * while commands of missed periods are owed, an arrival is one of them (late). */
void plant_app_note_arrival(plant_app_t *app, int64_t t_us)
{
    ++app->commands;
    if (app->owed > 0u) {
        --app->owed;
        ++M.x2003_run_control.late_commands;
        app->late_in_period = true;
        return;
    }
    app->cmd_ready = true;
    app->cmd_arrival_us = t_us;
    /* real time: the turnaround of a command of its own period, from that period's SYNC (a late one is an
     * overrun, counted at the deadline it missed) */
    if (app->started && M.x2003_run_control.mode == OD_PLANT_MODE_REALTIME)
        plant_rtstats_add(&app->turnaround, (t_us - app->last_sync_us) * 1000, app->k);
}

static void scan_arrivals(plant_app_t *app)
{
    const co_pdo_t *p = plant_app_cmd_rpdo(app);
    if (!p || !p->rx_buffered) return;
    if (app->cmd_seen && p->last_rx_us == app->cmd_seen_rx_us) return;
    app->cmd_seen = true;
    app->cmd_seen_rx_us = p->last_rx_us;
    plant_app_note_arrival(app, p->last_rx_us);
}

/* The current period ends without its command. */
static void handle_miss(plant_app_t *app)
{
    ++M.x2003_run_control.missed_commands;
    app->miss_flag = true;
    if (app->late_in_period) {
        /* lockstep: tolerate a drive that is several periods behind; real time:
         * the SYNCs do not wait, assume at once that a command was dropped */
        uint32_t limit = M.x2003_run_control.mode == OD_PLANT_MODE_REALTIME ? 1u : PLANT_APP_RESYNC_PERIODS;
        if (++app->late_timeout_streak >= limit) {
            app->owed = 0; /* resynchronise: the drive dropped a command */
            app->late_timeout_streak = 0;
            return;
        }
    } else {
        app->late_timeout_streak = 0;
    }
    if (app->owed < PLANT_APP_SCHED_RING - 1u) ++app->owed;
}

/* ------------------------------------------------------------------ drivers */

/* Lockstep: how long the command of the current period may still be waited for (us); 0 when the
 * wait is over; -1 (no wish) when command_timeout_us = 0, which waits for the command as long as
 * the drive is alive (its heartbeat, hook_on_hb_timeout): load then never turns into a held command. */
static int64_t command_wait_left_us(const plant_app_t *app, int64_t now_us)
{
    int64_t timeout = (int64_t)M.x2003_run_control.command_timeout_us;
    if (timeout == 0) return -1;
    int64_t left = timeout - (now_us - app->wait_start_us);
    return left > 0 ? left : 0;
}

static int produce(plant_app_t *app, int64_t now_us)
{
    app->paused = false;
    return co_sync_produce(app->node, now_us);
}

int64_t plant_app_poll(plant_app_t *app, int64_t now_us)
{
    if (!app->node) return -1;
    scan_arrivals(app);
    bool run = plant_app_running(app);
    if (!run) {
        /* Holding (run_periods exhausted) or not operational. The hold is announced only once the
         * command for the last sample is in (or timed out): a master that changes parameters on the
         * hold then changes them exactly between two periods. The announcement: 0x2003:09 = 0 and
         * every event-driven TPDO is sent once (map 0x2003 period_index/state into one to be told). */
        int64_t left = command_wait_left_us(app, now_us);
        bool settled =
            app->node->nmt != CO_NMT_OPERATIONAL || !app->started || app->cmd_ready || app->paused || left == 0;
        app->paused = settled;
        if (!settled) return left;
        if (M.x2003_run_control.state != 0u) {
            M.x2003_run_control.state = 0u;
            for (uint8_t n = 0; n < CO_NUM_PDO; ++n) co_tpdo_request(app->node, n);
        }
        return -1;
    }
    if (M.x2003_run_control.mode == OD_PLANT_MODE_REALTIME) return -1; /* real time: the transport ticks */
    if (app->paused) {
        app->paused = false;
        app->wait_start_us = now_us; /* the timeout counts from the resume */
    }
    if (!app->started || app->cmd_ready) {
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
    if (!plant_app_running(app) || M.x2003_run_control.mode != OD_PLANT_MODE_REALTIME) {
        app->paused = true;
        return -1;
    }
    /* an overrun: the command was not at the plant by the deadline (missed: the SYNC goes without it; or it came
     * after the deadline, before this late SYNC: applied, but late all the same) */
    if (app->started && !app->paused && !app->cmd_ready) {
        handle_miss(app);
        ++M.x2007_realtime_timing.overruns;
    } else if (app->started && !app->paused && app->cmd_arrival_us > now_us - lateness_ns / 1000) {
        ++M.x2007_realtime_timing.overruns;
    }
    plant_rtstats_add(&app->lateness, lateness_ns, app->started ? app->k + 1u : 0u); /* k of this SYNC */
    if (lateness_ns > period_us(app) * 1000) ++M.x2007_realtime_timing.sync_overruns;
    return produce(app, now_us);
}
