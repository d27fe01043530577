/* test_co_pdo_mapping.c - the C slave honours the EDS PDOMapping flag.
 *
 * Over real SDO frames (in-process co_membus), for every readable entry
 * 0x2000-0x2FFF of both generated object dictionaries: writing it into a TPDO
 * mapping is accepted exactly when the EDS marks it PDOMapping=1 (CO_ODF_PDO)
 * and refused with 0x06040041 otherwise.  Then the Zhao 2022 (0x2502) values
 * and the Drive status counters, mappable since they are per-period values,
 * go into the drive's TPDO3 (synchronous): each SYNC sends the values of the
 * moment, so a value that changes per period is traced per period.  Read-only
 * entries stay refused in an RPDO. */
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "co_node.h"
#include "od_drive.h"
#include "od_plant.h"
#include "testbus.h"

static testbus_t g_tb;

/* The bare slave (no app) of od at node-ID id; the bus time goes on from node to node. */
static void start(const co_od_t *od, uint8_t id)
{
    const int64_t now_us = g_tb.node_id ? g_tb.now_us : 1000;
    testbus_init(&g_tb, od, id, NULL, NULL, now_us, 100);
    testbus_deliver(&g_tb);
    testbus_clear(&g_tb); /* the boot-up */
}

/* One frame to the node; the recorder then holds it and the node's answers. */
static void inject(uint32_t cob, const uint8_t *d, uint8_t dlc)
{
    testbus_clear(&g_tb);
    testbus_send(&g_tb, cob, dlc, d);
}

/* Expedited SDO download of an UNSIGNED32/8; returns the abort code or 0. */
static uint32_t sdo_w(uint16_t index, uint8_t sub, uint32_t v, uint8_t len)
{
    const uint8_t b[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    testbus_clear(&g_tb);
    return testbus_sdo_download(&g_tb, index, sub, b, len);
}

static uint32_t map_entry(const co_od_entry_t *e)
{
    uint32_t bits = co_dt_size(e->datatype) * 8u;
    if (bits == 0u) bits = 8u; /* strings/domains: any length is refused */
    return (uint32_t)e->index << 16 | (uint32_t)e->subindex << 8 | bits;
}

/* Every readable manufacturer entry into TPDO3's mapping: accepted iff CO_ODF_PDO. */
static void sweep(const char *name, const co_od_t *od, uint8_t id)
{
    start(od, id);
    CHECK(sdo_w(0x1802, 1, 0x80000000u | (0x380u + id), 4) == 0, "%s: TPDO3 invalid", name);
    CHECK(sdo_w(0x1A02, 0, 0, 1) == 0, "%s: TPDO3 count 0", name);
    int accepted = 0, refused = 0;
    for (uint16_t i = 0; i < od->count; ++i) {
        const co_od_entry_t *e = &od->entries[i];
        if (e->index < 0x2000u || e->index > 0x2FFFu || !(e->flags & CO_ODF_READ)) continue;
        if (e->subindex == 0u && co_od_find(od, e->index, 1, NULL)) continue; /* record/array count */
        uint32_t a = sdo_w(0x1A02, 1, map_entry(e), 4);
        int mappable = (e->flags & CO_ODF_PDO) && co_dt_size(e->datatype) > 0u;
        if (mappable) {
            ++accepted;
            CHECK(a == 0, "%s: 0x%04X:%02X is PDOMapping=1 but refused (0x%08X)", name, e->index, e->subindex,
                  (unsigned)a);
        } else {
            ++refused;
            CHECK(a == CO_ABORT_NO_MAP, "%s: 0x%04X:%02X is PDOMapping=0 but got 0x%08X", name, e->index, e->subindex,
                  (unsigned)a);
        }
    }
    printf("%s: %d manufacturer entries mappable (accepted), %d not (refused with 0x06040041)\n", name, accepted,
           refused);
    CHECK(accepted > 0 && refused > 0, "%s: sweep found nothing", name);
}

static float f32_of(const uint8_t *b)
{
    float f;
    memcpy(&f, b, sizeof f);
    return f;
}

static void zhao_per_period(void)
{
    start(&od_drive, 0x20);
    /* TPDO3 <- 0x2502:04 limited + 0x2502:01 K1_V_A (5 bytes); TPDO4 <- 0x2204:01 current_steps +
     * 0x2204:02 lost_measurements (8 bytes) */
    CHECK(sdo_w(0x1802, 1, 0x80000000u | 0x3A0u, 4) == 0, "TPDO3 invalid");
    CHECK(sdo_w(0x1A02, 0, 0, 1) == 0, "TPDO3 count 0");
    CHECK(sdo_w(0x1A02, 1, 0x25020408u, 4) == 0, "0x2502:04 limited refused");
    CHECK(sdo_w(0x1A02, 2, 0x25020120u, 4) == 0, "0x2502:01 K1_V_A refused");
    CHECK(sdo_w(0x1A02, 0, 2, 1) == 0, "TPDO3 count 2");
    CHECK(sdo_w(0x1802, 2, 1, 1) == 0, "TPDO3 synchronous");
    CHECK(sdo_w(0x1802, 1, 0x3A0u, 4) == 0, "TPDO3 valid");
    CHECK(sdo_w(0x1803, 1, 0x80000000u | 0x4A0u, 4) == 0, "TPDO4 invalid");
    CHECK(sdo_w(0x1A03, 0, 0, 1) == 0, "TPDO4 count 0");
    CHECK(sdo_w(0x1A03, 1, 0x22040120u, 4) == 0, "0x2204:01 current_steps refused");
    CHECK(sdo_w(0x1A03, 2, 0x22040220u, 4) == 0, "0x2204:02 lost_measurements refused");
    CHECK(sdo_w(0x1A03, 0, 2, 1) == 0, "TPDO4 count 2");
    CHECK(sdo_w(0x1803, 2, 1, 1) == 0, "TPDO4 synchronous");
    CHECK(sdo_w(0x1803, 1, 0x4A0u, 4) == 0, "TPDO4 valid");
    /* a read-only value cannot be received: RPDO3 refuses it */
    CHECK(sdo_w(0x1402, 1, 0x80000000u | 0x420u, 4) == 0, "RPDO3 invalid");
    CHECK(sdo_w(0x1602, 0, 0, 1) == 0, "RPDO3 count 0");
    CHECK(sdo_w(0x1602, 1, 0x25020120u, 4) == CO_ABORT_NO_MAP, "read-only 0x2502:01 accepted in an RPDO");

    co_nmt_command(&g_tb.node, CO_NMT_CS_START);
    const int n = 6;
    int ok = 0;
    for (int k = 0; k < n; ++k) {
        /* what the drive app writes per current step (drive_app.c refresh) */
        OD_DRIVE.mfr.x2502_zhao_2022.limited = (uint8_t)(k == 1 || k == 2);
        OD_DRIVE.mfr.x2502_zhao_2022.K1_V_A = 188.9f;
        OD_DRIVE.mfr.x2204_drive_status.current_steps = (uint32_t)k;
        const uint8_t sync[1] = {(uint8_t)(k + 1)};
        inject(0x080u, sync, 1);
        const co_frame_t *t3 = NULL, *t4 = NULL;
        for (uint32_t i = 0; i < g_tb.n_rec; ++i) {
            const testbus_rec_t *r = &g_tb.rec[i];
            if (r->sender == CO_MEMBUS_EXTERNAL) continue;
            if (r->f.cob_id == 0x3A0u) t3 = &r->f;
            if (r->f.cob_id == 0x4A0u) t4 = &r->f;
        }
        CHECK(t3 && t3->dlc == 5 && t4 && t4->dlc == 8, "SYNC %d: TPDO3/4 missing", k);
        if (!t3 || !t4) continue;
        const uint32_t steps = (uint32_t)t4->data[0] | (uint32_t)t4->data[1] << 8;
        printf("SYNC %d: TPDO3 limited %u K1 %.1f V/A, TPDO4 current_steps %u\n", k, t3->data[0],
               (double)f32_of(&t3->data[1]), (unsigned)steps);
        ok += t3->data[0] == (uint8_t)(k == 1 || k == 2) && f32_of(&t3->data[1]) == 188.9f && steps == (uint32_t)k;
    }
    CHECK(ok == n, "per-period values: %d of %d right", ok, n);
}

int main(void)
{
    sweep("drive", &od_drive, 0x20);
    sweep("plant", &od_plant, 0x10);
    zhao_per_period();
    return check_finish("test_co_pdo_mapping");
}
