/* test_slcan.c - the SLCAN codec (firmware_shim/port/slcan.c): encode -> parse round
 * trips for every DLC and identifiers over the 11-bit range, remote frames, the
 * Lawicel commands python-can and slcand send (O, C, S0-S8, V, N, F, ...), and the
 * refusals: bad hex, wrong lengths, identifiers > 7FF, frames while closed, over-long
 * lines (each answered "\a" once, at its '\r', the parser usable afterwards). */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "slcan.h"

typedef struct {
    int frames; /* data frames completed */
    co_frame_t last;
    char reply[256]; /* every reply, concatenated */
    size_t reply_len;
} feed_result_t;

static feed_result_t feed(slcan_parser_t *p, const char *s)
{
    feed_result_t r;
    memset(&r, 0, sizeof r);
    for (const char *c = s; *c != '\0'; ++c) {
        slcan_reply_t rep;
        co_frame_t f;
        if (slcan_feed(p, (uint8_t)*c, &f, &rep)) {
            ++r.frames;
            r.last = f;
        }
        if (rep.len != 0u && r.reply_len + rep.len < sizeof r.reply) {
            memcpy(r.reply + r.reply_len, rep.text, rep.len);
            r.reply_len += rep.len;
        }
    }
    r.reply[r.reply_len] = '\0';
    return r;
}

static void open_channel(slcan_parser_t *p)
{
    slcan_init(p);
    const feed_result_t r = feed(p, "O\r");
    CHECK(strcmp(r.reply, "\r") == 0 && p->open, "O opens the channel");
}

static void test_round_trips(void)
{
    slcan_parser_t p;
    open_channel(&p);
    const uint32_t ids[] = {0x000u, 0x001u, 0x080u, 0x1A0u, 0x210u, 0x5FFu, 0x7FEu, 0x7FFu};
    int n = 0;
    for (uint8_t dlc = 0; dlc <= 8u; ++dlc) {
        for (size_t k = 0; k < sizeof ids / sizeof ids[0]; ++k) {
            co_frame_t f;
            memset(&f, 0, sizeof f);
            f.cob_id = ids[k];
            f.dlc = dlc;
            for (uint8_t i = 0; i < dlc; ++i) f.data[i] = (uint8_t)(0x5Au * (i + 1u) + ids[k] + dlc);
            char line[SLCAN_FRAME_MAX + 1];
            const uint8_t len = slcan_encode(&f, line);
            line[len] = '\0';
            CHECK(len == 6u + 2u * dlc && line[0] == 't' && line[len - 1] == '\r', "encoded length of dlc %u: %s",
                  (unsigned)dlc, line);
            const feed_result_t r = feed(&p, line);
            CHECK(r.frames == 1 && r.last.cob_id == f.cob_id && r.last.dlc == dlc &&
                      memcmp(r.last.data, f.data, dlc) == 0,
                  "round trip of %s", line);
            CHECK(strcmp(r.reply, "z\r") == 0, "a frame is acknowledged with z\\r");
            ++n;
        }
    }
    /* lower-case hex is accepted too */
    const feed_result_t r = feed(&p, "t2102abcd\r");
    CHECK(r.frames == 1 && r.last.cob_id == 0x210u && r.last.data[0] == 0xABu && r.last.data[1] == 0xCDu,
          "lower-case hex");
    /* '\n' after '\r' (a terminal) is ignored */
    const feed_result_t r2 = feed(&p, "t0000\r\n");
    CHECK(r2.frames == 1 && strcmp(r2.reply, "z\r") == 0, "\\r\\n ends one line");

    co_frame_t f = {.cob_id = 0x123u, .dlc = 9u, .data = {0}};
    char out[SLCAN_FRAME_MAX];
    CHECK(slcan_encode(&f, out) == 0u, "dlc 9 is not encoded");
    f.cob_id = 0x7FFu | CO_FRAME_RTR;
    f.dlc = 2u;
    const uint8_t len = slcan_encode(&f, out);
    CHECK(len == 6u && memcmp(out, "r7FF2\r", 6) == 0, "remote frame encoded as rIIIL");
    const feed_result_t rr = feed(&p, "r7FF2\r");
    CHECK(rr.frames == 0 && strcmp(rr.reply, "z\r") == 0, "a remote frame is accepted and ignored");
    printf("slcan: %d round trips\n", n);
}

static void test_refusals(void)
{
    slcan_parser_t p;
    open_channel(&p);
    const char *bad[] = {
        "t21021G34\r", /* bad hex in the data */
        "tG1020\r",    /* bad hex in the identifier */
        "t8000\r",     /* identifier > 7FF */
        "t2109\r",     /* DLC 9 */
        "t210X\r",     /* DLC not a digit */
        "t2102AB\r",   /* too short */
        "t2101ABCD\r", /* too long */
        "t21\r",       /* truncated header */
        "r2101AB\r",   /* a remote frame carries no data */
        "T000002101\r" /* extended frames are refused */,
        "X\r",  /* unknown command */
        "O1\r", /* trailing characters */
        "S9\r", /* no such bit rate */
        "S6\r", /* bit rate while open */
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        const feed_result_t r = feed(&p, bad[k]);
        CHECK(r.frames == 0 && strcmp(r.reply, "\a") == 0, "refused with BELL: %.*s", (int)strlen(bad[k]) - 1, bad[k]);
    }
    CHECK(p.errors == (uint32_t)(sizeof bad / sizeof bad[0]), "every refusal counted: %u", (unsigned)p.errors);

    /* an over-long line: one BELL at its end, nothing decoded, the next line works */
    char longline[128];
    memset(longline, 'A', sizeof longline);
    memcpy(longline, "t2108", 5);
    longline[sizeof longline - 2] = '\r';
    longline[sizeof longline - 1] = '\0';
    feed_result_t r = feed(&p, longline);
    CHECK(r.frames == 0 && strcmp(r.reply, "\a") == 0, "over-long line refused once: %zu reply bytes", r.reply_len);
    r = feed(&p, "t2100\r");
    CHECK(r.frames == 1 && r.last.cob_id == 0x210u && r.last.dlc == 0u, "the parser recovers after an over-long line");
    /* exactly SLCAN_LINE_MAX characters is still a line (refused here as a malformed frame, not as over-long) */
    memset(longline, '0', sizeof longline);
    longline[0] = 't';
    longline[SLCAN_LINE_MAX] = '\r';
    longline[SLCAN_LINE_MAX + 1] = '\0';
    r = feed(&p, longline);
    CHECK(r.frames == 0 && strcmp(r.reply, "\a") == 0, "a full-length bad line is refused");

    /* frames while closed or listen-only */
    r = feed(&p, "C\rt2100\r");
    CHECK(r.frames == 0 && strcmp(r.reply, "\r\a") == 0, "no frame while closed");
    r = feed(&p, "L\rt2100\r");
    CHECK(r.frames == 0 && strcmp(r.reply, "\r\a") == 0 && p.open && p.listen_only, "no frame in listen-only");
}

static void test_commands(void)
{
    slcan_parser_t p;
    slcan_init(&p);
    /* what slcand -s6 -o sends: C, S6, O */
    feed_result_t r = feed(&p, "C\rS6\rO\r");
    CHECK(strcmp(r.reply, "\r\r\r") == 0 && p.open && p.bitrate == 6u, "slcand's C S6 O");
    /* python-can: set_bitrate -> C, S<n>, "" (no data bit rate), O; shutdown -> C */
    r = feed(&p, "C\rS8\r\rO\r");
    CHECK(strcmp(r.reply, "\r\r\r\r") == 0 && p.open && p.bitrate == 8u, "python-can's C S8 (empty) O");
    for (char s = '0'; s <= '8'; ++s) {
        char cmd[] = {'C', '\r', 'S', s, '\r', '\0'};
        r = feed(&p, cmd);
        CHECK(strcmp(r.reply, "\r\r") == 0 && p.bitrate == (uint8_t)(s - '0'), "S%c", s);
    }
    r = feed(&p, "s031C\r");
    CHECK(strcmp(r.reply, "\r") == 0, "sXXYY while closed");
    r = feed(&p, "V\rN\rF\rZ0\rM00000000\rm000007FF\r");
    CHECK(strcmp(r.reply, "V1013\rNDRV1\rF00\r\r\r\r") == 0, "V N F Z M m answers");
    r = feed(&p, "t2100\r");
    CHECK(r.frames == 0 && strcmp(r.reply, "\a") == 0, "closed after C: frames refused");
    r = feed(&p, "O\rO\rt2100\rC\r");
    CHECK(r.frames == 1 && strcmp(r.reply, "\r\rz\r\r") == 0 && !p.open, "O twice, a frame, C");
}

int main(void)
{
    test_round_trips();
    test_refusals();
    test_commands();
    return check_finish("test_slcan");
}
