/* test_node_lockstep.c - lockstep SYNC production, missed and late commands,
 * run_periods holding, and the real-time tick (time driven by hand). */
#include <math.h>
#include <stdio.h>

#include "check.h"
#include "plant_testbus.h"

static tb_t g_tb;

#define RC (OD_PLANT.mfr.x2003_run_control)

static const tb_sample_t *last(const tb_t *tb) { return &tb->smp[tb->n_smp - 1u]; }

static void test_holds_and_timeout(void)
{
    tb_t *tb = &g_tb;
    tb_init(tb);
    const uint32_t timeout_us = 1000;
    CHECK(tb_w_u32(tb, 0x2003, OD_PLANT_RUN_CONTROL_COMMAND_TIMEOUT_US_SUB, timeout_us) == 0, "timeout");
    /* nothing before NMT start / run_periods */
    tb_poll(tb);
    CHECK(tb->n_sync == 0, "SYNC while pre-operational");
    tb_nmt(tb, 0x01u);
    tb->bus.now_us = 5000;
    tb_poll(tb);
    CHECK(tb->n_sync == 0, "SYNC with run_periods = 0");
    CHECK(RC.state == 0, "state %u", RC.state);
    tb_w_u32(tb, 0x2003, OD_PLANT_RUN_CONTROL_RUN_PERIODS_SUB, 0xFFFFFFFFu);
    int64_t t0 = tb->bus.now_us;
    int64_t hint = tb_poll(tb);
    CHECK(tb->n_sync == 1 && tb->n_smp == 1, "SYNC 0 (n_sync %u)", (unsigned)tb->n_sync);
    CHECK(hint == timeout_us, "wait hint %lld", (long long)hint);

    /* no command: the plant waits */
    uint32_t polls = 0;
    for (tb->bus.now_us = t0 + 1; tb->bus.now_us < t0 + timeout_us; tb->bus.now_us += 37) {
        hint = tb_poll(tb);
        ++polls;
        CHECK(tb->n_sync == 1, "SYNC 1 before the command / timeout at t+%lld", (long long)(tb->bus.now_us - t0));
        CHECK(hint == t0 + timeout_us - tb->bus.now_us, "hint %lld at t+%lld", (long long)hint,
              (long long)(tb->bus.now_us - t0));
    }
    printf("no command: %u polls over %u us, SYNCs %u (held)\n", (unsigned)polls, (unsigned)timeout_us,
           (unsigned)tb->n_sync);
    tb->bus.now_us = t0 + timeout_us;
    tb_poll(tb);
    CHECK(tb->n_sync == 2, "SYNC 1 at the timeout");
    CHECK(RC.missed_commands == 1, "missed %u", (unsigned)RC.missed_commands);
    CHECK(last(tb)->status & PLANT_STATUS_MISSED, "status bit2 after a miss");
    printf("timeout after %u us: SYNC 1 sent, missed = %u, status = 0x%02x\n", (unsigned)timeout_us,
           (unsigned)RC.missed_commands, last(tb)->status);

    /* the late command for sample 0 arrives now: late, does not release SYNC 2 */
    tb->bus.now_us += 50;
    tb_cmd(tb, 1.0f, 0.0f);
    tb_poll(tb);
    CHECK(tb->n_sync == 2, "a late command released a SYNC");
    CHECK(RC.late_commands == 1, "late %u", (unsigned)RC.late_commands);
    /* the command for sample 1: releases SYNC 2 at once */
    tb->bus.now_us += 50;
    tb_cmd(tb, 2.0f, 0.0f);
    tb_poll(tb);
    CHECK(tb->n_sync == 3, "the on-time command did not release SYNC 2");
    CHECK(!(last(tb)->status & PLANT_STATUS_MISSED), "status bit2 stuck");
    CHECK(tb->app.v_held_alpha_V == 2.0, "actuated %g, expected the on-time command 2 V", tb->app.v_held_alpha_V);
    printf("late command counted (late = %u), on-time one actuated (%.1f V)\n", (unsigned)RC.late_commands,
           tb->app.v_held_alpha_V);

    /* prompt commands: one SYNC per command, no timeouts */
    for (int j = 0; j < 100; ++j) tb_period(tb, 0.5f, 0.0f);
    CHECK(tb->n_sync == 103 && RC.missed_commands == 1 && RC.late_commands == 1, "steady run: %u %u %u",
          (unsigned)tb->n_sync, (unsigned)RC.missed_commands, (unsigned)RC.late_commands);

    /* a dropped command (never sent): lockstep resynchronises */
    uint32_t miss0 = RC.missed_commands;
    tb->bus.now_us += timeout_us;
    tb_poll(tb); /* timeout */
    uint32_t syncs0 = tb->n_sync;
    int extra_timeouts = 0;
    for (int j = 0; j < 10; ++j) {
        tb->bus.now_us += 10;
        tb_cmd(tb, 0.5f, 0.0f);
        tb_poll(tb);
        if (tb->n_sync == syncs0 + (uint32_t)j) { /* not released: wait for the timeout */
            tb->bus.now_us += timeout_us;
            tb_poll(tb);
            ++extra_timeouts;
        }
    }
    printf("dropped command: %u timeouts until resync (limit %u), missed %u, late %u\n",
           (unsigned)(RC.missed_commands - miss0), (unsigned)PLANT_TIMING_RESYNC_PERIODS, (unsigned)RC.missed_commands,
           (unsigned)RC.late_commands);
    CHECK(RC.missed_commands - miss0 == 1u + PLANT_TIMING_RESYNC_PERIODS, "resync took %u timeouts",
          (unsigned)(RC.missed_commands - miss0));

    /* a drive 3 periods behind (stall), then catching up: no permanent shift */
    tb_t *t = tb;
    uint32_t late0 = RC.late_commands;
    for (int j = 0; j < 3; ++j) {
        t->bus.now_us += timeout_us;
        tb_poll(t);
    }
    uint32_t s1 = t->n_sync;
    for (int j = 0; j < 3; ++j) {
        t->bus.now_us += 5;
        tb_cmd(t, 9.0f, 0.0f); /* the stale ones */
        tb_poll(t);
    }
    CHECK(t->n_sync == s1, "stale commands released a SYNC");
    CHECK(RC.late_commands - late0 == 3, "late %u", (unsigned)(RC.late_commands - late0));
    tb_period(t, 3.0f, 0.0f);
    CHECK(t->n_sync == s1 + 1 && t->app.v_held_alpha_V == 3.0, "catch-up command not actuated");
    printf("stall of 3 periods: 3 late commands discarded by order, the current one actuated\n");
}

static void test_run_periods(void)
{
    tb_t *tb = &g_tb;
    tb_init(tb);
    tb_start(tb, 5);
    for (int j = 0; j < 10; ++j) tb_period(tb, 0.0f, 0.0f);
    CHECK(tb->n_sync == 5, "run_periods 5 gave %u SYNCs", (unsigned)tb->n_sync);
    CHECK(last(tb)->status & PLANT_STATUS_HOLDING, "holding bit on the last sample");
    CHECK(RC.state == 0 && RC.run_periods == 0, "state %u run_periods %u", RC.state, (unsigned)RC.run_periods);
    /* the command for sample 4 arrived while holding: resume releases SYNC 5 at once */
    tb_w_u32(tb, 0x2003, OD_PLANT_RUN_CONTROL_RUN_PERIODS_SUB, 3);
    tb_poll(tb);
    CHECK(tb->n_sync == 6 && last(tb)->index == 5, "resume: n_sync %u", (unsigned)tb->n_sync);
    for (int j = 0; j < 5; ++j) tb_period(tb, 0.0f, 0.0f);
    CHECK(tb->n_sync == 8, "second run gave %u SYNCs in all", (unsigned)tb->n_sync);
    CHECK(RC.period_index == 7, "period_index %u", (unsigned)RC.period_index);
    CHECK(RC.missed_commands == 0, "missed %u", (unsigned)RC.missed_commands);
    /* NMT stop: nothing more even with run_periods */
    tb_w_u32(tb, 0x2003, OD_PLANT_RUN_CONTROL_RUN_PERIODS_SUB, 0xFFFFFFFFu);
    tb_nmt(tb, 0x02u);
    tb->bus.now_us += 1000000;
    tb_poll(tb);
    CHECK(tb->n_sync == 8, "SYNC while stopped");
    printf("run_periods: 5 -> %u SYNCs then holding (status 0x%02x), +3 -> 8; stopped: no SYNC\n", 5u,
           tb->smp[4].status);
}

static void test_realtime_tick(void)
{
    tb_t *tb = &g_tb;
    tb_init(tb);
    tb_w_u8(tb, 0x2003, OD_PLANT_RUN_CONTROL_MODE_SUB, 1);
    tb_w_u32(tb, 0x2003, OD_PLANT_RUN_CONTROL_RUN_PERIODS_SUB, 0xFFFFFFFFu);
    tb_nmt(tb, 0x01u);
    CHECK(tb_poll(tb) == -1 && tb->n_sync == 0, "poll produced a SYNC in real-time mode");
    const int64_t Ts = 55;
    int64_t deadline = 1000;
    /* arrival offsets relative to the next deadline: -40 (early), -5, +12 (late), none (miss) */
    const int64_t offs[] = {-40, -5, 12, 1000, -30, -30};
    tb->bus.now_us = deadline;
    plant_app_realtime_tick(&tb->app, tb->bus.now_us, 0);
    tb_deliver(tb);
    for (unsigned j = 0; j < sizeof offs / sizeof offs[0]; ++j) {
        int64_t next = deadline + Ts;
        if (offs[j] < 0) {
            tb->bus.now_us = next + offs[j];
            tb_cmd(tb, 1.0f, 0.0f);
            plant_app_poll(&tb->app, tb->bus.now_us);
        }
        tb->bus.now_us = next + 3; /* woke 3 us late */
        plant_app_realtime_tick(&tb->app, tb->bus.now_us, 3000);
        tb_deliver(tb);
        if (offs[j] >= 0 && offs[j] < 1000) {
            tb->bus.now_us = next + offs[j];
            tb_cmd(tb, 1.0f, 0.0f);
            plant_app_poll(&tb->app, tb->bus.now_us);
        }
        deadline = next;
    }
    /* turnarounds timed (commands of their own period, from its SYNC): 1015-1000, 1105-1058, (late: not
     * timed), (none), 1245-1223, 1300-1278 us; SYNC lateness 0 once, then 3 us six times */
    CHECK(tb->n_sync == 7, "n_sync %u", (unsigned)tb->n_sync);
    CHECK(RC.missed_commands == 2 && RC.late_commands == 1, "missed %u late %u", (unsigned)RC.missed_commands,
          (unsigned)RC.late_commands);
    float f[19];
    for (uint8_t sub = 1; sub <= 17; ++sub) {
        uint8_t buf[4] = {0, 0, 0, 0};
        uint32_t n = 0, segments = 0;
        CHECK(testbus_sdo_upload(&tb->bus, 0x2007, sub, buf, sizeof buf, &n, &segments) == 0 && n == 4,
              "0x2007:%u read", sub);
        memcpy(&f[sub], buf, 4);
    }
    uint32_t u[19];
    memcpy(u, f, sizeof u);
    printf("real time: SYNCs %u, missed %u, late %u; lateness min %.1f mean %.2f p50 %.1f max %.1f us; "
           "turnaround min %.1f mean %.2f p50 %.1f p99 %.1f max %.1f us; overruns %u\n",
           (unsigned)tb->n_sync, (unsigned)RC.missed_commands, (unsigned)RC.late_commands, (double)f[2], (double)f[3],
           (double)f[4], (double)f[7], (double)f[8], (double)f[9], (double)f[10], (double)f[11], (double)f[13],
           (unsigned)u[15]);
    CHECK(u[1] == 7 && u[14] == 4, "periods %u commands timed %u", (unsigned)u[1], (unsigned)u[14]);
    CHECK(f[2] == 0.0f && f[7] == 3.0f && fabs((double)f[3] - 18.0 / 7.0) < 1e-5, "lateness min/max/mean");
    CHECK(f[4] == 3.0f && f[5] == 3.0f, "lateness p50 %g p99 %g (a bin's upper edge, at most the max)", (double)f[4],
          (double)f[5]);
    CHECK(f[8] == 15.0f && f[13] == 47.0f && f[9] == 26.5f, "turnaround min/max/mean");
    CHECK(f[10] == 23.0f && f[11] == 47.0f && f[12] == 47.0f, "turnaround p50 %g p99 %g p99.9 %g", (double)f[10],
          (double)f[11], (double)f[12]);
    CHECK(u[15] == 2 && u[16] == 0 && u[17] == 1, "overruns %u sync_overruns %u worst period %u", (unsigned)u[15],
          (unsigned)u[16], (unsigned)u[17]);
    const co_domain_t *d = &OD_PLANT.mfr.x2006_timing_histograms;
    const uint32_t T = PLANT_RTSTATS_BINS * 4u; /* the turnaround's histogram follows the lateness' */
    CHECK(d->data == tb->app.timing.hist_bytes && d->size == 2u * T && d->data[0] == 1 && d->data[4 * 3] == 6 &&
              d->data[T + 4 * 15] == 1 && d->data[T + 4 * 22] == 2 && d->data[T + 4 * 47] == 1,
          "DOMAIN 0x2006");
    /* a period beyond the linear bins: 16 per octave */
    CHECK(plant_rtstats_bin(63) == 63 && plant_rtstats_bin(64) == 64 && plant_rtstats_bin(67) == 64 &&
              plant_rtstats_bin(68) == 65 && plant_rtstats_bin(128) == 80 &&
              plant_rtstats_bin(1 << 20) == PLANT_RTSTATS_BINS - 1,
          "log-linear bins");
    /* reset clears the figures and the histograms */
    CHECK(tb_w_u8(tb, 0x2007, OD_PLANT_REALTIME_TIMING_RESET_SUB, 1) == 0, "reset write");
    CHECK(tb->app.timing.lateness.n == 0 && tb->app.timing.turnaround.n == 0 && d->data[4 * 3] == 0 &&
              OD_PLANT.mfr.x2007_realtime_timing.overruns == 0,
          "reset");
}

/* A command after its deadline but before a late SYNC: applied (it was there when the SYNC went out), and still
 * an overrun (0x2007:0F: not at the plant by the deadline); not a miss. */
static void test_realtime_overrun_before_a_late_sync(void)
{
    tb_t *tb = &g_tb;
    tb_init(tb);
    tb_w_u8(tb, 0x2003, OD_PLANT_RUN_CONTROL_MODE_SUB, 1);
    tb_w_u32(tb, 0x2003, OD_PLANT_RUN_CONTROL_RUN_PERIODS_SUB, 0xFFFFFFFFu);
    tb_nmt(tb, 0x01u);
    tb->bus.now_us = 1000; /* deadlines 1000, 1055, 1110 (Ts 55 us) */
    plant_app_realtime_tick(&tb->app, tb->bus.now_us, 0);
    tb_deliver(tb);
    tb->bus.now_us = 1060; /* 5 us after the deadline */
    tb_cmd(tb, 1.0f, 0.0f);
    plant_app_poll(&tb->app, tb->bus.now_us);
    tb->bus.now_us = 1075; /* the SYNC 20 us late */
    plant_app_realtime_tick(&tb->app, tb->bus.now_us, 20000);
    tb_deliver(tb);
    tb->bus.now_us = 1100; /* on time */
    tb_cmd(tb, 1.0f, 0.0f);
    plant_app_poll(&tb->app, tb->bus.now_us);
    tb->bus.now_us = 1110;
    plant_app_realtime_tick(&tb->app, tb->bus.now_us, 0);
    tb_deliver(tb);
    uint8_t buf[4] = {0, 0, 0, 0};
    uint32_t n = 0, segments = 0, overruns = 0;
    CHECK(testbus_sdo_upload(&tb->bus, 0x2007, OD_PLANT_REALTIME_TIMING_OVERRUNS_SUB, buf, sizeof buf, &n, &segments) ==
              0,
          "0x2007 overruns read");
    memcpy(&overruns, buf, 4);
    CHECK(overruns == 1 && RC.missed_commands == 0 && RC.late_commands == 0, "overruns %u missed %u late %u",
          (unsigned)overruns, (unsigned)RC.missed_commands, (unsigned)RC.late_commands);
    printf("real time: a command 5 us after its deadline, before a SYNC 20 us late: applied, 1 overrun, 0 missed\n");
}

/* Real time: a drive late by several periods sends their commands in a burst, which reaches the plant before it
 * looks (the CAN box under load, issue 52). Each is counted, the owed ones late, the last the current period's, so
 * the hold at the segment's end is announced; counting only the frame left in the RPDO's buffer took the burst for
 * one late command, the plant waited for one that had come, and the loop stalled with both nodes alive. */
static void test_realtime_burst_of_late_commands(void)
{
    tb_t *tb = &g_tb;
    tb_init(tb);
    tb_w_u8(tb, 0x2003, OD_PLANT_RUN_CONTROL_MODE_SUB, 1);
    tb_w_u32(tb, 0x2003, OD_PLANT_RUN_CONTROL_RUN_PERIODS_SUB, 4);
    tb_nmt(tb, 0x01u);
    const int64_t Ts = 55;
    for (int j = 0; j < 4; ++j) { /* SYNCs 0..3 at their deadlines, no command: periods 0, 1, 2 missed */
        tb->bus.now_us = 1000 + j * Ts;
        plant_app_realtime_tick(&tb->app, tb->bus.now_us, 0);
        tb_deliver(tb);
    }
    CHECK(tb->n_sync == 4 && RC.missed_commands == 3 && RC.state == 1u, "SYNCs %u missed %u state %u",
          (unsigned)tb->n_sync, (unsigned)RC.missed_commands, (unsigned)RC.state);
    tb->bus.now_us += 20;
    for (int j = 0; j < 4; ++j) tb_cmd(tb, 1.0f + (float)j, 0.0f); /* the commands of periods 0..3 at once */
    tb_poll(tb);
    CHECK(RC.late_commands == 3, "late %u (the three owed)", (unsigned)RC.late_commands);
    CHECK(RC.state == 0u && RC.period_index == 3u, "the hold announced: state %u at period %u", (unsigned)RC.state,
          (unsigned)RC.period_index);
    printf("real time, a burst of 4 commands after 3 missed periods: %u late, the hold announced at period %u\n",
           (unsigned)RC.late_commands, (unsigned)RC.period_index);
}

int main(void)
{
    test_holds_and_timeout();
    test_run_periods();
    test_realtime_tick();
    test_realtime_overrun_before_a_late_sync();
    test_realtime_burst_of_late_commands();
    return check_finish("test_node_lockstep");
}
