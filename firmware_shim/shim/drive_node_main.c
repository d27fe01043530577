/* drive_node_main.c - the drive firmware as a Linux CANopen node process.
 *
 *   drive_node [--iface vcan0] [--node-id N]
 *
 * The portable node app (drive_app.c) on the SocketCAN runtime (co_runtime):
 * it waits in NMT pre-operational until the master starts it, then runs one
 * current step per measurement PDO of the plant.  SIGINT/SIGTERM end it
 * cleanly (exit 0) with a one-line summary on stderr. */
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "co_runtime.h"
#include "drive_app.h"
#include "od_drive.h"

#define EXIT_USAGE 64 /* sysexits.h EX_USAGE */
#define IFACE_MAX 15  /* IFNAMSIZ - 1 */

static void usage(FILE *f, const char *prog)
{
    fprintf(f,
            "usage: %s [--iface NAME] [--node-id N]\n"
            "\n"
            "PMSM drive firmware (firmware_shim/core) as a CANopen slave (drive.eds).\n"
            "Runs one current step per measurement of the plant (its TPDO2 -> RPDO2),\n"
            "answers with the voltage command (TPDO1, COB-ID 0x210), runs the outer loops\n"
            "every speed_loop_divider steps, and serves its object dictionary by SDO.\n"
            "Start it with NMT (e.g. cansend vcan0 000#01%02X).\n"
            "\n"
            "  --iface NAME    SocketCAN interface, 1..%d characters (default vcan0)\n"
            "  --node-id N     CANopen node-ID, 1..127 (default %u)\n"
            "  --help          this text\n"
            "\n"
            "Exit status: 0 clean stop (SIGINT/SIGTERM), 1 bus error, 64 bad option.\n",
            prog, (unsigned)OD_DRIVE_DEFAULT_NODE_ID, IFACE_MAX, (unsigned)OD_DRIVE_DEFAULT_NODE_ID);
}

static int64_t poll_app(void *user, co_runtime_t *rt, int64_t now_us)
{
    (void)user;
    (void)rt;
    (void)now_us;
    return -1; /* no timer of its own: everything is driven by frames */
}

/* Cycle counter of 0x2208 Step cost: CLOCK_MONOTONIC in ns (modulo 2^32). */
static uint32_t monotonic_ns(void *user)
{
    (void)user;
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint32_t)((uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec);
}

static drive_app_t g_app; /* ~40 KiB (trace buffer): static, not on the stack */
static co_runtime_t g_rt;

int main(int argc, char **argv)
{
    const char *prog = argc > 0 ? argv[0] : "drive_node";
    const char *iface = "vcan0";
    uint8_t node_id = (uint8_t)OD_DRIVE_DEFAULT_NODE_ID;

    for (int i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            usage(stdout, prog);
            return 0;
        }
    }
    int next = co_runtime_parse_args(argc, argv, &iface, &node_id);
    if (next < 0) return EXIT_USAGE; /* message (option and range) printed by the parser */
    if (next < argc) {
        if (strcmp(argv[next], "--iface") == 0)
            fprintf(stderr, "%s: --iface needs a value: an interface name of 1..%d characters\n", prog, IFACE_MAX);
        else if (strcmp(argv[next], "--node-id") == 0)
            fprintf(stderr, "%s: --node-id needs a value: an integer in 1..127\n", prog);
        else
            fprintf(stderr, "%s: unknown option '%s' (allowed: --iface NAME, --node-id 1..127, --help)\n", prog,
                    argv[next]);
        return EXIT_USAGE;
    }
    size_t n = strlen(iface);
    if (n == 0u || n > IFACE_MAX) {
        fprintf(stderr, "%s: --iface must be an interface name of 1..%d characters, got '%s'\n", prog, IFACE_MAX,
                iface);
        return EXIT_USAGE;
    }

    static const co_runtime_app_t app_cb = {poll_app};
    drive_app_init(&g_app);
    drive_app_set_cycle_counter(&g_app, monotonic_ns, NULL, 1000000000u);
    if (co_runtime_open(&g_rt, iface, &od_drive, node_id, drive_app_hooks(), &app_cb, &g_app) != 0) {
        fprintf(stderr, "%s: cannot open CAN interface '%s'\n", prog, iface);
        return 1;
    }
    drive_app_bind(&g_app, &g_rt.node);
    fprintf(stderr, "%s: node 0x%02X on %s, waiting for NMT start\n", prog, (unsigned)node_id, iface);

    int rc = co_runtime_run(&g_rt);
    co_runtime_close(&g_rt);
    fprintf(stderr, "%s: stopped: %u current steps, %u lost, %u late measurements, %u frames in\n", prog,
            (unsigned)g_app.sup.drive_status.current_steps, (unsigned)g_app.sup.drive_status.lost_measurements,
            (unsigned)g_app.sup.drive_status.late_measurements, (unsigned)g_rt.frames_in);
    return rc;
}
