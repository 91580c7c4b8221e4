/*
 * session.c - the device's host session, challenge and sent-sample ring (session.h).
 */
#include "session.h"

#include <string.h>

int64_t exo_serial_diff(uint32_t new_seq, uint32_t old_seq)
{
    uint32_t d = new_seq - old_seq; /* unsigned: wraps modulo 2^32 by definition */
    return d >= 0x80000000u ? (int64_t)d - 0x100000000 : (int64_t)d;
}

int exo_challenge_stale(const exo_challenge *c, uint64_t now_us)
{
    return !c->present || c->spent || now_us < c->drawn_us
           || now_us - c->drawn_us > EXO_CHALLENGE_REDRAW_US;
}

int exo_challenge_accepts(const exo_challenge *c, const uint8_t answer[EXO_CHALLENGE_BYTES],
                          uint64_t now_us)
{
    /* The comparison runs whatever the other conditions say, so its time tells a
     * forger nothing (not even whether a challenge is out). */
    int same = exo_ct_equal(c->bytes, answer, EXO_CHALLENGE_BYTES);
    int fresh = now_us >= c->drawn_us
                && now_us - c->drawn_us <= (uint64_t)EXO_CHALLENGE_LIFETIME_MS * 1000u;
    return same && c->present && !c->spent && fresh;
}

void exo_sent_clear(exo_sent_ring *r) { memset(r, 0, sizeof *r); }

void exo_sent_note(exo_sent_ring *r, uint32_t seq, uint64_t sent_us, uint64_t due_us)
{
    uint32_t slot = seq % EXO_SENT_RING;
    r->seq[slot] = seq;
    r->sent_us[slot] = sent_us;
    r->due_us[slot] = due_us <= sent_us ? due_us : sent_us;
    r->valid[slot] = 1;
}

int exo_sent_fresh(const exo_sent_ring *r, uint32_t seq, uint64_t now_us)
{
    uint32_t slot = seq % EXO_SENT_RING;
    if (!r->valid[slot] || r->seq[slot] != seq)
        return -1; /* never sent, or overwritten by a later sample: unknown */
    if (now_us < r->sent_us[slot] || now_us - r->sent_us[slot] > EXO_FRESH_US)
        return -1;
    return (int)slot;
}
