/* test_co_bindings.c - objects bound to their owners (co_od_ext_t, co_node_bind) and the PDO path resolved once.
 *
 * Over real frames (in-process co_membus), on the drive's generated OD with a small app of its own:
 *   - an SDO upload calls the object's read first (the uploaded value is what read wrote), a download its check
 *     (a veto is the SDO abort, nothing stored, written not called), then the store, then written (which sees the
 *     new value); an object nobody bound is plain storage;
 *   - a TPDO calls the read of the bound objects it maps, once per object however many of its entries it maps,
 *     also for a binding made after the PDO was configured; its frame holds the values read wrote;
 *   - the frame is packed and unpacked the same whether the mapped entries lie one after the other in RAM (one
 *     copy) or not (field by field): the same values in both orders of the References' two entries, RPDO and TPDO;
 *   - binding an index the OD does not have, or more objects than the table holds, is refused. */
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "co_node.h"
#include "od_drive.h"
#include "testbus.h"

#define ID 0x20u
#define SYNC_COB 0x080u
#define TPDO3_COB (0x380u + ID)
#define RPDO3_COB 0x420u

typedef struct {
    co_node_t *node;
    co_od_ext_t status, refs;
    int reads, checks, writes;
    uint16_t last_read_index;
    float written_value; /* 0x2202:02 as written saw it */
} app_t;

static testbus_t g_tb;
static app_t g_app;

static od_drive_mfr_t *mfr(void) { return &((od_drive_ram_t *)g_tb.node.od->ram)->mfr; }

/* 0x2204 is read: its counters from the app (here: how many reads there were). */
static void status_read(void *object, const co_od_entry_t *e)
{
    app_t *a = (app_t *)object;
    ++a->reads;
    a->last_read_index = e->index;
    mfr()->x2204_drive_status.current_steps = 1000u + (uint32_t)a->reads;
    mfr()->x2204_drive_status.id_A = 0.25f * (float)a->reads;
}

/* 0x2202: 2.5 A is refused (PARAM_INCOMPAT), anything else accepted; written sees the stored value. */
static uint32_t refs_check(void *object, const co_od_entry_t *e, const uint8_t *data, uint32_t len)
{
    app_t *a = (app_t *)object;
    ++a->checks;
    if (e->subindex == 2u && len == 4u && testbus_same_f32(testbus_get_f32(data), 2.5f)) return CO_ABORT_PARAM_INCOMPAT;
    return 0;
}

static void refs_written(void *object, const co_od_entry_t *e)
{
    app_t *a = (app_t *)object;
    ++a->writes;
    if (e->subindex == 2u) a->written_value = mfr()->x2202_References.iq_ref_A;
}

static void bind(void *user, co_node_t *node)
{
    app_t *a = (app_t *)user;
    a->node = node;
    a->status = (co_od_ext_t){a, status_read, NULL, NULL};
    a->refs = (co_od_ext_t){a, NULL, refs_check, refs_written};
    CHECK(co_node_bind(node, 0x2202u, &a->refs) == 0, "bind 0x2202");
}

static const co_hooks_t k_hooks = {.bind = bind};

static uint32_t sdo_w(uint16_t index, uint8_t sub, uint32_t v, uint8_t len)
{
    const uint8_t b[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    testbus_clear(&g_tb);
    return testbus_sdo_download(&g_tb, index, sub, b, len);
}

static uint32_t sdo_w_f32(uint16_t index, uint8_t sub, float v)
{
    uint8_t b[4];
    testbus_put_f32(b, v);
    testbus_clear(&g_tb);
    return testbus_sdo_download(&g_tb, index, sub, b, 4);
}

/* TPDO3 (synchronous, every SYNC) mapping these entries. */
static void map_tpdo3(const uint32_t *entries, uint8_t n)
{
    CHECK(sdo_w(0x1802, 1, 0x80000000u | TPDO3_COB, 4) == 0, "TPDO3 invalid");
    CHECK(sdo_w(0x1A02, 0, 0, 1) == 0, "TPDO3 count 0");
    for (uint8_t i = 0; i < n; ++i) CHECK(sdo_w(0x1A02, (uint8_t)(i + 1u), entries[i], 4) == 0, "TPDO3 entry %u", i);
    CHECK(sdo_w(0x1A02, 0, n, 1) == 0, "TPDO3 count %u", n);
    CHECK(sdo_w(0x1802, 2, 1, 1) == 0, "TPDO3 synchronous");
    CHECK(sdo_w(0x1802, 1, TPDO3_COB, 4) == 0, "TPDO3 valid");
}

static void map_rpdo3(const uint32_t *entries, uint8_t n)
{
    CHECK(sdo_w(0x1402, 1, 0x80000000u | RPDO3_COB, 4) == 0, "RPDO3 invalid");
    CHECK(sdo_w(0x1602, 0, 0, 1) == 0, "RPDO3 count 0");
    for (uint8_t i = 0; i < n; ++i) CHECK(sdo_w(0x1602, (uint8_t)(i + 1u), entries[i], 4) == 0, "RPDO3 entry %u", i);
    CHECK(sdo_w(0x1602, 0, n, 1) == 0, "RPDO3 count %u", n);
    CHECK(sdo_w(0x1402, 1, RPDO3_COB, 4) == 0, "RPDO3 valid");
}

/* A SYNC with its counter (0x1019 = 240 in drive.eds). */
static const co_frame_t *sync_and_take_tpdo3(void)
{
    static uint8_t counter = 0;
    counter = (uint8_t)(counter % 240u + 1u);
    testbus_clear(&g_tb);
    testbus_send(&g_tb, SYNC_COB, 1, &counter);
    return testbus_find(&g_tb, TPDO3_COB, 0);
}

static void test_sdo(void)
{
    uint8_t buf[8];
    uint32_t len = 0, segs = 0;
    /* read before an upload, once; not bound yet: plain storage */
    CHECK(testbus_sdo_upload(&g_tb, 0x2204, 1, buf, sizeof buf, &len, &segs) == 0 && g_app.reads == 0,
          "an unbound object is read without a handler");
    CHECK(co_node_bind(&g_tb.node, 0x2204u, &g_app.status) == 0, "bind 0x2204 after init");
    CHECK(testbus_sdo_upload(&g_tb, 0x2204, 1, buf, sizeof buf, &len, &segs) == 0, "upload 0x2204:01");
    CHECK(g_app.reads == 1 && g_app.last_read_index == 0x2204u, "read called once before the upload (%d)", g_app.reads);
    CHECK(len == 4u && testbus_get_u32(buf) == 1001u, "the upload holds what read wrote (%u)",
          (unsigned)testbus_get_u32(buf));
    /* check vetoes: the abort, nothing stored, written not called */
    const float before = mfr()->x2202_References.iq_ref_A;
    CHECK(sdo_w_f32(0x2202, 2, 2.5f) == CO_ABORT_PARAM_INCOMPAT, "check's veto is the abort");
    CHECK(g_app.checks == 1 && g_app.writes == 0 && testbus_same_f32(mfr()->x2202_References.iq_ref_A, before),
          "vetoed: not stored, written not called");
    CHECK(sdo_w_f32(0x2202, 2, 1.5f) == 0, "accepted");
    CHECK(g_app.checks == 2 && g_app.writes == 1 && testbus_same_f32(g_app.written_value, 1.5f),
          "written after the store, once (%d), sees the new value", g_app.writes);
    /* the generic checks come first: a write beyond the EDS's own limits never reaches check */
    CHECK(sdo_w(0x2202, 2, 0u, 2) == CO_ABORT_TOO_SHORT && g_app.checks == 2, "a too-short write stops at the node");
}

static void test_tpdo_reads_once_per_object(void)
{
    co_nmt_command(&g_tb.node, CO_NMT_CS_PREOP);
    /* 0x2204:01 (u32), 0x2204:04 (f32) of one object, then 0x2202:02 (f32, not read-bound) */
    const uint32_t entries[] = {0x22040120u, 0x22040420u};
    map_tpdo3(entries, 2);
    co_nmt_command(&g_tb.node, CO_NMT_CS_START);
    const int r0 = g_app.reads;
    const co_frame_t *f = sync_and_take_tpdo3();
    CHECK(f != NULL && f->dlc == 8u, "TPDO3 at the SYNC");
    CHECK(g_app.reads == r0 + 1, "read once for two entries of one object (%d)", g_app.reads - r0);
    if (f != NULL) {
        CHECK(testbus_get_u32(&f->data[0]) == 1000u + (uint32_t)g_app.reads, "the frame holds read's count");
        CHECK(testbus_same_f32(testbus_get_f32(&f->data[4]), 0.25f * (float)g_app.reads),
              "the frame holds read's id_A");
    }
}

/* The References' iq_ref_A, id_ref_A lie one after the other: the frame is one copy in that order, field by field
 * in the other; the same values either way. */
static void test_pack_unpack_both_orders(void)
{
    const uint32_t in_order[] = {0x22020220u, 0x22020320u}, reversed[] = {0x22020320u, 0x22020220u};
    const uint32_t *maps[] = {in_order, reversed};
    for (int k = 0; k < 2; ++k) {
        co_nmt_command(&g_tb.node, CO_NMT_CS_PREOP);
        map_rpdo3(maps[k], 2);
        map_tpdo3(maps[k], 2);
        co_nmt_command(&g_tb.node, CO_NMT_CS_START);
        CHECK((g_tb.node.rpdo[2].block != NULL) == (k == 0), "RPDO3 one copy exactly in RAM order (order %d)", k);
        CHECK((g_tb.node.tpdo[2].block != NULL) == (k == 0), "TPDO3 one copy exactly in RAM order (order %d)", k);
        uint8_t d[8];
        testbus_put_f32(&d[0], 3.25f + (float)k);
        testbus_put_f32(&d[4], -0.5f - (float)k);
        testbus_send(&g_tb, RPDO3_COB, 8, d);
        const float first = k == 0 ? mfr()->x2202_References.iq_ref_A : mfr()->x2202_References.id_ref_A;
        const float second = k == 0 ? mfr()->x2202_References.id_ref_A : mfr()->x2202_References.iq_ref_A;
        CHECK(testbus_same_f32(first, 3.25f + (float)k) && testbus_same_f32(second, -0.5f - (float)k),
              "RPDO3 unpacked (order %d)", k);
        const co_frame_t *f = sync_and_take_tpdo3();
        CHECK(f != NULL && memcmp(f->data, d, 8) == 0, "TPDO3 packs back the same bytes (order %d)", k);
    }
}

static void test_bind_refusals(void)
{
    static co_od_ext_t spare;
    CHECK(co_node_bind(&g_tb.node, 0x2FFFu, &spare) == -1, "no such object: refused");
    int ok = 0;
    for (uint16_t i = 0; i < g_tb.node.od->count; ++i) {
        const uint16_t index = g_tb.node.od->entries[i].index;
        if (co_node_ext(&g_tb.node, index) == NULL && co_node_bind(&g_tb.node, index, &spare) == 0) ++ok;
    }
    CHECK(g_tb.node.bindings.n == CO_NODE_BINDINGS, "the table fills up (%u)", (unsigned)g_tb.node.bindings.n);
    CHECK(co_node_ext(&g_tb.node, 0x2202u) == &g_app.refs, "an earlier binding stays");
    printf("bindings: %d more objects bound until the table of %u was full\n", ok, (unsigned)CO_NODE_BINDINGS);
}

int main(void)
{
    memset(&g_app, 0, sizeof g_app);
    testbus_init(&g_tb, &od_drive, ID, &k_hooks, &g_app, 1000, 100);
    testbus_deliver(&g_tb);
    CHECK(g_app.node == &g_tb.node && co_node_ext(&g_tb.node, 0x2202u) == &g_app.refs, "bound by the bind hook");
    test_sdo();
    test_tpdo_reads_once_per_object();
    test_pack_unpack_both_orders();
    test_bind_refusals();
    return check_finish("test_co_bindings");
}
