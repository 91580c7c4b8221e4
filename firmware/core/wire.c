/*
 * wire.c - encode and validate packets of protocol version 3.
 *
 * The validation order is the protocol's (docs/device-protocol.md, "Validation") and
 * matches controller/device/protocol.py check for check, because the drop counts of
 * the firmware and of the Python reference device must be comparable. Nothing but
 * the size, magic and length fields is believed before the tag has been checked.
 */
#include "wire.h"

#include <string.h>

/* The truth extension carries an IEEE 754 binary64; it is copied bit for bit. */
typedef char exo_double_is_binary64[sizeof(double) == 8 ? 1 : -1];

uint16_t exo_le16(const uint8_t *p) { return (uint16_t)(p[0] | (unsigned)p[1] << 8); }

uint32_t exo_le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

uint64_t exo_le64(const uint8_t *p) { return (uint64_t)exo_le32(p) | (uint64_t)exo_le32(p + 4) << 32; }

void exo_put_le16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

void exo_put_le32(uint8_t *p, uint32_t v)
{
    exo_put_le16(p, (uint16_t)v);
    exo_put_le16(p + 2, (uint16_t)(v >> 16));
}

void exo_put_le64(uint8_t *p, uint64_t v)
{
    exo_put_le32(p, (uint32_t)v);
    exo_put_le32(p + 4, (uint32_t)(v >> 32));
}

const char *exo_drop_reason_name(exo_drop_reason r)
{
    static const char *const names[EXO_DROP_REASONS] = {
        "ok",    "short",  "magic",  "length",   "auth",  "version",  "type",
        "flags", "counts", "status", "reserved", "truth", "identity"};
    return (unsigned)r < EXO_DROP_REASONS ? names[r] : "?";
}

int exo_utf8_valid(const uint8_t *s, size_t n)
{
    size_t i = 0;
    while (i < n) {
        uint8_t b = s[i];
        size_t more;
        uint8_t lo = 0x80, hi = 0xBF; /* allowed range of the first continuation byte */
        if (b < 0x80) {
            i++;
            continue;
        } else if (b >= 0xC2 && b <= 0xDF) {
            more = 1; /* C0 and C1 could only start overlong forms */
        } else if (b >= 0xE0 && b <= 0xEF) {
            more = 2;
            if (b == 0xE0)
                lo = 0xA0; /* overlong */
            if (b == 0xED)
                hi = 0x9F; /* UTF-16 surrogates D800..DFFF */
        } else if (b >= 0xF0 && b <= 0xF4) {
            more = 3;
            if (b == 0xF0)
                lo = 0x90; /* overlong */
            if (b == 0xF4)
                hi = 0x8F; /* above U+10FFFF */
        } else {
            return 0; /* stray continuation byte, C0/C1, or F5..FF */
        }
        if (n - i - 1 < more)
            return 0; /* truncated sequence */
        if (s[i + 1] < lo || s[i + 1] > hi)
            return 0;
        for (size_t j = 2; j <= more; j++)
            if ((s[i + j] & 0xC0) != 0x80)
                return 0;
        i += more + 1;
    }
    return 1;
}

int exo_firmware_valid(const uint8_t f[EXO_FIRMWARE_BYTES])
{
    size_t i = 0;
    while (i < EXO_FIRMWARE_BYTES && f[i] != 0) {
        if (f[i] < 0x20 || f[i] > 0x7E)
            return 0;
        i++;
    }
    if (i == 0)
        return 0; /* empty */
    for (; i < EXO_FIRMWARE_BYTES; i++)
        if (f[i] != 0)
            return 0; /* something after the padding began */
    return 1;
}

/* Header, payload already in place at buf + 8; append sessions and tag. */
static size_t finish(const exo_hmac_key *key, uint8_t *buf, unsigned type, size_t payload,
                     uint16_t flags, uint64_t sender, uint64_t receiver)
{
    buf[0] = 'E';
    buf[1] = 'X';
    buf[2] = (uint8_t)EXO_WIRE_VERSION;
    buf[3] = (uint8_t)type;
    exo_put_le16(buf + 4, (uint16_t)payload);
    exo_put_le16(buf + 6, flags);
    size_t at = EXO_HEADER_BYTES + payload;
    exo_put_le64(buf + at, sender);
    exo_put_le64(buf + at + 8, receiver);
    at += EXO_SESSIONS_BYTES;
    exo_hmac_sha256(key, buf, at, NULL, 0, buf + at);
    return at + EXO_TAG_BYTES;
}

size_t exo_wire_encode_sample(const exo_hmac_key *key, const exo_sample_fields *s,
                              uint64_t sender, uint64_t receiver, uint8_t *buf, size_t cap)
{
    for (unsigned i = 0; i < 4; i++)
        if (s->counts[i] >= EXO_ENCODER_COUNTS)
            return 0;
    if (s->status & ~(uint32_t)EXO_STATUS_KNOWN || sender == 0)
        return 0;
    size_t payload = EXO_SAMPLE_BODY_BYTES;
    if (s->has_truth) {
        if (s->truth.activity_len > EXO_MAX_ACTIVITY_BYTES
            || !exo_utf8_valid((const uint8_t *)s->truth.activity, s->truth.activity_len))
            return 0;
        payload += EXO_TRUTH_BODY_BYTES + s->truth.activity_len;
    }
    if (cap < EXO_SESSION_PACKET + payload)
        return 0;
    uint8_t *p = buf + EXO_HEADER_BYTES;
    exo_put_le64(p, s->t_us);
    exo_put_le32(p + 8, s->seq);
    exo_put_le32(p + 12, s->status);
    for (unsigned i = 0; i < 4; i++)
        exo_put_le16(p + 16 + 2 * i, s->counts[i]);
    exo_put_le32(p + 24, s->auth_drops);
    exo_put_le32(p + 28, s->replay_drops);
    exo_put_le32(p + 32, s->stale_drops);
    uint16_t flags = 0;
    if (s->has_truth) {
        uint64_t bits;
        memcpy(&bits, &s->truth.progress, sizeof bits);
        exo_put_le64(p + 36, bits);
        exo_put_le32(p + 44, (uint32_t)s->truth.lift_index);
        p[48] = s->truth.activity_len;
        memcpy(p + 49, s->truth.activity, s->truth.activity_len);
        flags = EXO_SAMPLE_HAS_TRUTH;
    }
    return finish(key, buf, EXO_TYPE_SAMPLE, payload, flags, sender, receiver);
}

size_t exo_wire_encode_command(const exo_hmac_key *key, uint32_t host_seq, uint32_t echo_seq,
                               unsigned locks, int stop_heartbeat, uint64_t sender,
                               uint64_t receiver, uint8_t *buf, size_t cap)
{
    if (locks & ~(EXO_LOCK_LEFT | EXO_LOCK_RIGHT) || sender == 0
        || cap < EXO_SESSION_PACKET + EXO_COMMAND_BODY_BYTES)
        return 0;
    uint8_t *p = buf + EXO_HEADER_BYTES;
    exo_put_le32(p, host_seq);
    exo_put_le32(p + 4, echo_seq);
    p[8] = (uint8_t)locks;
    p[9] = p[10] = p[11] = 0;
    return finish(key, buf, EXO_TYPE_COMMAND, EXO_COMMAND_BODY_BYTES,
                  stop_heartbeat ? EXO_COMMAND_STOP_HEARTBEAT : 0, sender, receiver);
}

size_t exo_wire_encode_hello(const exo_hmac_key *key, uint32_t host_seq, uint64_t sender,
                             uint64_t receiver, uint8_t *buf, size_t cap)
{
    if (sender == 0 || cap < EXO_SESSION_PACKET + EXO_HELLO_BODY_BYTES)
        return 0;
    uint8_t *p = buf + EXO_HEADER_BYTES;
    exo_put_le32(p, host_seq);
    memset(p + 4, 0, 4);
    return finish(key, buf, EXO_TYPE_HELLO, EXO_HELLO_BODY_BYTES, 0, sender, receiver);
}

size_t exo_wire_encode_challenge(const exo_hmac_key *key, const exo_challenge_fields *c,
                                 uint64_t sender, uint64_t receiver, uint8_t *buf, size_t cap)
{
    if (sender == 0 || !exo_firmware_valid(c->firmware)
        || cap < EXO_SESSION_PACKET + EXO_CHALLENGE_BODY_BYTES)
        return 0;
    uint8_t *p = buf + EXO_HEADER_BYTES;
    exo_put_le32(p, c->hello_seq);
    exo_put_le32(p + 4, c->lifetime_ms);
    memcpy(p + 8, c->challenge, EXO_CHALLENGE_BYTES);
    memcpy(p + 24, c->unique_id, EXO_UNIQUE_ID_BYTES);
    memcpy(p + 40, c->firmware, EXO_FIRMWARE_BYTES);
    return finish(key, buf, EXO_TYPE_CHALLENGE, EXO_CHALLENGE_BODY_BYTES, 0, sender, receiver);
}

size_t exo_wire_encode_join(const exo_hmac_key *key, uint32_t host_seq,
                            const uint8_t challenge[EXO_CHALLENGE_BYTES], uint64_t sender,
                            uint64_t receiver, uint8_t *buf, size_t cap)
{
    if (sender == 0 || cap < EXO_SESSION_PACKET + EXO_JOIN_BODY_BYTES)
        return 0;
    uint8_t *p = buf + EXO_HEADER_BYTES;
    exo_put_le32(p, host_seq);
    memset(p + 4, 0, 4);
    memcpy(p + 8, challenge, EXO_CHALLENGE_BYTES);
    return finish(key, buf, EXO_TYPE_JOIN, EXO_JOIN_BODY_BYTES, 0, sender, receiver);
}

size_t exo_wire_encode_version(const exo_hmac_key *key, unsigned lowest, unsigned highest,
                               uint8_t *buf, size_t cap)
{
    if (lowest > highest || highest > 255u || cap < EXO_VERSION_PACKET)
        return 0;
    buf[0] = 'E';
    buf[1] = 'X';
    buf[2] = (uint8_t)highest;
    buf[3] = (uint8_t)EXO_TYPE_VERSION;
    exo_put_le16(buf + 4, (uint16_t)EXO_VERSION_BODY_BYTES);
    exo_put_le16(buf + 6, 0);
    buf[8] = (uint8_t)lowest;
    buf[9] = (uint8_t)highest;
    buf[10] = buf[11] = 0;
    size_t at = EXO_HEADER_BYTES + EXO_VERSION_BODY_BYTES;
    exo_hmac_sha256(key, buf, at, NULL, 0, buf + at);
    return EXO_VERSION_PACKET;
}

/* SAMPLE checks in protocol.py's order: flags, minimum size, counts, status, then the
 * optional truth extension's size; the sender session (reserved) and the UTF-8 of the
 * activity name are the caller's last two checks. */
static exo_drop_reason decode_sample(uint16_t flags, const uint8_t *p, size_t n,
                                     exo_sample_fields *s)
{
    if (flags & ~EXO_SAMPLE_HAS_TRUTH)
        return EXO_DROP_FLAGS;
    /* The whole size first (the document's order: `length` before `counts` and
     * `status`), with and without the ground-truth extension. */
    const size_t base = EXO_SAMPLE_BODY_BYTES + EXO_TRUTH_BODY_BYTES;
    s->has_truth = (flags & EXO_SAMPLE_HAS_TRUTH) != 0;
    if (!s->has_truth && n != EXO_SAMPLE_BODY_BYTES)
        return EXO_DROP_LENGTH;
    if (s->has_truth && (n < base || n != base + p[48]))
        return EXO_DROP_LENGTH;
    s->t_us = exo_le64(p);
    s->seq = exo_le32(p + 8);
    s->status = exo_le32(p + 12);
    for (unsigned i = 0; i < 4; i++) {
        s->counts[i] = exo_le16(p + 16 + 2 * i);
        if (s->counts[i] >= EXO_ENCODER_COUNTS)
            return EXO_DROP_COUNTS;
    }
    if (s->status & ~(uint32_t)EXO_STATUS_KNOWN)
        return EXO_DROP_STATUS;
    s->auth_drops = exo_le32(p + 24);
    s->replay_drops = exo_le32(p + 28);
    s->stale_drops = exo_le32(p + 32);
    if (!s->has_truth)
        return EXO_DROP_NONE;
    uint8_t name_len = p[48];
    uint64_t bits = exo_le64(p + 36);
    memcpy(&s->truth.progress, &bits, sizeof bits);
    s->truth.lift_index = (int32_t)exo_le32(p + 44);
    /* Like the reference decoder, a name longer than a conforming sender's 64 bytes is
     * still valid; only its first 64 bytes are kept (the device never uses it). */
    s->truth.activity_len = name_len > EXO_MAX_ACTIVITY_BYTES ? (uint8_t)EXO_MAX_ACTIVITY_BYTES : name_len;
    memcpy(s->truth.activity, p + base, s->truth.activity_len);
    return EXO_DROP_NONE;
}

/* The type's own checks up to `reserved` (flags, payload size, counts, status,
 * reserved bytes); the caller then checks the sender session, truth and identity. */
static exo_drop_reason decode_body(unsigned type, uint16_t flags, const uint8_t *p, size_t n,
                                   exo_packet *out)
{
    switch (type) {
    case EXO_TYPE_SAMPLE:
        return decode_sample(flags, p, n, &out->sample);
    case EXO_TYPE_COMMAND:
        if (flags & ~EXO_COMMAND_STOP_HEARTBEAT)
            return EXO_DROP_FLAGS;
        if (n != EXO_COMMAND_BODY_BYTES)
            return EXO_DROP_LENGTH;
        if (p[9] | p[10] | p[11])
            return EXO_DROP_RESERVED;
        if (p[8] & ~(EXO_LOCK_LEFT | EXO_LOCK_RIGHT))
            return EXO_DROP_RESERVED;
        out->host_seq = exo_le32(p);
        out->echo_seq = exo_le32(p + 4);
        out->locks = p[8];
        out->stop_heartbeat = (flags & EXO_COMMAND_STOP_HEARTBEAT) != 0;
        return EXO_DROP_NONE;
    case EXO_TYPE_HELLO:
        if (flags)
            return EXO_DROP_FLAGS;
        if (n != EXO_HELLO_BODY_BYTES)
            return EXO_DROP_LENGTH;
        if (p[4] | p[5] | p[6] | p[7])
            return EXO_DROP_RESERVED;
        if (out->receiver != 0)
            return EXO_DROP_RESERVED; /* a HELLO never names a device session */
        out->host_seq = exo_le32(p);
        return EXO_DROP_NONE;
    case EXO_TYPE_CHALLENGE:
        if (flags)
            return EXO_DROP_FLAGS;
        if (n != EXO_CHALLENGE_BODY_BYTES)
            return EXO_DROP_LENGTH;
        out->challenge.hello_seq = exo_le32(p);
        out->challenge.lifetime_ms = exo_le32(p + 4);
        memcpy(out->challenge.challenge, p + 8, EXO_CHALLENGE_BYTES);
        memcpy(out->challenge.unique_id, p + 24, EXO_UNIQUE_ID_BYTES);
        memcpy(out->challenge.firmware, p + 40, EXO_FIRMWARE_BYTES);
        return EXO_DROP_NONE;
    case EXO_TYPE_JOIN:
        if (flags)
            return EXO_DROP_FLAGS;
        if (n != EXO_JOIN_BODY_BYTES)
            return EXO_DROP_LENGTH;
        if (p[4] | p[5] | p[6] | p[7])
            return EXO_DROP_RESERVED;
        out->host_seq = exo_le32(p);
        memcpy(out->join_challenge, p + 8, EXO_CHALLENGE_BYTES);
        return EXO_DROP_NONE;
    default: /* EXO_TYPE_VERSION */
        if (flags)
            return EXO_DROP_FLAGS;
        if (n != EXO_VERSION_BODY_BYTES)
            return EXO_DROP_LENGTH;
        if (p[2] | p[3] || p[0] > p[1])
            return EXO_DROP_RESERVED;
        out->lowest = p[0];
        out->highest = p[1];
        return EXO_DROP_NONE;
    }
}

exo_drop_reason exo_wire_decode(const exo_hmac_key *key, const uint8_t *data, size_t len,
                                exo_packet *out)
{
    if (len < EXO_MIN_PACKET)
        return EXO_DROP_SHORT;
    if (data[0] != 'E' || data[1] != 'X')
        return EXO_DROP_MAGIC;
    size_t payload = exo_le16(data + 4);
    /* VERSION's frozen layout has no session trailer: its size is read from the type
     * byte before the tag (a wrong type byte then fails the size or the tag). */
    int is_version = data[3] == EXO_TYPE_VERSION;
    size_t expect = EXO_HEADER_BYTES + payload + (is_version ? EXO_TAG_BYTES : EXO_TRAILER_BYTES);
    if (len != expect)
        return EXO_DROP_LENGTH;
    size_t signed_len = len - EXO_TAG_BYTES;
    uint8_t tag[EXO_TAG_BYTES];
    exo_hmac_sha256(key, data, signed_len, NULL, 0, tag);
    int authentic = exo_ct_equal(tag, data + signed_len, EXO_TAG_BYTES);
    if (!authentic)
        return EXO_DROP_AUTH;
    /* From here on every byte is the key holder's: what fails now is a sender bug or
     * another protocol version, not damage. */
    memset(out, 0, sizeof *out);
    out->version = data[2];
    if (data[2] != EXO_WIRE_VERSION && !is_version)
        return EXO_DROP_VERSION; /* a VERSION packet is read whatever its version byte */
    unsigned type = data[3];
    if (type < EXO_TYPE_SAMPLE || type > EXO_TYPE_VERSION)
        return EXO_DROP_TYPE;
    uint16_t flags = exo_le16(data + 6);
    out->type = type;
    if (!is_version) {
        out->sender = exo_le64(data + EXO_HEADER_BYTES + payload);
        out->receiver = exo_le64(data + EXO_HEADER_BYTES + payload + 8);
    }
    exo_drop_reason why = decode_body(type, flags, data + EXO_HEADER_BYTES, payload, out);
    if (why != EXO_DROP_NONE)
        return why;
    if (!is_version && out->sender == 0)
        return EXO_DROP_RESERVED; /* no side ever has session 0 */
    if (type == EXO_TYPE_SAMPLE && out->sample.has_truth
        && !exo_utf8_valid(data + EXO_HEADER_BYTES + EXO_SAMPLE_BODY_BYTES + EXO_TRUTH_BODY_BYTES,
                           data[EXO_HEADER_BYTES + 48]))
        return EXO_DROP_TRUTH;
    if (type == EXO_TYPE_CHALLENGE && !exo_firmware_valid(out->challenge.firmware))
        return EXO_DROP_IDENTITY;
    return EXO_DROP_NONE;
}
