/*
 * test_session.c - RFC 1982 serial arithmetic, the 64-number replay window (also
 * across the 2^32 wrap), and peer sessions: new, current, retired, 0, and the 1024
 * retired sessions of which the oldest is forgotten.
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

static void window(void)
{
    exo_replay_window w;
    memset(&w, 0, sizeof w);
    CHECK(exo_window_accept(&w, 100) == 1); /* first number: anything */
    CHECK(exo_window_accept(&w, 100) == 0); /* duplicate */
    CHECK(exo_window_accept(&w, 101) == 1);
    CHECK(exo_window_accept(&w, 99) == 1);  /* late but unseen, inside the window */
    CHECK(exo_window_accept(&w, 99) == 0);
    CHECK(exo_window_accept(&w, 200) == 1); /* jump: the window slides */
    CHECK(exo_window_accept(&w, 137) == 1); /* 63 below the top: last slot */
    CHECK(exo_window_accept(&w, 136) == 0); /* 64 below: too old */
    CHECK(exo_window_accept(&w, 101) == 0);
    CHECK(exo_window_accept(&w, 137) == 0);
    CHECK(exo_window_accept(&w, 199) == 1);
    /* Slide by exactly 63 and 64: what was seen is kept or forgotten accordingly. */
    CHECK(exo_window_accept(&w, 263) == 1); /* 200 is now 63 below */
    CHECK(exo_window_accept(&w, 200) == 0);
    CHECK(exo_window_accept(&w, 264) == 1); /* 200 is now 64 below: too old */
    CHECK(exo_window_accept(&w, 200) == 0);
    CHECK(exo_window_accept(&w, 201) == 1); /* 63 below, never seen */

    /* Across the wrap. */
    memset(&w, 0, sizeof w);
    CHECK(exo_window_accept(&w, 0xFFFFFFFEu) == 1);
    CHECK(exo_window_accept(&w, 0xFFFFFFFFu) == 1);
    CHECK(exo_window_accept(&w, 0) == 1);
    CHECK(exo_window_accept(&w, 1) == 1);
    CHECK(exo_window_accept(&w, 0xFFFFFFFFu) == 0);
    CHECK(exo_window_accept(&w, 0xFFFFFFFEu) == 0);
    CHECK(exo_window_accept(&w, 0xFFFFFFFDu) == 1); /* 4 below the top, unseen */
    CHECK(w.top == 1);
    /* Half the number space ahead counts as behind (RFC 1982): too old, dropped. */
    CHECK(exo_window_accept(&w, 0x80000001u) == 0);
    CHECK(w.top == 1);
}

static exo_peer_sessions peers; /* 8 KiB: static, as in the device */

static void sessions(void)
{
    exo_peer_init(&peers);
    CHECK(exo_peer_check(&peers, 0, 1) == EXO_PEER_REPLAY); /* 0 is "unknown", never a sender */
    CHECK(peers.have_current == 0);
    CHECK(exo_peer_check(&peers, 0xAAAA, 1) == EXO_PEER_NEW);
    CHECK(exo_peer_check(&peers, 0xAAAA, 2) == EXO_PEER_OK);
    CHECK(exo_peer_check(&peers, 0xAAAA, 2) == EXO_PEER_REPLAY);
    CHECK(exo_peer_check(&peers, 0, 3) == EXO_PEER_REPLAY);
    /* The peer restarts: new session, fresh window (number 1 again is fine). */
    CHECK(exo_peer_check(&peers, 0xBBBB, 1) == EXO_PEER_NEW);
    CHECK(exo_peer_check(&peers, 0xBBBB, 1) == EXO_PEER_REPLAY);
    CHECK(exo_peer_check(&peers, 0xAAAA, 50) == EXO_PEER_REPLAY); /* retired */
    CHECK(peers.current == 0xBBBB);
    CHECK(peers.n_retired == 1);

    /* 1024 retired sessions are remembered; the 1025th retirement forgets the oldest. */
    exo_peer_init(&peers);
    for (uint64_t s = 1; s <= 1025; s++)
        CHECK_EQ(exo_peer_check(&peers, s, 0), EXO_PEER_NEW);
    CHECK_EQ(peers.n_retired, 1024); /* sessions 1..1024 retired, 1025 current */
    CHECK(exo_peer_check(&peers, 1, 9) == EXO_PEER_REPLAY);
    CHECK(exo_peer_check(&peers, 1024, 9) == EXO_PEER_REPLAY);
    CHECK(exo_peer_check(&peers, 1026, 0) == EXO_PEER_NEW);   /* retires 1025, forgets 1 */
    CHECK(exo_peer_check(&peers, 2, 9) == EXO_PEER_REPLAY);   /* still remembered */
    CHECK(exo_peer_check(&peers, 1025, 9) == EXO_PEER_REPLAY);
    CHECK(exo_peer_check(&peers, 1, 9) == EXO_PEER_NEW);      /* forgotten: looks new */
}

void test_session(void)
{
    serial();
    window();
    sessions();
}
