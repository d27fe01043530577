/* fault_injector.c - see fault_injector.h. Portable: no OS headers, no allocation. */
#include "fault_injector.h"

#include <string.h>

#define SYNC_COB 0x080u
#define NMT_COB 0x000u
#define NMT_RESET_NODE 0x81u

void fi_init(fi_t *fi, fi_emit_fn emit, fi_node_fn node, void *user)
{
    memset(fi, 0, sizeof *fi);
    fi->period = -1;
    fi->sync_cob = SYNC_COB;
    fi->emit = emit;
    fi->node = node;
    fi->user = user;
}

static int is_frame_fault(uint8_t kind) { return kind >= FI_DROP && kind <= FI_REORDER; }

int fi_add_rule(fi_t *fi, const fi_rule_t *r)
{
    if (fi->n_rules >= FI_MAX_RULES) return -1;
    if (r->kind < FI_DROP || r->kind > FI_RESET || r->kind == FI_THAW) return -1;
    if (r->from > FI_SIDE_ANY || r->periods == 0u) return -1;
    if (r->kind == FI_CORRUPT && r->dlc > 8) return -1;
    if ((r->kind == FI_FREEZE || r->kind == FI_KILL) && r->from == FI_SIDE_ANY) return -1;
    fi->rule[fi->n_rules] = *r;
    return (int)fi->n_rules++;
}

static void log_event(fi_t *fi, uint16_t rule, uint8_t kind, uint8_t from, const co_frame_t *f, int64_t now_us)
{
    if (fi->n_log >= FI_LOG_SIZE) {
        ++fi->log_overflow;
        return;
    }
    fi_event_t *e = &fi->log[fi->n_log++];
    memset(e, 0, sizeof *e);
    e->period = fi->period;
    e->t_us = now_us;
    e->rule = rule;
    e->kind = kind;
    e->from = from;
    if (f != NULL) {
        e->cob_id = (uint16_t)(f->cob_id & 0x7FFu);
        e->dlc = f->dlc;
        memcpy(e->data, f->data, sizeof e->data);
    }
}

static void out(fi_t *fi, const co_frame_t *f, uint8_t from)
{
    ++fi->frames_out;
    fi->emit(fi->user, f, (uint8_t)(from == FI_SIDE_A ? FI_SIDE_B : FI_SIDE_A), from);
}

/* splitmix64's finaliser over (seed, rule, period, n-th match): the draw depends on nothing else. */
static uint64_t draw(uint64_t seed, uint32_t rule, int64_t period, uint32_t nth)
{
    uint64_t x = seed * 0x9E3779B97F4A7C15ull + (uint64_t)rule * 0xBF58476D1CE4E5B9ull +
                 (uint64_t)period * 0x94D049BB133111EBull + (uint64_t)nth;
    x ^= x >> 30;
    x *= 0xBF58476D1CE4E5B9ull;
    x ^= x >> 27;
    x *= 0x94D049BB133111EBull;
    x ^= x >> 31;
    return x >> 32;
}

static int in_window(const fi_t *fi, const fi_rule_t *r)
{
    if (fi->period < 0) return 0;
    uint64_t p = (uint64_t)fi->period;
    return p >= r->at_period && p < (uint64_t)r->at_period + r->periods;
}

static void hold(fi_t *fi, const co_frame_t *f, uint8_t from, uint16_t rule, uint8_t kind, int64_t rp, int64_t rus,
                 int64_t now_us)
{
    if (fi->n_held >= FI_MAX_HELD) {
        ++fi->held_overflow;
        log_event(fi, rule, FI_DROP, from, f, now_us);
        return;
    }
    fi_held_t *h = &fi->held[fi->n_held++];
    h->frame = *f;
    h->from = from;
    h->kind = kind;
    h->rule = rule;
    h->release_period = rp;
    h->release_us = rus;
}

/* Send the held frames that `due` selects, in the order they were held. */
static void release(fi_t *fi, int (*due)(const fi_held_t *, const void *), const void *arg, int64_t now_us)
{
    uint32_t keep = 0;
    for (uint32_t i = 0; i < fi->n_held; ++i) {
        fi_held_t h = fi->held[i];
        if (due(&h, arg)) {
            log_event(fi, h.rule, FI_RELEASE, h.from, &h.frame, now_us);
            out(fi, &h.frame, h.from);
        } else {
            fi->held[keep++] = h;
        }
    }
    fi->n_held = keep;
}

static int due_period(const fi_held_t *h, const void *arg)
{
    return h->release_period >= 0 && h->release_period <= *(const int64_t *)arg;
}

static int due_time(const fi_held_t *h, const void *arg)
{
    return h->release_us >= 0 && h->release_us <= *(const int64_t *)arg;
}

static int due_reorder(const fi_held_t *h, const void *arg)
{
    return h->kind == FI_REORDER && h->from == *(const uint8_t *)arg;
}

/* Node faults that start (or end) with the period just begun: before its SYNC goes out. */
static void node_faults(fi_t *fi, int64_t now_us)
{
    for (uint32_t i = 0; i < fi->n_rules; ++i) {
        const fi_rule_t *r = &fi->rule[i];
        const int64_t p = fi->period;
        if (r->kind == FI_FREEZE && p == (int64_t)r->at_period) {
            log_event(fi, (uint16_t)i, FI_FREEZE, r->from, NULL, now_us);
            ++fi->hits[i];
            if (fi->node) fi->node(fi->user, r->from, FI_FREEZE, 1);
        } else if (r->kind == FI_FREEZE && p == (int64_t)r->at_period + (int64_t)r->periods) {
            log_event(fi, (uint16_t)i, FI_THAW, r->from, NULL, now_us);
            if (fi->node) fi->node(fi->user, r->from, FI_FREEZE, 0);
        } else if (r->kind == FI_KILL && p == (int64_t)r->at_period) {
            log_event(fi, (uint16_t)i, FI_KILL, r->from, NULL, now_us);
            ++fi->hits[i];
            if (fi->node) fi->node(fi->user, r->from, FI_KILL, 1);
        } else if (r->kind == FI_RESET && p == (int64_t)r->at_period) {
            co_frame_t nmt;
            memset(&nmt, 0, sizeof nmt);
            nmt.cob_id = NMT_COB;
            nmt.dlc = 2;
            nmt.data[0] = NMT_RESET_NODE;
            nmt.data[1] = r->node_id;
            log_event(fi, (uint16_t)i, FI_RESET, r->from, &nmt, now_us);
            ++fi->hits[i];
            fi->frames_out += 2u;
            fi->emit(fi->user, &nmt, FI_SIDE_A, FI_FROM_INJECTOR);
            fi->emit(fi->user, &nmt, FI_SIDE_B, FI_FROM_INJECTOR);
        }
    }
}

/* The first frame rule that takes this frame, or -1. */
static int match(fi_t *fi, const co_frame_t *f, uint8_t from)
{
    const uint16_t cob = (uint16_t)(f->cob_id & 0x7FFu);
    for (uint32_t i = 0; i < fi->n_rules; ++i) {
        const fi_rule_t *r = &fi->rule[i];
        if (!is_frame_fault(r->kind) || !in_window(fi, r)) continue;
        if (r->cob_id != FI_ANY_COB && r->cob_id != cob) continue;
        if (r->from != FI_SIDE_ANY && r->from != from) continue;
        if (r->count != 0u && fi->hits[i] >= r->count) continue;
        const uint32_t nth = fi->nth[i]++;
        if (r->threshold < FI_ALWAYS && draw(r->seed, i, fi->period, nth) >= r->threshold) continue;
        ++fi->hits[i];
        return (int)i;
    }
    return -1;
}

static int is_sync(const fi_t *fi, const co_frame_t *frame, uint8_t from)
{
    return from == FI_SIDE_A && (frame->cob_id & 0x7FFu) == fi->sync_cob && !(frame->cob_id & CO_FRAME_RTR);
}

void fi_pass(fi_t *fi, const co_frame_t *frame, uint8_t from)
{
    ++fi->frames_in;
    ++fi->frames_out;
    if (is_sync(fi, frame, from)) ++fi->period;
}

void fi_frame(fi_t *fi, const co_frame_t *frame, uint8_t from, int64_t now_us)
{
    ++fi->frames_in;
    if (fi->n_held) release(fi, due_time, &now_us, now_us); /* held in us and due: before what comes after */
    const int sync = is_sync(fi, frame, from);
    if (sync) {
        ++fi->period;
        memset(fi->nth, 0, fi->n_rules * sizeof fi->nth[0]); /* the rules in use (the others stay 0) */
        node_faults(fi, now_us);
    }
    const int i = fi->n_rules ? match(fi, frame, from) : -1;
    if (i < 0) {
        out(fi, frame, from);
    } else {
        const fi_rule_t *r = &fi->rule[i];
        const uint16_t ri = (uint16_t)i;
        log_event(fi, ri, r->kind, from, frame, now_us);
        switch (r->kind) {
        case FI_DROP: break;
        case FI_DELAY:
            if (r->delay_us != 0u)
                hold(fi, frame, from, ri, FI_DELAY, -1, now_us + (int64_t)r->delay_us, now_us);
            else
                hold(fi, frame, from, ri, FI_DELAY, fi->period + (int64_t)r->delay_periods, -1, now_us);
            break;
        case FI_DUPLICATE:
            out(fi, frame, from);
            out(fi, frame, from);
            break;
        case FI_CORRUPT: {
            co_frame_t c = *frame;
            if (r->dlc >= 0) {
                for (uint8_t b = c.dlc < (uint8_t)r->dlc ? c.dlc : (uint8_t)r->dlc; b < 8u; ++b) c.data[b] = 0u;
                c.dlc = (uint8_t)r->dlc;
            } else if (r->bit < 8u * c.dlc) {
                c.data[r->bit / 8u] ^= (uint8_t)(1u << (r->bit % 8u));
            } /* a bit beyond the frame's data: sent unchanged (the log keeps the frame as it was) */
            out(fi, &c, from);
            break;
        }
        case FI_REORDER: hold(fi, frame, from, ri, FI_REORDER, -1, -1, now_us); break;
        default: out(fi, frame, from); break;
        }
    }
    if (fi->n_held) {
        if (i < 0 || fi->rule[i].kind != FI_REORDER) release(fi, due_reorder, &from, now_us);
        if (sync) release(fi, due_period, &fi->period, now_us);
    }
}

void fi_tick(fi_t *fi, int64_t now_us)
{
    if (fi->n_held) release(fi, due_time, &now_us, now_us);
}

int64_t fi_next_release_us(const fi_t *fi)
{
    int64_t t = -1;
    for (uint32_t i = 0; i < fi->n_held; ++i)
        if (fi->held[i].release_us >= 0 && (t < 0 || fi->held[i].release_us < t)) t = fi->held[i].release_us;
    return t;
}
