/* plant_timing.h - the plant's periods as the drive's commands fill them: which command answers which sample (on
 * time, late, missed) and the real-time timing of the SYNCs (the histograms 0x2006, the figures 0x2007).
 *
 * A component of the plant app (plant_app.h): its state is its own (plant_timing_t, held by plant_app_t), it
 * reads the node's RPDOs and writes its two objects 0x2006 and 0x2007 (given to it by the app), nothing else. It
 * counts nothing of 0x2003 Run control: it answers, and the app counts (a late command, a miss) and decides when a
 * SYNC goes out. Portable: no OS headers, no allocation.
 *
 * Command accounting: the n-th command frame answers sample n, so after a missed period the next arrival is taken
 * as that late command (0x2003:06) and does not release the next SYNC. Resynchronisation: after
 * PLANT_TIMING_RESYNC_PERIODS consecutive periods that ended without an on-time command although a (presumed late)
 * one arrived in them, the owed count is reset (the drive is assumed to have dropped a command). Real-time mode
 * uses 1. */
#ifndef PLANT_TIMING_H
#define PLANT_TIMING_H

#include <stdbool.h>
#include <stdint.h>

#include "co_node.h"
#include "od_plant.h"
#include "plant_rtstats.h"

#define PLANT_TIMING_RESYNC_PERIODS 3u
#define PLANT_TIMING_SCHED_RING 16u

typedef struct {
    /* command accounting (lockstep and real time) */
    bool cmd_ready;         /* the command for the current period arrived */
    bool cmd_seen;          /* the buffered RPDO has been accounted for */
    int64_t cmd_seen_rx_us; /* its reception time */
    int64_t cmd_arrival_us; /* when the command of the current period arrived (real time: overrun if late) */
    bool late_in_period;    /* a command classified late arrived in this period */
    uint32_t owed;          /* commands of missed periods that may still arrive */
    uint32_t late_timeout_streak;
    bool miss_flag;            /* status bit2 of the next sample */
    uint32_t commands;         /* command frames seen */
    uint32_t commands_at_sync; /* ... at the last SYNC (PLANT_STATUS_HELD) */
    int64_t sync_us;           /* the last SYNC */

    /* real time */
    plant_rtstats_t lateness;                         /* SYNC: its time minus its deadline */
    plant_rtstats_t turnaround;                       /* command arrival minus its period's SYNC */
    uint8_t hist_bytes[2u * PLANT_RTSTATS_BINS * 4u]; /* the DOMAIN 0x2006: lateness, then turnaround */
} plant_timing_t;

/* What a command frame was taken for. */
typedef enum {
    PLANT_CMD_NONE,    /* no new command frame */
    PLANT_CMD_ON_TIME, /* the command of the current period */
    PLANT_CMD_LATE     /* the late command of a missed period (the app counts it: 0x2003:06) */
} plant_cmd_t;

/* ---- state */

/* Forget the commands under way (the node's PDO buffers are gone): the current period's, the owed ones. */
void plant_timing_forget(plant_timing_t *t);
/* The node dropped its buffered RPDOs (it left OPERATIONAL): the current period's command is not in. */
void plant_timing_drop_buffered(plant_timing_t *t);
/* Start the command accounting afresh (the mode changed): nothing owed. */
void plant_timing_resync(plant_timing_t *t);
/* Clear the real-time timing: its statistics, the histograms and the figures `fig` (0x2007). */
void plant_timing_reset_stats(plant_timing_t *t, od_plant_realtime_timing_t *fig);
/* The histograms are read through `hist` (0x2006: a read-only DOMAIN over the component's bytes). */
void plant_timing_attach(plant_timing_t *t, co_domain_t *hist);
/* Copy the statistics into the figures `fig` (0x2007; the percentiles are computed here, not per period). */
void plant_timing_publish(const plant_timing_t *t, od_plant_realtime_timing_t *fig);

/* ---- commands: `timed` = real time and a period under way (the turnaround of an on-time command is timed from
 * its period's SYNC, sample k) */

/* The RPDO of `node` that carries the voltage command (maps 0x2102), NULL if none. */
const co_pdo_t *plant_timing_cmd_rpdo(const co_node_t *node);
/* A command frame was received at t_us: on time, or one of a missed period (late). */
plant_cmd_t plant_timing_arrival(plant_timing_t *t, int64_t t_us, bool timed, uint64_t k);
/* The command RPDO `p` received a frame (the node's on_rpdo_received hook, each frame when it came): taken as
 * arrival() takes it. A drive late by several periods sends their commands in a burst, each of which overwrites
 * the synchronous RPDO's buffer before the SYNC: every one of them is counted (a late one pays off what is owed),
 * so the last is the current period's and the plant's hold at the end of a segment is announced. */
plant_cmd_t plant_timing_received(plant_timing_t *t, const co_pdo_t *p, bool timed, uint64_t k);
/* A command frame in the command RPDO's receive buffer not accounted for yet: taken as arrival() takes it. */
plant_cmd_t plant_timing_scan(plant_timing_t *t, const co_node_t *node, bool timed, uint64_t k);
/* The synchronous RPDO `pdo` was actuated at this SYNC: its frame is taken if scan() did not see it yet. */
plant_cmd_t plant_timing_actuated(plant_timing_t *t, const co_node_t *node, uint8_t pdo, bool timed, uint64_t k);
/* The command of the current period is in. */
bool plant_timing_command_in(const plant_timing_t *t);

/* ---- periods */

/* The current period ends without its command (the app counts the miss: 0x2003:05). */
void plant_timing_miss(plant_timing_t *t, bool realtime);
/* Real time, at the deadline of a SYNC (sample k_sync) that ends a timed period (`period_timed`:
 * not the first, not after a pause): an overrun if the command was not at the plant by the deadline (missed: the SYNC
 * goes without it; or it came after the deadline, before this late SYNC: applied, but late all the same), the SYNC's
 * lateness, a SYNC later than a whole period; into 0x2007 `fig`. Returns whether the period was missed (the app
 * then takes it as plant_timing_miss() does, and counts it). */
bool plant_timing_deadline(plant_timing_t *t, od_plant_realtime_timing_t *fig, bool period_timed, int64_t now_us,
                           int64_t lateness_ns, uint64_t k_sync, int64_t period_us);
/* A SYNC at now_us starts the next period (`first`: its sample is the first). Returns the command's status bits
 * of the sample it takes: PLANT_STATUS_MISSED (a period since the previous sample went without its command),
 * PLANT_STATUS_HELD (no command frame since the previous SYNC; the first sample has none to hold). */
uint8_t plant_timing_sync(plant_timing_t *t, int64_t now_us, bool first);

#endif /* PLANT_TIMING_H */
