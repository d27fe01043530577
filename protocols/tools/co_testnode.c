/* co_testnode.c - a bare CANopen slave process serving the plant or drive object
 * dictionary with no application behind it: the conformance target for the
 * protocol layer alone (NMT, heartbeat, SYNC, PDO, SDO, EMCY).
 *
 *   co_testnode plant|drive [--iface vcan0] [--node-id N] [--sync-timer]
 *
 * --sync-timer produces SYNC every 0x1006 microseconds when 0x1005 bit 30 is set.
 * EMCY is provoked through protocol errors (a SYNC of the wrong length, a short RPDO).
 */
#include <stdio.h>
#include <string.h>

#include "co_runtime.h"
#include "od_drive.h"
#include "od_plant.h"

static uint8_t g_domain[512];

static void on_reset(void *user, co_node_t *node, int communication_only)
{
    (void)user;
    (void)node;
    if (communication_only) return;
    /* Give the DOMAIN objects a buffer so segmented transfers can be tested. */
    OD_PLANT.mfr.x2006_timing_histograms.data = g_domain;
    OD_PLANT.mfr.x2006_timing_histograms.size = 128;
    OD_PLANT.mfr.x2006_timing_histograms.capacity = 0;
    OD_PLANT.mfr.x2008_flux_map.data = g_domain;
    OD_PLANT.mfr.x2008_flux_map.size = 64;
    OD_PLANT.mfr.x2008_flux_map.capacity = 0;
    OD_PLANT.mfr.x2009_FMU.data = g_domain;
    OD_PLANT.mfr.x2009_FMU.size = 32;
    OD_PLANT.mfr.x2009_FMU.capacity = 0;
    OD_DRIVE.mfr.x2301_trace_buffer.data = g_domain;
    OD_DRIVE.mfr.x2301_trace_buffer.size = 300;
    OD_DRIVE.mfr.x2301_trace_buffer.capacity = 0;
    for (unsigned i = 0; i < sizeof g_domain; ++i) g_domain[i] = (uint8_t)(i * 7u + 3u);
}

int main(int argc, char **argv)
{
    if (argc < 2 || (strcmp(argv[1], "plant") != 0 && strcmp(argv[1], "drive") != 0)) {
        fprintf(stderr, "usage: %s plant|drive [--iface IFACE] [--node-id N]\n", argv[0]);
        return 64;
    }
    int is_plant = strcmp(argv[1], "plant") == 0;
    const char *iface = "vcan0";
    uint8_t node_id = is_plant ? (uint8_t)OD_PLANT_DEFAULT_NODE_ID : (uint8_t)OD_DRIVE_DEFAULT_NODE_ID;
    int next = co_runtime_parse_args(argc - 1, argv + 1, &iface, &node_id);
    if (next < 0) return 64;
    int sync_timer = 0;
    for (int i = next + 1; i < argc; ++i) {
        if (strcmp(argv[i], "--sync-timer") == 0) {
            sync_timer = 1;
        } else {
            fprintf(stderr, "unknown option '%s'\n", argv[i]);
            return 64;
        }
    }
    static co_runtime_t rt;
    co_hooks_t hooks;
    memset(&hooks, 0, sizeof hooks);
    hooks.on_reset = on_reset;
    if (co_runtime_open(&rt, iface, is_plant ? &od_plant : &od_drive, node_id, &hooks, NULL, NULL) != 0) return 2;
    printf("co_testnode: %s OD as node 0x%02X on %s\n", argv[1], node_id, iface);
    fflush(stdout);
    rt.node.sync_timer_enabled = sync_timer != 0;
    int rc = co_runtime_run(&rt);
    co_runtime_close(&rt);
    return rc;
}
