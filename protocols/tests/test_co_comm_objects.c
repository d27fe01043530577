/* test_co_comm_objects.c - CiA 301 rules of the EMCY COB-ID (0x1014) and of the TPDO SYNC
 * start value (0x18xx:06) on the bare C slave (drive OD), frame by frame on the test bus.
 *
 *   (a) 0x1014: while valid (bit 31 = 0) its CAN-ID may not change (abort 0x06090030), the
 *       same value and the valid bit may; invalid, a new CAN-ID is taken and the EMCY goes
 *       out on it once valid again
 *   (b) 0x18xx:06: written only while the TPDO is not valid (0x06090030), at most 240
 *   (c) start value S with transmission type n and a SYNC counter: the first TPDO at the
 *       SYNC whose counter is S, then S + n, S + 2n, ... (CANopenNode's CO_TPDO_process);
 *       after NMT pre-operational -> operational it waits for S again
 *   (d) start value without a SYNC counter (0x1019 = 0): ignored, every n-th SYNC
 *   (e) a stall of the node's own (co_node_excuse_us: its loop woke that much late) is not a
 *       producer's silence; a silence without it is (EMCY 0x8130)
 * The expected SYNC counters are derived from S and n, never copied from the node. */
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "co_node.h"
#include "od_drive.h"
#include "testbus.h"

#define ID 0x20u
#define COB_TPDO1 (0x180u + ID) /* the drive's TPDO1 is 0x210; a free identifier for this test */
#define COB_EMCY (0x80u + ID)

static testbus_t g_tb;

static void start(void)
{
    testbus_init(&g_tb, &od_drive, ID, NULL, NULL, 1000, 100);
    testbus_deliver(&g_tb);
    testbus_clear(&g_tb); /* the boot-up */
}

/* Expedited SDO download of len bytes of v; returns the abort code or 0. */
static uint32_t sdo_w(uint16_t index, uint8_t sub, uint32_t v, uint8_t len)
{
    const uint8_t b[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    testbus_clear(&g_tb);
    return testbus_sdo_download(&g_tb, index, sub, b, len);
}

static void nmt(uint8_t cs)
{
    const uint8_t d[2] = {cs, 0};
    testbus_send(&g_tb, 0x000u, 2, d);
}

/* One SYNC (counter c, or none when c == 0); returns 1 if the node sent cob in answer. */
static int sync_sends(uint8_t c, uint32_t cob)
{
    testbus_clear(&g_tb);
    testbus_send(&g_tb, 0x080u, c ? 1u : 0u, &c);
    return testbus_find(&g_tb, cob, 0) != NULL;
}

/* ------------------------------------------------------------------ (a) */
static void test_emcy_cob_id(void)
{
    start();
    const uint32_t dflt = 0x80u + ID;
    CHECK(sdo_w(0x1014, 0, 0x81u, 4) == CO_ABORT_INVALID_VALUE, "0x1014: CAN-ID changed while valid");
    CHECK(sdo_w(0x1014, 0, dflt, 4) == 0, "0x1014: the same value refused");
    CHECK(sdo_w(0x1014, 0, 0x80000000u | dflt, 4) == 0, "0x1014: invalidating refused");
    CHECK(sdo_w(0x1014, 0, 0x80000081u, 4) == 0, "0x1014: new CAN-ID while invalid refused");
    CHECK(sdo_w(0x1014, 0, 0x81u, 4) == 0, "0x1014: valid again with its new CAN-ID refused");
    CHECK(sdo_w(0x1014, 0, dflt, 4) == CO_ABORT_INVALID_VALUE, "0x1014: back to the default while valid");
    CHECK(sdo_w(0x1014, 0, 0x01u, 4) == CO_ABORT_INVALID_VALUE, "0x1014: restricted CAN-ID");
    /* the EMCY goes out on the new identifier: a SYNC of the wrong length (0x1019 = 240: 1 byte) */
    testbus_clear(&g_tb);
    testbus_send(&g_tb, 0x080u, 0u, NULL);
    const co_frame_t *e = testbus_find(&g_tb, 0x81u, 0);
    CHECK(e != NULL && e->data[0] == 0x40u && e->data[1] == 0x82u, "EMCY 0x8240 not on 0x81");
    CHECK(testbus_find(&g_tb, COB_EMCY, 0) == NULL, "EMCY still on the old identifier");
    printf("(a) 0x1014: CAN-ID refused while valid (0x06090030), same value and valid bit accepted; EMCY on the "
           "new CAN-ID 0x81\n");
}

/* TPDO1 -> COB_TPDO1, transmission type n, start value s (through the invalid state). */
static void tpdo1_sync(uint8_t n, uint8_t s)
{
    CHECK(sdo_w(0x1800, 1, 0x80000000u | COB_TPDO1, 4) == 0, "TPDO1 invalid");
    CHECK(sdo_w(0x1800, 2, n, 1) == 0, "TPDO1 type %u", n);
    CHECK(sdo_w(0x1800, 6, s, 1) == 0, "TPDO1 start value %u while invalid refused", s);
    CHECK(sdo_w(0x1800, 1, COB_TPDO1, 4) == 0, "TPDO1 valid");
}

/* ------------------------------------------------------------------ (b) */
static void test_start_value_writes(void)
{
    start();
    CHECK(sdo_w(0x1800, 6, 5u, 1) == CO_ABORT_INVALID_VALUE, "start value written while the TPDO is valid");
    CHECK(sdo_w(0x1800, 6, 0u, 1) == CO_ABORT_INVALID_VALUE, "start value (same) written while valid");
    CHECK(sdo_w(0x1800, 1, 0xC0000210u, 4) == 0, "TPDO1 invalid");
    CHECK(sdo_w(0x1800, 6, 241u, 1) != 0u, "start value 241 accepted");
    CHECK(sdo_w(0x1800, 6, 240u, 1) == 0, "start value 240 refused while invalid");
    printf("(b) 0x1800:06: refused while valid (0x06090030) and above 240, accepted while invalid\n");
}

/* ------------------------------------------------------------------ (c), (d) */
/* SYNCs with counters from first on (wrapping at ov, 0 = no counter); the counters at which the TPDO
 * went out into sent[], their number returned. */
static int run_syncs(uint8_t first, uint8_t ov, int count, uint8_t *sent, int cap)
{
    int n = 0;
    uint8_t c = first;
    for (int i = 0; i < count; ++i) {
        if (sync_sends(ov ? c : 0u, COB_TPDO1) && n < cap) sent[n++] = ov ? c : (uint8_t)(i + 1);
        c = (uint8_t)(c >= ov ? 1u : c + 1u);
    }
    return n;
}

static void test_start_value(void)
{
    const uint8_t S = 5u, N = 2u, OV = 10u;
    start();
    CHECK(sdo_w(0x1019, 0, OV, 1) == 0, "0x1019 = %u", OV);
    tpdo1_sync(N, S);
    nmt(0x01);
    uint8_t sent[16];
    int n = run_syncs(1u, OV, 14, sent, 16); /* counters 1..10, 1..4 */
    /* expected: S, S + N, ... wrapping modulo OV (1..OV) */
    int ok = n == 5;
    for (int i = 0; i < n && i < 5; ++i) ok &= sent[i] == (uint8_t)((S - 1u + (unsigned)i * N) % OV + 1u);
    CHECK(ok, "start value %u, type %u: %d TPDOs, first at SYNC counter %u (CANopenNode: %u)", S, N, n,
          n ? sent[0] : 0u, S);
    printf("(c) start value %u, type %u: TPDOs at SYNC counters", S, N);
    for (int i = 0; i < n; ++i) printf(" %u", sent[i]);
    printf("\n");
    /* pre-operational, operational again: waits for S again (a SYNC at S - 1 sends nothing) */
    nmt(0x80);
    nmt(0x01);
    n = run_syncs((uint8_t)(S - 2u), OV, 3, sent, 16); /* S - 2, S - 1, S */
    CHECK(n == 1 && sent[0] == S, "after NMT start: %d TPDOs, first at %u", n, n ? sent[0] : 0u);

    /* (d) no SYNC counter: the start value is ignored */
    start();
    CHECK(sdo_w(0x1019, 0, 0u, 1) == 0, "0x1019 = 0");
    tpdo1_sync(N, S);
    nmt(0x01);
    n = run_syncs(1u, 0u, 8, sent, 16);
    ok = n == 4;
    for (int i = 0; i < n && i < 4; ++i) ok &= sent[i] == (uint8_t)((i + 1) * N);
    CHECK(ok, "no SYNC counter, start value %u, type %u: %d TPDOs (every %u-th SYNC expected)", S, N, n, N);
    printf("(d) no SYNC counter: start value ignored, %d TPDOs in 8 SYNCs\n", n);
}

/* ------------------------------------------------------------------ (e) */
static int emcy_8130(void)
{
    const co_frame_t *f = testbus_find(&g_tb, COB_EMCY, 0);
    return f && f->data[0] == 0x30u && f->data[1] == 0x81u;
}

static void test_stall_excused(void)
{
    start();
    CHECK(sdo_w(0x1016, 1, (0x10u << 16) | 100u, 4) == 0, "consumer of node 0x10, 100 ms");
    nmt(0x01);
    const uint8_t op = 0x05;
    testbus_send(&g_tb, 0x710u, 1, &op); /* monitoring starts at the first heartbeat */
    testbus_clear(&g_tb);
    g_tb.now_us += 300000; /* 300 ms without running: the node's own stall */
    co_node_excuse_us(&g_tb.node, 295000);
    co_node_tick(&g_tb.node, g_tb.now_us);
    testbus_deliver(&g_tb);
    CHECK(!emcy_8130(), "a 300 ms stall of the node's own, excused: no heartbeat EMCY");
    testbus_send(&g_tb, 0x710u, 1, &op);
    testbus_clear(&g_tb);
    g_tb.now_us += 300000; /* 300 ms of the producer's silence, the node running */
    co_node_tick(&g_tb.node, g_tb.now_us);
    testbus_deliver(&g_tb);
    CHECK(emcy_8130(), "300 ms of silence with the node running: EMCY 0x8130");
    printf("(e) a stall of the node's own is not the producer's silence\n");
}

int main(void)
{
    test_stall_excused();
    test_emcy_cob_id();
    test_start_value_writes();
    test_start_value();
    return check_finish("test_co_comm_objects");
}
