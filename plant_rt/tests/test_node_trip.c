/* test_node_trip.c - over-current trip -> EMCY 0x2310 on the bus, status bit0,
 * 0x2003:08; cleared only by writing 1 to 0x2003:07 (EMCY error reset). */
#include <stdio.h>

#include "check.h"
#include "plant_testbus.h"

static tb_t g_tb;

#define RC (OD_PLANT.mfr.x2003_run_control)

static const tb_sample_t *last(const tb_t *tb) { return &tb->smp[tb->n_smp - 1u]; }

int main(void)
{
    tb_t *tb = &g_tb;
    tb_init(tb);
    CHECK(tb_w_f32(tb, 0x2001, OD_PLANT_INVERTER_I_TRIP_A_SUB, 3.0f) == 0, "I_trip");
    tb_start(tb, 0xFFFFFFFFu);
    int trip_k = -1;
    for (int j = 0; j < 200 && trip_k < 0; ++j) {
        tb_period(tb, 30.0f, 0.0f);
        if (tb->n_emcy) trip_k = (int)last(tb)->index;
    }
    printf("30 V step, I_trip 3 A: EMCY at sample %d, i_a = %.4f A, frame %02x %02x %02x | %02x %02x %02x %02x %02x\n",
           trip_k, (double)last(tb)->ia, tb->last_emcy[0], tb->last_emcy[1], tb->last_emcy[2], tb->last_emcy[3],
           tb->last_emcy[4], tb->last_emcy[5], tb->last_emcy[6], tb->last_emcy[7]);
    CHECK(trip_k > 0, "no trip");
    CHECK(tb->n_emcy == 1 && tb->last_emcy[0] == 0x10 && tb->last_emcy[1] == 0x23, "EMCY code");
    CHECK(tb->last_emcy[2] == (CO_ERR_REG_CURRENT | CO_ERR_REG_GENERIC), "error register 0x%02x", tb->last_emcy[2]);
    CHECK(OD_PLANT.comm.x1001_error_register == 0x03u, "0x1001");
    CHECK(OD_PLANT.comm.x1003_pre_defined_error_field.standard_error_field_1 == 0x2310u, "0x1003:01");
    CHECK(RC.trip_active == 1 && (last(tb)->status & PLANT_STATUS_TRIP), "trip flags");
    /* tripped: the inverter outputs 0 V, the current decays; it stays latched */
    for (int j = 0; j < 300; ++j) tb_period(tb, 30.0f, 0.0f);
    CHECK(tb->n_emcy == 1, "EMCY repeated");
    CHECK(RC.trip_active == 1 && (last(tb)->status & PLANT_STATUS_TRIP), "trip cleared by itself");
    printf("300 periods later (command still 30 V): i_a = %.5f A, status 0x%02x, still latched\n", (double)last(tb)->ia,
           last(tb)->status);
    CHECK(last(tb)->ia < 0.1f && last(tb)->ia > -0.1f, "current did not decay");
    /* writing 0 does nothing */
    tb_w_u8(tb, 0x2003, OD_PLANT_RUN_CONTROL_TRIP_CLEAR_SUB, 0);
    CHECK(RC.trip_active == 1 && tb->n_emcy == 1, "cleared by 0");
    /* clear with the command at 0 V */
    tb_period(tb, 0.0f, 0.0f);
    CHECK(tb_w_u8(tb, 0x2003, OD_PLANT_RUN_CONTROL_TRIP_CLEAR_SUB, 1) == 0, "trip clear write");
    printf("trip clear: EMCY frames %u, last %02x %02x reg %02x, trip_active %u\n", (unsigned)tb->n_emcy,
           tb->last_emcy[0], tb->last_emcy[1], tb->last_emcy[2], RC.trip_active);
    CHECK(tb->n_emcy == 2 && tb->last_emcy[0] == 0 && tb->last_emcy[1] == 0 && tb->last_emcy[2] == 0,
          "EMCY error reset");
    CHECK(RC.trip_active == 0 && OD_PLANT.comm.x1001_error_register == 0, "flags after clear");
    tb_period(tb, 1.0f, 0.0f);
    tb_period(tb, 1.0f, 0.0f);
    CHECK(!(last(tb)->status & PLANT_STATUS_TRIP) && !tb->app.state.tripped, "status bit0 after clear");
    for (int j = 0; j < 50; ++j) tb_period(tb, 1.0f, 0.0f);
    printf("after clear, 1 V command: inverter applies v_alpha = %.4f V (dead time included), i_a = %.4f A, "
           "status 0x%02x\n",
           tb->app.state.v_app_alpha_V, (double)last(tb)->ia, last(tb)->status);
    CHECK(tb->app.state.v_app_alpha_V != 0.0, "inverter still off");
    return check_finish("test_node_trip");
}
