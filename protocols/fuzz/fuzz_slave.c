/* fuzz_slave.c - libFuzzer harness for the C CANopen slave (build with
 * clang -fsanitize=fuzzer,address,undefined; `make fuzz`).
 *
 * Input: byte 0 selects the object dictionary (even: drive, odd: plant); then
 * records of 12 bytes: cob-id (2, LE, bit 15 = RTR), dlc (1, any value), 8 data
 * bytes, time advance (1, x100 us). Each frame goes to co_node_process, then
 * co_node_tick runs. Besides ASan/UBSan findings, the harness aborts when the slave
 * breaks a rule a malformed frame must never break:
 *   - a frame that is not NMT, SYNC, SDO-to-us, an RPDO or a heartbeat changes no state
 *     (object dictionary bytes, NMT state) and makes the node send nothing;
 *   - only an NMT frame changes the NMT state;
 *   - an SDO request with a DLC other than 8 gets no answer;
 *   - every SDO answer is a valid server command (or an abort with a CiA 301 code).
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "co_node.h"
#include "od_drive.h"
#include "od_plant.h"

static co_frame_t g_tx[64];
static int g_ntx;
static uint8_t g_domain[300];

static int tx(void *user, const co_frame_t *f)
{
    (void)user;
    if (g_ntx < 64) g_tx[g_ntx] = *f;
    ++g_ntx;
    return 0;
}

static void on_reset(void *user, co_node_t *node, int comm_only)
{
    (void)user;
    (void)node;
    if (comm_only) return;
    OD_DRIVE.mfr.x2301_trace_buffer.data = g_domain;
    OD_DRIVE.mfr.x2301_trace_buffer.size = sizeof g_domain;
    OD_DRIVE.mfr.x2301_trace_buffer.capacity = sizeof g_domain;
    OD_PLANT.mfr.x2006_timing_histograms.data = g_domain;
    OD_PLANT.mfr.x2006_timing_histograms.size = 128;
    OD_PLANT.mfr.x2006_timing_histograms.capacity = 0;
}

static uint8_t
    g_before[sizeof(od_drive_ram_t) > sizeof(od_plant_ram_t) ? sizeof(od_drive_ram_t) : sizeof(od_plant_ram_t)];

static int is_rpdo(const co_node_t *n, uint16_t id)
{
    for (unsigned i = 0; i < CO_NUM_PDO; ++i)
        if (n->rpdo[i].valid && n->rpdo[i].cob_id == id) return 1;
    return 0;
}

static int valid_sdo_answer(const co_frame_t *f)
{
    uint8_t scs = (uint8_t)(f->data[0] >> 5);
    if (f->dlc != 8) return 0;
    if (scs == 4) {
        uint32_t code =
            (uint32_t)f->data[4] | (uint32_t)f->data[5] << 8 | (uint32_t)f->data[6] << 16 | (uint32_t)f->data[7] << 24;
        return (code >> 24) == 0x05 || (code >> 24) == 0x06 || (code >> 24) == 0x08;
    }
    return scs <= 3;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static co_node_t node;
    if (size < 1) return 0;
    int plant = data[0] & 1;
    const co_od_t *od = plant ? &od_plant : &od_drive;
    uint8_t id = plant ? 0x10 : 0x20;
    co_hooks_t hooks;
    memset(&hooks, 0, sizeof hooks);
    hooks.on_reset = on_reset;
    int64_t now = 1000;
    co_node_init(&node, od, id, tx, NULL, &hooks, NULL, now);
    size_t ram = od->total_size;
    for (size_t off = 1; off + 12 <= size; off += 12) {
        const uint8_t *r = data + off;
        co_frame_t f;
        memset(&f, 0, sizeof f);
        uint16_t raw = (uint16_t)(r[0] | (r[1] << 8));
        f.cob_id = (uint32_t)(raw & 0x7FFu) | ((raw & 0x8000u) ? CO_FRAME_RTR : 0u);
        f.dlc = r[2] > 8 ? 8 : r[2];
        memcpy(f.data, r + 3, 8);
        uint16_t cob = (uint16_t)(f.cob_id & 0x7FFu);
        uint32_t sync_cob = co_od_get_u32(od, 0x1005, 0) & 0x7FFu;
        int relevant =
            cob == 0 || cob == sync_cob || cob == 0x600u + id || is_rpdo(&node, cob) || (cob > 0x700u && cob <= 0x77Fu);
        if (f.cob_id & CO_FRAME_RTR) relevant = 0;
        co_nmt_state_t st = node.nmt;
        memcpy(g_before, od->ram, ram);
        g_ntx = 0;
        co_node_process(&node, &f, now);
        if (!relevant) {
            if (g_ntx != 0 || node.nmt != st || memcmp(g_before, od->ram, ram) != 0) abort();
        }
        if (cob != 0 && node.nmt != st) abort();
        if (cob == 0x600u + id && !(f.cob_id & CO_FRAME_RTR)) {
            if (f.dlc != 8 && g_ntx != 0) abort();
            for (int i = 0; i < g_ntx && i < 64; ++i)
                if (g_tx[i].cob_id == 0x580u + id && !valid_sdo_answer(&g_tx[i])) abort();
        }
        now += (int64_t)r[11] * 100;
        co_node_tick(&node, now);
    }
    return 0;
}
