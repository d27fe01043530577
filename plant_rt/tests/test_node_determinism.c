/* test_node_determinism.c - same OD writes + same frames -> bit-identical bus traffic.
 *
 * A scripted drive (PI current control in the stator frame on the measured
 * samples) runs the plant with ADC noise and quantization on, changes a
 * parameter by SDO mid-run and skips one command (timeout). Two runs must
 * give byte-identical frame sequences (every frame on the bus, both directions).
 */
#include <stdio.h>
#include <stdlib.h>

#include "check.h"
#include "plant_testbus.h"

#define N_PER 400

static tb_t g_tb;
static testbus_rec_t g_rec[2][TESTBUS_MAX_REC];
static uint32_t g_n[2];

static uint64_t fnv(const testbus_rec_t *r, uint32_t n)
{
    uint64_t h = 1469598103934665603ULL;
    for (uint32_t i = 0; i < n; ++i) {
        uint8_t b[11] = {(uint8_t)r[i].f.cob_id, (uint8_t)(r[i].f.cob_id >> 8), r[i].f.dlc, 0};
        for (int j = 0; j < 8; ++j) b[3 + j] = r[i].f.data[j];
        for (int j = 0; j < 11; ++j) h = (h ^ b[j]) * 1099511628211ULL;
    }
    return h;
}

static void run(int which)
{
    tb_t *tb = &g_tb;
    tb_init(tb);
    CHECK(tb_w_f32(tb, 0x2002, OD_PLANT_SENSORS_ADC_NOISE_STD_A_SUB, 0.02f) == 0, "noise");
    CHECK(tb_w_f32(tb, 0x2002, OD_PLANT_SENSORS_ADC_LSB_A_SUB, 0.005f) == 0, "lsb");
    CHECK(tb_w_u32(tb, 0x2003, OD_PLANT_RUN_CONTROL_COMMAND_TIMEOUT_US_SUB, 500) == 0, "timeout");
    CHECK(tb_w_u8(tb, 0x2000, OD_PLANT_MOTOR_MODEL_MECH_MODE_SUB, 2) == 0, "mech");
    CHECK(tb_w_f32(tb, 0x2000, OD_PLANT_MOTOR_MODEL_OMEGA_IMPOSED_RAD_S_SUB, 150.0f) == 0, "omega");
    tb_start(tb, 0xFFFFFFFFu);
    float ia_ref = 2.0f, ib_ref = 0.0f, xa = 0, xb = 0;
    for (int k = 0; k < N_PER; ++k) {
        const tb_sample_t *s = &tb->smp[tb->n_smp - 1u];
        float ib_beta = (s->ia + 2.0f * s->ib) / 1.7320508f; /* i_beta from i_a, i_b */
        float ea = ia_ref - s->ia, eb = ib_ref - ib_beta;
        xa += 0.2f * ea;
        xb += 0.2f * eb;
        float va = 8.0f * ea + xa, vb = 8.0f * eb + xb;
        if (k == 150) CHECK(tb_w_f32(tb, 0x2000, OD_PLANT_MOTOR_MODEL_R_OHM_SUB, 2.0f) == 0, "R");
        if (k == 250) { /* the drive skips this command: timeout */
            tb->bus.now_us += 500;
            tb_poll(tb);
            continue;
        }
        tb_period(tb, va, vb);
    }
    CHECK(tb->n_smp == N_PER, "samples %u (one command taken as late after the skip)", (unsigned)tb->n_smp);
    for (uint32_t j = 0; j < tb->n_smp; j += 50)
        printf("  k=%u i_a=%.4f i_b=%.4f\n", (unsigned)j, (double)tb->smp[j].ia, (double)tb->smp[j].ib);
    g_n[which] = tb->bus.n_rec;
    memcpy(g_rec[which], tb->bus.rec, sizeof(testbus_rec_t) * tb->bus.n_rec);
    printf("run %d: %u frames, %u SYNCs, missed %u, fnv64 %016llx, last i_a %.6f A\n", which, (unsigned)tb->bus.n_rec,
           (unsigned)tb->n_sync, (unsigned)OD_PLANT.mfr.x2003_run_control.missed_commands,
           (unsigned long long)fnv(tb->bus.rec, tb->bus.n_rec), (double)tb->smp[tb->n_smp - 1u].ia);
}

int main(void)
{
    run(0);
    run(1);
    CHECK(g_n[0] == g_n[1], "frame counts %u vs %u", (unsigned)g_n[0], (unsigned)g_n[1]);
    uint32_t diff = 0;
    for (uint32_t i = 0; i < g_n[0] && i < g_n[1]; ++i) {
        const testbus_rec_t *a = &g_rec[0][i], *b = &g_rec[1][i];
        if (a->f.cob_id != b->f.cob_id || a->f.dlc != b->f.dlc || memcmp(a->f.data, b->f.data, 8) != 0 ||
            a->sender != b->sender || a->t_us != b->t_us)
            ++diff;
    }
    printf("frames differing: %u of %u\n", (unsigned)diff, (unsigned)g_n[0]);
    CHECK(diff == 0, "runs differ");
    return check_finish("test_node_determinism");
}
