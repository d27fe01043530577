/* slcan.h - the SLCAN (Lawicel ASCII) serial CAN protocol, portable codec.
 *
 * A host sees the drive as a serial CAN adapter: Linux's slcan line discipline
 * (slcand) or python-can's `slcan` interface (e.g. socket://127.0.0.1:PORT).
 *
 * Host -> device, one line per command, ended by '\r' ('\n' is ignored):
 *   tIIIL<data>   standard data frame: 3 hex digits of identifier (<= 7FF), the
 *                 DLC 0-8, 2*DLC hex digits          -> frame, answers "z\r"
 *   rIIIL         standard remote frame: accepted and ignored (the CANopen slave
 *                 answers no RTR)                     -> "z\r"
 *   O / L         open the channel (L: listen only)  -> "\r"
 *   C             close it                           -> "\r"
 *   S0..S8        bit rate 10k..1M (closed only)     -> "\r"
 *   sXXYY         BTR0/BTR1 (closed only)            -> "\r"
 *   V             version                            -> "V1013\r"
 *   N             serial number                      -> "NDRV1\r"
 *   F             status flags                       -> "F00\r"
 *   Z0/Z1, M/m    time stamps, acceptance filters: accepted, without effect -> "\r"
 *   (empty line)                                     -> "\r"
 * Anything else, bad hex, a wrong length, a frame while the channel is closed (or
 * listen-only), or a line longer than SLCAN_LINE_MAX -> "\a" (BELL), as Lawicel
 * devices answer.  Extended frames (T, R) are refused with "\a": CANopen here uses
 * 11-bit identifiers only.
 *
 * Device -> host: slcan_encode writes "tIIIL<data>\r" (or "rIIIL\r").
 */
#ifndef SLCAN_H
#define SLCAN_H

#include <stdint.h>

#include "co_frame.h"

/* Longest line accepted, without its '\r' ("T" + 8 + 1 + 16 = 26; one spare). */
#define SLCAN_LINE_MAX 27u
/* Longest encoded frame, '\r' included ("t" + 3 + 1 + 16 + 1). */
#define SLCAN_FRAME_MAX 22u
#define SLCAN_REPLY_MAX 8u

typedef struct {
    char line[SLCAN_LINE_MAX];
    uint8_t len;
    uint8_t overlong;    /* the current line passed SLCAN_LINE_MAX: refused at its '\r' */
    uint8_t open;        /* O (or L) received, C not since */
    uint8_t listen_only; /* opened with L: frames refused */
    uint8_t bitrate;     /* last S0..S8 (6 = 500 kbit/s by default) */
    uint32_t frames;     /* frames decoded */
    uint32_t errors;     /* lines answered with BELL */
} slcan_parser_t;

typedef struct {
    char text[SLCAN_REPLY_MAX];
    uint8_t len; /* 0: nothing to answer (the line is not complete yet) */
} slcan_reply_t;

void slcan_init(slcan_parser_t *p);

/* Feed one received byte.  Returns 1 when it completed a data frame (*frame
 * filled), else 0.  reply->len is set non-zero when the byte completed a line: the
 * caller sends reply->text back to the host (after handling the frame). */
int slcan_feed(slcan_parser_t *p, uint8_t byte, co_frame_t *frame, slcan_reply_t *reply);

/* Encode one frame as "tIIIL<data>\r" ("rIIIL\r" for CO_FRAME_RTR) into out;
 * returns its length (at most SLCAN_FRAME_MAX), 0 for an invalid frame (dlc > 8). */
uint8_t slcan_encode(const co_frame_t *frame, char out[SLCAN_FRAME_MAX]);

#endif /* SLCAN_H */
