/*
 * session.c - peer sessions, retired sessions and the 64-number replay window.
 *
 * Behaviour matches controller/device/auth.py (ReplayWindow, PeerSessions) decision
 * for decision, so the firmware and the reference device drop the same packets.
 */
#include "session.h"

#include <string.h>

int64_t exo_serial_diff(uint32_t new_seq, uint32_t old_seq)
{
    uint32_t d = new_seq - old_seq; /* unsigned: wraps modulo 2^32 by definition */
    return d >= 0x80000000u ? (int64_t)d - 0x100000000 : (int64_t)d;
}

int exo_window_accept(exo_replay_window *w, uint32_t seq)
{
    if (!w->have_top) {
        w->have_top = 1;
        w->top = seq;
        w->bits = 1;
        return 1;
    }
    uint32_t ahead = seq - w->top;
    if (ahead != 0 && ahead < 0x80000000u) {
        /* Newer: slide the window up; numbers that fall off the bottom are forgotten
         * (and from then on count as too old). */
        w->bits = ahead < EXO_WINDOW ? (w->bits << ahead) | 1u : 1u;
        w->top = seq;
        return 1;
    }
    uint32_t back = w->top - seq;
    if (back >= EXO_WINDOW || ((w->bits >> back) & 1u))
        return 0;
    w->bits |= (uint64_t)1 << back;
    return 1;
}

void exo_peer_init(exo_peer_sessions *p) { memset(p, 0, sizeof *p); }

static int is_retired(const exo_peer_sessions *p, uint64_t session)
{
    for (uint32_t i = 0; i < p->n_retired; i++)
        if (p->retired[i] == session)
            return 1;
    return 0;
}

exo_peer_verdict exo_peer_check(exo_peer_sessions *p, uint64_t session, uint32_t seq)
{
    if (p->have_current && session == p->current)
        return exo_window_accept(&p->window, seq) ? EXO_PEER_OK : EXO_PEER_REPLAY;
    if (session == 0 || is_retired(p, session))
        return EXO_PEER_REPLAY;
    if (p->have_current) {
        /* Retire the old session; past 1024 the oldest is forgotten (a ring). */
        p->retired[p->next_retired] = p->current;
        p->next_retired = (p->next_retired + 1u) % EXO_RETIRED_MAX;
        if (p->n_retired < EXO_RETIRED_MAX)
            p->n_retired++;
    }
    p->have_current = 1;
    p->current = session;
    memset(&p->window, 0, sizeof p->window);
    exo_window_accept(&p->window, seq);
    return EXO_PEER_NEW;
}
