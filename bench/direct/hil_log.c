/* hil_log.c - candump log files (can-utils `candump -L` format), written and read in C.
 *
 * Why hand-written: python-can's CanutilsLogWriter/CanutilsLogReader make one Python
 * can.Message (and a few str objects) per frame, ~10 µs to write and ~13 µs to read a frame,
 * ~90 µs a control period of ~8 frames: 18 s to write the log of 2e5 periods and as long to
 * read it back. Here (~0.1 µs a frame either way) a frame is a 24-byte hil_frame_t in a numpy
 * array (bench/run/record/canlog.py), formatted / parsed with hand-rolled decimal and hex (no
 * printf/scanf per field or byte), and python-can's own readers stay the reference: the
 * tests round-trip every line written here through CanutilsLogReader.
 *
 * A line (what candump -L writes and python-can reads):
 *     (1712345678.123456) vcan0 1A0#0011223344556677\n
 *     (1712345678.123457) vcan0 700#\n                       (dlc 0)
 *     (1712345678.123458) vcan0 181##1<32 hex digits>\n      (CAN FD, 16 bytes; the digit after ## is candump's
 *                                                           flags: 1 = bit-rate switch)
 * A classic run's frames are 24-byte hil_frame_t records; a run with CAN FD PDOs has 88-byte hil_frame_fd_t
 * (hil_log_format_fd, hil_log_parse_fd).
 * Pure C11, no allocation, no OS headers; called from Python by ctypes (build/libhil.so).
 */
#include <stdint.h>
#include <string.h>

#include "hil_frame.h"

/* Longest channel name accepted (IFNAMSIZ is 16; python-can writes any string). */
#define HIL_LOG_CHANNEL_MAX 64u

/* Worst case of one line, channel of length L:
 *   "(" + seconds (<= 14 digits: 2^64 µs) + "." + 6 digits + ") " + L + " " + 3 hex + "#"
 *   + 16 hex + "\n"  =  46 + L  bytes.
 * A buffer of n * hil_log_line_max(channel) bytes always holds n lines. */
#define HIL_LOG_LINE_FIXED 46u
/* A CAN FD line: "##" and the flags digit instead of "#", 128 hex digits instead of 16. */
#define HIL_LOG_LINE_FIXED_FD (HIL_LOG_LINE_FIXED + 2u + 112u)

static const char HEX_UP[] = "0123456789ABCDEF";

/* "00".."99": two decimal digits per table look-up (the tables below keep their rows). */
/* clang-format off */
static const char DEC2[200] = {
    '0','0','0','1','0','2','0','3','0','4','0','5','0','6','0','7','0','8','0','9',
    '1','0','1','1','1','2','1','3','1','4','1','5','1','6','1','7','1','8','1','9',
    '2','0','2','1','2','2','2','3','2','4','2','5','2','6','2','7','2','8','2','9',
    '3','0','3','1','3','2','3','3','3','4','3','5','3','6','3','7','3','8','3','9',
    '4','0','4','1','4','2','4','3','4','4','4','5','4','6','4','7','4','8','4','9',
    '5','0','5','1','5','2','5','3','5','4','5','5','5','6','5','7','5','8','5','9',
    '6','0','6','1','6','2','6','3','6','4','6','5','6','6','6','7','6','8','6','9',
    '7','0','7','1','7','2','7','3','7','4','7','5','7','6','7','7','7','8','7','9',
    '8','0','8','1','8','2','8','3','8','4','8','5','8','6','8','7','8','8','8','9',
    '9','0','9','1','9','2','9','3','9','4','9','5','9','6','9','7','9','8','9','9',
};

/* Character classes by table look-up (the parser's inner loops): white space of a line, and
 * hex digit value + 1 (0: not a hex digit). */
static const uint8_t SPACE[256] = {[' '] = 1, ['\t'] = 1, ['\r'] = 1, ['\v'] = 1, ['\f'] = 1};
static const uint8_t HEXV1[256] = {
    ['0'] = 1, ['1'] = 2, ['2'] = 3, ['3'] = 4, ['4'] = 5, ['5'] = 6, ['6'] = 7, ['7'] = 8, ['8'] = 9, ['9'] = 10,
    ['A'] = 11, ['B'] = 12, ['C'] = 13, ['D'] = 14, ['E'] = 15, ['F'] = 16,
    ['a'] = 11, ['b'] = 12, ['c'] = 13, ['d'] = 14, ['e'] = 15, ['f'] = 16,
};
/* clang-format on */

static int is_space(char c) { return SPACE[(unsigned char)c]; }

static uint64_t channel_len(const char *channel)
{
    if (!channel) return 0;
    uint64_t L = 0;
    while (channel[L] != '\0') {
        char c = channel[L];
        /* a token of the line: no white space, no control characters, no '(' at its start */
        if ((unsigned char)c <= ' ' || (unsigned char)c == 0x7F) return 0;
        if (++L > HIL_LOG_CHANNEL_MAX) return 0;
    }
    return L;
}

/* Bytes one line may take with this channel (0: channel not usable: empty, longer than
 * 64 bytes, or holding white space / control characters). */
uint64_t hil_log_line_max(const char *channel)
{
    uint64_t L = channel_len(channel);
    return L ? HIL_LOG_LINE_FIXED + L : 0;
}

/* The same for hil_log_format_fd's lines. */
uint64_t hil_log_line_max_fd(const char *channel)
{
    uint64_t L = channel_len(channel);
    return L ? HIL_LOG_LINE_FIXED_FD + L : 0;
}

/* Seconds with at least 10 digits, zero-padded (candump's %010llu). Returns the length. */
static unsigned put_seconds(char *p, uint64_t s)
{
    char tmp[24];
    unsigned n = 0;
    while (s >= 100) {
        unsigned r = (unsigned)(s % 100);
        s /= 100;
        tmp[n++] = DEC2[2 * r + 1];
        tmp[n++] = DEC2[2 * r];
    }
    if (s >= 10) {
        tmp[n++] = DEC2[2 * s + 1];
        tmp[n++] = DEC2[2 * s];
    } else {
        tmp[n++] = (char)('0' + s);
    }
    while (n < 10) tmp[n++] = '0';
    for (unsigned i = 0; i < n; ++i) p[i] = tmp[n - 1 - i];
    return n;
}

/* One frame's line at p (room checked by the caller); returns its length. fd: "III##F" + data (F: the flags
 * digit, 1 = bit-rate switch), else "III#" + data, dlc above 8 written as 8. */
static unsigned put_line(char *p, uint64_t ts, const char *channel, uint64_t L, unsigned id, unsigned dlc,
                         const uint8_t *data, int fd, int brs)
{
    char *const p0 = p;
    uint64_t s = ts / 1000000u;
    unsigned us = (unsigned)(ts % 1000000u);
    *p++ = '(';
    p += put_seconds(p, s);
    *p++ = '.';
    p[0] = DEC2[2 * (us / 10000)];
    p[1] = DEC2[2 * (us / 10000) + 1];
    p[2] = DEC2[2 * (us / 100 % 100)];
    p[3] = DEC2[2 * (us / 100 % 100) + 1];
    p[4] = DEC2[2 * (us % 100)];
    p[5] = DEC2[2 * (us % 100) + 1];
    p += 6;
    *p++ = ')';
    *p++ = ' ';
    memcpy(p, channel, (size_t)L);
    p += L;
    *p++ = ' ';
    p[0] = HEX_UP[id >> 8];
    p[1] = HEX_UP[(id >> 4) & 0xF];
    p[2] = HEX_UP[id & 0xF];
    p[3] = '#';
    p += 4;
    if (fd) {
        *p++ = '#';
        *p++ = brs ? '1' : '0';
    } else if (dlc > 8) {
        dlc = 8;
    }
    for (unsigned k = 0; k < dlc; ++k) {
        uint8_t b = data[k];
        p[0] = HEX_UP[b >> 4];
        p[1] = HEX_UP[b & 0xF];
        p += 2;
    }
    *p++ = '\n';
    return (unsigned)(p - p0);
}

/* The bytes of one line exactly (a buffer's last lines may still fit where the worst case does not). */
static uint64_t line_need(uint64_t ts, uint64_t L, unsigned dlc, int fd)
{
    uint64_t digits = 1;
    for (uint64_t v = ts / 1000000u; v >= 10; v /= 10) ++digits;
    if (digits < 10) digits = 10;
    return 1 + digits + 1 + 6 + 2 + L + 1 + 3 + 1 + (fd ? 2u : 0u) + 2u * dlc + 1;
}

/* n frames -> n candump lines in out[0..cap). Time stamp = t0_us + f[i].t_us (absolute µs
 * since the epoch: keep it absolute, log2asc prints its header again for every frame whose
 * stamp has 0 seconds). cob_id is written as 3 hex digits of its 11 bits, dlc above 8 as 8
 * (CAN: dlc 9..15 carry 8 bytes), data in upper-case hex, "III#" alone for dlc 0.
 * Returns the bytes written; 0 if n == 0, if the channel is unusable (see hil_log_line_max)
 * or if cap < the bytes of all n lines (nothing useful written then): cap >= n *
 * hil_log_line_max(channel) = n * (46 + strlen(channel)) is always enough. */
uint64_t hil_log_format(const hil_frame_t *f, uint32_t n, uint64_t t0_us, const char *channel, char *out, uint64_t cap)
{
    uint64_t L = channel_len(channel);
    if (!f || !out || L == 0 || n == 0) return 0;
    const uint64_t line_max = HIL_LOG_LINE_FIXED + L;
    char *p = out;
    char *const end = out + cap;
    for (uint32_t i = 0; i < n; ++i) {
        const hil_frame_t *g = &f[i];
        unsigned dlc = g->dlc > 8 ? 8u : g->dlc;
        if ((uint64_t)(end - p) < line_max && (uint64_t)(end - p) < line_need(t0_us + g->t_us, L, dlc, 0)) return 0;
        p += put_line(p, t0_us + g->t_us, channel, L, g->cob_id & 0x7FFu, dlc, g->data, 0, 0);
    }
    return (uint64_t)(p - out);
}

/* The same for the records of a run with CAN FD PDOs: a frame with HIL_FRAME_FDF becomes a "##" line (its flags
 * digit 1 with HIL_FRAME_BRS), the others classic lines. cap >= n * hil_log_line_max_fd(channel) is always
 * enough. */
uint64_t hil_log_format_fd(const hil_frame_fd_t *f, uint32_t n, uint64_t t0_us, const char *channel, char *out,
                           uint64_t cap)
{
    uint64_t L = channel_len(channel);
    if (!f || !out || L == 0 || n == 0) return 0;
    const uint64_t line_max = HIL_LOG_LINE_FIXED_FD + L;
    char *p = out;
    char *const end = out + cap;
    for (uint32_t i = 0; i < n; ++i) {
        const hil_frame_fd_t *g = &f[i];
        int fd = (g->flags & HIL_FRAME_FDF) != 0;
        unsigned dlc = g->dlc > (fd ? 64u : 8u) ? (fd ? 64u : 8u) : g->dlc;
        if ((uint64_t)(end - p) < line_max && (uint64_t)(end - p) < line_need(t0_us + g->t_us, L, dlc, fd)) return 0;
        p += put_line(p, t0_us + g->t_us, channel, L, g->cob_id & 0x7FFu, dlc, g->data, fd,
                      (g->flags & HIL_FRAME_BRS) != 0);
    }
    return (uint64_t)(p - out);
}

/* ------------------------------------------------------------------ parser */

/* What hil_log_parse_counted saw in the lines it used (ctypes mirror: _LogCounts in
 * bench/run/record/canlog.py). */
typedef struct {
    uint64_t lines;            /* lines used, each ended by '\n' */
    uint64_t skipped;          /* frames that are not an 11-bit data frame of <= 8 bytes */
    uint64_t extended;         /* of them, extended-ID (29-bit) data frames */
    uint64_t unparsable;       /* lines that are no candump frame */
    uint64_t first_unparsable; /* 1-based among the lines used; 0: none */
} hil_log_counts_t;

static int hexval(char c) { return (int)HEXV1[(unsigned char)c] - 1; }

/* Largest whole seconds whose µs still fit in 64 bits. */
#define SEC_MAX 18446744073708ull

/* What a line is: an 11-bit data frame of <= 8 bytes (ours), an extended-ID (29-bit) data frame,
 * another frame that is not ours (error, remote, CAN FD longer than 8 bytes), a line that is no
 * candump frame at all (malformed: garbage, a cut line), or silent (blank, comment). */
enum { LINE_FRAME, LINE_EXTENDED, LINE_OTHER, LINE_BAD, LINE_SILENT };

/* CAN_ERR_FLAG of linux/can.h: candump writes error frames as 8 hex digits with it set. */
#define HIL_CAN_ERR_FLAG 0x20000000u
#define HIL_CAN_EFF_MASK 0x1FFFFFFFu

/* One line [p, e) without its '\n'. LINE_FRAME fills *fr (a CAN FD frame of any length, flags set). */
static int parse_line(const char *p, const char *e, hil_frame_fd_t *fr)
{
    while (e > p && is_space(e[-1])) --e; /* "\r\n" line ends, trailing blanks */
    while (p < e && is_space(*p)) ++p;
    if (p == e) return LINE_SILENT;                 /* blank line */
    if (*p == '#' || *p == ';') return LINE_SILENT; /* comment */

    /* (SECONDS.FRACTION) */
    if (*p++ != '(') return LINE_BAD;
    uint64_t sec = 0;
    unsigned nd = 0;
    while (p < e && *p >= '0' && *p <= '9') {
        sec = sec * 10u + (uint64_t)(*p++ - '0');
        if (++nd > 14 || sec > SEC_MAX) return LINE_BAD;
    }
    if (nd == 0) return LINE_BAD;
    uint64_t us = 0;
    if (p < e && *p == '.') {
        ++p;
        unsigned nf = 0;
        int round_up = 0;
        while (p < e && *p >= '0' && *p <= '9') {
            if (nf < 6)
                us = us * 10u + (uint64_t)(*p - '0');
            else if (nf == 6)
                round_up = *p >= '5'; /* to the nearest µs, like round(float * 1e6) */
            ++nf;
            ++p;
        }
        for (unsigned k = nf; k < 6; ++k) us *= 10u;
        us += (uint64_t)round_up;
    }
    if (p >= e || *p++ != ')') return LINE_BAD;
    uint64_t t_us = sec * 1000000u + us; /* no overflow: sec <= SEC_MAX, us <= 1000000 */

    /* channel: one token */
    if (p >= e || !is_space(*p)) return LINE_BAD;
    while (p < e && is_space(*p)) ++p;
    if (p >= e) return LINE_BAD;
    while (p < e && !is_space(*p)) ++p;
    while (p < e && is_space(*p)) ++p;
    if (p >= e) return LINE_BAD;

    /* frame token [p, q) */
    const char *q = p;
    while (q < e && !is_space(*q)) ++q;
    /* optional direction token of python-can's writer (" R" / " T"), then nothing */
    const char *r = q;
    while (r < e && is_space(*r)) ++r;
    if (r < e) {
        if (e - r != 1 || (*r != 'R' && *r != 'r' && *r != 'T' && *r != 't')) return LINE_BAD;
    }

    /* identifier: 1..3 hex digits standard (as python-can: more than 3 digits = extended;
     * candump writes 3 or 8, error frames as 8 digits with CAN_ERR_FLAG) */
    const char *id0 = p;
    uint32_t id = 0;
    while (p < q && *p != '#') {
        int v = hexval(*p++);
        if (v < 0) return LINE_BAD;
        if (p - id0 <= 8) id = (id << 4) | (uint32_t)v;
    }
    long nid = (long)(p - id0);
    if (p >= q || nid == 0 || nid > 8) return LINE_BAD; /* no '#', no identifier, or too long */
    int kind = LINE_FRAME;
    if (nid > 3) { /* extended data frame, or an error frame: a frame, not ours */
        if (id & HIL_CAN_ERR_FLAG) {
            kind = LINE_OTHER;
        } else {
            if (id > HIL_CAN_EFF_MASK) return LINE_BAD;
            kind = LINE_EXTENDED;
        }
    } else if (id > 0x7FFu) {
        return LINE_BAD;
    }
    ++p; /* '#' */

    int fd = 0, fd_flags = 0;
    if (p < q && *p == '#') { /* CAN FD: ##<flags><data> */
        ++p;
        if (p >= q || hexval(*p) < 0) return LINE_BAD;
        fd_flags = hexval(*p);
        ++p;
        fd = 1;
    }
    if (!fd && p < q && (*p == 'R' || *p == 'r')) return LINE_OTHER; /* remote frame */

    uint8_t data[64];
    unsigned dlc = 0;
    const unsigned max_bytes = fd ? 64u : 8u;
    while (p < q) {
        if (*p == '.') { /* candump's optional byte separator */
            ++p;
            continue;
        }
        if (q - p < 2) return LINE_BAD; /* odd number of hex digits */
        int hi = hexval(p[0]), lo = hexval(p[1]);
        if (hi < 0 || lo < 0) return LINE_BAD;
        if (dlc >= max_bytes) return LINE_BAD;
        data[dlc++] = (uint8_t)((hi << 4) | lo);
        p += 2;
    }
    if (kind != LINE_FRAME) return kind;

    memset(fr, 0, sizeof *fr);
    fr->t_us = t_us;
    fr->seq = 0;
    fr->cob_id = (uint16_t)id;
    fr->dlc = (uint8_t)dlc;
    fr->sender = 255;
    memcpy(fr->data, data, dlc);
    fr->flags = (uint8_t)(fd ? (HIL_FRAME_FDF | ((fd_flags & 1) ? HIL_FRAME_BRS : 0u)) : 0u);
    return LINE_FRAME;
}

/* Parses the complete lines of buf[0..len) (those ending in '\n'; a trailing partial line is
 * left: feed it again with more data, or with a '\n' appended at the end of the file) into
 * out[0..cap). Returns the frames written; *consumed = bytes of the lines used (stops early
 * when out is full); *counts (may be NULL) = what the lines used were: lines, frames that are
 * not an 11-bit data frame of <= 8 bytes (skipped: extended, error, remote, CAN FD longer than
 * 8 bytes; of them `extended`: extended-ID data frames), and lines that are no candump frame
 * (unparsable, the first of them 1-based among these lines); blank lines and comment lines
 * ('#' or ';' first) count as lines only. t_us = absolute µs of the time stamp, seq = 0,
 * sender = 255, data past dlc = 0. Never reads outside buf[0..len). */
static uint32_t parse_lines(const char *buf, uint64_t len, void *out, int wide, uint32_t cap, uint64_t *consumed,
                            hil_log_counts_t *counts)
{
    hil_log_counts_t c = {0, 0, 0, 0, 0};
    uint64_t used = 0;
    uint32_t n = 0;
    if (buf && out) {
        const char *p = buf;
        const char *const end = buf + len;
        hil_frame_fd_t fr;
        while (n < cap && p < end) {
            const char *nl = memchr(p, '\n', (size_t)(end - p));
            if (!nl) break;
            ++c.lines;
            int k = parse_line(p, nl, &fr);
            if (k == LINE_FRAME && !wide && fr.dlc > 8) k = LINE_OTHER; /* CAN FD beyond a classic record */
            if (k == LINE_FRAME) {
                if (wide) {
                    ((hil_frame_fd_t *)out)[n++] = fr;
                } else {
                    hil_frame_t *g = &((hil_frame_t *)out)[n++];
                    g->t_us = fr.t_us;
                    g->seq = 0;
                    g->cob_id = fr.cob_id;
                    g->dlc = fr.dlc;
                    g->sender = fr.sender;
                    memcpy(g->data, fr.data, 8);
                }
            } else if (k == LINE_EXTENDED) {
                ++c.skipped;
                ++c.extended;
            } else if (k == LINE_OTHER) {
                ++c.skipped;
            } else if (k == LINE_BAD) {
                if (c.unparsable++ == 0) c.first_unparsable = c.lines;
            }
            p = nl + 1;
        }
        used = (uint64_t)(p - buf);
    }
    if (consumed) *consumed = used;
    if (counts) *counts = c;
    return n;
}

uint32_t hil_log_parse_counted(const char *buf, uint64_t len, hil_frame_t *out, uint32_t cap, uint64_t *consumed,
                               hil_log_counts_t *counts)
{
    return parse_lines(buf, len, out, 0, cap, consumed, counts);
}

/* The same into hil_frame_fd_t records: CAN FD frames of any length kept (flags: HIL_FRAME_FDF, HIL_FRAME_BRS from
 * candump's flags digit), nothing skipped for its length. */
uint32_t hil_log_parse_counted_fd(const char *buf, uint64_t len, hil_frame_fd_t *out, uint32_t cap, uint64_t *consumed,
                                  hil_log_counts_t *counts)
{
    return parse_lines(buf, len, out, 1, cap, consumed, counts);
}

/* hil_log_parse_counted with one count: *skipped = the lines that are not an 11-bit data frame
 * of <= 8 bytes (skipped frames and unparsable lines together), as a follower of a growing log needs. */
uint32_t hil_log_parse(const char *buf, uint64_t len, hil_frame_t *out, uint32_t cap, uint64_t *consumed,
                       uint64_t *skipped)
{
    hil_log_counts_t c;
    uint32_t n = hil_log_parse_counted(buf, len, out, cap, consumed, &c);
    if (skipped) *skipped = c.skipped + c.unparsable;
    return n;
}

/* hil_log_parse for hil_frame_fd_t records. */
uint32_t hil_log_parse_fd(const char *buf, uint64_t len, hil_frame_fd_t *out, uint32_t cap, uint64_t *consumed,
                          uint64_t *skipped)
{
    hil_log_counts_t c;
    uint32_t n = hil_log_parse_counted_fd(buf, len, out, cap, consumed, &c);
    if (skipped) *skipped = c.skipped + c.unparsable;
    return n;
}
