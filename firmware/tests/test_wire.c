/*
 * test_wire.c - the protocol document's eight test vectors byte for byte (encoding and
 * decoding, and rejection of every single-bit change), and each validation check in
 * the document's order, including which reason wins when several apply.
 */
#include <string.h>

#include "check.h"
#include "vectors.h"
#include "wire.h"

static exo_hmac_key key;

static void set_vector_key(void)
{
    uint8_t k[32];
    for (unsigned i = 0; i < 32; i++)
        k[i] = (uint8_t)i;
    exo_hmac_set_key(&key, k, sizeof k);
}

/* Recompute the tag of a hand-edited packet, so the check under test is reached. */
static void retag(uint8_t *p, size_t len)
{
    exo_hmac_sha256(&key, p, len - EXO_TAG_BYTES, NULL, 0, p + len - EXO_TAG_BYTES);
}

static exo_sample_fields vector_sample(int with_truth)
{
    exo_sample_fields s;
    memset(&s, 0, sizeof s);
    s.t_us = 2580000;
    s.seq = 258;
    s.status = EXO_STATUS_SOLENOID_LEFT | EXO_STATUS_LOCKED_LEFT;
    s.counts[0] = 3100;
    s.counts[1] = 3105;
    s.counts[2] = 12900;
    s.counts[3] = 12890;
    if (with_truth) {
        s.has_truth = 1;
        s.truth.progress = 0.5;
        s.truth.lift_index = 3;
        s.truth.activity_len = 5;
        memcpy(s.truth.activity, "squat", 5);
    } else {
        s.auth_drops = 1;
        s.replay_drops = 2;
        s.stale_drops = 3;
    }
    return s;
}

static const uint8_t VEC_CHALLENGE_BYTES[16] = {0xa0, 0xa1, 0xa2, 0xa3, 0xa4, 0xa5, 0xa6, 0xa7,
                                                0xa8, 0xa9, 0xaa, 0xab, 0xac, 0xad, 0xae, 0xaf};

static exo_challenge_fields vector_challenge(void)
{
    exo_challenge_fields c;
    memset(&c, 0, sizeof c);
    c.hello_seq = 5;
    c.lifetime_ms = 1000;
    memcpy(c.challenge, VEC_CHALLENGE_BYTES, 16);
    for (unsigned i = 0; i < 12; i++)
        c.unique_id[i] = (uint8_t)(0x10u + i);
    memcpy(c.firmware, "exostudy-c 3.0", 14);
    return c;
}

static void check_encoded(const char *hex, size_t want_len, size_t got_len, const uint8_t *got)
{
    uint8_t want[EXO_MAX_PACKET];
    size_t n = hex_bytes(hex, want, sizeof want);
    CHECK_EQ(n, want_len);
    CHECK_EQ(got_len, n);
    CHECK_BYTES(got, want, n);
}

static void encode_vectors(void)
{
    uint8_t got[EXO_MAX_PACKET];
    exo_sample_fields s = vector_sample(0);
    check_encoded(VEC_SAMPLE, 92,
                  exo_wire_encode_sample(&key, &s, VEC_DEVICE_SESSION, VEC_HOST_SESSION, got, sizeof got), got);
    s = vector_sample(1);
    check_encoded(VEC_SAMPLE_TRUTH, 110,
                  exo_wire_encode_sample(&key, &s, VEC_DEVICE_SESSION, VEC_HOST_SESSION, got, sizeof got), got);
    check_encoded(VEC_HELLO, 64, exo_wire_encode_hello(&key, 5, VEC_HOST_SESSION, 0, got, sizeof got), got);
    exo_challenge_fields c = vector_challenge();
    check_encoded(VEC_CHALLENGE, 112,
                  exo_wire_encode_challenge(&key, &c, VEC_DEVICE_SESSION, VEC_HOST_SESSION, got, sizeof got), got);
    check_encoded(VEC_JOIN, 80,
                  exo_wire_encode_join(&key, 6, VEC_CHALLENGE_BYTES, VEC_HOST_SESSION, VEC_DEVICE_SESSION,
                                       got, sizeof got), got);
    check_encoded(VEC_COMMAND, 68,
                  exo_wire_encode_command(&key, 7, 258, EXO_LOCK_LEFT, 0, VEC_HOST_SESSION,
                                          VEC_DEVICE_SESSION, got, sizeof got), got);
    check_encoded(VEC_COMMAND_HEARTBEAT, 68,
                  exo_wire_encode_command(&key, 8, 259, EXO_LOCK_LEFT | EXO_LOCK_RIGHT, 1,
                                          VEC_HOST_SESSION, VEC_DEVICE_SESSION, got, sizeof got), got);
    check_encoded(VEC_VERSION, 44, exo_wire_encode_version(&key, 3, 3, got, sizeof got), got);

    /* A buffer one byte short is refused rather than overrun. */
    CHECK_EQ(exo_wire_encode_hello(&key, 1, VEC_HOST_SESSION, 0, got, 63), 0);
    CHECK_EQ(exo_wire_encode_sample(&key, &s, 1, 2, got, 109), 0);
    CHECK_EQ(exo_wire_encode_challenge(&key, &c, 1, 2, got, 111), 0);
    CHECK_EQ(exo_wire_encode_join(&key, 6, VEC_CHALLENGE_BYTES, 1, 2, got, 79), 0);
    CHECK_EQ(exo_wire_encode_version(&key, 3, 3, got, 43), 0);
}

static void decode_vectors(void)
{
    uint8_t d[EXO_MAX_PACKET];
    exo_packet p;

    size_t n = hex_bytes(VEC_SAMPLE, d, sizeof d);
    CHECK_EQ(exo_wire_decode(&key, d, n, &p), EXO_DROP_NONE);
    CHECK_EQ(p.type, EXO_TYPE_SAMPLE);
    CHECK_EQ(p.sender, VEC_DEVICE_SESSION);
    CHECK_EQ(p.receiver, VEC_HOST_SESSION);
    CHECK_EQ(p.sample.t_us, 2580000);
    CHECK_EQ(p.sample.seq, 258);
    CHECK_EQ(p.sample.status, 5);
    CHECK_EQ(p.sample.counts[0], 3100);
    CHECK_EQ(p.sample.counts[3], 12890);
    CHECK_EQ(p.sample.auth_drops, 1);
    CHECK_EQ(p.sample.replay_drops, 2);
    CHECK_EQ(p.sample.stale_drops, 3);
    CHECK_EQ(p.sample.has_truth, 0);

    n = hex_bytes(VEC_SAMPLE_TRUTH, d, sizeof d);
    CHECK_EQ(exo_wire_decode(&key, d, n, &p), EXO_DROP_NONE);
    CHECK_EQ(p.sample.has_truth, 1);
    CHECK(p.sample.truth.progress == 0.5);
    CHECK_EQ(p.sample.truth.lift_index, 3);
    CHECK_EQ(p.sample.truth.activity_len, 5);
    CHECK(memcmp(p.sample.truth.activity, "squat", 5) == 0);

    n = hex_bytes(VEC_HELLO, d, sizeof d);
    CHECK_EQ(exo_wire_decode(&key, d, n, &p), EXO_DROP_NONE);
    CHECK_EQ(p.type, EXO_TYPE_HELLO);
    CHECK_EQ(p.host_seq, 5);
    CHECK_EQ(p.sender, VEC_HOST_SESSION);
    CHECK_EQ(p.receiver, 0);

    n = hex_bytes(VEC_CHALLENGE, d, sizeof d);
    CHECK_EQ(exo_wire_decode(&key, d, n, &p), EXO_DROP_NONE);
    CHECK_EQ(p.type, EXO_TYPE_CHALLENGE);
    exo_challenge_fields c = vector_challenge();
    CHECK_EQ(p.challenge.hello_seq, 5);
    CHECK_EQ(p.challenge.lifetime_ms, 1000);
    CHECK(memcmp(p.challenge.challenge, c.challenge, 16) == 0);
    CHECK(memcmp(p.challenge.unique_id, c.unique_id, 16) == 0);
    CHECK(memcmp(p.challenge.firmware, c.firmware, 16) == 0);
    CHECK_EQ(p.sender, VEC_DEVICE_SESSION);
    CHECK_EQ(p.receiver, VEC_HOST_SESSION);

    n = hex_bytes(VEC_JOIN, d, sizeof d);
    CHECK_EQ(exo_wire_decode(&key, d, n, &p), EXO_DROP_NONE);
    CHECK_EQ(p.type, EXO_TYPE_JOIN);
    CHECK_EQ(p.host_seq, 6);
    CHECK(memcmp(p.join_challenge, VEC_CHALLENGE_BYTES, 16) == 0);
    CHECK_EQ(p.sender, VEC_HOST_SESSION);
    CHECK_EQ(p.receiver, VEC_DEVICE_SESSION);

    n = hex_bytes(VEC_COMMAND, d, sizeof d);
    CHECK_EQ(exo_wire_decode(&key, d, n, &p), EXO_DROP_NONE);
    CHECK_EQ(p.type, EXO_TYPE_COMMAND);
    CHECK_EQ(p.sender, VEC_HOST_SESSION);
    CHECK_EQ(p.receiver, VEC_DEVICE_SESSION);
    CHECK_EQ(p.host_seq, 7);
    CHECK_EQ(p.echo_seq, 258);
    CHECK_EQ(p.locks, EXO_LOCK_LEFT);
    CHECK_EQ(p.stop_heartbeat, 0);

    n = hex_bytes(VEC_COMMAND_HEARTBEAT, d, sizeof d);
    CHECK_EQ(exo_wire_decode(&key, d, n, &p), EXO_DROP_NONE);
    CHECK_EQ(p.host_seq, 8);
    CHECK_EQ(p.echo_seq, 259);
    CHECK_EQ(p.locks, EXO_LOCK_LEFT | EXO_LOCK_RIGHT);
    CHECK_EQ(p.stop_heartbeat, 1);

    n = hex_bytes(VEC_VERSION, d, sizeof d);
    CHECK_EQ(exo_wire_decode(&key, d, n, &p), EXO_DROP_NONE);
    CHECK_EQ(p.type, EXO_TYPE_VERSION);
    CHECK_EQ(p.lowest, 3);
    CHECK_EQ(p.highest, 3);
}

#define N_VECTORS 8
static const char *const *const ALL_VECTORS[N_VECTORS] = {
    &VEC_SAMPLE, &VEC_SAMPLE_TRUTH, &VEC_HELLO,   &VEC_CHALLENGE,
    &VEC_JOIN,   &VEC_COMMAND,      &VEC_COMMAND_HEARTBEAT, &VEC_VERSION};

/* Every single-bit change of every vector is rejected (counted once per vector so the
 * pass count stays readable; a failure names the byte and bit). */
static void bit_flips(void)
{
    for (unsigned v = 0; v < N_VECTORS; v++) {
        uint8_t d[EXO_MAX_PACKET];
        size_t n = hex_bytes(*ALL_VECTORS[v], d, sizeof d);
        size_t accepted = 0, tried = 0;
        for (size_t i = 0; i < n; i++)
            for (unsigned bit = 0; bit < 8; bit++) {
                exo_packet p;
                d[i] = (uint8_t)(d[i] ^ (1u << bit));
                if (exo_wire_decode(&key, d, n, &p) == EXO_DROP_NONE)
                    accepted++;
                tried++;
                d[i] = (uint8_t)(d[i] ^ (1u << bit));
            }
        CHECK_EQ(tried, 8 * n);
        CHECK_EQ(accepted, 0);
        exo_packet p;
        CHECK_EQ(exo_wire_decode(&key, d, n, &p), EXO_DROP_NONE); /* restored intact */
    }
}

/* A COMMAND, HELLO, SAMPLE, CHALLENGE or JOIN built fresh for each check below. */
static size_t command(uint8_t *d)
{
    return exo_wire_encode_command(&key, 7, 258, EXO_LOCK_LEFT, 0, VEC_HOST_SESSION,
                                   VEC_DEVICE_SESSION, d, EXO_MAX_PACKET);
}

static size_t hello(uint8_t *d) { return exo_wire_encode_hello(&key, 5, VEC_HOST_SESSION, 0, d, EXO_MAX_PACKET); }

static size_t sample(uint8_t *d, int truth)
{
    exo_sample_fields s = vector_sample(truth);
    return exo_wire_encode_sample(&key, &s, VEC_DEVICE_SESSION, VEC_HOST_SESSION, d, EXO_MAX_PACKET);
}

static size_t challenge(uint8_t *d)
{
    exo_challenge_fields c = vector_challenge();
    return exo_wire_encode_challenge(&key, &c, VEC_DEVICE_SESSION, VEC_HOST_SESSION, d, EXO_MAX_PACKET);
}

static size_t join(uint8_t *d)
{
    return exo_wire_encode_join(&key, 6, VEC_CHALLENGE_BYTES, VEC_HOST_SESSION, VEC_DEVICE_SESSION,
                                d, EXO_MAX_PACKET);
}

static exo_drop_reason decode(const uint8_t *d, size_t n)
{
    exo_packet p;
    return exo_wire_decode(&key, d, n, &p);
}

/* Change the payload size in the header and the datagram size together, keeping the
 * trailer: the packet is then consistent except for the payload size check. */
static size_t resize_payload(uint8_t *d, size_t n, size_t new_payload)
{
    size_t old_payload = n - EXO_SESSION_PACKET;
    uint8_t trailer[EXO_TRAILER_BYTES];
    memcpy(trailer, d + n - EXO_TRAILER_BYTES, EXO_TRAILER_BYTES);
    if (new_payload > old_payload)
        memset(d + EXO_HEADER_BYTES + old_payload, 0, new_payload - old_payload);
    memcpy(d + EXO_HEADER_BYTES + new_payload, trailer, EXO_TRAILER_BYTES);
    exo_put_le16(d + 4, (uint16_t)new_payload);
    size_t m = EXO_SESSION_PACKET + new_payload;
    retag(d, m);
    return m;
}

/* Set the sender session (8 bytes before the receiver's) and retag. */
static void set_sender(uint8_t *d, size_t n, uint64_t sender)
{
    exo_put_le64(d + n - EXO_TRAILER_BYTES, sender);
    retag(d, n);
}

static void validation_order(void)
{
    uint8_t d[EXO_MAX_PACKET + 8];
    size_t n;

    /* short: under 44 bytes (the VERSION packet), whatever they hold, empty included */
    n = command(d);
    CHECK_EQ(decode(d, 43), EXO_DROP_SHORT);
    CHECK_EQ(decode(d, 0), EXO_DROP_SHORT);
    d[0] = 'Z';
    CHECK_EQ(decode(d, 43), EXO_DROP_SHORT); /* short wins over magic */
    n = command(d);
    CHECK_EQ(decode(d, 44), EXO_DROP_LENGTH); /* 44 bytes are not short */

    /* magic */
    n = command(d);
    d[1] = 'Y';
    CHECK_EQ(decode(d, n), EXO_DROP_MAGIC);
    CHECK_EQ(decode(d, n + 1), EXO_DROP_MAGIC); /* magic wins over length */

    /* length: datagram size disagrees with the header */
    n = command(d);
    d[n] = 0;
    CHECK_EQ(decode(d, n + 1), EXO_DROP_LENGTH);
    CHECK_EQ(decode(d, n - 1), EXO_DROP_LENGTH);
    exo_put_le16(d + 4, 13);
    CHECK_EQ(decode(d, n), EXO_DROP_LENGTH); /* length wins over auth */
    n = command(d);
    d[3] = EXO_TYPE_VERSION; /* a VERSION has no session trailer: 16 bytes too many */
    CHECK_EQ(decode(d, n), EXO_DROP_LENGTH);

    /* auth: any byte the tag covers, or the tag itself */
    n = command(d);
    d[n - 1] ^= 1;
    CHECK_EQ(decode(d, n), EXO_DROP_AUTH);
    n = command(d);
    d[2] = 1; /* a damaged version byte is damage: auth, not version */
    CHECK_EQ(decode(d, n), EXO_DROP_AUTH);
    uint8_t other[32];
    memset(other, 0x42, sizeof other);
    exo_hmac_key wrong;
    exo_hmac_set_key(&wrong, other, sizeof other);
    n = command(d);
    exo_packet p;
    CHECK_EQ(exo_wire_decode(&wrong, d, n, &p), EXO_DROP_AUTH); /* another key */

    /* version: authentic, but version 2 or 4; wins over type */
    n = command(d);
    d[2] = 2;
    retag(d, n);
    CHECK_EQ(exo_wire_decode(&key, d, n, &p), EXO_DROP_VERSION);
    CHECK_EQ(p.version, 2);
    d[2] = 4;
    d[3] = 9;
    retag(d, n);
    CHECK_EQ(decode(d, n), EXO_DROP_VERSION);
    /* ...but a VERSION packet is read whatever its version byte */
    n = exo_wire_encode_version(&key, 2, 7, d, sizeof d);
    CHECK_EQ(d[2], 7);
    CHECK_EQ(exo_wire_decode(&key, d, n, &p), EXO_DROP_NONE);
    CHECK_EQ(p.lowest, 2);
    CHECK_EQ(p.highest, 7);

    /* type */
    const uint8_t bad_types[3] = {0, 7, 255};
    for (unsigned i = 0; i < 3; i++) {
        n = command(d);
        d[3] = bad_types[i];
        d[6] = 0xFF; /* type wins over flags */
        retag(d, n);
        CHECK_EQ(decode(d, n), EXO_DROP_TYPE);
    }

    /* flags: undefined bits per type */
    n = command(d);
    exo_put_le16(d + 6, 0x0002);
    retag(d, n);
    CHECK_EQ(decode(d, n), EXO_DROP_FLAGS);
    n = command(d);
    exo_put_le16(d + 6, 0x8001);
    n = resize_payload(d, n, 13); /* flags win over payload size */
    CHECK_EQ(decode(d, n), EXO_DROP_FLAGS);
    size_t (*const no_flags[3])(uint8_t *) = {hello, challenge, join};
    for (unsigned i = 0; i < 3; i++) {
        n = no_flags[i](d);
        exo_put_le16(d + 6, 0x0001); /* HELLO, CHALLENGE, JOIN have no flags at all */
        retag(d, n);
        CHECK_EQ(decode(d, n), EXO_DROP_FLAGS);
    }
    n = exo_wire_encode_version(&key, 3, 3, d, sizeof d);
    exo_put_le16(d + 6, 0x0100);
    retag(d, n);
    CHECK_EQ(decode(d, n), EXO_DROP_FLAGS);
    n = sample(d, 0);
    exo_put_le16(d + 6, 0x0002);
    retag(d, n);
    CHECK_EQ(decode(d, n), EXO_DROP_FLAGS);

    /* length: payload size wrong for the type */
    const struct {
        size_t (*make)(uint8_t *);
        size_t right;
    } sized[4] = {{command, 12}, {hello, 8}, {challenge, 56}, {join, 24}};
    for (unsigned i = 0; i < 4; i++) {
        n = sized[i].make(d);
        CHECK_EQ(decode(d, resize_payload(d, n, sized[i].right + 1)), EXO_DROP_LENGTH);
        n = sized[i].make(d);
        CHECK_EQ(decode(d, resize_payload(d, n, sized[i].right - 1)), EXO_DROP_LENGTH);
    }
    n = exo_wire_encode_version(&key, 3, 3, d, sizeof d);
    exo_put_le16(d + 4, 5);
    d[12] = 0;
    retag(d, 45);
    CHECK_EQ(decode(d, 45), EXO_DROP_LENGTH);
    n = sample(d, 0);
    CHECK_EQ(decode(d, resize_payload(d, n, 35)), EXO_DROP_LENGTH);
    n = sample(d, 0);
    CHECK_EQ(decode(d, resize_payload(d, n, 37)), EXO_DROP_LENGTH);
    n = sample(d, 0);
    exo_put_le16(d + 6, EXO_SAMPLE_HAS_TRUTH); /* truth flag, no extension */
    retag(d, n);
    CHECK_EQ(decode(d, n), EXO_DROP_LENGTH);
    n = sample(d, 1);
    d[EXO_HEADER_BYTES + 48] = 6; /* activity length says 6, 5 bytes follow */
    retag(d, n);
    CHECK_EQ(decode(d, n), EXO_DROP_LENGTH);

    /* counts: any encoder above 16383; checked after the sample's exact size (the
     * document's order) and before status */
    for (unsigned i = 0; i < 4; i++) {
        n = sample(d, 0);
        exo_put_le16(d + EXO_HEADER_BYTES + 16 + 2 * i, 16384);
        exo_put_le32(d + EXO_HEADER_BYTES + 12, 0x800); /* counts win over status */
        retag(d, n);
        CHECK_EQ(decode(d, n), EXO_DROP_COUNTS);
    }
    n = sample(d, 0);
    exo_put_le16(d + EXO_HEADER_BYTES + 16, 0xFFFF);
    CHECK_EQ(decode(d, resize_payload(d, n, 37)), EXO_DROP_LENGTH);
    n = sample(d, 0);
    exo_put_le16(d + EXO_HEADER_BYTES + 16, 16383); /* the largest count is valid */
    retag(d, n);
    CHECK_EQ(decode(d, n), EXO_DROP_NONE);

    /* status: reserved bits 11..31 */
    for (unsigned bit = 11; bit < 32; bit++) {
        n = sample(d, 0);
        exo_put_le32(d + EXO_HEADER_BYTES + 12, (uint32_t)1 << bit);
        retag(d, n);
        CHECK_EQ(decode(d, n), EXO_DROP_STATUS);
    }
    n = sample(d, 0);
    exo_put_le32(d + EXO_HEADER_BYTES + 12, EXO_STATUS_KNOWN); /* every defined bit */
    retag(d, n);
    CHECK_EQ(decode(d, n), EXO_DROP_NONE);
    CHECK_EQ(EXO_STATUS_KNOWN, 0x7FF);

    /* reserved: COMMAND bytes 9..11 and lock bits 2..7; HELLO and JOIN bytes 4..7; a
     * HELLO's receiver session; VERSION's reserved bytes and lowest > highest; a
     * sender session of 0 in any packet that has one */
    for (unsigned i = 9; i < 12; i++) {
        n = command(d);
        d[EXO_HEADER_BYTES + i] = 0x80;
        retag(d, n);
        CHECK_EQ(decode(d, n), EXO_DROP_RESERVED);
    }
    for (unsigned bit = 2; bit < 8; bit++) {
        n = command(d);
        d[EXO_HEADER_BYTES + 8] = (uint8_t)(1u << bit);
        retag(d, n);
        CHECK_EQ(decode(d, n), EXO_DROP_RESERVED);
    }
    for (unsigned i = 4; i < 8; i++) {
        n = hello(d);
        d[EXO_HEADER_BYTES + i] = 1;
        retag(d, n);
        CHECK_EQ(decode(d, n), EXO_DROP_RESERVED);
        n = join(d);
        d[EXO_HEADER_BYTES + i] = 1;
        retag(d, n);
        CHECK_EQ(decode(d, n), EXO_DROP_RESERVED);
    }
    n = exo_wire_encode_hello(&key, 5, VEC_HOST_SESSION, VEC_DEVICE_SESSION, d, sizeof d);
    CHECK_EQ(decode(d, n), EXO_DROP_RESERVED);
    for (unsigned i = 10; i < 12; i++) {
        n = exo_wire_encode_version(&key, 3, 3, d, sizeof d);
        d[i] = 1;
        retag(d, n);
        CHECK_EQ(decode(d, n), EXO_DROP_RESERVED);
    }
    n = exo_wire_encode_version(&key, 3, 3, d, sizeof d);
    d[8] = 4; /* lowest 4 > highest 3 */
    retag(d, n);
    CHECK_EQ(decode(d, n), EXO_DROP_RESERVED);
    CHECK_EQ(exo_wire_encode_version(&key, 4, 3, d, sizeof d), 0);
    size_t (*const with_sender[4])(uint8_t *) = {command, hello, challenge, join};
    for (unsigned i = 0; i < 4; i++) {
        n = with_sender[i](d);
        set_sender(d, n, 0);
        CHECK_EQ(decode(d, n), EXO_DROP_RESERVED);
    }
    n = sample(d, 0);
    set_sender(d, n, 0);
    CHECK_EQ(decode(d, n), EXO_DROP_RESERVED);
    n = sample(d, 1);
    d[EXO_HEADER_BYTES + 49] = 0xFF; /* reserved (sender 0) wins over truth */
    set_sender(d, n, 0);
    CHECK_EQ(decode(d, n), EXO_DROP_RESERVED);
    n = challenge(d);
    d[EXO_HEADER_BYTES + 40] = 0; /* reserved (sender 0) wins over identity */
    set_sender(d, n, 0);
    CHECK_EQ(decode(d, n), EXO_DROP_RESERVED);
    CHECK_EQ(exo_wire_encode_command(&key, 1, 1, 0, 0, 0, 2, d, sizeof d), 0);

    /* truth: activity not UTF-8 */
    n = sample(d, 1);
    d[EXO_HEADER_BYTES + 49] = 0xC3;
    d[EXO_HEADER_BYTES + 50] = 0x28;
    retag(d, n);
    CHECK_EQ(decode(d, n), EXO_DROP_TRUTH);

    /* identity: firmware empty, not printable, or not NUL-padded */
    const struct {
        unsigned at;
        uint8_t value;
    } bad_fw[5] = {{0, 0}, {3, 0x1F}, {3, 0x7F}, {15, 'x'}, {5, 0xC3}};
    for (unsigned i = 0; i < 5; i++) {
        n = challenge(d);
        d[EXO_HEADER_BYTES + 40 + bad_fw[i].at] = bad_fw[i].value;
        retag(d, n);
        CHECK_EQ(decode(d, n), EXO_DROP_IDENTITY);
    }
    n = challenge(d);
    memset(d + EXO_HEADER_BYTES + 40, '~', 16); /* 16 printable characters, no NUL */
    retag(d, n);
    CHECK_EQ(decode(d, n), EXO_DROP_NONE);

    /* The drop reasons keep the Python reference's names. */
    static const char *const names[EXO_DROP_REASONS] = {
        "ok", "short", "magic", "length", "auth", "version", "type", "flags",
        "counts", "status", "reserved", "truth", "identity"};
    for (unsigned r = 0; r < EXO_DROP_REASONS; r++)
        CHECK(strcmp(exo_drop_reason_name((exo_drop_reason)r), names[r]) == 0);
    CHECK(strcmp(exo_drop_reason_name(EXO_DROP_REASONS), "?") == 0);
}

static void encoder_refuses(void)
{
    uint8_t d[EXO_MAX_PACKET];
    exo_sample_fields s = vector_sample(0);
    s.counts[2] = 16384;
    CHECK_EQ(exo_wire_encode_sample(&key, &s, 1, 2, d, sizeof d), 0);
    s = vector_sample(0);
    s.status = 0x800;
    CHECK_EQ(exo_wire_encode_sample(&key, &s, 1, 2, d, sizeof d), 0);
    s = vector_sample(1);
    s.truth.activity_len = 65;
    CHECK_EQ(exo_wire_encode_sample(&key, &s, 1, 2, d, sizeof d), 0);
    s = vector_sample(1);
    s.truth.activity[0] = (char)0xFF;
    CHECK_EQ(exo_wire_encode_sample(&key, &s, 1, 2, d, sizeof d), 0);
    CHECK_EQ(exo_wire_encode_command(&key, 1, 0, 4, 0, 1, 2, d, sizeof d), 0);
    exo_challenge_fields c = vector_challenge();
    c.firmware[0] = 0;
    CHECK_EQ(exo_wire_encode_challenge(&key, &c, 1, 2, d, sizeof d), 0);

    /* The largest packet: 64-byte activity, 169 bytes, and it decodes. */
    s = vector_sample(1);
    s.truth.activity_len = 64;
    memset(s.truth.activity, 'x', 64);
    size_t n = exo_wire_encode_sample(&key, &s, 1, 2, d, sizeof d);
    CHECK_EQ(n, EXO_MAX_PACKET);
    CHECK_EQ(n, 169);
    exo_packet p;
    CHECK_EQ(exo_wire_decode(&key, d, n, &p), EXO_DROP_NONE);
    CHECK_EQ(p.sample.truth.activity_len, 64);
}

/* The frozen VERSION layout and the firmware check on their own. */
static void version_and_identity(void)
{
    uint8_t d[EXO_MAX_PACKET];
    size_t n = exo_wire_encode_version(&key, 2, 3, d, sizeof d);
    CHECK_EQ(n, 44);
    CHECK_EQ(d[2], 3);
    CHECK_EQ(d[3], 6);
    CHECK_EQ(exo_le16(d + 4), 4);
    CHECK_EQ(d[8], 2);
    CHECK_EQ(d[9], 3);
    uint8_t fw[16];
    memset(fw, 0, sizeof fw);
    CHECK_EQ(exo_firmware_valid(fw), 0);
    memcpy(fw, "exo-linux-sim 3", 15);
    CHECK_EQ(exo_firmware_valid(fw), 1);
    fw[15] = ' ';
    CHECK_EQ(exo_firmware_valid(fw), 1);
    fw[14] = 0;
    CHECK_EQ(exo_firmware_valid(fw), 0); /* something after the padding */
}

static void utf8(void)
{
    static const struct {
        const char *bytes;
        size_t n;
        int valid;
    } cases[] = {
        {"", 0, 1},
        {"squat", 5, 1},
        {"\xc3\xa9", 2, 1},          /* e acute */
        {"\xe2\x82\xac", 3, 1},      /* euro sign */
        {"\xf0\x9d\x84\x9e", 4, 1},  /* U+1D11E, four bytes */
        {"\xf4\x8f\xbf\xbf", 4, 1},  /* U+10FFFF, the last code point */
        {"\xed\x9f\xbf", 3, 1},      /* U+D7FF, just below the surrogates */
        {"\x80", 1, 0},              /* stray continuation */
        {"\xc3", 1, 0},              /* truncated */
        {"\xe2\x82", 2, 0},          /* truncated */
        {"\xc3\x28", 2, 0},          /* bad continuation */
        {"\xc0\x80", 2, 0},          /* overlong NUL */
        {"\xc1\xbf", 2, 0},          /* overlong */
        {"\xe0\x80\x80", 3, 0},      /* overlong */
        {"\xe0\x9f\xbf", 3, 0},      /* overlong */
        {"\xed\xa0\x80", 3, 0},      /* surrogate U+D800 */
        {"\xf0\x80\x80\x80", 4, 0},  /* overlong */
        {"\xf4\x90\x80\x80", 4, 0},  /* above U+10FFFF */
        {"\xf5\x80\x80\x80", 4, 0},  /* lead byte out of range */
        {"\xff", 1, 0},
        {"ok\xe2\x82\xac\x80", 6, 0}, /* trailing stray continuation */
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        CHECK_EQ(exo_utf8_valid((const uint8_t *)cases[i].bytes, cases[i].n), cases[i].valid);
}

void test_wire(void)
{
    set_vector_key();
    encode_vectors();
    decode_vectors();
    bit_flips();
    validation_order();
    encoder_refuses();
    version_and_identity();
    utf8();
}
