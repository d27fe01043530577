/* lockstep_floor.c - the floor of the lockstep loop on a CAN bus: the same frames
 * per period as the real plant/drive loop, with no CANopen stack, no model and no
 * controller behind them. Whatever the real loop achieves is measured against this.
 *
 *   lockstep_floor drive IFACE N [EXTRA]   answer N periods, then exit
 *   lockstep_floor plant IFACE N [EXTRA]   run N periods, verify every answer, print stats
 *
 * Per period k (same COB-IDs, lengths and order as the lockstep loop, plant 0x10, drive 0x20):
 *   plant -> SYNC        0x080, 1 byte: counter 1..240 (CiA 301 SYNC counter)
 *   plant -> TPDO1       0x190, 8 bytes: i_a, i_b (REAL32 LE; here k and -k)
 *   plant -> TPDO2       0x290, 8 bytes: theta (REAL32), sync counter (u8), status (u8),
 *                                        sample index (u16 LE = k mod 65536)
 *   drive -> EXTRA x     0x3A0, 0x4A0, ... 8 bytes each, sent on SYNC (the drive's
 *                        synchronous trace TPDOs of a bench run; default EXTRA = 0)
 *   drive -> TPDO1       0x210, 8 bytes: v_alpha, v_beta (REAL32; here the sample
 *                        index as a float and its negative), sent when TPDO2 arrives
 * The plant sends SYNC k+1 only after the command of period k arrived (lockstep).
 * The drive checks that TPDO1 and TPDO2 of the period arrived in order with the
 * right counters; the plant checks every command. Exit 0 only if all N matched.
 *
 * The drive prints "ready" once its socket is bound (start it first, wait for it).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "co_socketcan.h"

#define SYNC_ID 0x080u
#define MEAS1_ID 0x190u
#define MEAS2_ID 0x290u
#define CMD_ID 0x210u
#define EXTRA_MAX 4u

static const uint16_t extra_ids[EXTRA_MAX] = {0x3A0u, 0x4A0u, 0x2A0u, 0x2A1u};

static int64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}
static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static void put_f32(uint8_t *p, float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    put_u32(p, u);
}
static float get_f32(const uint8_t *p)
{
    uint32_t u = get_u32(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}
static int cmp_i64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}
static uint8_t sync_counter(uint32_t k) { return (uint8_t)(1u + k % 240u); }

static int run_drive(int fd, uint32_t n, uint32_t extra)
{
    uint32_t answered = 0, errors = 0;
    uint32_t expect_k = 0;
    int have_meas1 = 0;
    printf("ready\n");
    fflush(stdout);
    while (answered < n) {
        co_frame_t f;
        int r = co_socketcan_recv(fd, &f, 10 * 1000 * 1000, NULL);
        if (r == 0) {
            fprintf(stderr, "drive: timeout after %u periods\n", answered);
            return 2;
        }
        if (r < 0) return 2;
        if (f.cob_id == SYNC_ID) {
            if (f.dlc != 1 || f.data[0] != sync_counter(expect_k)) ++errors;
            have_meas1 = 0;
            for (uint32_t e = 0; e < extra; ++e) {
                co_frame_t t = {.cob_id = extra_ids[e], .dlc = 8, .data = {0}};
                put_u32(t.data, expect_k);
                put_u32(t.data + 4, e);
                if (co_socketcan_send(&fd, &t) != 0) return 2;
            }
        } else if (f.cob_id == MEAS1_ID) {
            if (f.dlc != 8 || get_f32(f.data) != (float)expect_k) ++errors;
            have_meas1 = 1;
        } else if (f.cob_id == MEAS2_ID) {
            const uint16_t si = (uint16_t)(f.data[6] | f.data[7] << 8);
            if (f.dlc != 8 || !have_meas1 || si != (uint16_t)expect_k || f.data[4] != sync_counter(expect_k)) ++errors;
            co_frame_t c = {.cob_id = CMD_ID, .dlc = 8, .data = {0}};
            put_f32(c.data, (float)si);
            put_f32(c.data + 4, -(float)si);
            if (co_socketcan_send(&fd, &c) != 0) return 2;
            have_meas1 = 0;
            ++expect_k;
            ++answered;
        }
    }
    printf("drive: answered %u periods, %u errors\n", answered, errors);
    return errors == 0 ? 0 : 1;
}

static int run_plant(int fd, uint32_t n, uint32_t extra)
{
    int64_t *rtt = calloc(n, sizeof *rtt);
    if (!rtt) return 2;
    uint32_t ok = 0, bad = 0;
    uint64_t other = 0;
    const int64_t t_start = now_ns();
    for (uint32_t k = 0; k < n; ++k) {
        co_frame_t s = {.cob_id = SYNC_ID, .dlc = 1, .data = {sync_counter(k)}};
        co_frame_t m1 = {.cob_id = MEAS1_ID, .dlc = 8, .data = {0}};
        co_frame_t m2 = {.cob_id = MEAS2_ID, .dlc = 8, .data = {0}};
        put_f32(m1.data, (float)k);
        put_f32(m1.data + 4, -(float)k);
        put_f32(m2.data, 0.25f);
        m2.data[4] = sync_counter(k);
        m2.data[5] = 0;
        m2.data[6] = (uint8_t)k;
        m2.data[7] = (uint8_t)(k >> 8);
        const int64_t t0 = now_ns();
        if (co_socketcan_send(&fd, &s) != 0 || co_socketcan_send(&fd, &m1) != 0 || co_socketcan_send(&fd, &m2) != 0) {
            free(rtt);
            return 2;
        }
        for (;;) {
            co_frame_t a;
            int r = co_socketcan_recv(fd, &a, 2 * 1000 * 1000, NULL);
            if (r <= 0) {
                fprintf(stderr, "plant: no command for period %u\n", k);
                free(rtt);
                return 2;
            }
            if (a.cob_id != CMD_ID) {
                ++other;
                continue;
            }
            if (a.dlc != 8 || get_f32(a.data) != (float)(uint16_t)k)
                ++bad;
            else
                ++ok;
            break;
        }
        rtt[k] = now_ns() - t0;
    }
    const int64_t total = now_ns() - t_start;
    qsort(rtt, n, sizeof *rtt, cmp_i64);
    const double mean = (double)total / (double)n;
    printf("plant: %u periods, %u commands verified, %u bad, %llu other frames (expected %llu)\n", n, ok, bad,
           (unsigned long long)other, (unsigned long long)n * extra);
    printf("lockstep_floor: periods %u frames_per_period %u wall_s %.6f periods_per_s %.1f "
           "rtt_us mean %.1f min %.1f median %.1f p99 %.1f max %.1f\n",
           n, 4u + extra, 1e-9 * (double)total, 1e9 * (double)n / (double)total, mean / 1e3, (double)rtt[0] / 1e3,
           (double)rtt[n / 2] / 1e3, (double)rtt[((uint64_t)n * 99u) / 100u] / 1e3, (double)rtt[n - 1] / 1e3);
    free(rtt);
    return (bad == 0 && ok == n) ? 0 : 1;
}

int main(int argc, char **argv)
{
    if ((argc != 4 && argc != 5) || (strcmp(argv[1], "plant") != 0 && strcmp(argv[1], "drive") != 0)) {
        fprintf(stderr, "usage: %s plant|drive IFACE PERIODS [EXTRA_DRIVE_FRAMES 0..%u]\n", argv[0], EXTRA_MAX);
        return 64;
    }
    char *end = NULL;
    unsigned long n = strtoul(argv[3], &end, 10);
    if (!end || *end || n == 0 || n > 100000000ul) {
        fprintf(stderr, "PERIODS must be an integer in 1..100000000, got '%s'\n", argv[3]);
        return 64;
    }
    unsigned long extra = 0;
    if (argc == 5) {
        extra = strtoul(argv[4], &end, 10);
        if (!end || *end || extra > EXTRA_MAX) {
            fprintf(stderr, "EXTRA_DRIVE_FRAMES must be an integer in 0..%u, got '%s'\n", EXTRA_MAX, argv[4]);
            return 64;
        }
    }
    int fd = co_socketcan_open(argv[2], 1 << 20);
    if (fd < 0) return 2;
    return strcmp(argv[1], "drive") == 0 ? run_drive(fd, (uint32_t)n, (uint32_t)extra)
                                         : run_plant(fd, (uint32_t)n, (uint32_t)extra);
}
