/*
 * session.h - the peer's sessions and the replay window (protocol "Authentication,
 * sessions and replays"; the Python twin is controller/device/auth.py).
 *
 * An authentic packet can still be a recording. The receiver remembers the peer's
 * current session number, the sessions it saw replaced (a restarted peer never comes
 * back with an old number, so an old number is a replay), and which of the last 64
 * sequence numbers of the current session it has seen (RFC 4303 section 3.4.3).
 */
#ifndef EXO_SESSION_H
#define EXO_SESSION_H

#include <stdint.h>

#define EXO_WINDOW 64u         /* sequence numbers remembered per session */
#define EXO_RETIRED_MAX 1024u  /* replaced peer sessions remembered; oldest forgotten */

/* Signed distance from `old` to `new` in uint32 serial arithmetic (RFC 1982): > 0 if
 * `new` is later, < 0 if earlier, also across the wrap. A distance of exactly 2^31 is
 * "earlier", as in the Python seq_diff. */
int64_t exo_serial_diff(uint32_t new_seq, uint32_t old_seq);

typedef struct {
    int have_top;  /* 0 until the first number */
    uint32_t top;  /* highest number seen */
    uint64_t bits; /* bit i: top - i was seen */
} exo_replay_window;

/* 1 if `seq` is new and inside the window (it is then marked), 0 if it is a replay. */
int exo_window_accept(exo_replay_window *w, uint32_t seq);

typedef enum {
    EXO_PEER_OK = 0,     /* a new number in the current session */
    EXO_PEER_NEW = 1,    /* a session never seen: the peer restarted; now current */
    EXO_PEER_REPLAY = -1 /* seen before, too old, or a replaced session */
} exo_peer_verdict;

typedef struct {
    int have_current;
    uint64_t current;
    exo_replay_window window;
    uint64_t retired[EXO_RETIRED_MAX]; /* ring of replaced sessions */
    uint32_t n_retired;                /* how many are valid (<= EXO_RETIRED_MAX) */
    uint32_t next_retired;             /* slot the next retired session overwrites */
} exo_peer_sessions;

void exo_peer_init(exo_peer_sessions *p);

/* Classify one authentic packet from session `session` with sequence `seq`. Session 0
 * ("unknown" on the wire) is never accepted as a sender. */
exo_peer_verdict exo_peer_check(exo_peer_sessions *p, uint64_t session, uint32_t seq);

#endif /* EXO_SESSION_H */
