/* hil_master.c - the master's side of direct mode: the recorder and the master's receive queue (see hil_master.h). */
#include "hil_master.h"

#include <string.h>

#include "co_membus.h"
#include "hil_lock.h"

#define MASTER_Q 1024u

static struct {
    uint32_t seq; /* bus order */
    void *rec;    /* hil_frame_t, or hil_frame_fd_t when wide */
    int wide;
    uint32_t rec_cap, rec_n;
    uint64_t rec_dropped;
    hil_frame_t mq[MASTER_Q];
    uint32_t mq_head, mq_tail;
    uint64_t mq_dropped;
} M;

void hil_master_reset(void) { memset(&M, 0, sizeof M); }

static void record_wide(const co_frame_t *f, uint8_t sender, int64_t t_us, uint32_t seq)
{
    if (M.rec_n >= M.rec_cap) {
        ++M.rec_dropped;
        return;
    }
    hil_frame_fd_t *r = &((hil_frame_fd_t *)M.rec)[M.rec_n++];
    uint8_t n = f->dlc > 64u ? 64u : f->dlc;
    r->t_us = (uint64_t)t_us;
    r->seq = seq;
    r->cob_id = (uint16_t)(f->cob_id & 0x7FFu);
    r->dlc = n;
    r->sender = sender;
    memcpy(r->data, f->data, n);
    memset(&r->data[n], 0, (size_t)(64u - n));
    r->flags =
        (uint8_t)(((f->flags & CO_FRAME_FDF) ? HIL_FRAME_FDF : 0u) | ((f->flags & CO_FRAME_BRS) ? HIL_FRAME_BRS : 0u));
    memset(r->pad, 0, sizeof r->pad);
}

void hil_master_record(const co_frame_t *f, uint8_t sender, int64_t t_us, int running)
{
    /* nobody to keep it for: no recorder, and the master does not get the loop's frames */
    if (M.rec == NULL && (running || sender == CO_MEMBUS_EXTERNAL)) {
        ++M.seq;
        return;
    }
    hil_frame_t r;
    memset(&r, 0, sizeof r);
    r.t_us = (uint64_t)t_us;
    r.seq = M.seq++;
    r.cob_id = (uint16_t)(f->cob_id & 0x7FFu);
    r.dlc = f->dlc > 8u ? 8u : f->dlc; /* the master's queue: SDO answers, classic frames */
    r.sender = sender;
    memcpy(r.data, f->data, r.dlc);
    if (M.rec && M.wide) {
        record_wide(f, sender, t_us, r.seq);
    } else if (M.rec) {
        if (M.rec_n < M.rec_cap && f->dlc <= 8u)
            ((hil_frame_t *)M.rec)[M.rec_n++] = r;
        else
            ++M.rec_dropped; /* full, or a CAN FD frame the classic record cannot hold */
    }
    /* The master sees every frame of the nodes, like a CAN controller would, except the
     * PDO stream of a run (it reads the recorder instead). */
    if (sender != CO_MEMBUS_EXTERNAL && !running && f->dlc <= 8u) { /* SDO answers, heartbeats: classic frames */
        if (M.mq_tail - M.mq_head < MASTER_Q)
            M.mq[M.mq_tail++ % MASTER_Q] = r;
        else
            ++M.mq_dropped;
    }
}

uint32_t hil_master_mark(void) { return M.mq_tail; }

int hil_master_answer(uint32_t mark, uint16_t resp_cob, uint8_t resp[8])
{
    for (uint32_t i = mark; i != M.mq_tail; ++i) {
        if (M.mq[i % MASTER_Q].cob_id != resp_cob || M.mq[i % MASTER_Q].dlc != 8u) continue;
        memcpy(resp, M.mq[i % MASTER_Q].data, 8u);
        for (uint32_t j = i; j + 1u != M.mq_tail; ++j) M.mq[j % MASTER_Q] = M.mq[(j + 1u) % MASTER_Q];
        --M.mq_tail;
        return 1;
    }
    return 0;
}

void hil_set_recorder(void *buf, uint32_t capacity)
{
    M.rec = buf;
    M.rec_cap = capacity;
    M.rec_n = 0;
    M.rec_dropped = 0;
}

void hil_set_recorder_fd(int wide) { M.wide = wide != 0; }

uint32_t hil_take(void *buf, uint32_t capacity)
{
    hil_lock();
    uint32_t n = M.rec_n;
    M.rec = buf;
    M.rec_cap = capacity;
    M.rec_n = 0;
    hil_unlock();
    return n;
}

uint32_t hil_recorded(void) { return M.rec_n; }
uint64_t hil_record_dropped(void) { return M.rec_dropped; }

int hil_recv(hil_frame_t *out)
{
    hil_lock();
    int got = M.mq_head != M.mq_tail;
    if (got) *out = M.mq[M.mq_head++ % MASTER_Q];
    hil_unlock();
    return got;
}
