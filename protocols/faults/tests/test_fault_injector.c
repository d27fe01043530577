/* test_fault_injector.c - the fault injector on a synthetic frame stream: one period is SYNC (side a),
 * the measurement 0x190 (side a), then the command 0x210 (side b); every action checked frame by frame. */
#include <string.h>

#include "check.h"
#include "fault_injector.h"
#include "fault_rules.h"

#define OUT_MAX 16384u

static struct {
    co_frame_t f[OUT_MAX];
    uint8_t to[OUT_MAX];
    uint32_t n;
    int frozen, killed;
} g;

static void emit(void *user, const co_frame_t *f, uint8_t to, uint8_t from)
{
    (void)user;
    (void)from;
    if (g.n < OUT_MAX) {
        g.f[g.n] = *f;
        g.to[g.n++] = to;
    }
}

static void node(void *user, uint8_t side, uint8_t kind, int on)
{
    (void)user;
    (void)side;
    if (kind == FI_KILL)
        g.killed = 1;
    else
        g.frozen = on;
}

static co_frame_t frame(uint16_t cob, uint8_t tag)
{
    co_frame_t f;
    memset(&f, 0, sizeof f);
    f.cob_id = cob;
    f.dlc = 8;
    f.data[0] = tag;
    return f;
}

/* periods 0 .. n-1: SYNC, measurement (tag = period), command (tag = period) */
static void run(fi_t *fi, uint32_t periods)
{
    for (uint32_t p = 0; p < periods; ++p) {
        co_frame_t s = frame(0x080, (uint8_t)p), m = frame(0x190, (uint8_t)p), c = frame(0x210, (uint8_t)p);
        s.dlc = 1;
        fi_frame(fi, &s, FI_SIDE_A, (int64_t)p * 100);
        fi_frame(fi, &m, FI_SIDE_A, (int64_t)p * 100 + 10);
        fi_frame(fi, &c, FI_SIDE_B, (int64_t)p * 100 + 20);
    }
}

static fi_t g_fi;

static fi_t *setup(const char *rules)
{
    memset(&g, 0, sizeof g);
    fi_init(&g_fi, emit, node, NULL);
    char err[256] = "";
    int n = fi_parse_rules(&g_fi, rules, err, sizeof err);
    CHECK(n >= 0, "rules refused: %s", err);
    return &g_fi;
}

static uint32_t count(uint16_t cob, int tag)
{
    uint32_t n = 0;
    for (uint32_t i = 0; i < g.n; ++i)
        if ((g.f[i].cob_id & 0x7FFu) == cob && (tag < 0 || g.f[i].data[0] == tag)) ++n;
    return n;
}

static int index_of(uint16_t cob, int tag, uint32_t nth)
{
    for (uint32_t i = 0; i < g.n; ++i)
        if ((g.f[i].cob_id & 0x7FFu) == cob && g.f[i].data[0] == tag && nth-- == 0u) return (int)i;
    return -1;
}

int main(void)
{
    fi_t *fi = setup("");
    run(fi, 10);
    CHECK(g.n == 30 && fi->period == 9, "no rules: every frame passes (%u), periods counted (%lld)", g.n,
          (long long)fi->period);
    CHECK(g.to[0] == FI_SIDE_B && g.to[2] == FI_SIDE_A, "a frame goes to the other side");

    fi = setup("kind=drop from=b cob=0x210 at=4");
    run(fi, 10);
    CHECK(count(0x210, 4) == 0 && count(0x210, -1) == 9, "drop: exactly the command of period 4");
    CHECK(fi->n_log == 1 && fi->log[0].period == 4 && fi->log[0].kind == FI_DROP, "drop logged with its period");

    fi = setup("kind=drop from=a cob=0x210 at=4");
    run(fi, 10);
    CHECK(count(0x210, -1) == 10, "a rule on the other side's sender takes nothing");

    fi = setup("kind=delay from=b cob=0x210 at=4 delay_periods=2");
    run(fi, 10);
    {
        int sync6 = index_of(0x080, 6, 0), late = index_of(0x210, 4, 0), meas6 = index_of(0x190, 6, 0);
        CHECK(late == sync6 + 1 && late < meas6, "delay 2 periods: out right after SYNC 6 (%d %d %d)", sync6, late,
              meas6);
    }

    fi = setup("kind=delay from=b cob=0x210 at=4 delay_us=50");
    run(fi, 6);
    CHECK(count(0x210, 4) == 1 && index_of(0x210, 4, 0) == index_of(0x080, 5, 0) - 1,
          "delay in us: due at 470 us, out before the next frame (SYNC 5 at 500 us)");
    fi = setup("kind=delay from=b cob=0x210 at=4 delay_us=1000");
    run(fi, 6);
    CHECK(count(0x210, 4) == 0 && fi_next_release_us(fi) == 420 + 1000, "held until its time (%lld)",
          (long long)fi_next_release_us(fi));
    fi_tick(fi, 1420);
    CHECK(count(0x210, 4) == 1, "fi_tick releases it");

    fi = setup("kind=duplicate from=a cob=0x190 at=3 periods=2");
    run(fi, 10);
    CHECK(count(0x190, 3) == 2 && count(0x190, 4) == 2 && count(0x190, 5) == 1, "duplicate in the window only");

    fi = setup("kind=corrupt from=a cob=0x190 at=2 bit=9\nkind=corrupt from=a cob=0x190 at=3 dlc=4");
    run(fi, 5);
    {
        int i2 = index_of(0x190, 2, 0), i3 = index_of(0x190, 3, 0);
        CHECK(i2 >= 0 && g.f[i2].data[1] == 0x02 && g.f[i2].dlc == 8, "bit 9 flipped");
        CHECK(i3 >= 0 && g.f[i3].dlc == 4, "new DLC");
    }

    fi = setup("kind=reorder from=a cob=0x190 at=5");
    run(fi, 8);
    CHECK(index_of(0x190, 5, 0) == index_of(0x080, 6, 0) + 1, "reorder: the measurement goes after the next frame "
                                                              "from its side (the SYNC)");

    fi = setup("kind=drop from=b cob=0x210 prob=0.25 seed=42 at=0 periods=4000");
    run(fi, 4000);
    uint32_t dropped = 4000u - count(0x210, -1);
    CHECK(dropped > 880 && dropped < 1120, "probability 0.25: %u of 4000", dropped);
    uint32_t first = dropped;
    fi = setup("kind=drop from=b cob=0x210 prob=0.25 seed=42 at=0 periods=4000");
    run(fi, 4000);
    CHECK(4000u - count(0x210, -1) == first, "same seed, same frames");
    fi = setup("kind=drop from=b cob=0x210 prob=0.25 seed=43 at=0 periods=4000 count=7");
    run(fi, 4000);
    CHECK(4000u - count(0x210, -1) == 7, "count limits the hits");

    fi = setup("kind=freeze from=b at=3 periods=2\nkind=kill from=b at=8\nkind=reset from=b at=6 node_id=0x20");
    g.frozen = 0;
    for (uint32_t p = 0; p < 10; ++p) {
        co_frame_t s = frame(0x080, (uint8_t)p);
        fi_frame(fi, &s, FI_SIDE_A, p);
        if (p == 3) CHECK(g.frozen == 1, "frozen at period 3");
        if (p == 5) CHECK(g.frozen == 0, "thawed at period 5");
        if (p == 7) CHECK(!g.killed, "not killed before period 8");
    }
    CHECK(g.killed, "killed at period 8");
    CHECK(count(0x000, 0x81) == 2, "reset: NMT reset node sent to both sides");
    {
        int r = index_of(0x000, 0x81, 0);
        CHECK(r >= 0 && g.f[r].data[1] == 0x20 && r < index_of(0x080, 6, 0), "the NMT reset before SYNC 6");
    }

    char err[256];
    fi_t bad;
    fi_init(&bad, emit, node, NULL);
    CHECK(fi_parse_rules(&bad, "kind=explode", err, sizeof err) < 0 && strstr(err, "kind=explode"), "%s", err);
    CHECK(fi_parse_rules(&bad, "kind=drop cob=0x800", err, sizeof err) < 0 && strstr(err, "cob"), "%s", err);
    CHECK(fi_parse_rules(&bad, "kind=drop colour=red", err, sizeof err) < 0 && strstr(err, "colour"), "%s", err);
    CHECK(fi_parse_rules(&bad, "kind=freeze from=any", err, sizeof err) < 0, "freeze needs a side");
    CHECK(fi_parse_rules(&bad, "kind=drop prob=0", err, sizeof err) < 0, "probability 0 refused");
    return check_finish("test_fault_injector");
}
