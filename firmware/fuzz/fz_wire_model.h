/*
 * fz_wire_model.h - the protocol's validation table (docs/device-protocol.md, version
 * 3, "Validation"), written again from the document alone for the fuzz harnesses.
 *
 * It shares no code with core/wire.c: the harnesses compare the core's verdict and
 * fields with this one's, and build datagrams with fz_wire_build_*, so a
 * misreading of the document in either shows up as a disagreement.
 */
#ifndef FZ_WIRE_MODEL_H
#define FZ_WIRE_MODEL_H

#include <stddef.h>
#include <stdint.h>

#define FZ_VERSION 3u
#define FZ_T_SAMPLE 1u
#define FZ_T_COMMAND 2u
#define FZ_T_HELLO 3u
#define FZ_T_CHALLENGE 4u
#define FZ_T_JOIN 5u
#define FZ_T_VERSION 6u
#define FZ_MAX_DATAGRAM 256u /* larger than any packet (169 bytes) */

/* Verdicts, in the document's order; names are the shared drop reason names. */
typedef enum {
    FZ_OK = 0,
    FZ_SHORT,
    FZ_MAGIC,
    FZ_LENGTH,
    FZ_AUTH,
    FZ_VERSION_R,
    FZ_TYPE,
    FZ_FLAGS,
    FZ_COUNTS,
    FZ_STATUS,
    FZ_RESERVED,
    FZ_TRUTH,
    FZ_IDENTITY,
    FZ_REASONS
} fz_reason;

const char *fz_reason_name(fz_reason r);

typedef struct {
    unsigned version, type, flags;
    uint64_t sender, receiver; /* 0, 0 for VERSION */
    /* SAMPLE */
    uint64_t t_us;
    uint32_t seq, status;
    uint16_t counts[4];
    uint32_t auth_drops, replay_drops, stale_drops;
    int has_truth;
    uint64_t progress_bits;
    int32_t lift_index;
    uint8_t activity_len;
    uint8_t activity[255];
    /* COMMAND, HELLO, JOIN */
    uint32_t host_seq;
    uint32_t echo_seq;
    unsigned locks;
    int stop_heartbeat;
    /* CHALLENGE (and JOIN's challenge) */
    uint32_t hello_seq, lifetime_ms;
    uint8_t challenge[16], unique_id[16], firmware[16];
    /* VERSION */
    unsigned lowest, highest;
} fz_pkt;

/* The verdict on one datagram under `key`; fills `out` when FZ_OK. */
fz_reason fz_wire_check(const uint8_t key[32], const uint8_t *d, size_t n, fz_pkt *out);

/* Builders (tag included); return the length. `buf` holds FZ_MAX_DATAGRAM bytes. */
size_t fz_build_hello(const uint8_t key[32], uint8_t *buf, uint32_t seq, uint64_t sender,
                      uint64_t receiver);
size_t fz_build_join(const uint8_t key[32], uint8_t *buf, uint32_t seq,
                     const uint8_t challenge[16], uint64_t sender, uint64_t receiver);
size_t fz_build_command(const uint8_t key[32], uint8_t *buf, uint32_t seq, uint32_t echo,
                        unsigned locks, int stop_heartbeat, uint64_t sender, uint64_t receiver);
size_t fz_build_version(const uint8_t key[32], uint8_t *buf, unsigned lowest, unsigned highest);

/* Little-endian helpers. */
uint32_t fz_le32(const uint8_t *p);
uint64_t fz_le64(const uint8_t *p);
void fz_put32(uint8_t *p, uint32_t v);
void fz_put64(uint8_t *p, uint64_t v);

#endif /* FZ_WIRE_MODEL_H */
