/* shim_testbus.h - the in-process bus the drive-shim tests drive: one drive node (drive_app on
 * co_membus), every frame the drive sends captured in g_cap, little-endian float helpers. */
#ifndef SHIM_TESTBUS_H
#define SHIM_TESTBUS_H

#include <stdint.h>
#include <string.h>

#include "co_membus.h"
#include "co_node.h"
#include "drive_app.h"

#define CAP_MAX 64
static co_frame_t g_cap[CAP_MAX];
static int g_ncap;
static co_membus_t g_bus;
static co_node_t g_node;
static drive_app_t g_app;
static int64_t g_now;

/* Membus sink: keep the drive's frames (not those injected by the test). */
static inline void sink(void *user, const co_frame_t *f, uint8_t sender, int64_t now_us)
{
    (void)user;
    (void)now_us;
    if (sender == CO_MEMBUS_EXTERNAL) return;
    if (g_ncap < CAP_MAX) g_cap[g_ncap++] = *f;
}

static inline void put_f32(uint8_t *p, float v)
{
    uint32_t u;
    memcpy(&u, &v, 4);
    p[0] = (uint8_t)u; p[1] = (uint8_t)(u >> 8); p[2] = (uint8_t)(u >> 16); p[3] = (uint8_t)(u >> 24);
}

static inline float get_f32(const uint8_t *p)
{
    uint32_t u = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
    float v;
    memcpy(&v, &u, 4);
    return v;
}

static inline int same_bits(float a, float b) { return memcmp(&a, &b, sizeof a) == 0; }

#endif /* SHIM_TESTBUS_H */
