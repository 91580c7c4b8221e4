/*
 * session.h - what the device remembers about the host (protocol "The device's
 * rules"): one host session with its last applied host_seq, one single-use challenge,
 * and the send times of its last 16 samples. Nothing grows and nothing is a list an
 * attacker could overflow; the Python twin is controller/sim/device_server.py.
 */
#ifndef EXO_SESSION_H
#define EXO_SESSION_H

#include <stdint.h>

#include "wire.h"

#define EXO_SENT_RING 16u                 /* samples whose send time is kept */
#define EXO_FRESH_US 100000u              /* a COMMAND must echo a sample this recent */
#define EXO_CHALLENGE_LIFETIME_MS 1000u   /* a JOIN must answer a challenge this recent */
#define EXO_CHALLENGE_REDRAW_US 500000u   /* a HELLO redraws a challenge older than this */

/* Signed distance from `old` to `new` in uint32 serial arithmetic (RFC 1982): > 0 if
 * `new` is later, < 0 if earlier, also across the wrap. A distance of exactly 2^31 is
 * "earlier", as in the Python seq_diff. */
int64_t exo_serial_diff(uint32_t new_seq, uint32_t old_seq);

/* The device's one challenge. */
typedef struct {
    int present;  /* drawn at least once */
    int spent;    /* a JOIN has used it */
    uint64_t drawn_us;
    uint8_t bytes[EXO_CHALLENGE_BYTES];
} exo_challenge;

/* 1 if the challenge must be redrawn before it is sent at `now_us`: absent, spent, or
 * drawn more than EXO_CHALLENGE_REDRAW_US ago. */
int exo_challenge_stale(const exo_challenge *c, uint64_t now_us);

/* 1 if `answer` (from a JOIN arriving at `now_us`) is the present, unspent challenge,
 * at most EXO_CHALLENGE_LIFETIME_MS old. The bytes are compared in constant time. */
int exo_challenge_accepts(const exo_challenge *c, const uint8_t answer[EXO_CHALLENGE_BYTES],
                          uint64_t now_us);

/* Send and due times of the latest EXO_SENT_RING samples of the current host session.
 * The send time decides freshness and the round trip; the due time (the sample's
 * `t_us` on the device clock, at or before its send time) starts the 100 ms for which
 * a command echoing it may hold the outputs. */
typedef struct {
    uint32_t seq[EXO_SENT_RING];
    uint64_t sent_us[EXO_SENT_RING];
    uint64_t due_us[EXO_SENT_RING];
    uint8_t valid[EXO_SENT_RING];
} exo_sent_ring;

void exo_sent_clear(exo_sent_ring *r);
void exo_sent_note(exo_sent_ring *r, uint32_t seq, uint64_t sent_us, uint64_t due_us);
/* The slot of sample `seq` if it is in the ring and was sent at most EXO_FRESH_US
 * before `now_us`, else -1. */
int exo_sent_fresh(const exo_sent_ring *r, uint32_t seq, uint64_t now_us);

/* The host as far as the device knows it. */
typedef struct {
    int joined;             /* a JOIN has been accepted this boot */
    uint64_t session;       /* H */
    uint32_t last_host_seq; /* of the latest JOIN or applied COMMAND */
    exo_endpoint addr;      /* where samples go: the latest JOIN's source */
} exo_host;

#endif /* EXO_SESSION_H */
