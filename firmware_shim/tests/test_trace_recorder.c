/* test_trace_recorder.c - trigger, pre-trigger, decimation, byte readout. */
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "drive_core.h"
#include "drive_plant.h"

static trace_recorder_t rec;

static float rd(uint32_t row, uint32_t ch)
{
    uint8_t b[4];
    trace_read_bytes(&rec, (row * rec.n_channels + ch) * 4u, b, 4u);
    const uint32_t u = (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) | ((uint32_t)b[3] << 24);
    float f;
    memcpy(&f, &u, 4);
    return f;
}

int main(void)
{
    float sig[TRACE_SIG_COUNT];
    trace_init(&rec);
    trace_config_t c;
    memset(&c, 0, sizeof(c));
    c.signal_0 = TRACE_SIG_IQ_REF;
    c.signal_1 = TRACE_SIG_IQ;
    c.signal_2 = TRACE_SIG_THETA;
    c.trigger_signal = TRACE_SIG_IQ_REF;
    c.trigger_edge = TRACE_EDGE_RISING;
    c.trigger_level = 0.5f;
    c.pretrigger_samples = 100;
    c.decimation = 3;
    CHECK(trace_arm(&rec, &c) == 0, "arm");
    const uint32_t depth = TRACE_BUFFER_SAMPLES / 3u;
    int trig_call = 5000, done_call = -1;
    for (int n = 0; n < 20000; ++n) {
        memset(sig, 0, sizeof(sig));
        sig[TRACE_SIG_IQ_REF] = n >= trig_call ? 1.0f : 0.0f;
        sig[TRACE_SIG_IQ] = (float)n; /* call counter as a time stamp */
        sig[TRACE_SIG_THETA] = -(float)n;
        trace_sample(&rec, sig);
        if (done_call < 0 && rec.status == TRACE_DONE) done_call = n;
    }
    const uint32_t ti = trace_trigger_index(&rec);
    printf("[trace] depth=%u rows, size=%u bytes, trigger row=%u, t(trigger row)=%g, t(row 0)=%g,"
           " t(last)=%g, done at call %d\n",
           (unsigned)depth, (unsigned)trace_size_bytes(&rec), (unsigned)ti, (double)rd(ti, 1), (double)rd(0, 1),
           (double)rd(depth - 1, 1), done_call);
    CHECK(rec.status == TRACE_DONE, "not done");
    CHECK(trace_size_bytes(&rec) == depth * 3u * 4u, "size");
    /* decimation 3: recorded calls are 2, 5, 8, ... ; first recorded call >= 5000 is 5000 */
    CHECK(rd(ti, 0) == 1.0f && rd(ti - 1, 0) == 0.0f, "trigger edge position");
    CHECK(rd(ti, 1) == 5000.0f, "trigger sample time %g", (double)rd(ti, 1));
    CHECK(rd(0, 1) == 5000.0f - 3.0f * 100.0f, "pre-trigger");
    for (uint32_t r = 1; r < depth; ++r)
        if (rd(r, 1) - rd(r - 1, 1) != 3.0f) {
            CHECK(0, "decimation at row %u", (unsigned)r);
            break;
        }
    CHECK(rd(5, 2) == -rd(5, 1), "channel interleave");
    CHECK(done_call == 5000 + 3 * (int)(depth - 100 - 1), "done timing %d", done_call);
    /* trigger before the pre-trigger history is full is ignored */
    c.pretrigger_samples = 10;
    c.decimation = 1;
    c.trigger_edge = TRACE_EDGE_FALLING;
    trace_arm(&rec, &c);
    for (int n = 0; n < 5; ++n) {
        sig[TRACE_SIG_IQ_REF] = n < 2 ? 1.0f : 0.0f;
        trace_sample(&rec, sig);
    }
    CHECK(rec.status == TRACE_ARMED, "early trigger accepted");
    /* driven by the drive: capture a current step */
    static drive_t drv;
    drive_config_t cfg;
    drive_plant_t pl;
    drive_plant_init(&pl, "you2019");
    drive_default_config(&cfg);
    drive_init(&drv, &cfg);
    drive_attach_trace(&drv, &rec);
    memset(&c, 0, sizeof(c));
    c.signal_0 = TRACE_SIG_IQ_REF;
    c.signal_1 = TRACE_SIG_IQ;
    c.signal_2 = TRACE_SIG_VQ;
    c.signal_3 = TRACE_SIG_V_LIMITED;
    c.trigger_signal = TRACE_SIG_IQ_REF;
    c.trigger_edge = TRACE_EDGE_RISING;
    c.trigger_level = 0.5f;
    c.pretrigger_samples = 4;
    c.decimation = 1;
    trace_arm(&rec, &c);
    for (int k = 0; k < 3000; ++k) {
        drive_meas_t m;
        drive_cmd_t cmd;
        drive_plant_measure(&pl, &m);
        drv.sp.iq_ref_A = k >= 50 ? 1.0f : 0.0f;
        drive_current_step(&drv, &m, &cmd);
        drive_plant_advance(&pl, &cmd);
    }
    printf("[trace drive] rows around trigger: iq_ref/iq/vq:");
    for (uint32_t r = 3; r < 8; ++r) printf(" (%g %.4f %.2f)", (double)rd(r, 0), (double)rd(r, 1), (double)rd(r, 2));
    printf("\n");
    CHECK(rec.status == TRACE_DONE, "drive capture");
    CHECK(rd(4, 0) == 1.0f && rd(6, 1) > 0.9999f && rd(5, 1) == 0.0f, "drive capture content");
    return check_finish("test_trace_recorder");
}
