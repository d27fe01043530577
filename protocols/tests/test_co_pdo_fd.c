/* test_co_pdo_fd.c - PDOs in CAN FD frames (plant.eds / drive.eds 0x2105 "CAN FD"; issue 54).
 *
 * Over real SDO frames on the in-process bus:
 *  - classic frames (0x2105:01 = 0): a mapping beyond 8 bytes is refused (0x06040042), as before;
 *  - CAN FD (1, 2): a TPDO maps up to 64 bytes and goes out as a CAN FD frame (flags FDF, and BRS with 2) padded
 *    with zeros to the next CAN FD length (14 bytes -> 16); a TPDO of 0x2105:02 stays a classic frame;
 *  - an RPDO takes a CAN FD frame padded to its length without a length EMCY, and one longer than the padding
 *    with EMCY 0x8220; a shorter one is not processed (0x8210);
 *  - 0x2105 is written in PRE-OPERATIONAL only (0x08000022 in OPERATIONAL), within its EDS range (0x06090031);
 *    going back to classic frames is refused while a valid PDO maps more than 8 bytes (0x06040043), and once it is
 *    made invalid such a PDO stays without frames.
 * Built a second time as the Cortex-M4F image builds the core (CO_FRAME_MAX_DATA 8, with the sanitizers:
 * build/tests/protocols_test_co_pdo_fd_classic): that node refuses CAN FD (0x06090031) and its PDOs stay classic. */
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "co_node.h"
#include "od_drive.h"
#include "od_plant.h"
#include "testbus.h"

static testbus_t g_tb;

static void start(const co_od_t *od, uint8_t id)
{
    testbus_init(&g_tb, od, id, NULL, NULL, 1000, 100);
    testbus_deliver(&g_tb);
    testbus_clear(&g_tb);
}

static uint32_t sdo_w(uint16_t index, uint8_t sub, uint32_t v, uint8_t len)
{
    const uint8_t b[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    testbus_clear(&g_tb);
    return testbus_sdo_download(&g_tb, index, sub, b, len);
}

/* 0x2100 Measurement: i_a_A, i_b_A, theta_m_rad (REAL32), sync_counter, status (U8): 14 bytes */
static const uint32_t MEAS14[5] = {0x21000120u, 0x21000220u, 0x21000320u, 0x21000408u, 0x21000508u};

/* Maps `n` entries into the PDO at comm / map index (invalid first, as CiA 301's procedure); returns the abort of
 * the count's write. */
static uint32_t map_pdo(uint16_t comm, uint16_t mapi, uint32_t cob, const uint32_t *entries, uint8_t n, uint8_t type)
{
    CHECK(sdo_w(comm, 1, 0x80000000u | cob, 4) == 0, "0x%04X invalid", comm);
    CHECK(sdo_w(mapi, 0, 0, 1) == 0, "0x%04X count 0", mapi);
    for (uint8_t i = 0; i < n; ++i) CHECK(sdo_w(mapi, (uint8_t)(i + 1u), entries[i], 4) == 0, "entry %u", i);
    uint32_t a = sdo_w(mapi, 0, n, 1);
    CHECK(sdo_w(comm, 2, type, 1) == 0, "0x%04X type", comm);
    if (a == 0) CHECK(sdo_w(comm, 1, cob, 4) == 0, "0x%04X valid", comm);
    return a;
}

static void tpdo_frames(void)
{
    start(&od_plant, 0x10);
    CHECK(map_pdo(0x1800, 0x1A00, 0x190, MEAS14, 5, 254) == CO_ABORT_MAP_LEN, "classic: 14 bytes accepted");
    CHECK(sdo_w(0x2105, 1, 3, 1) == CO_ABORT_VALUE_HIGH, "0x2105:01 = 3 accepted");
    CHECK(sdo_w(0x2105, 1, 2, 1) == 0, "CAN FD with BRS refused");
    CHECK(map_pdo(0x1800, 0x1A00, 0x190, MEAS14, 5, 254) == 0, "CAN FD: 14 bytes refused");
    const uint32_t hold[1] = {0x21000120u};
    CHECK(sdo_w(0x2105, 2, 1u << 3, 1) == 0, "classic TPDO4 refused");
    CHECK(map_pdo(0x1803, 0x1A03, 0x490, hold, 1, 254) == 0, "TPDO4 refused");
    co_nmt_command(&g_tb.node, CO_NMT_CS_START);
    CHECK(sdo_w(0x2105, 1, 0, 1) == CO_ABORT_DATA_STATE, "0x2105 written in OPERATIONAL");
    OD_PLANT.mfr.x2100_Measurement.i_a_A = 1.5f;
    OD_PLANT.mfr.x2100_Measurement.status = 0x5A;
    testbus_clear(&g_tb);
    co_tpdo_request(&g_tb.node, 0);
    co_tpdo_request(&g_tb.node, 3);
    testbus_step(&g_tb);
    const co_frame_t *f = testbus_find(&g_tb, 0x190, 0);
    CHECK(f != NULL, "TPDO1 not sent");
    if (f) {
        printf("TPDO1: %u bytes, flags 0x%02X\n", f->dlc, f->flags);
        CHECK(f->dlc == 16 && f->flags == (CO_FRAME_FDF | CO_FRAME_BRS), "TPDO1: %u bytes, flags 0x%02X", f->dlc,
              f->flags);
        CHECK(testbus_same_f32(testbus_get_f32(&f->data[0]), 1.5f) && f->data[13] == 0x5A, "TPDO1 payload");
        CHECK(f->data[14] == 0 && f->data[15] == 0, "padding not zero");
    }
    const co_frame_t *h = testbus_find(&g_tb, 0x490, 0);
    CHECK(h != NULL && h->dlc == 4 && h->flags == 0, "TPDO4 (0x2105:02) not a classic frame");
    /* back to classic frames: refused while the 14-byte TPDO1 is valid (CiA 301: invalid first), then accepted */
    co_nmt_command(&g_tb.node, CO_NMT_CS_PREOP);
    CHECK(sdo_w(0x2105, 1, 0, 1) == CO_ABORT_PARAM_INCOMPAT, "classic accepted under a valid 14-byte TPDO1");
    CHECK(sdo_w(0x2105, 2, 1, 1) == CO_ABORT_PARAM_INCOMPAT, "TPDO1 made classic while it maps 14 bytes");
    CHECK(sdo_w(0x1800, 1, 0x80000190u, 4) == 0, "TPDO1 invalid refused");
    CHECK(sdo_w(0x2105, 1, 0, 1) == 0, "classic refused with TPDO1 invalid");
    CHECK(sdo_w(0x1800, 1, 0x190u, 4) == 0, "TPDO1 valid again refused");
    co_nmt_command(&g_tb.node, CO_NMT_CS_START);
    testbus_clear(&g_tb);
    co_tpdo_request(&g_tb.node, 0);
    testbus_step(&g_tb);
    CHECK(testbus_find(&g_tb, 0x190, 0) == NULL, "a 14-byte TPDO went out on classic frames");
    /* CAN FD without the bit-rate switch */
    co_nmt_command(&g_tb.node, CO_NMT_CS_PREOP);
    CHECK(sdo_w(0x2105, 1, 1, 1) == 0, "CAN FD refused");
    CHECK(map_pdo(0x1800, 0x1A00, 0x190, MEAS14, 5, 254) == 0, "CAN FD: 14 bytes refused");
    co_nmt_command(&g_tb.node, CO_NMT_CS_START);
    testbus_clear(&g_tb);
    co_tpdo_request(&g_tb.node, 0);
    testbus_step(&g_tb);
    f = testbus_find(&g_tb, 0x190, 0);
    CHECK(f != NULL && f->dlc == 16 && f->flags == CO_FRAME_FDF, "TPDO1 without BRS");
}

/* An RPDO of 14 bytes takes an FD frame of `len` bytes: returns the EMCY code sent (0: none). */
static uint16_t rpdo_gets(uint8_t len, float i_a)
{
    co_frame_t in;
    memset(&in, 0, sizeof in);
    in.cob_id = 0x190;
    in.dlc = len;
    in.flags = CO_FRAME_FDF | CO_FRAME_BRS;
    testbus_put_f32(&in.data[0], i_a);
    testbus_clear(&g_tb);
    co_membus_inject(&g_tb.bus, &in);
    testbus_step(&g_tb);
    const co_frame_t *e = testbus_find(&g_tb, 0x80u + 0x20u, 0);
    return e ? (uint16_t)(e->data[0] | e->data[1] << 8) : 0u;
}

static void rpdo_frames(void)
{
    start(&od_drive, 0x20);
    CHECK(sdo_w(0x2105, 1, 2, 1) == 0, "drive: CAN FD refused");
    CHECK(map_pdo(0x1400, 0x1600, 0x190, MEAS14, 5, 254) == 0, "drive: 14-byte RPDO1 refused");
    co_nmt_command(&g_tb.node, CO_NMT_CS_START);
    CHECK(rpdo_gets(16, 2.25f) == 0, "a 16-byte frame (the padding) raised an EMCY");
    CHECK(testbus_same_f32(OD_DRIVE.mfr.x2100_Measurement.i_a_A, 2.25f), "16-byte frame not stored");
    CHECK(rpdo_gets(12, 3.0f) == 0x8210, "a 12-byte frame: no length EMCY 0x8210");
    CHECK(testbus_same_f32(OD_DRIVE.mfr.x2100_Measurement.i_a_A, 2.25f), "a short frame was stored");
    start(&od_drive, 0x20);
    CHECK(sdo_w(0x2105, 1, 2, 1) == 0, "drive: CAN FD refused");
    CHECK(map_pdo(0x1400, 0x1600, 0x190, MEAS14, 5, 254) == 0, "drive: 14-byte RPDO1 refused");
    co_nmt_command(&g_tb.node, CO_NMT_CS_START);
    CHECK(rpdo_gets(20, 4.0f) == 0x8220, "a 20-byte frame: no EMCY 0x8220");
}

/* The classic-only build: CAN FD refused, a 14-byte mapping refused, an 8-byte TPDO a classic frame. */
static void classic_only(void)
{
    start(&od_plant, 0x10);
    CHECK(sdo_w(0x2105, 1, 1, 1) == CO_ABORT_VALUE_HIGH, "classic build: CAN FD accepted");
    CHECK(sdo_w(0x2105, 1, 2, 1) == CO_ABORT_VALUE_HIGH, "classic build: CAN FD with BRS accepted");
    CHECK(map_pdo(0x1800, 0x1A00, 0x190, MEAS14, 5, 254) == CO_ABORT_MAP_LEN, "classic build: 14 bytes accepted");
    CHECK(map_pdo(0x1800, 0x1A00, 0x190, MEAS14, 2, 254) == 0, "classic build: 8 bytes refused");
    co_nmt_command(&g_tb.node, CO_NMT_CS_START);
    testbus_clear(&g_tb);
    co_tpdo_request(&g_tb.node, 0);
    testbus_step(&g_tb);
    const co_frame_t *f = testbus_find(&g_tb, 0x190, 0);
    CHECK(f != NULL && f->dlc == 8 && f->flags == 0, "classic build: TPDO1 not a classic 8-byte frame");
}

int main(void)
{
    if (CO_FRAME_MAX_DATA <= 8u) {
        classic_only();
    } else {
        tpdo_frames();
        rpdo_frames();
    }
    return check_exit_code();
}
