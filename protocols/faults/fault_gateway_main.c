/* fault_gateway_main.c - the fault injector as a SocketCAN gateway process.
 *
 *   fault_gateway --a vcan0 --b vcan1 --rules FILE --log FILE [--pid-a PID] [--pid-b PID]
 *
 * Side A (the plant, the master, the recorder) and side B (the drive) are two CAN interfaces;
 * every frame from one goes to the other through fault_injector.c, the same code as the bench's
 * direct mode. Node faults: SIGSTOP/SIGCONT (freeze) and SIGKILL (kill) to the node's process.
 * SIGTERM/SIGINT: the injector's log is written (one action a line) and the process exits 0.
 * The kernel's can-gw would forward faster, but it cannot count periods, hold a frame for one
 * period or decide by a seeded draw: hence this small process (a few us a frame).
 */
#include <errno.h>
#include <inttypes.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <time.h>
#include <unistd.h>

#include "co_socketcan.h"
#include "fault_injector.h"
#include "fault_rules.h"

#define EXIT_USAGE 64

static fi_t g_fi;
static int g_fd[2] = {-1, -1};
static pid_t g_pid[2] = {0, 0};
static volatile sig_atomic_t g_stop = 0;
static uint64_t g_send_errors = 0;

static void on_signal(int sig)
{
    (void)sig;
    g_stop = 1;
}

static void emit(void *user, const co_frame_t *f, uint8_t to, uint8_t from)
{
    (void)user;
    (void)from;
    if (co_socketcan_send(&g_fd[to], f) != 0) ++g_send_errors;
}

static void node_fault(void *user, uint8_t side, uint8_t kind, int on)
{
    (void)user;
    if (g_pid[side] <= 0) {
        fprintf(stderr, "fault_gateway: node fault %s on side %c: no --pid-%c given, ignored\n", fi_kind_name(kind),
                side == FI_SIDE_A ? 'a' : 'b', side == FI_SIDE_A ? 'a' : 'b');
        return;
    }
    int sig = kind == FI_KILL ? SIGKILL : on ? SIGSTOP : SIGCONT;
    if (kill(g_pid[side], sig) != 0)
        fprintf(stderr, "fault_gateway: kill(%d, %d): %s\n", (int)g_pid[side], sig, strerror(errno));
}

static char *read_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    size_t cap = 4096, n = 0;
    char *buf = malloc(cap);
    size_t got;
    while (buf && (got = fread(buf + n, 1, cap - n - 1, f)) > 0) {
        n += got;
        if (n + 1 >= cap) {
            char *nb = realloc(buf, cap * 2);
            if (!nb) {
                free(buf);
                buf = NULL;
                break;
            }
            buf = nb;
            cap *= 2;
        }
    }
    fclose(f);
    if (buf) buf[n] = '\0';
    return buf;
}

static int write_log(const char *path)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        fprintf(stderr, "fault_gateway: cannot write %s: %s\n", path, strerror(errno));
        return -1;
    }
    fprintf(f, "# period t_us rule kind from cob_id dlc data\n");
    for (uint32_t i = 0; i < g_fi.n_log; ++i) {
        const fi_event_t *e = &g_fi.log[i];
        fprintf(f, "%" PRId64 " %" PRId64 " %u %s %c %03X %u ", e->period, e->t_us, (unsigned)e->rule,
                fi_kind_name(e->kind), e->from == FI_SIDE_A ? 'a' : 'b', (unsigned)e->cob_id, (unsigned)e->dlc);
        for (uint8_t b = 0; b < 8u; ++b) fprintf(f, "%02X", e->data[b]);
        fputc('\n', f);
    }
    fprintf(f,
            "# frames_in %" PRIu64 " frames_out %" PRIu64 " log_overflow %u held_overflow %u send_errors %" PRIu64
            " periods %" PRId64 "\n",
            g_fi.frames_in, g_fi.frames_out, g_fi.log_overflow, g_fi.held_overflow, g_send_errors, g_fi.period + 1);
    fclose(f);
    return 0;
}

static void usage(FILE *f)
{
    fprintf(f, "usage: fault_gateway --a IFACE --b IFACE --rules FILE --log FILE [--pid-a PID] [--pid-b PID]\n"
               "\n"
               "Joins two CAN interfaces (side a: plant, master, recorder; side b: drive) and injects\n"
               "the faults of FILE (protocols/faults/fault_rules.h) into the frames crossing them.\n"
               "Periods are counted from the SYNCs (0x080) crossing from side a. On SIGTERM/SIGINT\n"
               "every action taken is written to --log, one line each, and the process exits 0.\n");
}

int main(int argc, char **argv)
{
    const char *ifa = NULL, *ifb = NULL, *rules = NULL, *log = NULL;
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (strcmp(a, "--help") == 0) {
            usage(stdout);
            return 0;
        }
        if (!v) {
            usage(stderr);
            return EXIT_USAGE;
        }
        if (strcmp(a, "--a") == 0)
            ifa = v;
        else if (strcmp(a, "--b") == 0)
            ifb = v;
        else if (strcmp(a, "--rules") == 0)
            rules = v;
        else if (strcmp(a, "--log") == 0)
            log = v;
        else if (strcmp(a, "--pid-a") == 0)
            g_pid[0] = (pid_t)atoi(v);
        else if (strcmp(a, "--pid-b") == 0)
            g_pid[1] = (pid_t)atoi(v);
        else {
            fprintf(stderr, "fault_gateway: unknown option %s\n", a);
            usage(stderr);
            return EXIT_USAGE;
        }
        ++i;
    }
    if (!ifa || !ifb || !rules || !log) {
        usage(stderr);
        return EXIT_USAGE;
    }
    fi_init(&g_fi, emit, node_fault, NULL);
    char *text = read_file(rules);
    if (!text) {
        fprintf(stderr, "fault_gateway: cannot read %s: %s\n", rules, strerror(errno));
        return EXIT_USAGE;
    }
    char err[256];
    int n = fi_parse_rules(&g_fi, text, err, sizeof err);
    free(text);
    if (n < 0) {
        fprintf(stderr, "fault_gateway: %s: %s\n", rules, err);
        return EXIT_USAGE;
    }
    g_fd[0] = co_socketcan_open(ifa, 1 << 20);
    g_fd[1] = co_socketcan_open(ifb, 1 << 20);
    if (g_fd[0] < 0 || g_fd[1] < 0) return 1;
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    printf("fault_gateway: %s <-> %s, %d rule(s)\n", ifa, ifb, n);
    fflush(stdout);
    while (!g_stop) {
        int64_t now = co_socketcan_now_us();
        int64_t rel = fi_next_release_us(&g_fi);
        int64_t wait_us = 100000;
        if (rel >= 0) wait_us = rel <= now ? 0 : rel - now; /* microsecond delays: ppoll, not poll's ms */
        struct timespec ts = {(time_t)(wait_us / 1000000), (long)(wait_us % 1000000) * 1000L};
        struct pollfd p[2] = {{g_fd[0], POLLIN, 0}, {g_fd[1], POLLIN, 0}};
        int r = ppoll(p, 2, &ts, NULL);
        if (r < 0 && errno != EINTR) break;
        for (uint8_t s = 0; s < 2u; ++s) {
            if (r <= 0 || !(p[s].revents & POLLIN)) continue;
            co_frame_t f;
            while (co_socketcan_recv(g_fd[s], &f, 0, NULL) == 1) fi_frame(&g_fi, &f, s, co_socketcan_now_us());
        }
        fi_tick(&g_fi, co_socketcan_now_us());
    }
    return write_log(log) == 0 ? 0 : 1;
}
