/* fz_core_packet.c - see fz_core_packet.h. */
#include "fz_core_packet.h"

#include <string.h>

const char *fz_core_decode(const exo_hmac_key *key, const uint8_t *d, size_t n, fz_pkt *o)
{
    exo_packet p;
    memset(&p, 0, sizeof p);
    memset(o, 0, sizeof *o);
    exo_drop_reason r = exo_wire_decode(key, d, n, &p);
    if (r != EXO_DROP_NONE)
        return exo_drop_reason_name(r);
    o->version = p.version;
    o->type = p.type;
    o->sender = p.sender;
    o->receiver = p.receiver;
    switch (p.type) {
    case EXO_TYPE_SAMPLE:
        o->t_us = p.sample.t_us;
        o->seq = p.sample.seq;
        o->status = p.sample.status;
        memcpy(o->counts, p.sample.counts, sizeof o->counts);
        o->auth_drops = p.sample.auth_drops;
        o->replay_drops = p.sample.replay_drops;
        o->stale_drops = p.sample.stale_drops;
        o->has_truth = p.sample.has_truth != 0;
        if (o->has_truth) {
            memcpy(&o->progress_bits, &p.sample.truth.progress, sizeof o->progress_bits);
            o->lift_index = p.sample.truth.lift_index;
            o->activity_len = p.sample.truth.activity_len;
            memcpy(o->activity, p.sample.truth.activity, p.sample.truth.activity_len);
        }
        break;
    case EXO_TYPE_COMMAND:
        o->host_seq = p.host_seq;
        o->echo_seq = p.echo_seq;
        o->locks = p.locks;
        o->stop_heartbeat = p.stop_heartbeat != 0;
        break;
    case EXO_TYPE_HELLO:
        o->host_seq = p.host_seq;
        break;
    case EXO_TYPE_CHALLENGE:
        o->hello_seq = p.challenge.hello_seq;
        o->lifetime_ms = p.challenge.lifetime_ms;
        memcpy(o->challenge, p.challenge.challenge, 16);
        memcpy(o->unique_id, p.challenge.unique_id, 16);
        memcpy(o->firmware, p.challenge.firmware, 16);
        break;
    case EXO_TYPE_JOIN:
        o->host_seq = p.host_seq;
        memcpy(o->challenge, p.join_challenge, 16);
        break;
    case EXO_TYPE_VERSION:
        o->lowest = p.lowest;
        o->highest = p.highest;
        break;
    default:
        break;
    }
    return "ok";
}

#define SAME(x) \
    if (c->x != m->x) \
        return __LINE__
#define SAME_BYTES(x, n) \
    if (memcmp(c->x, m->x, n) != 0) \
        return __LINE__

int fz_pkt_diff(const fz_pkt *c, const fz_pkt *m)
{
    SAME(type);
    SAME(version);
    SAME(sender);
    SAME(receiver);
    switch (m->type) {
    case FZ_T_SAMPLE: {
        SAME(t_us);
        SAME(seq);
        SAME(status);
        SAME_BYTES(counts, sizeof m->counts);
        SAME(auth_drops);
        SAME(replay_drops);
        SAME(stale_drops);
        SAME(has_truth);
        if (m->has_truth) {
            SAME(progress_bits);
            SAME(lift_index);
            /* The core keeps the first 64 bytes of a longer (still valid) name. */
            size_t keep = m->activity_len > 64 ? 64u : m->activity_len;
            if (c->activity_len != keep)
                return __LINE__;
            SAME_BYTES(activity, keep);
        }
        break;
    }
    case FZ_T_COMMAND:
        SAME(host_seq);
        SAME(echo_seq);
        SAME(locks);
        SAME(stop_heartbeat);
        break;
    case FZ_T_HELLO:
        SAME(host_seq);
        break;
    case FZ_T_CHALLENGE:
        SAME(hello_seq);
        SAME(lifetime_ms);
        SAME_BYTES(challenge, 16);
        SAME_BYTES(unique_id, 16);
        SAME_BYTES(firmware, 16);
        break;
    case FZ_T_JOIN:
        SAME(host_seq);
        SAME_BYTES(challenge, 16);
        break;
    default:
        SAME(lowest);
        SAME(highest);
        break;
    }
    return 0;
}
