/* fz_device_model.c - see fz_device_model.h. */
#include "fz_device_model.h"

#include <string.h>

const char *fz_count_name(fz_count c, fz_reason r)
{
    switch (c) {
    case FZ_C_FOREIGN: return "foreign";
    case FZ_C_FLOOD: return "flood";
    case FZ_C_MALFORMED: return fz_reason_name(r);
    case FZ_C_UNEXPECTED: return "unexpected";
    case FZ_C_HELLO: return "hello";
    case FZ_C_JOIN: return "join";
    case FZ_C_COMMAND: return "command";
    case FZ_C_REPLAY: return "replay";
    case FZ_C_STALE: return "stale_echo";
    default: return "nothing";
    }
}

void fz_model_init(fz_model *m, const uint8_t key[32], uint32_t host_ip,
                   const uint8_t unique_id[16], const uint8_t firmware[16])
{
    memset(m, 0, sizeof *m);
    memcpy(m->key, key, 32);
    m->host_ip = host_ip;
    memcpy(m->unique_id, unique_id, 16);
    memcpy(m->firmware, firmware, 16);
}

/* RFC 1982: `a` is later than `b`. */
static int later(uint32_t a, uint32_t b)
{
    uint32_t d = a - b;
    return d != 0 && d < 0x80000000u;
}

fz_count fz_model_predict(const fz_model *m, const uint8_t *d, size_t n, uint32_t ip,
                          uint64_t now, fz_reason *reason, fz_pkt *p)
{
    *reason = FZ_OK;
    if (ip != m->host_ip)
        return FZ_C_FOREIGN;
    *reason = fz_wire_check(m->key, d, n, p);
    if (*reason != FZ_OK)
        return FZ_C_MALFORMED;
    switch (p->type) {
    case FZ_T_HELLO:
        return FZ_C_HELLO;
    case FZ_T_JOIN:
        if (m->d == 0 || p->receiver != m->d || !m->chal_present || m->chal_spent ||
            !m->chal_known || memcmp(p->challenge, m->chal, 16) != 0 ||
            now - m->chal_drawn_at > FZ_LIFETIME_US)
            return FZ_C_REPLAY;
        return FZ_C_JOIN;
    case FZ_T_COMMAND: {
        if (!m->joined || p->receiver != m->d || p->sender != m->h || !later(p->host_seq, m->last_seq))
            return FZ_C_REPLAY;
        for (unsigned i = 0; i < m->ring_n; i++)
            if (m->ring[i].seq == p->echo_seq)
                return now - m->ring[i].at <= FZ_FRESH_US ? FZ_C_COMMAND : FZ_C_STALE;
        return FZ_C_STALE;
    }
    default:
        return FZ_C_UNEXPECTED;
    }
}

int fz_model_apply(fz_model *m, fz_count c, fz_reason r, const fz_pkt *p, uint32_t ip,
                   uint16_t port, uint64_t now)
{
    switch (c) {
    case FZ_C_MALFORMED:
        if (r == FZ_AUTH)
            m->auth_drops++;
        if (r == FZ_VERSION_R) {
            if (!m->version_sent_ever || now - m->version_sent_at > FZ_VERSION_GAP_US)
                return FZ_ANSWER_VERSION;
            if (now - m->version_sent_at == FZ_VERSION_GAP_US)
                return FZ_ANSWER_VERSION_MAY;
        }
        return FZ_ANSWER_NONE;
    case FZ_C_HELLO: {
        if (!m->chal_present || m->chal_spent || now - m->chal_drawn_at > FZ_REDRAW_US) {
            m->chal_present = 1;
            m->chal_spent = 0;
            m->chal_known = 0;
            m->chal_awaiting_draw = 1;
            m->chal_drawn_at = now;
        }
        return FZ_ANSWER_CHALLENGE; /* every authentic HELLO within the budget */
    }
    case FZ_C_JOIN:
        m->chal_spent = 1;
        m->joined = 1;
        m->h = p->sender;
        m->last_seq = p->host_seq;
        m->dest_ip = ip;
        m->dest_port = port;
        m->applied = 0;
        m->locks = 0;
        m->stop_heartbeat = 0;
        m->ring_n = 0;
        if (!m->stream_started)
            m->origin = now; /* the first JOIN starts the stream: seq 0 at t_us 0 */
        m->stream_started = 1;
        return 0;
    case FZ_C_COMMAND:
        m->last_seq = p->host_seq;
        m->applied = 1;
        m->locks = p->locks;
        m->stop_heartbeat = p->stop_heartbeat;
        for (unsigned i = 0; i < m->ring_n; i++)
            if (m->ring[i].seq == p->echo_seq)
                m->echo_at = m->ring[i].due; /* predict found it, fresh */
        return 0;
    case FZ_C_REPLAY:
        m->replay_drops++;
        return 0;
    case FZ_C_STALE:
        m->stale_drops++;
        return 0;
    default:
        return 0;
    }
}
