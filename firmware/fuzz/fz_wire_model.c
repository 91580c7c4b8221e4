/* fz_wire_model.c - see fz_wire_model.h. Every check cites the document's table. */
#include "fz_wire_model.h"

#include <string.h>

#include "fz_hmac.h"

static const char *const NAMES[FZ_REASONS] = {
    "ok",     "short",  "magic",    "length", "auth",  "version",  "type",
    "flags",  "counts", "status",   "reserved", "truth", "identity"};

const char *fz_reason_name(fz_reason r)
{
    return (unsigned)r < FZ_REASONS ? NAMES[r] : "?";
}

uint32_t fz_le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

uint64_t fz_le64(const uint8_t *p) { return (uint64_t)fz_le32(p) | (uint64_t)fz_le32(p + 4) << 32; }

static unsigned le16(const uint8_t *p) { return (unsigned)p[0] | (unsigned)p[1] << 8; }

void fz_put32(uint8_t *p, uint32_t v)
{
    for (unsigned i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

void fz_put64(uint8_t *p, uint64_t v)
{
    fz_put32(p, (uint32_t)v);
    fz_put32(p + 4, (uint32_t)(v >> 32));
}

/* Strict UTF-8 (RFC 3629): shortest form, no surrogates, at most U+10FFFF. */
static int utf8_ok(const uint8_t *s, size_t n)
{
    size_t i = 0;
    while (i < n) {
        uint8_t c = s[i];
        size_t more;
        uint32_t cp, min;
        if (c < 0x80) {
            i++;
            continue;
        } else if ((c & 0xE0) == 0xC0) {
            more = 1, cp = c & 0x1Fu, min = 0x80;
        } else if ((c & 0xF0) == 0xE0) {
            more = 2, cp = c & 0x0Fu, min = 0x800;
        } else if ((c & 0xF8) == 0xF0) {
            more = 3, cp = c & 0x07u, min = 0x10000;
        } else {
            return 0;
        }
        if (n - i - 1 < more)
            return 0;
        for (size_t k = 1; k <= more; k++) {
            if ((s[i + k] & 0xC0) != 0x80)
                return 0;
            cp = cp << 6 | (s[i + k] & 0x3Fu);
        }
        if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF))
            return 0;
        i += more + 1;
    }
    return 1;
}

static const size_t PAYLOAD[7] = {0, 36, 12, 8, 56, 24, 4};

fz_reason fz_wire_check(const uint8_t key[32], const uint8_t *d, size_t n, fz_pkt *o)
{
    memset(o, 0, sizeof *o);
    if (n < 44)
        return FZ_SHORT; /* the smallest packet is VERSION, 44 bytes */
    if (d[0] != 0x45 || d[1] != 0x58)
        return FZ_MAGIC;
    unsigned version = d[2], type = d[3], flags = le16(d + 6);
    size_t length = le16(d + 4);
    if (n != 8 + length + (type == FZ_T_VERSION ? 32u : 48u))
        return FZ_LENGTH;
    if (!fz_tag_ok(key, d, n))
        return FZ_AUTH;
    if (type != FZ_T_VERSION && version != FZ_VERSION)
        return FZ_VERSION_R; /* a VERSION packet is read whatever its version byte */
    if (type < FZ_T_SAMPLE || type > FZ_T_VERSION)
        return FZ_TYPE;
    unsigned allowed = (type == FZ_T_SAMPLE || type == FZ_T_COMMAND) ? 1u : 0u;
    if (flags & ~allowed)
        return FZ_FLAGS;
    const uint8_t *p = d + 8;
    size_t want = PAYLOAD[type];
    if (type == FZ_T_SAMPLE && (flags & 1u)) {
        if (length < 36 + 13)
            return FZ_LENGTH;
        want = 36 + 13 + (size_t)p[48];
    }
    if (length != want)
        return FZ_LENGTH;
    o->version = version;
    o->type = type;
    o->flags = flags;
    if (type != FZ_T_VERSION) {
        o->sender = fz_le64(d + n - 48);
        o->receiver = fz_le64(d + n - 40);
    }
    int reserved = 0;
    switch (type) {
    case FZ_T_SAMPLE:
        o->t_us = fz_le64(p);
        o->seq = fz_le32(p + 8);
        o->status = fz_le32(p + 12);
        for (unsigned i = 0; i < 4; i++) {
            o->counts[i] = (uint16_t)le16(p + 16 + 2 * i);
            if (o->counts[i] > 16383)
                return FZ_COUNTS;
        }
        if (o->status & ~0x7FFu)
            return FZ_STATUS;
        o->auth_drops = fz_le32(p + 24);
        o->replay_drops = fz_le32(p + 28);
        o->stale_drops = fz_le32(p + 32);
        o->has_truth = (flags & 1u) != 0;
        if (o->has_truth) {
            o->progress_bits = fz_le64(p + 36);
            o->lift_index = (int32_t)fz_le32(p + 44);
            o->activity_len = p[48];
            memcpy(o->activity, p + 49, o->activity_len);
        }
        break;
    case FZ_T_COMMAND:
        o->host_seq = fz_le32(p);
        o->echo_seq = fz_le32(p + 4);
        o->locks = p[8];
        o->stop_heartbeat = (flags & 1u) != 0;
        reserved = (p[8] & ~3u) || p[9] || p[10] || p[11];
        break;
    case FZ_T_HELLO:
        o->host_seq = fz_le32(p);
        reserved = p[4] || p[5] || p[6] || p[7] || o->receiver != 0;
        break;
    case FZ_T_CHALLENGE:
        o->hello_seq = fz_le32(p);
        o->lifetime_ms = fz_le32(p + 4);
        memcpy(o->challenge, p + 8, 16);
        memcpy(o->unique_id, p + 24, 16);
        memcpy(o->firmware, p + 40, 16);
        break;
    case FZ_T_JOIN:
        o->host_seq = fz_le32(p);
        memcpy(o->challenge, p + 8, 16);
        reserved = p[4] || p[5] || p[6] || p[7];
        break;
    default: /* VERSION */
        o->lowest = p[0];
        o->highest = p[1];
        reserved = p[2] || p[3] || o->lowest > o->highest;
        break;
    }
    if (reserved || (type != FZ_T_VERSION && o->sender == 0))
        return FZ_RESERVED;
    if (type == FZ_T_SAMPLE && o->has_truth && !utf8_ok(o->activity, o->activity_len))
        return FZ_TRUTH;
    if (type == FZ_T_CHALLENGE) {
        const uint8_t *f = o->firmware;
        if (f[0] == 0)
            return FZ_IDENTITY;
        size_t i = 0;
        while (i < 16 && f[i] != 0) {
            if (f[i] < 0x20 || f[i] > 0x7e)
                return FZ_IDENTITY;
            i++;
        }
        for (; i < 16; i++)
            if (f[i] != 0)
                return FZ_IDENTITY;
    }
    return FZ_OK;
}

static size_t frame(const uint8_t key[32], uint8_t *buf, unsigned type, unsigned flags,
                    size_t payload, uint64_t sender, uint64_t receiver)
{
    buf[0] = 0x45;
    buf[1] = 0x58;
    buf[2] = FZ_VERSION;
    buf[3] = (uint8_t)type;
    buf[4] = (uint8_t)payload;
    buf[5] = (uint8_t)(payload >> 8);
    buf[6] = (uint8_t)flags;
    buf[7] = (uint8_t)(flags >> 8);
    size_t at = 8 + payload;
    fz_put64(buf + at, sender);
    fz_put64(buf + at + 8, receiver);
    size_t n = at + 16 + 32;
    fz_reauth(key, buf, n);
    return n;
}

size_t fz_build_hello(const uint8_t key[32], uint8_t *buf, uint32_t seq, uint64_t sender,
                      uint64_t receiver)
{
    memset(buf, 0, 16);
    fz_put32(buf + 8, seq);
    return frame(key, buf, FZ_T_HELLO, 0, 8, sender, receiver);
}

size_t fz_build_join(const uint8_t key[32], uint8_t *buf, uint32_t seq,
                     const uint8_t challenge[16], uint64_t sender, uint64_t receiver)
{
    memset(buf, 0, 32);
    fz_put32(buf + 8, seq);
    memcpy(buf + 16, challenge, 16);
    return frame(key, buf, FZ_T_JOIN, 0, 24, sender, receiver);
}

size_t fz_build_command(const uint8_t key[32], uint8_t *buf, uint32_t seq, uint32_t echo,
                        unsigned locks, int stop_heartbeat, uint64_t sender, uint64_t receiver)
{
    memset(buf, 0, 20);
    fz_put32(buf + 8, seq);
    fz_put32(buf + 12, echo);
    buf[16] = (uint8_t)locks;
    return frame(key, buf, FZ_T_COMMAND, stop_heartbeat ? 1u : 0u, 12, sender, receiver);
}

size_t fz_build_version(const uint8_t key[32], uint8_t *buf, unsigned lowest, unsigned highest)
{
    buf[0] = 0x45;
    buf[1] = 0x58;
    buf[2] = (uint8_t)highest;
    buf[3] = FZ_T_VERSION;
    buf[4] = 4;
    buf[5] = buf[6] = buf[7] = 0;
    buf[8] = (uint8_t)lowest;
    buf[9] = (uint8_t)highest;
    buf[10] = buf[11] = 0;
    fz_reauth(key, buf, 44);
    return 44;
}
