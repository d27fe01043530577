/* test_node_nonfinite.c - the plant node's trip levels and its non-finite trip.
 *
 *  - The EDS default of 0x2001:06 I_trip_A is the you2019 preset's level
 *    (12 A) and every preset written to 0x2004 brings its own level
 *    (presets.c); a scenario can still write another level or 0 (off).
 *  - A diverged drive sends a non-finite voltage command (NaN/inf in
 *    RPDO1): with the over-current level OFF the plant still trips (EMCY
 *    0x2310 once, 0x2003:08 trip_active = 1, measurement status bit0), the
 *    command never reaches the model and the measured currents stay finite
 *    and decay while the trip is latched. */
#include <math.h>
#include <stdio.h>

#include "check.h"
#include "plant_testbus.h"
#include "presets.h"

static tb_t g_tb;

#define RC (OD_PLANT.mfr.x2003_run_control)
#define INV (OD_PLANT.mfr.x2001_Inverter)

static const tb_sample_t *last(const tb_t *tb) { return &tb->smp[tb->n_smp - 1u]; }

static void test_levels(void)
{
    tb_t *tb = &g_tb;
    tb_init(tb);
    printf("EDS default I_trip_A = %g A\n", (double)INV.I_trip_A);
    CHECK(INV.I_trip_A == 12.0f, "EDS default I_trip_A %g, expected the you2019 level 12 A", (double)INV.I_trip_A);
    for (size_t i = 0; i < plant_preset_count(); ++i) {
        const char *name = plant_preset_name(i);
        plant_config_t p;
        plant_preset_load(name, &p);
        uint32_t a = tb_sdo_write(tb, 0x2004, 0, name, (uint32_t)strlen(name));
        printf("preset %-12s -> 0x2001:06 I_trip_A = %.6g A\n", name, (double)INV.I_trip_A);
        CHECK(a == 0 && INV.I_trip_A == (float)p.I_trip_A && INV.I_trip_A > 0.0f, "preset %s: I_trip_A %g", name,
              (double)INV.I_trip_A);
    }
    /* a scenario's explicit level (0 = off) after the preset */
    CHECK(tb_w_f32(tb, 0x2001, OD_PLANT_INVERTER_I_TRIP_A_SUB, 0.0f) == 0 && INV.I_trip_A == 0.0f, "level off");
}

static void test_nonfinite_command(void)
{
    tb_t *tb = &g_tb;
    tb_init(tb);
    CHECK(tb_w_f32(tb, 0x2001, OD_PLANT_INVERTER_I_TRIP_A_SUB, 0.0f) == 0, "level off");
    tb_start(tb, 0xFFFFFFFFu);
    for (int j = 0; j < 40; ++j) tb_period(tb, 3.0f, 0.0f);
    CHECK(tb->n_emcy == 0 && RC.trip_active == 0, "tripped before the bad command");
    const float ia0 = last(tb)->ia;
    const uint16_t bad_k = last(tb)->index; /* the command for this sample is the bad one */
    tb_period(tb, NAN, 0.0f);               /* actuated over [bad_k + 1, bad_k + 2] */
    CHECK(!(last(tb)->status & PLANT_STATUS_TRIP), "trip before the command was applied");
    tb_period(tb, 3.0f, 0.0f);
    const tb_sample_t *s = last(tb);
    printf("NaN command for sample %u, level off: sample %u status 0x%02x, trip_active %u, EMCY %u (%02x %02x), "
           "i_a %.4f -> %.4f A\n",
           (unsigned)bad_k, (unsigned)s->index, s->status, (unsigned)RC.trip_active, (unsigned)tb->n_emcy,
           tb->last_emcy[0], tb->last_emcy[1], (double)ia0, (double)s->ia);
    CHECK(s->index == bad_k + 2u && (s->status & PLANT_STATUS_TRIP), "status bit0 at the end of the bad period");
    CHECK(RC.trip_active == 1 && tb->n_emcy == 1 && tb->last_emcy[0] == 0x10 && tb->last_emcy[1] == 0x23,
          "trip_active / EMCY 0x2310");
    CHECK(isfinite(s->ia) && isfinite(s->ib), "measured current not finite");
    /* latched; +inf commands change nothing; the current decays, finite */
    int finite = 1;
    for (int j = 0; j < 300; ++j) {
        tb_period(tb, j % 2 ? INFINITY : 3.0f, -INFINITY);
        finite &= isfinite(last(tb)->ia) && isfinite(last(tb)->ib);
    }
    printf("300 periods later (commands inf / 3 V): i_a %.6f A, status 0x%02x, EMCY %u, all samples finite %d\n",
           (double)last(tb)->ia, last(tb)->status, (unsigned)tb->n_emcy, finite);
    CHECK(finite && fabsf(last(tb)->ia) < 1e-3f, "current not finite / not decaying while tripped");
    CHECK(RC.trip_active == 1 && (last(tb)->status & PLANT_STATUS_TRIP) && tb->n_emcy == 1, "not latched");
    /* a finite command and a clear bring the inverter back */
    tb_period(tb, 0.0f, 0.0f);
    CHECK(tb_w_u8(tb, 0x2003, OD_PLANT_RUN_CONTROL_TRIP_CLEAR_SUB, 1) == 0, "trip clear");
    for (int j = 0; j < 5; ++j) tb_period(tb, 3.0f, 0.0f);
    printf("after the clear, 3 V: i_a %.4f A, status 0x%02x\n", (double)last(tb)->ia, last(tb)->status);
    CHECK(RC.trip_active == 0 && !(last(tb)->status & PLANT_STATUS_TRIP) && tb->app.state.v_app_alpha_V > 0.0 &&
              last(tb)->ia > 0.02f,
          "clear");
}

int main(void)
{
    test_levels();
    test_nonfinite_command();
    return check_finish("test_node_nonfinite");
}
