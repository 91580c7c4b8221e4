/*
 * wire.h - packet layouts of the device protocol, version 3 (docs/device-protocol.md).
 *
 * Encoding and decoding only: no state. The decoder applies the checks in exactly the
 * order the protocol document lists them and returns the first failure as a drop
 * reason, so the firmware counts drops under the same names as the Python reference
 * device (controller/device/protocol.py). Multi-byte fields are little-endian on the
 * wire whatever the CPU is; they are assembled byte by byte, never by casting.
 */
#ifndef EXO_WIRE_H
#define EXO_WIRE_H

#include <stddef.h>
#include <stdint.h>

#include "exo_board.h"
#include "hmac.h"

#define EXO_WIRE_VERSION 3u
#define EXO_WIRE_LOWEST_VERSION 3u /* the versions this core speaks: 3..3 */
#define EXO_HEADER_BYTES 8u
#define EXO_SESSIONS_BYTES 16u /* sender's session u64, receiver's session u64 */
#define EXO_TAG_BYTES 32u      /* HMAC-SHA256 */
#define EXO_TRAILER_BYTES (EXO_SESSIONS_BYTES + EXO_TAG_BYTES)
#define EXO_SESSION_PACKET (EXO_HEADER_BYTES + EXO_TRAILER_BYTES) /* 56 + payload */
#define EXO_VERSION_BODY_BYTES 4u
#define EXO_VERSION_PACKET (EXO_HEADER_BYTES + EXO_VERSION_BODY_BYTES + EXO_TAG_BYTES) /* 44 */
#define EXO_MIN_PACKET EXO_VERSION_PACKET /* the smallest packet of any type */
#define EXO_SAMPLE_BODY_BYTES 36u
#define EXO_TRUTH_BODY_BYTES 13u /* progress f64, lift i32, activity length u8 */
#define EXO_MAX_ACTIVITY_BYTES 64u
#define EXO_COMMAND_BODY_BYTES 12u
#define EXO_HELLO_BODY_BYTES 8u
#define EXO_CHALLENGE_BODY_BYTES 56u
#define EXO_JOIN_BODY_BYTES 24u
#define EXO_CHALLENGE_BYTES 16u /* the device's random challenge */
#define EXO_UNIQUE_ID_BYTES 16u
#define EXO_FIRMWARE_BYTES 16u
#define EXO_MAX_PACKET                                                                       \
    (EXO_HEADER_BYTES + EXO_SAMPLE_BODY_BYTES + EXO_TRUTH_BODY_BYTES + EXO_MAX_ACTIVITY_BYTES \
     + EXO_TRAILER_BYTES) /* 169 */
#define EXO_ENCODER_COUNTS 16384u /* 14-bit AS5048A */

/* Packet types (header byte 3). */
#define EXO_TYPE_SAMPLE 1u
#define EXO_TYPE_COMMAND 2u
#define EXO_TYPE_HELLO 3u
#define EXO_TYPE_CHALLENGE 4u
#define EXO_TYPE_JOIN 5u
#define EXO_TYPE_VERSION 6u /* frozen layout: header, lowest, highest, reserved, tag */

/* Flags (header bytes 6-7). */
#define EXO_SAMPLE_HAS_TRUTH 0x0001u
#define EXO_COMMAND_STOP_HEARTBEAT 0x0001u

/* Lock bits of a COMMAND. */
#define EXO_LOCK_LEFT 0x01u
#define EXO_LOCK_RIGHT 0x02u

/* Status bits of a SAMPLE (same values as controller.device.base.Status). */
#define EXO_STATUS_SOLENOID_LEFT 0x001u
#define EXO_STATUS_SOLENOID_RIGHT 0x002u
#define EXO_STATUS_LOCKED_LEFT 0x004u
#define EXO_STATUS_LOCKED_RIGHT 0x008u
#define EXO_STATUS_HARD_STOP_LEFT 0x010u
#define EXO_STATUS_HARD_STOP_RIGHT 0x020u
#define EXO_STATUS_ENCODER_FAULT 0x040u
#define EXO_STATUS_WATCHDOG_RELEASED 0x080u
#define EXO_STATUS_SUPPLY_FAULT 0x100u
#define EXO_STATUS_HEARTBEAT_STOPPED 0x200u
#define EXO_STATUS_DRIVERS_OFF 0x400u
#define EXO_STATUS_KNOWN 0x7FFu /* bits 11-31 are reserved and must be 0 */

/* Why a datagram was dropped, in the protocol document's validation order. The
 * names (exo_drop_reason_name) are those of the Python ProtocolError reasons. */
typedef enum {
    EXO_DROP_NONE = 0, /* valid */
    EXO_DROP_SHORT,    /* shorter than 44 bytes (empty included) */
    EXO_DROP_MAGIC,    /* not "EX" */
    EXO_DROP_LENGTH,   /* datagram or payload size wrong */
    EXO_DROP_AUTH,     /* tag mismatch */
    EXO_DROP_VERSION,  /* authentic, but not version 3 (VERSION packets excepted) */
    EXO_DROP_TYPE,     /* unknown packet type */
    EXO_DROP_FLAGS,    /* undefined flag bit */
    EXO_DROP_COUNTS,   /* encoder count above 16383 */
    EXO_DROP_STATUS,   /* reserved status bit */
    EXO_DROP_RESERVED, /* reserved bytes, lock bits, HELLO receiver, VERSION range, sender 0 */
    EXO_DROP_TRUTH,    /* activity name not valid UTF-8 */
    EXO_DROP_IDENTITY, /* CHALLENGE firmware field not printable, NUL-padded, non-empty */
    EXO_DROP_REASONS   /* number of entries, for arrays indexed by reason */
} exo_drop_reason;

/* "short", "magic", ...; "ok" for EXO_DROP_NONE, "?" out of range. */
const char *exo_drop_reason_name(exo_drop_reason r);

typedef struct {
    uint64_t t_us;
    uint32_t seq;
    uint32_t status;
    uint16_t counts[4]; /* left output, left cam, right output, right cam */
    uint32_t auth_drops;
    uint32_t replay_drops;
    uint32_t stale_drops;
    int has_truth;
    exo_truth truth; /* only if has_truth */
} exo_sample_fields;

typedef struct {
    uint32_t hello_seq;
    uint32_t lifetime_ms;
    uint8_t challenge[EXO_CHALLENGE_BYTES];
    uint8_t unique_id[EXO_UNIQUE_ID_BYTES];
    uint8_t firmware[EXO_FIRMWARE_BYTES]; /* printable ASCII, NUL-padded */
} exo_challenge_fields;

/* A decoded, valid packet. */
typedef struct {
    unsigned type;     /* EXO_TYPE_* */
    unsigned version;  /* header byte 2 (3, or anything for a VERSION packet) */
    uint64_t sender;   /* sender's session (0 for VERSION, which has none) */
    uint64_t receiver; /* receiver's session as the sender knows it (0 in a HELLO) */
    exo_sample_fields sample;       /* SAMPLE */
    exo_challenge_fields challenge; /* CHALLENGE */
    uint8_t join_challenge[EXO_CHALLENGE_BYTES]; /* JOIN: the challenge it answers */
    uint32_t host_seq;  /* COMMAND, HELLO and JOIN */
    uint32_t echo_seq;  /* COMMAND */
    unsigned locks;     /* COMMAND: EXO_LOCK_* */
    int stop_heartbeat; /* COMMAND: flag STOP_HEARTBEAT */
    unsigned lowest, highest; /* VERSION */
} exo_packet;

/* Check one datagram and, if it is valid, fill `out`. Returns EXO_DROP_NONE or the
 * first failing check; `out` is unspecified on failure, except that on
 * EXO_DROP_VERSION out->version holds the version byte. */
exo_drop_reason exo_wire_decode(const exo_hmac_key *key, const uint8_t *data, size_t len,
                                exo_packet *out);

/* Encoders: write one packet into `buf` (at least EXO_MAX_PACKET bytes, or the exact
 * size) and return its length, or 0 if `cap` is too small or a field cannot be sent
 * (a count above 16383, a reserved status bit, a truth activity over 64 bytes or not
 * UTF-8, lock bits beyond left/right, a firmware name that is not printable ASCII,
 * NUL-padded and non-empty, a sender session of 0, lowest > highest). */
size_t exo_wire_encode_sample(const exo_hmac_key *key, const exo_sample_fields *s,
                              uint64_t sender, uint64_t receiver, uint8_t *buf, size_t cap);
size_t exo_wire_encode_command(const exo_hmac_key *key, uint32_t host_seq, uint32_t echo_seq,
                               unsigned locks, int stop_heartbeat, uint64_t sender,
                               uint64_t receiver, uint8_t *buf, size_t cap);
/* `receiver` is 0 in every valid HELLO; tests pass another value to make a bad one. */
size_t exo_wire_encode_hello(const exo_hmac_key *key, uint32_t host_seq, uint64_t sender,
                             uint64_t receiver, uint8_t *buf, size_t cap);
size_t exo_wire_encode_challenge(const exo_hmac_key *key, const exo_challenge_fields *c,
                                 uint64_t sender, uint64_t receiver, uint8_t *buf, size_t cap);
size_t exo_wire_encode_join(const exo_hmac_key *key, uint32_t host_seq,
                            const uint8_t challenge[EXO_CHALLENGE_BYTES], uint64_t sender,
                            uint64_t receiver, uint8_t *buf, size_t cap);
/* VERSION: header version byte = `highest`. */
size_t exo_wire_encode_version(const exo_hmac_key *key, unsigned lowest, unsigned highest,
                               uint8_t *buf, size_t cap);

/* 1 if the `n` bytes are well-formed UTF-8 as Python's strict decoder sees it (no
 * overlong forms, no surrogates, nothing above U+10FFFF), else 0. */
int exo_utf8_valid(const uint8_t *s, size_t n);

/* 1 if `f` is a valid firmware field: printable ASCII (0x20-0x7e), then only NULs,
 * first byte not NUL. */
int exo_firmware_valid(const uint8_t f[EXO_FIRMWARE_BYTES]);

/* Little-endian field access, byte by byte (alignment- and endian-independent). */
uint16_t exo_le16(const uint8_t *p);
uint32_t exo_le32(const uint8_t *p);
uint64_t exo_le64(const uint8_t *p);
void exo_put_le16(uint8_t *p, uint16_t v);
void exo_put_le32(uint8_t *p, uint32_t v);
void exo_put_le64(uint8_t *p, uint64_t v);

#endif /* EXO_WIRE_H */
