/* testbus.h - the in-process CAN bus of the node tests (header only).
 *
 * One CANopen node (co_node, with or without an app's hooks) on a co_membus; the test is every
 * other station (master, drive or plant): it injects frames, lets the bus deliver them, and
 * reads what the node sent.  Used by the plant node tests (plant_rt/tests/plant_testbus.h adds
 * the plant app), the drive node tests (firmware_shim/tests/shim_testbus.h adds the drive app)
 * and the CANopen slave tests (protocols/tests).
 *
 *   recorder   every frame on the bus (the node's and the injected ones, with sender and time)
 *              since testbus_init / testbus_clear, up to TESTBUS_MAX_REC (later ones are
 *              counted in n_lost); testbus_find() looks among the node's frames
 *   time       now_us is the bus time; testbus_step() advances it by step_us and delivers;
 *              testbus_send() = inject + step (one exchange with the node)
 *   SDO client expedited or segmented download and upload by real frames, to the node's
 *              default SDO (0x600 + id / 0x580 + id)
 *   bytes      little-endian REAL32 / UNSIGNED32 of the PDO and SDO payloads
 */
#ifndef TESTS_C_TESTBUS_H
#define TESTS_C_TESTBUS_H

#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "co_membus.h"
#include "co_node.h"

#define TESTBUS_MAX_REC 16384u

typedef struct {
    co_frame_t f;
    uint8_t sender; /* CO_MEMBUS_EXTERNAL: injected by the test */
    int64_t t_us;
} testbus_rec_t;

/* Called for every frame on the bus, after it is recorded. */
typedef void (*testbus_frame_fn)(void *user, const co_frame_t *f, uint8_t sender, int64_t now_us);

typedef struct {
    co_membus_t bus;
    co_node_t node;
    int port;
    uint8_t node_id;
    int64_t now_us;
    int64_t step_us; /* time of one exchange (testbus_step, testbus_send) */
    testbus_rec_t rec[TESTBUS_MAX_REC];
    uint32_t n_rec;
    uint32_t n_lost;
    bool sdo_got; /* an SDO response of the node arrived (reset by the SDO client) */
    uint8_t sdo_resp[8];
    testbus_frame_fn on_frame;
    void *on_frame_user;
} testbus_t;

/* ------------------------------------------------------------------ bytes */
static inline void testbus_put_f32(uint8_t *p, float v)
{
    uint32_t u;
    memcpy(&u, &v, 4);
    p[0] = (uint8_t)u;
    p[1] = (uint8_t)(u >> 8);
    p[2] = (uint8_t)(u >> 16);
    p[3] = (uint8_t)(u >> 24);
}

static inline uint32_t testbus_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static inline float testbus_get_f32(const uint8_t *p)
{
    const uint32_t u = testbus_get_u32(p);
    float v;
    memcpy(&v, &u, 4);
    return v;
}

static inline bool testbus_same_f32(float a, float b) { return memcmp(&a, &b, sizeof a) == 0; }

/* ------------------------------------------------------------------ bus */
static inline void testbus_sink(void *user, const co_frame_t *f, uint8_t sender, int64_t now_us)
{
    testbus_t *tb = (testbus_t *)user;
    if (tb->n_rec < TESTBUS_MAX_REC) {
        tb->rec[tb->n_rec].f = *f;
        tb->rec[tb->n_rec].sender = sender;
        tb->rec[tb->n_rec].t_us = now_us;
        ++tb->n_rec;
    } else {
        ++tb->n_lost;
    }
    if (sender != CO_MEMBUS_EXTERNAL && (f->cob_id & 0x7FFu) == 0x580u + tb->node_id) {
        tb->sdo_got = true;
        memcpy(tb->sdo_resp, f->data, 8);
    }
    if (tb->on_frame) tb->on_frame(tb->on_frame_user, f, sender, now_us);
}

/* The node on a fresh bus at now_us (not delivered yet: bind the app, then testbus_deliver or
 * testbus_step sends the boot-up).  hooks/app may be NULL (the bare slave). */
static inline void testbus_init(testbus_t *tb, const co_od_t *od, uint8_t node_id, const co_hooks_t *hooks, void *app,
                                int64_t now_us, int64_t step_us)
{
    memset(tb, 0, sizeof *tb);
    tb->node_id = node_id;
    tb->now_us = now_us;
    tb->step_us = step_us;
    co_membus_init(&tb->bus, testbus_sink, tb);
    tb->port = co_membus_port(&tb->bus);
    co_node_init(&tb->node, od, node_id, co_membus_tx, &tb->bus.ports[tb->port], hooks, app, now_us);
    co_membus_attach(&tb->bus, tb->port, &tb->node);
}

/* Forget the recorded frames. */
static inline void testbus_clear(testbus_t *tb) { tb->n_rec = 0; }

/* Queue a frame from the test (delivered by the next testbus_deliver); returns co_membus_inject's result. */
static inline int testbus_inject(testbus_t *tb, uint32_t cob_id, uint8_t dlc, const uint8_t *data)
{
    co_frame_t f;
    memset(&f, 0, sizeof f);
    f.cob_id = cob_id;
    f.dlc = dlc;
    if (dlc) memcpy(f.data, data, dlc);
    return co_membus_inject(&tb->bus, &f);
}

/* Deliver everything queued (and what it causes) at now_us. */
static inline uint32_t testbus_deliver(testbus_t *tb) { return co_membus_deliver(&tb->bus, tb->now_us); }

/* Advance the time by step_us and deliver. */
static inline uint32_t testbus_step(testbus_t *tb)
{
    tb->now_us += tb->step_us;
    return testbus_deliver(tb);
}

/* One exchange: inject and step. */
static inline int testbus_send(testbus_t *tb, uint32_t cob_id, uint8_t dlc, const uint8_t *data)
{
    const int r = testbus_inject(tb, cob_id, dlc, data);
    testbus_step(tb);
    return r;
}

/* The nth (0 = first) recorded frame of the node with this 11-bit identifier, or NULL. */
static inline const co_frame_t *testbus_find(const testbus_t *tb, uint32_t cob_id, int nth)
{
    for (uint32_t i = 0; i < tb->n_rec; ++i)
        if (tb->rec[i].sender != CO_MEMBUS_EXTERNAL && (tb->rec[i].f.cob_id & 0x7FFu) == cob_id && nth-- == 0)
            return &tb->rec[i].f;
    return NULL;
}

/* The nth (0 = first) recorded frame of the node, or NULL. */
static inline const co_frame_t *testbus_node_frame(const testbus_t *tb, uint32_t nth)
{
    for (uint32_t i = 0; i < tb->n_rec; ++i)
        if (tb->rec[i].sender != CO_MEMBUS_EXTERNAL && nth-- == 0) return &tb->rec[i].f;
    return NULL;
}

/* Number of recorded frames sent by the node. */
static inline uint32_t testbus_node_frames(const testbus_t *tb)
{
    uint32_t n = 0;
    for (uint32_t i = 0; i < tb->n_rec; ++i) n += tb->rec[i].sender != CO_MEMBUS_EXTERNAL;
    return n;
}

/* ------------------------------------------------------------------ SDO client */
#define TESTBUS_SDO_NO_ANSWER 0xFFFFFFFFu
#define TESTBUS_SDO_UNEXPECTED 0xFFFFFFFEu

/* One SDO request; the node's answer in tb->sdo_resp.  Returns 0, the abort code,
 * TESTBUS_SDO_NO_ANSWER or, if the answer's command byte masked by mask is not want,
 * TESTBUS_SDO_UNEXPECTED. */
static inline uint32_t testbus_sdo_request(testbus_t *tb, const uint8_t req[8], uint8_t mask, uint8_t want)
{
    tb->sdo_got = false;
    testbus_send(tb, 0x600u + tb->node_id, 8, req);
    if (!tb->sdo_got) return TESTBUS_SDO_NO_ANSWER;
    if (tb->sdo_resp[0] == 0x80u) return testbus_get_u32(&tb->sdo_resp[4]);
    return (tb->sdo_resp[0] & mask) == want ? 0u : TESTBUS_SDO_UNEXPECTED;
}

/* SDO download of len bytes: expedited up to 4, else segmented. */
static inline uint32_t testbus_sdo_download(testbus_t *tb, uint16_t index, uint8_t sub, const void *data, uint32_t len)
{
    const uint8_t *p = (const uint8_t *)data;
    uint8_t d[8] = {0, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
    if (len <= 4u) {
        d[0] = (uint8_t)(0x23u | ((4u - len) << 2));
        memcpy(&d[4], p, len);
        return testbus_sdo_request(tb, d, 0xFFu, 0x60u);
    }
    d[0] = 0x21u;
    d[4] = (uint8_t)len;
    d[5] = (uint8_t)(len >> 8);
    d[6] = (uint8_t)(len >> 16);
    d[7] = (uint8_t)(len >> 24);
    uint32_t a = testbus_sdo_request(tb, d, 0xFFu, 0x60u);
    uint8_t toggle = 0;
    for (uint32_t off = 0; a == 0u && off < len;) {
        const uint32_t n = len - off > 7u ? 7u : len - off;
        uint8_t s[8] = {0};
        const bool last = off + n >= len;
        s[0] = (uint8_t)((toggle << 4) | ((7u - n) << 1) | (last ? 1u : 0u));
        memcpy(&s[1], p + off, n);
        a = testbus_sdo_request(tb, s, 0xFFu, (uint8_t)(0x20u | (toggle << 4)));
        off += n;
        toggle ^= 1u;
    }
    return a;
}

/* SDO upload into buf (cap bytes): *len the bytes received, *segments the segments (0 for an
 * expedited answer, whose 4 data bytes are copied as sent when cap >= 4). */
static inline uint32_t testbus_sdo_upload(testbus_t *tb, uint16_t index, uint8_t sub, uint8_t *buf, uint32_t cap,
                                          uint32_t *len, uint32_t *segments)
{
    const uint8_t d[8] = {0x40, (uint8_t)index, (uint8_t)(index >> 8), sub, 0, 0, 0, 0};
    *len = 0;
    *segments = 0;
    uint32_t a = testbus_sdo_request(tb, d, 0xE0u, 0x40u);
    if (a) return a;
    const uint8_t cs = tb->sdo_resp[0];
    if (cs & 0x02u) { /* expedited */
        if ((cs & 0x01u) == 0u) return TESTBUS_SDO_UNEXPECTED;
        if (cap < 4u) return TESTBUS_SDO_UNEXPECTED;
        memcpy(buf, &tb->sdo_resp[4], 4);
        *len = 4u - ((cs >> 2) & 3u);
        return 0;
    }
    if (cs != 0x41u) return TESTBUS_SDO_UNEXPECTED;
    const uint32_t size = testbus_get_u32(&tb->sdo_resp[4]);
    uint8_t toggle = 0;
    for (;;) {
        const uint8_t q[8] = {(uint8_t)(0x60u | (toggle << 4)), 0, 0, 0, 0, 0, 0, 0};
        a = testbus_sdo_request(tb, q, 0xF0u, (uint8_t)(toggle << 4));
        if (a) return a;
        const uint32_t n = 7u - ((tb->sdo_resp[0] >> 1) & 7u);
        if (*len + n > cap) return TESTBUS_SDO_UNEXPECTED;
        memcpy(buf + *len, &tb->sdo_resp[1], n);
        *len += n;
        ++*segments;
        toggle ^= 1u;
        if (tb->sdo_resp[0] & 1u) break;
    }
    return *len == size ? 0u : TESTBUS_SDO_UNEXPECTED;
}

#endif /* TESTS_C_TESTBUS_H */
