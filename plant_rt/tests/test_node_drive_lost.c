/* test_node_drive_lost.c - the plant's reactions when the drive goes wrong:
 *   real time: the drive's heartbeat (0x1016) lost -> the inverter switches off (zero voltage, the trip
 *              latch), EMCY 0xFF10, status TRIP; the SYNCs go on; trip_clear ends it;
 *   lockstep:  the same loss changes nothing (simulated time waits for commands);
 *   both:      a period without a command frame is marked held (status bit 3) at the next sample. */
#include <stdio.h>

#include "check.h"
#include "plant_testbus.h"

static tb_t g_tb;

#define RC (OD_PLANT.mfr.x2003_run_control)
#define DRIVE_ID 0x20u

static void heartbeat(tb_t *tb)
{
    const uint8_t st = 0x05;
    tb_inject(tb, 0x700u + DRIVE_ID, 1, &st);
    tb_deliver(tb);
}

/* one real-time period: the drive's command, then the deadline's SYNC */
static void rt_period(tb_t *tb, int with_command)
{
    tb->bus.now_us += 50;
    if (with_command) tb_cmd(tb, 20.0f, 0.0f);
    tb->bus.now_us += 50;
    tb_deliver(tb);
    co_node_tick(&tb->bus.node, tb->bus.now_us);
    plant_app_realtime_tick(&tb->app, tb->bus.now_us, 0);
    tb_deliver(tb);
}

static void setup(tb_t *tb, uint8_t mode)
{
    tb_init(tb);
    CHECK(tb_w_u32(tb, 0x1016, 1, (DRIVE_ID << 16) | 100u) == 0, "consumer heartbeat time");
    CHECK(tb_w_u8(tb, OD_PLANT_RUN_CONTROL_IDX, OD_PLANT_RUN_CONTROL_MODE_SUB, mode) == 0, "mode");
    CHECK(tb_w_f32(tb, 0x2001, 1, 100e-6f) == 0, "Ts 100 us");
}

int main(void)
{
    tb_t *tb = &g_tb;

    /* real time */
    setup(tb, 1u);
    tb_start(tb, 0xFFFFFFFFu);
    heartbeat(tb);
    for (int j = 0; j < 50; ++j) rt_period(tb, 1);
    CHECK(tb->n_emcy == 0 && !(tb->smp[tb->n_smp - 1u].status & PLANT_STATUS_TRIP), "running, no EMCY");
    CHECK(tb->app.state.v_app_alpha_V > 1.0, "the command applied (%.2f V)", tb->app.state.v_app_alpha_V);
    const uint32_t syncs0 = tb->n_sync;
    /* the drive falls silent (no heartbeat, no command) for 1200 periods = 120 ms > 100 ms */
    int emcy_at = -1;
    for (int j = 0; j < 1200; ++j) {
        rt_period(tb, 0);
        if (emcy_at < 0 && tb->n_emcy >= 2) emcy_at = j;
    }
    CHECK(tb->n_sync == syncs0 + 1200u, "the SYNCs went on (%u)", (unsigned)(tb->n_sync - syncs0));
    CHECK(RC.trip_active == 1u && (tb->smp[tb->n_smp - 1u].status & PLANT_STATUS_TRIP), "tripped");
    CHECK(tb->last_emcy[0] == 0x10 && tb->last_emcy[1] == 0xFF, "EMCY 0xFF10 last (%02x%02x)", tb->last_emcy[1],
          tb->last_emcy[0]);
    CHECK(tb->app.state.v_app_alpha_V == 0.0 && tb->app.state.v_app_beta_V == 0.0, "zero voltage applied");
    emcy_at += 50; /* periods since the last heartbeat */
    printf("real time, drive silent: EMCY 0x8130 + 0xFF10 %d periods after its last heartbeat (consumer 100 ms = "
           "1000 periods), inverter off, %u SYNCs on\n",
           emcy_at, (unsigned)(tb->n_sync - syncs0));
    CHECK(emcy_at >= 1000 && emcy_at <= 1002, "reaction within the consumer time + 2 periods (%d)", emcy_at);
    /* the drive back: latched until trip_clear */
    heartbeat(tb);
    for (int j = 0; j < 5; ++j) rt_period(tb, 1);
    CHECK(RC.trip_active == 1u && tb->app.state.v_app_alpha_V == 0.0, "latched");
    CHECK(tb_w_u8(tb, OD_PLANT_RUN_CONTROL_IDX, OD_PLANT_RUN_CONTROL_TRIP_CLEAR_SUB, 1) == 0, "trip clear");
    for (int j = 0; j < 5; ++j) rt_period(tb, 1);
    CHECK(RC.trip_active == 0u && tb->app.state.v_app_alpha_V > 1.0, "back on after trip_clear (%.2f V)",
          tb->app.state.v_app_alpha_V);

    /* lockstep: the same silence trips nothing; a period without a command is held */
    setup(tb, 0u);
    CHECK(tb_w_u32(tb, OD_PLANT_RUN_CONTROL_IDX, OD_PLANT_RUN_CONTROL_COMMAND_TIMEOUT_US_SUB, 1000u) == 0, "timeout");
    tb_start(tb, 0xFFFFFFFFu);
    heartbeat(tb);
    for (int j = 0; j < 10; ++j) tb_period(tb, 5.0f, 0.0f);
    for (uint32_t i = 1; i < tb->n_smp; ++i) CHECK(!(tb->smp[i].status & PLANT_STATUS_HELD), "held at %u", i);
    /* no command: the timeout produces the next SYNC with the last command held */
    const uint32_t before = tb->n_smp;
    for (int j = 0; j < 3; ++j) {
        tb->bus.now_us += 600;
        tb_poll(tb);
    }
    CHECK(tb->n_smp == before + 1u, "one SYNC after the timeout (%u)", (unsigned)(tb->n_smp - before));
    CHECK((tb->smp[tb->n_smp - 1u].status & (PLANT_STATUS_HELD | PLANT_STATUS_MISSED)) ==
              (PLANT_STATUS_HELD | PLANT_STATUS_MISSED),
          "held and missed (0x%02x)", tb->smp[tb->n_smp - 1u].status);
    for (int j = 0; j < 300; ++j) { /* 300 ms without heartbeat, no command: waiting (timeouts hold) */
        tb->bus.now_us += 1000;
        tb_poll(tb);
    }
    CHECK(RC.trip_active == 0u, "lockstep: no trip on a lost drive");
    const uint32_t resumed = tb->n_smp;
    for (int j = 0; j < 10; ++j) { /* a command in every period again (counted late at first: the owed ones) */
        tb->bus.now_us += 10;
        tb_cmd(tb, 5.0f, 0.0f);
        tb->bus.now_us += 1100;
        tb_poll(tb);
    }
    CHECK(tb->n_smp > resumed && !(tb->smp[tb->n_smp - 1u].status & PLANT_STATUS_HELD), "a command again: not held");
    return check_finish("test_node_drive_lost");
}
