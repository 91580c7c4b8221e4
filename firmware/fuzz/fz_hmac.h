/*
 * fz_hmac.h - HMAC-SHA256 written again for the fuzz harnesses.
 *
 * The harnesses build and check datagrams with this copy, not with the core's
 * (core/hmac.c), so that a harness that re-authenticates a mutated datagram or checks
 * a tag the device sent does not share a bug with the code under test. Speed does
 * not matter here; clarity does.
 */
#ifndef FZ_HMAC_H
#define FZ_HMAC_H

#include <stddef.h>
#include <stdint.h>

#define FZ_TAG_BYTES 32u

/* HMAC-SHA256 of `n` bytes under a 32-byte key. */
void fz_hmac(const uint8_t key[32], const uint8_t *data, size_t n, uint8_t out[FZ_TAG_BYTES]);

/* Write the tag of the first len-32 bytes into the last 32 (len >= 32). */
void fz_reauth(const uint8_t key[32], uint8_t *data, size_t len);

/* 1 if the last 32 bytes are the tag of the bytes before them (len >= 32). */
int fz_tag_ok(const uint8_t key[32], const uint8_t *data, size_t len);

#endif /* FZ_HMAC_H */
