/*
 * test_session.c - RFC 1982 serial arithmetic (also across the 2^32 wrap), the
 * single-use challenge (redraw age, lifetime, spent, constant-time match), and the
 * ring of the last 16 samples' send times (freshness, overwrite, wrap of seq).
 */
#include <string.h>

#include "check.h"
#include "session.h"

static void serial(void)
{
    CHECK(exo_serial_diff(5, 4) == 1);
    CHECK(exo_serial_diff(4, 5) == -1);
    CHECK(exo_serial_diff(7, 7) == 0);
    CHECK(exo_serial_diff(0, 0xFFFFFFFFu) == 1);   /* across the wrap: later */
    CHECK(exo_serial_diff(0xFFFFFFFFu, 0) == -1);
    CHECK(exo_serial_diff(0x7FFFFFFFu, 0) == 0x7FFFFFFF);
    CHECK(exo_serial_diff(0x80000000u, 0) == -0x80000000LL); /* exactly half: earlier */
    CHECK(exo_serial_diff(0x10, 0x80000010u) == -0x80000000LL);
    CHECK(exo_serial_diff(10, 0x80000010u) == 0x7FFFFFFA);
}

static void challenge(void)
{
    exo_challenge c;
    memset(&c, 0, sizeof c);
    uint8_t answer[EXO_CHALLENGE_BYTES];
    memset(answer, 0, sizeof answer);
    CHECK(exo_challenge_stale(&c, 0) == 1);          /* absent */
    CHECK(exo_challenge_accepts(&c, answer, 0) == 0); /* zeros match, but none is out */

    const uint64_t t0 = 0xFFFFFFF0ull; /* near the 32-bit microsecond wrap (71 min) */
    c.present = 1;
    c.drawn_us = t0;
    memset(c.bytes, 0x5A, sizeof c.bytes);
    memcpy(answer, c.bytes, sizeof answer);
    CHECK(exo_challenge_stale(&c, t0 + 500000) == 0);
    CHECK(exo_challenge_stale(&c, t0 + 500001) == 1); /* older than 500 ms: redraw */
    CHECK(exo_challenge_accepts(&c, answer, t0) == 1);
    CHECK(exo_challenge_accepts(&c, answer, t0 + 1000000) == 1);
    CHECK(exo_challenge_accepts(&c, answer, t0 + 1000001) == 0); /* expired */
    CHECK(exo_challenge_accepts(&c, answer, t0 - 1) == 0);       /* clock went back */
    for (unsigned i = 0; i < EXO_CHALLENGE_BYTES; i++)
        for (unsigned bit = 0; bit < 8; bit++) {
            answer[i] = (uint8_t)(answer[i] ^ (1u << bit));
            CHECK(exo_challenge_accepts(&c, answer, t0 + 1) == 0);
            answer[i] = c.bytes[i];
        }
    c.spent = 1;
    CHECK(exo_challenge_accepts(&c, answer, t0 + 1) == 0);
    CHECK(exo_challenge_stale(&c, t0 + 1) == 1); /* spent: a HELLO redraws */
}

static void sent_ring(void)
{
    exo_sent_ring r;
    exo_sent_clear(&r);
    CHECK(exo_sent_fresh(&r, 0, 0) == -1); /* cleared: slot 0 holds seq 0, but invalid */
    const uint64_t t0 = 5000000;
    /* 20 samples across the u32 wrap: 0xFFFFFFF6 .. 0x00000009 */
    for (uint32_t i = 0; i < 20; i++)
        exo_sent_note(&r, 0xFFFFFFF6u + i, t0 + 10000u * i, t0 + 10000u * i - 300u);
    uint64_t now = t0 + 10000u * 19;
    CHECK(exo_sent_fresh(&r, 0xFFFFFFF6u, now) == -1); /* overwritten by a later one */
    CHECK(exo_sent_fresh(&r, 0xFFFFFFF9u, now) == -1);
    CHECK(exo_sent_fresh(&r, 0xFFFFFFFAu, now) == -1); /* in the ring, but 150 ms old */
    CHECK(exo_sent_fresh(&r, 0xFFFFFFFEu, now) == -1); /* 110 ms old */
    CHECK(exo_sent_fresh(&r, 0xFFFFFFFFu, now) >= 0);  /* exactly 100 ms: fresh */
    CHECK(exo_sent_fresh(&r, 0, now) >= 0);             /* 90 ms: fresh */
    CHECK(exo_sent_fresh(&r, 9, now) >= 0);
    CHECK(exo_sent_fresh(&r, 10, now) == -1); /* never sent */
    /* exactly 100 ms is still fresh; one microsecond more is not */
    CHECK(exo_sent_fresh(&r, 9, now + 100000) >= 0);
    CHECK(exo_sent_fresh(&r, 9, now + 100001) == -1);
    /* Freshness is judged by the send time; the due time is kept beside it (never
     * after the send time) for the watchdog. */
    int slot = exo_sent_fresh(&r, 9, now);
    CHECK(slot >= 0);
    CHECK_EQ(r.sent_us[slot], now);
    CHECK_EQ(r.due_us[slot], now - 300u);
    exo_sent_note(&r, 11, now, now + 5u); /* a due time after the send: clamped */
    slot = exo_sent_fresh(&r, 11, now);
    CHECK(slot >= 0);
    CHECK_EQ(r.due_us[slot], now);
    exo_sent_clear(&r);
    CHECK(exo_sent_fresh(&r, 9, now) == -1);
}

void test_session(void)
{
    serial();
    challenge();
    sent_ring();
}
