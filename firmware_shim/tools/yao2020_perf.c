/* yao2020_perf.c - Yao 2020: ns per call of the proposed identification
 * update (yao2020_identification_update: Eq. 22/26 dM with re-referenced M(t0),
 * dead zone, integral estimator) vs the RLS update of the baseline
 * (yao2020_rls_update: Eq. 46-48 incl. G2_hat and Eq. 48), plus the whole DPCC
 * step (model Eq. 5-7, observer Eq. 13-18, law Eq. 12) for scale.
 * Usage: yao2020_perf [steps]   (default 1000000; e.g. 20000 under
 *        valgrind --tool=callgrind) */
#define _POSIX_C_SOURCE 199309L
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "yao2020_dpcc.h"
#include "yao2020_identification.h"
#include "yao2020_rls.h"

static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

static volatile float sink;
static yao2020_dpcc_state_t st;

int main(int argc, char **argv)
{
    long n = argc > 1 ? atol(argv[1]) : 1000000L;
    if (n < 1) n = 1;
    yao2020_dpcc_config_t cfg;
    yao2020_dpcc_default_config(&cfg);
    cfg.R_hat_ohm = 3.3f;
    cfg.L_hat_H = 8.25e-3f;
    cfg.th_L_V = 0.0f; /* keep integrating: the costly branch */
    cfg.n_timeout = UINT32_MAX;
    yao2020_dpcc_init(&cfg, &st);
    const float w = 837.5f;
    yao2020_dpcc_cmd_t cmd;
    /* crude loop so the state holds realistic numbers */
    float id = 0.0f, iq = 0.0f, th = 0.0f;
    double t0 = now_ns();
    for (long k = 0; k < n; ++k) {
        yao2020_dpcc_step(&cfg, &st, 0.0f, 4.0f, id, iq, w, th, &cmd);
        iq = 0.96f * iq + 0.018f * (cmd.v_star_q_V - w * 0.12f);
        id = 0.96f * id + 0.018f * cmd.v_star_d_V;
        th += w * 1e-4f;
        if (th > 3.14159265f) th -= 6.28318531f;
        sink = cmd.v_alpha_V;
    }
    const double t_step = (now_ns() - t0) / (double)n;

    /* identification update in its integrating phase */
    yao2020_identification_start(&cfg, &st);
    st.id_state = (uint8_t)YAO2020_IDENTIFICATION_INJECT_L;
    st.phase_count = cfg.n_settle + 1u;
    t0 = now_ns();
    for (long k = 0; k < n; ++k) {
        st.L_hat_H = 8.25e-3f; /* keep the operating point */
        yao2020_identification_update(&cfg, &st, 4.0f, id, iq, w);
        sink = st.L_hat_H;
    }
    const double t_id = (now_ns() - t0) / (double)n;

    yao2020_rls_config_t rc;
    yao2020_rls_default_config(&rc);
    yao2020_rls_state_t rs;
    yao2020_rls_init(&rc, &rs, 3.3f, 8.25e-3f);
    t0 = now_ns();
    for (long k = 0; k < n; ++k) {
        const float j = (float)(k & 7) * 0.01f;
        yao2020_rls_update(&rc, &rs, j, 4.0f + j, -18.0f + j, 109.0f - j, w);
        sink = rs.R_hat_ohm;
    }
    const double t_rls = (now_ns() - t0) / (double)n;
    printf("steps per case: %ld\n", n);
    printf("DPCC step (Yao 2020 Eq. 5-7, 12, 13-18, + ident):      %8.1f ns\n", t_step);
    printf("proposed identification update (Yao 2020 Eq. 22-45): %8.1f ns\n", t_id);
    printf("RLS update (Yao 2020 Eq. 46-48):                      %8.1f ns\n", t_rls);
    printf("ratio RLS / proposed:                                 %8.2f\n", t_rls / t_id);
    return 0;
}
