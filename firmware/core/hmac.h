/*
 * hmac.h - HMAC-SHA256 (RFC 2104) and a constant-time comparison.
 *
 * The device authenticates every packet with the same link key, so the key is
 * absorbed once (exo_hmac_set_key): the SHA-256 states after the inner and outer
 * padded key blocks are kept, and each tag then costs only the message's blocks plus
 * one outer block instead of two extra key blocks.
 */
#ifndef EXO_HMAC_H
#define EXO_HMAC_H

#include <stddef.h>
#include <stdint.h>

#include "sha256.h"

typedef struct {
    exo_sha256_ctx inner; /* state after (key ^ ipad) */
    exo_sha256_ctx outer; /* state after (key ^ opad) */
} exo_hmac_key;

/* Absorb `key` (any length; longer than a block is hashed first, as RFC 2104 says). */
void exo_hmac_set_key(exo_hmac_key *k, const uint8_t *key, size_t key_len);

/* The tag of the concatenation of `a` (a_len bytes) and `b` (b_len bytes; may be NULL
 * with b_len 0). Two parts let a caller tag a packet it has not copied together. */
void exo_hmac_sha256(const exo_hmac_key *k, const uint8_t *a, size_t a_len, const uint8_t *b,
                     size_t b_len, uint8_t out[EXO_SHA256_BYTES]);

/* 1 if the `n` bytes are equal, else 0, in time that does not depend on where they
 * differ (a tag check that stops at the first wrong byte tells a forger how many of
 * its leading bytes were right). */
int exo_ct_equal(const uint8_t *a, const uint8_t *b, size_t n);

/* Overwrite `n` bytes at `p` with zeros in a way the compiler may not remove: every
 * store goes through a volatile pointer, so it is an observable side effect even when
 * the buffer is dead afterwards (a plain memset of a dead buffer may be optimised
 * away). Used for everything that holds key material. */
void exo_secure_zero(void *p, size_t n);

#endif /* EXO_HMAC_H */
