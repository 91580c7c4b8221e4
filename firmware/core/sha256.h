/*
 * sha256.h - SHA-256 (FIPS 180-4), streaming.
 *
 * Written for the device core: no heap, no libc beyond memcpy/memset, and a context
 * small enough to keep two copies in the device struct (the HMAC's precomputed inner
 * and outer states).
 */
#ifndef EXO_SHA256_H
#define EXO_SHA256_H

#include <stddef.h>
#include <stdint.h>

#define EXO_SHA256_BYTES 32
#define EXO_SHA256_BLOCK 64

typedef struct {
    uint32_t h[8];                   /* chaining value */
    uint64_t total;                  /* bytes hashed so far */
    uint8_t block[EXO_SHA256_BLOCK]; /* partial block waiting for more input */
    size_t fill;                     /* bytes in `block` */
} exo_sha256_ctx;

void exo_sha256_init(exo_sha256_ctx *c);
void exo_sha256_update(exo_sha256_ctx *c, const uint8_t *data, size_t len);
void exo_sha256_final(exo_sha256_ctx *c, uint8_t out[EXO_SHA256_BYTES]);

/* One-shot convenience. */
void exo_sha256(const uint8_t *data, size_t len, uint8_t out[EXO_SHA256_BYTES]);

#endif /* EXO_SHA256_H */
