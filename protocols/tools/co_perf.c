/* co_perf.c - cost of the C CANopen slave's frame handling, in-process.
 *
 *   co_perf [N]    prints ns per frame for: an event-driven RPDO (8 bytes, 2 REAL32),
 *                  a synchronous RPDO + SYNC + 2 synchronous TPDOs, an SDO expedited
 *                  download and an SDO expedited upload; N frames each (default 2e6).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "co_node.h"
#include "od_drive.h"
#include "od_plant.h"

static uint64_t g_tx;
static int tx(void *user, const co_frame_t *f)
{
    (void)user;
    g_tx += f->dlc;
    return 0;
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
    long n = argc > 1 ? atol(argv[1]) : 2000000L;
    if (n <= 0) {
        fprintf(stderr, "N must be a positive integer\n");
        return 64;
    }
    static co_node_t drive, plant;
    co_node_init(&drive, &od_drive, 0x20, tx, NULL, NULL, NULL, 0);
    co_node_init(&plant, &od_plant, 0x10, tx, NULL, NULL, NULL, 0);
    co_nmt_command(&drive, CO_NMT_CS_START);
    co_nmt_command(&plant, CO_NMT_CS_START);
    /* The drive's RPDO1 (event-driven, 2 x REAL32). */
    co_frame_t rpdo = {.cob_id = 0x220, .dlc = 8, .data = {0, 0, 0x80, 0x3F, 0, 0, 0, 0x40}};
    double t0 = now_s();
    for (long i = 0; i < n; ++i) {
        rpdo.data[0] = (uint8_t)i;
        co_node_process(&drive, &rpdo, i);
    }
    double t_rpdo = (now_s() - t0) / (double)n * 1e9;

    /* Plant: synchronous RPDO then SYNC (actuation + 2 synchronous TPDOs). */
    co_frame_t cmd = {.cob_id = 0x210, .dlc = 8, .data = {0, 0, 0x80, 0x3F, 0, 0, 0, 0x40}};
    t0 = now_s();
    for (long i = 0; i < n; ++i) {
        co_node_process(&plant, &cmd, i);
        co_sync_produce(&plant, i);
    }
    double t_sync = (now_s() - t0) / (double)n * 1e9;

    co_frame_t dl = {.cob_id = 0x620, .dlc = 8, .data = {0x23, 0x00, 0x22, 0x04, 0, 0, 0xC0, 0x3F}};
    t0 = now_s();
    for (long i = 0; i < n; ++i) co_node_process(&drive, &dl, i);
    double t_dl = (now_s() - t0) / (double)n * 1e9;
    co_frame_t ul = {.cob_id = 0x620, .dlc = 8, .data = {0x40, 0x00, 0x22, 0x04, 0, 0, 0, 0}};
    t0 = now_s();
    for (long i = 0; i < n; ++i) co_node_process(&drive, &ul, i);
    double t_ul = (now_s() - t0) / (double)n * 1e9;
    printf("co_perf: %ld frames each, tx bytes %llu\n", n, (unsigned long long)g_tx);
    printf("co_perf: rpdo_event_ns %.1f\n", t_rpdo);
    printf("co_perf: rpdo_sync_plus_sync_2tpdo_ns %.1f\n", t_sync);
    printf("co_perf: sdo_expedited_download_ns %.1f\n", t_dl);
    printf("co_perf: sdo_expedited_upload_ns %.1f\n", t_ul);
    return 0;
}
