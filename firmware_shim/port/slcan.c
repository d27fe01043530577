/* slcan.c - SLCAN (Lawicel ASCII) codec (see slcan.h).
 * Portable: no OS headers, no allocation. */
#include "slcan.h"

#include <string.h>

static const char HEX[] = "0123456789ABCDEF";

static int hex_value(char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    return -1;
}

/* n hex digits of s -> *out; 0 on a bad digit. */
static int parse_hex(const char *s, uint8_t n, uint32_t *out)
{
    uint32_t v = 0u;
    for (uint8_t i = 0; i < n; ++i) {
        const int d = hex_value(s[i]);
        if (d < 0) return 0;
        v = (v << 4) | (uint32_t)d;
    }
    *out = v;
    return 1;
}

static void set_reply(slcan_reply_t *r, const char *text)
{
    const size_t n = strlen(text);
    memcpy(r->text, text, n);
    r->len = (uint8_t)n;
}

/* "tIIIL<data>" / "rIIIL": identifier and DLC; 0 when malformed. */
static int parse_header(const char *s, uint8_t len, uint32_t *id, uint8_t *dlc)
{
    if (len < 5u || !parse_hex(s + 1, 3u, id) || *id > 0x7FFu) return 0;
    if (s[4] < '0' || s[4] > '8') return 0;
    *dlc = (uint8_t)(s[4] - '0');
    return 1;
}

/* A complete line (without '\r'): 1 when it is a data frame. */
static int handle_line(slcan_parser_t *p, co_frame_t *frame, slcan_reply_t *reply)
{
    const char *s = p->line;
    const uint8_t len = p->len;
    const char *bell = "\a";
    if (len == 0u) {
        set_reply(reply, "\r");
        return 0;
    }
    switch (s[0]) {
    case 't': {
        uint32_t id = 0u, byte = 0u;
        uint8_t dlc = 0u;
        if (!p->open || p->listen_only || !parse_header(s, len, &id, &dlc) || len != 5u + 2u * dlc) break;
        co_frame_t f;
        memset(&f, 0, sizeof f);
        f.cob_id = id;
        f.dlc = dlc;
        for (uint8_t i = 0; i < dlc; ++i) {
            if (!parse_hex(s + 5 + 2 * i, 2u, &byte)) {
                ++p->errors;
                set_reply(reply, bell);
                return 0;
            }
            f.data[i] = (uint8_t)byte;
        }
        *frame = f;
        ++p->frames;
        set_reply(reply, "z\r");
        return 1;
    }
    case 'r': {
        uint32_t id = 0u;
        uint8_t dlc = 0u;
        if (!p->open || p->listen_only || !parse_header(s, len, &id, &dlc) || len != 5u) break;
        set_reply(reply, "z\r");
        return 0;
    }
    case 'O':
    case 'L':
        if (len != 1u) break;
        p->open = 1u;
        p->listen_only = (uint8_t)(s[0] == 'L');
        set_reply(reply, "\r");
        return 0;
    case 'C':
        if (len != 1u) break;
        p->open = 0u;
        p->listen_only = 0u;
        set_reply(reply, "\r");
        return 0;
    case 'S':
        if (len != 2u || s[1] < '0' || s[1] > '8' || p->open) break;
        p->bitrate = (uint8_t)(s[1] - '0');
        set_reply(reply, "\r");
        return 0;
    case 's': {
        uint32_t btr = 0u;
        if (len != 5u || !parse_hex(s + 1, 4u, &btr) || p->open) break;
        set_reply(reply, "\r");
        return 0;
    }
    case 'V':
    case 'N':
    case 'F': /* queries: a fixed answer */
        if (len != 1u) break;
        set_reply(reply, s[0] == 'V' ? "V1013\r" : s[0] == 'N' ? "NDRV1\r" : "F00\r");
        return 0;
    case 'Z':
        if (len != 2u || (s[1] != '0' && s[1] != '1')) break;
        set_reply(reply, "\r");
        return 0;
    case 'M':
    case 'm': {
        uint32_t code = 0u;
        if (len != 9u || !parse_hex(s + 1, 8u, &code)) break;
        set_reply(reply, "\r");
        return 0;
    }
    default: break;
    }
    ++p->errors;
    set_reply(reply, bell);
    return 0;
}

void slcan_init(slcan_parser_t *p)
{
    memset(p, 0, sizeof *p);
    p->bitrate = 6u;
}

int slcan_feed(slcan_parser_t *p, uint8_t byte, co_frame_t *frame, slcan_reply_t *reply)
{
    reply->len = 0u;
    if (byte == (uint8_t)'\n') return 0;
    if (byte != (uint8_t)'\r') {
        if (p->len < SLCAN_LINE_MAX)
            p->line[p->len++] = (char)byte;
        else
            p->overlong = 1u;
        return 0;
    }
    int got = 0;
    if (p->overlong) {
        ++p->errors;
        set_reply(reply, "\a");
    } else {
        got = handle_line(p, frame, reply);
    }
    p->len = 0u;
    p->overlong = 0u;
    return got;
}

uint8_t slcan_encode(const co_frame_t *frame, char out[SLCAN_FRAME_MAX])
{
    if (frame->dlc > 8u) return 0u;
    const uint32_t id = frame->cob_id & 0x7FFu;
    const int rtr = (frame->cob_id & CO_FRAME_RTR) != 0u;
    uint8_t n = 0u;
    out[n++] = rtr ? 'r' : 't';
    out[n++] = HEX[(id >> 8) & 0xFu];
    out[n++] = HEX[(id >> 4) & 0xFu];
    out[n++] = HEX[id & 0xFu];
    out[n++] = (char)('0' + frame->dlc);
    if (!rtr) {
        for (uint8_t i = 0; i < frame->dlc; ++i) {
            out[n++] = HEX[frame->data[i] >> 4];
            out[n++] = HEX[frame->data[i] & 0xFu];
        }
    }
    out[n++] = '\r';
    return n;
}
