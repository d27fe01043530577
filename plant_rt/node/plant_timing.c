/* plant_timing.c - the plant's periods as the drive's commands fill them (see plant_timing.h). Portable: no OS
 * headers. */
#include "plant_timing.h"

#include <string.h>

#include "od_plant_fields.h"

/* ------------------------------------------------------------------ state */

void plant_timing_drop_buffered(plant_timing_t *t)
{
    t->cmd_seen = false;
    t->cmd_ready = false;
}

void plant_timing_resync(plant_timing_t *t)
{
    t->owed = 0;
    t->late_timeout_streak = 0;
}

void plant_timing_forget(plant_timing_t *t)
{
    plant_timing_drop_buffered(t);
    plant_timing_resync(t);
    t->cmd_seen_rx_us = 0;
    t->late_in_period = false;
    t->miss_flag = false;
}

void plant_timing_reset_stats(plant_timing_t *t, od_plant_realtime_timing_t *fig)
{
    plant_rtstats_init(&t->lateness, t->hist_bytes);
    plant_rtstats_init(&t->turnaround, t->hist_bytes + PLANT_RTSTATS_BINS * 4u);
    memset(fig, 0, sizeof *fig);
}

void plant_timing_attach(plant_timing_t *t, co_domain_t *hist)
{
    hist->data = t->hist_bytes;
    hist->size = (uint32_t)sizeof t->hist_bytes;
    hist->capacity = 0u; /* read-only */
}

/* One quantity's figures (us): min, mean, p50, p99, p99.9, max. */
static void put_figures(const plant_rtstats_t *s, float *const out[6])
{
    *out[0] = (float)((double)s->min_ns * 1e-3);
    *out[1] = (float)plant_rtstats_mean_us(s);
    *out[2] = (float)plant_rtstats_quantile_us(s, 0.5);
    *out[3] = (float)plant_rtstats_quantile_us(s, 0.99);
    *out[4] = (float)plant_rtstats_quantile_us(s, 0.999);
    *out[5] = (float)((double)s->max_ns * 1e-3);
}

void plant_timing_publish(const plant_timing_t *t, od_plant_realtime_timing_t *fig)
{
    fig->periods = (uint32_t)t->lateness.n;
    fig->worst_period = (uint32_t)t->lateness.max_at;
    fig->commands_timed = (uint32_t)t->turnaround.n;
    put_figures(&t->lateness, (float *const[6]){&fig->sync_lateness_min_us, &fig->sync_lateness_mean_us,
                                                &fig->sync_lateness_p50_us, &fig->sync_lateness_p99_us,
                                                &fig->sync_lateness_p99_9_us, &fig->sync_lateness_max_us});
    put_figures(&t->turnaround,
                (float *const[6]){&fig->turnaround_min_us, &fig->turnaround_mean_us, &fig->turnaround_p50_us,
                                  &fig->turnaround_p99_us, &fig->turnaround_p99_9_us, &fig->turnaround_max_us});
}

/* ------------------------------------------------------------------ commands */

const co_pdo_t *plant_timing_cmd_rpdo(const co_node_t *node)
{
    for (uint8_t n = 0; n < CO_NUM_PDO; ++n) {
        const co_pdo_t *p = &node->rpdo[n];
        if (p->valid && co_pdo_maps(p, OD_PLANT_VOLTAGE_COMMAND_IDX)) return p;
    }
    return NULL;
}

/* The n-th command answers sample n: while commands of missed periods are owed, an arrival is one of them. */
plant_cmd_t plant_timing_arrival(plant_timing_t *t, int64_t t_us, bool timed, uint64_t k)
{
    ++t->commands;
    if (t->owed > 0u) {
        --t->owed;
        t->late_in_period = true;
        return PLANT_CMD_LATE;
    }
    t->cmd_ready = true;
    t->cmd_arrival_us = t_us;
    /* real time: the turnaround of a command of its own period, from that period's SYNC (a late one is an
     * overrun, counted at the deadline it missed) */
    if (timed) plant_rtstats_add(&t->turnaround, (t_us - t->sync_us) * 1000, k);
    return PLANT_CMD_ON_TIME;
}

/* The command RPDO's buffered frame has been accounted for. */
static bool seen(const plant_timing_t *t, const co_pdo_t *p)
{
    return t->cmd_seen && p->last_rx_us == t->cmd_seen_rx_us;
}

plant_cmd_t plant_timing_received(plant_timing_t *t, const co_pdo_t *p, bool timed, uint64_t k)
{
    t->cmd_seen = true;
    t->cmd_seen_rx_us = p->last_rx_us;
    return plant_timing_arrival(t, p->last_rx_us, timed, k);
}

plant_cmd_t plant_timing_scan(plant_timing_t *t, const co_node_t *node, bool timed, uint64_t k)
{
    const co_pdo_t *p = plant_timing_cmd_rpdo(node);
    if (!p || !p->rx_buffered || seen(t, p)) return PLANT_CMD_NONE;
    return plant_timing_received(t, p, timed, k);
}

plant_cmd_t plant_timing_actuated(plant_timing_t *t, const co_node_t *node, uint8_t pdo, bool timed, uint64_t k)
{
    const co_pdo_t *p = plant_timing_cmd_rpdo(node);
    if (!p || p != &node->rpdo[pdo]) return PLANT_CMD_NONE; /* another RPDO: the command's accounting unchanged */
    plant_cmd_t got = seen(t, p) ? PLANT_CMD_NONE : plant_timing_arrival(t, p->last_rx_us, timed, k);
    t->cmd_seen = false;
    return got;
}

bool plant_timing_command_in(const plant_timing_t *t) { return t->cmd_ready; }

/* ------------------------------------------------------------------ periods */

void plant_timing_miss(plant_timing_t *t, bool realtime)
{
    t->miss_flag = true;
    if (t->late_in_period) {
        /* lockstep: tolerate a drive that is several periods behind; real time:
         * the SYNCs do not wait, assume at once that a command was dropped */
        uint32_t limit = realtime ? 1u : PLANT_TIMING_RESYNC_PERIODS;
        if (++t->late_timeout_streak >= limit) {
            t->owed = 0; /* resynchronise: the drive dropped a command */
            t->late_timeout_streak = 0;
            return;
        }
    } else {
        t->late_timeout_streak = 0;
    }
    if (t->owed < PLANT_TIMING_SCHED_RING - 1u) ++t->owed;
}

bool plant_timing_deadline(plant_timing_t *t, od_plant_realtime_timing_t *fig, bool period_timed, int64_t now_us,
                           int64_t lateness_ns, uint64_t k_sync, int64_t period_us)
{
    const bool missed = period_timed && !t->cmd_ready;
    if (missed || (period_timed && t->cmd_arrival_us > now_us - lateness_ns / 1000)) ++fig->overruns;
    plant_rtstats_add(&t->lateness, lateness_ns, k_sync);
    if (lateness_ns > period_us * 1000) ++fig->sync_overruns;
    return missed;
}

uint8_t plant_timing_sync(plant_timing_t *t, int64_t now_us, bool first)
{
    uint8_t status = 0;
    if (t->miss_flag) status |= PLANT_STATUS_MISSED;
    if (!first && t->commands == t->commands_at_sync) status |= PLANT_STATUS_HELD;
    t->miss_flag = false;
    t->commands_at_sync = t->commands;
    t->sync_us = now_us;
    t->cmd_ready = false;
    t->cmd_seen = false;
    t->late_in_period = false;
    return status;
}
