/*
 * wire.h - packet layouts of the device protocol, version 2 (docs/device-protocol.md).
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

#define EXO_WIRE_VERSION 2u
#define EXO_HEADER_BYTES 8u
#define EXO_SESSIONS_BYTES 16u /* sender's session u64, receiver's session u64 */
#define EXO_TAG_BYTES 32u      /* HMAC-SHA256 */
#define EXO_TRAILER_BYTES (EXO_SESSIONS_BYTES + EXO_TAG_BYTES)
#define EXO_MIN_PACKET (EXO_HEADER_BYTES + EXO_TRAILER_BYTES) /* 56 */
#define EXO_SAMPLE_BODY_BYTES 32u
#define EXO_TRUTH_BODY_BYTES 13u /* progress f64, lift i32, activity length u8 */
#define EXO_MAX_ACTIVITY_BYTES 64u
#define EXO_COMMAND_BODY_BYTES 12u
#define EXO_HELLO_BODY_BYTES 8u
#define EXO_MAX_PACKET                                                                       \
    (EXO_HEADER_BYTES + EXO_SAMPLE_BODY_BYTES + EXO_TRUTH_BODY_BYTES + EXO_MAX_ACTIVITY_BYTES \
     + EXO_TRAILER_BYTES) /* 165 */
#define EXO_ENCODER_COUNTS 16384u /* 14-bit AS5048A */

/* Packet types (header byte 3). */
#define EXO_TYPE_SAMPLE 1u
#define EXO_TYPE_COMMAND 2u
#define EXO_TYPE_HELLO 3u

/* Flags (header bytes 6-7). */
#define EXO_SAMPLE_HAS_TRUTH 0x0001u
#define EXO_COMMAND_ECHO_VALID 0x0001u

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
#define EXO_STATUS_KNOWN 0x1FFu /* bits 9-31 are reserved and must be 0 */

/* Why a datagram was dropped, in the protocol document's validation order. The
 * names (exo_drop_reason_name) are those of the Python ProtocolError reasons. */
typedef enum {
    EXO_DROP_NONE = 0, /* valid */
    EXO_DROP_SHORT,    /* shorter than 56 bytes */
    EXO_DROP_MAGIC,    /* not "EX" */
    EXO_DROP_LENGTH,   /* datagram or payload size wrong */
    EXO_DROP_AUTH,     /* tag mismatch */
    EXO_DROP_VERSION,  /* authentic, but not version 2 */
    EXO_DROP_TYPE,     /* unknown packet type */
    EXO_DROP_FLAGS,    /* undefined flag bit */
    EXO_DROP_COUNTS,   /* encoder count above 16383 */
    EXO_DROP_STATUS,   /* reserved status bit */
    EXO_DROP_RESERVED, /* reserved bytes or lock bits not zero */
    EXO_DROP_TRUTH,    /* activity name not valid UTF-8 */
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
    int has_truth;
    exo_truth truth; /* only if has_truth */
} exo_sample_fields;

/* A decoded, valid packet. */
typedef struct {
    unsigned type;     /* EXO_TYPE_* */
    uint64_t sender;   /* sender's session */
    uint64_t receiver; /* receiver's session as the sender knows it (0: unknown) */
    exo_sample_fields sample; /* SAMPLE */
    uint32_t host_seq;        /* COMMAND and HELLO */
    uint32_t echo_seq;        /* COMMAND, meaningful if echo_valid */
    int echo_valid;
    unsigned locks; /* COMMAND: EXO_LOCK_* */
} exo_packet;

/* Check one datagram and, if it is valid, fill `out`. Returns EXO_DROP_NONE or the
 * first failing check; `out` is unspecified on failure. */
exo_drop_reason exo_wire_decode(const exo_hmac_key *key, const uint8_t *data, size_t len,
                                exo_packet *out);

/* Encoders: write one packet into `buf` (at least EXO_MAX_PACKET bytes, or the exact
 * size) and return its length, or 0 if `cap` is too small or a field cannot be sent
 * (a count above 16383, a reserved status bit, a truth activity over 64 bytes or not
 * UTF-8, lock bits beyond left/right). */
size_t exo_wire_encode_sample(const exo_hmac_key *key, const exo_sample_fields *s,
                              uint64_t sender, uint64_t receiver, uint8_t *buf, size_t cap);
size_t exo_wire_encode_command(const exo_hmac_key *key, uint32_t host_seq, int echo_valid,
                               uint32_t echo_seq, unsigned locks, uint64_t sender,
                               uint64_t receiver, uint8_t *buf, size_t cap);
size_t exo_wire_encode_hello(const exo_hmac_key *key, uint32_t host_seq, uint64_t sender,
                             uint64_t receiver, uint8_t *buf, size_t cap);

/* 1 if the `n` bytes are well-formed UTF-8 as Python's strict decoder sees it (no
 * overlong forms, no surrogates, nothing above U+10FFFF), else 0. */
int exo_utf8_valid(const uint8_t *s, size_t n);

/* Little-endian field access, byte by byte (alignment- and endian-independent). */
uint16_t exo_le16(const uint8_t *p);
uint32_t exo_le32(const uint8_t *p);
uint64_t exo_le64(const uint8_t *p);
void exo_put_le16(uint8_t *p, uint16_t v);
void exo_put_le32(uint8_t *p, uint32_t v);
void exo_put_le64(uint8_t *p, uint64_t v);

#endif /* EXO_WIRE_H */
