/* fault_injector.h - faults on purpose between the plant's side and the drive's side of the bus.
 *
 * PORTABLE (no OS headers, no allocation): the same code joins the two sides in the bench's
 * direct mode (bench/direct/hil_direct.c, in-process) and in the SocketCAN gateway process
 * (fault_gateway_main.c, vcan0 <-> vcan1), so a scenario's [[faults]] give the same faults,
 * at the same periods, in both.
 *
 *   side A: the plant, the master, the recorder (what the bench records is what side A sees)
 *   side B: the drive
 *
 * Every frame crossing from one side to the other goes through fi_frame(); the injector calls
 * `emit` for what goes out to the other side now (0, 1 or 2 frames), holds delayed and
 * reordered frames, and counts periods from the SYNCs that cross from side A (period p starts
 * at the (p+1)-th SYNC, as the plant's sample index). Rules apply in the window
 * [at_period, at_period + periods), to frames of one identifier and one sender side, each
 * matching frame with a probability decided by a hash of (seed, rule, period, n-th match in the
 * period): the same frames are hit whatever the timing of the transport.
 *
 * Frame faults: drop, delay (whole periods: released right after the SYNC that starts the
 * period; or microseconds, for a gateway in real time), duplicate, corrupt (one bit flipped, or
 * a new DLC: a faulty sender, since a real bus's CRC would drop a flipped bit), reorder (held
 * until the next frame from the same side has gone out).
 * Node faults: the injector decides when, the transport does it (`node` callback): freeze for
 * `periods` (direct: the node neither runs nor hears; gateway: SIGSTOP/SIGCONT), kill, and
 * reset (an NMT reset-node frame for `node_id`, sent to both sides before the SYNC).
 * Every action taken is logged (fi_event_t) with its period and rule.
 */
#ifndef FAULT_INJECTOR_H
#define FAULT_INJECTOR_H

#include <stdint.h>

#include "co_frame.h"
/* FI_MAX_RULES, the rule table's size (a scenario's [[faults]] at most): generated from [FaultInjector] of
 * protocols/eds/common.ini by protocols/gen_od.py, which the bench reads too (bench/scenario/faults.py). */
#include "eds_common.h"

#define FI_MAX_HELD 256u
#define FI_LOG_SIZE 4096u
#define FI_ANY_COB 0xFFFFu
#define FI_ALWAYS 0x100000000ull /* threshold of probability 1 */

typedef enum {
    FI_PASS = 0,
    FI_DROP = 1,
    FI_DELAY = 2,
    FI_DUPLICATE = 3,
    FI_CORRUPT = 4,
    FI_REORDER = 5,
    FI_FREEZE = 6, /* node faults from here */
    FI_THAW = 7,   /* log only: the end of a freeze */
    FI_KILL = 8,
    FI_RESET = 9,
    FI_RELEASE = 10 /* log only: a held frame went out */
} fi_kind_t;

enum { FI_SIDE_A = 0, FI_SIDE_B = 1, FI_SIDE_ANY = 2 };

typedef struct {
    uint8_t kind;           /* fi_kind_t */
    uint8_t from;           /* sender side (frame faults) or the node's side (node faults) */
    uint16_t cob_id;        /* 11-bit identifier, or FI_ANY_COB */
    uint32_t at_period;     /* first period of the window */
    uint32_t periods;       /* window length (>= 1); freeze: its duration */
    uint64_t threshold;     /* probability * 2^32 (FI_ALWAYS: every matching frame) */
    uint64_t seed;          /* of the probability draw */
    uint32_t count;         /* at most this many frames hit (0: no limit) */
    uint32_t delay_periods; /* FI_DELAY in periods (if delay_us == 0) */
    uint32_t delay_us;      /* FI_DELAY in microseconds (real time) */
    uint8_t bit;            /* FI_CORRUPT: bit to flip (bit 0 = LSB of data[0]) when dlc < 0 */
    int8_t dlc;             /* FI_CORRUPT: new DLC (0..8), or -1: flip `bit` */
    uint8_t node_id;        /* FI_RESET: the node to reset */
} fi_rule_t;

typedef struct {
    int64_t period;  /* -1: before the first SYNC */
    int64_t t_us;    /* the transport's time */
    uint16_t rule;   /* index into the rules */
    uint8_t kind;    /* fi_kind_t of the action */
    uint8_t from;    /* sender side of the frame (frame faults) or the node's side */
    uint16_t cob_id; /* the frame's identifier (node faults: 0) */
    uint8_t dlc;     /* the frame as it was */
    uint8_t data[8];
} fi_event_t;

typedef struct {
    co_frame_t frame;
    uint8_t from;
    uint8_t kind; /* FI_DELAY or FI_REORDER */
    uint16_t rule;
    int64_t release_period; /* -1: not by period */
    int64_t release_us;     /* -1: not by time */
} fi_held_t;

/* Frame out to side `to`; `from` is its sender's side, or FI_FROM_INJECTOR for a frame the injector
 * made (the NMT reset of a node fault, sent to both sides). Must not call fi_frame (the injector may be
 * walking its hold queue). */
#define FI_FROM_INJECTOR 0xFFu
typedef void (*fi_emit_fn)(void *user, const co_frame_t *frame, uint8_t to, uint8_t from);
/* Node fault on the node of side `side`: kind FI_FREEZE (on = 1 freeze, 0 thaw) or FI_KILL. */
typedef void (*fi_node_fn)(void *user, uint8_t side, uint8_t kind, int on);

typedef struct {
    fi_rule_t rule[FI_MAX_RULES];
    uint32_t n_rules;
    uint32_t hits[FI_MAX_RULES];
    uint32_t nth[FI_MAX_RULES]; /* matches of the rule in the current period */
    int64_t period;
    uint16_t sync_cob;
    fi_held_t held[FI_MAX_HELD];
    uint32_t n_held;
    uint32_t held_overflow; /* frames that could not be held (dropped, logged) */
    fi_event_t log[FI_LOG_SIZE];
    uint32_t n_log;
    uint32_t log_overflow;
    uint64_t frames_in, frames_out;
    fi_emit_fn emit;
    fi_node_fn node;
    void *user;
} fi_t;

/* Start with no rules (every frame passes unchanged, in order). */
void fi_init(fi_t *fi, fi_emit_fn emit, fi_node_fn node, void *user);
/* Add a rule; returns its index or -1 (full, or a rule the injector cannot do). */
int fi_add_rule(fi_t *fi, const fi_rule_t *rule);
/* A frame from side `from` at the transport's time now_us. */
void fi_frame(fi_t *fi, const co_frame_t *frame, uint8_t from, int64_t now_us);
/* Whether the injector has no rule: every frame passes at once, unchanged, and nothing is ever held (the caller may
 * then hand each frame over itself and only count it with fi_pass, instead of fi_frame's call back). */
static inline int fi_passes_all(const fi_t *fi) { return fi->n_rules == 0u; }
/* What fi_frame does with a frame when the injector has no rule, but the emit: the frame and the period counted. */
void fi_pass(fi_t *fi, const co_frame_t *frame, uint8_t from);
/* Release frames delayed in microseconds whose time has come. */
void fi_tick(fi_t *fi, int64_t now_us);
/* Time of the next microsecond release, or -1 when none is held. */
int64_t fi_next_release_us(const fi_t *fi);

#endif /* FAULT_INJECTOR_H */
