/* test_co_vectors.c - replay the golden frame vectors (protocols/vectors/frames.txt)
 * against the C slave in-process (co_membus) and check every response byte. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "co_node.h"
#include "od_drive.h"
#include "od_plant.h"
#include "testbus.h"

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
    testbus_t tb;
    uint32_t expect_idx; /* next frame of the node expected */
    int failures;
    char name[256];
    int active;
} ctx_t;

static int64_t g_now = 1000;

static void start(ctx_t *c, const char *node, unsigned id)
{
    const co_od_t *od = strcmp(node, "drive") == 0 ? &od_drive : &od_plant;
    testbus_init(&c->tb, od, (uint8_t)id, NULL, NULL, g_now, 100);
    testbus_deliver(&c->tb);
    testbus_clear(&c->tb); /* ignore the boot-up message */
    c->expect_idx = 0;
}

static void flush_check(ctx_t *c)
{
    const uint32_t n_out = testbus_node_frames(&c->tb);
    if (c->active && c->expect_idx != n_out) {
        char b[64];
        for (uint32_t i = c->expect_idx; i < n_out; ++i) {
            fmt(testbus_node_frame(&c->tb, i), b, sizeof b);
            printf("  %s: unexpected frame %s\n", c->name, b);
        }
        ++c->failures;
    }
    testbus_clear(&c->tb);
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
            if (sscanf(line + 5, "%15s %x", node, &id) != 2) {
                printf("bad node line\n");
                return 1;
            }
            start(&c, node, id);
        } else if (strncmp(line, "nmt operational", 15) == 0) {
            co_nmt_command(&c.tb.node, CO_NMT_CS_START);
        } else if (line[0] == '>') {
            flush_check(&c);
            co_frame_t f;
            if (parse_frame(line + 2, &f)) {
                printf("bad frame '%s'\n", line);
                return 1;
            }
            testbus_send(&c.tb, f.cob_id, f.dlc, f.data);
            g_now = c.tb.now_us;
        } else if (line[0] == '<') {
            co_frame_t want;
            if (parse_frame(line + 2, &want)) {
                printf("bad frame '%s'\n", line);
                return 1;
            }
            char wb[64], gb[64];
            fmt(&want, wb, sizeof wb);
            ++frames_checked;
            if (c.expect_idx >= testbus_node_frames(&c.tb)) {
                printf("  %s: expected %s, got nothing\n", c.name, wb);
                ++c.failures;
                continue;
            }
            const co_frame_t *got = testbus_node_frame(&c.tb, c.expect_idx++);
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
