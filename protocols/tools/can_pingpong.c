/* can_pingpong.c - minimal C round trip over SocketCAN: the floor any CANopen
 * loop on the same bus is measured against, and the foundation's proof that two
 * processes exchange frames over a real (v)can interface.
 *
 *   can_pingpong echo IFACE N      answer N ping frames, then exit
 *   can_pingpong ping IFACE N      send N pings, check every answer, print RTT stats
 *
 * Ping: id 0x181, 8 bytes = seq (u32 LE), ~seq (u32 LE).
 * Echo: id 0x201, 8 bytes = seq (u32 LE), seq * 2654435761 mod 2^32 (u32 LE).
 * The pinger verifies every byte of every answer; exit 0 only if all N matched.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "co_socketcan.h"

#define PING_ID 0x181u
#define ECHO_ID 0x201u

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
static int cmp_i64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

static int run_echo(int fd, uint32_t n)
{
    uint32_t answered = 0;
    printf("echo: ready\n"); /* bound and listening: the ping may start (no sleep on a loaded machine) */
    fflush(stdout);
    while (answered < n) {
        co_frame_t f;
        int r = co_socketcan_recv(fd, &f, 10 * 1000 * 1000, NULL);
        if (r == 0) {
            fprintf(stderr, "echo: timeout after %u frames\n", answered);
            return 2;
        }
        if (r < 0) return 2;
        if (f.cob_id != PING_ID || f.dlc != 8) continue;
        uint32_t seq = get_u32(f.data);
        co_frame_t a = {.cob_id = ECHO_ID, .dlc = 8, .data = {0}};
        put_u32(a.data, seq);
        put_u32(a.data + 4, seq * 2654435761u);
        if (co_socketcan_send(&fd, &a) != 0) return 2;
        ++answered;
    }
    printf("echo: answered %u pings\n", answered);
    return 0;
}

static int run_ping(int fd, uint32_t n)
{
    int64_t *rtt = calloc(n ? n : 1, sizeof *rtt);
    if (!rtt) return 2;
    uint32_t bad = 0, ok = 0;
    int64_t t_start = co_socketcan_now_us();
    for (uint32_t seq = 0; seq < n; ++seq) {
        co_frame_t p = {.cob_id = PING_ID, .dlc = 8, .data = {0}};
        put_u32(p.data, seq);
        put_u32(p.data + 4, ~seq);
        int64_t t0 = co_socketcan_now_us();
        if (co_socketcan_send(&fd, &p) != 0) {
            free(rtt);
            return 2;
        }
        for (;;) {
            co_frame_t a;
            int r = co_socketcan_recv(fd, &a, 5 * 1000 * 1000, NULL);
            if (r <= 0) {
                fprintf(stderr, "ping: no answer to seq %u\n", seq);
                free(rtt);
                return 2;
            }
            if (a.cob_id != ECHO_ID) continue;
            if (a.dlc != 8 || get_u32(a.data) != seq || get_u32(a.data + 4) != seq * 2654435761u) {
                fprintf(stderr, "ping: bad answer to seq %u: dlc %u seq %u\n", seq, a.dlc, get_u32(a.data));
                ++bad;
            } else {
                ++ok;
            }
            break;
        }
        rtt[seq] = co_socketcan_now_us() - t0;
    }
    int64_t total = co_socketcan_now_us() - t_start;
    qsort(rtt, n, sizeof *rtt, cmp_i64);
    printf("ping: %u frames sent, %u answers verified, %u bad\n", n, ok, bad);
    if (n) {
        printf("ping: rtt_us min %lld median %lld p99 %lld max %lld; %.0f round trips/s\n", (long long)rtt[0],
               (long long)rtt[n / 2], (long long)rtt[(n * 99) / 100], (long long)rtt[n - 1],
               total > 0 ? 1e6 * n / (double)total : 0.0);
    }
    free(rtt);
    return (bad == 0 && ok == n) ? 0 : 1;
}

int main(int argc, char **argv)
{
    if (argc != 4 || (strcmp(argv[1], "echo") != 0 && strcmp(argv[1], "ping") != 0)) {
        fprintf(stderr, "usage: %s echo|ping IFACE COUNT\n", argv[0]);
        return 64;
    }
    char *end = NULL;
    unsigned long n = strtoul(argv[3], &end, 10);
    if (!end || *end || n == 0 || n > 100000000ul) {
        fprintf(stderr, "COUNT must be an integer in 1..100000000, got '%s'\n", argv[3]);
        return 64;
    }
    int fd = co_socketcan_open(argv[2], 1 << 20);
    if (fd < 0) return 2;
    return strcmp(argv[1], "echo") == 0 ? run_echo(fd, (uint32_t)n) : run_ping(fd, (uint32_t)n);
}
