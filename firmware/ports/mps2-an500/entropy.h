/*
 * entropy.h - random bytes for the device core on a board without a random number
 * generator: EMULATION ONLY (emu_prov.h says why).
 *
 * Every request returns HMAC-SHA256(seed, counter || timer), the counter rising by one
 * per 32-byte block, the timer the raw 25 MHz counter at the call. Without the seed
 * the output cannot be predicted (HMAC as a pseudo-random function); with a seed that
 * is new at every boot, no two boots draw the same sessions or challenges. The timer
 * adds the host's scheduling jitter, which nobody should count on.
 */
#ifndef ENTROPY_H
#define ENTROPY_H

#include <stddef.h>
#include <stdint.h>

void entropy_init(const uint8_t seed[32]);

/* 0, or -1 before entropy_init. The exo_board random_bytes signature. */
int entropy_read(void *ctx, uint8_t *out, size_t n);

#endif /* ENTROPY_H */
