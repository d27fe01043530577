/* test_node_delay.c - the two-period delay of the CANopen loop.
 *
 * The plant node runs on co_membus in lockstep; the test is the drive: after
 * sample j it sends the command u(j) (RPDO1). A voltage step sent after
 * sample K must leave sample K+1 bit-identical to a run without the step and
 * first change sample K+2. Every sample must equal the plant core driven
 * directly with the schedule "command u(j-1) held over [j, j+1]".
 */
#include <math.h>
#include <stdio.h>

#include "check.h"
#include "plant_testbus.h"

#define N_PER 40
#define K_STEP 10
#define V_STEP_V 20.0f

static tb_t g_tb;
static tb_sample_t run_a[N_PER + 1], run_b[N_PER + 1];

static float cmd_of(int j, int step) { return (step && j >= K_STEP) ? V_STEP_V : 0.0f; }

static void run(tb_sample_t *out, int step)
{
    tb_t *tb = &g_tb;
    tb_init(tb);
    /* a speed so that the stator-frame hold matters: imposed 100 rad/s */
    CHECK(tb_w_u8(tb, 0x2000, OD_PLANT_MOTOR_MODEL_MECH_MODE_SUB, 2) == 0, "mech_mode");
    CHECK(tb_w_f32(tb, 0x2000, OD_PLANT_MOTOR_MODEL_OMEGA_IMPOSED_RAD_S_SUB, 100.0f) == 0, "omega");
    tb_start(tb, 0xFFFFFFFFu);
    CHECK(tb->n_smp == 1 && tb->smp[0].index == 0, "sample 0 after start (n=%u)", (unsigned)tb->n_smp);
    for (int j = 0; j < N_PER; ++j) tb_period(tb, cmd_of(j, step), 0.0f);
    CHECK(tb->n_smp == N_PER + 1, "samples %u", (unsigned)tb->n_smp);
    for (int j = 0; j <= N_PER; ++j) {
        out[j] = tb->smp[j];
        CHECK(out[j].index == j, "sample_index %u != %d", (unsigned)out[j].index, j);
        CHECK(out[j].counter == (uint8_t)(j % 240 + 1), "sync counter %u at %d", (unsigned)out[j].counter, j);
    }
}

int main(void)
{
    run(run_a, 1);
    plant_config_t cfg = g_tb.app.cfg; /* as applied from the OD */
    run(run_b, 0);

    int first_diff = -1;
    for (int j = 0; j <= N_PER; ++j) {
        int same = testbus_same_f32(run_a[j].ia, run_b[j].ia) && testbus_same_f32(run_a[j].ib, run_b[j].ib);
        if (!same && first_diff < 0) first_diff = j;
    }
    printf("step sent after sample %d (%.1f V alpha); first sample that differs: %d\n", K_STEP, (double)V_STEP_V,
           first_diff);
    printf("  sample %d: i_a %.6g (step) vs %.6g (none)\n", K_STEP + 1, (double)run_a[K_STEP + 1].ia,
           (double)run_b[K_STEP + 1].ia);
    printf("  sample %d: i_a %.6g (step) vs %.6g (none)\n", K_STEP + 2, (double)run_a[K_STEP + 2].ia,
           (double)run_b[K_STEP + 2].ia);
    CHECK(first_diff == K_STEP + 2, "first difference at %d, expected %d", first_diff, K_STEP + 2);

    /* The plant core driven directly: u(j-1) is held over [j, j+1]. */
    plant_state_t s;
    plant_meas_t m;
    plant_init(&s, &cfg);
    int mismatches = 0;
    double max_err = 0.0;
    for (int j = 0; j <= N_PER; ++j) {
        if (j > 0) {
            double held = j >= 2 ? (double)cmd_of(j - 2, 1) : 0.0; /* held over [j-1, j] = u(j-2) */
            plant_step(&s, &cfg, held, 0.0);
        }
        plant_sample(&s, &cfg, &m);
        if (!testbus_same_f32(m.i_a_A, run_a[j].ia) || !testbus_same_f32(m.i_b_A, run_a[j].ib) ||
            !testbus_same_f32(m.theta_m_rad, run_a[j].th))
            ++mismatches;
        double e = fabs((double)m.i_a_A - (double)run_a[j].ia);
        if (e > max_err) max_err = e;
    }
    printf("direct core vs node: %d of %d samples differ (max |di_a| = %.3g A)\n", mismatches, N_PER + 1, max_err);
    printf("  i_a at K+2..K+5 (node): %.6g %.6g %.6g %.6g A\n", (double)run_a[K_STEP + 2].ia,
           (double)run_a[K_STEP + 3].ia, (double)run_a[K_STEP + 4].ia, (double)run_a[K_STEP + 5].ia);
    CHECK(mismatches == 0, "node and direct core disagree");
    return check_finish("test_node_delay");
}
