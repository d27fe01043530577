/* drive_perf.c - ns per current step (deadbeat, deadbeat + identification,
 * PI) and per identification average update, with clock_gettime.
 * Usage: drive_perf [steps]   (default 1000000; use e.g. 20000 under
 *        valgrind --tool=callgrind) */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "drive_core.h"
#include "you2019_identification.h"

static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

static drive_t drv;
static volatile float sink;

static double bench(uint8_t controller, uint8_t tuning, long n)
{
    drive_config_t cfg;
    drive_default_config(&cfg);
    cfg.controller = controller;
    cfg.Lq_hat_H = 0.8f * cfg.Lq_hat_H;
    drive_init(&drv, &cfg);
    od_drive_online_tuning_t *tuning_record = (od_drive_online_tuning_t *)drive_law_record(&drv);
    if (tuning_record != NULL) { /* You 2019 record (its law folder; the PI shares it) */
        tuning_record->enable = tuning;
        drive_apply_config(&drv);
    }
    drive_meas_t m = {0.0f, 0.0f, 0.0f};
    drive_cmd_t c;
    /* crude first-order plant in the loop so the code paths are realistic */
    float iq = 0.0f;
    const double t0 = now_ns();
    for (long k = 0; k < n; ++k) {
        drv.sp.iq_ref_A = (k & 512) ? 2.0f : -2.0f;
        m.theta_m_rad = (float)(k & 4095) * (6.2831853f / 4096.0f);
        m.i_a_A = -iq * 0.3f;
        m.i_b_A = iq * 0.5f;
        drive_current_step(&drv, &m, &c);
        iq = 0.98f * iq + 0.012f * c.v_beta_V;
        sink = c.v_alpha_V;
    }
    return (now_ns() - t0) / (double)n;
}

static double bench_average(long n)
{
    you2019_identification_config_t cfg = {1u, 0.2f, 8u, 0u};
    static you2019_identification_axis_state_t ax;
    you2019_identification_reset_axis(&ax);
    double t_sample = 0.0, t_avg = 0.0;
    for (long k = 0; k < n; ++k) {
        const double t0 = now_ns();
        for (int j = 0; j < 8; ++j) {
            const float i = (float)((k * 8 + j) % 7);
            you2019_identification_sample(&cfg, &ax, i, 83.0f * i - 81.8f * (float)((k * 8 + j + 6) % 7));
        }
        const double t1 = now_ns();
        sink = you2019_identification_average(&cfg, &ax, 55e-6f, 1.4f) ? ax.L_hat_H : 0.0f;
        t_avg += now_ns() - t1;
        t_sample += t1 - t0;
    }
    printf("identification sample (You 2019 Eq. 24-27, per call): %8.1f ns\n", t_sample / (double)(n * 8));
    return t_avg / (double)n;
}

int main(int argc, char **argv)
{
    long n = argc > 1 ? atol(argv[1]) : 1000000L;
    if (n < 1) n = 1;
    printf("steps per case: %ld\n", n);
    printf("deadbeat current step:                 %8.1f ns\n",
           bench((uint8_t)OD_DRIVE_CONTROLLER_DEADBEAT_YOU2019, 0u, n));
    printf("deadbeat + identification step:        %8.1f ns\n",
           bench((uint8_t)OD_DRIVE_CONTROLLER_DEADBEAT_YOU2019, 1u, n));
    od_drive_online_tuning_t tuned;
    drive_law_status(&drv, &tuned);
    const unsigned nupd = (unsigned)tuned.gain_updates;
    printf("PI current step:                       %8.1f ns\n", bench((uint8_t)OD_DRIVE_CONTROLLER_PI, 0u, n));
    const long na = n / 8 > 0 ? n / 8 : 1;
    printf("identification update (You 2019 Eq. 28-32): %8.1f ns\n", bench_average(na));
    printf("gain updates applied in tuning run:    %u\n", nupd);
    return 0;
}
