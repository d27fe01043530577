/* test_co_vectors.c - replay the golden frame vectors (protocols/vectors/frames.txt)
 * against the C slave in-process (co_membus) and check every response byte. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "co_membus.h"
#include "co_node.h"
#include "od_drive.h"
#include "od_plant.h"

#define MAX_OUT 64

static co_frame_t g_out[MAX_OUT];
static int g_n_out;

static void sink(void *user, const co_frame_t *f, uint8_t sender, int64_t now_us)
{
    (void)user;
    (void)now_us;
    if (sender == CO_MEMBUS_EXTERNAL) return;
    if (g_n_out < MAX_OUT) g_out[g_n_out++] = *f;
}

static int parse_frame(const char *s, co_frame_t *f)
{
    memset(f, 0, sizeof *f);
    char *hash = strchr(s, '#');
    if (!hash) return -1;
    f->cob_id = (uint32_t)strtoul(s, NULL, 16);
    const char *h = hash + 1;
    int n = 0;
    while (h[0] && h[0] != '\n' && h[0] != '\r' && h[1]) {
        char byte[3] = {h[0], h[1], 0};
        if (n >= 8) return -1;
        f->data[n++] = (uint8_t)strtoul(byte, NULL, 16);
        h += 2;
    }
    f->dlc = (uint8_t)n;
    return 0;
}

static void fmt(const co_frame_t *f, char *buf, size_t cap)
{
    int o = snprintf(buf, cap, "%03X#", (unsigned)f->cob_id);
    for (int i = 0; i < f->dlc && o + 2 < (int)cap; ++i) o += snprintf(buf + o, cap - (size_t)o, "%02X", f->data[i]);
}

typedef struct {
    co_membus_t bus;
    co_node_t node;
    int port;
    int expect_idx; /* next g_out index expected */
    int failures;
    char name[256];
    int active;
} ctx_t;

static int64_t g_now = 1000;

static void start(ctx_t *c, const char *node, unsigned id)
{
    co_membus_init(&c->bus, sink, NULL);
    c->port = co_membus_port(&c->bus);
    const co_od_t *od = strcmp(node, "drive") == 0 ? &od_drive : &od_plant;
    co_node_init(&c->node, od, (uint8_t)id, co_membus_tx, &c->bus.ports[c->port], NULL, NULL, g_now);
    co_membus_attach(&c->bus, c->port, &c->node);
    co_membus_deliver(&c->bus, g_now);
    g_n_out = 0; /* ignore the boot-up message */
    c->expect_idx = 0;
}

static void flush_check(ctx_t *c)
{
    if (c->active && c->expect_idx != g_n_out) {
        char b[64];
        for (int i = c->expect_idx; i < g_n_out; ++i) {
            fmt(&g_out[i], b, sizeof b);
            printf("  %s: unexpected frame %s\n", c->name, b);
        }
        ++c->failures;
    }
    g_n_out = 0;
    c->expect_idx = 0;
}

int main(int argc, char **argv)
{
    const char *path = argc > 1 ? argv[1] : "protocols/vectors/frames.txt";
    FILE *fp = fopen(path, "r");
    if (!fp) {
        printf("cannot open %s (run from the repository root)\n", path);
        return 1;
    }
    static ctx_t c;
    int vectors = 0, frames_checked = 0, total_failures = 0;
    char line[256];
    while (fgets(line, sizeof line, fp)) {
        if (line[0] == '#' || line[0] == '\n') continue;
        if (strncmp(line, "vector ", 7) == 0) {
            flush_check(&c);
            total_failures += c.failures;
            memset(&c, 0, sizeof c);
            snprintf(c.name, sizeof c.name, "%s", line + 7);
            c.name[strcspn(c.name, "\r\n")] = 0;
            c.active = 1;
            ++vectors;
        } else if (strncmp(line, "node ", 5) == 0) {
            char node[16];
            unsigned id;
            if (sscanf(line + 5, "%15s %x", node, &id) != 2) { printf("bad node line\n"); return 1; }
            start(&c, node, id);
        } else if (strncmp(line, "nmt operational", 15) == 0) {
            co_nmt_command(&c.node, CO_NMT_CS_START);
        } else if (line[0] == '>') {
            flush_check(&c);
            co_frame_t f;
            if (parse_frame(line + 2, &f)) { printf("bad frame '%s'\n", line); return 1; }
            co_membus_inject(&c.bus, &f);
            g_now += 100;
            co_membus_deliver(&c.bus, g_now);
        } else if (line[0] == '<') {
            co_frame_t want;
            if (parse_frame(line + 2, &want)) { printf("bad frame '%s'\n", line); return 1; }
            char wb[64], gb[64];
            fmt(&want, wb, sizeof wb);
            ++frames_checked;
            if (c.expect_idx >= g_n_out) {
                printf("  %s: expected %s, got nothing\n", c.name, wb);
                ++c.failures;
                continue;
            }
            const co_frame_t *got = &g_out[c.expect_idx++];
            fmt(got, gb, sizeof gb);
            if (got->cob_id != want.cob_id || got->dlc != want.dlc || memcmp(got->data, want.data, want.dlc) != 0) {
                printf("  %s: expected %s, got %s\n", c.name, wb, gb);
                ++c.failures;
            }
        }
    }
    flush_check(&c);
    total_failures += c.failures;
    fclose(fp);
    printf("vectors: %d replayed, %d response frames checked, %d failures\n", vectors, frames_checked, total_failures);
    return (total_failures == 0 && vectors > 0 && frames_checked > 0) ? 0 : 1;
}
